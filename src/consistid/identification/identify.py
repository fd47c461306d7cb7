r"""Identification of the dynamic parameters from a dataset: OLS, WLS and the consistent SDP.

Least squares on the base parameters (Gautier & Khalil 1990; Khalil & Dombre ch. 12):

.. math::  \hat\beta = \arg\min_\beta \|\Sigma^{-1/2}(W_b \beta - \tau)\|^2,
           \qquad \operatorname{cov}(\hat\beta) = (W_b^\top \Sigma^{-1} W_b)^{-1}

with ``Σ = σ² 1`` for OLS (``σ² = ‖ρ‖² / (N·nv − b)``) and, for WLS, ``Σ = diag(σ_j²)`` per joint
estimated from the OLS residuals (``σ_j² = ‖ρ_j‖² / (N − b/nv)``), Gautier 1997, "Dynamic
identification of robots with power model", ICRA, doi:10.1109/ROBOT.1997.614364; ``σ_j`` is
floored by :func:`consistid.identification.compression.floor_sigma` so that noise-free data keep
finite weights.
Everything is solved on the compressed problem (:mod:`consistid.identification.compression`), never
on the
N-row regressor.

Both covariances count the ``N`` rows of each joint as independent (``covariance="iid"``).
Filtered torque logs have residuals correlated over tens of samples, which makes them far too
small; with ``covariance="coloured"`` (the default, ``"auto"``, unless ``loss="huber"``) each
joint's rows count as ``N / τ_j`` independent ones, ``τ_j`` the
integrated autocorrelation time of its residual
(:func:`consistid.identification.statistics.autocorrelation_time`,
one extra pass over the data), through the sandwich
:func:`consistid.identification.statistics.coloured_covariance`

.. math::  \operatorname{cov}(\hat\beta) = C \Big(\sum_j τ_j w_j^2 v_j R_{jb}^\top R_{jb}\Big) C,

``C`` the covariance above, ``w_j = 1/σ_j²`` the weights it was computed with, ``v_j`` joint
``j``'s own residual variance (:func:`consistid.identification.compression.joint_sigma` with
``τ_j``: OLS
weighs the joints alike whatever their noise) and ``R_{jb}`` joint ``j``'s R factor restricted
to the base columns (``Y_{jb}^\top Y_{jb} = R_{jb}^\top R_{jb}``).
The estimate itself is unchanged. On white noise ``τ_j ≈ 1`` and the two agree.

``"coloured"`` also adds a model-error term to the diagonal: where a joint stands still, dry
friction takes any torque up to its break-away, which ``f_c sign(q̇)`` does not describe, and
those rows bias the fit beyond any noise ± (:mod:`consistid.identification.model_error`: the
Hausman difference of the least-squares fits with and without them, less its noise;
``details["model_error"]``, ``details["model_error_note"]``). A fit weighted per joint (WLS, the
SDP) also gets the excess of its difference from the equal-weight fit over that difference's
noise, when Hausman's test of the weights rejects (:mod:`consistid.identification.weighting_error`:
through the signal chain the residual is mostly model error, which the weights ``1/σ_j²``
follow; ``details["weighting_error"]``, ``details["weighting_error_note"]``).

``covariance="hac"`` replaces the per-joint ``τ_j`` by the heteroskedasticity- and
autocorrelation-consistent sandwich of the least-squares scores
(:func:`consistid.identification.statistics.hac_covariance`; Newey & West 1987, Andrews 1991),
with the same model-error term. The default stays ``"coloured"``: it reads the residual on a few
windows only (``"hac"`` needs the regressor of every sample once more, about as long as the
compression), and measured coverage is the same or better — MuJoCo UR5 and Panda with dry
friction: 1.000 with either; the benchmark's AR(1) noise (φ = 0.9, 2 000 samples): 0.85–0.92
against 0.83–0.90 for ``"hac"``, whose batch sums are few on short logs; white noise: both
0.93–0.97. ``"hac"`` is the one to use when the noise changes along the log (e.g. with the
torque), which ``τ_j`` and one variance per joint do not describe.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
import weakref
from typing import Any, Iterable, Sequence

import numpy as np
import scipy.linalg

from .angle_units import flag_degrees
from .base import COND_WARN, RANK_RTOL, BaseParameters, compute_base_parameters
from .compression import CompressedProblem, floor_sigma, joint_sigma
from ..data.checks import check_for_identification
from ..data.dataset import Dataset, as_dataset
from ..errors import (DataQualityWarning, ModelMisfitWarning, ModelWarning, OptionError,
                      PoorExcitationError, PoorExcitationWarning, check_option)
from ..friction.fit import NONLINEAR_OPTIONS, identify_nonlinear, is_nonlinear
from ..robot.inertia import degenerate_bodies
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel, require_model
from .regressor import DEFAULT_FRICTION, FrictionArg, RegressorSpec, parameter_names, prior_vector
from .result import IdentificationResult
from .solver import SolverReport
from .model_error import rest_bias, split_bias
from .weighting_error import weighting_bias
from .statistics import ScoreSums, coloured_covariance, hac_covariance, score_sums
from .uninformed import uninformed_directions
from .envelope import TrainingEnvelope
from .weak import one_way_note, weakly_informed
from .subset import (dead_channels, expand, lost_parameters, resolve_excluded, restricted,
                     rows_base, without_joints)
from .streaming import (BAND_ALPHA, BAND_RATIO, SPEED_EDGES, DataStream, ResidualStatistics,
                        as_stream, compress_data, is_one_pass, is_stream, residual_statistics)

METHODS = ("ols", "wls", "sdp")
#: ``covariance=`` choices: rows counted as independent, as ``N / τ_j`` per joint, or the HAC
#: sandwich of the scores.
COVARIANCES = ("iid", "coloured", "hac")
#: ... and ``"auto"``: ``"coloured"``, except ``"iid"`` with ``loss="huber"`` (re-weighted rows).
COVARIANCE_OPTIONS = ("auto", *COVARIANCES)
#: A joint's residual at standstill this many times its RMS where it moves (the factor the
#: diagnosis flags a remainder at), beyond chance at level :data:`STANDSTILL_ALPHA`, is said
#: (:func:`standstill_note`).
STANDSTILL_RATIO = BAND_RATIO
#: Level of that test (the diagnosis' remainder test's).
STANDSTILL_ALPHA = BAND_ALPHA


#: Base parameters computed per model object (weakly: they go with it), spec and gravity.
_BASES: "weakref.WeakKeyDictionary[RobotModel, dict[tuple, BaseParameters]]" = \
    weakref.WeakKeyDictionary()


def base_parameters_of(model: RobotModel, spec: RegressorSpec) -> BaseParameters:
    """:func:`~consistid.identification.base.compute_base_parameters` of ``(model, spec)`` with
    its defaults (deterministic: seeded random states), computed once per model object, spec
    and gravity (a pivoted QR of a ``4p × p`` regressor: 0.4 s on the 32-body Talos, as much as
    ``pin.rnea`` over 10⁵ samples), so that repeated ``identify`` calls on one model (Monte
    Carlo, refits) do not redo it."""
    key = (spec, tuple(np.asarray(model.pin_model.gravity.linear, dtype=float)))
    try:
        per_model = _BASES.setdefault(model, {})
    except TypeError:                       # not weakly referenceable: no cache
        return compute_base_parameters(model, spec)
    if key not in per_model:
        per_model[key] = compute_base_parameters(model, spec)
    return per_model[key]


def nearest_standard(base: BaseParameters, beta: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """The standard vector closest to ``prior`` (Euclidean) with ``B π = β``:
    ``π = π₀ + B⁺(β − B π₀)``. Not necessarily physically consistent."""
    B = base.matrix
    return prior + np.linalg.lstsq(B, beta - B @ prior, rcond=None)[0]


def check_excitation(r: np.ndarray, base: BaseParameters) -> tuple[float, np.ndarray]:
    """Singular values and condition number of a (weighted) base regressor factor ``r``.

    Raises :class:`PoorExcitationError` naming the unexcited directions as base groupings
    (:func:`consistid.identification.uninformed.uninformed_directions`) when ``r`` is singular.
    """
    s = np.linalg.svd(r, compute_uv=False)
    if s[0] == 0 or s[-1] < RANK_RTOL * s[0]:
        dead = uninformed_directions(r, base)
        raise PoorExcitationError(
            f"the data do not excite {len(dead)} of {base.n_base} base-parameter direction(s) "
            f"(condition number {s[0] / max(s[-1], 1e-300):.3g}), which least squares cannot "
            f"determine: {'; '.join(dead[:3])}{' …' if len(dead) > 3 else ''}. Use a richer "
            "excitation trajectory, or method='sdp' with a prior (its result names the "
            "directions the prior decides, res.uninformed)")
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
    cond, _ = check_excitation(r, base)
    beta = scipy.linalg.solve_triangular(r, z)
    sse = problem.sum_squares(beta, cols)
    if weighted:
        sigma = floor_sigma(joint_sigma(sse, n, b), problem)
        r, z, _ = problem.stacked(sigma=sigma, columns=cols)
        cond, _ = check_excitation(r, base)
        beta = scipy.linalg.solve_triangular(r, z)
        sse = problem.sum_squares(beta, cols)
        scale = 1.0                       # the weights already whiten the residual
    else:
        sigma = np.full(problem.nv, np.sqrt(sse.sum() / dof))
        scale = sigma[0] ** 2
    r_inv = scipy.linalg.solve_triangular(r, np.eye(b))
    cov = scale * r_inv @ r_inv.T
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


def default_prior(model: RobotModel) -> str:
    """The SDP's prior for ``prior="auto"``: ``"logdet"``, the Bregman divergence around the
    URDF bodies, when every URDF body is realisable to working precision
    (:func:`consistid.robot.inertia.is_degenerate`); else ``"euclidean"`` in the log-det metric of
    a regularised reference body (the same curvature where the URDF body is realisable), with a
    :class:`ModelWarning` naming the bodies: a log-det divergence centred on a body with no
    extent along some direction (a point mass, a rod, a CAD export's non-physical inertia)
    weighs that direction by ``1/λ_min`` and is no prior at all."""
    bad = degenerate_bodies(model.prior_parameters, model.body_names)
    if not bad:
        return "logdet"
    warnings.warn(f"{', '.join(bad)}: the URDF pseudo-inertia is not positive definite to "
                  "working precision (massless, a point mass or rod, or no physical body), so no "
                  "log-det prior can be centred on it; identify uses prior='euclidean' instead "
                  "(the log-det metric of a regularised body). Fix the URDF inertia for the "
                  "log-det prior, or pass prior='euclidean' / None to choose", ModelWarning,
                  stacklevel=3)
    return "euclidean"


def identify(model: RobotModel, dataset: Dataset | Sequence[Dataset] | Iterable | DataStream,
             method: str = "sdp",
             friction: FrictionArg = DEFAULT_FRICTION,
             armature: bool | Sequence[int | str] = False,
             constraints: str | dict[str, str] = "auto",
             prior: str | None = "auto",
             covariance: str = "auto",
             exclude_joints: Sequence[int | str] = (),
             parallel_filter: bool = True,
             **options: Any) -> IdentificationResult:
    """Identify a robot's dynamic parameters from measured torques.

    Parameters
    ----------
    model : the robot; its URDF inertias are the prior ``π₀``.
    dataset : a :class:`Dataset` with torques, or a list of them (stacked as separate
        recordings); or a stream, read one recording at a time and never held in memory whole
        (:mod:`consistid.identification.streaming`): files (``.npz``/``.csv``), a generator of
        Datasets, a :class:`~consistid.identification.streaming.DataStream`, or a Dask
        collection (:mod:`consistid.identification.distributed`). Same answer as the stacked data.
    method : ``"ols"`` (least squares on base parameters), ``"wls"`` (weighted by per-joint noise
        variance), ``"sdp"`` (physically consistent, see :mod:`consistid.identification.sdp`).
    friction : per-joint friction/offset columns, see :meth:`RegressorSpec.make`; or nonlinear
        laws, ``"stribeck" | "sigmoid" | "tanh"`` for every joint, ``("stribeck", "viscous",
        "offset")``, or ``{joint: law}`` (:mod:`consistid.friction.fit`, variable projection:
        returns a :class:`~consistid.friction.fit.NonlinearFrictionResult`; in-memory data only).
    armature : rotor-inertia columns (``True`` for all joints, or a list of joints).
    constraints : consistency level(s) of the bodies
        (:func:`consistid.identification.sdp.identify_sdp`).
        ``"auto"`` (default): ``"pseudo-inertia"`` for the SDP, none for OLS/WLS, which also
        accept an explicit ``"none"`` and refuse any level.
    prior : ``"logdet"``, ``"euclidean"`` or ``None``/``"none"`` (no prior). ``"auto"``
        (default): ``"logdet"`` for the SDP (``"euclidean"``, with a warning, when a URDF body is
        not realisable: :func:`default_prior`), none for OLS/WLS, which also accept
        ``None``/``"none"`` and refuse a prior.
    covariance : ``"coloured"`` widens ``base_covariance`` for residuals correlated in time
        (filtered torques), each joint's rows counting as ``N / τ_j`` (module docstring; one
        extra pass over the data; the estimate is unchanged; on white noise ``τ_j ≈ 1``),
        plus the model error the rows at rest put into the fit (module docstring;
        ``details["model_error"]`` per base parameter, ``details["model_error_note"]``);
        ``"hac"``: the heteroskedasticity- and autocorrelation-consistent sandwich of the
        least-squares scores (:func:`~consistid.identification.statistics.hac_covariance`:
        batch sums over Andrews' automatic bandwidth; no assumption of equal noise within a
        joint or of columns slower than the noise; one more pass over the regressor, in memory
        or a re-readable stream, not Dask), with the same model-error term;
        ``"iid"`` counts every row as an independent sample. ``"auto"`` (default):
        ``"coloured"``, or ``"iid"`` with ``loss="huber"``, whose re-weighted rows the sandwich
        does not cover, and for a stream that can be read only once (a generator: the sandwich
        needs a second reading). ``details["covariance"]`` names the choice; with ``"coloured"``,
        ``details["autocorrelation_time"]`` gives ``τ_j`` (samples, per joint), and that pass
        also tests each joint's residual where it stands still against where it moves
        (:func:`standstill_note`: a :class:`~consistid.errors.ModelMisfitWarning` and
        ``details["standstill"]``; not with ``"iid"``, which reads the data once), and names
        the joints with friction terms too slow to check their friction law
        (:func:`slow_note`: a :class:`~consistid.errors.PoorExcitationWarning` and
        ``details["slow_joints"]``).
    exclude_joints : joints (names or indices) whose torque rows are left out, e.g. a broken
        sensor: the other joints' rows still inform the rigid-body parameters
        (:mod:`consistid.identification.subset`); their friction columns are dropped, and
        ``details["excluded_joints"]`` names what cannot be identified then. A channel that
        reads one constant (0) throughout while the arm moves is excluded automatically, with
        a :class:`~consistid.errors.DataQualityWarning`. ``sigma`` and ``train_rms`` are NaN
        at excluded joints (no rows); ``res.excluded_joints`` names them.
    parallel_filter : on data that record an identification cut-off
        (``Dataset.identification_filter``: the signal chain sets it at 3 × the motion's band),
        low-pass the torques and every column of the regressor alike there before least
        squares (parallel filtering, :mod:`consistid.data.parallel`;
        ``details["parallel_filter"]``): the estimate, its Gram matrices and Huber's weights
        come from those filtered rows; ``sigma``, ``train_rms``, ``τ_j`` and the long-run
        variances of the sandwich, and the rows at rest, from the samples as they are (the
        filtered rows' σ in ``details["filtered_sigma"]``). ``False``: the
        samples as they are (the positions' derivatives and torques at the chain's derivative
        cut-off). Not for nonlinear friction laws, whose search reads the samples as they are.
    **options : keyword options of :func:`consistid.identification.sdp.identify_sdp`, for
        ``method="sdp"`` only.
        Options that only the SDP uses are refused for OLS/WLS, never silently ignored.

    Returns
    -------
    IdentificationResult
        ``uninformed`` names the base-parameter directions the data do not inform (SDP: their
        values come from the prior alone, a :class:`PoorExcitationWarning` says so).

    Raises
    ------
    OptionError for an unknown method or friction term; JointCountError when the dataset's joint
    count differs from the model's; DatasetError for values beyond ±1e8 (SI units) or every
    torque channel dead (one dead channel among live ones is excluded, with a warning),
    PoorExcitationError for data without any motion
    (:mod:`consistid.data.checks`, before any numerics; a lone glitch only warns,
    :class:`~consistid.errors.DataQualityWarning`); PoorExcitationError when the data cannot
    determine the base parameters (OLS/WLS, naming the directions); IdentificationError /
    InfeasibleError when the SDP solver fails, SolverError when it crashes.
    """
    check_option("method", method, METHODS)
    check_option("covariance", covariance, COVARIANCE_OPTIONS)
    chosen = covariance == "auto"           # not the caller's: said when it cannot hold
    if covariance == "auto":
        covariance = ("iid" if options.get("loss") == "huber" or is_one_pass(dataset)
                      else "coloured")
    if covariance in ("coloured", "hac") and options.get("loss") == "huber":
        raise OptionError(f"covariance={covariance!r} needs the unweighted rows: not with "
                          "loss='huber'")
    prior = None if prior == "none" else prior
    if method in ("ols", "wls"):
        own = NONLINEAR_OPTIONS if is_nonlinear(friction) else ()   # the search's options
        extra = sorted(set(options) - set(own)) + [
            k for k, v, none in (("constraints", constraints, ("none",)),
                                 ("prior", prior, (None,))) if v != "auto" and v not in none]
        if extra:
            raise OptionError(f"option(s) {extra} apply to method='sdp' only, not {method!r} "
                              "(OLS/WLS are unconstrained and have no prior)")
    require_model(model)
    if not isinstance(parallel_filter, (bool, np.bool_)):
        raise OptionError(f"parallel_filter must be True or False, got {parallel_filter!r}")
    excluded = resolve_excluded(model, exclude_joints)
    if is_stream(dataset):  # read part by part (joints checked per part)
        dataset = as_stream(dataset, covariance, options.get("loss"))
        if not parallel_filter:
            if not hasattr(dataset, "parallel"):
                raise OptionError("parallel_filter=False: a Dask collection is compressed where "
                                  "it lies; give datasets without identification_filter "
                                  "(dataclasses.replace(d, identification_filter=None))")
            dataset.parallel = False
    else:
        dataset = as_dataset(dataset)
        if not parallel_filter and dataset.identification_filter is not None:
            dataset = dataclasses.replace(dataset, identification_filter=None)
        dataset.check_joints(model.nv, model.joint_names)
        excluded = with_dead_channels(model, dataset, excluded)
        # magnitudes, motion, dead channels, glitches, positions beyond the limits
        check_for_identification(dataset, model.joint_names,
                                 (model.limits.lower, model.limits.upper, model.limits.effort),
                                 exclude=excluded)
    if excluded and (is_nonlinear(friction) or options.get("loss") == "huber"):
        raise OptionError("exclude_joints (or a dead torque channel) works with the linear "
                          "friction model and the squared loss: not with nonlinear friction "
                          "laws nor loss='huber'")
    if is_nonlinear(friction):  # Stribeck / sigmoid / tanh laws: consistid.friction.fit
        if not isinstance(dataset, Dataset):
            raise OptionError("nonlinear friction laws need the data in memory (a Dataset or a "
                              "list of them), not a stream")
        if method == "sdp" and prior == "auto":         # resolved once, not per search step
            prior = default_prior(model)
        result = identify_nonlinear(model, dataset, method, friction, armature, constraints,
                                    prior, covariance, **options)
        return flag_degrees(dataclasses.replace(
            result, envelope=TrainingEnvelope.of(dataset, model.joint_names),
            details={**result.details, "weakly_informed": "not assessed (nonlinear friction "
                     "laws: the search's covariance only; res.base_std)",
                     "parallel_filter": "none (nonlinear friction laws: the samples as they "
                                        "are)"}), dataset)
    spec = without_joints(RegressorSpec.make(model, friction, armature), excluded)
    kept = np.setdiff1d(np.arange(model.nv), excluded)
    base = base_parameters_of(model, spec) if not excluded else rows_base(model, spec, kept)
    problem = compress_data(model, dataset, spec, base)
    problem = restricted(problem, kept) if excluded else problem
    if method in ("ols", "wls"):
        try:
            result = least_squares(model, problem, base, spec, weighted=method == "wls")
        except PoorExcitationError as exc:
            if not isinstance(dataset, Dataset):
                raise
            raise PoorExcitationError(str(exc) + one_way_note(
                model, spec, TrainingEnvelope.of(dataset, model.joint_names))) from exc
    else:
        from .sdp import SDPOptions, identify_sdp

        given = options.pop("options", None)            # an SDPOptions value, or keywords
        if given is not None and (options or constraints != "auto" or prior != "auto"):
            raise OptionError("give the SDP options either as options=SDPOptions(...) or as "
                              "keywords (constraints=, prior=, ...), not both")
        if given is None:
            given = SDPOptions.from_keywords(
                constraints="pseudo-inertia" if constraints == "auto" else constraints,
                prior=default_prior(model) if prior == "auto" else prior, **options)
        result = identify_sdp(model, problem, base, spec, given,
                              dataset=dataset if isinstance(dataset, Dataset) else None)
    result = dataclasses.replace(result, details={**result.details,
                                                  "parallel_filter": parallel_note(dataset)})
    result = flag_degrees(with_covariance(result, problem, dataset, covariance, kept,
                                          chosen), dataset)
    result = with_sample_noise(with_weak_directions(result, problem, dataset, kept))
    return with_excluded(result, excluded, kept, friction, armature) if excluded else result


def with_sample_noise(result: IdentificationResult) -> IdentificationResult:
    """On parallel-filtered rows, ``result`` (of the kept joints) whose ``sigma`` and
    ``train_rms`` are those of the samples as they are (``details["sample_sigma"]``,
    ``["sample_rms"]``; one σ for all joints where the fit had one, OLS): the residuals a user
    compares them with (``res.residual``, held-out RMS, the report) are not low-passed at the
    identification cut-off, and the filtered rows' figures, a fraction ``≈ √(2 f_p / rate)`` of
    them, stay in ``details["filtered_sigma"]``, ``["filtered_train_rms"]``."""
    if "sample_sigma" not in result.details:
        return result
    return dataclasses.replace(result, sigma=result.details["sample_sigma"],
                               train_rms=result.details["sample_rms"])


def parallel_note(dataset: Dataset | DataStream) -> str:
    """What ``details["parallel_filter"]`` says of the data's identification low-pass."""
    if isinstance(dataset, Dataset):
        flt = dataset.identification_filter
        if flt is None:
            return "none (the samples as they are)"
        return (f"τ and every column of Y low-passed alike at {flt[0]:.4g} Hz (zero-phase "
                f"Butterworth, order {flt[1]}) per run of samples, before least squares; "
                "σ, train_rms and the residual statistics are those of the samples as they "
                "are (the filtered rows': details['filtered_sigma'], "
                "details['filtered_train_rms'])")
    if not getattr(dataset, "parallel", True):
        return "none (parallel_filter=False)"
    return "per part, as each records it (Dataset.identification_filter)"


def with_dead_channels(model: RobotModel, dataset: Dataset, excluded: tuple[int, ...]
                       ) -> tuple[int, ...]:
    """``excluded`` with the dead torque channels (:func:`~consistid.identification.subset.
    dead_channels`) added, each warned (:class:`~consistid.errors.DataQualityWarning`)."""
    dead = [int(j) for j in dead_channels(dataset) if j not in excluded]
    if not dead or len(dead) + len(excluded) == model.nv or (
            not np.any(dataset.dq) and not np.any(dataset.ddq)):
        return excluded          # no row left, or no motion: check_torque/check_motion say so
    names = [model.joint_names[j] for j in dead]
    value = dataset.tau[0, dead[0]]
    warnings.warn(f"the torque channel(s) of {names} read one value ({value:g} N·m for "
                  f"{names[0]}) in all {dataset.n_samples} samples while the arm moves: a dead "
                  "sensor. identify leaves their rows out and identifies from the other joints "
                  "(res.excluded_joints; details['excluded_joints'] names what cannot be "
                  "identified then); pass exclude_joints= to say so yourself",
                  DataQualityWarning, stacklevel=3)
    return tuple(sorted(set(excluded) | set(dead)))


def with_excluded(result: IdentificationResult, excluded: Sequence[int], kept: np.ndarray,
                  friction: FrictionArg, armature: bool | Sequence[int | str]
                  ) -> IdentificationResult:
    """``result`` of the kept joints' rows with per-joint figures over every joint (NaN at the
    excluded ones), ``excluded_joints`` and ``details["excluded_joints"]``: what the rows left
    out would have informed (:func:`~consistid.identification.subset.lost_parameters`)."""
    model = result.model
    full = base_parameters_of(model, RegressorSpec.make(model, friction, armature))
    lost = lost_parameters(full, result.base)
    names = tuple(model.joint_names[j] for j in excluded)
    details = {**result.details, "excluded_joints": (
        f"{', '.join(names)}: torque rows left out; not identifiable then: "
        f"{', '.join(lost) if lost else 'nothing beyond their rows'}")}
    for key in ("autocorrelation_time", "filtered_sigma", "filtered_train_rms",
                "sample_sigma", "sample_rms"):
        if key in details:
            details[key] = expand(details[key], kept, model.nv)
    return dataclasses.replace(
        result, sigma=expand(result.sigma, kept, model.nv),
        train_rms=expand(result.train_rms, kept, model.nv), details=details,
        excluded_joints=names)


def with_weak_directions(result: IdentificationResult, problem: CompressedProblem,
                         dataset: Dataset | DataStream, kept: np.ndarray
                         ) -> IdentificationResult:
    """``result`` with its training :attr:`~IdentificationResult.envelope` and its
    :attr:`~IdentificationResult.weakly_informed` directions
    (:func:`consistid.identification.weak.weakly_informed`), warned with a
    :class:`PoorExcitationWarning`. A stream's envelope is that of its parts, joined as
    :meth:`DataStream.compress` read them; a collection compressed where it lies (Dask) has
    none and keeps neither."""
    envelope = (TrainingEnvelope.of(dataset, result.model.joint_names)
                if isinstance(dataset, Dataset) else getattr(dataset, "envelope", None))
    if envelope is None:
        return dataclasses.replace(result, details={
            **result.details, "weakly_informed": "not assessed (data compressed where they lie: "
                                                 "no training envelope)"})
    r_b, _, _ = problem.stacked(sigma=result.sigma, columns=result.base.independent)
    weak = weakly_informed(result.model, result.spec, result.base, r_b, envelope,
                           np.sqrt(problem.tau_sum_squares / max(problem.n_samples, 1)), kept)
    if weak:
        decides = ("the SDP's priors decide them (the CAD bodies; for friction and offset the "
                   "joint prior, details['joint_prior'])" if result.method == "sdp" else
                   "least squares gives them whatever the noise does (± base_std)")
        warnings.warn(f"the data barely inform {len(weak)} direction(s) of the parameters: "
                      f"{'; '.join(weak[:3])}{' …' if len(weak) > 3 else ''}. {decides}; "
                      "res.weakly_informed lists them, and predict warns on data beyond the "
                      "training envelope (res.envelope). Move every joint both ways, over its "
                      "range, to inform them", PoorExcitationWarning, stacklevel=3)
    return dataclasses.replace(result, envelope=envelope, weakly_informed=weak)


def with_covariance(result: IdentificationResult, problem: CompressedProblem,
                    dataset: Dataset | DataStream, covariance: str,
                    kept: np.ndarray | None = None, chosen: bool = False
                    ) -> IdentificationResult:
    """``result`` with its base covariance counted as ``covariance`` says (module docstring)
    and ``details["covariance"]``, ``details["autocorrelation_time"]`` recorded.

    ``problem`` is the (unweighted) compressed ``dataset`` the result was fitted on; its weights
    are ``w_j = 1/σ_j²`` from ``result.sigma`` (OLS: one ``σ`` for all joints). ``kept``: the
    joints whose rows ``problem`` holds (default all). ``chosen``: the covariance was chosen
    for the caller (``"auto"``), so an iid count on a one-pass stream is warned.
    """
    kept = np.arange(result.model.nv) if kept is None else np.asarray(kept)
    check_option("covariance", covariance, COVARIANCES)
    if covariance == "iid":
        if problem.filtered:
            warnings.warn("covariance='iid' counts every row as an independent sample, but the "
                          "rows were low-passed at identification (parallel filtering: "
                          "details['parallel_filter']) and are correlated over about "
                          "rate / (2 × cut-off) samples: the σ are too narrow by about the root "
                          "of that. Use covariance='coloured' (squared loss, on data that can be "
                          "read twice: a Dataset, a list, or a re-readable DataStream), or "
                          "parallel_filter=False", DataQualityWarning, stacklevel=3)
        once = isinstance(dataset, DataStream) and not dataset.rereadable
        if once and chosen and not problem.filtered:
            warnings.warn("a one-pass stream (an iterator or generator) cannot be read again for "
                          "the residual's correlation, so σ count every row as an independent "
                          "sample: rows through a signal chain (derivatives, low-passes) or with "
                          "friction at rest are correlated, and σ may then be several times too "
                          "narrow. Give a re-readable stream (a list, or a function returning a "
                          "fresh iterator) for covariance='coloured'", DataQualityWarning,
                          stacklevel=3)
        return dataclasses.replace(result, details={
            **result.details, "covariance": "iid (every row an independent sample" + (
                "; a one-pass stream: the coloured sandwich needs a second reading)" if once
                else ")")})
    stats = residual_statistics(result.model, result.spec, result.parameters, dataset,
                                result.base, viscous_std(result))
    tau = stats.autocorrelation_time()[kept]
    cols = result.base.independent
    r_b = problem.factors[:, :-1, :-1][:, :, cols]
    grams = np.matmul(r_b.transpose(0, 2, 1), r_b)  # BLAS per joint (einsum is not)
    sigma = np.asarray(result.sigma, dtype=float)
    weights = np.where(sigma > 0, 1.0 / np.where(sigma > 0, sigma, 1.0) ** 2, 1.0)
    # each joint's own residual variance (OLS weighs joints alike whatever their noise)
    # every sample's residual, exact from the factors (the autocorrelation may read fewer)
    variances = joint_sigma(problem.sum_squares(result.parameters), problem.n_samples,
                            result.base.n_base, tau) ** 2
    if problem.filtered:
        variances = long_run_variances(stats, problem.n_samples, result.base.n_base, kept, tau)
        stats = unfiltered_slope_noise(stats, kept, variances, weights)
        details_noise = {"filtered_sigma": np.asarray(result.sigma, dtype=float),
                         "filtered_train_rms": np.asarray(result.train_rms, dtype=float),
                         "sample_sigma": (np.sqrt(variances) if np.ptp(sigma) > 0 else
                                          np.full(kept.size, np.sqrt(np.mean(variances)))),
                         "sample_rms": np.sqrt(stats.sum_squares[kept]
                                               / max(stats.n_samples, 1))}
    else:
        details_noise = {}
    variances = np.where(variances > 0, variances, 1.0 / weights)
    shown = ", ".join(f"{result.model.joint_names[j]} {t:.3g}" for j, t in zip(kept, tau))
    details = {**result.details, **details_noise, "autocorrelation_time": tau}
    if covariance == "hac":
        every = np.zeros(result.model.nv)       # excluded joints' rows: no score
        every[kept] = weights
        sums = score_sums_of(result, every, dataset)
        meat, batch = sums.meat()
        cov = hac_covariance(result.base_covariance, meat)
        details["covariance"] = (
            f"hac (sandwich of the scores' batch sums over {batch} samples, Andrews' bandwidth "
            f"{sums.bandwidth():.3g}; τ_j in samples: {shown})")
    else:
        cov = coloured_covariance(result.base_covariance, grams, weights, tau, variances)
        details["covariance"] = (f"coloured (sandwich, N/τ_j effective rows; τ_j in samples: "
                                 f"{shown})")
    rest = None if stats.rest is None else restricted(stats.rest, kept)
    # the rows at rest are judged on the samples as they are (parallel filtering: against
    # the reference problem of every sample; without one, a stream of filtered and unfiltered
    # parts, they cannot be)
    reference: CompressedProblem | None = problem
    if problem.filtered:
        reference = None if stats.reference is None else restricted(stats.reference, kept)
    cov, details = with_rest_error(result, reference, rest, cov, details,
                                   (weights, tau, variances),
                                   rest_suspected(stats, kept)
                                   or dry_friction_at_rest(result.spec, stats, kept))
    cov, details = with_split_error(result, stats, kept, cov, details)
    cov, details = with_weighting_error(result, problem, cov, details, (weights, tau, variances))
    # the speed per joint below which its rows counted as at rest (rad/s)
    details["model_error_speed"] = stats.rest_speeds()
    note = standstill_note(stats, result.model.joint_names, kept)
    if note:
        warnings.warn(note, ModelMisfitWarning, stacklevel=3)
        details["standstill"] = note
    note = slow_note(stats, result, kept)
    if note:
        warnings.warn(note, PoorExcitationWarning, stacklevel=3)
        details["slow_joints"] = note
    return dataclasses.replace(result, base_covariance=cov, details=details)


def long_run_variances(stats: ResidualStatistics, n_samples: int, n_base: int,
                       kept: np.ndarray, tau: np.ndarray) -> np.ndarray:
    r"""Per kept joint, the variance ``v_j`` of the residual of the samples as they are (read by
    ``stats``, :func:`~consistid.identification.compression.joint_sigma`'s degrees of freedom
    scaled to the samples read), for the sandwich of parallel-filtered rows: with ``τ_j`` from
    the same residual, ``τ_j v_j`` is its long-run variance (spectral density at zero), which
    the identification low-pass ``H`` (unit gain at DC) leaves unchanged, and the meat
    ``Σ_j τ_j w_j² v_j (HΦ_j)ᵀ(HΦ_j)`` is that of the filtered rows for columns slow against
    the correlation (:func:`~consistid.identification.statistics.coloured_covariance`; columns
    near the cut-off see less noise than that: conservative)."""
    read = max(stats.n_samples, 1)
    dof = np.maximum(read - tau * n_base / max(kept.size, 1) * read / max(n_samples, 1), 1.0)
    return stats.sum_squares[kept] / dof


def unfiltered_slope_noise(stats: ResidualStatistics, kept: np.ndarray, variances: np.ndarray,
                           weights: np.ndarray) -> ResidualStatistics:
    """``stats`` with its :attr:`~ResidualStatistics.viscous_noise` read at the noise of the
    samples as they are: :func:`viscous_std` of parallel-filtered rows counts the filtered
    residual's variance ``1/w_j``, a fraction ``≈ 2 f_p / rate`` of the variance ``v_j`` that
    ``√τ_j`` (from the unfiltered residual) then scales, so each kept joint's ``σ(f̂_v)`` is
    scaled by ``√(v_j w_j)`` (its column lies in its own joint's rows only; ``variances`` and
    ``weights`` of the kept joints, in their order)."""
    if stats.viscous_noise is None:
        return stats
    noise = stats.viscous_noise.copy()
    noise[kept] *= np.sqrt(np.maximum(variances * weights, 0.0))
    return dataclasses.replace(stats, viscous_noise=noise)


def viscous_std(result: IdentificationResult) -> np.ndarray:
    """Per joint, the standard deviation of the fitted ``f_v`` with rows counted as independent
    (``result.base_covariance`` before the sandwich), ``inf`` where ``f_v`` is not a base
    parameter: whether a slow joint's fit reads a slope the noise could not make
    (:meth:`ResidualStatistics.steep_joints`)."""
    names = list(result.base.names)
    var = np.diag(result.base_covariance)
    return np.array([np.sqrt(max(var[names.index(f"{joint}.fv")], 0.0))
                     if f"{joint}.fv" in names else np.inf for joint in result.model.joint_names])


def score_sums_of(result: IdentificationResult, weights: np.ndarray,
                  dataset: Dataset | DataStream) -> ScoreSums:
    """:class:`~consistid.identification.statistics.ScoreSums` of the fitted model on an
    in-memory dataset or, one part at a time, on a re-readable stream (a third reading)."""
    args = (result.model, result.spec, result.parameters, result.base.independent, weights)
    if isinstance(dataset, Dataset):
        return score_sums(*args, dataset)
    if not hasattr(dataset, "parts") or type(dataset).compress is not DataStream.compress:
        raise OptionError("covariance='hac' reads the data a third time, part by part: a Dask "
                          "collection is not read that way; use covariance='coloured'")
    total = None
    for _, part in dataset.parts(result.model):
        sums = score_sums(*args, part)
        total = sums if total is None else total + sums
    return total


def rest_suspected(stats: ResidualStatistics, kept: np.ndarray) -> bool:
    """Whether the residual shows the model wrong at rest on a joint of ``kept``: larger where
    it stands still (the test of :func:`standstill_note`) or in slow bands above standstill
    (:meth:`ResidualStatistics.rest_speeds` raised, slow joints included)."""
    ratio, p = stats.standstill_excess()
    bad = (p < STANDSTILL_ALPHA) & (ratio >= STANDSTILL_RATIO)
    raised = stats.rest_speeds() > STANDSTILL_SPEED
    return bool(np.any((bad | raised)[kept]))


def dry_friction_at_rest(spec: RegressorSpec, stats: ResidualStatistics, kept: np.ndarray
                         ) -> bool:
    """Whether a joint of ``kept`` carries a Coulomb column and has rows at rest: there the law
    ``f_c sign(q̇)`` is a set, not a value (static friction takes any torque up to its
    break-away, and the sign of a measured near-zero speed is noise), so the rows at rest are
    suspected whatever the residual shows. Hausman's per-parameter test alone lacks power when
    the noise is large beside the friction (MuJoCo ``frictionloss``, noise 3 N·m, 10 s: the
    term closed in 8 of 12 runs, Coulomb terms 6–9 σ off, Panda friction coverage 0.83)."""
    return bool(np.any((spec.mask("coulomb") & (stats.rest_count > 0))[kept]))


def with_rest_error(result: IdentificationResult, problem: CompressedProblem | None,
                    rest: CompressedProblem | None, cov: np.ndarray, details: dict,
                    noise: tuple[np.ndarray, np.ndarray, np.ndarray], suspected: bool = False
                    ) -> tuple[np.ndarray, dict]:
    """``cov`` with the model-error term of the rows at rest added to its diagonal
    (:mod:`consistid.identification.model_error`; ``noise`` = ``(w_j, τ_j, v_j)`` of the
    sandwich), and ``details["model_error"]`` (per base parameter, its standard deviation ``b``,
    N·m-consistent units of the parameter) with ``details["model_error_note"]`` saying what was
    done (``details["model_error_speed"]``, set by the caller: the speed per joint below which
    its rows counted as at rest). ``rest`` is the compressed problem of the rows at rest
    (``None``: there are none); ``suspected``: the residual shows the model wrong at rest
    (:func:`rest_suspected`) or dry friction makes it a set there (:func:`dry_friction_at_rest`);
    otherwise the term is added only when Hausman's test finds a bias."""
    cols = result.base.independent
    if problem is None:
        note = ("not assessed: a stream of parallel-filtered and unfiltered parts has no "
                "reference of its samples as they are; give parts filtered alike "
                "(or parallel_filter=False)")
        warnings.warn(f"the model error of the rows at rest is {note}", ModelWarning,
                      stacklevel=4)
        return cov, {**details, "model_error": np.zeros(cols.size), "model_error_note": note}
    if rest is None:
        return cov, {**details, "model_error": np.zeros(cols.size),
                     "model_error_note": "none: no joint stands still in the data"}
    b2, _ = rest_bias(problem, rest, cols, *noise, suspected=suspected)
    finite = np.isfinite(np.diag(cov))
    cov = cov + np.diag(np.where(finite, b2, 0.0))
    wide = np.flatnonzero(b2 > np.where(finite, np.diag(cov) - b2, np.inf))
    names = [result.base.names[i] for i in wide]
    note = (f"the rows where a joint stands still move {len(wide)} base parameter(s) by more "
            f"than their noise ± ({', '.join(names[:6])}{' …' if len(names) > 6 else ''}): "
            "their intervals include that model error (Hausman difference of the fits with and "
            "without those rows)" if wide.size else
            "the rows at rest move no base parameter beyond its noise ±")
    return cov, {**details, "model_error": np.sqrt(b2), "model_error_note": note}


def with_weighting_error(result: IdentificationResult, problem: CompressedProblem,
                         cov: np.ndarray, details: dict,
                         noise: tuple[np.ndarray, np.ndarray, np.ndarray]
                         ) -> tuple[np.ndarray, dict]:
    """``cov`` with the model error that the fit's per-joint weights put into it added to its
    diagonal (:func:`~consistid.identification.weighting_error.weighting_bias`: Hausman's test
    of the weights against equal ones; ``noise`` = ``(w_j, τ_j, v_j)`` of the sandwich), and to
    ``details["model_error"]``; ``details["weighting_error"]`` is that term alone (per base
    parameter, its standard deviation) and ``details["weighting_error_note"]`` says what was
    done."""
    b2, z, rejected = weighting_bias(problem, result.base.independent, *noise)
    if not rejected:
        return cov, {**details, "weighting_error": np.zeros(b2.size), "weighting_error_note": (
            "none: equal weights" if not np.any(z) else
            f"none: the per-joint weights do not move the estimate beyond chance (Hausman's "
            f"test against equal weights; largest |δ_i|/σ {np.max(np.abs(z)):.3g})")}
    b2 = np.where(np.isfinite(np.diag(cov)), b2, 0.0)
    worst = int(np.argmax(np.abs(z)))
    note = (f"the per-joint weights move {int(np.sum(b2 > 0))} base parameter(s) beyond their "
            f"noise (e.g. {result.base.names[worst]} by {abs(z[worst]):.3g} σ from the equal-"
            "weight fit): the residual is model error more than noise, and their intervals "
            "include that difference")
    return cov + np.diag(b2), {**details, "weighting_error": np.sqrt(b2),
                               "weighting_error_note": note,
                               "model_error": np.sqrt(details["model_error"] ** 2 + b2)}


def with_split_error(result: IdentificationResult, stats: ResidualStatistics, kept: np.ndarray,
                     cov: np.ndarray, details: dict) -> tuple[np.ndarray, dict]:
    """``cov`` with the model error of the Coulomb/viscous split that a slow joint's data
    cannot make (:func:`~consistid.identification.model_error.split_bias`, on the joints of
    :meth:`ResidualStatistics.slow_joints` whose fit reads a slope) added to its diagonal, and
    to ``details["model_error"]``."""
    steep = [j for j in stats.slow_joints() if j in kept and stats.steep_joints()[j]]
    if not steep:
        return cov, details
    b2 = split_bias(list(result.base.names), list(result.parameter_names), result.parameters,
                    list(result.model.joint_names), np.array(steep), stats.top_speed)
    b2 = np.where(np.isfinite(np.diag(cov)), b2, 0.0)
    return cov + np.diag(b2), {**details,
                               "model_error": np.sqrt(details["model_error"] ** 2 + b2)}


def slow_note(stats: ResidualStatistics, result: IdentificationResult,
              kept: np.ndarray) -> str:
    """What to say of the joints with fitted Coulomb or viscous terms that never move fast
    enough for :meth:`ResidualStatistics.rest_speeds` to check where their residual is the
    noise's (:meth:`ResidualStatistics.slow_joints`), or ``""``."""
    names = result.model.joint_names
    terms = set(result.parameter_names)
    slow = [j for j in stats.slow_joints() if j in kept
            and ({f"{names[j]}.fc", f"{names[j]}.fv"} & terms)]
    if not slow:
        return ""
    speeds = stats.rest_speeds()
    which = ", ".join(f"{names[j]} (rows below {speeds[j]:g} rad/s counted as at rest)"
                      for j in slow)
    return (f"{which} never moved faster than {SPEED_EDGES[-1]:g} rad/s long enough to check "
            "its friction law against the noise: dry friction smoothed over a band of slow "
            "speeds (a gearbox's Stribeck band, MuJoCo's soft frictionloss) looks like a "
            "steep viscous slope there, not like f_c·sign(q̇) + f_v·q̇, and its Coulomb and "
            "viscous estimates may be far off; their intervals include the model error the "
            "data can show and the Coulomb/viscous split they cannot make, at least "
            "(details['model_error']). Move those joints faster to identify "
            "their friction")


def standstill_note(stats: ResidualStatistics, joint_names: Sequence[str],
                    kept: np.ndarray | None = None) -> str:
    """What to say of the joints whose residual is larger where they stand still than where
    they move (:meth:`ResidualStatistics.standstill_excess`: by :data:`STANDSTILL_RATIO` in RMS
    at least, and beyond chance at level :data:`STANDSTILL_ALPHA`), or ``""``."""
    ratio, p = stats.standstill_excess()
    bad = np.flatnonzero((p < STANDSTILL_ALPHA) & (ratio >= STANDSTILL_RATIO))
    bad = bad if kept is None else np.intersect1d(bad, kept)   # excluded rows: no fit there
    if not bad.size:
        return ""
    share = stats.rest_count / max(stats.n_samples, 1)
    where = "; ".join(f"{joint_names[j]}: {ratio[j]:.3g} × (at rest in {share[j]:.0%} of the "
                      f"samples read, p = {p[j]:.2g})" for j in bad)
    return (f"the residual where a joint stands still (|q̇| < {STANDSTILL_SPEED:g} rad/s) is "
            f"larger than where it moves, in RMS: {where}. A joint held by static friction "
            "takes any torque up to its break-away, which f_c·sign(q̇) does not predict; the "
            "fit's friction and its ± absorb it. Judge data with res.residual(data, "
            "at_rest='cone'), fit a friction law that leaves rest rows out "
            "(friction='stribeck'), or see consistid.diagnose")
