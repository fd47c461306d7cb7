"""Names of the per-joint (non-rigid-body) terms of the torque model: friction, offset, armature.

Per joint ``j``: ``τ_f = fc·sign(q̇) + fv·q̇ + fo + ps1·sin q + pc1·cos q`` and ``Ia·q̈`` (names
``"<joint>.fc"`` …). They sit at the bottom of the package so that the URDF writer, the regressor
and the results name the same columns the same way.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import InconsistentParametersError, ModelError

if TYPE_CHECKING:
    from .model import RobotModel

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
#: Every per-joint column suffix (``fc``, ``fv``, ``fo``, ``ps1``, ``pc1``, ``Ia``).
SUFFIXES: tuple[str, ...] = tuple(s for suffixes in TERM_COLUMNS.values() for s in suffixes)
#: Below this joint speed (rad/s) a joint is taken to stand still: stiction holds it with any
#: torque up to the break-away, which no law of ``q̇`` predicts. The nonlinear friction fits
#: leave such rows out by default, the break-away estimate detects motion above it, and a
#: result's ``residual(..., at_rest="cone")`` judges such samples against the friction cone.
STANDSTILL_SPEED = 0.02


#: Per-joint term suffix → the MJCF ``<joint>`` attribute that holds it …
MJCF_ATTRIBUTES = {"fv": "damping", "fc": "frictionloss", "Ia": "armature"}
#: … and the URDF ``<dynamics>`` attribute.
URDF_ATTRIBUTES = {"fc": "friction", "fv": "damping"}


def check_nonnegative(terms: dict[str, dict[str, float]], attributes: dict[str, str],
                      element: str) -> None:
    """:class:`InconsistentParametersError` naming the first joint term that a model file
    holds as one of ``attributes`` (suffix → attribute of ``element``, e.g. "an MJCF joint")
    and that is negative: friction, damping and armature are ≥ 0 there."""
    for joint, values in terms.items():
        for term, attr in attributes.items():
            if values.get(term, 0.0) < 0:
                raise InconsistentParametersError(
                    f"joint {joint!r}: negative {attr} {values[term]:.6g} ({element}'s {attr} "
                    "must be ≥ 0)")


def export_parameters(model: "RobotModel", parameters: np.ndarray | None,
                      names: Sequence[str] | None
                      ) -> tuple[np.ndarray, dict[str, dict[str, float]]]:
    """What a model writer (URDF, MJCF) writes: the parameter vector (default the model's own
    inertias), checked finite and at least ``10·nbodies`` long, and its per-joint terms
    (:func:`joint_terms_of`)."""
    params = (model.prior_parameters if parameters is None
              else np.asarray(parameters, dtype=float))
    if params.ndim != 1 or params.size < model.n_inertial or not np.all(np.isfinite(params)):
        raise ModelError(f"parameters must be a finite vector of at least {model.n_inertial} "
                         f"entries, got shape {params.shape}")
    return params, joint_terms_of(model, params, names)


def joint_terms_of(model: "RobotModel", parameters: np.ndarray,
                   names: Sequence[str] | None) -> dict[str, dict[str, float]]:
    """``{joint: {"fc": …, "fv": …, "fo": …, "ps1": …, "pc1": …, "Ia": …}}`` from the entries of
    ``parameters`` after the ``10·nbodies`` inertial ones, placed by their ``names``
    (``"<joint>.<suffix>"``); what the URDF and MJCF writers put into each joint."""
    extra = parameters[model.n_inertial:]
    if extra.size == 0:
        return {}
    if names is None or len(names) != parameters.size:
        raise ModelError(f"{extra.size} entries after the inertial parameters need "
                         "parameter_names (e.g. 'panda_joint1.fc') to be placed")
    out: dict[str, dict[str, float]] = {}
    for name, value in zip(names[model.n_inertial:], extra):
        joint, _, term = name.rpartition(".")
        if joint not in model.joint_names or term not in SUFFIXES:
            raise ModelError(f"cannot place parameter {name!r}: expected "
                             f"'<joint>.{'|'.join(SUFFIXES)}'")
        out.setdefault(joint, {})[term] = float(value)
    return out
