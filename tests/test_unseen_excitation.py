"""Excitation design on arms other than the Panda: every promised limit checked independently
(Pinocchio RNEA and forward kinematics on a 1 kHz grid), and hostile limits refused or flagged."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import consistid as ci
from consistid.errors import ExcitationError, PoorExcitationWarning
from consistid.excitation import ExcitationLimits, FloorPlane

FAST = dict(harmonics=2, period=4.0, friction=None, n_starts=1, progress=False, n_check=500)


@pytest.mark.parametrize("name", ["ur5", "xarm7"])
def test_design_respects_every_limit_on_a_denser_grid(name):
    model = ci.RobotModel.example(name)
    limits = ExcitationLimits.from_model(model, acceleration=8.0, floor=FloorPlane(0.05))
    design = ci.design_excitation(model, limits=limits, max_iter=25, **FAST)
    assert design.constraints.feasible and design.cond < 1e3
    s = design.trajectory.sample(1000.0)              # 2× denser than the design's check
    assert np.all(s.q >= limits.lower) and np.all(s.q <= limits.upper)
    assert np.all(np.abs(s.dq) <= limits.velocity) and np.all(np.abs(s.ddq) <= limits.acceleration)
    pm = model.pin_model
    data, fid = pm.createData(), pm.getFrameId(pm.frames[-1].name)
    for q, dq, ddq in zip(s.q[::4], s.dq[::4], s.ddq[::4]):
        qq = model.configuration(q)
        assert np.all(np.abs(pin.rnea(pm, data, qq, dq, ddq)) <= limits.torque)
        pin.framesForwardKinematics(pm, data, qq)
        assert data.oMf[fid].translation[2] >= 0.05


def test_limits_in_degrees_are_refused():
    """Before: lower=-170, upper=170 accepted as radians (beyond the UR5's ±2π)."""
    model = ci.RobotModel.example("ur5")
    with pytest.raises(ExcitationError, match="radians"):
        ExcitationLimits.from_model(model, lower=-170.0, upper=170.0)
    # widening to 'no limit' stays allowed, and so does tightening
    ExcitationLimits.from_model(model, upper=np.inf, lower=-1.0)


def test_limits_that_leave_no_motion_warn_instead_of_a_silent_useless_design():
    """Before: 'feasible', cond(Y_b) = 1.5e22, no warning."""
    model = ci.RobotModel.example("ur5")
    limits = ExcitationLimits.from_model(model, velocity=1e-6, acceleration=1e-6)
    with pytest.warns(PoorExcitationWarning, match="cond"):
        design = ci.design_excitation(model, limits=limits, max_iter=5, **FAST)
    assert design.cond > 1e8


def test_continuous_joints_leave_no_numpy_warning_and_n_jobs_zero_is_named():
    """Kinova (continuous joints, ±inf limits): from_model compared inf − inf (a RuntimeWarning
    from the degrees check). n_jobs=0 reached joblib's own ValueError."""
    import warnings

    from consistid.errors import OptionError

    model = ci.RobotModel.example("kinova")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        limits = ExcitationLimits.from_model(model, acceleration=5.0)
    assert np.isinf(limits.lower).any()
    with pytest.raises(OptionError, match="n_jobs"):
        ci.design_excitation(model, limits=limits, n_jobs=0, max_iter=1, **FAST)
