r"""The friction the diagnosis reports: one joint's whole friction law, fitted set-valued, with
the model error of the rows near rest.

Where the diagnosis selected dry friction on a joint (``coulomb``, ``stribeck``) and the torques
went through the signal chain's recorded low-pass, the numbers it reports for that joint's
friction come from one fit (:func:`friction_law`): the joint's law

.. math::  τ_f = \sum_k a_k\, u_k(q̇) + f_v\, q̇
           \quad\text{moving}, \qquad |τ_f| ≤ c \quad\text{at rest},

``u_k`` the selected dry laws (``tanh(q̇/v_s)``, the Stribeck hump; ``sign(q̇)`` where only
viscous friction was selected), seen through the chain's filter with the held torques free
within the cone (:func:`~consistid.diagnosis.remainder.set_valued_refit`), and ``f_v q̇``
*always*, as ``identify`` fits ``f_c sign(q̇) + f_v q̇`` on every joint: a Coulomb level fitted
without the viscous term takes it up wherever the selection did not name it, and a viscous
slope without the step takes the step up. (On a simulated Panda, seed 2
of ``benchmarks/diagnosis_friction_coverage.py``, joint 7's viscous friction ``f_v = 0.3`` fell
below the selection's relevance floor: a Coulomb step tuned to a 1.8 Hz cut-off, below the
chain's 5.5 Hz, by the held torques at rest, took the viscous torque up and was reported
point-valued, ``f_c = 0.827 ± 0.007`` against the simulator's 0.6, 35 σ.)

**Model error.** The law still fails near rest where the simulator or the drive is not the ideal
set-valued friction (MuJoCo's soft ``frictionloss``, presliding): the same fit on the samples
*clear of rest*, beyond the filter's settling time of any sample at rest (``far``), which no
held torque reaches, is the alternative of Hausman's test (Hausman 1978, Econometrica 46(6),
1251–1271), as :mod:`consistid.identification.model_error` measures it for ``identify``:
``δ = \hat θ_{all} − \hat θ_{far}``, ``ΔV = V_{far} − V_{all}`` and the model-error term

.. math::  b_i^2 = \max\big(δ_i^2 − ΔV_{ii},\ ΔV_{ii}\big)

added to each variance. Without it the refit's σ were 1.45 × too small over eight Panda seeds
(z RMS 1.47 and 1.45 for ``f_c`` and ``f_v``); with it 0.99 and 1.09.

Where the dataset records no low-pass of the chain's kind (``Dataset.torque_filter``), the
held torques cannot be placed, and the point-valued fit of the selection is reported as before
(its σ without this model error).

**A slow joint.** A joint that never leaves the band where dry friction is smoothed gives its
friction torque, not the split into ``f_c`` and ``f_v``: where ``identify`` would call it slow
and reading a slope (:func:`_reads_a_slope`), the split's model error of
:func:`~consistid.identification.model_error.split_bias` is added too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..identification.model_error import split_bias
from ..identification.statistics import autocorrelation_time
from ..identification.streaming import MIN_REST_SAMPLES, SPEED_EDGES, STEP_SHARE
from .gapdata import GapData
from .remainder import SetValuedFit, set_valued_refit

#: Fewest samples clear of rest on which the model error of the rows near rest is measured (and
#: on which the diagnosis judges a joint's remainder point-valued before the set-valued friction
#: through a filter is tried).
FAR_SAMPLES = 200


@dataclass(frozen=True)
class FrictionLaw:
    """One joint's friction as reported: the dry amplitudes (N·m; one per selected dry law, or
    the Coulomb step the law adds, ``added_dry``) and the viscous slopes (N·m·s/rad; one per
    selected viscous atom, or the one the law adds, ``added_viscous``), their standard
    deviations with the model error, how that was measured (``far``: samples clear of rest it
    was measured on, 0 when too few; ``slow``: the split a slow joint's data cannot make added)
    and the chain's cut-off (Hz) the dry laws were seen through."""

    dry: np.ndarray
    viscous: np.ndarray
    dry_std: np.ndarray
    viscous_std: np.ndarray
    added_viscous: bool
    far: int
    cutoff: float
    slow: bool = False
    added_dry: bool = False

    @property
    def note(self) -> str:
        """How the values were obtained (for each parameter's note)."""
        error = (f"σ with the model error of the rows near rest (the same fit on the {self.far} "
                 "samples clear of rest, Hausman's difference)" if self.far else
                 f"σ without a model-error term: fewer than {FAR_SAMPLES} samples clear of rest "
                 "to measure it on")
        how = f"seen through the chain's {self.cutoff:.3g} Hz low-pass; {error}"
        if self.slow:
            how += ("; the joint never leaves the band where dry friction is smoothed, so the "
                    "data give its friction torque, not the split into f_c and f_v: the σ "
                    "include what the other term could take, as identify's slow-joint "
                    "warning says")
        if self.added_dry:
            how += (f"; fitted beside Coulomb friction {self.dry[0]:.4g} ± "
                    f"{self.dry_std[0]:.2g} N·m (sign(q̇)), which the selection did not name "
                    "on this joint")
        if self.added_viscous:
            how += (f"; fitted beside viscous friction {self.viscous[0]:.4g} ± "
                    f"{self.viscous_std[0]:.2g} N·m·s/rad, which the selection did not name "
                    "on this joint")
        return how


def friction_law(data: GapData, joint: int, remainder: np.ndarray, fitted: np.ndarray,
                 laws: Sequence[np.ndarray], slopes: Sequence[np.ndarray], cone: float,
                 cutoff: float, known: np.ndarray, far: np.ndarray,
                 fit: SetValuedFit | None = None) -> FrictionLaw | None:
    """:class:`FrictionLaw` of ``joint`` (module docstring): ``remainder`` (N,) is what every
    selected effect leaves, ``fitted`` (N,) the joint's selected friction as fitted, ``laws``
    its dry laws before the filter (``sign(q̇)`` is added when there are none, within a cone
    of its own amplitude), ``slopes`` its selected viscous signals (``q̇`` is added when there
    are none), ``cone`` the fitted static friction, ``cutoff`` the chain's low-pass
    (Hz), ``known`` (N,) the samples the model can predict, ``far`` (N,) those clear of rest;
    ``fit``: the same refit already made (with the same columns), else made here. ``None``
    where the set-valued refit cannot be made
    (:func:`~consistid.diagnosis.remainder.set_valued_refit`)."""
    added = not slopes
    columns = [data.dataset.dq[:, joint]] if added else list(slopes)
    dry_added = not laws
    if dry_added:        # viscous alone selected: the Coulomb step beside it, its cone unknown
        laws, cone = [np.sign(data.dataset.dq[:, joint])], np.inf

    def refit(rows: np.ndarray) -> SetValuedFit | None:
        return set_valued_refit(data, joint, remainder, fitted, laws, cone, cutoff, rows,
                                viscous=columns)

    main = fit if fit is not None and not (added or dry_added) else refit(known)
    if main is None:
        return None
    value = np.concatenate([main.dry, main.viscous])
    var = np.concatenate([main.dry_std, main.viscous_std]) ** 2
    clear = known & far
    alt = refit(clear) if clear.sum() >= FAR_SAMPLES else None
    if alt is not None:
        gap = np.maximum(np.concatenate([alt.dry_std, alt.viscous_std]) ** 2 - var, 0.0)
        delta = value - np.concatenate([alt.dry, alt.viscous])
        var = var + np.maximum(delta ** 2 - gap, gap)
    n = main.dry.size
    slow = _reads_a_slope(data, joint, main, known)
    if slow:
        var = var + _split_bias(data, joint, main, known, n)
    std = np.sqrt(var)
    return FrictionLaw(value[:n], value[n:], std[:n], std[n:], added,
                       int(clear.sum()) if alt is not None else 0, float(cutoff), slow,
                       dry_added)


def _top_speed(data: GapData, joint: int, known: np.ndarray) -> float:
    """The joint's fastest ``|q̇|`` (rad/s) on the known samples."""
    speed = np.abs(data.dataset.dq[known, joint])
    return float(speed.max()) if speed.size else 0.0


def _reads_a_slope(data: GapData, joint: int, fit: SetValuedFit, known: np.ndarray) -> bool:
    r"""Whether the law's split of dry and viscous friction is one the data cannot make, as
    ``identify`` judges a slow joint
    (:meth:`~consistid.identification.streaming.ResidualStatistics.slow_joints`): the joint
    reaches its fastest speed band (above ``SPEED_EDGES[-1]``) on fewer than
    ``MIN_REST_SAMPLES`` effectively independent samples (``n/τ``, ``τ`` the autocorrelation
    time of what the law leaves), and the fit reads a slope where a step should be, its dry
    level at most ``STEP_SHARE`` of its viscous torque at the top speed
    (``Σ a_k ≤ STEP_SHARE · f_v \max|q̇|``): MuJoCo's soft ``frictionloss`` on a wrist that
    never leaves its smoothing band rises linearly there, and the law takes it as viscous
    (the xArm7's joint 7 below 0.04 rad/s: ``f_c`` 0.000 ± 0.02 for 0.6, ``f_v``
    14.3 ± 0.7 for 0.3). Unlike ``identify`` it does not also ask the slope to be clear of 0
    (``SLOPE_Z``) nor apply the band test: it only widens σ, so it errs on the wide side."""
    if fit.viscous.size == 0:
        return False
    left = np.where(known, fit.remainder, 0.0)[:, None]
    tau = max(float(autocorrelation_time(data.dataset, left)[0]), 1.0)
    fast = np.sum(known & (np.abs(data.dataset.dq[:, joint]) > SPEED_EDGES[-1])) / tau
    top = _top_speed(data, joint, known)
    return bool(fast < MIN_REST_SAMPLES
                and np.sum(fit.dry) <= STEP_SHARE * float(np.sum(fit.viscous)) * top)


def _split_bias(data: GapData, joint: int, fit: SetValuedFit, known: np.ndarray, n: int
                ) -> np.ndarray:
    """``b²`` of each amplitude (dry ones first, then the viscous ones) for the split a slow
    joint's data cannot make: :func:`~consistid.identification.model_error.split_bias` of the
    law's summed dry level and viscous slope at the joint's top speed, ``(f_v v)²`` on each dry
    amplitude and ``f_v²`` on each viscous one."""
    names = ["joint.fc", "joint.fv"]
    b2 = split_bias(names, names, np.array([np.sum(fit.dry), np.sum(fit.viscous)]), ["joint"],
                    np.array([0]), np.array([_top_speed(data, joint, known)]))
    return np.concatenate([np.full(n, b2[0]), np.full(fit.viscous.size, b2[1])])
