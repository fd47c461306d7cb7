r"""What a diagnosis effect is: one class holding everything the diagnosis knows about it.

An effect adds a correction to the nominal torque that is linear in its parameters ``θ`` once
its *setting* (a smoothing speed, a harmonic order, a filter cut-off) is fixed:

.. math::  \tau \approx \tau_\text{nom} + \Phi_e(q, \dot q, \ddot q, \tau_\text{nom})\,\theta_e

An :class:`Effect` subclass states, in one module of :mod:`consistid.diagnosis.effects`:

* ``name`` (lower case, the design document's effect names), ``order`` (where reports list it);
* ``signature``: how it shows in the residual, and ``equation``: its model of the residual;
* its *atoms* (:meth:`Effect.atoms`): the effect on one joint or on the whole arm, each with
  parameter names and units;
* its *columns* ``Φ`` on a :class:`~consistid.diagnosis.gapdata.GapData` (:meth:`Effect.columns`),
  or, for an effect whose per-joint atom acts on its own joint alone (``row_only = True``), that
  joint's row (:meth:`Effect.row`; the candidate matrix is then filled row by row), itself the
  signal before the torques' low-pass (:meth:`Effect.unfiltered`) for an effect seen through it;
* its *physical sign rules* (``nonnegative``: parameters that must be ≥ 0, e.g. friction, a
  delay); a candidate fitted against them is not selected;
* its *wording*: how a parameter reads in the report (:meth:`Effect.parameters`);
* optional tuning of a nonlinear setting (:meth:`Effect.tune`, ``tuned = True``) and candidates
  found by a search on the training residual (``searched = True``).

The registry (:mod:`consistid.diagnosis.effects`) finds every module of the package that defines
``EFFECT = <instance>``: adding an effect is adding one module.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import scipy.optimize

from ...robot.inertia import INERTIAL_NAMES
from ..gapdata import GapData, lowpass_segments
from ..remainder import LOWPASS_ORDER

if TYPE_CHECKING:
    from ..candidates import EffectLibrary

#: Units of one body's standard inertial parameters.
INERTIAL_UNITS = dict(zip(INERTIAL_NAMES, ("kg", "kg·m", "kg·m", "kg·m", *["kg·m²"] * 6)))

#: Low-pass cut-offs (Hz) tried for Coulomb steps and ripple seen through filtered torques;
#: ``inf``: unfiltered.
FILTER_CUTOFFS: tuple[float, ...] = (np.inf, 50.0, 30.0, 20.0, 12.0, 8.0, 5.0, 3.0, 2.0)
#: A tuned cut-off within this factor of the dataset's recorded low-pass (either way) is that
#: low-pass (:attr:`Atom.chain`): the tuning's refinement stops within a few per cent of it.
CHAIN_MATCH = 1.15


@dataclass(frozen=True)
class Atom:
    """One candidate: an effect on one joint (or on the whole arm) with its parameter columns.

    Attributes
    ----------
    effect : effect name (one of :data:`consistid.diagnosis.effects.EFFECT_NAMES`).
    joint : the joint index it acts on, or ``None`` for an arm-wide atom.
    parameter_names : names of its parameters (columns), e.g. ``("panda_joint2.fc",)``.
    units : unit of each parameter.
    setting : the nonlinear setting fixed before the linear fit (ripple order ``k``, Coulomb
        smoothing speed ``v_s``), or ``None``.
    cutoff : for Coulomb and ripple, the low-pass cut-off (Hz) through which the torque sees
        them (``inf``: none).
    setting_name : how the setting is named in labels (``"v_s"``, ``"k"``).
    chain : the tuned cut-off is the low-pass the training dataset records
        (``Dataset.torque_filter``, within :data:`CHAIN_MATCH`): on every dataset that records
        its own, the atom is seen through that one (a held-out recording the chain filtered at
        another cut-off), else through ``cutoff``.
    """

    effect: str
    joint: int | None
    parameter_names: tuple[str, ...]
    units: tuple[str, ...]
    setting: float | None = None
    cutoff: float = np.inf
    setting_name: str = "v_s"
    chain: bool = False

    def seen_below(self, data: GapData) -> float:
        """The cut-off (Hz) through which ``data``'s torques see this atom: the dataset's
        recorded low-pass for a ``chain`` atom where it records one, else :attr:`cutoff`."""
        recorded = data.dataset.torque_filter
        if self.chain and recorded is not None and recorded[1] == LOWPASS_ORDER:
            return float(recorded[0])
        return self.cutoff

    @property
    def n_parameters(self) -> int:
        return len(self.parameter_names)

    def label(self, joint_names: list[str]) -> str:
        where = "all joints" if self.joint is None else joint_names[self.joint]
        extra = f", {self.setting_name}={self.setting:g}" if self.setting else ""
        if np.isfinite(self.cutoff):
            extra += f", seen below {self.cutoff:.3g} Hz"
        return f"{self.effect} ({where}{extra})"


@dataclass(frozen=True)
class EffectParameter:
    """One estimated parameter of a selected effect, with its standard deviation.

    ``value`` and ``std`` are in ``unit`` (SI: a delay in s, a tilt in rad); the text shows
    delays in ms and angles in degrees. ``wording`` is how the parameter reads after the joint
    name (``"Coulomb friction"``); empty: the parameter's ``name`` alone is shown.
    """

    name: str
    value: float
    std: float
    unit: str
    joint: str | None = None
    effect: str = ""
    note: str = ""
    wording: str = ""

    def __str__(self) -> str:
        scale, unit = {"s": (1e3, "ms"), "rad": (180 / np.pi, "°")}.get(self.unit,
                                                                       (1.0, self.unit))
        if self.wording:
            what = f"{self.joint} {self.wording}" if self.joint else self.wording
        else:
            what = self.name
        return (f"{what} {self.value * scale:.4g} ± {self.std * scale:.2g}"
                + (f" {unit}" if unit else "") + (f" ({self.note})" if self.note else ""))


def on_row(data: GapData, joint: int, cols: np.ndarray) -> np.ndarray:
    """Columns ``(N, k)`` placed on the row of ``joint`` of an ``(N, nv, k)`` block."""
    cols = cols.reshape(data.n, -1)
    out = np.zeros((data.n, data.nv, cols.shape[1]))
    out[:, joint, :] = cols
    return out


class Effect:
    """One candidate effect of the diagnosis (subclass it in its own module; see the module
    notes). Class attributes:

    name, order : effect name and its rank in reports (the registry sorts by ``order``).
    signature : how it shows in the residual (one line, for the report).
    equation : its model of the residual (for the documentation table).
    unit : unit of its per-joint parameter.
    suffix : the per-joint parameter's name after ``<joint>.`` (e.g. ``"fc"``).
    wording : how a parameter reads in text (``"Coulomb friction"``); empty: by its name.
    nonnegative : indices of parameters that must be ≥ 0 to be physical.
    scope : ``"joint"`` (one atom per joint), ``"arm"`` (one arm-wide atom) or ``"both"``.
    tuned : its atoms carry a nonlinear setting chosen by :meth:`tune` on training data.
    searched : its atoms are found on the training residual (:meth:`atoms` needs it).
    row_only : an atom on joint ``j`` acts on row ``j`` alone (its columns are zero on the other
        joints' rows; :meth:`row` gives that row): the candidate matrix is filled row by row.
    companions : effects whose atoms this effect's atoms interact with: the selection scores
        an atom of this effect with every not yet selected atom of these effects fitted beside
        it (:mod:`consistid.diagnosis.interaction`).
    """

    name: ClassVar[str] = ""
    order: ClassVar[int] = 1000
    signature: ClassVar[str] = ""
    equation: ClassVar[str] = ""
    unit: ClassVar[str] = ""
    suffix: ClassVar[str] = ""
    wording: ClassVar[str] = ""
    nonnegative: ClassVar[tuple[int, ...]] = ()
    scope: ClassVar[str] = "joint"
    tuned: ClassVar[bool] = False
    searched: ClassVar[bool] = False
    row_only: ClassVar[bool] = False
    companions: ClassVar[tuple[str, ...]] = ()

    # ------------------------------------------------------------------ candidates
    def atoms(self, library: "EffectLibrary", tuning: GapData | None = None,
              residual: np.ndarray | None = None) -> list[Atom]:
        """The candidate atoms (default: one per joint, parameter ``<joint>.<suffix>``)."""
        names = library.model.joint_names
        return [Atom(self.name, j, (f"{names[j]}.{self.suffix}",), (self.unit,))
                for j in range(library.model.nv)]

    def columns(self, library: "EffectLibrary", atom: Atom, data: GapData) -> np.ndarray:
        """The atom's columns on ``data``, shape ``(N, nv, n_parameters)``. Default, for a
        ``row_only`` effect: :meth:`row` on the atom's joint row, zeros elsewhere."""
        if not self.row_only:
            raise NotImplementedError(f"effect {self.name!r} defines no columns")
        return on_row(data, atom.joint, self.row(library, atom, data))

    def row(self, library: "EffectLibrary", atom: Atom, data: GapData) -> np.ndarray:
        """For a ``row_only`` effect, the atom's columns on its joint's row, ``(N, k)`` or
        ``(N,)``. Default, for an effect seen through the torques' low-pass (one that defines
        :meth:`unfiltered`): that signal through the filter at the atom's cut-off."""
        return lowpass_segments(data.dataset, self.unfiltered(library, atom, data),
                                atom.seen_below(data), data.segments)

    def unfiltered(self, library: "EffectLibrary", atom: Atom, data: GapData) -> np.ndarray:
        """For an effect on one joint seen through the torques' low-pass ``L`` (Coulomb steps,
        ripple): its signal before ``L``, ``(N, n_parameters)`` (the row of its joint; the
        cut-off tuning, :func:`tune_cutoffs`, filters it at each trial cut-off)."""
        raise NotImplementedError(f"effect {self.name!r} has no unfiltered signal")

    def tune(self, library: "EffectLibrary", data: GapData, residual: np.ndarray,
             atom: Atom) -> Atom:
        """The atom with its nonlinear setting chosen to explain ``residual`` (N,) of its joint
        (only called when ``tuned``)."""
        return atom

    # ------------------------------------------------------------------ physics and words
    def unphysical(self, atom: Atom, theta: np.ndarray, resolution: float | None = None
                   ) -> str | None:
        """Why the fitted parameters ``theta`` break a physical sign rule, or ``None``;
        ``resolution``: the data's time-stamp resolution (s), for effects measured in time."""
        for i in self.nonnegative:
            if theta[i] < 0:
                return (f"its {atom.parameter_names[i]} is negative: not a physical "
                        f"{atom.effect}")
        return None

    def stamping(self, theta: np.ndarray, resolution: float | None) -> bool:
        """Whether the fitted ``theta`` is an artefact of how the log was time-stamped rather
        than an effect (a shift within the time-stamp resolution; only time effects)."""
        return False

    def parameters(self, library: "EffectLibrary", atom: Atom, theta: np.ndarray,
                   std: np.ndarray, joint: str | None, fit) -> list[EffectParameter]:
        """Readable parameters of a fitted atom (``fit``: the
        :class:`~consistid.diagnosis.diagnose.GapModel` it belongs to)."""
        return [EffectParameter(n, float(v), float(s), u, joint, atom.effect,
                                wording=self.wording)
                for n, v, s, u in zip(atom.parameter_names, theta, std, atom.units)]

    def __repr__(self) -> str:
        return f"<effect {self.name!r}: {self.signature}>"


def tune_cutoff(effect: Effect, library: "EffectLibrary", data: GapData, residual: np.ndarray,
                atom: Atom) -> tuple[Atom, float]:
    """The atom (one joint) with the cut-off of :data:`FILTER_CUTOFFS` (below the Nyquist
    frequency), refined between its grid neighbours, whose columns explain most of ``residual``
    (N,) by least squares; and that explained sum of squares (:func:`tune_cutoffs` of one
    atom)."""
    return tune_cutoffs(effect, library, data, residual, [atom])[0]


def _explained(a: np.ndarray, residual: np.ndarray) -> float:
    """``cᵀG⁻¹c`` with ``G = aᵀa``, ``c = aᵀr``: what columns ``a`` (N, k) explain of ``r`` by
    least squares; ``−inf`` when ``G`` is singular (condition number above 1e12)."""
    g, c = a.T @ a, a.T @ residual
    if g.shape == (1, 1) and 0 < g[0, 0] < np.inf:
        # one column: condition number 1, and LAPACK's solve of a 1×1 system is c / g
        return float(c[0] * (c[0] / g[0, 0]))
    if np.linalg.cond(g) > 1e12:
        return -np.inf
    return float(c @ np.linalg.solve(g, c))


def tune_cutoffs(effect: Effect, library: "EffectLibrary", data: GapData, residual: np.ndarray,
                 atoms: list[Atom]) -> list[tuple[Atom, float]]:
    """:func:`tune_cutoff` of each of ``atoms`` (on one joint, e.g. one per smoothing speed).

    For each atom, the cut-off of :data:`FILTER_CUTOFFS` below ``0.9 ×`` the Nyquist frequency
    whose filtered :meth:`Effect.unfiltered` signal explains most of ``residual`` (N,) by least
    squares, refined between its grid neighbours (bounded Brent on ``log f_c``, ``xatol``
    1e-3); with that explained sum of squares. The unfiltered signals are built once, and each
    grid cut-off filters all atoms' signals in one pass (the filter acts column by column: the
    same numbers as one atom at a time).
    """
    nyquist = 0.5 / data.step
    raw = [np.asarray(effect.unfiltered(library, a, data), dtype=float).reshape(data.n, -1)
           for a in atoms]
    edges = np.cumsum([0] + [r.shape[1] for r in raw])
    stacked = np.concatenate(raw, axis=1)
    grid = [fc for fc in FILTER_CUTOFFS if not (np.isfinite(fc) and fc >= 0.9 * nyquist)]
    scores = np.empty((len(atoms), len(grid)))
    for m, fc in enumerate(grid):
        seen = lowpass_segments(data.dataset, stacked, fc, data.segments)
        for i in range(len(atoms)):
            scores[i, m] = _explained(seen[:, edges[i]:edges[i + 1]], residual)
    out = []
    for atom, signal, row in zip(atoms, raw, scores):
        def explained(fc: float, signal: np.ndarray = signal) -> float:
            return _explained(lowpass_segments(data.dataset, signal, fc, data.segments),
                              residual)

        i = int(np.argmax(row))
        if not np.isfinite(grid[i]):
            out.append((replace(atom, cutoff=np.inf), float(row[i])))
            continue
        lo = grid[i + 1] if i + 1 < len(grid) else grid[i] / 2
        hi = grid[i - 1] if np.isfinite(grid[i - 1]) else min(2 * grid[i], nyquist)
        res = scipy.optimize.minimize_scalar(lambda x: -explained(float(np.exp(x))),
                                             bounds=(np.log(lo), np.log(hi)), method="bounded",
                                             options={"xatol": 1e-3})
        if -res.fun > row[i]:
            out.append((replace(atom, cutoff=float(np.exp(res.x))), float(-res.fun)))
        else:
            out.append((replace(atom, cutoff=grid[i]), float(row[i])))
    return [(_on_chain(a, data), score) for a, score in out]


def _on_chain(atom: Atom, data: GapData) -> Atom:
    """``atom`` seen through the dataset's recorded low-pass (``chain``) when its tuned cut-off
    lies within :data:`CHAIN_MATCH` of it (same order): the tuning found the filter the dataset
    says the signal chain applied, so another recording is seen through its own."""
    recorded = data.dataset.torque_filter
    if (recorded is None or recorded[1] != LOWPASS_ORDER or not np.isfinite(atom.cutoff)
            or abs(np.log(atom.cutoff / recorded[0])) > np.log(CHAIN_MATCH)):
        return atom
    return replace(atom, cutoff=float(recorded[0]), chain=True)
