r"""A MuJoCo model of a :class:`~consistid.robot.model.RobotModel`: the simulated "real robot".

The MJCF is written from the Pinocchio model itself, so that MuJoCo and Pinocchio share joint
order, joint axes, kinematics, gravity and inertial parameters exactly (locked joints are already
merged into their parent by :meth:`RobotModel.from_urdf`, and no meshes are involved):

* one MuJoCo body per Pinocchio joint, placed by ``model.jointPlacements`` (the body frame is the
  joint frame), with a ``hinge`` or ``slide`` joint along the axis read from the joint's motion
  subspace;
* its ``<inertial>`` is mass, CoM and the full inertia about the CoM of ``model.inertias``
  (MuJoCo diagonalises it into ``body_ipos``/``body_iquat``); a payload is a jointless child
  body ``<body>__payload`` whose inertial is given in its principal axes, so that a thin rod
  (one zero moment, which MuJoCo's ``fullinertia`` refuses) is simulated as one;
* ``dof_armature`` is Pinocchio's ``model.armature`` (which ``pinocchio.rnea`` includes) plus the
  armature effect.

With no effects, ``mj_inverse`` equals ``pinocchio.rnea`` to rounding (:meth:`MujocoRobot.inverse`).
The effects of :class:`~consistid.simulate.effects.Effects` enter as MuJoCo elements: ``damping``,
``frictionloss`` and ``armature`` on the drive's joint, a jointless child body for the payload,
and for an elastic joint a *rotor* body (a sibling of the link, same joint placement and axis,
negligible mass, the motor inertia as ``armature`` so that it only adds to its own diagonal of the
mass matrix, as in Spong's reduced model) coupled to the link joint by a fixed tendon
``θ − q`` with the joint stiffness and damping. The smooth (``tanh``) Coulomb model, the
Stribeck relief (``frictionloss`` is then the static friction ``f_s``), the sigmoid friction
(:func:`~consistid.simulate.effects.explicit_friction`, evaluated at each step's velocity) and the
controller torque are applied through ``qfrc_applied``, held over each physics step.

MuJoCo (Todorov, Erez, Tassa 2012, "MuJoCo: a physics engine for model-based control", IROS,
doi:10.1109/IROS.2012.6386109): ``qfrc_inverse`` is the generalised force that produces a given
``qacc``. The logged acceleration is ``qacc`` of ``mj_forward`` at the logged state with that
step's torques, so ``M(q_k) q̈_k + h(q_k, q̇_k) = τ_k`` holds exactly at every logged sample.

Integrator. The default is MuJoCo's semi-implicit Euler with ``eulerdamp`` disabled:
``q̇_{k+1} = q̇_k + h q̈_k``, ``q_{k+1} = q_k + h q̇_{k+1}``. Its positions are exactly those whose
second difference is the logged acceleration, ``(q_{k+1} − 2q_k + q_{k−1})/h² = q̈_k``, while
their central difference is ``q̇_k + h q̈_k / 2`` (half a step ahead). With ``"RK4"`` the states
follow the continuous-time motion under a zero-order-held torque, and it is the acceleration
that a finite difference sees averaged across the torque step (``q̈_k − Δq̈_k/2``), i.e. the
torque log leads the positions by half a step, as on a real robot with a 1 kHz torque loop.
Identification from central differences of a 1 kHz log recovers the Panda's base parameters to
~4e-4 (Euler) vs ~4e-3 (RK4) relative; pick ``"RK4"`` with a higher ``physics_rate`` to study
that effect.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import ModelError, check_option
from ..robot.mjcf import joint_axes
from ..robot.model import RobotModel
from .effects import (Effects, MountedPayload, explicit_friction, explicit_friction_slope,
                      has_explicit_friction)

INTEGRATORS = ("Euler", "RK4", "implicitfast")
#: Impedance of the friction-loss constraint (``solimpfriction``); with the time constant at its
#: floor of two steps (``solreffriction``), the dry friction saturates at ``f_c·sign q̇`` exactly
#: once ``|q̇|`` exceeds ~0.01 rad/s at 1 kHz (MuJoCo's default, 0.9 and 0.02 s, needs up to
#: ~1 rad/s on a light wrist joint: a strong viscous damper in disguise).
FRICTION_SOLIMP = (0.99, 0.99, 0.001, 0.5, 2.0)
#: Mass (kg) and principal moments (kg·m²) of a rotor body: MuJoCo needs a positive mass; the
#: rotor's inertia about its axis is its joint's armature.
ROTOR_MASS, ROTOR_INERTIA = 1e-9, 1e-12
#: The tanh-friction stability check reads the mass matrix at up to this many evenly spaced
#: samples of the desired trajectory.
TANH_CHECK_SAMPLES = 1000
#: Fixed-point iterations allowed for the start deflection of the elastic joints, and the
#: change (rad) below which it has converged (it contracts by ~‖∂τ_J/∂q‖/K per iteration).
START_ITERATIONS, START_TOL = 100, 1e-13
#: The integration stage of ``mj_step``, by ``mjModel.opt.integrator``. MuJoCo's ``mj_step`` is
#: ``mj_checkPos``, ``mj_checkVel``, ``mj_forward``, ``mj_checkAcc`` (``mj_compareFwdInv`` only
#: with the ``fwdinv`` flag, never set here), then this (pipeline stages 1–26 of MuJoCo's
#: documentation, ``engine_forward.c``); RK4 takes its first stage from the ``qacc`` that
#: ``mj_forward`` left. :meth:`MujocoRobot.run` opens a logged step this way so that the
#: acceleration it logs is the one integrated, computed once.
_INTEGRATE: dict[int, Callable[[mujoco.MjModel, mujoco.MjData], None]] = {
    int(mujoco.mjtIntegrator.mjINT_EULER): mujoco.mj_Euler,
    int(mujoco.mjtIntegrator.mjINT_RK4): lambda m, d: mujoco.mj_RungeKutta(m, d, 4),
    int(mujoco.mjtIntegrator.mjINT_IMPLICIT): mujoco.mj_implicit,
    int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mujoco.mj_implicit,
}


def _num(values) -> str:
    return " ".join(f"{float(x):.17g}" for x in np.ravel(values))


def _inertial(inertia: pin.Inertia, name: str) -> str:
    if not inertia.mass > 0:
        raise ModelError(f"body {name!r} has mass {inertia.mass:g} kg; MuJoCo needs a positive "
                         "mass for every moving body (give the link an <inertial> in the URDF)")
    i = np.asarray(inertia.inertia)
    full = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
    return (f'<inertial pos="{_num(inertia.lever)}" mass="{inertia.mass:.17g}" '
            f'fullinertia="{_num(full)}"/>')


def _payload_inertial(payload: MountedPayload, parameters: np.ndarray) -> str:
    """The ``<inertial>`` of a payload from its 10-vector in the carrying joint's frame.

    A point mass (``payload.inertia`` all zero) gets zero moments. Otherwise the inertia about
    the CoM is written in its principal axes (``quat`` + ``diaginertia``): MuJoCo's
    ``fullinertia`` needs positive moments, a thin rod has a zero one. Round-off from the frame
    change (below :data:`~consistid.simulate.effects.PAYLOAD_INERTIA_TOL`, the payload was
    checked) is removed so that MuJoCo's ``I_1 + I_2 ≥ I_3`` holds exactly.
    """
    inertia = pin.Inertia.FromDynamicParameters(parameters)
    where = f'pos="{_num(inertia.lever)}" mass="{inertia.mass:.17g}"'
    if not np.any(payload.inertia):
        return f'<inertial {where} diaginertia="0 0 0"/>'
    moments, axes = np.linalg.eigh(np.asarray(inertia.inertia))
    if np.linalg.det(axes) < 0:
        axes[:, 0] *= -1.0                                       # a rotation, not a reflection
    moments = np.maximum(moments, 0.0)
    moments[2] = min(moments[2], moments[0] + moments[1])
    quat = pin.Quaternion(axes)
    return (f'<inertial {where} quat="{_num([quat.w, quat.x, quat.y, quat.z])}" '
            f'diaginertia="{_num(moments)}"/>')


def _mjcf(model: RobotModel, eff: Effects, payload: tuple[int, np.ndarray] | None,
          timestep: float, integrator: str, tendons: Sequence[str] = ()) -> str:
    """The MJCF text of ``model`` (its current inertias) with the resolved effects ``eff``, the
    payload's ``(joint, 10-vector)`` and extra ``<fixed>`` tendon elements ``tendons``."""
    check_option("integrator", integrator, INTEGRATORS)
    pm = model.pin_model
    kinds, axes = joint_axes(model)
    elastic = eff.elastic
    frictionloss = (np.where(eff.static_friction > 0, eff.static_friction, eff.coulomb)
                    if eff.coulomb_model == "frictionloss" else np.zeros(model.nv))
    armature = np.asarray(pm.armature, dtype=float)
    friction_solver = (f'solreffriction="{2 * timestep:.17g} 1" '
                       f'solimpfriction="{_num(FRICTION_SOLIMP)}"')
    children: dict[int, list[int]] = {j: [] for j in range(pm.njoints)}
    for j in range(1, pm.njoints):
        children[pm.parents[j]].append(j)

    def drive_attrs(i: int, inertia: float) -> str:
        """Drive-side effects; ``inertia`` is the drive's own (Pinocchio's armature, or the
        motor inertia of an elastic joint), to which the armature effect adds."""
        return (f'damping="{eff.viscous[i]:.17g}" frictionloss="{frictionloss[i]:.17g}" '
                f'armature="{inertia + eff.armature[i]:.17g}" {friction_solver}')

    def body(j: int, indent: str) -> list[str]:
        i = j - 1
        placement = pm.jointPlacements[j]
        quat = pin.Quaternion(placement.rotation)
        frame = (f'pos="{_num(placement.translation)}" '
                 f'quat="{_num([quat.w, quat.x, quat.y, quat.z])}"')
        joint_name, body_name = model.joint_names[i], model.body_names[i]
        lines = []
        if elastic[i]:
            lines += [
                f"{indent}<body name={quoteattr(joint_name + '__rotor')} {frame}>",
                f"{indent}  <joint name={quoteattr(joint_name + '__motor')} type=\"{kinds[i]}\" "
                f'axis="{_num(axes[i])}" {drive_attrs(i, eff.motor_inertia[i])}/>',
                f'{indent}  <inertial pos="0 0 0" mass="{ROTOR_MASS}" '
                f'diaginertia="{_num([ROTOR_INERTIA] * 3)}"/>',
                f"{indent}</body>"]
            joint_attrs = f'armature="{armature[i]:.17g}"'
        else:
            joint_attrs = drive_attrs(i, armature[i])
        lines += [f"{indent}<body name={quoteattr(body_name)} {frame}>",
                  f"{indent}  <joint name={quoteattr(joint_name)} type=\"{kinds[i]}\" "
                  f'axis="{_num(axes[i])}" {joint_attrs}/>',
                  f"{indent}  {_inertial(pm.inertias[j], body_name)}"]
        if payload is not None and payload[0] == i:
            lines += [f"{indent}  <body name={quoteattr(body_name + '__payload')}>",
                      f"{indent}    {_payload_inertial(eff.payload, payload[1])}",
                      f"{indent}  </body>"]
        for c in children[j]:
            lines += body(c, indent + "  ")
        lines.append(f"{indent}</body>")
        return lines

    tree = [line for c in children[0] for line in body(c, "    ")]
    springs = [
        f"    <fixed name={quoteattr(model.joint_names[i] + '__spring')} "
        f'stiffness="{eff.stiffness[i]:.17g}" damping="{eff.spring_damping[i]:.17g}" '
        f'springlength="0 0">'
        f"<joint joint={quoteattr(model.joint_names[i] + '__motor')} coef=\"1\"/>"
        f"<joint joint={quoteattr(model.joint_names[i])} coef=\"-1\"/></fixed>"
        for i in np.flatnonzero(elastic)]
    extra = [f"    {element}" for element in tendons]
    tendon = ["  <tendon>", *springs, *extra, "  </tendon>"] if springs or extra else []
    return "\n".join([
        f"<mujoco model={quoteattr(model.name)}>",
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option gravity="{_num(model.gravity)}" timestep="{timestep:.17g}" '
        f'integrator="{integrator}">',
        '    <flag contact="disable" eulerdamp="disable"/>',
        "  </option>",
        "  <worldbody>", *tree, "  </worldbody>", *tendon,
        "</mujoco>", ""])


@dataclass(frozen=True, eq=False)
class Trace:
    """Raw output of :meth:`MujocoRobot.run`: logged and per-physics-step arrays.

    Attributes
    ----------
    t : (N,) times of the logged steps.
    q, dq, ddq : (N, nv) link coordinates and MuJoCo's accelerations at the logged steps.
    motor_q, motor_dq : (N, nv) drive-side coordinates (equal to the link's on rigid joints).
    sensed_q : (N, nv) the angle each position sensor reads (noise free).
    t_fine, tau_fine : (S,) and (S, nv): every physics step's time and the torque at the torque
        sensor (drive torque on a rigid joint, spring torque on an elastic one).
    control : (N, nv) the controller torque at the logged steps.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    motor_q: np.ndarray
    motor_dq: np.ndarray
    sensed_q: np.ndarray
    t_fine: np.ndarray
    tau_fine: np.ndarray
    control: np.ndarray


class MujocoRobot:
    """A MuJoCo simulation of a robot with the given true inertias and effects.

    Parameters
    ----------
    model : the robot; its kinematics, gravity and (unless ``parameters`` is given) inertias.
    effects : :class:`Effects`; default none.
    parameters : true standard parameters (10 per body), default ``model.prior_parameters``.
    timestep : physics step (s).
    integrator : MuJoCo integrator, ``"Euler"`` (default, see the module notes), ``"RK4"`` or
        ``"implicitfast"``.
    tendons : extra MJCF ``<fixed>`` tendon elements over the joints (e.g. the motors of a
        coupled transmission, :mod:`consistid.simulate.drives`).

    Attributes
    ----------
    xml : the MJCF text; ``mj_model`` : ``mujoco.MjModel``.
    payload : ``(joint index, 10-vector)`` of the payload (:meth:`MountedPayload.parameters`), or
        ``None``.
    link_dof, motor_dof : (nv,) MuJoCo dof index of each link joint and of its drive (the rotor
        dof of an elastic joint, else the link dof); every joint has one coordinate, so these
        index ``qpos`` as well.
    """

    def __init__(self, model: RobotModel, effects: Effects | None = None,
                 parameters: np.ndarray | None = None, timestep: float = 1e-3,
                 integrator: str = "Euler", tendons: Sequence[str] = ()) -> None:
        if not (np.isfinite(timestep) and timestep > 0):
            raise ModelError(f"timestep = {timestep!r}; it must be a positive number of seconds")
        if effects is not None and not isinstance(effects, Effects):
            raise ModelError(f"effects must be a consistid.simulate.Effects (e.g. "
                             f"Effects(coulomb=0.5)), got {type(effects).__name__} {effects!r}")
        self.model = model if parameters is None else model.with_parameters(parameters)
        self.effects = (effects or Effects()).for_model(model)
        self.timestep = float(timestep)
        self.payload = (self.effects.payload.parameters(model)
                        if self.effects.payload is not None else None)
        self.xml = _mjcf(self.model, self.effects, self.payload, timestep, integrator, tendons)
        try:
            self.mj_model = mujoco.MjModel.from_xml_string(self.xml)
        except ValueError as exc:  # MuJoCo's compiler errors name the element
            raise ModelError(f"MuJoCo could not compile {model.name}: {exc}") from exc
        mj = self.mj_model
        self.link_dof = np.array([mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)]
                                  for n in model.joint_names])
        self.motor_dof = self.link_dof.copy()
        for i in np.flatnonzero(self.effects.elastic):
            jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, model.joint_names[i] + "__motor")
            self.motor_dof[i] = mj.jnt_dofadr[jid]

    @property
    def nv(self) -> int:
        return self.model.nv

    def spring_torque(self, data: mujoco.MjData) -> np.ndarray:
        """τ_J = K(θ − q) + D(θ̇ − q̇) per joint (0 on rigid joints)."""
        e = self.effects
        return (np.asarray(e.stiffness) * (data.qpos[self.motor_dof] - data.qpos[self.link_dof])
                + np.asarray(e.spring_damping)
                * (data.qvel[self.motor_dof] - data.qvel[self.link_dof]))

    def set_payload(self, attached: bool) -> None:
        """Attach or detach the payload in place, e.g. a grasp in the middle of a run: its
        jointless body keeps its place and gets the payload's mass and inertia, or zero.

        MuJoCo reads ``body_mass`` and ``body_inertia`` at every step (``mj_comPos``), so the
        change acts from the next step. Needs a robot built with ``effects.payload``.
        """
        if self.payload is None:
            raise ModelError("set_payload: this robot was built without a payload; give "
                             "Effects(payload=MountedPayload(...)) and detach it at the start")
        mj = self.mj_model
        name = self.model.body_names[self.payload[0]] + "__payload"
        body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name)
        if not hasattr(self, "_payload_inertial"):
            self._payload_inertial = (float(mj.body_mass[body]), mj.body_inertia[body].copy())
        mass, inertia = self._payload_inertial
        mj.body_mass[body] = mass if attached else 0.0
        mj.body_inertia[body] = inertia if attached else 0.0

    def inverse(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """``mj_inverse``: the drive torque for each sample, (N, nv), rigid robots only.

        Includes MuJoCo's passive forces (damping) and ``armature``; friction loss is a
        constraint force and depends on the solver state, so it is not included here.
        """
        if self.effects.elastic.any():
            raise ModelError("inverse dynamics of an elastic robot is not a function of (q, q̇, q̈) "
                             "alone; switch elasticity off")
        q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
        data = mujoco.MjData(self.mj_model)
        out = np.empty_like(q)
        for k in range(q.shape[0]):
            data.qpos[self.link_dof], data.qvel[self.link_dof] = q[k], dq[k]
            data.qacc[self.link_dof] = ddq[k]
            mujoco.mj_inverse(self.mj_model, data)
            out[k] = data.qfrc_inverse[self.link_dof]
        return out

    def _start_state(self, data: mujoco.MjData, q: np.ndarray, dq: np.ndarray,
                     ddq: np.ndarray) -> None:
        """Put ``data`` in the state the robot has while tracking ``(q, q̇, q̈)``.

        Every drive (the motor of an elastic joint) is on ``(q, q̇)``, where the collocated
        controller holds it, so that it sees no error at the start. On an elastic joint the
        link lags by the spring's deflection ``δ = τ_J(q − δ)/K``, with ``τ_J`` MuJoCo's own
        link-side torque (``mj_inverse`` at ``(q − δ, q̇, q̈)``, springs relaxed: the true
        inertias, payload and armature), solved by fixed-point iteration. Then the springs
        alone give every elastic link the acceleration ``q̈`` (Spong's model, cited in
        :mod:`consistid.simulate.effects`: the link side is ``M(q)q̈ + h(q, q̇) = τ_J``).

        Raises
        ------
        ModelError : the iteration does not converge (a spring too soft for its load).
        """
        mj, link, drive = self.mj_model, self.link_dof, self.motor_dof
        elastic = self.effects.elastic
        for dof in (link, drive):
            data.qpos[dof], data.qvel[dof] = q, dq
        if not elastic.any():
            return
        stiffness = np.asarray(self.effects.stiffness)[elastic]
        deflection = np.zeros(int(elastic.sum()))
        for _ in range(START_ITERATIONS):
            data.qpos[drive] = data.qpos[link]                   # springs relaxed
            data.qacc[link], data.qacc[drive] = ddq, ddq
            mujoco.mj_inverse(mj, data)
            new = data.qfrc_inverse[link[elastic]] / stiffness
            data.qpos[link[elastic]] = q[elastic] - new
            change, deflection = np.max(np.abs(new - deflection)), new
            if change < START_TOL:
                break
        else:
            worst = np.flatnonzero(elastic)[int(np.argmax(np.abs(deflection)))]
            raise ModelError(
                "the elastic joints cannot hold the start state: the deflection "
                f"δ = τ_J(q − δ)/K did not converge in {START_ITERATIONS} iterations (last "
                f"change {change:.3g} rad; largest on {self.model.joint_names[worst]!r}, "
                f"stiffness {self.effects.stiffness[worst]:g}); the spring is too soft for its "
                "load")
        data.qpos[drive] = q

    def _check_tanh_step(self, q: np.ndarray) -> None:
        """The tanh friction (and the Stribeck relief and sigmoid,
        :func:`~consistid.simulate.effects.explicit_friction`) is applied explicitly, once per
        step: it is stable only while ``h·s / M_jj(q) < 1``, ``s`` its largest slope
        (``f_c/v_s`` for the tanh; :func:`~consistid.simulate.effects.explicit_friction_slope`),
        checked with each drive's smallest ``M_jj`` over the link positions ``q`` (S, nv), e.g.
        the desired trajectory (at most :data:`TANH_CHECK_SAMPLES` of them, evenly spaced)."""
        e = self.effects
        if not has_explicit_friction(e):
            return
        mj = self.mj_model
        data = mujoco.MjData(mj)
        full = np.zeros((mj.nv, mj.nv))
        rows = np.unique(np.linspace(0, q.shape[0] - 1, min(q.shape[0], TANH_CHECK_SAMPLES))
                         .round().astype(int))
        diag = np.full(self.nv, np.inf)
        for k in rows:
            data.qpos[self.link_dof] = q[k]
            data.qpos[self.motor_dof] = q[k]          # a rotor's angle does not change M
            mujoco.mj_kinematics(mj, data)
            mujoco.mj_comPos(mj, data)
            mujoco.mj_crb(mj, data)
            mujoco.mj_fullM(mj, data, full)
            diag = np.minimum(diag, np.diag(full)[self.motor_dof])
        ratio = self.timestep * explicit_friction_slope(e) / diag
        worst = int(np.argmax(ratio))
        if ratio[worst] >= 1.0 and not (e.coulomb_model == "tanh" and e.coulomb[worst] > 0):
            raise ModelError(
                f"the Stribeck/sigmoid friction on {self.model.joint_names[worst]!r} is too steep "
                f"for the physics step: h·slope/M_jj = {ratio[worst]:.3g} ≥ 1 (smallest M_jj "
                f"{diag[worst]:.3g} kg·m²); raise stribeck_speed, lower sigmoid_steepness, add "
                "armature, or shorten the step")
        if ratio[worst] >= 1.0:
            raise ModelError(
                f"tanh Coulomb friction on {self.model.joint_names[worst]!r} is too stiff for the "
                f"physics step: h·fc/(v_s·M_jj) = {ratio[worst]:.3g} ≥ 1 (smallest M_jj along "
                f"the trajectory {diag[worst]:.3g} kg·m²); raise effects.coulomb_speed above "
                f"{e.coulomb_speed * ratio[worst]:.3g} rad/s, add armature, or shorten the step")

    def _check_stable(self, data: mujoco.MjData, t: float) -> None:
        """Raise if MuJoCo flagged a diverging state (it then resets the state and carries on,
        which would leave a silently wrong log)."""
        bad = [w for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                           mujoco.mjtWarning.mjWARN_BADQPOS) if data.warning[w].number]
        if bad:
            dof = int(data.warning[bad[0]].lastinfo)
            raise ModelError(
                f"the MuJoCo simulation of {self.model.name} diverged before t = {t:.3f} s "
                f"({bad[0].name} at dof {dof}): the physics step {self.timestep:g} s is too long "
                "for the stiffest element (an elastic joint, ω = √(K/M_jj), on a light link, or "
                "damping D·h/M_jj ≥ 2, explicit here), or the controller is too stiff for it; "
                "raise physics_rate or soften the effect")

    def run(self, gains: tuple[float, float], nominal: RobotModel, t: np.ndarray,
            desired: tuple[np.ndarray, np.ndarray, np.ndarray], log_every: int,
            log_from: int = 0, progress: Callable[[float], None] | None = None,
            step_hook: Callable[[mujoco.MjModel, mujoco.MjData], None] | None = None
            ) -> Trace:
        """Track ``desired = (q_d, dq_d, ddq_d)``, one row per physics step at the times ``t``
        (spaced by the time step), with the computed-torque law of
        :class:`consistid.simulate.TrackingController` on the ``nominal`` model,
        ``gains = (K_p, K_d)``.

        The robot starts as it tracks (:meth:`_start_state`): the drives on the desired state,
        the links of elastic joints deflected by the springs' load. Every ``log_every``-th step
        from ``log_from`` is logged; the acceleration is MuJoCo's at the logged state
        (``mj_forward`` with the step's torques). ``progress`` (if given) is called with the
        fraction done every 1000 steps. ``step_hook(mj_model, mj_data)`` (if given) is called
        before every physics step, after the controller's torque is applied: it may add to
        ``qfrc_applied`` or change the model's per-dof ``frictionloss``/``damping`` (effects
        beyond :class:`~consistid.simulate.effects.Effects`, e.g.
        :mod:`consistid.simulate.disturbances`). Raises :class:`ModelError` if the simulation
        diverges,
        or before it starts if a tanh friction is too stiff for the step anywhere along ``q_d``
        or the elastic joints cannot hold the start state.
        """
        qd, dqd, ddqd = desired
        steps = qd.shape[0]
        mj, data = self.mj_model, mujoco.MjData(self.mj_model)
        eff, nv = self.effects, self.nv
        elastic = eff.elastic
        any_elastic = bool(elastic.any())
        sense_dof = self.motor_dof if eff.position_sensor == "motor" else self.link_dof
        drive, link = self.motor_dof, self.link_dof
        self._start_state(data, qd[0], dqd[0], ddqd[0])
        integrate = _INTEGRATE[int(mj.opt.integrator)]
        self._check_tanh_step(qd)
        kp, kd = gains
        pm = nominal.pin_model
        pdata = pm.createData()
        use_explicit = has_explicit_friction(eff)
        logged = np.arange(log_from, steps, log_every)
        n = logged.size
        out = {k: np.empty((n, nv)) for k in ("q", "dq", "ddq", "motor_q", "motor_dq",
                                             "sensed_q", "control")}
        tau_fine = np.empty((steps, nv))
        applied = np.zeros(mj.nv)
        row = 0
        for k in range(steps):
            qs, vs = data.qpos[drive], data.qvel[drive]  # collocated feedback
            u = pin.rnea(pm, pdata, nominal.configuration(qs), vs,
                         ddqd[k] + kp * (qd[k] - qs) + kd * (dqd[k] - vs))
            applied[drive] = u
            if use_explicit:
                applied[drive] -= explicit_friction(eff, data.qvel[drive])
            data.qfrc_applied[:] = applied
            if step_hook is not None:
                step_hook(mj, data)
            tau_fine[k] = np.where(elastic, self.spring_torque(data), u) if any_elastic else u
            if row < n and k == logged[row]:
                # mj_step opened (see _INTEGRATE): log the qacc it integrates
                mujoco.mj_checkPos(mj, data)
                mujoco.mj_checkVel(mj, data)
                mujoco.mj_forward(mj, data)
                for key, value in (("q", data.qpos[link]), ("dq", data.qvel[link]),
                                   ("ddq", data.qacc[link]), ("motor_q", data.qpos[drive]),
                                   ("motor_dq", data.qvel[drive]),
                                   ("sensed_q", data.qpos[sense_dof]),
                                   ("control", u)):
                    out[key][row] = value
                row += 1
                mujoco.mj_checkAcc(mj, data)
                integrate(mj, data)
            else:
                mujoco.mj_step(mj, data)
            if k % 1000 == 999 or k == steps - 1:
                self._check_stable(data, t[k] + self.timestep)
                if progress is not None:
                    progress((k + 1) / steps)
        return Trace(t=t[logged], t_fine=t, tau_fine=tau_fine, **out)
