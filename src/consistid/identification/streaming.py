r"""Streaming identification: recordings read one at a time, never all in memory.

The compressed least-squares problem (:mod:`consistid.identification.compression`) is a
*reduction* over samples. For two disjoint sets of rows ``a`` and ``b`` of joint ``j``,

.. math::  \begin{bmatrix} A_{j,a} \\ A_{j,b} \end{bmatrix}^\top
           \begin{bmatrix} A_{j,a} \\ A_{j,b} \end{bmatrix}
           = \bar R_{j,a}^\top \bar R_{j,a} + \bar R_{j,b}^\top \bar R_{j,b}
           = \bar R_{j,ab}^\top \bar R_{j,ab},
           \qquad \bar R_{j,ab} = \operatorname{qr}\!\begin{bmatrix} \bar R_{j,a} \\
           \bar R_{j,b} \end{bmatrix}

so the R factor of all rows is the R factor of the stacked R factors (Golub & Van Loan,
*Matrix Computations*, 4th ed., §5.2 and §6.5, "updating the QR factorisation"; the tall-skinny
QR of Demmel, Grigori, Hoemmen, Langou 2012, doi:10.1137/080731992, is the same tree). Each
recording is compressed on its own (:func:`~consistid.identification.compression.compress`,
memory ``O(chunk·nv·p)``) and merged into the running factors (:func:`merge`); the problem handed
to OLS/WLS/SDP is then the one a single in-memory dataset would give, to round-off.

What ``identify`` reads as a stream (:func:`is_stream`): any iterable of
:class:`~consistid.Dataset` s or of files (``str`` / :class:`~pathlib.Path`, read with
:meth:`Dataset.load <consistid.Dataset.load>` or a given ``loader``) that is not a list or tuple
of Datasets (those are already in memory and are stacked, as before), and a :class:`DataStream`.

The coloured covariance (``covariance="coloured"``, :mod:`consistid.identification.statistics`)
needs the residual of the fitted model, so it reads the data a second time
(:meth:`DataStream.residual_statistics`). A list of files, or a :class:`DataStream` built on a
function that returns a fresh iterable, can be read again; a generator cannot, and is refused with
``covariance="coloured"`` (``covariance="auto"``, the default, then counts rows as independent
and says so in ``details["covariance"]``; make the stream re-readable for the sandwich). Huber
re-weighting (``loss="huber"``) re-compresses every sample at every pass and is refused on
streams.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np
import scipy.stats

from ..data.checks import check_magnitudes
from ..data.dataset import Dataset
from ..errors import DatasetError, OptionError
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel
from .base import BaseParameters
from .compression import CompressedProblem, compress
from .envelope import TrainingEnvelope
from .model_error import rest_problem, rest_reference
from .regressor import RegressorSpec, parameter_names, predict_torque
from .statistics import add_lagged, autocovariance_sum, integrated_time

#: What a stream yields: a dataset, or a file holding one.
Part = Dataset | str | os.PathLike
#: A stream source: an iterable of parts, or a function returning a fresh one (re-readable).
Source = Iterable[Part] | Callable[[], Iterable[Part]]


def merge(a: CompressedProblem, b: CompressedProblem) -> CompressedProblem:
    """The compressed problem of the rows of ``a`` and ``b`` together (module docstring):
    per joint ``R̄ = qr([R̄_a; R̄_b])``, sample counts and torque sums of squares added.

    Raises :class:`~consistid.errors.DatasetError` when the two have different shapes
    (another robot or other regressor columns).
    """
    if a.factors.shape != b.factors.shape:
        raise DatasetError(f"cannot merge compressed problems of shapes {a.factors.shape} and "
                           f"{b.factors.shape}: other joints or regressor columns")
    size = a.factors.shape[1]
    factors = np.empty_like(a.factors)
    for j in range(a.nv):
        r = np.linalg.qr(np.vstack([a.factors[j], b.factors[j]]), mode="r")
        factors[j] = r[:size] if r.shape[0] >= size else np.vstack(
            [r, np.zeros((size - r.shape[0], size))])
    return CompressedProblem(factors, a.n_samples + b.n_samples,
                             a.tau_sum_squares + b.tau_sum_squares, a.filtered or b.filtered)


def merge_all(problems: Iterable[CompressedProblem]) -> CompressedProblem:
    """:func:`merge` folded over ``problems`` (at least one)."""
    out = None
    for p in problems:
        out = p if out is None else merge(out, p)
    if out is None:
        raise DatasetError("nothing to merge: no compressed problem was given")
    return out


#: Samples of a dataset first read for the residual's autocorrelation
#: (:func:`autocorrelation_windows`): what :data:`TAU_PRECISION` asks of a white residual
#: (``2(10·1 + 1)/0.1² = 2 200``) with room to spare (τ of a white residual within 5 %), in
#: windows long enough (2 048 samples) to see a correlation time of a few hundred samples,
#: for which :meth:`ResidualStatistics.of` then reads more.
AUTOCORRELATION_SAMPLES = 2 ** 13
#: Windows they are taken in, spread evenly over the dataset.
AUTOCORRELATION_WINDOWS = 4
#: Relative standard error of the autocorrelation time that :meth:`ResidualStatistics.of`
#: reads enough samples for.
TAU_PRECISION = 0.1
#: Fewest effectively independent samples at standstill (``n_rest / τ``) on which
#: :meth:`ResidualStatistics.standstill_excess` tests the residual there.
MIN_REST_SAMPLES = 10
#: Upper edges (rad/s) of the speed bands in which :class:`ResidualStatistics` sums the residual
#: per joint (the last band is everything faster): ``STANDSTILL_SPEED × 2^k``.
SPEED_EDGES = STANDSTILL_SPEED * 2.0 ** np.arange(5)
#: A band's residual this many times the fastest band's RMS, beyond chance at level
#: :data:`BAND_ALPHA`, is structured (the factor and level of ``identify``'s standstill test and
#: of the diagnosis' remainder test).
BAND_RATIO = 1.5
BAND_ALPHA = 1e-3
#: A slow joint's fit "reads a slope" when its Coulomb level is at most this share of its
#: viscous torque at the top speed (:meth:`ResidualStatistics.steep_joints`): smoothed dry
#: friction fitted below its smoothing speed gives ``f_c ≈ 0`` (0.00 for a true 1.67 on a
#: Kinova wrist), while a step the data resolve keeps its level beside a steep viscous slope
#: (a harmonic drive's ``f_v = 5`` at 0.27 rad/s beside ``f_c = 1``: 0.74 of it, not slow).
STEP_SHARE = 0.25
#: ... and only when that viscous slope is one the data read: ``f̂_v`` beyond this many of its
#: standard deviations (those of rows counted as independent, times ``√τ_j``) from 0, its 95 %
#: interval clear of 0 (:meth:`ResidualStatistics.steep_joints`). A noise slope on poor data
#: (``f̂_v`` 11.6 ± 84 beside ``f̂_c ≈ 0``; 0.12 ± 8.5·10⁵ on a UR5 shoulder moved 2 s below
#: 0.16 rad/s) is not the mark of smoothed dry friction.
SLOPE_Z = 1.96


def autocorrelation_windows(dataset: Dataset, samples: int | None = AUTOCORRELATION_SAMPLES
                            ) -> Dataset:
    r"""The samples of ``dataset`` that the residual's autocorrelation is estimated on: all of
    them up to ``samples``, else :data:`AUTOCORRELATION_WINDOWS` contiguous windows of
    ``samples / windows`` samples spread evenly from its first to its last sample, each window
    (and each recording within it) its own segment, so that no lag pairs samples across a gap.

    The autocorrelation time is a property of the noise, not of the excitation: its estimate's
    relative standard error is about :math:`\sqrt{2(2M + 1)/n}` for a window of ``M`` lags on
    ``n`` samples (Madras & Sokal 1988, doi:10.1007/BF01022990; ``M ≈ 5τ``): 5 % for a white
    residual on :data:`AUTOCORRELATION_SAMPLES`, but 70 % for ``τ = 200`` (a heavily filtered
    high-rate log), for which :meth:`ResidualStatistics.of` reads more. The residual's sum of
    squares is exact from the compressed problem whatever is read here
    (:meth:`~consistid.identification.compression.CompressedProblem.sum_squares`). A stream
    reads this many per part.
    """
    n = dataset.n_samples
    if samples is None or n <= samples:
        return dataset
    width = max(samples // AUTOCORRELATION_WINDOWS, 1)
    starts = np.linspace(0, n - width, AUTOCORRELATION_WINDOWS).astype(int)
    index = (starts[:, None] + np.arange(width)).ravel()
    picked = dataset.select(index)
    window = np.repeat(np.arange(AUTOCORRELATION_WINDOWS), width)
    segment = picked.segment - picked.segment.min()
    return dataclasses.replace(picked, segment=segment * AUTOCORRELATION_WINDOWS + window)


@dataclass(frozen=True)
class ResidualStatistics:
    """What the coloured covariance needs from the residual ``τ − Y θ`` of the fitted model.

    The residual is that of the samples as they are, also on a dataset that records an
    identification cut-off (parallel filtering): its long-run variance ``τ_j v_j`` (the
    spectral density at zero frequency) is that of the filtered residual, a low-pass of unit
    DC gain leaving it unchanged, and is estimated far better from it (the filtered residual is
    correlated over ``f_d / f_p`` times as many samples: on 30 s of a 0.5 Hz band at 500 Hz,
    ``τ_j`` ≈ 350 samples, 43 effectively independent ones, against ≈ 45); its speed bands and
    rows at rest are not smeared over the filter's response. ``identify`` uses them with the
    Gram matrices of the filtered rows (:func:`~consistid.identification.identify.
    with_covariance`).

    Attributes
    ----------
    autocovariance : (lags, nv) autocovariance sums pooled over recordings
        (:func:`consistid.identification.statistics.autocovariance_sum`), or ``None``.
    sum_squares : (nv,) residual sum of squares per joint (N·m)².
    n_samples : samples read.
    rest_sum_squares, rest_count : (nv,) the part of ``sum_squares`` on the samples where the
        joint stands still (``|q̇_j| <`` :data:`~consistid.robot.joint_terms.STANDSTILL_SPEED`),
        and how many they are (:meth:`standstill_excess`).
    band_sum_squares, band_count : (nv, len(SPEED_EDGES) + 1) the residual's sum of squares
        and sample count per speed band of each joint (:data:`SPEED_EDGES`; the last band is
        every faster sample), on the samples read (:meth:`rest_speeds`).
    rest : the compressed problem of the rows at rest (below :meth:`rest_speeds`), every
        sample read (:func:`consistid.identification.model_error.rest_problem`), when the
        statistics were asked for with ``base``; else ``None``.
    top_speed : (nv,) the fastest ``|q̇_j|`` (rad/s) of every sample of the datasets (not only
        those read), or ``None`` (unknown).
    viscous_speed : (nv,) the speed ``|f_c|/f_v`` (rad/s) at which the fitted viscous torque
        of joint ``j`` equals its fitted Coulomb level (``inf`` where ``f_v ≤ 0`` or either term
        is not fitted), or ``None`` (:meth:`slow_joints`).
    viscous_noise : (nv,) ``σ(f̂_v)/f̂_v``, the fitted viscous term's relative standard
        deviation with rows counted as independent (``inf`` where ``f_v ≤ 0`` or it is not a
        base parameter), or ``None``: unknown, every fitted slope is read
        (:meth:`steep_joints`).
    reference : on parallel-filtered data, the compressed problem of every sample as it is,
        against which :attr:`rest` (always of the samples as they are) is judged
        (:func:`~consistid.identification.model_error.rest_reference`); ``None`` otherwise,
        and on a stream whose parts are not all filtered.
    """

    autocovariance: np.ndarray | None
    sum_squares: np.ndarray
    n_samples: int
    rest_sum_squares: np.ndarray
    rest_count: np.ndarray
    band_sum_squares: np.ndarray
    band_count: np.ndarray
    rest: CompressedProblem | None = None
    top_speed: np.ndarray | None = None
    viscous_speed: np.ndarray | None = None
    viscous_noise: np.ndarray | None = None
    reference: CompressedProblem | None = None

    @classmethod
    def of(cls, model: RobotModel, spec: RegressorSpec, theta: np.ndarray,
           dataset: Dataset, samples: int | None = AUTOCORRELATION_SAMPLES,
           base: BaseParameters | None = None, viscous_std: np.ndarray | None = None
           ) -> "ResidualStatistics":
        """The statistics of one in-memory dataset (by
        :func:`~consistid.identification.regressor.predict_torque`) over ``samples`` of its
        samples (:func:`autocorrelation_windows`; ``None``: all of them), or more when the
        correlation time found there asks for them: the estimate of ``τ`` has a relative
        standard error ``√(2(2M + 1)/n)`` with Sokal's window ``M ≈ 5τ``, so ``τ`` within
        :data:`TAU_PRECISION` needs ``n ≥ 2(10τ + 1)/TAU_PRECISION²`` samples (2 200 for a
        white residual, 400 000 for ``τ = 200``); the residual is then read again on that
        many. The sums and the count are those of the samples read; with ``base`` (of
        ``(model, spec)``), :attr:`rest` is compressed from all of them. ``viscous_std``: per
        joint, the standard deviation of the fitted ``f_v`` (rows counted as independent;
        :attr:`viscous_noise`)."""
        part = autocorrelation_windows(dataset, samples)
        stats = cls._of(model, spec, theta, part)
        if part is not dataset:
            tau = float(np.max(stats.autocorrelation_time()))
            needed = int(np.ceil(2.0 * (10.0 * tau + 1.0) / TAU_PRECISION ** 2))
            if needed > part.n_samples:
                stats = cls._of(model, spec, theta, autocorrelation_windows(dataset, needed))
        stats = dataclasses.replace(stats, top_speed=np.abs(dataset.dq).max(axis=0, initial=0.0),
                                    viscous_speed=viscous_speed(model, spec, theta),
                                    viscous_noise=viscous_noise(model, spec, theta, viscous_std))
        if base is not None:
            stats = dataclasses.replace(stats, rest=rest_problem(model, dataset, spec, base,
                                                                 stats.rest_speeds()),
                                        reference=rest_reference(model, dataset, spec, base))
        return stats

    @classmethod
    def _of(cls, model: RobotModel, spec: RegressorSpec, theta: np.ndarray,
            dataset: Dataset) -> "ResidualStatistics":
        residual = dataset.require_torque() - predict_torque(model, dataset, spec, theta)
        speed = np.abs(dataset.dq)
        rest = speed < STANDSTILL_SPEED
        band = np.searchsorted(SPEED_EDGES, speed, side="right")          # (N, nv)
        nb = SPEED_EDGES.size + 1
        band_ss, band_n = np.zeros((speed.shape[1], nb)), np.zeros((speed.shape[1], nb))
        for j in range(speed.shape[1]):
            band_ss[j] = np.bincount(band[:, j], residual[:, j] ** 2, minlength=nb)
            band_n[j] = np.bincount(band[:, j], minlength=nb)
        return cls(autocovariance_sum(dataset, residual), np.sum(residual ** 2, axis=0),
                   dataset.n_samples, np.sum(np.where(rest, residual ** 2, 0.0), axis=0),
                   np.sum(rest, axis=0), band_ss, band_n)

    def __add__(self, other: "ResidualStatistics") -> "ResidualStatistics":
        pooled = add_lagged(self.autocovariance, other.autocovariance)
        return ResidualStatistics(pooled, self.sum_squares + other.sum_squares,
                                  self.n_samples + other.n_samples,
                                  self.rest_sum_squares + other.rest_sum_squares,
                                  self.rest_count + other.rest_count,
                                  self.band_sum_squares + other.band_sum_squares,
                                  self.band_count + other.band_count,
                                  self.rest if other.rest is None else other.rest
                                  if self.rest is None else merge(self.rest, other.rest),
                                  None if self.top_speed is None or other.top_speed is None
                                  else np.maximum(self.top_speed, other.top_speed),
                                  self.viscous_speed if other.viscous_speed is None
                                  else other.viscous_speed,
                                  self.viscous_noise if other.viscous_noise is None
                                  else other.viscous_noise,
                                  None if self.reference is None or other.reference is None
                                  else merge(self.reference, other.reference))

    def rest_speeds(self) -> np.ndarray:
        r"""Per joint, the speed (rad/s) below which its residual is structured: the upper edge
        of the last of the consecutive slow bands (from rest up, :data:`SPEED_EDGES`) whose
        residual RMS is :data:`BAND_RATIO` times that of the fastest band or more, beyond chance
        at level :data:`BAND_ALPHA` (one-sided F-test on ``n/τ_j`` effective samples, as
        :meth:`standstill_excess`); at least
        :data:`~consistid.robot.joint_terms.STANDSTILL_SPEED`. Dry friction that a simulator or
        a gearbox smooths over a band of speeds (MuJoCo's soft ``frictionloss`` on a light
        joint: up to ~0.1 rad/s) is not ``f_c sign(q̇)`` anywhere in that band.

        A joint too slow for the test whose residual differs between the bands it reaches, or
        whose fit reads a slope (:meth:`slow_joints`), has no speed at which its residual is
        shown to be the noise's: every band but the fastest it reaches counts as at rest (a
        Kinova's wrist in a random excitation, ≤ 0.3 rad/s: its Coulomb and viscous terms
        4–6 σ off with the rest speed at 0.02 rad/s, ``benchmarks/coverage_friction.py``)."""
        tau = np.maximum(self.autocorrelation_time(), 1.0)
        out = np.full(self.sum_squares.size, STANDSTILL_SPEED)
        effective = self.band_count / tau[:, None]
        for j in self.slow_joints():
            reached = np.flatnonzero(effective[j] >= MIN_REST_SAMPLES)
            if reached.size and reached[-1] >= 2:
                out[j] = SPEED_EDGES[reached[-1] - 1]
        for j in range(out.size):
            ref_n = effective[j, -1]
            if ref_n < MIN_REST_SAMPLES or self.band_sum_squares[j, -1] <= 0:
                continue
            ref_var = self.band_sum_squares[j, -1] / self.band_count[j, -1]
            for k in range(1, SPEED_EDGES.size):
                n = self.band_count[j, k] / tau[j]
                if n < MIN_REST_SAMPLES:
                    break
                f = self.band_sum_squares[j, k] / self.band_count[j, k] / ref_var
                if f < BAND_RATIO ** 2 or scipy.stats.f.sf(f, n, ref_n) >= BAND_ALPHA:
                    break
                out[j] = SPEED_EDGES[k]
        return out

    def slow_joints(self) -> np.ndarray:
        r"""The joints too slow for :meth:`rest_speeds`' test whose friction law the data
        cannot check: their fastest speed band (above ``SPEED_EDGES[-1]``) holds fewer than
        :data:`MIN_REST_SAMPLES` effectively independent samples (``n/τ_j``), they reach at
        least two bands with as many, and either

        - the RMS of the largest-residual band they reach is :data:`BAND_RATIO` times that of
          the smallest or more, beyond chance at level :data:`BAND_ALPHA` (the F-test of
          :meth:`rest_speeds`, both bands from the data; its p-value times the ``m(m − 1)``
          ordered pairs of the ``m`` bands reached, of which the extreme one is tested:
          Bonferroni. Without it white noise on a joint moved 2 s below 0.16 rad/s, bands of
          ~25 samples, was flagged in 2 of 50 UR5 and Panda runs), or
        - the fit reads a slope where a step should be: its Coulomb level is at most
          :data:`STEP_SHARE` of its viscous torque at the joint's fastest speed,
          ``|f_c| ≤ STEP_SHARE · f_v \max|q̇_j|`` (:attr:`viscous_speed` ``≤ STEP_SHARE ×``
          :attr:`top_speed`), with ``f̂_v`` itself clear of 0 (beyond :data:`SLOPE_Z` of its
          standard deviation, :attr:`viscous_noise`: a slope the noise makes is no
          evidence). Dry friction smoothed over a band
          of slow speeds ``v_s`` (presliding, a Stribeck band, MuJoCo's soft
          ``frictionloss``) rises about linearly there, ``f ≈ f_c q̇/v_s``: fitted on
          ``|q̇| < v_s`` only, ``f_c sign(q̇) + f_v q̇`` takes it as ``f_v ≈ f_c/v_s`` and
          ``f_c ≈ 0``, with a residual that is the noise's in every band (a Kinova's wrist
          below 0.09 rad/s: ``f_c`` 0.00 for 1.67, ``f_v`` 18 for 0.25). Above that band the
          step dominates wherever the viscous torque is below the Coulomb level.

        A residual alike at every speed under a fitted step (white noise on a well-described
        slow joint), or a joint without both terms fitted and a residual alike, does not make
        a joint one of them."""
        tau = np.maximum(self.autocorrelation_time(), 1.0)
        effective = self.band_count / tau[:, None]
        steep = self.steep_joints()
        out = []
        for j in np.flatnonzero(effective[:, -1] < MIN_REST_SAMPLES):
            reached = np.flatnonzero(effective[j] >= MIN_REST_SAMPLES)
            if reached.size < 2:
                continue
            if steep[j]:
                out.append(j)
                continue
            var = self.band_sum_squares[j, reached] / self.band_count[j, reached]
            hi, lo = reached[np.argmax(var)], reached[np.argmin(var)]
            if not var.min() > 0:
                continue
            f = var.max() / var.min()
            pairs = reached.size * (reached.size - 1)
            if (f >= BAND_RATIO ** 2 and pairs * scipy.stats.f.sf(
                    f, effective[j, hi], effective[j, lo]) < BAND_ALPHA):
                out.append(j)
        return np.array(out, dtype=int)

    def steep_joints(self) -> np.ndarray:
        """(nv,) bool: the fitted Coulomb level is at most :data:`STEP_SHARE` of the fitted
        viscous torque at the joint's fastest speed and the viscous term is clear of 0 by
        :data:`SLOPE_Z` standard deviations (:attr:`viscous_noise` × ``√τ_j``, the residual's
        autocorrelation time) when that is known (:meth:`slow_joints`); all ``False`` when the
        speeds are unknown."""
        if self.top_speed is None or self.viscous_speed is None:
            return np.zeros(self.sum_squares.size, dtype=bool)
        steep = self.viscous_speed <= STEP_SHARE * self.top_speed
        if self.viscous_noise is None:
            return steep
        tau = np.maximum(self.autocorrelation_time(), 1.0)
        return steep & (SLOPE_Z * self.viscous_noise * np.sqrt(tau) < 1.0)

    def standstill_excess(self) -> tuple[np.ndarray, np.ndarray]:
        r"""``(ratio, p)`` per joint: the residual's RMS on the samples where the joint stands
        still over its RMS where it moves, and the p-value of that excess under the fitted
        model (the same noise everywhere): the one-sided F-test of the two variances,
        ``F = s²_rest / s²_moving`` with ``n_rest/τ_j`` and ``n_moving/τ_j`` degrees of freedom
        (``τ_j`` the residual's autocorrelation time: effectively independent samples). A joint
        held by static friction takes any torque up to its break-away, which no law of ``q̇``
        (``f_c sign(q̇)``) predicts: its residual at rest is larger. ``p = 1`` (ratio ``nan``)
        where fewer than :data:`MIN_REST_SAMPLES` effective samples stand still or none move."""
        tau = np.maximum(self.autocorrelation_time(), 1.0)
        moving = self.n_samples - self.rest_count
        n_rest, n_move = self.rest_count / tau, moving / tau
        with np.errstate(divide="ignore", invalid="ignore"):
            var_rest = self.rest_sum_squares / self.rest_count
            var_move = (self.sum_squares - self.rest_sum_squares) / moving
            ratio = np.sqrt(var_rest / var_move)
        ok = (n_rest >= MIN_REST_SAMPLES) & (moving > 0) & (var_move > 0)
        p = np.ones(ratio.shape)
        p[ok] = scipy.stats.f.sf(ratio[ok] ** 2, n_rest[ok], n_move[ok])
        return np.where(ok, ratio, np.nan), p

    def autocorrelation_time(self) -> np.ndarray:
        """``τ_j`` per joint (:func:`consistid.identification.statistics.integrated_time`)."""
        return integrated_time(self.autocovariance, self.sum_squares.size)


def viscous_speed(model: RobotModel, spec: RegressorSpec, theta: np.ndarray) -> np.ndarray:
    """Per joint, ``|f_c|/f_v`` of the fitted ``theta`` (rad/s): the speed at which its
    viscous torque reaches its Coulomb level; ``inf`` where ``f_v ≤ 0`` or a term is absent."""
    names = parameter_names(model, spec)
    out = np.full(model.nv, np.inf)
    for j, joint in enumerate(model.joint_names):
        fc, fv = f"{joint}.fc", f"{joint}.fv"
        if fc in names and fv in names and theta[names.index(fv)] > 0:
            out[j] = abs(theta[names.index(fc)]) / theta[names.index(fv)]
    return out


def viscous_noise(model: RobotModel, spec: RegressorSpec, theta: np.ndarray,
                  std: np.ndarray | None) -> np.ndarray | None:
    """Per joint, ``std_j / f̂_v`` of the fitted ``theta`` (``inf`` where ``f̂_v ≤ 0`` or the
    term is absent; :attr:`ResidualStatistics.viscous_noise`), or ``None`` without ``std``."""
    if std is None:
        return None
    names = parameter_names(model, spec)
    out = np.full(model.nv, np.inf)
    for j, joint in enumerate(model.joint_names):
        fv = f"{joint}.fv"
        if fv in names and theta[names.index(fv)] > 0 and np.isfinite(std[j]):
            out[j] = std[j] / theta[names.index(fv)]
    return out


def _label(part: Part, k: int) -> str:
    return f"file {str(part)!r}" if isinstance(part, (str, os.PathLike)) else f"data[{k}]"


class DataStream:
    """Recordings read one at a time, for :func:`consistid.identify` (module docstring).

    Parameters
    ----------
    source : an iterable of :class:`~consistid.Dataset` s and/or files, or a function of no
        argument returning one (then the stream can be read again, e.g. for the coloured
        covariance). A list or tuple can be read again; an iterator or generator only once.
    loader : reads a file into a Dataset; default :meth:`Dataset.load` (``.npz``/``.csv``). E.g.
        ``lambda path: consistid.load_recording(path, model=model).dataset`` for robot logs.

    Examples
    --------
    >>> files = sorted(Path("logs").glob("*.npz"))
    >>> res = ci.identify(model, files)                            # read one file at a time
    >>> res = ci.identify(model, (make_chunk(k) for k in range(100)), covariance="iid")
    """

    def __init__(self, source: Source, loader: Callable[[Path], Dataset] | None = None) -> None:
        if isinstance(source, (Dataset, str, bytes, os.PathLike)):
            raise DatasetError(f"a stream is an iterable of Datasets or files, got one "
                               f"{type(source).__name__}: pass [it], or the Dataset itself "
                               "to identify")
        if hasattr(source, "__dask_graph__"):
            # iterating a Dask collection would compute all of it here, in memory
            raise OptionError("a Dask collection: pass consistid.identification.distributed."
                              "on_dask(collection) so that it is reduced where it lies")
        if not callable(source):
            try:
                iter(source)  # type: ignore[call-overload]
            except TypeError:
                raise DatasetError(f"a stream is an iterable of Datasets or files, got "
                                   f"{type(source).__name__} {source!r:.60}") from None
        if loader is not None and not callable(loader):
            raise OptionError(f"loader must be a function path → Dataset, got {loader!r:.60}")
        self.source = source
        self.loader = loader or Dataset.load
        self._read = False
        #: The training envelope of the parts the last :meth:`compress` read (``None``
        #: before): where the data went, for ``identify``'s weak-direction check.
        self.envelope: TrainingEnvelope | None = None
        #: ``False``: every part is read without its identification cut-off
        #: (``identify(..., parallel_filter=False)``).
        self.parallel = True

    @property
    def rereadable(self) -> bool:
        """Whether the stream can be read more than once (a function or a container, not an
        iterator)."""
        if callable(self.source):
            return True
        return iter(self.source) is not self.source  # type: ignore[call-overload]

    def __repr__(self) -> str:
        kind = "re-readable" if self.rereadable else "one pass"
        return f"DataStream({type(self.source).__name__}, {kind})"

    # -------------------------------------------------------------------------- reading
    def parts(self, model: RobotModel | None = None) -> Iterator[tuple[str, Dataset]]:
        """``(label, dataset)`` of each part in turn, files loaded, joints, torques and
        magnitudes (:func:`consistid.data.checks.check_magnitudes`) checked against ``model``.
        Raises :class:`DatasetError` naming the part that is not a dataset or file, and
        when a one-pass stream is read a second time."""
        if self._read and not self.rereadable:
            raise DatasetError("this stream (an iterator or generator) was already read once; "
                               "build the DataStream on a list of files or on a function that "
                               "returns a fresh iterable to read it again")
        self._read = True
        source = self.source() if callable(self.source) else self.source
        files: dict[Path, int] = {}
        for k, part in enumerate(source):
            label = _label(part, k)
            if isinstance(part, (str, os.PathLike)):
                first = files.setdefault(Path(part).resolve(), k)
                if first != k:
                    raise DatasetError(f"{label} is part {first} again: read twice, its samples "
                                       "would count twice and every σ would shrink by √2; list "
                                       "each file once")
                try:
                    data = self.loader(Path(part))
                except DatasetError as exc:
                    raise DatasetError(f"{label}: {exc}") from exc
            else:
                data = part
            if not isinstance(data, Dataset):
                raise DatasetError(f"{label} is a {type(data).__name__}, not a Dataset or a file "
                                   "(the loader must return a Dataset)")
            if model is not None:
                try:
                    data.check_joints(model.nv, model.joint_names)
                    data.require_torque()
                    # per part: absurd values; motion and dead channels are the whole
                    # stream's business (a part may be a pause)
                    check_magnitudes(data, joint_names=model.joint_names)
                except DatasetError as exc:
                    raise type(exc)(f"{label}: {exc}") from exc
            if not self.parallel and data.identification_filter is not None:
                data = dataclasses.replace(data, identification_filter=None)
            yield label, data

    def compress(self, model: RobotModel, spec: RegressorSpec,
                 base: BaseParameters | None = None) -> CompressedProblem:
        """The compressed problem of every part: one pass, each part compressed and merged
        (:func:`merge`); memory that of one part plus ``O(nv·p²)``. ``base``: see
        :func:`~consistid.identification.compression.compress`. Sets :attr:`envelope`, the
        parts' :class:`~consistid.identification.envelope.TrainingEnvelope` joined."""
        problem, envelope = None, None
        for _, data in self.parts(model):
            part = compress(model, data, spec, base=base)
            problem = part if problem is None else merge(problem, part)
            seen = TrainingEnvelope.of(data, model.joint_names)
            envelope = seen if envelope is None else envelope + seen
        if problem is None:
            raise DatasetError("the data stream is empty: it yielded no Dataset or file")
        self.envelope = envelope
        return problem

    def residual_statistics(self, model: RobotModel, spec: RegressorSpec,
                            theta: np.ndarray, base: BaseParameters | None = None,
                            viscous_std: np.ndarray | None = None) -> ResidualStatistics:
        """:class:`ResidualStatistics` of ``τ − Y θ`` over every part (a second pass; each part
        counts as its own recordings for the autocorrelation; ``base``, ``viscous_std``: see
        :meth:`ResidualStatistics.of`)."""
        total = None
        for _, data in self.parts(model):
            stats = ResidualStatistics.of(model, spec, theta, data, base=base,
                                          viscous_std=viscous_std)
            total = stats if total is None else total + stats
        if total is None:
            raise DatasetError("the data stream is empty on its second reading: a function "
                               "source must return a fresh iterable each time")
        return total


def is_stream(data: Any) -> bool:
    """Whether ``identify`` reads ``data`` as a stream (module docstring): a
    :class:`DataStream`, a list/tuple holding a file, or any other iterable that is not a
    Dataset (a generator, a ``map``, …). A list or tuple of Datasets is not (it is stacked)."""
    if isinstance(data, DataStream):
        return True
    if isinstance(data, (Dataset, str, bytes, os.PathLike)) or type(data).__name__ in (
            "DataFrame", "Recording"):          # as_dataset names (or unwraps) these
        return False
    if isinstance(data, (list, tuple)):
        return any(isinstance(d, (str, os.PathLike)) for d in data)
    try:
        iter(data)
    except TypeError:
        return False
    return True


def is_one_pass(data: Any) -> bool:
    """Whether ``data`` is a stream that can be read only once (an iterator or generator)."""
    return is_stream(data) and not (data if isinstance(data, DataStream)
                                    else DataStream(data)).rereadable


def as_stream(data: Any, covariance: str = "iid", loss: str | None = None) -> DataStream:
    """``data`` as a :class:`DataStream`, refusing options a stream cannot honour:
    ``loss="huber"`` (re-reads every sample per pass) and ``covariance="coloured"`` on a
    one-pass stream (the residual needs a second reading)."""
    stream = data if isinstance(data, DataStream) else DataStream(data)
    if loss == "huber":
        raise OptionError("loss='huber' re-weights every sample at every pass, which a stream of "
                          "recordings does not allow: load the data as one Dataset, or use "
                          "loss='squared'")
    if covariance in ("coloured", "hac") and not stream.rereadable:
        raise OptionError(f"covariance={covariance!r} (the default: 'coloured') reads the data "
                          "again for the residual's statistics, and this stream (an iterator or "
                          "generator) can be read once: pass covariance='iid', or a list of "
                          "files, or DataStream(function returning a fresh iterable)")
    return stream


def compress_data(model: RobotModel, data: Dataset | DataStream, spec: RegressorSpec,
                  base: BaseParameters | None = None) -> CompressedProblem:
    """The compressed problem of an in-memory dataset or of a stream (``base``: the QR on each
    joint's independent columns only, :func:`~consistid.identification.compression.compress`)."""
    if isinstance(data, DataStream):
        return data.compress(model, spec, base)
    return compress(model, data, spec, base=base)


def residual_statistics(model: RobotModel, spec: RegressorSpec, theta: np.ndarray,
                        data: Dataset | DataStream, base: BaseParameters | None = None,
                        viscous_std: np.ndarray | None = None) -> ResidualStatistics:
    """:class:`ResidualStatistics` of ``τ − Y θ`` on an in-memory dataset or a stream
    (``base``: also the rows at rest; ``viscous_std``: σ of the fitted ``f_v`` per joint;
    :meth:`ResidualStatistics.of`)."""
    if isinstance(data, DataStream):
        return data.residual_statistics(model, spec, theta, base, viscous_std)
    return ResidualStatistics.of(model, spec, theta, data, base=base, viscous_std=viscous_std)


__all__ = ["DataStream", "ResidualStatistics", "as_stream", "compress_data", "is_one_pass",
           "is_stream",
           "merge", "merge_all", "residual_statistics"]
