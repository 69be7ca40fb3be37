"""imrosc's detector learning on ALFA, fast, with variants of its features and evidence.

    python bench/alfa_detector.py [--features base] [--evidence mean] [--horizon S] [--folds 5]

``bench/efficacy.py --only alfa`` measures the classified monitor end to end (infer,
classify, replay: several minutes). Its ALFA monitors keep the learnt detector of point
``m`` (``/alfa/merged``) alone, so what decides their figures is :mod:`imrosc.detectors`.
This script runs that learning directly on the samples of ``/alfa/merged``, through the
same session folds and scoring, in about a minute, to say what a change to the detector
would do before it is built:

* per fold, the runs classification would see: the other folds' no-failure flights and
  their fault flights' parts before the onset as good runs, their fault flights whole
  with the onset as failed runs;
* :func:`imrosc.detectors.choose` (penalty, smoothing, cross-fitted threshold at the
  budget 0.05 of one point) and :func:`imrosc.detectors.fit` on all of them;
* each held-out flight's evidence (:func:`imrosc.runtime.detector.evidence`) against the
  threshold: the first sample above it is the alarm.

With ``--features base`` and ``--evidence mean`` it is the product's detector (its
statistics from :func:`imrosc.runtime.detector.features`); the figures are close to the
bench's, not identical (the bench's variables are the point's as inferred, and its
replay runs the alarm engine). The variants, each a question about the score:

* ``--features``: ``base`` (mean, standard deviation and change over 1 s), ``mean`` and
  ``mean+change`` (fewer statistics), ``windows:A,B,...`` (the three statistics over each
  window), ``slope`` (the least-squares slope over the window added), ``residual`` (the
  mean and standard deviation over the window of each variable's one-step prediction error
  from the others and the previous sample, a ridge regression fitted on the fold's nominal
  samples);
* ``--evidence cusum``: Page's CUSUM of the score in log-odds seconds,
  ``S = max(0, S + (score - k) dt)``, the drift ``k`` from 0, 1, 2, 4 chosen by the
  cross-fitting in place of the smoothing;
* ``--horizon S``: the fit labels as faulty only the first ``S`` seconds after each onset
  and leaves the later samples out (the threshold and the choice still see every sample);
* ``--features interactions``: the base statistics and the products of every pair (squares
  included) of the variables' 1 s means, standardised by the fold's nominal samples (a
  quadratic score: "descending while the altitude error grows");
* ``--features relations``: the base statistics and each variable's 1 s mean less its ridge
  prediction from the other variables' 1 s means (fitted on the fold's nominal samples, in
  units of its nominal spread): the cross-variable relations good flights keep;
* ``--features squash``: the base statistics, each through ``asinh`` of its deviation from
  its nominal median in units of its nominal median absolute deviation (heavy tails tamed);
* ``--evidence probability``: the trailing mean of the probability ``1 / (1 + e^-score)`` in
  place of the log-odds (a good flight's odd moment then adds at most 1 per sample);
* ``--final average``: the detector applied to the held-out flights is the mean of the
  cross-fitting's fold models of the chosen penalty (the models whose held-out scores set
  the threshold), not a model fitted again on every run;
* ``--offsets=D,D,...``: a diagnosis, not a detector: the figures again with every fold's
  threshold moved by each ``D`` (log-odds), to say what the threshold's level costs;
* ``--fit-samples N``: fit the regressions on at most ``N`` samples (the product's
  :data:`imrosc.detectors.FIT_SAMPLES` otherwise; the quadratic features need fewer);
* ``--inner-folds K``: the cross-fitting's blocked folds (the product's
  :data:`imrosc.detectors.FOLDS` otherwise): more folds fit each held-out score on more of
  the runs, closer to the detector fitted on all of them;
* ``--nominal-copies once``: a fault flight's part before its onset is not also a good run
  of its own (``twice``, the default, is what ``bench/efficacy.py`` gives classification:
  the pre-onset copies are <success> runs beside the whole flights);
* ``--features A|B|...``: alternatives, each fold's the one whose cross-fitted choice ranks
  best (:meth:`imrosc.detectors.Choice.rank`: held-out detections, then mean delay), from
  the fold's training flights alone;
* ``--features rls:LAGS,FORGET[,alone]``: Keipour et al.'s online adaptation without their
  physical model (:class:`Adapted`): per flight, recursive least squares with the
  forgetting factor ``FORGET`` of every field on the ``LAGS`` previous samples of all
  fields, started from the fold's nominal fit; the 1 s mean and standard deviation of each
  field's innovation over its own running spread, and of the parameters' change, beside
  the base statistics (or ``alone``);
* ``--features keipour:LAGS,FORGET[,alone]``: Keipour et al.'s model of the commanded
  response (:class:`Commanded`): per flight, the measured roll, pitch (from the orientation,
  :func:`tracked`) and ground speed each as an ARX model of its own and its command's
  values at its ``LAGS`` previous updates (the command is the measured value plus
  ``delta_roll``, ``delta_pitch`` or ``aspd_error``: :func:`commanded_signals`), tracked by
  recursive least squares with the forgetting ``FORGET`` per 20 Hz sample, started from the
  fold's nominal fit; the 1 s mean and standard deviation of each innovation over its running
  spread, and of its parameters' change, beside the base statistics (or ``alone``);
* ``--responses LAGS,FORGET[,AFTER]``: no detector, a diagnosis: per fault flight, the largest
  1 s mean square of each of those innovations (models fitted without the flight's fold) in
  the ``AFTER`` seconds (3) from its onset, against its own largest before it and the largest
  any other session's flight reached while nominal (:func:`diagnose`);
* ``--evidence relative:S``: each score less the flight's own exponential running mean of
  its earlier scores over ``S`` seconds, then smoothed as the product smooths (a flight's
  standing regime absorbed, a rise shorter than ``S`` not);
* ``--model gbm1`` / ``gbm2``: a gradient-boosted sum of depth-1 / depth-2 trees on the
  statistics (:func:`boost`: logistic loss, Newton leaves, 32 quantile thresholds per
  statistic, shrinkage 0.1), the number of trees from ``--trees`` chosen by the
  cross-fitting in place of the penalty: comparisons, so that a large spread alone can be
  nominal while a shifted mean is a fault;
* ``--model mil:H[,T]``: the same linear score fitted for the run-level rule it is judged by
  (:class:`Pooled`, multiple-instance): each good run and each fault flight's part before
  its onset a negative bag, each fault flight's first ``H`` seconds from its onset a
  positive bag, a bag's score the smooth maximum ``T log sum exp(m / T)`` (``T`` 1 log-odds
  unless given) of its trailing 1 s mean scores ``m``; the bags' softplus loss, the classes
  weighed equally, plus the L2 penalty the cross-fitting chooses, by L-BFGS from
  :func:`imrosc.detectors.fit`'s solution;
* ``--model mil:H,T,anchored``: the penalty on the weights' distance from ``fit``'s
  solution, not from 0 (the cross-fitting chooses how far the bags may move it);
* ``--model hardneg:R[,Q]``: :func:`imrosc.detectors.fit`, then ``R`` refits in which each
  nominal stretch's top ``Q`` seconds of 1 s mean score (its odd moments: what sets the
  threshold) and each fault's first ``Q`` seconds after its onset hold half their class's
  weight (:class:`Hardened`);
* ``--model A|B|...``: alternatives, each fold's the one whose cross-fitted choice ranks best
  (as ``--features A|B``);
* ``--margins S,S,...``: beside the figures, per fault flight its largest evidence in the
  ``S`` seconds from its onset less its fold's threshold (above 0: detected by then), and per
  class their median;
* ``--features energy[:NAMES]``: fields of the total energy balance (what a fixed-wing
  autopilot's throttle controls) derived from the recorded ones beside them
  (:func:`energy_fields`: the energy the autopilot lacks, the specific power along the body
  axis, the kinetic energy, the inertial rate of the total energy), or those ``NAMES`` only;
  ``--features scan:NAME[:WINDOW[:BASELINE]]``: ``--scan``'s signal as one more field;
* ``--scan NAME[:WINDOW[:BASELINE]]``: no detector, one signal (:func:`scan_signal`: the trailing
  ``WINDOW``-second mean of an energy rate, less its mean over the ``BASELINE`` seconds before)
  against the largest value the fold's training flights reached while nominal
  (:func:`scan`): does it separate a fault's first seconds from every good stretch of the
  other sessions.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))

# the bench's sibling scripts, as they import each other (mypy checks bench/ through tests/
# only, without this directory on its path)
from alfa_reference import filled, read  # type: ignore[import-not-found]
from efficacy import (  # type: ignore[import-not-found]
    ALFA,
    REFERENCE,
    Outcome,
    print_scores,
    score,
    session_folds,
    session_of,
)

from imrosc import detectors
from imrosc.runtime.detector import evidence, features

Features = Callable[[Any, Any], Any]
"""A flight's statistics from its sample times and values (one row per sample)."""
CUSUM_DRIFTS = (0.0, 1.0, 2.0, 4.0)
"""Log-odds the CUSUM's drift is chosen from (``--evidence cusum``)."""
RIDGE = 1e-3
"""The residual model's ridge, per sample, on standardised inputs."""
FINALS = ("refit", "average")
"""How the detector applied to the held-out flights is made (``--final``)."""


def window_stats(times: Any, values: Any, window: float, slope: bool = False) -> Any:
    """Mean, standard deviation and change over the trailing ``window`` seconds of each
    column (the samples later than ``t - window``, as the runtime holds them), and with
    ``slope`` the least-squares slope over the window."""
    starts = np.searchsorted(times, times - window, side="right")
    zero = np.zeros((1, values.shape[1]))
    ends = np.arange(1, len(values) + 1)
    count = (ends - starts)[:, None].astype(np.float64)
    total = np.vstack([zero, np.cumsum(values, axis=0)])
    squares = np.vstack([zero, np.cumsum(values * values, axis=0)])
    mean = (total[ends] - total[starts]) / count
    var = np.maximum((squares[ends] - squares[starts]) / count - mean * mean, 0.0)
    found = [mean, np.sqrt(var), values - values[starts]]
    if slope:
        at = times - times[0]
        t1 = np.concatenate(([0.0], np.cumsum(at)))
        t2 = np.concatenate(([0.0], np.cumsum(at * at)))
        xt = np.vstack([zero, np.cumsum(values * at[:, None], axis=0)])
        mean_t = (t1[ends] - t1[starts]) / count[:, 0]
        var_t = (t2[ends] - t2[starts]) / count[:, 0] - mean_t * mean_t
        cov = (xt[ends] - xt[starts]) / count - mean * mean_t[:, None]
        steady = var_t[:, None] > 1e-9
        found.append(np.where(steady, cov / np.maximum(var_t, 1e-9)[:, None], 0.0))
    return np.hstack(found)


def cusum(times: Any, scores: Any, window: float, drift: float) -> Any:
    """Page's CUSUM of the scores in log-odds seconds, NaN before the samples span
    ``window`` (as :func:`imrosc.runtime.detector.evidence` has it)."""
    at = np.asarray(times, dtype=np.float64)
    values = np.nan_to_num(np.asarray(scores, dtype=np.float64))
    found = np.full(len(values), math.nan)
    spanning = at - at[0] >= window if len(at) else np.zeros(0, dtype=bool)
    if not spanning.any():
        return found
    first = int(np.argmax(spanning))
    total = 0.0
    for k in range(first, len(values)):
        step = at[k] - at[k - 1] if k > first else 0.0
        total = max(0.0, total + (values[k] - drift) * step)
        found[k] = total
    return found


class Residuals:
    """Each variable's one-step prediction error: a ridge regression of its value on the
    previous sample of every variable and the current values of the others, fitted on
    nominal samples."""

    def __init__(self, nominal: Sequence[Any]) -> None:
        pairs = np.vstack([self.inputs(x) for x in nominal])
        self.center, self.scale = pairs.mean(axis=0), pairs.std(axis=0)
        self.scale[self.scale == 0] = 1.0
        z = (pairs - self.center) / self.scale
        width = nominal[0].shape[1]
        self.models: list[tuple[list[int], Any]] = []
        for j in range(width):
            others = [c for c in range(2 * width) if c != width + j]
            x = np.hstack([z[:, others], np.ones((len(z), 1))])
            gram = x.T @ x + RIDGE * len(x) * np.eye(x.shape[1])
            self.models.append((others, np.linalg.solve(gram, x.T @ pairs[:, width + j])))

    @staticmethod
    def inputs(values: Any) -> Any:
        """Per sample: the previous sample (the first's own), then the sample."""
        return np.hstack([np.vstack([values[:1], values[:-1]]), values])

    def of(self, values: Any) -> Any:
        z = (self.inputs(values) - self.center) / self.scale
        found = np.empty_like(values)
        for j, (others, w) in enumerate(self.models):
            found[:, j] = values[:, j] - (z[:, others] @ w[:-1] + w[-1])
        return found


class Relations:
    """Each variable's deviation from what the others say it is: a ridge regression of its
    (standardised) value on the other variables' values, fitted on nominal rows; the
    residual in units of its nominal spread."""

    def __init__(self, nominal: Any) -> None:
        self.center, self.scale = spread(nominal)
        z = (nominal - self.center) / self.scale
        width = z.shape[1]
        self.models: list[tuple[list[int], Any]] = []
        for j in range(width):
            others = [c for c in range(width) if c != j]
            x = np.hstack([z[:, others], np.ones((len(z), 1))])
            gram = x.T @ x + RIDGE * len(x) * np.eye(x.shape[1])
            self.models.append((others, np.linalg.solve(gram, x.T @ z[:, j])))
        _, self.spread = spread(self.raw(nominal))

    def raw(self, values: Any) -> Any:
        z = (values - self.center) / self.scale
        found = np.empty_like(z)
        for j, (others, w) in enumerate(self.models):
            found[:, j] = z[:, j] - (z[:, others] @ w[:-1] + w[-1])
        return found

    def of(self, values: Any) -> Any:
        return self.raw(values) / self.spread


def spread(rows: Any) -> tuple[Any, Any]:
    """The columns' means and standard deviations (1 where a column is constant)."""
    center, scale = rows.mean(axis=0), rows.std(axis=0)
    scale[scale == 0] = 1.0
    return center, scale


def products(z: Any) -> Any:
    """The products of every pair of columns of ``z``, squares included (``i <= j``)."""
    i, j = np.triu_indices(z.shape[1])
    return z[:, i] * z[:, j]


def squashed(rows: Any, nominal: Any) -> Any:
    """``asinh`` of each column's deviation from its nominal median in units of its nominal
    median absolute deviation (the mean absolute one where that is 0; 1 where both are)."""
    median = np.median(nominal, axis=0)
    deviation = np.abs(nominal - median)
    unit = np.median(deviation, axis=0)
    fallback = deviation.mean(axis=0)
    unit = np.where(unit > 0, unit, np.where(fallback > 0, fallback, 1.0))
    return np.arcsinh((rows - median) / unit)


def probability(times: Any, scores: Any, window: float, smooth: float) -> Any:
    """The trailing mean of the probability of the scores, as
    :func:`imrosc.runtime.detector.evidence` means the log-odds."""
    odds = np.clip(np.nan_to_num(np.asarray(scores, dtype=np.float64)), -30.0, 30.0)
    return evidence(times, 1.0 / (1.0 + np.exp(-odds)), window, smooth)


def relative(memory: float) -> Callable[[Any, Any, float, float], Any]:
    """Evidence of each score less the flight's own running mean of its earlier scores
    (exponential, ``memory`` seconds): a flight's standing regime, its trim or a lasting
    oscillation, is absorbed; a rise that lasts less than ``memory`` is not."""

    def weigh(times: Any, scores: Any, window: float, smooth: float) -> Any:
        at = np.asarray(times, dtype=np.float64)
        values = np.clip(np.nan_to_num(np.asarray(scores, dtype=np.float64)), -30.0, 30.0)
        found = np.zeros(len(values))
        spanning = at - at[0] >= window if len(at) else np.zeros(0, dtype=bool)
        if spanning.any():
            first = int(np.argmax(spanning))
            tail = values[first:]
            # the samples are 20 Hz: one forgetting factor per sample of the median step
            step = float(np.median(np.diff(at))) if len(at) > 1 else 0.05
            keep = math.exp(-step / memory)
            level, _ = lfilter([1.0 - keep], [1.0, -keep], tail[:-1], zi=[keep * tail[0]])
            found[first:] = tail - np.concatenate(([tail[0]], level))
        return evidence(times, found, window, smooth)

    return weigh


class Linear:
    """A detector's score as one linear function of the statistics (what the runtime's
    standardised weights amount to)."""

    def __init__(self, weights: Any, bias: float) -> None:
        self.weights, self.bias = weights, bias

    @classmethod
    def mean_of(cls, models: Sequence[Any]) -> Linear:
        """The mean of fitted :class:`imrosc.detectors.Model`s' scores, itself linear."""
        slopes = [m.weights[:-1] / m.scale for m in models]
        biases = [float(m.weights[-1] - s @ m.center) for m, s in zip(models, slopes, strict=True)]
        return cls(np.mean(slopes, axis=0), float(np.mean(biases)))

    def scores(self, run: Any) -> Any:
        return run.stats @ self.weights + self.bias


class Recorded:
    """:func:`imrosc.detectors.fit`, keeping the models of the latest cross-fitting per
    penalty (``--final average``): :func:`imrosc.detectors.choose` fits the folds of each
    penalty in turn."""

    def __init__(self, fit: Callable[..., Any]) -> None:
        self.fit = fit
        self.models: dict[float, list[Any]] = {}

    def __call__(self, runs: Sequence[Any], strength: float) -> Any:
        model = self.fit(runs, strength)
        self.models.setdefault(strength, []).append(model)
        return model

    def forget(self) -> None:
        self.models.clear()


class Adapted:
    """Per flight, recursive least squares with forgetting (Keipour et al.'s idea without
    their physical model): every field, standardised by the fold's nominal samples, as an
    ARX model of the ``lags`` previous samples of all fields, its parameters adapted at each
    sample with the forgetting factor ``forget``. A flight starts from the fleet's model
    (a ridge regression on the fold's nominal samples) with the information of one
    forgetting horizon of them (``1 / (1 - forget)`` samples), so that its first seconds
    are not a transient; its own trim and oscillations are then absorbed, while a sudden
    change of dynamics shows as innovations (the a-priori one-step errors) large against
    their own running spread (the same forgetting) before the parameters follow.
    Per sample: each field's innovation over its running spread, and the size of the
    parameters' change (in standardised units)."""

    def __init__(self, nominal: Sequence[Any], lags: int, forget: float) -> None:
        self.lags, self.forget = lags, forget
        stacked = np.vstack(nominal)
        self.center, self.scale = spread(stacked)
        inputs, outputs = [], []
        for x in nominal:
            phi, y = self.pairs((x - self.center) / self.scale)
            inputs.append(phi)
            outputs.append(y)
        phi, y = np.vstack(inputs), np.vstack(outputs)
        count = len(phi)
        gram = phi.T @ phi / count + RIDGE * np.eye(phi.shape[1])
        self.theta = np.linalg.solve(gram, phi.T @ y / count)
        memory = 1.0 / (1.0 - forget)
        self.p0 = np.linalg.inv(gram) / memory
        self.variance = np.maximum(((y - phi @ self.theta) ** 2).mean(axis=0), 1e-6)

    def pairs(self, z: Any) -> tuple[Any, Any]:
        """The regressors (the ``lags`` previous samples, then 1) and outputs of ``z``."""
        n = len(z)
        padded = np.vstack([np.repeat(z[:1], self.lags, axis=0), z])
        lagged = [padded[self.lags - k : self.lags - k + n] for k in range(1, self.lags + 1)]
        return np.hstack([*lagged, np.ones((n, 1))]), z

    def of(self, values: Any) -> Any:
        phi, y = self.pairs((values - self.center) / self.scale)
        theta, p = self.theta.copy(), self.p0.copy()
        variance = self.variance.copy()
        bound = float(np.trace(self.p0))
        lam = self.forget
        found = np.empty((len(y), y.shape[1] + 1))
        for k in range(len(y)):
            error, step, p = rls_update(theta, p, phi[k], y[k], lam, bound)
            found[k, :-1] = error / np.sqrt(variance)
            found[k, -1] = math.sqrt(float((step * step).sum()))
            variance = lam * variance + (1.0 - lam) * error * error
        return found


def rls_update(
    theta: Any, p: Any, f: Any, y: Any, lam: float, bound: float
) -> tuple[Any, Any, Any]:
    """One step of recursive least squares with forgetting ``lam``: ``theta`` (parameters,
    one column per output, or a vector for one output) moves in place towards explaining
    ``y`` from the regressors ``f``; ``p`` is the inverse information, its trace held
    within ``bound`` (no wind-up while a flight does not excite every direction). Returns
    the prediction error, the parameters' step and the new ``p``."""
    pf = p @ f
    gain = pf / (lam + f @ pf)
    error = y - f @ theta
    step = np.multiply.outer(gain, error)
    theta += step
    p = (p - np.outer(gain, pf)) / lam
    trace = float(np.trace(p))
    if trace > bound:
        p *= bound / trace
    return error, step, p


class Commanded:
    """Keipour et al.'s model of how a measured response follows its command, per flight: for
    each output (its values standardised by the fold's nominal samples), an ARX model of its
    value at each of its updates on its own values and its command's at the ``lags``
    previous updates, tracked by recursive least squares with forgetting. ``forget`` is per
    ``step`` seconds (a 20 Hz sample of ``/alfa/merged``), so that an update ``dt`` after the
    previous one forgets ``forget ** (dt / step)``: the memory is ``step / (1 - forget)``
    seconds whatever the output's update rate. A flight starts from the fleet's model (a
    ridge regression on the fold's nominal samples) with the information of one memory of
    them, as :class:`Adapted`. Per sample, each output's latest innovation (its a-priori
    one-step error) over its running spread (the same forgetting), then the size of its
    parameters' latest change, both held between the output's updates."""

    def __init__(
        self, nominal: Sequence[tuple[Any, Any, Any, Any]], lags: int, forget: float
    ) -> None:
        """``nominal``: per flight its sample times, outputs and commands (a column per
        output) and where each output updates (booleans, the same shape)."""
        self.lags, self.forget = lags, forget
        self.step = float(np.median(np.concatenate([np.diff(t) for t, *_ in nominal])))
        self.center, self.scale = spread(np.vstack([y for _, y, _, _ in nominal]))
        self.command_center, self.command_scale = spread(np.vstack([u for _, _, u, _ in nominal]))
        width = nominal[0][1].shape[1]
        self.theta: list[Any] = []
        self.p0: list[Any] = []
        self.variance: list[float] = []
        for j in range(width):
            pairs = [self.pairs(t, y, u, w, j) for t, y, u, w in nominal]
            phi = np.vstack([f for f, *_ in pairs])
            y = np.concatenate([o for _, o, *_ in pairs])
            count = len(phi)
            gram = phi.T @ phi / count + RIDGE * np.eye(phi.shape[1])
            theta = np.linalg.solve(gram, phi.T @ y / count)
            # one memory of the nominal updates: its seconds times their rate
            seconds = sum(float(t[-1] - t[0]) for t, *_ in nominal)
            memory = count / max(seconds, self.step) * self.step / (1.0 - forget)
            self.theta.append(theta)
            self.p0.append(np.linalg.inv(gram) / max(memory, 1.0))
            self.variance.append(max(float(((y - phi @ theta) ** 2).mean()), 1e-6))

    def pairs(self, times: Any, outputs: Any, commands: Any, updates: Any, j: int) -> Any:
        """Output ``j``'s regressors (its ``lags`` previous updates' values, then its
        command's at them, then 1), outputs and the gaps since the previous updates (s),
        one row per update after the first ``lags``."""
        at = np.flatnonzero(updates[:, j])
        y = (outputs[at, j] - self.center[j]) / self.scale[j]
        u = (commands[at, j] - self.command_center[j]) / self.command_scale[j]
        n = len(at) - self.lags
        if n <= 0:
            return np.zeros((0, 2 * self.lags + 1)), np.zeros(0), np.zeros(0), at[:0]
        lagged = [y[self.lags - k : self.lags - k + n] for k in range(1, self.lags + 1)]
        commanded = [u[self.lags - k : self.lags - k + n] for k in range(1, self.lags + 1)]
        phi = np.column_stack([*lagged, *commanded, np.ones(n)])
        gaps = times[at[self.lags :]] - times[at[self.lags - 1 : -1]]
        return phi, y[self.lags :], gaps, at[self.lags :]

    def response(self, j: int) -> tuple[Any, Any]:
        """Output ``j``'s fleet model in the signals' own units: the coefficients of its
        previous values, then of its command's."""
        theta = self.theta[j]
        own = theta[: self.lags]
        gain = self.scale[j] / self.command_scale[j]
        return own, theta[self.lags : 2 * self.lags] * gain

    def of(self, times: Any, outputs: Any, commands: Any, updates: Any) -> Any:
        width = outputs.shape[1]
        found = np.zeros((len(times), 2 * width))
        for j in range(width):
            phi, y, gaps, at = self.pairs(times, outputs, commands, updates, j)
            theta, p = self.theta[j].copy(), self.p0[j].copy()
            variance = self.variance[j]
            bound = float(np.trace(p))
            rows = np.zeros((len(y), 2))
            for k in range(len(y)):
                lam = self.forget ** (max(float(gaps[k]), 0.0) / self.step)
                error, step, p = rls_update(theta, p, phi[k], y[k], lam, bound)
                rows[k, 0] = error / math.sqrt(variance)
                rows[k, 1] = math.sqrt(float(step @ step))
                variance = lam * variance + (1.0 - lam) * error * error
            # held from each update to the next
            latest = np.searchsorted(at, np.arange(len(times)), side="right") - 1
            seen = latest >= 0
            found[seen, j] = rows[latest[seen], 0]
            found[seen, width + j] = rows[latest[seen], 1]
        return found


COMMANDED = (
    (("orientation_x", "orientation_y", "orientation_z"), "delta_roll"),
    (("orientation_x", "orientation_y", "orientation_z"), "delta_pitch"),
    (("twist_linear_x", "twist_linear_y", "twist_linear_z"), "aspd_error"),
)
"""The responses ``--features keipour`` models: the fields a measured value is computed
from (an update is a sample where one of them changed) and the field that gives its
command less it."""


def commanded_signals(values: Any) -> tuple[Any, Any, Any]:
    """Per sample the measured roll and pitch (degrees, right wing down and nose up
    positive, from the orientation of :func:`tracked`) and speed (m/s, the ground speed of
    ``twist_linear_*``: the message holds no airspeed), their commands (the measured value
    plus ``delta_roll``, ``delta_pitch`` in degrees and ``aspd_error`` in cm/s: each is the
    command less the measured value, the signs and units under which the measured value
    follows its command with a stable response of gain near 1 on the ALFA flights), and
    where each measured value updates."""
    x = filled(values)
    at = {k: x[:, MERGED.index(k)] for k in MERGED}
    velocity = np.column_stack([at[f"twist_linear_{a}"] for a in "xyz"])
    r = tracked(at, velocity)
    roll = np.degrees(np.arctan2(r[:, 2, 1], r[:, 2, 2]))
    pitch = np.degrees(np.arcsin(np.clip(r[:, 2, 0], -1.0, 1.0)))
    speed = np.sqrt((velocity * velocity).sum(axis=1))
    outputs = np.column_stack([roll, pitch, speed])
    commands = outputs + np.column_stack(
        [at["delta_roll"], at["delta_pitch"], at["aspd_error"] / 100.0]
    )
    updates = np.zeros(outputs.shape, dtype=bool)
    for j, (sources, _) in enumerate(COMMANDED):
        changed = np.zeros(len(x), dtype=bool)
        for name in sources:
            changed[1:] |= np.diff(at[name]) != 0
        updates[:, j] = changed
    return outputs, commands, updates


BINS = 32
"""Candidate thresholds per statistic of a tree's split (its nominal-and-faulty quantiles)."""
SHRINK = 0.1
"""Each tree's leaves are shrunk by this much (boosting's learning rate)."""
LEAF_PENALTY = 1.0
"""The L2 penalty on a leaf's value, in units of the samples' (weighted) curvature."""


def best_split(bins: Any, g: Any, h: Any, rows: Any, width: int) -> tuple[float, int, int]:
    """The gain, statistic and bin of the best split of ``rows`` (Newton's gain)."""
    sub = bins[rows]
    offsets = sub + (np.arange(width) * BINS)[None, :]
    gh = np.bincount(offsets.ravel(), np.repeat(g[rows], width), width * BINS).reshape(width, BINS)
    hh = np.bincount(offsets.ravel(), np.repeat(h[rows], width), width * BINS).reshape(width, BINS)
    gl, hl = np.cumsum(gh, axis=1)[:, :-1], np.cumsum(hh, axis=1)[:, :-1]
    gt, ht = gh.sum(axis=1, keepdims=True), hh.sum(axis=1, keepdims=True)
    gr, hr = gt - gl, ht - hl
    reg = LEAF_PENALTY
    gain = gl**2 / (hl + reg) + gr**2 / (hr + reg) - gt**2 / (ht + reg)
    gain[(hl <= 0) | (hr <= 0)] = -np.inf
    f, b = np.unravel_index(int(np.argmax(gain)), gain.shape)
    return float(gain[f, b]), int(f), int(b)


def leaf(g: Any, h: Any, rows: Any) -> float:
    return float(-SHRINK * g[rows].sum() / (h[rows].sum() + LEAF_PENALTY))


class Tree:
    """A depth-2 tree: ``x[feature] <= at`` then each side's own comparison."""

    def __init__(self, feature: int, at: float, sides: list[tuple[int, float, float, float]]):
        self.feature, self.at, self.sides = feature, at, sides

    def __call__(self, x: Any) -> Any:
        low = x[:, self.feature] <= self.at
        out = np.empty(len(x))
        for mask, (f, t, a, b) in ((low, self.sides[0]), (~low, self.sides[1])):
            out[mask] = np.where(x[mask, f] <= t, a, b)
        return out


class Forest:
    def __init__(self, trees: list[Any], rounds: int, bias: float) -> None:
        self.trees, self.rounds, self.bias = trees, rounds, bias

    def scores(self, run: Any) -> Any:
        x = np.nan_to_num(run.stats)
        total = np.full(len(x), self.bias)
        for tree in self.trees[: self.rounds]:
            total += tree(x)
        return total


def boost(runs: Sequence[Any], rounds: int, depth: int) -> Forest:
    """:class:`Forest` of ``rounds`` trees of ``depth`` 1 or 2 fitted on ``runs`` (at most
    :data:`imrosc.detectors.FIT_SAMPLES` samples, thinned evenly)."""
    total = sum(int(r.scored.sum()) for r in runs)
    every = max(1, -(-total // detectors.FIT_SAMPLES))
    x = np.nan_to_num(np.vstack([r.stats[r.scored][::every] for r in runs]))
    y = np.concatenate([r.faulty[r.scored][::every] for r in runs]).astype(np.float64)
    positives = max(1.0, float(y.sum()))
    negatives = max(1.0, len(y) - positives)
    weight = np.where(y > 0, len(y) / (2 * positives), len(y) / (2 * negatives))
    weight /= weight.mean()
    width = x.shape[1]
    edges = np.quantile(x, np.linspace(0, 1, BINS + 1)[1:-1], axis=0).T  # width x (BINS-1)
    bins = np.empty(x.shape, dtype=np.int64)
    for j in range(width):
        bins[:, j] = np.searchsorted(edges[j], x[:, j], side="left")
    cut = np.hstack([edges, np.full((width, 1), np.inf)])  # bin b: x <= cut[j, b]
    score = np.zeros(len(y))
    trees: list[Any] = []
    everything = np.arange(len(y))
    for _ in range(rounds):
        p = 1 / (1 + np.exp(-np.clip(score, -30, 30)))
        g, h = weight * (p - y), weight * p * (1 - p)
        _, f, b = best_split(bins, g, h, everything, width)
        low = bins[:, f] <= b
        sides = []
        for rows in (np.flatnonzero(low), np.flatnonzero(~low)):
            if depth >= 2 and len(rows) > 1:
                gain, f2, b2 = best_split(bins, g, h, rows, width)
            else:
                gain, f2, b2 = -np.inf, 0, BINS - 1
            if not np.isfinite(gain):
                f2, b2 = 0, BINS - 1
            below = rows[bins[rows, f2] <= b2]
            above = rows[bins[rows, f2] > b2]
            sides.append(
                (
                    f2,
                    float(cut[f2, b2]),
                    leaf(g, h, below) if len(below) else 0.0,
                    leaf(g, h, above) if len(above) else 0.0,
                )
            )
        tree = Tree(f, float(cut[f, b]), sides)
        trees.append(tree)
        score += tree(x)
    return Forest(trees, rounds, 0.0)


class Boosting:
    """``detectors.fit`` for ``--model gbm``: the penalty grid is the number of trees,
    negated (:func:`imrosc.detectors.choose` breaks ties towards the larger penalty: here the
    fewer trees); the trees of one training set are fitted once, for the most, and cut for
    fewer."""

    def __init__(self, depth: int) -> None:
        self.depth = depth
        self.fitted: dict[tuple[str, ...], Forest] = {}

    def __call__(self, runs: Sequence[Any], strength: float) -> Any:
        key = tuple(sorted(r.name for r in runs))
        if key not in self.fitted:
            self.fitted[key] = boost(runs, int(-min(detectors.PENALTIES)), self.depth)
        full = self.fitted[key]
        return Forest(full.trees, int(-strength), full.bias)


LOGISTIC = detectors.fit
"""The product's fit, as imported (the variants below start from it, whatever
``detectors.fit`` is replaced by)."""
POOL = 1.0
"""Seconds of the trailing mean of the scores the bags pool (``--model mil``)."""
POOL_SAMPLES = 50_000
"""The most pooled means a ``--model mil`` fit weighs (the 1 s means change little between
neighbouring samples: a long run's are thinned evenly; a failed run's first seconds never)."""
MIL_STEPS = 300
"""L-BFGS iterations at most (``--model mil``)."""


def trailing_means(times: Any, rows: Any, seconds: float) -> tuple[Any, Any]:
    """The trailing ``seconds`` mean of each column of ``rows`` (the rows later than
    ``t - seconds``, as :func:`imrosc.runtime.detector.evidence` means the scores) and
    whether the rows so far span ``seconds`` (only those means are evidence)."""
    at = np.asarray(times, dtype=np.float64)
    starts = np.searchsorted(at, at - seconds, side="right")
    ends = np.arange(1, len(at) + 1)
    sums = np.vstack([np.zeros((1, rows.shape[1])), np.cumsum(rows, axis=0)])
    means = (sums[ends] - sums[starts]) / (ends - starts)[:, None]
    spans = at - at[0] >= seconds if len(at) else np.zeros(0, dtype=bool)
    return means, spans


class Bags:
    """A training set's runs as bags of the trailing :data:`POOL` s means of their
    standardised statistics (a column of ones last, the bias's): each good run and each
    failed run's part before its onset a negative bag, each failed run's first ``horizon``
    seconds from its onset a positive bag. The score's mean over a window is linear in the
    weights, so a bag's pooled score is a smooth maximum of ``rows @ w``."""

    def __init__(self, runs: Sequence[Any], center: Any, scale: Any, horizon: float) -> None:
        parts: list[tuple[Any, bool]] = []
        for r in runs:
            keep = r.scored
            times = r.times[keep]
            if not len(times):
                continue
            z = np.nan_to_num((r.stats[keep] - center) / scale, posinf=0.0, neginf=0.0)
            z = np.hstack([z, np.ones((len(z), 1))])
            means, spans = trailing_means(times, z, POOL)
            faulty = r.faulty[keep]
            since = times - r.start - (r.onset if r.onset is not None else math.inf)
            parts.append((means[spans & ~faulty], False))
            parts.append((means[spans & faulty & (since < horizon)], True))
        parts = [(m, positive) for m, positive in parts if len(m)]
        self.samples = sum(len(m) for m, _ in parts)
        """The pooled means before the thinning (what the penalty is weighed against)."""
        every = max(1, -(-self.samples // POOL_SAMPLES))
        rows = [m if positive else m[::every] for m, positive in parts]
        self.rows = np.vstack(rows) if rows else np.zeros((0, len(center) + 1))
        self.starts = np.cumsum([0] + [len(m) for m in rows[:-1]]).astype(np.int64)
        self.positive = np.array([positive for _, positive in parts], dtype=bool)
        self.bag = np.repeat(np.arange(len(rows)), [len(m) for m in rows])

    def pooled(self, w: Any, temperature: float) -> tuple[Any, Any]:
        """Each bag's smooth maximum ``T log sum exp(s / T)`` of its scores ``s``, and each
        row's weight in it (the softmax: the pooled score's gradient is their mean row)."""
        s = self.rows @ w / temperature
        top = np.maximum.reduceat(s, self.starts)
        e = np.exp(s - top[self.bag])
        total = np.add.reduceat(e, self.starts)
        return temperature * (top + np.log(total)), e / total[self.bag]


def mil_loss(
    w: Any, bags: Bags, temperature: float, penalty: float, anchor: Any = None
) -> tuple[float, Any]:
    """The bags' softplus loss, summed with the two classes weighed equally (each class
    as much as half the bags, as :func:`imrosc.detectors.fit` weighs its samples), plus
    ``penalty / 2`` times the squared weights' distance from ``anchor`` (from 0 without
    one; the bias unpenalised), and its gradient."""
    pooled, share = bags.pooled(w, temperature)
    sign = np.where(bags.positive, -1.0, 1.0)
    positives = max(1, int(bags.positive.sum()))
    negatives = max(1, len(pooled) - positives)
    weight = np.where(bags.positive, 0.5 / positives, 0.5 / negatives) * len(pooled)
    margin = sign * pooled
    loss = float(weight @ np.logaddexp(0.0, margin))
    slope = weight * sign / (1.0 + np.exp(-np.clip(margin, -30.0, 30.0)))  # d loss / d pooled
    gradient = bags.rows.T @ (share * slope[bags.bag])
    shrunk = w - anchor if anchor is not None else w.copy()
    shrunk[-1] = 0.0
    return loss + 0.5 * penalty * float(shrunk @ shrunk), gradient + penalty * shrunk


class Pooled:
    """``detectors.fit`` for ``--model mil:H[,T]`` (multiple-instance, pooled logistic
    regression): the product's linear score, trained on runs as bags for the run-level rule
    it is judged by. A good run (and a failed run's part before its onset) is a negative
    bag, a failed run's first ``H`` seconds after its onset a positive bag; a bag's score is
    the smooth maximum ``T log sum exp(m / T)`` (``T`` in log-odds) of the trailing 1 s means
    ``m`` of its scores: the threshold is the largest evidence of a good run, and a mean
    over a second, not one sample's score, is what a good run's isolated spike does not
    move and what the evidence's smoothing (0 to 4 s) weighs. The loss is ``fit``'s with
    bags in place of samples: the bags' softplus summed, the classes weighed equally, plus
    the L2 penalty ``strength`` (the bags are this objective's data, as the samples are
    ``fit``'s); L-BFGS with the analytic gradient, on the statistics standardised as
    ``fit`` standardises them, started from ``fit``'s solution. ``anchored``: the penalty
    is on the weights' distance from that solution, not from 0 (the cross-fitting's
    penalty then chooses how far the bags may move the per-sample fit)."""

    def __init__(self, horizon: float, temperature: float = 1.0, anchored: bool = False) -> None:
        self.horizon, self.temperature, self.anchored = horizon, temperature, anchored

    def __call__(self, runs: Sequence[Any], strength: float) -> Any:
        start = LOGISTIC(runs, strength)
        bags = Bags(runs, start.center, start.scale, self.horizon)
        if not bags.positive.any() or bags.positive.all():
            return start
        with threadpool_limits(limits=1, user_api="blas"):
            found = minimize(
                mil_loss,
                np.asarray(start.weights, dtype=np.float64),
                args=(bags, self.temperature, strength, start.weights if self.anchored else None),
                jac=True,
                method="L-BFGS-B",
                options={"maxiter": MIL_STEPS},
            )
        return detectors.Model(start.center, start.scale, found.x)


def newton(z: Any, y: Any, weight: Any, strength: float) -> Any:
    """The weighted, L2-regularised logistic regression of :func:`imrosc.detectors.fit`
    (its Newton's method) on standardised rows ``z`` (a column of ones last)."""
    w = np.zeros(z.shape[1])
    penalty = np.full(z.shape[1], strength)
    penalty[-1] = 0.0
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(detectors.NEWTON_STEPS):
            p = 1 / (1 + np.exp(-np.clip(z @ w, -30, 30)))
            gradient = z.T @ (weight * (p - y)) + penalty * w
            hessian = (z * (weight * p * (1 - p))[:, None]).T @ z + np.diag(penalty + 1e-9)
            step = np.linalg.solve(hessian, gradient)
            w -= step
            if float(np.abs(step).max()) <= detectors.CONVERGED * (1.0 + float(np.abs(w).max())):
                break
    return w


def hard_samples(run: Any, scores: Any, seconds: float) -> Any:
    """Per sample of ``run``, whether it is hard: of a nominal stretch, one of the samples
    whose trailing 1 s mean score is among the stretch's top ``seconds`` worth of samples,
    or one within the second before such a sample (the scores that made its mean); of a
    faulty stretch, the first ``seconds`` after the onset."""
    hard = np.zeros(len(run.times), dtype=bool)
    if run.onset is not None:
        since = run.times - run.start - run.onset
        hard |= run.faulty & (since < seconds)
    nominal = np.flatnonzero(~run.faulty & run.scored)
    if len(nominal) < 2:
        return hard
    at = run.times[nominal]
    means, spans = trailing_means(at, np.nan_to_num(scores[nominal])[:, None], POOL)
    ranked = np.where(spans, means[:, 0], -np.inf)
    step = float(np.median(np.diff(at)))
    count = max(1, min(int(spans.sum()), round(seconds / max(step, 1e-9))))
    top = np.argsort(ranked)[-count:]
    top = top[np.isfinite(ranked[top])]
    covered = np.zeros(len(at) + 1, dtype=np.int64)
    first = np.searchsorted(at, at[top] - POOL, side="right")
    np.add.at(covered, first, 1)
    np.add.at(covered, top + 1, -1)
    hard[nominal] |= np.cumsum(covered)[:-1] > 0
    return hard


class Hardened:
    """``detectors.fit`` for ``--model hardneg:R[,Q]`` (hard-negative reweighting): fit as
    the product fits, then ``R`` rounds of: score the training runs, find each nominal
    stretch's odd moments (its top ``Q`` seconds of 1 s mean score, what sets the
    threshold: :func:`hard_samples`) and each failed run's first ``Q`` seconds after its
    onset, and refit with those samples holding half their class's weight (the classes
    still weighed equally, as ``fit`` weighs them)."""

    def __init__(self, rounds: int, seconds: float = 4.0) -> None:
        self.rounds, self.seconds = rounds, seconds

    def __call__(self, runs: Sequence[Any], strength: float) -> Any:
        model = LOGISTIC(runs, strength)
        total = sum(int(r.scored.sum()) for r in runs)
        every = max(1, -(-total // detectors.FIT_SAMPLES))
        x = np.vstack([r.stats[r.scored][::every] for r in runs])
        y = np.concatenate([r.faulty[r.scored][::every] for r in runs])
        finite = np.isfinite(x).all(axis=1)
        z = np.hstack([(x - model.center) / model.scale, np.ones((len(x), 1))])[finite]
        y = y[finite]
        for _ in range(self.rounds):
            hard = np.concatenate(
                [hard_samples(r, model.scores(r), self.seconds)[r.scored][::every] for r in runs]
            )[finite]
            weight = np.zeros(len(y))
            for label in (False, True):
                for group in (hard, ~hard):
                    rows = (y == label) & group
                    # each class len(y) / 2 in all, as fit weighs it; half of it the hard ones
                    # (all of it when a class has none or only hard ones)
                    other = (y == label) & ~group
                    share = 0.5 if rows.any() and other.any() else 1.0
                    weight[rows] = share * len(y) / 2 / max(1, int(rows.sum()))
            w = newton(z, y.astype(np.float64), weight, strength)
            model = detectors.Model(model.center, model.scale, w)
        return model


def model_fit(kind: str, horizon: float | None) -> Callable[..., Any]:
    """The fit of ``--model kind`` (``logistic``, ``mil:H[,T]``, ``hardneg:R[,Q]``)."""
    if kind == "logistic":
        return with_horizon(horizon)
    name, _, spec = kind.partition(":")
    words = [v.strip() for v in spec.split(",") if v.strip()]
    anchored = words[-1:] == ["anchored"]
    values = [float(v) for v in words[: len(words) - anchored]]
    if horizon is not None:
        raise SystemExit(f"--model {kind}: without --horizon only")
    if name == "mil" and len(values) == 1:
        return Pooled(values[0], 1.0, anchored)
    if name == "mil" and len(values) == 2:
        return Pooled(values[0], values[1], anchored)
    if name == "hardneg" and 1 <= len(values) <= 2 and not anchored:
        return Hardened(int(values[0]), *values[1:])
    raise SystemExit(f"unknown --model {kind}")


G = 9.80665
"""Standard gravity (m/s^2)."""
MERGED = [
    "orientation_x",
    "orientation_y",
    "orientation_z",
    "angular_velocity_x",
    "angular_velocity_y",
    "angular_velocity_z",
    "linear_acceleration_x",
    "linear_acceleration_y",
    "linear_acceleration_z",
    "twist_linear_x",
    "twist_linear_y",
    "twist_linear_z",
    "twist_angular_x",
    "twist_angular_y",
    "twist_angular_z",
    "alt_error",
    "aspd_error",
    "xtrack_error",
    "delta_yaw",
    "delta_pitch",
    "delta_roll",
    "delta_x",
    "delta_y",
    "delta_z",
    "delta_roll_airspeed",
]
"""The fields of ``/alfa/merged``, in the order :func:`alfa_reference.read` gives them."""
ENERGY = ("energy_error", "power", "speed_energy", "inertial_power")
"""The derived fields of ``--features energy`` (:func:`energy_fields`)."""


def energy_fields(values: Any, names: Sequence[str]) -> Any:
    """Derived fields of the total energy balance, per sample (m, m/s): ``speed`` the
    ground speed ``V`` (``twist_linear_*``: the local velocity, z up); ``energy_error`` the
    specific energy the autopilot lacks, ``alt_error + V * aspd_error / (100 g)``
    (``aspd_error`` in cm/s, target less measured: its change over a window is the rate the
    demand outruns the energy); ``power`` the specific power the accelerometer measures,
    ``V * linear_acceleration_x / g`` (thrust less drag along the body axis, times ``V /
    (m g)``: the rate of the total energy ``h + V^2 / (2 g)``); ``speed_energy`` the kinetic
    part ``V^2 / (2 g)`` (its change plus the height's is the energy's change);
    ``inertial_power`` the rate of the total energy from the kinematics alone, ``v . f / g``
    with ``f`` the specific force the accelerometer measures turned into the local frame
    (``a = f + g_vec``, so ``d(h + V^2 / (2 g))/dt = v . a / g + v_z = v . f / g``: lift does
    no work on the air-relative path, and a turn's or a pull-up's accelerations drop out)."""
    x = filled(values)
    at = {k: x[:, MERGED.index(k)] for k in MERGED}
    speed = np.sqrt(sum(at[f"twist_linear_{a}"] ** 2 for a in "xyz"))
    found = {
        "speed": speed,
        "energy_error": at["alt_error"] + speed * at["aspd_error"] / (100.0 * G),
        "power": speed * at["linear_acceleration_x"] / G,
        "speed_energy": speed * speed / (2.0 * G),
    }
    if "inertial_power" in names:
        velocity = np.column_stack([at[f"twist_linear_{a}"] for a in "xyz"])
        force = np.column_stack([at[f"linear_acceleration_{a}"] for a in "xyz"])
        found["inertial_power"] = np.einsum("ki,ki->k", velocity, to_local(at, velocity, force)) / G
    return np.column_stack([found[n] for n in names])


SCANNED = {"inertial_power": -1.0, "power": -1.0, "climb": -1.0, "energy_error": 1.0}
"""The signals ``--scan`` knows, each with the sign that makes a lost engine raise it: the
energy's rates fall, the energy the autopilot lacks grows."""


def scan_signal(times: Any, values: Any, name: str, window: float, baseline: float) -> Any:
    """``--scan``'s signal of a flight: the mean over the trailing ``window`` seconds of
    ``name`` (:data:`SCANNED`; ``climb`` is ``twist_linear_z``, ``energy_error`` its rate: the
    least-squares slope over the window), signed so that a lost engine raises it; with a
    ``baseline`` less its mean over the ``baseline`` seconds before that window (a flight's
    own trim and sensor bias taken out). NaN until the samples span both."""
    if name == "climb":
        raw = filled(values)[:, MERGED.index("twist_linear_z")]
    else:
        raw = energy_fields(values, [name])[:, 0]
    stats = window_stats(times, raw[:, None], window, slope=name == "energy_error")
    found = SCANNED[name] * (stats[:, 3] if name == "energy_error" else stats[:, 0])
    span = window + baseline
    if baseline > 0:
        ends = np.searchsorted(times, times - window, side="right")
        starts = np.searchsorted(times, times - span, side="right")
        total = np.concatenate(([0.0], np.cumsum(found)))
        found = found - (total[ends] - total[starts]) / np.maximum(ends - starts, 1)
    found[times - times[0] < span] = math.nan
    return found


def scan(
    flights: Mapping[str, Flight], signals: Mapping[str, Any], folds: Sequence[Sequence[str]]
) -> list[Outcome]:
    """Each fold's flights against the largest value their training flights' signal reached
    while nominal (a no-failure flight whole, a fault flight before its onset): an alarm
    where a held-out flight's signal first passes it."""
    outcomes = []
    for held in folds:
        nominal = [
            signals[n][(times < (info["onset_ns"] or math.inf) / 1e9)]
            for n, (info, times, _) in flights.items()
            if n not in held
        ]
        threshold = max(float(np.nanmax(s)) for s in nominal if np.isfinite(s).any())
        for name in held:
            info, times, _ = flights[name]
            over = np.flatnonzero(signals[name] > threshold)
            onset = None if info["onset_ns"] is None else info["onset_ns"] / 1e9
            group = info["class"] if onset is not None else "no_failure"
            alarms = (float(times[over[0]]),) if len(over) else ()
            outcomes.append(Outcome(name, group, onset, alarms, start=info["start_ns"] / 1e9))
    return outcomes


def rotations(qx: Any, qy: Any, qz: Any) -> Any:
    """Per sample the rotation matrix (body to local) of the unit quaternion ``(qx, qy, qz,
    w)`` with ``w >= 0``."""
    qw = np.sqrt(np.clip(1.0 - qx * qx - qy * qy - qz * qz, 0.0, 1.0))
    r = np.empty((len(qx), 3, 3))
    r[:, 0, 0] = 1 - 2 * (qy * qy + qz * qz)
    r[:, 0, 1] = 2 * (qx * qy - qz * qw)
    r[:, 0, 2] = 2 * (qx * qz + qy * qw)
    r[:, 1, 0] = 2 * (qx * qy + qz * qw)
    r[:, 1, 1] = 1 - 2 * (qx * qx + qz * qz)
    r[:, 1, 2] = 2 * (qy * qz - qx * qw)
    r[:, 2, 0] = 2 * (qx * qz - qy * qw)
    r[:, 2, 1] = 2 * (qy * qz + qx * qw)
    r[:, 2, 2] = 1 - 2 * (qx * qx + qy * qy)
    return r


def oriented(at: Mapping[str, Any], velocity: Any) -> Any:
    """Per sample the rotation matrix (body to local) of the orientation. ``/alfa/merged``
    keeps the quaternion's x, y, z and drops w, so ``w``'s sign is lost: of the two
    rotations it leaves, the one under which the aircraft's velocity points forward (body x)
    is taken."""
    q = [at[f"orientation_{a}"] for a in "xyz"]
    best, best_forward = None, None
    for sign in (1.0, -1.0):
        r = rotations(*(sign * c for c in q))
        forward = np.einsum("kj,kj->k", r[:, :, 0], velocity)
        if best is None or best_forward is None:
            best, best_forward = r, forward
        else:
            pick = forward > best_forward
            best[pick] = r[pick]
            best_forward = np.maximum(forward, best_forward)
    return best


def tracked(at: Mapping[str, Any], velocity: Any) -> Any:
    """Per sample the rotation matrix (body to local) of the orientation, ``w``'s lost sign
    chosen along the flight as a whole: :func:`oriented`'s choice sample by sample fails
    where the two candidates' noses point alike (heading near east, the inverse rotation's
    roll and pitch of the opposite sign). The choice minimises, over the flight, each
    sample's ``1 - cos`` of the angle between the nose and the velocity plus the angle (rad)
    the rotation turns by from one sample to the next (a true orientation is continuous;
    the two candidates meet only where the rotation is a half turn or none): the cheapest
    sequence of signs, by dynamic programming over the two."""
    q = np.column_stack([at[f"orientation_{a}"] for a in "xyz"])
    w = np.sqrt(np.clip(1.0 - (q * q).sum(axis=1), 0.0, 1.0))
    signs = (1.0, -1.0)
    candidates = [np.column_stack([s * q, w]) for s in signs]
    speed = np.maximum(np.sqrt((velocity * velocity).sum(axis=1)), 1e-6)
    emit = np.column_stack(
        [
            1.0 - np.einsum("kj,kj->k", rotations(*(s * q.T))[:, :, 0], velocity) / speed
            for s in signs
        ]
    )
    n = len(q)
    # turn[k, s, p]: the angle from candidate p at k - 1 to candidate s at k
    turn = np.empty((max(n - 1, 0), 2, 2))
    for i in range(2):
        for j in range(2):
            dot = np.abs(np.einsum("kj,kj->k", candidates[i][1:], candidates[j][:-1]))
            turn[:, i, j] = 2.0 * np.arccos(np.minimum(dot, 1.0))
    cost = emit[0].copy() if n else np.zeros(2)
    back = np.zeros((n, 2), dtype=np.int64)
    for k in range(1, n):
        steps = cost[None, :] + turn[k - 1]
        back[k] = np.argmin(steps, axis=1)
        cost = steps[[0, 1], back[k]] + emit[k]
    path = np.zeros(n, dtype=np.int64)
    if n:
        path[-1] = int(np.argmin(cost))
    for k in range(n - 1, 0, -1):
        path[k - 1] = back[k, path[k]]
    sign = np.where(path == 0, 1.0, -1.0)[:, None]
    return rotations(*(sign * q).T)


def to_local(at: Mapping[str, Any], velocity: Any, force: Any) -> Any:
    """The body-frame ``force`` in the local frame (the rotation of :func:`oriented`)."""
    return np.einsum("kij,kj->ki", oriented(at, velocity), force)


Flight = tuple[Mapping[str, Any], Any, Any]
"""A flight's entry in ``onsets.json``, its sample times (s) and values."""


def nominal_part(flight: Flight) -> tuple[Any, Any]:
    """The samples of a flight before its onset (all of a no-failure flight's)."""
    info, times, values = flight
    if info["onset_ns"] is None:
        return times, values
    keep = times < info["onset_ns"] / 1e9
    return times[keep], values[keep]


def responses(
    flights: Mapping[str, Flight], folds: Sequence[Sequence[str]], lags: int, forget: float
) -> dict[str, Any]:
    """Per flight, the models of :class:`Commanded` fitted on the other folds' nominal parts:
    the trailing 1 s mean of each output's squared innovation (in units of its running
    spread) and of their sum, one column each (NaN in the flight's first second)."""
    found = {}
    for held in folds:
        parts = [nominal_part(f) for n, f in flights.items() if n not in held]
        model = Commanded([(t, *commanded_signals(v)) for t, v in parts], lags, forget)
        for name in held:
            _, times, values = flights[name]
            width = len(COMMANDED)
            squared = model.of(times, *commanded_signals(values))[:, :width] ** 2
            squared = np.hstack([squared, squared.sum(axis=1, keepdims=True)])
            mean = window_stats(times, squared, 1.0)[:, : width + 1]
            mean[times - times[0] < 1.0] = math.nan
            found[name] = mean
    return found


def diagnose(flights: Mapping[str, Flight], signals: Mapping[str, Any], after: float) -> None:
    """Per fault flight, each signal's largest value in the ``after`` seconds from its
    onset against its own largest before it and the largest any other session's flight
    reached while nominal (every flight's signal from models fitted without its session)."""
    nominal = {}
    for name, (info, times, _) in flights.items():
        before = signals[name][times < (info["onset_ns"] or math.inf) / 1e9]
        nominal[name] = np.nanmax(before, axis=0)
    columns = ["roll", "pitch", "speed", "all"]
    print(
        f"\nlargest 1 s mean square innovation: {after:g} s after the onset / before it / "
        "other sessions' nominal"
    )
    print(f"  {'flight':<52} " + " ".join(f"{c:>20}" for c in columns))
    passed = np.zeros(len(columns), dtype=int)
    above_own = np.zeros(len(columns), dtype=int)
    faults = 0
    for name, (info, times, _) in sorted(flights.items()):
        if info["onset_ns"] is None:
            continue
        faults += 1
        onset = info["onset_ns"] / 1e9
        window = (times >= onset) & (times < onset + after)
        high = np.nanmax(signals[name][window], axis=0)
        others = np.max(
            [v for n, v in nominal.items() if session_of(n) != session_of(name)], axis=0
        )
        own = nominal[name]
        passed += (high > own) & (high > others)
        above_own += high > own
        shown = " ".join(
            f"{high[j]:6.1f}/{own[j]:6.1f}/{others[j]:6.1f}" for j in range(len(columns))
        )
        print(f"  {Path(name).stem[:52]:<52} {shown}")
    for label, counts in (("its own before", above_own), ("both", passed)):
        shown = ", ".join(f"{c} {k}" for c, k in zip(columns, counts, strict=True))
        print(f"  above {label}: {shown} (of {faults})")


def features_of(kind: str, training: Sequence[Flight]) -> tuple[Features, float]:
    """The statistics of ``--features kind`` (fitted on ``training`` where they need it)
    and the longest window they span."""
    if kind == "base":
        return (lambda t, v: features(t, v, 1.0)), 1.0
    if kind == "mean":
        return (lambda t, v: window_stats(t, filled(v), 1.0)[:, : v.shape[1]]), 1.0
    if kind == "mean+change":

        def mean_change(t: Any, v: Any) -> Any:
            found = window_stats(t, filled(v), 1.0)
            return np.hstack([found[:, : v.shape[1]], found[:, 2 * v.shape[1] :]])

        return mean_change, 1.0
    if kind == "slope":
        return (lambda t, v: window_stats(t, filled(v), 1.0, slope=True)), 1.0
    if kind.startswith("windows:"):
        windows = [float(w) for w in kind.split(":", 1)[1].split(",")]
        return (
            lambda t, v: np.hstack([window_stats(t, filled(v), w) for w in windows]),
            max(windows),
        )
    if kind in ("interactions", "relations", "squash"):
        nominal = np.vstack([features(*nominal_part(f), 1.0) for f in training])
        width = nominal.shape[1] // 3
        if kind == "squash":
            return (lambda t, v: squashed(features(t, v, 1.0), nominal)), 1.0
        if kind == "relations":
            relations = Relations(nominal[:, :width])

            def with_relations(t: Any, v: Any) -> Any:
                found = features(t, v, 1.0)
                return np.hstack([found, relations.of(found[:, :width])])

            return with_relations, 1.0
        center, scale = spread(nominal[:, :width])

        def with_products(t: Any, v: Any) -> Any:
            found = features(t, v, 1.0)
            return np.hstack([found, products((found[:, :width] - center) / scale)])

        return with_products, 1.0
    if kind.startswith("rls:"):
        # rls:LAGS,FORGET[,alone]: the adapted models' innovations (their 1 s mean and
        # standard deviation, and the parameters' mean change) beside the base statistics,
        # or alone
        spec = kind.split(":", 1)[1].split(",")
        adapted = Adapted(
            [filled(nominal_part(f)[1]) for f in training], int(spec[0]), float(spec[1])
        )
        alone = spec[2:] == ["alone"]

        def with_innovations(t: Any, v: Any) -> Any:
            x = filled(v)
            found = window_stats(t, adapted.of(x), 1.0)
            width = found.shape[1] // 3
            innovations = found[:, : 2 * width]
            if alone:
                return innovations
            return np.hstack([features(t, v, 1.0), innovations])

        return with_innovations, 1.0
    if kind.startswith("keipour:"):
        # keipour:LAGS,FORGET[,alone]: the commanded-response models' innovations (their 1 s
        # mean and standard deviation, and the parameters' change) beside the base
        # statistics, or alone
        spec = kind.split(":", 1)[1].split(",")
        parts = [nominal_part(f) for f in training]
        signals = [(t, *commanded_signals(v)) for t, v in parts]
        responding = Commanded(signals, int(spec[0]), float(spec[1]))
        only = spec[2:] == ["alone"]

        def with_responses(t: Any, v: Any) -> Any:
            found = window_stats(t, responding.of(t, *commanded_signals(v)), 1.0)
            responses = found[:, : 2 * found.shape[1] // 3]
            if only:
                return responses
            return np.hstack([features(t, v, 1.0), responses])

        return with_responses, 1.0
    if kind.startswith("energy"):
        # energy[:NAMES]: derived fields of the total energy balance beside the recorded ones
        # (:func:`energy_fields`), their statistics as the base statistics'
        names = kind.split(":", 1)[1].split(",") if ":" in kind else list(ENERGY)

        def with_energy(t: Any, v: Any) -> Any:
            return features(t, np.hstack([v, energy_fields(v, names)]), 1.0)

        return with_energy, 1.0
    if kind.startswith("scan:"):
        # scan:NAME[:WINDOW[:BASELINE]]: --scan's signal as one more field
        name, *rest = kind.split(":")[1:]
        window = float(rest[0]) if rest else 1.0
        baseline = float(rest[1]) if len(rest) > 1 else 0.0

        def with_signal(t: Any, v: Any) -> Any:
            extra = scan_signal(t, v, name, window, baseline)[:, None]
            return features(t, np.hstack([v, extra]), 1.0)

        return with_signal, 1.0
    if kind == "residual":
        model = Residuals([filled(nominal_part(f)[1]) for f in training])

        def with_residuals(t: Any, v: Any) -> Any:
            x = filled(v)
            found = window_stats(t, model.of(x), 1.0)
            return np.hstack([window_stats(t, x, 1.0), found[:, : 2 * x.shape[1]]])

        return with_residuals, 1.0
    raise SystemExit(f"unknown --features {kind}")


def runs_of(
    names: Sequence[str], flights: Mapping[str, Flight], stats: Features, copies: str = "twice"
) -> list[Any]:
    """The runs classification sees of ``names`` (module docstring); with ``copies`` "once"
    a fault flight's part before its onset is not also a good run of its own."""
    runs = []
    for name in names:
        info, times, values = flights[name]
        start = info["start_ns"] / 1e9
        found = stats(times, values)
        if info["onset_ns"] is None:
            runs.append(detectors.Run(name, start, None, times, found))
            continue
        before = times < info["onset_ns"] / 1e9
        if copies == "twice":
            runs.append(
                detectors.Run(name + " (before)", start, None, times[before], found[before])
            )
        runs.append(detectors.Run(name, start, info["onset_s"], times, found))
    return runs


def with_horizon(horizon: float | None) -> Callable[..., Any]:
    """:func:`imrosc.detectors.fit` on runs cut ``horizon`` seconds after their onsets."""
    fit = detectors.fit

    def cut_fit(runs: Sequence[Any], strength: float) -> Any:
        if horizon is None:
            return fit(runs, strength)
        cut = []
        for r in runs:
            if r.onset is None:
                cut.append(r)
                continue
            keep = r.times - r.start < r.onset + horizon
            cut.append(detectors.Run(r.name, r.start, r.onset, r.times[keep], r.stats[keep]))
        return fit(cut, strength)

    return cut_fit


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--features", default="base")
    parser.add_argument("--evidence", default="mean", help="mean, cusum, probability, relative:S")
    parser.add_argument("--horizon", type=float, default=None, help="seconds after the onset")
    parser.add_argument("--final", choices=FINALS, default="refit")
    parser.add_argument("--offsets", default="", help="log-odds, comma-separated (--offsets=-1,1)")
    parser.add_argument("--fit-samples", type=int, default=detectors.FIT_SAMPLES)
    parser.add_argument("--inner-folds", type=int, default=detectors.FOLDS)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--nominal-copies", choices=("twice", "once"), default="twice")
    parser.add_argument(
        "--model",
        default="logistic",
        help="logistic, gbm1, gbm2, mil:H[,T], hardneg:R[,Q]; A|B|...: the cross-fitting's best",
    )
    parser.add_argument(
        "--margins",
        default="",
        help="S,S,...: per fault flight, its largest evidence in the S seconds from its onset "
        "less its fold's threshold",
    )
    parser.add_argument("--trees", default="30,100,300", help="--model gbm: tree counts")
    parser.add_argument(
        "--scan", default="", help="NAME[:WINDOW[:BASELINE]]: one signal against held-out maxima"
    )
    parser.add_argument(
        "--responses",
        default="",
        help="LAGS,FORGET[,AFTER]: no detector, the commanded-response innovations after "
        "each onset against the nominal ones",
    )
    args = parser.parse_args(argv)
    offsets = [float(d) for d in args.offsets.split(",") if d.strip()]
    detectors.FIT_SAMPLES = args.fit_samples
    detectors.FOLDS = args.inner_folds
    onsets: dict[str, dict[str, Any]] = json.loads((ALFA / "onsets.json").read_text())
    started = time.monotonic()
    flights: dict[str, Flight] = {n: (i, *read(ALFA / n)) for n, i in sorted(onsets.items())}
    print(f"read {len(flights)} flights in {time.monotonic() - started:.1f} s; {REFERENCE}")
    if args.scan:
        name, *rest = args.scan.split(":")
        window = float(rest[0]) if rest else 1.0
        baseline = float(rest[1]) if len(rest) > 1 else 0.0
        signals = {n: scan_signal(f[1], f[2], name, window, baseline) for n, f in flights.items()}
        print_outcomes(scan(flights, signals, session_folds(onsets, args.folds)))
        return 0
    if args.responses:
        spec = args.responses.split(",")
        folds = session_folds(onsets, args.folds)
        innovations = responses(flights, folds, int(spec[0]), float(spec[1]))
        diagnose(flights, innovations, float(spec[2]) if len(spec) > 2 else 3.0)
        return 0
    weighs: dict[str, Callable[[Any, Any, float, float], Any]] = {
        "mean": evidence,
        "cusum": cusum,
        "probability": probability,
    }
    if args.evidence.startswith("relative:"):
        weighs[args.evidence] = relative(float(args.evidence.split(":", 1)[1]))
    weigh = weighs[args.evidence]
    if args.evidence == "cusum":
        # choose() tries each of SMOOTHING, weighed by the evidence its module names
        detectors.SMOOTHING = CUSUM_DRIFTS  # type: ignore[assignment]
    detectors.evidence = weigh  # type: ignore[attr-defined,assignment]
    kinds = args.model.split("|")
    if any(k.startswith("gbm") for k in kinds):
        if args.final != "refit" or args.horizon is not None or len(kinds) > 1:
            raise SystemExit("--model gbm: alone, with --final refit and no --horizon only")
        if kinds[0] not in ("gbm1", "gbm2"):
            raise SystemExit(f"unknown --model {kinds[0]}")
        detectors.PENALTIES = tuple(-float(n) for n in args.trees.split(","))  # type: ignore[assignment]
        fitters = {kinds[0]: Recorded(Boosting(int(kinds[0][-1])))}
    else:
        fitters = {k: Recorded(model_fit(k, args.horizon)) for k in kinds}
    spans = [float(v) for v in args.margins.split(",") if v.strip()]
    margins: list[tuple[str, str, list[float]]] = []
    outcomes: list[Outcome] = []
    shifted: dict[float, list[Outcome]] = {d: [] for d in offsets}
    for index, held in enumerate(session_folds(onsets, args.folds)):
        training = [n for n in flights if n not in held]
        best = None
        for kind in args.features.split("|"):  # alternatives: the cross-fitting's best
            stats, window = features_of(kind, [flights[n] for n in training])
            detectors.WINDOW = window
            runs = runs_of(training, flights, stats, args.nominal_copies)
            for fitted, recorded in fitters.items():
                detectors.fit = recorded
                recorded.forget()
                tried = detectors.choose(runs, 0.05)
                if tried is not None and (best is None or tried.rank() > best[0].rank()):
                    best = (tried, kind, stats, window, runs, fitted, dict(recorded.models))
        if best is None:
            print(f"fold {index}: no detector")
            continue
        choice, kind, stats, window, runs, fitted, models = best
        detectors.WINDOW = window
        recorded = fitters[fitted]
        detectors.fit = recorded
        recorded.models = models
        if "|" in args.features or len(fitters) > 1:
            print(f"fold {index}: {kind}, {fitted}")
        if args.final == "average":
            model = Linear.mean_of(recorded.models[choice.strength])
        else:
            model = detectors.fit(runs, choice.strength)
        delays = list(choice.delays.values())
        print(
            f"fold {index}: penalty {choice.strength:g}, {args.evidence} "
            f"{choice.smooth:g}, threshold {choice.threshold:.2f}; held out in the choice "
            f"{len(choice.detected)} of {choice.failed} detected, mean delay "
            f"{sum(delays) / len(delays):.2f} s"
        )
        for name in held:
            info, times, values = flights[name]
            run = detectors.Run(name, times[0], None, times, stats(times, values))
            weighed = weigh(times, model.scores(run), window, choice.smooth)
            onset = None if info["onset_ns"] is None else info["onset_ns"] / 1e9
            group = info["class"] if onset is not None else "no_failure"
            if onset is not None and spans:
                found_margins = margin_after(times, weighed, onset, spans)
                margins.append((name, group, [*found_margins, choice.threshold]))
            for shift, found in [(0.0, outcomes), *shifted.items()]:
                over = np.flatnonzero(weighed > choice.threshold + shift)
                alarms = (float(times[over[0]]),) if len(over) else ()
                start = info["start_ns"] / 1e9
                found.append(Outcome(name, group, onset, alarms, start=start))
    print_outcomes(outcomes)
    if spans:
        print_margins(margins, spans)
    if shifted:
        print("\nevery fold's threshold moved by (log-odds):")
    for shift, found in shifted.items():
        print(f"  {shift:+g}: {describe(score(found))}")
    print(f"{time.monotonic() - started:.0f} s")
    return 0


def margin_after(times: Any, weighed: Any, onset: float, spans: Sequence[float]) -> list[float]:
    """Per span ``S``, the largest evidence from ``onset`` to ``onset + S`` (NaN with none)."""
    found = []
    for span in spans:
        inside = (times >= onset) & (times <= onset + span) & ~np.isnan(weighed)
        found.append(float(weighed[inside].max()) if inside.any() else math.nan)
    return found


def print_margins(rows: Sequence[tuple[str, str, list[float]]], spans: Sequence[float]) -> None:
    """Per fault flight, its largest evidence in each span from its onset less its fold's
    threshold (above 0: detected by then), and each class's median."""
    heads = " ".join(f"{f'{s:g} s':>8}" for s in spans)
    print("\nlargest evidence from the onset less the threshold:")
    print(f"  {'flight':<75} {heads} threshold")
    groups: dict[str, list[list[float]]] = {}
    for name, group, found in sorted(rows):
        *highs, threshold = found
        over = [h - threshold for h in highs]
        groups.setdefault(group, []).append(over)
        shown = " ".join(f"{v:8.2f}" for v in over)
        print(f"  {Path(name).stem[:64]:<64} {group:<10} {shown} {threshold:9.2f}")
    for group, members in sorted(groups.items()):
        medians = " ".join(f"{v:8.2f}" for v in np.nanmedian(np.array(members), axis=0))
        above = ", ".join(
            f"{sum(1 for f in members if f[j] > 0)} of {len(members)} above at {s:g} s"
            for j, s in enumerate(spans)
        )
        print(f"  median {group:<57} {medians} ({above})")


def describe(s: Any) -> str:
    """Recall, false-alarm flights and mean delay, in a line."""
    return (
        f"detected {s.detected} of {s.faulty}, false alarms on {s.false_alarms} of {s.runs} "
        f"flights, mean delay {s.mean_delay:.2f} s"
    )


def print_outcomes(outcomes: Sequence[Outcome]) -> None:
    """Per flight its delay, then the scores per class."""
    print("\nflights: delay (s), '-' missed, 'FA' an alarm before the onset or on a good flight")
    for o in sorted(outcomes, key=lambda o: o.name):
        shown = "FA" if o.false_alarm else ("-" if o.delay is None else f"{o.delay:.2f}")
        print(f"  {Path(o.name).stem:<66} {o.group:<10} {shown}")
    groups: dict[str, list[Outcome]] = {}
    for o in outcomes:
        groups.setdefault(o.group, []).append(o)
    table = {g: {"detector": score(found)} for g, found in sorted(groups.items())}
    table["overall"] = {"detector": score(outcomes)}
    print_scores(table)


if __name__ == "__main__":
    raise SystemExit(main())
