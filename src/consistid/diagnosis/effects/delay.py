r"""``delay``: the torque channel lags the position channel by ``d``:
``τ_meas(t) = τ(t − d)``, so ``r ≈ −d τ̇_nom`` (first order; :func:`consistid.diagnose` refines it
exactly, ``τ_nom(t − d) − τ_nom(t)``), in quadrature with the torque and growing with frequency.
Offered per joint and as one delay common to all channels."""

from __future__ import annotations

import numpy as np

from .base import Atom, Effect, on_row


class Delay(Effect):
    name = "delay"
    order = 80
    signature = "≈ −d·τ̇: in quadrature with the torque, grows with frequency"
    equation = "`τ_nom(t − d) − τ_nom(t)` (per joint or common)"
    unit = "s"
    suffix = "delay"
    wording = "delay"
    scope = "both"

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        return [Atom(self.name, None, ("delay",), ("s",)),
                *super().atoms(library, tuning, residual)]

    def columns(self, library, atom, data) -> np.ndarray:
        rate = data.tau_nom_derivatives[1]
        if atom.joint is None:
            return -rate[:, :, None]
        return on_row(data, atom.joint, -rate[:, atom.joint])


EFFECT = Delay()
