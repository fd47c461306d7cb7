r"""Recursive least squares on the base parameters, with forgetting, anti-windup and change
detection: the estimate a controller loop can update at 1 kHz.

The torque model is linear in the base parameters (:mod:`consistid.identification.base`),
``τ_k = W_k β + ε_k`` with ``W_k`` the independent columns of the regressor row
(:mod:`consistid.identification.regressor`: rigid body, then the friction/offset/armature columns)
and ``ε_k ~ N(0, Σ)``, ``Σ = diag(σ_j²)``. One sample (``n_v`` equations at once) updates the
estimate ``β̂`` and its covariance ``P`` as the Kalman filter of a constant parameter does
(Ljung & Söderström, *Theory and Practice of Recursive Identification*, MIT Press 1983, §2.6;
Åström & Wittenmark, *Adaptive Control*, 2nd ed., §2.2):

.. math::

    \bar P = P_{k-1}/\lambda_k, \quad
    S_k = W_k \bar P W_k^\top + \Sigma, \quad
    K_k = \bar P W_k^\top S_k^{-1}, \\
    e_k = \tau_k - W_k \hat\beta_{k-1}, \quad
    \hat\beta_k = \hat\beta_{k-1} + K_k e_k, \quad
    P_k = \bar P - K_k S_k K_k^\top .

``λ ∈ (0, 1]`` is exponential forgetting: old samples weigh ``λ^age``, a memory of
``1/(1 − λ)`` samples. The cost per sample is ``O(n_v b²)`` flops and the memory ``O(b²)``,
independent of time.

Windup. When the motion stops exciting some directions, forgetting divides their variance by
``λ`` every sample and ``P`` grows without bound, so the next informative sample makes the
estimate jump. ``windup="trace"`` bounds ``tr P``: the sample's forgetting factor is raised
towards 1 so that ``tr(P_{k−1}/λ_k) ≤ t_max`` (the "constant trace" idea of Sripada & Fisher,
"Improved least squares identification", Int. J. Control 46(6), 1987,
doi:10.1080/00207178708933989; Åström & Wittenmark §11.2), ``λ_k = max(λ, tr P_{k−1}/t_max)``
capped at 1; ``t_max`` defaults to the trace of the initial covariance. Information in the
directions the data keep exciting is still forgotten at rate λ while the trace is below the
bound.

Change detection: ``χ²_k = e_kᵀ S_k⁻¹ e_k`` (the whitened innovation, before the sample updates
the estimate) feeds a detector of :mod:`consistid.online.change`. On a flag the estimator
adapts (``on_change``): ``"payload"`` adds the prior covariance of a payload on the last body
(:data:`PAYLOAD_PRIOR_MASS`, :data:`PAYLOAD_PRIOR_RADIUS`; the rule of change of Gaz & De Luca
2017 cited in :mod:`consistid.estimation.payload`: ``β_L = β + B_{[:, n]} π_L``) to ``P``, so the
ten directions a payload moves are re-learnt at once and the rest is kept; ``"reset"`` divides
the information by :data:`RESET_FACTOR` and adds the initial covariance (every direction
re-learnt, no more certain than before the first sample); ``None`` only flags.
``"payload"`` escalates to a reset when the detector flags again as soon as it re-arms (the
change was not a payload). The
estimate and covariance just before the flag are kept (:attr:`RecursiveEstimator.changes`), and
:meth:`RecursiveEstimator.payload` runs :func:`consistid.payload_from_base_change` between them
and the current estimate.

Noise. ``noise_std`` (per joint, N·m) weights the joints and scales ``S``; without it ``σ_j`` is
estimated from the a-posteriori residuals: fixed at :data:`NOISE_START` during the ``warmup``
(default :data:`NOISE_MEMORY` samples; the first residuals are fitted away, and an estimate fed
back from them collapses the weights), set to the mean squared residual of the warm-up's second
half at its end (``P`` rescaled accordingly), then an exponential average over
:data:`NOISE_MEMORY` samples, frozen while a change is being absorbed. The detector is armed
only after the warm-up.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np
import pinocchio as pin
import scipy.stats
from scipy.linalg.lapack import dpotrf as _potrf
from scipy.linalg.lapack import dtrtri as _trtri

from ..errors import (DataQualityWarning, DatasetError, ExtrapolationWarning, IdentificationError,
                      JointCountError, OptionError, PoorExcitationWarning, check_number,
                      check_option)
from ..identification.base import BaseParameters, compute_base_parameters, random_states
from ..identification.envelope import (MIN_SIGN_SHARE, TrainingEnvelope, enough,
                                       state_bounds)
from ..identification.weak import weakly_informed
from ..identification.regressor import (DEFAULT_FRICTION, FrictionArg, RegressorSpec,
                                        parameter_names, prior_vector, regressor)
from ..identification.summary import table
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel, require_model
from .change import ChangeDetector, Cusum, WindowedChiSquare
from .report import fragment

WINDUP = (None, "trace")
ON_CHANGE = (None, "payload", "reset")
DETECTORS = (None, "chi2", "cusum")
#: Default a-priori standard deviation of each base parameter, as the torque (N·m) it makes
#: on the random states of the base map: ``std_i = PRIOR_TORQUE / rms(W_i)``.
PRIOR_TORQUE = 10.0
#: Prior of a grasped payload used by ``on_change="payload"``: mass standard deviation (kg) and
#: the size (m) that scales its first and second moments (``m r``, ``m r²``).
PAYLOAD_PRIOR_MASS, PAYLOAD_PRIOR_RADIUS = 10.0, 0.3
#: ``on_change="reset"`` multiplies the information ``P⁻¹`` by this.
RESET_FACTOR = 1e-4
#: This many flags in a row, each as soon as the detector re-armed, are a model that does not fit
#: (terms missing from the regressor, noise_std too small), not changes of the robot: warned.
CHAIN_FLAGS = 3
#: Samples of the exponential average that estimates σ when ``noise_std`` is not given.
NOISE_MEMORY = 2000
#: σ (N·m) assumed during the warm-up when it is estimated.
NOISE_START = 1.0
#: Smallest estimated σ (N·m): noise-free data would otherwise get infinite weights.
NOISE_FLOOR = 1e-6


@dataclass(frozen=True, eq=False)
class Change:
    """A flagged change.

    Attributes
    ----------
    index : the sample (count of updates from 0) at which it was flagged.
    time : its time (s), if the samples were given times (``t=``), else ``None``.
    statistic, threshold : the detector's value and threshold at the flag.
    base_parameters, covariance : the estimate ``β̂`` and ``P`` just before the sample that
        flagged it (what the robot was before the change, for :meth:`RecursiveEstimator.payload`).
    action : how the estimator adapted: ``"payload"``, ``"reset"`` or ``None``.
    """

    index: int
    time: float | None
    statistic: float
    threshold: float
    base_parameters: np.ndarray = field(repr=False)
    covariance: np.ndarray = field(repr=False)
    action: str | None = None

    def __str__(self) -> str:
        when = f"t = {self.time:.3f} s" if self.time is not None else f"sample {self.index}"
        adapted = f"; {self.action} adaptation" if self.action else ""
        return (f"change flagged at {when} (statistic {self.statistic:.4g} > "
                f"{self.threshold:.4g}{adapted})")


@dataclass(frozen=True, eq=False)
class RecursiveTrace:
    """What :meth:`RecursiveEstimator.update_batch` saw, one row per sample.

    Attributes
    ----------
    index : (N,) sample indices (counts of updates).
    t : (N,) times, or ``None``.
    base_parameters : (N, b) the estimate after each sample (``None`` with ``record=False``).
    std : (N, b) its standard deviations ``sqrt(diag P)`` (``None`` with ``record=False``).
    statistic : (N,) the per-sample ``χ²`` of the whitened innovation.
    flagged : indices (into this batch) of the samples that flagged a change.
    """

    index: np.ndarray
    t: np.ndarray | None
    base_parameters: np.ndarray | None
    std: np.ndarray | None
    statistic: np.ndarray
    flagged: np.ndarray


def _repaired(p: np.ndarray) -> np.ndarray:
    """``p`` symmetrised, its eigenvalues clipped below at ``1e-12`` of the largest: the
    nearest (in Frobenius norm) positive definite matrix up to that floor (Higham 1988)."""
    sym = 0.5 * (p + p.T)
    values, vectors = np.linalg.eigh(sym)
    floor = 1e-12 * max(float(values.max()), 1e-300)
    return (vectors * np.maximum(values, floor)) @ vectors.T


#: No joint sample of a manipulator reaches this magnitude in SI units (rad, rad/s, rad/s²,
#: N·m; m for a prismatic joint): a larger one is a unit or logging error, and one such sample
#: would move the estimate by its square (a torque of 1e100 gives parameters of ~1e199).
IMPLAUSIBLE = 1e6


def _numbers(what: str, name: str, value: Any) -> np.ndarray:
    """``value`` as a float array, or :class:`DatasetError` naming ``name`` (text, objects)."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{what}: {name} is not numbers ({exc}); the sample was refused "
                           "and the estimate is unchanged") from None


def _plausible(what: str, name: str, a: np.ndarray, start: int,
               joints: Sequence[str]) -> None:
    """Refuse (:class:`DatasetError`) a sample entry beyond :data:`IMPLAUSIBLE`."""
    big = np.argwhere(np.abs(a) > IMPLAUSIBLE)
    if big.size:
        k, j = (int(i) for i in big[0])
        raise DatasetError(f"{what}: sample {start + k}: {name}[{joints[j]!r}] is "
                           f"{a[k, j]:.6g}, beyond any joint's range in SI units "
                           f"(|value| ≤ {IMPLAUSIBLE:g}); a unit or logging error? The sample "
                           "was refused and the estimate is unchanged")


class RecursiveEstimator:
    r"""Recursive least squares on the base parameters (module docstring).

    Samples are used as they come: not parallel filtered (a dataset's identification cut-off,
    ``Dataset.identification_filter``, needs the zero-phase low-pass of ``consistid.identify``,
    which sees samples after each one; a causal low-pass would delay ``τ`` and ``Y`` alike but
    lag every estimate by its group delay).

    Parameters
    ----------
    model : the robot.
    friction, armature : per-joint columns (:meth:`RegressorSpec.make`); default Coulomb,
        viscous and offset on every joint, no armature (as :func:`consistid.identify`).
    forgetting : ``λ ∈ (0, 1]`` (1: no forgetting; ``0.9999`` at 1 kHz is a 10 s memory).
    noise_std : per-joint torque noise σ (N·m), a number or ``(nv,)``; default estimated online.
    windup : ``None`` or ``"trace"`` (bounded trace, module docstring).
    max_trace : the trace bound of ``windup="trace"``; default the initial covariance's trace.
    detector : ``"chi2"`` (:class:`~consistid.online.change.WindowedChiSquare`, default),
        ``"cusum"``, ``None``, or a detector object.
    on_change : ``"payload"`` (default), ``"reset"`` or ``None`` (module docstring).
    warmup : samples before the detector is armed (and, without ``noise_std``, over which σ is
        first estimated); default 0 with ``noise_std``, else :data:`NOISE_MEMORY`.
    initial : (b,) initial base estimate; default the URDF's (``B π₀``, zero friction).
    initial_std : (b,) or a number: its standard deviations; default ``PRIOR_TORQUE/rms(W_i)``.
    base : the base map (default :func:`compute_base_parameters` of the spec).
    payload_frame : frame of the payload for ``on_change="payload"`` and :meth:`payload`
        (default the last joint's).
    project_every : project the estimate onto the consistent set after every this many
        updates (:meth:`consistent_parameters`; the answer in :attr:`consistent`, each call's
        time in :attr:`projection_seconds`); default ``None``: only on request. A projection
        takes milliseconds (closed form) to tens of milliseconds (solver): in a 1 kHz loop, run
        it in another thread or every few hundred samples.

    Attributes
    ----------
    base : :class:`BaseParameters`; ``spec`` the regressor columns; ``parameter_names`` the
        base names (``base.names``); ``n_updates``.

    Raises
    ------
    OptionError : a bad option (named, with its allowed values or range).
    """

    def __init__(self, model: RobotModel, friction: FrictionArg = DEFAULT_FRICTION,
                 armature: bool | Sequence[int | str] = False, forgetting: float = 1.0, *,
                 noise_std: float | Sequence[float] | None = None,
                 windup: str | None = None, max_trace: float | None = None,
                 detector: str | ChangeDetector | None = "chi2",
                 on_change: str | None = "payload", warmup: int | None = None,
                 initial: np.ndarray | None = None,
                 initial_std: float | np.ndarray | None = None,
                 base: BaseParameters | None = None,
                 payload_frame: str | None = None,
                 project_every: int | None = None) -> None:
        self.model = require_model(model)
        self.spec = RegressorSpec.make(model, friction, armature)
        self.forgetting = check_number("forgetting", forgetting, 0, strict=True)
        if self.forgetting > 1:
            raise OptionError(f"forgetting must lie in (0, 1] (1: no forgetting), got "
                              f"{forgetting!r}")
        check_option("windup", windup, WINDUP)
        check_option("on_change", on_change, ON_CHANGE)
        self.windup, self.on_change = windup, on_change
        self.base = base or compute_base_parameters(model, self.spec)
        names = parameter_names(model, self.spec)
        if tuple(self.base.standard_names) != tuple(names):
            raise OptionError(f"base= is a map of {self.base.n_standard} columns "
                              f"({self.base.standard_names[-1]!r} last), but friction/armature "
                              f"give {len(names)} ({names[-1]!r} last)")
        self.parameter_names = tuple(self.base.names)
        nv, b = model.nv, self.base.n_base
        self._prepare_columns()
        self._scale = self._column_rms()
        self._beta = (self.base.project(prior_vector(model, self.spec)) if initial is None
                      else self._vector("initial", initial, b))
        if initial_std is None:
            std = PRIOR_TORQUE / self._scale
        elif np.ndim(initial_std) == 0:
            std = np.full(b, check_number("initial_std", initial_std, 0, strict=True))
        else:
            std = self._vector("initial_std", initial_std, b)
            if np.any(std <= 0):
                raise OptionError("initial_std must be > 0 for every base parameter")
        self._p = np.diag(std ** 2)
        self._p0 = self._p.copy()
        self.max_trace = (float(np.trace(self._p)) if max_trace is None
                          else check_number("max_trace", max_trace, 0, strict=True))
        if noise_std is None:
            self._sigma2 = np.full(nv, NOISE_START ** 2)
            self.noise_given = False
        else:
            sigma = (np.full(nv, check_number("noise_std", noise_std, 0, strict=True))
                     if np.ndim(noise_std) == 0 else self._vector("noise_std", noise_std, nv))
            if np.any(sigma <= 0):
                raise OptionError("noise_std must be > 0 on every joint")
            self._sigma2 = sigma ** 2
            self.noise_given = True
        self._sigma_matrix = np.diag(self._sigma2)
        self.warmup = (check_number("warmup", warmup, 0, integer=True) if warmup is not None
                       else 0 if self.noise_given else NOISE_MEMORY)
        self._noise_sum = np.zeros(nv)
        if isinstance(detector, str) or detector is None:
            check_option("detector", detector, DETECTORS)
            self.detector = (None if detector is None else WindowedChiSquare()
                             if detector == "chi2" else Cusum())
        elif hasattr(detector, "step") and hasattr(detector, "reset"):
            self.detector = detector
        else:
            raise OptionError(f"detector must be 'chi2', 'cusum', None or an object with step() "
                              f"and reset(), got {detector!r}")
        self.payload_frame = payload_frame
        self.project_every = (None if project_every is None
                              else check_number("project_every", project_every, 1, integer=True))
        #: the last projection (:class:`~consistid.online.projection.ProjectedEstimate`), and
        #: the wall time of every projection made (s)
        self.consistent = None
        self.projection_seconds: list[float] = []
        self._payload_cov = self._payload_covariance() if on_change == "payload" else None
        self._data = model.pin_model.createData()
        self._changes: list[Change] = []
        self._chain_warned = False
        self._still: np.ndarray | None = None       # joints at rest in the current sample
        #: times the covariance was repaired after losing definiteness to round-off
        self.n_repairs = 0
        self._flag = False
        self._absorbing = 0
        self.n_updates = 0
        # where the samples taken went: q min, q max, |q̇| max, |q̈| max, counts moving with
        # q̇ > 0 and q̇ < 0, torque squares (rows), and how many samples
        self._seen = np.vstack([np.full(nv, np.inf), np.full(nv, -np.inf), np.zeros((5, nv))])
        self._n_seen = 0
        self._bounds_at = -1        # the envelope and its bounds as of this many samples seen
        self._last_time: float | None = None
        self.last_statistic = float("nan")
        self.last_forgetting = self.forgetting

    # ------------------------------------------------------------------------- set-up helpers
    @staticmethod
    def _vector(name: str, value: Any, size: int) -> np.ndarray:
        try:
            out = np.array(value, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise OptionError(f"{name} must be {size} numbers, got {value!r:.80}") from exc
        if out.shape != (size,) or not np.all(np.isfinite(out)):
            raise OptionError(f"{name} must be {size} finite numbers, got shape {out.shape}")
        return out

    def _prepare_columns(self) -> None:
        """Index arrays that build the base row from one regressor call and the joint signals."""
        n_in, base = self.model.n_inertial, self.base
        independent = base.independent
        self._rigid_src = independent[independent < n_in]
        self._rigid_dst = np.flatnonzero(independent < n_in)
        suffixes = ("fc", "fv", "fo", "ps1", "pc1", "Ia")
        rows, dst, src = [], [], []
        columns = self.spec.columns
        for d, i in enumerate(independent):
            if i < n_in:
                continue
            _, j, suffix = columns[i - n_in]
            rows.append(j)
            dst.append(d)
            src.append(suffixes.index(suffix) * self.model.nv + j)
        self._joint_rows = np.array(rows, dtype=int)
        self._joint_dst = np.array(dst, dtype=int)
        self._joint_src = np.array(src, dtype=int)
        self._n_rigid = self._rigid_src.size          # rigid columns come first (sorted)
        self._w = np.zeros((self.model.nv, base.n_base))
        self._ones = np.ones(self.model.nv)

    def _column_rms(self) -> np.ndarray:
        """RMS of each base column over the base map's random states (torque per unit)."""
        q, dq, ddq = random_states(self.model, 200, np.random.default_rng(0))
        w = self.base.base_columns(regressor(self.model, q, dq, ddq, self.spec))
        rms = np.sqrt(np.mean(w ** 2, axis=0))
        return np.where(rms > 0, rms, 1.0)

    def _payload_covariance(self) -> np.ndarray:
        """``B_{[:, n]} A diag(s²) Aᵀ B_{[:, n]}ᵀ``: the base-parameter covariance of a payload
        of the prior size on the last body (``A`` the change from ``payload_frame``)."""
        from ..estimation.payload import frame_transform  # noqa: PLC0415 (cvxpy)

        pm = self.model.pin_model
        joint = self.model.nv
        rotation, translation = np.eye(3), np.zeros(3)
        if self.payload_frame is not None:
            if not pm.existFrame(self.payload_frame):
                raise OptionError(f"payload_frame {self.payload_frame!r} is not a frame of "
                                  f"{self.model.name}")
            frame = pm.frames[pm.getFrameId(self.payload_frame)]
            joint = frame.parentJoint
            rotation, translation = frame.placement.rotation, frame.placement.translation
        a = frame_transform(rotation, translation)
        m, r = PAYLOAD_PRIOR_MASS, PAYLOAD_PRIOR_RADIUS
        s = np.array([m, m * r, m * r, m * r] + [m * r * r] * 6)
        cols = self.base.matrix[:, 10 * (joint - 1):10 * joint] @ a
        return (cols * s ** 2) @ cols.T

    # ------------------------------------------------------------------------- properties
    @property
    def base_parameters(self) -> np.ndarray:
        """(b,) the current estimate ``β̂`` (a copy), named by :attr:`parameter_names`."""
        return self._beta.copy()

    @property
    def covariance(self) -> np.ndarray:
        """(b, b) its covariance ``P`` (a copy)."""
        return self._p.copy()

    @property
    def std(self) -> np.ndarray:
        """(b,) ``sqrt(diag P)``."""
        return np.sqrt(np.diag(self._p))

    @property
    def noise_std(self) -> np.ndarray:
        """(nv,) the σ in use (given, or the running estimate)."""
        return np.sqrt(self._sigma2)

    @property
    def change_detected(self) -> bool:
        """``True`` when the last :meth:`update` flagged a change."""
        return self._flag

    @property
    def changes(self) -> tuple[Change, ...]:
        """Every change flagged so far, in order."""
        return tuple(self._changes)

    @property
    def envelope(self) -> TrainingEnvelope | None:
        """Where the samples taken so far went (position range, velocity signs, largest
        ``|q̇|``, ``|q̈|``: :class:`~consistid.identification.envelope.TrainingEnvelope`), as
        ``res.envelope`` of a batch fit; ``None`` before the first update. Forgetting does not
        shrink it: a state seen once and forgotten is extrapolation all the same."""
        if not self._n_seen:
            return None
        s = self._seen
        return TrainingEnvelope(tuple(self.model.joint_names), s[0].copy(), s[1].copy(),
                                s[2].copy(), s[3].copy(), s[4].astype(int), s[5].astype(int),
                                self._n_seen)

    @property
    def weakly_informed(self) -> tuple[str, ...] | None:
        """The directions of the base parameters that the samples taken barely inform, in
        words (:func:`consistid.identification.weak.weakly_informed`, as
        ``res.weakly_informed``): each joint with a Coulomb column that moved one way only,
        then each direction along which one standard deviation of the current estimate
        (:attr:`covariance`, the initial spread included) changes the predicted torque on the
        envelope by more than a quarter of the torque RMS seen. Empty before the first
        update.

        ``None`` when not assessed — the information ``P⁻¹`` is not numerically positive
        definite (``P`` spans more than double precision holds: an ``initial_std`` far above
        what the data inform, next to directions they pin down), as a batch result says
        ``details["weakly_informed"] = "not assessed (…)"``; a
        :class:`~consistid.errors.PoorExcitationWarning` says why. Never ``()`` then: that
        would read as "every direction informed" of a check that did not run.
        """
        envelope = self.envelope
        if envelope is None:
            return ()
        try:
            chol, info = _potrf(np.linalg.inv(self._p), lower=0)
        except np.linalg.LinAlgError:
            info = -1
        if info != 0:
            warnings.warn(f"RecursiveEstimator: weakly informed directions not assessed: the "
                          f"information P⁻¹ is not numerically positive definite (condition "
                          f"number of P {np.linalg.cond(self._p):.3g}; initial_std far above "
                          "what the data inform next to directions they pin down?). None is "
                          "returned; a smaller initial_std, or more varied motion, lets it run",
                          PoorExcitationWarning, stacklevel=2)
            return None
        rms = np.sqrt(self._seen[6] / self._n_seen)
        return weakly_informed(self.model, self.spec, self.base, np.triu(chol), envelope, rms)

    def check_excitation(self) -> tuple[str, ...] | None:
        """:attr:`weakly_informed`, with a :class:`~consistid.errors.PoorExcitationWarning`
        naming them (as ``identify`` warns) when there are any, or saying why they were not
        assessed (``None``): call it after a run of updates, e.g. at the end of an excitation."""
        weak = self.weakly_informed
        if weak:
            warnings.warn(f"the samples taken barely inform {len(weak)} direction(s) of the "
                          f"parameters: {'; '.join(weak[:3])}{' …' if len(weak) > 3 else ''}. "
                          "Their estimate is the initial one's or the noise's; predict warns on "
                          "data beyond the envelope. Move every joint both ways, over its range, "
                          "to inform them", PoorExcitationWarning, stacklevel=2)
        return weak

    def _observe(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray
                 ) -> None:
        """Add samples (``(N, nv)`` arrays) to :attr:`envelope` and the torque RMS."""
        s = self._seen
        np.minimum(s[0], q.min(axis=0), out=s[0])
        np.maximum(s[1], q.max(axis=0), out=s[1])
        np.maximum(s[2], np.abs(dq).max(axis=0), out=s[2])
        np.maximum(s[3], np.abs(ddq).max(axis=0), out=s[3])
        s[4] += np.sum(dq >= STANDSTILL_SPEED, axis=0)      # as TrainingEnvelope counts them
        s[5] += np.sum(dq <= -STANDSTILL_SPEED, axis=0)
        s[6] += np.sum(tau ** 2, axis=0)
        self._n_seen += q.shape[0]

    def predict(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """``W(q, q̇, q̈) β̂`` for one sample (vectors) or many (``(N, nv)`` arrays).

        States that leave the :attr:`envelope` raise an
        :class:`~consistid.errors.ExtrapolationWarning` naming where
        (:meth:`~consistid.identification.envelope.TrainingEnvelope.departures`): a velocity
        sign never seen, or a range (``q``, ``|q̇|``, ``|q̈|``) exceeded by more than 10 % of its
        width or bound, in at least 1 % of the samples and at least 10 — or in all of them when
        fewer than 10 are given. One sample warns when it is itself outside: beyond a range by
        more than its 10 % margin, or moving (``|q̇| ≥ STANDSTILL_SPEED``) with a sign that
        fewer than max(10, 1 %) of the joint's moving samples taken had (once it moved in 10).
        The check compares the arrays with the envelope's bounds,
        cached between updates (no :class:`~consistid.Dataset` is built).

        Raises :class:`~consistid.errors.JointCountError` when ``q``, ``dq`` or ``ddq`` does
        not hold ``nv`` joints per sample, :class:`~consistid.errors.DatasetError` when they
        differ in rows or are not numbers.
        """
        nv, given = self.model.nv, []
        for name, a in (("q", q), ("dq", dq), ("ddq", ddq)):
            a = _numbers("predict", name, a)
            if a.ndim not in (1, 2) or a.shape[-1] != nv:
                joints = a.shape[-1] if a.ndim else 1
                raise JointCountError(f"predict: {name} has shape {a.shape} ({joints} joints); "
                                      f"{self.model.name} has {nv}: give {name} as a vector of "
                                      f"{nv} or an (N, {nv}) array")
            given.append(np.atleast_2d(a))
        q, dq, ddq = given
        for name, a in (("dq", dq), ("ddq", ddq)):
            if a.shape[0] != q.shape[0]:
                raise DatasetError(f"predict: {name} has {a.shape[0]} rows, q has {q.shape[0]}")
        if self._n_seen and self._outside(q, dq, ddq):
            away = self.envelope.departures_of(q, dq, ddq, self._bounds)
            if away:
                warnings.warn(f"these states go where the samples taken never went: "
                              f"{'; '.join(away[:4])}{' …' if len(away) > 4 else ''}. The "
                              "prediction there extrapolates (est.envelope holds the ranges "
                              "seen)", ExtrapolationWarning, stacklevel=2)
        out = np.empty_like(q)
        for k in range(q.shape[0]):
            out[k] = self.row(q[k], dq[k], ddq[k]) @ self._beta
        return out

    def _outside(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> bool:
        """Does a state leave the envelope's bounds
        (:func:`~consistid.identification.envelope.state_bounds`, cached)? Samples taken since
        the cache only widen the bounds, unless a velocity sign seen then is no longer
        :func:`~consistid.identification.envelope.sign_seen` — possible only once the joint's
        moving samples exceed that sign's count then over ``MIN_SIGN_SHARE`` (its cap): states
        inside bounds cached and still valid need no recomputation (a control loop's call)."""
        s = self._seen
        if 0 <= self._bounds_at != self._n_seen and (s[4] + s[5] > self._moving_cap).any():
            self._bounds_at = -1                          # a sign may be lost: recompute
        for _ in range(2):
            if self._bounds_at < 0:
                self._bounds = state_bounds(s[0], s[1], s[2:4], s[4:6])
                seen = enough(s[4:6], s[4] + s[5])
                self._moving_cap = np.where(seen, s[4:6] / MIN_SIGN_SHARE, np.inf).min(axis=0)
                self._bounds_at = self._n_seen
            lower, upper = self._bounds
            states = np.concatenate([q, dq, ddq], axis=1)
            if not ((states < lower).any() or (states > upper).any()):
                return False
            if self._bounds_at == self._n_seen:
                return True
            self._bounds_at = -1                                    # stale: decide on fresh
        return True

    # ------------------------------------------------------------------------- one sample
    def row(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """The base regressor row ``W(q, q̇, q̈)``, shape ``(nv, b)`` (inputs not checked)."""
        m = self.model.pin_model
        qc = q if m.nq == m.nv else self.model.configuration(q)
        y = pin.computeJointTorqueRegressor(m, self._data, qc, dq, ddq)
        w = self._w
        w[:, :self._n_rigid] = y[:, self._rigid_src]
        if self._joint_dst.size:
            signals = np.concatenate([np.sign(dq), dq, self._ones, np.sin(q), np.cos(q), ddq])
            w[self._joint_rows, self._joint_dst] = signals[self._joint_src]
        return w.copy()

    def _check(self, q: Any, dq: Any, ddq: Any, tau: Any) -> tuple[np.ndarray, ...]:
        nv = self.model.nv
        out = tuple(_numbers("update", name, v) for name, v in
                    zip(("q", "dq", "ddq", "tau"), (q, dq, ddq, tau)))
        if all(a.shape == (nv,) for a in out) and math.isfinite(
                float(out[0].sum() + out[1].sum() + out[2].sum() + out[3].sum())):
            for name, a in zip(("q", "dq", "ddq", "tau"), out):
                _plausible("update", name, a[None], self.n_updates, self.model.joint_names)
            return out
        for name, a in zip(("q", "dq", "ddq", "tau"), out):        # say what is wrong
            if a.shape != (nv,):
                raise JointCountError(f"update: {name} has shape {a.shape}; {self.model.name} "
                                      f"needs a vector of {nv} (one sample; update_batch takes "
                                      "(N, nv) arrays)")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise DatasetError(
                    f"update: sample {self.n_updates}: {name}[{self.model.joint_names[bad[0]]!r}]"
                    f" is {a[bad[0]]} ({bad.size} non-finite value(s)); the sample was refused "
                    "and the estimate is unchanged")
        raise DatasetError(f"update: sample {self.n_updates} overflows (sum of its entries is "
                           "not finite); the sample was refused and the estimate is unchanged")

    def update(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray,
               t: float | None = None) -> np.ndarray:
        """Take one sample (vectors of length ``nv``); return the updated ``β̂`` (the estimator's
        own array, replaced, never modified, by later updates).

        A sample with a NaN or infinite entry, or of the wrong width, raises
        (:class:`~consistid.errors.DatasetError`, :class:`~consistid.errors.JointCountError`)
        before touching the estimate. ``t`` (s) is recorded with a flagged change.
        """
        q, dq, ddq, tau = self._check(q, dq, ddq, tau)
        if t is not None:
            t = float(self._check_times("update", np.array([t], dtype=float))[0])
        self._still = np.abs(dq) < STANDSTILL_SPEED
        out = self._update(self.row(q, dq, ddq), tau, t)
        self._observe(q[None], dq[None], ddq[None], tau[None])
        if t is not None:
            self._last_time = t
        return out

    def _check_times(self, what: str, times: np.ndarray) -> np.ndarray:
        """Sample times must be finite and never go back (also across calls): a change is
        reported at its time, and a NaN or a clock that jumped back would be reported as one."""
        bad = np.flatnonzero(~np.isfinite(times))
        if bad.size:
            raise DatasetError(f"{what}: sample {self.n_updates + int(bad[0])}: t is "
                               f"{times[bad[0]]}; the sample was refused and the estimate is "
                               "unchanged (give finite times in s, or t=None)")
        previous = np.r_[-np.inf if self._last_time is None else self._last_time, times[:-1]]
        back = np.flatnonzero(times < previous)
        if back.size:
            k = int(back[0])
            raise DatasetError(f"{what}: sample {self.n_updates + k}: t = {times[k]!r} s is "
                               f"before the previous sample's {previous[k]!r} s; the sample was "
                               "refused and the estimate is unchanged (times must not decrease)")
        return times

    def _update(self, w: np.ndarray, tau: np.ndarray, t: float | None) -> np.ndarray:
        p, beta = self._p, self._beta
        lam = self.forgetting
        if self.windup == "trace" and lam < 1.0:
            lam = min(1.0, max(lam, float(np.trace(p)) / self.max_trace))
        self.last_forgetting = lam
        p_bar = p / lam if lam != 1.0 else p
        pw = p_bar @ w.T                                            # (b, nv)
        s = w @ pw + self._sigma_matrix
        chol, info = _potrf(s, lower=1)                             # S = L Lᵀ
        if info != 0:
            # P − K S Kᵀ lost definiteness to round-off (a reset's wide prior followed by
            # sharp data): repair P once — symmetric, eigenvalues clipped to a small positive
            # fraction of the largest — and say so; refuse only if that does not help
            p_bar = self._repair(p_bar)
            self._p = p_bar * lam if lam != 1.0 else p_bar
            pw = p_bar @ w.T
            s = w @ pw + self._sigma_matrix
            chol, info = _potrf(s, lower=1)
            if info != 0:
                raise IdentificationError(
                    f"update: sample {self.n_updates}: the innovation covariance is not "
                    "positive definite, even with P repaired; the estimate is unchanged")
        l_inv, _ = _trtri(chol, lower=1)       # dpotrf zeroed the upper triangle (clean=1)
        e = tau - w @ beta
        white = l_inv @ e                                           # S^{-1/2} e
        chi2 = float(white @ white)
        still = self._still
        if still is not None and still.any():
            # A joint at rest holds any torque its stiction allows (set-valued friction): its
            # innovation says nothing about a change of the robot. The detector sees the moving
            # joints' χ² plus the standing ones' expectation (1 each), so its degrees of freedom
            # and threshold stay those of nv joints.
            moving = ~still
            chi2 = float(still.sum())
            if moving.any():
                e_m = e[moving]
                chi2 += float(e_m @ np.linalg.solve(s[np.ix_(moving, moving)], e_m))
        self.last_statistic = chi2
        self._flag = False
        if (self.detector is not None and self.n_updates >= self.warmup
                and self._absorbing == 0):
            flag, value = self.detector.step(chi2, self.model.nv)
            if flag:
                self._flag = True
                self._changes.append(Change(self.n_updates, t, float(value),
                                            float(self.detector.threshold), beta.copy(),
                                            p.copy()))
                self.detector.reset()
                if self.on_change is not None:
                    return self._absorb(w, tau, t)
        g = pw @ l_inv.T                                            # K = G L⁻¹
        new_beta = beta + g @ white
        new_p = p_bar - g @ g.T                                     # symmetric (syrk)
        if not (math.isfinite(float(new_beta.sum())) and math.isfinite(float(new_p.sum()))):
            raise IdentificationError(f"update: sample {self.n_updates} made the estimate "
                                      "non-finite; it was not applied (check the sample's scale)")
        if float(np.diagonal(new_p).min()) <= 0.0:      # O(b): definiteness lost to round-off
            new_p = self._repair(new_p)
        self._beta, self._p = new_beta, new_p
        if not self.noise_given and self._absorbing == 0:
            self._learn_noise(tau - w @ new_beta)
        if self._absorbing:
            self._absorbing -= 1
        self.n_updates += 1
        if self.project_every is not None and self.n_updates % self.project_every == 0:
            self.consistent_parameters()
        return self._beta

    def _learn_noise(self, r: np.ndarray) -> None:
        """σ from a-posteriori residuals ``r`` (module docstring): fixed at
        :data:`NOISE_START` during the warm-up (early residuals are fitted away and would pull
        σ, hence the weights, to zero), the mean of ``r²`` over the warm-up's second half at its
        end (``P`` rescaled by the change of the mean variance), then an exponential average."""
        n, warm = self.n_updates, max(self.warmup, 2)
        if n < warm:
            if n >= warm // 2:
                self._noise_sum += r * r
            if n == warm - 1:
                sigma2 = np.maximum(self._noise_sum / (warm - warm // 2), NOISE_FLOOR ** 2)
                self._p = self._p * (float(np.mean(sigma2)) / NOISE_START ** 2)
                self._sigma2 = sigma2
                self._sigma_matrix = np.diag(sigma2)
            return
        self._sigma2 = np.maximum(self._sigma2 + (r * r - self._sigma2) / NOISE_MEMORY,
                                  NOISE_FLOOR ** 2)
        self._sigma_matrix = np.diag(self._sigma2)

    def _repair(self, p: np.ndarray) -> np.ndarray:
        """``p`` made positive definite (:func:`_repaired`), counted in ``n_repairs``; the
        first repair warns."""
        self.n_repairs += 1
        if self.n_repairs == 1:
            warnings.warn(f"RecursiveEstimator: at sample {self.n_updates} the covariance P lost "
                          "definiteness to round-off (a reset's wide prior, then sharp data); "
                          "repaired by clipping its negative eigenvalues — the estimate goes on, "
                          "its σ there is approximate (n_repairs counts them)",
                          DataQualityWarning, stacklevel=4)
        return _repaired(p)

    def _absorb(self, w: np.ndarray, tau: np.ndarray, t: float | None) -> np.ndarray:
        """Adapt to a flagged change (``on_change``), then take the flagging sample.

        ``"payload"`` escalates to ``"reset"`` when the previous change was flagged as soon as
        the detector re-armed after it (within two windows): the payload directions did not
        absorb it, so it is not a payload (an offset, a friction change …)."""
        window = max(int(getattr(self.detector, "window",
                                 getattr(self.detector, "refractory", 0))), 1)
        action = self.on_change
        if action == "payload" and len(self._changes) >= 2 \
                and self._changes[-1].index - self._changes[-2].index <= 2 * window + 1:
            action = "reset"
        recent = [c.index for c in self._changes[-CHAIN_FLAGS:]]
        if not self._chain_warned and len(recent) == CHAIN_FLAGS \
                and all(b - a <= 2 * window + 1 for a, b in zip(recent, recent[1:])):
            self._chain_warned = True
            warnings.warn(f"RecursiveEstimator: the change detector flagged {CHAIN_FLAGS} times "
                          f"in a row as soon as it re-armed (samples {recent}): not changes of "
                          "the robot but a model that does not fit the data — the regressor "
                          "lacks terms the torques hold (friction=, armature=True) or "
                          "noise_std is too small; each flag resets or widens the estimate",
                          DataQualityWarning, stacklevel=4)
        if action == "payload":
            self._p = self._p + self._payload_cov
        else:
            # every direction back to (at least) the prior's uncertainty: the old data's
            # information is gone, whatever its size (P / RESET_FACTOR alone kept 1e-4 of it,
            # which still outweighed the new data in the weakly excited directions)
            self._p = self._p / RESET_FACTOR + self._p0
        self._changes[-1] = replace(self._changes[-1], action=action)
        self._absorbing = window
        return self._update_after_flag(w, tau, t)

    def _update_after_flag(self, w: np.ndarray, tau: np.ndarray, t: float | None) -> np.ndarray:
        """The flagging sample, taken with the adapted covariance; the flag and the statistic
        that raised it are kept (not those of the re-run)."""
        flag, statistic = self._flag, self.last_statistic
        out = self._update(w, tau, t)
        self._flag, self.last_statistic = flag, statistic
        return out

    # ------------------------------------------------------------------------- many samples
    def update_batch(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray,
                     t: np.ndarray | None = None, record: bool = True) -> RecursiveTrace:
        """:meth:`update` on each row of ``(N, nv)`` arrays, in order (the same code path).

        All rows are checked before the first is used: a NaN anywhere raises
        :class:`~consistid.errors.DatasetError` naming the field, the row and the joint, and no
        row is taken. ``record=False`` keeps only the statistics (O(N) memory, not O(N b)).
        """
        arrays = []
        for name, value in (("q", q), ("dq", dq), ("ddq", ddq), ("tau", tau)):
            a = _numbers("update_batch", name, value)
            if a.ndim != 2 or a.shape[1] != self.model.nv:
                raise JointCountError(f"update_batch: {name} has shape {a.shape}; expected "
                                      f"(N, {self.model.nv})")
            arrays.append(a)
        n = arrays[0].shape[0]
        for name, a in zip(("q", "dq", "ddq", "tau"), arrays):
            if a.shape[0] != n:
                raise DatasetError(f"update_batch: {name} has {a.shape[0]} rows, q has {n}")
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                k, j = (int(i) for i in bad[0])
                raise DatasetError(f"update_batch: {name}[{k}, {self.model.joint_names[j]!r}] "
                                   f"is {a[k, j]}; no sample of the batch was taken")
            _plausible("update_batch", name, a, self.n_updates, self.model.joint_names)
        times = None if t is None else np.asarray(t, dtype=float).reshape(-1)
        if times is not None and times.shape != (n,):
            raise DatasetError(f"update_batch: t has shape {times.shape}; expected ({n},)")
        if times is not None and n:
            self._check_times("update_batch", times)
        start = self.n_updates
        b = self.base.n_base
        betas = np.empty((n, b)) if record else None
        stds = np.empty((n, b)) if record else None
        stats = np.empty(n)
        flagged = []
        qa, dqa, ddqa, taua = arrays
        still = np.abs(dqa) < STANDSTILL_SPEED
        for k in range(n):
            self._still = still[k]
            self._update(self.row(qa[k], dqa[k], ddqa[k]), taua[k],
                         None if times is None else float(times[k]))
            stats[k] = self.last_statistic
            if self._flag:
                flagged.append(k)
            if record:
                betas[k] = self._beta
                stds[k] = np.sqrt(np.diag(self._p))
        if times is not None and n:
            self._last_time = float(times[-1])
        if n:
            self._observe(qa, dqa, ddqa, taua)
        return RecursiveTrace(np.arange(start, start + n), times, betas, stds, stats,
                              np.array(flagged, dtype=int))

    # ------------------------------------------------------------------------- answers
    def payload(self, change: Change | int = -1, **options: Any):
        """The payload between the estimate before ``change`` (default the last) and now:
        :func:`consistid.payload_from_base_change` with both covariances.

        ``options`` go to it (``ellipsoid``, ``com_bounds``, ``mass_range``, ``solver`` …).
        Raises :class:`~consistid.errors.OptionError` when no change was flagged.
        """
        from ..estimation.payload import payload_from_base_change  # noqa: PLC0415 (cvxpy)

        if isinstance(change, (int, np.integer)):
            if not self._changes:
                raise OptionError("payload(): no change has been flagged yet (est.changes is "
                                  "empty); pass a Change")
            change = self._changes[int(change)]
        return payload_from_base_change(
            self.model, change.base_parameters, self._beta, base=self.base,
            covariance_unloaded=change.covariance, covariance_loaded=self._p,
            frame=self.payload_frame, **options)

    def consistent_parameters(self, projector: Any = None):
        """The current estimate projected onto the physically consistent set
        (:class:`consistid.online.projection.ConsistencyProjector`, built on first use and
        reused, so later calls only re-solve): a
        :class:`~consistid.online.projection.ProjectedEstimate` with the standard parameters,
        the solver's status and the projection's time."""
        from .projection import ConsistencyProjector  # noqa: PLC0415 (cvxpy)

        if projector is not None:
            self._projector = projector
        elif getattr(self, "_projector", None) is None:
            self._projector = ConsistencyProjector(self.model, self.base, self.spec)
        self.consistent = self._projector.project(self._beta, self._p)
        self.projection_seconds.append(self.consistent.seconds)
        return self.consistent

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Two-sided ``1 − alpha`` intervals of the base parameters from ``P``, shape (b, 2)."""
        alpha = check_number("alpha", alpha, 0, strict=True)
        if alpha >= 1:
            raise OptionError(f"alpha must lie in (0, 1), got {alpha}")
        z = float(scipy.stats.norm.ppf(1 - alpha / 2))
        return np.column_stack([self._beta - z * self.std, self._beta + z * self.std])

    def summary(self, max_rows: int | None = 20) -> str:
        """The estimate ± σ per base parameter (the first ``max_rows``; ``None``: all), the
        noise σ in use and the changes flagged."""
        std = self.std
        rows = [(n, b, s, g) for n, b, s, g in zip(self.parameter_names, self._beta, std,
                                                      self.base.groupings)]
        shown = rows if max_rows is None else rows[:max_rows]
        lines = [repr(self),
                 f"noise σ [N·m] ({'given' if self.noise_given else 'estimated'}): "
                 + ", ".join(f"{s:.3g}" for s in self.noise_std),
                 "", table(["base parameter", "estimate", "σ", "grouping"],
                           [(n, b, s, g if len(g) <= 60 else g[:59] + "…")
                            for n, b, s, g in shown])]
        if len(shown) < len(rows):
            lines.append(f"… {len(rows) - len(shown)} more (summary(max_rows=None))")
        lines += ["", *(str(c) for c in self._changes)] if self._changes else []
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return fragment(self.summary())

    def __repr__(self) -> str:
        return (f"RecursiveEstimator({self.model.name!r}, {self.base.n_base} base parameters, "
                f"{self.spec.describe()}, forgetting={self.forgetting:g}, windup={self.windup}, "
                f"detector={self.detector!r}, on_change={self.on_change}, "
                f"{self.n_updates} updates, {len(self._changes)} change(s))")
