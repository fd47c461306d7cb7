r"""Joint drive gains and dynamic parameters from motor currents, with a load of known mass.

A robot that logs motor currents ``i`` knows its joint torques only through the drive gains
``κ`` (N·m per A, joint side: gear ratio × torque constant), ``τ = G^\top \operatorname{diag}(κ)
\, i`` (:mod:`consistid.drives.transmission`). Currents alone fix ``(κ, θ)`` only up to a common
scale. Gautier & Briot (2014), "Global identification of joint drive gains and dynamic
parameters of robots", IEEE/ASME Trans. Mechatronics 19(1), doi:10.1109/TMECH.2013.2238946:
run the same excitation unloaded and with a load whose mass ``m_L`` is known. With the base
parameters ``β`` of the robot (friction included), the load's other nine parameters ``φ``
(first and second moments in the frame of the body that carries it) and the gains ``κ`` as
unknowns, every equation is linear:

.. math::

    \text{unloaded:}\quad W_b \beta - G^\top\operatorname{diag}(i)\,κ = 0, \qquad
    \text{loaded:}\quad W_b \beta + W_b B_φ φ - G^\top\operatorname{diag}(i_L)\,κ
        = -m_L\, W_b B_m,

``W_b`` the base regressor and ``B = [B_m | B_φ]`` the base map restricted to the load's body
(``W π = W_b B π``; the load adds to that body's ten parameters), so the known mass is the one
non-homogeneous column. Only the part of ``φ`` seen through ``B_φ`` is identifiable; the rest
is left out (its minimum-norm value is zero).

The measured currents sit in the columns of this system, so plain least squares on it is
biased towards smaller gains (errors in variables, by about ``σ_i² / var(i)`` per joint: 5 % on
a UR5 wrist at 0.01 A of noise). Two estimates that are not:

* ``method="wls"``: maximum likelihood with the noise in the currents. With ``c = 1/κ`` each
  motor's current is ``i_m = c_m (G^{-\top}(Aθ − y))_m + ε_m``, bilinear in ``(θ, c)``;
  Gauss–Newton from the linear WLS estimate (per-joint weights, Gautier 1997), per-motor
  weights from its residual, backtracking so the cost never rises.
* ``method="sdp"`` (default): the consistent one, a convex program over ``(π, φ, κ)`` with
  ``β = Bπ``, the pseudo-inertia LMI ``J ⪰ 0`` on every body and on the load (Wensing, Kim,
  Slotine 2018; linear because ``m_L`` is fixed) and the weighted cost of the linear system
  *bias-compensated*: the expected contribution of the current noise (its σ from the
  maximum-likelihood fit) is subtracted from the normal matrix (Stoica & Söderström 1982), so
  the cost's expectation is the noise-free one.

The gains' standard deviations are those of the maximum-likelihood fit (the inverse Gauss–Newton
information, each motor's rows counted as ``N/τ_m`` independent samples, ``τ_m`` the residual's
integrated autocorrelation time, :func:`consistid.identification.statistics.autocorrelation_time`;
``κ = 1/c`` by the delta method); the consistent estimate reports them widened by its shift
from the maximum-likelihood gains where that exceeds them (:func:`_constrained_std`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.linalg

from ..data.checks import check_for_identification
from ..data.dataset import Dataset, as_dataset
from ..errors import (BoundActiveWarning, IdentificationError, InaccurateSolutionWarning,
                      InfeasibleError, OptionError, PoorExcitationError, PoorExcitationWarning,
                      UninformedGainError,
                      check_number, check_option)
from ..identification.base import RANK_RTOL, BaseParameters
from ..identification.identify import base_parameters_of, identify
from ..identification.intervals import interval_frame, normal_intervals
from ..identification.report import identification_page
from ..identification.regressor import DEFAULT_FRICTION, FrictionArg, RegressorSpec, regressor
from ..identification.result import IdentificationResult
from ..identification.statistics import autocorrelation_time
from ..identification.summary import recorded_warnings
from ..report.html import Page, unique
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel, require_model
from .coupled import CoupledResult, identify_coupled
from .motor_terms import motor_column_names, motor_columns
from .transmission import Transmission

GAIN_METHODS = ("wls", "sdp")
#: Default ``max_relative_std``: a gain whose standard deviation exceeds this fraction of it is
#: not informed by the loaded run.
MAX_RELATIVE_STD = 0.05


@dataclass(frozen=True, eq=False)
class DriveGains:
    """Identified drive gains and the robot's dynamics in N·m.

    Attributes
    ----------
    gains : (n,) N·m per A, joint side (``τ = Gᵀ diag(gains) i``).
    std : (n,) their standard deviations (maximum likelihood, coloured rows; for ``"sdp"``
        widened by the constraints' shift; module docstring).
    joint_names : the joints (one motor per joint).
    result : the :class:`~consistid.identification.result.IdentificationResult` of the unloaded
        run's currents converted with ``gains`` (N·m; same ``method``).
    load : (10,) the load's parameters in the frame of ``payload_body`` (mass fixed; the nine
        others as identified, the uninformed part zero for ``"wls"``).
    payload_body : the body that carries the load.
    method : ``"wls"`` or ``"sdp"``.
    coupling : (n, n) the coupling ``G`` the gains go through.
    details : what the estimate rests on (noise per joint, autocorrelation times, solver status;
        ``"motor_terms"``: the coupled motors' terms of the maximum-likelihood fit).
    coupled : with coupled motors, the :class:`~consistid.drives.coupled.CoupledResult` whose
        ``result`` is :attr:`result` (its ``predict`` adds the coupled motors' torques).
    """

    gains: np.ndarray
    std: np.ndarray
    joint_names: tuple[str, ...]
    result: IdentificationResult
    load: np.ndarray
    payload_body: str
    method: str
    coupling: np.ndarray
    details: dict[str, Any] = field(default_factory=dict)
    coupled: CoupledResult | None = None

    def to_torque(self, dataset: Dataset) -> Dataset:
        """``dataset`` with its currents (``tau``, A) turned into joint torques (N·m)."""
        dataset = as_dataset(dataset)
        dataset.check_joints(len(self.gains), self.joint_names)
        tau = (dataset.require_torque() * self.gains) @ self.coupling
        return dataset.with_torque(tau, keep_filter=True)

    def conf_int(self, alpha: float = 0.05, *, labelled: bool = True) -> Any:
        """Normal confidence intervals of the gains at level ``1 − alpha``, as
        :meth:`IdentificationResult.conf_int` gives them: a pandas ``DataFrame`` indexed by
        joint name, columns ``lower`` and ``upper``; ``labelled=False``: the bare (n, 2)
        array."""
        if not labelled:
            return normal_intervals(self.gains, self.std, alpha)
        return interval_frame(self.gains, self.std, list(self.joint_names), alpha)

    def summary(self) -> str:
        """The gains with their σ, then the identification's summary."""
        rows = [f"{n:>24s}  {g:12.6g}  ± {s:.3g}  ({s / abs(g):.2%})"
                for n, g, s in zip(self.joint_names, self.gains, self.std)]
        return "\n".join([f"drive gains (N·m/A, joint side; {self.method}, load on "
                          f"{self.payload_body!r})", *rows, "", self.result.summary()])

    def __repr__(self) -> str:
        shown = ", ".join(f"{g:.4g}±{s:.2g}" for g, s in zip(self.gains, self.std))
        return f"DriveGains({self.method}: [{shown}] N·m/A)"

    def findings(self) -> list[tuple[str, str]]:
        """The gains' line of the report's first box: the least certain gain."""
        rel = self.std / np.abs(self.gains)
        j = int(np.nanargmax(rel)) if np.isfinite(rel).any() else 0
        warned = bool(self.details.get("warnings")) or not np.isfinite(rel[j])
        return [("warn" if warned else "ok",
                 f"Least certain gain: {self.joint_names[j]}, {self.gains[j]:.5g} ± "
                 f"{self.std[j]:.2g} N·m/A (σ/|gain| {rel[j]:.2%}); every gain's σ is in the "
                 "table below.")]

    def page(self, data: Dataset | None = None, held_out: Dataset | None = None) -> Page:
        """The HTML report: one first box (the robot's findings in N·m —
        :func:`~consistid.identification.report.identification_page` — with :meth:`findings`),
        the gains ± σ, then the rest of the robot's page (``data``/``held_out`` in amperes add
        its measured-vs-predicted plots)."""
        robot = identification_page(self.result,
                                    None if data is None else self.to_torque(data),
                                    None if held_out is None else self.to_torque(held_out),
                                    figures=data is not None or held_out is not None,
                                    extra=self.findings())
        box = next(k for k, part in enumerate(robot.parts)
                   if part.startswith('<div class="verdict '))
        page = Page(f"consistid drive gains: {self.result.model.name}",
                    f"N·m/A, joint side; {self.method}, load on {self.payload_body!r}")
        page.raw(robot.parts[box])
        page.table(["joint", "gain [N·m/A]", "σ [N·m/A]", "σ / |gain|"],
                   [(n, g, s, f"{s / abs(g):.2%}")
                    for n, g, s in zip(self.joint_names, self.gains, self.std)],
                   caption="Drive gains")
        page.heading("The robot in N·m (the unloaded run's currents × the gains)")
        page.parts += robot.parts[box + 1:]
        page.figures.update(robot.figures)
        return page

    def report(self, path: str | Path, *, data: Dataset | None = None,
               held_out: Dataset | None = None) -> Path:
        """Write the HTML report (``*.html``: one self-contained page, :meth:`page`)."""
        path = Path(path)
        if path.suffix.lower() not in (".html", ".htm"):
            raise OptionError(f"report path {str(path)!r}: give an .html file")
        return self.page(data, held_out).write(path)

    def _repr_html_(self) -> str:
        return self.page().fragment()


@dataclass(frozen=True, eq=False)
class GainProblem:
    """The stacked linear system of the module docstring, as per-joint R factors.

    ``factors[j]`` is the R factor of joint ``j``'s rows ``[A_j | y_j]`` (both runs, the
    rows ``kept[:, j]``: all but those at rest, :func:`moving_rows`); the columns of ``A``
    are ``[β (b) | ζ (c) | ψ (r) | κ (n)]`` with ``ζ`` the coupled motors' terms and
    ``ψ = Vᵀφ`` the identifiable part of the load (``basis`` = ``V``, (9, r)).
    """

    factors: np.ndarray
    kept: np.ndarray
    base: BaseParameters
    basis: np.ndarray
    mass: float
    n_motor: int = 0

    @property
    def n_columns(self) -> int:
        return self.factors.shape[2] - 1

    @property
    def n_rows(self) -> np.ndarray:
        """(nv,) the rows each joint's factor holds."""
        return self.kept.sum(axis=0)


def _blocks(model: RobotModel, data: Dataset, spec: RegressorSpec, base: BaseParameters,
            load_map: np.ndarray | None, mass_map: np.ndarray, mass: float,
            transmission: Transmission, n_load: int) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (N, nv, b + c + r + n) and ``y`` (N, nv) of one run (``load_map`` ``None``:
    unloaded); ``c`` the coupled motors' columns (:mod:`consistid.drives.motor_terms`)."""
    y_full = regressor(model, data.q, data.dq, data.ddq, spec, dq_sign=data.dq_sign)
    wb = y_full.reshape(data.n_samples, model.nv, -1)[:, :, base.independent]
    motor = motor_columns(transmission, data.dq, data.ddq)
    coupling = transmission.coupling
    currents = data.require_torque()
    drive = -currents[:, None, :] * coupling.T[None, :, :]         # (N, joint, motor)
    load = (wb @ load_map if load_map is not None
            else np.zeros((data.n_samples, model.nv, n_load)))
    rhs = (-mass * (wb @ mass_map) if load_map is not None
           else np.zeros((data.n_samples, model.nv)))
    return np.concatenate([wb, motor, load, drive], axis=2), rhs


def gain_problem(model: RobotModel, unloaded: Dataset, loaded: Dataset, spec: RegressorSpec,
                 body: int, mass: float, transmission: Transmission
                 ) -> tuple[GainProblem, list]:
    """Build :class:`GainProblem`; also returns the two runs' ``(A, y)`` for the residuals."""
    base = base_parameters_of(model, spec)
    b_map = base.matrix
    cols = np.arange(10 * body, 10 * body + 10)
    b_phi = b_map[:, cols[1:]]
    u, s, vt = np.linalg.svd(b_phi, full_matrices=False)
    rank = int(np.sum(s > RANK_RTOL * 1e3 * max(s[0], 1e-300)))
    basis = vt[:rank].T                                            # (9, r)
    runs = [_blocks(model, unloaded, spec, base, None, b_map[:, cols[0]], mass, transmission,
                    rank),
            _blocks(model, loaded, spec, base, b_phi @ basis, b_map[:, cols[0]], mass,
                    transmission, rank)]
    a = np.concatenate([r[0] for r in runs])
    y = np.concatenate([r[1] for r in runs])
    kept = np.concatenate([moving_rows(d, spec, transmission) for d in (unloaded, loaded)])
    factors = np.stack([np.linalg.qr(np.column_stack([a[kept[:, j], j], y[kept[:, j], j]]),
                                     mode="r") for j in range(model.nv)])
    return GainProblem(factors, kept, base, basis, mass,
                       3 * int(transmission.coupled_motors.size)), runs


def moving_rows(data: Dataset, spec: RegressorSpec, transmission: Transmission) -> np.ndarray:
    r"""(N, nv) which joint rows the gains are fitted on: all but those where a dry-friction
    column acts at a speed under :data:`~consistid.robot.joint_terms.STANDSTILL_SPEED` (the
    joint's own Coulomb column, or a coupled motor's ``fsm`` on the joints it drives, at the
    joint-side speed of its coordinate ``g_m^\top q̇``). There ``f_c \operatorname{sign}(q̇)``
    is not the friction: a joint at rest is held by any torque within ``±f_c``, and simulated or
    real dry friction is smooth over a band of slow speeds. On a UR5 with Coulomb friction of
    1–3 % of the effort limits (MuJoCo's ``frictionloss``) the current residual was 7 × the
    noise below 5 mrad/s and the wrist's gain 3.1 % off (3.3 σ) with those rows in."""
    dq = np.asarray(data.dq, dtype=float)
    slow = np.abs(dq) < STANDSTILL_SPEED
    at_rest = slow & spec.mask("coulomb")[None, :]
    for m in transmission.coupled_motors:
        g = transmission.coupling[m]
        at_rest |= (np.abs(dq @ g) < STANDSTILL_SPEED)[:, None] & (g != 0)[None, :]
    return ~at_rest


def _solve(problem: GainProblem, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares on the factors: ``(x, R of the weighted stack, condition)``."""
    stacked = np.concatenate([f / s for f, s in zip(problem.factors, sigma)])
    r = np.linalg.qr(stacked, mode="r")
    sv = np.linalg.svd(r[:, :-1], compute_uv=False)
    x = np.linalg.lstsq(r[:-1, :-1], r[:-1, -1], rcond=None)[0]
    return x, r[:-1, :-1], float(sv[0] / max(sv[-1], 1e-300))


def _joint_sse(problem: GainProblem, x: np.ndarray) -> np.ndarray:
    v = np.concatenate([x, [-1.0]])
    return np.array([float(np.sum((f @ v) ** 2)) for f in problem.factors])


def _check_informed(model: RobotModel, r: np.ndarray, cov: np.ndarray, gains: np.ndarray,
                    cond: float, n_theta: int, body_name: str, mass: float,
                    max_relative_std: float) -> None:
    """Raise :class:`UninformedGainError` for a gain the runs do not fix (module docstring):
    one in a null direction of the weighted system, or known no better than
    ``max_relative_std``."""
    names = model.joint_names
    sv_u, sv, vt = np.linalg.svd(r)
    dead = vt[sv < RANK_RTOL * sv[0]]
    rel = np.sqrt(np.diag(cov)[n_theta:]) / np.maximum(np.abs(gains), 1e-300)
    bad = sorted({int(j) for v in dead for j in np.flatnonzero(np.abs(v[n_theta:]) > 1e-3)}
                 | {int(j) for j in np.flatnonzero(~(rel <= max_relative_std))})
    if not bad:
        return
    shown = ", ".join(f"{names[j]!r} (σ {rel[j]:.1%} of it)" if np.isfinite(rel[j])
                      else f"{names[j]!r} (not determined)" for j in bad)
    raise UninformedGainError(
        f"the loaded run does not inform the drive gain of {shown}: the {mass:g} kg load on "
        f"{body_name!r} changes that joint's torque too little against the current noise "
        f"(condition number {cond:.3g}; max_relative_std={max_relative_std:g}). An "
        "experiment that would: a heavier load, or one whose centre of mass lies off that "
        "joint's axis on a body it carries (payload_body=), run with that joint accelerating "
        "and lifting the load against gravity")


#: A joint's residual whose mean is this many standard errors from zero, with no offset
#: column, is a current offset the model leaves out (:func:`_check_offset`) …
OFFSET_Z = 5.0
#: … when the mean is also this fraction of the residual's standard deviation or more.
OFFSET_SIZE = 0.2


def _check_offset(model: RobotModel, spec: RegressorSpec, blocks: list, runs: list[Dataset],
                  kept: np.ndarray, x: np.ndarray) -> None:
    """Raise :class:`OptionError` when a joint without an ``offset`` column has a residual
    whose mean is :data:`OFFSET_Z` standard errors (``σ √(τ/N)``, ``τ`` its autocorrelation
    time) from zero and :data:`OFFSET_SIZE` σ or more: a current sensor's constant bias ``b``
    adds ``Gᵀ(κ ⊙ b)`` to every row, which no other column carries; unmodelled, it biased the
    gains or made them look uninformed (UR5, 0.01–0.02 A on every motor: the wrist's σ 8 % and
    the load blamed). The size bound keeps other misfit with a small non-zero mean from being
    named an offset (a UR10 whose wrist did not track: 0.075 σ, 7 standard errors)."""
    missing = ~spec.mask("offset")
    if not missing.any():
        return
    e = np.concatenate([blk[0] @ x - blk[1] for blk in blocks]) * kept
    n = np.maximum(kept.sum(axis=0), 1)
    mean = e.sum(axis=0) / n
    sd = np.sqrt(np.sum(((e - mean) * kept) ** 2, axis=0) / n)
    tau = np.maximum(autocorrelation_time(Dataset.concatenate(runs), e), 1.0)
    z = mean / np.maximum(sd * np.sqrt(tau / n), 1e-300)
    bad = np.flatnonzero(missing & (np.abs(z) > OFFSET_Z) & (np.abs(mean) >= OFFSET_SIZE * sd))
    if bad.size:
        gains = x[-model.nv:]                  # the rows hold −κ i: the mean is −κ b
        shown = ", ".join(f"{model.joint_names[j]!r} (≈ {-mean[j] / gains[j]:.3g} A, "
                          f"{abs(z[j]):.0f} standard errors)" for j in bad)
        raise OptionError(
            f"the currents of {shown} carry a constant offset that friction= leaves out (it "
            "has no 'offset' there): the gains would absorb it. Add 'offset' to friction= (the "
            "default has it), or remove the current sensor's offset from the logs")


def identify_drive_gains(model: RobotModel, unloaded: Dataset, loaded: Dataset | None = None,
                         payload_mass: float | None = None, payload_body: str | None = None,
                         method: str = "sdp", friction: FrictionArg = DEFAULT_FRICTION,
                         armature: bool | Sequence[int | str] = False,
                         transmission: Transmission | None = None,
                         max_relative_std: float = MAX_RELATIVE_STD,
                         **identify_options: Any) -> DriveGains:
    """Identify the joint drive gains and the dynamic parameters from motor currents.

    Parameters
    ----------
    model : the robot (its URDF inertias are the SDP's prior).
    unloaded, loaded : :class:`Dataset` of the same kind of excitation, without and with the
        load; their ``tau`` hold motor currents (A), one per motor.
    payload_mass : the load's mass (kg), known (weighed): it fixes the scale of the gains.
    payload_body : the body the load is fixed to; default the last body.
    method : ``"wls"`` (weighted least squares) or ``"sdp"`` (consistent: pseudo-inertia LMIs
        on every body and on the load).
    friction, armature : the per-joint columns, as in :func:`consistid.identify`.
    transmission : a :class:`~consistid.drives.transmission.Transmission` whose coupling ``G``
        the currents go through (``τ = Gᵀ diag(κ) i``) and whose coupled motors' inertia and
        friction are identified with the rest (:mod:`consistid.drives.motor_terms`; its torque
        constants, if any, are not used); default independent joints.
    max_relative_std : a gain known no better than this fraction (1σ) is refused.
    **identify_options : passed to :func:`consistid.identify` for :attr:`DriveGains.result`.

    Returns
    -------
    DriveGains

    Raises
    ------
    OptionError without a loaded run or a positive ``payload_mass``, for an unknown body or
    method, and for currents with a constant offset that ``friction`` has no column for;
    JointCountError for data of another joint count; UninformedGainError when the runs do not
    fix a gain (naming the joint and what experiment would);
    PoorExcitationError when they do not determine the base parameters.
    """
    require_model(model)
    check_option("method", method, GAIN_METHODS)
    if loaded is None:
        raise OptionError(
            "identify_drive_gains needs loaded=: currents determine the drive gains and the "
            "dynamics only up to one common scale. Repeat the excitation with a load of known "
            "mass fixed to the flange and pass it as loaded=..., with payload_mass=<kg>; or, "
            "with datasheet torque constants and gear ratios, convert the currents directly "
            "(consistid.load_recording(..., drives=Transmission(...)))")
    if payload_mass is None:
        raise OptionError("identify_drive_gains needs payload_mass= (kg): the weighed mass of "
                          "the load in the loaded run fixes the scale of the gains")
    mass = check_number("payload_mass", payload_mass, 0, strict=True)
    check_number("max_relative_std", max_relative_std, 0, strict=True)
    body_name = model.body_names[-1] if payload_body is None else payload_body
    check_option("payload_body", body_name, model.body_names)
    body = model.body_names.index(body_name)
    transmission = transmission or Transmission(np.ones(model.nv))
    transmission.check_joints(model.nv, model.joint_names)
    g = transmission.coupling
    no_effort = (model.limits.lower, model.limits.upper, np.full(model.nv, np.inf))
    runs = []
    for name, data in (("unloaded", unloaded), ("loaded", loaded)):
        data = as_dataset(data, name)
        data.check_joints(model.nv, model.joint_names)
        check_for_identification(data, model.joint_names, no_effort)
        runs.append(data)
    spec = RegressorSpec.make(model, friction, armature)
    problem, blocks = gain_problem(model, runs[0], runs[1], spec, body, mass, transmission)
    n_theta = problem.n_columns - model.nv
    x0, cov0, r0, cond0 = _linear_start(problem, model.nv)
    kept = problem.kept
    _check_offset(model, spec, blocks, runs, kept, x0)
    _check_informed(model, r0, cov0, x0[n_theta:], cond0, n_theta, body_name, mass,
                    max_relative_std)
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:   # kept with the result too
            warnings.simplefilter("always")
            with np.errstate(all="ignore"):
                try:
                    fit = _maximum_likelihood(blocks, runs, g, x0, n_theta, kept)
                except np.linalg.LinAlgError:
                    fit = None
            if fit is None or not np.all(np.isfinite(fit.x)):
                raise IdentificationError(
                    "identify_drive_gains: the maximum-likelihood fit of the gains left the "
                    f"finite numbers (payload_mass={payload_mass!r} kg): check payload_mass= "
                    "(kg, the weighed load) and that the runs' tau hold motor currents in A")
            x = fit.x
            gains = x[n_theta:]
            _check_informed(model, fit.r, fit.covariance, gains, fit.condition, n_theta,
                            body_name, mass, max_relative_std)  # again, at the ML fit
            std = np.sqrt(np.diag(fit.covariance)[n_theta:])
            start = problem.base.n_base + problem.n_motor
            load = np.concatenate([[mass], problem.basis @ x[start:n_theta]])
            details: dict[str, Any] = {"current_sigma": fit.sigma, "autocorrelation_time": fit.tau,
                                       "condition_number": fit.condition,
                                       "gauss_newton_iterations": fit.iterations,
                                       "wls_gains": gains.copy()}
            if problem.n_motor:
                details["motor_terms"] = dict(zip(motor_column_names(transmission),
                                                  x[problem.base.n_base:start]))
            if fit.condition > 1e8:
                warnings.warn(f"the drive-gain problem has condition number {fit.condition:.3g}: "
                              "some directions are barely excited; check the gains' std",
                              PoorExcitationWarning, stacklevel=2)
            if method == "sdp":
                gains, load, status = _consistent(model, problem, spec, fit, g, body)
                details["solver_status"] = status
                std = _constrained_std(gains, fit.x[n_theta:], std, model.joint_names)
    finally:                            # passed on, even when the estimate raises
        for w in caught:
            warnings.warn(w.message, w.category, stacklevel=2)
    details["warnings"] = unique([str(w.message) for w in caught])
    torque = runs[0].with_torque((runs[0].require_torque() * gains) @ g, keep_filter=True)
    coupled = None
    if problem.n_motor:
        coupled = identify_coupled(model, torque, transmission, method=method,
                                   friction=friction, armature=armature, **identify_options)
        result = coupled.result
    else:
        result = identify(model, torque, method=method, friction=friction, armature=armature,
                          **identify_options)
    result = _with_gains(result, gains, std, model.joint_names, body_name, mass,
                         details["warnings"])
    if coupled is not None:
        coupled = dataclasses.replace(coupled, result=result)
    return DriveGains(gains, std, tuple(model.joint_names), result, load, body_name, method, g,
                      details, coupled)


#: A consistent gain this many maximum-likelihood σ from the unconstrained one is reported
#: (:class:`~consistid.errors.BoundActiveWarning`).
SHIFT_WARNING = 2.0


def _constrained_std(gains: np.ndarray, ml_gains: np.ndarray, std: np.ndarray,
                     joint_names: Sequence[str]) -> np.ndarray:
    r"""The σ of the consistent gains: ``σ² + max(δ² − σ², 0)``, ``δ = κ_{SDP} − κ_{ML}``.

    The maximum-likelihood σ covers the unconstrained gains. An inequality at or near its
    bound (a Coulomb coefficient ``≥ 0`` on a joint without dry friction, a body at the edge of
    ``J ⪰ 0``) can move the consistent gains by several of those σ through their correlation
    with it (UR5, κ from 0.08 to 13 N·m/A: 5.5 σ on one gain, 0.44 %): the excess of the shift
    over the noise is added to the variance, as the weighting term of
    :mod:`consistid.identification.identify` adds its bias, and a shift beyond
    :data:`SHIFT_WARNING` σ is named."""
    shift = (gains - ml_gains) / std
    far = np.flatnonzero(np.abs(shift) > SHIFT_WARNING)
    if far.size:
        shown = ", ".join(f"{joint_names[j]!r} {shift[j]:+.1f} σ" for j in far)
        warnings.warn(
            f"the consistency constraints move the drive gains of {shown} away from the "
            "unconstrained maximum-likelihood estimate (an inequality at its bound, e.g. a "
            "Coulomb coefficient ≥ 0 on a joint without dry friction): their std is widened by "
            "the shift; method='wls' gives the unconstrained gains, and a friction= without "
            "that joint's term may remove the bound", BoundActiveWarning, stacklevel=3)
    return np.sqrt(std ** 2 + np.maximum((gains - ml_gains) ** 2 - std ** 2, 0.0))


def _with_gains(result: IdentificationResult, gains: np.ndarray, std: np.ndarray,
                joint_names: Sequence[str], body: str, mass: float,
                warned: Sequence[str] = ()) -> IdentificationResult:
    """``result`` with the gains in its details, so that its summary, report and saved file
    say which gains its torques came from, and what the gains' estimate warned
    (``details['warning k']``, as the summary and the report's first box show them)."""
    shown = "; ".join(f"{n} {g:.6g} ± {s:.2g}" for n, g, s in zip(joint_names, gains, std))
    first = len(recorded_warnings(result.details))
    return dataclasses.replace(result, details={
        **result.details,
        **{f"warning {first + k + 1}": f"drive gains: {text}" for k, text in enumerate(warned)},
        "drive_gains": f"torques = currents × gains (N·m/A, identified with a {mass:g} kg load "
                       f"on {body!r}): {shown}",
        "drive_gain_values": np.asarray(gains, dtype=float),
        "drive_gain_std": np.asarray(std, dtype=float)})


def _linear_start(problem: GainProblem, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                          float]:
    """OLS, then WLS with per-joint σ from its residual, of the linear system: the start of
    :func:`_maximum_likelihood` (biased: the currents in its columns are noisy). Returns
    ``(x, covariance, R of the weighted stack, condition)``."""
    dof = problem.n_rows - problem.n_columns / nv
    if np.any(dof <= 0):
        raise PoorExcitationError(f"{int(problem.n_rows.min())} moving samples on a joint for "
                                  f"{problem.n_columns} unknowns: record longer, or move "
                                  "every joint faster than "
                                  f"{STANDSTILL_SPEED:g} rad/s for most of the run")
    x, _, _ = _solve(problem, np.ones(nv))
    sigma = np.sqrt(_joint_sse(problem, x) / dof)
    x, r, cond = _solve(problem, np.where(sigma > 0, sigma, 1.0))
    return x, np.linalg.pinv(r.T @ r), r, cond


@dataclass(frozen=True, eq=False)
class MotorFit:
    """The maximum-likelihood fit of :func:`_maximum_likelihood`.

    ``x`` = ``[β, ψ, κ]``; ``covariance`` of ``x`` (coloured rows); ``sigma`` (n,) the current
    noise per motor (A); ``tau`` (n,) the residual's autocorrelation time per motor
    (samples); ``r`` the R factor of the whitened Jacobian (for the rank test); ``condition``.
    """

    x: np.ndarray
    covariance: np.ndarray
    sigma: np.ndarray
    tau: np.ndarray
    r: np.ndarray
    condition: float
    iterations: int


def _maximum_likelihood(blocks: list, runs: list[Dataset], coupling: np.ndarray,
                        x0: np.ndarray, n_theta: int, kept: np.ndarray,
                        max_iterations: int = 50, tol: float = 1e-12) -> MotorFit:
    r"""Gauss–Newton on the currents: the noise is in the measured currents, which the linear
    system has in its columns (an errors-in-variables bias towards smaller gains, of order
    ``σ_i² / var(i)``). With ``c = 1/κ`` and the predicted joint torque ``p = Aθ − y``
    (``θ = [β, ψ]``), each motor's current is ``i_m = c_m (G^{-\top} p)_m + ε_m``: bilinear in
    ``(θ, c)``, minimised in the per-motor σ-weighted norm from the linear estimate ``x0``, on
    the samples where every joint row in ``(G^{-\top} p)_m`` is ``kept`` (:func:`moving_rows`,
    (N, nv))."""
    ginv_t = np.linalg.inv(coupling).T
    a = np.concatenate([blk[0][:, :, :n_theta] for blk in blocks])
    am = np.einsum("mj,kjp->kmp", ginv_t, a)
    ym = np.concatenate([blk[1] for blk in blocks]) @ ginv_t.T
    currents = np.concatenate([d.require_torque() for d in runs])
    n_samples, n = currents.shape
    used = (~kept).astype(float) @ (ginv_t != 0).T.astype(float) == 0          # (N, n)
    dof = np.maximum(used.sum(axis=0) - a.shape[2] / n, 1.0)
    theta, c = x0[:n_theta].copy(), 1.0 / x0[n_theta:]
    sigma = np.ones(n)

    def residual(th: np.ndarray, cc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``p`` and the current residual ``c ⊙ p − i`` (0 on the samples not ``used``)."""
        p = am @ th - ym
        return p, np.where(used, cc * p - currents, 0.0)

    for iteration in range(1, max_iterations + 1):
        p, raw = residual(theta, c)
        sigma = np.sqrt(np.sum(raw ** 2, axis=0) / dof)
        sigma = np.where(sigma > 0, sigma, 1.0)
        resid = raw / sigma
        jac = _jacobian(am, p, c, sigma, used)
        step = np.linalg.lstsq(jac.reshape(n_samples * n, -1), -resid.reshape(-1),
                               rcond=None)[0]
        before, shrink = float(np.sum(resid ** 2)), 1.0
        while shrink > 1e-6 and np.sum((residual(theta + shrink * step[:n_theta],
                                                 c + shrink * step[n_theta:])[1]
                                        / sigma) ** 2) > before:
            shrink /= 2.0                      # backtracking: the cost never rises
        step = shrink * step
        theta, c = theta + step[:n_theta], c + step[n_theta:]
        if np.linalg.norm(step) <= tol * (1.0 + np.linalg.norm(np.concatenate([theta, c]))):
            break
    p, raw = residual(theta, c)
    tau = autocorrelation_time(Dataset.concatenate(runs), raw)
    jac = _jacobian(am, p, c, sigma, used)
    r = np.linalg.qr(jac.reshape(n_samples * n, -1), mode="r")
    sv = np.linalg.svd(r, compute_uv=False)
    info = sum(jac[:, m].T @ jac[:, m] / max(float(tau[m]), 1.0) for m in range(n))
    cov_c = np.linalg.pinv(info)
    # κ = 1/c: the delta method, dκ = −κ² dc
    jmap = np.eye(cov_c.shape[0])
    jmap[n_theta:, n_theta:] = np.diag(-1.0 / c ** 2)
    return MotorFit(np.concatenate([theta, 1.0 / c]), jmap @ cov_c @ jmap.T, sigma, tau, r,
                    float(sv[0] / max(sv[-1], 1e-300)), iteration)


def _jacobian(am: np.ndarray, p: np.ndarray, c: np.ndarray, sigma: np.ndarray,
              used: np.ndarray) -> np.ndarray:
    """(N, n, n_θ + n) σ-weighted Jacobian of the currents ``c ⊙ p`` in ``(θ, c)``, zero on
    the samples not ``used``."""
    n = c.size
    jac = np.concatenate([c[None, :, None] * am, p[:, :, None] * np.eye(n)[None, :, :]],
                         axis=2) / sigma[None, :, None]
    return jac * used[:, :, None]


#: Weight of the Euclidean pull towards the URDF prior in the consistent program (on the null
#: space of the base map only), relative to the mean diagonal of the data's information: it
#: decides only directions the data do not see.
PRIOR_NUDGE = 1e-8


def _compensated_cost(problem: GainProblem, fit: MotorFit, coupling: np.ndarray) -> np.ndarray:
    r"""A factor ``L`` with ``‖L [x; −1]‖²`` the bias-compensated weighted cost of the linear
    system: ``Σ_j F_j^\top F_j / s_j^2`` (``F_j`` joint ``j``'s factor of ``[A_j | y_j]``,
    ``s_j^2 = Σ_m G_{mj}^2 κ_m^2 σ_m^2`` its residual variance) minus the expected
    contribution of the current noise to the drive columns,
    ``Σ_j N_j \operatorname{diag}_m(G_{mj}^2 σ_m^2) / s_j^2`` (``N_j`` joint ``j``'s rows;
    bias-compensated least squares,
    Stoica & Söderström 1982, "Bias correction in least-squares identification", Int. J.
    Control 35(3)); the cost's expectation is then the noise-free one, so its minimiser is
    free of the errors-in-variables bias. Negative eigenvalues (noise) are clipped."""
    nv = coupling.shape[0]
    gains = fit.x[-nv:]
    s2 = (coupling ** 2).T @ (gains ** 2 * fit.sigma ** 2)
    m = sum(f.T @ f / v for f, v in zip(problem.factors, s2))
    p = problem.n_columns
    drive = slice(p - nv, p)
    m[drive, drive] -= np.diag(sum(problem.n_rows[j] * coupling[:, j] ** 2 * fit.sigma ** 2
                                   / s2[j] for j in range(nv)))
    lam, vec = np.linalg.eigh((m + m.T) / 2.0)
    return np.sqrt(np.clip(lam, 0.0, None))[:, None] * vec.T


def _consistent(model: RobotModel, problem: GainProblem, spec: RegressorSpec,
                fit: MotorFit, coupling: np.ndarray, body: int
                ) -> tuple[np.ndarray, np.ndarray, str]:
    """The consistent estimate (module docstring): ``(gains, load 10-vector, solver status)``.

    Variables ``v = [π, φ, κ, ζ]``: the standard parameters ``π`` (``β = Bπ``), the load's nine
    ``φ`` (its mass fixed), the gains ``κ`` and the coupled motors' terms ``ζ``; cost the
    bias-compensated weighted residual (:func:`_compensated_cost`) plus a small pull of the
    unseen part of ``π`` towards the URDF (:data:`PRIOR_NUDGE`); constraints ``J(π_k) ⪰ 0``
    for every body (scaled by its URDF body when that one is realisable), ``J(m_L, φ) ⪰ 0``,
    the non-negative friction, armature and motor coefficients ``≥ 0``. Solved in whitened
    coordinates ``v = v_c + Φ w`` (:func:`_whitened_cost`), where the cost is ``‖w‖²``."""
    import cvxpy as cp

    from ..identification.constraints import BodyScaling, pseudo_inertia_lmi
    from ..robot.inertia import is_degenerate

    nv, n_motor, n_pi = model.nv, problem.n_motor, model.n_inertial + spec.n_joint_columns
    prior = np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])
    centre, phi_map = _whitened_cost(problem, fit, coupling, prior)
    w = cp.Variable(centre.size)
    v = centre + phi_map @ w
    pi, phi = v[:n_pi], v[n_pi:n_pi + 9]
    zeta = v[n_pi + 9 + nv:]
    constraints = []
    for k in range(model.n_inertial // 10):
        ref = model.prior_parameters[10 * k:10 * k + 10]
        scaling = None if is_degenerate(ref) else BodyScaling.from_reference(ref)
        constraints += pseudo_inertia_lmi(pi[10 * k:10 * k + 10], 0.0, scaling)
    mass = problem.mass
    constraints += pseudo_inertia_lmi(cp.hstack([np.array([mass]), phi]))
    nonneg = spec.nonnegative_columns
    if nonneg.size:
        constraints.append(pi[model.n_inertial + nonneg] >= 0)
    if n_motor:
        constraints.append(zeta >= 0)                    # rotor inertia, friction ≥ 0
    program = cp.Problem(cp.Minimize(cp.sum_squares(w)), constraints)
    program.solve(solver=cp.CLARABEL)
    if program.status not in ("optimal", "optimal_inaccurate") or w.value is None:
        raise InfeasibleError(f"the consistent drive-gain program ended {program.status!r} "
                              "(Clarabel); method='wls' gives the unconstrained estimate")
    if program.status != "optimal":
        warnings.warn(f"the consistent drive-gain program ended {program.status!r}",
                      InaccurateSolutionWarning, stacklevel=3)
    value = centre + phi_map @ np.asarray(w.value, dtype=float)
    load = np.concatenate([[mass], value[n_pi:n_pi + 9]])
    return value[n_pi + 9:n_pi + 9 + nv], load, str(program.status)


def _whitened_cost(problem: GainProblem, fit: MotorFit, coupling: np.ndarray,
                   prior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""``(v_c, Φ)`` with the consistent program's cost
    ``‖L_x M v − l‖² / s + ν ‖N^\top(π − π_0)‖² = ‖w‖² + const`` for ``v = v_c + Φ w``.

    ``[L_x | l]`` the bias-compensated factor (:func:`_compensated_cost`), ``M`` the map from
    ``v = [π, φ, κ, ζ]`` to the linear system's unknowns ``[Bπ, ζ, Vᵀφ, κ]``, ``s`` the mean
    squared column norm, ``ν`` = :data:`PRIOR_NUDGE`, ``N`` a basis of the null space of
    ``B``: the pull towards the URDF acts only on what the data do not see (on all of ``π``,
    scaled by ``s``, it had moved a 13 N·m/A gain by 0.84 % when another was 0.08 N·m/A). From
    one QR factorisation of the stacked, column-normalised system (a tiny ridge keeps the
    unseen load directions bounded), as the rigid-body SDP whitens its own
    (:mod:`consistid.identification.sdp`). Without it, gains of 0.05 and 20 N·m/A on one robot
    put the κ columns 10⁶ apart in scale and Clarabel stopped 'optimal' at gains 30–46 % off
    (UR5, κ log-uniform in [0.05, 20])."""
    factor = _compensated_cost(problem, fit, coupling)
    nv, n_motor, n_pi = coupling.shape[0], problem.n_motor, prior.size
    n_base, r = problem.base.n_base, problem.basis.shape[1]
    size = n_pi + 9 + nv + n_motor
    m = np.zeros((problem.n_columns, size))
    m[:n_base, :n_pi] = problem.base.matrix
    m[n_base:n_base + n_motor, n_pi + 9 + nv:] = np.eye(n_motor)
    m[n_base + n_motor:n_base + n_motor + r, n_pi:n_pi + 9] = problem.basis.T
    m[-nv:, n_pi + 9:n_pi + 9 + nv] = np.eye(nv)
    rx = factor[:, :-1] @ m
    scale = float(np.mean(np.sum(factor[:, :-1] ** 2, axis=0)))
    _, sv, vt = np.linalg.svd(problem.base.matrix)
    unseen = vt[int(np.sum(sv > RANK_RTOL * sv[0])):]      # null(B): π the data do not see
    nudge = np.zeros((unseen.shape[0], size))
    nudge[:, :n_pi] = np.sqrt(PRIOR_NUDGE) * unseen
    a = np.vstack([rx / np.sqrt(scale), nudge])
    z = np.concatenate([factor[:, -1] / np.sqrt(scale),
                        np.sqrt(PRIOR_NUDGE) * unseen @ prior])
    norms = np.sqrt(np.sum(a ** 2, axis=0))
    t = 1.0 / np.where(norms > 0, norms, 1.0)
    ridge = np.where(norms > 0, 1e-10, 1e-6)             # the unseen load directions: 1e-6
    a = np.vstack([a * t, np.diag(ridge)])
    q_aug, r_aug = np.linalg.qr(a)
    r_inv = scipy.linalg.solve_triangular(r_aug, np.eye(size))
    y_c = r_inv @ (q_aug.T @ np.concatenate([z, np.zeros(size)]))
    return t * y_c, t[:, None] * r_inv
