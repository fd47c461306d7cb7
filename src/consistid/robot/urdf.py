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

from ..errors import ModelError


@dataclass(frozen=True)
class JointDynamics:
    """One joint's ``<dynamics>`` tag: ``damping`` = viscous ``f_v``, ``friction`` = Coulomb
    ``f_c`` (0 where the attribute is absent)."""

    joint: str
    damping: float
    friction: float


def parse_urdf(path: Path) -> ET.ElementTree:
    """The URDF's XML tree; :class:`ModelError` for a missing file or malformed XML."""
    if not path.is_file():
        raise ModelError(f"URDF file {str(path)!r} does not exist")
    try:
        return ET.parse(path)
    except ET.ParseError as exc:
        raise ModelError(f"{path.name} is not well-formed XML: {exc}") from exc


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
