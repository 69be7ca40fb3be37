#!/usr/bin/python3
"""The source of ``bench/monitor_latency.py``: stamped messages at a fixed rate.

    bench_source.py --type PKG/Msg --topic T --rows ROWS.npy --rate HZ --seconds S --out FILE

Each message is a row of ``ROWS.npy`` (its columns fill the message's float fields in
order, rows taken in turn), its ``header.stamp`` set to now right before it is published. It
waits for a subscriber, publishes for ``S`` seconds, writes how many messages it published
to ``FILE`` and exits.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import rospy  # type: ignore[import-not-found]
from roslib.message import get_message_class  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--type", required=True)
    parser.add_argument("--topic", required=True)
    parser.add_argument("--rows", required=True)
    parser.add_argument("--rate", type=float, required=True)
    parser.add_argument("--seconds", type=float, required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("bench_source")
    cls = get_message_class(args.type)
    fields = [n for n, t in zip(cls.__slots__, cls._slot_types, strict=True) if t == "float64"]
    messages = []
    for row in np.load(args.rows).tolist():
        message = cls()
        for name, value in zip(fields, row, strict=True):
            setattr(message, name, value)
        messages.append(message)
    publisher = rospy.Publisher(args.topic, cls, queue_size=100)
    while publisher.get_num_connections() < 1 and not rospy.is_shutdown():
        time.sleep(0.01)
    rate = rospy.Rate(args.rate)
    end = time.monotonic() + args.seconds
    k = 0
    while time.monotonic() < end and not rospy.is_shutdown():
        message = messages[k % len(messages)]
        message.header.seq = k
        message.header.stamp = rospy.Time.now()
        publisher.publish(message)
        k += 1
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break
    with open(args.out, "w", encoding="utf-8") as out:
        out.write(f"{k}\n")
    time.sleep(0.2)
    rospy.signal_shutdown(f"published {k} messages")


if __name__ == "__main__":
    main()
