"""Severe violations, checked on held-out units: which margins hold, and which families alarm.

Calibration gives every range of one scalar a margin per limit (``params.margin``,
:meth:`.envelope.Envelopes.margin`): a violation beyond it is *severe* (severity at least
1) and alarms at once. The margins rest on a model of the units' extremes; the held-out
replays test it. Each held-out unit was replayed against its fold's margins (learnt
without it) and its trace keeps, per invariant, the largest severity it reached.

1. **Margins widen where held-out units went far out.** For an invariant that some
   held-out unit broke with severity 1 or more, the margin is multiplied by the prediction
   bound of one more unit's largest severity (the units' largest severities, 0 for those
   that did not break it), at the margins' level.
2. **A family whose units still go far out gets no severe alarm.** A unit's own severities
   are divided by the factors step 1 takes from the *other* folds' units alone (its own
   would explain it away by construction). A family whose held-out units still reach
   severity 1 more often than a per-run probability of its share of the severe alarms'
   quarter of the budget explains (the binomial test of :func:`.tolerance.too_many`) keeps
   its margins, shown, but alarms by persistence and agreement only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from imrosc.calibrate.rule import HeldOut
from imrosc.calibrate.tolerance import exp_or_inf, prediction_bound, too_many
from imrosc.runtime.families import VARIANCE

SEVERE = 1.0
"""The severity at which a violation alarms at once (in margins beyond the centre)."""


@dataclass
class SevereCheck:
    """What the held-out units said of the margins."""

    families: tuple[str, ...] = ()
    """The families whose severe violations alarm at once."""
    refused: dict[str, int] = field(default_factory=dict)
    """Per family refused, the held-out units that still reached severity 1."""
    reached: dict[str, int] = field(default_factory=dict)
    """Per family, the held-out units that reached severity 1 (after step 2's scaling)."""
    widened: int = 0
    """Margins widened by held-out severities (step 1)."""

    def as_json(self) -> dict[str, Any]:
        return {
            "families": list(self.families),
            "reached": dict(sorted(self.reached.items())),
            "refused": dict(sorted(self.refused.items())),
            "widened": self.widened,
        }


def factor(severities: Sequence[float], level: float) -> float:
    """How much a margin widens for held-out units' largest severities: 1 when none
    reached 1, else the prediction bound of one more unit's at ``level`` (at least 1).

    >>> factor([0.0, 0.5, 0.2], 0.01)
    1.0
    >>> factor([0.0, 2.0, 0.0, 0.0], 0.01) > 2
    True
    """
    if not severities or max(severities) < SEVERE:
        return 1.0
    bound = prediction_bound(list(severities), level)
    return max(1.0, max(severities) if bound is None else bound)


def scaled(margin: Sequence[float], by: float, logarithmic: bool) -> list[float]:
    """A margin ``[centre, limit]`` whose distance from the centre is multiplied by ``by``
    (in the logarithm for a variance; a limit past any float is ``inf``).

    >>> scaled([1.0, 3.0], 2.0, False), round(scaled([1.0, math.e], 2.0, True)[1], 6)
    ([1.0, 5.0], 7.389056)
    >>> scaled([1.0, 1e300], 2.0, True)
    [1.0, inf]
    """
    centre, limit = float(margin[0]), float(margin[1])
    if logarithmic:
        return [centre, exp_or_inf(math.log(centre) + by * (math.log(limit) - math.log(centre)))]
    return [centre, centre + by * (limit - centre)]


def check_severe(
    invariants: Sequence[dict[str, Any]],
    held_out: Sequence[HeldOut],
    budget: float,
    level: float,
) -> SevereCheck:
    """Steps 1 and 2 of the module's docstring on the file's ``invariants`` (their margins
    widened in place) from the ``held_out`` units' traces; ``level``: each margin's."""
    margined = [inv for inv in invariants if "margin" in inv["params"]]
    found = SevereCheck()
    if not margined or not held_out:
        return found
    folds = sorted({unit.fold for unit in held_out})
    per_unit = {
        inv["id"]: [float(u.trace.get(inv["id"], {}).get("severity", 0.0)) for u in held_out]
        for inv in margined
    }
    reached: dict[str, set[int]] = {inv["family"]: set() for inv in margined}
    for inv in margined:
        ident, family = inv["id"], inv["family"]
        severities = per_unit[ident]
        whole = factor(severities, level)
        if whole > 1:
            logarithmic = family == VARIANCE
            given = inv["params"]["margin"]
            margin = {side: scaled(pair, whole, logarithmic) for side, pair in given.items()}
            # a limit past any float is no margin (as :meth:`.envelope.Envelopes.margin`)
            margin = {side: pair for side, pair in margin.items() if math.isfinite(pair[1])}
            params = {k: v for k, v in inv["params"].items() if k != "margin"}
            inv["params"] = dict(params, margin=margin) if margin else params
            found.widened += 1
        if max(severities) < SEVERE:
            continue
        for fold in folds:
            others = [s for s, u in zip(severities, held_out, strict=True) if u.fold != fold]
            by = factor(others, level)
            for k, (s, unit) in enumerate(zip(severities, held_out, strict=True)):
                if unit.fold == fold and s / by >= SEVERE:
                    reached[family].add(k)
                    if family not in unit.severe:
                        unit.severe.append(family)
    share = budget / 4 / len(reached)
    families = []
    for family, units in sorted(reached.items()):
        if units:
            found.reached[family] = len(units)
        if too_many(len(units), len(held_out), share):
            found.refused[family] = len(units)
        else:
            families.append(family)
    found.families = tuple(families)
    return found


def margined_families(invariants: Sequence[Mapping[str, Any]]) -> set[str]:
    """The families of the invariants with margins."""
    return {inv["family"] for inv in invariants if "margin" in inv.get("params", {})}
