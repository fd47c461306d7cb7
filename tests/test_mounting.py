"""The mounting tilt (gravity direction in the base frame) estimated from torques."""

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.estimation.mounting import estimate_mounting, gravity_from_tilt
from consistid.identification.regressor import rigid_body_regressor

from .conftest import random_states

FRICTION = ("coulomb", "viscous", "offset")


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**16), g=st.lists(st.floats(-12, 12), min_size=3, max_size=3))
def test_regressor_is_affine_in_gravity(panda, seed, g):
    # the identity the estimator rests on, checked against Pinocchio with the gravity set
    q, dq, ddq = random_states(panda, 3, seed)
    rest = np.zeros_like(dq)
    split = rigid_body_regressor(panda.with_gravity(np.zeros(3)), q, dq, ddq) + sum(
        gk * rigid_body_regressor(panda.with_gravity(e), q, rest, rest)
        for gk, e in zip(g, np.eye(3)))
    direct = rigid_body_regressor(panda.with_gravity(g), q, dq, ddq)
    assert np.allclose(split, direct, atol=1e-9)
    tau = np.array([pin.rnea(panda.with_gravity(g).pin_model,
                             panda.with_gravity(g).pin_model.createData(), q[k], dq[k], ddq[k])
                    for k in range(3)])
    assert np.allclose(direct @ panda.prior_parameters, tau, atol=1e-9)


def test_with_gravity_copies_and_checks(panda):
    tilted = panda.with_gravity([0.1, 0.0, -9.8])
    assert np.allclose(tilted.gravity, [0.1, 0.0, -9.8])
    assert np.allclose(panda.gravity, [0.0, 0.0, -9.81])        # the original is untouched
    assert np.array_equal(tilted.prior_parameters, panda.prior_parameters)
    with pytest.raises(ci.ModelError, match="3 finite numbers"):
        panda.with_gravity([0.0, np.nan, -9.81])


def _tilted_run(model, roll, pitch, noise, seed=0):
    truth = model.with_gravity(gravity_from_tilt(model.gravity, (roll, pitch)))
    friction = np.concatenate([np.full(7, 0.3), np.full(7, 0.2), np.linspace(-0.2, 0.2, 7)])
    params = np.concatenate([model.prior_parameters, friction])
    return ci.simulate.excitation_run(truth, params, duration=10.0, rate=200.0,
                                      torque_noise=noise, friction=FRICTION, seed=seed).dataset


@pytest.mark.parametrize("roll_deg, pitch_deg", [(1.5, -0.8), (0.0, 0.0)])
def test_recovers_the_tilt_of_noise_free_data(panda, roll_deg, pitch_deg):
    roll, pitch = math.radians(roll_deg), math.radians(pitch_deg)
    est = estimate_mounting(panda, _tilted_run(panda, roll, pitch, 0.0), friction=FRICTION)
    assert np.allclose(est.angles, [roll, pitch], atol=1e-6)
    assert est.relative_error[1] < 1e-6
    assert np.isclose(np.linalg.norm(est.gravity), 9.81)
    assert np.isclose(est.tilt, math.acos(math.cos(roll) * math.cos(pitch)), atol=1e-6)
    assert np.allclose(est.model.gravity, est.gravity)


def test_noisy_estimate_is_within_its_standard_deviation(panda):
    roll, pitch = math.radians(-1.0), math.radians(2.0)
    errors = []
    for seed in range(3):
        est = estimate_mounting(panda, _tilted_run(panda, roll, pitch, 0.2, seed),
                                friction=FRICTION)
        errors.append((est.angles - [roll, pitch]) / est.std)
        assert est.relative_error[1] < est.relative_error[0]
        assert np.all(est.std < math.radians(0.2))
        assert np.allclose(est.autocorrelation_time, 1.0, atol=0.5)    # white noise: τ ≈ 1
    assert np.all(np.abs(errors) < 4.0)
    text = str(est)
    assert "about x" in text and "about y" in text and "→" in text


@pytest.mark.filterwarnings("ignore:URDF has no tag for torque offsets")
def test_identify_on_the_estimated_mounting_recovers_the_truth(panda, tmp_path):
    roll, pitch = math.radians(1.0), math.radians(0.5)
    data = _tilted_run(panda, roll, pitch, 0.0)
    level = ci.identify(panda, data, method="ols", friction=FRICTION)
    est = estimate_mounting(panda, data, friction=FRICTION)
    tilted = ci.identify(est.model, data, method="ols", friction=FRICTION)
    assert tilted.relative_error(data)[1] < 1e-6 < level.relative_error(data)[1]
    assert "gravity in the base frame" in tilted.summary()     # the report says which gravity
    assert "gravity in the base frame" not in level.summary()
    with pytest.warns(ci.errors.ExportWarning, match=r"no tag for gravity: .*\(-0.0856, "
                                                      r"\+0.1712, -9.8081\) m/s² .* not the level"):
        tilted.to_urdf(tmp_path / "tilted.urdf")


def test_refuses_what_it_cannot_estimate(panda):
    data = _tilted_run(panda, 0.0, 0.0, 0.1)
    with pytest.raises(ci.ModelError, match="zero gravity"):
        estimate_mounting(panda.with_gravity(np.zeros(3)), data)
    with pytest.raises(ci.JointCountError):
        estimate_mounting(ci.RobotModel.example("ur5"), data)


def test_a_direction_the_data_cannot_see_is_kept_level_with_infinite_std():
    # the double pendulum swings in a vertical plane: turning gravity within that plane shows
    # in its torques, turning it out of the plane does not (to first order)
    model = ci.RobotModel.example("double_pendulum")
    data = ci.simulate.excitation_run(model, duration=5.0, rate=100.0, torque_noise=0.0,
                                      seed=0).dataset
    with pytest.warns(ci.PoorExcitationWarning, match="1 of 2 directions"):
        est = estimate_mounting(model, data, friction=None)
    assert np.sum(np.isinf(est.std)) == 1
    assert np.allclose(est.angles, 0.0, atol=1e-9) and np.allclose(est.gravity, model.gravity)
