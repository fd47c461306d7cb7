r"""``offset``: ``r_j = f_o``, a constant bias, the same at rest and moving either way (a
torque-sensor offset). No sign rule."""

from __future__ import annotations

import numpy as np

from ...identification.regressor import TERM_COLUMNS
from .base import Effect


class Offset(Effect):
    name = "offset"
    order = 40
    signature = "a constant bias, at rest and moving either way"
    equation = "`f_o`"
    unit = "N·m"
    suffix = TERM_COLUMNS["offset"][0]
    row_only = True
    wording = "torque offset"

    def row(self, library, atom, data) -> np.ndarray:
        return np.ones(data.n)


EFFECT = Offset()
