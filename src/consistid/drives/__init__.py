"""Drives: what lies between a robot's motors and its joints.

:mod:`~consistid.drives.transmission` (gear ratios, coupling, torque constants: motor-side logs
in, joint-side quantities out), :mod:`~consistid.drives.motor_terms` (regressor columns of a
coupled motor's rotor inertia and friction), :mod:`~consistid.drives.coupled` (identification
with those columns) and :mod:`~consistid.drives.gains` (drive gains from motor currents and a
load of known mass, Gautier & Briot 2014).
"""

from .transmission import Transmission

__all__ = ["Transmission"]
