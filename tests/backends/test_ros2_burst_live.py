"""No message lost on the generated ROS 2 monitor's relay (issue 20): bursts through the
monitor arrive complete and in order, as they do through a bare rclpy relay beside it.

A sensor topic (``sensor_msgs/msg/Imu``) with a reliable, volatile, keep-last-100 publisher:
the bench's QoS and a bare relay's. The monitor starts on such a topic with the sensor-data
profile (best effort) and must take its publisher's QoS for its subscription and its relay,
or the reliable subscriber of ``/m/a/imu`` never hears it. Each burst is 100 messages
published back to back, one history's worth: a relay with the publisher's QoS delivers every
one however slow it is, so a loss is the relay's fault, never the machine's load. The driver
waits until both paths deliver (an uncounted pre-roll) before it counts: a volatile writer
drops what it publishes before its readers match, and that start is not what is tested.

Runs where ``tests/backends/ros2_support.py`` finds rclpy (``make test`` and so CI: marked
``live``, required under ``IMROSC_REQUIRE_ROS2=1``).
"""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

import pytest

from tests.backends.monitor_support import config_text, write_case, write_package
from tests.backends.ros2_build import build_ros2, ros2_document
from tests.backends.ros2_live_support import drive, invariant, start_monitor
from tests.backends.ros2_support import Reader, require_ros2, ros2_environment

pytestmark = pytest.mark.live

BURSTS, DEPTH = 5, 100
SCOPE = '<publish id="a">/a/imu</publish>'
MONITOR = """<monitor inv="demo.inv" period="0.2">
    <block>/a/imu</block>
  </monitor>"""

COMMON = r"""
import json, os, sys, threading, time
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
rclpy.init()
"""

RELAY = (
    COMMON
    + r"""
node = Node("bare_relay", namespace="/a")
publisher = node.create_publisher(Imu, "/relay/a/imu", QOS)
node.create_subscription(Imu, "/a/imu", publisher.publish, QOS)
print("relay up", flush=True)
try:
    rclpy.spin(node)
except BaseException:
    pass
"""
)

DRIVER = (
    COMMON
    + r"""
from rclpy.executors import SingleThreadedExecutor

node = Node("driver", namespace="/a")
executor = SingleThreadedExecutor()
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
paths = {"monitor": "/m/a/imu", "relay": "/relay/a/imu"}
got = {path: [] for path in paths}
heard = {path: False for path in paths}
lock = threading.Lock()

def receiver(path):
    def on_message(message):
        with lock:
            if message.header.frame_id == "pre":
                heard[path] = True
            else:
                got[path].append(int(message.header.frame_id))
    return on_message

for path, topic in paths.items():
    node.create_subscription(Imu, topic, receiver(path), QOS)
publisher = node.create_publisher(Imu, "/a/imu", QOS)

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.01)
    return False

def message(frame):
    m = Imu()
    m.header.frame_id = frame
    m.orientation.w = 1.0
    return m

out = {"ready": wait(lambda: publisher.get_subscription_count() >= 2, 60)}
# the pre-roll: until both paths deliver (the monitor takes its publisher's QoS at a poll)
out["heard"] = wait(lambda: publisher.publish(message("pre")) or all(heard.values()), 60)
time.sleep(0.5)  # the last pre-roll messages through both paths
qos = {}
for path, topic in paths.items():
    infos = node.get_publishers_info_by_topic(topic)
    qos[path] = [[int(i.qos_profile.reliability), int(i.qos_profile.durability)] for i in infos]
out["qos"] = qos
out["monitor_subscribes"] = [
    [int(i.qos_profile.reliability), int(i.qos_profile.durability)]
    for i in node.get_subscriptions_info_by_topic("/a/imu")
    if i.node_name == "demo_monitor"
]
k = 0
for burst in range(BURSTS):
    for _ in range(DEPTH):  # back to back: one history's worth
        publisher.publish(message(str(k)))
        k += 1
    wait(lambda: all(len(got[path]) >= k for path in paths), 30.0)
out["sent"] = k
with lock:
    out["got"] = {path: list(values) for path, values in got.items()}
print(json.dumps(out), flush=True)
os._exit(0)
"""
)


def test_bursts_through_the_monitor_arrive_complete_and_in_order_as_through_a_bare_relay(
    tmp_path: Path,
) -> None:
    ros2_python = require_ros2()
    document = ros2_document({"/a/imu": "sensor_msgs/msg/Imu"})
    document["invariants"] = [
        invariant("w", "a", "bounds", "range", variables=["imu.orientation.w"], min=0.0, max=2.0)
    ]
    config = write_case(tmp_path, config_text(scope=SCOPE, monitor=MONITOR), document)
    result = build_ros2(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    package = write_package(result.files, tmp_path / "out")
    environment = ros2_environment(tmp_path, PYTHONPATH=str(package))
    monitor = start_monitor(ros2_python, package, environment)
    relay = Reader(
        [ros2_python, "-c", RELAY.replace("DEPTH", str(DEPTH))], environment, cwd=tmp_path
    )
    try:
        relay.wait_for("relay up", 60)
        script = DRIVER.replace("BURSTS", str(BURSTS)).replace("DEPTH", str(DEPTH))
        driver = drive(ros2_python, script, environment, 240)
    finally:
        relay.stop(signal.SIGINT)
        monitor.send_signal(signal.SIGINT)
        try:
            log, _ = monitor.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            monitor.kill()
            log, _ = monitor.communicate()
    assert driver.returncode == 0, driver.stdout + driver.stderr + log
    out = json.loads(driver.stdout.strip().splitlines()[-1])
    context = json.dumps(out)[:3000] + "\n" + log
    assert out["ready"] and out["heard"], context
    reliable_volatile = [[1, 2]]  # rmw_qos_reliability_policy_e, rmw_qos_durability_policy_e
    assert out["qos"] == {"monitor": reliable_volatile, "relay": reliable_volatile}, context
    assert out["monitor_subscribes"] == reliable_volatile, context
    expected = list(range(BURSTS * DEPTH))
    assert out["sent"] == len(expected), context
    assert out["got"]["relay"] == expected, context  # the bare relay: the yardstick
    assert out["got"]["monitor"] == expected, context  # complete and in order
