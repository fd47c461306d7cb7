r"""Write identified values into the user's own MJCF, every other byte unchanged.

A copy of the source MJCF is made with, per moving body, its ``<inertial>`` set to the
identified mass, centre of mass and inertia, and per identified joint term its ``<joint>``
attribute (``damping = f_v``, ``frictionloss = f_c``, ``armature = I_a``). Elements are found
by a real parser (:mod:`consistid.robot.xml_spans`), and only their attribute values are
edited in the file's text (the URDF writer, :mod:`consistid.robot.export`, re-serialises its
tree instead): meshes, actuators, contacts, sensors, comments, quoting and attribute order stay
byte for byte.

What is written on a MuJoCo body ``b`` carrying the joint of a consistid body: the identified
10-vector ``π`` is about the Pinocchio joint frame (:mod:`consistid.robot.mjcf_in`); the
inertials of the other MuJoCo bodies merged into it (bodies welded to it, and bodies below
``locked_joints``) are kept as they are and subtracted, and what remains is expressed in ``b``'s
frame ``X`` (its placement in the joint frame): ``π_b = X⁻¹·(π − Σ π_kept)``, written as
``pos = c``, ``mass = m`` and ``fullinertia`` = ``I_c`` about the CoM, in the body's axes (an
``iquat``/``diaginertia`` pair is replaced). The remainder must be physically consistent
(pseudo-inertia level), else :class:`InconsistentParametersError` names the body.

* A joint attribute inherited from a ``<default>`` class is written on the element (it then
  overrides the class for this joint only), and an :class:`ExportWarning` says so.
* A body without ``<inertial>`` (``inertiafromgeom="auto"``: MuJoCo derives it from the geoms)
  gets an explicit ``<inertial>`` (warned); ``inertiafromgeom="true"`` (which ignores every
  ``<inertial>``) is refused.
* ``<include>`` is refused by name: the edits are spans of one file; write into the included
  file instead (its bodies and joints are matched by name).
* The armature written is the identified ``I_a``, the joint's whole rotor inertia (the regressor
  has no other); terms not identified keep the file's value, and an :class:`ExportWarning` lists
  those that are non-zero (the identified model did not include them).

* Assets (meshes, textures, height fields, skins) named by relative ``file`` resolve from the
  MJCF's folder (through ``<compiler meshdir/texturedir/assetdir>``). An output in another
  folder is refused, unless ``absolute_assets=True``: then every ``<compiler>`` of the copy
  gets ``meshdir`` and ``texturedir`` set to the absolute folders MuJoCo resolved for the
  source (``assetdir``, which they override, is removed; a file without ``<compiler>`` gets
  one), so that the copy loads the source's assets from anywhere on this machine. A relative
  ``file`` that no compiler folder governs (``<model file>``) is still refused.

The result is written to a temporary file beside the output, compiled by MuJoCo and read back
(:func:`~consistid.robot.mjcf_in.read_mjcf`); only when every written body and joint reads back
as identified (relative 1e-9) is it moved onto ``path``
(:func:`consistid.filesafety.replacing`). The source itself is never written.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import pinocchio as pin

from ..errors import ExportWarning, InconsistentParametersError, ModelError
from ..filesafety import replacing
from .inertia import InertialParameters, body_slice, writable_bodies
from .joint_terms import MJCF_ATTRIBUTES, check_nonnegative, export_parameters
from .mjcf_in import body_inertia, body_label, check_safe_xml, compile_mjcf, read_mjcf
from .xml_spans import (Element, apply, elements, insert_first_child, remove_attribute,
                        set_attribute)

if TYPE_CHECKING:
    from .model import RobotModel

#: ``<inertial>`` attributes replaced by ``pos``/``mass``/``fullinertia``.
INERTIAL_REPLACED = ("quat", "axisangle", "xyaxes", "zaxis", "euler", "diaginertia")
#: Relative tolerance of the read-back check.
READBACK_RTOL = 1e-9
#: Asset elements whose relative files MuJoCo looks up in ``<compiler meshdir>`` …
MESHDIR_ASSETS = ("mesh", "skin", "hfield")
#: … and in ``texturedir`` (a cube or skybox texture names up to six files).
TEXTUREDIR_ASSETS = ("texture",)


def _num(values: Any) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(values))


def _in_bodies(els: list[Element], tag: str) -> list[Element]:
    """``tag`` elements whose parent is a ``<body>``, ``<frame>`` or ``<worldbody>`` (not
    defaults, equality or tendon elements of the same tag)."""
    return [e for e in els if e.tag == tag and e.parent >= 0
            and els[e.parent].tag in ("body", "frame", "worldbody")]


def _check_source(model: "RobotModel", source: Path, out: Path, els: list[Element],
                  absolute_assets: bool = False) -> None:
    """Refuse an output over the source, an ``<include>``, ``inertiafromgeom="true"``, and
    relative asset files when the output goes to another folder (except those the compiler's
    folders govern, with ``absolute_assets``)."""
    if out.is_dir() or not out.parent.is_dir():
        raise ModelError(f"to_mjcf({str(out)!r}): " + ("a folder, not a file name" if out.is_dir()
                                                      else f"no folder {str(out.parent)!r}"))
    for src in {source, *([model.source] if model.source is not None else [])}:
        if Path(src).resolve() == out.resolve():
            raise ModelError(f"to_mjcf({str(out)!r}) would write over the MJCF {src} (a source); "
                             "write to another path")
    includes = [e.attrs.get("file", "?") for e in els if e.tag == "include"]
    if includes:
        raise ModelError(f"{source.name} includes {includes}: the writer edits one file; pass "
                         "the file that holds the robot's bodies as source= (bodies and joints "
                         "are matched by name)")
    for e in els:
        if e.tag == "compiler" and e.attrs.get("inertiafromgeom", "auto") in ("true", "True"):
            raise ModelError(f"{source.name}: <compiler inertiafromgeom=\"true\"> makes MuJoCo "
                             "ignore every <inertial>; set it to \"auto\" (the default) so that "
                             "the identified inertials are used")
    if out.resolve().parent != source.resolve().parent:
        governed = MESHDIR_ASSETS + TEXTUREDIR_ASSETS if absolute_assets else ()
        files = [value for e in els if e.tag not in governed for key, value in e.attrs.items()
                 if key.startswith("file") and not Path(value).is_absolute()]
        if files:
            raise ModelError(f"{source.name} refers to files by relative path ({files[0]!r} …), "
                             f"which would not resolve from {out.resolve().parent}; write the "
                             f"output into {source.resolve().parent}" + (
                                 "" if absolute_assets else ", or pass absolute_assets=True "
                                 "(the copy's <compiler> then names the source's asset "
                                 "folders by absolute path)"))


def _asset_folder_edits(data: bytes, els: list[Element], source: Path
                        ) -> list[tuple[int, int, bytes]]:
    """The edits that set ``meshdir`` and ``texturedir`` of every ``<compiler>`` to the absolute
    folders MuJoCo resolves for ``source`` (and remove ``assetdir``, which they override), or
    insert a ``<compiler>`` holding them."""
    import mujoco
    from xml.sax.saxutils import quoteattr

    spec = mujoco.MjSpec.from_file(str(source))
    folders = {key: str((source.resolve().parent / value).resolve())
               for key, value in (("meshdir", spec.meshdir), ("texturedir", spec.texturedir))}
    compilers = [e for e in els if e.tag == "compiler"]
    if not compilers:
        attrs = " ".join(f"{key}={quoteattr(value)}" for key, value in folders.items())
        return [insert_first_child(data, els[0], f"<compiler {attrs}/>")]
    edits = []
    for el in compilers:
        for key, value in folders.items():
            edits.append(set_attribute(data, el, key, quoteattr(value)[1:-1]))
        removed = remove_attribute(data, el, "assetdir")
        edits += [removed] if removed is not None else []
    return edits


def _mjcf_bodies(mj: Any, els: list[Element], source: str) -> dict[int, Element]:
    """MuJoCo body id → its ``<body>`` element (document order is MuJoCo's body order)."""
    import mujoco

    bodies = _in_bodies(els, "body")
    if len(bodies) != mj.nbody - 1:
        raise ModelError(f"{source}: {len(bodies)} <body> elements but MuJoCo compiled "
                         f"{mj.nbody - 1} bodies (<replicate>, <attach> or <frame> generated "
                         "some); the writer needs every body written out in the file")
    out = {}
    for b, el in enumerate(bodies, start=1):
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if el.attrs.get("name", "") != name:
            raise ModelError(f"{source}: body number {b} is {name!r} in MuJoCo but "
                             f"{el.attrs.get('name')!r} in the file")
        out[b] = el
    return out


def _body_edits(data: bytes, el: Element, els: list[Element], value: pin.Inertia
                ) -> tuple[list[tuple[int, int, bytes]], bool]:
    """Edits writing ``value`` (body frame) as the body's ``<inertial>``; True when inserted."""
    ic = np.asarray(value.inertia)
    attrs = {"pos": _num(value.lever), "mass": _num(value.mass),
             "fullinertia": _num([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]])}
    inertial = [els[c] for c in el.children if els[c].tag == "inertial"]
    if not inertial:
        text = "<inertial " + " ".join(f'{k}="{v}"' for k, v in attrs.items()) + "/>"
        return [insert_first_child(data, el, text)], True
    edits = [set_attribute(data, inertial[0], k, v) for k, v in attrs.items()]
    edits += [e for k in INERTIAL_REPLACED
              if (e := remove_attribute(data, inertial[0], k)) is not None]
    return edits, False


def _written_inertias(model: "RobotModel", params: np.ndarray, mj: Any, reduced: pin.Model
                      ) -> dict[int, pin.Inertia]:
    """MuJoCo body id → the inertial to write (its body frame), per moving consistid body."""
    import mujoco

    out = {}
    ids = {body_label(mj, b): b for b in range(1, mj.nbody)}    # unnamed ones too
    for i, (name, total) in enumerate(zip(model.body_names,
                                          writable_bodies(params, model.body_names))):
        jid = reduced.getJointId(model.joint_names[i])
        own = int(mj.jnt_bodyid[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT,
                                                  model.joint_names[i])])
        rest, own_frame, kept = total, None, []
        for frame in reduced.frames:
            if frame.type != pin.FrameType.BODY or frame.parentJoint != jid:
                continue
            b = ids.get(frame.name, 0)
            if b == own:
                own_frame = frame.placement
            elif b > 0:
                kept.append(frame.name)
                rest = rest - InertialParameters.from_pinocchio(
                    frame.placement.act(body_inertia(mj, b)))
        verdict = rest.consistent(name=body_label(mj, own))
        if not verdict.ok:
            raise InconsistentParametersError(
                f"body {name!r}: after subtracting the file's inertials of the bodies merged "
                f"into it {kept}, MuJoCo body {body_label(mj, own)!r} would be inconsistent "
                f"({verdict.reason}); unlock them or identify with them moving")
        out[own] = own_frame.actInv(rest.to_pinocchio())
    return out


def _class_of(els: list[Element], el: Element) -> str:
    """The default class a body element's joint takes its values from."""
    if "class" in el.attrs:
        return el.attrs["class"]
    at = el.parent
    while at >= 0:
        if "childclass" in els[at].attrs:
            return els[at].attrs["childclass"]
        at = els[at].parent
    return "main"


def _joint_edits(data: bytes, els: list[Element], mj: Any,
                 terms: dict[str, dict[str, float]]) -> tuple[list, list[str], list[str]]:
    """Edits of the identified joint terms, the values written over a class's, and the file's
    non-zero values the identification left out."""
    import mujoco

    check_nonnegative(terms, MJCF_ATTRIBUTES, "an MJCF joint")
    joints = {e.attrs.get("name"): e for e in _in_bodies(els, "joint")}
    edits, inherited, untouched = [], [], []
    for joint, values in terms.items():
        el = joints.get(joint)
        if el is None:
            raise ModelError(f"joint {joint!r} is not a <joint> of a body in the file")
        dof = int(mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, joint)])
        for suffix, attr in MJCF_ATTRIBUTES.items():
            value = values.get(suffix)
            before = float(getattr(mj, f"dof_{attr}")[dof])
            if value is None:
                if before:
                    untouched.append(f"{joint}.{attr}={before:.4g}")
                continue
            if attr not in el.attrs and before:
                inherited.append(f"{joint}.{attr} (class {_class_of(els, el)!r}: {before:.4g})")
            edits.append(set_attribute(data, el, attr, repr(float(value))))
    return edits, inherited, untouched


def write_mjcf_into(model: "RobotModel", path: str | Path, source: str | Path,
                    parameters: np.ndarray | None = None,
                    parameter_names: Sequence[str] | None = None, *,
                    absolute_assets: bool = False) -> Path:
    """Write ``source`` (an MJCF) to ``path`` carrying ``parameters`` (module docstring).

    Parameters
    ----------
    model : the robot identified (its joints and locked joints name the MJCF's).
    path : the output file (never the source).
    source : the user's MJCF whose bodies and joints carry the model's names.
    parameters : (10·nbodies [+ k],) standard parameters then per-joint terms named by
        ``parameter_names`` (``"<joint>.fv"``, ``".fc"``, ``".Ia"``; offsets and position terms
        have no MJCF attribute and are listed by an :class:`ExportWarning`).
    absolute_assets : for an output outside the source's folder: name the source's mesh and
        texture folders by absolute path in the copy's ``<compiler>`` (module docstring);
        without it such an output is refused when the file names assets by relative path.

    Raises
    ------
    InconsistentParametersError : a body (or its part written on its MuJoCo body) is not
        physically consistent, or a written term is negative (names it).
    ModelError : the output is a source, the file includes others, uses
        ``inertiafromgeom="true"``, does not hold the model's joints, or does not read back.
    """
    source, out = Path(source), Path(path)
    text = check_safe_xml(source)
    data = text.encode("utf-8")
    els = elements(data)
    _check_source(model, source, out, els, absolute_assets)
    params, terms = export_parameters(model, parameters, parameter_names)
    mj = compile_mjcf(source)
    reduced, _, _ = read_mjcf(source, model.locked_joints, model.locked_configuration)
    if list(reduced.names)[1:] != model.joint_names:
        raise ModelError(f"{source.name} has the moving joints {list(reduced.names)[1:]} (with "
                         f"locked {list(model.locked_joints)}), not {model.joint_names}")
    bodies = _mjcf_bodies(mj, els, source.name)
    edits, inserted = [], []
    for b, value in _written_inertias(model, params, mj, reduced).items():
        more, new = _body_edits(data, bodies[b], els, value)
        edits += more
        inserted += [body_label(mj, b)] if new else []
    more, inherited, untouched = _joint_edits(data, els, mj, terms)
    if absolute_assets and out.resolve().parent != source.resolve().parent:
        more += _asset_folder_edits(data, els, source)
    with replacing(out) as tmp:          # moved onto out only once it reads back as written
        tmp.write_bytes(apply(data, edits + more))
        _check_written(tmp, out, model, params, terms)
    _warn(inserted, inherited, untouched, terms)         # what was written, once it was
    return out


def _warn(inserted: list[str], inherited: list[str], untouched: list[str],
          terms: dict[str, dict[str, float]]) -> None:
    dropped = [f"{j}.{t}={v:.4g}" for j, vs in terms.items() for t, v in vs.items()
               if t not in MJCF_ATTRIBUTES and v]
    notes = []
    if inserted:
        notes.append(f"bodies {inserted} had no <inertial> (MuJoCo derived theirs from the "
                     "geoms): an explicit <inertial> is inserted")
    if inherited:
        notes.append(f"values inherited from <default> classes are written on the joint "
                     f"(overriding the class for it only): {', '.join(inherited)}")
    if untouched:
        notes.append(f"the file's {', '.join(untouched)} are kept, but the identified model has "
                     "no such term (identify with friction=/armature= to estimate them)")
    if dropped:
        notes.append(f"MJCF has no attribute for torque offsets or position terms; not "
                     f"written: {', '.join(dropped)}")
    for note in notes:
        warnings.warn(note, ExportWarning, stacklevel=3)


def _check_written(tmp: Path, out: Path, model: "RobotModel", params: np.ndarray,
                   terms: dict[str, dict[str, float]]) -> None:
    """The edited file ``tmp`` (beside ``out``) compiled and read back by MuJoCo; ModelError
    unless every body and joint term reads back as written."""
    try:
        back, _, _ = read_mjcf(tmp, model.locked_joints, model.locked_configuration)
    except ModelError as exc:
        raise ModelError(f"{out.name} not written: the edited file does not compile "
                         f"({exc})") from exc
    _compare(back, model, params, terms)


def _compare(back: pin.Model, model: "RobotModel", params: np.ndarray,
             terms: dict[str, dict[str, float]]) -> None:
    for i, name in enumerate(model.body_names):
        want = params[body_slice(i)]
        got = back.inertias[i + 1].toDynamicParameters()
        if not np.allclose(got, want, rtol=READBACK_RTOL,
                           atol=READBACK_RTOL * np.abs(want).max()):
            raise ModelError(f"body {name!r}: MuJoCo compiled the written file to the inertial "
                             f"{np.round(got, 6).tolist()}, not {np.round(want, 6).tolist()} "
                             "(compiler boundmass/boundinertia/balanceinertia?); not written")
    for joint, values in terms.items():
        k = back.getJointId(joint) - 1
        for suffix, field in (("fv", "damping"), ("fc", "friction"), ("Ia", "armature")):
            if suffix in values and not np.isclose(getattr(back, field)[k], values[suffix],
                                                   rtol=READBACK_RTOL, atol=1e-300):
                raise ModelError(f"joint {joint!r}: the written file compiles to {field} "
                                 f"{getattr(back, field)[k]:.6g}, not {values[suffix]:.6g}; "
                                 "not written")
