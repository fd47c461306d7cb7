import numpy as np
import pinocchio as pin
import pytest

import consistid as ci
from consistid.identification.base import random_states
from consistid.robot.model import EXAMPLE_ROBOTS
from .conftest import PLANAR_2R, PLANAR_2R_VALUES


@pytest.mark.parametrize("name", sorted(EXAMPLE_ROBOTS))
def test_example_robots_load_with_names_and_prior(name):
    model = ci.RobotModel.example(name)
    assert len(model.joint_names) == model.nv == model.n_bodies
    assert len(model.parameter_names) == model.prior_parameters.size == 10 * model.n_bodies
    assert len(set(model.parameter_names)) == len(model.parameter_names)
    # every prior mass is the URDF's: positive for a real arm
    assert np.all(model.prior_parameters[0::10] > 0)


def test_panda_fingers_locked_and_merged_into_link7(panda):
    full = pin.buildModelFromUrdf(str(panda.source))
    assert full.nv == 9 and panda.nv == 7
    assert panda.body_names[-1] == "panda_link7"
    assert panda.parameter_names[66] == "panda_link7.Iyy"
    # link7 carries the hand and both fingers: total mass is conserved by locking
    total_full = sum(full.inertias[j].mass for j in range(1, full.njoints))
    assert panda.prior_parameters[0::10].sum() == pytest.approx(total_full, rel=1e-12)


def test_limits_read_from_urdf(panda):
    assert panda.limits.upper[3] == pytest.approx(-0.0698)
    assert panda.limits.velocity[4] == pytest.approx(2.61)
    assert panda.limits.effort[0] == pytest.approx(87.0)
    assert np.allclose(panda.gravity, [0, 0, -9.81])


def test_continuous_joints_use_angles():
    kinova = ci.RobotModel.example("kinova")
    assert kinova.pin_model.nq == 9 and kinova.nv == 6
    assert np.isinf(kinova.limits.upper[0])
    q = np.linspace(-2.0, 2.0, 6)
    qp = kinova.configuration(q)
    # Pinocchio's own integrate from neutral gives the same configuration
    assert np.allclose(qp, pin.integrate(kinova.pin_model, pin.neutral(kinova.pin_model), q))


def test_with_parameters_changes_inertias_only(panda):
    pi = panda.prior_parameters.copy()
    pi[30] *= 2.0
    changed = panda.with_parameters(pi)
    assert np.allclose(changed.prior_parameters, pi)
    assert np.allclose(panda.prior_parameters[30] * 2, changed.prior_parameters[30])
    assert changed.joint_names == panda.joint_names and changed.source == panda.source
    assert changed.locked_joints == panda.locked_joints
    assert np.array_equal(changed.gravity, panda.gravity)
    # the original is untouched (Pinocchio models are copied, not shared)
    assert panda.prior_parameters[30] == pi[30] / 2


def test_bad_inputs_raise_named_errors(tmp_path, panda):
    with pytest.raises(ci.OptionError, match=r"name='iiwa' is not an example robot; they are "
                       r"'panda', .* another arm: RobotModel\.from_urdf"):
        ci.RobotModel.example("iiwa")
    with pytest.raises(ci.ModelError, match="does not exist"):
        ci.RobotModel.from_urdf(tmp_path / "missing.urdf")
    with pytest.raises(ci.ModelError, match="unknown joint"):
        ci.RobotModel.from_urdf(panda.source, locked_joints=["finger"])
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint/></robot>")
    with pytest.raises(ci.ModelError, match="could not read"):
        ci.RobotModel.from_urdf(bad)
    with pytest.raises(ci.ModelError, match="10 per body"):
        panda.with_parameters(np.ones(5))
    with pytest.raises(ci.ModelError, match="not in locked_joints"):
        ci.RobotModel.from_urdf(panda.source, locked_configuration={"panda_joint1": 0.3})
    with pytest.raises(ci.JointCountError, match="q has 6 joints"):
        panda.rnea(np.zeros(6), np.zeros(6), np.zeros(6))


def test_unset_urdf_limits_read_as_unlimited_and_excite_the_double_pendulum():
    pend = ci.RobotModel.example("double_pendulum")
    lim = pend.limits
    assert np.all(np.isinf(lim.lower)) and np.all(np.isinf(lim.upper))
    assert np.all(np.isinf(lim.velocity)) and np.all(np.isinf(lim.effort))
    # random states now move, so the base map sees every identifiable column (link1.mz included)
    base = ci.compute_base_parameters(pend)
    q, dq, ddq = random_states(pend, 400, np.random.default_rng(0))
    y = ci.regressor(pend, q, dq, ddq)
    assert base.n_base == np.linalg.matrix_rank(y)
    assert np.ptp(q) > 1.0


def test_a_continuous_joint_locks_like_a_revolute_one(tmp_path):
    """A continuous joint (Pinocchio coordinates cos θ, sin θ; Tiago's wheels) locks at the
    angle given, and the merged model equals the one where the same joint is revolute (was:
    'only 1-coordinate joints')."""
    text = PLANAR_2R.format(**PLANAR_2R_VALUES)
    cont = text.replace('<joint name="joint2" type="revolute">', '<joint name="joint2" '
                        'type="continuous">')
    assert cont != text
    models = []
    for name, urdf in (("revolute", text), ("continuous", cont)):
        path = tmp_path / f"{name}.urdf"
        path.write_text(urdf)
        models.append(ci.RobotModel.from_urdf(path, locked_joints=["joint2"],
                                              locked_configuration={"joint2": 0.7}))
    np.testing.assert_allclose(models[1].prior_parameters, models[0].prior_parameters,
                               atol=1e-12)
    q = np.array([[0.3], [-1.1]])
    np.testing.assert_allclose(models[1].rnea(q, q, q), models[0].rnea(q, q, q), atol=1e-12)
