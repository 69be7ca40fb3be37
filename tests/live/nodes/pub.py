#!/usr/bin/python3
"""Publishes one message, given as JSON, on a topic: an injector, or a second publisher.

    pub.py TOPIC TYPE JSON [--rate HZ] [--count N] [--wait-subscribers K] [--stamp]

``TYPE`` is ``pkg/Msg``; ``JSON`` an object of the fields (``'{"data": 3}'``). It waits until
``K`` subscribers are connected (0: does not wait), publishes ``N`` messages at ``HZ``
(``--count 0``: until shut down), with ``--stamp`` setting ``header.stamp`` to now on each,
then stays registered until shut down.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import TYPE_CHECKING

import rospy  # type: ignore[import-not-found]
from genpy.message import fill_message_args  # type: ignore[import-not-found]
from roslib.message import get_message_class  # type: ignore[import-not-found]

if TYPE_CHECKING:  # mypy sees this folder as a namespace package
    from tests.live.nodes.livenode import init_node
else:  # run as a script, the folder is on sys.path
    from livenode import init_node


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("topic")
    parser.add_argument("type")
    parser.add_argument("values", nargs="?", default="{}")
    parser.add_argument("--rate", type=float, default=10.0)
    parser.add_argument("--count", type=int, default=0)
    parser.add_argument("--wait-subscribers", type=int, default=0)
    parser.add_argument("--stamp", action="store_true")
    args = parser.parse_args(rospy.myargv()[1:])
    init_node("pub", anonymous=True)
    cls = get_message_class(args.type)
    if cls is None:
        parser.error(f"unknown message type {args.type}")
    publisher = rospy.Publisher(args.topic, cls, queue_size=100)
    deadline = time.monotonic() + 30.0
    while (
        publisher.get_num_connections() < args.wait_subscribers
        and time.monotonic() < deadline
        and not rospy.is_shutdown()
    ):
        time.sleep(0.02)
    values = json.loads(args.values)
    rate = rospy.Rate(args.rate)
    sent = 0
    while not rospy.is_shutdown() and (args.count == 0 or sent < args.count):
        message = cls()
        fill_message_args(message, [values])
        if args.stamp:
            message.header.stamp = rospy.Time.now()
        publisher.publish(message)
        sent += 1
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break
    rospy.spin()


if __name__ == "__main__":
    main()
