r"""Read an MJCF (MuJoCo's XML) as a nominal :class:`~consistid.robot.model.RobotModel`.

The file is compiled by **MuJoCo's own compiler** (``mujoco.MjModel.from_xml_path``), which
resolves ``<default>`` classes, ``<include>`` files, meshes, ``inertiafromgeom`` (inertias
derived from geoms), ``<compiler angle>``/``eulerseq`` and the ``iquat``/``ipos`` of each body;
the Pinocchio model is then built from the compiled numbers. ``pinocchio.buildModelFromMJCF``
re-implements that compiler and cannot derive an inertia from a mesh, so it is not used.

For each MuJoCo body ``b`` with one hinge or slide joint, a Pinocchio joint is placed at the
joint's anchor: the joint frame is ``B_b · (I, p_j) · exp(−r S)`` with
``B_b = (body_quat, body_pos)`` relative to the parent's body frame, ``p_j = jnt_pos`` and ``r``
the joint's ``ref`` (MuJoCo's body frames are at ``q = ref``: turned back by it, Pinocchio's
``q`` is MuJoCo's ``qpos``); the axis ``S`` is ``jnt_axis`` (body frame), and the body frame
is ``(I, −p_j)`` in the joint frame. The body's compiled inertial (mass ``m``, CoM ``ipos``,
principal moments ``d`` with axes ``R = iquat``) enters as ``I_c = R diag(d) Rᵀ`` about the CoM
at ``ipos − p_j`` in the joint frame. A body without a joint is welded to its parent
(``pinocchio.Model.appendBodyToJoint``); a body welded to the world is part of the fixed base.
Per joint, MuJoCo's ``armature``, ``damping`` and ``frictionloss`` go into Pinocchio's
``armature`` (which ``pinocchio.rnea`` includes, as ``mj_inverse`` does), ``damping`` and
``friction``; gravity is ``opt.gravity``. Joint ranges are the compiled ``jnt_range``; an
effort limit is the joint's ``actfrcrange``, else that of the actuators driving it
(``forcerange``, or ``gear · gain · ctrlrange`` for a fixed-gain motor).

Refused by name (:class:`ModelError`): a free joint (a floating base) or a ball joint, a body
with more than one joint, an unnamed joint, and what MuJoCo cannot compile (its message). The
user's XML is first read with ``defusedxml`` (no DTD, no entity expansion).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Iterable

import defusedxml.ElementTree as SafeET
import numpy as np
import pinocchio as pin
from defusedxml import DefusedXmlException

from ..errors import ModelError
from ..textsafety import check_writable_name

#: MuJoCo joint types (``mjtJoint``) consistid models: hinge (3) and slide (2).
HINGE, SLIDE, BALL, FREE = 3, 2, 1, 0


def check_safe_xml(path: Path) -> str:
    """The file's text after ``defusedxml`` found it well-formed with no DTD or entity
    declaration (:class:`ModelError` otherwise, naming the file)."""
    if path.is_dir():
        raise ModelError(f"MJCF file {str(path)!r} is a folder; name the .xml file in it")
    if not path.is_file():
        raise ModelError(f"MJCF file {str(path)!r} does not exist")
    text = _utf8(path)
    try:
        root = SafeET.fromstring(text, forbid_dtd=True)
    except DefusedXmlException as exc:
        raise ModelError(f"{path.name}: refusing XML with a DTD or entity declarations "
                         f"({type(exc).__name__}); an MJCF needs neither") from exc
    except SafeET.ParseError as exc:
        raise ModelError(f"{path.name} is not well-formed XML: {exc}") from exc
    if root.tag != "mujoco":
        raise ModelError(f"{path.name}: the root element is <{root.tag}>, not <mujoco>: not an "
                         "MJCF (a URDF? RobotModel.from_urdf)")
    _check_numbers(root, path.name)
    return text


#: MJCF attributes that hold names or paths, never numbers (``joint="inf"`` names a joint).
NAMING = frozenset({"name", "class", "childclass", "file", "model", "mesh", "material",
                    "texture", "hfield", "joint", "joint1", "joint2", "body", "body1", "body2",
                    "site", "tendon", "geom", "geom1", "geom2", "target", "objname", "refname",
                    "prefix", "content_type", "meshdir", "texturedir", "assetdir", "actuator",
                    "key", "skin", "flex", "camera", "light", "plugin", "instance"})


def _check_numbers(root: Any, source: str) -> None:
    """:class:`ModelError` for a NaN or infinity written in a numeric attribute: MuJoCo's
    compiler replaces it by 0 and only prints a warning, so the model would load with a
    number the file does not hold."""
    for element in root.iter():
        for key, value in element.attrib.items():
            if key in NAMING:
                continue
            for token in value.split():
                try:
                    bad = not np.isfinite(float(token))
                except ValueError:
                    continue
                if bad:
                    raise ModelError(f"{source}: <{element.tag} {key}=\"{value[:60]}\"> holds "
                                     f"{token!r}; MuJoCo would compile it as 0: write the "
                                     "number meant")


def _utf8(path: Path) -> str:
    """The file's text; :class:`ModelError` for bytes that are not UTF-8 (MuJoCo's XML parser
    reads UTF-8 only)."""
    try:
        return path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelError(f"{path.name}: byte {exc.object[exc.start:exc.start + 1]!r} at offset "
                         f"{exc.start} is not UTF-8; MuJoCo reads UTF-8 XML only: convert the "
                         "file (e.g. iconv -f latin1 -t utf-8) and drop its encoding=\"…\"") \
            from None


def is_mjcf(path: str | Path) -> bool:
    """The file's first element is ``<mujoco>`` (comments and the XML declaration skipped)."""
    try:
        raw = Path(path).read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        return False
    text = re.sub(r"<!--.*?-->|<\?.*?\?>", "", raw, flags=re.S)
    found = re.search(r"<([A-Za-z_][\w.-]*)", text)
    return bool(found and found.group(1) == "mujoco")


def compile_mjcf(path: Path) -> Any:
    """``mujoco.MjModel`` of the file, MuJoCo's compiler error as :class:`ModelError`."""
    import mujoco  # heavy

    check_safe_xml(path)
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not compile {path.name}: {exc}") from exc


def _name(mj: Any, kind: Any, index: int) -> str:
    import mujoco

    return mujoco.mj_id2name(mj, kind, index) or ""


def body_label(mj: Any, body: int) -> str:
    """A MuJoCo body's name, or ``"body<id>"`` for an unnamed one."""
    import mujoco

    return _name(mj, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"


def _quat_matrix(quat: np.ndarray) -> np.ndarray:
    w, x, y, z = (float(v) for v in quat)
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def body_placement(mj: Any, body: int) -> pin.SE3:
    """Body frame in its parent's body frame (compiled ``body_quat``, ``body_pos``)."""
    return pin.SE3(_quat_matrix(mj.body_quat[body]), np.array(mj.body_pos[body], dtype=float))


def body_inertia(mj: Any, body: int) -> pin.Inertia:
    """The compiled inertial of a MuJoCo body in its body frame (``ipos``, ``iquat``, principal
    moments ``body_inertia``): ``I_c = R diag(d) Rᵀ``."""
    rot = _quat_matrix(mj.body_iquat[body])
    ic = rot @ np.diag(np.asarray(mj.body_inertia[body], dtype=float)) @ rot.T
    return pin.Inertia(float(mj.body_mass[body]), np.array(mj.body_ipos[body], dtype=float),
                       0.5 * (ic + ic.T))


def _joint_model(kind: int, axis: np.ndarray) -> Any:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    unit = [k for k in range(3) if abs(abs(axis[k]) - 1.0) < 1e-15 and axis[k] > 0]
    if kind == HINGE:
        aligned = (pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ)
        return aligned[unit[0]]() if unit else pin.JointModelRevoluteUnaligned(axis)
    aligned = (pin.JointModelPX, pin.JointModelPY, pin.JointModelPZ)
    return aligned[unit[0]]() if unit else pin.JointModelPrismaticUnaligned(axis)


def _ref_shift(mj: Any, j: int) -> pin.SE3:
    """``exp(−ref·S)``: MuJoCo places a body at the joint's ``ref`` (``qpos0``), so the body
    frame moves by ``q − ref``: ``exp(−ref·S)·exp(q·S) = exp((q − ref)·S)`` (one axis)."""
    axis = np.asarray(mj.jnt_axis[j], dtype=float)
    ref = float(mj.qpos0[mj.jnt_qposadr[j]]) * axis / np.linalg.norm(axis)
    motion = (pin.Motion(np.zeros(3), ref) if mj.jnt_type[j] == HINGE
              else pin.Motion(ref, np.zeros(3)))
    return pin.exp6(motion).inverse()


def effort_limits(mj: Any) -> np.ndarray:
    """Per MuJoCo joint: ``actfrcrange`` when limited, else the largest force the actuators on
    it can apply (``forcerange``, or ``|gear · gain| · max|ctrlrange|`` of a fixed-gain motor);
    ``inf`` when nothing bounds it."""
    out = np.full(mj.njnt, np.inf)
    for a in range(mj.nu):
        if mj.actuator_trntype[a] not in (0, 1):            # mjTRN_JOINT, mjTRN_JOINTINPARENT
            continue
        j = int(mj.actuator_trnid[a, 0])
        gear = abs(float(mj.actuator_gear[a, 0]))
        if mj.actuator_forcelimited[a]:
            bound = np.max(np.abs(mj.actuator_forcerange[a])) * gear
        elif mj.actuator_ctrllimited[a] and mj.actuator_gaintype[a] == 0 \
                and mj.actuator_biastype[a] == 0:
            bound = np.max(np.abs(mj.actuator_ctrlrange[a])) * gear * abs(mj.actuator_gainprm[a, 0])
        else:
            continue
        out[j] = bound if not np.isfinite(out[j]) else max(out[j], bound)
    for j in range(mj.njnt):
        if mj.jnt_actfrclimited[j]:
            out[j] = float(np.max(np.abs(mj.jnt_actfrcrange[j])))
    return out


#: Compiled MuJoCo arrays a consistid model is built from (a NaN in the XML compiles, with a
#: warning printed, into them).
COMPILED = ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass", "body_inertia",
            "jnt_pos", "jnt_axis", "jnt_range", "qpos0", "dof_armature", "dof_damping",
            "dof_frictionloss")


def _check_finite(mj: Any, source: str) -> None:
    """:class:`ModelError` naming the array and body/joint of a non-finite compiled number."""
    for name in COMPILED:
        a = np.asarray(getattr(mj, name), dtype=float)
        if a.size == 0:
            continue
        bad = np.argwhere(~np.isfinite(a.reshape(a.shape[0], -1)))
        if bad.size:
            k = int(bad[0][0])
            who = (f"body {body_label(mj, k)!r}" if name.startswith("body")
                   else f"{name.split('_')[0]} {k}")
            raise ModelError(f"{source}: {who} compiles to a non-finite {name} "
                             f"({a.reshape(a.shape[0], -1)[k].tolist()}); fix the NaN or inf "
                             "in the XML")


def _check_joints(mj: Any, source: str) -> None:
    """Refuse what consistid cannot model, naming the joint and body."""
    import mujoco

    _check_finite(mj, source)
    for b in range(mj.nbody):
        check_writable_name(body_label(mj, b), f"{source}: body")
    for j in range(mj.njnt):
        body = body_label(mj, int(mj.jnt_bodyid[j]))
        name = _name(mj, mujoco.mjtObj.mjOBJ_JOINT, j)
        if name:
            check_writable_name(name, f"{source}: joint")
        kind = int(mj.jnt_type[j])
        if kind == FREE:
            raise ModelError(f"{source}: body {body!r} has a free joint {name or '(unnamed)'!r}: "
                             "a floating base, which consistid (fixed-base arms) does not model; "
                             "remove the <freejoint> to weld the robot's base to the world")
        if kind == BALL:
            raise ModelError(f"{source}: joint {name or '(unnamed)'!r} of body {body!r} is a ball "
                             "joint; consistid models hinge and slide joints only")
        if not name:
            raise ModelError(f"{source}: the {('slide', 'hinge')[kind == HINGE]} joint of body "
                             f"{body!r} has no name; give it name=\"…\" (results name joints)")
    per_body = np.bincount(np.asarray(mj.jnt_bodyid, dtype=int), minlength=mj.nbody)
    several = [body_label(mj, b) for b in np.flatnonzero(per_body > 1)]
    if several:
        raise ModelError(f"{source}: bod{'ies' if len(several) > 1 else 'y'} {several} "
                         "carry more than one joint; consistid needs one joint per body (split "
                         "the body into a chain of bodies with one joint each)")


def pinocchio_from_mujoco(mj: Any, source: str) -> tuple[pin.Model, dict[str, str]]:
    """The Pinocchio model of a compiled MuJoCo model (module docstring) and, per MuJoCo body
    merged into a moving body, the joint that carries it. Every MuJoCo body gets a Pinocchio
    ``BODY`` frame of its name."""
    import mujoco

    _check_joints(mj, source)
    model = pin.Model()
    model.name = source
    effort = effort_limits(mj)
    frame_of = {0: (0, pin.SE3.Identity())}   # MuJoCo body → (pin joint, body frame in it)
    carriers: dict[str, str] = {}
    for b in range(1, mj.nbody):
        parent_joint, parent_frame = frame_of[int(mj.body_parentid[b])]
        frame = parent_frame * body_placement(mj, b)
        name = body_label(mj, b)
        if mj.body_jntnum[b] == 1:
            j = int(mj.body_jntadr[b])
            anchor = pin.SE3(np.eye(3), np.array(mj.jnt_pos[j], dtype=float))
            placement = frame * anchor * _ref_shift(mj, j)
            jname = _name(mj, mujoco.mjtObj.mjOBJ_JOINT, j)
            lower, upper = ((float(mj.jnt_range[j, 0]), float(mj.jnt_range[j, 1]))
                            if mj.jnt_limited[j] else (-np.inf, np.inf))
            jid = model.addJoint(parent_joint, _joint_model(int(mj.jnt_type[j]), mj.jnt_axis[j]),
                                 placement, jname, np.array([effort[j]]), np.array([np.inf]),
                                 np.array([lower]), np.array([upper]))
            dof = int(mj.jnt_dofadr[j])
            model.armature[jid - 1] = float(mj.dof_armature[dof])
            model.damping[jid - 1] = float(mj.dof_damping[dof])
            model.friction[jid - 1] = float(mj.dof_frictionloss[dof])
            frame_of[b] = (jid, anchor.inverse())
            model.addJointFrame(jid)
        else:
            frame_of[b] = (parent_joint, frame)
        jid, in_joint = frame_of[b]
        if jid > 0:
            model.appendBodyToJoint(jid, body_inertia(mj, b), in_joint)
            carriers[name] = model.names[jid]
        model.addFrame(pin.Frame(name, jid, 0, in_joint, pin.FrameType.BODY))
    model.gravity = pin.Motion(np.array(mj.opt.gravity, dtype=float), np.zeros(3))
    return model, carriers


def read_mjcf(path: str | Path, locked_joints: Iterable[str] = (),
              locked_configuration: dict[str, float] | None = None
              ) -> tuple[pin.Model, list[str], dict[str, float]]:
    """The (reduced) Pinocchio model of the MJCF at ``path`` with ``locked_joints`` merged into
    their parents at ``locked_configuration`` (default each joint's ``qpos0``), the locked
    joints and their configuration."""
    path = Path(path)
    if isinstance(locked_joints, (str, bytes)):
        raise ModelError(f"locked_joints must be a list of joint names, got {locked_joints!r} "
                         f"(write [{locked_joints!r}])")
    mj = compile_mjcf(path)
    full, _ = pinocchio_from_mujoco(mj, path.name)
    locked, config = list(locked_joints), dict(locked_configuration or {})
    unknown = [j for j in [*locked, *config] if not isinstance(j, str)
               or not full.existJointName(j)]
    if unknown:
        raise ModelError(f"unknown joint(s) {unknown} in {path.name}; joints are "
                         f"{list(full.names)[1:]}")
    unlocked = sorted(set(config) - set(locked))
    if unlocked:
        raise ModelError(f"locked_configuration names joint(s) {unlocked} that are not in "
                         f"locked_joints {locked}")
    if not locked:
        return full, [], {}
    q_ref = np.array(mj.qpos0, dtype=float)       # one coordinate per hinge/slide, file order
    for name in locked:
        jid = full.getJointId(name)
        q_ref[full.joints[jid].idx_q] = config.setdefault(name, float(q_ref[full.joints[jid]
                                                                             .idx_q]))
    reduced = pin.buildReducedModel(full, [full.getJointId(j) for j in locked], q_ref)
    return reduced, locked, config

