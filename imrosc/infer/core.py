"""The contract between the translator, the template families and the inference engine.

The translator turns bags into :class:`Samples`: chunks of one program point from one run
(bag), a time column and one column per :class:`Variable`. Each template family is a
:class:`FamilyState` built for one point: the engine feeds it chunks (``update``), tells it
when a run ends (``end_run``: time windows and event intervals never span two bags), merges
the states of bags processed apart in sorted bag order (``merge``), and finally asks for the
:class:`Invariant` s it can justify (``finalize``).

Exactness rule: for every family, updating one state with runs R1..Rn in order and merging
the states of R1..Rn built apart must give the same invariants, bit for bit. States therefore
keep order-independent summaries (minima, maxima, sets, counts, exact sums) and decide
falsification monotonically.

Justification (thesis 3.5): an invariant's confidence is ``1 - 2**-n`` where ``n`` counts the
samples since it last changed; it is reported when the confidence exceeds the configured
limit (0.99 by default, so n >= 7).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np
import numpy.typing as npt

from imrosc.ir import Tunables

VariableType = Literal["float", "int", "uint", "bool", "string", "time", "set"]
Derived = Literal["len", "avg", "std", "min", "max"]

FloatArray = npt.NDArray[np.float64]
ObjectArray = npt.NDArray[np.object_]


@dataclass(frozen=True)
class Variable:
    """One variable of a program point.

    ``name`` is how invariants print it (``imu.linear_acceleration.x``, ``len(scan.ranges)``);
    ``topic`` and ``path`` say where it comes from (``path`` is the field path, empty for a
    whole-message variable); ``derived`` marks a statistic of a numeric array; ``trigger``
    says whether it belongs to the point's own topic (time-related families only use those);
    ``discrete`` says it may define conditions (integers, bools, strings).
    """

    name: str
    type: VariableType
    topic: str = ""
    path: str = ""
    derived: Derived | None = None
    trigger: bool = True

    @property
    def numeric(self) -> bool:
        """Whether its column is float64 (numbers and bools)."""
        return self.type in ("float", "int", "uint", "bool", "time")

    @property
    def discrete(self) -> bool:
        """Whether it can split a trace into conditional sub-traces (thesis 3.6)."""
        return self.type in ("int", "uint", "bool", "string") and self.derived is None


@dataclass
class Samples:
    """A chunk of one program point's samples from one run.

    ``time`` is float64 seconds (receive time of the triggering message), non-decreasing.
    Numeric columns (``Variable.numeric``) are float64 arrays (NaN where a value is missing
    or not a number, +-inf kept); string columns and set columns (architecture) are object
    arrays of ``str`` / ``frozenset[str]``. Every column has ``len(time)`` rows.
    """

    point: str
    run: int
    time: FloatArray
    columns: Mapping[str, npt.NDArray[Any]]
    variables: tuple[Variable, ...]
    restarts: npt.NDArray[np.bool_] | None = None
    """A conditional point's samples that begin an episode of its condition (it did not
    hold at the trigger's sample before): time windows restart there, as they do at a run's
    start (None: none does)."""

    def __len__(self) -> int:
        return len(self.time)

    def column(self, name: str) -> npt.NDArray[Any]:
        """The column of the variable called ``name``."""
        return self.columns[name]

    def select(
        self, mask: npt.NDArray[np.bool_], restarts: npt.NDArray[np.bool_] | None = None
    ) -> Samples:
        """The rows where ``mask`` holds (conditional sub-traces); ``restarts`` (of every
        row, optional) replaces the rows' own."""
        chosen = self.restarts if restarts is None else restarts
        return Samples(
            self.point,
            self.run,
            self.time[mask],
            {name: column[mask] for name, column in self.columns.items()},
            self.variables,
            None if chosen is None else chosen[mask],
        )


def condition_restarts(
    held: npt.NDArray[np.bool_], gap: bool, restarts: npt.NDArray[np.bool_] | None = None
) -> tuple[npt.NDArray[np.bool_], bool]:
    """Where a condition's episodes begin among a chunk's samples: the rows where it holds
    and did not at the row before (``gap``: it did not at the chunk before's last row), or
    where the rows themselves begin one (``restarts``); and whether it does not hold at the
    chunk's last row (the next chunk's ``gap``)."""
    if not len(held):
        return np.zeros(0, dtype=bool), gap
    before = np.empty(len(held), dtype=bool)
    before[0] = not gap
    before[1:] = held[:-1]
    begins = held & ~before
    if restarts is not None:
        begins |= held & restarts
    return begins, not bool(held[-1])


def kept_restarts(
    present: npt.NDArray[np.bool_], held: npt.NDArray[np.bool_], gap: bool
) -> tuple[npt.NDArray[np.bool_], bool]:
    """:func:`condition_restarts` of a chunk whose condition is judged at the rows
    ``present`` and ``held`` at some of them: where episodes begin among the rows kept
    (``present & held``), and the next chunk's ``gap``."""
    begins, gap = condition_restarts(held[present], gap)
    restarts = np.zeros(len(present), dtype=bool)
    restarts[present] = begins
    return restarts[present & held], gap


@dataclass(frozen=True)
class Invariant:
    """One inferred property.

    ``family`` is the template family (``bounds``, ``linear``, ``frequency``, ``polygon``,
    ``architecture``, ``interval``, ``pattern``, ...); ``kind`` refines it where a family has
    several forms (``lower``/``upper``, ``<``/``<=``, ``max_pubs``/``min_subs``); ``params``
    holds what the checker needs, as JSON data; ``text`` is the readable form (Daikon-like,
    coefficients as short as the data allow); ``samples`` the support; ``confidence`` the
    justification value.
    """

    family: str
    kind: str
    point: str
    variables: tuple[str, ...]
    params: Mapping[str, Any]
    text: str
    samples: int
    confidence: float
    condition: str | None = None
    runs: int = 0


@dataclass(frozen=True)
class FinalizeContext:
    """What ``finalize`` may consult: the tunables and the point's variables."""

    tunables: Tunables
    variables: tuple[Variable, ...]
    point: str
    condition: str | None = None
    runs: int = 0

    def justified(self, samples_since_change: int) -> bool:
        """Whether ``1 - 2**-n`` exceeds the confidence limit."""
        return confidence(samples_since_change) > self.tunables.confidence


def confidence(samples_since_change: int) -> float:
    """``1 - 2**-n`` (thesis 3.5)."""
    if samples_since_change <= 0:
        return 0.0
    return 1.0 - math.ldexp(1.0, -min(samples_since_change, 1074))


class FamilyState(Protocol):
    """A mergeable inference state of one template family at one program point."""

    family: str

    def update(self, samples: Samples) -> None:
        """Consume one chunk (all of one run's chunks arrive in time order)."""

    def end_run(self) -> None:
        """The current run (bag) ended: nothing windowed continues into the next one."""

    def merge(self, other: Any) -> None:
        """Absorb a state of the same family and point whose runs all come after ours."""

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """The justified invariants."""


@dataclass
class Counter:
    """Samples and runs seen: the support of a point's invariants."""

    samples: int = 0
    runs: int = 0
    extra: dict[str, int] = field(default_factory=dict)
