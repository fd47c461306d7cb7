r"""Sim-to-real gap diagnosis: where the nominal model's residual lies, which unmodelled effect
explains it, and how far each effect shrinks it on held-out data.

Method
------
1. *Residual.* ``r = τ_meas − τ_nom`` with the nominal (simulator) parameters, on training and
   held-out data (a different recording, or the last 30 % of each recording when none is given).
2. *Candidates.* Every effect of the registry (:mod:`consistid.diagnosis.effects`) offers atoms
   (an effect on one joint,
   or arm-wide) whose correction ``Φ_a θ_a`` is linear in its parameters. All atoms' columns are
   compressed once into per-joint Gram matrices ``Φ_jᵀΦ_j``, ``Φ_jᵀr_j`` (training and held-out),
   so that any subset is fitted and scored without touching the samples again.
3. *Greedy forward selection* (Efroymson 1960; Hastie, Tibshirani, Friedman, *The Elements of
   Statistical Learning*, §3.3.2): at each step every remaining atom is fitted on the training
   data jointly with the atoms already chosen (least squares weighted by ``1/σ_j²``) and scored by
   its reduction of the held-out weighted sum of squares. An atom may be kept if, on the rows
   it acts on (its joint, or every joint),

   * the training BIC decreases (Schwarz 1978, doi:10.1214/aos/1176344136),
     ``N log(SSE₁/SSE₀) + k log N < 0`` with ``N`` the number of training rows,
   * its held-out reduction passes an F-test at level ``alpha``,
     ``F = (ΔSSE_ho / k) / (SSE_ho / N_ho)``,
   * the reduction is at least ``min_gain`` of the nominal held-out sum of squares of its joint,
     or, for an arm-wide atom, of the joint it reduces most (a practical-relevance floor: an
     arm-wide effect that matters on one joint, such as a tilted base loading a vertical first
     joint, is not drowned by the residual of the others),
   * and its parameter is physical where the effect has a sign (friction, rotor inertia,
     compliance, payload mass ≥ 0).

   The best atom (largest held-out reduction) that passes is kept. Rows are counted as
   ``N / τ`` effectively independent samples, ``τ`` the integrated autocorrelation time of the
   residual that no candidate explains
   (:func:`consistid.identification.statistics.autocorrelation_time`): filtered
   torques make neighbouring samples nearly equal, and tests counting every row would accept
   any wiggle.

   Two kinds of atom are scored otherwise. The rigid-body atoms (``inertia``, ``payload``)
   are fitted with the quadratic model of the final fit's log-det prior around the nominal
   bodies, its weight of greatest evidence (:mod:`consistid.diagnosis.rigid_prior`): tens of
   base parameters, some barely excited, are not set from the noise. And an atom whose effect
   names *companions* (inertia and payload: Coulomb and viscous friction) is scored against
   the chosen atoms plus its companions not yet chosen, the partial test of a block beside
   nuisance columns (:mod:`consistid.diagnosis.interaction`): friction still missing on
   some joint is not taken up by the inertia, which would then fail on held-out data; it is
   fitted and tested with each joint weighted by the variance the fit leaves there, not by its
   floor (feasible generalised least squares), so that a joint's model error (a wrist held in
   its friction cone at rest) does not steer the fit of every body. Where
   the floor is read from the residual spectrum, it is read again without the tails of every
   candidate fitted at once before the selection (an unexplained Coulomb step's ``1/f²`` tail
   raises it several-fold and would weigh that joint down in every test).

   Atoms whose held-out reductions are within ``tie`` of the best and whose corrections are
   nearly collinear with it (cosine ≥ 0.9 on the held-out data) are *indistinguishable* on these
   data: the one with fewer parameters is kept and the others are listed as alternatives instead
   of being ranked arbitrarily.
   Candidates left out whose columns lie in the span of the selected ones (a ``payload`` or a
   once-per-revolution ``position`` torque inside ``inertia``) are named in a note: such an
   effect is in the fit, but these data cannot tell it apart.
4. *How far it shrinks.* Selected atoms are grouped by effect and the groups ranked by how
   much the held-out residual grows when a group is removed from all the selected atoms (atoms
   nested in the span of others, e.g. a payload inside inertia, are merged first); the groups
   are added one by one in that order (a per-joint atom of an effect that is a companion of a
   group still to come is judged, for making its joint worse, with every selected atom in the
   fit; a selected payload gives way to inertia when the consistent fit of every body predicts
   the held-out data better), each time refitted on the training data (the delay
   refined exactly, ``τ_nom(t − d)``; inertia by the consistent SDP near the nominal, started
   from the joint least-squares fit) and scored per joint on the held-out data: RMS before →
   after, shrink, parameters ± standard deviation (each joint's rows counted as ``N / τ_j``
   independent ones, as in the tests: :func:`_coloured_covariance`). A group that no longer
   reduces the held-out residual in this final fit is left out, with a note. The friction
   parameters reported are one set-valued fit of each joint's whole friction law with the
   model error of the rows near rest (:mod:`consistid.diagnosis.friction_law`), where the
   torques went through a recorded low-pass.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import scipy.ndimage
import scipy.optimize
import scipy.stats

from ..data.checks import check_for_identification
from ..data.dataset import Dataset, as_dataset
from ..data.filters import settling_time
from ..errors import (DataQualityWarning, ModelError, ModelMisfitWarning, OptionError, check_number,
                      check_option)
from ..identification.regressor import joint_columns
from ..identification.statistics import autocorrelation_time, coloured_covariance
from ..progress import Progress
from ..robot.inertia import degenerate_bodies
from ..robot.model import RobotModel, require_model
from .candidates import EFFECT_NAMES, SIGNATURES, Atom, EffectLibrary, GapData
from .effects import REGISTRY, EffectParameter
from .gap import GapBreakdown, gap_breakdown, residual_spectra
from .interaction import companions, residual_scale
from .rigid_prior import evidence_prior_weight, prior_curvature
from .noise import NoiseFloor, estimate_noise_floor, spectral_estimate
from .persistence import read_diagnosis, write_diagnosis
from .friction_law import FAR_SAMPLES, friction_law
from .remainder import (
    LOWPASS_ORDER,
    REMAINDER_RATIO,
    Remainder,
    SetValuedFit,
    analyse_remainder,
    dry_friction_at_rest,
    set_valued_refit,
    standstill_mask,
)
from .confidence import DETERMINED_Z, Evidence, confidence_label
from .verdict import verdict_head

#: Two candidates are not indistinguishable when one leaves a joint above the flag's ratio with
#: more than this × the other's held-out sum of squares there (twice its RMS).
DISTINCT_LEFT = 4.0
#: A held-out shrink below this fraction does not list a joint under an arm-wide effect.
JOINT_SHRINK_FLOOR = 0.05
#: An effect raising a joint's held-out RMS above this factor (and above the remainder's flag)
#: makes that joint worse: a per-joint atom is refused, an arm-wide effect reported, low.
WORSE_RATIO = 1.1
#: Held-out corrections with at least this cosine explain the same residual (rivals).
RIVAL_COSINE = 0.5
#: Speed (rad/s) below which a joint counts as at rest when a Stribeck hump is weighed against
#: what is left (:func:`_clear_of_rest`): the presliding or soft-constraint regime of dry
#: friction, where no law of q̇ predicts the torque.
REST_SPEED = 0.01
#: Effects that are dry friction: set-valued at rest (judged against their cone there, see
#: :func:`consistid.diagnosis.remainder.dry_friction_at_rest`).
DRY_FRICTION = ("coulomb", "stribeck")
#: Effects that are viscous friction: refitted beside the dry friction where that is judged
#: set-valued through a filter
#: (:func:`consistid.diagnosis.remainder.dry_friction_through_filter`).
VISCOUS_FRICTION = ("viscous",)


# --------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class EffectFinding:
    """A selected effect: where it acts, how far it shrinks the held-out residual, its parameters.

    Attributes
    ----------
    name : effect name (``"coulomb"`` …).
    joints : joints it explains: the joints of its per-joint atoms, or, for an arm-wide effect,
        the joints whose held-out RMS it shrinks by at least 5 %.
    scope : ``"joint"`` (per-joint atoms) or ``"arm"`` (one atom acting on every joint).
    rms_before, rms_after : (nv,) held-out RMS per joint before and after adding this effect to
        the effects ranked above it (N·m).
    shrink : (nv,) ``1 − rms_after / rms_before`` per joint.
    total_shrink : ``1 − ‖r_after‖_w / ‖r_before‖_w`` over all joints, residuals weighted by the
        per-joint noise floor used in the selection.
    parameters : estimated parameters with standard deviations.
    alternatives : other candidates indistinguishable from it on these data (same signature).
    n_parameters : parameters it adds.
    delta_bic : change of the training BIC when it entered (negative = better).
    p_value : held-out F-test p-value when it entered.
    signature : how this effect shows in the residual.
    runner_up : the best other candidate that explains the same residual (its own held-out
        correction has cosine ≥ 0.5 with this one's) when it entered, or ``""``.
    margin : confidence against it: ``1 − gain_runner_up / gain`` of the held-out reductions
        (1: no rival; near 0: the runner-up explains nearly as much, both are shown; negative:
        the runner-up explains more but was refused, e.g. an unphysical fit).
    worsened : joints whose held-out RMS this (arm-wide) effect raised above
        :data:`WORSE_RATIO` × what it was and above the remainder's flag (a per-joint atom
        that does so on its own joint is refused instead).
    unexplained : its joints that the verdict leaves flagged or undetermined (what is left
        there is above the floor: the effect is not the whole story).
    """

    name: str
    joints: tuple[str, ...]
    scope: str
    rms_before: np.ndarray
    rms_after: np.ndarray
    shrink: np.ndarray
    total_shrink: float
    parameters: tuple[EffectParameter, ...]
    alternatives: tuple[str, ...]
    n_parameters: int
    delta_bic: float
    p_value: float
    signature: str
    runner_up: str = ""
    margin: float = 1.0
    worsened: tuple[str, ...] = ()
    unexplained: tuple[str, ...] = ()

    @property
    def determined(self) -> bool:
        """Every per-joint parameter at least :data:`DETERMINED_Z` standard deviations from
        zero (arm-wide effects' parameters, such as inertia's base parameters, are not
        judged one by one)."""
        return self.scope != "joint" or all(
            abs(p.value) >= DETERMINED_Z * p.std for p in self.parameters
            if np.isfinite(p.std))

    @property
    def confidence(self) -> str:
        """``"high"``, ``"medium"`` or ``"low"``
        (:func:`consistid.diagnosis.confidence.confidence_label`: low when a parameter is not
        determined, a refused rival explains more, or it worsens a joint; high with a margin
        ≥ 0.5, p < 1e-6 and none of its joints left unexplained by the verdict)."""
        return confidence_label(Evidence.of(self))

    def __str__(self) -> str:
        alt = f" (indistinguishable from {', '.join(self.alternatives)})" if self.alternatives \
            else ""
        rival = (f"; runner-up {self.runner_up} explains {100 * (1 - self.margin):.0f} % as much"
                 + (" but was refused (see the steps)" if self.margin < 0 else "")
                 if self.runner_up and self.margin < 0.5 else "")
        return (f"{self.name} on {', '.join(self.joints) or 'no joint'}: held-out shrink "
                f"{100 * self.total_shrink:.1f} %, confidence {self.confidence} (margin "
                f"{self.margin:.2f}, p = {self.p_value:.2g}){alt}{rival}")


@dataclass(frozen=True)
class Step:
    """One step of the greedy selection, with the candidates it compared (for the report)."""

    chosen: str
    gain: float
    delta_bic: float
    p_value: float
    accepted: bool
    reason: str
    candidates: tuple[tuple[str, float, int], ...]


@dataclass(frozen=True, eq=False)
class GapModel:
    """The nominal model plus the selected corrections, fitted on the training data.

    ``predict(dataset)`` gives the corrected torque; with no atoms it is the nominal torque.
    """

    model: RobotModel
    library: EffectLibrary
    nominal: np.ndarray
    atoms: tuple[Atom, ...]
    theta: tuple[np.ndarray, ...]
    delays: dict[int, float] = field(default_factory=dict)
    inertial: np.ndarray | None = None
    nominal_extra: Callable[[Dataset], np.ndarray] | None = None

    def data(self, dataset: Dataset) -> GapData:
        extra = self.nominal_extra(dataset) if self.nominal_extra is not None else None
        return GapData(self.model, dataset, self.nominal, extra)

    def correction(self, data: GapData) -> np.ndarray:
        """Torque added to the nominal one, (N, nv)."""
        out = np.zeros((data.n, data.nv))
        for i, (atom, th) in enumerate(zip(self.atoms, self.theta)):
            if i in self.delays:
                continue
            if atom.effect == "inertia" and self.inertial is not None:
                out += data.rigid @ (self.inertial - self.nominal)
            else:
                out += self.library.columns(atom, data) @ th
        # A delayed channel delays all of its torque: the other effects' too.
        return out + sum((exact_delay(data, self.atoms[i], d, out)
                          for i, d in self.delays.items()), np.zeros_like(out))

    def predict(self, dataset: Dataset) -> np.ndarray:
        data = self.data(dataset)
        return data.tau_nom + self.correction(data)

    def __repr__(self) -> str:
        labels = ", ".join(a.label(self.model.joint_names) for a in self.atoms) or "nominal only"
        return f"GapModel({self.model.name!r}: {labels})"


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """What :func:`diagnose` found.

    Attributes
    ----------
    effects : selected effects, ranked by how much the held-out residual grows when the effect
        is removed from all the selected ones (largest first; their ``total_shrink``, each
        measured after the ones above it, need not decrease down the list);
        ``rms_before``/``rms_after`` of each are cumulative in this order.
    where : where the nominal model's residual lies
        (:class:`~consistid.diagnosis.gap.GapBreakdown`).
    noise_floor : (nv,) torque noise standard deviation per joint (N·m), through the low-pass of
        the recordings it was read on (:attr:`held_floor`: on the held-out ones).
    noise_source : ``"given"`` or how it was estimated.
    rms_nominal, rms_final : (nv,) held-out RMS of the nominal model and of the nominal model
        plus every selected effect.
    library_floor : (nv,) held-out RMS with *every* candidate atom fitted at once: the most the
        candidate library can explain. Reported, never used as the noise floor (it holds
        whatever an effect outside the library leaves).
    held_out_source : how the held-out data were obtained.
    steps : the greedy selection's steps (candidates compared, why it stopped).
    fit : the corrected model (:class:`GapModel`); ``fit.predict(dataset)``.
    notes : remarks (e.g. which inertia solver was used).
    remainder : the unexplained remainder per joint, its verdict and where it lies
        (:class:`~consistid.diagnosis.remainder.Remainder`).
    noise : how the noise floor was obtained (:class:`~consistid.diagnosis.noise.NoiseFloor`).
    held_floor : (nv,) the noise floor on the held-out recordings: ``noise_floor`` scaled once
        by how much more white noise their recorded low-pass lets through (never less), where
        it was read on other recordings (``noise.on_repeating``).
    rms_left : (nv,) held-out RMS after every selected effect as the verdict judges it: dry
        friction set-valued at rest (a held joint's torque within its cone is no error) and the
        samples the model cannot predict left out (``rms_final`` is point-valued); the verdict
        flags a joint above ``REMAINDER_RATIO`` × its floor here.
    rollout : how far the gap shrinks in the user's simulator, when given
        (:meth:`with_rollout`: a :class:`~consistid.simulator.rollout.RolloutValidation`).
    """

    model_name: str
    joint_names: tuple[str, ...]
    effects: tuple[EffectFinding, ...]
    where: GapBreakdown
    noise_floor: np.ndarray
    noise_source: str
    rms_nominal: np.ndarray
    rms_final: np.ndarray
    library_floor: np.ndarray
    held_out_source: str
    steps: tuple[Step, ...]
    fit: GapModel
    notes: tuple[str, ...] = ()
    remainder: Remainder | None = None
    noise: NoiseFloor | None = None
    rms_left: np.ndarray | None = None
    held_floor: np.ndarray | None = None
    rollout: Any = None

    def with_rollout(self, validation: Any) -> "Diagnosis":
        """This diagnosis carrying a rollout validation (closed- and open-loop replays in the
        user's simulator, :func:`consistid.simulator.validate_rollout`), shown in its summary
        and report."""
        return replace(self, rollout=validation)

    @property
    def verdict(self) -> str:
        """``"explained"``, ``"remainder on <joints>"``, ``"undetermined on <joints>"`` (the
        noise floor could not be seen there, or the joint is left above the flag within the
        signal chain's tolerance; see :attr:`remainder`), or both, ``"remainder on A;
        undetermined on B"``: every joint the held-out table leaves above the flag is named
        (:func:`consistid.diagnosis.verdict.verdict_head`)."""
        if self.remainder is None:
            return "explained"
        return verdict_head(self.remainder.flagged, self.remainder.undetermined)

    @property
    def gap_to_noise(self) -> np.ndarray:
        """Held-out RMS after every selected effect divided by the held-out noise floor, per
        joint."""
        return self.rms_final / (self.noise_floor if self.held_floor is None
                                 else self.held_floor)

    @property
    def left_to_noise(self) -> np.ndarray:
        """:attr:`rms_left` over the held-out noise floor, per joint (the held-out column the
        verdict judges; :attr:`gap_to_noise` where it was not computed)."""
        if self.rms_left is None:
            return self.gap_to_noise
        floor = self.noise_floor if self.held_floor is None else self.held_floor
        return self.rms_left / floor

    @property
    def at_noise_floor(self) -> bool:
        """True when every joint's remaining held-out RMS is within 10 % of its noise floor."""
        return bool(np.all(self.gap_to_noise <= 1.1))

    @property
    def at_library_floor(self) -> bool:
        """True when every joint's remaining held-out RMS is within 10 % of the library floor
        (what all candidates together reach): the selection left nothing explainable out."""
        return bool(np.all(self.rms_final <= 1.1 * self.library_floor))

    def summary(self) -> str:
        from .report import diagnosis_text

        return diagnosis_text(self)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        """Jupyter: the HTML report without plots (:func:`.report.diagnosis_page`)."""
        from .report import diagnosis_page

        return diagnosis_page(self, figures=False).fragment()

    def __repr__(self) -> str:
        found = ", ".join(f"{e.name}({', '.join(e.joints)})" for e in self.effects) or "none"
        return (f"Diagnosis({self.model_name!r}, effects=[{found}], "
                f"verdict={self.verdict!r})")

    def save(self, path: str | Path) -> Path:
        """Write this diagnosis as JSON (:mod:`consistid.diagnosis.persistence`); returns the
        path. :meth:`load` gives back the same tables, verdict, report and corrected model."""
        return write_diagnosis(self, path)

    @classmethod
    def load(cls, path: str | Path) -> "Diagnosis":
        """A diagnosis written by :meth:`save`."""
        return read_diagnosis(path, cls)

    def report(self, path: str | None = None):
        """Write the report: ``*.html`` (plots embedded), ``*.txt``, or a directory (both, plus
        the plots as PNG files). Returns the text, or the path written."""
        from .report import write_report

        if path is None:
            return self.summary()
        return write_report(self, path)


# --------------------------------------------------------------------------------- algebra
def _solve(G: np.ndarray, c: np.ndarray, rtol: float = 1e-10
           ) -> tuple[np.ndarray, int, np.ndarray]:
    """Least squares from normal equations, column-scaled, truncated eigen-decomposition.

    Returns ``(θ, rank, G⁺)``; directions of ``G`` below ``rtol`` of its largest eigenvalue (after
    scaling the columns to unit norm) are not determined by the data and left at zero.
    """
    d = np.sqrt(np.clip(np.diag(G), 0, None))
    d[d == 0] = 1.0
    gs = G / np.outer(d, d)
    w, v = np.linalg.eigh(gs)
    keep = w > rtol * max(w[-1], 1e-300)
    vk = v[:, keep]
    pinv = (vk / w[keep]) @ vk.T
    theta = pinv @ (c / d)
    return theta / d, int(keep.sum()), pinv / np.outer(d, d)


@dataclass(frozen=True)
class _Grams:
    """Per-joint normal equations of one dataset: ``G[j] = Φ_jᵀΦ_j``, ``c[j] = Φ_jᵀr_j``,
    ``s[j] = r_jᵀr_j`` and the sample count."""

    G: np.ndarray
    c: np.ndarray
    s: np.ndarray
    n: int

    @classmethod
    def build(cls, phi: np.ndarray, r: np.ndarray) -> "_Grams":
        # per joint through BLAS (an einsum over all joints at once does not use it: 1.8 s of a
        # 7 s diagnosis of a 30 s, 500 Hz Panda log)
        nv = phi.shape[1]
        g = np.stack([phi[:, j, :].T @ phi[:, j, :] for j in range(nv)]) if nv else \
            np.zeros((0, phi.shape[2], phi.shape[2]))
        c = np.stack([phi[:, j, :].T @ r[:, j] for j in range(nv)]) if nv else \
            np.zeros((0, phi.shape[2]))
        return cls(g, c, np.sum(r ** 2, axis=0), r.shape[0])

    def sse(self, cols: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Per-joint ``‖r_j − Φ_j[:, cols] θ‖²``, (nv,)."""
        if cols.size == 0:
            return self.s.copy()
        g = self.G[:, cols][:, :, cols]
        return (self.s - 2 * self.c[:, cols] @ theta
                + np.einsum("p,jpq,q->j", theta, g, theta))

    def weighted(self, w: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = np.einsum("j,jpq->pq", w, self.G[:, cols][:, :, cols])
        return g, w @ self.c[:, cols]


def exact_delay(data: GapData, atom: Atom, d: float, others: np.ndarray | None = None
                ) -> np.ndarray:
    """Correction ``τ̂(t − d) − τ̂(t)`` of a delay atom (its joint, or all joints), ``τ̂ = τ_nom``
    plus ``others`` (N, nv), the other effects' corrections (a delayed channel delays all of
    its torque), by linear interpolation within each recording segment (held at the ends)."""
    signal = data.tau_nom if others is None else data.tau_nom + others
    return _delayed(data, signal, d, atom.joint) - signal


def _delayed(data: GapData, x: np.ndarray, d: float, joint: int | None) -> np.ndarray:
    """``x`` (N, nv[, p]) with joint ``joint``'s rows (all joints for ``None``) replaced by
    ``x(t − d)``, linearly interpolated within each recording segment (held at the ends)."""
    out = x.copy()
    joints = range(data.nv) if joint is None else [joint]
    for seg in data.segments:
        t = seg.t
        for j in joints:
            rows = x[seg.index, j].reshape(seg.size, -1)
            out[seg.index, j] = np.column_stack([np.interp(t - d, t, c) for c in rows.T]
                                                ).reshape(out[seg.index, j].shape)
    return out


# --------------------------------------------------------------------------------- helpers
def _resolve_nominal(model: RobotModel, nominal) -> tuple[np.ndarray, Callable | None]:
    """Standard inertial vector of the nominal model and an optional extra-torque function."""
    from ..identification.result import IdentificationResult

    if nominal is None:
        return model.prior_parameters, None
    if isinstance(nominal, RobotModel):
        if nominal.joint_names != model.joint_names:
            raise ModelError(f"nominal model joints {nominal.joint_names} differ from "
                             f"{model.joint_names}")
        return nominal.prior_parameters, None
    if isinstance(nominal, IdentificationResult):
        pi0 = nominal.inertial_parameters.copy()
        theta_joint = nominal.parameters[nominal.model.n_inertial:]

        def extra(ds: Dataset) -> np.ndarray:
            # Its prediction minus the rigid body: the per-joint columns (friction, armature).
            return joint_columns(ds.q, ds.dq, ds.ddq, nominal.spec,
                                 dq_sign=ds.dq_sign) @ theta_joint

        return pi0, extra
    try:
        pi0 = np.asarray(nominal, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"nominal must be a RobotModel, an IdentificationResult or "
                         f"{model.n_inertial} numbers, got {nominal!r:.60}") from None
    if pi0.shape != (model.n_inertial,):
        raise ModelError(f"nominal parameters have shape {pi0.shape}; {model.name} needs "
                         f"({model.n_inertial},) standard inertial parameters (10 per body)")
    bad = np.flatnonzero(~np.isfinite(pi0))
    if bad.size:
        raise ModelError(f"nominal[{int(bad[0])}] ({model.parameter_names[bad[0]]}) is "
                         f"{pi0[bad[0]]} ({bad.size} non-finite value(s)): the nominal "
                         "parameters must be finite numbers")
    return pi0, None


def _sigma(sigma, nv: int, name: str = "sigma") -> np.ndarray:
    try:
        s = np.broadcast_to(np.asarray(sigma, dtype=float), (nv,)).copy()
    except (TypeError, ValueError):
        s = np.array([np.nan])
    if not np.all(np.isfinite(s) & (s > 0)):
        raise OptionError(f"{name} must be one number or {nv} numbers (one per joint), positive "
                          f"and finite (N·m), got {sigma!r}")
    return s


# --------------------------------------------------------------------------------- selection
@dataclass
class _Problem:
    """Everything the selection needs: atoms, their column slices, Grams, weights."""

    library: EffectLibrary
    atoms: list[Atom]
    slices: list[np.ndarray]
    train: _Grams
    held: _Grams
    w: np.ndarray
    #: (nv,) integrated autocorrelation time of the residual per joint (samples per
    #: independent sample)
    tau_corr: np.ndarray | float = 1.0
    #: time-stamp resolution (s): the median sample interval of the training data
    resolution: float = 0.0
    #: per Stribeck atom (index): held-out Grams of its joint on the rows clear of rest, and
    #: their count (:func:`_clear_of_rest`)
    moving: dict[int, tuple["_Grams", int]] = field(default_factory=dict)
    #: (P, P) weighted prior curvature ``γS`` on the rigid-body atoms' columns
    #: (:mod:`consistid.diagnosis.rigid_prior`), or ``None``
    prior: np.ndarray | None = None
    #: (nv,) per-joint weights of the fits once an atom scored by feasible generalised least
    #: squares is chosen (:func:`consistid.diagnosis.interaction.residual_scale`), else ``None``
    #: (``w``)
    fit_w: np.ndarray | None = None

    def cols(self, chosen: Sequence[int]) -> np.ndarray:
        if not chosen:
            return np.zeros(0, dtype=int)
        return np.concatenate([self.slices[i] for i in chosen])

    def fit(self, chosen: Sequence[int], w: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, int]:
        """``(columns, θ, rank)`` of the chosen atoms' weighted least-squares fit on the
        training data (weights ``w``, default :attr:`fit_w` or :attr:`w`), with the rigid-body
        prior where they hold its columns; ``rank`` counts the directions the data determine
        (the prior's are not counted)."""
        cols = self.cols(chosen)
        if cols.size == 0:
            return cols, np.zeros(0), 0
        w = w if w is not None else self.fit_w if self.fit_w is not None else self.w
        g, c = self.train.weighted(w, cols)
        theta, rank, _ = _solve(g, c)
        prior = None if self.prior is None else self.prior[np.ix_(cols, cols)]
        if prior is not None and prior.any():
            theta = _solve(g + prior, c)[0]
        return cols, theta, rank


def _rigid_prior(prob: _Problem, nominal: np.ndarray) -> np.ndarray | None:
    """``γS``, the rigid-body atoms' prior (:mod:`consistid.diagnosis.rigid_prior`) with the
    weight of greatest evidence on the inertia fitted beside its companions (every joint's
    friction), or ``None`` (no rigid atom, or a nominal body not realisable)."""
    curvature = prior_curvature(prob.library, prob.atoms, nominal)
    inertia = [i for i, a in enumerate(prob.atoms) if a.effect == "inertia"]
    if curvature is None or not inertia:
        return curvature
    cols = prob.cols(companions(prob.atoms, [], inertia[0]) + inertia)
    g, c = prob.train.weighted(prob.w, cols)
    return evidence_prior_weight(g, c, curvature[np.ix_(cols, cols)]) * curvature


def _nested_by_final_fit(prob: _Problem, nuisance: list[int], chosen: list[int],
                         train: GapData, held: GapData, model: RobotModel, nominal: np.ndarray,
                         extra_fn, names: list[str], notes: list[str], alpha: float
                         ) -> list[int]:
    """``chosen`` with a selected ``payload`` replaced by ``inertia`` (whose columns span it)
    when the final fit with ``inertia`` (the consistent SDP near the nominal, every body free)
    predicts the held-out data better than the final fit with the payload: a larger held-out
    Gaussian log-likelihood with each joint's noise variance profiled out,
    ``−(N/2) Σ_j log SSE_j`` (the floors, which may be unreliable where the noise cannot be
    seen, do not weigh the joints); a note says so. The selection scores both by regularised
    least squares, where the ten payload columns can edge out the full rigid body on held-out
    data (xArm7 mixed case, seed 2: 6 % more held-out gain) although the consistent fit of
    every body, the one the user gets, predicts it better (worst joint 0.92 × ``identify``'s
    against 1.27 × with the payload): the held-out data, with the final fit, decide — by a
    likelihood-ratio test at level ``alpha`` for the extra parameters, and only if no joint's
    held-out RMS rises (the issue's rule: an effect that makes a joint worse on held-out data is
    refused). A payload alone beside friction on every joint (UR5, xArm7, 1 kg) is better
    predicted by every body's inertia on most joints, which soak up friction's model error, but
    worse on one (wrist_3 0.312 → 0.317, joint1 0.204 → 0.206 N·m): it stays a payload."""
    kinds = [prob.atoms[i].effect for i in chosen]
    inertia = [i for i, a in enumerate(prob.atoms) if a.effect == "inertia"]
    if "payload" not in kinds or "inertia" in kinds or not inertia:
        return chosen
    swapped = [inertia[0] if prob.atoms[i].effect == "payload" else i for i in chosen]

    def held_rms(atoms: list[int]) -> np.ndarray:
        fit = _refit(prob, nuisance + atoms, train, model, nominal, extra_fn, "sdp")[0]
        return np.sqrt(np.mean((held.residual - fit.correction(held)) ** 2, axis=0))

    with_payload, with_inertia = held_rms(chosen), held_rms(swapped)
    # the profiled held-out likelihood ratio, Σ_j (n_j/2) log(SSE_pay/SSE_in) with n_j the
    # effectively independent samples, against χ² of the extra parameters (Wilks): the full
    # rigid body must earn its columns, as every candidate of the selection must
    n_eff = held.n / np.maximum(prob.tau_corr, 1.0)
    ratio = float(np.sum(n_eff * np.log(with_payload / with_inertia)))
    extra = prob.atoms[inertia[0]].n_parameters - sum(
        prob.atoms[i].n_parameters for i in chosen if prob.atoms[i].effect == "payload")
    how = ", ".join(f"{n} {a:.3g} → {b:.3g}" for n, a, b in zip(names, with_payload, with_inertia))
    if ratio <= 0.5 * scipy.stats.chi2.ppf(1.0 - alpha, max(extra, 1)):
        return chosen
    if np.any(with_inertia > with_payload):
        worse = ", ".join(n for n, a, b in zip(names, with_payload, with_inertia) if b > a)
        notes.append("payload was selected and kept: inertia (its columns span the payload's) "
                     "fitted by the consistent SDP in its place predicts the held-out data "
                     f"better on some joints but worse on {worse} (held-out RMS, N·m: {how}); "
                     "these data do not tell a payload from every body's inertia being off "
                     "(friction's model error can lend the larger fit its gain): weigh both")
        return chosen
    notes.append("payload was selected; inertia (its columns span the payload's) fitted by the "
                 "consistent SDP in its place predicts the held-out data better (held-out RMS, "
                 f"N·m: {how}): inertia kept")
    return swapped


def _floor_without_tails(floor: np.ndarray, noise: NoiseFloor, source: str, on: GapData,
                         train: GapData, held: GapData, phi_tr: np.ndarray, phi_ho: np.ndarray,
                         cols: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, str]:
    """``(floor, source)`` with each spectral floor estimated again on the residual less every
    candidate fitted at once (``θ`` on ``cols``), where that is lower: the high band of the
    nominal residual also holds the tails of the steps the candidates explain (a Coulomb step's
    spectrum falls as ``1/f²``; three times the noise on the xArm7 mixed case), which would
    weigh the joints with unexplained friction down in every test of the selection. Still the
    level above the motion band (:func:`~consistid.diagnosis.noise.spectral_estimate`), never
    what a fit leaves; the floors read on a repetition, or given, are kept."""
    spectral = np.array([m == "spectrum" for m in noise.method])
    if not spectral.any() or cols.size == 0:
        return floor, source
    parts = {id(train): (phi_tr,), id(held): (phi_ho,)}.get(id(on), (phi_tr, phi_ho))
    correction = np.concatenate([phi[:, :, cols] @ theta for phi in parts])
    again = spectral_estimate(on.dataset, on.residual - correction, on.tau_nom).sigma
    if not np.any(spectral & (again < floor)):
        return floor, source
    return (np.where(spectral, np.minimum(floor, again), floor),
            source + " (spectral level estimated again without the candidates' tails)")


def _rows_of(atom: Atom, nv: int) -> np.ndarray:
    return np.arange(nv) if atom.joint is None else np.array([atom.joint])


def _select(prob: _Problem, joint_names: list[str], alpha: float, min_gain: float,
            min_excess: float, tie: float, max_steps: int, progress: Callable[[str], None] | None
            ) -> tuple[list[int], list[tuple[str, ...]], list[Step], list[float], list[float],
                       list[tuple[str, float]], list[int]]:
    """Greedy forward selection; returns chosen atom indices, their alternatives, the steps, the
    ΔBIC and p-value at entry of each chosen atom, its rival: the best other candidate whose
    held-out correction has cosine ≥ :data:`RIVAL_COSINE` with its own, as ``(label, margin)``,
    ``margin = 1 − gain_rival / gain`` (``("", 1.0)`` without a rival), and the *nuisance*
    atoms: a delay that explains most but lies within the time-stamp resolution (a logger's
    stamping, :mod:`consistid.diagnosis.effects.delay`) is kept in every later fit, so that no
    effect (viscous friction, whose torque shares the shift's ``q̇`` terms) stands in for it,
    and is never a finding."""
    nv = prob.w.size
    n_tr_j, n_ho_j = prob.train.n / prob.tau_corr, prob.held.n / prob.tau_corr
    nominal_ho = prob.held.s * prob.w
    chosen: list[int] = []
    nuisance: list[int] = []
    alternatives: list[tuple[str, ...]] = []
    bics: list[float] = []
    pvals: list[float] = []
    rivals: list[tuple[str, float]] = []
    steps: list[Step] = []
    cols, theta, rank = prob.fit(chosen)
    sse_tr = prob.w * prob.train.sse(cols, theta)
    sse_ho = prob.w * prob.held.sse(cols, theta)
    full_p = sum(s.size for s in prob.slices)
    g_ho = np.einsum("j,jpq->pq", prob.w, prob.held.G)
    for _ in range(max_steps):
        scores = []
        references: dict[tuple[int, ...], tuple] = {}
        for i, atom in enumerate(prob.atoms):
            if i in chosen:
                continue
            # An atom with companions is scored against the chosen atoms plus its companions
            # not yet chosen (:mod:`consistid.diagnosis.interaction`), others against the chosen.
            ref = companions(prob.atoms, chosen, i)
            if ref and tuple(ref) not in references:
                c0, th0, r0 = prob.fit(chosen + ref)
                references[tuple(ref)] = (c0, th0, r0, prob.w * prob.train.sse(c0, th0),
                                          prob.w * prob.held.sse(c0, th0))
            c0, th0, r0, tr0, ho0 = (references[tuple(ref)] if ref
                                     else (cols, theta, rank, sse_tr, sse_ho))
            c2, th2, r2 = prob.fit(chosen + ref + [i])
            scale = np.ones(nv)
            if ref:
                # beside its companions, weighted by what each joint has left
                # (:func:`~consistid.diagnosis.interaction.residual_scale`), the reference too
                scale = residual_scale(prob.w * prob.train.sse(c2, th2), prob.train.n)
                c0, th0, r0 = prob.fit(chosen + ref, prob.w * scale)
                tr0, ho0 = prob.w * prob.train.sse(c0, th0), prob.w * prob.held.sse(c0, th0)
                c2, th2, r2 = prob.fit(chosen + ref + [i], prob.w * scale)
            k = r2 - r0
            if k <= 0:
                continue
            tr2 = prob.w * prob.train.sse(c2, th2)
            ho2 = prob.w * prob.held.sse(c2, th2)
            u = np.zeros(full_p)
            u[c2] = th2
            u[c0] -= th0
            own = th2[-atom.n_parameters:]
            # ranked by the held-out gain in the floors' units, one unit for every candidate
            # (each rigid atom's weights are its own); tested in its weights (verdict below)
            scores.append((i, float(ho0.sum() - ho2.sum()), k, tr2, ho2, u, own,
                           (c2, th2, r2), tr0, ho0, bool(ref), scale))
        if not scores:
            break
        scores.sort(key=lambda s: -s[1])

        def verdict(s: tuple) -> tuple[str, float, float]:
            # Tests on the rows the atom acts on (its joint, or all): another joint's residual
            # says nothing about this atom's significance.
            i, gain, k, tr2, ho2 = s[:5]
            tr0, ho0 = s[8], s[9]        # the fit it is compared with (companions included)
            scale = s[11][_rows_of(prob.atoms[i], nv)]     # its rows' weights (1: the floor's)
            atom = prob.atoms[i]
            rows = _rows_of(atom, nv)
            n_tr, n_ho = float(n_tr_j[rows].sum()), float(n_ho_j[rows].sum())
            before_tr, after_tr = float(scale @ tr0[rows]), float(scale @ tr2[rows])
            dbic = n_tr * np.log(after_tr / before_tr) + k * np.log(n_tr)
            gain_rows = float(scale @ (ho0[rows] - ho2[rows]))
            f = (gain_rows / k) / (float(scale @ ho2[rows]) / n_ho)
            p = float(scipy.stats.f.sf(f, k, n_ho)) if gain_rows > 0 else 1.0
            # relevance: the atom's joint, or (arm-wide atoms) the joint it helps most, must
            # lose min_gain of its nominal held-out sum of squares, or min_excess of what is
            # left there above the noise floor (on a joint still above the flag's ratio)
            reduced = ho0[rows] - ho2[rows]
            per_joint = reduced / np.maximum(nominal_ho[rows], 1e-300)
            relevance = float(per_joint.max())
            excess = ho0[rows] - prob.held.n
            above = ho0[rows] > REMAINDER_RATIO ** 2 * prob.held.n
            if i in prob.moving:           # a hump: what is left where it can explain it
                grams, n_moving = prob.moving[i]      # (no companions: c0 is the chosen fit)
                left = prob.w[rows] * grams.sse(cols, theta)
                excess = left - n_moving
                above = left > REMAINDER_RATIO ** 2 * n_moving
            of_excess = float(np.max(np.where(above & (excess > 0),
                                              reduced / np.maximum(excess, 1e-300), 0.0)))
            if gain <= 0:
                return "does not reduce the held-out residual", dbic, p
            unphysical = REGISTRY[atom.effect].unphysical(atom, s[6], prob.resolution)
            if unphysical is not None:
                return unphysical, dbic, p
            if dbic >= 0:
                return f"ΔBIC {dbic:.3g} ≥ 0", dbic, p
            if p >= alpha:
                return f"held-out F-test p = {p:.2g} ≥ {alpha:g}", dbic, p
            if relevance < min_gain and of_excess < min_excess:
                return (f"held-out gain {relevance:.2%} of the nominal residual "
                        f"{'' if len(rows) == 1 else 'on its best joint '}< min_gain "
                        f"{min_gain:.0%} and {of_excess:.0%} of what is left above the noise "
                        f"floor < min_excess {min_excess:.0%}", dbic, p)
            return "accepted", dbic, p

        verdicts = {}
        passing = None
        for sc in scores:
            verdicts[sc[0]] = verdict(sc)
            if verdicts[sc[0]][0] == "accepted":
                passing = sc
                break
        table = _cand_table(prob, scores, joint_names)
        best = scores[0]
        if not nuisance and best[1] > 0 and verdicts[best[0]][0] != "accepted" \
                and REGISTRY[prob.atoms[best[0]].effect].stamping(best[6], prob.resolution):
            # The largest gain is a shift within the time-stamp resolution: the logger's
            # stamping, not an effect. Kept in every fit from now on (so that no effect stands
            # in for it), never reported as a finding.
            nuisance.append(best[0])
            chosen.append(best[0])
            steps.append(Step(prob.atoms[best[0]].label(joint_names), best[1],
                              float(verdicts[best[0]][1]), verdicts[best[0]][2], False,
                              "kept as the logger's time stamping (not an effect): "
                              + verdicts[best[0]][0], table))
            if progress is not None:
                progress(f"step {len(steps)}: {steps[-1].reason}")
            (cols, theta, rank), sse_tr, sse_ho = best[7], best[3], best[4]
            continue
        if passing is None:
            best = scores[0]
            steps.append(Step(prob.atoms[best[0]].label(joint_names), best[1],
                              float(verdicts[best[0]][1]), verdicts[best[0]][2], False,
                              f"stop: no candidate passes (best: {verdicts[best[0]][0]})",
                              table))
            if progress is not None:
                progress(f"step {len(steps)}: stop — {steps[-1].reason}")
            break
        # Indistinguishable candidates: similar held-out gain, collinear corrections, and none
        # leaving a joint above the flag's ratio with more than DISTINCT_LEFT × the held-out
        # residual the best leaves there; the one with the fewest parameters (that passes) is
        # kept, the others are its alternatives. (Gains alone are measured against different
        # fits when an atom has companions: a 2-parameter stand-in leaving 385 × the floor
        # tied with the inertia that leaves 1.5 ×.)
        ub = passing[5]
        nb = float(ub @ g_ho @ ub)
        group = [passing]
        flag = REMAINDER_RATIO ** 2 * prob.held.n
        for sc in scores:
            if sc is passing or abs(sc[1] - passing[1]) > tie * passing[1] \
                    or np.any((sc[4] > flag) & (sc[4] > DISTINCT_LEFT * passing[4])):
                continue
            ns = float(sc[5] @ g_ho @ sc[5])
            if nb > 0 and ns > 0 and (sc[5] @ g_ho @ ub) / np.sqrt(nb * ns) >= 0.9:
                group.append(sc)
        for sc in group:
            if sc[0] not in verdicts:
                verdicts[sc[0]] = verdict(sc)
        eligible = [sc for sc in group if verdicts[sc[0]][0] == "accepted"]
        pick = min(eligible, key=lambda sc: (sc[2], -sc[1]))
        i, gain = pick[0], pick[1]
        reason, dbic, p = verdicts[i]
        atom = prob.atoms[i]
        steps.append(Step(atom.label(joint_names), gain, float(dbic), p, True, reason, table))
        if progress is not None:
            progress(f"step {len(steps)}: {atom.label(joint_names)} — {reason}")
        chosen.append(i)
        alternatives.append(tuple(prob.atoms[sc[0]].label(joint_names) for sc in group
                                  if sc[0] != i))
        bics.append(float(dbic))
        pvals.append(p)
        # Its rival: the best other candidate whose own correction (its columns times its
        # parameters, on the held-out data) points the same way — it explains the same residual.
        # (Gains in the floors' units for every candidate: a rigid body's in its residual
        # weights is smaller, and a per-joint stand-in's margin over it read wide.)
        def own(sc: tuple) -> np.ndarray:
            u = np.zeros(full_p)
            u[prob.slices[sc[0]]] = sc[6]
            return u

        up = own(pick)
        nu = float(up @ g_ho @ up)
        rival = ("", 1.0)
        for sc in scores:
            if sc[0] == i or sc[0] in [g[0] for g in group] or sc[1] <= 0:
                continue
            us = own(sc)
            ns = float(us @ g_ho @ us)
            if nu > 0 and ns > 0 and abs(us @ g_ho @ up) / np.sqrt(nu * ns) >= RIVAL_COSINE:
                rival = (prob.atoms[sc[0]].label(joint_names), 1.0 - sc[1] / gain)
                break
        rivals.append(rival)
        # The fit of chosen + [i] was made when scoring it (with its companions: made anew,
        # and every later fit weighted as it was scored).
        if pick[10]:
            prob.fit_w = prob.w * pick[11]
            cols, theta, rank = prob.fit(chosen)
            sse_tr = prob.w * prob.train.sse(cols, theta)
            sse_ho = prob.w * prob.held.sse(cols, theta)
        else:
            (cols, theta, rank), sse_tr, sse_ho = pick[7], pick[3], pick[4]
    return [i for i in chosen if i not in nuisance], alternatives, steps, bics, pvals, rivals, \
        nuisance


def _clear_of_rest(atoms: Sequence[Atom], phi_ho: np.ndarray, held: GapData
                   ) -> dict[int, tuple[_Grams, int]]:
    r"""Per Stribeck atom, the held-out Grams of its joint on the rows where it acts clear of
    rest, and their count: ``min_excess`` weighs a hump against what is left there, and the
    joint counts as above its floor when that is. Clear of rest,
    ``|q̇_j| ≥ min(v_s / 2, REST_SPEED)`` with ``sign(q̇_j)`` resolved
    (:attr:`GapData.sign_unresolved`): nearer rest the torque is set-valued (any torque within
    the friction cone; a simulator's soft friction constraint, presliding on a real joint): no
    law of ``q̇`` predicts it, and the verdict judges those samples against the cone too.
    Weighed against the whole excess, most of it the error at rest, a hump 5 × the noise on the
    UR5 or xArm7 explained 18–21 % of it and was refused. Where it acts: the rows where its
    held-out column is at least ``e⁻⁹`` of its largest (``|q̇_j| ≲ 3 v_s`` unfiltered), as an
    atom's tests are made on its joint's rows and not the arm's: a hump is a few zero
    crossings of a joint that moves fast elsewhere, and judged on all of the joint's rows
    (1.27 × its floor on the UR5, seed 6) it was refused as within the floor although it left
    twice the floor's variance where it acts. Where the plain Coulomb step leaves nothing
    there, no hump passes."""
    out = {}
    offsets = np.cumsum([0] + [a.n_parameters for a in atoms])
    for i, atom in enumerate(atoms):
        if atom.effect != "stribeck" or atom.joint is None:
            continue
        j = atom.joint
        rest = min(0.5 * (atom.setting or 0.0), REST_SPEED)
        column = np.abs(phi_ho[:, j, offsets[i]:offsets[i + 1]]).max(axis=1)
        keep = ((np.abs(held.dataset.dq[:, j]) >= rest) & ~held.sign_unresolved[:, j]
                & (column >= np.exp(-9.0) * column.max(initial=0.0)))
        g = _Grams.build(phi_ho[keep][:, [j], :], held.residual[keep][:, [j]])
        out[i] = (g, int(keep.sum()))
    return out


def _cand_table(prob: _Problem, scores: list, joint_names: list[str], top: int = 8
                ) -> tuple[tuple[str, float, int], ...]:
    return tuple((prob.atoms[s[0]].label(joint_names), s[1], s[2]) for s in scores[:top])


# --------------------------------------------------------------------------------- refit
def _coloured_covariance(prob: _Problem, cols: np.ndarray, pinv: np.ndarray, s2: float
                         ) -> np.ndarray:
    r"""Covariance of the weighted least-squares parameters when each joint's residual is
    coloured with integrated autocorrelation time ``τ_j`` (samples).

    .. math::

        \operatorname{Cov}(\hat θ) = s^2\, G^{+} \Big(\sum_j τ_j\, w_j\, Φ_j^\top Φ_j\Big) G^{+},
        \qquad G = \sum_j w_j\, Φ_j^\top Φ_j,

    ``s²`` the weighted residual variance. It is the sandwich covariance of least squares with
    serially correlated errors, ``G⁻¹ (Σ_j w_j² Φ_jᵀ Cov(e_j) Φ_j) G⁻¹``, with
    ``Φ_jᵀ Cov(e_j) Φ_j ≈ σ_j² τ_j Φ_jᵀΦ_j`` for columns that vary slowly against the residual's
    correlation time (the variance of a mean of ``N`` correlated samples is ``τ σ²/N``: each
    joint's ``N`` rows count as ``N_eff = N / τ_j``; Bayley & Hammersley, "The 'effective' number
    of independent observations in an autocorrelated time series", J. R. Stat. Soc. Suppl. 8(2),
    184–197, 1946; the general form with a lag-window estimate is Newey & West, Econometrica
    55(3), 703–708, 1987). Parameters of one joint are thus ``√τ_j`` times less certain than
    independent rows say, arm-wide ones by a mixture of the joints' ``τ``; ``τ`` is the one the
    selection counts ``N_eff`` with
    (:func:`consistid.identification.statistics.autocorrelation_time` of the
    residual that no candidate explains). With ``τ_j = 1`` this is ``s² G⁺``
    (:func:`consistid.identification.statistics.coloured_covariance` with ``C = s² G⁺``,
    ``w_j / s²``).
    """
    tau = np.broadcast_to(np.asarray(prob.tau_corr, dtype=float), prob.w.shape)
    return coloured_covariance(s2 * pinv, prob.train.G[:, cols][:, :, cols],
                               prob.w / s2 if s2 > 0 else prob.w, tau)


def _refit(prob: _Problem, chosen: Sequence[int], train: GapData, model: RobotModel,
           nominal: np.ndarray, nominal_extra, inertia_solver: str,
           ) -> tuple[GapModel, list[np.ndarray], list[str]]:
    """Fit the chosen atoms on the training data: linear least squares, then the delays exactly
    (``τ_nom(t − d)``) and, when ``inertia_solver == "sdp"``, the rigid body by the consistent
    SDP near the nominal, alternating with the linear atoms (block coordinate descent).

    Returns the fitted model, the standard deviation of each atom's parameters (coloured
    residual counted, :func:`_coloured_covariance`; the SDP inertia's base-parameter deviations
    widened by the same per-parameter factor as the least-squares ones), and notes.
    """
    notes: list[str] = []
    atoms = [prob.atoms[i] for i in chosen]
    cols = prob.cols(chosen)
    theta, rank, pinv = _solve(*prob.train.weighted(prob.w, cols))
    sse = float(prob.w @ prob.train.sse(cols, theta))
    dof = max(prob.train.n * prob.w.size - rank, 1)
    cov = _coloured_covariance(prob, cols, pinv, sse / dof)
    std_all = np.sqrt(np.clip(np.diag(cov), 0, None))
    # What the coloured residual adds to each standard deviation, for the SDP inertia below
    # (whose own base-parameter deviations count rows as independent).
    white = np.sqrt(np.clip(np.diag(pinv) * sse / dof, 0, None))
    inflation_all = np.where(white > 0, std_all / np.where(white > 0, white, 1.0), 1.0)
    thetas, stds, inflation, o = [], [], [], 0
    for a in atoms:
        thetas.append(theta[o:o + a.n_parameters])
        stds.append(std_all[o:o + a.n_parameters])
        inflation.append(inflation_all[o:o + a.n_parameters])
        o += a.n_parameters
    fit = GapModel(model, prob.library, nominal, tuple(atoms), tuple(thetas), {}, None,
                   nominal_extra)
    delay_idx = [k for k, a in enumerate(atoms) if a.effect == "delay"]
    inertia_idx = [k for k, a in enumerate(atoms) if a.effect == "inertia"]
    if not delay_idx and not (inertia_idx and inertia_solver == "sdp"):
        return fit, stds, notes
    phi = [prob.library.columns(a, train) for a in atoms]
    w = prob.w
    sdp = bool(inertia_idx) and inertia_solver == "sdp"
    linear = [k for k in range(len(atoms)) if k not in delay_idx
              and not (sdp and k in inertia_idx)]
    delays = {k: float(thetas[k][0]) for k in delay_idx}
    inertial = None
    r = train.residual

    def contribution(k: int) -> np.ndarray:
        if k in inertia_idx and inertial is not None:
            return train.rigid @ (inertial - nominal)
        return phi[k] @ thetas[k]

    def others(skip: Sequence[int]) -> np.ndarray:
        """Every correction but ``skip``'s; the delays shift the others' torque too."""
        plain = sum((contribution(m) for m in range(len(atoms))
                     if m not in skip and m not in delay_idx), np.zeros_like(r))
        return plain + sum((exact_delay(train, atoms[m], delays[m], plain)
                            for m in delay_idx if m not in skip), np.zeros_like(r))

    if linear:
        a_mat = np.concatenate([phi[k] for k in linear], axis=2)
    # Block coordinate descent started from the joint least-squares fit (where the linearised
    # delay and the unconstrained inertia already sit near the answer).
    for _ in range(3):
        for k in delay_idx:
            rest = others([k])
            target = r - rest
            d0 = delays[k]
            span = max(3 * abs(d0), 5 * float(np.median(np.diff(train.dataset.t))))

            def cost(d: float, k: int = k, target: np.ndarray = target,
                     rest: np.ndarray = rest) -> float:
                return float(w @ np.sum((target - exact_delay(train, atoms[k], d, rest)) ** 2,
                                        axis=0))

            res = scipy.optimize.minimize_scalar(cost, bounds=(d0 - span, d0 + span),
                                                 method="bounded", options={"xatol": 1e-6})
            delays[k] = float(res.x)
        if sdp:
            inertial, note, base_std = _sdp_inertia(model, train, nominal, others(inertia_idx))
            stds[inertia_idx[0]] = base_std * inflation[inertia_idx[0]]
            if note not in notes:
                notes.append(note)
        if linear:
            # The delayed joints see the linear atoms' columns delayed too.
            shifted = a_mat
            for m in delay_idx:
                shifted = _delayed(train, shifted, delays[m], atoms[m].joint)
            gl = np.einsum("j,njp,njq->pq", w, shifted, shifted)
            cl = np.einsum("j,njp,nj->p", w, shifted, r - others(linear))
            th, _, _ = _solve(gl, cl)
            o = 0
            for k in linear:
                thetas[k] = th[o:o + atoms[k].n_parameters]
                o += atoms[k].n_parameters
    for k in delay_idx:
        thetas[k] = np.array([delays[k]])
    fit = GapModel(model, prob.library, nominal, tuple(atoms), tuple(thetas),
                   {k: delays[k] for k in delay_idx}, inertial, nominal_extra)
    return fit, stds, notes


def _sdp_inertia(model: RobotModel, train: GapData, nominal: np.ndarray, others: np.ndarray
                 ) -> tuple[np.ndarray, str, np.ndarray]:
    """Consistent rigid-body parameters near the nominal (log-det prior) fitted to the measured
    torque minus the other effects' corrections; returns them, a note, and the standard
    deviations of the base parameters."""
    from ..identification.identify import identify

    corrected = train.dataset.with_torque(train.tau - others
                                          - (0 if train.nominal_extra is None
                                             else train.nominal_extra))
    # The log-det prior needs every nominal body realisable (J ≻ 0 to working precision,
    # robot.inertia.is_degenerate). A nominal that is not (a massless, flat or non-physical URDF
    # link) is no prior at all: a Euclidean pull towards it held
    # the fitted link near zero mass and left most of the gap unexplained. Then the data and
    # the consistency constraints alone decide (the torques depend on the base parameters only).
    bad = degenerate_bodies(nominal, model.body_names)
    prior = None if bad else "logdet"
    with warnings.catch_warnings():
        # the refit's torques have the other effects (dry friction among them) taken out; what
        # it leaves at standstill is judged by the remainder, not by identify's own note
        warnings.simplefilter("ignore", ModelMisfitWarning)
        # at the chain's torque filter, as every other effect's columns are judged
        res = identify(model.with_parameters(nominal), corrected, method="sdp", friction=None,
                       prior=prior, parallel_filter=False)
    if bad:
        how = (f"without a prior (the nominal {', '.join(bad)} "
               f"{'is' if len(bad) == 1 else 'are'} not realisable to working precision: no prior "
               "around it means anything; the data and the consistency constraints decide)")
    else:
        how = "with a log-det prior around the nominal parameters"
    return res.inertial_parameters, (f"inertia re-identified by the consistent SDP "
                                     f"({res.solver.name}: {res.solver.status}) {how}"), \
        res.base_std


def _tuned_atoms(library: EffectLibrary, train: GapData, floor: np.ndarray
                 ) -> tuple[list[Atom], np.ndarray]:
    """All candidate atoms with their nonlinear settings chosen on the training data, and their
    training columns ``(N, nv, P)``.

    The settings are tuned against the residual of the *saturated* fit (every linear candidate
    at once): a *tuned* effect's setting (the Coulomb smoothing speed) on that residual plus what
    the tuned atoms of its joint explain in it, a *searched* effect's atoms (ripple orders) on
    that residual; so other effects do not masquerade as them. Searched effects' atoms come
    last.
    """
    model = library.model
    plain = [e for e in library.effects if not REGISTRY[e].searched]
    searched = [e for e in library.effects if REGISTRY[e].searched]
    atoms = EffectLibrary(model, tuple(plain), base=library.base).atoms()
    if not atoms:
        return [], np.zeros((train.n, model.nv, 0))
    phi_tr = library.matrix(atoms, train)
    if not searched and not any(REGISTRY[e].tuned for e in plain):
        return atoms, phi_tr
    g = _Grams.build(phi_tr, train.residual)
    theta, _, _ = _solve(*g.weighted(1.0 / floor ** 2, np.arange(phi_tr.shape[2])))
    rest = train.residual - phi_tr @ theta
    offsets = np.cumsum([0] + [a.n_parameters for a in atoms])
    # What the tuned atoms of each joint explain together in the saturated fit (e.g. a Coulomb
    # step and a Stribeck hump share the step at q̇ = 0): each is tuned on the rest plus that.
    tuned_part: dict[int, np.ndarray] = {}
    for i, a in enumerate(atoms):
        if REGISTRY[a.effect].tuned and a.joint is not None:
            own = theta[offsets[i]:offsets[i + 1]]
            tuned_part[a.joint] = (tuned_part.get(a.joint, 0.0)
                                   + phi_tr[:, a.joint, offsets[i]:offsets[i + 1]] @ own)
    for i, a in enumerate(atoms):
        if REGISTRY[a.effect].tuned and a.joint is not None:
            atoms[i] = library.tune(train, rest[:, a.joint] + tuned_part[a.joint], a)
    if searched:
        atoms += EffectLibrary(model, tuple(searched), base=library.base,
                               ripple_orders=library.ripple_orders).atoms(train, rest)
    return atoms, library.matrix(atoms, train)


# --------------------------------------------------------------------------------- main
def diagnose(model: RobotModel, dataset: Dataset | Sequence[Dataset], nominal=None,
             held_out: Dataset | Sequence[Dataset] | None = None,
             effects: Sequence[str] = EFFECT_NAMES, sigma: float | Sequence[float] | None = None,
             *, torque_resolution: float | Sequence[float] | None = None, alpha: float = 1e-3,
             min_gain: float = 0.01, min_excess: float = 0.25, tie: float = 0.05,
             max_steps: int = 20, split: float = 0.7, inertia_solver: str = "sdp",
             progress: bool | None | Callable[[str], None] = None) -> Diagnosis:
    """Diagnose the gap between a nominal (simulator) model and measured torques.

    Parameters
    ----------
    model : the robot (kinematics, joint order).
    dataset : measured data (several recordings are stacked as segments).
    nominal : the simulator's parameters: ``None`` (the model's URDF inertias), a standard
        inertial vector (10 per body), a :class:`RobotModel`, or an
        :class:`~consistid.IdentificationResult` (its rigid body and friction are the nominal).
    held_out : data to score on (ideally a different trajectory); default the last
        ``1 − split`` of each recording of ``dataset``.
    effects : candidate effect names (default all of the registry,
        :data:`~consistid.diagnosis.effects.EFFECT_NAMES`).
    sigma : torque noise standard deviation (N·m), scalar or per joint; default estimated
        without the candidates (:func:`consistid.diagnosis.noise.estimate_noise_floor`: from the
        repetition of a periodic excitation, else from the residual spectrum above the motion
        band); the report says which.
    torque_resolution : the torque sensor's resolution (N·m per count), scalar or per joint: a
        floor of ``Δ/√12`` (the larger of it and ``sigma`` when both are given).
    alpha : level of the held-out F-test.
    min_gain : smallest held-out reduction, as a fraction of the nominal residual's sum of
        squares of the atom's joint (arm-wide atoms: of the joint it reduces most), for the atom
        to be selected, unless it reaches ``min_excess``.
    min_excess : or the smallest held-out reduction as a fraction of what is left above the
        noise floor on the atom's joint (``SSE_ho,j − N_ho σ_j²``; the joint it reduces most for
        an arm-wide atom), on a joint whose held-out RMS is still above the remainder's flag
        (``REMAINDER_RATIO`` × the floor): the selection stops against the floor, not against
        a nominal gap that may be hundreds of times the noise.
    tie : relative held-out gain within which collinear candidates count as indistinguishable.
    max_steps : most atoms selected.
    split : training fraction of each recording when ``held_out`` is ``None``.
    inertia_solver : how the selected ``inertia`` effect is finally fitted: ``"sdp"``
        (:mod:`consistid.identification.sdp`: every body physically consistent, log-det prior
        around the
        nominal; Euclidean when a nominal body is not realisable) or ``"ls"`` (least squares on
        the base parameters). The selection itself always scores inertia by least squares.
    progress : ``None`` (default: a progress bar over the selection steps when stderr is a
        terminal), ``True``/``False`` (always/never; :mod:`consistid.progress`), or a callable
        called with a line of text after each selection step.

    Returns
    -------
    Diagnosis
    """
    check_option("inertia_solver", inertia_solver, ("sdp", "ls"))
    alpha = check_number("alpha", alpha, 0, strict=True)
    if alpha >= 1:
        raise OptionError(f"alpha is a test level in (0, 1), got {alpha!r}")
    min_gain, tie = check_number("min_gain", min_gain, 0), check_number("tie", tie, 0)
    min_excess = check_number("min_excess", min_excess, 0)
    max_steps = check_number("max_steps", max_steps, 0, integer=True)
    effects = (effects,) if isinstance(effects, str) else effects
    if effects is None or hasattr(effects, "__len__") and not len(effects):
        raise OptionError(f"effects={effects!r} names no effect to test; give some of "
                          f"{list(EFFECT_NAMES)} (the default is all of them)")
    require_model(model)
    dataset = as_dataset(dataset)
    dataset.check_joints(model.nv, model.joint_names)
    check_for_identification(dataset, model.joint_names,           # before any numerics
                             (model.limits.lower, model.limits.upper, model.limits.effort))
    if held_out is None:
        train_ds, held_ds = dataset.split(split)
        held_source = f"last {1 - split:.0%} of each recording (time split)"
    else:
        train_ds, held_ds = dataset, as_dataset(held_out, "held_out")
        held_ds.check_joints(model.nv, model.joint_names)
        held_source = f"given ({held_ds.n_samples} samples, {held_ds.duration:.1f} s)"
    pi0, extra_fn = _resolve_nominal(model, nominal)

    def gap_data(ds: Dataset) -> GapData:
        return GapData(model, ds, pi0, extra_fn(ds) if extra_fn is not None else None)

    train, held = gap_data(train_ds), gap_data(held_ds)
    everything = GapData.concatenate([train, held])
    spectra = residual_spectra(everything.dataset, everything.residual, everything.tau_nom)
    given = None if sigma is None else _sigma(sigma, model.nv)
    resolution = (None if torque_resolution is None
                  else _sigma(torque_resolution, model.nv, "torque_resolution"))
    # the spectrum through the torques' recorded low-pass: on all recordings when they share
    # one, else on the held-out ones (what a spectrum floor is judged on)
    on = (held if everything.dataset.torque_filter is None
          and held.dataset.torque_filter is not None else everything)
    # the level a repetition floor is checked against: that spectrum when it is of all
    # recordings (the training ones among them, through the same filter), else the training
    # recordings' own
    noise = estimate_noise_floor(everything.dataset, everything.tau, everything.residual,
                                 everything.tau_nom, given, resolution,
                                 spectrum_on=(on.dataset, on.residual, on.tau_nom),
                                 repeating=None if on is everything
                                 else (train.dataset, train.residual, train.tau_nom))
    floor, noise_source = noise.sigma.copy(), noise.description
    library = EffectLibrary(model, tuple(effects))

    atoms, phi_tr = _tuned_atoms(library, train, floor)
    phi_ho = library.matrix(atoms, held)
    slices, o = [], 0
    for a in atoms:
        slices.append(np.arange(o, o + a.n_parameters))
        o += a.n_parameters
    prob = _Problem(library, atoms, slices, _Grams.build(phi_tr, train.residual),
                    _Grams.build(phi_ho, held.residual), 1.0 / floor ** 2)
    prob.resolution = float(np.median(np.diff(train.dataset.t)))
    prob.moving = _clear_of_rest(atoms, phi_ho, held)
    everything_cols, theta_all, _ = prob.fit(list(range(len(atoms))))
    floor, noise_source = _floor_without_tails(floor, noise, noise_source, on, train, held,
                                               phi_tr, phi_ho, everything_cols, theta_all)
    prob.w = 1.0 / floor ** 2
    prob.prior = _rigid_prior(prob, pi0)
    everything_cols, theta_all, _ = prob.fit(list(range(len(atoms))))
    library_floor = np.sqrt(prob.held.sse(everything_cols, theta_all) / held.n)
    # Rows are not independent when the residual is coloured (filtered noise): count effective
    # samples with the autocorrelation time of what no candidate explains.
    theta_full = np.zeros(phi_tr.shape[2])          # every column (no copy of phi_tr)
    theta_full[everything_cols] = theta_all
    saturated = train.residual - phi_tr @ theta_full
    prob.tau_corr = autocorrelation_time(train.dataset, saturated)
    names = model.joint_names
    callback = progress if callable(progress) and not isinstance(progress, bool) else None
    with Progress(False if callback else progress, None, "diagnosis: selecting effects",
                  "step") as bar:
        def tell(line: str) -> None:
            bar.step(line)
            if callback is not None:
                callback(line)

        chosen, alts, steps, bics, pvals, rivals, nuisance = _select(
            prob, names, alpha, min_gain, min_excess, tie, max_steps, tell)

    notes: list[str] = []
    chosen, alts, bics, pvals, rivals = _prune_nested(prob, chosen, alts, bics, pvals, rivals,
                                                      names, notes)
    if inertia_solver == "sdp":
        chosen = _nested_by_final_fit(prob, nuisance, chosen, train, held, model, pi0, extra_fn,
                                      names, notes, alpha)
    # Group the atoms by effect and rank the groups by how much the held-out residual grows
    # when the group is removed from all the selected atoms; add them one by one in that order.
    groups = list(dict.fromkeys(prob.atoms[i].effect for i in chosen))
    cols_all, th_all, _ = prob.fit(nuisance + chosen)
    sse_all = float(prob.w @ prob.held.sse(cols_all, th_all))
    importance = {}
    for g in groups:
        rest = [i for i in chosen if prob.atoms[i].effect != g]
        c, th, _ = prob.fit(nuisance + rest)
        importance[g] = float(prob.w @ prob.held.sse(c, th)) - sse_all
    order = sorted(groups, key=lambda g: -importance[g])
    rms_nominal = np.sqrt(np.mean(held.residual ** 2, axis=0))
    before = rms_nominal
    findings: list[EffectFinding] = []
    fit = GapModel(model, library, pi0, (), (), {}, None, extra_fn)
    cumulative: list[int] = list(nuisance)
    final_stds: list[np.ndarray] = []
    if nuisance:
        # The logger's time stamping, fitted exactly before any effect and never reported.
        fit, final_stds, _ = _refit(prob, nuisance, train, model, pi0, extra_fn, inertia_solver)
        before = np.sqrt(np.mean((held.residual - fit.correction(held)) ** 2, axis=0))
        shift = 1e3 * float(fit.theta[0][0])
        notes.append(f"the torques {'lag' if shift > 0 else 'lead'} the positions by "
                     f"{abs(shift):.3g} ms, within the time-stamp resolution (half a "
                     f"{1e3 * prob.resolution:.3g} ms sample): taken as the logger's stamping "
                     "(one that averages each interval and stamps its "
                     f"{'end' if shift > 0 else 'start'}), kept in the fit, not an effect; "
                     f"load with timestamp=\"{'end' if shift > 0 else 'start'}\" to correct it "
                     "at the source")
    held_floor = _held_floor(floor, noise, train, held, on is held)
    for name in order:
        members = [k for k, i in enumerate(chosen) if prob.atoms[i].effect == name]
        while True:
            trial = cumulative + [chosen[k] for k in members]
            trial_fit, stds, fit_notes = _refit(prob, trial, train, model, pi0, extra_fn,
                                                inertia_solver)
            after = np.sqrt(np.mean((held.residual - trial_fit.correction(held)) ** 2,
                                    axis=0))
            worse = _worsened(before, after, held_floor)
            # A per-joint atom that makes its own joint worse on the held-out data is refused
            # (the rest of its effect is refitted without it); one whose effect interacts with
            # an effect still to come (friction beside a later inertia) is judged in the model
            # holding every selected atom instead (:func:`_worse_in_full`).
            pending = {c for g in order[order.index(name) + 1:] for c in REGISTRY[g].companions}
            judged = {k: (_worse_in_full(prob, nuisance + chosen, chosen[k], held_floor)
                          if prob.atoms[chosen[k]].effect in pending else (before, after))
                      for k in members if prob.atoms[chosen[k]].joint is not None}
            dropped = [k for k, (b, a) in judged.items()
                       if _worsened(b, a, held_floor)[prob.atoms[chosen[k]].joint]]
            if not dropped or len(dropped) == len(members):
                break
            notes += [_worse_note([prob.atoms[chosen[k]]], *judged[k], names) + ": refused"
                      for k in dropped]
            members = [k for k in members if k not in dropped]
        labels = ", ".join(prob.atoms[chosen[k]].label(names) for k in members)
        verb = "was" if len(members) == 1 else "were"
        # The final fit (exact delay, consistent inertia) may break a sign rule the linear
        # selection kept: such a finding is rejected, never reported.
        broken = [why for k, (atom, th) in enumerate(zip(trial_fit.atoms, trial_fit.theta))
                  if k >= len(cumulative)
                  for why in [REGISTRY[atom.effect].unphysical(atom, th, prob.resolution)]
                  if why is not None]
        if broken:
            notes.append(f"{labels} {verb} selected but rejected after the final fit: "
                         + "; ".join(broken))
            continue
        if dropped:
            notes.append(_worse_note([prob.atoms[chosen[k]] for k in dropped], before, after,
                                     names) + ": left out")
            continue
        shrink = 1.0 - after / np.where(before > 0, before, 1.0)
        total = 1.0 - (np.linalg.norm(after / held_floor)
                       / max(np.linalg.norm(before / held_floor), 1e-300))
        if total <= 0:
            # Selected with the least-squares inertia, it no longer generalises once the final
            # fit (exact delay, consistent inertia) is made: say so and leave it out.
            notes.append(f"{labels} {verb} selected but do{'es' if verb == 'was' else ''} not "
                         f"reduce the held-out residual in the final fit (shrink "
                         f"{100 * total:.1f} %): left out")
            continue
        cumulative, fit, final_stds = trial, trial_fit, stds
        notes += [n for n in fit_notes if n not in notes]
        atoms_here = [prob.atoms[chosen[k]] for k in members]
        if all(a.joint is not None for a in atoms_here):
            joints = tuple(names[a.joint] for a in atoms_here)
            scope = "joint"
        else:
            scope = "arm"
            joints = tuple(names[j] for j in np.flatnonzero(shrink >= JOINT_SHRINK_FLOOR))
        if worse.any():
            notes.append(_worse_note(atoms_here, before, after, names, worse)
                         + ": kept for what it explains elsewhere, confidence low")
        rival = min((rivals[k] for k in members), key=lambda r: r[1])
        findings.append(EffectFinding(
            name=name, joints=joints, scope=scope, rms_before=before, rms_after=after,
            shrink=shrink, total_shrink=float(total), parameters=(),
            alternatives=tuple(sorted({x for k in members for x in alts[k]})),
            n_parameters=int(sum(a.n_parameters for a in atoms_here)),
            delta_bic=float(sum(bics[k] for k in members)),
            p_value=float(max(pvals[k] for k in members)), signature=SIGNATURES[name],
            runner_up=rival[0], margin=float(rival[1]),
            worsened=tuple(names[j] for j in np.flatnonzero(worse))))
        before = after
    notes += _asymmetric_friction(fit, names)
    notes += _contained(prob, cumulative, names)
    if inertia_solver == "ls" and "inertia" in order:
        notes.append("inertia re-identified by least squares on base parameters "
                     "(inertia_solver='ls': not checked for physical consistency)")
    rms_final = before
    spectral = np.array([m == "spectrum" for m in noise.method])
    if fit.atoms and spectral.any():
        # The nominal residual's high band also holds the tails of steps and spikes that the
        # effects explain (a Coulomb step has a 1/f² spectrum); estimate the level again
        # without them. Still the level above the motion band, never what the fit leaves.
        again = spectral_estimate(on.dataset, on.residual - fit.correction(on), on.tau_nom).sigma
        floor = np.where(spectral, np.minimum(floor, again), floor)
        noise_source += " (spectral level re-estimated without the selected effects' tails)"
        held_floor = _held_floor(floor, noise, train, held, on is held)
    where = gap_breakdown(everything, floor, spectra=spectra)
    # Held-out data are the judge: what the effects leave there, judged with dry friction
    # set-valued at rest, against the floor in the held-out recordings' terms. (The training
    # residual also holds what repeats with the excitation yet is no effect, such as the
    # chain's own error where its low-pass cuts into the motion, which a repetition floor,
    # noise only, never sees.)
    unknown = _unpredictable(fit, held)
    left, cone, refitted = _set_valued_friction(fit, held, held.residual - fit.correction(held),
                                                unknown, held_floor)
    findings = _with_parameters(findings, fit, final_stds, refitted, names)
    if refitted:
        notes.append(_identify_friction_note(fit, refitted, names))
    rms_left = _known_rms(left, unknown)
    remainder = analyse_remainder(held, left, held_floor,
                                  autocorrelation_time(held.dataset, left),
                                  where.band_edges, reliable=noise.reliable, source="held-out",
                                  cone=cone, unknown=unknown,
                                  tried=bool(library.effects) and max_steps > 0,
                                  refused=_refused_by_min_gain(steps), held_out=rms_left,
                                  held_floor=held_floor)
    named = set(remainder.flagged) | set(remainder.undetermined)
    findings = [replace(f, unexplained=tuple(j for j in f.joints if j in named))
                for f in findings]
    if not noise.reliable.all():
        unseen = ("the noise floor cannot be seen on "
                  + ", ".join(names[j] for j in np.flatnonzero(~noise.reliable))
                  + " (torques filtered below the motion band and no repetition of the "
                  "excitation): pass sigma for a trustworthy remainder verdict")
        notes.append(unseen)
        warnings.warn(f"diagnose: {unseen}; until then the verdict there is 'undetermined' and "
                      "the effects' significance rests on a floor that may be far too low",
                      DataQualityWarning, stacklevel=2)
    return Diagnosis(model.name, tuple(names), tuple(findings), where, floor, noise_source,
                     rms_nominal, rms_final, library_floor, held_source, tuple(steps), fit,
                     tuple(notes), remainder, noise, rms_left, held_floor)


def _with_parameters(findings: list[EffectFinding], fit: GapModel, stds: list[np.ndarray],
                     refitted: dict[int, tuple[float, float, str, bool]], names: list[str]
                     ) -> list[EffectFinding]:
    """``findings`` with their parameters from the final fit (all effects together); a friction
    atom whose joint's friction law was refitted set-valued on the held-out data (``refitted``:
    atom index → value, std, how, whether the verdict judges that fit;
    :mod:`consistid.diagnosis.friction_law`) reports that refit's value and σ, the
    point-valued fit's beside it in its note: one friction fit per joint, the one the verdict
    judges where it judges one."""
    by_effect: dict[str, list[EffectParameter]] = {}
    for i, (atom, th, sd) in enumerate(zip(fit.atoms, fit.theta, stds)):
        joint = names[atom.joint] if atom.joint is not None else None
        effect = REGISTRY[atom.effect]
        if i in refitted:
            point = effect.parameters(fit.library, atom, th, sd, joint, fit)[0]
            value, std, how, verdict = refitted[i]
            # the law as refitted: through the chain's own low-pass (``how`` says which)
            param = effect.parameters(fit.library, replace(atom, cutoff=np.inf),
                                      np.array([value]), np.array([std]), joint, fit)[0]
            note = ("set-valued refit of the joint's friction law on the held-out data (held "
                    "torques within the friction cone at rest)"
                    f"{', as the verdict judges' if verdict else ''}; {how}; "
                    f"point-valued fit {point.value:.4g} ± {point.std:.2g}")
            params = [replace(param, note="; ".join(x for x in (param.note, note) if x))]
        else:
            params = effect.parameters(fit.library, atom, th, sd, joint, fit)
        by_effect.setdefault(atom.effect, []).extend(params)
    return [replace(f, parameters=tuple(by_effect.get(f.name, ()))) for f in findings]


def _identify_friction_note(fit: GapModel, refitted: dict[int, tuple[float, float, str, bool]],
                            names: list[str]) -> str:
    """One line on why ``identify``'s friction differs from the set-valued refit reported."""
    joints = ", ".join(dict.fromkeys(names[fit.atoms[i].joint] for i in sorted(refitted)))
    return (f"friction on {joints} is the set-valued refit of each joint's friction law "
            "(f_c and f_v together, a held joint's torque within its friction cone is no "
            "error), its σ with the model error of the rows near rest: identify's point-valued "
            "fit of f_c sign(q̇) and f_v q̇ differs from it, as the point-valued fit here does, "
            "because it fits sign(q̇) on samples at rest and through the torque filter, which "
            "biases f_c and f_v in opposite directions; identify widens its σ by that bias "
            "(details['standstill'] and its model-error warning), so the two agree within "
            "their σ while the refit's are narrower")


def _worse_in_full(prob: _Problem, chosen: Sequence[int], i: int, floor: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(nv,) held-out RMS per joint of the selection's fit of ``chosen`` without atom ``i``
    and with it (``floor`` scales the weights back to torque): whether ``i`` makes a joint
    worse once every selected atom, the ones it interacts with among them, is in the fit."""
    def rms(atoms: Sequence[int]) -> np.ndarray:
        cols, theta, _ = prob.fit(atoms)
        return np.sqrt(prob.held.sse(cols, theta) / prob.held.n)

    return rms([m for m in chosen if m != i]), rms(chosen)


def _worsened(before: np.ndarray, after: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """(nv,) joints whose held-out RMS an effect raised: above :data:`WORSE_RATIO` × what it
    was and above the remainder's flag (``REMAINDER_RATIO`` × ``floor``)."""
    return (after > WORSE_RATIO * before) & (after > REMAINDER_RATIO * floor)


def _worse_note(atoms: Sequence[Atom], before: np.ndarray, after: np.ndarray,
                names: list[str], worse: np.ndarray | None = None) -> str:
    """``"<labels> make(s) <joint> worse on the held-out data (a → b N·m, …)"``, on the atoms'
    own joints or, given, the joints ``worse``."""
    joints = (np.flatnonzero(worse) if worse is not None
              else sorted({a.joint for a in atoms if a.joint is not None}))
    labels = ", ".join(a.label(names) for a in atoms)
    how = ", ".join(f"{names[j]} {before[j]:.3g} → {after[j]:.3g} N·m" for j in joints)
    return (f"{labels} make{'s' if len(atoms) == 1 else ''} the held-out prediction worse "
            f"({how})")


def _held_floor(floor: np.ndarray, noise: NoiseFloor, train: GapData, held: GapData,
                spectrum_on_held: bool) -> np.ndarray:
    """(nv,) ``floor`` in the held-out recordings' terms, each joint scaled once: as it is where
    it was read on them (a spectrum estimated on the held-out recordings,
    ``spectrum_on_held``), else × :func:`noise_gain_ratio` (a floor read on the training
    recordings, or on all of them through one low-pass, or given)."""
    read_on_held = (np.zeros(floor.size, dtype=bool)
                    if not spectrum_on_held or noise.on_repeating is None
                    else ~noise.on_repeating)
    return np.where(read_on_held, floor, floor * noise_gain_ratio(train.dataset, held.dataset))


def noise_gain_ratio(train: Dataset, held: Dataset) -> float:
    r"""How much more noise the held-out recordings' recorded low-pass lets through than the
    training ones', ``max(1, g_held / g_train)``: white noise of variance ``σ²`` through the
    zero-phase filter of impulse response ``h`` (:func:`~consistid.data.filters.impulse_response`)
    has variance ``σ² Σ h_k²``, so ``g = √(Σ h_k²)`` (1 for no filter, or a cut-off at or above
    0.45 × the rate, which the chain leaves unfiltered). Never below 1: a noise coloured below
    the cut-offs loses less to the lower one than white noise, and an understated floor would
    flag what is noise. 1 when either dataset records no filter."""
    from ..data.filters import impulse_response

    def gain(ds: Dataset) -> float | None:
        chain = ds.torque_filter
        if chain is None or ds.n_samples < 2:
            return None
        rate = 1.0 / float(np.median(np.diff(ds.t)))
        if chain[0] >= 0.45 * rate:
            return 1.0
        return float(np.sqrt(np.sum(impulse_response(float(chain[0]), rate,
                                                     int(chain[1])) ** 2)))

    a, b = gain(train), gain(held)
    return 1.0 if a is None or b is None else max(1.0, b / a)


def _known_rms(left: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """(nv,) RMS of ``left`` (N, nv) over the samples not ``unknown``; ``nan`` on a joint
    without any (nothing there can be judged: :attr:`JointRemainder.judged`)."""
    known = ~unknown
    n = known.sum(axis=0)
    return np.where(n > 0, np.sqrt(np.sum(np.where(known, left, 0.0) ** 2, axis=0)
                                   / np.maximum(n, 1)), np.nan)


def _refused_by_min_gain(steps: Sequence[Step]) -> str:
    """``"<candidate>: <why>"`` when the selection stopped because its best candidate's
    held-out gain was below ``min_gain`` (the stop reason :func:`_select` writes), else ``""``."""
    if not steps or steps[-1].accepted or "< min_gain" not in steps[-1].reason:
        return ""
    why = steps[-1].reason.split("(best: ", 1)[-1].removesuffix(")")
    return f"{steps[-1].chosen}: {why}"


def _unpredictable(fit: GapModel, data: GapData) -> np.ndarray:
    """(N, nv) samples whose corrected torque the model cannot form: within the first ``d``
    seconds of their recording on a channel delayed by ``d`` (they hold torque from before it
    began), and within the low-pass's settling time
    (:func:`~consistid.data.filters.settling_time`, 99.9 % of its impulse response's energy) of
    a recording's ends on a joint whose effect was seen through that filter (the filter there
    depends on torque outside the recording)."""
    out = np.zeros((data.n, data.nv), dtype=bool)
    since, until = np.zeros(data.n), np.zeros(data.n)
    for seg in data.segments:
        since[seg.index] = seg.t - seg.t[0]
        until[seg.index] = seg.t[-1] - seg.t
    for i, atom in enumerate(fit.atoms):
        cols = slice(None) if atom.joint is None else atom.joint
        if i in fit.delays:
            edge = since < fit.delays[i]
        elif np.isfinite(atom.cutoff):
            width = np.zeros(data.n)
            for seg in data.segments:
                rate = 1.0 / seg.step if seg.size > 1 else 0.0
                if atom.cutoff < 0.45 * rate:   # else lowpass_segments leaves it unfiltered
                    width[seg.index] = settling_time(atom.cutoff, rate, energy=0.999)
            edge = (since < width) | (until < width)
        else:
            continue
        out[:, cols] |= edge[:, None] if atom.joint is None else edge
    return out


def _set_valued_friction(fit: GapModel, data: GapData, residual: np.ndarray,
                         unknown: np.ndarray, floor: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray,
                                    dict[int, tuple[float, float, str, bool]]]:
    """``residual`` (N, nv), what every selected effect leaves on ``data``, with the selected
    dry friction (its Coulomb and Stribeck atoms) taken as set-valued at rest, the cone
    half-width each joint was judged against (nv,; 0: none), and, by index into ``fit.atoms``,
    the ``(value, std, how, judged)`` of each friction atom as reported: on every joint with
    dry friction where the dataset records the chain's low-pass, the set-valued refit of the
    joint's whole friction law with its model error
    (:func:`~consistid.diagnosis.friction_law.friction_law`; ``judged``: the verdict judges
    the joint by that fit). Atoms seen
    without a filter:
    :func:`~consistid.diagnosis.remainder.dry_friction_at_rest`, against the fitted static
    friction ``f_c + Δf``; seen through a low-pass, where the dataset says which one the signal
    chain applied to the torques (``torque_filter``):
    :func:`~consistid.diagnosis.remainder.dry_friction_through_filter`, with the joint's
    viscous atoms refitted beside it (the point-valued fit biased them too), on the joints whose
    point-valued remainder would be flagged (above ``REMAINDER_RATIO`` × ``floor``): elsewhere
    the set-valued friction, which can only leave less, changes no verdict and its solve (a
    second or more per joint on a 30 s log) is skipped; and not where the remainder on the
    samples clear of standstill (beyond the filter's settling time of any sample at rest,
    :func:`_near_rest`) is flagged on its own, which no held torque reaches (a position- or
    load-dependent friction that the refitted amplitudes and the held torques near rest would
    otherwise take up in part). Through no recorded filter: not at all."""
    dry, cone = np.zeros((data.n, data.nv)), np.zeros(data.nv)
    damped = np.zeros((data.n, data.nv))            # the selected viscous friction, as fitted
    filtered = np.zeros(data.nv, dtype=bool)
    laws: dict[int, list[np.ndarray]] = {}
    slopes: dict[int, list[np.ndarray]] = {}
    owners: dict[int, tuple[list[int], list[int]]] = {}    # atoms of the laws, of the slopes
    refitted: dict[int, tuple[float, float, str, bool]] = {}
    for i, (atom, th) in enumerate(zip(fit.atoms, fit.theta)):
        if atom.effect in DRY_FRICTION and atom.joint is not None:
            dry += fit.library.columns(atom, data) @ th
            cone[atom.joint] += max(float(th[0]), 0.0)
            filtered[atom.joint] |= bool(np.isfinite(atom.cutoff))
            law = np.reshape(REGISTRY[atom.effect].unfiltered(fit.library, atom, data),
                             (data.n, -1)).T
            laws.setdefault(atom.joint, []).extend(law)
            owners.setdefault(atom.joint, ([], []))[0].extend([i] * len(law))
        elif atom.effect in VISCOUS_FRICTION and atom.joint is not None:
            columns = fit.library.columns(atom, data)
            damped += columns @ th
            slopes.setdefault(atom.joint, []).extend(columns[:, atom.joint].T)
            owners.setdefault(atom.joint, ([], []))[1].append(i)
    left = dry_friction_at_rest(data, residual, dry, np.where(filtered, 0.0, cone))
    chain = data.dataset.torque_filter       # (cut-off Hz, order) of the chain's low-pass
    known = ~unknown
    rate = 1.0 / min((seg.step for seg in data.segments if seg.size > 1), default=np.inf)
    static = cone.copy()
    judged_on: dict[int, SetValuedFit] = {}
    for j in np.flatnonzero(filtered & (cone > 0)):
        rms = float(np.sqrt(np.mean(left[known[:, j], j] ** 2))) if known[:, j].any() else 0.0
        if (chain is None or chain[1] != LOWPASS_ORDER or chain[0] >= 0.45 * rate
                or rms <= REMAINDER_RATIO * floor[j]):
            cone[j] = 0.0
            continue
        judged = set_valued_refit(data, int(j), residual[:, j], dry[:, j] + damped[:, j],
                                  laws[int(j)], float(cone[j]), float(chain[0]), known[:, j],
                                  viscous=slopes.get(int(j), []))
        # Held torques reach, through the filter, only the samples within its settling time of
        # a sample at rest: what the set-valued fit still leaves on the samples beyond (moving
        # well clear of standstill), if flagged on its own, is a remainder no set-valued
        # friction explains — the joint is judged point-valued
        far = known[:, j] & ~_near_rest(data, j, float(chain[0]), rate)
        if judged is None or (far.sum() >= FAR_SAMPLES
                              and np.sqrt(np.mean(judged.remainder[far] ** 2))
                              > REMAINDER_RATIO * floor[j]):
            cone[j] = 0.0
        else:
            left[:, j], cone[j] = judged.remainder, judged.cone
            judged_on[int(j)] = judged
    if chain is None or chain[1] != LOWPASS_ORDER or chain[0] >= 0.45 * rate:
        return left, cone, refitted
    # the friction reported: each joint's whole law, fitted set-valued, with its model error
    for j in sorted(set(np.flatnonzero(static > 0)) | set(slopes)):
        law = friction_law(data, int(j), residual[:, j], dry[:, j] + damped[:, j],
                           laws.get(int(j), []), slopes.get(int(j), []), float(static[j]),
                           float(chain[0]),
                           known[:, j], ~_near_rest(data, int(j), float(chain[0]), rate),
                           judged_on.get(int(j)))
        if law is None:
            continue
        dry_atoms, viscous_atoms = owners[int(j)]
        for i, v, sd in zip(dry_atoms + viscous_atoms,
                            np.concatenate([law.dry[:len(dry_atoms)], law.viscous]),
                            np.concatenate([law.dry_std[:len(dry_atoms)], law.viscous_std])):
            refitted[i] = (float(v), float(sd), law.note, int(j) in judged_on)
    return left, cone, refitted


def _near_rest(data: GapData, joint: int, cutoff: float, rate: float) -> np.ndarray:
    """(N,) samples within the zero-phase low-pass's settling time (99.9 % of its impulse
    response's energy, :func:`~consistid.data.filters.settling_time`) of a sample where
    ``joint`` is at rest (:func:`~consistid.diagnosis.remainder.standstill_mask`)."""
    rest = standstill_mask(data.dataset.dq)[:, joint]
    half = int(np.ceil(settling_time(cutoff, rate, energy=0.999) * rate))
    # a running maximum keeps the data's length (np.convolve's "same" takes the longer of the
    # two: a record shorter than the window came back the window's length)
    return scipy.ndimage.maximum_filter1d(rest.astype(np.uint8), 2 * half + 1,
                                          mode="constant") > 0


def _prune_nested(prob: _Problem, chosen: list[int], alts: list, bics: list, pvals: list,
                  rivals: list, names: list[str], notes: list[str]
                  ) -> tuple[list, list, list, list, list]:
    """Drop selected atoms whose columns lie in the span of the other selected atoms (e.g. a
    ``payload`` chosen as the simpler of two indistinguishable candidates, after which
    ``inertia`` entered too): they add nothing to the fit. Appends a note per dropped atom."""
    keep = list(range(len(chosen)))
    _, _, full_rank = prob.fit(chosen)
    for k in reversed(range(len(chosen))):
        others = [chosen[m] for m in keep if m != k]
        if not others:
            continue
        _, _, rank = prob.fit(others)
        if rank == full_rank:
            keep.remove(k)
            notes.append(f"{prob.atoms[chosen[k]].label(names)} is contained in the other "
                         "selected effects (its columns lie in their span): merged into them")
    return ([chosen[k] for k in keep], [alts[k] for k in keep], [bics[k] for k in keep],
            [pvals[k] for k in keep], [rivals[k] for k in keep])


def _contained(prob: _Problem, chosen: list[int], names: list[str]) -> list[str]:
    """A note naming the candidates left out whose columns lie in the span of the selected atoms
    (e.g. ``position`` on a joint whose link's gravity torque is ``a sin q_j + b cos q_j``,
    inside ``inertia``): an effect of that form is in the fit, but not told apart from them."""
    if not chosen:
        return []
    _, _, rank = prob.fit(chosen)
    inside = [prob.atoms[i].label(names) for i in range(len(prob.atoms))
              if i not in chosen and prob.fit(chosen + [i])[2] == rank]
    if not inside:
        return []
    return [f"contained in the selected effects (their columns span it, so the data cannot tell "
            f"it apart from them): {', '.join(inside)}"]


def _asymmetric_friction(fit: GapModel, names: list[str]) -> list[str]:
    """Coulomb friction and an offset on the same joint read together as asymmetric friction,
    ``τ_f = f_o + f_c sign(q̇)``: ``f_o + f_c`` moving forward, ``f_o − f_c`` backward."""
    found: dict[int, dict[str, float]] = {}
    for atom, th in zip(fit.atoms, fit.theta):
        if atom.effect in ("coulomb", "offset") and atom.joint is not None:
            found.setdefault(atom.joint, {})[atom.effect] = float(th[0])
    return [f"{names[j]}: Coulomb friction and offset together are an asymmetric friction, "
            f"{v['offset'] + v['coulomb']:.3g} N·m moving +, {v['offset'] - v['coulomb']:.3g} N·m "
            "moving − (or a sensor offset beside symmetric friction: the data cannot tell)"
            for j, v in sorted(found.items()) if len(v) == 2]
