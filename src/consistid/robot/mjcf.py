r"""Write a robot with identified parameters as MJCF, built through MuJoCo's own ``MjSpec``.

The model is made element by element with the ``mujoco.MjSpec`` API (MuJoCo ≥ 3.2, "Model
Editing"), compiled by MuJoCo (which checks every inertia), and written with ``MjSpec.to_xml``:

* one body per joint, placed by Pinocchio's ``jointPlacements`` (the body frame is the joint
  frame), with a ``hinge``/``slide`` joint along the axis of the joint's motion subspace;
* the body's inertial from the standard 10-vector: ``mass = m``, ``ipos = c = h/m`` and the full
  inertia **about the CoM** ``I_c = I_O − m [c]ₓᵀ[c]ₓ`` in the body frame (``fullinertia``);
* per joint: viscous friction ``fv`` → ``damping``, Coulomb friction ``fc`` → ``frictionloss``
  (MuJoCo's dry friction, a soft constraint), armature ``Ia`` → ``armature`` (the joint's whole
  rotor inertia: the regressor has no other; without ``Ia`` the model's own ``armature``, which
  ``pinocchio.rnea`` includes); torque offsets and
  once-per-revolution terms have no MJCF element and raise an :class:`ExportWarning`;
* position limits as joint ``range``, effort limits as the range of a ``motor`` actuator per
  joint (gear 1, so ``ctrl`` is the joint torque);
* gravity as the model's (MJCF carries it, unlike URDF).

There is no geometry (collision or visual): the file is for dynamics. With no friction and no
armature, ``mj_inverse`` of the written model equals ``pinocchio.rnea`` with the identified
parameters (tested), and ``pinocchio.buildModelFromMJCF`` reads back the damping, friction loss
and armature.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import pinocchio as pin

from ..errors import ExportWarning, ModelError
from ..filesafety import replacing
from .export import check_not_source
from .inertia import body_slice, writable_bodies
from .joint_terms import MJCF_ATTRIBUTES, check_nonnegative, export_parameters

if TYPE_CHECKING:
    from .model import RobotModel

#: Per-joint parameter suffixes MJCF has an element for, and the joint attribute they set.


def joint_axes(model: "RobotModel") -> tuple[list[str], np.ndarray]:
    """Joint kind (``"hinge"``/``"slide"``) and unit axis in the joint frame, per joint.

    Read from the joint's motion subspace (the joint's column of the ``LOCAL`` Jacobian at the
    neutral configuration): ``[0; a]`` for a revolute joint, ``[a; 0]`` for a prismatic one.
    """
    pm = model.pin_model
    data = pm.createData()
    pin.computeJointJacobians(pm, data, pin.neutral(pm))
    kinds, axes = [], np.zeros((model.nv, 3))
    for j in range(1, pm.njoints):
        s = pin.getJointJacobian(pm, data, j, pin.LOCAL)[:, pm.joints[j].idx_v]
        lin, ang = s[:3], s[3:]
        if np.linalg.norm(lin) < 1e-12 and abs(np.linalg.norm(ang) - 1) < 1e-9:
            kinds.append("hinge")
            axes[j - 1] = ang
        elif np.linalg.norm(ang) < 1e-12 and abs(np.linalg.norm(lin) - 1) < 1e-9:
            kinds.append("slide")
            axes[j - 1] = lin
        else:
            raise ModelError(f"joint {pm.names[j]!r} ({pm.joints[j].shortname()}) is neither a "
                             "revolute nor a prismatic joint about a fixed axis")
    return kinds, axes


def mjcf_spec(model: "RobotModel", parameters: np.ndarray | None = None,
              parameter_names: Sequence[str] | None = None) -> Any:
    """The ``mujoco.MjSpec`` of ``model`` carrying ``parameters`` (module docstring).

    Parameters
    ----------
    parameters : (10·nbodies [+ k],) standard parameters, then optionally per-joint terms named
        by ``parameter_names``; default the model's inertias.

    Raises
    ------
    InconsistentParametersError : a body is not physically consistent, or a friction
        coefficient or armature is negative (names it).
    """
    import mujoco  # heavy: loaded with the first export

    params, terms = export_parameters(model, parameters, parameter_names)
    writable_bodies(params, model.body_names)
    dropped = []
    check_nonnegative(terms, MJCF_ATTRIBUTES, "an MJCF joint")
    for joint, values in terms.items():
        dropped += [f"{joint}.{t}={v:.4g}" for t, v in values.items()
                    if t not in MJCF_ATTRIBUTES and v]
    if dropped:
        warnings.warn(f"MJCF has no element for torque offsets or position terms; not written: "
                      f"{', '.join(dropped)}", ExportWarning, stacklevel=3)

    pm = model.pin_model
    kinds, axes = joint_axes(model)
    limits = model.limits
    spec = mujoco.MjSpec()
    spec.modelname = model.name
    spec.compiler.degree = False
    spec.option.gravity = np.asarray(model.gravity, dtype=float)
    bodies: dict[int, Any] = {0: spec.worldbody}
    for j in range(1, pm.njoints):
        i = j - 1
        placement = pm.jointPlacements[j]
        quat = pin.Quaternion(placement.rotation)
        body = bodies[pm.parents[j]].add_body(
            name=model.body_names[i], pos=np.array(placement.translation),
            quat=np.array([quat.w, quat.x, quat.y, quat.z]))
        inertia = pin.Inertia.FromDynamicParameters(params[body_slice(i)])
        ic = np.asarray(inertia.inertia)
        body.explicitinertial = True
        body.mass = float(inertia.mass)
        body.ipos = np.array(inertia.lever)
        body.fullinertia = np.array([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2],
                                     ic[1, 2]])
        values = terms.get(model.joint_names[i], {})
        joint = body.add_joint(
            name=model.joint_names[i],
            type=(mujoco.mjtJoint.mjJNT_HINGE if kinds[i] == "hinge"
                  else mujoco.mjtJoint.mjJNT_SLIDE),
            axis=axes[i], damping=values.get("fv", 0.0),
            frictionloss=values.get("fc", 0.0),
            armature=values.get("Ia", float(pm.armature[i])))
        if np.isfinite(limits.lower[i]) and np.isfinite(limits.upper[i]):
            joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.range = np.array([limits.lower[i], limits.upper[i]])
        bodies[j] = body
    for i, name in enumerate(model.joint_names):
        act = spec.add_actuator(name=f"{name}_motor", target=name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.gear[0] = 1.0
        if np.isfinite(limits.effort[i]):
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = np.array([-limits.effort[i], limits.effort[i]])
    return spec


def write_mjcf(model: "RobotModel", path: str | Path, parameters: np.ndarray | None = None,
               parameter_names: Sequence[str] | None = None) -> Path:
    """Write the MJCF of :func:`mjcf_spec` to ``path`` after MuJoCo compiled it (a compiler
    error raises :class:`ModelError` with MuJoCo's message). Returns the path."""
    out = check_not_source(model, path, "to_mjcf")
    spec = mjcf_spec(model, parameters, parameter_names)
    try:
        spec.compile()
    except ValueError as exc:
        raise ModelError(f"MuJoCo could not compile the MJCF of {model.name!r}: {exc}") from exc
    with replacing(out) as tmp:                 # never a half-written MJCF
        tmp.write_text(_exact_numbers(spec, spec.to_xml()), encoding="utf-8")
    return out


def _num(values: Any) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(values))


def _exact_numbers(spec: Any, xml: str) -> str:
    """``xml`` (MuJoCo's writer, 6 significant digits in MuJoCo 4.0, inertias in principal
    axes) with every number of the spec written back with 17: body placements, the inertial as
    ``fullinertia`` about the CoM, joint axes and ranges, actuator ranges, gravity. The file
    then reloads to the same model bit for bit instead of to ~1e-6."""
    root = ET.fromstring(xml)
    # by name, not by an XPath ".//body[@name='…']", which a quote in a name would break
    elements = {el.get("name"): el for el in root.iter("body")}
    joints = {el.get("name"): el for el in root.iter("joint")}
    section = root.find("actuator")
    actuators = {} if section is None else {el.get("name"): el for el in section}
    for body in spec.bodies[1:]:                           # [0] is the world
        el = elements[body.name]
        el.set("pos", _num(body.pos))
        el.set("quat", _num(body.quat))
        inertial = el.find("inertial")
        for key in list(inertial.attrib):
            del inertial.attrib[key]
        inertial.set("pos", _num(body.ipos))
        inertial.set("mass", _num(body.mass))
        inertial.set("fullinertia", _num(body.fullinertia))
    for joint in spec.joints:
        el = joints[joint.name]
        el.set("axis", _num(joint.axis))
        if joint.limited == 1:                            # mjLIMITED_TRUE
            el.set("range", _num(joint.range))
        for attr in MJCF_ATTRIBUTES.values():
            value = np.ravel(getattr(joint, attr))         # frictionloss etc. may be arrays
            if np.any(value):
                el.set(attr, _num(value[:1]))
    for act in spec.actuators:
        el = actuators[act.name]
        if act.ctrllimited == 1:
            el.set("ctrlrange", _num(act.ctrlrange))
    option = root.find("option")
    if option is None:
        option = ET.Element("option")
        root.insert(1, option)
    option.set("gravity", _num(spec.option.gravity))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
