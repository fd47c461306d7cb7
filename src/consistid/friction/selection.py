r"""Which friction law the held-out data prefer, joint by joint.

Each law (the linear ``f_c sign q̇`` — ``"coulomb"`` — and the nonlinear ones of
:mod:`consistid.friction.models`) is fitted on the training data with the rigid body
(:func:`consistid.friction.fit.identify_nonlinear`, the same law on every joint, viscous and
offset columns with all of them) and scored on held-out data:

.. math::  \mathrm{RMS}_{j}(\text{law}) = \sqrt{\tfrac{1}{|K_j|}\textstyle\sum_{k ∈ K_j}
           (τ_{kj} - \hat τ_{kj})^2}

over all held-out samples with ``|q̇_j| ≥ min_speed`` (the rows the fits use), and over the
low-speed band ``min_speed ≤ |q̇_j| < low_speed``, where the laws differ most. A joint
*prefers* the law with the smallest held-out RMS; :attr:`FrictionComparison.gain` says by how
much it beats the linear law (a preference worth a fraction of a percent is a tie in practice,
and the table shows it). Held-out scoring, not training fit, is what penalises the extra shape
parameters (a law that fits noise does worse on new data).

The best of the laws compared need not be a good one (a friction that depends on the position,
a dead band, hysteresis): the held-out torque noise floor ``σ_j``
(:func:`consistid.diagnosis.noise.estimate_noise_floor`, or ``sigma=``) is estimated on the
preferred law's residual, and a joint whose best held-out RMS exceeds
``REMAINDER_RATIO · σ_j`` (:mod:`consistid.diagnosis.remainder`, the diagnosis' rule for an
unexplained component) is listed in :attr:`FrictionComparison.unexplained`: none of the laws
describes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..data.dataset import Dataset
from ..diagnosis.noise import estimate_noise_floor
from ..diagnosis.remainder import REMAINDER_RATIO
from ..errors import OptionError, check_number
from ..identification.summary import table
from ..report.html import Page
from ..report.result import Reported
from ..robot.model import RobotModel
from .fit import NonlinearFrictionResult, identify_nonlinear
from .models import LINEAR, MODELS

#: Laws compared by default, the linear one first.
LAWS: tuple[str, ...] = (LINEAR, "stribeck", "sigmoid", "tanh")


@dataclass(frozen=True, eq=False)
class FrictionComparison(Reported):
    """Held-out scores of friction laws per joint (module docstring).

    Attributes
    ----------
    joint_names : (nv,) names.
    laws : the laws compared, in order.
    rms : (n_laws, nv) held-out RMS over ``|q̇_j| ≥ min_speed`` (N·m).
    low_rms : (n_laws, nv) held-out RMS in ``min_speed ≤ |q̇_j| < low_speed`` (NaN without
        such samples).
    n_low : (nv,) held-out samples in the low-speed band.
    train_rms : (n_laws, nv) training RMS.
    results : the fits, by law.
    method, low_speed, min_speed : the settings.
    noise_floor : (nv,) held-out torque noise σ (N·m; NaN where the estimate is unreliable:
        pass ``sigma=``), ``noise_source`` how it was obtained.
    """

    joint_names: tuple[str, ...]
    laws: tuple[str, ...]
    rms: np.ndarray
    low_rms: np.ndarray
    n_low: np.ndarray
    train_rms: np.ndarray
    method: str
    low_speed: float
    min_speed: float
    results: dict[str, NonlinearFrictionResult] = field(default_factory=dict)
    noise_floor: np.ndarray | None = None
    noise_source: str = ""

    @property
    def unexplained(self) -> tuple[str, ...]:
        """Joints whose best held-out RMS exceeds ``REMAINDER_RATIO`` × the noise floor: no law
        compared describes their friction (module docstring)."""
        if self.noise_floor is None:
            return ()
        best = np.min(self.rms, axis=0)
        return tuple(name for name, r, s in zip(self.joint_names, best, self.noise_floor)
                     if np.isfinite(s) and r > REMAINDER_RATIO * s)

    @property
    def preferred(self) -> tuple[str, ...]:
        """Per joint, the law with the smallest held-out RMS."""
        return tuple(self.laws[int(i)] for i in np.argmin(self.rms, axis=0))

    @property
    def preferred_low_speed(self) -> tuple[str, ...]:
        """Per joint, the law with the smallest held-out RMS at low speed."""
        filled = np.where(np.isfinite(self.low_rms), self.low_rms, np.inf)
        return tuple(self.laws[int(i)] for i in np.argmin(filled, axis=0))

    @property
    def gain(self) -> np.ndarray:
        """(nv,) held-out RMS of the linear law over that of the preferred one (≥ 1; 1 where
        the linear law is preferred or not compared: NaN)."""
        if LINEAR not in self.laws:
            return np.full(len(self.joint_names), np.nan)
        return self.rms[self.laws.index(LINEAR)] / np.min(self.rms, axis=0)

    def summary(self) -> str:
        head = [f"rms {law}" for law in self.laws] + [f"low {law}" for law in self.laws]
        rows = [[name, *self.rms[:, j], *self.low_rms[:, j], int(self.n_low[j]),
                 self.preferred[j], f"{self.gain[j]:.3f}", self.preferred_low_speed[j]]
                for j, name in enumerate(self.joint_names)]
        text = (f"friction laws on held-out data (method={self.method}; RMS in N·m over "
                f"|q̇| ≥ {self.min_speed:g} rad/s; 'low': {self.min_speed:g} ≤ |q̇| < "
                f"{self.low_speed:g} rad/s)\n")
        text += table(["joint", *head, "n low", "preferred", "linear/best",
                       "preferred (low)"], rows, floatfmt=".4g")
        return "\n".join([text, *self._floor_lines()])

    def _floor_lines(self) -> list[str]:
        """The noise floor and, where a joint's best law stays above it, the verdict that no
        law compared fits (the text summary and the HTML report alike)."""
        lines = []
        if self.noise_floor is not None:
            lines.append(f"noise floor (N·m) {self.noise_source}: "
                         + ", ".join(f"{n} {s:.4g}" for n, s in zip(self.joint_names,
                                                                     self.noise_floor)))
        if self.unexplained:
            best = np.min(self.rms, axis=0)
            lines.append("no law compared fits " + ", ".join(
                f"{n} (best {best[j]:.4g} = {best[j] / self.noise_floor[j]:.3g} × the noise)"
                for j, n in enumerate(self.joint_names) if n in self.unexplained) + (
                f": above {REMAINDER_RATIO:g} × the noise floor; their preferred law is only the "
                "least wrong (position-dependent friction, a dead band, hysteresis…? "
                "consistid.diagnose looks further)"))
        return lines

    def __str__(self) -> str:
        return self.summary()

    def page(self) -> Page:
        """The HTML report: held-out RMS of each law per joint, overall and at low speed, the
        noise floor and the joints no law fits (as :meth:`summary`)."""
        page = Page("consistid friction laws",
                    f"held-out RMS (N·m, method={self.method}) over |q̇| ≥ {self.min_speed:g} "
                    f"rad/s; low speed: {self.min_speed:g} ≤ |q̇| < {self.low_speed:g} rad/s")
        page.table(["joint", *[f"RMS {law}" for law in self.laws],
                    *[f"low {law}" for law in self.laws], "n low", "preferred",
                    "linear / best", "preferred at low speed"],
                   [[name, *self.rms[:, j], *self.low_rms[:, j], int(self.n_low[j]),
                     self.preferred[j], self.gain[j], self.preferred_low_speed[j]]
                    for j, name in enumerate(self.joint_names)])
        for line in self._floor_lines():
            page.paragraph(line)
        return page


def compare_friction_models(model: RobotModel, train: Dataset, held_out: Dataset,
                            laws: Sequence[str] = LAWS, method: str = "ols",
                            low_speed: float = 0.1, min_speed: float = 0.0,
                            covariance: str = "iid", sigma: float | Sequence[float] | None = None,
                            **options: Any) -> FrictionComparison:
    """Fit each law on ``train``, score on ``held_out`` (module docstring).

    ``method``, ``covariance`` and ``options`` (e.g. ``armature=True``, ``max_nfev``) go to
    :func:`consistid.friction.fit.identify_nonlinear`; ``min_speed`` leaves standstill rows out
    of the fits and the scores alike; ``sigma`` (N·m, a number or per joint): the torque noise,
    default estimated on the held-out data (module docstring).
    """
    laws = tuple(laws)
    unknown = [law for law in laws if law != LINEAR and law not in MODELS]
    if unknown or not laws:
        raise OptionError(f"laws {unknown or '(none)'} are not known; choose among "
                          f"{[LINEAR, *MODELS]}")
    low_speed = check_number("low_speed", low_speed, 0, strict=True)
    min_speed = check_number("min_speed", min_speed, 0)
    held_out.check_joints(model.nv, model.joint_names)
    tau = held_out.require_torque()
    speed = np.abs(held_out.dq)
    used = speed >= min_speed
    low = used & (speed < low_speed)
    if sigma is not None:
        try:
            given = np.broadcast_to(np.asarray(sigma, dtype=float), (model.nv,)).copy()
        except (TypeError, ValueError):            # not numbers, or not 1 or nv of them
            given = np.array([np.nan])
        if not np.all(np.isfinite(given) & (given > 0)):
            raise OptionError(f"sigma must be a positive torque noise (N·m), one number or "
                              f"one per joint ({model.nv}), got {sigma!r}")
        sigma = given
    results, rms, low_rms, train_rms, predictions = {}, [], [], [], []
    for law in laws:
        res = identify_nonlinear(model, train, method, {j: law for j in range(model.nv)},
                                 covariance=covariance, min_speed=min_speed, **options)
        predictions.append(res.predict(held_out))
        e2 = (tau - predictions[-1]) ** 2
        results[law] = res
        rms.append(np.sqrt(np.sum(e2 * used, axis=0) / np.maximum(used.sum(axis=0), 1)))
        with np.errstate(invalid="ignore"):
            low_rms.append(np.sqrt(np.sum(e2 * low, axis=0) / low.sum(axis=0)))
        train_rms.append(res.train_rms)
    rms_arr = np.array(rms)
    best = np.take_along_axis(np.array(predictions), np.argmin(rms_arr, axis=0)[None, None, :],
                              axis=0)[0]
    floor = estimate_noise_floor(held_out, tau, tau - best, best, sigma=sigma)
    # a floor the spectrum cannot see (torques filtered below the motion band) judges nothing
    return FrictionComparison(tuple(model.joint_names), laws, rms_arr, np.array(low_rms),
                              low.sum(axis=0), np.array(train_rms), method, low_speed,
                              min_speed, results,
                              np.where(floor.reliable, floor.sigma, np.nan), floor.description)
