"""The invariants file (``detect/@inv``): versioned JSON that every later stage reads.

It holds, per invariant, a stable id, the family, program point, condition, variables,
parameters, support (samples, runs) and confidence; per point its kind, trigger,
variables and support (samples, runs and, when training held some, the NaN or missing, +inf
and -inf values of each variable that inference left out: ``nonfinite``); and per topic
its message type and variable layout (the monitor backends generate their flatteners from
it). Ids are stable: the same invariant (point, family, kind,
variables) gets the same id in every run, so ``/m/clear_inv`` and reports can name it.

The format in three forms kept in step by ``tests/test_invariants_format.py``: the typed
dictionaries below (:class:`InvariantsDocument`), the JSON schema beside this module
(``invariants.schema.json``: :func:`schema`) and the reader's own check (:func:`validate`,
which also builds the engine); ``docs/invariants.md`` describes every key.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, TypedDict

from imrosc.infer.core import Invariant, Variable
from imrosc.onboard.files import ENGINE_ERRORS, invariants_problem
from imrosc.outputs import INVARIANTS, mark
from imrosc.runtime.families import INTERVAL, NAMES, PATTERN
from imrosc.runtime.points import Pairing, PairingEntry

FORMAT = "imrosc-invariants"
VERSION = 1
MAX_BYTES = 512 << 20


SCHEMA = "invariants.schema.json"
"""The JSON schema of the format, shipped beside this module."""


class Support(TypedDict):
    """How much an invariant or a point was learnt from."""

    samples: int
    runs: int


class VariableEntry(TypedDict):
    """One variable of a point or a topic."""

    name: str
    type: str
    topic: str
    path: str
    derived: str | None
    trigger: bool


class PointSupport(Support, total=False):
    """How much a point was learnt from, and the non-finite values inference left out:
    per variable, ``{"nan": n, "+inf": n, "-inf": n}``."""

    nonfinite: dict[str, dict[str, int]]


class _RequiredPoint(TypedDict):
    kind: str
    variables: list[VariableEntry]


class PointEntry(_RequiredPoint, PairingEntry, total=False):
    """One program point (``points.<key>``): its kind, trigger, condition, support and
    variables, and how the engine pairs its samples (:class:`~imrosc.runtime.points.
    PairingEntry`, read by :class:`~imrosc.runtime.points.Pairing`)."""

    trigger: str
    condition: str | None
    support: PointSupport


class InvariantEntry(TypedDict):
    """One invariant (``invariants[]``)."""

    id: str
    family: str
    kind: str
    point: str
    condition: str | None
    variables: list[str]
    params: dict[str, Any]
    text: str
    support: Support
    confidence: float


_RequiredDocument = TypedDict(
    "_RequiredDocument",
    {
        "$comment": str,
        "format": str,
        "version": int,
        "topics": dict[str, dict[str, Any]],
        "points": dict[str, PointEntry],
        "invariants": list[InvariantEntry],
    },
)


class InvariantsDocument(_RequiredDocument, total=False):
    """An invariants file: what :func:`document` makes; calibration adds ``alarms`` and
    ``calibration``, ``imrosc classify`` ``classified``."""

    project: str
    source: str
    bags: list[str]
    tunables: dict[str, Any]
    alarms: dict[str, Any]
    calibration: dict[str, Any]
    classified: dict[str, Any]


def schema() -> dict[str, Any]:
    """The JSON schema of the format (draft 2020-12)."""
    text = resources.files("imrosc").joinpath(SCHEMA).read_text(encoding="utf-8")
    found: dict[str, Any] = json.loads(text)
    return found


class InvariantsFileError(ValueError):
    """An invariants file that cannot be read: the message names the file and the problem."""


def invariant_id(invariant: Invariant) -> str:
    """A stable id: a short hash of what the invariant is about (not of its values)."""
    parts = [invariant.point, invariant.family, invariant.kind, *invariant.variables]
    params = invariant.params
    if invariant.family == INTERVAL:  # every ordered pair of a point has variables ("event",)
        parts += [str(params["first"]), str(params["second"])]
    elif invariant.family == PATTERN:
        parts.append(str(params["pattern"]))
    return hashed_id(parts)


def hashed_id(parts: Sequence[str]) -> str:
    """The id of an invariant about ``parts`` (point, family, kind, variables, ...)."""
    subject = "\0".join(parts)
    return "i" + hashlib.sha1(subject.encode(), usedforsecurity=False).hexdigest()[:11]


def _variable(variable: Variable) -> VariableEntry:
    return {
        "name": variable.name,
        "type": variable.type,
        "topic": variable.topic,
        "path": variable.path,
        "derived": variable.derived,
        "trigger": variable.trigger,
    }


def _json_safe(value: Any) -> Any:
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if value in (float("inf"), float("-inf")):
            return "inf" if value > 0 else "-inf"
        return value
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        items = [_json_safe(v) for v in value]
        return sorted(items, key=repr) if isinstance(value, set | frozenset) else items
    if hasattr(value, "item"):  # numpy scalars
        return _json_safe(value.item())
    return value


@dataclass(frozen=True)
class PointInfo:
    """What the file says about one program point."""

    key: str
    kind: str
    trigger: str
    condition: str | None
    samples: int
    runs: int
    variables: tuple[Variable, ...]
    pairing: Pairing = field(default_factory=Pairing)
    """What the runtime engine needs to rebuild the point's samples: ``inputs`` (topics),
    ``params``, ``events`` and ``filters`` (its conditions)."""
    nonfinite: Mapping[str, Sequence[int]] | None = None
    """Per numeric variable that had some in training, its NaN (or missing), +inf and -inf
    values, which inference left out (``support.nonfinite``: ``{"nan", "+inf", "-inf"}``)."""


def _support(point: PointInfo) -> PointSupport:
    """A point's support: samples and runs, and the non-finite values left out, if any."""
    found: PointSupport = {"samples": point.samples, "runs": point.runs}
    if point.nonfinite:
        found["nonfinite"] = {
            name: dict(zip(("nan", "+inf", "-inf"), counts, strict=True))
            for name, counts in sorted(point.nonfinite.items())
        }
    return found


def _point(point: PointInfo) -> PointEntry:
    pairing = point.pairing.to_json()
    return {
        "kind": point.kind,
        "trigger": point.trigger,
        "condition": point.condition,
        "support": _support(point),
        "variables": [_variable(v) for v in point.variables],
        "inputs": pairing["inputs"],
        "params": pairing["params"],
        "events": pairing["events"],
        "filter": _json_safe(pairing["filter"]),  # a discovered value may be a numpy scalar
    }


def document(
    *,
    project: str,
    source: str,
    bags: Sequence[str],
    tunables: Mapping[str, Any],
    topics: Mapping[str, Mapping[str, Any]],
    points: Sequence[PointInfo],
    invariants: Sequence[Invariant],
) -> dict[str, Any]:
    """The JSON document of an invariants file (an :class:`InvariantsDocument`, which the
    type checker holds it to; calibration and classification then edit it as JSON data)."""
    ordered = sorted(invariants, key=lambda i: (i.point, i.family, i.kind, i.variables))
    typed: InvariantsDocument = {
        "$comment": f"{mark(INVARIANTS)} (imrosc infer) from {source}",
        "format": FORMAT,
        "version": VERSION,
        "project": project,
        "source": source,
        "bags": list(bags),
        "tunables": dict(tunables),
        "topics": {name: dict(info) for name, info in sorted(topics.items())},
        "points": {p.key: _point(p) for p in points},
        "invariants": [
            {
                "id": invariant_id(i),
                "family": i.family,
                "kind": i.kind,
                "point": i.point,
                "condition": i.condition,
                "variables": list(i.variables),
                "params": _json_safe(i.params),
                "text": i.text,
                "support": {"samples": i.samples, "runs": i.runs},
                "confidence": i.confidence,
            }
            for i in ordered
        ],
    }
    return typed  # type: ignore[return-value]


def dumps(doc: Mapping[str, Any]) -> str:
    """Deterministic JSON text."""
    return json.dumps(doc, indent=1, ensure_ascii=False, allow_nan=False) + "\n"


MAX_DEPTH = 64
"""The deepest nesting of arrays and objects an invariants file may have (it has about 8)."""
MAX_NUMBER = 2.0**1000
"""The largest magnitude of a number in an invariants file (a float64 goes to about 2**1024;
a larger number, or a longer integer, is no measurement)."""


def load(path: Path) -> dict[str, Any]:
    """Read and check an invariants file (:func:`validate`); raise
    :class:`InvariantsFileError` with the reason, one line naming the file."""
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise InvariantsFileError(f"{path}: {size} bytes, over the {MAX_BYTES}-byte cap")
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise InvariantsFileError(f"{path}: cannot read: {error.strerror}") from None
    except UnicodeDecodeError:
        raise InvariantsFileError(f"{path}: not UTF-8 text") from None
    except json.JSONDecodeError as error:
        raise InvariantsFileError(
            f"{path}:{error.lineno}:{error.colno}: not JSON: {error.msg}"
        ) from None
    except RecursionError:
        raise InvariantsFileError(f"{path}: not an invariants file: nested too deeply") from None
    except ValueError as error:  # an integer of more than 4300 digits
        first = str(error).split(";")[0]  # not Python's advice on raising its limit
        raise InvariantsFileError(f"{path}: not JSON: {first}") from None
    validate(data, path)
    return data  # type: ignore[no-any-return]


def _walk(value: Any, where: str, depth: int) -> str | None:
    """The first problem of a JSON value's shape: too deep, or a number out of range."""
    if depth > MAX_DEPTH:
        return f"{where}: nested deeper than {MAX_DEPTH} levels"
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        if isinstance(value, int) and abs(value) > MAX_NUMBER:
            return f"{where}: number too large"
        if isinstance(value, float) and math.isfinite(value) and abs(value) > MAX_NUMBER:
            return f"{where}: number too large"
        if isinstance(value, float) and not math.isfinite(value):
            return f"{where}: number too large"
        return None
    if isinstance(value, dict):
        for key, item in value.items():
            found = _walk(item, f"{where}.{key}", depth + 1)
            if found:
                return found
    elif isinstance(value, list):
        for index, item in enumerate(value):
            found = _walk(item, f"{where}[{index}]", depth + 1)
            if found:
                return found
    return None


def validate(data: Any, path: Path) -> None:
    """Check an invariants document's shape (what the runtime engine reads, and numbers that
    fit a float); raise :class:`InvariantsFileError` naming the file and the first problem.
    The engine that checks the invariants is then built once, so that nothing it reads is
    missing or of a wrong type."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InvariantsFileError(f"{path}: not an imrosc invariants file")
    if data.get("version") != VERSION:
        raise InvariantsFileError(
            f"{path}: invariants file version {data.get('version')!r}; this imrosc reads {VERSION}"
        )
    for key in ("points", "invariants", "topics"):
        if key not in data:
            raise InvariantsFileError(f"{path}: missing '{key}'")
    problem = _walk(data, "$", 0) or invariants_problem(data, NAMES)
    if problem:
        raise InvariantsFileError(f"{path}: malformed: {problem}")
    from imrosc.runtime import Engine

    try:
        Engine(data)
    except ENGINE_ERRORS as error:
        what = f"missing {error}" if isinstance(error, KeyError) else str(error)
        culprit = _first_unbuildable(data)
        where = "" if culprit is None else f"$.invariants[{culprit}]: "
        raise InvariantsFileError(
            f"{path}: malformed: {where}{type(error).__name__}: {what}".splitlines()[0]
        ) from None


def _first_unbuildable(data: Mapping[str, Any]) -> int | None:
    """The index of the first invariant the engine cannot be built from (halving the list:
    about two builds of the whole engine), or ``None`` when each half builds alone."""
    from imrosc.runtime import Engine

    def builds(invariants: list[Any]) -> bool:
        try:
            Engine({**data, "invariants": invariants})
        except ENGINE_ERRORS:
            return False
        return True

    invariants = list(data["invariants"])
    low, high = 0, len(invariants)
    if builds(invariants[low:high]):
        return None
    while high - low > 1:
        middle = (low + high) // 2
        if not builds(invariants[low:middle]):
            high = middle
        elif not builds(invariants[middle:high]):
            low = middle
        else:  # only together: no single one to name
            return None
    return low
