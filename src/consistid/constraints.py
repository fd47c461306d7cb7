r"""cvxpy constraint builders for physical consistency of one body's standard parameters.

Each builder takes a cvxpy expression ``x`` of shape (10,) in Pinocchio order
``[m, hx, hy, hz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (``h = m c``, inertia about the body origin)
and returns a plain list of constraints for the caller to combine.

Pseudo-inertia (Wensing, Kim, Slotine 2017, RA-L 3(1), doi:10.1109/LRA.2017.2729659, eq. 7):

.. math::  J(x) = \begin{bmatrix} \tfrac12\operatorname{tr}(I)\,1 - I & h \\ h^\top & m
           \end{bmatrix} \succeq \varepsilon 1

is linear in ``x``; ``J ⪰ 0`` is density realizability, and implies ``m ≥ 0``, ``I_c ⪰ 0`` and the
triangle inequalities (its Schur complement is ``Σ_c = ½ tr(I_c) 1 − I_c``, whose eigenvalues are
the triangle slacks ``(I_l + I_m − I_k)/2``). So the ``"triangle"`` level *is* the pseudo-inertia
LMI for a single body.

Mass–inertia (Sousa & Cortesão 2014, IJRR 33(6), doi:10.1177/0278364913514870):

.. math::  \begin{bmatrix} I & S(h)^\top \\ S(h) & m 1 \end{bmatrix} \succeq \varepsilon 1

whose Schur complement is ``I − S(h)ᵀS(h)/m = I_c``, i.e. ``m > 0`` and ``I_c ⪰ 0``.

Bounding ellipsoid (Wensing et al. 2017, eq. 12): all mass inside
``{p : (p − c)ᵀ Σ_E⁻¹ (p − c) ≤ 1}`` is ``tr(J Q) ≥ 0`` with
``Q = [[−Σ_E⁻¹, Σ_E⁻¹ c], [cᵀ Σ_E⁻¹, 1 − cᵀ Σ_E⁻¹ c]]``, together with ``J ⪰ 0``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import cvxpy as cp
import numpy as np

from .errors import check_option

LEVELS = ("none", "mass-inertia", "triangle", "pseudo-inertia", "ellipsoid")


def inertia_matrix(x: cp.Expression) -> cp.Expression:
    """3×3 inertia about the body origin from the 10-vector expression."""
    return cp.bmat([[x[4], x[5], x[7]], [x[5], x[6], x[8]], [x[7], x[8], x[9]]])


def pseudo_inertia(x: cp.Expression) -> cp.Expression:
    """The 4×4 pseudo-inertia ``J(x)`` as an affine cvxpy expression."""
    inertia = inertia_matrix(x)
    half_trace = 0.5 * (x[4] + x[6] + x[9])
    sigma = half_trace * np.eye(3) - inertia
    h = cp.reshape(x[1:4], (3, 1), order="F")
    return cp.bmat([[sigma, h], [h.T, cp.reshape(x[0], (1, 1), order="F")]])


def skew(h: cp.Expression) -> cp.Expression:
    return cp.bmat([[0, -h[2], h[1]], [h[2], 0, -h[0]], [-h[1], h[0], 0]])


def pseudo_inertia_lmi(x: cp.Expression, eps: float = 0.0) -> list[cp.Constraint]:
    """``J(x) ⪰ eps·1``: density realizability (also covers ``"triangle"``)."""
    return [pseudo_inertia(x) >> eps * np.eye(4)]


def mass_inertia_lmi(x: cp.Expression, eps: float = 0.0) -> list[cp.Constraint]:
    """``[[I, S(h)ᵀ], [S(h), m·1]] ⪰ eps·1``: positive mass and ``I_c ⪰ 0``."""
    s = skew(x[1:4])
    block = cp.bmat([[inertia_matrix(x), s.T], [s, x[0] * np.eye(3)]])
    return [block >> eps * np.eye(6)]


@dataclass(frozen=True)
class Ellipsoid:
    """``{p : (p − center)ᵀ shape⁻¹ (p − center) ≤ 1}`` in the body frame (m, m²)."""

    center: np.ndarray
    shape: np.ndarray

    @classmethod
    def from_semi_axes(cls, center: Sequence[float], semi_axes: Sequence[float],
                       rotation: np.ndarray | None = None) -> "Ellipsoid":
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
        return cls(np.asarray(center, float), r @ np.diag(np.square(semi_axes)) @ r.T)

    def q_matrix(self) -> np.ndarray:
        inv = np.linalg.inv(self.shape)
        c = self.center
        return np.block([[-inv, (inv @ c)[:, None]], [(inv @ c)[None, :],
                                                      np.array([[1.0 - c @ inv @ c]])]])

    def contains(self, point: np.ndarray) -> bool:
        d = np.asarray(point, float) - self.center
        return bool(d @ np.linalg.solve(self.shape, d) <= 1.0 + 1e-12)


def ellipsoid_lmi(x: cp.Expression, ellipsoid: Ellipsoid, eps: float = 0.0
                  ) -> list[cp.Constraint]:
    """``J ⪰ eps·1`` and ``tr(J Q) ≥ 0``: a density supported in the ellipsoid exists."""
    j = pseudo_inertia(x)
    return [j >> eps * np.eye(4), cp.trace(j @ ellipsoid.q_matrix()) >= 0]


def com_box(x: cp.Expression, lower: Sequence[float], upper: Sequence[float]
            ) -> list[cp.Constraint]:
    """Centre of mass in a box, ``m·lower ≤ h ≤ m·upper`` (linear because ``m > 0``)."""
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    return [x[1:4] >= x[0] * lo, x[1:4] <= x[0] * hi]


def mass_bounds(x: cp.Expression, lower: float | None = None, upper: float | None = None
                ) -> list[cp.Constraint]:
    out = []
    if lower is not None:
        out.append(x[0] >= lower)
    if upper is not None:
        out.append(x[0] <= upper)
    return out


def body_constraints(x: cp.Expression, level: str, eps: float = 0.0,
                     ellipsoid: Ellipsoid | None = None) -> list[cp.Constraint]:
    """The constraints of one consistency level (see :data:`LEVELS`)."""
    check_option("constraints", level, LEVELS)
    if level == "none":
        return []
    if level == "mass-inertia":
        return mass_inertia_lmi(x, eps)
    if level == "ellipsoid":
        if ellipsoid is None:
            raise ValueError("constraints='ellipsoid' needs an Ellipsoid for the body")
        return ellipsoid_lmi(x, ellipsoid, eps)
    return pseudo_inertia_lmi(x, eps)
