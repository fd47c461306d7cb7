r"""The running estimate projected onto the physically consistent set, fast enough to repeat.

A recursive estimator carries the base estimate ``β̂`` and its covariance ``P``: the Gaussian
likelihood of every sample seen so far, in compressed form (``P⁻¹ = RᵀR`` plays the part of
the R factor of :mod:`consistid.identification.compression`). Its consistent counterpart is the
maximum a-posteriori standard vector of :mod:`consistid.identification.sdp` with that likelihood
and its Euclidean prior,

.. math::

    \min_\pi \; \|R (B\pi - \hat\beta)\|^2 + \gamma \|W(\pi - \pi_0)\|^2
    \quad\text{s.t.}\quad J_i(\pi) \succeq \epsilon J_i(\pi_0), \quad f_c, f_v, I_a \ge 0,

(Wensing, Kim, Slotine 2017, doi:10.1109/LRA.2017.2729659), ``W`` the log-det metric at the
prior (:func:`consistid.identification.priors.logdet_metric`: the log-det divergence of Lee,
Wensing, Park 2019, doi:10.1109/TRO.2019.2926491, to second order) and ``γ = 2/r²``
(:func:`consistid.identification.sdp.default_prior_weight`). With no forgetting, a vague initial
covariance and the same σ it is ``consistid.identify(..., method="sdp", prior="euclidean")`` on
the same samples (a test checks it). The log-det prior itself would add exponential cones and
triple the solve time; near the prior the two agree.

Speed.

* The objective is quadratic: one QR factorisation gives its unconstrained minimiser ``π*`` and
  a factor ``K`` with objective ``‖K(y − y*)‖² + c`` (prior-normalised coordinates ``π = T y``,
  ``T`` from :class:`~consistid.identification.constraints.BodyScaling`, where each body's LMI
  reads ``J(y) ⪰ ε 1``). If ``π*`` satisfies every constraint it *is* the answer (a convex
  problem's unconstrained minimiser, when feasible, is its minimiser): no solver call
  (``solver.name == "closed form"``).
* Otherwise the solver sees ``y = y* + K⁻¹ w`` and minimises ``‖w‖²``: unit curvature in every
  direction, whatever the amount of data (the whitening of :mod:`consistid.identification.sdp`).
  The program is built once as a *parametrised* cvxpy problem (disciplined parametrised
  programming, Agrawal et al. 2019, "Differentiable convex optimization layers", NeurIPS):
  ``y*`` and ``K⁻¹`` are :class:`cvxpy.Parameter` values, so a call writes them and re-solves;
  canonicalisation is cached after the first call (which is slower,
  ``details["first_call"]``). Clarabel, an interior-point method, has no warm start: what is
  reused is the compiled program, not the previous solution. Each call reports its wall time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import cvxpy as cp
import numpy as np
import scipy.linalg

from ..errors import IdentificationError, InconsistentParametersError, OptionError, check_number
from ..identification.base import BaseParameters
from ..identification.constraints import BodyScaling, body_constraints, relative_bound
from ..identification.priors import logdet_metric
from ..identification.regressor import RegressorSpec, parameter_names, prior_vector
from ..identification.result import StandardParameterSet
from ..identification.sdp import default_prior_weight
from ..identification.solver import DEFAULT_SOLVER, SolverReport, check_solver, solve
from ..robot.inertia import pseudo_inertia
from ..robot.model import RobotModel
from .report import fragment

#: Weight (1/N·m) of the ridge that keeps the per-joint columns' normal matrix definite.
JOINT_RIDGE = 1e-6


@dataclass(frozen=True, eq=False)
class ProjectedEstimate(StandardParameterSet):
    """A running estimate made physically consistent.

    Attributes
    ----------
    model, parameters, parameter_names : the standard vector (10 per body, then the per-joint
        terms) and its names.
    base_parameters : (b,) ``B π``, the base coefficients of the projection.
    given : (b,) the estimate ``β̂`` that was projected.
    distance : ``‖R(Bπ − β̂)‖²``, χ² units of the estimate's covariance: how far consistency moved
        it (≈ b or less when ``β̂`` was consistent within its noise).
    margins : (nbodies,) smallest eigenvalue of each body's pseudo-inertia (kg·m²).
    solver : the :class:`~consistid.identification.result.SolverReport`.
    seconds : wall time of the call (writing parameters, solving, checking).
    """

    model: RobotModel
    parameters: np.ndarray
    parameter_names: tuple[str, ...]
    base_parameters: np.ndarray
    given: np.ndarray
    distance: float
    margins: np.ndarray
    solver: SolverReport
    seconds: float
    details: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> str:
        worst = int(np.argmin(self.margins))
        return (f"consistent projection of {self.model.name!r}: {self.solver}; "
                f"{self.seconds * 1e3:.1f} ms; moved {self.distance:.3g} χ² units from the "
                f"estimate; smallest margin {self.margins[worst]:.3g} "
                f"({self.model.body_names[worst]}); {self.consistency}")

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        return fragment(self.summary())


class ConsistencyProjector:
    """Projects ``(β̂, P)`` onto the consistent set (module docstring); build once, call often.

    Parameters
    ----------
    model, base, spec : the robot, the base map of ``β̂`` and its regressor columns.
    prior_parameters : (p,) ``π₀``; default the URDF's inertias and zero friction. Every body
        must be realisable (``J₀ ≻ 0``).
    prior_weight : ``γ``; default :func:`consistid.identification.sdp.default_prior_weight`.
    margin : ``J_i ⪰ margin·J_i(π₀)``.
    solver, solver_options : cvxpy solver (default Clarabel) and options.
    """

    def __init__(self, model: RobotModel, base: BaseParameters, spec: RegressorSpec, *,
                 prior_parameters: np.ndarray | None = None, prior_weight: float | None = None,
                 margin: float = 1e-6, solver: str = DEFAULT_SOLVER,
                 solver_options: dict[str, Any] | None = None) -> None:
        self.model, self.base, self.spec = model, base, spec
        names = parameter_names(model, spec)
        if tuple(base.standard_names) != tuple(names):
            raise OptionError("the base map and the regressor spec describe different columns")
        self.parameter_names = tuple(names)
        pi0 = (prior_vector(model, spec) if prior_parameters is None
               else np.asarray(prior_parameters, dtype=float))
        if pi0.shape != (len(names),) or not np.all(np.isfinite(pi0)):
            raise OptionError(f"prior_parameters must be {len(names)} finite numbers, got shape "
                              f"{pi0.shape}")
        self.prior = pi0
        self.gamma = (default_prior_weight() if prior_weight is None
                      else check_number("prior_weight", prior_weight, 0, strict=True))
        self.margin = check_number("margin", margin, 0)
        self.solver = check_solver(solver)
        self.options = dict(solver_options or {})
        nb, p, n_in = model.n_bodies, len(names), model.n_inertial
        t = np.eye(p)
        scalings = []
        for i, body in enumerate(model.body_names):
            try:
                sc = BodyScaling.from_reference(pi0[10 * i:10 * i + 10])
            except InconsistentParametersError as exc:
                raise InconsistentParametersError(
                    f"prior body {body!r}: {exc}; the projection needs a realisable prior "
                    "(pass prior_parameters)") from exc
            scalings.append(sc)
            t[10 * i:10 * i + 10, 10 * i:10 * i + 10] = sc.parameter_map()
        self._t = t
        # the quadratic prior in y: ‖M (y − y0)‖², M = W T per body; a tiny ridge on the
        # per-joint columns keeps the normal matrix definite where the data leave them free
        m = np.zeros((p, p))
        for i in range(nb):
            sl = slice(10 * i, 10 * i + 10)
            m[sl, sl] = logdet_metric(pi0[sl]) @ t[sl, sl]
        self._prior_rows = np.sqrt(self.gamma) * m
        self._prior_rows[n_in:, n_in:] = JOINT_RIDGE * np.eye(p - n_in)
        self._y0 = np.linalg.solve(t, pi0)
        self._bt = base.matrix @ t                                    # (b, p)
        self._centre = cp.Parameter(p, name="centre")                 # T y*
        self._map = cp.Parameter((p, p), name="map")                  # T K⁻¹
        self._w = cp.Variable(p, name="w")
        x = self._centre + self._map @ self._w
        constraints: list[cp.Constraint] = []
        for i, body in enumerate(model.body_names):
            pi = pi0[10 * i:10 * i + 10]
            constraints += body_constraints(x[10 * i:10 * i + 10], "pseudo-inertia",
                                            relative_bound(pi, "pseudo-inertia", self.margin),
                                            None, scalings[i])
        self._keep = n_in + spec.nonnegative_columns
        if self._keep.size:
            constraints.append(x[self._keep] >= 0)
        self._scalings = tuple(scalings)
        self._problem = cp.Problem(cp.Minimize(cp.sum_squares(self._w)), constraints)
        self.calls = 0

    def _feasible(self, pi: np.ndarray) -> bool:
        """Every constraint holds at ``pi`` (prior-normalised LMI slack ≥ margin, entries ≥ 0)."""
        for i, sc in enumerate(self._scalings):
            j_hat = sc.l_inv @ pseudo_inertia(pi[10 * i:10 * i + 10]) @ sc.l_inv.T
            if np.linalg.eigvalsh(j_hat)[0] < self.margin:
                return False
        return bool(np.all(pi[self._keep] >= 0))

    def project(self, beta: np.ndarray, covariance: np.ndarray) -> ProjectedEstimate:
        """The consistent standard vector nearest ``β̂`` in the metric ``P⁻¹``, with the prior.

        Raises
        ------
        OptionError : ``beta``/``covariance`` of the wrong shape, non-finite, or a covariance
            that is not positive definite.
        InfeasibleError, IdentificationError : the solver failed (status named), or its answer
            is not consistent.
        """
        start = time.perf_counter()
        b, p = self.base.n_base, self._bt.shape[1]
        beta = np.asarray(beta, dtype=float)
        cov = np.asarray(covariance, dtype=float)
        if beta.shape != (b,) or cov.shape != (b, b) or not (
                np.all(np.isfinite(beta)) and np.all(np.isfinite(cov))):
            raise OptionError(f"project: expected a finite ({b},) estimate and ({b}, {b}) "
                              f"covariance, got {beta.shape} and {cov.shape}")
        try:
            chol = np.linalg.cholesky(0.5 * (cov + cov.T))            # P = C Cᵀ
        except np.linalg.LinAlgError as exc:
            raise OptionError("project: the covariance is not positive definite") from exc
        r = scipy.linalg.solve_triangular(chol, np.eye(b), lower=True)  # RᵀR = P⁻¹
        rows = np.vstack([r @ self._bt, self._prior_rows])
        rhs = np.concatenate([r @ beta, self._prior_rows @ self._y0])
        q_f, k = np.linalg.qr(rows)
        y_star = scipy.linalg.solve_triangular(k, q_f.T @ rhs)
        centre = self._t @ y_star
        first = self.calls == 0
        self.calls += 1
        if self._feasible(centre):
            pi = centre
            report = SolverReport("closed form", "optimal", 0.0, 0.0, 0)
        else:
            self._centre.value = centre
            self._map.value = self._t @ scipy.linalg.solve_triangular(k, np.eye(p))
            options = ({"equilibrate_enable": False, **self.options}
                       if self.solver == "CLARABEL" else self.options)
            report = solve(self._problem, f"consistent projection of {self.model.name!r}",
                           self.solver, options)
            pi = centre + self._map.value @ self._w.value
            pi[self._keep] = np.maximum(pi[self._keep], 0.0)  # solver round-off on entries ≥ 0
        margins = np.array([np.linalg.eigvalsh(pseudo_inertia(pi[10 * i:10 * i + 10]))[0]
                            for i in range(self.model.n_bodies)])
        if np.any(margins < 0):
            worst = int(np.argmin(margins))
            raise IdentificationError(
                f"consistent projection: the solver reported {report.status} but body "
                f"{self.model.body_names[worst]!r} has a pseudo-inertia eigenvalue "
                f"{margins[worst]:.3g} < 0")
        projected = self.base.project(pi)
        misfit = r @ (projected - beta)
        return ProjectedEstimate(
            model=self.model, parameters=pi, parameter_names=self.parameter_names,
            base_parameters=projected, given=beta.copy(), distance=float(misfit @ misfit),
            margins=margins, solver=report, seconds=time.perf_counter() - start,
            details={"first_call": first, "prior_weight": self.gamma,
                     "unconstrained_feasible": report.name == "closed form"})
