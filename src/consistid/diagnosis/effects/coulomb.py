r"""``coulomb``: dry friction, ``r_j = f_c L[tanh(q̇_j / v_s)]`` (``v_s = 0``: ``sign``) with
``f_c ≥ 0``: a step at ``q̇_j = 0`` in residual-versus-velocity. The smoothing speed ``v_s`` (a
smooth friction law) is chosen from :data:`COULOMB_SPEEDS` and ``L`` from
:data:`~consistid.diagnosis.effects.base.FILTER_CUTOFFS` on the training data: ``L`` is the
identity, or, when the torques were low-pass filtered, the zero-phase Butterworth filter of the
signal chain (:func:`consistid.data.signals.lowpass`) at cut-off ``f_c``, which smears the step
over its response time and does not commute with the sign."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...identification.regressor import TERM_COLUMNS
from ..gapdata import smooth_sign
from .base import Effect, EffectParameter, tune_cutoffs

#: Smoothing speeds (rad/s) tried for the ``coulomb`` atom; 0 is the sign function.
COULOMB_SPEEDS: tuple[float, ...] = (0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1)


class Coulomb(Effect):
    name = "coulomb"
    order = 20
    signature = "a step at q̇ = 0 in residual-versus-velocity"
    equation = "`f_c L[tanh(q̇_j/v_s)]`, `v_s` and the filter `L` tuned"
    unit = "N·m"
    row_only = True
    suffix = TERM_COLUMNS["coulomb"][0]
    wording = "Coulomb friction"
    nonnegative = (0,)
    tuned = True

    def unfiltered(self, library, atom, data) -> np.ndarray:
        return smooth_sign(data.dataset.dq[:, atom.joint], atom.setting or 0.0)

    def tune(self, library, data, residual, atom):
        """The smoothing speed of :data:`COULOMB_SPEEDS` and the cut-off
        (:func:`~consistid.diagnosis.effects.base.tune_cutoffs`) that together explain most of
        ``residual`` (N,)."""
        trials = tune_cutoffs(self, library, data, residual,
                              [replace(atom, setting=v) for v in COULOMB_SPEEDS])
        return max(trials, key=lambda t: t[1])[0]

    def parameters(self, library, atom, theta, std, joint, fit) -> list[EffectParameter]:
        note = ""
        if atom.setting or np.isfinite(atom.cutoff):
            law = f"tanh(q̇/{atom.setting:g} rad/s)" if atom.setting else "sign(q̇)"
            seen = (f" seen through a ≈{atom.cutoff:.3g} Hz low-pass"
                    if np.isfinite(atom.cutoff) else "")
            note = law + seen
        return [EffectParameter(f"{joint}.fc", float(theta[0]), float(std[0]), self.unit, joint,
                                self.name, note, self.wording)]


EFFECT = Coulomb()
