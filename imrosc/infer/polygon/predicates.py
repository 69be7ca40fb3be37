"""Exact 2-D orientation, vectorised: Shewchuk's adaptive ``orient2d`` on numpy arrays.

``orientation(ax, ay, bx, by, cx, cy)`` is the exact sign of
``(ax - cx) * (by - cy) - (ay - cy) * (bx - cx)``: ``+1`` when ``a, b, c`` turn
counter-clockwise, ``-1`` clockwise, ``0`` collinear. Stage A is the float determinant
with Shewchuk's error bound; the elements it cannot decide go to stages B and C (products
and differences as exact two-term expansions, with their bounds); what is still undecided
(in practice: exactly collinear points whose differences round) gets stage D: the
determinant as sixteen floats whose sum is exact, the sign of which vectorised
error-free summation settles (``math.fsum``, correctly rounded, for the rare rows it does
not). Inputs of extreme magnitude, where a product could underflow or overflow
(Shewchuk's bounds assume neither), get exact rational arithmetic.
Inputs must be finite.
"""

from __future__ import annotations

import math

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
_GATHER = 0.875
"""A later stage runs on the elements still open, gathered, unless they are nearly all
(gathering a few arrays costs far less than a stage's dozens of operations on the rest)."""


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


def turn(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """:func:`orientation` of one triple of (finite) Python floats: the float determinant
    where stage A's bound decides it (Python's floats round as numpy's do), else the
    exact sign in integers (:func:`_integer_sign`)."""
    acx, bcx, acy, bcy = ax - cx, bx - cx, ay - cy, by - cy
    left = acx * bcy
    right = acy * bcx
    det = left - right
    detsum = abs(left) + abs(right)
    if abs(det) >= _CCW_ERR_A * detsum and detsum >= _TINY and math.isfinite(det):
        return (det > 0) - (det < 0)
    return _integer_sign(ax, ay, bx, by, cx, cy)


def _integer_sign(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """The exact sign of ``orient2d``: every float is ``n / 2**k`` exactly, so scaled to
    one power of two the determinant is a Python integer (no rounding, no overflow)."""
    ratios = [v.as_integer_ratio() for v in (ax, ay, bx, by, cx, cy)]
    shift = max(d.bit_length() for _, d in ratios) - 1
    pax, pay, pbx, pby, pcx, pcy = (n << (shift - d.bit_length() + 1) for n, d in ratios)
    det = (pax - pcx) * (pby - pcy) - (pay - pcy) * (pbx - pcx)
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
    """Stages B, C (vectorised) and D (exact) for the elements stage A left open; first,
    the exactly parallel differences (:func:`_parallel`), which are zero."""
    out = np.zeros(len(ax), np.int8)
    with np.errstate(all="ignore"):
        acx, bcx = ax - cx, bx - cx
        acy, bcy = ay - cy, by - cy
        acx_t = _two_diff_tail(ax, cx, acx)
        bcx_t = _two_diff_tail(bx, cx, bcx)
        acy_t = _two_diff_tail(ay, cy, acy)
        bcy_t = _two_diff_tail(by, cy, bcy)
    level = _parallel(acx, acx_t, acy, acy_t, bcx, bcx_t, bcy, bcy_t)
    todo = np.flatnonzero(~level)
    if not len(todo):
        return out
    every = (ax, ay, bx, by, cx, cy, detsum, acx, bcx, acy, bcy, acx_t, bcx_t, acy_t, bcy_t)
    if len(todo) > _GATHER * len(ax):  # nearly all open: no gathering, the parallel ones are zero
        return np.where(level, out, _stages_bcd(*every, settled=level))
    out[todo] = _stages_bcd(*(v.take(todo) for v in every))
    return out


def _stages_bcd(
    ax: FloatArray,
    ay: FloatArray,
    bx: FloatArray,
    by: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
    detsum: FloatArray,
    acx: FloatArray,
    bcx: FloatArray,
    acy: FloatArray,
    bcy: FloatArray,
    acx_t: FloatArray,
    bcx_t: FloatArray,
    acy_t: FloatArray,
    bcy_t: FloatArray,
    *,
    settled: npt.NDArray[np.bool_] | None = None,
) -> SignArray:
    """Stages B, C and D given the differences and their tails (none for the elements
    ``settled`` already, whose result is ignored)."""
    out = np.zeros(len(ax), np.int8)
    big = detsum >= _TINY
    with np.errstate(all="ignore"):
        left, left_tail = _two_product(acx, bcy)
        right, right_tail = _two_product(acy, bcx)
        j, z, b0 = _two_one_diff(left, left_tail, right_tail)
        b3, b2, b1 = _two_one_diff(j, z, right)
        det = ((b0 + b1) + b2) + b3
        decided = np.abs(det) >= _CCW_ERR_B * detsum
        exact = (acx_t == 0) & (bcx_t == 0) & (acy_t == 0) & (bcy_t == 0)
        decided |= exact & np.isfinite(det)
        bound = _CCW_ERR_C * detsum + _RESULT_ERR * np.abs(det)
        det_c = det + ((acx * bcy_t + bcy * acx_t) - (acy * bcx_t + bcx * acy_t))
        use_c = ~decided & (np.abs(det_c) >= bound) & np.isfinite(det_c)
        sign = np.where(use_c, np.sign(det_c), np.sign(det))
        decided |= use_c
        decided &= np.isfinite(sign) & big
    out[decided] = sign[decided].astype(np.int8)
    rest = np.flatnonzero(~decided if settled is None else ~decided & ~settled)
    if len(rest):
        out[rest] = _stage_d(ax[rest], ay[rest], bx[rest], by[rest], cx[rest], cy[rest])
    return out


def _parallel(
    acx: FloatArray,
    acx_t: FloatArray,
    acy: FloatArray,
    acy_t: FloatArray,
    bcx: FloatArray,
    bcx_t: FloatArray,
    bcy: FloatArray,
    bcy_t: FloatArray,
) -> npt.NDArray[np.bool_]:
    """Where ``a - c`` and ``b - c`` are exactly parallel with a power-of-two ratio of
    coordinates (``y - y' == s * (x - x')`` for both, ``s = +-2**k``): the points lie on
    one line of such a slope (``q = -p``, ``y = x + c``, ``ab = |n|`` on either side,
    ``mx = max(n1, n2)`` where it is ``n1``), and the determinant is exactly zero.

    The exact differences are ``hi + tail`` (two-diff); scaling by a power of two is exact
    away from underflow, which the guard on the operands' magnitudes excludes, so equal
    scaled parts prove ``a - c == s * (...)`` exactly. A cheap test: exact relations put
    many points on an edge of their hull, which only stage D could otherwise settle.
    """
    with np.errstate(all="ignore"):
        s = np.where(acx != 0, acy / acx, bcy / bcx)
        mantissa, exponent = np.frexp(s)
        ok = (np.abs(mantissa) == 0.5) & (np.abs(exponent) <= 60)
        for v in (acx, acx_t, bcx, bcx_t):
            size = np.abs(v)
            ok &= (size == 0) | ((size >= _SAFE_LOW) & np.isfinite(size))
        ok &= (acy == s * acx) & (acy_t == s * acx_t) & (bcy == s * bcx) & (bcy_t == s * bcx_t)
    result: npt.NDArray[np.bool_] = ok
    return result


_SAFE_HIGH = 2.0**400
_SAFE_LOW = 2.0**-400
"""Inputs of magnitudes in ``[_SAFE_LOW, _SAFE_HIGH)`` (or zero) make every partial product
of stage D a multiple of ``2**-904`` below ``2**810``: no underflow, no overflow, so
Dekker's products are exact. Anything else goes to rational arithmetic."""


_STAGE_D_BLOCK = 1 << 16
"""Elements of stage D computed together (its sixteen terms per element stay small)."""


def _stage_d(
    ax: FloatArray,
    ay: FloatArray,
    bx: FloatArray,
    by: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
) -> SignArray:
    """:func:`_stage_d_block` by blocks of ``_STAGE_D_BLOCK`` elements."""
    out = np.zeros(len(ax), np.int8)
    for first in range(0, len(ax), _STAGE_D_BLOCK):
        part = slice(first, first + _STAGE_D_BLOCK)
        out[part] = _stage_d_block(ax[part], ay[part], bx[part], by[part], cx[part], cy[part])
    return out


def _stage_d_block(
    ax: FloatArray,
    ay: FloatArray,
    bx: FloatArray,
    by: FloatArray,
    cx: FloatArray,
    cy: FloatArray,
) -> SignArray:
    """The exact sign from the 16 floats whose sum is the determinant.

    Each difference is exactly ``hi + tail``; each product of two such sums is exactly
    eight floats (Dekker's product); :func:`exact_sum_signs` finds the exact sign of their
    sum. Where a product may have underflowed or a split overflowed, the
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
    easy = np.flatnonzero(safe)
    out[easy] = exact_sum_signs(stacked[easy])
    for k in np.flatnonzero(~safe).tolist():
        out[k] = _integer_sign(
            float(ax[k]), float(ay[k]), float(bx[k]), float(by[k]), float(cx[k]), float(cy[k])
        )
    return out


_PASSES = 12
"""Distillation passes of :func:`exact_sum_signs` before a row falls back to ``math.fsum``."""


def exact_sum_signs(terms: FloatArray) -> SignArray:
    """The exact sign of each row's sum (``(rows, k)`` finite floats whose partial sums
    neither overflow nor lose bits to underflow), vectorised.

    Each pass is Ogita, Rump and Oishi's ``VecSum``: a cascade of error-free two-sums that
    leaves the row's exact sum unchanged, its rounded sum in the last column and the
    rounding errors in the others. The sign is settled once the errors are all zero, or
    once the rounded sum exceeds the sum of their magnitudes even with that sum's own
    rounding (``k`` units) doubled; exact cancellations (collinear points) settle in a
    pass or two. Rows still open after ``_PASSES`` passes get ``math.fsum`` (correctly
    rounded, so its sign is exact).
    """
    rows, width = terms.shape
    out = np.zeros(rows, np.int8)
    if not rows:
        return out
    work = np.array(terms, dtype=np.float64, order="F")
    open_ = np.arange(rows)
    margin = 1.0 + 4 * width * _EPS
    with np.errstate(all="ignore"):
        for _ in range(_PASSES):
            total = work[:, 0].copy()
            for k in range(1, width):
                term = work[:, k]
                total, work[:, k - 1] = _two_sum(total, term)
            work[:, width - 1] = total
            rest = np.abs(work[:, : width - 1]).sum(axis=1)
            done = (rest == 0) | (np.abs(total) > rest * margin)
            hit = np.flatnonzero(done)
            out[open_[hit]] = np.sign(total[hit]).astype(np.int8)
            keep = np.flatnonzero(~done)
            open_ = open_[keep]
            if not len(open_):
                return out
            work = np.asfortranarray(work[keep])
    for k, row in zip(open_.tolist(), work.tolist(), strict=True):
        total = math.fsum(row)
        out[k] = (total > 0) - (total < 0)
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
    if len(open_) > _GATHER * len(out):  # nearly all open (samples on an edge): no gathering
        return np.where(sure, out, _adaptive(ax, ay, bx, by, cx, cy, detsum))
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


_FRAME_SLOPE = 2.0**-60
"""Shears have slopes zero or ``+-2**-k``, ``0 <= k <= 60``."""
_FRAME_HIGH = 2.0**900
_FRAME_LOW = 2.0**-900
"""Coordinates of magnitude in ``[_FRAME_LOW, _FRAME_HIGH]`` (or zero) scale by such a
slope and sum with no overflow or underflow: their sheared offsets are exact."""
_FRAME_ERR = 8 * _EPS
_NEAR_SLOPE = 2.0**-20
"""Edges get a frame when their slope in it is this close to the shear's (``|rise| <=
_NEAR_SLOPE * |run|``): lines of exact relations with simple slopes, up to rounding.
Other edges' samples are rarely so close to them that the guide's chords leave them."""
_HALF_OCTAVE = 0.7071067811865476


def _frame_safe(r: FloatArray, q: FloatArray) -> npt.NDArray[np.bool_]:
    with np.errstate(invalid="ignore"):
        ok = (np.abs(r) <= _FRAME_HIGH) & (np.abs(q) <= _FRAME_HIGH)
        ok &= (r == 0) | (np.abs(r) >= _FRAME_LOW)
    result: npt.NDArray[np.bool_] = ok
    return result


Frames = tuple[
    npt.NDArray[np.int8], FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray
]
"""Per edge ``(kind, slope, high, low, origin, run, rise)``, see :func:`edge_frames`."""


def edge_frames(ax: FloatArray, ay: FloatArray, bx: FloatArray, by: FloatArray) -> Frames:
    """Each edge ``a -> b`` in a sheared frame where :func:`frame_orientation` places
    points against it cheaply: ``(kind, slope, high, low, origin, run, rise)``.

    The frame reads points as ``(r, q)``: ``(x, y)`` (kind 1) or, for steep edges,
    ``(y, x)`` (kind 2, where orientations change sign); ``slope`` ``s`` is zero or the
    power of two nearest the edge's slope in the frame, and a point's offset ``w = q -
    s*r`` is exact as two floats. ``(high, low)`` is the edge's start's offset,
    ``origin`` its ``r``, ``run`` and ``rise`` the rounded ``r_b - r_a`` and ``w_b -
    w_a`` (the latter the rounded sum of two exact differences, so zero exactly when the
    ends have one offset); kind 0 where any of that may not hold (magnitudes outside the
    safe range, differences of offsets that round) and where the slope is not within
    ``_NEAR_SLOPE`` of the shear's. Shearing keeps orientations, so that
    of ``(a, b, p)`` is ``run * (w_p - w_a) - rise * (r_p - r_a)``: for edges of exact
    relations with simple slopes (``y = 2*x + 3``, ``|n|``, ``x + 5`` rounded) ``rise`` is
    zero or tiny and the float value of that has a small error bound, where the
    unsheared one has none to speak of.
    """
    with np.errstate(all="ignore"):
        swap = np.abs(by - ay) > np.abs(bx - ax)
        ar, aq = np.where(swap, ay, ax), np.where(swap, ax, ay)
        br, bq = np.where(swap, by, bx), np.where(swap, bx, by)
        steep = (bq - aq) / (br - ar)
        mantissa, exponent = np.frexp(steep)
        exponent = np.where(np.abs(mantissa) > _HALF_OCTAVE, exponent, exponent - 1)
        slope = np.where(
            np.abs(steep) >= _FRAME_SLOPE, np.copysign(np.ldexp(1.0, exponent), steep), 0.0
        )
        slope = np.where(np.abs(slope) <= 1.0, slope, 0.0)
        high, low = _two_sum(aq, -(slope * ar))
        end_high, end_low = _two_sum(bq, -(slope * br))
        run = br - ar
        top, top_tail = _two_diff(end_high, high)
        tail, tail_tail = _two_diff(end_low, low)
        rise = top + tail
        ok = _frame_safe(ar, aq) & _frame_safe(br, bq) & (run != 0) & np.isfinite(run)
        ok &= (top_tail == 0) & (tail_tail == 0)
        ok &= np.isfinite(rise) & np.isfinite(high) & np.isfinite(low)
        ok &= np.abs(rise) <= _NEAR_SLOPE * np.abs(run)
    kind = np.where(ok, np.where(swap, 2, 1), 0).astype(np.int8)
    return kind, slope, high, low, ar, run, rise


def frame_orientation(
    frames: Frames, px: FloatArray, py: FloatArray
) -> tuple[SignArray, npt.NDArray[np.bool_]]:
    """The sign of ``orient2d(a, b, p)`` for each point and edge in its frame
    (:func:`edge_frames`, kinds 1 and 2), and where it is certain.

    ``w_p - w_a`` is ``(h_p - high) + (l_p - low)`` exactly. With ``rise`` zero (``a``,
    ``b`` and every point of the edge's line have one offset) the sign is that of ``run``
    times that of the offsets' difference: of ``h_p - high`` if nonzero (rounding is
    monotone, so the offsets differ as their roundings do), else of the tails'.
    Otherwise the float value of ``run * (w_p - w_a) - rise * (r_p - r_a)`` decides where
    it exceeds its error bound, ``8 * 2**-53`` of its terms' magnitudes plus ``2 * 2**-53``
    of itself (the roundings of ``run``, ``rise``, ``w_p - w_a``, ``r_p - r_a``, both
    products and the difference add up to less than ``5 * 2**-53`` and ``3 * 2**-53`` of
    the terms and ``2**-53`` of the result); underflow is excluded by a floor on that
    bound, overflow by the comparisons failing on infinities and NaN. Undecided: NaN
    points, magnitudes outside the frame's safe range, values too close to the line.
    """
    kind, slope, high, low, origin, run, rise = frames
    swap = kind == 2
    with np.errstate(all="ignore"):
        r = np.where(swap, py, px)
        q = np.where(swap, px, py)
        ph, pl = _two_sum(q, -(slope * r))
        # each difference is zero exactly when its operands are equal, and of their sign
        e1 = ph - high
        e2 = pl - low
        value = np.sign(np.where(e1 != 0, e1, e2))
        value *= np.sign(run)
        decided = _frame_safe(r, q) & (kind > 0)
        # edges of exact relations have ``rise`` zero: the float determinant is only
        # needed for the others, computed on them alone
        tilted = np.flatnonzero(rise != 0)
        if len(tilted):
            if len(tilted) < len(rise):
                e1, e2, r = e1.take(tilted), e2.take(tilted), r.take(tilted)
                origin, run, rise = origin.take(tilted), run.take(tilted), rise.take(tilted)
            det = run * (e1 + e2)
            shift = rise * (r - origin)
            det -= shift
            bound = np.abs(e1) + np.abs(e2)
            bound *= np.abs(run)
            bound += np.abs(shift)
            bound *= _FRAME_ERR
            bound += 2 * _EPS * np.abs(det)
            # NaN and infinite values fail these comparisons: undecided
            decided[tilted] &= (np.abs(det) > bound) & (bound >= _FRAME_LOW)
            value[tilted] = np.sign(det)
    value = np.where(swap, -value, value)
    sign = np.where(decided, value, 0.0).astype(np.int8)
    return sign, decided
