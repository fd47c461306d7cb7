r"""URDF joint ``<dynamics>`` tags: read them as friction, or strip them before loading.

A URDF joint may carry ``<dynamics damping="…" friction="…"/>``. consistid reads them as the
per-joint friction of its default model (see :mod:`consistid.regressor`):

.. math::  \tau_{f,j} = f_{c,j}\,\operatorname{sign}(\dot q_j) + f_{v,j}\,\dot q_j

with ``f_v = damping`` (N·m·s/rad) and ``f_c = friction`` (N·m), the convention of ROS/Gazebo and
of FloBaRoID's URDF export (Bethge et al., FloBaRoID, github.com/kjyv/FloBaRoID). Identification
tools may write *negative* values there (FloBaRoID's KUKA LWR4+ model does), which Pinocchio's
URDF parser refuses; :func:`model_without_dynamics` loads such a file by stripping the tags into
a temporary copy first, and returns the tags alongside so nothing is lost.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import defusedxml.ElementTree as safe_et
import numpy as np
from defusedxml import DefusedXmlException

from ..errors import ModelError
from ..textsafety import check_writable_name


@dataclass(frozen=True)
class JointDynamics:
    """One joint's ``<dynamics>`` tag: ``damping`` = viscous ``f_v``, ``friction`` = Coulomb
    ``f_c`` (0 where the attribute is absent)."""

    joint: str
    damping: float
    friction: float


def parse_urdf(path: Path) -> ET.ElementTree:
    """The URDF's XML tree; :class:`ModelError` for a missing file, malformed XML or XML that
    declares entities (parsed with ``defusedxml``: an entity could expand to gigabytes, read a
    local file, or slip a name past Pinocchio's parser, which leaves ``&n;`` unexpanded). A
    default namespace (``<robot xmlns="…">``) is removed from the tags, as URDF readers ignore
    it."""
    if path.is_dir():
        raise ModelError(f"URDF file {str(path)!r} is a folder, not a file")
    if not path.is_file():
        raise ModelError(f"URDF file {str(path)!r} does not exist")
    try:
        tree = safe_et.parse(path)
    except ET.ParseError as exc:
        raise ModelError(f"{path.name} is not well-formed XML: {exc}") from exc
    except DefusedXmlException as exc:
        raise ModelError(f"{path.name} declares XML entities or external references ({exc}); "
                         "consistid refuses them: expand them first (e.g. with xacro) and "
                         "give the plain URDF") from exc
    for element in tree.getroot().iter():
        if isinstance(element.tag, str) and element.tag.startswith("{"):
            element.tag = element.tag.split("}", 1)[1]
    return tree


def robot_joints(root: ET.Element) -> list[ET.Element]:
    """The URDF's ``<joint>`` elements: the children of ``<robot>`` only.

    Other elements reuse the tag name: a ROS ``<transmission>`` names its joint in
    ``<joint name="…"><hardwareInterface>…``, ``<ros2_control>`` in ``<joint name="…">
    <command_interface …>``. Those are not joints; ``root.iter("joint")`` would find them too
    (and a later one would shadow the real joint of the same name).
    """
    return root.findall("joint")


def robot_links(root: ET.Element) -> list[ET.Element]:
    """The URDF's ``<link>`` elements (children of ``<robot>``; see :func:`robot_joints`)."""
    return root.findall("link")


def check_urdf(path: str | Path, locked_joints: Sequence[str] = ()) -> None:
    """Refuse (:class:`ModelError`, naming the link or joint) what Pinocchio's URDF parser
    accepts but consistid cannot model: an ``<inertial>`` mass that is negative or not a finite
    number (Pinocchio prints an error and goes on), an inertia entry that is not a finite
    number, a moving joint whose ``<axis>`` is zero or not finite, and ``<mimic>`` joints
    (one joint driven by another: the regressor would treat them as independent) unless they
    are among ``locked_joints`` (e.g. the Panda's second finger) or fixed (Talos's grippers)."""
    locked = set(locked_joints)
    path = Path(path)
    root = parse_urdf(path).getroot()
    check_tree(root, path.name)
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        mass = inertial.find("mass")
        text = None if mass is None else mass.get("value")
        if text is not None:
            value = _float(text)
            if not (np.isfinite(value) and value >= 0):
                raise ModelError(f"{path.name}: link {name!r} has <mass value={text!r}>: a mass "
                                 "must be a finite number ≥ 0 (kg)")
        tensor = inertial.find("inertia")
        for attr in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
            text = None if tensor is None else tensor.get(attr)
            if text is not None and not np.isfinite(_float(text)):
                raise ModelError(f"{path.name}: link {name!r} has <inertia {attr}={text!r}>: "
                                 "not a finite number (kg·m²)")
    for joint in robot_joints(root):           # not a <transmission>'s <joint> elements
        name, kind = joint.get("name", "?"), joint.get("type", "?")
        if name in locked:
            continue
        mimic = joint.find("mimic")
        if mimic is not None and kind != "fixed":  # a fixed joint never moves: nothing mimicked
            raise ModelError(
                f"{path.name}: joint {name!r} mimics joint {mimic.get('joint', '?')!r} "
                f"(multiplier {mimic.get('multiplier', '1')}, offset {mimic.get('offset', '0')}): "
                "consistid models every joint as independently actuated and would identify a "
                "wrong model. Remove the <mimic> tag (an independent joint), or lock the joint "
                "(locked_joints=[...]) if it does not move in your logs")
        if kind in ("fixed", "floating", "planar"):
            continue
        axis = joint.find("axis")
        text = "1 0 0" if axis is None else axis.get("xyz", "1 0 0")
        values = np.array([_float(v) for v in text.split()] or [np.nan])
        if values.shape != (3,) or not np.all(np.isfinite(values)) \
                or np.linalg.norm(values) < 1e-12:
            raise ModelError(f"{path.name}: joint {name!r} has <axis xyz={text!r}>: a {kind} "
                             "joint needs 3 finite numbers, not all zero (the direction it "
                             "moves along)")


def check_tree(root: ET.Element, source: str) -> None:
    """Refuse (:class:`ModelError`, naming the element) a URDF that is not one tree of links:
    no ``<robot>`` root element, duplicate link or joint names, a joint whose parent or child
    link is not defined, a link that is the child of two joints (a closed loop), several root
    links, and a revolute or prismatic joint without ``<limit>`` (which URDF requires).
    Pinocchio's parser refuses these too, with a message that names none of them."""
    if root.tag != "robot":
        raise ModelError(f"{source}: the root element is <{root.tag}>, not <robot>: not a URDF "
                         "(an SDF or MJCF file? MJCF: pinocchio.buildModelFromMJCF)")
    links = [link.get("name", "") for link in robot_links(root)]
    joints = robot_joints(root)
    for kind, elements in (("link", robot_links(root)), ("joint", joints)):
        for element in elements:
            check_writable_name(element.get("name", ""), f"{source}: <{kind} name>")
    for kind, elements in (("link", robot_links(root)), ("joint", joints)):
        unnamed = [k for k, e in enumerate(elements) if not e.get("name")]
        if unnamed:
            raise ModelError(f"{source}: <{kind}> number {unnamed[0] + 1} (in file order) has no "
                             "name attribute; every link and joint needs one")
    for kind, names in (("link", links), ("joint", [j.get("name", "") for j in joints])):
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ModelError(f"{source}: {kind} name(s) {dup} defined more than once; every "
                             f"{kind} needs its own name")
    parent_of: dict[str, str] = {}
    for joint in joints:
        name, kind = joint.get("name", "?"), joint.get("type", "?")
        ends = {}
        for end in ("parent", "child"):
            tag = joint.find(end)
            ends[end] = None if tag is None else tag.get("link")
            if ends[end] not in links:
                raise ModelError(f"{source}: joint {name!r} has <{end} link="
                                 f"{ends[end]!r}>, which is not a <link> of the file; links are "
                                 f"{links[:12]}{' …' if len(links) > 12 else ''}")
        child = ends["child"]
        if child in parent_of:
            raise ModelError(f"{source}: link {child!r} is the child of joints "
                             f"{parent_of[child]!r} and {name!r}: a closed kinematic loop, which "
                             "a URDF (a tree) cannot hold; remove one of the joints")
        parent_of[child] = name
        if kind in ("revolute", "prismatic") and joint.find("limit") is None:
            raise ModelError(f"{source}: {kind} joint {name!r} has no <limit>, which URDF "
                             "requires for it: add <limit lower=\"…\" upper=\"…\" effort=\"…\" "
                             "velocity=\"…\"/>" + (", or make it type=\"continuous\" if it "
                                                 "turns without end" if kind == "revolute"
                                                 else ""))
    roots = [link for link in links if link not in parent_of]
    if len(roots) > 1:
        raise ModelError(f"{source}: {len(roots)} root links {roots[:8]} (links that no joint "
                         "attaches): a URDF is one tree; attach each of them by a joint, or "
                         "remove the unused ones")


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def joint_dynamics(path: str | Path) -> dict[str, JointDynamics]:
    """The ``<dynamics>`` tag of every joint that has one, by joint name (file order)."""
    path = Path(path)
    out: dict[str, JointDynamics] = {}
    for joint in robot_joints(parse_urdf(path).getroot()):
        tag = joint.find("dynamics")
        if tag is None:
            continue
        name = joint.get("name", "?")
        values = {}
        for attr in ("damping", "friction"):
            text = tag.get(attr, "0")
            try:
                values[attr] = float(text)
            except ValueError as exc:
                raise ModelError(f"{path.name}: joint {name!r} has <dynamics {attr}={text!r}>, "
                                 "not a number") from exc
        out[name] = JointDynamics(name, values["damping"], values["friction"])
    return out


def remove_dynamics(root: ET.Element) -> ET.Element:
    """Remove every joint ``<dynamics>`` tag from a parsed URDF tree, in place; returns ``root``."""
    for joint in robot_joints(root):
        for tag in joint.findall("dynamics"):
            joint.remove(tag)
    return root


def strip_dynamics(path: str | Path, out: str | Path) -> Path:
    """Write a copy of the URDF at ``path`` to ``out`` without any joint ``<dynamics>`` tag."""
    tree = parse_urdf(Path(path))
    remove_dynamics(tree.getroot())
    out = Path(out)
    tree.write(out, encoding="utf-8", xml_declaration=True)
    return out
