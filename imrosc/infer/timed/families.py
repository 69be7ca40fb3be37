"""The time-related template families (thesis 3.4.1, Algorithms 2-4, errata fixed).

* ``frequency``: messages per second of the point's trigger topic, ``|window| / window``;
* ``variance``: the fixed-algorithm sample variance of each numeric, non-derived trigger
  variable over the window (see :mod:`imrosc.infer.timed.windows`);
* ``rate``: ``(v_last - v_first) / (t_last - t_first)`` over the window, for the same
  variables (Algorithm 4 with ``rate_min`` tracking the minimum and ``-inf`` as the
  initial maximum);
* ``mean``: the mean of each such variable over the window (the fixed algorithm's mean,
  the very float its variance carries), so a sensor whose level moves (a scaled or offset
  reading) breaks it although every single sample stays within the variable's range;
* ``step``: ``v_last - v_previous``, the change between the window's last two messages,
  for the same variables, kept only where its envelope (``max - min`` of the steps) is
  narrower than the variable's own range: a jump (a position teleported, a reading
  offset at once) breaks it although both values lie within the range; where a step can
  span the range, the bounds already say all it could.

Each keeps, per variable, the minimum and maximum over all defined windows with the
position of their first occurrence (:class:`~imrosc.infer.timed.windows.Extremes`), so
merging states of runs processed apart is exact. A window value that is not finite (a NaN
or infinite sample in the window, or two messages with the same time for ``rate``) is
skipped. Each family reports ``lower <= f(x) <= upper`` with params
``{"min": lower, "max": upper, "window": seconds}`` when ``1 - 2**-n`` exceeds the
confidence limit, ``n`` being the defined windows since either bound last changed.
"""

from __future__ import annotations

import math
import weakref
from abc import ABC, abstractmethod
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from imrosc.infer.builders import StateBuilder, States, builds
from imrosc.infer.core import FinalizeContext, FloatArray, Invariant, Samples, Variable, confidence
from imrosc.infer.timed.windows import (
    Extremes,
    IntArray,
    WindowTracker,
    consecutive,
    windowed_moments,
)
from imrosc.ir import Tunables
from imrosc.runtime.families import FREQUENCY, MEAN, RATE, STEP, VARIANCE
from imrosc.translate.points import PointSpec

_last: tuple[weakref.ref[Samples], tuple[str, ...], FloatArray] | None = None


def stacked(samples: Samples, names: tuple[str, ...]) -> FloatArray:
    """The columns ``names`` as one ``(rows, variables)`` array.

    Variance and rate read the same columns of the same chunk: the last stack is kept
    (for that very chunk object only) so the second family does not copy them again.
    """
    global _last  # noqa: PLW0603
    if _last is not None and _last[0]() is samples and _last[1] == names:
        return _last[2]
    if names:
        values = np.stack(
            [np.asarray(samples.column(name), dtype=np.float64) for name in names], axis=1
        )
    else:
        values = np.empty((len(samples), 0))
    values.flags.writeable = False
    _last = (weakref.ref(samples), names, values)
    return values


_last_moments: (
    tuple[weakref.ref[Samples], tuple[str, ...], IntArray, IntArray, tuple[FloatArray, FloatArray]]
    | None
) = None


def moments(
    samples: Samples,
    names: tuple[str, ...],
    values: FloatArray,
    starts: IntArray,
    length: IntArray,
) -> tuple[FloatArray, FloatArray]:
    """:func:`windowed_moments` of the windows ``values[starts : starts + length]``, computed
    once for variance and mean.

    Both families of a point carry the same window over the same chunks (each its own
    tracker, so each its own copy of the carried rows): the second asks for the very windows
    of the very chunk ``samples`` and columns ``names``, and gets the first one's answer.
    """
    global _last_moments  # noqa: PLW0603
    last = _last_moments
    if (
        last is not None
        and last[0]() is samples
        and last[1] == names
        and np.array_equal(last[2], starts)
        and np.array_equal(last[3], length)
    ):
        return last[4]
    found = windowed_moments(values, starts, length)
    _last_moments = (weakref.ref(samples), names, starts, length, found)
    return found


def format_bound(value: float) -> str:
    """A bound as text: six significant digits, integers without a fraction."""
    if math.isfinite(value) and value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return f"{value:.6g}"


def tracked(variables: Sequence[Variable]) -> tuple[Variable, ...]:
    """The variables variance and rate follow: numeric, not derived, on the trigger topic."""
    return tuple(v for v in variables if v.numeric and v.derived is None and v.trigger)


def trigger_topic(variables: Sequence[Variable]) -> str:
    """The point's own topic, as its trigger variables name it ("" if none does)."""
    for variable in variables:
        if variable.trigger and variable.topic:
            return variable.topic
    return ""


class TimedState(ABC):
    """Shared machinery: the window carried across chunks, the extremes, finalize."""

    family = ""
    label = ""

    def __init__(self, names: Sequence[str], window: float) -> None:
        self.names = tuple(names)
        self.window = float(window)
        self.tracker = WindowTracker(self.window, len(self.names))
        self.extremes = Extremes(max(len(self.names), 1))

    @abstractmethod
    def update(self, samples: Samples) -> None:
        """Add the windows of a chunk of the point's samples (each family its statistic)."""

    def end_run(self) -> None:
        """Windows never span runs."""
        self.tracker.reset()

    def merge(self, other: Any) -> None:
        """Absorb a state whose runs all come after ours."""
        if not isinstance(other, type(self)) or other.names != self.names:
            raise TypeError(f"cannot merge {type(other).__name__} into {type(self).__name__}")
        if other.window != self.window:
            raise ValueError("cannot merge time-related states with different windows")
        self.extremes.merge(other.extremes)
        self.tracker.adopt(other.tracker)

    def _values(self, samples: Samples) -> FloatArray:
        return stacked(samples, self.names)

    def _subjects(self, context: FinalizeContext) -> list[tuple[str, tuple[str, ...]]]:
        """``(text of f(x), variables)`` per column of the extremes."""
        return [(f"{self.label}({name})", (name,)) for name in self.names]

    def _params(self, context: FinalizeContext) -> dict[str, Any]:
        return {"window": self.window}

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """One ``lower <= f(x) <= upper`` invariant per justified variable."""
        found: list[Invariant] = []
        since = self.extremes.since_change()
        for col, (subject, variables) in enumerate(self._subjects(context)):
            n = int(since[col])
            if not context.justified(n):
                continue
            low = float(self.extremes.low[col])
            high = float(self.extremes.high[col])
            params: dict[str, Any] = {"min": low, "max": high, **self._params(context)}
            found.append(
                Invariant(
                    family=self.family,
                    kind="range",
                    point=context.point,
                    variables=variables,
                    params=params,
                    text=f"{format_bound(low)} <= {subject} <= {format_bound(high)}",
                    samples=int(self.extremes.count[col]),
                    confidence=confidence(n),
                    condition=context.condition,
                    runs=context.runs,
                )
            )
        return found


class FrequencyState(TimedState):
    """Algorithm 2: ``freq_min <= messages per second <= freq_max`` over full windows."""

    family = FREQUENCY
    label = "freq"

    def __init__(self, topic: str, window: float) -> None:
        super().__init__((), window)
        self.topic = topic

    def update(self, samples: Samples) -> None:
        """Count the messages of every defined window of the chunk."""
        _, _, ends, starts = self.tracker.advance(
            np.asarray(samples.time, dtype=np.float64), restarts=samples.restarts
        )
        freq = ((ends - starts + 1) / self.window)[:, None]
        self.extremes.add(freq, np.ones(freq.shape, bool))

    def _subjects(self, context: FinalizeContext) -> list[tuple[str, tuple[str, ...]]]:
        return [(f"freq({self.topic or context.point})", ())]

    def _params(self, context: FinalizeContext) -> dict[str, Any]:
        return {"window": self.window, "topic": self.topic or context.point}


class MomentState(TimedState):
    """A statistic of the fixed dyadic algorithm (:func:`moments`) over every defined window
    of at least two messages: ``moment`` 0 the mean, 1 the variance."""

    moment = 1

    def update(self, samples: Samples) -> None:
        """Evaluate the statistic of every defined window of at least two messages."""
        _, values, ends, starts = self.tracker.advance(
            np.asarray(samples.time, dtype=np.float64), self._values(samples), samples.restarts
        )
        length = ends - starts + 1
        keep = length >= 2
        found = moments(samples, self.names, values, starts[keep], length[keep])[self.moment]
        self.extremes.add(found, np.isfinite(found))


class VarianceState(MomentState):
    """Algorithm 3: ``var_min <= window variance <= var_max`` per trigger variable."""

    family = VARIANCE
    label = "var"
    moment = 1


class MeanState(MomentState):
    """``mean_min <= window mean <= mean_max`` per trigger variable (windows of at least two
    messages, as the variance's)."""

    family = MEAN
    label = "mean"
    moment = 0


class RateState(TimedState):
    """Algorithm 4 (errata fixed): ``rate_min <= window change rate <= rate_max``."""

    family = RATE
    label = "rate"

    def update(self, samples: Samples) -> None:
        """``(last - first) / (t_last - t_first)`` of every defined window."""
        time, values, ends, starts = self.tracker.advance(
            np.asarray(samples.time, dtype=np.float64), self._values(samples), samples.restarts
        )
        dt = time[ends] - time[starts]
        keep = dt > 0
        if not keep.all():
            ends, starts, dt = ends[keep], starts[keep], dt[keep]
        with np.errstate(all="ignore"):
            if consecutive(ends) and consecutive(starts):  # a steady rate: slices
                first, start = int(ends[0]), int(starts[0])
                last = values[first : first + len(ends)]
                rate = (last - values[start : start + len(starts)]) / dt[:, None]
            else:
                rate = (values[ends] - values[starts]) / dt[:, None]
        self.extremes.add(rate, np.isfinite(rate))


class StepState(TimedState):
    """``step_min <= v_last - v_previous <= step_max`` over every defined window of at
    least two messages, per trigger variable, where the steps' envelope is narrower than
    the variable's range (the range is tracked alongside, over the same samples)."""

    family = STEP
    label = "step"

    def __init__(self, names: Sequence[str], window: float) -> None:
        super().__init__(names, window)
        self.values = Extremes(max(len(self.names), 1))
        """The variables' own extremes over the windows' last samples."""

    def update(self, samples: Samples) -> None:
        """The last step of every defined window of at least two messages."""
        _, values, ends, starts = self.tracker.advance(
            np.asarray(samples.time, dtype=np.float64), self._values(samples), samples.restarts
        )
        keep = ends > starts
        if not keep.all():
            ends = ends[keep]
        with np.errstate(all="ignore"):
            step = values[ends] - values[ends - 1]
        last = values[ends]
        self.extremes.add(step, np.isfinite(step))
        self.values.add(last, np.isfinite(last))

    def merge(self, other: Any) -> None:
        super().merge(other)
        self.values.merge(other.values)

    def finalize(self, context: FinalizeContext) -> list[Invariant]:
        """Those of :meth:`TimedState.finalize` narrower than their variable's range."""
        found = []
        span = {
            name: float(self.values.high[k] - self.values.low[k])
            for k, name in enumerate(self.names)
            if self.values.count[k] > 0
        }
        for invariant in super().finalize(context):
            width = invariant.params["max"] - invariant.params["min"]
            if width < span.get(invariant.variables[0], -math.inf):
                found.append(invariant)
        return found


def make_states(
    variables: Sequence[Variable], tunables: Tunables, families: Collection[str]
) -> list[TimedState]:
    """The enabled time-related states of one point (``frequency``, ``variance``, ``rate``,
    ``mean``, ``step``)."""
    enabled = set(families)
    states: list[TimedState] = []
    names = tuple(v.name for v in tracked(variables))
    if FREQUENCY in enabled:
        states.append(FrequencyState(trigger_topic(variables), tunables.window))
    if VARIANCE in enabled and names:
        states.append(VarianceState(names, tunables.window))
    if RATE in enabled and names:
        states.append(RateState(names, tunables.window))
    if MEAN in enabled and names:
        states.append(MeanState(names, tunables.window))
    if STEP in enabled and names:
        states.append(StepState(names, tunables.window))
    return states


def _one(name: str) -> StateBuilder:
    def build(point: PointSpec, tunables: Tunables, enabled: frozenset[str]) -> States:
        return list(make_states(point.variables, tunables, {name}))

    return build


for _name in (FREQUENCY, VARIANCE, RATE, MEAN, STEP):
    builds(_name)(_one(_name))
