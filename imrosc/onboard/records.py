"""The record format's encoder (``docs/record-format.md``): the one every recorder writes with.

A record is a ``std_msgs/String`` message on one of :data:`RECORD_TOPICS` whose ``data`` is
one JSON object with ``"version": 1``: the node graph (:func:`arch_text`), the parameters
(:func:`params_text`) or one service call (:func:`call_text`). The text is canonical (keys
and name lists sorted, no spaces), so one snapshot is one string and a recorder publishes a
snapshot only when its text changed. The ROS 1 recorder (``imrosc/onboard/record_ros1``), the ROS 2
recorder (``imrosc/onboard/record_ros2``) and :func:`imrosc.records.encode` all write through this
module; :mod:`imrosc.records` reads the records back.

The three records' JSON objects are typed below (:class:`ArchRecord`, :class:`ParamsRecord`,
:class:`CallRecord`; their JSON schema is ``imrosc/backends/schemas/records.schema.json``).
Python 3.8 syntax, standard library only: the ROS 2 backend copies it into generated
packages and the ROS 1 recorder imports it under the robot's Python.

>>> arch_text({"/t": ({"/b", "/a"}, [])}, {"/s": ["/c"]})
'{"services":{"/s":["/c"]},"topics":{"/t":{"pubs":["/a","/b"],"subs":[]}},"version":1}'
"""

from __future__ import annotations

import json
import re
from typing import Any, Dict, Iterable, List, Mapping, Optional, Tuple, TypedDict

VERSION = 1
RECORD_PREFIX = "/imrosc/"
"""Every record topic lives under this namespace."""
ARCH_TOPIC = "/imrosc/arch"
PARAMS_TOPIC = "/imrosc/params"
SRVS_TOPIC = "/imrosc/srvs"
RECORD_TOPICS = (ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC)
RECORD_TYPE = "std_msgs/msg/String"
"""The message type of every record (rosbags' name for ROS 1 ``std_msgs/String`` too)."""
_GLOBAL_NAME = re.compile(r"^(/[A-Za-z0-9_]+)+$")


class TopicEndsEntry(TypedDict):
    """A topic's publishers and subscribers in an architecture snapshot."""

    pubs: List[str]
    subs: List[str]


class ArchRecord(TypedDict):
    """``/imrosc/arch``: the node graph."""

    version: int
    topics: Dict[str, TopicEndsEntry]
    services: Dict[str, List[str]]


class ParamsRecord(TypedDict):
    """``/imrosc/params``: every parameter's value."""

    version: int
    params: Dict[str, Any]


class CallRecord(TypedDict):
    """``/imrosc/srvs``: one service call (``response`` None and ``ok`` false: no answer)."""

    version: int
    service: str
    client: str
    server: str
    request: Dict[str, Any]
    response: Optional[Dict[str, Any]]
    ok: bool
    stamp: float
    delay: float


def dumps(document: Any) -> str:
    """Canonical JSON: keys sorted, no spaces, ASCII only (NaN and infinities as Python has them).

    >>> dumps({"b": 1, "a": [float("nan")]})
    '{"a":[NaN],"b":1}'
    """
    return json.dumps(document, sort_keys=True, separators=(",", ":"))


def is_global_name(name: Any) -> bool:
    """Whether ``name`` is a valid global ROS name (what the record readers accept).

    >>> [is_global_name(n) for n in ("/a/b_1", "/1a", "/", "/a//b", "/a/", "a", "/a-b")]
    [True, True, False, False, False, False, False]
    """
    return isinstance(name, str) and _GLOBAL_NAME.match(name) is not None


def arch_text(
    topics: Mapping[str, Tuple[Iterable[str], Iterable[str]]],
    services: Mapping[str, Iterable[str]],
) -> str:
    """An architecture snapshot: topic -> (publishers, subscribers), service -> servers."""
    record: ArchRecord = {
        "version": VERSION,
        "topics": {
            name: {"pubs": sorted(set(pubs)), "subs": sorted(set(subs))}
            for name, (pubs, subs) in topics.items()
        },
        "services": {name: sorted(set(servers)) for name, servers in services.items()},
    }
    return dumps(record)


def params_text(params: Mapping[str, Any]) -> str:
    """A parameter snapshot: global name -> JSON value.

    >>> params_text({"/b": "x", "/a": 1.5})
    '{"params":{"/a":1.5,"/b":"x"},"version":1}'
    """
    record: ParamsRecord = {"version": VERSION, "params": dict(params)}
    return dumps(record)


def call_text(
    service: str,
    client: str,
    server: str,
    request: Mapping[str, Any],
    response: Optional[Mapping[str, Any]],
    stamp: float,
    delay: float,
) -> str:
    """A service-call record: ``stamp`` the time of the request, ``delay`` the seconds to
    the response (never negative); ``response`` None means the call failed (no answer),
    and ``ok`` says so.

    >>> call_text("/s", "/c", "/n", {"a": 1}, None, 2.5, 0.25)
    '{"client":"/c","delay":0.25,"ok":false,"request":{"a":1},"response":null,\
"server":"/n","service":"/s","stamp":2.5,"version":1}'
    """
    record: CallRecord = {
        "version": VERSION,
        "service": service,
        "client": client,
        "server": server,
        "request": dict(request),
        "response": None if response is None else dict(response),
        "ok": response is not None,
        "stamp": float(stamp),
        "delay": max(0.0, float(delay)),
    }
    return dumps(record)
