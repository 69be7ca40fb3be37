"""rclpy helpers shared by the ROS 2 monitor node and its fail-open watchdog.

Interface classes by name (:func:`message_class`, :func:`service_class`), QoS profiles from
:class:`logic.Qos` (:func:`profile`), one reading of the graph API (:func:`read_graph`),
node parameters with defaults that work from Foxy on (:func:`get_param`), other nodes'
parameters (:class:`ParameterAsker`, also the recorder's), a service call that waits with a
timeout (:func:`call`) and a callback that logs instead of killing the executor
(:func:`guarded`, used by the recorder: the monitor stops instead, see ``node.py``). Python
3.8 syntax.
"""

from __future__ import annotations

import contextlib
import importlib
import threading
from typing import Any, Callable, Dict, List, Optional, Sequence, Set, Tuple

from ..fill import FillError
from . import logic

try:  # only a ROS 2 system has these; the functions below need them
    from rcl_interfaces.srv import (  # type: ignore[import-not-found, unused-ignore]
        GetParameters,
    )
    from rclpy.qos import (  # type: ignore[import-not-found, unused-ignore]
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
    )
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    QoSProfile = None
try:  # Humble and later: spin() ends with it when SIGINT shut the context down
    from rclpy.executors import (  # type: ignore[import-not-found, unused-ignore]
        ExternalShutdownException,
    )
except ImportError:  # Foxy, Galactic (and no ROS 2 at all)
    ExternalShutdownException = KeyboardInterrupt
SPIN_ENDED = (KeyboardInterrupt, ExternalShutdownException)
"""What ends an executor's ``spin()`` on Ctrl-C or SIGINT, in every ROS 2 release."""
try:  # Humble and later: the wait set of rclpy's executors, for :class:`Waiter`
    from rclpy.callback_groups import (  # type: ignore[import-not-found, unused-ignore]
        CallbackGroup,
    )
    from rclpy.guard_condition import (  # type: ignore[import-not-found, unused-ignore]
        GuardCondition,
    )
    from rclpy.impl.implementation_singleton import (  # type: ignore[import-not-found, unused-ignore]
        rclpy_implementation as _rclpy,
    )

    WAIT_SET: Any = getattr(_rclpy, "WaitSet", None)
    if not hasattr(getattr(_rclpy, "Subscription", None), "take_message"):
        WAIT_SET = None  # nothing to take a message with outside the executor
except ImportError:  # no ROS 2, or a release without them: the executor takes every message
    CallbackGroup = object
    WAIT_SET = None


def spin_until_stopped(
    executor: Any, node: Any, before_destroy: Optional[Callable[[], None]] = None
) -> None:
    """Spin ``executor`` until Ctrl-C (either way it ends the spin), then shut it down,
    call ``before_destroy`` (threads that use the node's endpoints end there), and shut
    ``node`` and rclpy down."""
    import rclpy  # type: ignore[import-not-found, unused-ignore]

    try:
        executor.spin()
    except SPIN_ENDED:
        pass
    finally:
        executor.shutdown()
        if before_destroy is not None:
            before_destroy()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


QUEUE = 100
"""Depth of the monitor's other subscriptions and publishers (KEEP_LAST), as ROS 1's
queue_size; and the most messages a topic's callback takes at once (node.py)."""
TOPIC_DEPTH = 1000
"""Depth of the subscriptions to watched and blocked topics and of their relays (KEEP_LAST):
a second's worth at 1 kHz. A full KEEP_LAST history drops its oldest message for the next
one, so a monitor whose executor thread the machine did not run for longer than the depth
lasts would lose messages of the topic, and its relay would lose them for the subscribers
(the executor held 0.3 s in a 1 kHz burst of 300: 143 lost at depth 100, none at 1000)."""


def interface_class(name: str, kind: str) -> Any:
    """The class of a ``msg`` or ``srv`` type by name; ``None`` if it cannot be imported."""
    try:
        module, attribute = logic.interface_name(name, kind)
        return getattr(importlib.import_module(module), attribute)
    except (ImportError, AttributeError, ValueError):
        return None


def message_class(name: str) -> Any:
    """A message class (``pkg/msg/Name`` or ``pkg/Name``), or ``None``."""
    return interface_class(name, "msg")


def service_class(name: str) -> Any:
    """A service class (``pkg/srv/Name`` or ``pkg/Name``), or ``None``."""
    return interface_class(name, "srv")


def fill_class(name: str) -> Any:
    """A message class for :func:`logic.fill`: ``FillError`` if it is unknown."""
    found = message_class(name)
    if found is None:
        raise FillError(f"unknown message type {name}")
    return found


def profile(qos: logic.Qos, depth: int = QUEUE) -> Any:
    """An rclpy ``QoSProfile`` (KEEP_LAST ``depth``) with the reliability and durability of
    ``qos``."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=(
            ReliabilityPolicy.BEST_EFFORT
            if qos.reliability == logic.BEST_EFFORT
            else ReliabilityPolicy.RELIABLE
        ),
        durability=(
            DurabilityPolicy.TRANSIENT_LOCAL
            if qos.durability == logic.TRANSIENT_LOCAL
            else DurabilityPolicy.VOLATILE
        ),
    )


def taker(subscription: Any) -> Optional[Callable[[], Any]]:
    """A function that takes the next message waiting on ``subscription`` (bytes for a raw
    one) outside the executor, ``None`` when none is waiting (or the subscription is gone);
    ``None`` itself where rclpy has no ``take_message`` on the handle (before Humble)."""
    handle: Any = getattr(subscription, "handle", None)
    take = getattr(handle, "take_message", None)
    if take is None:
        return None
    kind, raw = subscription.msg_type, subscription.raw

    def next_message() -> Any:
        try:
            with handle:
                taken = take(kind, raw)
        except Exception:  # destroyed, or the context shut down: nothing to take
            return None
        return None if taken is None else taken[0]

    return next_message


class NotByTheExecutor(CallbackGroup):  # type: ignore[misc, valid-type, unused-ignore]
    """A callback group no executor runs, nor waits on (``can_execute`` is false): the
    subscriptions in it are waited on and taken by a :class:`Waiter`."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        return None


class Waiter:
    """Waits for messages on a set of subscriptions (made in a :class:`NotByTheExecutor`
    group) outside the executor, in the thread that calls :meth:`wait`. rclpy's executor
    rebuilds its wait set from every entity of the node in Python each time it wakes, and
    makes a task of each callback: at 1 kHz that cost more than the monitor's checks
    (``bench/monitor_latency.py``). A wait here is one wait set of the subscriptions and a
    guard condition that :meth:`put`, :meth:`remove` and :meth:`close` trigger."""

    def __init__(self, context: Any) -> None:
        self.context = context
        self.wake = GuardCondition(None, None, context=context)
        self.lock = threading.Lock()
        self.subscriptions: Dict[str, Any] = {}
        self.closed = False

    @staticmethod
    def available() -> bool:
        """Whether this rclpy has the wait set and the take of a subscription (Humble on)."""
        return WAIT_SET is not None

    def put(self, key: str, subscription: Any) -> None:
        """Wait on ``subscription`` under ``key`` (in place of the one there)."""
        with self.lock:
            self.subscriptions[key] = subscription
        self.wake.trigger()

    def close(self) -> None:
        """End :meth:`wait`: it returns nothing from now on."""
        self.closed = True
        with contextlib.suppress(Exception):
            self.wake.trigger()

    def wait(self, timeout: float) -> List[str]:
        """The keys of the subscriptions with a message waiting, once one has one or after
        ``timeout`` seconds (none then); none once closed or once the context shut down."""
        with self.lock:
            waited = list(self.subscriptions.items())
        if self.closed:
            return []
        with contextlib.ExitStack() as held:  # none is destroyed while it is waited on
            handles = []
            for key, subscription in waited:
                try:
                    held.enter_context(subscription.handle)
                except Exception:  # destroyed meanwhile: the next wait has its successor
                    continue
                handles.append((key, subscription.handle))
            try:
                held.enter_context(self.wake.handle)
                held.enter_context(self.context.handle)
                wait_set = WAIT_SET(len(handles), 1, 0, 0, 0, 0, self.context.handle)
            except Exception:  # the context shut down
                return []
            wait_set.clear_entities()
            for _, handle in handles:
                wait_set.add_subscription(handle)
            wait_set.add_guard_condition(self.wake.handle)
            try:
                wait_set.wait(int(timeout * 1e9))
            except Exception:  # the context shut down while waiting
                return []
            if self.closed or not self.context.ok():
                return []
            ready = wait_set.get_ready_entities("subscription")
            return [key for key, handle in handles if handle.pointer in ready]


def get_param(node: Any, name: str, default: Any) -> Any:
    """A parameter of ``node`` (created with ``allow_undeclared_parameters`` and
    ``automatically_declare_parameters_from_overrides``, so any type given on the command
    line or in a launch file is accepted); ``default`` when it is not set."""
    try:
        value = node.get_parameter(name).value
    except Exception:
        return default
    return default if value is None else value


def read_graph(node: Any) -> logic.GraphView:
    """Publishers, subscribers (with the publishers' QoS) and servers, from rclpy's graph
    API. A node or topic that vanishes while it is read is skipped; an endpoint whose node
    is not discovered yet is left out and marks the view incomplete."""
    topics: Dict[str, Tuple[List[str], List[str]]] = {}
    types: Dict[str, List[str]] = {}
    qos: Dict[str, List[Tuple[str, Optional[logic.Qos]]]] = {}
    complete = True
    for name, kinds in node.get_topic_names_and_types():
        try:
            publishers = node.get_publishers_info_by_topic(name)
            subscribers = node.get_subscriptions_info_by_topic(name)
        except Exception:
            continue
        pubs: List[str] = []
        subs: List[str] = []
        offered: List[Tuple[str, Optional[logic.Qos]]] = []
        for info in publishers:
            full = logic.endpoint_node(info.node_namespace, info.node_name)
            complete = complete and full is not None
            pubs += [full] if full is not None else []
            offered.append((full or "", logic.endpoint_qos(info.qos_profile)))  # QoS counts
        for info in subscribers:
            full = logic.endpoint_node(info.node_namespace, info.node_name)
            complete = complete and full is not None
            subs += [full] if full is not None else []
        topics[name] = (pubs, subs)
        types[name] = list(kinds)
        qos[name] = offered
    services: Dict[str, List[str]] = {}
    service_types: Dict[str, List[str]] = {}
    nodes: Set[str] = set()
    for name, namespace in node.get_node_names_and_namespaces():
        full = logic.node_name(namespace, name)
        nodes.add(full)
        try:
            served = node.get_service_names_and_types_by_node(name, namespace)
        except Exception:
            continue
        for service, kinds in served:
            services.setdefault(service, []).append(full)
            service_types.setdefault(service, list(kinds))
    return logic.GraphView(topics, types, qos, services, service_types, sorted(nodes), complete)


class CallTimeoutError(Exception):
    """A service did not answer in time."""


def call(client: Any, request: Any, timeout: float) -> Any:
    """Call a service and wait for its response (at most ``timeout`` seconds). The response
    arrives in an executor thread: the caller must not hold the only one (a node that relays
    services spins a ``MultiThreadedExecutor`` and puts clients in a reentrant callback group;
    actions call from their own thread)."""
    future = client.call_async(request)
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    if not done.wait(timeout):
        remove = getattr(client, "remove_pending_request", None)
        if remove is not None:
            remove(future)
        raise CallTimeoutError(f"no response within {timeout} s")
    return future.result()


def guarded(logger: Any, what: str, callback: Callable[..., Any]) -> Callable[..., Any]:
    """``callback`` that logs an exception instead of raising it out of the executor's spin
    (which would end the node)."""

    def run(*args: Any) -> Any:
        try:
            return callback(*args)
        except Exception as error:
            logger.error(f"imrosc: {what} failed: {type(error).__name__}: {error}")
            return None

    return run


class ParameterAsker:
    """Asks nodes for their parameters with ``GetParameters`` on ``/<node>/get_parameters``,
    one call per parameter: rclpy answers a call that names one undeclared parameter with no
    values at all, which would hide the others. Answers arrive in an executor thread;
    ``answers`` (record name -> value, a parameter not set left out) and ``pending`` are
    read and written under ``lock``; ``warn`` takes a line without the node's prefix."""

    def __init__(self, node: Any, group: Any, lock: Any, warn: Callable[[str], Any]) -> None:
        self.node = node
        self.group = group
        self.lock = lock
        self.warn = warn
        self.clients: Dict[str, Any] = {}
        self.pending: Set[str] = set()
        self.answers: Dict[str, Any] = {}
        self.answered = False
        """Whether an answer has come back."""

    def ask(self, owner: str, asked: Sequence[Tuple[str, str]]) -> None:
        """Ask node ``owner`` for its ``(record name, ROS 2 name)`` parameters that are not
        asked already (nothing while its service is not ready)."""
        client = self.clients.get(owner)
        if client is None:
            name = owner.rstrip("/") + "/get_parameters"
            client = self.node.create_client(GetParameters, name, callback_group=self.group)
            self.clients[owner] = client
        if not client.service_is_ready():
            return
        for record, name in asked:
            with self.lock:
                if record in self.pending:
                    continue
                self.pending.add(record)
            future = client.call_async(GetParameters.Request(names=[name]))
            future.add_done_callback(self._on_answer(owner, (record, name)))

    def forget(self, asked: Sequence[Tuple[str, str]]) -> None:
        """Drop the answers for ``asked`` (their node is gone)."""
        with self.lock:
            for record, _ in asked:
                self.answers.pop(record, None)

    def _on_answer(self, owner: str, asked: Tuple[str, str]) -> Callable[[Any], None]:
        def on_answer(future: Any) -> None:
            try:
                response = future.result()
                answered, missing = logic.parameter_answers([asked], list(response.values))
            except Exception as error:
                self.warn(f"parameter {asked[0]} of {owner}: {error}")
                answered, missing = {}, []
            with self.lock:
                self.answers.update(answered)
                for name in missing:
                    self.answers.pop(name, None)
                self.pending.discard(asked[0])
                self.answered = True

        return on_answer
