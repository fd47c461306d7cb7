r"""Prior-neighbourhood penalties that keep an estimate near CAD values where data cannot tell.

Log-det (Bregman) divergence between pseudo-inertias (Lee, Wensing, Park 2019, "Geometric robot
dynamic identification: a convex programming approach", IEEE T-RO 36(2),
doi:10.1109/TRO.2019.2926491, eq. 24):

.. math::  d(J \,\|\, J_0) = -\log\det J + \log\det J_0 + \operatorname{tr}(J_0^{-1} J) - 4

convex in ``J``, zero only at ``J = J_0``, invariant to the choice of body frame and units of
length. Weighted Euclidean: ``‖W (x − x_0)‖²``.
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from .constraints import pseudo_inertia
from .parameters import pseudo_inertia as pseudo_inertia_numeric


def logdet_divergence(x: cp.Expression, prior: np.ndarray) -> cp.Expression:
    """``d(J(x) ‖ J(prior))`` for one body; ``prior`` must have a positive definite ``J``."""
    j0 = pseudo_inertia_numeric(prior)
    eig = np.linalg.eigvalsh(j0)
    if eig[0] <= 0:
        raise ValueError(f"the prior pseudo-inertia is not positive definite (min eigenvalue "
                         f"{eig[0]:.3g}); the log-det prior needs a realizable prior body")
    j = pseudo_inertia(x)
    return (-cp.log_det(j) + float(np.sum(np.log(eig)))
            + cp.trace(np.linalg.inv(j0) @ j) - 4.0)


def logdet_divergence_value(x: np.ndarray, prior: np.ndarray) -> float:
    """Numeric ``d(J(x) ‖ J(prior))`` (``inf`` when ``J(x)`` is not positive definite)."""
    j, j0 = pseudo_inertia_numeric(x), pseudo_inertia_numeric(prior)
    sign, logdet = np.linalg.slogdet(j)
    if sign <= 0:
        return float("inf")
    return float(-logdet + np.linalg.slogdet(j0)[1] + np.trace(np.linalg.solve(j0, j)) - 4.0)


def euclidean(x: cp.Expression, prior: np.ndarray, weights: np.ndarray | None = None
              ) -> cp.Expression:
    """``‖W (x − prior)‖²`` with a diagonal (1-D ``weights``) or full ``W``; default ``W = 1``."""
    diff = x - prior
    if weights is None:
        return cp.sum_squares(diff)
    w = np.asarray(weights, dtype=float)
    return cp.sum_squares(cp.multiply(w, diff) if w.ndim == 1 else w @ diff)
