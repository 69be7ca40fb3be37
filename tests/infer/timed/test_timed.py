"""Time-related families: known answers, the thesis' errata, windows, exact merging."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.infer.core import FinalizeContext, FloatArray, Invariant, Samples, Variable
from imrosc.infer.timed import (
    FrequencyState,
    RateState,
    StepState,
    TimedState,
    VarianceState,
    effective_width,
    make_states,
    window_mean,
    window_variance,
    windowed_moments,
    windowed_variances,
)
from imrosc.infer.timed.windows import Extremes, window_starts
from imrosc.ir import Tunables

EPOCH = 1.7e9
X = Variable("x", "float", topic="/a", path="x")
Y = Variable("y", "float", topic="/a", path="y")
States = TimedState


def samples(time: Sequence[float] | FloatArray, run: int = 0, **columns: Any) -> Samples:
    names = sorted(columns)
    variables = tuple(Variable(n, "float", topic="/a", path=n) for n in names)
    return Samples(
        "p",
        run,
        np.asarray(time, dtype=np.float64),
        {n: np.asarray(columns[n], dtype=np.float64) for n in names},
        variables,
    )


def context(confidence: float = 0.99, window: float = 1.0) -> FinalizeContext:
    return FinalizeContext(Tunables(window=window, confidence=confidence), (X, Y), "p")


def only(states: list[States], family: str) -> States:
    (state,) = [s for s in states if s.family == family]
    return state


def run_all(states: Sequence[States], runs: Sequence[Samples]) -> None:
    for chunk in runs:
        for state in states:
            state.update(chunk)
        for state in states:
            state.end_run()


def invariant(state: States, ctx: FinalizeContext | None = None) -> Invariant:
    (found,) = state.finalize(ctx or context())
    return found


def test_frequency_of_a_10hz_stream_is_10_and_ignores_the_warm_up() -> None:
    time = EPOCH + np.arange(200) / 10  # epoch seconds: 0.1 s steps round differently
    state = FrequencyState("/a", 1.0)
    state.update(samples(time))
    found = invariant(state)
    assert (found.params["min"], found.params["max"]) == (10.0, 10.0)
    assert found.params["window"] == 1.0
    assert found.text == "10 <= freq(/a) <= 10"
    # the first 10 messages come before a full window has passed: no value (not 1/window)
    assert found.samples == 190


def test_frequency_counts_the_warm_up_only_once_a_window_has_passed() -> None:
    state = FrequencyState("/a", 1.0)
    state.update(samples(EPOCH + np.arange(10) / 10))  # 0.9 s of data: never a full window
    state.end_run()
    assert state.finalize(context()) == []
    assert int(state.extremes.count[0]) == 0


def test_a_slowed_segment_lowers_freq_min() -> None:
    time = np.concatenate(
        [np.arange(0, 20, 0.1), 20 + np.arange(0, 5, 0.25), 25 + np.arange(0, 20, 0.1)]
    )
    state = FrequencyState("/a", 1.0)
    state.update(samples(EPOCH + time))
    found = invariant(state)
    assert found.params["min"] == 4.0  # 4 Hz for five seconds
    assert found.params["max"] == 10.0


def test_variance_of_a_stuck_sensor_is_zero() -> None:
    time = EPOCH + np.arange(300) / 30
    state = VarianceState(("x",), 1.0)
    state.update(samples(time, x=np.full(300, 0.1)))
    found = invariant(state)
    assert (found.params["min"], found.params["max"]) == (0.0, 0.0)


def test_variance_matches_numpy_and_the_sample_definition() -> None:
    rng = np.random.default_rng(3)
    time = np.sort(rng.uniform(0, 30, 600))
    values = rng.normal(5, 2, 600)
    state = VarianceState(("x",), 2.0)
    state.update(samples(time, x=values))
    cut = time - effective_width(2.0)
    expected = [
        np.var(values[(time > c) & (np.arange(600) <= i)], ddof=1)
        for i, c in enumerate(cut)
        if c >= time[0] and np.count_nonzero((time > c) & (np.arange(600) <= i)) >= 2
    ]
    found = invariant(state)
    assert found.params["min"] == pytest.approx(min(expected), rel=1e-12)
    assert found.params["max"] == pytest.approx(max(expected), rel=1e-12)


def test_rate_of_x_equal_2t_is_2() -> None:
    time = EPOCH + np.arange(100) / 10
    state = RateState(("x",), 1.0)
    state.update(samples(time, x=2 * (time - EPOCH)))
    found = invariant(state)
    assert (found.params["min"], found.params["max"]) == (2.0, 2.0)
    assert found.text == "2 <= rate(x) <= 2"


def test_rate_of_steady_and_jittered_streams_matches_each_window() -> None:
    """Windows of a steady stream (consecutive starts: read as slices) and of a jittered one
    with repeated stamps (gathered), fed in chunks: the bounds are the per-window
    ``(last - first) / (t_last - t_first)`` extremes, bit for bit."""
    rng = np.random.default_rng(8)
    for time in (
        EPOCH + np.arange(900) / 50,
        EPOCH + np.sort(np.repeat(rng.uniform(0, 18, 450), 2)),
    ):
        values = np.cumsum(rng.normal(size=900))
        state = RateState(("x",), 1.0)
        for start in range(0, 900, 128):
            state.update(samples(time[start : start + 128], x=values[start : start + 128]))
        starts = window_starts(time, 1.0)
        rates = [
            (values[i] - values[j]) / (time[i] - time[j])
            for i, j in enumerate(starts.tolist())
            if time[0] <= time[i] - effective_width(1.0) and time[i] > time[j]
        ]
        found = invariant(state)
        assert (found.params["min"], found.params["max"]) == (min(rates), max(rates))


def _thesis_algorithm_4(time: FloatArray, values: FloatArray, window: float) -> tuple[float, float]:
    """Algorithm 4 as printed: ``min(rate, rate_max)`` and ``Float.min_value`` start."""
    rate_max, rate_min = 1.4e-45, math.inf
    first = 0
    for i in range(len(time)):
        while time[i] - time[first] > window:
            first += 1
        if i - first + 1 > 1:
            rate = (values[i] - values[first]) / (time[i] - time[first])
            rate_max = max(rate, rate_max)
            rate_min = min(rate, rate_max)
    return rate_min, rate_max


def test_rate_errata_min_tracks_rate_min_and_max_starts_at_minus_infinity() -> None:
    time = np.arange(0, 30, 0.1)
    slope = np.where(time < 10, -3.0, np.where(time < 20, -1.0, -2.0))
    values = np.concatenate([[0.0], np.cumsum(slope[:-1] * 0.1)])
    state = RateState(("x",), 1.0)
    state.update(samples(time, x=values))
    found = invariant(state)
    assert found.params["min"] == pytest.approx(-3.0)
    assert found.params["max"] == pytest.approx(-1.0)
    printed_min, printed_max = _thesis_algorithm_4(time, values, 1.0)
    assert printed_max == 1.4e-45  # a falling signal never beats Float.min_value
    assert printed_min != pytest.approx(-3.0)  # min(rate, rate_max) forgets the minimum


def test_windows_never_span_runs() -> None:
    first = EPOCH + np.arange(30) / 10
    second = first[-1] + 0.1 + np.arange(30) / 10
    runs = [samples(first, 0, x=np.arange(30.0)), samples(second, 1, x=np.arange(30.0))]
    states: list[States] = make_states((X,), Tunables(), {"frequency", "variance", "rate"})
    run_all(states, runs)
    joined: list[States] = make_states((X,), Tunables(), {"frequency", "variance", "rate"})
    run_all(joined, [samples(np.concatenate([first, second]), x=np.arange(60.0) % 30)])
    # each run has its own warm-up: 20 defined windows per run, not 50 in one
    assert int(only(states, "frequency").extremes.count[0]) == 40
    assert int(only(joined, "frequency").extremes.count[0]) == 50
    # the jump between runs never shows as a rate
    assert invariant(only(states, "rate")).params["min"] == pytest.approx(10.0)
    assert invariant(only(joined, "rate")).params["min"] < 0


def test_justification_needs_samples_since_the_last_change() -> None:
    time = EPOCH + np.arange(16) / 10  # 6 defined windows: 1 - 2**-6 < 0.99
    state = FrequencyState("/a", 1.0)
    state.update(samples(time))
    assert state.finalize(context()) == []
    state.update(samples(EPOCH + 1.6 + np.arange(2) / 10))
    found = invariant(state)
    assert found.samples == 8
    assert found.confidence == 1 - 2**-8
    # a bound that changed on the last sample is not justified
    late = VarianceState(("x",), 1.0)
    values = np.concatenate([np.zeros(59), [100.0]])
    late.update(samples(EPOCH + np.arange(60) / 10, x=values))
    assert late.finalize(context()) == []


def test_nan_and_infinite_samples_only_void_their_windows() -> None:
    time = EPOCH + np.arange(100) / 10
    values = 2 * (time - EPOCH)
    values[50] = np.nan
    values[70] = np.inf
    state = RateState(("x",), 1.0)
    state.update(samples(time, x=values))
    found = invariant(state)
    assert (found.params["min"], found.params["max"]) == (2.0, 2.0)
    # windows ending at or starting on a broken sample have no rate
    assert int(state.extremes.count[0]) == 90 - 4  # windows ending at 50, 59, 70, 79


def test_make_states_follows_the_enabled_families_and_variable_kinds() -> None:
    variables = (
        X,
        Variable("len(scan.ranges)", "int", topic="/a", derived="len"),
        Variable("other.z", "float", topic="/b", trigger=False),
        Variable("label", "string", topic="/a"),
    )
    states = make_states(variables, Tunables(window=2.0), {"frequency", "rate", "bounds"})
    assert [s.family for s in states] == ["frequency", "rate"]
    rate = only(states, "rate")
    assert isinstance(rate, RateState)
    assert rate.names == ("x",)
    assert rate.window == 2.0
    assert make_states((), Tunables(), {"variance"}) == []


def test_frequency_topic_falls_back_to_the_point() -> None:
    state = only(make_states((), Tunables(), {"frequency"}), "frequency")
    state.update(samples(EPOCH + np.arange(50) / 10))
    found = invariant(state)
    assert found.text == "10 <= freq(p) <= 10"
    assert found.params["topic"] == "p"


def test_merge_rejects_other_states() -> None:
    with pytest.raises(TypeError):
        FrequencyState("/a", 1.0).merge(VarianceState(("x",), 1.0))
    with pytest.raises(ValueError, match="window"):
        FrequencyState("/a", 1.0).merge(FrequencyState("/a", 2.0))
    with pytest.raises(ValueError, match="positive"):
        FrequencyState("/a", 0.0)


# --- the fixed variance algorithm -------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e9, max_value=1e9),
        min_size=2,
        max_size=80,
    ),
    st.data(),
)
def test_vectorised_variance_equals_the_reference_bit_for_bit(
    values: list[float], data: st.DataObject
) -> None:
    column = np.array(values)[:, None]
    count = data.draw(st.integers(1, 12))
    length = np.array(
        data.draw(st.lists(st.integers(2, len(values)), min_size=count, max_size=count))
    )
    start = np.array([data.draw(st.integers(0, len(values) - n)) for n in length.tolist()])
    got = windowed_variances(column, start, length)[:, 0]
    for k in range(count):
        window = values[int(start[k]) : int(start[k] + length[k])]
        want = window_variance(window)
        assert got[k] == want or (math.isnan(got[k]) and math.isnan(want))


def test_window_means_are_the_variance_algorithm_s_means_bit_for_bit() -> None:
    """The mean a window's variance carries, on both of inference's paths (few distinct
    lengths: grouped; many: bit masks), is the reference algorithm's, and near numpy's."""
    rng = np.random.default_rng(3)
    values = rng.normal(size=(400, 2)) * 1e3 + 9.81
    for lengths in (rng.integers(2, 5, 200), rng.integers(2, 120, 200)):
        start = rng.integers(0, 400 - 120, 200)
        means, variances = windowed_moments(values, start, lengths)
        assert np.array_equal(variances, windowed_variances(values, start, lengths))
        for k in range(200):
            window = values[start[k] : start[k] + lengths[k]]
            for c in range(2):
                assert means[k, c] == window_mean(window[:, c].tolist())
            assert np.allclose(means[k], window.mean(axis=0), rtol=1e-12)
    assert math.isnan(window_mean([1.0]))


def test_steady_windows_read_as_slices_equal_the_reference_bit_for_bit() -> None:
    """One length and consecutive starts (a steady rate) take the blocks as slices of the
    levels; one length with gaps between starts, and two lengths, gather them: every path
    gives the reference's mean and variance, and leaves the data as it was."""
    rng = np.random.default_rng(11)
    values = rng.normal(size=(300, 3)) * 1e4 + 1e3
    before = values.copy()
    for start, length in (
        (np.arange(20, 220), np.full(200, 77)),
        (np.arange(0, 200, 2), np.full(100, 100)),
        (np.arange(10, 210), np.where(np.arange(200) % 2 == 0, 64, 65)),
    ):
        means, variances = windowed_moments(values, start, length)
        for k in range(len(start)):
            window = values[start[k] : start[k] + length[k]]
            for c in range(3):
                assert variances[k, c] == window_variance(window[:, c].tolist())
                assert means[k, c] == window_mean(window[:, c].tolist())
    assert np.array_equal(values, before)


def test_a_scaled_sensor_breaks_its_mean_but_not_its_bounds() -> None:
    """Noise around 9.81 with shocks to 25: a reading scaled by 1.5 stays within the bounds
    and leaves the window mean's envelope."""
    rng = np.random.default_rng(5)
    time = (EPOCH + np.arange(2000) * 0.01).tolist()
    good = 9.81 + rng.normal(0, 2.0, 2000)
    good[::400] = 25.0
    states = make_states((X,), Tunables(window=1.0), {"mean"})
    run_all(states, [samples(time, 0, x=good)])
    (mean,) = states[0].finalize(context())
    scaled = 9.81 * 1.5 + rng.normal(0, 2.0 * 1.5, 2000)
    assert float(np.max(scaled)) < 25.0 and float(np.min(scaled)) > float(np.min(good))
    states = make_states((X,), Tunables(window=1.0), {"mean"})
    run_all(states, [samples(time, 0, x=scaled)])
    (moved,) = states[0].finalize(context())
    assert moved.params["min"] > mean.params["max"]


def test_the_bit_mask_path_equals_the_grouped_path() -> None:
    rng = np.random.default_rng(0)
    values = rng.normal(size=(400, 3)) * 1e4 + 7
    length = rng.integers(2, 120, 300)  # many distinct lengths: the bit-mask path
    start = rng.integers(0, 400 - 120, 300)
    got = windowed_variances(values, start, length)
    for k in range(300):
        for c in range(3):
            assert got[k, c] == window_variance(values[start[k] : start[k] + length[k], c].tolist())


def test_constant_windows_have_exactly_zero_variance() -> None:
    for value in (0.1, -3.3e7, 1e-300, 12345.678):
        assert window_variance([value] * 37) == 0.0
    assert math.isnan(window_variance([1.0]))


# --- brute force and exact merging ------------------------------------------------------


def brute(time: FloatArray, values: FloatArray, window: float) -> dict[str, list[float]]:
    """Every defined window's frequency, variance, rate and mean, straight from the
    definition (a window is defined once the first sample of its stretch has left it; a
    sample whose predecessor has left its window begins a stretch)."""
    cut = time - effective_width(window)
    out: dict[str, list[float]] = {"frequency": [], "variance": [], "rate": [], "mean": []}
    stretch = 0
    for i in range(len(time)):
        if i and time[i - 1] <= cut[i]:
            stretch = i
        if cut[i] < time[stretch]:
            continue
        first = int(np.searchsorted(time, cut[i], side="right"))
        members = values[first : i + 1]
        out["frequency"].append((i - first + 1) / window)
        if len(members) >= 2:
            var = window_variance(members.tolist())
            if math.isfinite(var):
                out["variance"].append(var)
            mean = window_mean(members.tolist())
            if math.isfinite(mean):
                out["mean"].append(mean)
            if time[i] > time[first]:
                with np.errstate(invalid="ignore"):
                    rate = (values[i] - values[first]) / (time[i] - time[first])
                if math.isfinite(rate):
                    out["rate"].append(rate)
    return out


def summary(state: States) -> tuple[Any, ...]:
    e: Extremes = state.extremes
    return (
        e.count.tolist(),
        e.low.tolist(),
        e.low_at.tolist(),
        e.high.tolist(),
        e.high_at.tolist(),
    )


streams = st.lists(
    st.tuples(
        st.sampled_from([0.0, 0.01, 0.05, 0.1, 0.1, 0.1, 0.3, 1.1]),
        st.one_of(
            st.floats(-100, 100, allow_nan=False),
            st.sampled_from([0.0, 1.0, 1.0, math.nan, math.inf]),
        ),
    ),
    min_size=1,
    max_size=120,
)


def _cut(length: int, points: list[int]) -> list[tuple[int, int]]:
    edges = sorted({0, length, *[p % (length + 1) for p in points]})
    return list(itertools.pairwise(edges))


@settings(max_examples=60, deadline=None)
@given(
    streams,
    st.lists(st.integers(0, 200), max_size=4),
    st.lists(st.integers(0, 200), max_size=8),
    st.sampled_from([0.25, 0.5, 1.0]),
)
def test_fold_merge_and_rechunking_agree_exactly(
    stream: list[tuple[float, float]],
    run_points: list[int],
    chunk_points: list[int],
    window: float,
) -> None:
    gaps = np.array([g for g, _ in stream])
    time = EPOCH + np.cumsum(gaps)
    values = np.array([v for _, v in stream])
    runs = _cut(len(stream), run_points)
    tunables = Tunables(window=window)
    families = {"frequency", "variance", "rate", "mean"}

    def fresh() -> list[States]:
        return make_states((X,), tunables, families)

    # fold: one state, runs in order, each run cut into chunks
    folded = fresh()
    for index, (a, b) in enumerate(runs):
        for c, d in _cut(b - a, chunk_points):
            chunk = samples(time[a + c : a + d], index, x=values[a + c : a + d])
            for state in folded:
                state.update(chunk)
        for state in folded:
            state.end_run()
    # merge: one state per run (whole), merged in run order
    merged = fresh()
    for index, (a, b) in enumerate(runs):
        mine = fresh()
        run_all(mine, [samples(time[a:b], index, x=values[a:b])])
        for state, other in zip(merged, mine, strict=True):
            state.merge(other)
    # brute force over each run
    want: dict[str, list[float]] = {"frequency": [], "variance": [], "rate": [], "mean": []}
    for a, b in runs:
        for family, found in brute(time[a:b], values[a:b], window).items():
            want[family] += found
    ctx = context(window=window)
    for fold_state, merge_state in zip(folded, merged, strict=True):
        assert summary(fold_state) == summary(merge_state)
        assert fold_state.finalize(ctx) == merge_state.finalize(ctx)
        expected = want[fold_state.family]
        extremes = fold_state.extremes
        assert int(extremes.count[0]) == len(expected)
        if expected:
            assert float(extremes.low[0]) == min(expected)
            assert float(extremes.high[0]) == max(expected)
            assert int(extremes.low_at[0]) == expected.index(min(expected))
            assert int(extremes.high_at[0]) == expected.index(max(expected))


@settings(max_examples=60, deadline=None)
@given(
    streams,
    st.lists(st.integers(0, 200), max_size=5),
    st.lists(st.integers(0, 200), max_size=8),
    st.sampled_from([0.25, 0.5, 1.0]),
)
def test_a_condition_s_episodes_restart_windows_as_runs_do(
    stream: list[tuple[float, float]],
    episode_points: list[int],
    chunk_points: list[int],
    window: float,
) -> None:
    """Samples marked as restarts (an episode of the point's condition begins) give the
    windows of one run per episode, however the run is cut into chunks."""
    time = EPOCH + np.cumsum([g for g, _ in stream])
    values = np.array([v for _, v in stream])
    episodes = _cut(len(stream), episode_points)
    restarts = np.zeros(len(stream), dtype=bool)
    restarts[[a for a, _ in episodes]] = True
    restarts[0] = False  # a run's first sample needs none
    tunables = Tunables(window=window)
    families = {"frequency", "variance", "rate", "mean"}
    marked = make_states((X,), tunables, families)
    for c, d in _cut(len(stream), chunk_points):
        chunk = samples(time[c:d], x=values[c:d])
        chunk.restarts = restarts[c:d]
        for state in marked:
            state.update(chunk)
    apart = make_states((X,), tunables, families)
    run_all(apart, [samples(time[a:b], x=values[a:b]) for a, b in episodes])
    for one, other in zip(marked, apart, strict=True):
        assert summary(one) == summary(other)


def test_step_is_the_change_between_a_window_s_last_two_messages() -> None:
    time = EPOCH + np.arange(200) / 10
    x = np.sin(time - EPOCH)  # steps of at most 0.1 over a range of 2
    state = StepState(("x",), 1.0)
    state.update(samples(time, x=x))
    found = invariant(state)
    defined = np.diff(x)[9:]  # the windows defined once a second has passed
    assert (found.params["min"], found.params["max"]) == (defined.min(), defined.max())
    assert found.text.startswith("-0.0") and " <= step(x) <= 0.0" in found.text


def test_a_step_that_can_span_the_range_is_not_kept() -> None:
    time = EPOCH + np.arange(100) / 10
    state = StepState(("x",), 1.0)
    state.update(samples(time, x=np.tile([0.0, 1.0], 50)))  # every step spans the range
    assert state.finalize(context()) == []


def test_step_states_merge_exactly() -> None:
    time = EPOCH + np.arange(200) / 10
    x = np.cumsum(np.random.default_rng(3).normal(size=200))
    whole, first, second = (StepState(("x",), 1.0) for _ in range(3))
    run_all([whole], [samples(time[:100], x=x[:100]), samples(time[100:], 1, x=x[100:])])
    run_all([first], [samples(time[:100], x=x[:100])])
    run_all([second], [samples(time[100:], 1, x=x[100:])])
    first.merge(second)
    assert invariant(first).params == invariant(whole).params
