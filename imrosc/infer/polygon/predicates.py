"""Exact 2-D orientation, vectorised: Shewchuk's adaptive ``orient2d`` on numpy arrays.

``orientation(ax, ay, bx, by, cx, cy)`` is the exact sign of
``(ax - cx) * (by - cy) - (ay - cy) * (bx - cx)``: ``+1`` when ``a, b, c`` turn
counter-clockwise, ``-1`` clockwise, ``0`` collinear. Stage A is the float determinant
with Shewchuk's error bound; the elements it cannot decide go to stages B and C (products
and differences as exact two-term expansions, with their bounds); what is still undecided
(in practice: exactly collinear points whose differences round) gets stage D: the
determinant as sixteen floats whose sum is exact, summed with ``math.fsum`` (correctly
rounded, so its sign is exact). Inputs of extreme magnitude, where a product could
underflow or overflow (Shewchuk's bounds assume neither), get exact rational arithmetic.
Inputs must be finite.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray

SignArray = npt.NDArray[np.int8]

_EPS = 2.0**-53
_SPLITTER = 134217729.0  # 2**27 + 1
_RESULT_ERR = (3.0 + 8.0 * _EPS) * _EPS
_CCW_ERR_A = (3.0 + 16.0 * _EPS) * _EPS
_CCW_ERR_B = (2.0 + 12.0 * _EPS) * _EPS
_CCW_ERR_C = (9.0 + 64.0 * _EPS) * _EPS * _EPS
_TINY = 2.0**-900
"""Below this, products may have underflowed: the float stages prove nothing there."""


def _two_sum(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


def _two_diff_tail(a: FloatArray, b: FloatArray, x: FloatArray) -> FloatArray:
    bv = a - x
    av = x + bv
    return (a - av) + (bv - b)


def _two_diff(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    x = a - b
    return x, _two_diff_tail(a, b, x)


def _split(a: FloatArray) -> tuple[FloatArray, FloatArray]:
    c = _SPLITTER * a
    big = c - a
    hi = c - big
    return hi, a - hi


def _two_product(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    x = a * b
    ahi, alo = _split(a)
    bhi, blo = _split(b)
    err1 = x - ahi * bhi
    err2 = err1 - alo * bhi
    err3 = err2 - ahi * blo
    return x, alo * blo - err3


def _two_one_diff(
    a1: FloatArray, a0: FloatArray, b: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    i, x0 = _two_diff(a0, b)
    x2, x1 = _two_sum(a1, i)
    return x2, x1, x0


def _exact_sign(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    det = (Fraction(ax) - Fraction(cx)) * (Fraction(by) - Fraction(cy)) - (
        Fraction(ay) - Fraction(cy)
    ) * (Fraction(bx) - Fraction(cx))
    return (det > 0) - (det < 0)


def _adaptive(
    ax: FloatArray,
    ay: FloatArray,
    bx: FloatArray,
    by: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
    detsum: FloatArray,
) -> SignArray:
    """Stages B, C (vectorised) and D (exact) for the elements stage A left open."""
    out = np.zeros(len(ax), np.int8)
    big = detsum >= _TINY
    with np.errstate(all="ignore"):
        acx, bcx = ax - cx, bx - cx
        acy, bcy = ay - cy, by - cy
        left, left_tail = _two_product(acx, bcy)
        right, right_tail = _two_product(acy, bcx)
        j, z, b0 = _two_one_diff(left, left_tail, right_tail)
        b3, b2, b1 = _two_one_diff(j, z, right)
        det = ((b0 + b1) + b2) + b3
        decided = np.abs(det) >= _CCW_ERR_B * detsum
        acx_t = _two_diff_tail(ax, cx, acx)
        bcx_t = _two_diff_tail(bx, cx, bcx)
        acy_t = _two_diff_tail(ay, cy, acy)
        bcy_t = _two_diff_tail(by, cy, bcy)
        exact = (acx_t == 0) & (bcx_t == 0) & (acy_t == 0) & (bcy_t == 0)
        decided |= exact & np.isfinite(det)
        bound = _CCW_ERR_C * detsum + _RESULT_ERR * np.abs(det)
        det_c = det + ((acx * bcy_t + bcy * acx_t) - (acy * bcx_t + bcx * acy_t))
        use_c = ~decided & (np.abs(det_c) >= bound) & np.isfinite(det_c)
        sign = np.where(use_c, np.sign(det_c), np.sign(det))
        decided |= use_c
        decided &= np.isfinite(sign) & big
    out[decided] = sign[decided].astype(np.int8)
    rest = np.flatnonzero(~decided)
    if len(rest):
        out[rest] = _stage_d(ax[rest], ay[rest], bx[rest], by[rest], cx[rest], cy[rest])
    return out


_SAFE_HIGH = 2.0**400
_SAFE_LOW = 2.0**-400
"""Inputs of magnitudes in ``[_SAFE_LOW, _SAFE_HIGH)`` (or zero) make every partial product
of stage D a multiple of ``2**-904`` below ``2**810``: no underflow, no overflow, so
Dekker's products are exact. Anything else goes to rational arithmetic."""


def _stage_d(
    ax: FloatArray,
    ay: FloatArray,
    bx: FloatArray,
    by: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
) -> SignArray:
    """The exact sign from the 16 floats whose sum is the determinant.

    Each difference is exactly ``hi + tail``; each product of two such sums is exactly
    eight floats (Dekker's product). ``math.fsum`` rounds their sum correctly, so its sign
    is the exact sign. Where a product may have underflowed or a split overflowed, the
    sign comes from rational arithmetic instead.
    """
    with np.errstate(all="ignore"):
        acx, bcx = ax - cx, bx - cx
        acy, bcy = ay - cy, by - cy
        acx_t = _two_diff_tail(ax, cx, acx)
        bcx_t = _two_diff_tail(bx, cx, bcx)
        acy_t = _two_diff_tail(ay, cy, acy)
        bcy_t = _two_diff_tail(by, cy, bcy)
        terms = []
        for p, q, sign in (
            (acx, bcy, 1.0),
            (acx, bcy_t, 1.0),
            (acx_t, bcy, 1.0),
            (acx_t, bcy_t, 1.0),
            (acy, bcx, -1.0),
            (acy, bcx_t, -1.0),
            (acy_t, bcx, -1.0),
            (acy_t, bcx_t, -1.0),
        ):
            high, low = _two_product(p, q)
            terms.append(sign * high)
            terms.append(sign * low)
        stacked = np.stack(terms, axis=1)
        safe = np.ones(len(ax), np.bool_)
        for v in (ax, ay, bx, by, cx, cy):
            size = np.abs(v)
            safe &= (size == 0) | ((size >= _SAFE_LOW) & (size < _SAFE_HIGH))
    out = np.zeros(len(ax), np.int8)
    for k, row in enumerate(stacked.tolist()):
        if safe[k]:
            total = math.fsum(row)
            out[k] = (total > 0) - (total < 0)
        else:
            out[k] = _exact_sign(
                float(ax[k]), float(ay[k]), float(bx[k]), float(by[k]), float(cx[k]), float(cy[k])
            )
    return out


def orientation(
    ax: FloatArray, ay: FloatArray, bx: FloatArray, by: FloatArray, cx: FloatArray, cy: FloatArray
) -> SignArray:
    """The exact sign of ``orient2d(a, b, c)`` elementwise (arrays of one shape, 1-D)."""
    with np.errstate(all="ignore"):
        acx, bcx, acy, bcy = ax - cx, bx - cx, ay - cy, by - cy
        left = acx * bcy
        right = acy * bcx
        det = left - right
        detsum = np.abs(left) + np.abs(right)
        sure = np.abs(det) >= _CCW_ERR_A * detsum
        sure &= np.isfinite(det)
        # Shewchuk's bounds assume no underflow: tiny products prove nothing, unless a
        # factor of each is exactly zero (then the determinant is exactly zero)
        zero = ((acx == 0) | (bcy == 0)) & ((acy == 0) | (bcx == 0))
        sure &= (detsum >= _TINY) | zero
    out = np.sign(det, where=sure, out=np.zeros(det.shape)).astype(np.int8)
    open_ = np.flatnonzero(~sure)
    if len(open_):
        out[open_] = _adaptive(
            ax[open_], ay[open_], bx[open_], by[open_], cx[open_], cy[open_], detsum[open_]
        )
    return out


def surely_left(
    ax: FloatArray, ay: FloatArray, bx: FloatArray, by: FloatArray, cx: FloatArray, cy: FloatArray
) -> npt.NDArray[np.bool_]:
    """Where ``c`` is certainly strictly left of ``a -> b`` by the float test alone.

    A cheap conservative filter: ``False`` means "strictly left is not proven" (it may
    still be). Broadcasts.
    """
    with np.errstate(all="ignore"):
        left = (ax - cx) * (by - cy)
        right = (ay - cy) * (bx - cx)
        det = left - right
        detsum = np.abs(left) + np.abs(right)
        result: npt.NDArray[np.bool_] = (det > _CCW_ERR_A * detsum) & (detsum >= _TINY)
    return result
