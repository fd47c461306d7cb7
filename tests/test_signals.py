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
    assert pre.cutoff == 5.0


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
