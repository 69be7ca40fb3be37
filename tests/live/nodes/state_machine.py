#!/usr/bin/python3
"""The consumer of the landing example: the UAV's state machine.

Started as ``/a/ctrl_state_machine`` it subscribes to ``/a/cmd_subject_ctrl_state`` (a blocked
topic: the monitor's launch file remaps it to ``/m/a/cmd_subject_ctrl_state``) and publishes
the last command it received as ``std_msgs/UInt8`` on ``/a/subject_ctrl_state`` at ``--rate``
(10 Hz; 0 before the first command). With ``--log FILE`` it writes every command it receives
as a JSON line ``{"t": receipt time, "data": state, "callerid": publisher}``.
"""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

import rospy  # type: ignore[import-not-found]

if TYPE_CHECKING:  # mypy sees this folder as a namespace package
    from tests.live.nodes.livenode import init_node, open_log, parse, write_line
else:  # run as a script, the folder is on sys.path
    from livenode import init_node, open_log, parse, write_line
from std_msgs.msg import UInt8  # type: ignore[import-not-found]


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rate", type=float, default=10.0)
    parser.add_argument("--log", default="")


def main() -> None:
    args = parse(__doc__ or "", options)
    init_node("ctrl_state_machine")
    log = open_log(args.log) if args.log else None
    last = {"data": 0}

    def on_command(message: Any) -> None:
        last["data"] = int(message.data)
        if log is not None:
            header = getattr(message, "_connection_header", None) or {}
            record = {"t": time.time(), "data": last["data"], "callerid": header.get("callerid")}
            write_line(log, record)

    rospy.Subscriber("/a/cmd_subject_ctrl_state", UInt8, on_command, queue_size=10)
    publisher = rospy.Publisher("/a/subject_ctrl_state", UInt8, queue_size=10)
    rate = rospy.Rate(args.rate)
    while not rospy.is_shutdown():
        publisher.publish(UInt8(data=last["data"]))
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


if __name__ == "__main__":
    main()
