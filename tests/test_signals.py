"""Signal chain: each block against a closed form, and the chain on awkward logs."""

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.data import signals
from consistid.errors import DatasetError, OptionError
from consistid.excitation import FourierTrajectory

RATE = 1000.0


def sines(t, freqs, amps, phases=None):
    """Σ a sin(2πft + φ) and its two derivatives, (N, k) each with one column per frequency."""
    phases = np.zeros(len(freqs)) if phases is None else phases
    w = 2 * np.pi * np.asarray(freqs)
    arg = np.outer(t, w) + phases
    a = np.asarray(amps)
    return a * np.sin(arg), a * w * np.cos(arg), -a * w ** 2 * np.sin(arg)


# ----------------------------------------------------------------------------- building blocks
def test_lowpass_magnitude_and_zero_phase():
    t = np.arange(20000) / RATE
    fc = 10.0
    x, _, _ = sines(t, [1.0, 20.0], [1.0, 1.0])
    y = signals.lowpass(x, fc, RATE)
    mid = slice(5000, 15000)
    # passband: |H|² at f = fc/10 is 1/(1 + 0.1⁸)² ≈ 1; zero phase means no lag either
    np.testing.assert_allclose(y[mid, 0], x[mid, 0], atol=1e-6)
    # stopband: forward-backward order-4 Butterworth, |H(2 fc)|² = 1/(1 + 2⁸)
    gain = np.max(np.abs(y[mid, 1]))
    assert gain == pytest.approx(1.0 / (1.0 + 2.0 ** 8), rel=1e-2)


def test_central_difference_closed_form_on_a_cubic():
    t = np.arange(50) / RATE
    x = 3 * t ** 3 - t ** 2 + 2 * t
    dx, ddx = signals.central_difference(x[:, None], RATE)
    h = 1 / RATE
    # interior: (x(t+h) − x(t−h))/2h = x' + h² x'''/6 exactly for a cubic; second difference exact
    np.testing.assert_allclose(dx[1:-1, 0], (9 * t ** 2 - 2 * t + 2)[1:-1] + h ** 2 * 18 / 6,
                               rtol=1e-9)
    np.testing.assert_allclose(ddx[:, 0], 18 * t - 2, rtol=1e-6, atol=1e-6)


def test_savgol_is_exact_on_polynomials_up_to_its_order():
    t = np.arange(400) / RATE
    x = (1 - 2 * t + 5 * t ** 2 - 4 * t ** 3 + 7 * t ** 4 - 3 * t ** 5)[:, None]
    w = signals.savgol_window(20.0, RATE, 5)
    assert w % 2 == 1
    xs, dx, ddx = signals.savgol_derivatives(x, RATE, w, 5)
    np.testing.assert_allclose(xs[:, 0], x[:, 0], atol=1e-10)
    np.testing.assert_allclose(dx[:, 0], -2 + 10 * t - 12 * t ** 2 + 28 * t ** 3 - 15 * t ** 4,
                               atol=1e-7)
    np.testing.assert_allclose(ddx[:, 0], 10 - 24 * t + 84 * t ** 2 - 60 * t ** 3, atol=1e-4)


def test_fourier_derivatives_average_periods_and_differentiate_exactly():
    period, rate = 2.0, 500.0
    t = np.arange(int(3.5 * period * rate)) / rate          # 3.5 periods: the half is left out
    f = np.array([0.5, 1.5, 2.5])                           # harmonics 1, 3, 5
    q, dq, ddq = (s.sum(axis=1) for s in sines(t, f, [1.0, 0.3, 0.1], [0.2, 1.0, -0.5]))
    noise = 0.01 * np.random.default_rng(0).standard_normal(t.size)
    mean, n = signals.period_average((q + noise)[:, None], period, rate)
    assert n == 3 and mean.shape == (1000, 1)
    clean, _ = signals.period_average(q[:, None], period, rate)
    qf, dqf, ddqf = signals.fourier_derivatives(clean, rate, period, harmonics=5)
    np.testing.assert_allclose(qf[:, 0], q[:1000], atol=1e-12)
    np.testing.assert_allclose(dqf[:, 0], dq[:1000], atol=1e-10)
    np.testing.assert_allclose(ddqf[:, 0], ddq[:1000], atol=1e-9)
    # with noise, harmonics above 5 are cut and 3 periods averaged: error ≪ the noise
    _, dqn, _ = signals.fourier_derivatives(mean, rate, period, harmonics=5)
    assert np.sqrt(np.mean((dqn[:, 0] - dq[:1000]) ** 2)) < 0.01
    with pytest.raises(DatasetError, match="whole number"):
        signals.period_average(q[:, None], 2.0001, rate)


def test_hampel_replaces_spikes_only():
    t = np.arange(3000) / RATE
    x = np.sin(2 * np.pi * 0.7 * t) + 1e-3 * np.random.default_rng(1).standard_normal(t.size)
    spiky = x.copy()
    spiky[[100, 1500, 2999]] += [0.5, -0.3, 0.2]
    cleaned, mask = signals.hampel(spiky[:, None])
    assert set(np.flatnonzero(mask[:, 0])) == {100, 1500, 2999}
    assert np.max(np.abs(cleaned[:, 0] - x)) < 0.01


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), counts=st.sampled_from([0, 2 ** 12, 2 ** 16]))
def test_hampel_leaves_smooth_and_quantised_signals_alone(seed, counts):
    """A smooth excitation, raw or as an encoder staircase, has no outlier."""
    rng = np.random.default_rng(seed)
    t = np.arange(4000) / RATE
    x = sines(t, rng.uniform(0.05, 2.0, 4), rng.uniform(0.1, 1.0, 4),
              rng.uniform(0, 6, 4))[0].sum(axis=1)
    if counts:
        step = 2 * np.pi / counts
        x = np.round(x / step) * step
    _, mask = signals.hampel(x[:, None])
    assert not mask.any()


def test_low_speed_mask():
    dq = np.array([[0.5, -0.2], [0.01, 1.0], [0.3, -0.001]])
    np.testing.assert_array_equal(signals.low_speed_mask(dq, 0.05), [True, False, False])
    np.testing.assert_array_equal(signals.low_speed_mask(dq, [0.005, 0.0]), [True, True, True])


def test_bandwidth_estimate_and_default_cutoff():
    t = np.arange(20000) / RATE
    f = [0.1, 0.2, 0.3, 0.4, 0.5]
    q = sines(t, f, [1 / k for k in range(1, 6)])[0].sum(axis=1)
    bw = signals.estimate_bandwidth(q[:, None], RATE)
    assert 0.3 <= bw <= 0.6
    assert signals.default_cutoff(bw, RATE) == pytest.approx(10 * bw)
    assert signals.default_cutoff(3.0, RATE) == 30.0           # the seeds' 30 Hz at 1 kHz
    assert signals.default_cutoff(100.0, 200.0) == 80.0        # at most 0.4 × the rate


# ----------------------------------------------------------------------------- the chain
@pytest.fixture(scope="module")
def excitation():
    model = ci.RobotModel.example("ur5")
    traj = FourierTrajectory.random(model, 5, 10.0, seed=2)
    return traj, traj.sample(RATE, 10.0)


@pytest.mark.parametrize("method", ["central", "savgol", "fourier"])
def test_chain_recovers_derivatives_of_a_known_trajectory(excitation, method):
    traj, exact = excitation
    tau = np.cos(exact.q)                      # any smooth torque: it is only filtered
    pre = signals.preprocess(exact.t, exact.q, tau, derivative=method, period=10.0,
                             bandwidth=0.5)
    d = pre.dataset
    q, dq, ddq = traj.evaluate(d.t)
    scale = np.max(np.abs(exact.ddq))
    assert np.max(np.abs(d.dq - dq)) < 1e-4 * np.max(np.abs(exact.dq))
    assert np.max(np.abs(d.ddq - ddq)) < 1e-3 * scale
    np.testing.assert_allclose(d.tau, np.cos(q), atol=1e-4)
    assert [s.name for s in pre.steps][:2] == ["outliers", "cut-off"]
    # q differentiated (and τ filtered) at 10 × the band; identification low-passes τ and Y
    # alike at 3 × the band, except on the one averaged period of "fourier"
    assert pre.derivative_cutoff == 5.0
    assert pre.cutoff == (5.0 if method == "fourier" else 1.5)
    assert d.identification_filter == (None if method == "fourier" else (1.5, 4))


def test_chain_copes_with_jitter_duplicates_disorder_and_gaps(excitation, caplog):
    traj, exact = excitation
    rng = np.random.default_rng(4)
    t = exact.t + rng.uniform(-2e-4, 2e-4, exact.t.size)          # ±20 % jitter
    t[3000:] += 0.5                                                 # a 0.5 s gap
    q, _, _ = traj.evaluate(t)
    tau = np.cos(q)
    dup = np.arange(100, 5000, 250)                                 # repeated stamps
    t, q, tau = (np.insert(a, dup, a[dup], axis=0) for a in (t, q, tau))
    swap = np.array([2000, 2001])                                   # two rows out of order
    t[swap], q[swap], tau[swap] = t[swap[::-1]], q[swap[::-1]], tau[swap[::-1]]
    with caplog.at_level(logging.INFO, logger="consistid.data.chain"):
        pre = signals.preprocess(t, q, tau, bandwidth=0.5, rate=RATE)
    names = [s.name for s in pre.steps]
    for name in ("sort", "duplicates", "gaps", "resample"):
        assert name in names
    assert "resample" in caplog.text
    d = pre.dataset
    assert list(np.unique(d.segment)) == [0, 1]
    assert np.allclose(np.diff(d.t[d.segment == 1]), 1e-3)
    _, dq, ddq = traj.evaluate(d.t)
    assert np.max(np.abs(d.dq - dq)) < 1e-3 * np.max(np.abs(dq))
    assert np.max(np.abs(d.ddq - ddq)) < 1e-2 * np.max(np.abs(ddq))
    assert "duplicates: 20 duplicated time stamp(s)" in str(pre)


def test_from_recording_is_the_default_chain(excitation):
    _, exact = excitation
    tau = np.sin(exact.q)
    data = ci.Dataset.from_recording(exact.t, exact.q, tau, joint_names=list("abcdef"))
    same = signals.preprocess(exact.t, exact.q, tau).dataset
    np.testing.assert_array_equal(data.ddq, same.ddq)
    assert data.joint_names == tuple("abcdef")


def test_decimation_and_low_speed_removal(excitation):
    _, exact = excitation
    pre = signals.preprocess(exact.t, exact.q, np.cos(exact.q), bandwidth=0.5, decimate=10,
                             min_speed=0.05)
    d = pre.dataset
    assert pre.rate == 100.0 and np.allclose(np.diff(d.t).min(), 0.01)
    assert np.all(np.abs(d.dq) >= 0.05)
    assert [s.name for s in pre.steps][-2:] == ["decimate", "low speed"]
    with pytest.raises(OptionError, match="alias"):
        signals.preprocess(exact.t, exact.q, exact.q, cutoff=30.0, decimate=20)


def test_chain_errors_name_the_problem(excitation):
    _, exact = excitation
    q = exact.q.copy()
    q[17, 2] = np.nan
    with pytest.raises(DatasetError, match=r"q\[17, 2\] is nan"):
        signals.preprocess(exact.t, q, exact.q)
    with pytest.raises(DatasetError, match="tau has 10 samples"):
        signals.preprocess(exact.t, exact.q, exact.q[:10])
    with pytest.raises(OptionError, match="period"):
        signals.preprocess(exact.t, exact.q, exact.q, derivative="fourier")
    with pytest.raises(OptionError, match="derivative"):
        signals.preprocess(exact.t, exact.q, exact.q, derivative="magic")


# ----------------------------------------------------------------------------- review fixes
@pytest.mark.parametrize("cutoff, polyorder", [(3.0, 5), (20.0, 3), (30.0, 5), (100.0, 5)])
def test_savgol_window_puts_minus_3_db_at_the_cutoff(cutoff, polyorder):
    """A sine at the cut-off comes out of scipy's smoother at 1/√2 of its amplitude, up to what
    the next odd window would change."""
    t = np.arange(int(20 * RATE / cutoff) + 2000) / RATE
    w = signals.savgol_window(cutoff, RATE, polyorder)
    out = {}
    for n in (w - 2, w, w + 2):
        x = np.sin(2 * np.pi * cutoff * t)[:, None]
        y = signals.savgol_derivatives(x, RATE, n, polyorder)[0][1000:-1000, 0]
        out[n] = np.sqrt(2 * np.mean(y ** 2))                      # amplitude of the output
    gain = 1 / np.sqrt(2)
    assert abs(out[w] - gain) <= min(abs(out[w - 2] - gain), abs(out[w + 2] - gain))
    assert out[w] == pytest.approx(gain, abs=0.03)


def test_savgol_refuses_numerically_broken_windows():
    x = np.ones((3000, 1))
    with pytest.raises(OptionError, match="broken"):
        signals.savgol_derivatives(x, RATE, signals.savgol_window(1.0, RATE, 5), 5)
    np.testing.assert_allclose(signals.savgol_derivatives(x, RATE, 901, 3)[0], 1.0)


def test_fourier_chain_refuses_a_trim(excitation):
    _, exact = excitation
    with pytest.raises(OptionError, match="trim"):
        signals.preprocess(exact.t, exact.q, exact.q, derivative="fourier", period=10.0,
                           bandwidth=0.5, trim=0.5)


def test_rate_below_the_log_rate_is_refused(excitation):
    _, exact = excitation
    with pytest.raises(OptionError, match="decimate"):
        signals.preprocess(exact.t, exact.q, exact.q, bandwidth=0.5, rate=500.0)
    pre = signals.preprocess(exact.t, exact.q, exact.q, bandwidth=0.5, decimate=2)
    assert pre.rate == 500.0


# ----------------------------------------------------------------------------- jittered logs
def jittered_stamps(n, step, rng, long_fraction=0.02, longest=8.8):
    """Steps around ``step`` (σ 10 %, ≥ 0.7 step) with occasional long ones up to ``longest``
    steps: the 0.7–8.8 ms, median 1.0 ms kind of log of issue 13."""
    dt = np.clip(rng.normal(step, 0.1 * step, n), 0.7 * step, None)
    long = rng.random(n) < long_fraction
    dt[long] = rng.uniform(2 * step, longest * step, long.sum())
    dt[np.argmax(long)] = longest * step
    return np.concatenate([[0.0], np.cumsum(dt)])


@pytest.mark.parametrize("robot", ["kinova", "xarm7"])
def test_a_jittered_1khz_log_with_long_steps_loads_with_the_default_call(robot):
    """Issue 13: steps 0.7–8.8 ms around 1 ms used to raise 'would alias'; now the log loads,
    at the rate it supports, as accurately as the same motion logged uniformly."""
    model = ci.RobotModel.example(robot)
    traj = FourierTrajectory.random(model, 5, 10.0, seed=3)
    t = jittered_stamps(12000, 1e-3, np.random.default_rng(1))
    dt = np.diff(t)
    assert dt.min() == pytest.approx(7e-4) and dt.max() == pytest.approx(8.8e-3)
    assert np.median(dt) == pytest.approx(1e-3, rel=0.02)
    q, dq, ddq = traj.evaluate(t)
    data = ci.Dataset.from_recording(t, q, np.cos(q))                   # the default call
    pre = signals.preprocess(t, q, np.cos(q))
    np.testing.assert_array_equal(pre.dataset.ddq, data.ddq)
    text = str(pre)
    assert "rate:" in text and "long steps:" in text and "resample:" in text
    assert abs(pre.rate - 1000.0) < 20.0
    assert len(np.unique(data.segment)) == 1              # long steps bridged, not split
    _, dq_true, ddq_true = traj.evaluate(data.t)
    uniform = signals.preprocess(np.arange(12000) / 1000.0, *traj.evaluate(
        np.arange(12000) / 1000.0)[:1], np.cos(traj.evaluate(np.arange(12000) / 1000.0)[0]))
    _, _, ddq_u = traj.evaluate(uniform.dataset.t)
    err_u = np.max(np.abs(uniform.dataset.ddq - ddq_u))
    err = np.max(np.abs(data.ddq - ddq_true))
    assert err < 3 * err_u + 1e-4 * np.max(np.abs(ddq_true))
    assert np.max(np.abs(data.dq - dq_true)) < 1e-3 * np.max(np.abs(dq_true))


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), rate=st.sampled_from([100.0, 250.0, 1000.0, 4000.0]),
       outage=st.booleans())
def test_jittered_gapped_logs_at_any_rate_load_by_default(seed, rate, outage):
    rng = np.random.default_rng(seed)
    t = jittered_stamps(int(8 * rate), 1 / rate, rng, long_fraction=rng.uniform(0, 0.05))
    if outage:
        t[len(t) // 2:] += 0.5                                         # a real outage
    f = rng.uniform(0.2, 1.0, 2)
    q = np.sin(2 * np.pi * np.outer(t, f))
    pre = signals.preprocess(t, q, np.cos(q))
    d = pre.dataset
    assert 0.9 * rate < pre.rate < 1.1 * rate
    if outage:      # split there (segments shorter than the filter edges are dropped, said)
        assert "gaps" in [s.name for s in pre.steps]
    dq = 2 * np.pi * f * np.cos(2 * np.pi * np.outer(d.t, f))
    scale = np.max(np.abs(dq))
    # the bulk is as accurate as a uniform log; the worst sample sits at a segment edge, in the
    # low-pass's transient after the trim (as on uniform logs cut by the same gaps)
    assert np.sqrt(np.mean((d.dq - dq) ** 2)) < 2e-3 * scale
    assert np.max(np.abs(d.dq - dq)) < 1e-2 * scale


def test_a_given_rate_below_a_segments_own_is_refused_with_decimate_as_the_way():
    t = jittered_stamps(4000, 1e-3, np.random.default_rng(0))
    q = np.sin(np.outer(t, [1.0, 2.0]))
    with pytest.raises(OptionError, match="would alias.*decimate="):
        signals.preprocess(t, q, q, rate=800.0)
    assert signals.preprocess(t, q, q, rate=950.0).rate == 950.0


# ----------------------------------------------------------------------------- stamps
def test_interval_averaged_torques_are_moved_to_the_interval_centre():
    """A logger that averages τ over [t_{k-1}, t_k] and stamps it t_k lags it half a step; with
    timestamp="end" the chain undoes it (closed-form interval averages of a sinusoid)."""
    rate, f = 200.0, 3.0
    t = np.arange(4000) / rate
    w, h = 2 * np.pi * f, 1 / rate
    q = np.column_stack([np.sin(0.5 * w * t), np.cos(0.3 * w * t)])
    exact = np.column_stack([np.sin(w * t), np.cos(w * t)])
    averaged = np.column_stack([(np.cos(w * (t - h)) - np.cos(w * t)) / (w * h),
                                (np.sin(w * t) - np.sin(w * (t - h))) / (w * h)])
    kw = dict(cutoff=20.0, outliers=None)
    plain = signals.preprocess(t, q, averaged, **kw)
    fixed = signals.preprocess(t, q, averaged, timestamp="end", **kw)
    ref = signals.preprocess(t, q, exact, **kw)
    common = np.isin(ref.dataset.t, fixed.dataset.t)
    lag = np.max(np.abs(plain.dataset.tau - ref.dataset.tau))
    err = np.max(np.abs(fixed.dataset.tau - ref.dataset.tau[common]))
    assert lag > 0.04                                    # half a step at 3 Hz: 2π·3·2.5 ms
    # what is left is the interval average's own second-order term, h²ẍ/24 (closed form)
    assert err < 1.1 * (w * h) ** 2 / 24 < 0.01 * lag
    assert "timestamp" in [s.name for s in fixed.steps]
    ahead = np.column_stack([(np.cos(w * t) - np.cos(w * (t + h))) / (w * h),
                             (np.sin(w * (t + h)) - np.sin(w * t)) / (w * h)])   # [t, t + h]
    start = signals.preprocess(t, q, ahead, timestamp="start", **kw)
    common = np.isin(ref.dataset.t, start.dataset.t)
    assert np.max(np.abs(start.dataset.tau - ref.dataset.tau[common])) < 1.1 * (w * h) ** 2 / 24
    with pytest.raises(OptionError, match="timestamp"):
        signals.preprocess(t, q, averaged, timestamp="middle")


def test_collapsed_stamps_are_named_and_spread_only_when_asked():
    """A 1 kHz log stamped by a 10 ms clock: 9 of 10 samples repeat a stamp."""
    t_true = np.arange(3000) / 1000.0
    t = np.floor(t_true * 100 + 1e-9) / 100
    q = np.sin(np.outer(t_true, [1.0, 3.0]))
    with pytest.raises(DatasetError, match="collapsed time stamps: 2700 of 3000.*'spread'"):
        signals.preprocess(t, q, q)
    pre = signals.preprocess(t, q, q, duplicates="spread")
    assert pre.rate == pytest.approx(1000.0)
    assert "spread evenly" in str(pre)
    merged = signals.preprocess(t, q, q, duplicates="average")
    assert merged.rate == pytest.approx(100.0) and "collapsed" in str(merged)


def test_time_units_are_checked_and_converted_only_when_asked():
    t = np.arange(3000) * 1.0                          # milliseconds, at 1 kHz
    q = np.sin(np.outer(t / 1000.0, [1.0, 3.0]))
    with pytest.raises(DatasetError, match=r"1 Hz in seconds.*time_unit='ms' \(1000 Hz\)"):
        ci.Dataset.from_recording(t, q, q)
    a = signals.preprocess(t, q, q, time_unit="ms")
    b = signals.preprocess(t, q, q, time_unit="auto")
    c = signals.preprocess(t / 1000.0, q, q)
    np.testing.assert_allclose(a.dataset.dq, c.dataset.dq, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b.dataset.t, c.dataset.t, rtol=1e-12)
    assert "time_unit='auto'" in str(b) and "time_unit='ms'" in str(a)
    ns = signals.preprocess(np.arange(3000) * 1_000_000.0, q, q, time_unit="auto")
    assert ns.rate == pytest.approx(1000.0) and "read as ns" in str(ns)


def test_unknown_chain_options_are_named():
    t = np.arange(100) / 100.0
    with pytest.raises(OptionError, match=r"unknown signal-chain option\(s\) \['cutof'\]"):
        ci.Dataset.from_recording(t, t, t, cutof=3.0)


# ----------------------------------------------------------------------------- the resampler
def test_the_resampler_against_closed_forms():
    from consistid.data import resample as rs

    rng = np.random.default_rng(2)
    t = np.sort(rng.uniform(0, 2, 400))
    x = np.column_stack([np.sin(3 * t), t ** 2])
    grid, xg = rs.to_uniform(t, x, 500.0)
    assert grid[0] == t[0] and grid[-1] <= t[-1] and np.allclose(np.diff(grid), 2e-3)
    np.testing.assert_allclose(xg[:, 0], np.sin(3 * grid), atol=1e-5)
    np.testing.assert_allclose(xg[:, 1], grid ** 2, atol=1e-9)      # a cubic spline is exact
    lin = rs.resample(t, x, grid, "linear")
    assert np.max(np.abs(lin[:, 0] - np.sin(3 * grid))) > 10 * np.max(np.abs(xg[:, 0] -
                                                                            np.sin(3 * grid)))
    with pytest.raises(DatasetError, match="no extrapolation"):
        rs.resample(t, x, [t[-1] + 0.1])
    back = rs.on_uniform_grid(t, x, lambda xx, r: xx)
    np.testing.assert_allclose(back[:, 1], t ** 2, atol=1e-4)


def test_a_log_whose_rate_changed_is_resampled_at_its_faster_rate():
    """500 Hz for 8 s, then (after a pause) 1 kHz for 2 s: no stretch is resampled below its
    own rate (the median step says 500 Hz); the slower one is interpolated up."""
    t = np.concatenate([np.arange(4000) / 500.0, 8.5 + np.arange(2000) / 1000.0])
    q = np.sin(np.outer(t, [1.0, 2.0]))
    pre = signals.preprocess(t, q, q)
    assert pre.rate == 1000.0 and "fastest stretch" in str(pre)
    assert list(np.unique(pre.dataset.segment)) == [0, 1]
    np.testing.assert_allclose(np.diff(pre.dataset.t[pre.dataset.segment == 0]), 1e-3)


def test_a_simulated_jittered_log_loads_as_accurately_as_a_uniform_one():
    """Issue 13's acceptance on a MuJoCo log: UR5 at 5 kHz, cut into a 1 kHz log and a log with
    steps of 0.8–8.8 ms (median 1 ms); the default call loads both, with comparable q̇, q̈
    against MuJoCo's true states."""
    from consistid.simulate import Effects, record

    model = ci.RobotModel.example("ur5")
    traj = FourierTrajectory.random(model, 5, 10.0, seed=4)
    rec = record(model, traj, Effects(torque_noise=0.05), duration=6.0, rate=5000.0,
                 physics_rate=5000.0, seed=4)
    rng = np.random.default_rng(4)
    steps = np.clip(np.rint(rng.normal(5, 0.5, rec.n_samples // 4)), 4, None)
    steps[rng.random(steps.size) < 0.02] = rng.integers(10, 45, 1)[0]
    steps[7] = 44
    jit = np.concatenate([[0], np.cumsum(steps.astype(int))])
    jit = jit[jit < rec.n_samples]
    dt = np.diff(rec.t[jit])
    assert dt.min() <= 8.1e-4 and dt.max() == pytest.approx(8.8e-3)
    assert np.median(dt) == pytest.approx(1e-3)
    errors = {}
    for name, idx in (("uniform", np.arange(0, rec.n_samples, 5)), ("jittered", jit)):
        d = ci.Dataset.from_recording(rec.t[idx], rec.q[idx], rec.tau[idx])
        true_dq = np.column_stack([np.interp(d.t, rec.t, c) for c in rec.true_dq.T])
        true_ddq = np.column_stack([np.interp(d.t, rec.t, c) for c in rec.true_ddq.T])
        errors[name] = (np.sqrt(np.mean((d.dq - true_dq) ** 2)),
                        np.sqrt(np.mean((d.ddq - true_ddq) ** 2)))
    assert errors["jittered"][0] < 1.5 * errors["uniform"][0]
    assert errors["jittered"][1] < 1.5 * errors["uniform"][1]


def test_interval_centres_follow_the_actual_steps_of_a_jittered_log():
    """With jitter, each averaged torque belongs to the centre of its own interval
    [t_{k-1}, t_k], not to a median half-step away."""
    rng = np.random.default_rng(8)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(3.5e-3, 6.5e-3, 3000))])
    w = 2 * np.pi * 3.0
    q = np.column_stack([np.sin(0.5 * w * t), np.cos(0.3 * w * t)])
    prev = np.concatenate([[t[0] - 5e-3], t[:-1]])
    h = t - prev
    averaged = np.column_stack([(np.cos(w * prev) - np.cos(w * t)) / (w * h),
                                (np.sin(w * t) - np.sin(w * prev)) / (w * h)])
    kw = dict(cutoff=20.0, outliers=None)
    fixed = signals.preprocess(t, q, averaged, timestamp="end", **kw).dataset
    plain = signals.preprocess(t, q, averaged, **kw).dataset
    exact = np.column_stack([np.sin(w * fixed.t), np.cos(w * fixed.t)])
    lag = np.max(np.abs(plain.tau - np.column_stack([np.sin(w * plain.t), np.cos(w * plain.t)])))
    err = np.max(np.abs(fixed.tau - exact))
    assert err < 1.2 * (w * h.max()) ** 2 / 24 < 0.05 * lag
