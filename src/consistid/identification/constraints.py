r"""cvxpy constraint builders for physical consistency of one body's standard parameters.

Each builder takes a cvxpy expression ``x`` of shape (10,) in Pinocchio order
``[m, hx, hy, hz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (``h = m c``, inertia about the body origin)
and returns a plain list of constraints for the caller to combine. An LMI's lower bound ``eps``
is a number (``⪰ eps·1``) or a matrix ``E`` (``⪰ E``); :func:`relative_bound` gives the bound
``margin × (the reference body's matrix)`` that the SDP and recovery use as their margin.

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

from ..errors import InconsistentParametersError, OptionError, check_option
from ..robot.inertia import inertia_about_origin, pseudo_inertia_map
from ..robot.inertia import pseudo_inertia as pseudo_inertia_numeric
from ..robot.shapes import Ellipsoid

LEVELS = ("none", "mass-inertia", "triangle", "pseudo-inertia", "ellipsoid")


def _linear_map(shape: tuple[int, int], entries: dict[tuple[int, int], dict[int, float]]
                ) -> np.ndarray:
    """``(rows·cols, 10)`` matrix of a matrix-valued linear function of the 10-vector."""
    out = np.zeros((shape[0] * shape[1], 10))
    for (r, c), terms in entries.items():
        for k, coef in terms.items():
            out[r + shape[0] * c, k] = coef
    return out


_INERTIA_INDEX = {(0, 0): 4, (0, 1): 5, (1, 1): 6, (0, 2): 7, (1, 2): 8, (2, 2): 9}
#: vec(I) = _INERTIA_MAP x (column-major), I the inertia about the body origin.
_INERTIA_MAP = _linear_map((3, 3), {(r, c): {_INERTIA_INDEX[min(r, c), max(r, c)]: 1.0}
                                    for r in range(3) for c in range(3)})
_SKEW_TERMS = {(0, 1): (3, -1.0), (0, 2): (2, 1.0), (1, 0): (3, 1.0), (1, 2): (1, -1.0),
               (2, 0): (2, -1.0), (2, 1): (1, 1.0)}
#: vec([[I, S(h)ᵀ], [S(h), m 1]]) = _MASS_INERTIA_MAP x: the 6×6 matrix of Sousa & Cortesão.
_MASS_INERTIA_MAP = _linear_map((6, 6), {
    **{(r, c): {_INERTIA_INDEX[min(r, c), max(r, c)]: 1.0} for r in range(3) for c in range(3)},
    **{(3 + r, c): {k: v} for (r, c), (k, v) in _SKEW_TERMS.items()},
    **{(c, 3 + r): {k: v} for (r, c), (k, v) in _SKEW_TERMS.items()},
    **{(3 + r, 3 + r): {0: 1.0} for r in range(3)}})
_PSEUDO_INERTIA_MAP = pseudo_inertia_map()


def inertia_matrix(x: cp.Expression) -> cp.Expression:
    """3×3 inertia about the body origin from the 10-vector expression."""
    return cp.reshape(_INERTIA_MAP @ x, (3, 3), order="F")


def pseudo_inertia(x: cp.Expression) -> cp.Expression:
    """The 4×4 pseudo-inertia ``J(x)`` as an affine cvxpy expression (one matrix product)."""
    return cp.reshape(_PSEUDO_INERTIA_MAP @ x, (4, 4), order="F")


def mass_inertia_matrix(x: cp.Expression) -> cp.Expression:
    """The 6×6 ``[[I, S(h)ᵀ], [S(h), m·1]]`` (``S(h)`` the cross-product matrix of ``h = m c``)."""
    return cp.reshape(_MASS_INERTIA_MAP @ x, (6, 6), order="F")


@dataclass(frozen=True, eq=False)
class BodyScaling:
    """Congruences that make one body's LMIs well scaled, from a realizable reference body.

    With ``J_ref = L Lᵀ`` (Cholesky), ``J ⪰ eps·1 ⟺ L⁻¹ J L⁻ᵀ ⪰ eps·L⁻¹L⁻ᵀ``: the same set,
    but the scaled matrix is ``1`` at the reference, whatever the units and the body's size.
    The 6×6 mass–inertia matrix is scaled by ``D = diag(1/√ī·1₃, 1/√m·1₃)`` (``ī`` the mean
    diagonal inertia of the reference about the body origin).
    """

    l_inv: np.ndarray
    d: np.ndarray

    @classmethod
    def from_reference(cls, reference: np.ndarray) -> "BodyScaling":
        j_ref = pseudo_inertia_numeric(reference)
        try:
            chol = np.linalg.cholesky(j_ref)
        except np.linalg.LinAlgError as exc:
            raise InconsistentParametersError(
                "the reference body's pseudo-inertia is not positive definite (min eigenvalue "
                f"{np.linalg.eigvalsh(j_ref)[0]:.3g})") from exc
        i_bar = np.trace(inertia_about_origin(reference)) / 3.0
        d = np.concatenate([np.full(3, i_bar ** -0.5), np.full(3, reference[0] ** -0.5)])
        return cls(np.linalg.inv(chol), d)

    def pseudo_inertia(self, x: cp.Expression) -> cp.Expression:
        """``L⁻¹ J(x) L⁻ᵀ``."""
        return self.l_inv @ pseudo_inertia(x) @ self.l_inv.T

    def pseudo_inertia_eps(self, eps: float | np.ndarray) -> np.ndarray:
        """The bound ``eps·1`` (or ``E``) of ``J`` in scaled form: ``L⁻¹ (eps·1 | E) L⁻ᵀ``."""
        bound = eps * np.eye(4) if np.ndim(eps) == 0 else np.asarray(eps, dtype=float)
        return self.l_inv @ bound @ self.l_inv.T

    def parameter_map(self) -> np.ndarray:
        """The (10, 10) ``T`` with ``J(T y) = L J(y) Lᵀ``: normalised → standard parameters
        (``y`` of the reference body is the unit pseudo-inertia, ``J(y) = 1``)."""
        pmap = pseudo_inertia_map()
        l_mat = np.linalg.inv(self.l_inv)
        return np.linalg.pinv(pmap) @ np.kron(l_mat, l_mat) @ pmap


_NO_SCALING = BodyScaling(np.eye(4), np.ones(6))


def pseudo_inertia_lmi(x: cp.Expression, eps: float | np.ndarray = 0.0,
                       scaling: BodyScaling | None = None) -> list[cp.Constraint]:
    """``J(x) ⪰ eps·1`` (or ``⪰ E``, a 4×4 ``eps``): density realizability (also covers
    ``"triangle"``).

    ``scaling`` (from a reference body) imposes the same set in a well-scaled form.
    """
    sc = scaling or _NO_SCALING
    return [sc.pseudo_inertia(x) >> sc.pseudo_inertia_eps(eps)]


def mass_inertia_lmi(x: cp.Expression, eps: float | np.ndarray = 0.0,
                     scaling: BodyScaling | None = None) -> list[cp.Constraint]:
    """``[[I, S(h)ᵀ], [S(h), m·1]] ⪰ eps·1`` (or ``⪰ E``, a 6×6 ``eps``): positive mass and
    ``I_c ⪰ 0``. Scaled: ``D M D ⪰ D (eps·1 | E) D``."""
    d = (scaling or _NO_SCALING).d
    bound = eps * np.eye(6) if np.ndim(eps) == 0 else np.asarray(eps, dtype=float)
    return [cp.multiply(np.outer(d, d), mass_inertia_matrix(x)) >> np.outer(d, d) * bound]


def relative_bound(reference: np.ndarray, level: str, margin: float) -> np.ndarray | float:
    """``margin`` times the reference body's matrix of ``level``: ``margin·J(ref)`` (4×4) for
    the pseudo-inertia levels, ``margin·M(ref)`` (6×6) for ``"mass-inertia"``, 0 for ``"none"``.

    As the ``eps`` of :func:`body_constraints` it reads "the body's matrix ⪰ ``margin`` × the
    reference's": a margin relative to the reference in every direction, independent of units
    and of how flat the reference is; in the scaled form of a :class:`BodyScaling` built from
    the same reference, the pseudo-inertia bound is exactly ``margin·1``.
    """
    check_option("constraints", level, LEVELS)
    reference = np.asarray(reference, dtype=float)
    if level == "none":
        return 0.0
    if level == "mass-inertia":
        return margin * (_MASS_INERTIA_MAP @ reference).reshape(6, 6, order="F")
    return margin * pseudo_inertia_numeric(reference)


def ellipsoid_lmi(x: cp.Expression, ellipsoid: Ellipsoid, eps: float | np.ndarray = 0.0,
                  scaling: BodyScaling | None = None) -> list[cp.Constraint]:
    """``J ⪰ eps·1`` (or ``⪰ E``) and ``tr(J Q) ≥ 0``: a density supported in the ellipsoid
    exists.

    With ``scaling``, ``tr(J Q) = tr(Ĵ Q̂)`` for ``Ĵ = L⁻¹JL⁻ᵀ``, ``Q̂ = LᵀQL`` (normalised).
    """
    sc = scaling or _NO_SCALING
    l_mat = np.linalg.inv(sc.l_inv)
    q_hat = l_mat.T @ ellipsoid.q_matrix() @ l_mat
    q_hat /= max(np.abs(q_hat).max(), 1e-300)
    j_hat = sc.pseudo_inertia(x)
    return [j_hat >> sc.pseudo_inertia_eps(eps), cp.sum(cp.multiply(j_hat, q_hat)) >= 0]


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


def body_constraints(x: cp.Expression, level: str, eps: float | np.ndarray = 0.0,
                     ellipsoid: Ellipsoid | None = None,
                     scaling: BodyScaling | None = None) -> list[cp.Constraint]:
    """The constraints of one consistency level (see :data:`LEVELS`); ``eps`` is the LMI's
    lower bound (a number, or the level's matrix, e.g. from :func:`relative_bound`).

    ``"triangle"`` and ``"pseudo-inertia"`` give the same LMI: for one body, ``J ⪰ 0`` is
    exactly ``m ≥ 0`` plus the triangle inequalities of ``I_c`` (module docstring).
    """
    check_option("constraints", level, LEVELS)
    if level == "none":
        return []
    if level == "mass-inertia":
        return mass_inertia_lmi(x, eps, scaling)
    if level == "ellipsoid":
        if ellipsoid is None:
            raise OptionError("constraints='ellipsoid' needs an Ellipsoid for the body")
        return ellipsoid_lmi(x, ellipsoid, eps, scaling)
    return pseudo_inertia_lmi(x, eps, scaling)
