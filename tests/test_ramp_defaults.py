"""Break-away ramp defaults follow the effort limits; a ramp without motion reads "above"
(issue 26). Truth: the MuJoCo robot's frictionloss."""

from __future__ import annotations

import numpy as np
import pytest

import consistid as ci
from consistid.friction import estimate_breakaway
from consistid.friction.ramp import EFFORT_FRACTION, EFFORT_HEADROOM, ramp_plan
from consistid.simulate import Effects


@pytest.mark.parametrize("arm", ["panda", "ur5", "xarm7", "kinova"])
def test_the_default_range_is_a_share_of_each_effort_limit_within_headroom(arm):
    model = ci.RobotModel.example(arm)
    plan = ramp_plan(model)
    effort = model.limits.effort
    zero = np.zeros((1, model.nv))
    g = model.rnea(plan.pose[None], zero, zero)[0]          # independent of the plan's own g
    assert np.all(plan.max_torque <= EFFORT_FRACTION * effort + 1e-12)
    assert np.all(np.abs(g) + plan.max_torque <= EFFORT_HEADROOM * effort + 1e-9)
    assert np.all(plan.max_torque > 0)


def test_a_panda_joint_6_breaking_away_at_2_45_moves_under_the_default_ramp():
    """The issue's case: the former default (20 % of 12 N·m = 2.4 N·m) never moved it."""
    panda = ci.RobotModel.example("panda")
    est = estimate_breakaway(panda, effects=Effects(coulomb={"panda_joint6": 2.45}),
                             joints=["panda_joint6"], repeats=1)
    assert est.torque[5] == pytest.approx(2.45, rel=0.05)


def test_a_direction_that_never_moves_reads_above_the_range():
    """A ramp towards one side only ends without motion: an offset torque of 0.5 N·m on joint 7
    adds to the ramp one way and takes from it the other, so with max_torque 1.0 against a
    break-away of 0.8 one direction (0.8 + 0.5 > 1.0) never moves."""
    panda = ci.RobotModel.example("panda")
    plan = ramp_plan(panda, joints=[6], repeats=1, max_torque=1.0)
    eff = Effects(coulomb={"panda_joint7": 0.8})
    gravity_off = np.zeros(7)
    gravity_off[6] = 0.5
    shifted = type(plan)(plan.joint_names, plan.pose, plan.gravity + gravity_off, plan.rate,
                         plan.max_torque, plan.abort_speed, plan.max_excursion, plan.settle,
                         plan.ramps)
    with pytest.warns(UserWarning, match=r"panda_joint7: 1 ramp\(s\) towards − ended without "
                                         r"motion.*above 1 N·m"):
        est = estimate_breakaway(panda, effects=eff, plan=shifted)
    assert any("above 1 N·m" in n for n in est.notes)
