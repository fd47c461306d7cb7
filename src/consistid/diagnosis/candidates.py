r"""The candidate effects for one robot: which atoms to try and their columns, from the registry.

The nominal (simulator) model predicts ``τ_nom = Y(q, q̇, q̈) π₀``. An effect adds a correction
that is linear in its parameters ``θ`` once its *setting* (a harmonic order) is fixed:

.. math::  \tau \approx \tau_\text{nom} + \Phi_e(q, \dot q, \ddot q, \tau_\text{nom})\,\theta_e

Each effect is one class in its own module of :mod:`consistid.diagnosis.effects` (name,
signature, columns, parameter names and units, physical sign rules, wording; the module
docstrings give each equation and its source); the registry lists them.
:class:`EffectLibrary` selects effects of the registry for one robot, builds their *atoms* (the
effect on one joint, ``coulomb`` on joint 3, or on the whole arm, ``inertia``, ``payload``,
``tilt``, a ``delay`` common to all channels) and evaluates their columns on
:class:`~consistid.diagnosis.gapdata.GapData`. :mod:`consistid.diagnosis.diagnose` selects atoms
greedily by their held-out residual reduction. The linearisations (delay, elasticity, tilt) are
first-order Taylor expansions; :mod:`consistid.diagnosis.diagnose` refines the delay exactly
afterwards.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ModelError
from ..identification.base import BaseParameters, compute_base_parameters
from ..robot.model import RobotModel
from .effects import EFFECT_NAMES, REGISTRY, Atom, Effect, EffectParameter, effect
from .effects.base import FILTER_CUTOFFS, INERTIAL_UNITS, tune_cutoff
from .effects.coulomb import COULOMB_SPEEDS
from .effects.ripple import ripple_order
from .gapdata import (
    DERIVATIVE_WINDOW,
    GapData,
    lowpass_segments,
    smooth_sign,
    tilt_directions,
    time_derivatives,
)

#: How each effect shows in the residual (from the registry).
SIGNATURES: dict[str, str] = {name: e.signature for name, e in REGISTRY.items()}
#: Unit of each effect's per-joint parameter (from the registry).
UNITS: dict[str, str] = {name: e.unit for name, e in REGISTRY.items()}

__all__ = [
    "COULOMB_SPEEDS",
    "DERIVATIVE_WINDOW",
    "EFFECT_NAMES",
    "FILTER_CUTOFFS",
    "INERTIAL_UNITS",
    "SIGNATURES",
    "UNITS",
    "Atom",
    "Effect",
    "EffectLibrary",
    "EffectParameter",
    "GapData",
    "lowpass_segments",
    "smooth_sign",
    "tilt_directions",
    "time_derivatives",
]


class EffectLibrary:
    """The candidate effects for one robot: builds atoms and evaluates their columns.

    Parameters
    ----------
    model : the robot.
    effects : names among :data:`EFFECT_NAMES` (the registry of
        :mod:`consistid.diagnosis.effects`).
    base : base parameters of the rigid body (computed when ``None``); the ``inertia`` atom's
        columns are the base regressor.
    ripple_orders : (min, max) integer ripple orders ``k`` searched (min is further raised so that
        the joint's range holds two periods, max lowered by the sampling rate and speed so that
        ``k·|q̇|·Δt < π/2``; order 1 is the ``position`` effect).
    """

    def __init__(self, model: RobotModel, effects: tuple[str, ...] | list[str] = EFFECT_NAMES,
                 base: BaseParameters | None = None,
                 ripple_orders: tuple[int, int] = (2, 400)) -> None:
        for e in effects:
            effect(e)
        if len(set(effects)) != len(effects):
            raise ModelError(f"effects list {list(effects)} names an effect twice")
        self.model = model
        self.effects = tuple(effects)
        self.base = base if base is not None else compute_base_parameters(model)
        self.ripple_orders = ripple_orders

    def effect(self, name: str) -> Effect:
        """The registered effect ``name``."""
        return REGISTRY[name]

    # ----------------------------------------------------------------------------- atoms
    def atoms(self, tuning: GapData | None = None,
              tuning_residual: np.ndarray | None = None) -> list[Atom]:
        """All candidate atoms, effect by effect in the order of :attr:`effects`; the atoms of a
        *searched* effect (``ripple`` orders) are found on ``tuning_residual`` (N, nv) of the
        ``tuning`` data (needed when such an effect is among the effects)."""
        out: list[Atom] = []
        for name in self.effects:
            out += REGISTRY[name].atoms(self, tuning, tuning_residual)
        return out

    def columns(self, atom: Atom, data: GapData) -> np.ndarray:
        """The atom's columns on ``data``, shape ``(N, nv, n_parameters)``."""
        return REGISTRY[atom.effect].columns(self, atom, data)

    def matrix(self, atoms: list[Atom], data: GapData) -> np.ndarray:
        """Every atom's columns side by side, ``(N, nv, Σ n_parameters)``: the concatenation of
        :meth:`columns` along the last axis, filled in place; a ``row_only`` effect's atom
        writes only its joint's row (:meth:`Effect.row`) into the zeros, not ``nv − 1`` rows of
        zeros too (a seventh of the memory traffic on a 7-joint arm)."""
        sizes = [a.n_parameters for a in atoms]
        out = np.zeros((data.n, data.nv, sum(sizes)))
        o = 0
        for a, k in zip(atoms, sizes):
            eff = REGISTRY[a.effect]
            if eff.row_only and a.joint is not None:
                out[:, a.joint, o:o + k] = np.reshape(eff.row(self, a, data), (data.n, k))
            else:
                out[:, :, o:o + k] = eff.columns(self, a, data)
            o += k
        return out

    # ----------------------------------------------------------------------------- tuning
    def tune_cutoff(self, data: GapData, residual: np.ndarray, atom: Atom
                    ) -> tuple[Atom, float]:
        """See :func:`consistid.diagnosis.effects.base.tune_cutoff`."""
        return tune_cutoff(REGISTRY[atom.effect], self, data, residual, atom)

    def tune(self, data: GapData, residual: np.ndarray, atom: Atom) -> Atom:
        """The atom with its nonlinear setting tuned on ``residual`` (N,) by its effect."""
        return REGISTRY[atom.effect].tune(self, data, residual, atom)

    def tune_coulomb(self, data: GapData, residual: np.ndarray, atom: Atom) -> Atom:
        """The Coulomb atom with its smoothing speed and cut-off tuned (:meth:`tune`)."""
        return self.tune(data, residual, replace(atom, effect="coulomb"))

    def ripple_order(self, data: GapData, residual: np.ndarray, joint: int) -> int | None:
        """See :func:`consistid.diagnosis.effects.ripple.ripple_order`."""
        return ripple_order(data, residual, joint, self.ripple_orders)
