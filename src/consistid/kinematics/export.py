r"""Write calibrated joint origins and axes into the URDF's text, changing nothing else.

The source file is edited as text, not re-serialised: for each calibrated joint only the values of
its ``<origin xyz="…" rpy="…">`` and ``<axis xyz="…">`` attributes that the calibration changed
are replaced (an absent element or attribute is added), so comments, formatting, attribute order
and every other number stay byte for byte, and a ``diff`` shows the calibration and nothing else.

With the URDF origin :math:`O = (R_O, t_O)` of a joint, its corrections (δp, θ, axis tilt φ,
zero offset ζ; :mod:`consistid.kinematics.parameters`) and the turned axis
:math:`a = \exp([\varphi]_\times) a_0`:

.. math::  t_O' = t_O + \delta p \;(+\, R_O e^{[\theta]_\times} a\,\zeta \text{ prismatic}),
           \qquad R_O' = R_O\, e^{[\theta]_\times}\, e^{[a\zeta]_\times} \text{ (revolute)},

i.e. the zero offset is folded into the origin (the link frame at encoder reading ``q`` is where
the link is), written as URDF ``rpy`` (``R = R_z(y) R_y(p) R_x(r)``). The measured frame's fixed
joint gets the tool corrections the same way. Loading the written file with the same locked
joints reproduces the calibrated model's kinematics (to the 17 significant digits written).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..errors import ExportWarning, ModelError

if TYPE_CHECKING:
    from .parameters import KinematicParameters
    from .result import CalibrationResult


def _fmt(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) if v != 0 else "0" for v in values)


class _UrdfText:
    """Locate elements of a URDF's text outside comments and edit attribute values."""

    def __init__(self, text: str, source: str) -> None:
        self.text, self.source = text, source
        self.comments = [m.span() for m in re.finditer(r"<!--.*?-->", text, re.S)]
        self.edits: list[tuple[int, int, str]] = []

    def _outside(self, pos: int) -> bool:
        return not any(a <= pos < b for a, b in self.comments)

    def joint_span(self, name: str) -> tuple[int, int, int]:
        """(start of ``<joint …>``, end of the open tag, start of ``</joint>``)."""
        pattern = re.compile(r"<joint\b[^>]*?\bname\s*=\s*([\"'])" + re.escape(name)
                             + r"\1[^>]*>", re.S)
        for m in pattern.finditer(self.text):
            # a <transmission> names joints too (<joint name="…"> without a type)
            if not self._outside(m.start()) or not re.search(r"\btype\s*=", m.group(0)):
                continue
            if m.group(0).endswith("/>"):
                raise ModelError(f"{self.source}: joint {name!r} is an empty element")
            close = self.text.find("</joint>", m.end())
            if close < 0:
                raise ModelError(f"{self.source}: joint {name!r} is not closed")
            return m.start(), m.end(), close
        raise ModelError(f"{self.source}: no joint named {name!r} (is this the model's URDF?)")

    def element(self, tag: str, lo: int, hi: int) -> re.Match | None:
        for m in re.compile(r"<" + tag + r"\b[^>]*?/?>", re.S).finditer(self.text, lo, hi):
            if self._outside(m.start()):
                return m
        return None

    @staticmethod
    def attribute(tag_text: str, attr: str) -> re.Match | None:
        return re.search(r"\b" + attr + r"\s*=\s*([\"'])(.*?)\1", tag_text, re.S)

    def read(self, tag: re.Match | None, attr: str, default: str) -> np.ndarray:
        if tag is None:
            return np.array([float(v) for v in default.split()])
        a = self.attribute(tag.group(0), attr)
        text = default if a is None else a.group(2)
        try:
            values = np.array([float(v) for v in text.split()])
        except ValueError as exc:
            raise ModelError(f"{self.source}: {attr}={text!r} is not three numbers") from exc
        if values.shape != (3,):
            raise ModelError(f"{self.source}: {attr}={text!r} is not three numbers")
        return values

    def set(self, tag: re.Match | None, tag_name: str, attr: str, value: str,
            insert_at: int) -> None:
        """Replace ``attr``'s value in ``tag`` (add it, or add the element after
        ``insert_at`` — the end of the joint's open tag — when absent)."""
        if tag is None:
            line_start = self.text.rfind("\n", 0, insert_at)
            indent = re.match(r"[ \t]*", self.text[line_start + 1:]).group(0)
            self.edits.append((insert_at, insert_at,
                               f"\n{indent}  <{tag_name} {attr}=\"{value}\"/>"))
            return
        a = self.attribute(tag.group(0), attr)
        if a is not None:
            self.edits.append((tag.start() + a.start(2), tag.start() + a.end(2), value))
        else:
            end = tag.end() - (2 if tag.group(0).endswith("/>") else 1)
            self.edits.append((end, end, f" {attr}=\"{value}\""))

    def result(self) -> str:
        text = self.text
        merged: dict[int, list[tuple[int, int, str]]] = {}
        for e in self.edits:                 # two insertions at one place keep their order
            merged.setdefault(e[0], []).append(e)
        for start in sorted(merged, reverse=True):
            group = merged[start]
            end = max(e[1] for e in group)
            text = text[:start] + "".join(e[2] for e in group) + text[end:]
        return text


def calibrated_urdf_text(res: "CalibrationResult") -> str:
    """The nominal URDF's text with the calibration written in (module docstring)."""
    return corrected_urdf_text(res.chart, res.full_values)


def corrected_urdf_text(chart: "KinematicParameters", values: np.ndarray) -> str:
    """The URDF of ``chart.model`` with the corrections ``values`` (named by ``chart.names``)
    written into its joint origins and axes (module docstring)."""
    model = chart.model
    if model.source is None or not Path(model.source).is_file():
        raise ModelError(f"{model.name!r} has no source URDF to write the calibration into "
                         "(build the model with RobotModel.from_urdf)")
    source = Path(model.source)
    doc = _UrdfText(source.read_bytes().decode("utf-8"), source.name)
    joint_d = values[:chart.n_joint].reshape(-1, 9)
    for g, d in zip(chart.joints, joint_d):
        if not np.any(d):
            continue
        start, open_end, close = doc.joint_span(g.name)
        origin = doc.element("origin", open_end, close)
        xyz = doc.read(origin, "xyz", "0 0 0")
        rpy = doc.read(origin, "rpy", "0 0 0")
        rot = pin.rpy.rpyToMatrix(rpy) @ pin.exp3(d[4:7])
        axis = chart.axis(g, d)
        t = xyz + d[1:4]
        if g.revolute:
            rot = rot @ pin.exp3(axis * d[0])
        else:
            t = t + rot @ axis * d[0]
        if np.any(t != xyz):
            doc.set(origin, "origin", "xyz", _fmt(t), open_end)
        if np.any(d[4:7]) or (g.revolute and d[0]):
            doc.set(origin, "origin", "rpy", _fmt(pin.rpy.matrixToRpy(rot)), open_end)
        if d[7] or d[8]:
            doc.set(doc.element("axis", open_end, close), "axis", "xyz", _fmt(axis), open_end)
    tool_d = values[chart.n_joint:chart.n_kinematic]
    if np.any(tool_d):
        if chart.tool.fixed_joint is None:
            warnings.warn(f"the corrections of {chart.frame!r} (tool.*) have no place in the "
                          f"URDF: the frame is not the child of a fixed joint; not written",
                          ExportWarning, stacklevel=3)
        else:
            start, open_end, close = doc.joint_span(chart.tool.fixed_joint)
            origin = doc.element("origin", open_end, close)
            xyz = doc.read(origin, "xyz", "0 0 0")
            rpy = doc.read(origin, "rpy", "0 0 0")
            if np.any(tool_d[:3]):
                doc.set(origin, "origin", "xyz", _fmt(xyz + tool_d[:3]), open_end)
            if np.any(tool_d[3:]):
                rot = pin.rpy.rpyToMatrix(rpy) @ pin.exp3(tool_d[3:])
                doc.set(origin, "origin", "rpy", _fmt(pin.rpy.matrixToRpy(rot)), open_end)
    return doc.result()


def write_calibrated_urdf(res: "CalibrationResult", path: str | Path) -> Path:
    """Write :func:`calibrated_urdf_text` to ``path`` (never over the source URDF)."""
    out = Path(path)
    text = calibrated_urdf_text(res)
    if out.exists() and out.resolve() == Path(res.nominal.source).resolve():
        raise ModelError(f"refusing to overwrite the source URDF {str(out)!r}; write the "
                         "calibrated one elsewhere")
    out.write_bytes(text.encode("utf-8"))
    return out
