"""The pre-pass over a set of bags: message types and the layout of the record topics.

Before any message is translated, every bag is opened once to learn each topic's message
type (the first bag that has a topic decides its type; a later bag with another type is
reported), the ROS 1 ``callerid`` publishers, and, from the small record topics written by
``imrosc record``, which parameters, service fields and architecture resources exist. Every
run of a program point then has the same variables, so states merge.
"""

from __future__ import annotations

import json
import multiprocessing
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from imrosc import records
from imrosc.bags import BagError, MessageError, discover_bags, open_bag, recovered_diagnostic
from imrosc.diagnostics import Diagnostic, make
from imrosc.graph.bags import BagGraphs, graph_of_reader, merge_graphs
from imrosc.graph.model import Graph
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
    graphs: dict[Path, Graph] = field(default_factory=dict)
    """The node graph each bag records (read with its note: the bags are opened once)."""
    graph_problems: list[Diagnostic] = field(default_factory=list)
    """What reading the graphs of the bags that could be read found."""

    def bag_graphs(self) -> BagGraphs:
        """The graph of the catalogued bags, as :func:`~imrosc.graph.bags.read_bag_graphs`
        reads it from them."""
        read = tuple(bag for bag in self.bags if bag in self.graphs)
        graph = merge_graphs([self.graphs[bag] for bag in read])
        return BagGraphs(graph, tuple(self.graph_problems), read)


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


@dataclass
class Seen:
    """One connection of a bag as the catalogue read it, before it is set against the bags
    noted before (:func:`merge_note`)."""

    topic: str
    msgtype: str
    defined: bool
    """Whether the bag stores the definition of ``msgtype``."""
    fields: tuple[FieldSpec, ...] | None = None
    """The type's variables, sequences at their first message's length; read only for the
    bag's first connections of a topic (up to one whose type is known)."""
    missing: str | None = None
    """The type of which the bag stores no definition (``fields`` could not be read)."""
    failure: str | None = None
    """How reading the first message broke the bag (only the bag that decides the type
    reads it: for any other bag this is no error)."""
    callerid: str | None = None


@dataclass
class BagNote:
    """What one bag adds to the catalogue, read without the bags before it
    (:func:`note_bag`, on any process: a cluster's worker), merged in bag order by
    :func:`merge_note`: the catalogue of every bag then is the one of reading them in turn."""

    bag: Path
    warning: Diagnostic | None = None
    connections: list[Seen] = field(default_factory=list)
    messages: int | None = None
    """All its messages (``None``: the bag broke before its connections were all read)."""
    records: Catalog | None = None
    """Its record topics' parameters, services, resources and diagnostics."""
    graph: Graph | None = None
    """The node graph it records (``None``: it could not be read)."""
    graph_problems: list[Diagnostic] = field(default_factory=list)
    error: str | None = None
    """Why the bag cannot be read (a ``bag-error``)."""


def _renamed(error: BagError, bag: Path, name: Path) -> str:
    """The message of ``error`` of the bag read as ``bag``, about the bag as the user
    names it."""
    return error.message if bag == name else error.message.replace(str(bag), str(name))


def note_bag(bag: Path, name: Path | None = None) -> BagNote:
    """Read one bag's part of the catalogue; ``name``: the bag as the user names it, in the
    diagnostics (``bag`` is where this process reads it)."""
    name = bag if name is None else name
    note = BagNote(name)
    try:
        with open_bag(bag) as reader:
            note.warning = recovered_diagnostic(name, reader)
            count = 0
            decided: set[str] = set()
            for connection in reader.connections:
                count += connection.msgcount
                if connection.topic in records.RECORD_TOPICS:
                    continue
                seen = Seen(
                    connection.topic,
                    connection.msgtype,
                    connection.msgtype in reader.typestore.fielddefs,
                    callerid=getattr(connection.ext, "callerid", None) or None,
                )
                if connection.topic not in decided:
                    try:
                        fields = flatten(reader.typestore, connection.msgtype)
                    except KeyError as missing:
                        seen.missing = str(missing.args[0])
                    else:
                        try:
                            seen.fields = _observed_lengths(reader, connection, fields)
                        except BagError as error:
                            seen.failure = _renamed(error, bag, name)
                        else:
                            decided.add(connection.topic)
                note.connections.append(seen)
            note.messages = count
            note.records = Catalog()
            _note_records(note.records, reader, name)
            try:
                note.graph, note.graph_problems = graph_of_reader(reader, name)
            except BagError as error:
                note.graph_problems = [
                    make(str(name), 1, 1, "bag-error", _renamed(error, bag, name))
                ]
    except BagError as error:
        note.error = _renamed(error, bag, name)
    return note


def merge_note(catalog: Catalog, note: BagNote) -> None:
    """Add a bag's note to the catalogue of the bags before it: what reading the bag in turn
    would have added (the first bag of a topic decides its type)."""
    bag = note.bag
    if note.warning is not None:
        catalog.diagnostics.append(note.warning)
    error = note.error
    for seen in note.connections:
        known = catalog.types.get(seen.topic)
        if known is not None and not seen.defined:
            message = (
                f"topic {seen.topic}: unknown message type {seen.msgtype} in "
                f"this bag (it stores no definition of it); its messages are skipped"
            )
            catalog.diagnostics.append(make(str(bag), 1, 1, "bag-error", message))
            continue
        if known is None:
            if seen.missing is not None:
                message = (
                    f"topic {seen.topic}: unknown message type {seen.missing} (the "
                    f"bag stores no definition of it); the topic is skipped"
                )
                catalog.unusable.setdefault(seen.topic, (bag, message))
                continue
            if seen.failure is not None:  # read in turn, the bag breaks here
                error = seen.failure
                break
            assert seen.fields is not None, f"{bag}: {seen.topic} was not read"
            catalog.types[seen.topic] = (seen.msgtype, seen.fields)
        elif known[0] != seen.msgtype:
            message = (
                f"topic {seen.topic} has type {seen.msgtype} here but "
                f"{known[0]} in an earlier bag; fields are matched by name"
            )
            catalog.drift.setdefault(seen.topic, []).append((bag, message))
        if seen.callerid:
            catalog.callerids.setdefault(seen.topic, set()).add(seen.callerid)
    else:
        if note.messages is not None:
            catalog.messages[bag] = note.messages
        found = note.records
        if found is not None:
            if found.has_records:
                catalog.has_records.add(bag)
            for path, kind in found.params.items():
                catalog.params.setdefault(path, kind)
            for service, fields in found.services.items():
                known_fields = catalog.services.setdefault(service, {})
                for path, kind in fields.items():
                    known_fields.setdefault(path, kind)
            for kind, names in found.resources.items():
                catalog.resources[kind] |= names
            catalog.diagnostics += found.diagnostics
    if error is not None:
        catalog.diagnostics.append(make(str(bag), 1, 1, "bag-error", error))
        catalog.has_records.discard(bag)
        catalog.messages.pop(bag, None)
        return
    catalog.bags.append(bag)
    if bag not in catalog.graphs:  # a bag given twice: read once
        if note.graph is not None:
            catalog.graphs[bag] = note.graph
        catalog.graph_problems += note.graph_problems


Noter = Callable[[Sequence[Path]], Iterable[BagNote]]
"""Notes of bags (:func:`note_bag`), in their order: one process reads them in turn, a Dask
cluster one task per bag (:meth:`imrosc.fleet.Fleet.note_bags`)."""


def note_in_turn(bags: Sequence[Path]) -> Iterator[BagNote]:
    """Each bag's note, read by this process one after the other."""
    for bag in bags:
        yield note_bag(bag)


def note_in_pool(workers: int) -> Noter:
    """Notes read by ``workers`` forked processes, a bag at a time, in bag order."""

    def noter(bags: Sequence[Path]) -> Iterator[BagNote]:
        if workers <= 1 or len(bags) <= 1:
            yield from note_in_turn(bags)
            return
        context = multiprocessing.get_context("fork")
        with context.Pool(min(workers, len(bags))) as pool:
            yield from pool.imap(note_bag, bags)

    return noter


def build_catalog(paths: Sequence[Path] | Iterable[Path], noter: Noter | None = None) -> Catalog:
    """Open every bag under ``paths`` once (``noter``: where, this process by default); bad
    bags are reported and left out."""
    catalog = Catalog()
    found = [discover_bags(path) for path in paths]
    notes = iter((noter or note_in_turn)([bag for bags, _ in found for bag in bags]))
    for bags, problems in found:  # the diagnostics in the order of reading path by path
        catalog.diagnostics += problems
        for _ in bags:
            merge_note(catalog, next(notes))
    catalog.bags = sorted(dict.fromkeys(catalog.bags))
    return catalog


def arch_resources(catalog: Catalog, kinds: Sequence[str]) -> dict[str, list[str]]:
    """Per architecture kind, every resource a snapshot or a callerid names."""
    found: Mapping[str, set[str]] = catalog.resources
    out = {kind: sorted(found[kind]) for kind in kinds}
    if "pub" in out:
        out["pub"] = sorted(set(out["pub"]) | set(catalog.callerids))
    return out
