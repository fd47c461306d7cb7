r"""``viscous``: ``r_j = f_v q̇_j`` with ``f_v ≥ 0``, a straight line through the origin in
residual-versus-velocity."""

from __future__ import annotations

import numpy as np

from ...identification.regressor import TERM_COLUMNS
from .base import Effect


class Viscous(Effect):
    name = "viscous"
    order = 30
    signature = "a line through the origin in residual-versus-velocity"
    equation = "`f_v q̇_j`"
    unit = "N·m·s/rad"
    suffix = TERM_COLUMNS["viscous"][0]
    wording = "viscous friction"
    nonnegative = (0,)
    row_only = True

    def row(self, library, atom, data) -> np.ndarray:
        return data.dataset.dq[:, atom.joint]


EFFECT = Viscous()
