"""The ROS 1 master, as ``imrosc record`` sees it: over XML-RPC, without rospy.

imrosc runs under its own Python, where rospy is usually not importable; the master API is
plain XML-RPC (``http://wiki.ros.org/ROS/Master_API``), so the standard library is enough to
check that a master is there and to read the node graph before recording.
"""

from __future__ import annotations

import http.client
import os
import xmlrpc.client
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from imrosc.graph.model import Graph, Node

__all__ = ["DEFAULT_MASTER_URI", "MasterError", "SystemState", "master_uri", "system_state"]

DEFAULT_MASTER_URI = "http://localhost:11311"
CALLER_ID = "/imrosc_record"
SOURCE_MASTER = "master"


class MasterError(Exception):
    """No master answers at the URI, or it refused a call; the message is one line."""


@dataclass(frozen=True)
class SystemState:
    """``getSystemState``: who publishes, subscribes to and serves what."""

    publishers: Mapping[str, frozenset[str]]
    subscribers: Mapping[str, frozenset[str]]
    services: Mapping[str, frozenset[str]]

    @staticmethod
    def parse(value: Any) -> SystemState:
        """From the master's ``[publishers, subscribers, services]`` lists.

        >>> state = SystemState.parse([[["/t", ["/a"]]], [["/t", ["/b"]]], [["/s", ["/a"]]]])
        >>> sorted(state.publishers["/t"]), sorted(state.services["/s"])
        (['/a'], ['/a'])
        """
        pubs, subs, srvs = value
        return SystemState(
            {str(t): frozenset(map(str, n)) for t, n in pubs},
            {str(t): frozenset(map(str, n)) for t, n in subs},
            {str(s): frozenset(map(str, n)) for s, n in srvs},
        )

    def graph(self, hidden: Iterable[str] = ()) -> Graph:
        """The node graph (it knows subscriptions), without the ``hidden`` nodes.

        >>> state = SystemState.parse([[["/t", ["/a"]]], [["/t", ["/b", "/x"]]], []])
        >>> graph = state.graph(hidden={"/x"})
        >>> list(graph.nodes), graph.subscribers("/t")
        (['/a', '/b'], ('/b',))
        """
        skip = set(hidden)
        nodes: list[Node] = []
        for topic, names in self.publishers.items():
            nodes += [Node(n, publishes=frozenset({topic})) for n in names if n not in skip]
        for topic, names in self.subscribers.items():
            nodes += [Node(n, subscribes=frozenset({topic})) for n in names if n not in skip]
        for service, names in self.services.items():
            nodes += [Node(n, serves=frozenset({service})) for n in names if n not in skip]
        return Graph.build(nodes, (SOURCE_MASTER,), knows_subscriptions=True)

    def servers(self) -> dict[str, set[str]]:
        """Service name to the nodes that serve it."""
        return {name: set(nodes) for name, nodes in self.services.items()}


class _Transport(xmlrpc.client.Transport):
    """XML-RPC over HTTP with a timeout."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def master_uri(environment: Mapping[str, str] | None = None) -> str:
    """``ROS_MASTER_URI`` of the environment, or ROS's default."""
    env = os.environ if environment is None else environment
    return env.get("ROS_MASTER_URI") or DEFAULT_MASTER_URI


def call(uri: str, method: str, *args: Any, timeout: float = 3.0) -> Any:
    """Call the master API; raises :class:`MasterError` with a one-line reason."""
    if not uri.startswith(("http://", "https://")):
        raise MasterError(f"ROS_MASTER_URI {uri!r} is not an http:// URI")
    proxy = xmlrpc.client.ServerProxy(uri, transport=_Transport(timeout))
    try:
        code, message, value = getattr(proxy, method)(CALLER_ID, *args)
    except (OSError, http.client.HTTPException, xmlrpc.client.Error, ValueError) as error:
        reason = getattr(error, "strerror", None) or str(error) or type(error).__name__
        raise MasterError(
            f"no ROS master at {uri} ({reason}): start roscore, or set ROS_MASTER_URI"
        ) from None
    if code != 1:
        raise MasterError(f"the ROS master at {uri} refused {method}: {message}")
    return value


def system_state(uri: str) -> SystemState:
    """The master's graph now."""
    try:
        return SystemState.parse(call(uri, "getSystemState"))
    except (TypeError, ValueError) as error:
        raise MasterError(f"the ROS master at {uri} sent an odd system state: {error}") from None
