import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings, strategies as st

import consistid as ci
from consistid.robot.inertia import perturb
from consistid.identification.regressor import RegressorSpec, parameter_names, regressor

from .conftest import random_states

SEEDS = st.integers(0, 2**32 - 1)


@settings(max_examples=25, deadline=None)
@given(seed=SEEDS)
def test_rigid_regressor_matches_rnea(panda, seed):
    q, dq, ddq = random_states(panda, 5, seed)
    y = regressor(panda, q, dq, ddq)
    tau = (y @ panda.prior_parameters).reshape(5, panda.nv)
    assert np.allclose(tau, panda.rnea(q, dq, ddq), atol=1e-9, rtol=0)


@settings(max_examples=15, deadline=None)
@given(seed=SEEDS)
def test_friction_and_armature_columns_match_independent_model(panda, seed):
    rng = np.random.default_rng(seed)
    q, dq, ddq = random_states(panda, 4, seed)
    fc, fv, fo, ps, pc, ia = (rng.uniform(-2.0, 2.0, panda.nv) for _ in range(6))
    spec = RegressorSpec.make(panda, ("coulomb", "viscous", "offset", "position"), armature=True)
    # position columns come per joint as (sin, cos) pairs
    pi = np.concatenate([panda.prior_parameters, fc, fv, fo, np.column_stack([ps, pc]).ravel(),
                         ia])
    tau = (regressor(panda, q, dq, ddq, spec) @ pi).reshape(4, panda.nv)
    # independent: Pinocchio's rnea with model.armature, plus the friction law written out
    m = panda.pin_model.copy()
    m.armature = ia
    d = m.createData()
    expected = np.array([pin.rnea(m, d, q[k], dq[k], ddq[k]) for k in range(4)])
    expected += fc * np.sign(dq) + fv * dq + fo + ps * np.sin(q) + pc * np.cos(q)
    assert np.allclose(tau, expected, atol=1e-9, rtol=0)


@settings(max_examples=15, deadline=None)
@given(seed=SEEDS, a=st.floats(0.1, 3.0), b=st.floats(0.1, 3.0))
def test_dynamics_are_linear_in_the_parameters(panda, seed, a, b):
    rng = np.random.default_rng(seed)
    p1, p2 = (perturb(panda.prior_parameters, 0.3, rng) for _ in range(2))
    q, dq, ddq = random_states(panda, 3, seed)
    lhs = panda.with_parameters(a * p1 + b * p2).rnea(q, dq, ddq)
    rhs = a * panda.with_parameters(p1).rnea(q, dq, ddq) + b * panda.with_parameters(p2).rnea(
        q, dq, ddq)
    assert np.allclose(lhs, rhs, atol=1e-9 * (1 + np.abs(rhs).max()))


def test_rows_are_sample_major_and_blocks_switch_per_joint(panda):
    q, dq, ddq = random_states(panda, 3, 0)
    spec = RegressorSpec.make(panda, {"coulomb": [1, "panda_joint4"], "offset": True})
    names = parameter_names(panda, spec)
    y = regressor(panda, q, dq, ddq, spec)
    assert y.shape == (3 * 7, 70 + 2 + 7)
    assert names[70:72] == ["panda_joint2.fc", "panda_joint4.fc"]
    assert names[72] == "panda_joint1.fo"
    y3 = y.reshape(3, 7, -1)
    assert y3[2, 3, 71] == np.sign(dq[2, 3]) and y3[2, 1, 71] == 0.0
    single = regressor(panda, q[2], dq[2], ddq[2], spec)
    assert np.array_equal(single, y[14:21])
    # the position term: a (sin, cos) pair per chosen joint, after the offsets, on its joint only
    spec = RegressorSpec.make(panda, {"offset": [0], "position": ["panda_joint7", 2]})
    assert spec.describe() == "offset on 1/7, position on 2/7"
    assert parameter_names(panda, spec)[70:] == [
        "panda_joint1.fo", "panda_joint3.ps1", "panda_joint3.pc1", "panda_joint7.ps1",
        "panda_joint7.pc1"]
    y3 = regressor(panda, q, dq, ddq, spec).reshape(3, 7, -1)
    assert y3[1, 6, 73] == np.sin(q[1, 6]) and y3[1, 6, 74] == np.cos(q[1, 6])
    assert not np.any(y3[:, :6, 73:]) and not np.any(y3[:, :, 71:73][:, [0, 1, 3, 4, 5, 6]])


def test_unknown_terms_and_joints_are_named(panda):
    with pytest.raises(ci.OptionError, match="stribeck"):
        RegressorSpec.make(panda, ("stribeck",))
    with pytest.raises(ci.OptionError, match="joint='elbow'"):
        RegressorSpec.make(panda, {"coulomb": ["elbow"]})
    with pytest.raises(ci.OptionError, match="joint index 9 out of range"):
        RegressorSpec.make(panda, {"coulomb": [9]})
    with pytest.raises(ci.JointCountError):
        regressor(panda, np.zeros((2, 6)), np.zeros((2, 6)), np.zeros((2, 6)))
