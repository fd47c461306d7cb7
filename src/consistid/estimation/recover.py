r"""Base coefficients → a full, physically consistent set of standard parameters.

Given base coefficients ``β̂`` (from our least squares, a manufacturer or a paper) and the map
``β = B π`` of :mod:`consistid.identification.base`, find standard parameters ``π`` (10 per body,
then the
friction/armature entries of the regressor spec) such that every body's pseudo-inertia is
positive semidefinite (Wensing, Kim, Slotine 2017, RA-L 3(1), doi:10.1109/LRA.2017.2729659):

``mode="exact"``
    .. math::  \min_\pi \sum_i d(J_i(\pi) \,\|\, J_i(\pi_0)) \quad \text{s.t.}\quad
               B\pi = \hat\beta,\; J_i(\pi) \succeq \epsilon\, J_i(\pi_0)\;\forall i

    with ``d`` the log-det divergence (Lee, Wensing, Park 2019, T-RO 36(2),
    doi:10.1109/TRO.2019.2926491) or a relative Euclidean distance (:func:`euclidean_weights`).
    This is the problem Gaz, Flacco, De Luca ("Extracting feasible robot parameters from dynamic
    coefficients using nonlinear optimization methods", ICRA 2016, pp. 2075–2081) and Gaz et al.
    (Panda identification, RA-L 4(4), 2019, pp. 4147–4154) solve by nonlinear, penalty-based
    search; here it is convex and solved globally by one SDP. **Every** body is constrained,
    including bodies some (or all) of whose columns vanish from the regressor: their parameters
    are then set by the prior.

``mode="nearest"``
    when ``β̂`` itself is not realisable (noisy OLS), two convex stages:

    .. math::  d^* = \min_\pi \|L(B\pi - \hat\beta)\|^2 \;\text{s.t. consistency}, \qquad
               \min_\pi \textstyle\sum_i d(J_i \| J_{0,i}) \;\text{s.t. consistency},\;
               \|L(B\pi - \hat\beta)\|^2 \le d^*(1 + 10^{-3}) + \delta

    with ``LᵀL = Σ⁻¹`` the inverse covariance of ``β̂``: the first finds how close any consistent
    set can get (in χ² units), the second lets the prior choose among the sets that are, to
    ``δ`` (default 1 χ² unit: statistically as close as the closest), just as close. The nearest
    set lies on the boundary of consistency, where the coefficients alone pin the null space of
    ``B`` to odd values; measured on the Panda (OLS, 1 N·m noise, Euclidean prior), ``δ = 0.01``
    left link masses up to 15 kg (truth ≤ 4 kg), ``δ = 1`` gave masses within 0.5 kg of the
    truth while moving no coefficient by more than 1.1 σ. A one-stage penalty
    ``‖L(Bπ − β̂)‖² + λ d`` has no such bound on how far the prior pulls the coefficients.
    With a nearly flat prior body (Panda link 2: ``λ_min/λ_max(J₀) ≈ 1e-6``) the log-det prior
    resists any thickness change there and may push other bodies' masses far instead; the
    summary names such bodies (``prior="euclidean"`` does not have this stiffness).

When ``mode="exact"`` is infeasible, :class:`~consistid.errors.UnrealizableCoefficientsError`
names the coefficients (by their readable grouping) that no consistent set can meet, with the
smallest weighted-L1 changes that make them realisable (L1 so that few coefficients are named).

Friction/armature entries of the spec are variables too: Coulomb, viscous and armature are kept
``≥ 0``; where the coefficients do not fix them (e.g. armatures grouped with link inertias), a
Euclidean pull towards their prior (zero) decides.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Sequence

import cvxpy as cp
import numpy as np

from ..identification.base import BaseParameters, compute_base_parameters
from ..identification.solver import DEFAULT_SOLVER, check_solver, solve
from ..identification.constraints import BodyScaling, body_constraints, relative_bound
from ..data.dataset import Dataset
from ..errors import (IdentificationError, InaccurateSolutionWarning,
                     InconsistentParametersError, InfeasibleError, ModelError, OptionError,
                     SolverError, UnrealizableCoefficientsError, check_number, check_option)
from ..robot.model import RobotModel, require_model
from ..robot.inertia import body_slice, is_physically_consistent, pseudo_inertia
from ..identification.priors import euclidean, logdet_divergence, logdet_divergence_value
from ..identification.regressor import (FRICTION_TERMS, FrictionArg, RegressorSpec,
                        dataset_regressor, matching_settings, parameter_names, prior_vector,
                        resolve_spec)
from ..identification.result import IdentificationResult, StandardParameterSet
from ..identification.solver import SolverReport

MODES = ("exact", "nearest")
#: Unlike the SDP's (:data:`consistid.identification.sdp.PRIORS`), no ``None``: the coefficients
#: leave the null space of the base map free, and only a prior picks a point there.
PRIORS = ("logdet", "euclidean")
#: Without a covariance, coefficient ``i`` gets the pseudo standard deviation
#: ``RELATIVE_STD·|β̂_i| + ABSOLUTE_STD`` (SI units of the coefficient).
RELATIVE_STD = 0.01
ABSOLUTE_STD = 1e-6
#: Moves smaller than this many standard deviations are not listed.
MOVE_THRESHOLD = 1e-3
#: Weight of the prior tie-break in the first (distance) stage of nearest mode.
STAGE1_TIE = 1e-6
#: Relative part of the second stage's allowance, ``d ≤ d*(1 + SLACK_RTOL) + slack``.
SLACK_RTOL = 1e-3
#: Clarabel tolerances of both nearest-mode stages and of the infeasibility diagnosis: d* is
#: needed to well within ``slack`` only, the prior's optimum to 1e-6 relative, and the answer is
#: checked afterwards (margins ≥ 1e-6 relative ≫ 1e-7 feasibility, distance recomputed). The
#: default 1e-8 makes Clarabel stall ("AlmostSolved") one step after meeting these.
NEAREST_CLARABEL = {"tol_gap_rel": 1e-6, "tol_gap_abs": 1e-9, "tol_feas": 1e-7}
#: A prior body with cond(J₀) above this is "nearly flat" (named in messages and notes).
FLAT_PRIOR = 1e5
#: Round-off below zero accepted (and set to 0) on entries constrained ≥ 0 (N·m, N·m·s/rad, kg·m²).
NONNEGATIVE_ROUNDOFF = 1e-7


@dataclass(frozen=True)
class CoefficientMove:
    """How far one base coefficient had to move (nearest mode / infeasibility diagnosis).

    Attributes
    ----------
    index : position in the base vector.
    name : short name (``BaseParameters.names``).
    grouping : the readable combination of standard parameters (``BaseParameters.groupings``).
    given, recovered : the coefficient before and after.
    std : its (pseudo) standard deviation used for weighting.
    """

    index: int
    name: str
    grouping: str
    given: float
    recovered: float
    std: float

    @property
    def change(self) -> float:
        return self.recovered - self.given

    @property
    def sigmas(self) -> float:
        """The change in standard deviations."""
        return self.change / self.std

    @property
    def relative(self) -> float:
        """The change relative to ``|given|`` (``inf`` for a zero coefficient)."""
        return self.change / abs(self.given) if self.given != 0 else float("inf")

    def __str__(self) -> str:
        return (f"β{self.index + 1} = {self.grouping}: {self.given:.6g} → {self.recovered:.6g} "
                f"({self.change:+.3g}, {self.sigmas:+.2f} σ)")


@dataclass(frozen=True, eq=False)
class RecoveryCheck:
    """Does a recovered set reproduce the coefficients and predict the same torques?

    Attributes
    ----------
    max_abs_residual : ``max |Bπ − β̂|`` (mixed SI units).
    max_scaled_residual : ``max |Bπ − β̂| / max(|β̂|, 1)``: the figure compared with ``tol``.
    min_margin : smallest pseudo-inertia eigenvalue over the bodies (kg·m² or kg).
    torque_difference : ``max |Y π − W_b β̂|`` per joint on the dataset given to
        :meth:`RecoveryResult.check`, else ``None``.
    ok : residual within ``tol`` (exact mode only; always ``True`` for nearest), every body
        consistent.
    """

    max_abs_residual: float
    max_scaled_residual: float
    min_margin: float
    torque_difference: np.ndarray | None
    ok: bool

    def __str__(self) -> str:
        torque = ("" if self.torque_difference is None else
                  f", max torque difference {np.max(self.torque_difference):.3g} N·m")
        return (f"{'ok' if self.ok else 'FAILED'}: max |Bπ − β̂| = {self.max_abs_residual:.3g} "
                f"(scaled {self.max_scaled_residual:.3g}), min pseudo-inertia eigenvalue "
                f"{self.min_margin:.3g}{torque}")


@dataclass(frozen=True, eq=False)
class RecoveryResult(StandardParameterSet):
    """Standard parameters recovered from base coefficients.

    Attributes
    ----------
    mode, prior : as requested.
    model, spec, base : the robot, its regressor spec and the base map ``β = B π``.
    parameters : (p,) standard parameters (10 per body, then friction/armature), named by
        ``parameter_names``.
    prior_parameters : (p,) the prior ``π₀``.
    given : (b,) the coefficients ``β̂`` to reproduce.
    std : (b,) their standard deviations (from the covariance, else pseudo ones, see
        :data:`RELATIVE_STD`) used for weighting and for :class:`CoefficientMove`.
    margins : (nbodies,) smallest eigenvalue of each body's pseudo-inertia ``J_i``.
    divergences : (nbodies,) prior divergence of each body (log-det, or the Euclidean form).
    distance : weighted squared distance ``‖L(Bπ − β̂)‖²`` (χ² units with a covariance).
    moves : coefficients moved by more than :data:`MOVE_THRESHOLD` σ, largest first (nearest mode;
        empty in exact mode).
    solver : one :class:`SolverReport` per solved stage.
    """

    mode: str
    prior: str
    model: RobotModel
    spec: RegressorSpec
    base: BaseParameters
    parameters: np.ndarray
    parameter_names: tuple[str, ...]
    prior_parameters: np.ndarray
    given: np.ndarray
    std: np.ndarray
    margins: np.ndarray
    divergences: np.ndarray
    distance: float
    moves: tuple[CoefficientMove, ...]
    solver: tuple[SolverReport, ...]
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def recovered_base(self) -> np.ndarray:
        """``B π``: the base coefficients of the recovered set."""
        return self.base.project(self.parameters)

    @property
    def residual(self) -> np.ndarray:
        """``B π − β̂``, (b,)."""
        return self.recovered_base - self.given

    def check(self, dataset: Dataset | None = None, tol: float = 1e-6) -> RecoveryCheck:
        """Compare ``B π`` with ``β̂`` and, given a dataset, ``Y π`` with ``W_b β̂``.

        ``tol`` bounds ``max |Bπ − β̂| / max(|β̂|, 1)`` in exact mode.
        """
        res = np.abs(self.residual)
        scaled = float(np.max(res / np.maximum(np.abs(self.given), 1.0)))
        torque = None
        if dataset is not None:
            y = dataset_regressor(self.model, dataset, self.spec)
            diff = y @ self.parameters - self.base.base_columns(y) @ self.given
            torque = np.max(np.abs(diff.reshape(dataset.n_samples, self.model.nv)), axis=0)
        ok = self.is_consistent and (self.mode == "nearest" or scaled <= tol)
        return RecoveryCheck(float(res.max()), scaled, float(self.margins.min()), torque, ok)

    def summary(self, max_rows: int | None = None) -> str:
        """Solver, residual, per-body margins and (nearest mode) the moved coefficients (at most
        ``max_rows`` of them; ``None``: all, as :meth:`IdentificationResult.summary`)."""
        from ..identification.summary import table

        lines = [f"consistid recovery of {self.model.name!r}: mode={self.mode}, "
                 f"prior={self.prior}, {self.base.n_base} base coefficients → "
                 f"{len(self.parameters)} standard parameters"]
        lines += [f"solver        {s}" for s in self.solver]
        lines.append(f"residual      max |Bπ − β̂| = {np.abs(self.residual).max():.3g}, "
                     f"weighted distance {self.distance:.4g}")
        lines += ["", table(["body", "mass [kg]", "min eig J", "divergence"],
                            [(b, self.parameters[10 * i], self.margins[i], self.divergences[i])
                             for i, b in enumerate(self.model.body_names)])]
        if self.moves:
            shown = self.moves if max_rows is None else self.moves[:max_rows]
            lines += ["", f"{len(self.moves)} coefficient(s) moved by more than "
                      f"{MOVE_THRESHOLD:g} σ:",
                      table(["coefficient", "grouping", "given", "recovered", "change", "σ"],
                            [(f"β{m.index + 1}", _shorten(m.grouping, 50), m.given, m.recovered,
                              m.change, f"{m.sigmas:+.2f}") for m in shown])]
            if len(shown) < len(self.moves):
                lines.append(f"… {len(self.moves) - len(shown)} more")
        lines += ["", "Notes:", f"  - physical consistency: {self.consistency}"]
        if self.details.get("pseudo_std"):
            lines.append(f"  - the covariance leaves {len(self.details['pseudo_std'])} "
                         f"coefficient(s) undetermined (infinite variance: "
                         f"{', '.join(self.details['pseudo_std'][:6])}"
                         f"{' …' if len(self.details['pseudo_std']) > 6 else ''}); they are "
                         f"weighted with pseudo standard deviations {RELATIVE_STD:g}·|β| + "
                         f"{ABSOLUTE_STD:g}")
        flat = _flat_bodies(self.model, self.prior_parameters)
        if flat:
            lines.append(f"  - nearly flat prior bodies {flat} (cond(J₀) > {FLAT_PRIOR:.0e}): a "
                         "log-det prior keeps their thickness; large divergences there mean the "
                         "coefficients ask for a thicker body")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary(max_rows=20)


#: Largest base coefficient accepted (SI units): beyond it the coefficients cannot be a robot's,
#: and the solver's arithmetic breaks down (a Clarabel panic at 1e300).
MAX_COEFFICIENT = 1e10


def _shorten(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


# --------------------------------------------------------------------------------- the problem
@dataclass(frozen=True, eq=False)
class _Problem:
    """Everything the conic stages share (built once)."""

    model: RobotModel
    spec: RegressorSpec
    base: BaseParameters
    beta: np.ndarray
    std: np.ndarray
    weight: np.ndarray        # L with LᵀL = Σ⁻¹, (b, b)
    prior: np.ndarray
    prior_kind: str
    margin: float
    joint_constraints: bool
    undetermined: tuple[str, ...]  # coefficients weighted by pseudo std (infinite variance)

    @property
    def n_inertial(self) -> int:
        return self.model.n_inertial

    def variables(self) -> tuple[cp.Variable, list[cp.Constraint], cp.Expression]:
        """The variable π, the consistency constraints, and the prior objective."""
        x = cp.Variable(self.base.n_standard)
        constraints: list[cp.Constraint] = []
        objective: cp.Expression = cp.Constant(0.0)
        for i, body in enumerate(self.model.body_names):
            xi, pi = x[body_slice(i)], self.prior[body_slice(i)]
            # J ⪰ margin·J₀ (⟺ L₀⁻¹ J L₀⁻ᵀ ⪰ margin·1): the SDP's relative margin
            constraints += body_constraints(xi, "pseudo-inertia",
                                            relative_bound(pi, "pseudo-inertia", self.margin),
                                            scaling=BodyScaling.from_reference(pi))
            objective = objective + (logdet_divergence(xi, pi) if self.prior_kind == "logdet"
                                     else euclidean(xi, pi, euclidean_weights(pi)))
        n_joint = self.base.n_standard - self.n_inertial
        if n_joint:
            f, f0 = x[self.n_inertial:], self.prior[self.n_inertial:]
            objective = objective + euclidean(f, f0)
            if self.joint_constraints:
                keep = self.spec.nonnegative_columns
                if keep.size:
                    constraints.append(f[keep] >= 0)
        return x, constraints, objective

    def label(self, what: str) -> str:
        """``what`` plus, for the log-det prior, the nearly flat prior bodies that stiffen it."""
        flat = _flat_bodies(self.model, self.prior)
        if self.prior_kind != "logdet" or not flat:
            return what
        return (f"{what} [log-det prior with nearly flat prior bodies {flat} (λ_min/λ_max(J₀) < "
                f"{1 / FLAT_PRIOR:.0e}): it resists any change of their thickness; consider "
                "prior='euclidean' or a thicker prior]")

    def misfit(self, x: cp.Expression) -> cp.Expression:
        """``L (B π − β̂)``."""
        return self.weight @ (self.base.matrix @ x - self.beta)


def _flat_bodies(model: RobotModel, prior: np.ndarray) -> list[str]:
    out = []
    for i, body in enumerate(model.body_names):
        eig = np.linalg.eigvalsh(pseudo_inertia(prior[body_slice(i)]))
        if eig[-1] > FLAT_PRIOR * eig[0]:
            out.append(body)
    return out


def euclidean_weights(prior: np.ndarray) -> np.ndarray:
    r"""Per-parameter weights ``1/s`` of the Euclidean prior for one body, ``s`` its natural scale.

    ``s = [m₀, m₀ℓ·1₃, m₀ℓ²·1₆]`` with ``ℓ = √(tr I₀ / 2m₀)`` the prior's radius of gyration
    about the body origin, so that ``Σ ((π − π₀)/s)²`` is a unit-free relative distance. (The
    whitened metric ``‖L₀⁻¹(J − J₀)L₀⁻ᵀ‖_F`` is unit-free too, but on a nearly flat prior body such
    as the Panda's link 2, ``λ_min(J₀)/λ_max(J₀) ≈ 1e-6``, it spans 12 orders of magnitude and
    stalls the interior-point solver.)
    """
    m0 = prior[0]
    ell2 = (prior[4] + prior[6] + prior[9]) / (2.0 * m0)
    return 1.0 / np.concatenate([[m0], np.full(3, m0 * np.sqrt(ell2)), np.full(6, m0 * ell2)])



def _weights(beta: np.ndarray, covariance: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(std, L, undetermined)`` from a covariance (full or variances), else pseudo standard
    deviations.

    Coefficients with infinite variance (an SDP's covariance marks the directions its data do
    not excite so, :func:`consistid.identification.sdp.identify_sdp`) get the pseudo standard
    deviation and no
    correlation; ``undetermined`` flags them.
    """
    b = beta.size
    pseudo = RELATIVE_STD * np.abs(beta) + ABSOLUTE_STD
    if covariance is None:
        return pseudo, np.diag(1.0 / pseudo), np.zeros(b, dtype=bool)
    try:
        cov = np.array(covariance, dtype=float)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"covariance must be numbers, shape ({b}, {b}) or ({b},): {exc}") from exc
    if cov.shape == (b,):
        cov = np.diag(cov)
    if cov.shape != (b, b) or np.any(np.isnan(cov)):
        raise OptionError(f"covariance must have shape ({b}, {b}) or ({b},) and no NaN, got "
                          f"{cov.shape}")
    undetermined = np.isposinf(np.diag(cov))
    if not np.all(np.isfinite(cov[np.ix_(~undetermined, ~undetermined)])):
        raise OptionError("covariance has infinite entries outside the rows and columns of "
                          "coefficients with infinite variance")
    cov[undetermined, :] = 0.0
    cov[:, undetermined] = 0.0
    cov[undetermined, undetermined] = pseudo[undetermined] ** 2
    cov = 0.5 * (cov + cov.T)
    try:
        chol = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError as exc:
        raise OptionError("covariance is not positive definite (min eigenvalue "
                          f"{np.linalg.eigvalsh(cov)[0]:.3g})") from exc
    return np.sqrt(np.diag(cov)), np.linalg.inv(chol), undetermined


def _matching_settings(model: RobotModel, n_base: int) -> str:
    """Which common ``friction``/``armature`` settings give ``n_base`` base coefficients.

    One base map with every per-joint column suffices: ``rank Y[:, S] = rank B[:, S]`` for any
    column subset ``S`` (``Y = W_b B`` with ``W_b`` of full column rank).
    """
    full_spec = RegressorSpec.make(model, FRICTION_TERMS, True)
    full = compute_base_parameters(model, full_spec)
    index = {name: k for k, name in enumerate(parameter_names(model, full_spec))}
    matches = matching_settings(model, lambda spec: np.linalg.matrix_rank(
        full.matrix[:, [index[n] for n in parameter_names(model, spec)]]) == n_base)
    if not matches:
        return ("No combination of per-joint terms gives that many: are these coefficients "
                f"of {model.name!r}, in consistid's base map?")
    return "Settings that give that many: " + "; ".join(matches[:4]) + (
        " …" if len(matches) > 4 else "") + " (pass base= for another base map)"


def _moves(problem: _Problem, recovered: np.ndarray, threshold: float
           ) -> tuple[CoefficientMove, ...]:
    names, groups = problem.base.names, problem.base.groupings
    out = [CoefficientMove(i, names[i], groups[i], float(problem.beta[i]), float(recovered[i]),
                           float(problem.std[i]))
           for i in range(problem.beta.size)
           if abs(recovered[i] - problem.beta[i]) > threshold * problem.std[i]]
    return tuple(sorted(out, key=lambda m: -abs(m.sigmas)))


def _diagnose_infeasibility(problem: _Problem, solver: str = DEFAULT_SOLVER,
                           options: dict[str, Any] | None = None
                           ) -> tuple[tuple[CoefficientMove, ...], SolverReport]:
    """The smallest weighted-L1 change ``Σ |Δβ_i| / σ_i`` that makes ``β̂`` realisable.

    L1 concentrates the change on few coefficients: those no consistent set can meet. (The
    minimiser need not be unique; the coefficients named are one smallest explanation.)
    """
    x, constraints, _ = problem.variables()
    change = problem.base.matrix @ x - problem.beta
    # A diagnosis: the L1 optimum is needed to well within the reported moves only.
    options1 = {**NEAREST_CLARABEL, **(options or {})} if solver == "CLARABEL" else options
    report = solve(cp.Problem(cp.Minimize(cp.norm1(cp.multiply(1.0 / problem.std, change))),
                              constraints), "infeasibility diagnosis", solver, options1)
    return _moves(problem, problem.base.matrix @ x.value, 1e-4), report


def _finish(problem: _Problem, mode: str, x: np.ndarray, reports: tuple[SolverReport, ...],
            details: dict[str, Any]) -> RecoveryResult:
    model = problem.model
    x = np.array(x, dtype=float)
    if problem.joint_constraints:
        # Entries constrained ≥ 0 come back within the solver's feasibility tolerance, e.g.
        # −8e-10; set those (only those) to 0 so that exporters see the sign the constraint gave.
        keep = model.n_inertial + problem.spec.nonnegative_columns
        low = x[keep]
        if np.any(low < -NONNEGATIVE_ROUNDOFF):
            raise IdentificationError(
                f"solver returned {problem.base.standard_names[keep[np.argmin(low)]]} = "
                f"{low.min():.3g} despite the constraint ≥ 0")
        details["clipped_to_zero"] = int(np.sum(low < 0))
        x[keep] = np.maximum(low, 0.0)
    if problem.undetermined:
        details["pseudo_std"] = problem.undetermined
    margins, divergences = np.empty(model.n_bodies), np.empty(model.n_bodies)
    for i in range(model.n_bodies):
        xi, pi = x[body_slice(i)], problem.prior[body_slice(i)]
        margins[i] = np.linalg.eigvalsh(pseudo_inertia(xi))[0]
        divergences[i] = (logdet_divergence_value(xi, pi) if problem.prior_kind == "logdet"
                          else float(np.sum((euclidean_weights(pi) * (xi - pi)) ** 2)))
    recovered = problem.base.project(x)
    misfit = problem.weight @ (recovered - problem.beta)
    moves = _moves(problem, recovered, MOVE_THRESHOLD) if mode == "nearest" else ()
    return RecoveryResult(
        mode=mode, prior=problem.prior_kind, model=model, spec=problem.spec, base=problem.base,
        parameters=x, parameter_names=tuple(parameter_names(model, problem.spec)),
        prior_parameters=problem.prior, given=problem.beta, std=problem.std, margins=margins,
        divergences=divergences, distance=float(misfit @ misfit), moves=moves, solver=reports,
        details=details)


def _far_from_prior(problem: _Problem, exc: IdentificationError) -> IdentificationError:
    """The error for a solver failure on realisable coefficients: if some coefficient is far
    (> 100×) from the prior's, name it; if the whole robot is far from the kilogram scale, say
    so — valid but extreme scaling, not a solver to swap."""
    prior_beta = problem.base.project(problem.prior)
    scale = np.maximum(np.abs(prior_beta), 1e-3 * max(np.max(np.abs(prior_beta)), 1e-12))
    ratio = np.abs(problem.beta - prior_beta) / scale
    k = int(np.argmax(ratio))
    if ratio[k] <= 100:
        masses = np.abs(problem.prior[: problem.model.n_inertial: 10])
        unit = float(np.max(masses)) if masses.size else 1.0
        if 1e-3 <= unit <= 1e3:
            return exc
        return type(exc)(
            f"{exc}. The coefficients match the prior's scale, but the bodies weigh up to "
            f"{unit:.3g} kg, far from the ~1 kg scale the solver's tolerances suit: the failure "
            "is one of scale, not of the data. Express the robot in other units (scale the "
            "masses and inertias, and the coefficients, by the same factor) and scale back")
    return type(exc)(
        f"{exc}. The coefficients look realisable but far from the prior: β[{k}] "
        f"({problem.base.groupings[k]}) = {problem.beta[k]:.4g} against the prior's "
        f"{prior_beta[k]:.4g} ({ratio[k]:.3g}× its scale), so the consistent set lies far "
        "outside the scale the program is built on. Check the coefficients' units and "
        "origin, or pass prior_parameters= of a robot of that size")


def _exact(problem: _Problem, solver: str, options: dict[str, Any] | None) -> RecoveryResult:
    x, constraints, objective = problem.variables()
    B = problem.base.matrix
    rows = np.linalg.norm(B, axis=1)
    constraints.append((B / rows[:, None]) @ x == problem.beta / rows)
    try:
        report = solve(cp.Problem(cp.Minimize(objective), constraints),
                       problem.label("exact recovery"), solver, options)
    except IdentificationError as exc:
        # A solver that fails without proving infeasibility (status "solver_error", a crash) is
        # often facing unrealisable coefficients too: the L1 diagnosis (always feasible) tells
        # which, so the message blames the coefficients, not the solver, when they are the cause.
        try:
            moves, _ = _diagnose_infeasibility(problem, solver, options)
        except IdentificationError:
            if not isinstance(exc, InfeasibleError):
                raise _far_from_prior(problem, exc) from exc
            moves = ()
        if not moves and not isinstance(exc, InfeasibleError):
            raise _far_from_prior(problem, exc) from exc
        listed = "; ".join(str(m) for m in moves[:8])
        more = f" (and {len(moves) - 8} more)" if len(moves) > 8 else ""
        proof = ("" if isinstance(exc, InfeasibleError) else
                 "; the solver stopped without proving it, the L1 diagnosis below shows it")
        raise UnrealizableCoefficientsError(
            f"no physically consistent standard parameters reproduce these {problem.beta.size} "
            f"base coefficients ({exc}{proof}). Smallest changes that make them realisable: "
            f"{listed or 'not found'}{more}. Use mode='nearest' to get the closest consistent "
            "set.", moves) from exc
    return _finish(problem, "exact", x.value, (report,), {})


def _nearest(problem: _Problem, slack: float, solver: str, options: dict[str, Any] | None
             ) -> RecoveryResult:
    x1, constraints1, _ = problem.variables()
    # The distance alone leaves the null space of B free (and unbounded), which stalls an
    # interior-point method; a tiny well-conditioned pull to the prior fixes it and can only
    # raise d* (the stage-1 point stays feasible for stage 2).
    tie = STAGE1_TIE * sum(euclidean(x1[body_slice(i)], problem.prior[body_slice(i)],
                                     euclidean_weights(problem.prior[body_slice(i)]))
                           for i in range(problem.model.n_bodies))
    # Both stages end on the boundary of the cone, where Clarabel's gap and residuals stall
    # near 1e-6..1e-8 ("AlmostSolved"); ask for what is needed (NEAREST_CLARABEL).
    options1 = {**NEAREST_CLARABEL, **(options or {})} if solver == "CLARABEL" else options
    stage1 = solve(cp.Problem(cp.Minimize(cp.sum_squares(problem.misfit(x1)) + tie),
                              constraints1), "nearest recovery (stage 1: distance)", solver,
                   options1)
    d_star = float(np.sum((problem.weight @ (problem.base.project(x1.value) - problem.beta)) ** 2))
    x2, constraints2, objective = problem.variables()
    bound = d_star * (1.0 + SLACK_RTOL) + slack
    # normalised to 1 so that the cone's scale does not depend on how misfit β̂ is
    constraints2.append(cp.sum_squares(problem.misfit(x2) / np.sqrt(bound)) <= 1.0)
    try:
        stage2 = solve(cp.Problem(cp.Minimize(objective), constraints2),
                       problem.label("nearest recovery (stage 2: prior)"), solver, options1)
    except SolverError as exc:
        if problem.prior_kind != "logdet":
            raise
        # the stage-1 point exists; the log-det barrier's exponential
        # cones are what the solver could not handle (coefficients moved far, bodies far from
        # the prior), and the Euclidean prior, without them, usually solves
        raise SolverError(f"{exc}. Stage 1 found the nearest realisable coefficients "
                          f"(weighted distance {d_star:.3g}); only the log-det prior stage "
                          "failed: prior='euclidean' solves the same stage without exponential "
                          "cones") from exc
    return _finish(problem, "nearest", x2.value, (stage1, stage2),
                   {"stage1_distance": d_star, "slack": slack})


def recover_standard(model: RobotModel, base_params: np.ndarray | IdentificationResult,
                     prior: str = "logdet", mode: str = "exact", *,
                     base: BaseParameters | None = None,
                     covariance: np.ndarray | None = None,
                     friction: FrictionArg | str = "auto",
                     armature: bool | Sequence[int | str] | str = "auto",
                     prior_parameters: np.ndarray | None = None, margin: float = 1e-6,
                     slack: float = 1.0, joint_constraints: bool = True,
                     solver: str = DEFAULT_SOLVER,
                     solver_options: dict[str, Any] | None = None) -> RecoveryResult:
    """Physically consistent standard parameters with the given base coefficients.

    Parameters
    ----------
    model : the robot; its URDF inertias are the default prior ``π₀``.
    base_params : (b,) base coefficients ``β̂``, or an :class:`IdentificationResult` (whose base
        map, spec, coefficients, covariance and prior are then used).
    prior : ``"logdet"`` (log-det divergence of pseudo-inertias, default) or ``"euclidean"``
        (relative squared distance per parameter, see :func:`euclidean_weights`).
    mode : ``"exact"`` (``B π = β̂``) or ``"nearest"`` (closest realisable coefficients).
    base : the base map the coefficients refer to; default
        ``compute_base_parameters(model, RegressorSpec.make(model, friction, armature))``.
        Coefficients from elsewhere must be expressed in this map (check ``base.groupings``).
    covariance : (b, b) or (b,) covariance of ``β̂``; default that of the result, else pseudo
        standard deviations ``1 % |β̂| + 1e-6`` (see :data:`RELATIVE_STD`). Coefficients with
        infinite variance (e.g. an SDP result's unexcited directions) get the pseudo ones too
        (named in ``details["pseudo_std"]`` and the summary).
    friction, armature : per-joint columns (see :meth:`RegressorSpec.make`). ``"auto"``
        (default): the result's columns, or for an array those of ``identify``'s default
        (``friction=("coulomb", "viscous", "offset")``, no armature); with a result, an explicit
        value must describe its columns (:func:`consistid.identification.regressor.resolve_spec`).
    prior_parameters : (p,) prior ``π₀`` (default the URDF, zero friction/armature); every body
        must be realisable (``J₀ ≻ 0``).
    margin : require ``J_i ⪰ margin · J_i(π₀)``: a relative margin, by default ``1e-6``, so that
        solver round-off (≈1e-8 in the scaled LMI) cannot leave a body with a slightly negative
        eigenvalue (the Euclidean prior, which has no barrier, ends on the boundary otherwise).
        ``0`` allows bodies on the boundary of consistency.
    slack : nearest mode: extra weighted squared distance (χ² units with a covariance) allowed
        to the prior stage beyond ``d*(1 + 1e-3)``.
    joint_constraints : keep the :data:`~consistid.identification.regressor.NONNEGATIVE_TERMS`
        entries
        (Coulomb, viscous, armature) ``≥ 0`` (solver round-off
        down to ``−NONNEGATIVE_ROUNDOFF`` is set to 0; counted in ``details``).
    solver, solver_options : cvxpy solver (default Clarabel) and its options.

    Returns
    -------
    RecoveryResult

    Raises
    ------
    UnrealizableCoefficientsError
        exact mode, when no consistent set has these coefficients; lists the coefficients that
        must move and by how much.
    OptionError, ModelError
        bad options, or coefficients that do not fit the base map.
    InfeasibleError, IdentificationError
        the solver proved infeasibility (e.g. a margin too large) or failed; inaccurate solves
        warn with :class:`~consistid.errors.InaccurateSolutionWarning`.
    """
    require_model(model)
    check_option("mode", mode, MODES)
    check_option("prior", prior, PRIORS)
    solver = check_solver(solver)
    if isinstance(base_params, IdentificationResult):
        if base is not None:
            raise OptionError("base is taken from the IdentificationResult; do not pass it")
        res = base_params
        if tuple(res.parameter_names[: model.n_inertial]) != tuple(model.parameter_names):
            raise ModelError(f"the identification result is for {res.model.name!r}, whose "
                             f"parameters differ from {model.name!r}'s")
        spec = resolve_spec(model, friction, armature, given=res.spec)
        base, beta = res.base, np.asarray(res.base_parameters, dtype=float)
        if covariance is None:
            covariance = res.base_covariance
        default_prior = res.prior
    else:
        spec = resolve_spec(model, friction, armature)
        try:
            beta = np.asarray(base_params, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"base coefficients must be numbers (or an IdentificationResult), "
                             f"got {base_params!r}") from exc
        if base is None:
            base = compute_base_parameters(model, spec)
            if beta.ndim == 1 and beta.size != base.n_base:
                raise ModelError(
                    f"{beta.size} base coefficients, but {model.name!r} with {spec.describe()} "
                    f"has {base.n_base}. {_matching_settings(model, beta.size)}")
        default_prior = prior_vector(model, spec)
    names = parameter_names(model, spec)
    if tuple(base.standard_names) != tuple(names):
        raise ModelError(f"the base map has {base.n_standard} standard columns "
                         f"({base.standard_names[-1]!r} last) but the model and spec give "
                         f"{len(names)} ({names[-1]!r} last)")
    if beta.shape != (base.n_base,) or not np.all(np.isfinite(beta)):
        where = ""
        if beta.shape == (base.n_base,):
            k = int(np.flatnonzero(~np.isfinite(beta))[0])
            where = f"; β[{k}] ({base.names[k]}) is {beta[k]}"
        raise ModelError(f"base coefficients must be {base.n_base} finite numbers (the base map "
                         f"of {model.name!r} with {spec.describe()}), got shape "
                         f"{beta.shape}{where}")
    if np.max(np.abs(beta)) > MAX_COEFFICIENT:
        k = int(np.argmax(np.abs(beta)))
        raise ModelError(f"base coefficient β[{k}] ({base.groupings[k]}) = {beta[k]:.3g} is beyond "
                         f"±{MAX_COEFFICIENT:.0e}: no robot's mass or inertia in SI units (kg, "
                         "kg·m, kg·m²); check the units and where the coefficients came from")
    pi0 = default_prior if prior_parameters is None else np.asarray(prior_parameters, float)
    if pi0.shape != (len(names),) or not np.all(np.isfinite(pi0)):
        raise ModelError(f"prior_parameters must be {len(names)} finite numbers, got shape "
                         f"{pi0.shape}")
    margin, slack = check_number("margin", margin, 0), check_number("slack", slack, 0, strict=True)
    prior_check = is_physically_consistent(pi0[: model.n_inertial], "pseudo-inertia",
                                           model.body_names)
    bad = [b.body for b in prior_check.bodies if not b.min_pseudo_inertia_eigenvalue > 0]
    if bad:
        raise InconsistentParametersError(
            f"prior bodies {bad} have a singular or indefinite pseudo-inertia ({prior_check}); "
            "recovery needs a realisable prior with positive volume: pass prior_parameters")
    std, weight, undetermined = _weights(beta, covariance)
    problem = _Problem(model, spec, base, beta, std, weight, pi0, prior, margin, joint_constraints,
                       tuple(str(n) for n, u in zip(base.names, undetermined) if u))
    result = (_exact(problem, solver, solver_options) if mode == "exact"
              else _nearest(problem, slack, solver, solver_options))
    _warn_if_inconsistent(result)
    return result


def _warn_if_inconsistent(result: RecoveryResult) -> None:
    """Both modes promise a physically consistent set: when the solver's answer is not one
    (round-off on the constraints of bodies scaled far from their prior), say so by name
    instead of returning it as if it were."""
    if result.is_consistent:
        return
    bad = [b for b in result.consistency.bodies if not b.ok]
    worst = max((b for b in result.consistency.bodies), key=lambda b: abs(b.mass))
    warnings.warn(
        f"recovery ({result.mode}) returned standard parameters that are not physically "
        f"consistent although the solver reported {result.solver[-1].status!r}: "
        + "; ".join(b.reason for b in bad[:3])
        + f". The heaviest body is {worst.body} at {worst.mass:.4g} kg: the constraints hold "
        "only to solver round-off at this scale. Do not export these parameters; check the "
        "coefficients (and their covariance) or raise margin=", InaccurateSolutionWarning,
        stacklevel=3)
