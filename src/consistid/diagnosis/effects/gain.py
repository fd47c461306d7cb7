r"""``gain``: a torque-channel scale error, ``τ_meas,j = (1 + g_j) τ_j``, so
``r_j = g_j τ_nom,j``: proportional to the joint's own torque. Either sign."""

from __future__ import annotations

import numpy as np

from .base import Effect


class Gain(Effect):
    name = "gain"
    order = 50
    signature = "proportional to the joint's own torque"
    equation = "`g_j τ_nom,j`"
    suffix = "gain"
    row_only = True
    wording = "torque gain error"

    def row(self, library, atom, data) -> np.ndarray:
        return data.tau_nom[:, atom.joint]


EFFECT = Gain()
