"""Which invariants classification keeps for the monitor (``<check select>``).

A monitor alarms when *any* invariant it checks alarms: its detections are the union of
its invariants' detections, and so are its false alarms. Two selections:

* ``cover`` (the default): the set of invariants whose union is worth the most, counted as
  the product counts a monitor: failed runs it detects minus runs it would raise a false
  alarm on. Invariants are added greedily, each time the one that adds the most, while one
  adds anything. A failed run counts as detected when one of the set breaks at or after its
  fault's onset (anywhere, without an onset) and none of the set breaks before it.

  False alarms are *estimated*, not counted: with hundreds of candidates and a few runs,
  some invariant always happens to hold on the runs at hand, and picking it for that is
  picking noise. An invariant broken by ``k`` of the ``n`` successful runs that tested it
  breaks a new nominal run with probability ``(k + 1) / (n + 2)`` (Laplace's rule of
  succession: 1/(n + 2) when none broke it). A failed run up to its onset is not counted
  among the ``n``: it is part of a run, cut where the fault began, and a per-run probability
  is learnt from whole runs; what it breaks before its onset is counted where it happened
  (it spoils that run's detection). The set's false alarm probability is
  ``1 - prod(1 - p_i)`` (as if the
  invariants broke independently: more, not less, than their correlated breaks give). Over
  the classification's runs (successful and failed alike, each of which can raise a false
  alarm) the set costs ``runs * (1 - prod(1 - p_i))`` false alarms. A successful run that
  trained the invariants is evidence only about the invariants it was replayed against
  when calibration held it out (``absent`` in the file's held-out units).

  The cover is one candidate monitor among others (:func:`imrosc.classify.monitor_choice`):
  the inferred monitor as calibrated (:class:`Whole`: every invariant under the file's own
  alarm rule) is another, and learnt detectors make more; the one worth the most on failed
  runs the choice did not see sets the bar, and of those within a standard error of it
  (:func:`within_noise`) the one of fewest invariants is kept.

* ``fscore``: the thesis' filter (section 4.2): each invariant is scored alone as a
  classifier of failed runs and kept when its F-beta score reaches ``threshold``. It keeps
  the invariants that detect most kinds of failure at once and drops the specialists (an
  invariant detecting only one of seven fault kinds has a recall of 1/7).
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

Run = TypeVar("Run", bound=Hashable)
"""A failed run, however the caller names it (a bag's path)."""

SELECTIONS = ("cover", "fscore")
"""The values of ``<check select>``; the first is the default."""


@dataclass(frozen=True)
class Nominal:
    """What the nominal runs say of one invariant: how many tested it, how many broke it."""

    tested: int
    broken: int
    ceiling: float = 1.0
    """A bound its threshold was set to keep (a learnt detector's share of the budget)."""

    @property
    def false_alarm(self) -> float:
        """The probability that it breaks on a new nominal run (rule of succession, or the
        ceiling when lower).

        >>> Nominal(8, 0).false_alarm, Nominal(8, 2).false_alarm, Nominal(8, 0, 0.02).false_alarm
        (0.1, 0.3, 0.02)
        """
        return min(self.ceiling, (self.broken + 1) / (self.tested + 2))


@dataclass(frozen=True)
class Cover:
    """The chosen invariants (in the order they were chosen) and what the set is worth on
    the classification's runs."""

    chosen: tuple[str, ...]
    detected: int
    """Failed runs the set detects."""
    false_alarm: float
    """The estimated probability that the set raises a false alarm on a new nominal run."""
    value: float
    """``detected - runs * false_alarm``."""
    worth: Worth | None = None
    """With learnt detectors, the candidate monitor kept and its held-out worth."""
    candidates: tuple[Worth, ...] = ()
    """With learnt detectors, every candidate monitor's held-out worth."""


@dataclass(frozen=True)
class Whole:
    """The inferred monitor as calibration left it: every invariant of the file, under the
    file's own alarm rule (persistence, agreement, events). What it is worth is read from
    its alarms, not from its invariants' breaks: a break the rule holds back is no alarm.

    Its false alarms are estimated as an invariant's are, by the rule of succession over the
    nominal runs that saw the whole monitor: calibration's held-out units (each replayed
    against invariants learnt without it, and judged under the alarm rule and margins its
    fold did not set: :func:`imrosc.calibrate.rule.unseen_alarms`) and successful runs that
    did not train it; ``k`` of ``n`` alarming, a new nominal run alarms with probability
    ``(k + 1) / (n + 2)``. The failed runs' detections need no holding out: nothing about the
    monitor was chosen on them.

    >>> Whole(("a", "b"), frozenset({1}), frozenset(), 6, 0).false_alarm
    0.125
    """

    chosen: tuple[str, ...]
    """Its invariants, in the file's order."""
    detected: frozenset[Any]
    """Failed runs whose first alarm is at or after the onset (anywhere, without one)."""
    early: frozenset[Any]
    """Failed runs with an alarm before their onset."""
    tested: int
    """Nominal runs (or calibration's held-out units) it was replayed on."""
    alarmed: int
    """Those of them on which it raised an alarm."""

    @property
    def false_alarm(self) -> float:
        return (self.alarmed + 1) / (self.tested + 2)


def detected_by(
    chosen: set[str], detects: Mapping[Run, set[str]], early: Mapping[Run, set[str]]
) -> int:
    """The failed runs that ``chosen`` detects: one of it breaks at or after the run's onset
    (``detects``), none before it (``early``).

    >>> detected_by({"a"}, {1: {"a"}, 2: {"a", "b"}}, {2: {"a"}})
    1
    """
    return sum(
        1 for run, ids in detects.items() if ids & chosen and not early.get(run, set()) & chosen
    )


def cover(
    nominal: Mapping[str, Nominal],
    detects: Mapping[Run, set[str]],
    early: Mapping[Run, set[str]],
    runs: int,
    order: Sequence[str] = (),
) -> Cover:
    """Greedy selection (see the module's docstring). ``nominal``: per candidate invariant,
    its evidence from nominal runs; ``detects``: per failed run, the invariants that break
    at or after its onset; ``early``: per failed run with an onset, those breaking before it;
    ``runs``: the classification's runs (each can raise a false alarm). ``order`` breaks
    ties (earlier first; then fewer false alarms, then the id).

    >>> nominal = {"a": Nominal(10, 0), "b": Nominal(10, 0), "c": Nominal(10, 6)}
    >>> found = cover(nominal, {1: {"a", "c"}, 2: {"a", "c"}, 3: {"b", "c"}}, {}, 13)
    >>> found.chosen, found.detected, round(found.false_alarm, 3)
    (('a', 'b'), 3, 0.16)
    """
    rank = {ident: k for k, ident in enumerate(order)}
    useful = {ident for ids in detects.values() for ident in ids} & set(nominal)
    candidates = sorted(
        useful,
        key=lambda i: (rank.get(i, len(rank)), nominal[i].false_alarm, i),
    )
    chosen: list[str] = []
    taken: set[str] = set()
    clean = 1.0
    value = 0.0
    detected = 0
    while True:
        best: tuple[str, float, int] | None = None
        for ident in candidates:
            if ident in taken:
                continue
            found = detected_by(taken | {ident}, detects, early)
            worth = found - runs * (1.0 - clean * (1.0 - nominal[ident].false_alarm))
            if worth > (best[1] if best else value) + 1e-9:
                best = (ident, worth, found)
        if best is None:
            return Cover(tuple(chosen), detected, 1.0 - clean, value)
        ident, value, detected = best
        chosen.append(ident)
        taken.add(ident)
        clean *= 1.0 - nominal[ident].false_alarm


@dataclass(frozen=True)
class Worth:
    """A candidate monitor's worth as held-out runs show it: failed runs it detects, failed
    runs it alarms on before their onset, and the false alarms it is expected to raise on
    new nominal runs (``runs * p``)."""

    name: str
    detected: int
    early: int
    expected: float

    @property
    def value(self) -> float:
        return self.detected - self.early - self.expected

    @classmethod
    def of(cls, name: str, outcomes: Mapping[Any, int], expected: float) -> Worth:
        """The worth of per-run held-out outcomes (1 detected, -1 alarmed on before the
        onset, 0 neither; :func:`held_out_outcomes`).

        >>> Worth.of("cover", {1: 1, 2: -1, 3: 0, 4: 1}, 0.5).value
        0.5
        """
        found = list(outcomes.values())
        return cls(name, sum(v > 0 for v in found), sum(v < 0 for v in found), expected)


def held_out_outcomes(
    nominal: Mapping[str, Nominal],
    detects: Mapping[Run, set[str]],
    early: Mapping[Run, set[str]],
    runs: int,
    folds: Sequence[Sequence[Run]],
    order: Sequence[str] = (),
    extra: Mapping[Run, bool] | None = None,
) -> dict[Run, int]:
    """Per failed run, what ``cover``'s choice does with it when each fold of failed runs is
    held out of the choice (the choice is made on the others): 1 detected, -1 alarmed on
    before its onset, 0 neither. The worth of the selection itself, which the set's own
    counts overstate (the set was picked because it detects those very runs). ``extra``:
    per failed run, whether another part of the monitor (a detector, cross-fitted) detects
    it.

    >>> nominal = {"a": Nominal(10, 0), "b": Nominal(10, 0)}
    >>> held_out_outcomes(nominal, {1: {"a"}, 2: {"a"}, 3: {"b"}}, {}, 3, [[1], [2], [3]])
    {1: 1, 2: 1, 3: 0}
    """
    found: dict[Run, int] = {}
    for fold in folds:
        held = set(fold)
        chosen = set(
            cover(
                nominal,
                {r: ids for r, ids in detects.items() if r not in held},
                {r: ids for r, ids in early.items() if r not in held},
                runs,
                order,
            ).chosen
        )
        for run in fold:
            spoiled = bool(early.get(run, set()) & chosen)
            hit = bool(detects.get(run, set()) & chosen) or bool((extra or {}).get(run))
            found[run] = -1 if spoiled else int(hit)
    return found


def within_noise(best: Mapping[Any, int], other: Mapping[Any, int]) -> float:
    """The standard error of the difference between two candidates' held-out counts over
    the same failed runs (paired: per run, one's outcome less the other's, -2 to 2; runs
    missing from one count 0 there): ``sqrt(n) * sd``, 0 with fewer than two runs.

    >>> within_noise({1: 1, 2: 1, 3: 0, 4: 0}, {1: 0, 2: 1, 3: 0, 4: 0})
    1.0
    >>> within_noise({1: 1, 2: 1}, {1: 1, 2: 1})
    0.0
    """
    runs = set(best) | set(other)
    n = len(runs)
    if n < 2:
        return 0.0
    d = [best.get(r, 0) - other.get(r, 0) for r in runs]
    mean = sum(d) / n
    return math.sqrt(n * sum((x - mean) ** 2 for x in d) / (n - 1))


def union_false_alarm(nominal: Mapping[str, Nominal], chosen: Sequence[str]) -> float:
    """The probability that any of ``chosen`` breaks on a new nominal run (independence).

    >>> round(union_false_alarm({"a": Nominal(8, 0), "b": Nominal(8, 2)}, ["a", "b"]), 2)
    0.37
    """
    clean = 1.0
    for ident in chosen:
        clean *= 1.0 - nominal[ident].false_alarm
    return 1.0 - clean
