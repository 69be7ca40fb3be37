"""bench/alfa_detector.py's pieces: the window statistics its variants add (the base ones as
the runtime computes them), the CUSUM, the residual model, the runs a fold learns from and
the fit cut at a horizon. The bench itself is not run (it reads the ALFA flights)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench import alfa_detector as a
from bench.alfa_detector import products
from imrosc import detectors
from imrosc.runtime.detector import features


def test_window_stats_are_the_runtime_statistics() -> None:
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.02, 0.09, 200))
    values = rng.normal(size=(200, 3))
    found = a.window_stats(times, values, 1.0)
    assert np.allclose(found, features(times, values, 1.0))


def test_slope_of_a_ramp_is_its_gradient() -> None:
    times = np.arange(0.0, 5.0, 0.05)
    values = np.column_stack([3.0 * times + 1.0, np.full(len(times), 2.0)])
    slope = a.window_stats(times, values, 1.0, slope=True)[:, 6:]
    assert np.allclose(slope[30:, 0], 3.0)
    assert np.allclose(slope[:, 1], 0.0)


def test_cusum_accumulates_the_score_above_its_drift_in_seconds() -> None:
    times = np.arange(0.0, 4.0, 0.5)
    found = a.cusum(times, np.full(len(times), 3.0), 1.0, 1.0)
    assert all(math.isnan(v) for v in found[:2])
    assert np.allclose(found[2:], 2.0 * (times[2:] - 1.0))
    assert np.allclose(a.cusum(times, np.full(len(times), -3.0), 1.0, 0.0)[2:], 0.0)


def test_residuals_show_a_broken_relation() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(size=(500, 2))
    kept = np.column_stack([x[:, 0], 2.0 * x[:, 0] + 0.01 * x[:, 1]])
    model = a.Residuals([kept])
    broken = kept.copy()
    broken[:, 1] += 1.0
    assert np.abs(model.of(kept)[:, 1]).mean() < 0.05
    assert np.abs(model.of(broken)[:, 1]).mean() > 0.5


def test_a_fault_flight_gives_its_part_before_the_onset_and_itself_whole() -> None:
    times = np.arange(100.0, 110.0, 0.5)
    info: dict[str, Any] = {"start_ns": 99_000_000_000, "onset_ns": 105_000_000_000, "onset_s": 6.0}
    good: dict[str, Any] = {"start_ns": 99_000_000_000, "onset_ns": None}
    flights = {"f": (info, times, np.ones((20, 1))), "g": (good, times, np.ones((20, 1)))}
    runs = a.runs_of(["f", "g"], flights, lambda t, v: v)
    assert [(r.name, r.onset, len(r.times)) for r in runs] == [
        ("f (before)", None, 10),
        ("f", 6.0, 20),
        ("g", None, 20),
    ]
    assert runs[1].faulty.sum() == 10 and not runs[0].faulty.any()


def test_the_horizon_leaves_the_later_faulty_samples_out_of_the_fit() -> None:
    rng = np.random.default_rng(7)
    times = np.arange(0.0, 20.0, 0.1)
    stats = rng.normal(size=(len(times), 2))
    stats[100:, 0] += 1.0
    stats[130:, 1] += 5.0  # only after the horizon
    runs = [
        detectors.Run("f", 0.0, 10.0, times, stats),
        detectors.Run("g", 0.0, None, times[:100], stats[:100]),
    ]
    cut = a.with_horizon(2.0)(runs, 1.0)
    keep = times < 12.0
    alone = detectors.fit([detectors.Run("f", 0.0, 10.0, times[keep], stats[keep]), runs[1]], 1.0)
    assert np.allclose(cut.weights, alone.weights)
    assert not np.allclose(a.with_horizon(None)(runs, 1.0).weights, cut.weights)


def test_relations_show_a_variable_leaving_what_the_others_say_it_is() -> None:
    rng = np.random.default_rng(11)
    x = rng.normal(size=(800, 3))
    kept = np.column_stack([x[:, 0], 3.0 * x[:, 0] + 0.1 * x[:, 1], x[:, 2]])
    relations = a.Relations(kept)
    assert np.allclose(relations.of(kept).std(axis=0), 1.0)
    broken = kept.copy()
    broken[:, 1] += 1.0  # ten nominal spreads of its relation to the first
    assert np.abs(relations.of(kept)[:, 1]).mean() < 1.0
    assert np.abs(relations.of(broken)[:, 1]).mean() > 5.0
    assert np.abs(relations.of(broken)[:, 2]).mean() < 1.5  # unrelated to the others


def test_products_are_every_pair_once_squares_included() -> None:
    z = np.array([[1.0, 2.0, 3.0]])
    assert products(z).tolist() == [[1.0, 2.0, 3.0, 4.0, 6.0, 9.0]]


def test_squashed_is_odd_about_the_nominal_median_in_its_deviation_units() -> None:
    nominal = np.array([[0.0, 5.0], [1.0, 5.0], [2.0, 5.0], [3.0, 5.0], [4.0, 5.0]])
    rows = np.array([[2.0, 5.0], [3.0, 6.0], [1.0, 4.0], [1002.0, 5.0]])
    found = a.squashed(rows, nominal)
    assert found[0].tolist() == [0.0, 0.0]
    assert math.isclose(found[1, 0], math.asinh(1.0)) and math.isclose(found[1, 1], math.asinh(1.0))
    assert math.isclose(found[2, 0], -found[1, 0])
    assert found[3, 0] < 8.0  # a thousand units away: logarithmic, not linear


def test_probability_evidence_is_the_mean_probability() -> None:
    times = np.arange(0.0, 4.0, 0.5)
    scores = np.array([0.0, 0.0, 0.0, 0.0, math.inf, -math.inf, 0.0, 0.0])
    found = a.probability(times, scores, 1.0, 1.0)
    assert all(math.isnan(v) for v in found[:4])
    assert np.allclose(found[4:], [0.75, 0.5, 0.25, 0.5])


def test_the_mean_of_fold_models_scores_their_mean() -> None:
    rng = np.random.default_rng(13)
    times = np.arange(0.0, 30.0, 0.1)
    stats = rng.normal(size=(len(times), 3)) * [1.0, 5.0, 0.1] + [0.0, 2.0, -1.0]
    stats[200:, 0] += 2.0
    run = detectors.Run("f", 0.0, 20.0, times, stats)
    other = detectors.Run("g", 0.0, 20.0, times, stats[::-1].copy())
    recorded = a.Recorded(detectors.fit)
    models = [recorded([run], 1.0), recorded([run, other], 1.0), recorded([other], 10.0)]
    assert [len(v) for v in recorded.models.values()] == [2, 1]
    mean = a.Linear.mean_of(recorded.models[1.0])
    assert np.allclose(mean.scores(run), (models[0].scores(run) + models[1].scores(run)) / 2)
    recorded.forget()
    assert not recorded.models


def test_once_a_fault_flight_is_not_also_a_good_run() -> None:
    times = np.arange(100.0, 110.0, 0.5)
    info: dict[str, Any] = {"start_ns": 99_000_000_000, "onset_ns": 105_000_000_000, "onset_s": 6.0}
    flights = {"f": (info, times, np.ones((20, 1)))}
    runs = a.runs_of(["f"], flights, lambda t, v: v, "once")
    assert [(r.name, r.onset, len(r.times)) for r in runs] == [("f", 6.0, 20)]


def test_adapted_models_absorb_a_flights_regime_and_show_a_change_of_dynamics() -> None:
    """An AR(1) process: the adapted model's innovations keep their own spread while the
    dynamics hold, also in a flight whose trim differs from the fleet's, and are large
    against it once the coefficient flips."""
    rng = np.random.default_rng(11)

    def flight(a1: float, trim: float, flip: int | None = None) -> Any:
        x = np.zeros((3000, 2))
        for k in range(1, 3000):
            coefficient = -a1 if flip is not None and k >= flip else a1
            x[k, 0] = coefficient * x[k - 1, 0] + rng.normal(0.0, 0.1)
            x[k, 1] = 0.5 * x[k - 1, 1] + rng.normal(0.0, 0.1)
        return x + trim

    model = a.Adapted([flight(0.9, 0.0) for _ in range(3)], 1, 0.99)
    steady = model.of(flight(0.9, 2.0))
    assert steady.shape == (3000, 3)
    assert np.abs(steady[200:, 0]).mean() < 1.2  # standard normal: about 0.8
    changed = model.of(flight(0.9, 0.0, flip=2000))
    assert np.abs(changed[2000:2040, 0]).mean() > 2.0 * np.abs(changed[1500:2000, 0]).mean()
    assert changed[2000:2040, -1].mean() > 1.2 * changed[1500:2000, -1].mean()


def test_boosted_trees_learn_a_mean_shift_that_a_spread_alone_does_not_mean() -> None:
    """Statistic 0 faulty when high; statistic 1 spread high in good runs too: the trees
    split on statistic 0."""
    rng = np.random.default_rng(13)
    times = np.arange(0.0, 100.0, 0.05)
    runs = []
    for k in range(4):
        stats = rng.normal(size=(len(times), 2))
        stats[:, 1] *= 1.0 + 4.0 * (times > 50.0)
        onset = 60.0 if k % 2 else None
        if onset is not None:
            stats[times >= onset, 0] += 2.0
        runs.append(detectors.Run(str(k), 0.0, onset, times, stats))
    forest = a.boost(runs, 40, 2)
    assert {tree.feature for tree in forest.trees[:10]} == {0}  # later ones fit the noise
    scores = forest.scores(runs[1])
    assert scores[times >= 60.0].mean() > 1.0 > -1.0 > scores[times < 60.0].mean()
    fewer = a.Boosting(2)
    detectors_penalties = detectors.PENALTIES
    try:
        detectors.PENALTIES = (-40.0, -10.0)  # type: ignore[assignment]
        assert len(fewer(runs, -10.0).trees[: fewer(runs, -10.0).rounds]) == 10
        assert len(fewer.fitted) == 1  # fitted once for the most trees
    finally:
        detectors.PENALTIES = detectors_penalties


def test_relative_evidence_absorbs_a_standing_level() -> None:
    times = np.arange(0.0, 60.0, 0.05)
    scores = np.where(times < 30.0, 4.0, 9.0)
    found = a.relative(5.0)(times, scores, 1.0, 0.0)
    assert abs(found[int(20 / 0.05)]) < 1e-6  # a standing level is no evidence
    assert found[int(30 / 0.05)] == np.float64(5.0)  # a step is, at once
    assert abs(found[-1]) < 0.02  # and less as it lasts (5 e^-6)


def merged_row(**fields: float) -> Any:
    """One ``/alfa/merged`` sample with ``fields`` set, the others 0."""
    return np.array([[fields.get(k, 0.0) for k in a.MERGED]])


def test_inertial_power_is_the_rate_of_the_total_energy_whatever_the_attitude() -> None:
    # a yaw of 240 degrees (the quaternion's w < 0: /alfa/merged drops it, its sign with
    # it) pitched up 10 degrees, flying along its nose at 15 m/s while accelerating
    rng = np.random.default_rng(11)
    for yaw, pitch in ((4.19, 0.17), (1.0, -0.1), (-2.5, 0.3)):
        cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
        cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
        # a unit quaternion (yaw about z, pitch about y), its rotation body (FLU) to local (ENU)
        q = np.array([-sy * sp, cy * sp, sy * cp, cy * cp])  # x, y, z, w
        r = a.rotations(*(q[:3, None] * np.sign(q[3])))[0]
        velocity = r @ np.array([15.0, 0.0, 0.0])
        accel = rng.normal(size=3)
        force = r.T @ (accel + np.array([0.0, 0.0, a.G]))
        row = merged_row(
            orientation_x=q[0], orientation_y=q[1], orientation_z=q[2],
            twist_linear_x=velocity[0], twist_linear_y=velocity[1], twist_linear_z=velocity[2],
            linear_acceleration_x=force[0], linear_acceleration_y=force[1],
            linear_acceleration_z=force[2],
        )  # fmt: skip
        found = a.energy_fields(row, ["inertial_power", "speed_energy"])[0]
        # d(h + V^2 / 2g)/dt = v_z + v . a / g
        assert math.isclose(found[0], velocity[2] + velocity @ accel / a.G, abs_tol=1e-9)
        assert math.isclose(found[1], 15.0**2 / (2 * a.G))


def test_energy_error_adds_the_speed_deficit_as_height() -> None:
    row = merged_row(
        twist_linear_x=20.0, alt_error=3.0, aspd_error=-150.0, linear_acceleration_x=-1.0
    )
    error, power = a.energy_fields(row, ["energy_error", "power"])[0]
    assert math.isclose(error, 3.0 + 20.0 * -1.5 / a.G)
    assert math.isclose(power, -20.0 / a.G)


def test_a_signal_less_its_baseline_is_its_change_and_nan_until_it_spans_both() -> None:
    times = np.arange(0.0, 25.0, 0.05)
    climb = np.where(times < 15.0, 2.0, -1.0)
    values = np.vstack([merged_row(twist_linear_z=c)[0] for c in climb])
    found = a.scan_signal(times, values, "climb", 1.0, 5.0)
    assert np.isnan(found[times < 6.0]).all()
    assert np.allclose(found[(times > 6.0) & (times < 15.0)], 0.0)  # a steady climb: no change
    # signed, a sink raises it: by 3 once the window has left the climb, until the baseline
    # (the mean of the windows' means over the 5 s before) has too
    assert np.isclose(np.nanmax(found), 3.0)
    assert np.isclose(found[np.searchsorted(times, 16.0)], 3.0, atol=0.01)
    assert np.allclose(found[times > 22.1], 0.0)
    assert np.allclose(a.scan_signal(times, values, "climb", 1.0, 0.0)[times > 16.0], 1.0)


def test_a_scan_alarms_where_a_held_out_flight_passes_the_training_flights_nominal_maximum() -> (
    None
):
    times = np.arange(100.0, 110.0, 0.5)
    good: dict[str, Any] = {"start_ns": 100e9, "onset_ns": None, "class": "no_failure"}
    bad: dict[str, Any] = {"start_ns": 100e9, "onset_ns": 105e9, "class": "engine"}
    flights: dict[str, Any] = {"g": (good, times, None), "f": (bad, times, None)}
    signals = {"g": np.where(times > 108.0, 2.0, 1.0), "f": np.where(times >= 106.0, 3.0, 0.0)}
    found = {o.name: o for o in a.scan(flights, signals, [["f"], ["g"]])}
    assert found["f"].delay == 1.0  # above the good flight's 2
    assert found["g"].false_alarm  # above the fault flight's 0 before its onset


def arx_flight(
    rng: Any, n: int, own: float, gain: float, change: int | None = None
) -> tuple[Any, Any, Any, Any]:
    """A flight whose output answers its command as ``y = own y[-1] + gain u[-1] + noise``
    (from sample ``change`` on with a tenth of the gain), every sample an update."""
    times = np.arange(n) * 0.05
    u = np.repeat(rng.normal(scale=5.0, size=n // 10 + 1), 10)[:n]  # held commands
    y = np.zeros(n)
    for k in range(1, n):
        b = gain if change is None or k < change else 0.1 * gain
        y[k] = own * y[k - 1] + b * u[k - 1] + rng.normal(scale=0.1)
    return times, y[:, None], u[:, None], np.ones((n, 1), dtype=bool)


def test_the_commanded_response_is_recovered_and_its_change_shows() -> None:
    rng = np.random.default_rng(17)
    model = a.Commanded([arx_flight(rng, 3000, 0.8, 0.3) for _ in range(3)], 1, 0.99)
    own, commanded = model.response(0)
    assert math.isclose(own[0], 0.8, abs_tol=0.02)
    assert math.isclose(commanded[0], 0.3, abs_tol=0.02)
    flight = arx_flight(rng, 1000, 0.8, 0.3, change=600)
    found = model.of(*flight)
    assert found.shape == (1000, 2)
    before, after = np.abs(found[100:600, 0]), np.abs(found[600:610, 0])
    assert before.mean() < 1.2  # innovations in units of their nominal spread
    assert after.mean() > 4.0 * before.mean()  # the response changed: surprise
    assert found[600:610, 1].mean() > 4.0 * found[100:600, 1].mean()  # the parameters move
    assert np.abs(found[900:, 0]).mean() < 0.5 * after.mean()  # then follow


def test_commanded_values_hold_between_updates() -> None:
    rng = np.random.default_rng(19)
    model = a.Commanded([arx_flight(rng, 2000, 0.5, 1.0)], 2, 0.995)
    times, y, u, _ = arx_flight(rng, 200, 0.5, 1.0)
    updates = np.zeros((200, 1), dtype=bool)
    updates[::4] = True
    found = model.of(times, y, u, updates)
    assert np.all(found[:8] == 0.0)  # before the lags' updates: nothing to predict from
    assert np.all(found[8:12] == found[8]) and found[8, 0] != 0.0


def test_commanded_signals_read_roll_pitch_speed_and_their_commands() -> None:
    # nose up 10 degrees, no roll, heading east at 15 m/s; the commands 5 degrees of roll
    # and 2 of pitch more, and 1.5 m/s faster (aspd_error in cm/s)
    pitch = math.radians(10.0)
    q = (0.0, -math.sin(pitch / 2))  # about y (left): nose up is negative
    fields = {
        "orientation_y": q[1],
        "twist_linear_x": 15.0 * math.cos(pitch),
        "twist_linear_z": 15.0 * math.sin(pitch),
        "delta_roll": 5.0,
        "delta_pitch": 2.0,
    }
    rows = np.vstack([merged_row(**fields, aspd_error=150.0 + k) for k in range(2)])
    outputs, commands, updates = a.commanded_signals(rows)
    assert np.allclose(outputs[0], [0.0, 10.0, 15.0])
    assert np.allclose(commands[0], [5.0, 12.0, 16.5])
    assert updates.tolist() == [[False] * 3, [False, False, False]]


def burst_and_spikes(seed: int) -> list[detectors.Run]:
    """Four good runs, each with one isolated 1.5 s spike of statistic 1, and four failed
    runs whose fault moves statistic 0 a little from its onset (30 s) and statistic 1 a lot
    from 3 s later: the bulk of the faulty samples is the late, obvious part."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, 60.0, 0.05)
    runs = []
    for k in range(8):
        stats = rng.normal(size=(len(times), 2))
        if k % 2:
            stats[times >= 30.0, 0] += 1.5
            stats[times >= 33.0, 1] += 4.0
            runs.append(detectors.Run(f"f{k}", 0.0, 30.0, times, stats))
        else:
            at = rng.uniform(5.0, 50.0)
            stats[(times >= at) & (times < at + 1.5), 1] += 6.0
            runs.append(detectors.Run(f"g{k}", 0.0, None, times, stats))
    return runs


def early_margin(model: Any, runs: list[detectors.Run]) -> float:
    """The failed runs' smallest largest 1 s mean score in their first 2 s after the onset,
    less the good runs' largest 1 s mean score (above 0: each detected within 2 s at a
    threshold on the good runs' maxima)."""
    early, nominal = [], []
    for run in runs:
        means, spans = a.trailing_means(run.times, model.scores(run)[:, None], 1.0)
        found = means[:, 0]
        if run.onset is None:
            nominal.append(float(found[spans].max()))
        else:
            since = run.times - run.onset
            early.append(float(found[spans & (since >= 0.0) & (since < 2.0)].max()))
    return min(early) - max(nominal)


def test_the_pooled_fit_ranks_a_faults_first_seconds_above_good_runs_odd_moments() -> None:
    training, new = burst_and_spikes(17), burst_and_spikes(18)
    assert early_margin(detectors.fit(training, 1.0), new) < 0.0
    assert early_margin(a.Pooled(2.0)(training, 1.0), new) > 0.0


def test_hard_negative_rounds_weigh_good_runs_odd_moments_down() -> None:
    training, new = burst_and_spikes(17), burst_and_spikes(18)
    alone, hardened = a.Hardened(0, 2.0)(training, 1.0), a.Hardened(3, 2.0)(training, 1.0)
    assert np.allclose(alone.weights, detectors.fit(training, 1.0).weights)  # no round: fit
    # the spikes' statistic weighs less than half as much, the gap closes by 4 log-odds
    assert hardened.weights[1] < 0.5 * alone.weights[1]
    assert early_margin(hardened, new) > early_margin(alone, new) + 4.0


def test_the_pooled_loss_gradient_is_its_derivative() -> None:
    runs = burst_and_spikes(19)
    start = detectors.fit(runs, 1.0)
    bags = a.Bags(runs, start.center, start.scale, 2.0)
    # a good run and the failed runs' parts before their onsets are negative bags
    assert (len(bags.starts), int(bags.positive.sum())) == (12, 4)
    w = np.asarray(start.weights) + np.random.default_rng(3).normal(0.0, 0.3, 3)
    _, gradient = a.mil_loss(w, bags, 1.0, 0.5)
    step = 1e-6
    numeric = [
        (a.mil_loss(w + e, bags, 1.0, 0.5)[0] - a.mil_loss(w - e, bags, 1.0, 0.5)[0]) / (2 * step)
        for e in np.eye(3) * step
    ]
    assert np.allclose(gradient, numeric, rtol=1e-5, atol=1e-6)
    pooled, share = bags.pooled(w, 1.0)
    first = bags.rows[: bags.starts[1]] @ w
    assert math.isclose(pooled[0], float(np.log(np.exp(first).sum())))
    assert np.allclose(np.add.reduceat(share, bags.starts), 1.0)


def test_hard_samples_are_a_stretchs_top_second_and_a_faults_first_seconds() -> None:
    times = np.arange(0.0, 20.0, 0.1)
    scores = np.zeros(len(times))
    scores[(times >= 6.0) & (times < 7.0)] = 5.0
    run = detectors.Run("f", 0.0, 15.0, times, np.zeros((len(times), 1)))
    hard = a.hard_samples(run, scores, 1.0)
    marked = times[hard]
    # the 1 s means highest at 6.9 s; the second of samples that made them, from 5.9 s on
    assert marked.min() > 5.0 and marked[marked < 15.0].max() < 8.0
    assert np.allclose(times[hard & (times >= 15.0)], np.arange(15.0, 16.0, 0.1))


def test_an_anchored_pooled_fit_stays_near_the_per_sample_fit_under_a_strong_penalty() -> None:
    runs = burst_and_spikes(17)
    start = detectors.fit(runs, 1e6)
    anchored = a.Pooled(2.0, 1.0, anchored=True)(runs, 1e6)
    shrunk = a.Pooled(2.0, 1.0)(runs, 1e6)
    assert np.allclose(anchored.weights[:-1], start.weights[:-1], atol=1e-4)
    assert np.abs(shrunk.weights[:-1]).max() < 1e-3 < np.abs(start.weights[:-1]).max()
    loose = a.Pooled(2.0, 1.0, anchored=True)(runs, 1.0)
    assert early_margin(loose, burst_and_spikes(18)) > 0.0
