r"""Identification of the dynamic parameters from a dataset: OLS, WLS and the consistent SDP.

Least squares on the base parameters (Gautier & Khalil 1990; Khalil & Dombre ch. 12):

.. math::  \hat\beta = \arg\min_\beta \|\Sigma^{-1/2}(W_b \beta - \tau)\|^2,
           \qquad \operatorname{cov}(\hat\beta) = (W_b^\top \Sigma^{-1} W_b)^{-1}

with ``Σ = σ² 1`` for OLS (``σ² = ‖ρ‖² / (N·nv − b)``) and, for WLS, ``Σ = diag(σ_j²)`` per joint
estimated from the OLS residuals (``σ_j² = ‖ρ_j‖² / (N − b/nv)``), Gautier 1997, "Dynamic
identification of robots with power model", ICRA, doi:10.1109/ROBOT.1997.614364; ``σ_j`` is
floored by :func:`consistid.compression.floor_sigma` so that noise-free data keep finite weights.
Everything is solved on the compressed problem (:mod:`consistid.compression`), never on the
N-row regressor.
"""

from __future__ import annotations

import time
import warnings
from typing import Any, Sequence

import numpy as np
import scipy.linalg

from .base import BaseParameters, compute_base_parameters
from .compression import CompressedProblem, compress, floor_sigma
from .dataset import Dataset
from .errors import OptionError, PoorExcitationError, PoorExcitationWarning, check_option
from .model import RobotModel
from .regressor import DEFAULT_FRICTION, FrictionArg, RegressorSpec, parameter_names, prior_vector
from .result import IdentificationResult, SolverReport

METHODS = ("ols", "wls", "sdp")
#: Above this condition number of the (weighted) base regressor, a PoorExcitationWarning is issued.
COND_WARN = 1e4
#: Below this ratio of the smallest to the largest singular value, the base regressor is singular.
RANK_RTOL = 1e-11


def nearest_standard(base: BaseParameters, beta: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """The standard vector closest to ``prior`` (Euclidean) with ``B π = β``:
    ``π = π₀ + B⁺(β − B π₀)``. Not necessarily physically consistent."""
    B = base.matrix
    return prior + np.linalg.lstsq(B, beta - B @ prior, rcond=None)[0]


def check_excitation(r: np.ndarray, names: Sequence[str]) -> tuple[float, np.ndarray]:
    """Singular values and condition number of a (weighted) base regressor factor ``r``.

    Raises :class:`PoorExcitationError` naming the unexcited directions when ``r`` is singular.
    """
    _, s, vt = np.linalg.svd(r)
    if s[0] == 0 or s[-1] < RANK_RTOL * s[0]:
        dead = vt[s < RANK_RTOL * max(s[0], 1e-300)]
        lines = []
        for v in dead[:5]:
            top = np.argsort(-np.abs(v))[:3]
            lines.append(" + ".join(f"{v[i]:.2f}·{names[i]}" for i in top))
        raise PoorExcitationError(
            f"the data do not excite {len(dead)} base-parameter direction(s) "
            f"(condition number {s[0] / max(s[-1], 1e-300):.3g}); e.g. {'; '.join(lines)}. "
            "Use a richer excitation trajectory, or method='sdp' with a prior.")
    return float(s[0] / s[-1]), s


def least_squares(model: RobotModel, problem: CompressedProblem, base: BaseParameters,
                  spec: RegressorSpec, weighted: bool) -> IdentificationResult:
    """OLS (``weighted=False``) or per-joint-weighted WLS on the base parameters."""
    start = time.perf_counter()
    cols, n, b = base.independent, problem.n_samples, base.n_base
    dof = n * problem.nv - b
    if dof <= 0:
        raise PoorExcitationError(f"{n} samples × {problem.nv} joints give {n * problem.nv} "
                                  f"equations for {b} base parameters")
    r, z, _ = problem.stacked(columns=cols)
    cond, _ = check_excitation(r, base.names)
    beta = scipy.linalg.solve_triangular(r, z)
    sse = problem.sum_squares(beta, cols)
    sigma = np.full(problem.nv, np.sqrt(sse.sum() / dof))
    r_inv = scipy.linalg.solve_triangular(r, np.eye(b))
    cov = sigma[0] ** 2 * r_inv @ r_inv.T
    if weighted:
        sigma = floor_sigma(np.sqrt(sse / max(n - b / problem.nv, 1.0)), problem)
        r, z, _ = problem.stacked(sigma=sigma, columns=cols)
        cond, _ = check_excitation(r, base.names)
        beta = scipy.linalg.solve_triangular(r, z)
        sse = problem.sum_squares(beta, cols)
        r_inv = scipy.linalg.solve_triangular(r, np.eye(b))
        cov = r_inv @ r_inv.T
    if cond > COND_WARN:
        warnings.warn(f"base regressor condition number {cond:.3g} > {COND_WARN:.0e}: the data "
                      "excite some base parameters poorly; check relative_std",
                      PoorExcitationWarning, stacklevel=3)
    prior = prior_vector(model, spec)
    return IdentificationResult(
        method="wls" if weighted else "ols", model=model, spec=spec, base=base,
        parameters=nearest_standard(base, beta, prior),
        parameter_names=tuple(parameter_names(model, spec)), prior=prior,
        base_parameters=beta, base_covariance=cov, sigma=sigma, condition_number=cond,
        train_rms=np.sqrt(sse / n), n_samples=n,
        solver=SolverReport("numpy QR (compressed)", "optimal", time.perf_counter() - start))


def identify(model: RobotModel, dataset: Dataset | Sequence[Dataset], method: str = "sdp",
             friction: FrictionArg = DEFAULT_FRICTION,
             armature: bool | Sequence[int | str] = False,
             constraints: str | dict[str, str] = "auto",
             prior: str | None = "auto",
             **options: Any) -> IdentificationResult:
    """Identify a robot's dynamic parameters from measured torques.

    Parameters
    ----------
    model : the robot; its URDF inertias are the prior ``π₀``.
    dataset : a :class:`Dataset` with torques, or several (stacked as separate recordings).
    method : ``"ols"`` (least squares on base parameters), ``"wls"`` (weighted by per-joint noise
        variance), ``"sdp"`` (physically consistent, see :mod:`consistid.sdp`).
    friction : per-joint friction/offset columns, see :meth:`RegressorSpec.make`.
    armature : rotor-inertia columns (``True`` for all joints, or a list of joints).
    constraints : consistency level(s) of the bodies (:func:`consistid.sdp.identify_sdp`).
        ``"auto"`` (default): ``"pseudo-inertia"`` for the SDP, none for OLS/WLS, which also
        accept an explicit ``"none"`` and refuse any level.
    prior : ``"logdet"``, ``"euclidean"`` or ``None``/``"none"`` (no prior). ``"auto"``
        (default): ``"logdet"`` for the SDP, none for OLS/WLS, which also accept
        ``None``/``"none"`` and refuse a prior.
    **options : keyword options of :func:`consistid.sdp.identify_sdp`, for ``method="sdp"`` only.
        Options that only the SDP uses are refused for OLS/WLS, never silently ignored.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    OptionError for an unknown method or friction term; JointCountError when the dataset's joint
    count differs from the model's; PoorExcitationError when the data cannot determine the base
    parameters (OLS/WLS); IdentificationError / InfeasibleError when the SDP solver fails.
    """
    check_option("method", method, METHODS)
    prior = None if prior == "none" else prior
    if method in ("ols", "wls"):
        extra = sorted(options) + [k for k, v, none in (("constraints", constraints, ("none",)),
                                                        ("prior", prior, (None,)))
                                   if v != "auto" and v not in none]
        if extra:
            raise OptionError(f"option(s) {extra} apply to method='sdp' only, not {method!r} "
                              "(OLS/WLS are unconstrained and have no prior)")
    if not isinstance(dataset, Dataset):
        dataset = Dataset.concatenate(list(dataset))
    dataset.check_joints(model.nv, model.joint_names)
    spec = RegressorSpec.make(model, friction, armature)
    base = compute_base_parameters(model, spec)
    problem = compress(model, dataset, spec)
    if method in ("ols", "wls"):
        return least_squares(model, problem, base, spec, weighted=method == "wls")
    from .sdp import identify_sdp

    return identify_sdp(model, problem, base, spec,
                        constraints="pseudo-inertia" if constraints == "auto" else constraints,
                        prior="logdet" if prior == "auto" else prior, dataset=dataset, **options)
