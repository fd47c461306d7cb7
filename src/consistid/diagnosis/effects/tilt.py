r"""``tilt``: the robot's base is not level. Gravity in the base frame is
``g(a) = R_v(a₂) R_u(a₁) g₀`` (rad; for ``g₀ ∥ −z`` roll ``a₁`` about the base ``x`` axis, then
pitch ``a₂`` about ``y``) instead of the URDF's ``g₀``. The torques are linear in gravity
(:mod:`consistid.estimation.mounting`), and ``∂g/∂a₁ = u × g₀``, ``∂g/∂a₂ = v × g₀`` at ``a = 0``
(:func:`consistid.diagnosis.gapdata.tilt_directions`), so to first order

.. math::  r = a_1\, Y(q, 0, 0;\, u \times g_0)\, \pi_0 + a_2\, Y(q, 0, 0;\, v \times g_0)\, \pi_0,

one arm-wide atom of two parameters. It loads a vertical first joint, which a level base leaves
without gravity torque, with a torque that turns with ``q₁``; on the other joints it shows as a
gravity torque of the wrong direction, partly inside the span of ``inertia`` (only the first
joint's motion tells the two apart). First order, with the nominal ``π₀``: ``O(a²)`` of the
gravity torque is left out (1.5·10⁻⁴ of it at 1°). Offered only for a model with gravity."""

from __future__ import annotations

import numpy as np

from .base import Atom, Effect


class Tilt(Effect):
    name = "tilt"
    order = 120
    signature = "gravity torque of a tilted base, also on a vertical first joint (turns with it)"
    equation = ("the base is not level: gravity `R_v(a₂) R_u(a₁) g₀`, first order "
                "`a₁ Y(q,0,0; u×g₀) π₀ + a₂ Y(q,0,0; v×g₀) π₀`")
    unit = "rad"
    scope = "arm"

    def atoms(self, library, tuning=None, residual=None) -> list[Atom]:
        if not np.any(library.model.gravity):
            return []
        return [Atom(self.name, None, ("tilt.roll", "tilt.pitch"), (self.unit,) * 2)]

    def columns(self, library, atom, data) -> np.ndarray:
        return data.tilt_gravity


EFFECT = Tilt()
