r"""``inertia``: rigid-body parameter mismatch, ``r = W_b δβ`` with ``W_b`` the base regressor
(Gautier 1991, doi:10.1002/rob.4620080405). Couples joints, scales with q̈ and with
gravity-loaded poses. :func:`consistid.diagnose` finally fits it by the consistent SDP near the
nominal (``inertia_solver="sdp"``)."""

from __future__ import annotations

import numpy as np

from .base import INERTIAL_UNITS, Atom, Effect, EffectParameter


class Inertia(Effect):
    name = "inertia"
    order = 10
    signature = "follows the rigid-body regressor: scales with q̈ and gravity poses, couples joints"
    equation = ("`W_b δβ` (base parameters); finally fitted by the consistent SDP with a "
                "log-det prior around the nominal")
    scope = "arm"
    #: scored with every joint's friction free beside it (the interaction module)
    companions = ("coulomb", "viscous")

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        base = library.base
        units = tuple(INERTIAL_UNITS[n.rstrip("*").split(".")[-1]] for n in base.names)
        return [Atom(self.name, None, tuple(f"δ{n}" for n in base.names), units)]

    def columns(self, library, atom, data) -> np.ndarray:
        return data.rigid[..., library.base.independent]

    def parameters(self, library, atom, theta, std, joint, fit) -> list[EffectParameter]:
        """The six base-parameter changes most significant against their deviations."""
        beta = (library.base.project(fit.inertial - fit.nominal) if fit.inertial is not None
                else theta)
        z = np.abs(beta) / np.where(std > 0, std, np.inf)
        return [EffectParameter(atom.parameter_names[i], float(beta[i]), float(std[i]),
                                atom.units[i], None, self.name) for i in np.argsort(-z)[:6]]


EFFECT = Inertia()
