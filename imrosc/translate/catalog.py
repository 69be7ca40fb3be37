"""The pre-pass over a set of bags: message types and the layout of the record topics.

Before any message is translated, every bag is opened once to learn each topic's message
type (the first bag that has a topic decides its type; a later bag with another type is
reported), the ROS 1 ``callerid`` publishers, and, from the small record topics written by
``imrosc record``, which parameters, service fields and architecture resources exist. Every
run of a program point then has the same variables, so states merge.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from imrosc import records
from imrosc.bags import BagError, MessageError, discover_bags, open_bag, recovered_diagnostic
from imrosc.diagnostics import Diagnostic, make
from imrosc.msgtypes import FieldSpec, flatten


def flatten_json(value: Any, prefix: str = "") -> dict[str, Any]:
    """Scalars of a JSON value by dotted path; a list gives its length as ``len(path)``.

    >>> flatten_json({"a": {"b": 1, "c": "x"}, "d": [1, 2], "e": None})
    {'a.b': 1, 'a.c': 'x', 'len(d)': 2}
    """
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        for key, item in value.items():
            out.update(flatten_json(item, f"{prefix}.{key}" if prefix else str(key)))
        return out
    if isinstance(value, list):
        return {f"len({prefix})": len(value)}
    if value is None:
        return {}
    return {prefix: value}


def value_type(value: Any) -> str:
    """``numeric`` or ``string`` for a JSON scalar."""
    return "string" if isinstance(value, str) else "numeric"


@dataclass
class Catalog:
    """What all bags together hold."""

    bags: list[Path] = field(default_factory=list)
    types: dict[str, tuple[str, tuple[FieldSpec, ...]]] = field(default_factory=dict)
    callerids: dict[str, set[str]] = field(default_factory=dict)
    params: dict[str, str] = field(default_factory=dict)
    services: dict[str, dict[str, str]] = field(default_factory=dict)
    resources: dict[str, set[str]] = field(
        default_factory=lambda: {"pub": set(), "sub": set(), "srv": set()}
    )
    has_records: set[Path] = field(default_factory=set)
    unusable: dict[str, tuple[Path, str]] = field(default_factory=dict)
    drift: dict[str, list[tuple[Path, str]]] = field(default_factory=dict)
    """Per topic, the bags where its message type differs from the first bag's."""
    """Topics whose type cannot be decoded, with the first bag and the reason; reported only
    for topics a configuration uses."""
    messages: dict[Path, int] = field(default_factory=dict)
    diagnostics: list[Diagnostic] = field(default_factory=list)


def _note_records(catalog: Catalog, reader: Any, bag: Path) -> None:
    wanted = [c for c in reader.connections if c.topic in records.RECORD_TOPICS]
    if not wanted:
        return
    catalog.has_records.add(bag)
    for connection, stamp, raw in reader.messages(connections=wanted):
        text = reader.deserialize(raw, connection.msgtype).data
        try:
            if connection.topic == records.PARAMS_TOPIC:
                for name, value in records.decode_params(text).params.items():
                    for path, item in flatten_json(value, name).items():
                        catalog.params.setdefault(path, value_type(item))
            elif connection.topic == records.SRVS_TOPIC:
                call = records.decode_call(text)
                fields = catalog.services.setdefault(call.service, {})
                payload = {"request": call.request, "response": call.response}
                for path, item in flatten_json(payload).items():
                    fields.setdefault(path, value_type(item))
            else:
                snapshot = records.decode_arch(text)
                catalog.resources["pub"] |= {t for t, e in snapshot.topics.items() if e.pubs}
                catalog.resources["sub"] |= {t for t, e in snapshot.topics.items() if e.subs}
                catalog.resources["srv"] |= set(snapshot.services)
        except (records.RecordError, json.JSONDecodeError) as error:
            message = f"bad {connection.topic} record at {stamp / 1e9:.9f}: {error}"
            catalog.diagnostics.append(make(str(bag), 1, 1, "bag-error", message))


def _observed_lengths(
    reader: Any, connection: Any, fields: tuple[FieldSpec, ...]
) -> tuple[FieldSpec, ...]:
    """Numeric sequences get the length their first message has (layouts expand short ones)."""
    open_ended = [f for f in fields if f.array == "sequence" and "[]" not in f.path]
    if not open_ended or not connection.msgcount:
        return fields
    try:
        for _, _, raw in reader.messages(connections=[connection]):
            message = reader.deserialize(raw, connection.msgtype)
            break
        else:
            return fields
    except MessageError:
        return fields
    lengths = {}
    for spec in open_ended:
        value: Any = message
        for part in spec.path.split("."):
            value = getattr(value, part, None)
        lengths[spec.path] = len(value) if value is not None and hasattr(value, "__len__") else None
    return tuple(
        replace(f, length=lengths[f.path])
        if f.path in lengths and f.type in ("float", "int", "uint")
        else f
        for f in fields
    )


def _note_bag(catalog: Catalog, bag: Path) -> None:
    with open_bag(bag) as reader:
        warning = recovered_diagnostic(bag, reader)
        if warning is not None:
            catalog.diagnostics.append(warning)
        count = 0
        for connection in reader.connections:
            count += connection.msgcount
            if connection.topic in records.RECORD_TOPICS:
                continue
            known = catalog.types.get(connection.topic)
            if known is not None and connection.msgtype not in reader.typestore.fielddefs:
                message = (
                    f"topic {connection.topic}: unknown message type {connection.msgtype} in "
                    f"this bag (it stores no definition of it); its messages are skipped"
                )
                catalog.diagnostics.append(make(str(bag), 1, 1, "bag-error", message))
                continue
            if known is None:
                try:
                    fields = flatten(reader.typestore, connection.msgtype)
                except KeyError as missing:
                    message = (
                        f"topic {connection.topic}: unknown message type {missing.args[0]} (the "
                        f"bag stores no definition of it); the topic is skipped"
                    )
                    catalog.unusable.setdefault(connection.topic, (bag, message))
                    continue
                fields = _observed_lengths(reader, connection, fields)
                catalog.types[connection.topic] = (connection.msgtype, fields)
            elif known[0] != connection.msgtype:
                message = (
                    f"topic {connection.topic} has type {connection.msgtype} here but "
                    f"{known[0]} in an earlier bag; fields are matched by name"
                )
                catalog.drift.setdefault(connection.topic, []).append((bag, message))
            callerid = getattr(connection.ext, "callerid", None)
            if callerid:
                catalog.callerids.setdefault(connection.topic, set()).add(callerid)
        catalog.messages[bag] = count
        _note_records(catalog, reader, bag)


def build_catalog(paths: Sequence[Path] | Iterable[Path]) -> Catalog:
    """Open every bag under ``paths`` once; bad bags are reported and left out."""
    catalog = Catalog()
    for path in paths:
        found, problems = discover_bags(path)
        catalog.diagnostics += problems
        for bag in found:
            try:
                _note_bag(catalog, bag)
            except BagError as error:
                catalog.diagnostics.append(error.diagnostic())
                catalog.has_records.discard(bag)
                catalog.messages.pop(bag, None)
                continue
            catalog.bags.append(bag)
    catalog.bags = sorted(dict.fromkeys(catalog.bags))
    return catalog


def arch_resources(catalog: Catalog, kinds: Sequence[str]) -> dict[str, list[str]]:
    """Per architecture kind, every resource a snapshot or a callerid names."""
    found: Mapping[str, set[str]] = catalog.resources
    out = {kind: sorted(found[kind]) for kind in kinds}
    if "pub" in out:
        out["pub"] = sorted(set(out["pub"]) | set(catalog.callerids))
    return out
