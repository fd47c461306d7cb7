"""Standard parameters, pseudo-inertia conversions and consistency checks.

Bodies are built independently of the code under test: as clouds of point masses, whose
parameters follow from their definitions (``m = Σ m_k``, ``h = Σ m_k p_k``,
``I = Σ m_k (‖p_k‖² 1 − p_k p_kᵀ)``, ``J = Σ m_k [p_k; 1][p_k; 1]ᵀ``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.robot.inertia import (from_mass_com_inertia, from_pseudo_inertia,
                                  is_physically_consistent, perturb, pseudo_inertia,
                                  pseudo_inertia_map, to_mass_com_inertia)

SETTINGS = settings(max_examples=40, deadline=None)


def point_cloud(seed: int, n: int = 6, spread: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Standard 10-vector and pseudo-inertia of ``n`` random point masses (a 3-D cloud)."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(0.05, 3.0, n)
    pts = rng.normal(0.0, spread, (n, 3)) + rng.normal(0.0, 0.5, 3)
    h = m @ pts
    inertia = sum(mk * (pk @ pk * np.eye(3) - np.outer(pk, pk)) for mk, pk in zip(m, pts))
    vec = np.array([m.sum(), *h, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                    inertia[1, 2], inertia[2, 2]])
    ph = np.column_stack([pts, np.ones(n)])
    return vec, (ph.T * m) @ ph


def rotation(seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=4)
    return pin.Quaternion(*(q / np.linalg.norm(q))).toRotationMatrix()


@SETTINGS
@given(st.integers(0, 2**31))
def test_point_clouds_are_consistent_and_pseudo_inertia_is_their_second_moment(seed):
    vec, j_true = point_cloud(seed)
    np.testing.assert_allclose(pseudo_inertia(vec), j_true, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(from_pseudo_inertia(j_true), vec, rtol=1e-12, atol=1e-12)
    for level in ("mass-inertia", "triangle", "pseudo-inertia"):
        report = is_physically_consistent(vec, level)
        assert report.ok and report.bodies[0].condition == "", (level, str(report))


@SETTINGS
@given(st.floats(0.01, 100.0), st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.lists(st.floats(1e-4, 1.0), min_size=3, max_size=3), st.integers(0, 2**31))
def test_round_trips_are_exact(m, c, second_moments, seed):
    """(m, c, I_c) → π → J → π → (m, c, I_c) for a solid body (moments from second moments)."""
    sx, sy, sz = second_moments
    i_c = rotation(seed) @ np.diag([m * (sy + sz), m * (sx + sz), m * (sx + sy)]) @ rotation(
        seed).T
    vec = from_mass_com_inertia(m, c, i_c)
    assert is_physically_consistent(vec, "pseudo-inertia").ok
    back = from_pseudo_inertia(pseudo_inertia(vec))
    np.testing.assert_allclose(back, vec, rtol=1e-12, atol=1e-14 * np.abs(vec).max())
    m2, c2, i_c2 = to_mass_com_inertia(back)
    assert m2 == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(c2, c, atol=1e-12)
    np.testing.assert_allclose(i_c2, i_c, atol=1e-10 * np.abs(i_c).max())


@SETTINGS
@given(st.integers(0, 2**31), st.floats(0.01, 10.0))
def test_negative_mass_is_named(seed, scale):
    vec, _ = point_cloud(seed)
    bad = vec.copy()
    bad[0] = -scale
    for level in ("mass-inertia", "triangle", "pseudo-inertia"):
        body = is_physically_consistent(bad, level, ["forearm"]).bodies[0]
        assert not body.ok and body.condition == "mass"
        assert "forearm" in body.reason and "mass" in body.reason


@SETTINGS
@given(st.integers(0, 2**31), st.floats(1e-3, 1.0))
def test_inertia_not_positive_definite_is_named(seed, deficit):
    """A principal moment below zero: every level names ``I_c``."""
    rng = np.random.default_rng(seed)
    m, c = rng.uniform(0.1, 5.0), rng.normal(0, 0.2, 3)
    moments = np.array([-deficit, 1.0, 1.0 + deficit]) * rng.uniform(0.01, 1.0)
    vec = from_mass_com_inertia(m, c, rotation(seed) @ np.diag(moments) @ rotation(seed).T)
    for level in ("mass-inertia", "triangle", "pseudo-inertia"):
        body = is_physically_consistent(vec, level).bodies[0]
        assert not body.ok and body.condition == "inertia", (level, body.reason)


@SETTINGS
@given(st.integers(0, 2**31), st.floats(0.05, 2.0))
def test_triangle_violation_is_named_and_pseudo_inertia_is_indefinite(seed, excess):
    """Positive moments with I3 > I1 + I2: fine for "mass-inertia", a triangle violation for
    the stronger levels, and the pseudo-inertia then has a negative eigenvalue."""
    rng = np.random.default_rng(seed)
    m, c = rng.uniform(0.1, 5.0), rng.normal(0, 0.2, 3)
    i1, i2 = rng.uniform(0.01, 1.0, 2)
    vec = from_mass_com_inertia(m, c, rotation(seed) @ np.diag([i1, i2, (i1 + i2) * (1 + excess)])
                                @ rotation(seed).T)
    assert is_physically_consistent(vec, "mass-inertia").ok
    for level in ("triangle", "pseudo-inertia"):
        body = is_physically_consistent(vec, level).bodies[0]
        assert not body.ok and body.condition == "triangle", (level, body.reason)
    assert np.linalg.eigvalsh(pseudo_inertia(vec))[0] < 0


@SETTINGS
@given(st.lists(st.floats(-10, 10), min_size=10, max_size=10))
def test_pseudo_inertia_map_matches_pinocchio_for_any_vector(values):
    vec = np.array(values)
    j = pin.PseudoInertia.FromDynamicParameters(vec).toMatrix()
    np.testing.assert_allclose(pseudo_inertia_map() @ vec, np.asarray(j).ravel(order="F"),
                               atol=1e-12)


@SETTINGS
@given(st.integers(0, 2**31), st.floats(0.0, 0.5))
def test_perturb_keeps_bodies_consistent(seed, relative):
    vecs = np.concatenate([point_cloud(seed + k)[0] for k in range(3)])
    out = perturb(vecs, relative, np.random.default_rng(seed))
    assert is_physically_consistent(out, "pseudo-inertia").ok
    assert np.all(np.abs(out[0::10] / vecs[0::10] - 1) <= relative + 1e-12)


def test_body_count_comes_from_names_and_trailing_entries_are_ignored():
    vec = np.concatenate([point_cloud(1)[0], point_cloud(2)[0], np.full(14, -5.0)])
    report = is_physically_consistent(vec, "pseudo-inertia", ["a", "b"])
    assert report.ok and [b.body for b in report.bodies] == ["a", "b"]
    with pytest.raises(ValueError, match="not 10 per body"):
        is_physically_consistent(vec)
    with pytest.raises(ValueError, match="need 30"):
        is_physically_consistent(vec[:20], body_names=["a", "b", "c"])


def test_report_lists_each_failing_body():
    good, _ = point_cloud(3)
    bad = good.copy()
    bad[0] = -1.0
    report = is_physically_consistent(np.concatenate([good, bad]), "pseudo-inertia",
                                      ["upper_arm", "forearm"])
    assert not report and report.violations == [report.bodies[1].reason]
    assert "forearm" in str(report) and "upper_arm" not in str(report)
    assert report.min_eigenvalues[1] < 0 < report.min_eigenvalues[0]


@SETTINGS
@given(st.integers(0, 2**31))
def test_from_mass_com_inertia_matches_pinocchio_inertia(seed):
    rng = np.random.default_rng(seed)
    m, c = rng.uniform(0.1, 5.0), rng.normal(0, 0.3, 3)
    i_c = rotation(seed) @ np.diag(rng.uniform(0.01, 0.1, 3) + [0, 0, 0.05]) @ rotation(seed).T
    np.testing.assert_allclose(from_mass_com_inertia(m, c, i_c),
                               pin.Inertia(m, c, i_c).toDynamicParameters(), atol=1e-12)
