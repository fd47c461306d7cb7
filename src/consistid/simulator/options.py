r"""Options of a replay in the user's simulator: the physics step, the integrator, the
controller of a closed-loop replay and the window of an open-loop one.

The closed-loop controller is a joint PD around the logged motion with the logged torque as
feed-forward,

.. math:: u = \tau_{log} + K_p (q_{log} - q) + K_d (\dot q_{log} - \dot q),

so that a model that *is* the robot needs no correction (``u − τ_log`` is noise-driven) and a
wrong one shows its error as tracking error ``q − q_log`` and correction torque ``u − τ_log``
(the direct-and-inverse-dynamics idea of Gautier, Janot, Vandanjon 2013, "A new closed-loop
output error method for parameter identification of robot dynamics", IEEE TCST,
doi:10.1109/TCST.2012.2185697: the same input and the same control law drive the simulated and
the real robot). The PD is a MuJoCo actuator (``gain = K_p``, ``bias = [0, −K_p, −K_d]``,
``ctrl = q_log + (K_d/K_p) q̇_log``), so that ``implicitfast`` integrates its damping
implicitly as it would for the user's own position servo, and whole replays run in one
``mujoco.rollout`` call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError, check_number, check_option

#: MuJoCo's integrators by their MJCF names.
INTEGRATORS = ("Euler", "implicit", "implicitfast", "RK4")
#: The most threads a replay asks ``mujoco.rollout`` for (each holds one ``MjData``).
MAX_THREADS = 256


@dataclass(frozen=True)
class PDGains:
    r"""Joint PD gains of the closed-loop replay.

    Either explicit ``kp`` (N·m/rad) and ``kd`` (N·m·s/rad), a scalar or one per joint, or (the
    default) a bandwidth: ``K_p = M_jj ω²``, ``K_d = 2 ζ ω M_jj`` with ``M_jj`` the mean
    diagonal of the first replayed model's mass matrix (armature included) over the log, the
    same gains then for every model compared (:meth:`resolve`).

    Parameters
    ----------
    bandwidth : ω (rad/s), > 0.
    damping_ratio : ζ, > 0.
    kp, kd : explicit gains (both or neither), ≥ 0 with ``kp > 0``.
    """

    bandwidth: float = 20.0
    damping_ratio: float = 1.0
    kp: float | tuple[float, ...] | None = None
    kd: float | tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        check_number("PDGains.bandwidth", self.bandwidth, 0, strict=True)
        check_number("PDGains.damping_ratio", self.damping_ratio, 0, strict=True)
        _check_gains("PDGains", self.kp, self.kd)

    def resolve(self, mass_diagonal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(K_p, K_d)`` per joint, (nv,) each."""
        nv = mass_diagonal.size
        if self.kp is None:
            w, z = self.bandwidth, self.damping_ratio
            return mass_diagonal * w ** 2, 2.0 * z * w * mass_diagonal
        return _per_joint("PDGains", self.kp, self.kd, nv)


@dataclass(frozen=True)
class ComputedTorque:
    r"""Computed-torque control of the closed-loop replay (module docstring): the commanded
    joint acceleration ``a = q̈_log + K_d ė + K_p e`` is turned into torque by the inverse
    dynamics of the simulated model (``mujoco.mj_inverse`` of the very ``MjModel`` stepped:
    its armature, damping, friction loss and every body of the user's MJCF included, and, under
    ``Euler``/``implicit``/``implicitfast``, MuJoCo's discrete-time inverse
    (``mjENBL_INVDISCRETE``), so that the step reaches ``a`` exactly).

    Gains are accelerations per error, the same for every joint and every model: either a
    bandwidth (``K_p = ω²``, ``K_d = 2 ζ ω``) or explicit ``kp`` (1/s²) and ``kd`` (1/s), a
    scalar or one per joint.

    Parameters
    ----------
    bandwidth : ω (rad/s), > 0.
    damping_ratio : ζ, > 0.
    kp, kd : explicit gains (both or neither), ``kp > 0``, ``kd ≥ 0``.
    """

    bandwidth: float = 20.0
    damping_ratio: float = 1.0
    kp: float | tuple[float, ...] | None = None
    kd: float | tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        check_number("ComputedTorque.bandwidth", self.bandwidth, 0, strict=True)
        check_number("ComputedTorque.damping_ratio", self.damping_ratio, 0, strict=True)
        _check_gains("ComputedTorque", self.kp, self.kd)

    def resolve(self, mass_diagonal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(K_p, K_d)`` per joint, (nv,) each (``mass_diagonal`` gives only the count: the
        inverse dynamics scales the gains by the model's own mass matrix)."""
        nv = mass_diagonal.size
        if self.kp is None:
            w, z = self.bandwidth, self.damping_ratio
            return np.full(nv, w ** 2), np.full(nv, 2.0 * z * w)
        return _per_joint("ComputedTorque", self.kp, self.kd, nv)


#: The closed-loop controllers a replay runs.
Controller = PDGains | ComputedTorque


def _check_gains(owner: str, kp: object, kd: object) -> None:
    """Explicit gains: both or neither, ``kp > 0``, ``kd ≥ 0``, finite."""
    if (kp is None) != (kd is None):
        raise OptionError(f"{owner}: give both kp and kd, or neither (then the bandwidth "
                          "sets them)")
    if kp is not None:
        try:
            p, d = np.ravel(kp).astype(float), np.ravel(kd).astype(float)
        except (TypeError, ValueError):
            raise OptionError(f"{owner}: kp and kd must be numbers (a scalar or one per "
                              f"joint), got kp={kp!r}, kd={kd!r}") from None
        if not (np.all(np.isfinite(p)) and np.all(p > 0) and np.all(np.isfinite(d))
                and np.all(d >= 0)):
            raise OptionError(f"{owner}: kp must be > 0 and kd ≥ 0 (finite), got "
                              f"kp={kp!r}, kd={kd!r}")


def _per_joint(owner: str, kp: object, kd: object, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Explicit gains broadcast to (nv,) each."""
    p, d = (np.broadcast_to(np.ravel(g).astype(float), (nv,)).copy()
            if np.size(g) in (1, nv) else None for g in (kp, kd))
    if p is None or d is None:
        raise OptionError(f"{owner}: kp and kd need 1 or {nv} values (one per joint), got "
                          f"{np.size(kp)} and {np.size(kd)}")
    return p, d


@dataclass(frozen=True)
class RolloutOptions:
    """How to replay a log in the user's simulator.

    Parameters
    ----------
    timestep : the simulator's physics step (s), > 0; ``None``: the MJCF's own (``mjcf=``).
    integrator : ``"Euler"``, ``"implicit"``, ``"implicitfast"`` or ``"RK4"``; ``None``: the
        MJCF's own.
    window : open-loop replay: the state is reset to the logged one every ``window`` seconds
        and the drift ``q − q_log`` is reported per window; > 0.
    controller : the closed-loop replay's controller: :class:`PDGains` (joint PD around the
        log, the logged torque fed forward) or :class:`ComputedTorque`.
    threads : threads of ``mujoco.rollout``, 1 … :data:`MAX_THREADS`.
    """

    timestep: float | None = 0.002
    integrator: str | None = "implicitfast"
    window: float = 1.0
    controller: Controller = PDGains()
    threads: int = 1

    def __post_init__(self) -> None:
        if self.timestep is not None:
            check_number("RolloutOptions.timestep", self.timestep, 0, strict=True)
        if self.integrator is not None:
            check_option("RolloutOptions.integrator", self.integrator, INTEGRATORS)
        check_number("RolloutOptions.window", self.window, 0, strict=True)
        check_number("RolloutOptions.threads", self.threads, 1, integer=True)
        if self.threads > MAX_THREADS:
            raise OptionError(f"RolloutOptions.threads={self.threads} is more than "
                              f"{MAX_THREADS} (each thread holds a MuJoCo data copy); give at "
                              "most the machine's cores")
        if not isinstance(self.controller, (PDGains, ComputedTorque)):
            raise OptionError(f"RolloutOptions.controller must be a PDGains or a "
                              f"ComputedTorque, got {type(self.controller).__name__}")
