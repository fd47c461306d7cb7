"""Angle units: ``angle_unit="deg"`` converts, a log in degrees read as radians warns at load
time naming its joints, and identify never answers "consistent, optimal_inaccurate" quietly on
such data (issue 31)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.data.recordings import from_arrays, load_recording
from consistid.data.units import degree_suspects, model_limits, revolute_joints
from consistid.errors import DataQualityWarning, ModelMisfitWarning, OptionError

DEG = 180.0 / np.pi


@pytest.fixture(scope="module")
def ur5_run():
    model = ci.RobotModel.example("ur5")
    return model, ci.simulate.excitation_run(model, duration=6.0, seed=3)


def _csv(path, d, scale=1.0, unit=""):
    """The simulated run as a CSV: positions (× ``scale``) and torques, named by joint."""
    names = list(d.joint_names)
    header = ["time", *(f"{n}.q{unit}" for n in names), *(f"{n}.tau" for n in names)]
    table = np.column_stack([d.t, d.q * scale, d.tau])
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    return path


@pytest.mark.parametrize("arm", ["panda", "ur5", "xarm7", "kinova"])
def test_detection_flags_degrees_and_never_radians(arm):
    """Simulated excitation runs of four arms: in radians nothing is flagged (with and without
    the model's limits); the same run in degrees flags every joint that moves faster than
    720 °/s / 57.3 or spans more than 4π / 57.3 — computed here from the run itself."""
    model = ci.RobotModel.example(arm)
    d = ci.simulate.excitation_run(model, duration=6.0, seed=11).dataset
    rev, lim = revolute_joints(model), model_limits(model)
    assert degree_suspects(d.q, d.dq, model.joint_names, rev, lim) == []
    assert degree_suspects(d.q, d.dq, model.joint_names) == []
    found = degree_suspects(d.q * DEG, d.dq * DEG, model.joint_names, rev, lim)
    moving = [n for j, n in enumerate(model.joint_names)
              if np.ptp(d.q[:, j]) * DEG > 4 * np.pi
              or np.percentile(np.abs(d.dq[:, j]), 99) * DEG > 4 * np.pi]
    assert moving and [f.split(" ")[0].strip("'") for f in found] == moving


def test_real_kuka_logs_are_not_flagged(kuka_dir):
    model = ci.RobotModel.from_urdf(kuka_dir / "kuka_lwr4.urdf")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        for k in (1, 2, 3):
            rec = load_recording(kuka_dir / f"measurements_{k}.npz",
                                 joint_names=model.joint_names, model=model)
            assert not any("degrees" in s for s in rec.steps)


def test_a_csv_in_degrees_warns_and_angle_unit_converts(tmp_path, ur5_run):
    model, run = ur5_run
    d = run.dataset
    rad = load_recording(_csv(tmp_path / "rad.csv", d), model=model).dataset
    with pytest.warns(DataQualityWarning, match="look like degrees") as rec:
        load_recording(_csv(tmp_path / "deg.csv", d, DEG), model=model)
    text = str(rec[0].message)
    assert "'shoulder_pan_joint'" in text and 'angle_unit="deg"' in text
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        conv = load_recording(tmp_path / "deg.csv", model=model, angle_unit="deg")
    assert any("converted to radians" in s for s in conv.steps)
    for f in ("q", "dq", "ddq", "tau"):
        np.testing.assert_allclose(getattr(conv.dataset, f), getattr(rad, f), rtol=1e-9,
                                   atol=1e-9, err_msg=f)
    with pytest.raises(OptionError, match="names the unit"):       # a header unit wins
        load_recording(_csv(tmp_path / "named.csv", d, DEG, " [deg]"), model=model,
                       angle_unit="deg")
    with pytest.raises(OptionError, match="angle_unit='grad'"):
        load_recording(tmp_path / "rad.csv", model=model, angle_unit="grad")


RP_ARM = """<?xml version="1.0"?>
<robot name="rp">
  <link name="base"/>
  <link name="l1"><inertial><mass value="2"/><origin xyz="0.2 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/><origin xyz="0 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="3" effort="50"/></joint>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.5" velocity="1" effort="50"/></joint>
</robot>
"""


def test_angle_unit_leaves_prismatic_joints_in_metres(tmp_path):
    """With a model, only the revolute joint's columns are converted; without one, all."""
    path = tmp_path / "rp.urdf"
    path.write_text(RP_ARM)
    model = ci.RobotModel.from_urdf(path)
    t = np.arange(200) * 0.01
    q = np.column_stack([30 * np.sin(t), 0.2 + 0.1 * np.sin(t)])
    dq = np.column_stack([30 * np.cos(t), 0.1 * np.cos(t)])
    ddq = -q + [0, 0.2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataQualityWarning)      # torques are not the model's
        rec = from_arrays(t, q, np.ones_like(q), dq, ddq, joint_names=["turn", "slide"],
                          model=model, angle_unit="deg")
        bare = from_arrays(t, q, np.ones_like(q), dq, ddq, angle_unit="deg")
    for f, a in (("q", q), ("dq", dq), ("ddq", ddq)):
        np.testing.assert_allclose(getattr(rec.dataset, f), a * [np.pi / 180, 1], err_msg=f)
        np.testing.assert_allclose(getattr(bare.dataset, f), a * np.pi / 180, err_msg=f)
    assert revolute_joints(model).tolist() == [True, False]


def test_identify_on_degrees_is_loud(ur5_run):
    """The solve on degrees is flagged (ModelMisfitWarning, details['angle unit'], summary);
    on the same data in radians it is not."""
    model, run = ur5_run
    d = run.dataset
    bad = ci.Dataset(t=d.t, q=d.q * DEG, dq=d.dq * DEG, ddq=d.ddq * DEG, tau=d.tau,
                     joint_names=d.joint_names)
    with pytest.warns(ModelMisfitWarning, match="look like degrees"):
        res = ci.identify(model, bad, method="ols")
    assert "angle_unit" in res.details["angle unit"] and "angle unit" in res.summary()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelMisfitWarning)
        good = ci.identify(model, d, method="ols")
    assert "angle unit" not in good.details


@pytest.mark.parametrize("arm", ["ur5", "ur10", "panda", "xarm7"])
def test_small_motions_in_degrees_are_caught_by_the_torque(arm):
    """A ±1–2° motion logged in degrees stays inside a UR's ±2π limits and below every speed
    bound, so the position checks miss it; the URDF's torque does not: read as degrees it
    explains the logged torque (MuJoCo, inertias ±20 % off the URDF, friction the URDF lacks,
    noise), read as radians it does not. The same run in radians is never flagged, nor with
    its gravity subtracted. (Not the Kinova: near its zero pose gravity is about 0, so the
    degrees reading explains little of a torque that is mostly friction; 1 of 9 runs caught by
    the torque in ``benchmarks/angle_units.py``, 9 of 9 by its positions.)"""
    from consistid.data.units import degree_torque_evidence
    from consistid.robot.inertia import perturb
    from consistid.simulate import Effects, record

    model = ci.RobotModel.example(arm)
    truth = perturb(model.prior_parameters, 0.2, np.random.default_rng(5))
    traj = ci.FourierTrajectory.random(model, harmonics=4, period=6.0, seed=5, amplitude=0.02)
    rec = record(model, traj, Effects(coulomb=1.0, viscous=0.5, torque_noise=0.1),
                 true_parameters=truth, duration=4.0, rate=100.0, seed=5)
    rad = ci.Dataset.from_recording(rec.t, rec.q, rec.tau)
    assert degree_torque_evidence(model, rad.q, rad.dq, rad.ddq, rad.tau) is None
    # a radians log whose torque is gravity compensated (a commanded or tau_J_d-style log) is
    # no RNEA torque: the degrees reading's collapsed pose fits it better, yet explains little
    # of it (flagged on 9/9 Panda runs before the torque's own RMS was a bound too; the review)
    compensated = rad.tau - model.rnea(rad.q, 0 * rad.dq, 0 * rad.ddq)
    assert degree_torque_evidence(model, rad.q, rad.dq, rad.ddq, compensated) is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        deg = from_arrays(rec.t, rec.q * DEG, rec.tau, joint_names=model.joint_names,
                          model=model)
    said = [str(w.message) for w in caught if issubclass(w.category, DataQualityWarning)
            and "read as degrees" in str(w.message)]
    assert said and "RNEA torque of these angles read as degrees" in said[0]
    assert any("RNEA torque of these angles" in s for s in deg.steps)
    if arm in ("ur5", "ur10"):          # the position checks alone miss it on the URs
        d = deg.dataset
        assert degree_suspects(d.q, d.dq, model.joint_names, revolute_joints(model),
                               model_limits(model)) == []
