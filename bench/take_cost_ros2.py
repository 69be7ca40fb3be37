"""CPU time per message of the ROS 2 monitor's way of taking a blocked topic's messages,
against rclpy's executor and bare relays, in one process, so the machine's load moves every
figure alike.

    python bench/take_cost_ros2.py [--blocks 40] [--runs 3]

Needs the ROS 2 interpreter (``IMROSC_ROS2_PYTHON``, or the virtualenv ``tools/ros2_venv.sh``
builds). One rclpy process, on a DDS domain of its own with discovery kept on the machine,
holds a source node, a sink node and four ways of relaying a ``sensor_msgs/msg/JointState``
of 56 values (every endpoint reliable, volatile, keep-last 1000):

* ``monitor, waiter``: what the monitor does (``imrosc/onboard/monitor_ros2/plumbing.py``):
  a raw subscription in a callback group no executor runs, waited on by ``plumbing.Waiter``
  and taken with the subscription's ``take_message``, the bytes published on the relay;
* ``monitor, executor``: the same raw subscription and relay taken by a
  ``SingleThreadedExecutor`` through the subscription's callback, as the monitor did before,
  on a node with the monitor's other endpoints (``/m/broken_inv``, ``/m/heartbeat``,
  ``/m/clear_inv``, its poll timer);
* ``plain relay`` and ``raw relay``: bench/latency_ros2.py's bare relays, a node with one
  subscription (decoded, or raw) and one publisher, spun by a ``SingleThreadedExecutor``.

The source publishes one message, then the path takes and relays it; the CPU time of the
taking thread (``time.thread_time``) from the publish to the relay is counted. The paths
take turns every 50 messages, ``--blocks`` turns each. No checks run: this is what the
plumbing costs around them (``bench/check.py`` measures the checks).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.latency_ros2 import ros2_python  # noqa: E402
from tests.backends.ros2_support import ros2_environment  # noqa: E402

PATHS = ("monitor, waiter", "monitor, executor", "plain relay", "raw relay")
MEASURE = r"""
import json, sys, time
import rclpy
from builtin_interfaces.msg import Time
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from imrosc.onboard.monitor_ros2 import plumbing

BLOCK = 50
QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
rclpy.init()
source, sink, monitor = Node("source"), Node("sink"), Node("monitor")
checks = MutuallyExclusiveCallbackGroup()
monitor.create_publisher(String, "/m/broken_inv", 100)
monitor.create_publisher(Time, "/m/heartbeat", 1)
monitor.create_subscription(String, "/m/clear_inv", lambda m: None, 100, callback_group=checks)
monitor.create_timer(1.0, lambda: None, callback_group=checks)


def relay_to(node, name):
    sink.create_subscription(JointState, "/out/" + name, lambda m: None, QOS)
    return node.create_publisher(JointState, "/out/" + name, QOS)


def spun(node, name, raw, group=None):
    # a path taken by an executor: its publisher and one turn (publish, spin until relayed)
    relay, relayed = relay_to(node, name), [0]

    def on_message(message):
        relay.publish(message)
        relayed[0] += 1

    node.create_subscription(
        JointState, "/in/" + name, on_message, QOS, callback_group=group, raw=raw
    )
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    def turn():
        before = relayed[0]
        while relayed[0] == before:
            executor.spin_once(timeout_sec=1.0)

    return source.create_publisher(JointState, "/in/" + name, QOS), turn


def waited(name):
    # the monitor's way: its own wait set, take, relay the bytes
    relay = relay_to(monitor, name)
    subscription = monitor.create_subscription(
        JointState, "/in/" + name, lambda m: None, QOS,
        callback_group=plumbing.NotByTheExecutor(), raw=True,
    )
    take = plumbing.taker(subscription)
    waiter = plumbing.Waiter(monitor.context)
    waiter.put(name, subscription)

    def turn():
        done = False
        while not done:
            for _ in waiter.wait(1.0):
                message = take()
                while message is not None:
                    relay.publish(message)
                    done = True
                    message = take()

    return source.create_publisher(JointState, "/in/" + name, QOS), turn


paths = {
    "monitor, waiter": waited("waiter"),
    "monitor, executor": spun(monitor, "executor", True, checks),
    "plain relay": spun(Node("plain_relay"), "plain", False),
    "raw relay": spun(Node("raw_relay"), "raw", True),
}
message = JointState()
message.position = [float(i) for i in range(56)]
time.sleep(2.0)  # discovery and matching
for publisher, turn in paths.values():  # every path warm once
    publisher.publish(message)
    turn()
cpu = dict.fromkeys(paths, 0.0)
for _ in range(int(sys.argv[1])):
    for name, (publisher, turn) in paths.items():
        for _ in range(BLOCK):
            publisher.publish(message)
            started = time.thread_time()
            turn()
            cpu[name] += time.thread_time() - started
print(json.dumps({name: spent / (int(sys.argv[1]) * BLOCK) for name, spent in cpu.items()}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=40, help="turns of 50 messages per path")
    parser.add_argument("--runs", type=int, default=3, help="processes, one after the other")
    args = parser.parse_args()
    python = ros2_python()
    if python is None:
        sys.exit("no ROS 2 here: set IMROSC_ROS2_PYTHON to a python with rclpy")
    load = os.getloadavg()[0]
    runs: list[dict[str, float]] = []
    with tempfile.TemporaryDirectory(prefix="imrosc-take-cost-") as tmp:
        for _ in range(args.runs):
            environment = ros2_environment(Path(tmp), PYTHONPATH=str(ROOT))
            done = subprocess.run(
                [python, "-c", MEASURE, str(args.blocks)],
                env=environment,
                capture_output=True,
                text=True,
                check=False,
                timeout=600,
            )
            if done.returncode != 0:
                sys.exit(f"the measuring process failed:\n{done.stdout}{done.stderr}")
            runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    print(
        f"ROS 2 Jazzy (rclpy, rmw_fastrtps), sensor_msgs/msg/JointState of 56 float64; "
        f"{args.runs} runs x {args.blocks} turns of 50 messages per path; CPU time of the "
        f"taking thread per message, publish to relay; load average {load:.1f} before, "
        f"{os.getloadavg()[0]:.1f} after"
    )
    print(f"{'path':<18} {'us per message, each run':>26}  {'/ plain relay':>13}")
    for path in PATHS:
        figures = ", ".join(f"{run[path] * 1e6:.0f}" for run in runs)
        ratios = ", ".join(f"{run[path] / run['plain relay']:.2f}" for run in runs)
        print(f"{path:<18} {figures:>26}  {ratios:>13}")


if __name__ == "__main__":
    main()
