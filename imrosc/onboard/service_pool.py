"""Persistent, pooled connections to one ROS 1 service, for the two nodes that forward
calls to a remapped server: the recorder's relay (``record_ros1``) and the monitor's
(``monitor_ros1``).

A call forwarded over a new ``rospy.ServiceProxy`` first asks the master where the service
is and opens a TCP connection; over a pooled persistent one it costs one local hop. Both
nodes forward the same way, so the response delay the monitor checks is measured as the
recorder measured the delay it learnt from. Python 3.8 syntax; rospy is passed in (this
module imports no middleware).
"""

from __future__ import annotations

import threading
import time
from typing import Any, List, Optional, Tuple

TRANSPORT_ERROR = "transport error"
"""How rospy's ``ServiceException`` starts when a persistent connection's server is gone."""


class ServicePool:
    """Calls ``target`` over persistent connections, one per concurrent call, each kept for
    the next call. A pooled connection whose server has restarted fails with a transport
    error: the call is then tried once more on a fresh connection."""

    def __init__(self, rospy: Any, target: str, cls: Any) -> None:
        self.rospy = rospy
        self.target = target
        self.cls = cls
        self.pool: List[Any] = []
        self.lock = threading.Lock()
        self.busy = 0
        self.idle = threading.Condition(self.lock)

    def _take(self) -> Tuple[Any, bool]:
        with self.lock:
            self.busy += 1
            if self.pool:
                return self.pool.pop(), True
        return self.rospy.ServiceProxy(self.target, self.cls, persistent=True), False

    def _give(self, proxy: Optional[Any]) -> None:
        with self.lock:
            if proxy is not None:
                self.pool.append(proxy)
            self.busy -= 1
            self.idle.notify_all()

    def call(self, request: Any) -> Any:
        """The server's response to ``request`` (raises what the call raised)."""
        proxy, reused = self._take()
        try:
            try:
                response = proxy.call(request)
            except self.rospy.ServiceException as error:
                proxy.close()
                if not (reused and str(error).startswith(TRANSPORT_ERROR)):
                    raise
                proxy = self.rospy.ServiceProxy(self.target, self.cls, persistent=True)
                response = proxy.call(request)
        except BaseException:
            proxy.close()
            self._give(None)
            raise
        self._give(proxy)
        return response

    def drain(self, timeout: float) -> None:
        """Wait until no call is in flight (at most ``timeout`` seconds), then close the
        pooled connections."""
        deadline = time.monotonic() + timeout
        with self.lock:
            while self.busy and time.monotonic() < deadline:
                self.idle.wait(max(0.0, deadline - time.monotonic()))
            pool, self.pool = self.pool, []
        for proxy in pool:
            proxy.close()
