"""Fixtures of the live tests: a real roscore per test module (see ``harness.py``).

Every live test is marked ``@pytest.mark.live``. Without Debian's ROS 1 (``/usr/bin/roscore``,
rospy under ``/usr/bin/python3``) they are skipped with the reason; under CI (``CI`` set, as
``.ci/run`` is run) they fail instead, since ``make test`` installs ROS 1 there.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from tests.live.harness import Ros, ros_missing

collect_ignore_glob = ["nodes/*"]  # rospy scripts, run under /usr/bin/python3 only


def require_ros() -> None:
    """Skip (fail under CI) when ROS 1 is not installed."""
    reason = ros_missing()
    if reason is None:
        return
    if os.environ.get("CI", "").lower() not in ("", "0", "false"):
        pytest.fail(f"live ROS 1 tests cannot run under CI: {reason}", pytrace=False)
    pytest.skip(f"no ROS 1 here: {reason}")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("live") is not None:
        require_ros()


@pytest.fixture(scope="module")
def ros(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros]:
    """A roscore on a free port for the module; everything started on it dies with it."""
    require_ros()
    graph = Ros(tmp_path_factory.mktemp("ros"))
    try:
        graph.start()
        yield graph
    finally:
        strays = graph.shutdown()
    assert not strays, f"processes outlived their shutdown and were killed: {strays}"
