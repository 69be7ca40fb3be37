"""Run-level calibration (``imrosc infer``): invariants that hold on the next normal run.

Exact training extremes do not generalise: with ``R`` runs a new run exceeds one extreme
with probability about ``1/(R+1)``, and a point holds hundreds. Runs (bags), not samples,
are the unit of evidence here. Given the invariants inferred from all runs and the
invariants of each *unit* alone (each run, or time segments of the runs when there are
fewer than four), calibration

1. widens every envelope (:mod:`.limits`) by a prediction bound over the units' extremes,
   so that a new run breaks an invariant with probability at most the per-run false-alarm
   budget ``alpha`` (each of its ``m`` limits at ``alpha / m``; :mod:`.tolerance`);
2. drops the sets (one-of values, strings, architecture nodes) that more held-out units
   break than ``alpha`` explains: no tolerance can stabilise a set;
3. replays every unit against the envelopes learnt without it (k-fold over the units),
   drops the invariants that more held-out units still break than ``alpha`` explains, and
   sets the alarm rule (:mod:`imrosc.runtime.alarms`) so that no more than ``alpha`` of the
   held-out units would have raised an alarm with the others (:mod:`.rule`).

The figures, and what a user trades with the budget, are in ``docs/calibration.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from imrosc.calibrate.envelope import Envelopes, FoldDocument, UnitView
from imrosc.calibrate.rule import HeldOut, Learnt, Replays, calibrate_rule
from imrosc.calibrate.severe import SEVERE, SevereCheck, check_severe
from imrosc.folds import at_gaps
from imrosc.infer.engine import Unit
from imrosc.remote import bag_path
from imrosc.runtime.alarms import AlarmRule

DEFAULT_BUDGET = 0.05
"""The default per-run false-alarm budget (``<detect budget>``)."""


@dataclass
class Calibration:
    """What calibration did, as the invariants file records it (``calibration``)."""

    budget: float
    units: str
    """``runs`` or ``segments`` (pseudo-runs: too few runs)."""
    count: int
    widened: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    """Sets broken by held-out units (one-of values, strings, nodes), per family."""
    unstable: dict[str, int] = field(default_factory=dict)
    """Invariants held-out units broke even with their tolerance, per family."""
    unsupported: dict[str, int] = field(default_factory=dict)
    """Invariants that fewer than two units support (justified by one run alone)."""
    rule: AlarmRule = field(default_factory=AlarmRule)
    certified: bool = False
    held_out: list[HeldOut] = field(default_factory=list)
    severe: SevereCheck | None = None
    """What held-out units said of the margins (``None``: no margins, one bag alone)."""

    def as_json(self) -> dict[str, Any]:
        return {
            "budget": self.budget,
            "units": self.units,
            "count": self.count,
            "widened": dict(sorted(self.widened.items())),
            "dropped": dict(sorted(self.dropped.items())),
            "unstable": dict(sorted(self.unstable.items())),
            "unsupported": dict(sorted(self.unsupported.items())),
            "certified": self.certified,
            "held_out": [h.as_json() for h in self.held_out],
            **({} if self.severe is None else {"severe": self.severe.as_json()}),
        }

    def summary(self) -> str:
        """One paragraph for the command line."""
        unit = "runs" if self.units == "runs" else "pseudo-runs (time segments of too few runs)"
        widened = sum(self.widened.values())
        dropped = sum(self.dropped.values()) + sum(self.unstable.values())
        unsupported = sum(self.unsupported.values())
        rule = self.rule
        alarm = f"an alarm after {rule.persist} consecutive violating samples of one invariant"
        if rule.seconds is not None:
            alarm += f" or {rule.seconds:g} s of them"
        if rule.distinct:
            alarm += f" or {rule.distinct} invariants of a point broken within {rule.window:g} s"
        if rule.severe_families:
            alarm += f" or at once beyond a margin ({', '.join(rule.severe_families)})"
        certified = (
            "certified"
            if self.certified
            else f"not certified by {self.count} {self.units} (a prediction bound used)"
        )
        return (
            f"calibrated on {self.count} {unit} at a false-alarm budget of {self.budget:g} "
            f"per run ({certified}): {widened} invariants widened, {dropped} dropped as "
            f"unstable, {unsupported} as seen in fewer than two {self.units}; {alarm}"
        )


def blocks(units: Sequence[Unit], folds: int) -> list[list[int]]:
    """Blocked k-fold by session (:func:`imrosc.folds.at_gaps`): the units (indexes) in the
    order they were recorded, cut into ``folds`` contiguous blocks at the widest gaps
    between their starts (evenly spaced units: near-equal blocks); units that overlap on
    the bag clock (runs of simulated time, each from 0) have no gap between them.

    >>> from pathlib import Path
    >>> units = [Unit(Path(name), [], start=start) for name, start in
    ...          [("c", 30.0), ("a", 10.0), ("b", 20.0), ("d", 40.0), ("e", 50.0)]]
    >>> blocks(units, 2), blocks(units, 3)
    ([[1, 2, 0], [3, 4]], [[1, 2], [0, 3], [4]])
    """
    order = sorted(range(len(units)), key=lambda k: (units[k].start, str(units[k].bag)))
    cut = at_gaps([units[k].start for k in order], folds, [units[k].end for k in order])
    return [[order[k] for k in group] for group in cut]


def _evidence(
    held_out: Sequence[HeldOut],
    units: Sequence[Unit],
    envelopes: Envelopes,
    held: Sequence[tuple[Learnt, list[int]]],
    kept: set[str],
) -> None:
    """What each held-out unit says of the kept invariants beyond its replay: those it could
    not test (``absent``: its fold's document holds them as learnt from every unit) and the
    sets it breaks when they are learnt from its fold's training units (``set_breaks``)."""
    index = {(unit.bag, unit.span): k for k, unit in enumerate(units)}
    everyone = set(range(len(units)))
    for unit in held_out:
        training = everyone - set(held[unit.fold][1])
        at = index[(bag_path(unit.bag), unit.span)]
        unit.absent = sorted(envelopes.untested(training) & kept)
        unit.set_breaks = sorted(envelopes.set_breaks(at, training) & kept)


def calibrate(
    document: dict[str, Any],
    units: Sequence[Unit],
    budget: float = DEFAULT_BUDGET,
    *,
    folds: int = 5,
    workers: int = 1,
    replays: Replays | None = None,
    step_tail: str = "select",
) -> Calibration:
    """Calibrate ``document`` (an invariants document, changed in place) on ``units``; the
    held-out replays run in ``workers`` processes, or with ``replays`` (a cluster);
    ``step_tail``: how steps' margins model the units' largest steps
    (:meth:`.envelope.Envelopes.margin`)."""
    segments = any(u.span is not None for u in units)
    report = Calibration(budget, "segments" if segments else "runs", len(units))
    if len(units) < 2:
        return report
    views = [UnitView.of(u) for u in units]
    # time segments of one bag give no margins: a landing is in one segment only, and one
    # run cannot say how hard the next one's is
    margins = len({bag_path(u.bag) for u in units}) >= 2
    envelopes = Envelopes(document, views, budget, margins=margins, step_tail=step_tail)
    everyone = set(range(len(views)))
    final = envelopes.document(everyone, final=True)
    report.widened, report.dropped = envelopes.widened, envelopes.dropped
    report.unsupported = envelopes.unsupported
    groups = blocks(units, folds)
    # each fold's document is built where its units are replayed (a worker, a process)
    held: list[tuple[Learnt, list[int]]] = [
        (FoldDocument(envelopes, frozenset(everyone - set(group))), group)
        for group in groups
        if group
    ]
    parts = 4 if margins else 3
    found = calibrate_rule(held, units, budget, workers=workers, replays=replays, parts=parts)
    report.rule, report.certified, report.held_out = found.rule, found.certified, found.held_out
    kept = []
    for invariant in final["invariants"]:
        if invariant["id"] in found.dropped:
            family = invariant["family"]
            report.unstable[family] = report.unstable.get(family, 0) + 1
        else:
            kept.append(invariant)
    final["invariants"] = kept
    if margins:
        report.severe = check_severe(kept, report.held_out, budget, envelopes.severe_level)
        report.rule = report.rule._replace(
            severe=SEVERE if report.severe.families else 0.0,
            severe_families=report.severe.families,
        )
    _evidence(report.held_out, units, envelopes, held, {inv["id"] for inv in kept})
    document.clear()
    document.update(final)
    document["alarms"] = report.rule.as_json()
    document["calibration"] = report.as_json()
    return report
