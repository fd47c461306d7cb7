"""The MuJoCo robot against Pinocchio, and each effect against its closed form."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.errors import ModelError, OptionError
from consistid.excitation import FourierTrajectory
from consistid.simulate.mujoco_robot import MujocoRobot
from consistid.robot.inertia import perturb
from consistid.simulate.effects import Effects, MountedPayload, effect_torque, sensor_torque
from consistid.simulate import TrackingController, record

from .conftest import random_states

SHORT = dict(duration=2.0, settle=0.1)


@pytest.fixture(scope="module")
def trajectory(panda):
    return FourierTrajectory.random(panda, 5, 10.0, seed=3)


@pytest.fixture(scope="module")
def nominal(panda, trajectory):
    """A run without effects, and its RNEA torques at the true states."""
    rec = record(panda, trajectory, **SHORT)
    return rec


def rnea_at(model, rec):
    return model.rnea(rec.true_q, rec.true_dq, rec.true_ddq)


# ----------------------------------------------------------------------------- model equivalence
@pytest.mark.parametrize("name", ["panda", "ur5", "kinova"])
def test_inverse_dynamics_equals_rnea(name):
    model = ci.RobotModel.example(name)
    q, dq, ddq = random_states(model, 40, seed=0)
    tau = MujocoRobot(model).inverse(q, dq, ddq)
    np.testing.assert_allclose(tau, model.rnea(q, dq, ddq), rtol=0, atol=1e-8)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_inverse_dynamics_with_true_parameters_and_armature(panda, seed):
    """True parameters go into the MJCF; Pinocchio's armature becomes dof_armature."""
    rng = np.random.default_rng(seed)
    truth = perturb(panda.prior_parameters, 0.3, rng)
    true_model = panda.with_parameters(truth)
    true_model.pin_model.armature = rng.uniform(0, 0.5, panda.nv)
    q, dq, ddq = random_states(panda, 5, seed)
    np.testing.assert_allclose(MujocoRobot(true_model).inverse(q, dq, ddq),
                               true_model.rnea(q, dq, ddq), rtol=0, atol=1e-8)


def test_locked_fingers_are_merged_like_pinocchio(panda):
    robot = MujocoRobot(panda)
    assert robot.mj_model.nv == panda.nv == 7
    hand = panda.pin_model.inertias[7]
    assert robot.mj_model.body_mass[-1] == pytest.approx(hand.mass, abs=1e-12)


# ----------------------------------------------------------------------------- acceptance
def test_identification_through_signal_chain_recovers_base_parameters(panda):
    """No effects, no noise: MuJoCo log → Dataset.from_recording → OLS recovers β to 1e-3."""
    truth = perturb(panda.prior_parameters, 0.2, np.random.default_rng(11))
    traj = FourierTrajectory.random(panda, 5, 10.0, seed=0)
    rec = record(panda, traj, true_parameters=truth, duration=10.0, settle=0.5)
    data = ci.Dataset.from_recording(rec.t, rec.q, rec.tau, bandwidth=0.5)
    res = ci.identify(panda, data, method="ols", friction=None)
    beta = res.base.project(truth)
    error = res.base_parameters - beta
    assert np.linalg.norm(error) / np.linalg.norm(beta) < 1e-3
    # the same in torque, at the exact states: the prediction error is < 1e-3 of the torque
    residual = res.residual(rec.true_dataset())
    assert np.linalg.norm(residual) < 1e-3 * np.linalg.norm(rec.tau)
    np.testing.assert_allclose(rec.true_parameters, truth)


def test_record_is_a_real_log(panda, nominal):
    rec = nominal
    assert rec.t[0] == 0.0 and np.allclose(np.diff(rec.t), 1e-3)
    assert rec.q.shape == rec.tau.shape == (2000, 7)
    np.testing.assert_allclose(rec.q, rec.true_q)          # no sensor effects
    np.testing.assert_allclose(rec.tau, rnea_at(panda, rec), atol=1e-9)
    assert np.max(np.abs(rec.true_q - rec.desired_q)) < 1e-3   # perfect model: tight tracking


# ----------------------------------------------------------------------------- effects, one each
def run(panda, trajectory, effects, **kw):
    rec = record(panda, trajectory, effects, **{**SHORT, **kw})
    return rec, rec.tau - rnea_at(panda, rec)


def test_viscous(panda, trajectory):
    fv = np.linspace(0.2, 0.8, 7)
    rec, extra = run(panda, trajectory, Effects(viscous=fv))
    np.testing.assert_allclose(extra, fv * rec.true_dq, atol=1e-9)


def test_coulomb_frictionloss(panda, trajectory):
    fc = np.linspace(0.5, 2.0, 7)
    rec, extra = run(panda, trajectory, Effects(coulomb=fc))
    moving = np.abs(rec.true_dq) > 0.01
    assert moving.mean() > 0.75   # the wrist sticks at times (stick-slip under 2 N·m)
    np.testing.assert_allclose(extra[moving], (fc * np.sign(rec.true_dq))[moving], atol=1e-9)
    assert np.all(np.abs(extra) <= fc + 1e-9)   # never more than the friction bound


def test_coulomb_tanh(panda, trajectory):
    fc, speed = np.linspace(0.5, 2.0, 7), 0.5
    rec, extra = run(panda, trajectory, Effects(coulomb=fc, coulomb_model="tanh",
                                                coulomb_speed=speed))
    np.testing.assert_allclose(extra, fc * np.tanh(rec.true_dq / speed), atol=1e-9)


def test_tanh_too_stiff_for_the_step_raises(panda, trajectory):
    with pytest.raises(ModelError, match="panda_joint7.*coulomb_speed"):
        record(panda, trajectory, Effects(coulomb=2.0, coulomb_model="tanh",
                                          coulomb_speed=0.01), duration=0.01, settle=0.0)


def test_armature(panda, trajectory):
    ia = np.linspace(0.05, 0.4, 7)
    rec, extra = run(panda, trajectory, Effects(armature=ia))
    np.testing.assert_allclose(extra, ia * rec.true_ddq, atol=1e-9)


def test_payload(panda, trajectory):
    """The extra torque is the flange body's regressor times the payload's 10-vector, which is
    the payload's (m, c, I_c) moved from the hand frame to joint 7's frame."""
    payload = MountedPayload(1.5, (0.01, -0.02, 0.08), np.diag([0.004, 0.005, 0.003]),
                      frame="panda_hand")
    rec, extra = run(panda, trajectory, Effects(payload=payload))
    pm = panda.pin_model
    placement = pm.frames[pm.getFrameId("panda_hand")].placement
    com = placement.act(np.array([0.01, -0.02, 0.08]))
    assert rec.payload_joint == 6
    np.testing.assert_allclose(rec.payload_parameters[:4], 1.5 * np.r_[1.0, com], atol=1e-12)
    data = pm.createData()
    y = np.array([pin.computeJointTorqueRegressor(pm, data, q, v, a)[:, 60:70]
                  for q, v, a in zip(rec.true_q, rec.true_dq, rec.true_ddq)])
    np.testing.assert_allclose(extra, y @ rec.payload_parameters, atol=1e-9)
    assert np.max(np.abs(extra)) > 1.0


def test_torque_offset_and_gain(panda, trajectory):
    offset, gain = np.arange(7) - 3.0, np.linspace(-0.05, 0.1, 7)
    rec, _ = run(panda, trajectory, Effects(torque_offset=offset, torque_gain=gain))
    np.testing.assert_allclose(rec.true_tau, rnea_at(panda, rec), atol=1e-9)
    np.testing.assert_allclose(rec.tau, (1 + gain) * rec.true_tau + offset, atol=1e-9)


def test_delay(panda, trajectory):
    rec, _ = run(panda, trajectory, Effects(delay={"panda_joint2": 0.004}))
    rn = rnea_at(panda, rec)
    np.testing.assert_allclose(rec.tau[4:, 1], rn[:-4, 1], atol=1e-9)
    np.testing.assert_allclose(np.delete(rec.tau, 1, axis=1), np.delete(rn, 1, axis=1),
                               atol=1e-9)
    assert np.max(np.abs(rec.tau[:, 1] - rn[:, 1])) > 0.01


def test_elasticity(panda, trajectory):
    """Spong's model: the sensor reads τ_J = K(θ − q) + D(θ̇ − q̇), which is the link-side RNEA;
    drive-side friction is invisible to it; the encoder reads the motor angle θ."""
    k, d = np.full(7, 4000.0), 3.0
    eff = Effects(stiffness=k, spring_damping=d, motor_inertia=0.3, viscous=0.5, coulomb=1.0)
    rec, _ = run(panda, trajectory, eff)
    spring = k * (rec.motor_q - rec.true_q) + d * (rec.motor_dq - rec.true_dq)
    np.testing.assert_allclose(rec.tau, spring, atol=1e-9)
    np.testing.assert_allclose(rec.tau, rnea_at(panda, rec), atol=1e-6)
    np.testing.assert_allclose(rec.q, rec.motor_q)
    assert np.max(np.abs(rec.motor_q - rec.true_q)) > 1e-3     # the deflection is visible
    link, _ = run(panda, trajectory, Effects(stiffness=k, position_sensor="link"))
    np.testing.assert_allclose(link.q, link.true_q)


def test_divergence_raises_instead_of_a_silently_reset_log(panda, trajectory):
    """Too stiff a spring for a 1 ms step on the light wrist: MuJoCo would reset and go on."""
    with pytest.raises(ModelError, match="diverged.*physics_rate"):
        record(panda, trajectory, Effects(stiffness=50000.0), duration=0.5, settle=0.0)


def test_quantisation(panda, trajectory):
    step = 2 * np.pi / 2 ** 14
    rec, _ = run(panda, trajectory, Effects(quantisation=step))
    counts = rec.q / step
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    assert np.max(np.abs(rec.q - rec.true_q)) <= step / 2 + 1e-12


def test_noise(panda, trajectory):
    rec, extra = run(panda, trajectory, Effects(position_noise=1e-4, torque_noise=0.05),
                     seed=5)
    assert np.std(rec.q - rec.true_q) == pytest.approx(1e-4, rel=0.05)
    assert np.std(extra) == pytest.approx(0.05, rel=0.05)
    again, _ = run(panda, trajectory, Effects(position_noise=1e-4, torque_noise=0.05), seed=5)
    np.testing.assert_array_equal(again.tau, rec.tau)    # seeded


def test_effect_torque_is_the_closed_form_of_several_effects_at_once(panda, trajectory):
    payload = MountedPayload(0.8, (0.0, 0.02, 0.05))
    eff = Effects(viscous=0.3, coulomb=0.4, armature=0.1, payload=payload,
                  torque_offset=0.2, torque_gain=-0.03)
    rec, _ = run(panda, trajectory, eff)
    truth = (rec.true_q, rec.true_dq, rec.true_ddq)
    predicted = sensor_torque(rec.effects, panda.rnea(*truth)
                              + effect_torque(panda, rec.effects, *truth))
    moving = np.abs(rec.true_dq) > 0.01
    # (friction loss is a soft constraint: near 0.01 rad/s it can miss saturation by ~1e-7)
    np.testing.assert_allclose(rec.tau[moving], predicted[moving], atol=1e-6)


# ----------------------------------------------------------------------------- the effect API
def test_effects_resolve_per_joint(panda):
    eff = Effects(viscous=0.3, coulomb={"panda_joint2": 1.5, 4: 0.5}).for_model(panda)
    np.testing.assert_allclose(eff.viscous, np.full(7, 0.3))
    np.testing.assert_allclose(eff.coulomb, [0, 1.5, 0, 0, 0.5, 0, 0])
    assert Effects(viscous=0.3, coulomb={"panda_joint2": 1.5}).active() == ["viscous", "coulomb"]
    assert Effects().active() == [] and "no effects" in Effects().describe()
    one = Effects().with_effect("elasticity", 3000.0, joints=[1]).with_effect(
        "elasticity", 2000.0, joints=["panda_joint4"]).for_model(panda)
    np.testing.assert_allclose(one.stiffness, [0, 3000, 0, 2000, 0, 0, 0])
    assert one.motor_inertia[1] > 0 and one.motor_inertia[0] == 0


def test_effects_errors_name_field_and_joint(panda):
    with pytest.raises(ModelError, match=r"effects.viscous\['panda_joint3'\]"):
        Effects(viscous=[0, 0, -1, 0, 0, 0, 0]).for_model(panda)
    with pytest.raises(ModelError, match="effects.delay has shape"):
        Effects(delay=[0.1, 0.2]).for_model(panda)
    with pytest.raises(OptionError, match="nope"):
        Effects().with_effect("nope", 1.0)
    with pytest.raises(OptionError):
        Effects(coulomb={"elbow": 1.0}).for_model(panda)
    with pytest.raises(ModelError, match="not elastic"):
        Effects(motor_inertia=0.2).for_model(panda)
    with pytest.raises(ModelError, match="payload.mass"):
        MountedPayload(-1.0)
    with pytest.raises(ModelError, match="payload.frame"):
        Effects(payload=MountedPayload(1.0, frame="gripper")).for_model(panda)


def test_record_option_errors(panda, trajectory):
    with pytest.raises(ModelError, match="positive integer"):
        record(panda, trajectory, rate=300.0, duration=0.1)
    with pytest.raises(ModelError, match="settle"):
        record(panda, trajectory, Effects(delay=0.5), duration=0.1, settle=0.1)
    with pytest.raises(ModelError):
        TrackingController(bandwidth=-1.0)


# ----------------------------------------------------------------------------- review fixes
def test_effect_torque_keeps_the_payload_on_elastic_joints(panda, trajectory):
    """An elastic joint's sensor reads the link side: the payload's torque, not the drive's
    friction and armature; rigid joints read both (Spong's model, MuJoCo as the judge)."""
    payload = MountedPayload(1.2, (0.02, 0.0, 0.06), np.diag([0.003, 0.002, 0.004]))
    eff = Effects(stiffness={1: 4000.0, 5: 3000.0}, spring_damping={1: 3.0, 5: 2.0},
                  viscous=0.4, armature=0.05, payload=payload)
    rec, _ = run(panda, trajectory, eff)
    truth = (rec.true_q, rec.true_dq, rec.true_ddq)
    extra = effect_torque(panda, rec.effects, *truth)
    np.testing.assert_allclose(rec.tau, panda.rnea(*truth) + extra, atol=1e-6)
    assert np.min(np.max(np.abs(extra[:, [1, 5]]), axis=0)) > 0.05   # the payload is there
    data = panda.pin_model.createData()
    y = np.array([pin.computeJointTorqueRegressor(panda.pin_model, data, q, v, a)[:, 60:70]
                  for q, v, a in zip(*truth)])
    np.testing.assert_allclose(extra[:, [1, 5]], (y @ rec.payload_parameters)[:, [1, 5]],
                               atol=1e-12)


def test_thin_rod_payload_is_simulated_as_a_rod(panda, trajectory):
    """A rod (one zero principal moment, tilted) is accepted and is not made a point mass."""
    r = pin.rpy.rpyToMatrix(0.3, 0.5, 0.7)
    rod = MountedPayload(1.0, (0.0, 0.0, 0.1), r @ np.diag([0.01, 0.01, 0.0]) @ r.T)
    rec, extra = run(panda, trajectory, Effects(payload=rod))
    data = panda.pin_model.createData()
    y = np.array([pin.computeJointTorqueRegressor(panda.pin_model, data, q, v, a)[:, 60:70]
                  for q, v, a in zip(rec.true_q, rec.true_dq, rec.true_ddq)])
    np.testing.assert_allclose(extra, y @ rec.payload_parameters, atol=1e-9)
    point = y @ MountedPayload(1.0, (0.0, 0.0, 0.1)).parameters(panda)[1]
    assert np.max(np.abs(extra - point)) > 1e-3                   # the rod's inertia counts
    xml = MujocoRobot(panda, Effects(payload=rod)).xml
    assert 'name="panda_link7__payload"' in xml and 'name="payload"' not in xml


def test_payload_inertia_must_satisfy_the_triangle_inequality():
    with pytest.raises(ModelError, match="payload.inertia violates the triangle"):
        MountedPayload(1.0, inertia=np.diag([0.001, 0.001, 0.01]))
    with pytest.raises(ModelError, match="symmetric"):
        MountedPayload(1.0, inertia=[[0.01, 0.001, 0], [0, 0.01, 0], [0, 0, 0.01]])
    MountedPayload(1.0, inertia=np.diag([0.0, 0.02, 0.02]))               # a rod along x: accepted


class _Fold:
    """Panda from stretched out (large M_11) to folded (small M_11) in one second."""

    period = 1.0
    a = np.array([0.0, 1.5, 0.0, -0.1, 0.0, 1.6, 0.0])
    b = np.array([0.0, -0.3, 0.0, -3.0, 0.0, 3.0, 0.0])

    def evaluate(self, t):
        t = np.clip(np.atleast_1d(t), 0.0, 1.0)[:, None]
        s, ds, dds = ((1 - np.cos(np.pi * t)) / 2, np.pi / 2 * np.sin(np.pi * t),
                      np.pi ** 2 / 2 * np.cos(np.pi * t))
        d = self.b - self.a
        return self.a + s * d, ds * d, dds * d


def test_tanh_step_check_covers_the_whole_trajectory(panda):
    mj = MujocoRobot(panda).mj_model
    full = np.zeros((7, 7))
    m11 = []
    for q in (_Fold.a, _Fold.b):
        data = mujoco.MjData(mj)
        data.qpos[:] = q
        mujoco.mj_forward(mj, data)
        mujoco.mj_fullM(mj, data, full)
        m11.append(full[0, 0])
    assert m11[0] > 4 * m11[1]
    fc = 1.5 * m11[1] * 0.05 / 1e-3          # h·fc/(v_s·M_11) = 1.5 folded, < 0.4 stretched
    eff = Effects(coulomb={0: fc}, coulomb_model="tanh", coulomb_speed=0.05)
    with pytest.raises(ModelError, match="panda_joint1.*coulomb_speed"):
        record(panda, _Fold(), eff, settle=0.0)


def test_open_trajectory_is_held_at_its_start_while_settling(planar_2r):
    from consistid.excitation import BoundaryConditions, FourierPolynomial
    fp = FourierPolynomial(2, 2, 2.0, BoundaryConditions(q_start=[0.2, -0.3], q_end=[0.5, 0.1]))
    traj = fp.trajectory(0.2 * np.ones((2, fp.n_coefficients)))
    assert not traj.periodic
    rec = record(planar_2r, traj, settle=0.5)               # was: ExcitationError at t < 0
    np.testing.assert_allclose(rec.desired_q[0], [0.2, -0.3], atol=1e-12)
    np.testing.assert_allclose(rec.true_q[0], [0.2, -0.3], atol=1e-6)   # settled on the start
    assert rec.n_samples == 2000 and np.all(rec.tracking_error < 1e-3)
    moving = BoundaryConditions(q_start=[0.2, -0.3], q_end=[0.5, 0.1], dq_start=0.1)
    fp = FourierPolynomial(2, 2, 2.0, moving)
    with pytest.raises(ModelError, match="settle"):
        record(planar_2r, fp.trajectory(np.zeros((2, fp.n_coefficients))), settle=0.5)
    record(planar_2r, fp.trajectory(np.zeros((2, fp.n_coefficients))), settle=0.0)


def test_tracking_error_is_reported_and_warns_above_the_bound(panda, trajectory):
    from consistid.errors import TrackingWarning
    eff = Effects(coulomb={6: 2.0})
    with pytest.warns(TrackingWarning, match="panda_joint7"):
        rec = record(panda, trajectory, eff, max_tracking_error=0.05, **SHORT)
    np.testing.assert_allclose(rec.tracking_error,
                               np.max(np.abs(rec.true_q - rec.desired_q), axis=0))
    assert np.argmax(rec.tracking_error) == 6 and rec.tracking_error[6] > 0.05
    assert rec == rec and rec != record(panda, trajectory, eff, **SHORT)   # no array ==


def test_excitation_run_parameter_shape_is_a_model_error(panda):
    with pytest.raises(ModelError, match="true parameters have shape"):
        ci.simulate.excitation_run(panda, np.zeros(5), duration=1.0)


def test_elastic_start_is_the_deflection_under_mujocos_own_link_torque(panda, trajectory):
    """At t = 0 the motors sit on the desired state (the collocated controller sees no error)
    and only the springs act on the links (every joint elastic): the links accelerate at q̈_d
    iff each deflection is the true link-side torque over K, payload included (the nominal
    RNEA left it out: 19 rad/s² off at t = 0)."""
    payload = MountedPayload(2.0, (0.02, 0.0, 0.08), np.diag([0.004, 0.003, 0.005]))
    eff = Effects(stiffness=4000.0, spring_damping=2.0, payload=payload)
    rec = record(panda, trajectory, eff, duration=0.005, settle=0.0)
    q, dq, ddq = trajectory.evaluate(rec.t[:1])
    np.testing.assert_allclose(rec.motor_q[0], q[0], atol=1e-12)
    np.testing.assert_allclose(rec.true_ddq[0], ddq[0], atol=1e-6)
    link = (rec.true_q[:1], dq, ddq)
    static = panda.rnea(*link)[0] + effect_torque(panda, rec.effects, *link)[0]
    np.testing.assert_allclose(q[0] - rec.true_q[0], static / 4000.0, atol=1e-12)
    assert np.max(np.abs(static / 4000.0)) > 5e-3


def test_too_soft_a_spring_cannot_hold_the_start(panda, trajectory):
    with pytest.raises(ModelError, match="panda_joint2.*too soft"):
        record(panda, trajectory, Effects(stiffness={1: 20.0}), duration=0.005, settle=0.0)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_logging_does_not_change_the_physics(panda, trajectory, integrator):
    # a logged step is mj_step opened (checks, mj_forward, log, integrator); an unlogged one is
    # mj_step itself: logging every step or every other must give the same run (to round-off:
    # measured ≤ 5e-13 relative; a step that integrated differently would drift far more)
    kw = dict(duration=0.2, settle=0.05, physics_rate=1000.0, integrator=integrator,
              effects=Effects(coulomb=0.5, viscous=0.2))
    every = record(panda, trajectory, rate=1000.0, **kw)
    other = record(panda, trajectory, rate=500.0, **kw)
    np.testing.assert_allclose(every.true_q[::2], other.true_q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(every.tau[::2], other.tau, rtol=1e-10, atol=1e-10)


def test_a_simulation_oscillating_beyond_the_effort_limits_is_named():
    """Kinova, viscous 0.2 N·m·s/rad on its light links at a 1 ms step: MuJoCo flags no bad state
    but the torques reach hundreds of times the effort limits; record names the divergence and
    physics_rate (it warned 'raise the controller's bandwidth', which made it worse); at 4 kHz
    the same run stays within the limits."""
    from consistid.robot.inertia import perturb

    model = ci.RobotModel.example("kinova")
    truth = perturb(model.prior_parameters, 0.15, np.random.default_rng(4))
    traj = ci.FourierTrajectory.random(model, harmonics=5, period=10.0, seed=4)
    eff = Effects(viscous=0.2, torque_noise=0.05)
    with pytest.raises(ci.errors.ModelError, match=r"diverged.*effort limit.*physics_rate=4000"):
        record(model, traj, eff, true_parameters=truth, duration=20.0, rate=500.0, seed=4)
    rec = record(model, traj, eff, true_parameters=truth, duration=20.0, rate=500.0, seed=4,
                 physics_rate=4000.0)
    assert np.all(np.abs(rec.tau).max(axis=0) < model.limits.effort)
