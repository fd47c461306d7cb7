r"""Prior-neighbourhood penalties that keep an estimate near CAD values where data cannot tell.

Log-det (Bregman) divergence between pseudo-inertias (Lee, Wensing, Park 2019, "Geometric robot
dynamic identification: a convex programming approach", IEEE T-RO 36(2),
doi:10.1109/TRO.2019.2926491, eq. 24):

.. math::  d(J \,\|\, J_0) = -\log\det J + \log\det J_0 + \operatorname{tr}(J_0^{-1} J) - 4

convex in ``J``, zero only at ``J = J_0``, invariant to the choice of body frame and units of
length. Weighted Euclidean: ``‖W (x − x_0)‖²``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from .constraints import BodyScaling, inertia_matrix
from .constraints import pseudo_inertia as pseudo_inertia_expression
from ..errors import InconsistentParametersError, check_number
from ..robot.inertia import inertia_about_origin, pseudo_inertia_map
from ..robot.inertia import pseudo_inertia as pseudo_inertia_numeric


def _check_prior_body(prior: np.ndarray) -> np.ndarray:
    j0 = pseudo_inertia_numeric(prior)
    eig = np.linalg.eigvalsh(j0)
    if eig[0] <= 0:
        raise InconsistentParametersError(
            f"the prior pseudo-inertia is not positive definite (min eigenvalue {eig[0]:.3g}); "
            "the log-det prior needs a realizable prior body")
    return j0


def logdet_divergence(x: cp.Expression, prior: np.ndarray, normalised: bool = True
                      ) -> cp.Expression:
    r"""``d(J(x) ‖ J(prior))`` for one body; ``prior`` must have a positive definite ``J``.

    Built in the normalised form ``d = −log det Ĵ + tr Ĵ − 4`` with ``Ĵ = L⁻¹ J L⁻ᵀ``,
    ``J₀ = L Lᵀ`` (identical value, since ``log det J₀ = 2 log det L`` and
    ``tr(J₀⁻¹J) = tr Ĵ``), so that the cone the solver sees is ``1`` at the prior whatever the
    body's size and units. ``normalised=False`` builds the defining form on the raw ``J``
    instead (same value; it exists to measure what the normalisation buys, ``sdp`` with
    ``scale=False``).
    """
    j0 = _check_prior_body(prior)
    if not normalised:
        return (-cp.log_det(pseudo_inertia_expression(x)) + float(np.linalg.slogdet(j0)[1])
                + cp.trace(np.linalg.inv(j0) @ pseudo_inertia_expression(x)) - 4.0)
    j_hat = BodyScaling.from_reference(np.asarray(prior, dtype=float)).pseudo_inertia(x)
    return -cp.log_det(j_hat) + cp.trace(j_hat) - 4.0


def logdet_divergence_value(x: np.ndarray, prior: np.ndarray) -> float:
    """Numeric ``d(J(x) ‖ J(prior))`` (``inf`` when ``J(x)`` is not positive definite)."""
    j, j0 = pseudo_inertia_numeric(x), pseudo_inertia_numeric(prior)
    sign, logdet = np.linalg.slogdet(j)
    if sign <= 0:
        return float("inf")
    return float(-logdet + np.linalg.slogdet(j0)[1] + np.trace(np.linalg.solve(j0, j)) - 4.0)


def logdet_metric(prior: np.ndarray) -> np.ndarray:
    r"""The (10, 10) ``W`` with ``‖W (x − x₀)‖² = ½ ‖L⁻¹ (J(x) − J₀) L⁻ᵀ‖²_F``.

    This is the second-order expansion of the log-det divergence at the prior,
    ``d(J₀ + Δ ‖ J₀) = ½ tr((J₀⁻¹Δ)²) + O(Δ³)``, so a Euclidean prior with these weights has the
    same local curvature as the log-det prior (and, like it, does not depend on units or frame).
    """
    j0 = _check_prior_body(prior)
    l_inv = np.linalg.inv(np.linalg.cholesky(j0))
    # vec(L⁻¹ J L⁻ᵀ) = (L⁻¹ ⊗ L⁻¹) vec(J) = (L⁻¹ ⊗ L⁻¹) P x
    m = np.kron(l_inv, l_inv) @ pseudo_inertia_map() / np.sqrt(2.0)
    _, r = np.linalg.qr(m)
    return r


def euclidean(x: cp.Expression, prior: np.ndarray, weights: np.ndarray | None = None
              ) -> cp.Expression:
    """``‖W (x − prior)‖²`` with a diagonal (1-D ``weights``) or full ``W``; default ``W = 1``."""
    diff = x - prior
    if weights is None:
        return cp.sum_squares(diff)
    w = np.asarray(weights, dtype=float)
    return cp.sum_squares(cp.multiply(w, diff) if w.ndim == 1 else w @ diff)


@dataclass(frozen=True)
class Neighbourhood:
    r"""Hard bounds around the prior body (the "neighbourhood constraints" of the Maestro
    identification write-up, in ``consistid``'s shared seeds, made convex in ``π``).

    Attributes
    ----------
    mass : relative mass bound ``α``: ``|m − m₀| ≤ α m₀`` (``None``: no bound).
    com : CoM radius ``β`` in metres: ``‖c − c₀‖ ≤ β``, i.e. the second-order cone
        ``‖h − m c₀‖ ≤ β m`` (convex because ``m > 0``).
    inertia : relative bound ``δ`` on the inertia about the body origin:
        ``‖I − I₀‖_F ≤ δ ‖I₀‖_F``.
    """

    mass: float | None = None
    com: float | None = None
    inertia: float | None = None

    def __post_init__(self) -> None:
        for name in ("mass", "com", "inertia"):
            value = getattr(self, name)
            if value is not None:
                check_number(f"Neighbourhood.{name}", value, 0)


def neighbourhood_constraints(x: cp.Expression, prior: np.ndarray,
                              bounds: Neighbourhood) -> list[cp.Constraint]:
    """The constraints of :class:`Neighbourhood` for one body (each row scaled by the prior)."""
    prior = np.asarray(prior, dtype=float)
    m0 = prior[0]
    if not m0 > 0:
        raise InconsistentParametersError(
            f"neighbourhood bounds need a prior body with positive mass, got {m0}")
    out = []
    if bounds.mass is not None:
        out.append(cp.abs(x[0] / m0 - 1.0) <= bounds.mass)
    if bounds.com is not None:
        c0 = prior[1:4] / m0
        out.append(cp.norm(x[1:4] / m0 - (x[0] / m0) * c0) <= bounds.com * x[0] / m0)
    if bounds.inertia is not None:
        i0 = inertia_about_origin(prior)
        norm0 = np.linalg.norm(i0)
        out.append(cp.norm(inertia_matrix(x) / norm0 - i0 / norm0, "fro") <= bounds.inertia)
    return out
