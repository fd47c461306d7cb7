r"""Optimal excitation design: minimise an excitation criterion subject to the robot's limits.

The problem (Swevers et al. 1997, doi:10.1109/70.631234; Rackl et al. 2012,
doi:10.1109/ICRA.2012.6225279, §III):

.. math::

    \min_X\; J\bigl(Σ^{-1/2} Y_b(q(t_i), \dot q(t_i), \ddot q(t_i))\, D\bigr)
    \quad\text{s.t.}\quad g_r(q(t_i), \dot q(t_i), \ddot q(t_i)) \ge \text{safety}\cdot s_r

over the coefficients ``X`` of a trajectory :class:`~.trajectory.Parameterisation`, with ``J`` one
of :mod:`~.criteria` and ``g_r`` the margins of :mod:`~.limits` (scales ``s_r``), both on a coarse
grid ``t_i`` of ``n_grid`` samples. Joint limits are linear in ``X``; the torque and Cartesian
margins and the criterion are nonlinear, with gradients from Pinocchio (RNEA derivatives, frame
Jacobians) and per-sample finite differences of the regressor
(:func:`~.criteria.regressor_sensitivity`). SLSQP is the default (≈ 0.1–0.2 s per iteration for
the Panda with 5 harmonics and ``n_grid = 150``); trust-constr works too but is several times
slower per start. The result of every start is verified on a dense grid (``n_check`` samples).

Multi-start (Rackl et al. 2012 §III-C): every start is a random *feasible* trajectory — a random
rest pose plus a random motion direction scaled to the largest amplitude that satisfies all
constraints (:func:`random_feasible`).
"""

from __future__ import annotations

import logging
import warnings
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import scipy.optimize
import scipy.sparse

from ..identification.base import BaseParameters, compute_base_parameters
from ..data.dataset import Dataset
from ..errors import (
    InfeasibleExcitationError,
    OptionError,
    PoorExcitationWarning,
    check_number,
    check_seed,
    check_option,
)
from ..report.html import Page
from ..report.result import Reported
from ..progress import Progress
from ..threads import single_blas_thread
from ..robot.model import RobotModel, require_model
from ..identification.regressor import FrictionArg, RegressorSpec, prior_vector, regressor
from .criteria import CRITERIA, criteria_values, criterion_and_gradient, prior_column_scale
from .criteria import regressor_sensitivity
from .limits import ConstraintBlock, ConstraintReport, ConstraintSet, ExcitationLimits
from .trajectory import (MAX_SAMPLE_BYTES, BoundaryConditions, BSplineParameterisation,
                         FourierPolynomial,
                         Parameterisation, Trajectory, position_range)

logger = logging.getLogger(__name__)

METHODS = ("SLSQP", "trust-constr")
TRAJECTORIES = ("fourier", "bspline")


# --------------------------------------------------------------------------------- assessment
@dataclass(frozen=True)
class ExcitationQuality:
    """How well a trajectory excites the base parameters, and its constraint margins.

    Attributes
    ----------
    cond : condition number of the *unscaled, unweighted* base regressor ``Y_b`` over one period
        (what :attr:`IdentificationResult.condition_number` reports for OLS on these samples).
    criteria : ``cond``, ``d-opt``, ``e-opt`` of the weighted, column-scaled regressor
        ``Σ^{-1/2} Y_b D`` the design optimises (the unscaled ones when neither ``noise_std`` nor
        ``column_scale`` is given).
    constraints : worst margins on the same samples.
    n_samples : samples over one period.
    """

    cond: float
    criteria: dict[str, float]
    constraints: ConstraintReport
    n_samples: int


def _grid(param: Parameterisation, n: int) -> np.ndarray:
    return np.linspace(0.0, param.duration, n, endpoint=not param.periodic)


def assess_excitation(model: RobotModel, trajectory: Trajectory,
                      limits: ExcitationLimits | None = None,
                      friction: FrictionArg = ("coulomb", "viscous", "offset"),
                      armature: bool | Sequence[int | str] = False, n_samples: int = 2000,
                      base: BaseParameters | None = None,
                      noise_std: float | Sequence[float] | None = None,
                      column_scale: str | np.ndarray | None = None) -> ExcitationQuality:
    """Excitation criteria and constraint margins of ``trajectory`` on ``n_samples`` samples of
    one period (the dense check of :func:`design_excitation`)."""
    spec = RegressorSpec.make(model, friction, armature)
    base = base or compute_base_parameters(model, spec)
    limits = limits or ExcitationLimits.from_model(model)
    t = _grid(trajectory.parameterisation, n_samples)
    q, dq, ddq = trajectory.evaluate(t)
    yb = base.base_columns(regressor(model, q, dq, ddq, spec))
    row_w, col_s = _weights(model, base, spec, noise_std, column_scale)
    weighted = (yb.reshape(t.size, model.nv, -1) * row_w[:, None]).reshape(yb.shape) * col_s
    crit = criteria_values(weighted, t.size)
    cond = criteria_values(yb, t.size)["cond"]
    report = ConstraintSet(model, limits).report(t, q, dq, ddq)
    return ExcitationQuality(cond, crit, report, int(t.size))


def _weights(model: RobotModel, base: BaseParameters, spec: RegressorSpec,
             noise_std: float | Sequence[float] | None,
             column_scale: str | np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Row weights ``1/σ_j`` (nv,) and column scales (b,)."""
    sigma = np.ones(model.nv) if noise_std is None else np.broadcast_to(
        np.asarray(noise_std, dtype=float), (model.nv,)).copy()
    if not np.all(sigma > 0):
        raise OptionError(f"noise_std must be positive per joint, got {sigma}")
    if column_scale is None:
        scale = np.ones(base.n_base)
    elif isinstance(column_scale, str):
        check_option("column_scale", column_scale, ("prior",))
        scale = prior_column_scale(model, base, spec)
    else:
        scale = np.asarray(column_scale, dtype=float)
        if scale.shape != (base.n_base,) or not np.all(scale > 0):
            raise OptionError(f"column_scale must be 'prior' or {base.n_base} positive numbers")
    return 1.0 / sigma, scale


# --------------------------------------------------------------------------------- the problem
class _FeasibilityProblem:
    """The constraints on the coarse grid (margins and Jacobians), cached per point."""

    def __init__(self, model: RobotModel, param: Parameterisation, constraints: ConstraintSet,
                 n_grid: int, safety: float) -> None:
        self.model, self.param, self.constraints = model, param, constraints
        self.safety = float(safety)
        self.t = _grid(param, n_grid)
        self.G, self.O = param.basis(self.t)
        self.shape = (param.nv, param.n_coefficients)
        lin = constraints.blocks(self.O[0], self.O[1], self.O[2], derivatives=True, linear=True)
        self.A_lin, self.b_lin = self._stack(lin)
        self.has_nonlinear = constraints.limits.checks_torque or bool(constraints.cartesian)
        self._cache: dict[str, tuple[bytes, object]] = {}

    def _chain(self, block: ConstraintBlock) -> np.ndarray:
        """Jacobian of a block's normalised margins w.r.t. the flat coefficients."""
        d = block.derivative / block.scale[None, :, None, None]          # (N, k, 3, nv)
        jac = np.einsum("irdj,dic->irjc", d, self.G)
        return jac.reshape(-1, self.shape[0] * self.shape[1])

    @staticmethod
    def _values(blocks: list[ConstraintBlock]) -> np.ndarray:
        return np.concatenate([(b.values / b.scale).ravel() for b in blocks] or [np.zeros(0)])

    def _stack(self, blocks: list[ConstraintBlock]) -> tuple[np.ndarray, np.ndarray]:
        if not blocks:
            return np.zeros((0, self.shape[0] * self.shape[1])), np.zeros(0)
        return np.vstack([self._chain(b) for b in blocks]), self._values(blocks)

    def states(self, x: np.ndarray) -> np.ndarray:
        return self.O + np.einsum("dic,jc->dij", self.G, x.reshape(self.shape))

    def _cached(self, name: str, x: np.ndarray, compute: Callable[[np.ndarray], object]):
        key = x.tobytes()
        hit = self._cache.get(name)
        if hit is None or hit[0] != key:
            hit = (key, compute(x))
            self._cache[name] = hit
        return hit[1]

    def linear_margins(self, x: np.ndarray) -> np.ndarray:
        return self.A_lin @ x + self.b_lin

    def nonlinear_margins(self, x: np.ndarray) -> np.ndarray:
        """Normalised torque and Cartesian margins on the grid."""
        def compute(x: np.ndarray) -> np.ndarray:
            s = self.states(x)
            return self._values(self.constraints.blocks(s[0], s[1], s[2], linear=False))
        return self._cached("margins", x, compute)

    def nonlinear_jacobian(self, x: np.ndarray) -> np.ndarray:
        def compute(x: np.ndarray) -> np.ndarray:
            s = self.states(x)
            return self._stack(self.constraints.blocks(s[0], s[1], s[2], derivatives=True,
                                                       linear=False))[0]
        return self._cached("jacobian", x, compute)

    def min_margin(self, x: np.ndarray) -> float:
        """Smallest normalised margin on the grid (≥ safety: feasible for the optimiser)."""
        m = np.concatenate([self.linear_margins(x), self.nonlinear_margins(x)])
        return float(m.min()) if m.size else np.inf


class _DesignProblem(_FeasibilityProblem):
    """Objective, constraints and their gradients on the coarse grid, cached per point."""

    def __init__(self, model: RobotModel, param: Parameterisation, spec: RegressorSpec,
                 base: BaseParameters, constraints: ConstraintSet, criterion: str,
                 row_weight: np.ndarray, col_scale: np.ndarray, torque_weight: float,
                 n_grid: int, safety: float) -> None:
        super().__init__(model, param, constraints, n_grid, safety)
        self.spec, self.base, self.criterion = spec, base, criterion
        self.row_weight, self.col_scale = row_weight, col_scale
        self.torque_weight = float(torque_weight)
        self.prior = prior_vector(model, spec)
        self.n_evaluations = 0
        self.n_gradients = 0

    def _weighted(self, y: np.ndarray) -> np.ndarray:
        """``Σ^{-1/2} Y_b D`` from per-sample regressors (N, nv, p), as (N·nv, b)."""
        a = y[..., self.base.independent] * self.row_weight[None, :, None] * self.col_scale
        return a.reshape(-1, self.base.n_base)

    def _transform(self, value: float) -> float:
        """The well-scaled objective optimised: log κ, −log det F / b, −log λ_min as is."""
        if self.criterion == "cond":
            return float(np.log(value))
        return value / self.base.n_base if self.criterion == "d-opt" else value

    def _regressor(self, x: np.ndarray) -> np.ndarray:
        """The regressor per grid sample, (N, nv, p), computed once per point: the value and
        the gradient at the same ``x`` (SLSQP asks for both at each iterate) share it."""
        def compute(x: np.ndarray) -> np.ndarray:
            s = self.states(x)
            return regressor(self.model, s[0], s[1], s[2], self.spec).reshape(
                self.t.size, self.model.nv, -1)
        return self._cached("regressor", x, compute)

    def _compute_value(self, x: np.ndarray) -> float:
        self.n_evaluations += 1
        y = self._regressor(x)
        value, _ = criterion_and_gradient(self._weighted(y), self.criterion, self.t.size,
                                          gradient=False)
        if self.torque_weight:
            value += self.torque_weight / np.mean(np.abs(y @ self.prior))
        return value

    def _compute_gradient(self, x: np.ndarray) -> np.ndarray:
        """Gradient of the (untransformed) criterion w.r.t. the flat coefficients."""
        self.n_gradients += 1
        s = self.states(x)
        n, nv = self.t.size, self.model.nv
        y, dy = regressor_sensitivity(self.model, s[0], s[1], s[2], self.spec,
                                      y=self._regressor(x))
        value, grad_a = criterion_and_gradient(self._weighted(y), self.criterion, n)
        grad_y = grad_a.reshape(n, nv, -1) * self.row_weight[None, :, None] * self.col_scale
        dstate = np.einsum("ijc,isjc->is", grad_y, dy[..., self.base.independent])  # (N, 3nv)
        if self.torque_weight:
            tau = y @ self.prior                                          # (N, nv)
            mean_abs = np.mean(np.abs(tau))
            value += self.torque_weight / mean_abs
            dmean = np.einsum("ij,isj->is", np.sign(tau), dy @ self.prior) / tau.size
            dstate -= self.torque_weight / mean_abs ** 2 * dmean
        gx = np.einsum("idj,dic->jc", dstate.reshape(n, 3, nv), self.G).ravel()
        if self.criterion == "cond":
            return gx / value
        return gx / self.base.n_base if self.criterion == "d-opt" else gx

    # scipy interfaces: f and its gradient separately, so line searches cost no gradient
    def value(self, x: np.ndarray) -> float:
        """The criterion ``J`` at ``x`` (grid)."""
        return self._cached("value", x, self._compute_value)

    def objective(self, x: np.ndarray) -> float:
        return self._transform(self.value(x))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return self._cached("gradient", x, self._compute_gradient)


# --------------------------------------------------------------------------------- starts
def random_feasible(problem: _FeasibilityProblem, rng: np.random.Generator, max_tries: int = 25
                    ) -> np.ndarray:
    """Flat coefficients of a random trajectory that satisfies every constraint on the grid.

    A rest pose ``q_c`` is drawn uniformly in the middle half of each joint's range (±π/2 for
    unbounded joints, of one turn from the bound for one-sided ones) and a motion direction
    ``d_j`` per joint from :meth:`Parameterisation.random_direction`. Each joint's amplitude
    ``s_j`` is the largest for which its own position/velocity/acceleration limits hold (exact:
    they are linear in ``s_j``); a common factor ``γ ∈ (0, 1]`` is then reduced by bisection
    until the torque and Cartesian constraints hold too: ``X = X_rest(q_c) + γ · diag(s) · D``.

    Raises
    ------
    InfeasibleExcitationError when no rest pose among ``max_tries`` satisfies the constraints.
    """
    param, lim = problem.param, problem.constraints.limits
    nv, nc = problem.shape
    lo, hi = position_range(lim.lower, lim.upper)
    mid, half = 0.5 * (lo + hi), 0.25 * (hi - lo)
    safety, worst = problem.safety, None
    for _ in range(max_tries):
        x0 = param.rest(rng.uniform(mid - half, mid + half)).ravel()
        direction = param.random_direction(rng)
        m0 = problem.linear_margins(x0)
        if m0.size and m0.min() < safety:
            worst = ("joint limits", m0.min())
            continue
        if problem.has_nonlinear and problem.nonlinear_margins(x0).min() < safety:
            worst = ("torque/Cartesian limits", problem.nonlinear_margins(x0).min())
            continue
        d = np.zeros((nv, nc))
        for j in range(nv):                       # joint limits involve one joint's coefficients
            dj = np.zeros((nv, nc))
            dj[j] = direction[j]
            m1 = problem.A_lin @ dj.ravel()
            shrinking = m1 < 0
            s = float(np.min((m0[shrinking] - safety) / -m1[shrinking])) if shrinking.any() else 1.0
            d[j] = s * direction[j]
        d = d.ravel()
        gamma = 1.0
        if problem.has_nonlinear and problem.nonlinear_margins(x0 + d).min() < safety:
            lo_g, hi_g = 0.0, 1.0
            for _ in range(30):
                g = 0.5 * (lo_g + hi_g)
                if problem.nonlinear_margins(x0 + g * d).min() >= safety:
                    lo_g = g
                else:
                    hi_g = g
            gamma = lo_g
        return x0 + gamma * d
    what, value = worst
    raise InfeasibleExcitationError(
        f"no feasible rest pose in {max_tries} random draws: the {what} are violated at rest "
        f"(normalised margin {value:.3g} < safety {safety:g}); relax the limits")


@dataclass(frozen=True, eq=False)
class StartResult:
    """One optimisation start.

    Attributes
    ----------
    index : 0-based start number.
    initial_value, value : criterion at the random feasible start and at the result (grid).
    cond : unscaled base-regressor condition number of the result on the dense grid.
    feasible : every constraint holds on the dense grid.
    min_margin : smallest relative margin on the dense grid.
    iterations, evaluations, gradients : optimiser iterations, criterion and gradient
        evaluations.
    status : the optimiser's message (and whether the best feasible iterate was used).
    seconds : wall time.
    """

    index: int
    initial_value: float
    value: float
    cond: float
    feasible: bool
    min_margin: float
    iterations: int
    evaluations: int
    gradients: int
    status: str
    seconds: float
    coefficients: np.ndarray = field(repr=False)

    def __str__(self) -> str:
        return (f"start {self.index}: {self.initial_value:.4g} → {self.value:.4g} "
                f"(cond {self.cond:.4g}, {'feasible' if self.feasible else 'INFEASIBLE'}, "
                f"min margin {self.min_margin * 100:.2f} %, {self.iterations} it, "
                f"{self.evaluations} f / {self.gradients} ∇f, "
                f"{self.seconds:.1f} s; {self.status})")


def _optimise(problem: _DesignProblem, x0: np.ndarray, method: str, max_iter: int
              ) -> tuple[np.ndarray, int, str]:
    """Run one local optimisation; return the best grid-feasible point visited, its iteration
    count and a status message."""
    tol = 1e-6
    best = {"x": x0.copy(), "f": problem.objective(x0)}

    def track(xk: np.ndarray, *_: object) -> None:
        if problem.min_margin(xk) >= problem.safety - tol:
            f = problem.objective(xk)
            if f < best["f"]:
                best["x"], best["f"] = xk.copy(), f

    nonlinear = problem.has_nonlinear
    if method == "SLSQP":
        cons = [{"type": "ineq", "fun": lambda x: problem.linear_margins(x) - problem.safety,
                 "jac": lambda x: problem.A_lin}]
        if nonlinear:
            cons.append({"type": "ineq",
                         "fun": lambda x: problem.nonlinear_margins(x) - problem.safety,
                         "jac": problem.nonlinear_jacobian})
        res = scipy.optimize.minimize(problem.objective, x0, jac=problem.gradient, method="SLSQP",
                                      constraints=cons, callback=track,
                                      options={"maxiter": max_iter, "ftol": 1e-7})
    else:
        # Sparse Jacobians: the interior-point method then factorises its KKT systems sparsely
        # (joint-limit rows touch one joint's coefficients only); dense ones take minutes.
        cons = [scipy.optimize.LinearConstraint(scipy.sparse.csr_array(problem.A_lin),
                                                problem.safety - problem.b_lin, np.inf)]
        if nonlinear:
            cons.append(scipy.optimize.NonlinearConstraint(
                problem.nonlinear_margins, problem.safety, np.inf,
                jac=lambda x: scipy.sparse.csr_array(problem.nonlinear_jacobian(x))))
        res = scipy.optimize.minimize(problem.objective, x0, jac=problem.gradient,
                                      method="trust-constr",
                                      constraints=cons, callback=track,
                                      options={"maxiter": max_iter, "verbose": 0})
    track(res.x)
    used = "" if np.array_equal(best["x"], res.x) else "; best feasible iterate used"
    return best["x"], int(getattr(res, "nit", 0) or 0), f"{res.message}{used}"


# --------------------------------------------------------------------------------- the design
@dataclass(frozen=True, eq=False)
class ExcitationDesign(Reported):
    """An optimised excitation trajectory with the evidence that it is good and safe.

    Attributes
    ----------
    trajectory : the best :class:`Trajectory` (feasible on the dense grid).
    criterion : ``"cond" | "d-opt" | "e-opt"``; ``value`` its value at the design (grid).
    cond : condition number of the unscaled base regressor over one period (dense grid) — the
        figure :attr:`IdentificationResult.condition_number` reports for OLS.
    quality : all criteria and the constraint margins on the dense grid.
    starts : per-start results, in order; ``best_start`` indexes the chosen one.
    base, spec, limits : the base parameters, regressor columns and limits designed for.
    """

    trajectory: Trajectory
    criterion: str
    value: float
    quality: ExcitationQuality
    starts: tuple[StartResult, ...]
    best_start: int
    base: BaseParameters = field(repr=False)
    spec: RegressorSpec = field(repr=False)
    limits: ExcitationLimits = field(repr=False)
    joint_names: tuple[str, ...] = field(repr=False)
    seconds: float = 0.0

    @property
    def cond(self) -> float:
        return self.quality.cond

    @property
    def constraints(self) -> ConstraintReport:
        return self.quality.constraints

    @property
    def period(self) -> float:
        return self.trajectory.duration

    def sample(self, rate: float, duration: float | None = None) -> Dataset:
        """The trajectory at ``rate`` Hz over ``duration`` s (default one period), as a
        :class:`Dataset` without torques (t, q, dq, ddq)."""
        return self.trajectory.sample(rate, duration, joint_names=self.joint_names)

    def save_csv(self, path: str | Path, rate: float, duration: float | None = None) -> Path:
        """CSV ``t, q_<joint>.., dq_<joint>.., ddq_<joint>..`` named by the robot's joints,
        for a robot controller (:meth:`Trajectory.save_csv`)."""
        return self.trajectory.save_csv(path, rate, duration, self.joint_names)

    def summary(self) -> str:
        return str(self)

    def page(self) -> Page:
        """The HTML report: the criteria, every start, the margin of every limit."""
        c = self.quality.criteria
        page = Page("consistid excitation design",
                    f"{self.trajectory.parameterisation!r}, criterion {self.criterion} = "
                    f"{self.value:.4g}, {self.base.n_base} base parameters "
                    f"({self.spec.describe()})")
        page.key_values([("cond(Y_b), unscaled", self.cond), ("cond, weighted", c["cond"]),
                         ("d-opt", c["d-opt"]), ("e-opt", c["e-opt"]),
                         ("period [s]", self.period), ("design time [s]", self.seconds)])
        page.heading("Starts")
        page.table(["start", "result"], [(i + 1, str(s)) for i, s in enumerate(self.starts)],
                   row_classes=["best" if i == self.best_start else ""
                                for i in range(len(self.starts))])
        page.heading("Limits")
        page.paragraph(str(self.constraints))
        return page

    def __str__(self) -> str:
        c = self.quality.criteria
        lines = [f"excitation design: {self.trajectory.parameterisation!r}",
                 f"  criterion {self.criterion} = {self.value:.4g}; base parameters "
                 f"{self.base.n_base} ({self.spec.describe()})",
                 f"  cond(Y_b) unscaled = {self.cond:.4g}; weighted/scaled: "
                 f"cond = {c['cond']:.4g}, "
                 f"d-opt = {c['d-opt']:.4g}, e-opt = {c['e-opt']:.4g}",
                 f"  {self.best_start + 1}/{len(self.starts)} starts chosen, "
                 f"{self.seconds:.1f} s in total"]
        lines += ["  " + str(s) for s in self.starts]
        lines += [str(self.constraints)]
        return "\n".join(lines)


def make_parameterisation(nv: int, trajectory: str = "fourier", harmonics: int = 5,
                          period: float = 10.0, via_points: int | Sequence[float] = 10,
                          degree: int = 4, boundary: BoundaryConditions | None = None
                          ) -> Parameterisation:
    """A :class:`FourierPolynomial` (``"fourier"``) or :class:`BSplineParameterisation`
    (``"bspline"``, ``via_points`` intervals over ``period`` s or explicit times)."""
    check_option("trajectory", trajectory, TRAJECTORIES)
    if trajectory == "fourier":
        return FourierPolynomial(nv, harmonics, period, boundary)
    return BSplineParameterisation(nv, via_points, period, degree, boundary)


def _check_grid_size(model: RobotModel, spec: RegressorSpec, n_grid: int, n_check: int) -> None:
    """:class:`OptionError` (before allocating) when the regressor on the ``n_grid`` or
    ``n_check`` grid, ``(n · nv) × columns`` float64, would exceed :data:`MAX_SAMPLE_BYTES`."""
    columns = model.n_inertial + spec.n_joint_columns
    for name, n in (("n_grid", n_grid), ("n_check", n_check)):
        size = float(n) * model.nv * columns * 8
        if size > MAX_SAMPLE_BYTES:
            raise OptionError(f"{name} = {n}: the regressor on that grid takes "
                              f"{size / 2**30:.3g} GiB, more than "
                              f"{MAX_SAMPLE_BYTES / 2**30:g} GiB; a few hundred samples per "
                              "period suffice (default n_grid = 150, n_check = 2000)")


@single_blas_thread
def design_excitation(model: RobotModel, harmonics: int = 5, period: float = 10.0,
                      criterion: str = "cond", seed: int = 0, *,
                      trajectory: str = "fourier", via_points: int | Sequence[float] = 10,
                      degree: int = 4, boundary: BoundaryConditions | None = None,
                      limits: ExcitationLimits | None = None,
                      friction: FrictionArg = ("coulomb", "viscous", "offset"),
                      armature: bool | Sequence[int | str] = False,
                      column_scale: str | np.ndarray | None = None, torque_weight: float = 0.0,
                      noise_std: float | Sequence[float] | None = None,
                      n_starts: int = 4, max_iter: int = 100, method: str = "SLSQP",
                      n_grid: int = 150, n_check: int = 2000, safety: float = 0.01,
                      progress: bool | None | Callable[[StartResult], None] = None,
                      n_jobs: int | None = None) -> ExcitationDesign:
    r"""Design an optimal excitation trajectory (multi-start local optimisation).

    Parameters
    ----------
    model : the robot; its URDF inertias are the prior for torque limits and column scaling.
    harmonics, period : Fourier harmonics ``H`` and period ``T`` (s); for B-splines ``period`` is
        the duration.
    criterion : ``"cond"`` (condition number), ``"d-opt"`` (−log det of the Fisher information),
        ``"e-opt"`` (−log of its smallest eigenvalue); see :mod:`consistid.excitation.criteria`.
    seed : seeds every random start; the design is deterministic for a given seed.
    trajectory : ``"fourier"`` (Fourier series + quintic, :class:`FourierPolynomial`) or
        ``"bspline"`` (:class:`BSplineParameterisation` with ``via_points`` and ``degree``).
    boundary : start/end states, default free closed position with zero velocity/acceleration.
    limits : default :meth:`ExcitationLimits.from_model` (URDF limits, 10 rad/s², efforts).
    friction, armature : the columns that will be identified (as in :func:`consistid.identify`,
        whose defaults these are); they enter the base regressor.
    column_scale : ``None``, ``"prior"`` (Rackl eq. 15: ``|β_prior|``) or (b,) scales.
    torque_weight : ``ξ ≥ 0`` of Rackl's term ``ξ / mean|τ|`` added to ``"cond"`` (N·m); only
        with ``criterion="cond"``.
    noise_std : per-joint torque noise σ (N·m) weighting the rows (``Σ⁻¹`` in the Fisher
        information); default 1 for all joints.
    n_starts, max_iter, method : starts, iterations per start, ``"SLSQP"`` or ``"trust-constr"``.
    n_grid : samples per period inside the optimiser; ``n_check`` for the dense verification.
    safety : relative margin every constraint keeps on the grid (absorbs inter-sample overshoot).
    progress : ``None`` (default: a progress bar over the starts when stderr is a terminal),
        ``True``/``False`` (always/never a bar; :mod:`consistid.progress`), or a callable called
        with each :class:`StartResult` as it finishes. Each start is also logged at INFO.
    n_jobs : run the starts through :class:`joblib.Parallel` with this many workers (``-1``: all
        cores; inside ``joblib.parallel_config(backend="dask")`` they go to a Dask cluster).
        ``None`` (default): one after the other in this process. The starting points are drawn
        in order from ``seed`` either way, so the design is the same; in parallel a start's
        ``evaluations`` and ``time`` leave out drawing its starting point.

    Returns
    -------
    ExcitationDesign

    Raises
    ------
    InfeasibleExcitationError when a limit leaves no room to move (e.g. a zero velocity limit),
    no feasible rest pose exists, or no start ends feasible on the dense grid.
    OptionError for an unknown criterion, trajectory or method, or a ``torque_weight`` with
    another criterion than ``"cond"``.
    """
    start_time = time.perf_counter()
    check_option("criterion", criterion, CRITERIA)
    check_option("method", method, METHODS)
    require_model(model)
    n_starts, max_iter, n_grid, n_check, harmonics, seed = (
        check_number(name, value, integer=True) for name, value in (
            ("n_starts", n_starts), ("max_iter", max_iter), ("n_grid", n_grid),
            ("n_check", n_check), ("harmonics", harmonics), ("seed", seed)))
    period = check_number("period", period)
    check_seed("seed", seed)
    if trajectory == "fourier" and 2 * harmonics >= n_grid:
        raise OptionError(f"harmonics = {harmonics} needs n_grid > {2 * harmonics} samples per "
                          f"period (Nyquist: the optimiser could not see the higher "
                          f"harmonics), n_grid = {n_grid}; lower harmonics (5 to 10 is usual) "
                          "or raise n_grid")
    if n_starts < 1 or max_iter < 0 or n_grid < 2 or n_check < 2:
        raise OptionError(f"need n_starts ≥ 1, max_iter ≥ 0, n_grid ≥ 2, n_check ≥ 2; got "
                          f"{n_starts}, {max_iter}, {n_grid}, {n_check}")
    if not 0.0 <= safety < 0.5:
        raise OptionError(f"safety = {safety} must lie in [0, 0.5)")
    if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, (int, np.integer))
                               or n_jobs == 0):
        raise OptionError(f"n_jobs = {n_jobs!r}: give None (in this process), a number of "
                          "workers ≥ 1, or -1 for all cores (joblib's convention)")
    if not torque_weight >= 0:
        raise OptionError(f"torque_weight = {torque_weight}; it must be ≥ 0 (N·m)")
    if torque_weight and criterion != "cond":
        raise OptionError(f"torque_weight = {torque_weight} applies to criterion='cond' only "
                          f"(Rackl's ξ / mean|τ| term); criterion is {criterion!r}")
    limits = limits or ExcitationLimits.from_model(model)
    constraints = ConstraintSet(model, limits)                           # validates the limits
    param = make_parameterisation(model.nv, trajectory, harmonics, period, via_points, degree,
                                  boundary)
    spec = RegressorSpec.make(model, friction, armature)
    _check_grid_size(model, spec, n_grid, n_check)
    base = compute_base_parameters(model, spec)
    row_w, col_s = _weights(model, base, spec, noise_std, column_scale)
    problem = _DesignProblem(model, param, spec, base, constraints, criterion, row_w, col_s,
                             torque_weight, n_grid, safety)
    rng = np.random.default_rng(seed)
    starts: list[StartResult] = []
    qualities: list[ExcitationQuality] = []
    callback = progress if callable(progress) and not isinstance(progress, bool) else None
    bar = Progress(False if callback else progress, n_starts, "excitation design", "start")
    check = (limits, friction, armature, n_check, base, noise_std, column_scale)
    if n_jobs is None:
        runs = (_run_start(problem, k, lambda: random_feasible(problem, rng), method, max_iter,
                           check) for k in range(n_starts))
    else:
        import joblib

        x0s = [random_feasible(problem, rng) for _ in range(n_starts)]
        runs = joblib.Parallel(n_jobs=n_jobs, return_as="generator")(
            joblib.delayed(_run_start)(problem, k, x0, method, max_iter, check)
            for k, x0 in enumerate(x0s))
    for result, quality in runs:
        qualities.append(quality)
        starts.append(result)
        logger.info("excitation %s", result)
        bar.step(f"cond {quality.cond:.4g}, {'feasible' if result.feasible else 'infeasible'}")
        if callback is not None:
            callback(result)
    bar.close()
    feasible = [s for s in starts if s.feasible]
    if not feasible:
        detail = "; ".join(f"start {s.index}: min margin {s.min_margin * 100:.2f} %"
                           for s in starts)
        raise InfeasibleExcitationError(
            f"no start satisfies every constraint on the dense grid ({detail}); increase "
            "safety or n_grid, or relax the limits")
    best = min(feasible, key=lambda s: s.value)
    traj = param.trajectory(best.coefficients)
    _warn_if_uninformative(qualities[best.index].cond, limits)
    return ExcitationDesign(traj, criterion, best.value, qualities[best.index], tuple(starts),
                            best.index, base, spec, limits, tuple(model.joint_names),
                            time.perf_counter() - start_time)


#: ``cond(Y_b)`` beyond which least squares on the design's data loses every digit of the
#: worst-determined base parameter: ``1/√ε`` (the normal equations square the condition number).
UNINFORMATIVE_COND = 1.0 / np.sqrt(np.finfo(float).eps)


def _warn_if_uninformative(cond: float, limits: ExcitationLimits) -> None:
    """A feasible design is not a useful one: warn when the best trajectory leaves base
    parameters unexcited (``cond(Y_b) > 1/√ε``), usually because the limits leave no motion."""
    if np.isfinite(cond) and cond <= UNINFORMATIVE_COND:
        return
    tight = {name: float(np.min(v)) for name, v in
             (("velocity", limits.velocity), ("acceleration", limits.acceleration))}
    warnings.warn(
        f"the best feasible trajectory has cond(Y_b) = {cond:.3g} > 1/√ε = "
        f"{UNINFORMATIVE_COND:.3g}: it does not excite every base parameter, and an "
        "identification from it would be decided by noise and the prior. The limits leave "
        f"little room to move (smallest velocity limit {tight['velocity']:.3g} rad/s, "
        f"acceleration {tight['acceleration']:.3g} rad/s²): relax them, lengthen the period or "
        "add harmonics", PoorExcitationWarning, stacklevel=3)


def _run_start(problem: "_DesignProblem", k: int, x0: np.ndarray | Callable[[], np.ndarray],
               method: str, max_iter: int, check: tuple
               ) -> tuple[StartResult, ExcitationQuality]:
    """One start of :func:`design_excitation` from ``x0`` (or from what the function ``x0``
    draws, counted in the start's time and evaluations): local optimisation, then the dense
    check (``check``: its limits, friction, armature, n_check, base, noise_std, column_scale)."""
    t0 = time.perf_counter()
    evals0, grads0 = problem.n_evaluations, problem.n_gradients
    x0 = x0() if callable(x0) else x0
    initial = problem.value(x0)
    x, nit, status = _optimise(problem, x0, method, max_iter)
    limits, friction, armature, n_check, base, noise_std, column_scale = check
    quality = assess_excitation(problem.model, problem.param.trajectory(x.reshape(problem.shape)),
                                limits, friction, armature, n_check, base, noise_std,
                                column_scale)
    return StartResult(k, initial, problem.value(x), quality.cond, quality.constraints.feasible,
                       quality.constraints.min_relative_margin, nit,
                       problem.n_evaluations - evals0, problem.n_gradients - grads0, status,
                       time.perf_counter() - t0, x.reshape(problem.shape)), quality


def random_excitation(model: RobotModel, harmonics: int = 5, period: float = 10.0,
                      seed: int | np.random.Generator = 0, *, trajectory: str = "fourier",
                      via_points: int | Sequence[float] = 10, degree: int = 4,
                      boundary: BoundaryConditions | None = None,
                      limits: ExcitationLimits | None = None, n_grid: int = 150,
                      safety: float = 0.01) -> Trajectory:
    """A random trajectory of the same class as :func:`design_excitation`'s, scaled to the
    largest amplitude that satisfies every constraint on the grid (see :func:`random_feasible`):
    the baseline an optimised design is compared with."""
    limits = limits or ExcitationLimits.from_model(model)
    constraints = ConstraintSet(model, limits)
    param = make_parameterisation(model.nv, trajectory, harmonics, period, via_points, degree,
                                  boundary)
    problem = _FeasibilityProblem(model, param, constraints, n_grid, safety)
    x = random_feasible(problem, np.random.default_rng(seed))
    return param.trajectory(x.reshape(problem.shape))
