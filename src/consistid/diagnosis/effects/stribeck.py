r"""``stribeck``: the Stribeck hump that a linear Coulomb friction leaves near ``q̇ = 0``,
``r_j = Δf L[sign(q̇_j) e^{-(q̇_j/v_s)^2}]`` with ``Δf = f_s − f_c ≥ 0`` (static over Coulomb
friction): in residual-versus-velocity, a step at ``q̇ = 0`` that decays back within ``±v_s``
(the Stribeck curve of :mod:`consistid.friction.models` with ``δ = 2``, its Coulomb part being
the ``coulomb`` effect). ``v_s`` is chosen from :data:`STRIBECK_SPEEDS` and the filter ``L`` from
:data:`~consistid.diagnosis.effects.base.FILTER_CUTOFFS` on the training data, as for the
``coulomb`` effect. To identify the full law with the rigid body, use
``consistid.identify(..., friction={joint: "stribeck"})``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...friction.models import MODELS
from .base import Effect, EffectParameter, tune_cutoffs

#: Stribeck speeds ``v_s`` (rad/s) tried: a hump within the low-velocity range.
STRIBECK_SPEEDS: tuple[float, ...] = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2)
#: The Stribeck exponent ``δ`` of the hump (Gaussian, the classic choice).
STRIBECK_EXPONENT = 2.0


class StribeckHump(Effect):
    name = "stribeck"
    order = 22
    signature = "a step at q̇ = 0 that decays within ±v_s (a hump beside the Coulomb step)"
    equation = "`Δf L[sign(q̇_j) exp(−(q̇_j/v_s)²)]`, `Δf = f_s − f_c`, `v_s` and `L` tuned"
    unit = "N·m"
    row_only = True
    suffix = "dfs"
    wording = "Stribeck excess of static over Coulomb friction"
    nonnegative = (0,)
    tuned = True

    def unfiltered(self, library, atom, data) -> np.ndarray:
        """The hump; on torques the signal chain did not low-pass filter, 0 where
        ``sign(q̇_j)`` is not resolved
        (:attr:`~consistid.diagnosis.gapdata.GapData.sign_unresolved`): a joint held there
        carries any torque within its friction cone, and fitting ``±Δf`` to it pulls ``Δf``
        towards the mean held torque (on the Panda, ``Δf`` 0.25 N·m at ``v_s`` 0.05 rad/s
        was fitted 0.18 with the 1.5 % of samples at rest, 0.249 without). Through a recorded
        low-pass the held torque reaches the neighbouring samples too: the set-valued refit of
        the verdict (:func:`~consistid.diagnosis.remainder.set_valued_refit`) treats that, and
        zeroing the unresolved samples alone named a hump the simulator did not have (the
        example Panda, joint 6)."""
        speed = atom.setting or STRIBECK_SPEEDS[0]
        hump = MODELS["stribeck"].columns(data.dataset.dq[:, atom.joint],
                                          np.array([speed, STRIBECK_EXPONENT]))[:, 1]
        if data.dataset.torque_filter is not None:
            return hump
        return np.where(data.sign_unresolved[:, atom.joint], 0.0, hump)

    def tune(self, library, data, residual, atom):
        """The speed of :data:`STRIBECK_SPEEDS` and the cut-off that explain most of
        ``residual`` (N,) *beside the Coulomb step* (:func:`~consistid.diagnosis.effects.base.
        tune_cutoffs` of the columns ``[sign(q̇_j), hump]``): tuned alone on a residual that
        holds the Coulomb step too, the widest hump wins by standing in for the step."""
        trials = tune_cutoffs(_BesideCoulomb(), library, data, residual,
                              [replace(atom, setting=v) for v in STRIBECK_SPEEDS])
        return max(trials, key=lambda t: t[1])[0]

    def parameters(self, library, atom, theta, std, joint, fit) -> list[EffectParameter]:
        seen = (f", seen through a ≈{atom.cutoff:.3g} Hz low-pass"
                if np.isfinite(atom.cutoff) else "")
        return [EffectParameter(f"{joint}.{self.suffix}", float(theta[0]), float(std[0]),
                                self.unit, joint, self.name,
                                f"v_s = {atom.setting:g} rad/s{seen}", self.wording)]


class _BesideCoulomb:
    """The hump's tuning signal: the Coulomb step ``sign(q̇_j)`` and the hump, so that a speed
    is scored by what the hump explains beyond the step."""

    def unfiltered(self, library, atom, data) -> np.ndarray:
        return np.column_stack([np.sign(data.dataset.dq[:, atom.joint]),
                                EFFECT.unfiltered(library, atom, data)])


EFFECT = StribeckHump()
