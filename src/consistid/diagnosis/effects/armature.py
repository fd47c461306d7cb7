r"""``armature``: rotor inertia reflected through the gear, ``r_j = I_a q̈_j`` on joint ``j`` alone
(Pinocchio's ``model.armature``), ``I_a ≥ 0``."""

from __future__ import annotations

import numpy as np

from ...identification.regressor import TERM_COLUMNS
from .base import Effect


class Armature(Effect):
    name = "armature"
    order = 60
    signature = "proportional to the joint's own acceleration q̈_j"
    equation = "`I_a q̈_j`"
    unit = "kg·m²"
    suffix = TERM_COLUMNS["armature"][0]
    wording = "armature"
    nonnegative = (0,)
    row_only = True

    def row(self, library, atom, data) -> np.ndarray:
        return data.dataset.ddq[:, atom.joint]


EFFECT = Armature()
