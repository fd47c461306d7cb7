"""Robot models: a Pinocchio model plus the names and the prior (CAD) parameters consistid needs.

A :class:`RobotModel` wraps a ``pinocchio.Model`` built from a URDF (dynamics only; meshes are never
loaded). It keeps Pinocchio's description/workspace split: the model is immutable, and every
algorithm creates its own ``pinocchio.Data``.

Joint coordinates in consistid are always *angles* (one per velocity DoF). Pinocchio represents an
unbounded revolute joint (URDF ``continuous``) by ``(cos θ, sin θ)``;
:meth:`RobotModel.configuration`
converts, so datasets stay ``(N, nv)`` for every robot.
"""

from __future__ import annotations

import hashlib
import re
import site
import sys
import tempfile
import warnings
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np
import pinocchio as pin

from ..errors import DatasetError, JointCountError, ModelError, ModelWarning, OptionError
from .export import write_urdf
from .inertia import INERTIAL_NAMES, check_body, inertias_from_vector
from .mjcf_in import is_mjcf, read_mjcf
from .urdf import JointDynamics, check_urdf, joint_dynamics, strip_dynamics

#: Gravity (m/s², base frame) of a level base: what a URDF implies.
DEFAULT_GRAVITY = (0.0, 0.0, -9.81)

#: example-robot-data arms consistid knows by name: URDF path below ``robots/`` and joints to lock.
EXAMPLE_ROBOTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "panda": ("panda_description/urdf/panda.urdf", ("panda_finger_joint1", "panda_finger_joint2")),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", ()),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", ()),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", ()),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", ()),
    "kinova": ("kinova_description/robots/kinova.urdf", ()),
    "z1": ("z1_description/urdf/z1.urdf", ("jointGripper",)),
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", ()),
}


def example_robot_data_dir() -> Path:
    """The ``robots/`` folder that the ``example-robot-data`` wheel installs.

    The wheel ships URDFs under ``site-packages/cmeel.prefix/share/example-robot-data/robots``
    and no Python module (see the project's stack notes), so we look for that folder on the path.
    """
    roots = [*sys.path, *site.getsitepackages(), site.getusersitepackages()]
    for root in roots:
        candidate = Path(root) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if candidate.is_dir():
            return candidate
    raise ModelError(
        "example-robot-data is not installed (no cmeel.prefix/share/example-robot-data/robots on "
        "the Python path); install it with `pip install example-robot-data`"
    )


def _check_gravity(gravity: object, warn: bool = True) -> np.ndarray:
    """``gravity`` as 3 finite floats (m/s², base frame), else :class:`ModelError`; a magnitude
    beyond :data:`MAX_GRAVITY` warns (:class:`ModelWarning`) when ``warn``."""
    try:
        g = np.asarray(gravity, dtype=float)
    except (TypeError, ValueError):
        g = np.full(1, np.nan)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ModelError(f"gravity must be 3 finite numbers (m/s², base frame), got "
                         f"{gravity!r}")
    if warn and np.linalg.norm(g) > MAX_GRAVITY:
        warnings.warn(f"gravity {[float(v) for v in g]} has magnitude {np.linalg.norm(g):.4g} "
                      f"m/s², more than {MAX_GRAVITY:g}: in mm/s² (or g's) rather than m/s²? "
                      "Every torque of the model scales with it", ModelWarning, stacklevel=3)
    return g


#: Gravity magnitudes beyond this (m/s²) warn (:func:`_check_gravity`): 9.81 in mm/s² reads 9810.
MAX_GRAVITY = 30.0


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Joint limits read from the URDF, one entry per velocity DoF (SI units)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


#: The most moving joints a model may have: far beyond any manipulator or humanoid (≈ 40), and
#: below where Pinocchio's ``createData`` (run by every computation; it grows as ~nv^2.6: 0.35 s
#: at 128 joints, 2 s at 256, 28 s at 500 on one core) makes each call a minutes-long wait.
MAX_MOVING_JOINTS = 256



class RobotModel:
    """A fixed-base robot for identification.

    Parameters
    ----------
    model : pinocchio.Model
        Dynamics model; bodies are the joints' child links (locked joints already merged).
    name : str
        A label used in reports.
    source : pathlib.Path, optional
        The URDF the model was read from (used by exporters and the MuJoCo simulator).
    locked_joints : tuple of str
        Joints that were locked (merged into their parent) when building the model.

    Attributes
    ----------
    joint_names : list of str, length ``nv``
    body_names : list of str, length ``nbodies`` (the link that moves with each joint)
    parameter_names : list of str, length ``10·nbodies``, e.g. ``"panda_link3.Izz"``
    prior_parameters : ndarray, shape (10·nbodies,)
        The URDF's standard parameters in Pinocchio order
        ``[m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` per body, inertia about the joint
        frame origin (``pinocchio.Inertia.toDynamicParameters``).
    """

    def __init__(
        self,
        model: pin.Model,
        name: str = "robot",
        source: Path | None = None,
        locked_joints: Sequence[str] = (),
        locked_configuration: dict[str, float] | None = None,
    ) -> None:
        if model.nv > MAX_MOVING_JOINTS:
            raise ModelError(
                f"robot {name!r} has {model.nv} moving joints, more than the "
                f"{MAX_MOVING_JOINTS} consistid takes (consistid.robot.model.MAX_MOVING_JOINTS): "
                "Pinocchio's workspace for such a model takes seconds to minutes to build (2 s "
                "at 256 joints, 28 s at 500 on one core), at every call, and cannot be "
                "interrupted; lock the joints that do not move (locked_joints=) or raise the "
                "limit knowingly")
        if model.nv == 0:
            locked = f" (locked: {list(locked_joints)})" if locked_joints else ""
            raise ModelError(f"robot {name!r} has no moving joint{locked}: nothing to identify; "
                             "a URDF needs revolute, continuous or prismatic joints, and "
                             "locked_joints must leave at least one of them")
        for j in range(1, model.njoints):
            if model.joints[j].nv != 1:
                raise ModelError(
                    f"joint {model.names[j]!r} has {model.joints[j].nv} DoF; consistid handles "
                    "fixed-base robots with 1-DoF joints (revolute, continuous, prismatic)"
                )
            values = model.inertias[j].toDynamicParameters()
            if not np.all(np.isfinite(values)):
                k = int(np.flatnonzero(~np.isfinite(values))[0])
                raise ModelError(f"robot {name!r}: the body of joint {model.names[j]!r} has "
                                 f"{INERTIAL_NAMES[k]} = {values[k]} (not finite)")
        _check_gravity(model.gravity.linear, warn=False)
        self.pin_model = model
        self.name = name
        self.source = Path(source) if source is not None else None
        self.locked_joints = tuple(locked_joints)
        self.locked_configuration = dict(locked_configuration or {})
        #: A reloaded result's record of its URDF (``source``, ``urdf_sha256``, ``urdf`` text),
        #: written back by ``save`` as it was read; the path in it is never opened.
        self.urdf_record: dict[str, str | None] | None = None

    # ----------------------------------------------------------------------------- construction
    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        locked_joints: Iterable[str] = (),
        locked_configuration: dict[str, float] | None = None,
        name: str | None = None,
        gravity: Sequence[float] | None = None,
    ) -> "RobotModel":
        """Read a URDF (dynamics only) and lock the named joints.

        Parameters
        ----------
        path : path to the URDF file, or the URDF text itself (a string starting with ``<``;
            kept in a temporary file for the session, ``model.source``, so that ``to_urdf``
            and the collision shapes can read it). Meshes are not loaded, so ``package://``
            URIs need not resolve.
        locked_joints : joints merged into their parent link (e.g. a gripper's fingers).
        locked_configuration : angle (rad) or position (m) at which to lock each joint, default 0.
        name : label for reports; default the file stem (the ``<robot name>`` of URDF text).
        gravity : gravity vector in the base frame, default ``(0, 0, -9.81)``.
        """
        if isinstance(path, bytes):
            try:
                path = path.decode("utf-8")
            except UnicodeDecodeError:
                raise ModelError("from_urdf got bytes that are not UTF-8 text; pass the URDF's "
                                 "path or its text") from None
        if isinstance(path, str) and path.lstrip().startswith("<"):
            path, name = _urdf_text_file(path, name)
        if not isinstance(path, (str, Path)) or (isinstance(path, str) and not path.strip()):
            raise ModelError(f"from_urdf needs the URDF's path or its XML text, got {path!r}")
        path = Path(path)
        if path.is_dir():
            found = sorted(p.name for p in path.glob("*.urdf"))
            raise ModelError(f"URDF file {str(path)!r} is a folder, not a file"
                             + (f"; it holds {found[:6]}" if found else ""))
        if not path.is_file():
            raise ModelError(f"URDF file {str(path)!r} does not exist")
        if isinstance(locked_joints, (str, bytes)):
            raise ModelError(f"locked_joints must be a list of joint names, got "
                             f"{locked_joints!r} (write [{locked_joints!r}])")
        g = None if gravity is None else _check_gravity(gravity)
        try:
            full = pin.buildModelFromUrdf(str(path))
        except Exception as exc:  # Pinocchio raises plain RuntimeError / ValueError
            try:
                check_urdf(path, list(locked_joints))   # a named cause, when there is one
            except ModelError as named:
                raise ModelError(f"Pinocchio could not read URDF {str(path)!r}: "
                                 f"{named}") from exc
            raise ModelError(f"Pinocchio could not read URDF {str(path)!r}: {exc}") from exc
        locked = list(locked_joints)
        config = dict(locked_configuration or {})
        bad_names = [j for j in locked if not isinstance(j, str)]
        if bad_names:
            raise ModelError(f"locked_joints must be joint names (strings), got {bad_names}")
        unknown = [j for j in [*locked, *config] if not full.existJointName(j)]
        if unknown:
            raise ModelError(
                f"unknown joint(s) {unknown} in {path.name}; joints are {list(full.names)[1:]}"
            )
        twice = sorted({j for j in locked if locked.count(j) > 1})
        if twice:
            raise ModelError(f"locked_joints names {twice} more than once: {locked}")
        unlocked = sorted(set(config) - set(locked))
        if unlocked:
            raise ModelError(f"locked_configuration names joint(s) {unlocked} that are not in "
                             f"locked_joints {locked}")
        check_urdf(path, locked)  # what Pinocchio accepts silently: bad masses, axes, mimics
        model = full
        if locked:
            q_ref = pin.neutral(full)
            outside = []
            for joint in locked:
                jid = full.getJointId(joint)
                iq = full.joints[jid].idx_q
                if full.joints[jid].nq == 2 and full.joints[jid].nv == 1:
                    # a continuous joint: Pinocchio's coordinates are (cos θ, sin θ)
                    angle = config.get(joint, 0.0)
                    q_ref[iq:iq + 2] = np.cos(angle), np.sin(angle)
                    continue
                if full.joints[jid].nq != 1:
                    raise ModelError(f"cannot lock joint {joint!r}: only 1-DoF joints")
                q_ref[iq] = config.get(joint, 0.0)
                lo, hi = full.lowerPositionLimit[iq], full.upperPositionLimit[iq]
                if joint in config and lo < hi and not lo - 1e-9 <= q_ref[iq] <= hi + 1e-9:
                    outside.append(f"{joint!r} at {q_ref[iq]:g} outside [{lo:.4g}, {hi:.4g}]")
            if outside:
                warnings.warn(f"{path.name}: locked_configuration puts {'; '.join(outside)} (its "
                              "URDF limits): in degrees rather than radians (or mm rather than "
                              "m)? The merged body is built at that position",
                              ModelWarning, stacklevel=2)
            try:
                model = pin.buildReducedModel(full, [full.getJointId(j) for j in locked], q_ref)
            except (ValueError, RuntimeError) as exc:   # Pinocchio's own lookups by frame name
                links = {f.name for f in full.frames if f.type == pin.FrameType.BODY}
                clash = [j for j in locked if j in links]
                cause = (f"locked joint(s) {clash} share their name with a link, which Pinocchio "
                         "cannot tell apart once the joint is fixed; rename the joint in the "
                         f"URDF (e.g. '{clash[0]}_joint') or leave it out of locked_joints"
                         if clash else str(exc))
                raise ModelError(f"{path.name}: cannot lock {locked}: {cause}") from exc
        if g is not None:
            model.gravity.linear = g
        robot = cls(model, name=name or path.stem, source=path, locked_joints=locked,
                    locked_configuration=config)
        _warn_unphysical(robot, path.name)
        return robot

    @classmethod
    def from_mjcf(
        cls,
        path: str | Path,
        locked_joints: Iterable[str] = (),
        locked_configuration: dict[str, float] | None = None,
        name: str | None = None,
        gravity: Sequence[float] | None = None,
    ) -> "RobotModel":
        """Read an MJCF (MuJoCo XML, e.g. a MuJoCo Menagerie arm) as a nominal model, compiled
        by MuJoCo (defaults classes, includes, meshes, inertias from geoms); see
        :mod:`consistid.robot.mjcf_in`. The joints' ``armature`` is the model's
        (``pinocchio.rnea`` includes it, as ``mj_inverse`` does); ``damping`` and
        ``frictionloss`` are kept as the Pinocchio model's ``damping`` and ``friction``
        (priors, not part of ``rnea``). Identified values go back into the file with
        ``result.to_mjcf(path, source=model.source)``.

        Parameters
        ----------
        path : the MJCF file (its meshes are read by MuJoCo's compiler).
        locked_joints : joints merged into their parent body (e.g. a gripper's fingers).
        locked_configuration : position at which to lock each joint, default its ``qpos0``.
        name : label for reports; default the file stem.
        gravity : gravity in the base frame; default the file's ``<option gravity>``.

        Raises
        ------
        ModelError : a free joint (floating base), a ball joint, a body with several joints,
            an unnamed joint, XML with a DTD or entities, or what MuJoCo cannot compile
            (named).
        """
        path = Path(path)
        g = None if gravity is None else _check_gravity(gravity)
        model, locked, config = read_mjcf(path, locked_joints, locked_configuration)
        if g is not None:
            model.gravity.linear = g
        robot = cls(model, name=name or path.stem, source=path, locked_joints=locked,
                    locked_configuration=config)
        _warn_unphysical(robot, path.name)
        return robot

    @property
    def source_format(self) -> str | None:
        """``"mjcf"`` for a model read by :meth:`from_mjcf`, ``"urdf"`` for one read from a
        URDF, ``None`` without a source file."""
        if self.source is None or not self.source.is_file():
            return None
        return "mjcf" if is_mjcf(self.source) else "urdf"

    @classmethod
    def example(cls, name: str) -> "RobotModel":
        """An arm shipped by ``example-robot-data``, grippers locked.

        Known names: ``panda, ur3, ur5, ur10, xarm7, kinova, z1, double_pendulum``.
        """
        if name not in EXAMPLE_ROBOTS:
            raise OptionError(f"name={name!r} is not an example robot; they are "
                              f"{', '.join(map(repr, EXAMPLE_ROBOTS))}. For another arm: "
                              "RobotModel.from_urdf('path/to/robot.urdf')")
        relative, locked = EXAMPLE_ROBOTS[name]
        return cls.from_urdf(example_robot_data_dir() / relative, locked_joints=locked, name=name)

    def with_parameters(self, parameters: np.ndarray) -> "RobotModel":
        """A copy whose body inertias are ``parameters`` (standard vector, 10 per body).

        Extra entries after the ``10·nbodies`` inertial ones (friction, armature) are ignored here.
        """
        try:
            parameters = np.asarray(parameters, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"parameters must be a vector of numbers: {exc}") from None
        if parameters.ndim != 1 or parameters.shape[0] < self.n_inertial:
            raise ModelError(
                f"parameter vector has shape {parameters.shape}; {self.name} needs a vector of "
                f"at least {self.n_inertial} inertial parameters (10 per body)"
            )
        inertial = parameters[: self.n_inertial]
        bad = np.flatnonzero(~np.isfinite(inertial))
        if bad.size:
            raise ModelError(f"parameters[{int(bad[0])}] ({self.parameter_names[bad[0]]}) is "
                             f"{inertial[bad[0]]}: {bad.size} non-finite inertial parameter(s)")
        massless = [self.body_names[i] for i in range(self.n_bodies) if inertial[10 * i] == 0
                    and np.any(inertial[10 * i + 1:10 * i + 4])]
        if massless:
            raise ModelError(f"bodies {massless} have mass 0 but a non-zero first moment m·c: "
                             "no centre of mass represents that (c = m·c / m)")
        model = self.pin_model.copy()
        for j, (inertia, p) in enumerate(zip(inertias_from_vector(inertial),
                                             inertial.reshape(-1, 10)), start=1):
            if p[0] == 0:   # massless (m·c = 0 checked above): no CoM, c = m·c/m would be NaN;
                xx, xy, yy, xz, yz, zz = p[4:]      # its rotational inertia is the same anywhere
                inertia = pin.Inertia(0.0, np.zeros(3), np.array([[xx, xy, xz], [xy, yy, yz],
                                                                  [xz, yz, zz]]))
            model.inertias[j] = inertia
        return RobotModel(model, name=self.name, source=self.source,
                          locked_joints=self.locked_joints,
                          locked_configuration=self.locked_configuration)

    def with_gravity(self, gravity: Sequence[float]) -> "RobotModel":
        """A copy whose gravity vector (base frame, m/s²) is ``gravity``; inertias unchanged.

        E.g. the gravity of a tilted mounting,
        :func:`consistid.estimation.mounting.estimate_mounting`.
        """
        g = _check_gravity(gravity)
        model = self.pin_model.copy()
        model.gravity = pin.Motion(g, np.zeros(3))
        return RobotModel(model, name=self.name, source=self.source,
                          locked_joints=self.locked_joints,
                          locked_configuration=self.locked_configuration)

    def with_kinematics(self, pin_model: pin.Model, source: str | Path | None = None
                        ) -> "RobotModel":
        """A copy built on ``pin_model``: the same joints (names, order) with other kinematics,
        e.g. the calibrated joint placements and axes of
        :func:`consistid.kinematics.calibrate_kinematics`. Inertias and gravity are
        ``pin_model``'s. ``source`` is the URDF that describes it (default none: this model's
        source no longer does, so exporters refuse rather than write the old kinematics)."""
        if not isinstance(pin_model, pin.Model) or list(pin_model.names) != \
                list(self.pin_model.names):
            raise ModelError(f"with_kinematics needs a pinocchio.Model with the joints "
                             f"{self.joint_names} of {self.name}")
        return RobotModel(pin_model, name=self.name, source=source,
                          locked_joints=self.locked_joints,
                          locked_configuration=self.locked_configuration)

    def to_urdf(self, path: str | Path, parameters: np.ndarray | None = None,
                parameter_names: Sequence[str] | None = None, merged: str = "auto") -> Path:
        """Write the source URDF carrying this model's inertias (or ``parameters``, with optional
        friction entries named by ``parameter_names``); see
        :func:`consistid.robot.export.write_urdf`.

        Refuses (``InconsistentParametersError``) to write a physically inconsistent body, and
        (:class:`ModelError`) to write over the URDF the model was read from.
        """
        return write_urdf(self, path, parameters, parameter_names, merged)

    # ----------------------------------------------------------------------------- description
    @property
    def nv(self) -> int:
        """Number of joints (velocity DoF)."""
        return int(self.pin_model.nv)

    @property
    def n_bodies(self) -> int:
        """Number of moving bodies (one per joint)."""
        return int(self.pin_model.njoints - 1)

    @property
    def n_inertial(self) -> int:
        """Number of standard inertial parameters, ``10·n_bodies``."""
        return 10 * self.n_bodies

    @cached_property
    def joint_names(self) -> list[str]:
        return list(self.pin_model.names)[1:]

    @cached_property
    def body_names(self) -> list[str]:
        names = []
        for j in range(1, self.pin_model.njoints):
            bodies = [f.name for f in self.pin_model.frames
                      if f.parentJoint == j and f.type == pin.FrameType.BODY]
            names.append(bodies[0] if bodies else f"body{j}")
        return names

    @cached_property
    def parameter_names(self) -> list[str]:
        return [f"{body}.{p}" for body in self.body_names for p in INERTIAL_NAMES]

    @property
    def prior_parameters(self) -> np.ndarray:
        return np.concatenate([self.pin_model.inertias[j].toDynamicParameters()
                               for j in range(1, self.pin_model.njoints)])

    @property
    def gravity(self) -> np.ndarray:
        return np.array(self.pin_model.gravity.linear)

    @property
    def has_default_gravity(self) -> bool:
        """Gravity is the level default ``(0, 0, −9.81)`` m/s², the one a URDF implies (a URDF
        has no tag for gravity: anything else must travel beside the file)."""
        return bool(np.allclose(self.gravity, DEFAULT_GRAVITY))

    @cached_property
    def limits(self) -> JointLimits:
        """Joint limits per DoF; ``±inf`` where the URDF sets none.

        Unbounded (continuous) joints get ``±inf``. A URDF ``<limit>`` with an empty position
        range (``lower ≥ upper``) or a zero velocity/effort — example-robot-data's double pendulum
        writes ``0`` for all four, meaning "not set" — is read as unlimited, not as a joint that
        cannot move.
        """
        m = self.pin_model
        lower, upper = np.empty(self.nv), np.empty(self.nv)
        for j in range(1, m.njoints):
            joint = m.joints[j]
            if joint.nq == 1:
                lower[joint.idx_v] = m.lowerPositionLimit[joint.idx_q]
                upper[joint.idx_v] = m.upperPositionLimit[joint.idx_q]
            else:
                lower[joint.idx_v], upper[joint.idx_v] = -np.inf, np.inf
        unset = lower >= upper
        lower[unset | ~np.isfinite(lower) | (lower < -1e10)] = -np.inf
        upper[unset | ~np.isfinite(upper) | (upper > 1e10)] = np.inf
        velocity, effort = np.array(m.velocityLimit), np.array(m.effortLimit)
        velocity[velocity <= 0] = np.inf
        effort[effort <= 0] = np.inf
        return JointLimits(lower, upper, velocity, effort)

    def __repr__(self) -> str:
        return (f"RobotModel({self.name!r}, nv={self.nv}, bodies={self.n_bodies}, "
                f"locked={list(self.locked_joints)})")

    # ----------------------------------------------------------------------------- kinematics
    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration (``nq``) from joint angles (``nv``): ``(nv,) → (nq,)``, or
        ``(N, nv) → (N, nq)`` sample by sample."""
        q = np.asarray(q, dtype=float)
        m = self.pin_model
        if q.ndim not in (1, 2) or q.shape[-1] != self.nv:
            raise JointCountError(f"q has shape {q.shape}, not ({self.nv},) or (N, {self.nv}) "
                                  f"for the {self.nv} joints of {self.name}")
        if m.nq == m.nv:
            return q
        out = np.empty(q.shape[:-1] + (m.nq,))
        for j in range(1, m.njoints):
            joint = m.joints[j]
            if joint.nq == 1:
                out[..., joint.idx_q] = q[..., joint.idx_v]
            else:  # unbounded revolute: (cos, sin)
                out[..., joint.idx_q] = np.cos(q[..., joint.idx_v])
                out[..., joint.idx_q + 1] = np.sin(q[..., joint.idx_v])
        return out

    def rnea(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """Rigid-body inverse dynamics ``τ = M(q)q̈ + C(q,q̇)q̇ + g(q)`` for each sample, (N, nv).

        Uses ``pinocchio.rnea`` (which adds ``model.armature · q̈``); samples along axis 0.
        """
        q, dq, ddq = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, dq, ddq))
        for name, a in (("q", q), ("dq", dq), ("ddq", ddq)):
            if a.ndim != 2:
                raise JointCountError(f"{name} has shape {a.shape}, not (N, {self.nv}) for the "
                                      f"{self.nv} joints of {self.name}")
            if a.shape[1] != self.nv:
                raise JointCountError(f"{name} has {a.shape[1]} joints but {self.name} has "
                                      f"{self.nv}")
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                k, j = (int(i) for i in bad[0])
                raise DatasetError(f"{name}[{k}, {self.joint_names[j]!r}] is {a[k, j]} "
                                   f"({len(bad)} non-finite value(s) in {name})")
        data = self.pin_model.createData()
        out = np.empty_like(dq)
        for k in range(q.shape[0]):
            out[k] = pin.rnea(self.pin_model, data, self.configuration(q[k]), dq[k], ddq[k])
        return out


#: Round-off forgiven by :func:`_warn_unphysical` (kg·m²).
UNPHYSICAL_TOL = 1e-9


def _warn_unphysical(robot: RobotModel, source: str) -> None:
    """Warn (:class:`ModelWarning`) about bodies of a loaded URDF whose inertia no physical body
    has (a principal moment below 0, or the triangle inequality violated, beyond
    :data:`UNPHYSICAL_TOL`). Massless bodies (virtual links) are left to what needs a mass."""
    found = []
    for i, body in enumerate(robot.body_names):
        p = robot.prior_parameters[10 * i:10 * i + 10]
        if p[0] > 0:
            verdict = check_body(p, "triangle", body, tol=UNPHYSICAL_TOL)
            if not verdict.ok:
                found.append(verdict.reason)
    if found:
        warnings.warn(f"{source}: {len(found)} of {robot.n_bodies} bodies have an inertia no "
                      f"physical body has ({'; '.join(found[:3])}{' …' if len(found) > 3 else ''}"
                      "). MuJoCo refuses them (consistid.simulate), identify(method='sdp') centres "
                      "its prior on them with the Euclidean metric, not the default log-det one "
                      "(which cannot be centred there; prior='logdet' refuses them), and a "
                      "diagnosis measures against a robot that cannot exist", ModelWarning,
                      stacklevel=3)


_TEXT_DIR: list[tempfile.TemporaryDirectory] = []


def _urdf_text_file(text: str, name: str | None) -> tuple[Path, str]:
    """URDF text written to a file in a folder removed when the interpreter exits, and the
    model's name (``name``, else the ``<robot name>``, else ``"robot"``)."""
    found = re.search(r"<robot\b[^>]*\bname\s*=\s*[\"']([^\"']+)[\"']", text)
    label = name or (found.group(1) if found else "robot")
    if not _TEXT_DIR:
        _TEXT_DIR.append(tempfile.TemporaryDirectory(prefix="consistid-urdf-"))
    digest = hashlib.sha1(text.encode()).hexdigest()[:10]
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", label)
    path = Path(_TEXT_DIR[0].name) / f"{safe}-{digest}.urdf"
    path.write_text(text)
    return path, label


def require_model(model: object) -> RobotModel:
    """``model`` if it is a :class:`RobotModel`, else :class:`ModelError` saying how to make one."""
    if not isinstance(model, RobotModel):
        raise ModelError(f"model must be a consistid.RobotModel (RobotModel.from_urdf(path) or "
                         f"RobotModel.example(name)), got {type(model).__name__} {model!r:.60}")
    return model


def model_without_dynamics(path: str | Path, **from_urdf: Any
                           ) -> tuple[RobotModel, dict[str, JointDynamics]]:
    """Load a URDF whose ``<dynamics>`` tags Pinocchio refuses; return the model and the tags.

    The tags are stripped into a temporary copy (deleted afterwards), which is loaded with
    :meth:`RobotModel.from_urdf` (``from_urdf`` keyword arguments are passed on; the model's
    ``source`` and default name are those of the original file). Rigid-body dynamics are
    unaffected: Pinocchio does not use the tags in ``rnea`` or the regressor.
    """
    path = Path(path)
    dynamics = joint_dynamics(path)
    from_urdf.setdefault("name", path.stem)
    with tempfile.TemporaryDirectory(prefix="consistid-urdf-") as tmp:
        loaded = RobotModel.from_urdf(strip_dynamics(path, Path(tmp) / path.name), **from_urdf)
    model = RobotModel(loaded.pin_model, name=loaded.name, source=path,
                       locked_joints=loaded.locked_joints,
                       locked_configuration=loaded.locked_configuration)
    return model, dynamics
