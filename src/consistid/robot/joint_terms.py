"""Names of the per-joint (non-rigid-body) terms of the torque model: friction, offset, armature.

Per joint ``j``: ``τ_f = fc·sign(q̇) + fv·q̇ + fo + ps1·sin q + pc1·cos q`` and ``Ia·q̈`` (names
``"<joint>.fc"`` …). They sit at the bottom of the package so that the URDF writer, the regressor
and the results name the same columns the same way.
"""

from __future__ import annotations

JOINT_TERMS: tuple[str, ...] = ("coulomb", "viscous", "offset", "position", "armature")
#: The terms chosen through ``friction=`` (every term but armature).
FRICTION_TERMS: tuple[str, ...] = JOINT_TERMS[:4]
#: Name suffixes of each term's columns, per enabled joint, in column order.
TERM_COLUMNS: dict[str, tuple[str, ...]] = {
    "coulomb": ("fc",), "viscous": ("fv",), "offset": ("fo",), "position": ("ps1", "pc1"),
    "armature": ("Ia",)}
#: The default ``friction=`` of :meth:`RegressorSpec.make`, ``identify``, ``recover_standard`` …
DEFAULT_FRICTION: tuple[str, ...] = ("coulomb", "viscous", "offset")
#: Terms whose values are physically ``≥ 0`` (``offset`` and ``position`` have a free sign).
NONNEGATIVE_TERMS: tuple[str, ...] = ("coulomb", "viscous", "armature")
