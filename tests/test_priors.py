"""Prior terms: the log-det divergence, its metric, and the neighbourhood bounds."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.identification import priors
from consistid.errors import InconsistentParametersError, OptionError
from consistid.robot.inertia import from_mass_com_inertia, pseudo_inertia

SETTINGS = settings(max_examples=25, deadline=None)


def body(seed: int, m: float | None = None) -> np.ndarray:
    rng = np.random.default_rng(seed)
    s = rng.uniform(1e-3, 0.05, 3)  # second moments: always a solid body
    mass = rng.uniform(0.5, 5.0) if m is None else m
    return from_mass_com_inertia(mass, rng.normal(0, 0.2, 3),
                                 mass * np.diag([s[1] + s[2], s[0] + s[2], s[0] + s[1]]))


def divergence(j: np.ndarray, j0: np.ndarray) -> float:
    """Definition (Lee, Wensing, Park 2019, eq. 24), computed independently."""
    return float(-np.log(np.linalg.det(j)) + np.log(np.linalg.det(j0))
                 + np.trace(np.linalg.solve(j0, j)) - 4)


@SETTINGS
@given(st.integers(0, 2**31))
def test_logdet_divergence_expression_matches_definition(seed):
    p0, p = body(seed), body(seed + 1)
    x = cp.Variable(10)
    x.value = p
    expected = divergence(pseudo_inertia(p), pseudo_inertia(p0))
    assert priors.logdet_divergence(x, p0).value == pytest.approx(expected, rel=1e-9, abs=1e-9)
    raw = priors.logdet_divergence(x, p0, normalised=False).value
    assert raw == pytest.approx(expected, rel=1e-9, abs=1e-9)
    assert priors.logdet_divergence_value(p, p0) == pytest.approx(expected, rel=1e-9, abs=1e-9)
    assert priors.logdet_divergence_value(p0, p0) == pytest.approx(0.0, abs=1e-9)


@SETTINGS
@given(st.integers(0, 2**31))
def test_logdet_metric_is_the_second_order_expansion(seed):
    p0 = body(seed)
    w = priors.logdet_metric(p0)
    d = np.random.default_rng(seed).normal(size=10)
    d *= 1e-3 * np.linalg.norm(p0) / np.linalg.norm(d)
    # The even part (d(J₀ + sΔ) + d(J₀ − sΔ))/2 = s²‖WΔ‖² + O(s⁴) has no third-order term, so
    # its ratio to the quadratic form tends to 1 quadratically (over 3000 seeds the worst errors
    # are 3.3e-3 at s = 0.1 and 3.3e-5 at s = 0.01); a one-sided ratio converges only linearly,
    # with a seed-dependent constant, which made a fixed bound flaky.
    for step, tol in ((0.1, 1e-2), (0.01, 1e-4)):
        quad = np.sum((w @ (step * d)) ** 2)
        even = 0.5 * (priors.logdet_divergence_value(p0 + step * d, p0)
                      + priors.logdet_divergence_value(p0 - step * d, p0))
        assert abs(even / quad - 1) < tol


def test_neighbourhood_bounds_hold_when_minimising_against_them():
    """Pull a body far away; the optimum sits on each bound."""
    p0 = body(5, m=2.0)
    far = body(6, m=4.0)
    bounds = priors.Neighbourhood(mass=0.1, com=0.02, inertia=0.2)
    x = cp.Variable(10)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x - far)),
                         priors.neighbourhood_constraints(x, p0, bounds))
    problem.solve(solver="CLARABEL")
    assert problem.status == "optimal"
    v = x.value
    assert abs(v[0] / p0[0] - 1) == pytest.approx(0.1, abs=1e-6)
    c, c0 = v[1:4] / v[0], p0[1:4] / p0[0]
    assert np.linalg.norm(c - c0) <= 0.02 + 1e-6
    # inertia about the body origin, by its definition from the 10-vector (not the library's)
    def inertia(p):
        return np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])

    i0 = inertia(p0)
    assert np.linalg.norm(inertia(v) - i0) <= (0.2 + 1e-6) * np.linalg.norm(i0)
    # the far body is outside each bound, so the optimum presses against every one of them
    assert np.linalg.norm(inertia(far) - i0) > 0.2 * np.linalg.norm(i0)
    assert np.linalg.norm(inertia(v) - i0) == pytest.approx(0.2 * np.linalg.norm(i0), rel=1e-5)
    with pytest.raises(OptionError, match="Neighbourhood.com"):
        priors.Neighbourhood(com=-1.0)
    with pytest.raises(InconsistentParametersError, match="positive mass"):
        priors.neighbourhood_constraints(x, np.zeros(10), bounds)
