r"""``elasticity``: a spring of compliance ``c_j = 1/k_j ≥ 0`` between the measured (motor-side)
position and the link, with the torque measured at the spring (the two-mass model; Spong 1987,
doi:10.1115/1.3143884): the link is at ``q − c_j τ_j e_j``, so to first order
``r = −c_j (∂τ/∂q_j τ_j + ∂τ/∂q̇_j τ̇_j + M_{:,j} τ̈_j)``. Acts on every joint; grows with
frequency towards the joint resonance. Reported as the stiffness ``k_j``."""

from __future__ import annotations

import numpy as np

from .base import Effect, EffectParameter


class Elasticity(Effect):
    name = "elasticity"
    order = 90
    signature = "spring deflection τ/k: grows with frequency towards a resonance"
    equation = "link at `q − τ_j/k_j` (first order)"
    unit = "rad/(N·m)"
    suffix = "compliance"
    wording = "stiffness"
    nonnegative = (0,)

    def columns(self, library, atom, data) -> np.ndarray:
        j = atom.joint
        tau, tau_d, tau_dd = (x[:, j] for x in data.tau_nom_derivatives)
        d_q, d_v, mass = data.rnea_derivatives
        col = d_q[:, :, j] * tau[:, None] + d_v[:, :, j] * tau_d[:, None] \
            + mass[:, :, j] * tau_dd[:, None]
        return -col[:, :, None]

    def parameters(self, library, atom, theta, std, joint, fit) -> list[EffectParameter]:
        if theta[0] > 0:
            c, sc = float(theta[0]), float(std[0])
            return [EffectParameter(f"{joint}.stiffness", 1.0 / c, sc / c ** 2, "N·m/rad", joint,
                                    self.name, wording=self.wording)]
        return [EffectParameter(atom.parameter_names[0], float(theta[0]), float(std[0]),
                                atom.units[0], joint, self.name, wording="compliance")]


EFFECT = Elasticity()
