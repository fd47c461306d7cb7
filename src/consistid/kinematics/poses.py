r"""Choose the configurations to measure: the most informative ``k`` of a feasible candidate set.

Candidates (random configurations within the joint limits, or the user's) are kept when every
margin of :class:`~consistid.excitation.ExcitationLimits` holds at rest (``q̇ = q̈ = 0``): joint
limits, the gravity torque against the effort limits, a workspace box, a floor plane and a
keep-out sphere for the measured frame — the excitation module's constraints, so a pose plan and
an excitation trajectory respect the same cell.

With ``J_c`` the whitened residual Jacobian of candidate ``c`` over the identifiable parameters
(:mod:`.identifiability`), the information of a set ``S`` is :math:`M_S = \sum_{c\in S} J_c^\top
J_c`` (the Fisher information; its inverse the Cramér–Rao covariance).

``criterion="d-opt"``
    maximise :math:`\log\det M_S` (D-optimality): greedy additions by the matrix determinant
    lemma :math:`\det(M + J_c^\top J_c) = \det M \det(I + J_c M^{-1} J_c^\top)`, then Fedorov
    exchanges (Fedorov 1972, *Theory of Optimal Experiments*) until no swap helps;
``criterion="cond"``
    minimise the condition number of the column-normalised stacked Jacobian (Borm & Menq 1991,
    doi:10.1177/027836499101000105): D-optimal until full rank, then greedy on ``cond`` over a
    random subset of candidates per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
import pinocchio as pin

from ..errors import DatasetError, OptionError, PoorExcitationError, check_number, check_option
from ..excitation.limits import (
    CartesianBox,
    ConstraintSet,
    ExcitationLimits,
    FloorPlane,
    KeepOutSphere,
    end_effector_frame,
)
from ..robot.model import RobotModel, require_model
from .identifiability import normalised, structural_selection
from .measurements import (
    COMPONENTS,
    Measurements,
    joint_coordinates,
    noise_covariance,
    residual_jacobian,
    whitening,
)
from .parameters import KINDS, KinematicParameters, random_configurations

CRITERIA = ("d-opt", "cond")


@dataclass(frozen=True, eq=False)
class PoseSelection:
    """The chosen configurations and how informative they are.

    Attributes
    ----------
    q : (k, nv) the configurations to measure.
    indices : (k,) their rows in ``candidates``.
    candidates : (M, nv) the feasible candidates chosen from.
    n_offered : candidates before the feasibility filter.
    criterion : ``"d-opt"`` or ``"cond"``.
    logdet : ``log det(JᵀJ)`` of the selection (whitened, identifiable parameters).
    cond : condition number of the column-normalised Jacobian.
    parameter_names : the identifiable parameters the information is about.
    predicted_std : (r,) Cramér–Rao standard deviations of those parameters for the given σ.
    """

    q: np.ndarray
    indices: np.ndarray
    candidates: np.ndarray
    n_offered: int
    criterion: str
    logdet: float
    cond: float
    parameter_names: tuple[str, ...]
    predicted_std: np.ndarray
    units: tuple[str, ...]

    def mean_std(self) -> dict[str, float]:
        """Mean predicted σ of the length (m) and of the angle (rad) parameters."""
        u = np.asarray(self.units)
        return {unit: float(np.mean(self.predicted_std[u == unit])) for unit in ("m", "rad")
                if np.any(u == unit)}

    def __str__(self) -> str:
        ms = self.mean_std()
        parts = [f"{len(self.indices)} poses ({self.criterion}) of {len(self.candidates)} "
                 f"feasible candidates ({self.n_offered} offered)",
                 f"log det(JᵀJ) = {self.logdet:.4g}, cond = {self.cond:.4g}, "
                 f"{len(self.parameter_names)} identifiable parameters"]
        if "m" in ms:
            parts.append(f"mean predicted σ: {ms['m'] * 1e3:.4g} mm (lengths)"
                         + (f", {np.degrees(ms['rad']):.4g}° (angles)" if "rad" in ms else ""))
        return "\n".join(parts)


def _feasible(model: RobotModel, q: np.ndarray, limits: ExcitationLimits) -> np.ndarray:
    zeros = np.zeros_like(q)
    ok = np.ones(q.shape[0], dtype=bool)
    for block in ConstraintSet(model, limits).blocks(q, zeros, zeros):
        if block.kind in ("velocity", "acceleration"):
            continue
        ok &= np.all(block.values >= 0, axis=1)
    return ok


def candidate_jacobians(chart: KinematicParameters, q: np.ndarray, sel: np.ndarray,
                        cov: np.ndarray, anchor: np.ndarray | None,
                        values: np.ndarray | None = None) -> np.ndarray:
    """Whitened residual Jacobians (M, m, len(sel)) at the generic point near the URDF
    (:attr:`~consistid.kinematics.parameters.KinematicParameters.generic_values`; measurement
    frame at the identity, the residual zero)."""
    values = chart.generic_point(sel) if values is None else values
    pos, rot, tw = chart.frame_kinematics(values, q)
    if chart.kind == "distance":
        meas = Measurements("distance", distances=np.linalg.norm(pos - anchor, axis=1))
    else:
        meas = Measurements(chart.kind, positions=pos,
                            rotations=rot if chart.kind == "pose" else None)
    jac = residual_jacobian(meas, pos, rot, tw, pin.SE3.Identity(), np.zeros(3), anchor)
    return np.einsum("ij,njk->nik", whitening(cov[:1])[0], jac[:, :, sel])


def _logdet(m: np.ndarray) -> float:
    sign, value = np.linalg.slogdet(m)
    return float(value) if sign > 0 else -np.inf


def _gains(jac: np.ndarray, jac_t: np.ndarray, inv: np.ndarray) -> np.ndarray:
    """``log det(I + J_c M⁻¹ J_cᵀ)`` for every candidate (matrix determinant lemma)."""
    m = jac.shape[1]
    return np.linalg.slogdet(np.eye(m) + (jac @ inv) @ jac_t)[1]


def _d_optimal(jac: np.ndarray, k: int, max_passes: int = 4) -> np.ndarray:
    n, m, r = jac.shape
    jac_t = jac.transpose(0, 2, 1).copy()
    info_all = np.einsum("nji,njk->ik", jac, jac)
    eps = 1e-8 * np.trace(info_all) / (r * n)
    info = eps * np.eye(r)
    chosen: list[int] = []
    for _ in range(k):
        gain = _gains(jac, jac_t, np.linalg.inv(info))
        gain[chosen] = -np.inf
        c = int(np.argmax(gain))
        chosen.append(c)
        info = info + jac[c].T @ jac[c]
    for _ in range(max_passes):                 # Fedorov exchange
        improved = False
        for pos in range(k):
            i = chosen[pos]
            rest = info - jac[i].T @ jac[i]
            inv = np.linalg.inv(rest)
            gain = _gains(jac, jac_t, inv)
            gain[chosen] = -np.inf
            c = int(np.argmax(gain))
            own = np.linalg.slogdet(np.eye(m) + jac[i] @ inv @ jac[i].T)[1]
            if gain[c] > own + 1e-9:
                chosen[pos] = c
                info = rest + jac[c].T @ jac[c]
                improved = True
        if not improved:
            break
    return np.array(chosen)


def _cond(jac: np.ndarray, rows: Iterable[int]) -> float:
    a = normalised(jac[list(rows)].reshape(-1, jac.shape[2]))[0]
    s = np.linalg.svd(a, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else np.inf


def _min_cond(jac: np.ndarray, k: int, rng: np.random.Generator, subset: int = 300
              ) -> np.ndarray:
    n, m, r = jac.shape
    start = min(k, -(-r // m) + 1)
    chosen = list(_d_optimal(jac, start, max_passes=0))
    while len(chosen) < k:
        pool = np.setdiff1d(np.arange(n), chosen)
        pool = rng.choice(pool, size=min(subset, pool.size), replace=False)
        values = [_cond(jac, chosen + [int(c)]) for c in pool]
        chosen.append(int(pool[int(np.argmin(values))]))
    return np.array(chosen)


def select_poses(model: RobotModel, k: int, frame: str | None = None, kind: str = "pose",
                 parameters: str | Iterable[str] = "all", *, candidates: object = None,
                 n_candidates: int = 2000, criterion: str = "d-opt",
                 limits: ExcitationLimits | None = None, workspace: CartesianBox | None = None,
                 floor: FloorPlane | None = None, sphere: KeepOutSphere | None = None,
                 sigma: object = None, anchor: object = None, seed: int = 0) -> PoseSelection:
    """The ``k`` most informative configurations for calibrating ``model`` (module docstring).

    Parameters
    ----------
    model, frame, kind, parameters : as :func:`consistid.kinematics.calibrate_kinematics`
        (``kind`` ``"position"``, ``"pose"`` or ``"distance"``).
    k : number of configurations to choose.
    candidates : (M, nv) configurations to choose from (default ``n_candidates`` uniform within
        the joint limits, seeded by ``seed``); infeasible ones are dropped.
    criterion : ``"d-opt"`` (default) or ``"cond"``.
    limits : an :class:`~consistid.excitation.ExcitationLimits` (default: the URDF's joint
        and effort limits); ``workspace``, ``floor``, ``sphere`` are added to it (for the
        measured frame unless they name frames).
    sigma : measurement noise as in ``calibrate_kinematics`` (for ``predicted_std``; default
        0.1 mm and 1 mrad).
    anchor : the anchor point for ``kind="distance"`` (base frame, m; required then).

    Raises
    ------
    PoorExcitationError : fewer feasible candidates than ``k``, or ``k`` too small to identify
        the parameters.
    """
    model = require_model(model)
    check_option("kind", kind, tuple(KINDS))
    check_option("criterion", criterion, CRITERIA)
    k = int(check_number("k", k, 1, integer=True))
    n_candidates = int(check_number("n_candidates", n_candidates, 1, integer=True))
    frame = end_effector_frame(model) if frame is None else frame
    chart = KinematicParameters(model, frame, kind)
    sel = chart.select(parameters)
    m = len(COMPONENTS[kind])
    rng = np.random.default_rng(seed)
    if candidates is None:
        offered = random_configurations(model, n_candidates, rng)
    else:
        offered = joint_coordinates(model, candidates)
    lim = limits if limits is not None else ExcitationLimits.from_model(model)
    if not isinstance(lim, ExcitationLimits):
        raise OptionError(f"limits must be an ExcitationLimits, got {type(lim).__name__}")
    extra = {}
    for key, value in (("workspace", workspace), ("floor", floor), ("sphere", sphere)):
        if value is not None:
            extra[key] = value if value.frames else type(value)(**{
                **{f: getattr(value, f) for f in value.__dataclass_fields__}, "frames": (frame,)})
    if extra:
        lim = ExcitationLimits(**{**{f: getattr(lim, f) for f in lim.__dataclass_fields__},
                                  **extra})
    ok = _feasible(model, offered, lim)
    cand = offered[ok]
    if cand.shape[0] < k:
        raise PoorExcitationError(f"only {cand.shape[0]} of {offered.shape[0]} candidate "
                                  f"configurations respect the limits; need k = {k} (offer more "
                                  "candidates or relax the workspace)")
    anchor_a = None
    if kind == "distance":
        if anchor is None:
            raise OptionError("kind='distance' needs anchor=(x, y, z) (base frame, m)")
        anchor_a = np.asarray(anchor, dtype=float)
    default = {"position": 1e-4, "distance": 1e-4, "pose": (1e-4, 1e-3)}[kind]
    cov = noise_covariance(kind, default if sigma is None else sigma, 1)
    if cov.shape[0] != 1:
        raise DatasetError("sigma for select_poses is one covariance for every pose")
    jac_all = candidate_jacobians(chart, cand, sel, cov, anchor_a)
    order = chart.priority(sel)
    nominal = candidate_jacobians(chart, cand[:200], sel, cov, anchor_a, np.zeros(chart.size))
    kept = structural_selection(nominal.reshape(-1, sel.size),
                                jac_all[:200].reshape(-1, sel.size), order)
    jac = jac_all[:, :, kept]
    r = int(kept.sum())
    if k * m < r:
        raise PoorExcitationError(f"k = {k} {kind} measurements give {k * m} residuals for {r} "
                                  f"identifiable parameters; choose k ≥ {-(-r // m)}")
    idx = (_d_optimal(jac, k) if criterion == "d-opt" else _min_cond(jac, k, rng))
    info = np.einsum("nji,njk->ik", jac[idx], jac[idx])
    names = tuple(chart.names[i] for i in sel[kept])
    with np.errstate(invalid="ignore"):
        std = np.sqrt(np.diag(np.linalg.pinv(info)))
    return PoseSelection(cand[idx], idx, cand, offered.shape[0], criterion, _logdet(info),
                         _cond(jac, idx), names, std, tuple(chart.units(n) for n in names))
