import numpy as np
from hypothesis import given, settings, strategies as st

import consistid as ci
from consistid.identification.base import base_parameters_from_regressor
from consistid.identification.regressor import RegressorSpec, regressor

from .conftest import PLANAR_2R_VALUES, random_states


def test_planar_2r_matches_the_closed_form(planar_2r):
    v, g = PLANAR_2R_VALUES, 9.81
    base = ci.compute_base_parameters(planar_2r)
    # 20 standard parameters; in the plane: mx1+m2 l1, my1, Izz1+m2 l1², mx2, my2, Izz2
    assert base.n_base == 6
    beta = base.project(planar_2r.prior_parameters)
    m1, d1, i1, m2, d2, i2, l1 = (v[k] for k in ("m1", "d1", "i1", "m2", "d2", "i2", "l1"))
    seed_beta = [m1 * d1 + m2 * l1, i1 + m1 * d1**2 + m2 * l1**2, m2 * d2, i2 + m2 * d2**2]
    # with the CoM on the link axes, the two my-combinations vanish and the rest are the seed's
    nonzero = beta[np.abs(beta) > 1e-12]
    assert np.allclose(np.sort(nonzero), np.sort(seed_beta), rtol=1e-12)
    grouping = base.groupings[list(base.names).index("link1.mx*")]
    assert grouping == f"link1.mx + {l1:.4g}·link2.m"

    # the seed's 2×4 base regressor (lecture notes ch. 6) reproduces Pinocchio's torques
    q, dq, ddq = random_states(planar_2r, 20, 3)
    for k in range(20):
        (q1, q2), (w1, w2), (a1, a2) = q[k], dq[k], ddq[k]
        yb = np.array([
            [g * np.cos(q1), a1, l1 * np.cos(q2) * (2 * a1 + a2)
             - l1 * np.sin(q2) * (w2**2 + 2 * w1 * w2) + g * np.cos(q1 + q2), a1 + a2],
            [0.0, 0.0, l1 * np.cos(q2) * a1 + l1 * np.sin(q2) * w1**2 + g * np.cos(q1 + q2),
             a1 + a2]])
        assert np.allclose(yb @ seed_beta, planar_2r.rnea(q[k], dq[k], ddq[k])[0], atol=1e-10)


def test_panda_base_count_equals_rank_of_large_random_regressor(panda):
    base = ci.compute_base_parameters(panda)
    q, dq, ddq = random_states(panda, 3000, 11)
    y = regressor(panda, q, dq, ddq)
    assert base.n_base == 43 == np.linalg.matrix_rank(y)


def test_friction_and_armature_columns_add_their_counts(panda):
    plain = ci.compute_base_parameters(panda).n_base
    fr = RegressorSpec.make(panda, ("coulomb", "viscous", "offset"))
    assert ci.compute_base_parameters(panda, fr).n_base == plain + 21
    # rotor inertia of joint 1 merges with link1's Izz-combination; joint 2's with link 2's
    arm = RegressorSpec.make(panda, ("coulomb", "viscous"), armature=True)
    assert ci.compute_base_parameters(panda, arm).n_base == 62


def test_position_term_on_a_joint_with_fixed_gravity_axis_is_its_link_gravity(planar_2r):
    # Joint 1's axis never turns w.r.t. gravity: link 1's gravity torque on it is
    # g·(mx1 cos q1 − my1 sin q1) (closed form), exactly the position pair; joint 2's pair is new.
    g = 9.81
    spec = RegressorSpec.make(planar_2r, ("position",))
    base = ci.compute_base_parameters(planar_2r, spec)
    assert base.n_base == 6 + 2
    names = list(base.standard_names)

    def beta(name):
        return base.matrix[:, names.index(name)]

    assert np.allclose(g * beta("joint1.pc1"), beta("link1.mx"), atol=1e-9)
    assert np.allclose(-g * beta("joint1.ps1"), beta("link1.my"), atol=1e-9)
    assert {"joint2.ps1", "joint2.pc1"} <= {names[i] for i in base.independent}


def test_position_term_counts_on_the_panda(panda):
    # Joint 2's axis is horizontal and meets the vertical axis 1 at a fixed point: its pair is
    # link 2's gravity torque (as above) and adds nothing; the six other pairs add 12.
    full = RegressorSpec.make(panda, ("coulomb", "viscous", "offset", "position"))
    base = ci.compute_base_parameters(panda, full)
    q, dq, ddq = random_states(panda, 300, 5)
    assert base.n_base == 64 + 12 == np.linalg.matrix_rank(regressor(panda, q, dq, ddq, full))
    only2 = RegressorSpec.make(panda, {"position": ["panda_joint2"]})
    assert ci.compute_base_parameters(panda, only2).n_base == 43


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1),
       position=st.lists(st.integers(0, 6), max_size=7, unique=True))
def test_base_parameters_predict_the_same_torques(panda, seed, position):
    rng = np.random.default_rng(seed)
    spec = RegressorSpec.make(panda, {"coulomb": True, "viscous": True, "position": position})
    base = ci.compute_base_parameters(panda, spec)
    pi = rng.normal(size=base.n_standard)
    q, dq, ddq = random_states(panda, 6, seed)
    y = regressor(panda, q, dq, ddq, spec)
    assert np.allclose(y @ pi, base.base_columns(y) @ base.project(pi), atol=1e-8)
    # a change along the null space of B changes no torque
    B = base.matrix
    null = pi - np.linalg.pinv(B) @ (B @ pi)
    assert np.allclose(y @ null, 0.0, atol=1e-8 * (1 + np.abs(null).max()))


def test_zero_columns_are_reported_unidentifiable(panda):
    base = ci.compute_base_parameters(panda)
    assert "panda_link1.m" in base.unidentifiable
    assert "panda_link1.mz" in base.unidentifiable


def test_rank_from_a_given_regressor():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(100, 3))
    y = np.column_stack([a, a[:, 0] + 2 * a[:, 1]])
    base = base_parameters_from_regressor(y, ["a", "b", "c", "d"])
    assert base.n_base == 3
    assert np.allclose(y, base.base_columns(y) @ base.matrix)
