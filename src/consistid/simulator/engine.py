r"""The user's simulator as a MuJoCo model: a robot's parameters in it, a PD actuator per joint.

:func:`build_simulator` makes the ``mujoco.MjModel`` a replay runs in, from either

* a :class:`~consistid.robot.model.RobotModel` and a parameter vector (10 per body, then
  per-joint terms by name): the dynamics-only MJCF of :func:`consistid.robot.mjcf.mjcf_spec`
  (armature ``Ia`` added to the model's own, viscous ``fv`` → ``damping``, Coulomb ``fc`` →
  ``frictionloss``), or
* the user's MJCF file (``mjcf=``, read with ``mujoco.MjSpec.from_file``; the file is not
  changed): the bodies and joints named as the robot's get the parameters in the compiled
  model (``body_mass``, ``body_ipos``, principal ``body_inertia``/``body_iquat`` of the inertia
  about the CoM, ``I_c = I_O − m [c]ₓᵀ[c]ₓ``; ``dof_armature``, ``dof_damping``,
  ``dof_frictionloss``), everything else (geometry, contacts, other joints) as the file has it.

Either way the file's own actuators are removed (the replay drives every joint by torque,
``qfrc_applied``) and one PD actuator per robot joint is added (:mod:`.options`), and the
physics step and integrator are the user's (``RolloutOptions``; ``None`` keeps the MJCF's).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import ModelError, ModelMisfitWarning
from ..robot.inertia import body_slice
from ..robot.joint_terms import joint_terms_of
from ..robot.mjcf import mjcf_spec
from ..robot.model import RobotModel

#: Prefix of the PD actuators the replay adds.
PD_PREFIX = "consistid_pd_"
#: The state a rollout starts from, and the controls it is given (actuator ctrl, then the
#: generalised applied force).
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
CONTROLS = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED
#: Per-joint terms a simulator holds, by the suffix of their parameter name.
SIM_TERMS = ("Ia", "fv", "fc")


@dataclass(frozen=True, eq=False)
class Simulator:
    """A compiled simulator of the robot.

    Attributes
    ----------
    mj_model : ``mujoco.MjModel`` with one PD actuator per robot joint (actuators ``0..nv-1``).
    dofs, qpos : (nv,) MuJoCo dof and ``qpos`` index of each robot joint (joint order).
    joint_names : the robot's joints.
    gain, delay : the actuation of a commanded torque ``τ``: the joints receive
        ``gain ⊙ τ(t − delay)`` ((nv,), s; :mod:`.terms`); ``None``, 0: as commanded.
    """

    mj_model: Any
    dofs: np.ndarray
    qpos: np.ndarray
    joint_names: tuple[str, ...]
    gain: np.ndarray | None = None
    delay: float = 0.0

    @property
    def nv(self) -> int:
        return self.dofs.size

    def joint_terms(self) -> dict[str, np.ndarray]:
        """The simulator's per-joint ``armature``, ``damping``, ``frictionloss``, (nv,) each."""
        m = self.mj_model
        return {"armature": m.dof_armature[self.dofs].copy(),
                "damping": m.dof_damping[self.dofs].copy(),
                "frictionloss": m.dof_frictionloss[self.dofs].copy()}

    def variant(self, armature: np.ndarray | None = None, damping: np.ndarray | None = None,
                frictionloss: np.ndarray | None = None) -> Any:
        """A copy of ``mj_model`` with other per-joint terms (for a batch of rollouts)."""
        m = mujoco.MjModel.__copy__(self.mj_model)
        for field, value in (("dof_armature", armature), ("dof_damping", damping),
                             ("dof_frictionloss", frictionloss)):
            if value is not None:
                getattr(m, field)[self.dofs] = value
        return m

    def with_gains(self, model: Any, kp: np.ndarray, kd: np.ndarray) -> Any:
        r"""A copy of ``model`` (this simulator's or a variant) with PD gains on the added
        actuators, ``force = K_p ctrl − K_p q − K_d q̇``.

        """
        out = mujoco.MjModel.__copy__(model)
        out.actuator_gainprm[:self.nv, 0] = kp
        out.actuator_biasprm[:self.nv, :3] = np.column_stack([np.zeros_like(kp), -kp, -kd])
        return out

    @property
    def implicit(self) -> bool:
        """The integrator treats actuator velocity gains implicitly (``implicit``,
        ``implicitfast``): their damping acts on the velocity at the end of the step."""
        return integrator_name(int(self.mj_model.opt.integrator)) in ("implicit", "implicitfast")

    @property
    def discrete_inverse(self) -> bool:
        """MuJoCo's discrete-time inverse dynamics (``mjENBL_INVDISCRETE``) exists for this
        integrator (all but ``RK4``): ``mj_inverse`` then returns the force that makes one step
        reach the given acceleration, implicit damping included."""
        return integrator_name(int(self.mj_model.opt.integrator)) != "RK4"

    def initial_state(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The full physics state (``mjSTATE_FULLPHYSICS``) at joint positions and velocities
        ``q``, ``dq`` (nv,), every other coordinate at the model's ``qpos0`` and rest."""
        data = mujoco.MjData(self.mj_model)
        data.qpos[self.qpos], data.qvel[self.dofs] = q, dq
        state = np.empty(mujoco.mj_stateSize(self.mj_model, STATE))
        mujoco.mj_getState(self.mj_model, data, state, STATE)
        return state

    def mass_diagonal(self, q: np.ndarray) -> np.ndarray:
        """Mean diagonal of the joint-space mass matrix (armature included) over the rows of
        ``q`` (S, nv), (nv,)."""
        m, data = self.mj_model, mujoco.MjData(self.mj_model)
        full = np.zeros((m.nv, m.nv))
        total = np.zeros(self.nv)
        for row in q:
            data.qpos[self.qpos] = row
            mujoco.mj_forward(m, data)
            mujoco.mj_fullM(m, data, full)
            total += np.diag(full)[self.dofs]
        return total / len(q)


def simulator_terms(model: RobotModel, parameters: np.ndarray,
                    names: Sequence[str] | None) -> tuple[np.ndarray, list[str]]:
    """``parameters`` and ``names`` restricted to what a simulator holds: the inertial entries
    and the ``Ia``, ``fv``, ``fc`` terms (torque offsets have no MuJoCo element)."""
    n = model.n_inertial
    names = list(names) if names is not None else list(model.parameter_names)
    keep = list(range(n)) + [k for k in range(n, len(parameters))
                             if names[k].rsplit(".", 1)[-1] in SIM_TERMS]
    return np.asarray(parameters, dtype=float)[keep], [names[k] for k in keep]


def build_simulator(model: RobotModel, parameters: np.ndarray | None = None,
                    parameter_names: Sequence[str] | None = None, *,
                    mjcf: str | Path | None = None, timestep: float | None = None,
                    integrator: str | None = None) -> Simulator:
    """The :class:`Simulator` of ``model`` with ``parameters`` (module docstring).

    Raises
    ------
    ModelError : the MJCF does not load or compile, or lacks a robot joint or body, or a
        body's frame is not its joint's (then its inertia cannot be written in its frame).
    InconsistentParametersError : a body is not physically consistent or a term is negative.
    """
    params = model.prior_parameters if parameters is None else np.asarray(parameters, float)
    params, names = simulator_terms(model, params, parameter_names)
    if mjcf is None:
        spec = mjcf_spec(model, params, names)
    else:
        try:
            spec = mujoco.MjSpec.from_file(str(mjcf))
        except ValueError as exc:
            raise ModelError(f"mjcf={str(mjcf)!r} does not load in MuJoCo: {exc}") from exc
    for act in list(spec.actuators):
        spec.delete(act)
    for name in model.joint_names:
        act = spec.add_actuator(name=PD_PREFIX + name, target=name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    if timestep is not None:
        spec.option.timestep = float(timestep)
    if integrator is not None:
        spec.option.integrator = getattr(mujoco.mjtIntegrator, _INTEGRATOR[integrator])
    try:
        mj = spec.compile()
    except ValueError as exc:
        where = f"mjcf={str(mjcf)!r}" if mjcf is not None else f"the MJCF of {model.name!r}"
        raise ModelError(f"MuJoCo could not compile {where} with a PD actuator on every "
                         f"joint of the robot: {exc}") from exc
    sim = Simulator(mj, *_joint_indices(mj, model.joint_names, mjcf),
                    tuple(model.joint_names))
    if mjcf is not None:
        _write_parameters(sim, model, params, names)
    return sim


_INTEGRATOR = {"Euler": "mjINT_EULER", "implicit": "mjINT_IMPLICIT",
               "implicitfast": "mjINT_IMPLICITFAST", "RK4": "mjINT_RK4"}


def integrator_name(code: int) -> str:
    """The MJCF name of MuJoCo's integrator ``code`` (``mjModel.opt.integrator``)."""
    return next(k for k, v in _INTEGRATOR.items() if int(getattr(mujoco.mjtIntegrator, v)) == code)


def _joint_indices(mj: Any, joints: Sequence[str], mjcf: Any) -> tuple[np.ndarray, np.ndarray]:
    ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n) for n in joints]
    missing = [n for n, i in zip(joints, ids) if i < 0]
    if missing:
        raise ModelError(f"mjcf={str(mjcf)!r} has no joint named {missing}; the robot's joints "
                         "are matched by name")
    return mj.jnt_dofadr[ids].copy(), mj.jnt_qposadr[ids].copy()


def _write_parameters(sim: Simulator, model: RobotModel, params: np.ndarray,
                      names: Sequence[str]) -> None:
    """Put the inertial parameters and per-joint terms into ``sim.mj_model`` by name."""
    mj = sim.mj_model
    for joint_name in model.joint_names:
        jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, joint_name)
        if np.linalg.norm(mj.jnt_pos[jid]) > 1e-9:
            raise ModelError(f"joint {joint_name!r} sits at {mj.jnt_pos[jid]} in its MJCF body; "
                             "its inertia is identified in the joint's frame, so the body "
                             "frame must be the joint frame (joint pos = 0)")
    write_inertias(sim, mj, params[:model.n_inertial])
    terms = joint_terms_of(model, params, names)
    pm = model.pin_model
    for i, joint in enumerate(model.joint_names):
        values = terms.get(joint, {})
        dof = sim.dofs[i]
        if "Ia" in values:
            mj.dof_armature[dof] = float(pm.armature[i]) + values["Ia"]
        if "fv" in values:
            mj.dof_damping[dof] = values["fv"]
        if "fc" in values:
            mj.dof_frictionloss[dof] = values["fc"]
    mujoco.mj_setConst(mj, mujoco.MjData(mj))


def write_inertias(sim: Simulator, mj: Any, inertial: np.ndarray) -> None:
    """Put the standard parameters ``inertial`` (10 per body, joint order) into ``mj`` (this
    simulator's model or a variant): mass, CoM, and the inertia about the CoM in its principal
    axes (``body_inertia``, ``body_iquat``), the body frame being the joint frame. Call
    ``mujoco.mj_setConst`` afterwards. A negative moment (not a physical body) is raised to 0
    with a :class:`~consistid.errors.ModelMisfitWarning`, never silently."""
    for i, body in enumerate(mj.dof_bodyid[sim.dofs]):
        inertia = pin.Inertia.FromDynamicParameters(inertial[body_slice(i)])
        moments, axes = np.linalg.eigh(np.asarray(inertia.inertia))
        if np.linalg.det(axes) < 0:
            axes[:, 0] *= -1.0
        quat = pin.Quaternion(axes)
        mj.body_mass[body] = inertia.mass
        mj.body_ipos[body] = inertia.lever
        if moments.min() < -1e-9 * max(np.abs(moments).max(), 1e-300):
            name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, int(body))
            warnings.warn(f"body {name!r}: principal moments {moments} about its centre of "
                          "mass include a negative one, not a physical body; "
                          "the simulator gets it raised to 0 (identify with method='sdp' for "
                          "consistent inertias)", ModelMisfitWarning, stacklevel=3)
        mj.body_inertia[body] = np.maximum(moments, 0.0)
        mj.body_iquat[body] = [quat.w, quat.x, quat.y, quat.z]
