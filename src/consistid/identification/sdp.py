r"""Physically consistent identification as a compressed semidefinite program.

The estimate is the maximum a-posteriori standard parameter vector under physical-consistency
constraints (Wensing, Kim, Slotine 2017, "Linear matrix inequalities for physically consistent
inertial parameter identification", IEEE RA-L 3(1), doi:10.1109/LRA.2017.2729659; Lee, Wensing,
Park 2019, "Geometric robot dynamic identification: a convex programming approach", IEEE T-RO
36(2), doi:10.1109/TRO.2019.2926491):

.. math::

    \min_\theta \; \|\Sigma^{-1/2}(Y\theta - \tau)\|^2
    + \gamma \sum_i d(J_i(\theta) \,\|\, J_i(\pi_0))
    \quad\text{s.t.}\quad J_i(\theta) \succeq \epsilon\, J_{\text{ref},i}
    \;(\text{or body } i\text{'s level}),
    \quad f_c, f_v, I_a \ge 0,

* **Fisher weighting**: ``Σ = diag(σ_j²)`` per joint, from an OLS pass
  (``σ_j² = ‖ρ_j‖² / (N − r/nv)``, ``r`` the rank of the base regressor) unless ``sigma`` is given;
  optionally re-estimated from the SDP's own residuals (``reweight`` passes, IRLS) or, with
  ``loss="huber"``, replaced by Huber weights per sample (Huber 1964, doi:10.1214/aoms/1177703732;
  IRLS of Holland & Welsch 1977, doi:10.1080/03610927708827533) with a MAD noise scale.
* **Compression**: the data term equals ``‖R θ − z‖² + ρ²`` with ``(R, z)`` the R factor of the
  weighted ``[Y | τ]`` (:mod:`consistid.identification.compression`), so the program has ``p``
  unknowns and a
  ``p × p`` quadratic whatever the number of samples.
* **Priors**: ``"logdet"``: the Bregman divergence
  ``d(J‖J₀) = −log det J + log det J₀ + tr(J₀⁻¹J) − 4`` (Lee et al. 2019, eq. 24);
  ``"euclidean"``: ``‖W(π − π₀)‖²`` with ``W`` by default the log-det metric at the prior
  (:func:`consistid.identification.priors.logdet_metric`), so both priors have the same curvature
  at ``π₀``;
  ``None``: constraints only. Optional hard :class:`~consistid.identification.priors.Neighbourhood`
  bounds.
* **Default prior weight** (:func:`default_prior_weight`): ``γ = 2 / r²`` with ``r`` the relative
  uncertainty of the CAD bodies (default :data:`DEFAULT_PRIOR_UNCERTAINTY`). Near the prior,
  ``γ d ≈ ‖Ĵ − 1‖²_F / r²`` (``Ĵ = L⁻¹JL⁻ᵀ``, ``J₀ = LLᵀ``): a Gaussian prior of standard deviation
  ``r`` on each entry of the normalised pseudo-inertia, in the same χ² units as the Fisher-weighted
  data term (equivalently, a Wishart prior with ``ν − 5 = γ`` degrees of freedom). It depends on
  neither the data set nor its length: as samples accumulate, the data dominate.
* **Prior weight from the data** (the default unless ``prior_weight`` or ``prior_uncertainty``
  is given): the weight of greatest evidence (marginal likelihood) of the quadratic model of the
  prior on the compressed problem, MacKay's fixed point
  (:mod:`consistid.identification.prior_weight`), clipped to :data:`EVIDENCE_RANGE` × ``2/r²``:
  data that put the bodies further from the CAD values than ``r`` says weaken the prior (down to
  1/100), never strengthen it. No extra solve: the compiled program is re-solved at that ``γ``.
* **Scaling**: the solver sees ``θ = θ_c + Φ w`` with ``Φᵀ(RᵀR + ½γ H₀)Φ = 1`` (``H₀`` the
  prior's Hessian at ``π₀``; ``Φ`` from one QR factorisation, in per-body prior-normalised
  coordinates) and ``θ_c`` the minimiser of that quadratic model: the objective's Hessian is
  ``≈ 1`` in ``w`` for every prior weight, and every body's LMI is imposed on its prior-normalised
  pseudo-inertia (:class:`~consistid.identification.constraints.BodyScaling`). Clarabel's own
  equilibration is
  then redundant and is switched off. A solve that still ends ``optimal_inaccurate`` is rescaled
  once around its answer and repeated (``details["refinements"]``). Changes of variables only:
  the optimum is unchanged. Per-joint ``σ`` (also the Huber scale) is floored at
  :data:`~consistid.identification.compression.SIGMA_FLOOR` times the joint's torque RMS
  (:func:`~consistid.identification.compression.floor_sigma`), so noise-free data do not give
  infinite weights.
* **Compiled once**: with Clarabel and ``scale=True`` the program's structure (constraints, and
  the prior at unit weight, in prior-normalised variables) is canonicalised by cvxpy once per
  model and options and cached; every pass, re-weighting, refinement and later call on the same
  model binds its ``θ_c, Φ, R, z, σ, γ`` and calls Clarabel directly
  (:mod:`consistid.identification.program`). Other solvers and ``scale=False`` build the cvxpy
  program afresh.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, fields, replace
from typing import Any, Mapping, Sequence

import cvxpy as cp
import numpy as np
import scipy.linalg

from . import constraints as cons
from . import priors
from . import program as compiled_programs
from .base import COND_WARN, RANK_RTOL, BaseParameters
from .compression import CompressedProblem, compress, floor_sigma, joint_sigma
from .joint_prior import append_rows, joint_prior_rows
from .prior_weight import evidence_weight
from .solver import DEFAULT_SOLVER, SolverReport, check_solver, solve
from .uninformed import uninformed_directions
from ..data.dataset import Dataset
from ..errors import (IdentificationError, InconsistentParametersError, InfeasibleError,
                     ModelError, OptionError, PoorExcitationWarning, check_bounds, check_box,
                     check_number, check_option)
from ..robot.model import RobotModel
from ..robot.inertia import body_slice, from_pseudo_inertia, is_degenerate, pseudo_inertia
from .regressor import RegressorSpec, parameter_names, prior_vector, residual_torque
from .result import IdentificationResult

#: Prior weights (× the default) over which every solve of ``benchmarks/sdp_accuracy.py`` ended
#: ``optimal``; a solver failure outside it is blamed on the weight (:func:`_extreme_weight`).
PRIOR_WEIGHT_SOLVED = (1e-6, 1e2)
#: Relative uncertainty ``r`` of CAD pseudo-inertias assumed by :func:`default_prior_weight`.
DEFAULT_PRIOR_UNCERTAINTY = 0.3
#: ``None``: constraints only. (Recovery from base coefficients,
#: :data:`consistid.estimation.recover.PRIORS`, has no ``None``: there only a prior picks a point
#: in the null space of the base map.)
PRIORS = (None, "euclidean", "logdet")
LOSSES = ("squared", "huber")
#: ``prior_weight`` rules by name: the weight chosen from the data by empirical Bayes
#: (:mod:`consistid.identification.prior_weight`).
WEIGHT_RULES = ("evidence",)
#: The range (× the default ``2/r²``) the evidence's weight is clipped to. At most the default:
#: the data may show the CAD bodies to be further from the truth than ``r`` says, and the prior
#: then weakens, but a quadratic model of the prior without the constraints is not trusted to
#: make it stronger than the uncertainty stated (simulated arms whose truth is within ±20 % of
#: the URDF got 2–23 × from it, and predicted held-out data worse from poor data: 1.03–1.11 ×
#: the noise against 1.02–1.06 at the default). At least 10⁻²: on the real KUKA LWR4+ logs the
#: evidence asks 10⁻⁵ × and Clarabel fails below ~10⁻³ × (held-out error the same within 0.5 %
#: from 10⁻⁴ to 10 ×).
EVIDENCE_RANGE = (1e-2, 1.0)
#: A constraint counts as active when its prior-normalised slack is below this …
ACTIVE_TOL = 1e-6
#: … and as violated (the answer is rejected) when its slack is below minus this.
CHECK_TOL = 1e-6
#: Huber's ``c`` (units of σ) when ``huber_threshold`` is not given: 95 % efficiency for Gaussian
#: noise (Huber 1964).
HUBER_DEFAULT = 1.345


def default_prior_weight(uncertainty: float = DEFAULT_PRIOR_UNCERTAINTY) -> float:
    """The documented default prior weight ``γ = 2 / r²`` (module docstring).

    ``uncertainty`` ``r`` is the relative (one standard deviation) deviation expected between the
    prior bodies' normalised pseudo-inertias and the truth; 0.3 gives ``γ ≈ 22``.
    """
    if not (np.isfinite(uncertainty) and uncertainty > 0):
        raise OptionError(f"prior_uncertainty must be a finite number > 0, got {uncertainty}")
    with np.errstate(over="ignore", divide="ignore"):
        gamma = 2.0 / np.float64(uncertainty) ** 2
    if not np.isfinite(gamma):
        raise OptionError(f"prior_uncertainty = {uncertainty!r} gives the prior weight 2/r² = "
                          f"{gamma}: give a relative uncertainty such as 0.01 … 1")
    return float(gamma)


@dataclass(frozen=True, eq=False)
class _Setup:
    """Everything the program needs that does not change between re-weighting passes."""

    levels: tuple[str, ...]
    references: np.ndarray          # (10·nb,) realisable reference bodies (= prior if realisable)
    scalings: tuple[cons.BodyScaling, ...]
    bounds: tuple[np.ndarray | float, ...]  # per body: LMI lower bound, margin × J_ref (M_ref)
    ellipsoids: tuple[cons.Ellipsoid | None, ...]
    nonnegative: np.ndarray         # (p,) bool
    euclid_w: np.ndarray | None     # (p_inertial, p_inertial) Euclidean prior weights
    prior: str | None
    gamma: float
    neighbourhood: priors.Neighbourhood | None
    com_boxes: Mapping[str, tuple[Sequence[float], Sequence[float]]]
    mass_bounds: Mapping[str, tuple[float | None, float | None]]
    total_mass: tuple[float | None, float | None] | None


@dataclass(frozen=True)
class SDPOptions:
    """The options of the consistent SDP (:func:`identify_sdp`), validated on construction.

    One value shared by the Python API (``ci.identify(model, data, method="sdp", **options)``
    builds one from its keywords) and the TOML schema (the ``[identify]`` keys of the ``consistid``
    command are its field names). The meaning of each field is in :func:`identify_sdp`'s
    docstring. What needs the robot (body names in ``constraints``, ``com_boxes``,
    ``mass_bounds``, the length of ``sigma``) is checked when the program is set up.

    >>> SDPOptions(prior="euclidean", prior_weight=10.0).prior_weight
    10.0
    """

    constraints: str | Mapping[str, str] = "pseudo-inertia"
    prior: str | None = "logdet"
    prior_weight: float | str | None = None
    prior_uncertainty: float | None = None
    prior_weights: np.ndarray | None = None
    neighbourhood: priors.Neighbourhood | None = None
    ellipsoids: Mapping[str, cons.Ellipsoid] | str | None = None
    com_boxes: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None
    mass_bounds: Mapping[str, tuple[float | None, float | None]] | None = None
    total_mass: tuple[float | None, float | None] | None = None
    friction_nonnegative: bool = True
    joint_prior: bool = True
    margin: float = 1e-6
    sigma: Sequence[float] | None = None
    reweight: int | None = None
    loss: str = "squared"
    huber_threshold: float | None = None
    solver: str = DEFAULT_SOLVER
    solver_options: Mapping[str, Any] | None = None
    scale: bool = True

    def __post_init__(self) -> None:
        check_option("prior", self.prior, PRIORS)
        check_option("loss", self.loss, LOSSES)
        object.__setattr__(self, "solver", check_solver(self.solver))
        for name in ("scale", "friction_nonnegative", "joint_prior"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise OptionError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.solver_options is not None and not isinstance(self.solver_options, Mapping):
            raise OptionError(f"solver_options must be a mapping of solver settings (e.g. "
                              f"{{'max_iter': 200}}), got {self.solver_options!r}")
        _check_combinations(self.prior, self.prior_weight, self.prior_uncertainty,
                            self.prior_weights, self.loss, self.huber_threshold, self.reweight)
        if self.reweight is not None:
            check_number("reweight", self.reweight, 0, integer=True)
        margin = check_number("margin", self.margin, 0)
        if margin >= 1:
            raise OptionError(f"margin = {margin!r}: the LMIs ask J ⪰ margin·J_ref with J_ref "
                              "the prior body, so margin ≥ 1 excludes the prior itself; use a "
                              "small relative margin such as 1e-6 (the default)")
        if self.huber_threshold is not None:
            check_number("huber_threshold", self.huber_threshold, 0, strict=True)
        if self.prior_uncertainty is not None:
            check_number("prior_uncertainty", self.prior_uncertainty, 0, strict=True)
        if isinstance(self.prior_weight, str) and self.prior_weight not in WEIGHT_RULES:
            raise OptionError(f"prior_weight must be a finite number ≥ 0, got "
                              f"{self.prior_weight!r}, or one of {WEIGHT_RULES} (chosen from "
                              "the data)")
        if self.prior is not None and self.prior_weight is not None and \
                self.prior_weight not in WEIGHT_RULES:
            check_number("prior_weight", self.prior_weight, 0)
        if self.neighbourhood is not None \
                and not isinstance(self.neighbourhood, priors.Neighbourhood):
            raise OptionError(f"neighbourhood must be a consistid.identification.priors."
                              f"Neighbourhood(...) (or None), got "
                              f"{type(self.neighbourhood).__name__} {self.neighbourhood!r:.60}")

    @classmethod
    def from_keywords(cls, **keywords: Any) -> "SDPOptions":
        """The options from keywords, an unknown one an :class:`OptionError` naming the known
        ones (the dataclass constructor would raise a bare ``TypeError``)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(keywords) - known)
        if unknown:
            raise OptionError(f"unknown SDP option(s) {unknown}; the options are "
                              f"{sorted(known)}")
        return cls(**keywords)

    @property
    def passes(self) -> int:
        """Re-weighting passes after the first solve (5 for Huber unless ``reweight`` says)."""
        return (5 if self.loss == "huber" else 0) if self.reweight is None else int(self.reweight)

    @property
    def default_weight(self) -> float:
        """``γ`` of :func:`default_prior_weight` at ``prior_uncertainty`` (or the default)."""
        return default_prior_weight(DEFAULT_PRIOR_UNCERTAINTY if self.prior_uncertainty is None
                                    else self.prior_uncertainty)

    @property
    def weight(self) -> float:
        """The prior weight ``γ`` used: 0 without a prior, else ``prior_weight`` or the default
        (for ``"evidence"``: the start of its search, :func:`identify_sdp` chooses it)."""
        if self.prior is None:
            return 0.0
        return (self.default_weight if self.prior_weight is None or self.from_data
                else float(self.prior_weight))

    @property
    def from_data(self) -> bool:
        """Whether the prior weight is chosen from the data: ``prior_weight="evidence"``, or
        neither ``prior_weight`` nor ``prior_uncertainty`` given (the default)."""
        return self.prior is not None and (self.prior_weight == "evidence" or (
            self.prior_weight is None and self.prior_uncertainty is None))


def identify_sdp(model: RobotModel, problem: CompressedProblem, base: BaseParameters,
                 spec: RegressorSpec, options: SDPOptions | None = None, *,
                 dataset: Dataset | None = None, **keywords: Any) -> IdentificationResult:
    r"""Physically consistent identification on a compressed problem (module docstring).

    Usually called through ``consistid.identify(model, data, method="sdp", ...)``.

    Parameters
    ----------
    model, problem, base, spec : the robot, the compressed data (:func:`compression.compress`),
        its base parameters and regressor columns.
    options : an :class:`SDPOptions`; or its fields given as keywords (``**keywords``), the
        convenience ``ci.identify`` uses — not both.
    constraints : consistency level of every body, ``"none" | "mass-inertia" | "triangle" |
        "pseudo-inertia" | "ellipsoid"``, or a mapping ``{body: level}`` (unlisted bodies get
        ``"pseudo-inertia"``). ``"triangle"`` is imposed as the pseudo-inertia LMI, which for one
        body is exactly ``m ≥ 0`` plus the triangle inequalities. The log-det prior keeps every
        ``J ≻ 0`` by its domain whatever the level.
    prior : ``None``, ``"euclidean"`` or ``"logdet"``.
    prior_weight : ``γ``, a number; or ``"evidence"`` (the default when ``prior_uncertainty``
        is not given either): chosen from the data, the weight of greatest evidence (marginal
        likelihood) of the quadratic model of the prior
        (:mod:`consistid.identification.prior_weight`) within :data:`EVIDENCE_RANGE` × the
        default ``2/r²``, after the σ of the Fisher weighting and before the first solve (no
        extra solve; the compiled program is re-used). ``details["prior_weight"]`` gives the
        weight used, ``details["prior_weight_rule"]`` how it was found.
    prior_uncertainty : ``r`` of :func:`default_prior_weight` (default
        :data:`DEFAULT_PRIOR_UNCERTAINTY`): the fixed weight ``2/r²``, not chosen from the data;
        give it or ``prior_weight``, not both.
    prior_weights : Euclidean ``W`` on the inertial parameters, (10·nb,) diagonal or
        (10·nb, 10·nb) full; default the log-det metric at the prior (``prior="euclidean"``
        only).
    neighbourhood : hard bounds around each prior body
        (:class:`~consistid.identification.priors.Neighbourhood`).
    ellipsoids : ``{body: Ellipsoid}``, for (and only for) the bodies at level ``"ellipsoid"``;
        or ``"collision"``: the minimum-volume ellipsoids of the URDF's collision geometry
        (:func:`consistid.robot.shapes.collision_ellipsoids`) for the bodies at level
        ``"ellipsoid"``. With ``constraints="ellipsoid"`` (a string), bodies without collision
        geometry then get ``"pseudo-inertia"`` (a :class:`~consistid.errors.GeometryWarning`
        names them); a ``{body: "ellipsoid"}`` body without geometry is refused.
    com_boxes : ``{body: (lower, upper)}`` CoM boxes in the body frame (m).
    mass_bounds : ``{body: (lower, upper)}`` in kg (``None`` for no bound).
    total_mass : ``(lower, upper)`` bounds on the sum of the body masses (kg).
    friction_nonnegative : constrain Coulomb, viscous friction and armature to be ``≥ 0``.
    joint_prior : a weak Gaussian prior on Coulomb, viscous friction and offset, σ the joint's
        effort limit (viscous: effort / velocity limit), which decides the directions the data
        leave free, e.g. ``f_c − f_o`` of a joint that moves one way only
        (:mod:`consistid.identification.joint_prior`; default on, ``details["joint_prior"]``).
    margin : ``J_i ⪰ margin·J_ref,i`` for the pseudo-inertia levels (``M_i ⪰ margin·M_ref,i``,
        the 6×6 matrix, for ``"mass-inertia"``), ``J_ref`` the prior body (or its realisable
        stand-in when the prior is not realisable): a margin relative to the prior in every
        direction (:func:`consistid.identification.constraints.relative_bound`), the definition
        :func:`consistid.estimation.recover.recover_standard` uses, so that answers are strictly
        realisable
        despite the solver's tolerance. ``details["relative_margins"]`` reports it.
    sigma : (nv,) per-joint torque-noise standard deviation; default from an OLS pass.
    reweight : re-weighting passes after the first solve: σ re-estimated from the SDP residuals
        (``loss="squared"``) or Huber weights and MAD scale updated (``loss="huber"``, which
        needs at least 1). Default 0 for ``"squared"``, 5 for ``"huber"``.
    loss : ``"squared"`` or ``"huber"`` (needs ``dataset``: per-sample weights re-compress it).
    huber_threshold : Huber's ``c`` in units of σ (``loss="huber"`` only; default
        :data:`HUBER_DEFAULT` = 1.345: 95 % efficiency for Gaussian noise).
    dataset : the data ``problem`` was compressed from (needed for ``loss="huber"`` only).
    solver, solver_options : cvxpy solver name and options (default Clarabel; with
        ``scale=True`` its own equilibration is off unless ``solver_options`` says otherwise).
    scale : solve in whitened, prior-normalised coordinates (default). ``False`` hands the
        solver raw parameters and unscaled LMIs; it exists to measure what scaling buys.

    Returns
    -------
    IdentificationResult
        ``method="sdp"``; ``base_parameters = B θ`` of the answer with the covariance
        ``(R_bᵀ R_b)⁻¹`` of the weighted fit. ``details``: ``constraints`` (levels and active
        ones, text), ``prior``, ``prior_weight``, ``prior_weight_rule``, ``solver``,
        ``sigma_source`` (``"ols" | "given" | "irls" | "huber"``), ``scaled``;
        ``active_constraints`` (labels); ``min_eigenvalues`` (``λ_min(J)``, kg·m²) and
        ``relative_margins`` (``λ_min(L⁻¹JL⁻ᵀ)``, prior-normalised) per body;
        ``fit`` (``data_chi2``, ``prior_divergence``, ``default_prior_weight``);
        ``timing`` (``solve``, ``compile``, ``setup`` seconds, also in ``solver``);
        ``passes`` (``reweighting``, ``refinements``); ``program_size`` (variables,
        constraints, data entries handed to cvxpy: independent of N).

    Raises
    ------
    OptionError : unknown option value, body name, a missing ellipsoid / dataset, or an option
        that the other options make meaningless (e.g. ``prior_weight`` with ``prior=None``,
        ``huber_threshold`` with ``loss="squared"``): refused, never silently ignored.
    InconsistentParametersError : a log-det prior body that is not realisable.
    InfeasibleError : the constraints admit no solution (solver proved it).
    IdentificationError : any other solver failure (status named), or an answer that violates
        its constraints beyond tolerance.
    """
    start = time.perf_counter()
    if options is not None and keywords:
        raise OptionError(f"give the SDP options either as SDPOptions or as keywords, not both "
                          f"(got options= and {sorted(keywords)})")
    opts = options if options is not None else SDPOptions.from_keywords(**keywords)
    (constraints, prior, prior_weights, neighbourhood, ellipsoids, com_boxes, mass_bounds,
     total_mass, friction_nonnegative, margin, sigma, loss, solver, solver_options, scale) = (
        opts.constraints, opts.prior, opts.prior_weights, opts.neighbourhood, opts.ellipsoids,
        opts.com_boxes, opts.mass_bounds, opts.total_mass, opts.friction_nonnegative,
        float(opts.margin), opts.sigma, opts.loss, opts.solver, opts.solver_options, opts.scale)
    nv, n = problem.nv, problem.n_samples
    if problem.n_columns != base.n_standard:
        raise OptionError(f"the compressed problem has {problem.n_columns} columns but the base "
                          f"parameters are of {base.n_standard} standard ones")
    if loss == "huber" and dataset is None:
        raise OptionError("loss='huber' re-weights individual samples: pass dataset=")
    passes = opts.passes
    huber_c = HUBER_DEFAULT if opts.huber_threshold is None else float(opts.huber_threshold)
    gamma_default, gamma = opts.default_weight, opts.weight
    _check_bound_options(model, constraints, com_boxes, mass_bounds, total_mass)
    constraints, ellipsoids = _collision_levels(model, constraints, ellipsoids)
    prior_vec = prior_vector(model, spec)
    setup = _make_setup(model, spec, prior_vec, constraints, prior, gamma, prior_weights,
                        ellipsoids, neighbourhood, com_boxes, mass_bounds, total_mass,
                        friction_nonnegative, margin)

    if sigma is None:
        sig, source = _ols_sigma(problem, base), "ols"
    else:
        try:
            sig, source = np.asarray(sigma, dtype=float), "given"
        except (TypeError, ValueError):
            sig = np.array([np.nan])
        if sig.shape != (nv,) or not np.all(np.isfinite(sig)) or np.any(sig <= 0):
            raise OptionError(f"sigma must be {nv} finite values > 0 (one per joint), got "
                              f"{sigma!r}")
    sig = floor_sigma(sig, problem)
    evidence = None
    prior_rows = (joint_prior_rows(model, spec, prior_vec) if opts.joint_prior
                  else (np.zeros((0, prior_vec.size)), np.zeros(0), "off (joint_prior=False)"))
    if opts.from_data:
        t0 = time.perf_counter()
        gamma, iterations_gamma = _evidence_gamma(problem, sig, prior_vec, setup, model.n_bodies,
                                                  gamma_default, prior_rows[:2])
        setup = replace(setup, gamma=gamma)
        evidence = (iterations_gamma, time.perf_counter() - t0)

    work, theta = problem, None
    solve_time = compile_time = 0.0
    iterations = refinements = 0
    setup_time = time.perf_counter() - start
    for k in range(passes + 1):
        t0 = time.perf_counter()
        r_full, z_full = append_rows(*work.stacked(sigma=sig)[:2], *prior_rows[:2])
        program = _build(model, spec, r_full, z_full, prior_vec, setup, scale, solver=solver)
        setup_time += time.perf_counter() - t0
        try:
            program, reports = _solve_pass(program, model, spec, r_full, z_full, prior_vec,
                                           setup, solver, solver_options, scale)
        except IdentificationError as exc:
            raise _extreme_weight(exc, gamma, gamma_default) from exc
        report = reports[-1]
        refinements += len(reports) - 1
        solve_time += sum(rep.solve_time for rep in reports)
        compile_time += sum(rep.compile_time for rep in reports)
        iterations += sum(rep.iterations or 0 for rep in reports)
        active = _check_answer(program)
        new = program.theta()
        # Entries constrained ≥ 0 (friction, armature) come back within the solver's tolerance,
        # e.g. −7e-12 (larger violations were refused just above): set those to 0, so that the
        # URDF/MJCF writers, which refuse negative damping, see the sign the constraint gave.
        new = np.where(setup.nonnegative & (new < 0), 0.0, new)
        done = theta is not None and (np.linalg.norm(new - theta)
                                      <= 1e-8 * max(np.linalg.norm(theta), 1e-300))
        theta = new
        if k == passes or done:
            break
        t0 = time.perf_counter()
        if loss == "huber":
            sig, row_weights = _huber_weights(model, dataset, spec, theta, huber_c, problem)
            work = compress(model, dataset, spec, weights=row_weights, base=base)
            source = "huber"
        else:
            sig = floor_sigma(joint_sigma(problem.sum_squares(theta), n, base.n_base), problem)
            source = "irls"
        setup_time += time.perf_counter() - t0

    r_b, _, _ = work.stacked(sigma=sig, columns=base.independent)
    cond, cov = _base_covariance(r_b)
    uninformed = uninformed_directions(r_b, base)
    if uninformed:
        source = (f"the {prior} prior alone (prior_weight {gamma:.3g})" if prior is not None
                  else "the constraints alone, arbitrary within them (no prior)")
        warnings.warn(
            f"the data do not inform {len(uninformed)} of {base.n_base} base-parameter "
            f"direction(s) (cond {cond:.3g}): their values come from {source}, and their "
            f"base_std is inf; e.g. {'; '.join(uninformed[:3])}. res.uninformed lists them "
            "all; excite the robot more richly (consistid.design_excitation) to identify "
            "them", PoorExcitationWarning, stacklevel=3)
    elif prior is None and cond > COND_WARN:
        warnings.warn(f"weighted base regressor condition number {cond:.3g} > {COND_WARN:.0e} "
                      "and no prior: poorly excited directions are decided by the constraints "
                      "alone; consider prior='logdet'", PoorExcitationWarning, stacklevel=3)
    chi2 = float(np.sum(work.sum_squares(theta) / sig ** 2))
    details = _details(model, theta, setup, prior_vec, gamma_default, opts.prior_weight, active,
                       chi2, evidence)
    size = program.problem.size_metrics
    details.update(program_size={"variables": int(size.num_scalar_variables),
                                 "constraints": len(program.problem.constraints),
                                 "data": int(size.num_scalar_data)},
                   solver=solver, sigma_source=source,
                   passes={"reweighting": k + 1, "refinements": refinements},
                   timing={"solve": solve_time, "compile": compile_time, "setup": setup_time},
                   scaled=scale, joint_prior=prior_rows[2])
    return IdentificationResult(
        method="sdp", model=model, spec=spec, base=base, parameters=theta,
        parameter_names=tuple(parameter_names(model, spec)), prior=prior_vec,
        base_parameters=base.project(theta), base_covariance=cov, sigma=sig,
        condition_number=cond, train_rms=np.sqrt(problem.sum_squares(theta) / n), n_samples=n,
        solver=SolverReport(
            f"{solver} on a program cvxpy compiled once (compressed, scaled)"
            if isinstance(program, compiled_programs.BoundProgram)
            else f"{solver} via cvxpy (compressed{', scaled' if scale else ''})",
            report.status, solve_time, compile_time, iterations),
        details=details, uninformed=uninformed)


def _extreme_weight(exc: IdentificationError, gamma: float, gamma_default: float
                    ) -> IdentificationError:
    """``exc``, or (for a solver failure with a prior weight far from the default) the same
    error naming the weight as the cause: valid but extreme, not a solver to swap."""
    ratio = gamma / gamma_default
    if isinstance(exc, InfeasibleError) or gamma == 0 or PRIOR_WEIGHT_SOLVED[0] <= ratio \
            <= PRIOR_WEIGHT_SOLVED[1]:
        return exc
    return type(exc)(
        f"{exc}. The likely cause is the prior weight: prior_weight = {gamma:.3g} is "
        f"{ratio:.3g} × the default {gamma_default:.3g}, which leaves the solver a program "
        f"scaled beyond what it resolves (solved: {PRIOR_WEIGHT_SOLVED[0]:g} … "
        f"{PRIOR_WEIGHT_SOLVED[1]:g} × default, benchmarks/sdp_accuracy.py); use a weight in "
        "that range, or prior=None for no prior at all")


# ------------------------------------------------------------------------------------ options
def _check_combinations(prior: str | None, prior_weight: float | None,
                        prior_uncertainty: float | None, prior_weights: np.ndarray | None,
                        loss: str, huber_threshold: float | None, reweight: int | None) -> None:
    """Refuse options that the other options make meaningless (never ignore them silently)."""
    if prior is None:
        given = [k for k, v in (("prior_weight", prior_weight),
                                ("prior_uncertainty", prior_uncertainty)) if v is not None]
        if given:
            raise OptionError(f"{given} weight a prior, but prior=None has none")
    if prior_weight is not None and prior_uncertainty is not None:
        raise OptionError("give prior_weight or prior_uncertainty (which sets the default "
                          "prior_weight = 2/r²), not both")
    if prior_weights is not None and prior != "euclidean":
        raise OptionError(f"prior_weights are the Euclidean prior's metric; prior={prior!r}")
    if huber_threshold is not None and loss != "huber":
        raise OptionError(f"huber_threshold applies to loss='huber', not loss={loss!r}")
    if loss == "huber" and reweight is not None and int(reweight) == 0:
        raise OptionError("loss='huber' needs reweight ≥ 1: the first solve is a squared-loss "
                          "fit, and the Huber weights come from its residuals")


def _check_bound_options(model: RobotModel, constraints: object, com_boxes: object,
                         mass_bounds: object, total_mass: object) -> None:
    """Shapes and types of the per-body options, each error naming its option and body."""
    if not isinstance(constraints, (str, Mapping)):
        raise OptionError(f"constraints must be a level name or {{body: level}}, got "
                          f"{constraints!r}")
    for name, mapping in (("com_boxes", com_boxes), ("mass_bounds", mass_bounds)):
        if mapping is not None and not isinstance(mapping, Mapping):
            raise OptionError(f"{name} must be a mapping {{body: bounds}}, got {mapping!r}")
    for body, box in (com_boxes or {}).items():
        check_box(f"com_boxes[{body!r}]", box)
    for body, bounds in (mass_bounds or {}).items():
        check_bounds(f"mass_bounds[{body!r}]", bounds)
    if total_mass is not None:
        check_bounds("total_mass", total_mass)


def _body_levels(model: RobotModel, constraints: str | Mapping[str, str]) -> tuple[str, ...]:
    if isinstance(constraints, str):
        check_option("constraints", constraints, cons.LEVELS)
        return (constraints,) * model.n_bodies
    unknown = sorted(set(constraints) - set(model.body_names))
    if unknown:
        raise OptionError(f"constraints name unknown bodies {unknown}; bodies are "
                          f"{model.body_names}")
    for body, level in constraints.items():
        check_option(f"constraints[{body!r}]", level, cons.LEVELS)
    return tuple(constraints.get(b, "pseudo-inertia") for b in model.body_names)


def _collision_levels(model: RobotModel, constraints: str | Mapping[str, str],
                      ellipsoids: Mapping[str, cons.Ellipsoid] | str | None
                      ) -> tuple[str | Mapping[str, str], Mapping[str, cons.Ellipsoid] | None]:
    """``(constraints, ellipsoids)`` with ``ellipsoids="collision"`` resolved (see
    :func:`identify_sdp`); other values pass unchanged."""
    if not isinstance(ellipsoids, str):
        return constraints, ellipsoids
    check_option("ellipsoids", ellipsoids, ("collision",))
    levels = _body_levels(model, constraints)
    if "ellipsoid" not in levels:
        raise OptionError("ellipsoids='collision' bounds the bodies at level 'ellipsoid', and "
                          "none is: use constraints='ellipsoid' or {body: 'ellipsoid'}")
    from ..robot.shapes import collision_ellipsoids

    try:
        found = collision_ellipsoids(model)
    except ModelError as exc:
        raise ModelError(f"{exc} (ellipsoids='collision' reads the meshes with no package_dirs: "
                         "build them with consistid.robot.shapes.collision_ellipsoids(model, "
                         "package_dirs=[...]) and pass that dict as ellipsoids=)") from exc
    missing = [b for b, lvl in zip(model.body_names, levels)
               if lvl == "ellipsoid" and b not in found]
    if missing and not isinstance(constraints, str):
        raise OptionError(f"bodies {missing} have constraints='ellipsoid' but no <collision> "
                          "geometry for ellipsoids='collision'")
    chosen = {b: ("pseudo-inertia" if b in missing else lvl)
              for b, lvl in zip(model.body_names, levels)}
    return chosen, {b: e for b, e in found.items() if chosen[b] == "ellipsoid"}


def _check_bodies(model: RobotModel, *mappings: Mapping[str, Any] | None) -> None:
    for mapping in mappings:
        unknown = sorted(set(mapping or {}) - set(model.body_names))
        if unknown:
            raise OptionError(f"unknown bodies {unknown}; bodies are {model.body_names}")


def _reference(body: np.ndarray, fallback: float) -> np.ndarray:
    """The prior body itself if realisable, else its pseudo-inertia with eigenvalues raised to
    ``10⁻³`` of its largest (or to ``fallback`` for a massless body): a well-conditioned
    realisable body that only scales the program (and the default Euclidean metric)."""
    if not is_degenerate(body):
        return body
    lam, vec = np.linalg.eigh(pseudo_inertia(body))
    floor = 1e-3 * lam[-1] if lam[-1] > 0 else fallback
    return from_pseudo_inertia(vec @ np.diag(np.maximum(lam, floor)) @ vec.T)


def _make_setup(model: RobotModel, spec: RegressorSpec, prior_vec: np.ndarray,
                constraints: str | Mapping[str, str], prior: str | None, gamma: float,
                prior_weights: np.ndarray | None, ellipsoids: Mapping[str, cons.Ellipsoid] | None,
                neighbourhood: priors.Neighbourhood | None, com_boxes: Mapping | None,
                mass_bounds: Mapping | None, total_mass: tuple | None,
                friction_nonnegative: bool, margin: float) -> _Setup:
    levels = _body_levels(model, constraints)
    ellipsoids = dict(ellipsoids or {})
    _check_bodies(model, ellipsoids, com_boxes, mass_bounds)
    missing = [b for b, lvl in zip(model.body_names, levels)
               if lvl == "ellipsoid" and b not in ellipsoids]
    if missing:
        raise OptionError(f"bodies {missing} have constraints='ellipsoid' but no ellipsoids[...]")
    unused = [b for b, lvl in zip(model.body_names, levels)
              if lvl != "ellipsoid" and b in ellipsoids]
    if unused:
        raise OptionError(f"ellipsoids given for bodies {unused}, whose constraints level is not "
                          "'ellipsoid' (set constraints={body: 'ellipsoid'} for them)")
    nb = model.n_bodies
    bodies = prior_vec[:10 * nb].reshape(nb, 10)
    if prior == "logdet":
        for name, body in zip(model.body_names, bodies):
            if is_degenerate(body):
                lam = np.linalg.eigvalsh(pseudo_inertia(body))
                what = ("no physical body, or a massless one" if not lam[0] > 0 else
                        "a body with no extent along some direction")
                raise InconsistentParametersError(
                    f"{name}: the prior (URDF) pseudo-inertia is not positive definite to "
                    f"working precision (eigenvalues {lam[0]:.3g} … {lam[-1]:.3g}: {what}); "
                    "the log-det prior needs realisable prior bodies and weighs that direction "
                    "without bound. Fix the URDF inertia or use prior='euclidean' / None")
    lam_max = max(float(np.linalg.eigvalsh(pseudo_inertia(b))[-1]) for b in bodies)
    refs = np.concatenate([_reference(b, 1e-3 * max(lam_max, 1e-12)) for b in bodies])
    scalings = tuple(cons.BodyScaling.from_reference(refs[body_slice(i)])
                     for i in range(nb))
    bounds = tuple(cons.relative_bound(refs[body_slice(i)], levels[i], margin)
                   for i in range(nb))
    nonneg = np.zeros(prior_vec.size, dtype=bool)
    if friction_nonnegative:
        nonneg[10 * nb + spec.nonnegative_columns] = True
    euclid_w = None
    if prior == "euclidean":
        p_in = 10 * nb
        if prior_weights is None:
            euclid_w = scipy.linalg.block_diag(*(priors.logdet_metric(refs[body_slice(i)])
                                                 for i in range(nb)))
        else:
            w = np.asarray(prior_weights, dtype=float)
            if w.shape == (p_in,):
                w = np.diag(w)
            if w.shape != (p_in, p_in) or not np.all(np.isfinite(w)):
                raise OptionError(f"prior_weights must be finite, of shape ({p_in},) or "
                                  f"({p_in}, {p_in}), got {np.shape(prior_weights)}")
            euclid_w = w
    return _Setup(levels, refs, scalings, bounds,
                  tuple(ellipsoids.get(b) for b in model.body_names), nonneg, euclid_w, prior,
                  gamma, neighbourhood, dict(com_boxes or {}), dict(mass_bounds or {}), total_mass)


# ------------------------------------------------------------------------------------ noise
def _ols_sigma(problem: CompressedProblem, base: BaseParameters) -> np.ndarray:
    """Per-joint σ from the residual of an (unconstrained, minimum-norm) OLS fit; works for
    rank-deficient data, where the residual is still unique."""
    r, z, _ = problem.stacked(columns=base.independent)
    beta, _, rank, _ = np.linalg.lstsq(r, z, rcond=1e-11)
    sse = problem.sum_squares(beta, base.independent)
    return joint_sigma(sse, problem.n_samples, rank)


def _huber_weights(model: RobotModel, dataset: Dataset, spec: RegressorSpec, theta: np.ndarray,
                   c: float, problem: CompressedProblem) -> tuple[np.ndarray, np.ndarray]:
    """MAD noise scale per joint (floored as every σ, :func:`floor_sigma`: noise-free data have
    MAD = 0) and Huber IRLS weights ``min(1, c σ / |r|)`` per sample, in ``[0, 1]``."""
    res = residual_torque(model, dataset, spec, theta)      # the rows the fit sees
    mad = np.median(np.abs(res - np.median(res, axis=0)), axis=0)
    sig = floor_sigma(1.4826 * mad, problem)
    u = np.abs(res) / sig
    return sig, np.clip(c / np.maximum(u, c), 0.0, 1.0)


# ------------------------------------------------------------------------------------ program
def _prior_hessian(prior: str | None, setup: _Setup, nb: int,
                   around: np.ndarray | None = None) -> np.ndarray:
    """Curvature ``H₀`` of the prior term (per unit weight) on the inertial block, at ``π₀``
    or, for the log-det prior, at ``around`` (bodies there that are not realisable: at ``π₀``)."""
    if prior == "euclidean":
        return 2.0 * setup.euclid_w.T @ setup.euclid_w
    blocks = []
    for i in range(nb):
        at = setup.references[body_slice(i)]
        if around is not None and prior == "logdet":
            body = around[body_slice(i)]
            if np.linalg.eigvalsh(pseudo_inertia(body))[0] > 0:
                at = body
        blocks.append(priors.logdet_metric(at))
    metric = scipy.linalg.block_diag(*blocks)
    return 2.0 * metric.T @ metric


def _normalising_map(r: np.ndarray, setup: _Setup, p: int, nb: int) -> np.ndarray:
    """``T`` of the prior-normalised coordinates ``θ = T y``: per-body congruence
    (:meth:`~consistid.identification.constraints.BodyScaling.parameter_map`), and each joint
    column scaled to unit norm in ``r`` (unit scale where it has none)."""
    p_in = 10 * nb
    t = np.eye(p)
    t[:p_in, :p_in] = scipy.linalg.block_diag(*(sc.parameter_map() for sc in setup.scalings))
    d = np.sum((r @ t)[:, p_in:] ** 2, axis=0)
    t[:, p_in:] /= np.sqrt(np.where(d > 0, d, 1.0))
    return t


def _evidence_gamma(problem: CompressedProblem, sig: np.ndarray, prior_vec: np.ndarray,
                    setup: _Setup, nb: int, gamma_default: float,
                    joint_rows: tuple[np.ndarray, np.ndarray]) -> tuple[float, int]:
    """The prior weight of :func:`~consistid.identification.prior_weight.evidence_weight` on
    the σ-weighted ``problem`` with the joint prior's rows ``(D, t)`` appended, as the solve
    has them (:mod:`consistid.identification.joint_prior`: the per-joint terms are integrated
    out under that Gaussian, not flat), in prior-normalised coordinates, within
    :data:`EVIDENCE_RANGE` × the default; ``(γ, iterations)``."""
    r, z = append_rows(*problem.stacked(sigma=sig)[:2], *joint_rows)
    p, p_in = prior_vec.size, 10 * nb
    t = _normalising_map(r, setup, p, nb)
    s = np.zeros((p, p))
    s[:p_in, :p_in] = 0.5 * (t[:p_in, :p_in].T @ _prior_hessian(setup.prior, setup, nb)
                             @ t[:p_in, :p_in])
    a = r @ t
    b = z - a @ np.linalg.solve(t, prior_vec)
    lo, hi = EVIDENCE_RANGE
    return evidence_weight(a, s, b, (lo * gamma_default, hi * gamma_default), gamma_default)


def _whitening(r: np.ndarray, z: np.ndarray, prior_vec: np.ndarray, setup: _Setup, nb: int,
               around: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(θ_c, Φ)`` with ``Φᵀ(RᵀR + ½γ_s H₀)Φ = 1`` and ``θ_c`` its quadratic-model minimiser
    (both from one QR factorisation, so that noise-free data, whose weights are ~10⁶ σ⁻¹, stay
    accurate).

    Computed in prior-normalised coordinates ``θ = T y`` (per-body congruence, unit scale for the
    joint columns), where the Cholesky factor is well conditioned. ``γ_s = γ`` (exact
    whitening of the quadratic model, which keeps Clarabel accurate from ``γ = 10⁻⁶`` to ``10²``
    times the default), or 1 without a prior: then unexcited directions get the unit scale of
    ``Ĵ``. Only the coordinates change, not the optimum.

    ``around`` (a previous, inaccurate answer): centre there instead, with the log-det
    curvature ``J⁻¹ ⊗ J⁻¹`` of that answer rather than of the prior (one Newton-like rescaling).
    """
    prior, gamma = setup.prior, setup.gamma
    p, p_in = prior_vec.size, 10 * nb
    t = _normalising_map(r, setup, p, nb)
    a = r @ t
    h0 = np.zeros((p, p))
    h0[:p_in, :p_in] = (t[:p_in, :p_in].T @ _prior_hessian(prior, setup, nb, around)
                        @ t[:p_in, :p_in])
    m2 = 0.5 * (gamma if gamma > 0 else 1.0) * h0
    m2[p_in:, p_in:] += 1e-9 * np.eye(p - p_in)
    m2 += 1e-12 * np.diag(np.sum(a ** 2, axis=0) + np.diag(m2))  # keeps m2 definite
    m_half = np.linalg.cholesky(m2).T                       # m2 = m_halfᵀ m_half
    # QR of [a; m_half] (not Cholesky of the normal matrix, whose condition number is squared):
    # r_augᵀ r_aug = aᵀa + m2, and the centre minimises ‖a y − z‖² + ‖m_half (y − y0)‖².
    y0 = np.linalg.solve(t, prior_vec)
    q_aug, r_aug = np.linalg.qr(np.vstack([a, m_half]))
    y_c = scipy.linalg.solve_triangular(r_aug, q_aug.T @ np.concatenate([z, m_half @ y0]))
    phi = t @ scipy.linalg.solve_triangular(r_aug, np.eye(p))
    if around is not None:
        return around.copy(), phi
    return t @ y_c, phi


@dataclass(frozen=True, eq=False)
class _Program:
    """A built program: the cvxpy problem, its variable, ``θ(w) = θ_c + Φ w`` and the labelled
    constraints (one label per constraint, or one per row of a vector constraint)."""

    problem: cp.Problem
    w: cp.Variable
    theta_c: np.ndarray
    phi: np.ndarray
    labelled: tuple[tuple[cp.Constraint, tuple[str, ...]], ...]

    def theta(self) -> np.ndarray:
        return self.theta_c + self.phi @ self.w.value

    def slacks(self) -> list[tuple[str, float]]:
        """``(label, slack)`` of every constraint at ``w.value``: ``−expr`` for inequalities, the
        smallest eigenvalue over ``max(1, largest)`` for LMIs (prior-normalised when scaled)."""
        out = []
        for con, labels in self.labelled:
            out += compiled_programs.constraint_slacks(con, labels,
                                                       np.asarray(con.expr.value, dtype=float))
        return out


def _build(model: RobotModel, spec: RegressorSpec, r: np.ndarray, z: np.ndarray,
           prior_vec: np.ndarray, setup: _Setup, scale: bool,
           around: np.ndarray | None = None, solver: str = DEFAULT_SOLVER
           ) -> _Program | compiled_programs.BoundProgram:
    """The program of one pass (module docstring). Scaled and solved by Clarabel: the
    structure compiled once per model and options (:mod:`consistid.identification.program`)
    with this pass's data bound to it; otherwise a cvxpy program built afresh."""
    nb, p = model.n_bodies, prior_vec.size
    if scale:
        theta_c, phi = _whitening(r, z, prior_vec, setup, nb, around)
    else:
        theta_c, phi = np.zeros(p), np.eye(p)
    if scale and solver == "CLARABEL":
        key = (tuple(model.body_names), tuple(parameter_names(model, spec)),
               _structure_key(spec, prior_vec, setup))
        program = compiled_programs.compiled(
            key, lambda: _compile(model, spec, prior_vec, setup))
        return program.bind(theta_c, phi, r, z, setup.gamma)
    w = cp.Variable(p, name="w")
    theta = theta_c + phi @ w
    objective = cp.sum_squares((r @ phi) @ w - (z - r @ theta_c))
    labelled, prior_terms = _constraints(model, spec, theta, prior_vec, setup, scale, phi)
    if prior_terms and setup.gamma > 0:
        objective = objective + setup.gamma * cp.sum(cp.hstack(prior_terms))
    problem = cp.Problem(cp.Minimize(objective), [c for c, _ in labelled])
    return _Program(problem, w, theta_c, phi, tuple(labelled))


def _structure_key(spec: RegressorSpec, prior_vec: np.ndarray, setup: _Setup) -> tuple:
    """What fixes a compiled program's structure and constants (not the data, σ or γ)."""
    akey = compiled_programs.array_key
    return (spec, akey(prior_vec), setup.levels, akey(setup.references),
            tuple(akey(b) for b in setup.bounds),
            tuple(None if e is None else (akey(e.center), akey(e.shape))
                  for e in setup.ellipsoids),
            akey(setup.nonnegative), akey(setup.euclid_w), setup.prior, setup.gamma > 0,
            setup.neighbourhood,
            tuple((b, akey(lo), akey(hi)) for b, (lo, hi) in sorted(setup.com_boxes.items())),
            tuple((b, lo, hi) for b, (lo, hi) in sorted(setup.mass_bounds.items())),
            None if setup.total_mass is None else tuple(setup.total_mass))


def _compile(model: RobotModel, spec: RegressorSpec, prior_vec: np.ndarray,
             setup: _Setup) -> compiled_programs.CompiledProgram:
    """The structure of the scaled program in prior-normalised variables ``y`` (``θ = T y``),
    its prior term at unit weight: :class:`~consistid.identification.program.CompiledProgram`."""
    nb, p = model.n_bodies, prior_vec.size
    t_map = np.eye(p)
    t_map[:10 * nb, :10 * nb] = scipy.linalg.block_diag(
        *(sc.parameter_map() for sc in setup.scalings))
    y = cp.Variable(p, name="y")
    labelled, prior_terms = _constraints(model, spec, t_map @ y, prior_vec, setup, True, None)
    euclidean = None
    if setup.prior == "euclidean":      # a quadratic in w, added by the bound program itself
        prior_terms = []
        if setup.gamma > 0:
            euclidean = (setup.euclid_w, prior_vec[:10 * nb])
    objective = (cp.sum(cp.hstack(prior_terms)) if prior_terms and setup.gamma > 0
                 else cp.Constant(0.0))
    problem = cp.Problem(cp.Minimize(objective), [c for c, _ in labelled])
    idx = np.flatnonzero(setup.nonnegative)
    return compiled_programs.CompiledProgram(problem, y, t_map, labelled,
                                             (len(labelled) - 1, idx) if idx.size else None,
                                             euclidean)


def _constraints(model: RobotModel, spec: RegressorSpec, theta: cp.Expression,
                 prior_vec: np.ndarray, setup: _Setup, scale: bool, phi: np.ndarray | None
                 ) -> tuple[list[tuple[cp.Constraint, tuple[str, ...]]], list[cp.Expression]]:
    """The labelled constraints and the prior terms (unit weight) on ``theta``; ``phi`` gives
    the friction bounds' unit scale (``None``: unscaled rows, which
    :class:`~consistid.identification.program.BoundProgram` normalises itself)."""
    nb = model.n_bodies
    prior, neighbourhood = setup.prior, setup.neighbourhood
    com_boxes, mass_bounds, total_mass = setup.com_boxes, setup.mass_bounds, setup.total_mass
    labelled: list[tuple[cp.Constraint, tuple[str, ...]]] = []
    prior_terms = []
    for i, body in enumerate(model.body_names):
        x = theta[body_slice(i)]
        body_prior = prior_vec[body_slice(i)]
        for con in cons.body_constraints(x, setup.levels[i], setup.bounds[i],
                                         setup.ellipsoids[i],
                                         setup.scalings[i] if scale else None):
            level = "pseudo-inertia" if setup.levels[i] == "ellipsoid" else setup.levels[i]
            kind = f"{level} LMI" if isinstance(con, cp.constraints.PSD) else "bounding ellipsoid"
            labelled.append((con, (f"{body}: {kind}",)))
        if prior == "logdet":
            prior_terms.append(priors.logdet_divergence(x, body_prior, normalised=scale))
        if neighbourhood is not None:
            kinds = [k for k in ("mass", "com", "inertia") if getattr(neighbourhood, k) is not None]
            labelled += [(con, (f"{body}: {k} neighbourhood",)) for con, k in zip(
                priors.neighbourhood_constraints(x, body_prior, neighbourhood), kinds)]
        m_ref = max(setup.references[10 * i], 1e-12) if scale else 1.0
        if com_boxes and body in com_boxes:
            lo, hi = (np.asarray(v, dtype=float) for v in com_boxes[body])
            c_lo, c_hi = cons.com_box(x / m_ref, lo, hi)
            labelled += [(c_lo, tuple(f"{body}: c{a} ≥ {v:g}" for a, v in zip("xyz", lo))),
                         (c_hi, tuple(f"{body}: c{a} ≤ {v:g}" for a, v in zip("xyz", hi)))]
        if mass_bounds and body in mass_bounds:
            lo, hi = mass_bounds[body]
            for con, bound in zip(cons.mass_bounds(x / m_ref, None if lo is None else lo / m_ref,
                                                   None if hi is None else hi / m_ref),
                                  [f"m ≥ {v:g}" if k == 0 else f"m ≤ {v:g}"
                                   for k, v in enumerate((lo, hi)) if v is not None]):
                labelled.append((con, (f"{body}: {bound}",)))
    if prior == "euclidean":
        prior_terms.append(priors.euclidean(theta[:10 * nb], prior_vec[:10 * nb], setup.euclid_w))
    if total_mass is not None:
        m_tot = max(float(np.sum(setup.references[0:10 * nb:10])), 1e-12) if scale else 1.0
        masses = cp.sum(theta[0:10 * nb:10]) / m_tot
        lo, hi = total_mass
        if lo is not None:
            labelled.append((masses >= lo / m_tot, (f"total mass ≥ {lo:g}",)))
        if hi is not None:
            labelled.append((masses <= hi / m_tot, (f"total mass ≤ {hi:g}",)))
    idx = np.flatnonzero(setup.nonnegative)
    if idx.size:
        names = parameter_names(model, spec)
        # unit scale per column: the whitening's scale of that parameter
        col = (np.maximum(np.linalg.norm(phi[idx], axis=1), 1e-300)
               if scale and phi is not None else np.ones(idx.size))
        labelled.append((cp.multiply(1.0 / col, theta[idx]) >= 0,
                         tuple(f"{names[k]} ≥ 0" for k in idx)))
    return labelled, prior_terms


def _solve_pass(program: _Program, model: RobotModel, spec: RegressorSpec, r: np.ndarray,
                z: np.ndarray, prior_vec: np.ndarray, setup: _Setup, solver: str,
                options: dict[str, Any] | None, scale: bool
                ) -> tuple[_Program, list[SolverReport]]:
    """Solve; if the scaled program ends ``optimal_inaccurate``, rescale around that answer
    (:func:`_whitening` with ``around``) and solve once more. The refined answer replaces the
    first only if its solve succeeds; otherwise the first stands, with its warning."""
    if not scale:
        return program, [_solve(program, model, prior_vec, solver, options, scale)]
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            first = _solve(program, model, prior_vec, solver, options, scale)
    except Exception:
        _rewarn(caught)  # what the solver said before failing is part of the diagnosis
        raise
    if first.status != cp.OPTIMAL_INACCURATE:
        _rewarn(caught)
        return program, [first]
    refined = _build(model, spec, r, z, prior_vec, setup, scale, around=program.theta(),
                     solver=solver)
    try:
        second = _solve(refined, model, prior_vec, solver, options, scale)
    except IdentificationError:
        _rewarn(caught)
        return program, [first]
    return refined, [first, second]


def _rewarn(caught: list[warnings.WarningMessage]) -> None:
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _solve(program: _Program, model: RobotModel, prior_vec: np.ndarray, solver: str,
           options: dict[str, Any] | None, scale: bool) -> SolverReport:
    """:func:`consistid.identification.solver.solve` (status contract), with a diagnosis added to
    its errors.

    An infeasibility claim is checked at the prior: if the prior satisfies every constraint the
    claim is numerical (typically: no prior, and parameters the data leave free are unbounded),
    and an :class:`IdentificationError` says so; otherwise the constraints the prior violates
    are named.
    """
    if scale and solver == "CLARABEL":
        # The variables are already whitened: Clarabel's Ruiz equilibration is redundant, and
        # with it the Panda sweep over prior weights 1e-6..1e2 × default ended inaccurate once
        # (at 1e-6) in 54 solves, without it never.
        options = {"equilibrate_enable": False, **(options or {})}
    what = f"SDP identification of {model.name!r}"
    try:
        if isinstance(program, compiled_programs.BoundProgram):
            status, solve_time, setup_time, iterations = program.solve(what, options)
            return SolverReport(solver, status, solve_time, setup_time, iterations)
        return solve(program.problem, what, solver, options)
    except InfeasibleError as exc:
        program.w.value = np.linalg.solve(program.phi, prior_vec - program.theta_c)
        violated = [f"{label} (slack {v:.3g})" for label, v in program.slacks()
                    if v < -CHECK_TOL]
        if not violated:
            raise IdentificationError(
                f"{exc}, but the prior satisfies every constraint, so the problem is feasible "
                "and the solver failed numerically. Hint: without a prior, parameters the data "
                "do not determine (e.g. the first link's mass on a fixed base) are unbounded; "
                "use prior='logdet' (a small prior_weight keeps it weak) or bound the masses "
                "(mass_bounds, total_mass)") from exc
        raise InfeasibleError(
            f"{exc}. Hint: the prior violates {len(violated)} of the constraints: "
            + "; ".join(violated[:5]) + ". Check com_boxes, mass_bounds, total_mass, ellipsoids "
            "and neighbourhood bounds against each other") from exc
    except IdentificationError as exc:
        hint = ("scale=False hands the solver badly scaled data: use scale=True" if not scale
                else "bounds (com_boxes, mass_bounds, total_mass, ellipsoids, neighbourhood) may "
                "contradict each other without the solver proving it; a prior (prior='logdet') "
                "bounds directions the data leave free; solver_options={'max_iter': ...} or "
                "another solver may help")
        raise type(exc)(f"{exc}. Hint: {hint}") from exc


# ------------------------------------------------------------------------------------ answer
def _check_answer(program: _Program) -> tuple[str, ...]:
    """FloBaRoID-style check of the answer against every constraint, beyond the status: raises
    when one is violated by more than the solver's tolerance, else returns the active ones."""
    slacks = program.slacks()
    bad = [f"{label} (slack {v:.3g})" for label, v in slacks if v < -CHECK_TOL]
    if bad:
        raise IdentificationError("the solver reported success but the answer violates "
                                  f"{len(bad)} constraint(s): " + "; ".join(bad[:5])
                                  + ". Hint: keep scale=True, or try another solver")
    return tuple(label for label, v in slacks if v < ACTIVE_TOL)


def _base_covariance(r_b: np.ndarray) -> tuple[float, np.ndarray]:
    """Condition number of the weighted base factor and ``(R_bᵀR_b)⁻¹``; parameters touched by
    directions the data do not excite (singular value below
    :data:`~consistid.identification.identify.RANK_RTOL` of the largest) get infinite variance."""
    _, s, vt = np.linalg.svd(r_b)
    if s[0] == 0:
        return float("inf"), np.full((s.size, s.size), np.inf)
    keep = s > RANK_RTOL * s[0]
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    cov = (vt[keep].T / s[keep] ** 2) @ vt[keep]
    if not np.all(keep):
        touched = np.linalg.norm(vt[~keep], axis=0) > 1e-6
        cov[touched, :] = np.inf
        cov[:, touched] = np.inf
    return cond, cov


def _details(model: RobotModel, theta: np.ndarray, setup: _Setup, prior_vec: np.ndarray,
             gamma_default: float, given: float | str | None, active: tuple[str, ...],
             chi2: float, evidence: tuple[int, float] | None = None) -> dict[str, Any]:
    nb, prior, gamma = model.n_bodies, setup.prior, setup.gamma
    lam, rel = {}, {}
    for i, b in enumerate(model.body_names):
        j = pseudo_inertia(theta[body_slice(i)])
        l_inv = setup.scalings[i].l_inv
        lam[b] = float(np.linalg.eigvalsh(j)[0])
        rel[b] = float(np.linalg.eigvalsh(l_inv @ j @ l_inv.T)[0])
    divergence = float("nan")
    if prior == "logdet":
        divergence = sum(priors.logdet_divergence_value(theta[body_slice(i)],
                                                        prior_vec[body_slice(i)])
                         for i in range(nb))
    elif prior == "euclidean":
        divergence = float(np.sum((setup.euclid_w @ (theta[:10 * nb] - prior_vec[:10 * nb])) ** 2))
    levels = set(setup.levels)
    described = (levels.pop() if len(levels) == 1 else
                 ", ".join(f"{b}={lvl}" for b, lvl in zip(model.body_names, setup.levels)))
    shown = ", ".join(active[:4]) + (f" … ({len(active)} in all)" if len(active) > 4 else "")
    return {
        # strings and numbers (the summary prints these)
        "constraints": f"{described}; active: {shown or 'none'}",
        "prior": str(prior),
        "prior_weight": gamma,
        "prior_weight_rule": "no prior" if prior is None else (
            f"chosen from the data (evidence of the quadratic prior model): "
            f"{gamma / gamma_default:.3g} × the default 2/r², {evidence[0]} fixed-point "
            f"iterations, {evidence[1] * 1e3:.2g} ms") if evidence is not None
        else "given" if given is not None
        else f"default 2/r², r = {np.sqrt(2.0 / gamma_default):.3g}",
        # structured figures
        "active_constraints": active,
        "min_eigenvalues": lam,
        "relative_margins": rel,
        "fit": {"data_chi2": chi2, "prior_divergence": divergence,
                "default_prior_weight": gamma_default},
    }
