"""The repetition noise floor on logs whose torque changes once (issue 27): a joint's Coulomb
friction that steps after a pause, a payload released. Truth: the simulation's torque noise
through the chain's own filter (the chain applied to the noise-free and the noisy log)."""

import warnings

import numpy as np
import pinocchio as pin
import pytest

import consistid as ci
from consistid.data.signals import preprocess
from consistid.diagnosis.candidates import GapData
from consistid.diagnosis.noise import ar1_knee, estimate_noise_floor, repetition_estimate
from consistid.excitation import FourierTrajectory
from consistid.simulate import Effects, record

PERIOD, RATE = 5.0, 200.0


def payload_torque(model: ci.RobotModel, q, dq, ddq, mass: float) -> np.ndarray:
    """The torque a point mass at the last body's frame origin adds (RNEA with and without it,
    Pinocchio directly)."""
    heavy = model.pin_model.copy()
    last = heavy.njoints - 1
    heavy.inertias[last] = heavy.inertias[last] + pin.Inertia(mass, np.zeros(3),
                                                              np.zeros((3, 3)))
    a, b = model.pin_model.createData(), heavy.createData()
    return np.array([pin.rnea(heavy, b, model.configuration(q[k]), dq[k], ddq[k])
                     - pin.rnea(model.pin_model, a, model.configuration(q[k]), dq[k], ddq[k])
                     for k in range(q.shape[0])])


@pytest.mark.parametrize("arm, kind, seed", [("ur5", "friction step", 1), ("panda", "payload", 2),
                                             ("xarm7", "friction step", 3)])
def test_floor_within_its_accuracy_after_a_change(arm, kind, seed):
    """Four periods of training log; after 40 % of it one joint's Coulomb friction steps by
    1.5 N·m (its torque gains 1.5 sign(q̇)), or a 2 kg payload is released (the rigid-body
    torque it added goes): the reported floor lies within 0.7–1.5 × the processed noise's
    standard deviation on every joint (FLOOR_ACCURACY), where the mean of squares swells
    10–26 ×; the standard error is finite."""
    model = ci.RobotModel.example(arm)
    traj = FourierTrajectory.random(model, 3, PERIOD, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = record(model, traj, Effects(), duration=4 * PERIOD, rate=RATE, seed=seed)
    rng = np.random.default_rng(seed)
    noise = 0.05 * rng.standard_normal(rec.tau.shape)
    before = rec.t < rec.t[0] + 0.4 * (rec.t[-1] - rec.t[0])
    extra = np.zeros_like(rec.tau)
    if kind == "friction step":
        j = int(rng.integers(model.nv))
        extra[~before, j] = 1.5 * np.sign(rec.true_dq[~before, j])
    else:
        extra[before] = payload_torque(model, rec.q[before], rec.true_dq[before],
                                       rec.true_ddq[before], 2.0)
    noisy = preprocess(rec.t, rec.q, rec.tau + extra + noise).dataset
    clean = preprocess(rec.t, rec.q, rec.tau + extra).dataset
    true = np.std(noisy.tau - clean.tau, axis=0)
    g = GapData(model, noisy, model.prior_parameters)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        floor = estimate_noise_floor(noisy, g.tau, g.residual, g.tau_nom)
    ratio = floor.sigma / true
    assert np.all((ratio > 0.7) & (ratio < 1.5)), (ratio, floor.description)
    assert np.all(np.isfinite(floor.stderr))
    assert np.all(floor.raw > floor.sigma)            # the chain's low-pass removed noise
    # what a mean of squares over the period differences gives where the change is large
    changed = np.flatnonzero(np.sqrt(np.mean(extra ** 2, axis=0)) > 10 * true)
    d = noisy.tau[int(round(PERIOD * RATE)):] - noisy.tau[:-int(round(PERIOD * RATE))]
    swollen = np.sqrt(np.mean(d ** 2, axis=0) / 2)[changed] / true[changed]
    assert changed.size and np.all(swollen > 3), swollen


def test_repetition_estimate_of_clean_noise_has_an_honest_error():
    """White noise through the chain's filter on a repeating log, 20 seeds: the estimate's log
    error is covered by 3 × its standard error, and its mean bias is below 10 %."""
    t = np.arange(int(4 * PERIOD * RATE)) / RATE
    q = np.column_stack([np.sin(2 * np.pi * t / PERIOD), np.cos(4 * np.pi * t / PERIOD)])
    errors = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        data = preprocess(t, q, 5 * q + 0.1 * rng.standard_normal(q.shape)).dataset
        clean = preprocess(t, q, 5 * q).dataset
        rep = repetition_estimate(data, data.tau, PERIOD, data.torque_filter)
        log_error = np.log(rep.sigma / np.std(data.tau - clean.tau, axis=0))
        assert np.all(np.abs(log_error) <= 3 * rep.stderr), (log_error, rep.stderr)
        errors.append(log_error)
    assert abs(np.mean(errors)) < 0.1


def test_ar1_knee_of_a_vanishing_coefficient_does_not_overflow():
    """The knee ``f_r ln(1/φ)/2π`` for φ = 1e-310 (a fitted white spectrum): finite, no
    RuntimeWarning (``1/φ`` overflows)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        knee = ar1_knee(1e-310, 1000.0)
    assert knee == pytest.approx(1000.0 * 310 * np.log(10) / (2 * np.pi))
    assert ar1_knee(0.5, 200.0) == pytest.approx(200.0 * np.log(2) / (2 * np.pi))
    assert ar1_knee(0.0, 200.0) == np.inf
