"""Kinematic calibration on inputs nobody tuned it to: empty arrays, degrees for radians,
millimetres for metres (each must be refused by name, not fitted)."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

import consistid as ci
from consistid.errors import DataQualityWarning, DatasetError, PoorExcitationError
from consistid.kinematics import KinematicParameters


def _ur5_with_offsets(rng: np.random.Generator):
    """A UR5, its tool0 position chart, zero offsets drawn within ±0.5° and the robot that has
    them: ``(model, chart, truth, real)``."""
    model = ci.RobotModel.example("ur5")
    chart = KinematicParameters(model, "tool0", "position")
    truth = np.zeros(chart.size)
    for i, name in enumerate(chart.names[:chart.n_kinematic]):
        if name.endswith(".zero"):
            truth[i] = np.radians(rng.uniform(-0.5, 0.5))
    return model, chart, truth, chart.robot_model(truth)


def _tool0_positions(real: ci.RobotModel, q: np.ndarray, rng: np.random.Generator
                     ) -> np.ndarray:
    """``real``'s tool0 positions at ``q`` (N, 3), with 10 µm noise."""
    data, fid = real.pin_model.createData(), real.pin_model.getFrameId("tool0")
    pos = []
    for qk in q:
        pin.framesForwardKinematics(real.pin_model, data, real.configuration(qk))
        pos.append(data.oMf[fid].translation + rng.normal(0, 1e-5, 3))
    return np.array(pos)


@pytest.fixture(scope="module")
def ur5_positions():
    """A UR5 whose zero offsets are off by ±0.5°, measured at tool0 (positions, 10 µm noise)."""
    rng = np.random.default_rng(3)
    model, chart, truth, real = _ur5_with_offsets(rng)
    lim = model.limits
    q = rng.uniform(np.maximum(lim.lower, -np.pi), np.minimum(lim.upper, np.pi), (40, model.nv))
    return model, chart, truth, q, _tool0_positions(real, q, rng)


def test_empty_input_is_named(ur5_positions):
    model, _, _, q, pos = ur5_positions
    with pytest.raises(DatasetError, match="empty"):
        ci.calibrate_kinematics(model, q[:0], pos[:0], frame="tool0")


def test_degrees_are_refused_with_the_hint(ur5_positions):
    model, _, _, q, pos = ur5_positions
    with pytest.raises(DatasetError, match="degrees"):
        ci.calibrate_kinematics(model, np.degrees(q), pos, frame="tool0", sigma=1e-5)


def test_millimetres_are_refused(ur5_positions):
    """Before: a 'converged' fit with a 110 m joint-origin correction and χ²/dof = NaN."""
    model, _, _, q, pos = ur5_positions
    with pytest.raises(DatasetError, match="unit"):
        ci.calibrate_kinematics(model, q, pos * 1000.0, frame="tool0", sigma=1e-5)


def test_metres_in_another_frame_still_calibrate(ur5_positions):
    """The unit check must not refuse a rigid change of measurement frame, and the zero
    offsets the positions identify come back to within 5 σ of the injected ones."""
    model, chart, truth, q, pos = ur5_positions
    tracker = pin.SE3(pin.exp3(np.array([0.1, -0.2, 0.7])), np.array([2.0, -1.0, 0.3]))
    moved = pos @ tracker.rotation.T + tracker.translation
    cal = ci.calibrate_kinematics(model, q, moved, frame="tool0", sigma=1e-5,
                                  parameters=["zero", "base"])
    for name in ("shoulder_lift_joint.zero", "elbow_joint.zero", "wrist_1_joint.zero",
                 "wrist_2_joint.zero"):
        i = list(cal.parameter_names).index(name)
        assert cal.identified[i]
        lo, hi = cal.conf_int(alpha=1e-6)[i]
        assert lo <= truth[chart.names.index(name)] <= hi, name


def test_distances_in_millimetres_are_refused():
    """Before: PoorExcitationError 'anchor.y not seen' (the trilaterated anchor was metres
    away), which points at the poses, not the unit."""
    from consistid.kinematics import select_poses

    model = ci.RobotModel.example("xarm7")
    anchor = np.array([0.8, 0.3, 0.1])
    q = select_poses(model, 40, "link_eef", "distance", seed=0, anchor=anchor).q
    data, fid = model.pin_model.createData(), model.pin_model.getFrameId("link_eef")
    d = []
    for qk in q:
        pin.framesForwardKinematics(model.pin_model, data, model.configuration(qk))
        d.append(np.linalg.norm(data.oMf[fid].translation - anchor))
    d = np.array(d)
    cal = ci.calibrate_kinematics(model, q, d, frame="link_eef", parameters=["zero", "anchor"],
                                  sigma=1e-5)
    assert max(abs(v) for v in cal.corrections.values()) < 1e-9     # the URDF robot: nothing
    with pytest.raises(DatasetError, match="unit"):
        ci.calibrate_kinematics(model, q, d * 1000.0, frame="link_eef",
                                parameters=["zero", "anchor"], sigma=1e-5)


def test_held_out_rms_refuses_degrees_too(ur5_positions):
    """Before: cal.rms(np.degrees(q), measured) returned a 0.55 m 'RMS' without a word."""
    model, _, _, q, pos = ur5_positions
    cal = ci.calibrate_kinematics(model, q[:30], pos[:30], frame="tool0", sigma=1e-5,
                                  parameters=["zero", "base"])
    assert cal.rms(q[30:], pos[30:])["position"] < 5e-5
    with pytest.raises(DatasetError, match="degrees"):
        cal.rms(np.degrees(q[30:]), pos[30:])


def test_a_sigma_ten_times_too_small_is_warned_not_used_to_reject_the_data(ur5_positions):
    """Before: sigma 10× below the tracker's noise made the χ² data snooping reject 36 of 40
    good measurements one by one, and the 4 left gave zero offsets 6σ off, without a word."""
    model, _, _, q, pos = ur5_positions              # 10 µm noise
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataQualityWarning)
        right = ci.calibrate_kinematics(model, q, pos, frame="tool0", parameters="zero",
                                        sigma=1e-5)
    assert right.rejected == ()
    with pytest.warns(DataQualityWarning, match="exceed the given sigma"):
        cal = ci.calibrate_kinematics(model, q, pos, frame="tool0", parameters="zero",
                                      sigma=1e-6)
    assert cal.rejected == ()
    assert np.allclose(cal.values, right.values, atol=1e-9)


def test_nearly_identical_poses_are_refused_not_held_with_tight_sigma():
    """Before: 40 poses within 1e-4 rad of one another held two zero offsets at 0 (as for a
    point on a joint axis) and gave the other three ± 0.001°, 100–600 σ from the truth."""
    rng = np.random.default_rng(2)
    model, _, _, real = _ur5_with_offsets(rng)
    q = rng.uniform(-1, 1, 6) + rng.normal(0, 1e-4, (40, 6))
    pos = _tool0_positions(real, q, rng)
    with pytest.raises(PoorExcitationError, match=r"40 configurations barely see \w+_joint\.zero"):
        ci.calibrate_kinematics(model, q, pos, frame="tool0", parameters="zero", sigma=1e-5)
