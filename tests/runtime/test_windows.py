"""The online windows of the runtime against inference's vectorised windows, bit for bit."""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.timed import effective_width, window_starts, window_variance
from imrosc.infer.timed.windows import WindowTracker, windowed_moments
from imrosc.runtime.windows import Windows
from imrosc.runtime.windows import effective_width as runtime_width

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

GAPS = st.one_of(
    st.sampled_from([0.0, 0.0, 1e-9, 1e-6, 0.001, 0.01, 0.1, 0.125, 0.5, 0.999999, 1.0]),
    st.floats(0.0, 1.5),
)
SPECIAL = np.array(
    [0.0, -0.0, 1.0, 0.1, 1e300, -1e300, 5e-324, -7.5, math.nan, math.inf, -math.inf]
)
WIDTHS = st.sampled_from([1.0, 0.5, 2.0, 0.3, 1e-4, 0.1])


def stretch_start(times: FloatArray, window: float) -> float:
    """The time of the first sample of the last stretch: the run's first, or the last one
    whose predecessor had left its window (a silence longer than the window)."""
    width = effective_width(window)
    begins = [0] + [i for i in range(1, len(times)) if times[i - 1] <= times[i] - width]
    return float(times[begins[-1]])


def bits(values: FloatArray) -> list[int]:
    """The float64 bit patterns, every NaN made one."""
    canonical = np.where(np.isnan(values), np.nan, values)
    return np.asarray(canonical, dtype=np.float64).view(np.uint64).tolist()  # type: ignore[no-any-return]


@st.composite
def streams(draw: st.DrawFn) -> tuple[float, FloatArray, FloatArray, list[int]]:
    """``(window, times, values, chunk cuts)`` of one run."""
    window = draw(WIDTHS)
    size = draw(st.integers(1, 40))
    width = draw(st.integers(1, 3))
    start = draw(st.sampled_from([0.0, 1.7e9, 12.3]))
    gaps = draw(st.lists(GAPS, min_size=size, max_size=size))
    times = start + np.cumsum(np.asarray(gaps, dtype=np.float64))
    times = np.maximum.accumulate(times)  # float rounding keeps order, but make sure
    # values: noise at a drawn scale, with special values (NaN, huge, tiny, signed zeros)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = draw(st.sampled_from([1.0, 1e-3, 1e8]))
    values = rng.normal(draw(st.sampled_from([0.0, 1e6])), scale, (size, width))
    special = rng.random((size, width)) < draw(st.sampled_from([0.0, 0.1, 0.5]))
    values[special] = rng.choice(SPECIAL, int(special.sum()))
    if draw(st.booleans()):
        values = np.round(values)  # many equal values: constant windows
    cuts = sorted(set(draw(st.lists(st.integers(1, size), max_size=3))))
    return window, times, values, cuts


def inference(
    window: float, times: FloatArray, values: FloatArray, cuts: list[int]
) -> dict[int, tuple[float, FloatArray, FloatArray, FloatArray]]:
    """Per defined window (by the index of its last sample): frequency, variance, rate and
    mean, as inference's states compute them, chunk by chunk."""
    tracker = WindowTracker(window, values.shape[1])
    found: dict[int, tuple[float, FloatArray, FloatArray, FloatArray]] = {}
    bounds = [0, *cuts, len(times)]
    for lo, hi in itertools.pairwise(bounds):
        if lo == hi:
            continue
        all_time, all_values, ends, starts = tracker.advance(times[lo:hi], values[lo:hi])
        offset = hi - len(all_time)  # absolute index of all_time[0]
        frequency = (ends - starts + 1) / window  # FrequencyState
        length = ends - starts + 1
        keep = length >= 2
        variance = np.full((len(ends), values.shape[1]), np.nan)
        mean = np.full((len(ends), values.shape[1]), np.nan)
        mean[keep], variance[keep] = windowed_moments(all_values, starts[keep], length[keep])
        dt = all_time[ends] - all_time[starts]  # RateState
        with np.errstate(all="ignore"):
            rate = (all_values[ends] - all_values[starts]) / dt[:, None]
        rate[~(dt > 0)] = np.nan
        for k, end in enumerate(ends.tolist()):
            found[offset + end] = (float(frequency[k]), variance[k], rate[k], mean[k])
    return found


@settings(max_examples=150, deadline=None)
@given(streams())
def test_windows_agree_with_inference_bit_for_bit(
    stream: tuple[float, FloatArray, FloatArray, list[int]],
) -> None:
    window, times, values, cuts = stream
    expected = inference(window, times, values, cuts)
    online = Windows(window, values.shape[1])
    starts = window_starts(times, window)
    for i, (time, row) in enumerate(zip(times.tolist(), values, strict=True)):
        defined = online.add(time, row.tolist())
        assert defined == (i in expected)
        assert online.size() == i - int(starts[i]) + 1
        assert online.last_time() == time
        if not defined:
            continue
        frequency, variance, rate, mean = expected[i]
        assert online.frequency() == frequency
        assert bits(online.variance()) == bits(variance)
        assert bits(online.rate()) == bits(rate)
        assert bits(online.mean()) == bits(mean)


@settings(max_examples=100, deadline=None)
@given(streams())
def test_variance_is_the_reference_algorithm(
    stream: tuple[float, FloatArray, FloatArray, list[int]],
) -> None:
    window, times, values, _ = stream
    online = Windows(window, values.shape[1])
    starts = window_starts(times, window)
    for i, time in enumerate(times.tolist()):
        online.add(time, values[i])
        got = online.variance()
        for col in range(values.shape[1]):
            reference = window_variance(values[int(starts[i]) : i + 1, col].tolist())
            assert bits(np.asarray([got[col]])) == bits(np.asarray([reference]))


@settings(max_examples=100, deadline=None)
@given(streams(), st.lists(st.floats(0.0, 3.0), min_size=1, max_size=5))
def test_timer_queries_match_a_window_ending_then(
    stream: tuple[float, FloatArray, FloatArray, list[int]], delays: list[float]
) -> None:
    window, times, values, _ = stream
    online = Windows(window, values.shape[1])
    assert not online.defined_at(float(times[0]) + 10 * window)  # nothing seen yet
    assert math.isnan(online.last_time())
    for time, row in zip(times.tolist(), values, strict=True):
        online.add(time, row)
    width = effective_width(window)
    last = float(times[-1])
    for delay in sorted(delays):
        now = last + delay
        cutoff = now - width
        # a sample at ``now`` would see the samples after the cutoff, plus itself
        expected = len(times) - int(np.searchsorted(times, cutoff, side="right"))
        assert online.size_at(now) == expected
        assert online.defined_at(now) == (stretch_start(times, window) <= cutoff)


def test_effective_width_is_inferences() -> None:
    for window in (1.0, 0.5, 2.0, 1e-4, 1e-3, 0.1, 3600.0):
        assert runtime_width(window) == effective_width(window)


def test_a_10hz_stream_on_epoch_seconds_counts_10_per_window() -> None:
    online = Windows(1.0, 1)
    times = 1.7e9 + np.arange(40) / 10
    frequencies = [online.frequency() for t in times.tolist() if online.add(t, [t])]
    assert frequencies == [10.0] * 30


def test_long_irregular_streams_and_eviction() -> None:
    """Thousands of samples (the window's storage is compacted) and many window lengths
    (inference switches to its bit-mask path): still bit for bit."""
    rng = np.random.default_rng(7)
    size = 6000
    gaps = rng.exponential(0.01, size)
    gaps[rng.random(size) < 0.1] = 0.0  # equal times
    times = 1.7e9 + np.cumsum(gaps)
    values = np.stack([rng.normal(0, 1, size), rng.normal(1e6, 1e-3, size)], axis=1)
    values[rng.random(size) < 0.01, 0] = np.nan
    for window, cuts in ((2.0, [1000, 4000]), (0.05, [])):
        expected = inference(window, times, values, cuts)
        online = Windows(window, 2)
        checked = 0
        for i in range(size):
            if not online.add(float(times[i]), values[i]):
                assert i not in expected
                continue
            frequency, variance, rate, mean = expected[i]
            assert online.frequency() == frequency
            assert bits(online.variance()) == bits(variance)
            assert bits(online.rate()) == bits(rate)
            assert bits(online.mean()) == bits(mean)
            checked += 1
        assert checked == len(expected) > size // 2
        assert online.base > 0  # old samples were dropped


def test_reset_starts_a_new_run() -> None:
    online = Windows(1.0, 1)
    for i in range(30):
        online.add(i * 0.125, [float(i)])
    assert online.defined_at(4.0)
    online.reset()
    assert not online.defined_at(4.0)
    assert online.size() == 0
    assert not online.add(10.0, [1.0])  # warm-up again
    assert not online.add(10.5, [2.0])
    assert online.add(11.0, [3.0])
    assert online.size() == 2  # the sample at 10.0 is one window old
    assert online.rate().tolist() == [2.0]
    assert online.variance().tolist() == [0.5]


def test_a_silence_longer_than_the_window_begins_a_stretch() -> None:
    """After a pause the windows warm up again, as at a run's start: a live monitor, one
    run for its whole life, would otherwise judge a rate over two samples 0.05 s apart.
    Inference computes the same windows."""
    times = np.concatenate([np.arange(0.0, 3.0, 0.05), 30.0 + np.arange(0.0, 3.0, 0.05)])
    values = np.sin(times)[:, None]
    online = Windows(1.0, 1)
    defined = [i for i, t in enumerate(times.tolist()) if online.add(t, values[i])]
    after = [float(times[i]) for i in defined if times[i] >= 30.0]
    assert after[0] == pytest.approx(31.0)  # not 30.05, whose window holds two samples
    assert sorted(inference(1.0, times, values, [70])) == defined
    assert online.defined_at(33.5)  # the silence timer's queries: the stretch's warm-up
    silent = Windows(1.0, 1)
    for t in (0.0, 0.5, 1.0, 1.5):
        silent.add(t, [t])
    assert silent.defined_at(4.9) and silent.size_at(4.9) == 0  # a silence to report
    assert not silent.add(5.0, [5.0])  # it begins a stretch
    assert not silent.defined_at(5.5)
    assert silent.defined_at(6.0)


def test_undefined_statistics_are_nan() -> None:
    online = Windows(1.0, 2)
    online.add(0.0, [1.0, 2.0])
    assert np.isnan(online.variance()).all()
    assert np.isnan(online.rate()).all()  # one sample: no time span
    online.add(0.0, [2.0, 4.0])
    assert np.isnan(online.rate()).all()  # two samples at the same time
    assert online.variance().tolist() == [0.5, 2.0]
