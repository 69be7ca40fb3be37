"""The float screen of the linear and ternary families.

A candidate (two or three variables) can only be reported if some relation
``g_1 v_1 + ... + g_m v_m + c = 0`` with *every* ``g_k`` nonzero holds within tolerance on
all samples (a zero coefficient makes it a relation of fewer variables, reported by another
family or suppressed). Such a relation also holds on any subset ``S`` of the rows. The screen
computes, on ``S``, the centered Gram matrix of the candidate's variables and drops the
candidate when some variable ``v_d`` cannot take part with a nonzero coefficient:

* ``v_d`` varies on ``S`` while the others are constant there;
* ``v_d`` is far from every affine function of the others on ``S``: the relative misfit
  ``1 - R^2`` exceeds ``REL`` *and* the misfit sum exceeds ``(ABS * T)**2``, ``T`` the
  magnitude of the fitted terms (``max|v_d| + sum |a_k| max|v_k|`` on ``S``);
* the other two are collinear on ``S`` (``1 - r^2 <= COLL``) and ``v_d`` is far from every
  affine function of one of them.

A subset where a variable is constant, or where the other two are neither well
conditioned (``1 - r^2 > EVAL``) nor collinear, gives no evidence. The thresholds sit far
above float64 rounding (the Gram entries are exact to about ``1e-14`` relative) and a
thousand times above the final tolerance, so a candidate the exact test would accept is
not dropped unless a variable's magnitude grows more than about a thousandfold after the
subset (see ``docs/families/daikon.md``). Every statistic of a candidate is computed from
its own columns on rows fixed by the chunk alone, so the screen's decisions do not depend
on which other candidates are alive: folding and merging see the same decisions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray
from imrosc.infer.daikon.common import PREFIX, BoolArray, IntArray, window

__all__ = [
    "ABS",
    "COLL",
    "EVAL",
    "PREFIX",
    "REL",
    "SPREAD",
    "Stats",
    "candidate_stats",
    "gather",
    "pair_dead",
    "spread_rows",
    "triple_dead",
    "window",
]

REL = 1e-9
ABS = 1e-6
COLL = 1e-13
EVAL = 1e-3
SPREAD = 2048
_BLOCK = 2048


def spread_rows(rows: int) -> IntArray:
    """The second look for candidates the window could not judge: about ``SPREAD`` rows
    evenly spaced over the chunk, plus the window (any subset of rows is sound)."""
    step = max(1, rows // SPREAD)
    return np.union1d(np.arange(0, rows, step, dtype=np.int64), window(rows))


@dataclass
class Stats:
    """Per-candidate statistics on a row subset: Gram ``(c, m, m)``, flags ``(c, m)``."""

    gram: FloatArray
    constant: BoolArray
    magnitude: FloatArray
    rows: IntArray


def candidate_stats(matrix: FloatArray, candidates: IntArray) -> Stats:
    """Statistics of each candidate (rows of variable indices into ``matrix``).

    ``matrix`` holds one row per variable over the subset's rows (NaN/inf allowed); a
    candidate uses the rows where all its variables are finite.
    """
    count, width = candidates.shape
    gram = np.zeros((count, width, width))
    constant = np.ones((count, width), dtype=bool)
    magnitude = np.zeros((count, width))
    rows = np.zeros(count, dtype=np.int64)
    if count == 0 or matrix.shape[1] == 0:
        return Stats(gram, constant, magnitude, rows)
    finite = np.asarray(np.isfinite(matrix), dtype=bool)
    clean: BoolArray = np.asarray(finite.all(axis=1), dtype=bool)
    fast: BoolArray = np.asarray(clean[candidates].all(axis=1), dtype=bool)
    with np.errstate(all="ignore"):
        _fast_stats(matrix, candidates, fast, gram, constant, magnitude, rows)
        slow = np.flatnonzero(~fast)
        for start in range(0, slow.size, _BLOCK):
            block = slow[start : start + _BLOCK]
            _masked_stats(matrix, finite, candidates[block], block, gram, constant, magnitude, rows)
    return Stats(gram, constant, magnitude, rows)


def _fast_stats(
    matrix: FloatArray,
    candidates: IntArray,
    fast: BoolArray,
    gram: FloatArray,
    constant: BoolArray,
    magnitude: FloatArray,
    rows: IntArray,
) -> None:
    chosen = np.flatnonzero(fast)
    if chosen.size == 0:
        return
    width = candidates.shape[1]
    used = np.unique(candidates[chosen])
    local = np.full(matrix.shape[0], -1, dtype=np.int64)
    local[used] = np.arange(used.size)
    values = matrix[used]
    mean = values.sum(axis=1) / values.shape[1]
    centered = values - mean[:, None]
    flat = values.min(axis=1) == values.max(axis=1)
    size = np.abs(values).max(axis=1)
    picked = local[candidates[chosen]]
    first, second = np.triu_indices(used.size)
    entries = np.empty(first.size)
    step = max(1, (1 << 20) // max(1, values.shape[1]))
    for start in range(0, first.size, step):
        a, b = first[start : start + step], second[start : start + step]
        entries[start : start + step] = (centered[a] * centered[b]).sum(axis=1)
    full = np.empty((used.size, used.size))
    full[first, second] = entries
    full[second, first] = entries
    for i in range(width):
        constant[chosen, i] = flat[picked[:, i]]
        magnitude[chosen, i] = size[picked[:, i]]
        for j in range(width):
            gram[chosen, i, j] = full[picked[:, i], picked[:, j]]
    rows[chosen] = values.shape[1]


def _masked_stats(
    matrix: FloatArray,
    finite: BoolArray,
    members: IntArray,
    block: IntArray,
    gram: FloatArray,
    constant: BoolArray,
    magnitude: FloatArray,
    rows: IntArray,
) -> None:
    width = members.shape[1]
    values = matrix[members]  # (b, m, r)
    mask: BoolArray = np.asarray(finite[members].all(axis=1), dtype=bool)  # (b, r)
    count = mask.sum(axis=1)
    rows[block] = count
    present = count > 0
    kept = np.where(mask[:, None, :], values, 0.0)
    mean = kept.sum(axis=2) / np.maximum(count, 1)[:, None]
    centered = np.where(mask[:, None, :], values - mean[:, :, None], 0.0)
    low = np.where(mask[:, None, :], values, np.inf).min(axis=2)
    high = np.where(mask[:, None, :], values, -np.inf).max(axis=2)
    constant[block] = (low == high) | ~present[:, None]
    magnitude[block] = np.where(mask[:, None, :], np.abs(values), 0.0).max(axis=2)
    for i in range(width):
        for j in range(i, width):
            entry = (centered[:, i] * centered[:, j]).sum(axis=1)
            gram[block, i, j] = entry
            gram[block, j, i] = entry


def _not_affine(stats: Stats, d: int, p: int) -> BoolArray:
    """Rows where ``v_d`` is far from every affine function of ``v_p`` (slope 0 allowed)."""
    g = stats.gram
    gdd, gpp, gdp = g[:, d, d], g[:, p, p], g[:, d, p]
    ad, ap = stats.magnitude[:, d], stats.magnitude[:, p]
    cd, cp = stats.constant[:, d], stats.constant[:, p]
    significant = gdd > (ABS * ad) ** 2
    relative = 1.0 - gdp * gdp / (gdd * gpp)
    slope = gdp / gpp
    limit = ABS * (ad + np.abs(slope) * ap)
    varying = (relative > REL) & (gdd * relative > limit * limit)
    result = np.where(cd, False, np.where(cp, significant, varying))
    finite = np.isfinite(gdd) & np.isfinite(gpp) & np.isfinite(gdp) & np.isfinite(limit)
    finite |= cp & np.isfinite(gdd)
    return np.asarray(result & finite & (stats.rows > 0), dtype=bool)


def pair_dead(stats: Stats) -> BoolArray:
    """Pairs that cannot hold ``y = a x + b`` with ``a != 0`` (evidence from ``stats``)."""
    with np.errstate(all="ignore"):
        return _not_affine(stats, 1, 0) | _not_affine(stats, 0, 1)


def _orientation_impossible(stats: Stats, d: int, p: int, q: int) -> BoolArray:
    g = stats.gram
    cd, cp, cq = stats.constant[:, d], stats.constant[:, p], stats.constant[:, q]
    gdd, gpp, gqq = g[:, d, d], g[:, p, p], g[:, q, q]
    gdp, gdq, gpq = g[:, d, p], g[:, d, q], g[:, p, q]
    r_pq = gpq / np.sqrt(gpp * gqq)
    r_dp = gdp / np.sqrt(gdd * gpp)
    r_dq = gdq / np.sqrt(gdd * gqq)
    det2 = 1.0 - r_pq * r_pq
    det3 = 1.0 + 2.0 * r_pq * r_dp * r_dq - r_pq * r_pq - r_dp * r_dp - r_dq * r_dq
    relative = det3 / det2
    denominator = gpp * gqq - gpq * gpq
    a = (gdp * gqq - gdq * gpq) / denominator
    b = (gdq * gpp - gdp * gpq) / denominator
    limit = ABS * (stats.magnitude[:, d] + np.abs(a) * stats.magnitude[:, p])
    limit = limit + ABS * np.abs(b) * stats.magnitude[:, q]
    misfit = (relative > REL) & (gdd * relative > limit * limit) & ~cd
    misfit &= np.isfinite(relative) & np.isfinite(limit) & np.isfinite(gdd)
    conditioned = det2 > EVAL
    collinear = det2 <= COLL
    vary = np.where(conditioned, misfit, np.where(collinear, _not_affine(stats, d, p), False))
    vary &= np.isfinite(det2)
    result = np.where(
        ~cp & ~cq,
        vary,
        np.where(cq, _not_affine(stats, d, p), _not_affine(stats, d, q)),
    )
    return np.asarray(result, dtype=bool)


def triple_dead(stats: Stats) -> BoolArray:
    """Triples that cannot hold ``a x + b y + c z + d = 0`` with ``a, b, c`` all nonzero."""
    with np.errstate(all="ignore"):
        dead = _orientation_impossible(stats, 0, 1, 2)
        dead |= _orientation_impossible(stats, 1, 0, 2)
        dead |= _orientation_impossible(stats, 2, 0, 1)
    return dead & (stats.rows > 0)


def gather(
    columns: list[FloatArray], variables: npt.ArrayLike, rows: IntArray | None
) -> FloatArray:
    """A ``(variables, rows)`` matrix of the given columns (all rows if ``rows`` is None)."""
    chosen = np.asarray(variables, dtype=np.int64)
    if chosen.size == 0:
        return np.zeros((0, 0 if rows is None else rows.size))
    length = columns[int(chosen[0])].size if rows is None else rows.size
    out = np.empty((chosen.size, length))
    for k, v in enumerate(chosen):
        out[k] = columns[int(v)] if rows is None else columns[int(v)][rows]
    return out
