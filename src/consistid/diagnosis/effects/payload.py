r"""``payload``: a rigid load on the last body, ``r = Y_n δπ_n`` (the regressor block of the last
body; a subset of ``inertia``). Acts on every joint, following the flange pose; its mass (the
first parameter) must be ≥ 0."""

from __future__ import annotations

import numpy as np

from ...robot.inertia import INERTIAL_NAMES
from .base import INERTIAL_UNITS, Atom, Effect


class Payload(Effect):
    name = "payload"
    order = 70
    signature = "a load on the last body: gravity/inertia residual on all joints"
    equation = "last body's 10 parameters"
    scope = "arm"
    #: scored with every joint's friction free beside it (the interaction module)
    companions = ("coulomb", "viscous")
    nonnegative = (0,)

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        return [Atom(self.name, None, tuple(f"payload.{p}" for p in INERTIAL_NAMES),
                     tuple(INERTIAL_UNITS[p] for p in INERTIAL_NAMES))]

    def columns(self, library, atom, data) -> np.ndarray:
        return data.rigid[..., -10:]


EFFECT = Payload()
