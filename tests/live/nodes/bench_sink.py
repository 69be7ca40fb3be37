#!/usr/bin/python3
"""The sink of ``bench/monitor_latency.py``: the latency of every message it receives.

    bench_sink.py --type PKG/Msg --topic T --out FILE

For each message it keeps its sequence number, its receipt time and receipt minus
``header.stamp`` (seconds); on shutdown it writes them as one JSON object to ``FILE``.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import rospy  # type: ignore[import-not-found]
from roslib.message import get_message_class  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--type", required=True)
    parser.add_argument("--topic", required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("bench_sink")
    cls = get_message_class(args.type)
    seqs: list[int] = []
    received: list[float] = []
    latencies: list[float] = []

    def on_message(message: Any) -> None:
        now = time.time()
        stamp = message.header.stamp
        latencies.append(now - (stamp.secs + stamp.nsecs * 1e-9))
        received.append(now)
        seqs.append(message.header.seq)

    def write() -> None:
        record = {"seq": seqs, "received": received, "latency": latencies}
        with open(args.out, "w", encoding="utf-8") as out:
            json.dump(record, out)

    rospy.Subscriber(args.topic, cls, on_message, queue_size=100)
    rospy.on_shutdown(write)
    rospy.spin()


if __name__ == "__main__":
    main()
