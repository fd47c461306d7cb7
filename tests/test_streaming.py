"""Streaming identification: recordings read one at a time give the stacked data's answer."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.errors import DatasetError, JointCountError, OptionError
from consistid.identification.compression import compress, joint_sigma
from consistid.identification.regressor import RegressorSpec, predict_torque
from consistid.identification.statistics import (add_lagged, autocorrelation_time,
                                                 coloured_covariance)
from consistid.identification.streaming import (
    AUTOCORRELATION_SAMPLES,
    TAU_PRECISION,
    DataStream,
    ResidualStatistics,
    autocorrelation_windows,
    is_stream,
    merge,
    merge_all,
)


def normal_equations(problem):
    """``RᵀR`` and ``Rᵀz`` (unique, unlike R's row signs; ``ρ²`` is no residual when the
    regressor is rank-deficient, as every robot's is)."""
    r, z, _ = problem.stacked()
    return r.T @ r, r.T @ z


def runs(model, n, duration=3.0, rate=100.0, noise=0.05):
    return [ci.simulate.excitation_run(model, duration=duration, rate=rate, seed=s,
                                       torque_noise=noise).dataset for s in range(n)]


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**16), cuts=st.lists(st.integers(1, 299), min_size=1, max_size=4))
def test_merged_factors_equal_the_factor_of_all_rows(planar_2r, seed, cuts):
    """qr([R̄_a; R̄_b]) of any split of the samples has the normal equations of the whole."""
    data = ci.simulate.excitation_run(planar_2r, duration=3.0, rate=100.0, seed=seed).dataset
    spec = RegressorSpec.make(planar_2r, ("coulomb", "viscous", "offset"))
    edges = [0, *sorted(set(cuts)), data.n_samples]
    parts = [compress(planar_2r, data.select(slice(a, b)), spec)
             for a, b in zip(edges[:-1], edges[1:])]
    whole = compress(planar_2r, data, spec)
    merged = merge_all(parts)
    assert merged.n_samples == data.n_samples
    np.testing.assert_allclose(merged.tau_sum_squares, whole.tau_sum_squares, rtol=1e-12)
    for got, want in zip(normal_equations(merged), normal_equations(whole)):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10 * np.max(np.abs(want)))
    # residual sums of squares of any θ, per joint, from the merged factors
    theta = np.random.default_rng(seed).normal(size=whole.n_columns)
    np.testing.assert_allclose(merged.sum_squares(theta), whole.sum_squares(theta), rtol=1e-9)


def test_merge_refuses_other_shapes(planar_2r):
    data = runs(planar_2r, 1)[0]
    a = compress(planar_2r, data, RegressorSpec.make(planar_2r, None))
    b = compress(planar_2r, data, RegressorSpec.make(planar_2r, ("coulomb",)))
    with pytest.raises(DatasetError, match="shapes"):
        merge(a, b)
    with pytest.raises(DatasetError, match="nothing to merge"):
        merge_all([])


@pytest.mark.parametrize("method", ["ols", "wls", "sdp"])
def test_files_give_the_stacked_answer(tmp_path, planar_2r, method):
    data = runs(planar_2r, 3)
    files = []
    for k, d in enumerate(data):
        files.append(tmp_path / f"run{k}.{'npz' if k % 2 else 'csv'}")
        d.save(files[-1])
    stacked = ci.identify(planar_2r, data, method=method)
    streamed = ci.identify(planar_2r, files, method=method)
    # OLS/WLS: exact to round-off; SDP: the same program, solved to the solver's tolerance
    tol = 1e-10 if method != "sdp" else 1e-6
    scale = np.max(np.abs(stacked.base_parameters))
    np.testing.assert_allclose(streamed.base_parameters, stacked.base_parameters,
                               atol=tol * scale)
    np.testing.assert_allclose(streamed.base_covariance, stacked.base_covariance,
                               rtol=1e-6 if method == "sdp" else 1e-9,
                               atol=1e-12 * np.max(np.abs(stacked.base_covariance)))
    np.testing.assert_allclose(streamed.details["autocorrelation_time"],
                               stacked.details["autocorrelation_time"], rtol=1e-9)
    assert streamed.n_samples == sum(d.n_samples for d in data)


def test_generator_on_another_arm_iid(ur5_model):
    """A one-pass generator of Datasets (UR5): same OLS answer and iid covariance as stacked."""
    data = runs(ur5_model, 3, duration=2.0)
    stacked = ci.identify(ur5_model, data, method="ols", covariance="iid")
    streamed = ci.identify(ur5_model, (d for d in data), method="ols", covariance="iid")
    np.testing.assert_allclose(streamed.base_parameters, stacked.base_parameters,
                               rtol=1e-9, atol=1e-10 * np.max(np.abs(stacked.base_parameters)))
    np.testing.assert_allclose(streamed.base_covariance, stacked.base_covariance, rtol=1e-8,
                               atol=1e-14)
    np.testing.assert_allclose(streamed.train_rms, stacked.train_rms, rtol=1e-9)


@pytest.fixture(scope="module")
def ur5_model():
    return ci.RobotModel.example("ur5")


def test_residual_statistics_pool_like_one_dataset(planar_2r):
    """Parts pooled chunk by chunk give the autocorrelation time of the stacked recordings."""
    data = runs(planar_2r, 3, noise=0.0)
    spec = RegressorSpec.make(planar_2r, None)
    rng = np.random.default_rng(0)
    theta = planar_2r.prior_parameters * rng.uniform(0.8, 1.2, planar_2r.n_inertial)
    # a coloured residual: AR(1) torques, so that τ_j is well above 1
    noisy = [d.with_torque(d.tau + ci.simulate.experiments.ar1_noise(d.tau.shape, 0.8, 0.1, rng))
             for d in data]
    stream = DataStream(noisy)
    stats = stream.residual_statistics(planar_2r, spec, theta)
    stacked = ci.Dataset.concatenate(noisy)
    from consistid.identification.regressor import predict_torque

    residual = stacked.tau - predict_torque(planar_2r, stacked, spec, theta)
    np.testing.assert_allclose(stats.autocorrelation_time(),
                               autocorrelation_time(stacked, residual), rtol=1e-10)
    assert np.all(stats.autocorrelation_time() > 3.0)
    np.testing.assert_allclose(stats.sum_squares, np.sum(residual ** 2, axis=0), rtol=1e-12)
    assert stats.n_samples == stacked.n_samples
    single = ResidualStatistics.of(planar_2r, spec, theta, noisy[0])
    assert single.n_samples == noisy[0].n_samples


def test_autocorrelation_windows_read_few_samples_and_keep_the_correlation_time(planar_2r):
    """A long log's residual autocorrelation is first read on AUTOCORRELATION_SAMPLES samples in
    four windows, none pairing samples across a gap; the correlation time found there (AR(1)
    with φ = 0.8: τ = (1 + φ)/(1 − φ) = 9 in closed form) asks for ``2(10τ + 1)/0.1²`` samples,
    more than were read, so they are read, and give the correlation time of all samples to
    three of the standard errors they were read for."""
    data = ci.simulate.excitation_run(planar_2r, duration=1300.0, rate=100.0, seed=3,
                                      torque_noise=0.0).dataset
    rng = np.random.default_rng(1)
    noise = ci.simulate.experiments.ar1_noise(data.tau.shape, 0.8, 0.1, rng)
    noisy = ci.Dataset.concatenate([data.with_torque(data.tau + noise)] * 2)   # two recordings
    spec = RegressorSpec.make(planar_2r, None)
    theta = planar_2r.prior_parameters
    picked = autocorrelation_windows(noisy)
    assert picked.n_samples == AUTOCORRELATION_SAMPLES < noisy.n_samples
    # each window, and each recording within one, is its own segment, time increasing within
    labels = np.unique(picked.segment)
    assert 4 <= labels.size <= 8
    for label in labels:
        assert np.all(np.diff(picked.t[picked.segment == label]) > 0)
    assert autocorrelation_windows(noisy, None) is noisy
    few = ResidualStatistics.of(planar_2r, spec, theta, noisy)
    every = ResidualStatistics.of(planar_2r, spec, theta, noisy, samples=None)
    assert every.n_samples == noisy.n_samples
    tau_few, tau_all = few.autocorrelation_time(), every.autocorrelation_time()
    np.testing.assert_allclose(tau_all, 9.0, rtol=0.1)
    needed = 2.0 * (10.0 * 9.0 + 1.0) / TAU_PRECISION ** 2
    assert 0.7 * needed <= few.n_samples < noisy.n_samples
    np.testing.assert_allclose(tau_few, tau_all, rtol=3 * TAU_PRECISION)


def test_a_long_correlation_reads_enough_samples_for_its_time(planar_2r):
    """AR(1) with φ = 0.98 (τ = 99 samples in closed form) on a 300 000-sample log: the
    windows' first estimate asks for more samples than they hold (τ within 10 % needs ~200 000), the
    residual is read again on them, and τ lands within 30 % (three standard errors) of the
    closed form."""
    data = ci.simulate.excitation_run(planar_2r, duration=3000.0, rate=100.0, seed=5,
                                      torque_noise=0.0).dataset
    noise = ci.simulate.experiments.ar1_noise(data.tau.shape, 0.98, 0.1,
                                              np.random.default_rng(2))
    noisy = data.with_torque(data.tau + noise)
    spec = RegressorSpec.make(planar_2r, None)
    stats = ResidualStatistics.of(planar_2r, spec, planar_2r.prior_parameters, noisy)
    assert stats.n_samples > 2 ** 17
    np.testing.assert_allclose(stats.autocorrelation_time(), 99.0, rtol=0.3)


def test_pooled_autocovariances_keep_the_longer_ones_lags():
    """A short recording adds nothing beyond its own lags; it does not cut the long one's."""
    long, short = np.ones((50, 2)), np.full((5, 2), 2.0)
    both = add_lagged(long, short)
    assert both.shape == (50, 2)
    np.testing.assert_array_equal(both[:5], 3.0)
    np.testing.assert_array_equal(both[5:], 1.0)
    np.testing.assert_array_equal(add_lagged(short, long), both)
    assert add_lagged(None, short) is short and add_lagged(None, None) is None


def test_coloured_covariance_counts_every_sample_in_the_variance(planar_2r):
    """The σ of the coloured covariance comes from every sample's residual (exact from the
    factors) even when the autocorrelation reads a part: identify's ± on a long log equals the
    sandwich computed by hand from the residual of all samples and the windows' τ."""
    data = ci.simulate.excitation_run(planar_2r, duration=500.0, rate=100.0, seed=4,
                                      torque_noise=0.05).dataset
    res = ci.identify(planar_2r, data, method="ols", covariance="coloured")
    iid = ci.identify(planar_2r, data, method="ols", covariance="iid")
    residual = data.tau - predict_torque(planar_2r, data, res.spec, res.parameters)
    tau = ResidualStatistics.of(planar_2r, res.spec, res.parameters, data).autocorrelation_time()
    problem = compress(planar_2r, data, res.spec)
    cols = res.base.independent
    r_b = problem.factors[:, :-1, :-1][:, :, cols]
    grams = np.matmul(r_b.transpose(0, 2, 1), r_b)
    w = 1.0 / np.asarray(iid.sigma, dtype=float) ** 2
    v = joint_sigma(np.sum(residual ** 2, axis=0), data.n_samples, res.base.n_base, tau) ** 2
    expected = coloured_covariance(iid.base_covariance, grams, w, tau, v)
    # plus the model-error term of the rows at rest on its diagonal (test_model_error.py)
    expected += np.diag(res.details["model_error"] ** 2)
    np.testing.assert_allclose(res.base_covariance, expected, rtol=1e-8)


def test_which_inputs_stream(tmp_path, planar_2r):
    data = runs(planar_2r, 2)
    data[0].save(tmp_path / "a.npz")
    assert not is_stream(data[0]) and not is_stream(data) and not is_stream(tuple(data))
    assert is_stream([tmp_path / "a.npz"]) and is_stream([str(tmp_path / "a.npz"), data[1]])
    assert is_stream(d for d in data) and is_stream(DataStream(data))
    assert not is_stream(3) and not is_stream("a.npz")


def test_one_pass_streams_refuse_what_needs_a_second_reading(planar_2r):
    data = runs(planar_2r, 2)
    with pytest.raises(OptionError, match="covariance='iid'"):
        ci.identify(planar_2r, (d for d in data), method="ols", covariance="coloured")
    auto = ci.identify(planar_2r, (d for d in data), method="ols")   # "auto": iid, said so
    assert "one-pass stream" in auto.details["covariance"]
    iid = ci.identify(planar_2r, data, method="ols", covariance="iid")
    np.testing.assert_allclose(auto.base_covariance, iid.base_covariance, rtol=1e-9)
    with pytest.raises(OptionError, match="huber"):
        ci.identify(planar_2r, DataStream(data), method="sdp", loss="huber")
    once = DataStream(iter(data))
    assert not once.rereadable
    ci.identify(planar_2r, once, method="ols", covariance="iid")
    with pytest.raises(DatasetError, match="already read"):
        ci.identify(planar_2r, once, method="ols", covariance="iid")


def test_a_function_source_is_read_twice_for_the_coloured_covariance(planar_2r):
    data = runs(planar_2r, 2)
    calls = []

    def source():
        calls.append(1)
        return (d for d in data)

    res = ci.identify(planar_2r, DataStream(source), method="wls")
    assert len(calls) == 2 and res.details["covariance"].startswith("coloured")
    ref = ci.identify(planar_2r, data, method="wls")
    np.testing.assert_allclose(res.base_covariance, ref.base_covariance, rtol=1e-8)


def test_bad_parts_are_named(tmp_path, planar_2r, ur5_model):
    data = runs(planar_2r, 1)
    with pytest.raises(DatasetError, match=r"data\[1\] is a int"):
        ci.identify(planar_2r, DataStream([data[0], 3]), method="ols", covariance="iid")
    with pytest.raises(DatasetError, match="missing.npz"):
        ci.identify(planar_2r, [tmp_path / "missing.npz"], method="ols")
    other = runs(ur5_model, 1, duration=1.0)[0]
    other.save(tmp_path / "ur5.npz")
    with pytest.raises(JointCountError, match="ur5.npz"):
        ci.identify(planar_2r, [data[0], tmp_path / "ur5.npz"], method="ols")
    with pytest.raises(DatasetError, match="empty"):
        ci.identify(planar_2r, iter([]), method="ols", covariance="iid")
    no_tau = ci.Dataset(t=data[0].t, q=data[0].q, dq=data[0].dq, ddq=data[0].ddq)
    with pytest.raises(DatasetError, match=r"data\[0\].*tau is missing"):
        ci.identify(planar_2r, iter([no_tau]), method="ols", covariance="iid")
    with pytest.raises(DatasetError, match="one Dataset"):
        DataStream(data[0])
    wild = data[0].with_torque(data[0].tau.copy())
    wild.tau[7, 1] = 1e12
    with pytest.raises(DatasetError, match=r"data\[1\].*tau\[7"):
        ci.identify(planar_2r, iter([data[0], wild]), method="ols")
    with pytest.raises(OptionError, match="loader"):
        DataStream([tmp_path], loader=3)


def test_memory_is_one_part_not_the_stream(planar_2r):
    """Python-traced peak memory while streaming 15 parts stays below 4 parts' worth of data
    (the stacked data would be 15; the regressor buffer is about one part here)."""
    template = runs(planar_2r, 1, duration=100.0, rate=200.0)[0]   # 20 000 samples
    part_bytes = sum(getattr(template, f).nbytes for f in ("t", "q", "dq", "ddq", "tau"))

    def parts():
        for k in range(15):
            yield template.with_torque(template.tau + 0.01 * k)  # a fresh array per part

    ci.identify(planar_2r, parts(), method="ols", covariance="iid")  # imports, caches
    tracemalloc.start()
    try:
        res = ci.identify(planar_2r, parts(), method="ols", covariance="iid")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert res.n_samples == 15 * template.n_samples
    assert peak < 4 * part_bytes + 1e6, (peak, part_bytes)


def test_payload_from_files_equals_the_stacked_recordings(tmp_path, ur5_model):
    """estimate_payload (route 1) reads a stream like identify: the same payload as the
    concatenated recordings, and it is the true one."""
    from consistid.robot.inertia import from_mass_com_inertia

    model = ur5_model
    payload = from_mass_com_inertia(1.2, (0.0, 0.02, 0.05), np.diag([2e-3, 2e-3, 1e-3]))
    loaded_truth = model.prior_parameters.copy()
    loaded_truth[-10:] += payload
    data = [ci.simulate.excitation_run(model, loaded_truth, duration=3.0, rate=100.0, seed=s,
                                       torque_noise=0.02).dataset for s in range(3)]
    paths = []
    for k, d in enumerate(data):
        paths.append(tmp_path / f"loaded{k}.npz")
        d.save(paths[-1])
    robot = model.prior_parameters
    streamed = ci.estimate_payload(model, paths, robot, friction=None)
    stacked = ci.estimate_payload(model, ci.Dataset.concatenate(data), robot, friction=None)
    assert streamed.n_samples == stacked.n_samples == sum(d.n_samples for d in data)
    np.testing.assert_allclose(streamed.mass, stacked.mass, rtol=1e-6)
    np.testing.assert_allclose(streamed.com, stacked.com, atol=1e-7)
    assert abs(streamed.mass - 1.2) < 0.05
    with pytest.raises(OptionError, match="stream"):
        ci.estimate_payload(model, 3.0, robot, friction=None)


def test_mounting_from_files_equals_the_stacked_recordings(tmp_path, ur5_model):
    """estimate_mounting reads a re-readable stream twice: the same tilt and ± as the stacked
    recordings; a generator (one pass) is refused."""
    from consistid.estimation.mounting import gravity_from_tilt

    g0 = ur5_model.gravity
    tilted = ur5_model.with_gravity(gravity_from_tilt(g0, np.radians([1.0, -0.5])))
    data = [ci.simulate.excitation_run(tilted, duration=3.0, rate=100.0, seed=s,
                                       torque_noise=0.05).dataset for s in range(3)]
    paths = []
    for k, d in enumerate(data):
        paths.append(tmp_path / f"tilted{k}.npz")
        d.save(paths[-1])
    streamed = ci.estimate_mounting(ur5_model, paths, friction=None)
    stacked = ci.estimate_mounting(ur5_model, ci.Dataset.concatenate(data), friction=None)
    np.testing.assert_allclose(streamed.angles, stacked.angles, atol=1e-9)
    np.testing.assert_allclose(streamed.covariance, stacked.covariance, rtol=1e-6)
    # (the tilt comes from Nelder–Mead on factors equal to round-off: equal to ~1e-9)
    np.testing.assert_allclose(streamed.autocorrelation_time, stacked.autocorrelation_time,
                               rtol=1e-6)
    np.testing.assert_allclose(np.degrees(streamed.angles), [1.0, -0.5], atol=0.2)
    with pytest.raises(OptionError, match="read once"):
        ci.estimate_mounting(ur5_model, (d for d in data), friction=None)
