"""Exact arithmetic for the linear and ternary families.

Sums of float64 values and of their pairwise products are kept as Python integers ``S``
meaning ``S * 2**-SCALE``; with ``SCALE = 2300`` every double and every product of two
doubles is an integer multiple of ``2**-SCALE``, so these sums are exact and adding them is
associative: merged states hold bit-identical sums whatever the order of additions.

* A column sum: Rump-Ogita-Oishi extraction (``exact_sums``), exact float sums of high
  parts until nothing remains; near overflow/underflow, ``np.frexp`` integer mantissas
  summed per exponent with ``np.bincount``.
* A product ``x*y`` is ``p + e`` exactly with ``p = fl(x*y)`` and ``e`` from Dekker's
  two-product (Veltkamp split by ``2**27 + 1``), exact while no step overflows or
  underflows: rows whose values lie outside ``[2**-450, 2**450]`` (zero is fine) are
  multiplied as Python integers instead.

``finalize`` solves least squares in ``fractions.Fraction``, rounds the coefficients to
floats, and evaluates the sum of squared residuals of those floats exactly as a dyadic
rational: ``w^T M w`` with ``M`` the exact moment matrix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from imrosc.infer.core import FloatArray

SCALE = 2300
_MANTISSA = 9007199254740992.0  # 2**53
_SPLIT = 134217729.0  # 2**27 + 1
_GUARD_LO = 2.0**-450
_GUARD_HI = 2.0**450
_MAX_ROWS = 1 << 26
READABLE = 4
"""Coefficients with at most this many significant digits keep the canonical orientation."""

BoolArray = npt.NDArray[np.bool_]
Dyadic = tuple[int, int]
"""``(m, e)`` meaning ``m * 2**e``."""


def exact_sums(matrix: FloatArray, consume: bool = False) -> list[int]:
    """The exact sum of each row of a finite ``(rows, n)`` matrix, scaled by ``2**SCALE``
    (``consume``: ``matrix``, a float64 temporary of the caller's, is worked on in place
    rather than copied).

    Rump, Ogita and Oishi's extraction (AccSum): with ``sigma = 2**(e + M)`` above every
    ``|r_i| < 2**e`` and ``2**M > n + 2``, ``q_i = (sigma + r_i) - sigma`` is an exact high
    part of ``r_i`` and ``sum q_i`` is exact in floating point; the remainders ``r_i - q_i``
    (exact) go round again until they are all zero. Rows near overflow or underflow are
    summed by exponent groups instead (``_grouped_sums``).
    """
    rows, n = matrix.shape
    totals = [0] * rows
    if n == 0:
        return totals
    spare = math.ceil(math.log2(n + 2)) + 1
    consume = consume and matrix.dtype == np.float64 and matrix.flags.c_contiguous
    part = matrix if consume else np.array(matrix, dtype=np.float64)
    high = np.empty_like(part)  # the pass's high parts, in place
    active = np.arange(rows)
    while active.size:
        top = np.maximum(part.max(axis=1), -part.min(axis=1))  # max |r_i|, no temporary
        awkward = (top > 2.0 ** (1000 - spare)) | ((top < 2.0**-900) & (top > 0))
        if awkward.any():
            chosen = np.flatnonzero(awkward)
            for k, total in zip(chosen, _grouped_sums(part[chosen]), strict=True):
                totals[int(active[k])] += total
        keep = ~awkward & (top > 0)
        if not keep.all():
            part, active, top = part[keep], active[keep], top[keep]
            high = high[: len(part)]
            if not active.size:
                break
        sigma = np.ldexp(1.0, np.frexp(top)[1] + spare)[:, None]
        np.add(sigma, part, out=high)
        high -= sigma
        part -= high
        for k, total in zip(active.tolist(), high.sum(axis=1).tolist(), strict=True):
            if total:
                numerator, denominator = total.as_integer_ratio()
                totals[k] += numerator << (SCALE + 1 - denominator.bit_length())
    return totals


def _grouped_sums(matrix: FloatArray) -> list[int]:
    """Exact row sums by exponent groups: integer mantissas summed with ``np.bincount``."""
    rows, n = matrix.shape
    if n > _MAX_ROWS:
        parts = [_grouped_sums(matrix[:, s : s + _MAX_ROWS]) for s in range(0, n, _MAX_ROWS)]
        return [sum(column) for column in zip(*parts, strict=True)]
    fraction, exponent = np.frexp(matrix)
    mantissa = (fraction * _MANTISSA).astype(np.int64)
    exponent = exponent.astype(np.int64)
    low = int(exponent.min())
    span = int(exponent.max()) - low + 1
    index = (exponent - low) + (np.arange(rows, dtype=np.int64) * span)[:, None]
    high_part = np.bincount(
        index.ravel(), weights=(mantissa >> 26).astype(np.float64).ravel(), minlength=rows * span
    )
    low_part = np.bincount(
        index.ravel(),
        weights=(mantissa & 0x3FFFFFF).astype(np.float64).ravel(),
        minlength=rows * span,
    )
    totals = [0] * rows
    for k in np.flatnonzero((high_part != 0) | (low_part != 0)):
        row, offset = divmod(int(k), span)
        group = (int(high_part[k]) << 26) + int(low_part[k])
        totals[row] += group << (offset + low - 53 + SCALE)
    return totals


def _in_guard(values: FloatArray) -> BoolArray:
    size = np.abs(values)
    if size.max() <= _GUARD_HI and not ((size < _GUARD_LO) & (size > 0)).any():
        return np.ones(values.shape, dtype=bool)
    return np.asarray((size == 0) | ((size >= _GUARD_LO) & (size <= _GUARD_HI)), dtype=bool)


def _scaled_product(x: float, y: float) -> int:
    mx, ex = math.frexp(x)
    my, ey = math.frexp(y)
    product = int(mx * _MANTISSA) * int(my * _MANTISSA)
    return product << (ex + ey - 106 + SCALE)


def exact_dots(left: FloatArray, right: FloatArray) -> list[int]:
    """``sum(left[r] * right[r])`` exactly for each row ``r`` of two finite matrices."""
    rows = left.shape[0]
    if rows == 0:
        return []
    stacked = np.concatenate([left, right])
    return exact_products(stacked, [(r, rows + r) for r in range(rows)])


def exact_products(matrix: FloatArray, pairs: Sequence[tuple[int, int]]) -> list[int]:
    """``sum(matrix[i] * matrix[j])`` exactly for each pair ``(i, j)`` of rows (finite).

    Each row is split once (Veltkamp); each product is ``p + e`` with Dekker's error term.
    """
    if not pairs:
        return []
    n = matrix.shape[1]
    if n == 0:
        return [0] * len(pairs)
    safe = _in_guard(matrix)
    clean: BoolArray = np.asarray(safe.all(axis=1), dtype=bool)
    values = matrix if bool(clean.all()) else np.where(safe, matrix, 0.0)
    high = _SPLIT * values
    upper = high - (high - values)
    lower = values - upper
    out = np.empty((2 * len(pairs), n))
    for k, (i, j) in enumerate(pairs):
        product = np.multiply(values[i], values[j], out=out[k])
        error = np.multiply(upper[i], upper[j], out=out[len(pairs) + k])
        error -= product
        error += upper[i] * lower[j]
        error += lower[i] * upper[j]
        error += lower[i] * lower[j]
    sums = exact_sums(out, consume=True)
    totals = [sums[k] + sums[len(pairs) + k] for k in range(len(pairs))]
    for k, (i, j) in enumerate(pairs):
        if clean[i] and clean[j]:
            continue
        for c in np.flatnonzero(~(safe[i] & safe[j])):
            totals[k] += _scaled_product(float(matrix[i, c]), float(matrix[j, c]))
    return totals


def dyadic(value: float) -> Dyadic:
    """A finite float as ``(m, e)``."""
    numerator, denominator = value.as_integer_ratio()
    return numerator, 1 - denominator.bit_length()


def dyadic_le(left: Dyadic, right: Dyadic) -> bool:
    """``left <= right`` exactly."""
    (a, x), (b, y) = left, right
    if x <= y:
        return a <= b << (y - x)
    return a << (x - y) <= b


class Moments:
    """Exact moment matrix of ``m`` variables and the constant 1 over joint samples.

    ``values`` holds the upper triangle (row-major) of the ``(m+1) x (m+1)`` matrix of
    ``sum v_i v_j``, the last index standing for 1 (its diagonal entry is the count), every
    entry scaled by ``2**SCALE``.
    """

    __slots__ = ("count", "size", "values")

    def __init__(self, size: int, values: list[int] | None = None, count: int = 0) -> None:
        self.size = size
        self.count = count
        entries = (size + 1) * (size + 2) // 2
        self.values = values if values is not None else [0] * entries

    def __getstate__(self) -> tuple[int, int, list[int]]:
        return self.size, self.count, self.values

    def __setstate__(self, state: tuple[int, int, list[int]]) -> None:
        self.size, self.count, self.values = state

    def _position(self, i: int, j: int) -> int:
        if i > j:
            i, j = j, i
        dim = self.size + 1
        return i * dim - i * (i - 1) // 2 + (j - i)

    def entry(self, i: int, j: int) -> int:
        """``sum v_i v_j`` (index ``size`` is the constant 1), scaled."""
        return self.values[self._position(i, j)]

    def add(self, sums: dict[tuple[int, int], int], count: int) -> None:
        """Add a chunk's sums: ``sums[(i, j)]`` for ``i <= j <= size``."""
        for (i, j), value in sums.items():
            self.values[self._position(i, j)] += value
        self.count += count
        self.values[self._position(self.size, self.size)] += count << SCALE

    def merge(self, other: Moments) -> None:
        """Add another state's moments."""
        self.values = [a + b for a, b in zip(self.values, other.values, strict=True)]
        self.count += other.count

    def restrict(self, keep: Sequence[int]) -> Moments:
        """The moments of a subset of the variables (same samples)."""
        index = [*keep, self.size]
        out = Moments(len(keep), count=self.count)
        for a in range(len(index)):
            for b in range(a, len(index)):
                out.values[out._position(a, b)] = self.entry(index[a], index[b])
        return out

    def residual(self, weights: Sequence[Dyadic]) -> Dyadic:
        """``sum (w . (v, 1))**2`` exactly (unscaled) for dyadic weights over (vars, 1)."""
        terms: list[tuple[int, int]] = []
        dim = self.size + 1
        for i in range(dim):
            mi, ei = weights[i]
            if mi == 0:
                continue
            for j in range(i, dim):
                mj, ej = weights[j]
                if mj == 0:
                    continue
                factor = 1 if i == j else 2
                terms.append((factor * mi * mj * self.entry(i, j), ei + ej))
        if not terms:
            return 0, 0
        low = min(e for _, e in terms)
        total = sum(m << (e - low) for m, e in terms)
        return total, low - SCALE

    def solve(self, dependent: int, independents: Sequence[int]) -> list[Fraction] | None:
        """Least-squares coefficients of ``v_dep = sum a_k v_k + c`` (None if singular)."""
        columns = [*independents, self.size]
        dim = len(columns)
        matrix = [
            [Fraction(self.entry(r, c)) for c in columns] + [Fraction(self.entry(r, dependent))]
            for r in columns
        ]
        for col in range(dim):
            pivot = next((r for r in range(col, dim) if matrix[r][col] != 0), None)
            if pivot is None:
                return None
            matrix[col], matrix[pivot] = matrix[pivot], matrix[col]
            head = matrix[col][col]
            for r in range(dim):
                if r != col and matrix[r][col] != 0:
                    factor = matrix[r][col] / head
                    matrix[r] = [
                        a - factor * b for a, b in zip(matrix[r], matrix[col], strict=True)
                    ]
        return [matrix[r][dim] / matrix[r][r] for r in range(dim)]


def significant_digits(value: float) -> int:
    """Significant digits of the shortest repr of ``value`` (0 for zero)."""
    if value == 0:
        return 0
    text = repr(abs(value)).split("e")[0].replace(".", "").lstrip("0")
    return max(1, len(text.rstrip("0")))


def rounded(value: float, digits: int) -> float:
    """``value`` rounded to ``digits`` significant decimal digits (0 digits: zero)."""
    if digits <= 0 or value == 0:
        return 0.0
    return float(f"{value:.{digits - 1}e}")


class Fit:
    """One orientation of a relation: ``v_dep = sum a_k v_k + c`` over exact moments."""

    def __init__(
        self,
        moments: Moments,
        dependent: int,
        independents: Sequence[int],
        spread: Sequence[float],
        magnitude: Sequence[float],
    ) -> None:
        self.moments = moments
        self.dependent = dependent
        self.independents = tuple(independents)
        self.spread = spread
        self.magnitude = magnitude
        self.coefficients: tuple[float, ...] = ()
        self.tolerance = 0.0
        self.accepted = False
        solution = moments.solve(dependent, independents)
        if solution is None:
            return
        try:
            coefficients = tuple(float(c) for c in solution)
        except OverflowError:
            return
        if not all(math.isfinite(c) for c in coefficients):
            return
        terms = magnitude[dependent] + abs(coefficients[-1])
        terms += sum(
            abs(a) * magnitude[k] for a, k in zip(coefficients, independents, strict=False)
        )
        self.tolerance = 1e-9 * spread[dependent] + 1e-14 * terms
        if not math.isfinite(self.tolerance):
            return
        limit = dyadic(self.tolerance)
        self._limit = (limit[0] * limit[0], 2 * limit[1])
        if self.holds(coefficients):
            self.coefficients = self._shorten(coefficients)
            self.accepted = True

    def holds(self, coefficients: Sequence[float]) -> bool:
        """Whether every sample is within tolerance: exact residual sum <= tolerance**2."""
        weights: list[Dyadic] = [(0, 0)] * (self.moments.size + 1)
        weights[self.dependent] = (1, 0)
        for a, k in zip(coefficients, self.independents, strict=False):
            weights[k] = dyadic(-a)
        weights[self.moments.size] = dyadic(-coefficients[-1])
        return dyadic_le(self.moments.residual(weights), self._limit)

    def _shorten(self, exact: tuple[float, ...]) -> tuple[float, ...]:
        best = exact
        for digits in range(1, 18):
            candidate = tuple(rounded(v, digits) for v in exact)
            if self.holds(candidate):
                best = candidate
                break
        for position in range(len(best)):
            for digits in range(significant_digits(best[position])):
                trial = list(best)
                trial[position] = rounded(exact[position], digits)
                if self.holds(trial):
                    best = tuple(trial)
                    break
        return best

    def digits(self) -> int:
        """Total significant digits of the printed coefficients (1 and -1 count 0)."""
        total = 0
        for position, value in enumerate(self.coefficients):
            slope = position < len(self.coefficients) - 1
            if slope and abs(value) == 1:
                continue
            total += significant_digits(value)
        return total

    def readable(self) -> bool:
        """Whether every printed coefficient has at most ``READABLE`` significant digits."""
        return all(significant_digits(value) <= READABLE for value in self.coefficients)


def choose(fits: Sequence[Fit]) -> Fit | None:
    """The orientation to print: the first (canonical) one if readable, else the one with
    the fewest significant digits (earlier ones win ties)."""
    if not fits:
        return None
    if fits[0].readable():
        return fits[0]
    best = fits[0]
    for fit in fits[1:]:
        if fit.digits() < best.digits():
            best = fit
    return best
