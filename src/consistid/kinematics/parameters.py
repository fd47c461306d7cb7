r"""Named kinematic parameters of a serial arm, their effect on forward kinematics, and derivatives.

Every parameter is a *correction* to the URDF (SI units: m, rad); zero is the URDF itself.

Per moving joint ``J`` (nine):

``J.zero``
    zero offset: the joint's true coordinate is ``q + J.zero`` (the encoder reads ``q``);
``J.x, J.y, J.z``
    the joint origin's translation (URDF ``<origin xyz>``), added in the parent link's frame;
``J.rx, J.ry, J.rz``
    a small rotation ``θ`` of the joint origin, :math:`R = R_0 \exp([\theta]_\times)`
    (about the axes of the origin frame itself, i.e. the joint frame at ``q = 0``);
``J.axis_u, J.axis_v``
    the joint axis turned about two unit vectors ``u, v`` perpendicular to it,
    :math:`a = \exp([\theta_u u + \theta_v v]_\times)\, a_0` (for an axis along a coordinate axis,
    ``u, v`` are the next two in cyclic order: axis z → x, y).

The measured frame (``tool.x … tool.rz``): the origin of the fixed joint that carries it, in the
same two conventions. The measurement system (``base.x … base.rz``): the pose ``T_MB`` of the
robot's base in the tracker's frame, :math:`t = t_0 + \delta t`,
:math:`R = R_0\exp([\theta]_\times)`.
For distance measurements, ``anchor.x, anchor.y, anchor.z``: the fixed point (ball-bar pivot,
tracker station) in the base frame.

Forward kinematics and the zero-offset derivatives are Pinocchio's (``forwardKinematics``,
``getFrameJacobian``). The other derivatives are the frame-origin twists of a right-multiplied
perturbation at the frame where the parameter acts (Murray, Li, Sastry 1994, *A Mathematical
Introduction to Robotic Manipulation*, ch. 2–3), with the exact Jacobians of the exponential map
(``pinocchio.Jexp3``) so that they hold away from the URDF too. The model is the "complete"
parametrisation of kinematic calibration (each joint a full 6-D origin; Everett, Driels, Mooring
1987, doi:10.1109/ROBOT.1987.1087818; Hollerbach & Wampler 1996, doi:10.1177/027836499601500604):
it is redundant by design, and :mod:`consistid.kinematics.identifiability` says which combinations
the data fix.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass
from functools import cached_property
from typing import Iterable, Sequence

import numpy as np
import pinocchio as pin

from ..errors import ModelError, OptionError
from ..robot.model import RobotModel

#: the suffixes of one joint's parameters, in the order they are stored
JOINT_SUFFIXES = ("zero", "x", "y", "z", "rx", "ry", "rz", "axis_u", "axis_v")
#: the suffixes of a rigid transform (tool, base)
FRAME_SUFFIXES = ("x", "y", "z", "rx", "ry", "rz")
ANCHOR_SUFFIXES = ("x", "y", "z")
#: measurement kinds and the number of residuals per measurement
KINDS = {"position": 3, "pose": 6, "distance": 1}

#: selection keywords → predicate on (owner, suffix); owner is a joint name, "tool", "base" or
#: "anchor"
GROUPS: dict[str, str] = {
    "all": "every parameter the measurement kind can see (no base for distances)",
    "zero": "zero offsets (J.zero)",
    "translation": "joint origin translations (J.x, J.y, J.z): the link lengths",
    "orientation": "joint origin rotations (J.rx, J.ry, J.rz)",
    "origin": "translation + orientation",
    "axis": "joint axis directions (J.axis_u, J.axis_v)",
    "joints": "every per-joint parameter",
    "tool": "the measured frame's placement (tool.*)",
    "base": "the measurement system's frame (base.*)",
    "anchor": "the distance anchor point (anchor.*)",
}


def _exp3(v: np.ndarray) -> np.ndarray:
    return pin.exp3(np.asarray(v, dtype=float))


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v]×``, so that ``[v]× w = v × w`` (3×3)."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _perpendicular(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``u, v`` with ``(u, v, axis)`` right-handed and orthonormal."""
    k = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[k]) - 1.0) < 1e-12:          # along a coordinate axis: the next two
        u, v = np.eye(3)[(k + 1) % 3], np.eye(3)[(k + 2) % 3]
        return (u, v) if axis[k] > 0 else (v, u)
    u = np.cross(axis, np.eye(3)[int(np.argmin(np.abs(axis)))])
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


@dataclass(frozen=True, eq=False)
class JointGeometry:
    """What the chart needs of one moving joint (index ``j`` in the Pinocchio model)."""

    j: int
    name: str
    revolute: bool
    unbounded: bool
    axis: np.ndarray          # unit, in the joint frame
    u: np.ndarray
    v: np.ndarray
    placement: pin.SE3        # URDF placement in the parent joint's frame (jointPlacements)
    parent_rotation: np.ndarray  # rotation of the URDF parent link in the parent joint's frame


@dataclass(frozen=True, eq=False)
class ToolGeometry:
    """The measured frame: its id, placement in its joint's frame, and the rotation of the link
    its fixed joint hangs from (identity when the frame is not below a fixed joint)."""

    frame: str
    fid: int
    joint: int
    placement: pin.SE3
    parent_rotation: np.ndarray
    moved: tuple[int, ...]    # frame ids that ride on the measured frame (itself included)
    fixed_joint: str | None   # the URDF fixed joint whose origin places it


def _joint_geometry(model: RobotModel) -> list[JointGeometry]:
    pm = model.pin_model
    data = pm.createData()
    pin.computeJointJacobians(pm, data, pin.neutral(pm))
    out = []
    for j in range(1, pm.njoints):
        s = pin.getJointJacobian(pm, data, j, pin.LOCAL)[:, pm.joints[j].idx_v]
        lin, ang = s[:3], s[3:]
        if np.linalg.norm(lin) < 1e-12 and abs(np.linalg.norm(ang) - 1) < 1e-9:
            revolute, axis = True, ang
        elif np.linalg.norm(ang) < 1e-12 and abs(np.linalg.norm(lin) - 1) < 1e-9:
            revolute, axis = False, lin
        else:
            raise ModelError(f"joint {pm.names[j]!r} ({pm.joints[j].shortname()}) is neither "
                             "revolute nor prismatic about a fixed axis")
        parent_rotation = np.eye(3)
        if pm.existFrame(pm.names[j], pin.FrameType.JOINT):
            jf = pm.frames[pm.getFrameId(pm.names[j], pin.FrameType.JOINT)]
            above = pm.frames[jf.parentFrame]
            if above.parentJoint == pm.parents[j] and jf.parentFrame != 0:
                parent_rotation = np.array(above.placement.rotation)
        u, v = _perpendicular(axis)
        out.append(JointGeometry(j, pm.names[j], revolute, pm.joints[j].nq == 2,
                                 np.array(axis), u, v, pin.SE3(pm.jointPlacements[j]),
                                 parent_rotation))
    return out


def _tool_geometry(model: RobotModel, frame: str) -> ToolGeometry:
    pm = model.pin_model
    if not isinstance(frame, str) or not pm.existFrame(frame):
        names = [f.name for f in pm.frames if f.type in (pin.FrameType.BODY,
                                                         pin.FrameType.OP_FRAME)]
        raise ModelError(f"frame {frame!r} does not exist in {model.name}; its body and "
                         f"operational frames are {names}")
    fid = pm.getFrameId(frame)
    f = pm.frames[fid]
    if f.parentJoint == 0:
        raise ModelError(f"frame {frame!r} is fixed to the base of {model.name}: it does not "
                         "move with the joints, so it cannot calibrate them")
    parent_rotation, fixed_joint = np.eye(3), None
    above = pm.frames[f.parentFrame]
    if above.type == pin.FrameType.FIXED_JOINT and above.parentJoint == f.parentJoint:
        fixed_joint = above.name
        grand = pm.frames[above.parentFrame]
        if grand.parentJoint == f.parentJoint:
            parent_rotation = np.array(grand.placement.rotation)
    moved = [fid] + ([f.parentFrame] if fixed_joint else [])
    changed = True
    while changed:                        # frames hanging below the measured one move with it
        changed = False
        for k, g in enumerate(pm.frames):
            if k not in moved and g.parentFrame in moved and g.parentJoint == f.parentJoint \
                    and g.parentFrame != f.parentFrame:
                moved.append(k)
                changed = True
    return ToolGeometry(frame, fid, int(f.parentJoint), pin.SE3(f.placement), parent_rotation,
                        tuple(moved), fixed_joint)


def _corrected_placement(placement: pin.SE3, parent_rotation: np.ndarray,
                         d: np.ndarray) -> pin.SE3:
    """``(t₀ + A·δp, R₀ exp(θ))`` for ``d = (δp, θ)``."""
    return pin.SE3(placement.rotation @ _exp3(d[3:6]),
                   placement.translation + parent_rotation @ d[:3])


class KinematicParameters:
    """The named kinematic parameters of ``model`` measured at ``frame`` (module docstring).

    Parameters
    ----------
    model : the nominal robot (its URDF values are the zero of every parameter).
    frame : the measured frame's name.
    kind : ``"position"``, ``"pose"`` or ``"distance"`` (decides whether base or anchor
        parameters exist).

    Attributes
    ----------
    names : tuple of str, all parameter names: per joint (:data:`JOINT_SUFFIXES`), then
        ``tool.*``, then ``base.*`` (positions, poses) or ``anchor.*`` (distances).
    """

    def __init__(self, model: RobotModel, frame: str, kind: str = "position") -> None:
        if kind not in KINDS:
            raise OptionError(f"measurement kind {kind!r} is not one of {list(KINDS)}")
        self.model, self.frame, self.kind = model, frame, kind
        self.joints = _joint_geometry(model)
        self.tool = _tool_geometry(model, frame)
        # only the joints between the base and the measured frame move it
        chain, j = set(), self.tool.joint
        while j > 0:
            chain.add(j)
            j = model.pin_model.parents[j]
        self.chain = chain
        names = [f"{g.name}.{s}" for g in self.joints for s in JOINT_SUFFIXES]
        names += [f"tool.{s}" for s in FRAME_SUFFIXES]
        names += ([f"anchor.{s}" for s in ANCHOR_SUFFIXES] if kind == "distance"
                  else [f"base.{s}" for s in FRAME_SUFFIXES])
        self.names: tuple[str, ...] = tuple(names)
        self.index = {n: i for i, n in enumerate(names)}
        self.n_joint = 9 * len(self.joints)
        self.n_kinematic = self.n_joint + 6      # joints + tool: these move the frame
        #: axis parameters of continuous joints (not offered: see :meth:`select`)
        self.fixed_axes = frozenset(f"{g.name}.{s}" for g in self.joints if g.unbounded
                                    for s in ("axis_u", "axis_v"))

    # ----------------------------------------------------------------------------- naming
    @property
    def size(self) -> int:
        return len(self.names)

    def units(self, name: str) -> str:
        """``"m"`` or ``"rad"`` (``"m"`` for a prismatic joint's zero offset)."""
        owner, _, suffix = name.rpartition(".")
        if suffix in ("x", "y", "z"):
            return "m"
        if suffix == "zero":
            g = next(g for g in self.joints if g.name == owner)
            return "rad" if g.revolute else "m"
        return "rad"

    def owner_of(self, name: str) -> str:
        return name.rpartition(".")[0]

    def select(self, parameters: str | Iterable[str] = "all") -> np.ndarray:
        """Indices of the named parameters, in :attr:`names` order.

        ``parameters`` is a keyword of :data:`GROUPS` or a parameter name or shell pattern
        (``"panda_joint2.*"``, ``"*.zero"``), or a list of them; every item must match something
        (:class:`OptionError` otherwise, listing the keywords and an example name).
        """
        if isinstance(parameters, str):
            items = [parameters]
        else:
            try:
                items = list(parameters)
            except TypeError:
                raise OptionError(f"parameters must be a keyword, a name or a list of them (e.g. "
                                  f"'all' or ['zero', 'translation']), got {parameters!r}"
                                  ) from None
        if not items:
            raise OptionError("parameters is empty; name at least one (e.g. 'all', 'zero', "
                              f"'translation', {self.names[0]!r})")
        chosen: set[int] = set()
        joint_names = {g.name for g in self.joints}
        for item in items:
            if not isinstance(item, str):
                raise OptionError(f"parameters must be names or keywords, got {item!r}")
            if item in GROUPS:   # keywords skip what cannot be turned (continuous joints' axes)
                hits = [i for i, n in enumerate(self.names)
                        if self._in_group(item, n, joint_names) and n not in self.fixed_axes]
            else:
                hits = [i for i, n in enumerate(self.names) if fnmatch.fnmatchcase(n, item)]
                fixed = sorted(self.names[i] for i in hits if self.names[i] in self.fixed_axes)
                if fixed:
                    raise OptionError(
                        f"parameters item {item!r} names the axis of a continuous joint "
                        f"({fixed}): Pinocchio has no unbounded revolute joint about an "
                        "arbitrary axis; the joint's and its child's origin rotations cover "
                        "the tilt")
            if not hits:
                raise OptionError(
                    f"parameters item {item!r} matches no parameter of {self.model.name} "
                    f"measured at {self.frame!r} ({self.kind}); keywords: {list(GROUPS)}; "
                    f"names look like {self.names[0]!r}, 'tool.x', "
                    f"{self.names[-1]!r} (shell patterns allowed)")
            chosen.update(hits)
        return np.array(sorted(chosen), dtype=int)

    @staticmethod
    def _in_group(group: str, name: str, joint_names: set[str]) -> bool:
        owner, _, suffix = name.rpartition(".")
        joint = owner in joint_names
        return {
            "all": True,
            "zero": joint and suffix == "zero",
            "translation": joint and suffix in ("x", "y", "z"),
            "orientation": joint and suffix in ("rx", "ry", "rz"),
            "origin": joint and suffix in FRAME_SUFFIXES,
            "axis": joint and suffix in ("axis_u", "axis_v"),
            "joints": joint,
            "tool": owner == "tool",
            "base": owner == "base",
            "anchor": owner == "anchor",
        }.get(group, False)

    def priority(self, sel: np.ndarray) -> np.ndarray:
        """The order in which :func:`~consistid.kinematics.identifiability.sequential_selection`
        considers the selected columns: measurement frame / anchor, then joints from the base
        out (zero offset, translation, rotation) and the tool, then every axis tilt last (a tilt
        is always a combination of origin rotations, so with those selected the axes are held).
        Returns positions into ``sel``."""
        sel = np.asarray(sel)
        axis = np.array([self.names[i].endswith((".axis_u", ".axis_v")) for i in sel], bool)
        extra = sel >= self.n_kinematic
        return np.concatenate([np.flatnonzero(extra), np.flatnonzero(~extra & ~axis),
                               np.flatnonzero(axis)])

    def describe(self, name: str) -> str:
        """What a parameter moves, in words (for tables)."""
        owner, _, suffix = name.rpartition(".")
        if owner in ("base", "anchor"):
            return {"base": "measurement frame", "anchor": "anchor point"}[owner] + f" {suffix}"
        if owner == "tool":
            return f"{self.frame} placement {suffix}"
        if suffix.startswith("axis"):
            g = next(g for g in self.joints if g.name == owner)
            vec = g.u if suffix == "axis_u" else g.v
            return f"axis tilt about ({', '.join(f'{c:g}' for c in np.round(vec, 3))})"
        return {"zero": "zero offset", "x": "origin x", "y": "origin y", "z": "origin z",
                "rx": "origin rot x", "ry": "origin rot y", "rz": "origin rot z"}[suffix]

    # ----------------------------------------------------------------------------- the model
    def _split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        values = np.asarray(values, dtype=float)
        if values.shape != (self.size,):
            raise OptionError(f"kinematic parameter vector has shape {values.shape}; "
                              f"expected ({self.size},) named by .names")
        return (values[:self.n_joint].reshape(-1, 9), values[self.n_joint:self.n_kinematic],
                values[self.n_kinematic:])

    def axis(self, g: JointGeometry, d: np.ndarray) -> np.ndarray:
        """The joint axis (joint frame) for the joint's corrections ``d`` (9,)."""
        return _exp3(d[7] * g.u + d[8] * g.v) @ g.axis

    def pin_model(self, values: np.ndarray) -> pin.Model:
        """A copy of the nominal ``pinocchio.Model`` with the corrections ``values`` applied:
        joint placements (origin corrections, then the zero offset folded in:
        ``P · exp(a·zero)``, so that the model takes the encoder's ``q``), joint axes
        (``Joint…Unaligned`` where turned) and the measured frame's placement (and every frame
        below it). Inertias stay in their (moving) joint frames."""
        joint_d, tool_d, _ = self._split(values)
        pm = self.model.pin_model.copy()
        for g, d in zip(self.joints, joint_d):
            if not np.any(d):
                continue
            placement = _corrected_placement(g.placement, g.parent_rotation, d[1:7])
            axis = self.axis(g, d)
            if d[7] or d[8]:
                old = pm.joints[g.j]
                if g.unbounded:
                    raise OptionError(f"the axis of continuous joint {g.name!r} cannot be "
                                      "turned (Pinocchio has no unbounded revolute joint about "
                                      "an arbitrary axis); its origin rotations cover the tilt")
                if g.revolute:
                    new = pin.JointModelRevoluteUnaligned(axis)
                else:
                    new = pin.JointModelPrismaticUnaligned(axis)
                new.setIndexes(old.id, old.idx_q, old.idx_v)
                pm.joints[g.j] = pin.JointModel(new)
            zero = (pin.SE3(_exp3(axis * d[0]), np.zeros(3)) if g.revolute
                    else pin.SE3(np.eye(3), axis * d[0]))
            pm.jointPlacements[g.j] = placement * zero
        if np.any(tool_d):
            t = self.tool
            new = _corrected_placement(t.placement, t.parent_rotation, tool_d)
            change = new * t.placement.inverse()
            for k in t.moved:
                pm.frames[k].placement = change * pm.frames[k].placement
        return pm

    def robot_model(self, values: np.ndarray) -> RobotModel:
        """:meth:`pin_model` as a :class:`RobotModel` (same names, locks and gravity)."""
        return self.model.with_kinematics(self.pin_model(values))

    def base_transform(self, values: np.ndarray, base0: pin.SE3) -> pin.SE3:
        """``T_MB`` for the ``base.*`` corrections of ``values`` on the initial ``base0``."""
        *_, extra = self._split(values)
        if self.kind == "distance":
            return base0
        return pin.SE3(base0.rotation @ _exp3(extra[3:6]), base0.translation + extra[:3])

    # ----------------------------------------------------------------------------- FK + twists
    def frame_kinematics(self, values: np.ndarray, q: np.ndarray, derivatives: bool = True
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Poses of the measured frame in the robot's base frame and their derivatives.

        Parameters
        ----------
        values : (p,) corrections.
        q : (N, nv) joint coordinates as the encoders read them.

        Returns
        -------
        positions : (N, 3)
        rotations : (N, 3, 3)
        twists : (N, 6, n_kinematic) or None — per joint/tool parameter, the frame-origin
            twist ``[v; ω]`` in base-frame axes (Pinocchio's ``LOCAL_WORLD_ALIGNED``) that a
            unit change of the parameter produces.
        """
        joint_d, tool_d, _ = self._split(values)
        pm = self.pin_model(values)
        data = pm.createData()
        n = q.shape[0]
        pos, rot = np.empty((n, 3)), np.empty((n, 3, 3))
        twists = np.zeros((n, 6, self.n_kinematic)) if derivatives else None
        fid, t = self.tool.fid, self.tool
        pre = {g.j: _corrected_placement(g.placement, g.parent_rotation, d[1:7])
               for g, d in zip(self.joints, joint_d)}
        axes = {g.j: self.axis(g, d) for g, d in zip(self.joints, joint_d)}
        for k in range(n):
            qk = self.model.configuration(q[k])
            if derivatives:
                pin.computeJointJacobians(pm, data, qk)
            else:
                pin.forwardKinematics(pm, data, qk)
            oMf = pin.updateFramePlacement(pm, data, fid)
            p = np.array(oMf.translation)
            pos[k], rot[k] = p, oMf.rotation
            if not derivatives:
                continue
            jac = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
            tw = twists[k]
            for i, (g, d) in enumerate(zip(self.joints, joint_d)):
                if g.j not in self.chain:
                    continue
                c = 9 * i
                tw[:, c] = jac[:, pm.joints[g.j].idx_v]                 # zero offset
                parent = data.oMi[pm.parents[g.j]]
                x = parent * pre[g.j]                                   # origin frame, q = 0
                tw[:3, c + 1:c + 4] = parent.rotation @ g.parent_rotation
                omega = x.rotation @ pin.Jexp3(d[4:7])                  # origin rotation
                tw[3:, c + 4:c + 7] = omega
                lever = _skew(x.translation - p)               # ω × (p − o) = [o − p]× ω
                tw[:3, c + 4:c + 7] = lever @ omega
                s = q[k, g.j - 1] + d[0]                                # axis direction
                a = axes[g.j]
                dphi = pin.Jexp3(-(d[7] * g.u + d[8] * g.v)) @ np.column_stack([g.u, g.v])
                da = -_skew(a) @ dphi                                   # dφ × a, (3, 2)
                if g.revolute:
                    w = x.rotation @ (pin.Jexp3(-s * a) @ (s * da))
                    tw[3:, c + 7:c + 9] = w
                    tw[:3, c + 7:c + 9] = lever @ w
                else:
                    tw[:3, c + 7:c + 9] = x.rotation @ (s * da)
            oMi = data.oMi[t.joint]
            c = self.n_joint
            tw[:3, c:c + 3] = oMi.rotation @ t.parent_rotation
            tw[3:, c + 3:c + 6] = oMf.rotation @ pin.Jexp3(tool_d[3:6])
        return pos, rot, twists

    @cached_property
    def generic_values(self) -> np.ndarray:
        """Small seeded corrections (±1 mm, ±0.3° on every joint and tool parameter): the
        generic point at which structural identifiability is judged. At the URDF itself special
        geometry can hide a parameter that any real robot shows (a measured point on the last
        joint's axis makes that joint's zero offset invisible — only exactly there)."""
        rng = np.random.default_rng(0)
        out = np.zeros(self.size)
        for i, name in enumerate(self.names[:self.n_kinematic]):
            if name in self.fixed_axes:
                continue
            out[i] = rng.uniform(-1e-3, 1e-3) if self.units(name) == "m" else \
                rng.uniform(-1, 1) * np.radians(0.3)
        return out

    def generic_point(self, sel: np.ndarray) -> np.ndarray:
        """:attr:`generic_values` on the selected parameters ``sel`` only (the others stay at
        the URDF: the family of robots a calibration of ``sel`` considers)."""
        out = np.zeros(self.size)
        out[sel] = self.generic_values[sel]
        return out

    @cached_property
    def random_configurations(self) -> np.ndarray:
        """200 configurations drawn uniformly within the joint limits (±π where a joint has
        none), seeded: the generic points at which structural identifiability is judged."""
        return random_configurations(self.model, 200, np.random.default_rng(0))


def random_configurations(model: RobotModel, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, nv) joint coordinates uniform within the URDF limits (``±π`` for an unbounded
    revolute joint, ``±1 m`` for an unbounded prismatic one)."""
    lim = model.limits
    lo = np.where(np.isfinite(lim.lower), lim.lower, -np.pi)
    hi = np.where(np.isfinite(lim.upper), lim.upper, np.pi)
    return lo + (hi - lo) * rng.random((n, model.nv))


def check_values(params: KinematicParameters, values: Sequence[float] | dict[str, float]
                 ) -> np.ndarray:
    """A full correction vector from a dict ``{name: value}`` (others 0) or a vector."""
    if isinstance(values, dict):
        out = np.zeros(params.size)
        for name, v in values.items():
            if name not in params.index:
                raise OptionError(f"unknown kinematic parameter {name!r}; names look like "
                                  f"{params.names[0]!r}")
            out[params.index[name]] = float(v)
        return out
    out = np.asarray(values, dtype=float)
    if out.shape != (params.size,) or not np.all(np.isfinite(out)):
        raise OptionError(f"kinematic corrections must be {params.size} finite numbers named "
                          f"by .names, got shape {out.shape}")
    return out
