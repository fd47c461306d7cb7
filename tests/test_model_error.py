"""The covariance's model-error term for the rows at rest (identification/model_error.py), and
the coverage of identify's 95 % intervals on a MuJoCo arm with dry and viscous friction."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.stats

import consistid as ci
from consistid.identification.model_error import rest_bias, rest_problem
from consistid.identification.regressor import RegressorSpec, dataset_regressor
from consistid.simulate.mujoco_logs import friction_run

FRICTION = ("coulomb", "viscous", "offset")


def test_intervals_cover_the_mujoco_truth_with_dry_friction():
    """UR5 in MuJoCo, inertias ±12 % off the URDF, frictionloss + damping on every joint: the
    reported 95 % intervals (OLS and SDP, default covariance) hold the simulated truth for at
    least 88 % of the base parameters, and 90 % of the Coulomb and viscous ones, over two seeds.
    Measured: 1.00 and 1.00; with intervals half as wide, 0.63–0.75 of the friction terms (so
    this fails for them); with the noise-only sandwich, 0.29–0.42."""
    model = ci.RobotModel.example("ur5")
    z = {"ols": [], "sdp": []}
    friction = {"ols": [], "sdp": []}
    for seed in (3, 8):
        run = friction_run(model, seed)
        data = run.dataset
        for method in z:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, data, method=method, friction=FRICTION)
            truth = res.base.project(run.truth(model, list(res.parameter_names)))
            std = np.sqrt(np.diag(res.base_covariance))
            z[method].append(np.abs(res.base_parameters - truth) / std)
            friction[method].append([res.parameter_names[c].endswith((".fc", ".fv"))
                                     for c in res.base.independent])
            assert "model_error_note" in res.details
    for method, values in z.items():
        values, terms = np.concatenate(values), np.concatenate(friction[method])
        covered = np.mean(values <= 1.96)
        assert covered >= 0.88, f"{method}: 95 % intervals hold the truth for {covered:.2f}"
        covered = np.mean(values[terms] <= 1.96)
        assert covered >= 0.9, f"{method}: friction intervals hold the truth for {covered:.2f}"


def test_rest_bias_is_the_difference_of_two_explicit_fits(planar_2r):
    """``δ`` of rest_bias equals the difference of two least-squares fits computed on the
    explicit regressor (numpy lstsq): all rows, and all rows but those at rest; a torque
    disturbance on the rows at rest only (a stuck joint's torque) gives a b² that covers δ's
    excess over its noise (or that noise, when the excess is smaller), and data with no joint
    at rest give no rest problem."""
    rng = np.random.default_rng(0)
    traj = ci.FourierTrajectory.random(planar_2r, 3, 4.0, rng)
    data = traj.sample(100.0, 8.0)
    spec = RegressorSpec.make(planar_2r, ("coulomb", "viscous"))
    base = ci.identification.base.compute_base_parameters(planar_2r, spec)
    cols = base.independent
    y = dataset_regressor(planar_2r, data, spec).reshape(data.n_samples, planar_2r.nv, -1)
    theta = np.concatenate([planar_2r.prior_parameters, [0.5, 0.3, 0.2, 0.4]])
    tau = np.einsum("njp,p->nj", y, theta) + 0.01 * rng.standard_normal((data.n_samples, 2))
    rest = np.abs(data.dq) < ci.robot.joint_terms.STANDSTILL_SPEED
    assert rest.any()
    tau = tau + np.where(rest, 0.3, 0.0)                 # a stuck joint's torque, not sign(q̇)
    data = data.with_torque(tau)
    problem = ci.identification.compression.compress(planar_2r, data, spec, base=base)
    at_rest = rest_problem(planar_2r, data, spec, base)
    w = np.array([1.0, 1.0])
    b2, delta = rest_bias(problem, at_rest, cols, w, np.ones(2), np.full(2, 1e-4))
    a = y[:, :, cols]
    fit_all = np.linalg.lstsq(a.reshape(-1, cols.size), tau.ravel(), rcond=None)[0]
    keep = ~rest.ravel()
    fit_moving = np.linalg.lstsq(a.reshape(-1, cols.size)[keep], tau.ravel()[keep],
                                 rcond=None)[0]
    np.testing.assert_allclose(delta, fit_all - fit_moving, rtol=1e-6,
                               atol=1e-9 * np.max(np.abs(fit_all)))
    # the noise part of δ's variance, V_moving − V_all, from the explicit regressors (white
    # residual of variance 1e-4 on every row): b² is δ²'s excess over it, or it at least
    flat = a.reshape(-1, cols.size)
    gap = 1e-4 * np.diag(np.linalg.inv(flat[keep].T @ flat[keep]) - np.linalg.inv(flat.T @ flat))
    np.testing.assert_allclose(b2, np.maximum(delta ** 2 - gap, gap), rtol=1e-6, atol=1e-15)
    assert np.all(gap > 0) and np.any(delta ** 2 > 2 * gap)
    moving = data.select(~rest.any(axis=1))
    assert rest_problem(planar_2r, moving, spec, base) is None


#: A joint the motion never moves faster than this (rad/s) is too slow to check its friction law
#: against the noise (the premise of the next test), as the warning's text says.
SLOW_SPEED = 0.32


@pytest.mark.parametrize("arm, seed", [
    ("kinova", 0), ("kinova", 5), ("kinova", 1), ("xarm7", 0)])
def test_a_joint_too_slow_to_check_its_friction_is_warned_and_covered(arm, seed):
    """An arm in MuJoCo (benchmarks/coverage_friction.py's runs) whose slowest joints never
    move faster than SLOW_SPEED, inside the band where MuJoCo's soft frictionloss is not
    f_c·sign(q̇) + f_v·q̇ (Kinova seed 0: joints 4 and 6, seed 5: joint 6, seed 1: joints 4 and 6
    below 0.09 rad/s; xArm7 seed 0: joint 7 below 0.06 rad/s; found from the data, not listed).
    Seeds 1 and 0 leave a residual that is the noise's in every band (the fit reads the smoothed
    step as a steep viscous slope, f_c ≈ 0): they are found by that slope and their intervals
    include the Coulomb/viscous split the data cannot make. They are warned
    (PoorExcitationWarning, details['slow_joints']), their rows below their fastest band count
    as at rest, and the 95 % intervals of their Coulomb and
    viscous terms hold the simulated truth as 95 % intervals do: of m terms, at least the 2 %
    quantile of Binomial(m, 0.95) lie within 1.96 σ (3 of 4, 1 of 2: a calibrated σ fails this
    in < 2 % of runs) and none beyond 3.29 σ (the two-sided 0.1 % point). Measured |error|/σ:
    Kinova seed 0 0.12, 0.69, 0.55, 0.76; seed 5 0.35, 0.72; seed 1 0.00, 0.95, 1.67, 0.92;
    xArm7 seed 0 1.29, 0.98 (before the split's error: Kinova seed 1 0.00, 3.32, 10.7, 3.62,
    xArm7 30.8, 18.6; before the slope test, unwarned and 24–280 σ off)."""
    model = ci.RobotModel.example(arm)
    run = friction_run(model, seed, duration=30.0, rate=500.0)
    data = run.dataset
    joints = np.flatnonzero(np.abs(data.dq).max(axis=0) < SLOW_SPEED)
    assert joints.size
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = ci.identify(model, data, method="ols", friction=FRICTION)
    slow = [str(w.message) for w in caught if issubclass(w.category, ci.PoorExcitationWarning)
            and "never moved faster" in str(w.message)]
    assert slow and all(model.joint_names[j] in slow[0] for j in joints), slow
    assert np.all(res.details["model_error_speed"][joints] > 0.02)
    names = list(res.parameter_names)
    truth = res.base.project(run.truth(model, names))
    z = np.abs(res.base_parameters - truth) / np.sqrt(np.diag(res.base_covariance))
    base_names = [names[c] for c in res.base.independent]
    z = np.array([z[base_names.index(f"{model.joint_names[j]}.{term}")]
                  for j in joints for term in ("fc", "fv")])
    need = scipy.stats.binom.ppf(0.02, z.size, 0.95)
    assert np.sum(z <= 1.96) >= need and np.all(z < 3.29), f"|error|/σ {np.round(z, 2)}"


def test_slow_joints_need_a_structured_residual():
    """ResidualStatistics.slow_joints from band sums built here: a joint whose fastest band is
    empty is one when its band variances differ beyond BAND_RATIO (4× in variance here) and
    not when they are alike (white noise), nor when it reaches the fastest band; its rows below
    the fastest band it reaches count as at rest, the white one's below STANDSTILL_SPEED
    (no autocovariance given: τ = 1)."""
    from consistid.identification.streaming import SPEED_EDGES, ResidualStatistics

    nb = SPEED_EDGES.size + 1
    count = np.full((3, nb), 2000.0)
    count[:2, -1] = 0.0                                 # joints 0 and 1 never reach it
    var = np.full((3, nb), 0.01)
    var[0, 3:] = 0.04                                   # joint 0: structured residual
    var[2, :3] = 0.04                                   # joint 2: structured, but reaches it
    stats = ResidualStatistics(None, (var * count).sum(axis=1), int(count[2].sum()),
                               np.zeros(3), np.zeros(3), var * count, count)
    np.testing.assert_array_equal(stats.slow_joints(), [0])
    speeds = stats.rest_speeds()
    assert speeds[0] == SPEED_EDGES[-2] and speeds[1] == SPEED_EDGES[0]


def test_a_slow_joint_whose_fit_reads_a_slope_is_slow():
    """ResidualStatistics.slow_joints with a residual alike in every band: a joint that never
    reaches the fastest band is one when its fitted Coulomb level is at most STEP_SHARE of its
    viscous torque at its fastest speed (viscous_speed = |f_c|/f_v ≤ STEP_SHARE × top_speed),
    not when the Coulomb step holds its own beside it, nor when it reaches the fastest band
    (τ = 1)."""
    from consistid.identification.streaming import SPEED_EDGES, ResidualStatistics

    nb = SPEED_EDGES.size + 1
    count = np.full((3, nb), 2000.0)
    count[:2, -1] = 0.0                                 # joints 0 and 1 never reach it
    var = np.full((3, nb), 0.01)                        # white: alike in every band
    args = (None, (var * count).sum(axis=1), int(count[2].sum()), np.zeros(3), np.zeros(3),
            var * count, count)
    top = np.array([0.09, 0.09, 1.0])
    slope = ResidualStatistics(*args, top_speed=top, viscous_speed=np.array([0.01, 0.05, 0.5]))
    np.testing.assert_array_equal(slope.slow_joints(), [0])
    assert slope.rest_speeds()[0] == SPEED_EDGES[-2]
    np.testing.assert_array_equal(ResidualStatistics(*args).slow_joints(), [])
    pooled = slope + ResidualStatistics(*args, top_speed=np.array([0.3, 0.3, 1.0]),
                                        viscous_speed=np.array([0.01, 0.05, 0.5]))
    np.testing.assert_array_equal(pooled.slow_joints(), [0, 1])
    # the same slope read with σ(f̂_v)/f̂_v = 0.4 (clear of 0 at 1.96 σ) and 0.6 (not)
    noisy = ResidualStatistics(*args, top_speed=top, viscous_speed=np.array([0.01, 0.05, 0.5]),
                               viscous_noise=np.array([0.6, 0.4, 0.1]))
    np.testing.assert_array_equal(noisy.slow_joints(), [])
    clear = ResidualStatistics(*args, top_speed=top, viscous_speed=np.array([0.01, 0.05, 0.5]),
                               viscous_noise=np.array([0.4, 0.4, 0.1]))
    np.testing.assert_array_equal(clear.slow_joints(), [0])


@pytest.mark.parametrize("arm, seeds", [("ur5", (7, 19, 22)), ("panda", (14,)),
                                        ("xarm7", (18,))])
def test_poor_data_whose_friction_law_holds_flag_no_slow_joint(arm, seeds):
    """2 s of small motion (every joint below ~0.16 rad/s, speed bands of ~25 samples), torques
    from pin.rnea of the URDF plus f_c·sign(q̇) + f_v·q̇ exactly and white noise, the SDP: the
    friction law holds, so no joint is warned slow. These seeds were (UR5 shoulder_lift and
    wrist_3, Panda joint 3, xArm7 joint 7): a noise slope (f̂_v 0.12 ± 8.5·10⁵) read as
    smoothed dry friction, or the extreme pair of four band variances tested as if it were the
    only one (5 of 90 such runs on four arms; none after)."""
    model = ci.RobotModel.example(arm)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        data = ci.FourierTrajectory.random(model, 5, 10.0, rng, amplitude=0.05).sample(200.0,
                                                                                       2.0)
        fc, fv = rng.uniform(0.5, 2.0, model.nv), rng.uniform(0.2, 1.0, model.nv)
        tau = (model.rnea(data.q, data.dq, data.ddq) + fc * np.sign(data.dq) + fv * data.dq
               + 0.1 * rng.standard_normal(data.q.shape))
        assert np.abs(data.dq).max() < SLOW_SPEED
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ci.identify(model, data.with_torque(tau), method="sdp", friction=FRICTION)
        slow = [str(w.message) for w in caught if "never moved faster" in str(w.message)]
        assert not slow, (seed, slow[0][:80])


def test_a_sharp_step_beside_a_steep_slope_on_a_slow_joint_is_not_slow():
    """A harmonic drive's friction: f_c = 1 N·m beside f_v = 5 N·m·s/rad on a wrist that never
    exceeds ~0.27 rad/s, sharp ``f_c sign(q̇) + f_v q̇`` (the law holds), σ = 0.05 N·m. The fit
    resolves the step, so the joint is not read as a slope: no slow-joint warning, and the
    Coulomb and viscous σ stay the data's (the review's repro: σ(f_v) was 5.00, 100 % of it)."""
    model = ci.RobotModel.example("ur5")
    rng = np.random.default_rng(0)
    t = np.arange(0, 60, 0.002)
    amp = rng.uniform(0.2, 0.4, size=(3, model.nv)) / np.arange(1, 4)[:, None]
    amp[:, -1] *= 0.55                                           # the slow wrist
    phase = rng.uniform(0, 2 * np.pi, size=(3, model.nv))
    w = 2 * np.pi * 0.1 * np.arange(1, 4)[:, None, None]
    arg = w * t[None, :, None] + phase[:, None, :]
    q = np.sum(amp[:, None, :] * np.sin(arg), axis=0)
    dq = np.sum(amp[:, None, :] * w * np.cos(arg), axis=0)
    ddq = -np.sum(amp[:, None, :] * w ** 2 * np.sin(arg), axis=0)
    assert 0.1 < np.abs(dq[:, -1]).max() < SLOW_SPEED
    tau = (model.rnea(q, dq, ddq) + np.sign(dq) + 5.0 * dq
           + 0.05 * rng.standard_normal(q.shape))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = ci.identify(model, ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau),
                          friction=FRICTION, method="ols")
    assert not [w for w in caught if "never moved faster" in str(w.message)]
    names = list(res.parameter_names)
    base = [names[c] for c in res.base.independent]
    std = np.sqrt(np.diag(res.base_covariance))
    for term, truth in (("fc", 1.0), ("fv", 5.0)):
        k = base.index(f"{model.joint_names[-1]}.{term}")
        assert abs(res.base_parameters[k] - truth) < 0.02 * truth
        assert std[k] < 0.05 * truth, (term, std[k])


def test_white_noise_at_rest_adds_no_model_error(panda):
    """2 s of small Panda motion (benchmarks/run_all.py's ``poor`` case: many rows at rest),
    torques from pin.rnea of the URDF plus white noise, no friction: nothing is wrong at rest,
    so Hausman's test leaves the model-error term closed in all but its false alarms (level
    5 %: at most 3 of 20 runs, P(Binomial(20, 0.05) > 3) = 1.6 %), and elsewhere the default
    intervals are the exact OLS ones (s² (YᵀY)⁻¹ from the explicit regressor, numpy) up to the
    sampling error of the autocorrelation time and of each joint's own residual variance, which
    the sandwich uses (within −10 %, +15 %). Before the gate every run
    carried the floor V_moving − V_all: σ up to 1.9 × the exact OLS σ (coverage 0.977 on the
    benchmark's 50 runs for 0.95)."""
    spec = RegressorSpec.make(panda, None)
    opened = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        data = ci.FourierTrajectory.random(panda, 5, 10.0, rng, amplitude=0.2).sample(200.0, 2.0)
        tau = panda.rnea(data.q, data.dq, data.ddq) + 0.1 * rng.standard_normal(data.q.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = ci.identify(panda, data.with_torque(tau), method="ols", friction=None)
        assert np.any(np.abs(data.dq) < ci.robot.joint_terms.STANDSTILL_SPEED)
        if np.any(res.details["model_error"] > 0):
            opened += 1
            continue
        y = dataset_regressor(panda, data, spec)[:, res.base.independent]
        beta, rss = np.linalg.lstsq(y, tau.ravel(), rcond=None)[:2]
        exact = np.diag(np.linalg.inv(y.T @ y)) * rss[0] / (y.shape[0] - y.shape[1])
        np.testing.assert_allclose(res.base_parameters, beta, rtol=1e-6,
                                   atol=1e-8 * np.max(np.abs(beta)))
        ratio = np.sqrt(np.diag(res.base_covariance) / exact)
        assert np.all((ratio > 0.9) & (ratio < 1.15)), np.round(ratio, 3)
    assert opened <= 3, opened
