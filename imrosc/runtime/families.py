"""The invariant families: one record each, the one place that names them.

Every stage speaks of a family by the constants below, never by a bare string: the job
schema's list (a test holds them equal), which families inference instantiates at which
kind of program point (:func:`for_point`), how summaries group them (:func:`in_group`), how
the runtime checks them (:attr:`Family.check`) and whether its compiled kernel does
(:attr:`Family.compiled`; a point holding a value family the kernel does not know is
checked by numpy alone, never cleared unchecked).

Adding a value family is one row here, one state module in ``imrosc/infer``, its check in
:mod:`.checks`, tests and docs (``docs/architecture.md``).

Python 3.8 syntax, standard library only: this module is copied into generated packages.

>>> for_point(CALL)[:3], in_group("time-related")
(('bounds', 'one-of', 'non-zero'), ('frequency', 'variance', 'rate', 'mean', 'step'))
>>> FAMILIES[POLYGON].check, FAMILIES[INTERVAL].check
('value', 'event')
"""

from typing import Dict, FrozenSet, Iterable, NamedTuple, Tuple

BOUNDS = "bounds"
ONE_OF = "one-of"
NON_ZERO = "non-zero"
EQUALITY = "equality"
ORDER = "order"
LINEAR = "linear"
TERNARY = "ternary"
FUNCTION = "function"
STRING_ONE_OF = "string-one-of"
ARRAY = "array"
FREQUENCY = "frequency"
VARIANCE = "variance"
RATE = "rate"
MEAN = "mean"
STEP = "step"
POLYGON = "polygon"
ARCHITECTURE = "architecture"
INTERVAL = "interval"
PATTERN = "pattern"
DETECTOR = "detector"

PUBLISH = "publish"
CALL = "call"
PARAM = "param"
ARCH = "arch"
TEMPORAL = "temporal"
POINT_KINDS = (PUBLISH, CALL, PARAM, ARCH, TEMPORAL)
"""The kinds of program point (``plan.json``'s and the IR's)."""

GROUPS = ("default", "time-related", "polygon", "architecture", "temporal", "detector")
"""How summaries group families, as the thesis counts them (465 default, 362
time-related, ...); detectors are learnt by classification, not inferred."""


class Family(NamedTuple):
    """One invariant family."""

    name: str
    group: str
    """Its summary group (:data:`GROUPS`)."""
    points: FrozenSet[str]
    """The kinds of program point inference instantiates it at."""
    check: str
    """How the runtime checks it: ``value`` (each sample's values), ``window`` (the
    point's values over its time window), ``event`` (timers, the graph, orderings: each
    violation an alarm), ``score`` (a learnt score of the point's recent samples: each
    violation an alarm)."""
    compiled: bool = False
    """Whether the compiled kernel (:mod:`.compiled`) checks it (value families)."""
    ranged: bool = False
    """A range of one variable (the alarm rule's agreement does not count a relation broken
    in a sample that also breaks such a range of one of its variables)."""


_VALUES = frozenset({PUBLISH, CALL})
_PARAMS = frozenset({PUBLISH, CALL, PARAM})

CATALOG: Tuple[Family, ...] = (
    Family(BOUNDS, "default", _PARAMS, "value", compiled=True, ranged=True),
    Family(ONE_OF, "default", _PARAMS, "value", compiled=True),
    Family(NON_ZERO, "default", _VALUES, "value", compiled=True),
    Family(EQUALITY, "default", _VALUES, "value", compiled=True),
    Family(ORDER, "default", _VALUES, "value", compiled=True),
    Family(LINEAR, "default", _VALUES, "value", compiled=True),
    Family(TERNARY, "default", _VALUES, "value", compiled=True),
    Family(FUNCTION, "default", _VALUES, "value"),
    Family(STRING_ONE_OF, "default", _PARAMS, "value"),
    Family(ARRAY, "default", _VALUES, "value", compiled=True, ranged=True),
    Family(FREQUENCY, "time-related", frozenset({PUBLISH}), "window"),
    Family(VARIANCE, "time-related", frozenset({PUBLISH}), "window"),
    Family(RATE, "time-related", frozenset({PUBLISH}), "window"),
    Family(MEAN, "time-related", frozenset({PUBLISH}), "window"),
    Family(STEP, "time-related", frozenset({PUBLISH}), "window"),
    Family(POLYGON, "polygon", _VALUES, "value", compiled=True),
    Family(ARCHITECTURE, "architecture", frozenset({ARCH}), "event"),
    Family(INTERVAL, "temporal", frozenset({TEMPORAL}), "event"),
    Family(PATTERN, "temporal", frozenset({TEMPORAL}), "event"),
    Family(DETECTOR, "detector", frozenset(), "score"),
)
"""Every family, in the order inference instantiates them and files list them."""

FAMILIES: Dict[str, Family] = {family.name: family for family in CATALOG}
NAMES: Tuple[str, ...] = tuple(family.name for family in CATALOG)
WINDOW: FrozenSet[str] = frozenset(f.name for f in CATALOG if f.check == "window")
"""Families checked on window values (frequency, variance, change rate, mean, step)."""
EVENT: FrozenSet[str] = frozenset(f.name for f in CATALOG if f.check == "event")
"""Families whose violations are events (the graph, orderings)."""
RANGED: FrozenSet[str] = frozenset(f.name for f in CATALOG if f.ranged)
COMPILED: FrozenSet[str] = frozenset(f.name for f in CATALOG if f.compiled)
INFERRED_GROUPS: Tuple[str, ...] = tuple(
    g for g in GROUPS if any(f.points for f in CATALOG if f.group == g)
)
"""The summary groups of the families inference instantiates (``imrosc infer``'s counts)."""


def in_group(group: str) -> Tuple[str, ...]:
    """The families of a summary group, in catalog order."""
    return tuple(f.name for f in CATALOG if f.group == group)


def group_of(name: str) -> str:
    """The summary group of a family (its own name for one the catalog does not hold)."""
    family = FAMILIES.get(name)
    return family.group if family is not None else name


def select(words: Iterable[str], kind: str) -> Tuple[Tuple[str, ...], Tuple[str, ...]]:
    """The families of a point of ``kind`` that ``words`` (family or group names) select,
    in catalog order, and the words that name none of them.

    >>> select(["default", "rate", "polygons"], PUBLISH)[1]
    ('polygons',)
    >>> select(["time-related", "bounds"], PUBLISH)[0]
    ('bounds', 'frequency', 'variance', 'rate', 'mean', 'step')
    """
    applicable = for_point(kind)
    wanted = set()
    unknown = []
    for word in words:
        found = [name for name in applicable if word in (name, FAMILIES[name].group)]
        if found:
            wanted.update(found)
        else:
            unknown.append(word)
    return tuple(name for name in applicable if name in wanted), tuple(unknown)


def for_point(kind: str, patterns: bool = False) -> Tuple[str, ...]:
    """The families inference instantiates at a point of ``kind``; ``patterns``: a
    temporal point with event patterns (``<temporal>`` with ``pattern``)."""
    return tuple(f.name for f in CATALOG if kind in f.points and (f.name != PATTERN or patterns))
