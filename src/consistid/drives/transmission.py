r"""The transmission between motors and joints: gear ratios, a coupling matrix, torque constants.

Motor ``m`` turns ``r_m`` times per unit of its joint-side coordinate ``(G q)_m``, and
the coupling matrix ``G`` (identity for independent joints) says which joints a motor drives
(Khalil & Dombre, *Modeling, Identification and Control of Robots*, §9.3; FIGAROH's TX40 wrist,
where motor 6 turns with joints 5 and 6). Power conservation gives the joint torques:

.. math::

    q_m = \operatorname{diag}(r)\, G\, q, \qquad
    \tau = G^\top \operatorname{diag}(r)\, \tau_m, \qquad
    \tau_m = \operatorname{diag}(k_t)\, i,

so a joint-side *drive gain* ``κ_m = r_m k_{t,m}`` (N·m per A) maps motor ``m``'s current to
the torque it puts on its joint-side coordinate: ``τ = G^\top \operatorname{diag}(κ)\, i``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import JointCountError, OptionError

#: A coupling matrix whose condition number exceeds this is refused as singular.
MAX_COUPLING_CONDITION = 1e8


def _vector(name: str, values: Sequence[float] | np.ndarray, nonzero: bool) -> np.ndarray:
    try:
        a = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        a = np.empty((0, 0))
    if a.ndim != 1 or a.size == 0:
        raise OptionError(f"{name} must be a list of numbers, one per motor, got {values!r}")
    bad = np.flatnonzero(~np.isfinite(a) | ((a == 0) if nonzero else False))
    if bad.size:
        raise OptionError(f"{name}[{int(bad[0])}] = {float(a[bad[0]]):g}: every entry must be "
                          f"a finite {'non-zero ' if nonzero else ''}number (the sign gives "
                          "the direction)")
    return a


@dataclass(frozen=True, eq=False)
class Transmission:
    """Gear ratios (sign included), an optional coupling ``G`` and optional torque constants.

    Parameters
    ----------
    ratios : (n,) motor turns per joint-side turn, non-zero; a negative one turns the other way.
    coupling : (n, n) invertible ``G`` with ``q_m = diag(r) G q``; ``None`` for the identity.
    torque_constants : (n,) N·m per A at the motor, or ``None`` when unknown
        (:func:`~consistid.drives.gains.identify_drive_gains` identifies the gains then).
    name : prefix of the motor-side regressor columns (``"<name>.Iam6"``).

    Raises :class:`OptionError` naming the keyword for a zero or non-finite ratio or constant,
    a coupling of the wrong shape, and a singular coupling.
    """

    ratios: Sequence[float] | np.ndarray
    coupling: Sequence[Sequence[float]] | np.ndarray | None = None
    torque_constants: Sequence[float] | np.ndarray | None = None
    name: str = "drives"
    _inverse: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        ratios = _vector("ratios", self.ratios, nonzero=True)
        n = ratios.size
        if self.coupling is None:
            coupling = np.eye(n)
        else:
            coupling = np.asarray(self.coupling, dtype=float)
            if coupling.shape != (n, n) or not np.isfinite(coupling).all():
                raise OptionError(f"coupling must be a finite {n}×{n} matrix (one row per motor, "
                                  f"one column per joint), got shape {coupling.shape}")
            cond = np.linalg.cond(coupling)
            if not cond < MAX_COUPLING_CONDITION:
                raise OptionError(
                    f"coupling is singular (condition number {cond:.3g}): q_m = diag(r) G q "
                    "must determine the joint angles from the motor angles; check that no two "
                    "rows describe the same motor and that every joint is driven")
        if self.torque_constants is not None:
            constants = _vector("torque_constants", self.torque_constants, nonzero=True)
            if constants.size != n:
                raise OptionError(f"torque_constants has {constants.size} entries but ratios has "
                                  f"{n}: one per motor")
            object.__setattr__(self, "torque_constants", constants)
        if not isinstance(self.name, str) or not self.name:
            raise OptionError(f"name must be a non-empty string, got {self.name!r}")
        object.__setattr__(self, "ratios", ratios)
        object.__setattr__(self, "coupling", coupling)
        object.__setattr__(self, "_inverse", np.linalg.inv(coupling))

    @property
    def n(self) -> int:
        return int(self.ratios.size)

    def check_joints(self, nv: int, joint_names: Sequence[str] | None = None) -> None:
        """Raise :class:`JointCountError` unless there is one motor per joint."""
        if self.n != nv:
            robot = f" ({', '.join(joint_names)})" if joint_names else ""
            raise JointCountError(f"ratios has {self.n} entries but the robot has {nv} "
                                  f"joints{robot}: give one gear ratio per joint")

    @property
    def coupled_motors(self) -> np.ndarray:
        """Indices of the motors that drive more than one joint (rows of ``G`` with more than
        one non-zero entry)."""
        return np.flatnonzero(np.count_nonzero(self.coupling, axis=1) > 1)

    @property
    def gains(self) -> np.ndarray:
        """``κ = r ⊙ k_t`` (N·m per A, joint side); needs the torque constants."""
        if self.torque_constants is None:
            raise OptionError("this transmission has no torque_constants: give them "
                              "(datasheet values, N·m/A) or identify the gains with "
                              "consistid.identify_drive_gains")
        return self.ratios * self.torque_constants

    def joint_positions(self, motor_q: np.ndarray) -> np.ndarray:
        """``q = G⁻¹ (q_m / r)`` for samples ``(N, n)`` (also velocities, accelerations)."""
        return (np.asarray(motor_q, dtype=float) / self.ratios) @ self._inverse.T

    def motor_positions(self, q: np.ndarray) -> np.ndarray:
        """``q_m = r ⊙ (G q)`` for samples ``(N, n)``."""
        return (np.asarray(q, dtype=float) @ self.coupling.T) * self.ratios

    def joint_torque(self, motor_torque: np.ndarray) -> np.ndarray:
        """``τ = Gᵀ (r ⊙ τ_m)`` for samples ``(N, n)``."""
        return (np.asarray(motor_torque, dtype=float) * self.ratios) @ self.coupling

    def motor_torque(self, tau: np.ndarray) -> np.ndarray:
        """``τ_m = (G⁻ᵀ τ) / r``, the inverse of :meth:`joint_torque`."""
        return (np.asarray(tau, dtype=float) @ self._inverse) / self.ratios

    def current_torque(self, currents: np.ndarray, gains: np.ndarray | None = None
                       ) -> np.ndarray:
        """``τ = Gᵀ (κ ⊙ i)``: joint torques of motor currents ``(N, n)`` through the gains
        ``κ`` (default :attr:`gains`, from the torque constants)."""
        gains = self.gains if gains is None else np.asarray(gains, dtype=float)
        return (np.asarray(currents, dtype=float) * gains) @ self.coupling
