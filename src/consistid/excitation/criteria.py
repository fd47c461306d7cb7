r"""Excitation criteria of a base regressor and their gradients.

With the base regressor ``Y_b`` (rows sample-major, one per joint and sample) weighted by the
per-joint noise ``Σ = diag(σ_j²)`` and optionally column-scaled, ``A = Σ^{-1/2} Y_b D``:

``"cond"``
    the 2-norm condition number ``κ(A) = s_max / s_min`` (Gautier & Khalil 1992, "Exciting
    trajectories for the identification of base inertial parameters of robots", IJRR 11(4),
    doi:10.1177/027836499201100408). With ``D = diag(|β_prior|)`` it is the scaled criterion of
    Pressé & Gautier 1993 used by Rackl et al. 2012 (ICRA, doi:10.1109/ICRA.2012.6225279,
    eq. 15), to which :func:`consistid.excitation.design_excitation` can add Rackl's torque
    term ``ξ / mean|τ|``.
``"d-opt"``
    ``−log det F`` with the Fisher information per sample ``F = Aᵀ A / N`` (Swevers et al. 1997,
    doi:10.1109/70.631234; the Maestro write-up's ``det(Ȳᵀ Σ⁻¹ Ȳ)``). Column scaling shifts it
    by a constant only.
``"e-opt"``
    ``−log λ_min(F)``: the worst-determined direction.

Gradients w.r.t. ``A`` come from the singular value decomposition ``A = U S Vᵀ``
(``∂s_k = u_kᵀ ∂A v_k``); :func:`regressor_sensitivity` gives ``∂Y/∂(q, q̇, q̈)`` per sample.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..identification.base import BaseParameters
from ..errors import check_option
from ..robot.model import RobotModel
from ..identification.regressor import RegressorSpec, prior_vector, regressor

CRITERIA = ("cond", "d-opt", "e-opt")


def criterion_and_gradient(a: np.ndarray, criterion: str, n_samples: int,
                           gradient: bool = True) -> tuple[float, np.ndarray | None]:
    """Value of ``criterion`` for the weighted, scaled base regressor ``a`` (rows × b) and its
    gradient ``∂J/∂a`` (same shape; ``None`` unless ``gradient``). ``n_samples`` is ``N`` in
    ``F = aᵀa / N``. A rank-deficient ``a`` gives ``inf`` (and a zero gradient)."""
    check_option("criterion", criterion, CRITERIA)
    if not gradient:
        return criteria_values(a, n_samples)[criterion], None
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    if not s[-1] > 0:
        return np.inf, np.zeros_like(a)
    if criterion == "cond":
        value = s[0] / s[-1]
        grad = (np.outer(u[:, 0], vt[0]) - value * np.outer(u[:, -1], vt[-1])) / s[-1]
    elif criterion == "d-opt":
        value = -2.0 * np.sum(np.log(s)) + s.size * np.log(n_samples)
        grad = -2.0 * (u / s) @ vt
    else:
        value = -2.0 * np.log(s[-1]) + np.log(n_samples)
        grad = -2.0 / s[-1] * np.outer(u[:, -1], vt[-1])
    return float(value), grad


def criteria_values(a: np.ndarray, n_samples: int) -> dict[str, float]:
    """All three criteria of ``a`` at once (one SVD)."""
    s = np.linalg.svd(a, compute_uv=False)
    if not s[-1] > 0:
        return {"cond": np.inf, "d-opt": np.inf, "e-opt": np.inf}
    return {"cond": float(s[0] / s[-1]),
            "d-opt": float(-2.0 * np.sum(np.log(s)) + s.size * np.log(n_samples)),
            "e-opt": float(-2.0 * np.log(s[-1]) + np.log(n_samples))}


def prior_column_scale(model: RobotModel, base: BaseParameters, spec: RegressorSpec,
                       joint_column_scale: float = 1.0, floor: float = 1e-3) -> np.ndarray:
    r"""Rackl's column scaling ``D = diag(|β_prior|)`` (eq. 15) for the base parameters.

    ``β_prior = B π_prior`` with the URDF inertias and ``joint_column_scale`` for every
    friction/armature column (their prior is unknown: 1 means N·m, N·m·s/rad, kg·m²). Entries are
    floored at ``floor · max|β_prior|`` so that a base parameter whose prior is zero keeps a
    column.
    """
    prior = prior_vector(model, spec)
    prior[model.n_inertial:] = joint_column_scale
    beta = np.abs(base.project(prior))
    return np.maximum(beta, floor * beta.max())


def regressor_sensitivity(model: RobotModel, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
                          spec: RegressorSpec, step: float = 1e-6, y: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    r"""The regressor per sample and its derivative w.r.t. the sample's state.

    Returns ``Y`` (N, nv, p) and ``dY`` (N, 3·nv, nv, p) with
    ``dY[i, d·nv + k] = ∂Y_i/∂x_k`` for ``x = q, q̇, q̈`` (``d = 0, 1, 2``). The rigid-body block
    is linear in ``q̈`` (differenced with a unit step, exact), quadratic in ``q̇`` and smooth in
    ``q`` (forward differences with ``step``); the per-joint columns are differentiated
    analytically (``∂ sign(q̇)/∂q̇ = 0``, ``∂ sin q/∂q = cos q``, ``∂ cos q/∂q = −sin q``).
    ``y``: ``Y`` at these samples if already computed (``regressor(...)`` reshaped to
    ``(N, nv, p)``); it is then returned as is and not computed again.
    """
    m = model.pin_model
    data = m.createData()
    n, nv = q.shape
    ni = model.n_inertial
    p = ni + spec.n_joint_columns
    if y is None:
        y = regressor(model, q, dq, ddq, spec).reshape(n, nv, p)
    rigid = np.ascontiguousarray(y[:, :, :ni])
    dy = np.zeros((n, 3 * nv, nv, p))
    eye = np.eye(nv)
    for i in range(n):
        qi, vi, ai = q[i], dq[i], ddq[i]
        cfg = model.configuration(qi)
        y0 = rigid[i]
        for k in range(nv):
            cfg_k = model.configuration(qi + step * eye[k])
            dy[i, k, :, :ni] = (pin.computeJointTorqueRegressor(m, data, cfg_k, vi, ai)
                                - y0) / step
        for k in range(nv):
            dy[i, nv + k, :, :ni] = (pin.computeJointTorqueRegressor(
                m, data, cfg, vi + step * eye[k], ai) - y0) / step
            dy[i, 2 * nv + k, :, :ni] = pin.computeJointTorqueRegressor(
                m, data, cfg, vi, ai + eye[k]) - y0
    if spec.n_joint_columns:
        for c, (_, j, suffix) in enumerate(spec.columns, start=ni):
            if suffix == "fv":
                dy[:, nv + j, j, c] = 1.0
            elif suffix == "Ia":
                dy[:, 2 * nv + j, j, c] = 1.0
            elif suffix == "ps1":
                dy[:, j, j, c] = np.cos(q[:, j])
            elif suffix == "pc1":
                dy[:, j, j, c] = -np.sin(q[:, j])
    return y, dy
