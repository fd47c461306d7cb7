r"""Payload estimation: the 10 inertial parameters of a tool or load on the last link.

Rule of change (Gaz & De Luca, "Payload estimation based on identified coefficients of robot
dynamics — with an application to collision detection", IROS 2017, pp. 3033–3040; Robotics 2
lecture notes in consistid's seeds): a payload rigidly
attached to body ``n`` only adds to that body's standard parameters, expressed in the same frame,

.. math::  \pi_n \;\to\; \pi_n + \pi_L, \qquad
           \tau_L = \tau + Y_n(q, \dot q, \ddot q)\, A\, \pi_L, \qquad
           \beta_L = \beta + B_{[:, n]}\, A\, \pi_L ,

where ``Y_n`` are body ``n``'s ten regressor columns, ``B_{[:, n]}`` the matching columns of the
base map and ``A`` the (linear) change of frame from the payload frame (e.g. the flange) to the
joint frame of body ``n`` (:func:`frame_transform`). Hence two routes, both linear in ``π_L``:

1. :func:`estimate_payload` with a loaded :class:`~consistid.Dataset` and an identified robot:
   fit ``π_L`` to the torque difference ``τ_measured − τ̂_robot``;
2. :func:`payload_from_base_change` (or :func:`estimate_payload` with a loaded
   :class:`~consistid.IdentificationResult`): fit ``π_L`` to the change of base coefficients.

Both solve a weighted least-squares problem under ``J(π_L) ⪰ 0`` (optionally the payload inside
an ellipsoid, its CoM in a box, mass bounds) by one SDP, report which payload parameters the
information determines (``B_{[:, n]}A`` or ``Y_n A`` may be rank deficient, e.g. on a planar arm),
and give standard deviations of the unconstrained weighted fit, ``(AᵀY_nᵀΣ⁻¹Y_nA)⁻¹`` (route 1:
plus the propagated uncertainty of the identified robot, :func:`_robot_covariance`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Sequence

import cvxpy as cp
import numpy as np
import scipy.stats

from ..identification.base import BaseParameters, random_states
from ..identification.compression import CompressedProblem, floor_sigma, joint_sigma
from ..identification.solver import DEFAULT_SOLVER, solve
from ..robot.shapes import Ellipsoid
from ..identification.constraints import (BodyScaling, com_box, ellipsoid_lmi, mass_bounds,
                          pseudo_inertia_lmi)
from ..data.checks import check_effort
from ..data.dataset import Dataset
from ..errors import (BoundActiveWarning, IdentificationError, InfeasibleError, ModelError,
                     ModelMisfitWarning, NothingFoundWarning,
                     OptionError, PoorExcitationError, PoorExcitationWarning, check_bounds,
                     check_box, check_option)
from ..report.html import Page
from ..report.result import Reported
from ..robot.model import RobotModel, require_model
from ..robot.inertia import (INERTIAL_NAMES, body_slice, from_mass_com_inertia, pseudo_inertia,
                             to_mass_com_inertia)
from ..identification.regressor import FrictionArg, matching_settings, regressor, resolve_spec
from ..identification.result import IdentificationResult
from ..identification.solver import SolverReport
from ..identification.streaming import DataStream, as_stream, compress_data, is_stream

#: A payload direction is unidentified when its singular value of the column-normalised payload
#: regressor is below this fraction of the largest (looser than identify's numerical rank
#: tolerance: a payload direction seen this weakly is not worth reporting as determined).
IDENTIFIABLE_RTOL = 1e-6
#: Reference size used only to scale the SDP (m): a payload is about this big.
REFERENCE_RADIUS = 0.1


@dataclass(frozen=True, eq=False)
class Payload(Reported):
    """An estimated payload, expressed in ``frame``.

    Attributes
    ----------
    parameters : (10,) ``[m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` in ``frame``,
        inertia about the frame origin (Pinocchio order).
    covariance : (10, 10) covariance of the unconstrained weighted fit (``inf`` on the diagonal
        of parameters the data do not determine).
    frame, body : the frame the parameters are expressed in, and the body it is fixed to.
    method : ``"torque"`` (route 1) or ``"base-change"`` (route 2).
    identifiable : (10,) whether each parameter is determined by the information used.
    unidentified : readable combinations of parameters that the information does not determine.
    rank : rank of the payload regressor (``B_{[:, n]}A`` for route 2), out of 10.
    condition_number : of the column-normalised, weighted payload regressor (its identifiable
        part).
    min_eigenvalue : smallest eigenvalue of the payload's pseudo-inertia (kg·m² or kg).
    solver : the SDP's report.
    n_samples : samples used (route 1), else ``None``.
    residual_rms : (nv,) per-joint RMS of the torque fit (route 1), else ``None``.
    notes : what the user should know (identifiability, minimum number of states …).
    found : ``False`` when the mass is within :data:`NO_PAYLOAD_SIGMAS` standard deviations of
        0: no payload detected (a :class:`~consistid.errors.NothingFoundWarning` and a note say
        so; ``com``, ``inertia`` and ``com_std`` are then NaN, being undefined).
    """

    parameters: np.ndarray
    covariance: np.ndarray
    frame: str
    body: str
    method: str
    identifiable: tuple[bool, ...]
    unidentified: tuple[str, ...]
    rank: int
    condition_number: float
    min_eigenvalue: float
    solver: SolverReport
    n_samples: int | None = None
    residual_rms: np.ndarray | None = None
    notes: tuple[str, ...] = ()
    details: dict[str, Any] = field(default_factory=dict)
    found: bool = True

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(f"payload.{n}" for n in INERTIAL_NAMES)

    @property
    def mass(self) -> float:
        return float(self.parameters[0])

    @property
    def com(self) -> np.ndarray:
        """Centre of mass in ``frame`` (m); ``nan`` for a zero mass or no payload found."""
        if not (self.mass > 0 and self.found):
            return np.full(3, np.nan)
        return self.parameters[1:4] / self.mass

    @property
    def inertia(self) -> np.ndarray:
        """3×3 rotational inertia about the CoM, axes of ``frame`` (kg·m²); NaN when no payload
        was found (:attr:`found`)."""
        if not (self.mass > 0 and self.found):
            return np.full((3, 3), np.nan)
        return to_mass_com_inertia(self.parameters)[2]

    @cached_property
    def std(self) -> np.ndarray:
        """(10,) standard deviations of ``parameters`` (``inf`` where not identifiable)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def mass_std(self) -> float:
        return float(self.std[0])

    @cached_property
    def com_std(self) -> np.ndarray:
        r"""(3,) standard deviations of the CoM by the delta method,
        ``∂c/∂m = −h/m²``, ``∂c/∂h = 1/m``."""
        m, h = self.mass, self.parameters[1:4]
        if not (m > 0 and self.found):
            return np.full(3, np.nan)
        jac = np.zeros((3, 10))
        jac[:, 0] = -h / m ** 2
        jac[:, 1:4] = np.eye(3) / m
        out = np.empty(3)
        for i in range(3):
            # only the parameters c_i depends on: a 0 × inf term of an undetermined moment on
            # another axis (a planar arm's m·c_z) must not make c_x undetermined too
            used = np.flatnonzero(jac[i])
            block = self.covariance[np.ix_(used, used)]
            if not np.all(np.isfinite(np.diag(block))):
                out[i] = np.inf        # an undetermined moment leaves c_i undetermined
                continue
            var = float(jac[i, used] @ np.nan_to_num(block, nan=0.0) @ jac[i, used])
            out[i] = np.sqrt(max(var, 0.0))
        return out

    def summary(self) -> str:
        from ..identification.summary import table

        rows = [(n, v, s, "yes" if ok else "no")
                for n, v, s, ok in zip(self.parameter_names, self.parameters, self.std,
                                       self.identifiable)]
        com = np.array2string(self.com, precision=4)
        lines = [f"payload on {self.body!r} in frame {self.frame!r} (method={self.method}, "
                 f"rank {self.rank}/10, cond {self.condition_number:.3g})",
                 f"solver        {self.solver}",
                 f"mass          {self.mass:.4g} ± {self.mass_std:.2g} kg",
                 f"CoM           {com} m ± [{' '.join(f'{v:.2g}' for v in self.com_std)}]",
                 "", table(["parameter", "estimate", "± std", "identifiable"], rows)]
        if self.residual_rms is not None:
            lines.append(f"\nresidual RMS per joint [N·m]: "
                         f"{np.array2string(self.residual_rms, precision=3)}")
        notes = [f"pseudo-inertia min eigenvalue {self.min_eigenvalue:.3g}", *self.notes]
        return "\n".join(lines + ["", "Notes:"] + [f"  - {n}" for n in notes])

    @property
    def estimate(self) -> np.ndarray:
        """The estimated vector: the ten ``parameters``; ``std``, ``covariance``, ``conf_int``
        are its."""
        return self.parameters

    def page(self) -> Page:
        """The HTML report: mass and CoM ± σ, the ten parameters with 95 % intervals."""
        verdict = (f"payload on {self.body!r}: {self.mass:.4g} ± {self.mass_std:.2g} kg"
                   if self.found else f"no payload found on {self.body!r}")
        page = Page(f"consistid payload: {self.body}", verdict)
        page.key_values([("method", self.method), ("frame", self.frame),
                         ("rank / 10", self.rank), ("condition number", self.condition_number),
                         ("solver", str(self.solver)),
                         ("pseudo-inertia min eigenvalue", self.min_eigenvalue)])
        ci = self.conf_int()
        page.table(["parameter", "estimate", "± σ", "95 % interval", "identifiable"],
                   [(n, v, s, f"{lo:.4g} … {hi:.4g}", "yes" if ok else "no")
                    for n, v, s, (lo, hi), ok in zip(self.parameter_names, self.parameters,
                                                     self.std, ci, self.identifiable)])
        page.bullets(self.notes)
        return page

    def __str__(self) -> str:
        return self.summary()


#: A payload whose mass is not above this many standard deviations is reported as not found.
NO_PAYLOAD_SIGMAS = 3.0
#: False-alarm probability of the test that a change of coefficients is a payload at all
#: (:func:`payload_from_base_change`: the unconstrained payload's weighted misfit against
#: χ²(b − rank)).
MISFIT_ALPHA = 1e-3


# ------------------------------------------------------------------------------- frames
def frame_transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    r"""The (10, 10) matrix ``A`` with ``π_body = A π_frame`` for a frame at ``(R, p)`` in the
    body frame.

    With ``h_r = R h``:

    .. math::  m' = m,\quad h' = R h + m p,\quad
               I' = R I R^\top + m(\|p\|^2 1 - p p^\top)
                    + 2 (p^\top h_r) 1 - p h_r^\top - h_r p^\top

    (substitute ``r = p + R s`` in ``I = Σ m_k(‖r‖²1 − r rᵀ)``). Linear, valid for any
    10-vector (no mass needed, unlike ``pinocchio.Inertia.se3Action``).
    """
    R = np.asarray(rotation, dtype=float)
    p = np.asarray(translation, dtype=float)
    out = np.empty((10, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        m, h = e[0], e[1:4]
        inertia = np.array([[e[4], e[5], e[7]], [e[5], e[6], e[8]], [e[7], e[8], e[9]]])
        hr = R @ h
        i_new = (R @ inertia @ R.T + m * (p @ p * np.eye(3) - np.outer(p, p))
                 + 2.0 * (p @ hr) * np.eye(3) - np.outer(p, hr) - np.outer(hr, p))
        out[:, k] = [m, *(hr + m * p), i_new[0, 0], i_new[0, 1], i_new[1, 1], i_new[0, 2],
                     i_new[1, 2], i_new[2, 2]]
    return out


def _resolve_frame(model: RobotModel, frame: str | None, body: str | None
                   ) -> tuple[int, str, np.ndarray]:
    """``(body index, frame name, A)`` for the payload frame (default: last body's frame)."""
    pm = model.pin_model
    if body is not None:
        check_option("body", body, model.body_names)
        index = model.body_names.index(body)
    else:
        index = None
    if frame is None:
        index = model.n_bodies - 1 if index is None else index
        return index, model.body_names[index], np.eye(10)
    if not pm.existFrame(frame):
        attached = [f.name for f in pm.frames if f.parentJoint == pm.njoints - 1]
        raise ModelError(f"unknown frame {frame!r} in {model.name}; frames on the last body: "
                         f"{attached}")
    f = pm.frames[pm.getFrameId(frame)]
    if f.parentJoint == 0:
        raise ModelError(f"frame {frame!r} is fixed to the robot base, not to a moving body")
    if index is not None and f.parentJoint != index + 1:
        raise ModelError(f"frame {frame!r} belongs to body {model.body_names[f.parentJoint - 1]!r},"
                         f" not {body!r}")
    index = f.parentJoint - 1
    return index, frame, frame_transform(f.placement.rotation, f.placement.translation)


# ------------------------------------------------------------------------------- identifiability
def _identifiability(y: np.ndarray) -> tuple[int, float, np.ndarray, tuple[bool, ...],
                                               tuple[str, ...]]:
    """Rank, condition, null-space basis (columns), identifiable flags and named directions of a
    payload regressor ``y`` (any rows × 10), decided on normalised columns."""
    norms = np.linalg.norm(y, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    _, s, vt = np.linalg.svd(y / scale, full_matrices=True)
    s_full = np.zeros(10)
    s_full[: s.size] = s
    keep = s_full > IDENTIFIABLE_RTOL * max(s_full[0], 1e-300)
    rank = int(keep.sum())
    cond = float(s_full[0] / s_full[rank - 1]) if rank else float("inf")
    null = vt[~keep].T / scale[:, None]            # back to unnormalised parameters
    if null.size:
        null, _ = np.linalg.qr(null)
    flags = tuple(bool(np.linalg.norm(null[k]) < 1e-6) if null.size else True for k in range(10))
    names = []
    for v in null.T:
        top = np.argsort(-np.abs(v))[:3]
        names.append(" + ".join(f"{v[i] / v[top[0]]:.3g}·payload.{INERTIAL_NAMES[i]}"
                                for i in top if abs(v[i]) > 1e-6 * abs(v[top[0]])))
    return rank, cond, null, flags, tuple(names)


def minimum_states(model: RobotModel, body: int, transform: np.ndarray, seed: int = 0
                   ) -> tuple[int, int, int, int]:
    """Generic identifiability of a payload on ``body``: ``(rank, states, static_rank,
    static_states)``.

    ``rank`` is the largest rank of the payload regressor ``Y_n A`` over random states and
    ``states`` the fewest random (q, q̇, q̈) samples that reach it; ``static_*`` the same for
    static configurations (q̇ = q̈ = 0, which see only ``m`` and ``m·c``). Real trajectories need
    more samples than these lower bounds (noise, correlated samples).
    """
    rng = np.random.default_rng(seed)
    cols = body_slice(body)
    q, dq, ddq = random_states(model, 12, rng)
    out = []
    for static in (False, True):
        v, a = (np.zeros_like(dq), np.zeros_like(ddq)) if static else (dq, ddq)
        y = regressor(model, q, v, a).reshape(12, model.nv, -1)[:, :, cols] @ transform
        ranks = [np.linalg.matrix_rank(y[:k].reshape(-1, 10) / np.maximum(
            np.linalg.norm(y.reshape(-1, 10), axis=0), 1e-300), tol=None) for k in range(1, 13)]
        best = max(ranks)
        out += [int(best), ranks.index(best) + 1]
    return out[0], out[1], out[2], out[3]


# ------------------------------------------------------------------------------- the SDP
def _reference(m_hat: float, ellipsoid: Ellipsoid | None) -> np.ndarray:
    """A solid sphere (or the ellipsoid, filled) used only to scale the SDP."""
    mass = max(abs(m_hat), 1e-2)
    if ellipsoid is not None:
        shape, c = ellipsoid.shape, ellipsoid.center
        inertia_c = mass / 5.0 * (np.trace(shape) * np.eye(3) - shape)
        return from_mass_com_inertia(mass, c, inertia_c)
    return from_mass_com_inertia(mass, np.zeros(3), 0.4 * mass * REFERENCE_RADIUS ** 2 * np.eye(3))


def _check_payload_options(frame: object, body: object, ellipsoid: object, com_bounds: object,
                           mass_range: object) -> None:
    """Types and shapes of the payload options, each error naming its option."""
    for name, value in (("frame", frame), ("body", body)):
        if value is not None and not isinstance(value, str):
            raise OptionError(f"{name} must be a frame/body name (str) or None, got {value!r}")
    if ellipsoid is not None and not isinstance(ellipsoid, Ellipsoid):
        raise OptionError(f"ellipsoid must be a consistid.Ellipsoid, got {ellipsoid!r}")
    if com_bounds is not None:
        check_box("com_bounds", com_bounds)
    if mass_range is not None:
        lo, hi = check_bounds("mass_range", mass_range)
        if lo is not None and hi is not None and lo > hi:
            raise OptionError(f"mass_range = {tuple(mass_range)!r}: lower bound above the upper")
        if hi is not None and hi < 0:
            raise OptionError(f"mass_range = {tuple(mass_range)!r}: a payload mass is ≥ 0 kg")


def _solve_payload(r: np.ndarray, z: np.ndarray, null: np.ndarray, what: str,
                   ellipsoid: Ellipsoid | None, box: tuple[Sequence[float], Sequence[float]] | None,
                   mass_range: tuple[float | None, float | None] | None, solver: str,
                   options: dict[str, Any] | None
                   ) -> tuple[np.ndarray, SolverReport, str | None]:
    """``min ‖r θ − z‖²`` s.t. ``J(θ) ⪰ 0`` and the optional payload constraints; directions in
    ``null`` (not determined by ``r``) are pulled to zero (the most compact payload)."""
    theta_ls = np.linalg.lstsq(r, z, rcond=None)[0]
    scaling = BodyScaling.from_reference(_reference(theta_ls[0], ellipsoid))
    x = cp.Variable(10)
    # ellipsoid_lmi carries J ⪰ 0 itself (a duplicated cone makes the dual degenerate).
    constraints: list[cp.Constraint] = (ellipsoid_lmi(x, ellipsoid, 0.0, scaling)
                                        if ellipsoid is not None
                                        else pseudo_inertia_lmi(x, 0.0, scaling))
    if box is not None:
        constraints += com_box(x, box[0], box[1])
    if mass_range is not None:
        constraints += mass_bounds(x, *mass_range)
    objective = cp.sum_squares(r @ x - z)
    if null.size:
        # ‖(scaled) null-space component‖²: does not change the fit, fixes what it leaves free.
        objective = objective + cp.sum_squares(null.T @ x / np.linalg.norm(null, axis=0))
    try:
        report = solve(cp.Problem(cp.Minimize(objective), constraints), what, solver, options)
    except InfeasibleError as exc:
        raise _infeasible_options(exc, r, z, null, ellipsoid, box, mass_range, solver,
                                  options) from exc
    theta = np.asarray(x.value, dtype=float)
    note = (_bounds_decide(theta, r, z, null, ellipsoid, box, mass_range, solver, options)
            if box is not None or mass_range is not None else None)
    return theta, report, note


def _bounds_decide(theta: np.ndarray, r: np.ndarray, z: np.ndarray, null: np.ndarray,
                   ellipsoid: Ellipsoid | None, box: tuple | None, mass_range: tuple | None,
                   solver: str, options: dict[str, Any] | None) -> str | None:
    r"""Warn (and return the note) when ``mass_range``/``com_bounds`` decide the estimate.

    Likelihood-ratio test on the whitened problem: the bounds raise ``‖r θ − z‖²`` above the
    fit with ``J ⪰ 0`` alone by ``Δχ² > 3²`` (one parameter moved by more than 3 σ, the
    threshold of "no payload found"), i.e. the data alone put the payload outside the bounds.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            free, _, _ = _solve_payload(r, z, null, "payload (without bounds)", ellipsoid, None,
                                        None, solver, options)
    except IdentificationError:
        return None
    delta = float(np.sum((r @ theta - z) ** 2) - np.sum((r @ free - z) ** 2))
    if delta <= NO_PAYLOAD_SIGMAS ** 2:
        return None
    given = [f"{name} = {tuple(tuple(v) if np.ndim(v) else v for v in value)!r}"
             for name, value in (("mass_range", mass_range), ("com_bounds", box))
             if value is not None]
    com = (f", CoM {np.array2string(free[1:4] / free[0], precision=4)} m" if free[0] > 0
           else "")
    verb = "decide" if len(given) > 1 else "decides"
    text = (f"{' and '.join(given)} {verb} the payload: the data alone (J ⪰ 0) give "
            f"{free[0]:.4g} kg{com}, and the bounds cost Δχ² = {delta:.3g} > "
            f"{NO_PAYLOAD_SIGMAS ** 2:g} ({NO_PAYLOAD_SIGMAS:g} σ). The estimate sits on the "
            "bound, not where the data put it: check the bounds, the frame and the body")
    warnings.warn(text, BoundActiveWarning, stacklevel=4)
    return text


def _infeasible_options(exc: InfeasibleError, r: np.ndarray, z: np.ndarray, null: np.ndarray,
                        ellipsoid: Ellipsoid | None, box: tuple | None, mass_range: tuple | None,
                        solver: str, options: dict[str, Any] | None) -> InfeasibleError:
    """Which option made the payload problem infeasible: each given one is dropped in turn
    (``mass_range``, ``com_bounds``, ``ellipsoid``); the first whose removal makes the problem
    feasible is named, with the mass the other constraints then give."""
    given = {"mass_range": mass_range, "com_bounds": box, "ellipsoid": ellipsoid}
    for name in [k for k, v in given.items() if v is not None]:
        kept = {k: (None if k == name else v) for k, v in given.items()}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                theta, _, _ = _solve_payload(r, z, null, "payload (diagnosis)", kept["ellipsoid"],
                                          kept["com_bounds"], kept["mass_range"], solver,
                                          options)
        except IdentificationError:
            continue
        shown = repr(tuple(given[name])) if name != "ellipsoid" else "the given ellipsoid"
        com = (f"CoM {np.array2string(theta[1:4] / theta[0], precision=4)} m" if theta[0] > 0
               else "no CoM")
        return InfeasibleError(
            f"{exc}: {name} = {shown} is what admits no payload: without it the other "
            f"constraints give a mass of {theta[0]:.4g} kg ({com}). Widen or drop {name}")
    if len([v for v in given.values() if v is not None]) > 0:
        return InfeasibleError(f"{exc}: no single option explains it; the given "
                               f"{[k for k, v in given.items() if v is not None]} together "
                               "admit no payload consistent with J ⪰ 0")
    return exc


def _covariance(r: np.ndarray, identifiable_null: np.ndarray) -> np.ndarray:
    """``(rᵀr)⁻¹`` on the identifiable subspace, ``inf`` variance along unidentified ones."""
    cov = np.linalg.pinv(r.T @ r, rcond=1e-12, hermitian=True)
    if identifiable_null.size:
        touched = np.linalg.norm(identifiable_null, axis=1) > 1e-6
        cov[touched, :] = np.nan
        cov[:, touched] = np.nan
        cov[touched, touched] = np.inf
    return cov


def _notes(model: RobotModel, index: int, transform: np.ndarray, rank: int,
           unidentified: tuple[str, ...], route: str) -> tuple[list[str], bool]:
    generic, states, static_rank, static_states = minimum_states(model, index, transform)
    notes = []
    short = rank < generic
    if unidentified:
        notes.append(f"{10 - rank} payload direction(s) not determined by the {route}: "
                     + "; ".join(unidentified) + " (set to the most compact payload; std = inf)")
    if short:
        notes.append(f"the {route} reach rank {rank}, the robot allows {generic}: at least "
                     f"{states} generic (q, q̇, q̈) states are needed (a lower bound; use a "
                     f"longer, richer excitation). Static configurations identify only m and m·c "
                     f"(rank {static_rank}, from ≥ {static_states} configurations)")
    elif generic < 10:
        notes.append(f"this robot's motion determines only {generic} of the 10 payload "
                     "parameters on this body, whatever the data")
    return notes, short


def _payload_result(theta: np.ndarray, cov: np.ndarray, frame: str, body: str, method: str,
                    ident: tuple, report: SolverReport, notes: list[str], **extra: Any
                    ) -> Payload:
    rank, cond, _, flags, names = ident
    mass = float(theta[0])
    mass_std = float(np.sqrt(max(cov[0, 0], 0.0))) if np.isfinite(cov[0, 0]) else np.inf
    found = bool(mass > NO_PAYLOAD_SIGMAS * mass_std)
    if not found and not np.isfinite(mass_std):
        text = (f"payload mass not determined: these data do not fix the mass of a payload on "
                f"{body!r} (σ = inf; the value {mass:.3g} kg is the most compact one, not a "
                "measurement), so found = False means 'cannot tell', not 'no payload'; its "
                "centre of mass and inertia are undefined (NaN). The notes say which "
                "directions the data, or the robot's structure, leave free")
        notes = [text, *notes]
        warnings.warn(text, NothingFoundWarning, stacklevel=3)
    elif not found:
        text = (f"no payload found: the mass {mass:.3g} ± {mass_std:.2g} kg is within "
                 f"{NO_PAYLOAD_SIGMAS:g} σ of 0, so the data carry no detectable payload on "
                 f"{body!r}; its centre of mass and inertia are undefined (NaN). Check that the "
                 "loaded data were recorded with the payload mounted, on that body")
        notes = [text, *notes]
        warnings.warn(text, NothingFoundWarning, stacklevel=3)
    return Payload(parameters=theta, covariance=cov, frame=frame, body=body, method=method,
                   identifiable=flags, unidentified=names, rank=rank, condition_number=cond,
                   min_eigenvalue=float(np.linalg.eigvalsh(pseudo_inertia(theta))[0]),
                   solver=report, notes=tuple(notes), found=found, **extra)


# ------------------------------------------------------------------------------- route 1
def estimate_payload(model: RobotModel, loaded: Dataset | DataStream | IdentificationResult,
                     robot: IdentificationResult | np.ndarray, *, frame: str | None = None,
                     body: str | None = None, friction: FrictionArg | str = "auto",
                     armature: bool | Sequence[int | str] | str = "auto",
                     ellipsoid: Ellipsoid | None = None,
                     com_bounds: tuple[Sequence[float], Sequence[float]] | None = None,
                     mass_range: tuple[float | None, float | None] | None = None,
                     solver: str = DEFAULT_SOLVER,
                     solver_options: dict[str, Any] | None = None) -> Payload:
    r"""Estimate a payload's 10 inertial parameters, physically consistent.

    Route 1 (``loaded`` a :class:`Dataset` recorded with the payload mounted): with the robot's
    prediction ``τ̂ = Y π_robot`` (friction included), fit

    .. math:: \min_{\pi_L} \sum_j \sigma_j^{-2} \|Y_{n,j} A \pi_L - (\tau_j - \hat\tau_j)\|^2
              \quad\text{s.t.}\quad J(\pi_L) \succeq 0 \;[\,\text{ellipsoid, CoM box, mass}\,]

    with per-joint noise ``σ_j`` estimated from the unconstrained fit's residuals.
    Route 2 (``loaded`` an :class:`IdentificationResult` of the loaded robot, ``robot`` that of
    the unloaded one): see :func:`payload_from_base_change`.

    Parameters
    ----------
    model : the robot.
    loaded : loaded recording (route 1), or a stream of them (files, a generator: read one at
        a time, :mod:`consistid.identification.streaming`), or loaded identification (route 2).
    robot : the identified unloaded robot: an :class:`IdentificationResult`, or (route 1) its
        standard parameter vector (10 per body, then the columns of ``friction``/``armature``).
    frame : the frame the payload parameters are expressed in (a Pinocchio frame fixed to the
        last body, e.g. the flange ``"panda_link8"``); default the last body's joint frame.
    body : the body carrying the payload; default the frame's body, else the last one.
    friction, armature : the per-joint columns of a ``robot`` vector; ``"auto"`` (default):
        ``identify``'s default (Coulomb, viscous, offset; no armature), or the columns of a
        ``robot`` result, which an explicit value must then describe
        (:func:`consistid.identification.regressor.resolve_spec`).
    ellipsoid : the payload lies in this ellipsoid (in ``frame``).
    com_bounds : ``(lower, upper)`` box on the CoM (in ``frame``, m).
    mass_range : ``(lower, upper)`` kg, either may be ``None``.

    Returns
    -------
    Payload

    Raises
    ------
    PoorExcitationError : fewer equations than 10; a :class:`PoorExcitationWarning` (and notes)
        when the data do not determine every parameter the robot's motion could.
    InfeasibleError : the constraints (e.g. ellipsoid and mass bounds) admit no payload.
    """
    require_model(model)
    _check_payload_options(frame, body, ellipsoid, com_bounds, mass_range)
    if isinstance(loaded, IdentificationResult):
        if not isinstance(robot, IdentificationResult):
            raise OptionError("route 2 (loaded identification) needs robot= the unloaded "
                              "IdentificationResult")
        resolve_spec(model, friction, armature, given=robot.spec)  # refuses other columns
        return payload_from_base_change(model, robot, loaded, frame=frame, body=body,
                                        ellipsoid=ellipsoid, com_bounds=com_bounds,
                                        mass_range=mass_range, solver=solver,
                                        solver_options=solver_options)
    if is_stream(loaded):  # files or a generator, read one at a time (joints checked per part)
        loaded = as_stream(loaded)
    elif not isinstance(loaded, Dataset):
        raise OptionError(f"loaded must be a Dataset, a stream of them (files, a generator) or "
                          f"an IdentificationResult, got {type(loaded).__name__}")
    else:
        loaded.check_joints(model.nv, model.joint_names)
        loaded.require_torque()
        # torques no motor of this robot can give (a payload beyond its rating, or mN·m): the
        # estimate is then of a load that was never carried as logged. Only this of identify's
        # checks: static poses (a payload's m, m·c) legitimately leave a joint without torque
        check_effort(loaded, model.limits.effort, model.joint_names, stacklevel=3)
    if isinstance(robot, IdentificationResult):
        spec = resolve_spec(model, friction, armature, given=robot.spec)
        theta = robot.parameters
        if not np.allclose(robot.model.gravity, model.gravity):
            raise ModelError(f"robot was identified with gravity {robot.model.gravity} but model "
                             f"has {model.gravity} (e.g. a tilt from estimate_mounting): pass "
                             "robot.model as model")
    else:
        spec = resolve_spec(model, friction, armature)
        theta = np.asarray(robot, dtype=float)
        expected = model.n_inertial + spec.n_joint_columns
        if theta.shape != (expected,):
            raise ModelError(f"robot parameters have shape {theta.shape}; {model.name} with "
                             f"{spec.describe()} needs ({expected},). "
                             f"{_matching_settings(model, theta.size - model.n_inertial)}")
    index, frame_name, transform = _resolve_frame(model, frame, body)
    measured = compress_data(model, loaded, spec)
    problem = measured.minus(theta)                     # what the robot leaves: τ − Y θ
    n = problem.n_samples
    if n * model.nv <= 10:
        raise PoorExcitationError(f"{n} samples × {model.nv} joints give {n * model.nv} "
                                  "equations for 10 payload parameters")
    cols = np.r_[body_slice(index)]
    # Per-joint noise from the unconstrained fit, then the weighted problem (as identify's WLS).
    r1, z1, _ = problem.stacked(columns=cols)
    theta_ls = np.linalg.lstsq(r1 @ transform, z1, rcond=None)[0]
    sse = problem.sum_squares(transform @ theta_ls, cols)
    # floored at a fraction of the measured torque's RMS (floor_sigma, as identify does):
    # noise-free data fit to round-off, and 1/σ would blow the weights up to ~1e16
    sigma = floor_sigma(joint_sigma(sse, n, 10), measured)
    r, z, _ = problem.stacked(sigma=sigma, columns=cols)
    r = r @ transform
    ident = _identifiability(r)
    notes, short = _notes(model, index, transform, ident[0], ident[4], "data")
    if short:
        warnings.warn("payload: " + notes[-1], PoorExcitationWarning, stacklevel=2)
    theta, report, bound_note = _solve_payload(r, z, ident[2], "payload estimation (torque)",
                                               ellipsoid, com_bounds, mass_range, solver,
                                               solver_options)
    if bound_note is not None:
        notes.insert(0, bound_note)
    rms = np.sqrt(problem.sum_squares(transform @ theta, cols) / n)
    cov = _covariance(r, ident[2])
    if isinstance(robot, IdentificationResult):
        cov = cov + _robot_covariance(problem, sigma, cols, transform, robot, ident[2])
    else:
        notes.append("the standard deviations do not include the robot model's uncertainty "
                     "(pass robot= an IdentificationResult to include it)")
    return _payload_result(theta, cov, frame_name, model.body_names[index], "torque", ident,
                           report, notes, n_samples=n, residual_rms=rms,
                           details={"sigma": sigma})


def _matching_settings(model: RobotModel, n_joint_columns: int) -> str:
    """Which ``friction``/``armature`` settings give ``n_joint_columns`` per-joint entries."""
    matches = matching_settings(model, lambda spec: spec.n_joint_columns == n_joint_columns)
    if not matches:
        return f"No friction/armature setting gives {n_joint_columns} per-joint entries."
    return ("Settings with that many per-joint entries: " + "; ".join(matches[:4])
            + (" …" if len(matches) > 4 else ""))


def _robot_covariance(problem: CompressedProblem, sigma: np.ndarray, cols: np.ndarray,
                      transform: np.ndarray, robot: IdentificationResult, null: np.ndarray
                      ) -> np.ndarray:
    r"""The payload covariance due to the robot's own estimate, ``M Σ_β Mᵀ``.

    The prediction error ``W_b δβ`` of the unloaded model enters the torque difference, so the
    weighted fit ``θ = G⁻¹ Y_Lᵀ Σ⁻¹ (Δτ)`` moves by ``M δβ`` with
    ``M = (Y_Lᵀ Σ⁻¹ Y_L)⁻¹ Y_Lᵀ Σ⁻¹ W_b`` (both Gram blocks from the compressed factors).
    """
    r, _, _ = problem.stacked(sigma=sigma)
    gram = r.T @ r
    g_ll = transform.T @ gram[np.ix_(cols, cols)] @ transform
    g_lb = transform.T @ gram[np.ix_(cols, robot.base.independent)]
    m = np.linalg.pinv(g_ll, rcond=1e-12, hermitian=True) @ g_lb
    out = m @ robot.base_covariance @ m.T
    if null.size:
        touched = np.linalg.norm(null, axis=1) > 1e-6
        out[touched, :] = 0.0
        out[:, touched] = 0.0
    return out


# ------------------------------------------------------------------------------- route 2
def _as_coefficients(x: IdentificationResult | np.ndarray, cov: np.ndarray | None, name: str
                     ) -> tuple[np.ndarray, np.ndarray | None, BaseParameters | None]:
    if isinstance(x, IdentificationResult):
        return (np.asarray(x.base_parameters, float),
                x.base_covariance if cov is None else np.asarray(cov, float), x.base)
    beta = np.asarray(x, dtype=float)
    if beta.ndim != 1 or not np.all(np.isfinite(beta)):
        raise ModelError(f"{name} coefficients must be a finite 1-D vector, got {beta.shape}")
    return beta, None if cov is None else np.asarray(cov, float), None


def payload_from_base_change(model: RobotModel, unloaded: IdentificationResult | np.ndarray,
                             loaded: IdentificationResult | np.ndarray, *,
                             base: BaseParameters | None = None,
                             covariance_unloaded: np.ndarray | None = None,
                             covariance_loaded: np.ndarray | None = None,
                             frame: str | None = None, body: str | None = None,
                             ellipsoid: Ellipsoid | None = None,
                             com_bounds: tuple[Sequence[float], Sequence[float]] | None = None,
                             mass_range: tuple[float | None, float | None] | None = None,
                             solver: str = DEFAULT_SOLVER,
                             solver_options: dict[str, Any] | None = None) -> Payload:
    r"""Payload from two sets of base coefficients, unloaded and loaded (Gaz & De Luca 2017).

    .. math:: \min_{\pi_L} \|L(B_{[:, n]} A \pi_L - (\hat\beta_L - \hat\beta))\|^2
              \quad\text{s.t.}\quad J(\pi_L) \succeq 0, \qquad L^\top L = (\Sigma + \Sigma_L)^{-1}

    The two identifications are independent experiments, so the covariance of the change is the
    sum. Coefficients from two :class:`IdentificationResult` objects whose base maps chose
    different independent columns are first expressed in the unloaded map,
    ``β_L ← B_u B_l⁺ β_L`` (valid because both maps have the row space of the regressor).

    Parameters
    ----------
    unloaded, loaded : :class:`IdentificationResult` or (b,) coefficient vectors (the covariances
        default to the results'; with none at all the fit is unweighted, with one the other set
        is treated as exact, both noted in ``notes``).
    base : the base map of coefficient vectors (default: that of the other argument if it is a
        result; refused when both are results, whose own maps are used).
    covariance_unloaded, covariance_loaded : (b, b) covariances (default: the results').
    frame, body, ellipsoid, com_bounds, mass_range, solver, solver_options : as in
        :func:`estimate_payload`.

    Returns
    -------
    Payload
        with ``identifiable`` / ``unidentified`` telling which payload parameters the change of
        coefficients determines (all 10 for a 6- or 7-DoF arm; fewer for planar or short chains).
    """
    require_model(model)
    _check_payload_options(frame, body, ellipsoid, com_bounds, mass_range)
    beta_u, cov_u, base_u = _as_coefficients(unloaded, covariance_unloaded, "unloaded")
    beta_l, cov_l, base_l = _as_coefficients(loaded, covariance_loaded, "loaded")
    if base is not None and base_u is not None and base_l is not None:
        raise OptionError("base= is for coefficient vectors; both arguments are "
                          "IdentificationResults, whose own base maps are used")
    base_u, base_l = base_u or base or base_l, base_l or base or base_u
    if base_u is None:
        raise OptionError("coefficient vectors need base= (the BaseParameters they refer to)")
    if base_l is not base_u:
        if tuple(base_l.standard_names) != tuple(base_u.standard_names):
            raise ModelError("the unloaded and loaded identifications used different parameter "
                             "columns (friction/armature specs); use the same spec for both")
        T = base_u.matrix @ np.linalg.pinv(base_l.matrix)
        if not np.allclose(T @ base_l.matrix, base_u.matrix, atol=1e-8):
            raise ModelError("the unloaded and loaded base maps do not span the same space")
        beta_l = T @ beta_l
        cov_l = None if cov_l is None else T @ cov_l @ T.T
    b = base_u.n_base
    if beta_u.shape != (b,) or beta_l.shape != (b,):
        raise ModelError(f"coefficient vectors must have {b} entries (the base map), got "
                         f"{beta_u.shape} and {beta_l.shape}")
    if base_u.n_standard < model.n_inertial or tuple(
            base_u.standard_names[: model.n_inertial]) != tuple(model.parameter_names):
        raise ModelError(f"the base map does not belong to {model.name!r}")
    index, frame_name, transform = _resolve_frame(model, frame, body)
    notes_weight = []
    if cov_u is None and cov_l is None:
        cov = np.eye(b)
        notes_weight.append("no covariances given: the change of coefficients is fitted "
                            "unweighted and the standard deviations assume unit variance")
    else:
        cov = sum(c for c in (cov_u, cov_l) if c is not None)
        if cov_u is None or cov_l is None:
            exact = "unloaded" if cov_u is None else "loaded"
            notes_weight.append(f"only the {'loaded' if cov_u is None else 'unloaded'} "
                                f"coefficients have a covariance: the {exact} ones are treated "
                                "as exact (their uncertainty is in neither the weights nor the "
                                "standard deviations)")
    try:
        weight = np.linalg.inv(np.linalg.cholesky(0.5 * (cov + cov.T)))
    except np.linalg.LinAlgError as exc:
        raise OptionError("the covariance of the coefficient change is not positive definite")\
            from exc
    r = weight @ base_u.matrix[:, body_slice(index)] @ transform
    z = weight @ (beta_l - beta_u)
    ident = _identifiability(r)
    notes, _ = _notes(model, index, transform, ident[0], ident[4], "change of coefficients")
    theta, report, bound_note = _solve_payload(r, z, ident[2],
                                               "payload estimation (base change)", ellipsoid,
                                               com_bounds, mass_range, solver, solver_options)
    if bound_note is not None:
        notes = [bound_note, *notes]
    # whether any payload on this body explains the change: the misfit of the unconstrained
    # least-squares payload (bounds and consistency aside, which warn on their own)
    free, _, rank, _ = np.linalg.lstsq(r, z, rcond=None)
    misfit, dof = float(np.sum((r @ free - z) ** 2)), b - int(rank)
    if cov_u is not None and cov_l is not None and dof > 0 \
            and misfit > scipy.stats.chi2.ppf(1 - MISFIT_ALPHA, dof):
        # the change has components a payload on this body cannot make: the mass moved
        # elsewhere on the arm (or friction, an offset changed); the fit is only the nearest
        text = (f"the change of coefficients is not a payload on {frame_name!r}: the best "
                f"payload there leaves a weighted misfit χ² = {misfit:.4g} for {dof} degrees "
                f"of freedom (p < {MISFIT_ALPHA:g}); "
                "mass was added elsewhere on the arm (body=/frame=), or friction or an offset "
                "changed: this payload is only the nearest one and its ± do not hold")
        notes = [text, *notes]
        warnings.warn(text, ModelMisfitWarning, stacklevel=2)
    return _payload_result(theta, _covariance(r, ident[2]), frame_name,
                           model.body_names[index], "base-change", ident, report,
                           notes_weight + notes,
                           details={"chi2": float(np.sum((r @ theta - z) ** 2)), "dof": b - 10})

