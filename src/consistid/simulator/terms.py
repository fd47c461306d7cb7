r"""The simulator-only terms a calibration fits, and where each sits in its parameter vector.

Per joint ``j`` (names ``"<joint>.<term>"``):

* ``armature``, ``damping``, ``frictionloss``: MuJoCo's ``dof_armature``, ``dof_damping``,
  ``dof_frictionloss`` (the default set, :data:`TERMS`);
* ``gain`` (opt-in): the actuator's torque gain ``g_j``, the joint receiving ``g_j τ_j`` for a
  commanded (logged) ``τ_j`` (a torque constant or current calibration off by a factor);

and one for the robot (name ``"delay"``, opt-in): the actuation delay ``δ`` (s), the joint
receiving ``g ⊙ τ(t − δ)`` (bus and drive latency). Both act on the logged torque of the PD
replay (:mod:`.replay`), not inside the ``MjModel``; a :class:`~.engine.Simulator` carries
them (``gain``, ``delay``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import OptionError

#: The per-joint terms fitted by default, in the order of the calibrated vector.
TERMS = ("armature", "damping", "frictionloss")
#: Every term a calibration may fit (``terms=``).
ALL_TERMS = TERMS + ("gain", "delay")
#: Typical magnitudes (kg·m², N·m·s/rad, N·m, 1, s) of a small arm's terms: they set the
#: finite-difference steps, the thresholds of ``gain`` and ``delay`` (a relative torque error
#: and a latency, the same on any arm) and cap the noise floor of the others
#: (:func:`informed_threshold`).
TYPICAL = {"armature": 0.05, "damping": 0.1, "frictionloss": 0.1, "gain": 0.1,
           "delay": 0.005}
#: A per-joint physical term is informed when its σ is at most this fraction of its magnitude
#: (its value ≥ 2σ from zero: the data show it is there).
RELATIVE = 0.5
#: The terms judged relative to their own magnitude.
PHYSICAL = ("armature", "damping", "frictionloss")
#: Lower bounds (a gain below 0.05 would be a dead drive, not a calibration).
LOWER = {"armature": 0.0, "damping": 0.0, "frictionloss": 0.0, "gain": 0.05, "delay": 0.0}


def check_terms(terms: Sequence[str]) -> tuple[str, ...]:
    """``terms`` as a tuple in :data:`ALL_TERMS` order; :class:`OptionError` for an unknown
    one, a repeat, or none."""
    terms = tuple(terms) if not isinstance(terms, str) else (terms,)
    bad = [t for t in terms if t not in ALL_TERMS]
    if bad or not terms or len(set(terms)) != len(terms):
        raise OptionError(f"terms={terms!r}: give distinct terms among {ALL_TERMS}")
    return tuple(t for t in ALL_TERMS if t in terms)


def informed_threshold(layout: "TermLayout", values: np.ndarray, start: np.ndarray,
                       noise_floor: np.ndarray) -> np.ndarray:
    r"""(size,) the σ above which each term is *not informed* by the data (then held at its
    start by :func:`~.calibrate.calibrate_simulator`).

    ``armature``, ``damping``, ``frictionloss`` of joint ``j``:
    ``max(RELATIVE · max(|θ̂|, |θ₀|), min(σ_noise, TYPICAL))`` — informed when the value (the
    calibrated ``θ̂`` or the physical start ``θ₀``) is at least ``1/RELATIVE`` σ from zero, a
    rule that is the same on an industrial arm (armature of kg·m²) and a small one; or, for a
    term near zero, when its σ is below ``σ_noise`` (``noise_floor``: the σ whose torque equals
    the identification's residual RMS of the joint on the log, ``s_j / RMS(∂τ_j/∂θ)``: the data
    show the term is negligible) and below its :data:`TYPICAL` magnitude (so that a joint
    which hardly moves, whose ``σ_noise`` is huge, does not pass). ``gain`` and ``delay``
    (dimensionless, seconds; the same scale on any arm): their :data:`TYPICAL` value.
    """
    typical = layout.per_entry(TYPICAL)
    physical = layout.per_entry({t: float(t in PHYSICAL) for t in ALL_TERMS}) > 0
    relative = RELATIVE * np.maximum(np.abs(values), np.abs(start))
    return np.where(physical, np.maximum(relative, np.minimum(noise_floor, typical)), typical)


@dataclass(frozen=True)
class TermLayout:
    """Where each term sits in the calibrated vector: per-joint terms ``nv`` entries each,
    ``delay`` one, in :data:`ALL_TERMS` order."""

    terms: tuple[str, ...]
    nv: int

    def size_of(self, term: str) -> int:
        return 1 if term == "delay" else self.nv

    @property
    def size(self) -> int:
        return sum(self.size_of(t) for t in self.terms)

    def slice(self, term: str) -> slice:
        """The entries of ``term``; :class:`OptionError` for one not fitted."""
        if term not in self.terms:
            raise OptionError(f"term={term!r} was not calibrated; the calibration holds "
                              f"{self.terms}")
        start = sum(self.size_of(t) for t in self.terms[:self.terms.index(term)])
        return slice(start, start + self.size_of(term))

    def names(self, joints: Sequence[str]) -> tuple[str, ...]:
        return tuple(n for t in self.terms
                     for n in (["delay"] if t == "delay" else [f"{j}.{t}" for j in joints]))

    def per_entry(self, table: dict[str, float]) -> np.ndarray:
        """A per-term constant spread over the entries, (size,)."""
        return np.concatenate([np.full(self.size_of(t), table[t]) for t in self.terms])

    @classmethod
    def of_names(cls, names: Sequence[str], joints: Sequence[str]) -> "TermLayout":
        """The layout of a saved calibration's ``names``."""
        terms = tuple(dict.fromkeys(n.rpartition(".")[2] for n in names))
        layout = cls(check_terms(terms), len(joints))
        if layout.names(joints) != tuple(names):
            raise OptionError(f"simulator parameter names {list(names)[:4]}… are not in the "
                              "calibration's order")
        return layout
