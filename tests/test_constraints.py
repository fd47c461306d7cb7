"""cvxpy constraint builders: the matrices they build, and that scaling keeps the feasible set."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.identification import constraints as cons
from consistid.errors import InconsistentParametersError
from consistid.robot.inertia import (from_mass_com_inertia, from_pseudo_inertia,
                                  pseudo_inertia)

SETTINGS = settings(max_examples=25, deadline=None)


def body(seed: int, triangle_excess: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    i1, i2 = rng.uniform(0.01, 0.1, 2)
    i3 = (i1 + i2) * (0.9 + triangle_excess)
    q = rng.normal(size=4)
    rot = pin.Quaternion(*(q / np.linalg.norm(q))).toRotationMatrix()
    return from_mass_com_inertia(rng.uniform(0.5, 5), rng.normal(0, 0.2, 3),
                                 rot @ np.diag([i1, i2, i3]) @ rot.T)


def value(expr_fn, p: np.ndarray) -> np.ndarray:
    x = cp.Variable(10)
    x.value = p
    return expr_fn(x).value


@SETTINGS
@given(st.lists(st.floats(-5, 5), min_size=10, max_size=10))
def test_matrices_match_their_definitions(values):
    p = np.array(values)
    i = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    np.testing.assert_allclose(value(cons.inertia_matrix, p), i, atol=1e-12)
    np.testing.assert_allclose(value(cons.pseudo_inertia, p), pseudo_inertia(p), atol=1e-12)
    s = pin.skew(p[1:4])
    np.testing.assert_allclose(value(cons.mass_inertia_matrix, p),
                               np.block([[i, s.T], [s, p[0] * np.eye(3)]]), atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_scaled_lmis_are_the_same_sets(seed):
    """``L⁻¹JL⁻ᵀ ⪰ L⁻¹EL⁻ᵀ`` and the D-scaled 6×6 LMI hold exactly when the raw ones do, for
    a scalar bound ``eps·1`` and for a matrix bound (the relative margin)."""
    ref = body(seed)
    scaling = cons.BodyScaling.from_reference(ref)
    for candidate in (body(seed + 10), body(seed + 20, triangle_excess=0.5), 0.5 * ref):
        for builder, level in ((cons.pseudo_inertia_lmi, "pseudo-inertia"),
                               (cons.mass_inertia_lmi, "mass-inertia")):
            for eps in (1e-6, cons.relative_bound(ref, level, 0.6)):
                x = cp.Variable(10)
                x.value = candidate
                raw = builder(x, eps)[0]
                scaled = builder(x, eps, scaling)[0]
                lam_raw = np.linalg.eigvalsh(raw.expr.value)[0]
                lam_scaled = np.linalg.eigvalsh(scaled.expr.value)[0]
                assert np.sign(lam_raw) == np.sign(lam_scaled)


@pytest.mark.parametrize("seed", range(3))
def test_relative_bound_is_a_margin_relative_to_the_reference(seed):
    """``J ⪰ margin·J_ref`` ⟺ every generalised eigenvalue of ``(J, J_ref)`` is ≥ margin; in the
    reference's scaled form the bound is ``margin·1``. Likewise for the 6×6 matrix."""
    ref, other = body(seed), body(seed + 30)
    scaling = cons.BodyScaling.from_reference(ref)
    bound = cons.relative_bound(ref, "pseudo-inertia", 0.3)
    np.testing.assert_allclose(bound, 0.3 * pseudo_inertia(ref))
    np.testing.assert_allclose(scaling.pseudo_inertia_eps(bound), 0.3 * np.eye(4), atol=1e-12)
    for level, matrix in (("pseudo-inertia", pseudo_inertia),
                          ("mass-inertia", lambda p: value(cons.mass_inertia_matrix, p))):
        lowest = scipy.linalg.eigh(matrix(other), matrix(ref), eigvals_only=True)[0]
        for margin in (0.9 * lowest, 1.1 * lowest):
            x = cp.Variable(10)
            x.value = other
            (con,) = cons.body_constraints(x, level, cons.relative_bound(ref, level, margin),
                                           scaling=scaling)
            assert (np.linalg.eigvalsh(con.expr.value)[0] >= 0) == (margin < lowest)
    assert cons.relative_bound(ref, "none", 0.3) == 0.0


def test_parameter_map_normalises_the_reference():
    ref = body(3)
    scaling = cons.BodyScaling.from_reference(ref)
    t = scaling.parameter_map()
    np.testing.assert_allclose(pseudo_inertia(np.linalg.solve(t, ref)), np.eye(4), atol=1e-10)
    y = np.random.default_rng(0).normal(size=10)
    l_mat = np.linalg.inv(scaling.l_inv)
    np.testing.assert_allclose(pseudo_inertia(t @ y), l_mat @ pseudo_inertia(y) @ l_mat.T,
                               atol=1e-12)
    with pytest.raises(InconsistentParametersError, match="not positive definite"):
        cons.BodyScaling.from_reference(body(3, triangle_excess=0.5))


def test_ellipsoid_constraint_separates_inside_from_outside():
    """Point masses inside a sphere satisfy tr(JQ) ≥ 0; a body with mass outside does not."""
    rng = np.random.default_rng(1)
    ell = cons.Ellipsoid.from_semi_axes([0.1, 0, 0], [0.2, 0.2, 0.2])

    def cloud(radius):
        pts = rng.normal(size=(8, 3))
        pts = [0.1, 0, 0] + radius * pts / np.linalg.norm(pts, axis=1, keepdims=True)
        m = rng.uniform(0.1, 1.0, 8)
        ph = np.column_stack([pts, np.ones(8)])
        return (ph.T * m) @ ph

    scaling = cons.BodyScaling.from_reference(from_pseudo_inertia(cloud(0.1)))
    for radius, inside in ((0.15, True), (0.3, False)):
        j = cloud(radius)
        x = cp.Variable(10)
        x.value = from_pseudo_inertia(j)
        _, support = cons.ellipsoid_lmi(x, ell, scaling=scaling)
        slack = -support.expr.value  # the builder's tr(Ĵ Q̂), normalised
        assert (slack >= 0) == inside
        assert (np.trace(j @ ell.q_matrix()) >= 0) == inside
