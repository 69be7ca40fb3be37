#!/usr/bin/python3
"""Writes every message of some topics as JSON lines, for a test to read.

    listener.py --out FILE TOPIC [TOPIC...]

Each line is ``{"topic", "t" (receipt time), "callerid" (publisher), "type", "msg"}``; any
message type works (rospy.AnyMsg, decoded with the type of the connection). The file is
line-buffered: a test reading it sees each message as soon as it is written.
"""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

import rospy  # type: ignore[import-not-found]

if TYPE_CHECKING:  # mypy sees this folder as a namespace package
    from tests.live.nodes.livenode import init_node, open_log, to_plain, write_line
else:  # run as a script, the folder is on sys.path
    from livenode import init_node, open_log, to_plain, write_line
from roslib.message import get_message_class  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True)
    parser.add_argument("topics", nargs="+")
    args = parser.parse_args(rospy.myargv()[1:])
    init_node("listener", anonymous=True)
    log = open_log(args.out)
    classes: dict[str, Any] = {}

    def make_callback(topic: str) -> Any:
        def on_message(raw: Any) -> None:
            received = time.time()
            header = raw._connection_header
            kind = header["type"]
            cls = classes.get(kind)
            if cls is None:
                cls = classes[kind] = get_message_class(kind)
            message = cls().deserialize(raw._buff)
            record = {
                "topic": topic,
                "t": received,
                "callerid": header.get("callerid"),
                "type": kind,
                "msg": to_plain(message),
            }
            write_line(log, record)

        return on_message

    for topic in args.topics:
        rospy.Subscriber(topic, rospy.AnyMsg, make_callback(topic), queue_size=100)
    rospy.spin()


if __name__ == "__main__":
    main()
