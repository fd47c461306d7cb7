r"""Regressor columns of the motor-side terms of coupled motors (rotor inertia and friction).

Motor ``m`` of a :class:`~consistid.drives.transmission.Transmission` turns at
``q̇_m = r_m\, g_m^\top q̇`` (``g_m^\top`` row ``m`` of the coupling ``G``). Its rotor inertia
``I_{a,m}``, viscous friction ``f_{v,m}`` and Coulomb friction ``f_{s,m}`` act on the motor
shaft; mapped to the joints by ``τ = G^\top \operatorname{diag}(r)\, τ_m``
(Khalil & Dombre, *Modeling, Identification and Control of Robots*, §9.3 and §12.5):

.. math::

    τ_{(m)} = r_m^2\, g_m\, (g_m^\top \ddot q)\, I_{a,m}
            + r_m^2\, g_m\, (g_m^\top \dot q)\, f_{v,m}
            + |r_m|\, g_m \operatorname{sign}(g_m^\top \dot q)\, f_{s,m} .

For a motor that drives one joint (``g_m = e_j``) these are the joint's own armature, viscous
and Coulomb columns scaled by ``r_m^2``, ``r_m^2``, ``|r_m|``
(:mod:`consistid.identification.regressor`). For a coupled motor they are not: one coefficient
enters several joints' rows, with the cross terms of the coupled wrist (FIGAROH's TX40
``Iam6``, ``fvm6``, ``fsm6``). This module builds these columns for the coupled motors only, in
motor-side units (kg·m², N·m·s/rad, N·m at the motor), named ``"<name>.Iam<m+1>"``,
``".fvm<m+1>"``, ``".fsm<m+1>"``.
"""

from __future__ import annotations

import numpy as np

from .transmission import Transmission

#: Motor-side terms, their column suffixes, in column order per coupled motor.
MOTOR_TERMS = ("Iam", "fvm", "fsm")


def motor_column_names(transmission: Transmission) -> list[str]:
    """Names of the columns of :func:`motor_columns`, motor by motor."""
    return [f"{transmission.name}.{term}{m + 1}" for m in transmission.coupled_motors
            for term in MOTOR_TERMS]


def motor_columns(transmission: Transmission, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """The coupled motors' columns for samples ``(N, n)``, shape ``(N, n, 3·n_coupled)``
    (module docstring)."""
    dq, ddq = np.asarray(dq, dtype=float), np.asarray(ddq, dtype=float)
    motors = transmission.coupled_motors
    out = np.zeros((*dq.shape, 3 * motors.size))
    for k, m in enumerate(motors):
        g, r = transmission.coupling[m], transmission.ratios[m]
        speed = dq @ g
        out[:, :, 3 * k] = r ** 2 * np.outer(ddq @ g, g)
        out[:, :, 3 * k + 1] = r ** 2 * np.outer(speed, g)
        out[:, :, 3 * k + 2] = abs(r) * np.outer(np.sign(speed), g)
    return out
