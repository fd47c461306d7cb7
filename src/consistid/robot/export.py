r"""Write identified parameters back into a URDF.

The source URDF is copied with each moving body's ``<inertial>`` replaced by the identified mass,
centre of mass and inertia, and (when friction entries are given) each joint's
``<dynamics damping="f_v" friction="f_c"/>`` (the convention read by
:mod:`consistid.robot.urdf` and by Pinocchio, Gazebo, FloBaRoID), on the ``<joint>`` children of
``<robot>`` only: a ROS ``<transmission>``, ``<ros2_control>`` or ``<gazebo>`` block names joints
in ``<joint>`` elements of its own, which are left as they are
(:func:`consistid.robot.urdf.robot_joints`). A URDF ``<inertial>`` holds the mass, the CoM as
``<origin xyz>`` in the link frame, and the inertia **about the CoM**; consistid's 10-vector has
the inertia about the joint frame origin, so

.. math::  c = h / m, \qquad I_c = I_O - m\,[c]_\times^\top [c]_\times

(parallel axes), written with ``rpy="0 0 0"`` so the tensor's axes are the link's.

Merged bodies
-------------
A consistid body is the joint's child link **plus** every link attached below it through fixed
joints (Pinocchio merges them when parsing) and through locked joints (e.g. the Panda's fingers,
merged by ``buildReducedModel``). Only their sum is identified; how to split it is a choice
(``merged``):

``"auto"`` (default)
    links below **fixed** joints are lumped into the joint's child link (their ``<inertial>`` is
    removed: nothing can move them apart, and Pinocchio and MuJoCo fuse them anyway); links below
    **locked** joints keep their source inertial (they are movable in the URDF, and a simulator
    needs their mass there) and are subtracted from the identified total — unless that leaves
    the child link inconsistent (the identified body lighter or thinner than the URDF's locked
    links along some axis): then they are lumped too, with an :class:`ExportWarning`.
``"lump"``
    every merged link is lumped into the child link (locked children become massless).
``"subtract"``
    every merged link keeps its source inertial; the child link gets the identified total minus
    them.

The written child link must itself be physically consistent (``check_body``, pseudo-inertia
level); if a subtraction with ``merged="subtract"`` leaves it inconsistent,
:class:`InconsistentParametersError` names the link and suggests ``merged="lump"``. Loading the
written file with the same locked joints gives back the identified parameters (to rounding, 17
significant digits are written).
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np
import pinocchio as pin

from ..errors import ExportWarning, InconsistentParametersError, ModelError, check_option
from ..filesafety import check_destination, replacing
from .inertia import InertialParameters, writable_bodies
from .joint_terms import URDF_ATTRIBUTES, check_nonnegative, export_parameters
from .urdf import parse_urdf, remove_dynamics, robot_joints, robot_links

if TYPE_CHECKING:
    from .model import RobotModel

MERGED = ("auto", "lump", "subtract")
#: Per-joint parameter name suffixes (``"<joint>.<suffix>"``); only fc and fv have URDF tags.


@dataclass(frozen=True)
class _Link:
    """A URDF link with mass, its owner body and its placement in the owner's joint frame."""

    name: str
    owner: int            # index of the consistid body
    placement: pin.SE3    # link frame in the owner's joint frame
    via: str              # "child" (the joint's child link), "fixed" or "locked"


def _fmt(x: float) -> str:
    return repr(float(x))


def _read_inertial(link: ET.Element, source: str) -> pin.Inertia | None:
    """The link's ``<inertial>`` as a ``pinocchio.Inertia`` in the link frame (None if absent or
    massless)."""
    tag = link.find("inertial")
    if tag is None:
        return None
    try:
        mass = float(tag.find("mass").get("value"))
        origin = tag.find("origin")
        xyz = np.array([float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None
                                            else "0 0 0").split()])
        rpy = np.array([float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None
                                            else "0 0 0").split()])
        it = tag.find("inertia")
        v = {k: float(it.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    except (AttributeError, TypeError, ValueError) as exc:
        raise ModelError(f"{source}: link {link.get('name')!r} has a malformed <inertial>") from exc
    if mass == 0.0:
        return None
    inertia = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                        [v["ixz"], v["iyz"], v["izz"]]])
    rot = pin.rpy.rpyToMatrix(*rpy)
    return pin.Inertia(mass, xyz, rot @ inertia @ rot.T)


def _kinematic_model(root: ET.Element) -> pin.Model:
    """The full Pinocchio model of the URDF tree, ``<dynamics>`` stripped (Pinocchio refuses
    negative values there, and only the kinematics are needed)."""
    copy = remove_dynamics(ET.fromstring(ET.tostring(root)))
    return pin.buildModelFromXML(ET.tostring(copy, encoding="unicode"))


def _links(model: RobotModel, full: pin.Model, root: ET.Element) -> list[_Link]:
    """Every URDF link that moves with a consistid body, with its owner and placement."""
    locked = set(model.locked_joints)
    q = pin.neutral(full)
    for name, value in model.locked_configuration.items():
        q[full.joints[full.getJointId(name)].idx_q] = value
    data = full.createData()
    pin.forwardKinematics(full, data, q)
    pin.updateFramePlacements(full, data)
    child_of = {j.find("child").get("link"): j.get("name") for j in robot_joints(root)
                if j.find("child") is not None}
    out = []
    for fid, frame in enumerate(full.frames):
        if frame.type != pin.FrameType.BODY:
            continue
        joint, via = frame.parentJoint, "fixed"
        while joint != 0 and full.names[joint] in locked:
            joint, via = full.parents[joint], "locked"
        if joint == 0:
            continue
        name = full.names[joint]
        if name not in model.joint_names:
            raise ModelError(f"joint {name!r} of {model.source} is not in the model "
                             f"{model.name!r}; was it built from this URDF?")
        if child_of.get(frame.name) == name:
            via = "child"
        placement = data.oMi[joint].actInv(data.oMf[fid])
        out.append(_Link(frame.name, model.joint_names.index(name), placement, via))
    return out


def _set_inertial(link: ET.Element, inertia: pin.Inertia | None) -> None:
    for tag in link.findall("inertial"):
        link.remove(tag)
    if inertia is None:
        return
    m, c = inertia.mass, inertia.lever
    i = inertia.inertia
    indent = link.text if link.text and not link.text.strip() else "\n  "
    tag = ET.Element("inertial")
    tag.text, tag.tail = indent + "  ", indent
    ET.SubElement(tag, "origin", xyz=" ".join(_fmt(v) for v in c), rpy="0 0 0")
    ET.SubElement(tag, "mass", value=_fmt(m))
    ET.SubElement(tag, "inertia", ixx=_fmt(i[0, 0]), ixy=_fmt(i[0, 1]), ixz=_fmt(i[0, 2]),
                  iyy=_fmt(i[1, 1]), iyz=_fmt(i[1, 2]), izz=_fmt(i[2, 2]))
    for child in tag:
        child.tail = indent + "  "
    tag[-1].tail = indent
    link.text = indent
    link.insert(0, tag)


def check_not_source(model: "RobotModel", path: str | Path, what: str) -> Path:
    """``path`` as a :class:`~pathlib.Path`, unless it names the URDF ``model`` was read from
    (:class:`ModelError`: a writer never replaces its input) or a file cannot be written there
    (:func:`consistid.filesafety.check_destination`)."""
    check_destination(path)
    out = Path(path)
    source = None if model.source is None else Path(model.source)
    if source is not None and source.exists() and out.exists() \
            and out.resolve().samefile(source.resolve()):
        raise ModelError(f"{what}({str(path)!r}) would write over the "
                         f"{(model.source_format or 'urdf').upper()} {model.name!r} was read "
                         "from (its source); write to another path")
    return out


def write_urdf(model: RobotModel, path: str | Path, parameters: np.ndarray | None = None,
               parameter_names: Sequence[str] | None = None, merged: str = "auto") -> Path:
    """Write ``model.source`` with the given parameters as ``<inertial>`` / ``<dynamics>`` tags.

    Parameters
    ----------
    model : a model read from a URDF (``model.source``); its locked joints define the merging.
    path : the output file.
    parameters : (10·nbodies [+ k],) standard parameters, then optionally friction/armature
        entries named by ``parameter_names`` (``"<joint>.fc"`` → ``friction``, ``".fv"`` →
        ``damping``; ``".fo"`` offsets, ``".ps1"``/``".pc1"`` position terms and ``".Ia"``
        armatures have no URDF tag and are reported by an :class:`ExportWarning`). Default: the
        model's current inertias.
    parameter_names : names of ``parameters`` (needed with friction entries).
    merged : how a body's merged links share its parameters (module docstring).

    Returns
    -------
    pathlib.Path of the written file.

    Raises
    ------
    InconsistentParametersError
        a body (or the part of it written on its child link) is not physically consistent, or a
        Coulomb/viscous coefficient is negative; names the body/link/joint.
    ModelError
        the model has no source URDF, or does not match it, or ``path`` is that source.
    """
    check_option("merged", merged, MERGED)
    check_not_source(model, path, "to_urdf")
    if model.source is None or not Path(model.source).is_file():
        raise ModelError(f"{model.name!r} has no source URDF to write parameters into")
    if model.source_format == "mjcf":
        raise ModelError(f"{model.name!r} was read from the MJCF {Path(model.source).name}, not a "
                         "URDF: write into it with to_mjcf(path, source=model.source)")
    source = Path(model.source)
    params, terms = export_parameters(model, parameters, parameter_names)
    tree = parse_urdf(source)
    root = tree.getroot()
    links = _links(model, _kinematic_model(root), root)
    elements = {link.get("name"): link for link in robot_links(root)}

    for body, (name, inertial) in enumerate(zip(model.body_names,
                                                 writable_bodies(params, model.body_names))):
        mine = [ln for ln in links if ln.owner == body]
        child = [ln for ln in mine if ln.via == "child"]
        if len(child) != 1:
            raise ModelError(f"body {name!r}: cannot find the child link of joint "
                             f"{model.joint_names[body]!r} in {source.name}")
        keep = [ln for ln in mine if ln.via != "child"
                and (merged == "subtract" or (merged == "auto" and ln.via == "locked"))]
        lump = [ln for ln in mine if ln.via != "child" and ln not in keep]
        rest = inertial
        for ln in keep:
            own = _read_inertial(elements[ln.name], source.name)
            if own is not None:
                rest = rest - InertialParameters.from_pinocchio(ln.placement.act(own))
        verdict = rest.consistent(name=child[0].name)
        if not verdict.ok and merged == "auto":
            # The identified body cannot hold the URDF's locked links as they are: lump them
            # (the body stays whole and consistent), and say so.
            warnings.warn(f"body {name!r}: subtracting the source inertials of "
                          f"{[ln.name for ln in keep]} would leave link {child[0].name!r} "
                          f"inconsistent ({verdict.reason}); merged='auto' lumped them into "
                          f"it instead (merged='subtract' refuses)", ExportWarning,
                          stacklevel=2)
            lump, keep, rest = lump + keep, [], inertial
        elif not verdict.ok:
            raise InconsistentParametersError(
                f"body {name!r}: after subtracting the source inertials of "
                f"{[ln.name for ln in keep]}, link {child[0].name!r} would be inconsistent "
                f"({verdict.reason}); use merged='lump'")
        written = child[0].placement.actInv(rest.to_pinocchio())
        _set_inertial(elements[child[0].name], written)
        for ln in lump:
            if _read_inertial(elements[ln.name], source.name) is not None:
                _set_inertial(elements[ln.name], None)

    dropped = []
    joints = {j.get("name"): j for j in robot_joints(root)}
    check_nonnegative(terms, URDF_ATTRIBUTES, "a URDF <dynamics>")
    for joint, values in terms.items():
        dropped += [f"{joint}.{t}={v:.4g}" for t, v in values.items()
                    if t not in ("fc", "fv") and v]
        if "fc" in values or "fv" in values:
            tag = joints[joint].find("dynamics")
            if tag is None:
                tag = ET.SubElement(joints[joint], "dynamics")
            if "fv" in values:
                tag.set("damping", _fmt(values["fv"]))
            if "fc" in values:
                tag.set("friction", _fmt(values["fc"]))
    if dropped:
        warnings.warn(f"URDF has no tag for torque offsets, position terms or armature; not "
                      f"written: "
                      f"{', '.join(dropped)}", ExportWarning, stacklevel=2)
    if not model.has_default_gravity:
        warnings.warn(f"URDF has no tag for gravity: the model's, "
                      f"({', '.join(f'{v:+.4f}' for v in model.gravity)}) m/s² in the base "
                      "frame, is not the level (0, 0, −9.81) a simulator assumes; give it "
                      "beside the file", ExportWarning, stacklevel=2)

    out = Path(path)
    if out.resolve().parent != source.resolve().parent:
        _absolute_mesh_paths(root, source.resolve().parent)
    with replacing(out) as tmp:                 # never a half-written URDF
        tree.write(tmp, encoding="utf-8", xml_declaration=True)
    return out


def _absolute_mesh_paths(root: ET.Element, folder: Path) -> None:
    """Relative mesh file names point into the source folder (``package://`` URIs stay)."""
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name and "://" not in name and not Path(name).is_absolute():
            mesh.set("filename", str((folder / name).resolve()))
