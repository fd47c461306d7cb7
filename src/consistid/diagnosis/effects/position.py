r"""``position``: a torque that turns with the joint, once per revolution,
``r_j = p_s sin q_j + p_c cos q_j`` (the identification's ``position`` columns, names
``<joint>.ps1``, ``.pc1``), offered on every joint without a search. Physically: cross-talk of
the bending moments a joint torque sensor carries, whose direction in the sensor frame turns with
the joint (Lee, Kim & Song 2010, doi:10.1007/s12541-010-0025-0), or a mounting eccentricity or
misalignment of sensor or bearing. Needs no full period in the data; over a small range it is
nearly ``offset``. Where a link's gravity torque on its joint is exactly ``a sin q_j + b cos q_j``
the atom lies in the span of ``inertia`` (reported as indistinguishable alternatives). The torque
filter is ignored: ``|q̇_j| / 2π`` stays far below the cut-offs."""

from __future__ import annotations

import numpy as np

from ...identification.regressor import TERM_COLUMNS, RegressorSpec, joint_columns
from .base import Atom, Effect


class Position(Effect):
    name = "position"
    order = 110
    signature = "turns with the joint, once per revolution: a sin q_j + b cos q_j"
    equation = ("`p_s sin q_j + p_c cos q_j` (the identification's `position` columns, "
                "`<joint>.ps1`, `.pc1`)")
    unit = "N·m"

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        names = library.model.joint_names
        return [Atom(self.name, j, tuple(f"{names[j]}.{c}" for c in TERM_COLUMNS[self.name]),
                     (self.unit,) * 2) for j in range(library.model.nv)]

    row_only = True

    def columns(self, library, atom, data) -> np.ndarray:
        d = data.dataset
        spec = RegressorSpec.make(library.model, {"position": [atom.joint]})
        return joint_columns(d.q, d.dq, d.ddq, spec)

    def row(self, library, atom, data) -> np.ndarray:
        return self.columns(library, atom, data)[:, atom.joint, :]


EFFECT = Position()
