"""A supervised reference on ALFA: what a learnt linear detector reaches under the same folds.

    python bench/alfa_reference.py [--folds 5] [--window 1.0]

``bench/efficacy.py`` measures imrosc's monitors on the 21 labelled ALFA flights, k-fold by
recording session. This script runs a plain supervised detector through exactly the same
folds and scoring, to say how far the data themselves carry: it is not imrosc and it tunes
nothing (its few settings are fixed below, chosen before measuring, and printed).

Per sample of ``/alfa/merged`` (20 Hz; a missing value is the last one seen, 0 before the
first), over the trailing window of ``--window`` seconds, three statistics of each of its 25
fields: the mean, the standard deviation and the change across the window. Per fold:

1. **Fit** on the other folds' flights an L2-regularised logistic regression (Newton's
   method on standardised features, the two classes weighted equally): samples before the
   onset and every sample of a no-failure flight are nominal (0), samples from the onset on
   are faulty (1).
2. **Threshold**, cross-fitted as imrosc's calibration sets its alarm rule: the other
   folds' flights are split again by session; each inner fold's flights are scored by a
   model fitted without them, and the threshold is the largest score any of them reached
   before its onset (with so few flights no conformal rank certifies a budget; the largest
   held-out value is the rule imrosc uses then too).
3. **Penalty**, chosen in the same inner folds from a fixed logarithmic grid: the one
   whose cross-fitted scores detect the most inner held-out fault flights (a score above
   the threshold at or after the onset; none before it, by the threshold's construction),
   the strongest penalty on ties. The fold's own flights play no part in any choice.
4. **Replay**: the model fitted on all the other folds with that penalty scores the fold's
   flights; an alarm is every sample whose score exceeds the threshold.

Scoring is :func:`efficacy.score`'s: detected when the first alarm is at or after the onset,
a false-alarm flight when one comes before it (or at all on a no-failure flight), delays over
the detected flights.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from efficacy import (
    ALFA,
    ALFA_DELAY,
    ALFA_FALSE,
    ALFA_RECALL,
    REFERENCE,
    Outcome,
    print_scores,
    score,
    session_folds,
    session_of,
)

from imrosc.bags import open_bag

TOPIC = "/alfa/merged"
PENALTIES = (1.0, 10.0, 100.0, 1e3, 1e4, 1e5)
"""The L2 penalties (on the standardised weights) the inner folds choose from."""
NEWTON_STEPS = 25
INNER_FOLDS = 4


@dataclass(frozen=True)
class Flight:
    name: str
    group: str
    onset: float | None
    """Seconds (bag clock)."""
    times: Any
    """Seconds (bag clock), one per sample."""
    features: Any
    """Samples x (3 statistics x fields)."""

    @property
    def faulty(self) -> Any:
        """Per sample: at or after the onset."""
        if self.onset is None:
            return np.zeros(len(self.times), dtype=bool)
        return self.times >= self.onset


def read(bag: Path) -> tuple[Any, Any]:
    """The samples of TOPIC: their times (s) and values (one column per numeric field)."""
    times: list[float] = []
    rows: list[list[float]] = []
    with open_bag(bag) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        for connection, stamp, raw in reader.messages(connections):
            message = reader.deserialize(raw, connection.msgtype)
            fields = [k for k in vars(message) if not k.startswith("_")]
            rows.append([float(getattr(message, k)) for k in fields])
            times.append(stamp / 1e9)
    return np.asarray(times), np.asarray(rows, dtype=np.float64)


def filled(values: Any) -> Any:
    """Each NaN replaced by the last value seen in its column (0 before the first)."""
    out = values.copy()
    for column in out.T:
        last = 0.0
        for i, v in enumerate(column):
            if math.isnan(v):
                column[i] = last
            else:
                last = v
    return out


def window_features(times: Any, values: Any, window: float) -> Any:
    """Mean, standard deviation and change over the trailing window, per sample."""
    x = filled(values)
    starts = np.searchsorted(times, times - window, side="right")
    ones = np.ones((1, x.shape[1]))
    total = np.vstack([0 * ones, np.cumsum(x, axis=0)])
    squares = np.vstack([0 * ones, np.cumsum(x * x, axis=0)])
    ends = np.arange(1, len(x) + 1)
    count = (ends - starts)[:, None].astype(np.float64)
    mean = (total[ends] - total[starts]) / count
    var = np.maximum((squares[ends] - squares[starts]) / count - mean * mean, 0.0)
    change = x - x[starts]
    return np.hstack([mean, np.sqrt(var), change])


def fit(flights: Sequence[Flight], strength: float) -> tuple[Any, Any, Any]:
    """Standardisation and weights of the logistic regression on ``flights`` with the L2
    penalty ``strength``."""
    x = np.vstack([f.features for f in flights])
    y = np.concatenate([f.faulty for f in flights]).astype(np.float64)
    center, scale = x.mean(axis=0), x.std(axis=0)
    scale[scale == 0] = 1.0
    z = np.hstack([(x - center) / scale, np.ones((len(x), 1))])
    positives = max(1.0, y.sum())
    weight = np.where(y > 0, len(y) / (2 * positives), len(y) / (2 * max(1.0, len(y) - positives)))
    w = np.zeros(z.shape[1])
    penalty = np.full(z.shape[1], strength)
    penalty[-1] = 0.0
    for _ in range(NEWTON_STEPS):
        p = 1 / (1 + np.exp(-np.clip(z @ w, -30, 30)))
        gradient = z.T @ (weight * (p - y)) + penalty * w
        hessian = (z * (weight * p * (1 - p))[:, None]).T @ z + np.diag(penalty + 1e-9)
        w -= np.linalg.solve(hessian, gradient)
    return center, scale, w


def scores(model: tuple[Any, Any, Any], flight: Flight) -> Any:
    center, scale, w = model
    return ((flight.features - center) / scale) @ w[:-1] + w[-1]


@dataclass(frozen=True)
class Choice:
    """A penalty, its cross-fitted threshold and the inner fault flights it detected."""

    strength: float
    limit: float
    detected: int


def choose(flights: Sequence[Flight]) -> Choice:
    """The penalty and threshold of :data:`PENALTIES` that the inner folds (by session)
    of ``flights`` choose (module docstring, steps 2 and 3)."""
    inner = session_folds([f.name for f in flights], INNER_FOLDS)
    best: Choice | None = None
    for strength in PENALTIES:
        held_scores: list[tuple[Flight, Any]] = []
        for held in inner:
            model = fit([f for f in flights if f.name not in held], strength)
            held_scores += [(f, scores(model, f)) for f in flights if f.name in held]
        limit = max(float(found[~f.faulty].max()) for f, found in held_scores if (~f.faulty).any())
        detected = sum(bool((found[f.faulty] > limit).any()) for f, found in held_scores)
        if best is None or detected >= best.detected:
            best = Choice(strength, limit, detected)
    assert best is not None
    return best


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--window", type=float, default=1.0, help="seconds (default 1.0)")
    args = parser.parse_args(argv)
    onsets: dict[str, dict[str, Any]] = json.loads((ALFA / "onsets.json").read_text())
    started = time.monotonic()
    flights: dict[str, Flight] = {}
    for name, info in sorted(onsets.items()):
        times, values = read(ALFA / name)
        onset = None if info["onset_ns"] is None else info["onset_ns"] / 1e9
        group = info["class"] if onset is not None else "no_failure"
        features = window_features(times, values, args.window)
        flights[name] = Flight(name, group, onset, times, features)
    print(f"read {len(flights)} flights in {time.monotonic() - started:.1f} s")
    print(
        f"settings: window {args.window} s, 3 statistics x {values.shape[1]} fields, "
        f"L2 penalty from {PENALTIES}, {NEWTON_STEPS} Newton steps, {INNER_FOLDS} inner folds"
    )
    print(f"reference to beat: {REFERENCE}")
    outcomes: list[Outcome] = []
    for index, held in enumerate(session_folds(onsets, args.folds)):
        training = [f for n, f in flights.items() if n not in held]
        chosen = choose(training)
        limit = chosen.limit
        model = fit(training, chosen.strength)
        for name in held:
            flight = flights[name]
            alarms = tuple(float(t) for t in flight.times[scores(model, flight) > limit])
            start = float(flight.times[0])
            outcomes.append(Outcome(name, flight.group, flight.onset, alarms, start=start))
        sessions = len({session_of(n) for n in held})
        print(
            f"fold {index}: {len(held)} flights of {sessions} sessions; penalty "
            f"{chosen.strength:g} (inner folds: {chosen.detected} of "
            f"{sum(f.onset is not None for f in training)} fault flights detected), "
            f"threshold {limit:.2f}"
        )
    print("\nflights (s from the bag's start):")
    for o in sorted(outcomes, key=lambda o: o.name):
        onset = "-" if o.onset is None else f"{o.onset - o.start:7.2f}"
        first = "-" if o.first is None else f"{o.first - o.start:7.2f}"
        delay = "-" if o.delay is None else f"{o.delay:5.2f}"
        verdict = "detected" if o.detected else ("false alarm" if o.false_alarm else "missed")
        if o.onset is None:
            verdict = "false alarm" if o.alarms else "quiet"
        short = Path(o.name).stem.removeprefix("carbonZ_")
        print(f"  {short:<58} {o.group:<10} onset {onset} first {first} delay {delay} {verdict}")
    groups: dict[str, list[Outcome]] = {}
    for o in outcomes:
        groups.setdefault(o.group, []).append(o)
    table = {g: {"reference": score(found)} for g, found in sorted(groups.items())}
    table["overall"] = {"reference": score(outcomes)}
    print("\nper class (precision: detected / flights with any alarm):")
    print_scores(table)
    total = table["overall"]["reference"]
    met = (
        total.recall >= ALFA_RECALL
        and total.false_rate <= ALFA_FALSE
        and total.mean_delay <= ALFA_DELAY
    )
    print(
        f"\nissue 17's ALFA target (recall >= {ALFA_RECALL}, false alarms <= {ALFA_FALSE:.0%}, "
        f"mean delay <= {ALFA_DELAY} s) by this reference: {'MET' if met else 'NOT MET'}; "
        f"detected minus false-alarm flights: {total.detected - total.false_alarms}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
