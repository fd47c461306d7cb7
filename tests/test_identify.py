import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.identification.compression import SIGMA_FLOOR
from consistid.errors import ModelMisfitWarning, PoorExcitationWarning
from consistid.robot.joint_terms import STANDSTILL_SPEED
from consistid.robot.inertia import perturb
from consistid.identification.regressor import dataset_regressor

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states


@pytest.fixture(scope="module")
def truth(panda):
    return perturb(panda.prior_parameters, 0.2, np.random.default_rng(7))


@pytest.fixture(scope="module")
def runs(panda, truth):
    train = ci.simulate.excitation_run(panda, truth, duration=30.0, rate=500.0,
                                       torque_noise=0.1, seed=1)
    held = ci.simulate.excitation_run(panda, truth, duration=10.0, rate=500.0,
                                      torque_noise=0.1, seed=2)
    return train.dataset, held.dataset


def test_ols_acceptance_on_simulated_panda(panda, truth, runs):
    train, held = runs
    res = ci.identify(panda, train, method="ols", friction=None)
    z = (res.base_parameters - res.base.project(truth)) / res.base_std
    assert np.mean(np.abs(z) < 3) >= 0.95
    assert np.all(res.rms(held) / 0.1 <= 1.05)
    assert res.sigma[0] == pytest.approx(0.1, rel=0.03)
    assert res.base.n_base == 43 and res.condition_number < 1e3
    text = res.summary()
    assert "panda_link3.mz*" in text and "cond(W_b)" in text and "Notes:" in text


def test_compressed_solution_equals_lstsq_on_all_rows(panda, runs):
    train, _ = runs
    res = ci.identify(panda, train, method="ols", friction=None)
    y = res.base.base_columns(dataset_regressor(panda, train))
    beta = np.linalg.lstsq(y, train.tau.ravel(), rcond=None)[0]
    assert np.allclose(res.base_parameters, beta, rtol=1e-9, atol=1e-12)
    # the standard vector predicts exactly what the base parameters predict
    assert np.allclose(res.predict(train).ravel(), y @ beta, atol=1e-9)


def test_wls_estimates_per_joint_noise_and_friction(panda, truth):
    rng = np.random.default_rng(3)
    friction = np.concatenate([rng.uniform(0.2, 1.0, 7), rng.uniform(0.05, 0.3, 7),
                               rng.uniform(-0.5, 0.5, 7)])
    run = ci.simulate.excitation_run(panda, np.concatenate([truth, friction]), duration=20.0,
                                     friction=("coulomb", "viscous", "offset"), seed=4,
                                     torque_noise=0.0)
    sigma = np.array([0.3, 0.3, 0.2, 0.2, 0.05, 0.05, 0.02])
    tau = run.dataset.tau + sigma * rng.standard_normal(run.dataset.tau.shape)
    res = ci.identify(panda, run.dataset.with_torque(tau), method="wls")
    assert np.allclose(res.sigma, sigma, rtol=0.05)
    names = list(res.base.names)
    for j, joint in enumerate(panda.joint_names):
        k = names.index(f"{joint}.fc")
        assert abs(res.base_parameters[k] - friction[j]) < 4 * res.base_std[k]
    ols = ci.identify(panda, run.dataset.with_torque(tau), method="ols")
    # weighting helps the low-noise wrist: its parameters get smaller standard deviations
    k = names.index("panda_joint7.fv")
    assert res.base_std[k] < ols.base_std[k]


def test_wls_floors_sigma_on_noise_free_data(tmp_path):
    """A noise-free fit leaves round-off residuals (or none): WLS must floor σ_j at
    SIGMA_FLOOR·RMS(τ_j) as the SDP does, not weight by 1/1e-16 (or divide by zero)."""
    path = tmp_path / "planar2r.urdf"
    path.write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    model = ci.RobotModel.from_urdf(path, gravity=(0.0, 0.0, -9.81))
    q, dq, ddq = random_states(model, 200, seed=0)
    dq[:120] = ddq[:120] = 0.0                  # at rest, torque and regressor rows exactly 0
    data = ci.Dataset(t=0.01 * np.arange(200), q=q, dq=dq, ddq=ddq, tau=model.rnea(q, dq, ddq))
    res = ci.identify(model, data, method="wls", friction=None)
    np.testing.assert_allclose(res.sigma, SIGMA_FLOOR * np.sqrt(np.mean(data.tau ** 2, axis=0)))
    expected = res.base.project(model.prior_parameters)
    assert np.max(np.abs(res.base_parameters - expected)) <= 1e-9 * np.max(np.abs(expected))
    assert np.all(np.isfinite(res.base_covariance))


def test_no_motion_raises_with_the_unexcited_directions(panda):
    n = 200
    q = np.tile(np.array([0, -0.5, 0, -2.0, 0, 1.5, 0.5]), (n, 1))
    still = ci.Dataset(t=np.arange(n) / 100, q=q, dq=np.zeros((n, 7)), ddq=np.zeros((n, 7)),
                       tau=panda.rnea(q, 0 * q, 0 * q))
    with pytest.raises(ci.PoorExcitationError, match="no motion at all"):
        ci.identify(panda, still, method="ols", friction=None)
    # one moving state repeated: motion, but the same regressor rows over and over
    dq = np.tile(np.linspace(0.1, 0.7, 7), (n, 1))
    repeated = ci.Dataset(t=still.t, q=q, dq=dq, ddq=0 * q, tau=panda.rnea(q, dq, 0 * q))
    with pytest.raises(ci.PoorExcitationError, match="condition number") as err:
        ci.identify(panda, repeated, method="ols", friction=None)
    assert "panda_link" in str(err.value)


def test_small_motion_warns_with_condition_number(panda, truth):
    traj = ci.FourierTrajectory.random(panda, 5, 10.0, seed=5, amplitude=0.05)
    run = ci.simulate.excitation_run(panda, truth, duration=2.0, trajectory=traj, seed=5)
    with pytest.warns(PoorExcitationWarning, match="condition number"):
        ci.identify(panda, run.dataset, method="ols", friction=None)


def test_unknown_options_are_refused(panda, runs):
    with pytest.raises(ci.OptionError, match="allowed: 'ols', 'wls', 'sdp'"):
        ci.identify(panda, runs[0], method="ridge")
    with pytest.raises(ci.OptionError, match="apply to method='sdp' only"):
        ci.identify(panda, runs[0], method="ols", prior="euclidean")
    # an explicit SDP default is an SDP option too: refused, not ignored
    for kw in (dict(prior="logdet"), dict(constraints="pseudo-inertia"),
               dict(constraints={"panda_link1": "none"}), dict(reweight=1)):
        with pytest.raises(ci.OptionError, match=f"{list(kw)[0]}.*apply to method='sdp' only"):
            ci.identify(panda, runs[0], method="wls", friction=None, **kw)


def test_wrong_argument_types_are_named(panda, runs):
    data = runs[0]
    cases = ((("panda", data), {}, ci.ModelError, "model must be a consistid.RobotModel"),
             ((panda, "data.npz"), {}, ci.DatasetError, "a Dataset or a list of Datasets"),
             ((panda, [data, 3]), {}, ci.DatasetError, r"dataset\[1\] is a int"),
             ((panda, data), dict(friction=5), ci.OptionError, "friction must be term names"),
             ((panda, data), dict(armature=2.5), ci.OptionError, "joints must be True/False"),
             ((panda, data), dict(friction={"offset": [1.5]}), ci.OptionError,
              "a joint is a name or an index, got 1.5"))
    for args, kw, error, message in cases:
        with pytest.raises(error, match=message):
            ci.identify(*args, method="ols", **kw)
    with pytest.raises(ci.DatasetError, match="held_out is an empty list"):
        ci.diagnose(panda, data, held_out=[])
    # numpy spellings are accepted like the Python ones; any iterable of Datasets stacks
    a = ci.identify(panda, (d for d in (data,)), method="ols",
                    friction=np.array(["coulomb", "offset"]), armature=np.True_)
    b = ci.identify(panda, [data], method="ols", friction=("coulomb", "offset"), armature=True)
    assert a.parameter_names == b.parameter_names
    np.testing.assert_allclose(a.base_parameters, b.base_parameters)
    # one joint alone, by name or index, is that joint
    one = ci.identify(panda, data, method="ols", friction=None, armature="panda_joint7")
    assert one.parameter_names[-1] == "panda_joint7.Ia"
    assert ci.identify(panda, data, method="ols", friction=None,
                       armature=6).parameter_names == one.parameter_names


def test_ols_accepts_saying_no_prior_and_no_constraints(planar_2r):
    """``prior=None``/``"none"`` and ``constraints="none"`` describe OLS/WLS: accepted."""
    q, dq, ddq = random_states(planar_2r, 100, seed=1)
    data = ci.Dataset(t=0.01 * np.arange(100), q=q, dq=dq, ddq=ddq,
                      tau=planar_2r.rnea(q, dq, ddq) + 0.01 * np.sin(np.arange(100))[:, None])
    plain = ci.identify(planar_2r, data, method="ols", friction=None)
    for kw in (dict(prior=None), dict(prior="none", constraints="none")):
        res = ci.identify(planar_2r, data, method="wls", friction=None, **kw)
        assert res.method == "wls"
        res = ci.identify(planar_2r, data, method="ols", friction=None, **kw)
        np.testing.assert_array_equal(res.base_parameters, plain.base_parameters)


def test_report_writes_the_summary(panda, runs, tmp_path):
    res = ci.identify(panda, runs[0], method="ols", friction=None)
    path = res.report(tmp_path / "report.txt")       # the path written, as Diagnosis.report
    assert path == tmp_path / "report.txt"
    assert path.read_text() == res.summary() + "\n"
    assert res.report() == res.summary()


def test_summary_prints_numbers_to_six_significant_digits(panda, runs):
    """The default prior weight 2/r² with r = 0.3 is 22.2… : the notes print 22.2222, not the
    float's 16 digits."""
    res = ci.identify(panda, runs[0], friction=None)
    np.testing.assert_allclose(res.details["prior_weight"], 2 / 0.3 ** 2, rtol=1e-12)
    assert "  - prior_weight: 22.2222\n" in res.summary()


def test_summary_says_at_bound_for_friction_held_at_zero(panda, runs):
    # No friction in the simulation: the SDP's bounds fc, fv ≥ 0 hold some of them at 0, where
    # σ % = 100·σ/|β| printed as ~1e10 % (σ over an estimate of 1e-12).
    res = ci.identify(panda, runs[0], friction=["coulomb", "viscous"])
    active = res.details["active_constraints"]
    held = [name for name in res.base.names if f"{name} ≥ 0" in active]
    assert held, "no bound active: this test would check nothing"
    cells = {line.split()[0]: line.split(None, 4)[4] for line in res.summary().splitlines()
             if line.split() and line.split()[0] in res.base.names}
    assert [cells[name] for name in held] == ["at bound"] * len(held)
    free = [cells[name] for name in res.base.names if name not in held]
    assert all(c == "inf" or float(c) < 1e5 for c in free), free
    np.testing.assert_array_equal(res.at_bound, [name in held for name in res.base.names])
    assert np.all(np.abs(res.base_parameters[res.at_bound]) < 1e-3 * res.base_std[res.at_bound])


@pytest.mark.parametrize("method", ["ols", "sdp"])
def test_coloured_covariance_matches_spread_over_seeds(panda, method):
    # Ideal data on one fixed trajectory plus AR(1) torque noise (φ = 0.95, τ = 39 samples):
    # the reported σ of well-determined base parameters must match their spread over seeds.
    from dataclasses import replace

    ideal = ci.simulate.excitation_run(panda, duration=10.0, rate=200.0, torque_noise=0.0,
                                       seed=0).dataset
    est, iid, col = [], [], []
    for seed in range(8):
        noise = ci.simulate.ar1_noise(ideal.tau.shape, 0.95, 0.05,
                                      np.random.default_rng(100 + seed))
        noisy = replace(ideal, tau=ideal.tau + noise)
        a = ci.identify(panda, noisy, method=method, friction=None, covariance="iid")
        b = ci.identify(panda, noisy, method=method, friction=None)       # default: coloured
        assert np.allclose(a.base_parameters, b.base_parameters)
        assert "iid" in a.details["covariance"] and "coloured" in b.details["covariance"]
        assert np.all(b.details["autocorrelation_time"] > 10)
        est.append(a.base_parameters), iid.append(a.base_std), col.append(b.base_std)
    est, iid, col = np.array(est), np.mean(iid, axis=0), np.mean(col, axis=0)
    spread = np.std(est, axis=0, ddof=1)
    best = np.argsort(iid / np.abs(est.mean(axis=0)))[:6]
    assert np.all((col[best] / spread[best] > 0.5) & (col[best] / spread[best] < 2.0))
    assert np.all(iid[best] / spread[best] < 0.35)


def test_coloured_ols_covariance_follows_each_joints_own_noise(panda):
    # AR(1) noise 15× larger on joints 1–3 than on 4–7: OLS weighs the joints alike, so the
    # sandwich needs each joint's residual variance; with one pooled variance the parameters
    # that the quiet joints determine got σ up to 2.5× their spread (5–95 %: 0.46–2.49).
    from dataclasses import replace

    ideal = ci.simulate.excitation_run(panda, duration=10.0, rate=200.0, torque_noise=0.0,
                                       seed=0).dataset
    scale = np.array([0.3, 0.3, 0.3, 0.02, 0.02, 0.02, 0.02])
    est, std = [], []
    for seed in range(8):
        rng = np.random.default_rng(100 + seed)
        noise = ci.simulate.ar1_noise(ideal.tau.shape, 0.95, 1.0, rng) * scale
        res = ci.identify(panda, replace(ideal, tau=ideal.tau + noise), method="ols",
                          friction=None)
        est.append(res.base_parameters), std.append(res.base_std)
    ratio = np.mean(std, axis=0) / np.std(est, axis=0, ddof=1)
    low, high = np.percentile(ratio, [5, 95])              # measured 0.52, 1.40
    assert 0.4 < low and high < 1.8


def test_coloured_covariance_on_white_noise_equals_iid(panda):
    run = ci.simulate.excitation_run(panda, duration=10.0, rate=200.0, torque_noise=0.05, seed=3)
    a = ci.identify(panda, run.dataset, method="wls", friction=None, covariance="iid")
    b = ci.identify(panda, run.dataset, method="wls", friction=None, covariance="coloured")
    assert np.all(b.details["autocorrelation_time"] < 1.5)
    assert np.allclose(b.base_std / a.base_std, 1.0, atol=0.25)
    assert "τ_j in samples" in b.summary()


def test_coloured_covariance_refuses_unknown_choice_and_huber(panda, runs):
    train, _ = runs
    with pytest.raises(ci.errors.OptionError, match="covariance"):
        ci.identify(panda, train, method="ols", covariance="newey-west")
    with pytest.raises(ci.errors.OptionError, match="huber"):
        ci.identify(panda, train, method="sdp", loss="huber", covariance="coloured")
    huber = ci.identify(panda, train, method="sdp", loss="huber")    # default: iid for Huber
    assert huber.details["covariance"].startswith("iid")


def test_results_read_a_recording_and_name_a_dataframe(tmp_path):
    """A loader's Recording stands for its dataset in a result's residual/rms/relative_error
    (raw AttributeError before); a pandas DataFrame given to identify is named, with how to read
    it (was "dataset file 't' does not exist"); a result never writes over its source URDF."""
    pd = pytest.importorskip("pandas")
    from consistid.data.recordings import from_arrays

    model = ci.RobotModel.example("ur5")
    run = ci.simulate.excitation_run(model, duration=4.0, rate=200.0, torque_noise=0.05, seed=2)
    data = run.dataset
    res = ci.identify(model, data, friction=None, covariance="iid")
    rec = from_arrays(data.t, data.q, data.tau, data.dq, data.ddq, model=model)
    np.testing.assert_array_equal(res.rms(rec), res.rms(rec.dataset))
    assert res.relative_error(rec)[1] == res.relative_error(rec.dataset)[1]
    with pytest.raises(ci.errors.DatasetError, match="DataFrame.*from_frame"):
        ci.identify(model, pd.DataFrame(data.columns()))
    with pytest.raises(ci.errors.ModelError, match="would write over the URDF"):
        res.to_urdf(model.source)
    with pytest.raises(ci.errors.ModelError, match="would write over the URDF"):
        res.to_mjcf(model.source)


def _held_at_rest(model: ci.RobotModel, joint: int | None, seed: int) -> ci.Dataset:
    """An excitation run (white noise σ = 0.05) whose torque, where ``joint`` stands still
    (|q̇| < STANDSTILL_SPEED), carries a held torque of up to 10 σ that no law of q̇ predicts
    (static friction holding it); ``joint=None``: none."""
    run = ci.simulate.excitation_run(model, duration=40.0, rate=200.0, torque_noise=0.05,
                                     seed=seed)
    data = run.dataset
    if joint is None:
        return data
    tau = data.tau.copy()
    rest = np.abs(data.dq[:, joint]) < STANDSTILL_SPEED
    assert rest.sum() >= 40, "too few samples at rest: the test would check nothing"
    tau[rest, joint] += np.random.default_rng(seed).uniform(-0.5, 0.5, rest.sum())
    return data.with_torque(tau)


@pytest.mark.parametrize("method", ["ols", "sdp"])
def test_a_residual_larger_at_standstill_is_said_and_kept(planar_2r, method):
    """A torque held at rest on joint 2 only (up to 10 σ, uniform): identify warns, naming that
    joint alone and its ratio (the RMS at rest over the RMS moving; the held torque's RMS is
    0.29 N·m against σ = 0.05, so several times), and keeps the note in details."""
    data = _held_at_rest(planar_2r, 1, seed=3)
    with pytest.warns(ModelMisfitWarning, match="stands still") as caught:
        res = ci.identify(planar_2r, data, method=method, friction=None)
    text = str([w for w in caught if w.category is ModelMisfitWarning][0].message)
    assert planar_2r.joint_names[1] in text and planar_2r.joint_names[0] not in text
    ratio = float(text.split(planar_2r.joint_names[1] + ": ")[1].split(" ×")[0])
    assert ratio > 3.0
    assert res.details["standstill"] == text


def test_equal_noise_at_rest_and_moving_is_not_called_a_misfit(planar_2r):
    """White noise of one σ everywhere: no joint's residual at rest is larger beyond chance."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelMisfitWarning)
        res = ci.identify(planar_2r, _held_at_rest(planar_2r, None, seed=3), friction=None)
    assert "standstill" not in res.details
