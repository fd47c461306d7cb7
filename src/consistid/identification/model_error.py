r"""The model error a fit takes from the samples where a joint stands still.

A joint held by dry friction (a real gearbox, MuJoCo's ``frictionloss``) takes any torque up to
its break-away at rest, which no law of the velocity describes: ``f_c \operatorname{sign}(q̇)``
there is a guess, and the rows at rest pull the Coulomb (and, through them, other) parameters
away from their value by far more than the noise-only covariance allows (a UR5 in MuJoCo with
Coulomb and viscous friction: Coulomb terms 5–20 σ off; the residual is the noise's at every
speed but below a few mrad/s). This bias is not noise, and no sandwich of the residual covers it.

It is measured as Hausman's specification test measures it (Hausman 1978, "Specification tests
in econometrics", Econometrica 46(6), 1251–1271, doi:10.2307/1913827): the same (weighted) least
squares without those rows,

.. math::  δ = \hat β_{\text{all}} − \hat β_{\text{moving}},
           \qquad \operatorname{Cov}(δ) = V_{\text{moving}} − V_{\text{all}}

when the model holds everywhere (the fit on all rows is then the efficient one, and the
difference of the two covariances is that of ``δ``). Its excess over that noise,

.. math::  b_i^2 = \max\big(0,\ δ_i^2 − (V_{\text{moving}} − V_{\text{all}})_{ii}\big),

is an unbiased estimate of the squared bias of parameter ``i`` (clipped at zero), added to the
diagonal of the covariance as a model-error term: the interval of a parameter the rows at rest
move by more than chance widens by that much. Where they do not (``δ_i² ≤ 2 ΔV_ii``,
``ΔV = V_moving − V_all``) the test cannot tell a bias of the order of ``ΔV_ii`` from noise, and
the term is ``ΔV_ii``: no interval is narrower than that of the rows the model is not suspected
on (``V_all + b² ≥ V_moving``),

.. math::  b_i^2 = \max\big(δ_i^2 − ΔV_{ii},\ ΔV_{ii}\big).

That is the term *when the model is suspected at rest*: when Hausman's test finds the rows at
rest moving some base parameter beyond chance (:func:`moved_beyond_chance`: the largest
``δ_i²/ΔV_ii`` against χ²₁ at the familywise level :data:`REST_ALPHA`, Bonferroni over the
parameters), or the caller suspects it (``suspected``: a Coulomb column on a joint with rows
at rest, where ``f_c sign(q̇)`` is a set and not a value; a joint's residual larger at rest or in
its slow bands; a slow joint). Otherwise ``δ`` is the noise that ``V_all`` already
counts, the fit on all rows is the efficient one, and the term is 0: the floor ``ΔV_ii`` on
white noise, where nothing is wrong at rest, only widens intervals — on 2 s of small motion
(the rows at rest a large share) by 10–20 % of their variance, coverage of the 95 % intervals
0.95 → 0.977 (Panda) and 0.958 → 0.974 (xArm7) in ``benchmarks/run_all.py``'s ``poor`` cells.
Under the model the gate opens in at most ``REST_ALPHA`` of data sets; with MuJoCo's dry
friction the Coulomb terms are 5–20 σ off and it always opens.

A parameter that the rows at rest hardly inform (most of them) is widened by a small fraction
of its variance; one that they inform most of (a joint that barely moves: its friction) gets
the interval of the moving rows, not the false precision of rows the model does not describe
(``benchmarks/coverage_friction.py``: the xArm7's and the Kinova's friction terms). Least
squares' own estimate is used for ``δ`` whatever the method (the SDP sits on the same rows).

The rows "at rest" are joint ``j``'s rows with ``|q̇_j|`` below a speed chosen from the
residual: :data:`~consistid.robot.joint_terms.STANDSTILL_SPEED`, or higher where the residual of
the slow speed bands is larger than that of the fast ones
(:meth:`consistid.identification.streaming.ResidualStatistics.rest_speeds`: MuJoCo's soft
``frictionloss`` on a light, slow arm leaves a structured residual up to ~0.1 rad/s). They are
compressed on their own (a few percent of the samples on an excitation trajectory; one more
pass over those samples only): the Gram matrices of the moving rows are those of all rows less
those of the rows at rest.

A joint that never leaves the band where dry friction is smoothed (speeds below ``v_s``:
presliding, a Stribeck band, MuJoCo's soft ``frictionloss``) has no moving rows in that sense,
and Hausman's difference is blind to it: every row it has shows ``f ≈ f_c q̇/v_s``, a slope,
and the fit reads ``f_c ≈ 0`` and ``f_v ≈ f_c/v_s`` with a residual that is the noise's
everywhere (:meth:`~consistid.identification.streaming.ResidualStatistics.slow_joints`). The
data give the friction torque at the joint's fastest speed ``v`` and not its split: with
``v_s ≥ v`` (the joint never left the band) and ``f_c, f_v ≥ 0``, the truth has
``f_c ≥ \hat f_v v`` less its own viscous part and ``0 ≤ f_v ≤ \hat f_v``. The split's model
error (:func:`split_bias`) is the whole of what the other term could take,

.. math::  b_{f_c}^2 = (\hat f_v v)^2, \qquad b_{f_v}^2 = \hat f_v^2,

the least a Coulomb level hidden in the slope can be (``v_s = v``); it is larger when ``v_s``
is far above ``v``, which the data cannot show, and the slow-joint warning says so.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.stats

from ..data.dataset import Dataset
from ..robot.joint_terms import STANDSTILL_SPEED
from ..robot.model import RobotModel
from .base import BaseParameters
from .compression import CompressedProblem, compress
from .regressor import RegressorSpec
from .statistics import coloured_covariance

#: Familywise level of :func:`moved_beyond_chance`: the model-error term of the rows at rest is
#: added when they move some base parameter beyond chance at this level. A false alarm costs
#: intervals as wide as the moving rows' on that data set; a missed bias costs coverage (dry
#: friction: 5–20 σ), hence the usual 5 % rather than the warnings' 0.1 %.
REST_ALPHA = 0.05
#: Relative variance below which the rows at rest do not inform a parameter
#: (:func:`moved_beyond_chance`): round-off of the two solves, not information.
GAP_RTOL = 1e-9


def split_bias(base_names: list[str], names: list[str], theta: np.ndarray,
               joint_names: list[str], joints: np.ndarray, top_speed: np.ndarray
               ) -> np.ndarray:
    """``b²`` per base parameter (``base_names``) of the Coulomb/viscous split the data cannot
    make (module docstring) on ``joints``, from the fitted ``theta`` (named ``names``) and
    each joint's fastest speed; 0 elsewhere and where a term is not a base parameter."""
    b2 = np.zeros(len(base_names))
    for j in joints:
        fc, fv = f"{joint_names[j]}.fc", f"{joint_names[j]}.fv"
        if fc in base_names and fv in base_names:
            slope = max(float(theta[names.index(fv)]), 0.0)
            b2[base_names.index(fc)] = (slope * float(top_speed[j])) ** 2
            b2[base_names.index(fv)] = slope ** 2
    return b2


def rest_problem(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                 base: BaseParameters | None = None, speeds: np.ndarray | float = STANDSTILL_SPEED
                 ) -> CompressedProblem | None:
    """The compressed problem of the rows where a joint stands still (joint ``j``'s rows with
    ``|q̇_j| < speeds[j]``, the other joints' rows of those samples weighted 0), or ``None``
    when no joint ever does. The samples as they are, also on parallel-filtered data
    (:func:`rest_reference`)."""
    rest = np.abs(dataset.dq) < np.asarray(speeds, dtype=float)
    samples = np.flatnonzero(rest.any(axis=1))
    if samples.size == 0:
        return None
    data = dataclasses.replace(dataset, identification_filter=None)
    return compress(model, data.select(samples), spec, weights=rest[samples].astype(float),
                    base=base)


def rest_reference(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
                   base: BaseParameters | None = None) -> CompressedProblem | None:
    """On parallel-filtered data (``Dataset.identification_filter``), the compressed problem of
    all its samples as they are, which :func:`rest_bias` compares with :func:`rest_problem`'s;
    ``None`` otherwise (the fit's own problem serves). The identification low-pass smears a
    torque error at rest over its moving neighbours, so that filtered rows without those at
    rest keep it and Hausman's ``δ`` misses it (Panda, MuJoCo dry friction, noise 1 N·m: ``b``
    0.08 against 0.35 on the samples, Coulomb/viscous coverage 0.86 against 0.99); widening the
    rows at rest by the filter's response instead left too few moving rows (σ of the shipped
    Panda example's friction up to 24 × wider). The bias the rows at rest put into the fit is
    estimated on the samples and added to the filtered fit's covariance."""
    if dataset.identification_filter is None:
        return None
    return compress(model, dataclasses.replace(dataset, identification_filter=None), spec,
                    base=base)


def joint_grams(problem: CompressedProblem, columns: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(Φ_jᵀΦ_j, Φ_jᵀτ_j)`` per joint on ``columns``, from the R factors."""
    r = problem.factors[:, :-1, :]
    r_b = r[:, :, columns]
    return np.matmul(r_b.transpose(0, 2, 1), r_b), np.einsum("jkp,jk->jp", r_b, r[:, :, -1])


def rest_bias(problem: CompressedProblem, rest: CompressedProblem, columns: np.ndarray,
              weights: np.ndarray, tau: np.ndarray, variances: np.ndarray,
              suspected: bool = False) -> tuple[np.ndarray, np.ndarray]:
    r"""``(b², δ)`` of the module docstring: the squared bias per base parameter that the rows
    at rest (``rest``, part of ``problem``) put into the least squares of weights ``w_j``, and
    the difference ``δ`` it is estimated from. The covariances ``V`` are the coloured sandwich's
    (:func:`~consistid.identification.statistics.coloured_covariance`, ``τ_j`` and ``v_j`` as
    there). ``b² = 0`` where removing the rows at rest leaves a direction unexcited, and
    everywhere when the model is not suspected at rest: neither ``suspected`` (the residual's
    evidence, the caller's) nor :func:`moved_beyond_chance`."""
    g_all, h_all = joint_grams(problem, columns)
    g_rest, h_rest = joint_grams(rest, columns)
    g_move, h_move = g_all - g_rest, h_all - h_rest
    w = np.asarray(weights, dtype=float)
    zero = np.zeros(columns.size)
    try:
        c_all = np.linalg.inv(np.einsum("j,jpq->pq", w, g_all))
        c_move = np.linalg.inv(np.einsum("j,jpq->pq", w, g_move))
    except np.linalg.LinAlgError:
        return zero, zero
    delta = c_all @ (w @ h_all) - c_move @ (w @ h_move)
    v_all = np.diag(coloured_covariance(c_all, g_all, w, tau, variances))
    v_move = np.diag(coloured_covariance(c_move, g_move, w, tau, variances))
    if not (np.all(np.isfinite(v_move)) and np.all(np.isfinite(delta))):
        return zero, zero
    gap = np.maximum(v_move - v_all, 0.0)
    if not (suspected or moved_beyond_chance(delta, gap, v_move)):
        return zero, delta
    return np.maximum(delta ** 2 - gap, gap), delta


def moved_beyond_chance(delta: np.ndarray, gap: np.ndarray, scale: np.ndarray,
                        alpha: float = REST_ALPHA) -> bool:
    r"""Hausman's test per base parameter, Bonferroni over them: does some ``δ_i`` exceed its
    noise, ``b · P(χ²₁ > \max_i δ_i²/ΔV_ii) < α`` (``gap`` = ``ΔV_ii``, ``b`` the parameters
    tested)? Only parameters the rows at rest inform beyond round-off are tested
    (``ΔV_ii > GAP_RTOL · scale_i``, ``scale`` their variance without those rows): elsewhere
    ``δ_i`` is the difference of two solves of one value. The joint χ² test
    ``δᵀ ΔV⁺ δ`` would use the correlations too, but on poor data ``ΔV`` is nearly singular
    and its small eigenvalues are round-off: the joint test rejected white noise in 17–50 % of
    the ``poor`` runs at level 0.05, this one in 0–5 % (UR5, Panda, xArm7, 40 runs each)."""
    tested = gap > GAP_RTOL * np.abs(scale)
    if not tested.any():
        return False
    worst = float(np.max(delta[tested] ** 2 / gap[tested]))
    return bool(tested.sum() * scipy.stats.chi2.sf(worst, 1) < alpha)
