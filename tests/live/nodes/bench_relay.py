#!/usr/bin/python3
"""A plain rospy relay, the baseline of ``bench/monitor_latency.py``.

    bench_relay.py --type PKG/Msg --input T --output T2 [--raw]

It subscribes with the message class (messages are decoded) and republishes each one as it
comes; queues of 100 and TCP_NODELAY on its subscription, as the monitor's relays.
``--raw``: it subscribes with ``rospy.AnyMsg`` and republishes the bytes as they came (no
decoding, no encoding; what the monitor does on a blocked topic, less the checks).
"""

from __future__ import annotations

import argparse
from typing import Any

import rospy  # type: ignore[import-not-found]
from roslib.message import get_message_class  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--type", required=True)
    parser.add_argument("--input", required=True)
    parser.add_argument("--output", required=True)
    parser.add_argument("--raw", action="store_true")
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("bench_relay")
    cls = get_message_class(args.type)
    publisher = rospy.Publisher(args.output, cls, queue_size=100)

    def relay(message: Any) -> None:
        publisher.publish(message)

    subscribed = rospy.AnyMsg if args.raw else cls
    rospy.Subscriber(args.input, subscribed, relay, queue_size=100, tcp_nodelay=True)
    rospy.spin()


if __name__ == "__main__":
    main()
