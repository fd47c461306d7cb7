r"""Bounding shapes of a robot's bodies: minimum-volume ellipsoids around the URDF's collision
geometry, in the frames of Pinocchio's dynamic parameters.

A body of a :class:`~consistid.robot.model.RobotModel` is the link that moves with a joint plus
every
link merged into it (by fixed joints, and by the joints locked when the model was built, e.g. the
Panda's hand and fingers in its last body). Its collision points are those of the merged links'
``<collision>`` elements mapped into the body (joint) frame,

.. math::  p_{\text{body}} = {}^{B}T_{L}\; {}^{L}T_{G}\; (s \odot v),

with ``ᴮT_L`` the link's BODY-frame placement w.r.t. its parent joint (Pinocchio's
``model.frames``; :func:`pinocchio.buildReducedModel` keeps the merged links' frames, at the
locked configuration), ``ᴸT_G`` the collision ``<origin>`` (URDF roll–pitch–yaw about fixed axes)
and ``s`` a mesh's ``scale``.

The enclosing ellipsoid of minimum volume (Löwner–John) of those points is computed by
Khachiyan's barycentric coordinate ascent (L. G. Khachiyan 1996, "Rounding of polytopes in the
real number model of computation", Math. Oper. Res. 21(2):307–320,
doi:10.1287/moor.21.2.307) with the away steps of Todd & Yıldırım 2007 ("On Khachiyan's
algorithm for the computation of minimum-volume enclosing ellipsoids", Discrete Appl. Math.
155(13):1731–1744, doi:10.1016/j.dam.2007.02.013), on the vertices of the points' convex hull
(the same ellipsoid: an ellipsoid is convex). These are the bounding ellipsoids of the SDP's
``"ellipsoid"`` level (Wensing, Kim, Slotine 2017, RA-L 3(1):60–67,
doi:10.1109/LRA.2017.2729659): ``consistid.identify(..., constraints="ellipsoid",
ellipsoids="collision")``.

Geometry: ``<box>`` (its 8 corners, exact), ``<cylinder>`` (a circumscribed 64-gon prism) and
``<sphere>`` (a circumscribed polytope), both containing the primitive exactly; ``<mesh>``: STL
(binary and ASCII) and Wavefront OBJ vertices read here with numpy; other formats (COLLADA
``.dae``…) through ``coal``'s assimp loader, which Pinocchio installs. A file that cannot be
found or read, or a geometry of another kind, raises :class:`~consistid.errors.ModelError`
naming the link and file: nothing is skipped.

``package://pkg/rest`` URIs are searched in ``package_dirs`` (``dir/pkg/rest``, or ``dir/rest``
when ``dir`` is itself named ``pkg``), then example-robot-data's share folder
(``pkg = "example-robot-data"``), then the URDF's parent folders named ``pkg``; ``file://`` and
plain paths are read as given, relative ones against the URDF's folder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
import warnings
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from ..errors import (GeometryWarning, InaccurateSolutionWarning, ModelError, OptionError,
                      check_number)
from .model import RobotModel, example_robot_data_dir
from .urdf import parse_urdf


def _vector(name: str, value: object, size: int) -> np.ndarray:
    """``value`` as ``size`` finite floats, else :class:`OptionError` naming ``name``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.full(1, np.nan)
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise OptionError(f"{name} must be {size} finite numbers, got {value!r}")
    return v


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """``{p : (p − center)ᵀ shape⁻¹ (p − center) ≤ 1}`` in the body frame (m, m²)."""

    center: np.ndarray
    shape: np.ndarray

    def __post_init__(self) -> None:
        """Refuse (:class:`OptionError`) a centre that is not ``d`` finite numbers (3 for a
        body) and a shape that is not a finite, symmetric, positive definite ``d×d`` matrix (a
        degenerate ellipsoid has no volume and no inverse)."""
        try:
            d = int(np.size(self.center))
        except (TypeError, ValueError):
            d = 0
        center = _vector("Ellipsoid center", self.center, max(d, 1))
        try:
            shape = np.asarray(self.shape, dtype=float)
        except (TypeError, ValueError):
            shape = np.full(1, np.nan)
        if shape.shape != (d, d) or not np.all(np.isfinite(shape)) \
                or not np.allclose(shape, shape.T, rtol=1e-9, atol=1e-15):
            raise OptionError(f"Ellipsoid shape must be a finite symmetric {d}×{d} matrix (m²), "
                              f"got {self.shape!r}")
        lam = np.linalg.eigvalsh(shape)
        if not lam[0] > 0:
            raise OptionError(f"Ellipsoid shape must be positive definite (every semi-axis > 0); "
                              f"its smallest eigenvalue is {lam[0]:.3g} m²")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "shape", shape)

    @classmethod
    def from_semi_axes(cls, center: Sequence[float], semi_axes: Sequence[float],
                       rotation: np.ndarray | None = None) -> "Ellipsoid":
        """The ellipsoid with these semi-axes (m, each finite and > 0) along the columns of
        ``rotation`` (a 3×3 rotation matrix, default the body axes), centred at ``center``."""
        axes = _vector("Ellipsoid semi_axes", semi_axes, 3)
        bad = np.flatnonzero(~(axes > 0))
        if bad.size:
            raise OptionError(f"Ellipsoid semi_axes[{int(bad[0])}] = {axes[bad[0]]:g} must be > 0 "
                              f"(m); got {semi_axes!r}")
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)) \
                or not np.allclose(r.T @ r, np.eye(3), atol=1e-8):
            raise OptionError(f"Ellipsoid rotation must be a 3×3 rotation matrix, got {rotation!r}")
        return cls(_vector("Ellipsoid center", center, 3), r @ np.diag(np.square(axes)) @ r.T)

    def q_matrix(self) -> np.ndarray:
        inv = np.linalg.inv(self.shape)
        c = self.center
        return np.block([[-inv, (inv @ c)[:, None]], [(inv @ c)[None, :],
                                                      np.array([[1.0 - c @ inv @ c]])]])

    def contains(self, point: np.ndarray) -> bool:
        d = np.asarray(point, float) - self.center
        return bool(d @ np.linalg.solve(self.shape, d) <= 1.0 + 1e-12)


#: Khachiyan's stopping tolerance ``ε``: the answer's volume is within ``(1 + ε(d+1)/d)^{d/2}``
#: of the minimum (:func:`minimum_volume_ellipsoid`), i.e. ≲ 2·10⁻⁴ relative in 3-D, far below
#: the accuracy of collision meshes. Convergence is sublinear near the optimum: on the Panda's
#: bodies (~120 hull vertices) 10⁻⁴ takes ~0.02 s per body, 10⁻⁶ ~0.1 s.
MVEE_TOL = 1e-4
#: Sides of the polygon that circumscribes a cylinder's circle (radius overestimated by
#: ``1/cos(π/64) − 1 ≈ 0.12 %``).
CYLINDER_SIDES = 64
#: Points of the Fibonacci sphere whose hull, scaled to circumscribe it, stands for a sphere.
SPHERE_POINTS = 256


# ------------------------------------------------------------------------------------ MVEE
def minimum_volume_ellipsoid(points: np.ndarray, tol: float = MVEE_TOL,
                             max_iter: int = 100_000) -> Ellipsoid:
    r"""The minimum-volume ellipsoid enclosing ``points`` (Khachiyan, with away steps).

    With ``q_i = (x_i, 1)`` and weights ``u`` on the simplex, ``X(u) = Σ u_i q_i q_iᵀ`` and
    ``M_i = q_iᵀ X(u)⁻¹ q_i``; each step moves weight towards the point of largest ``M_i``
    (Khachiyan 1996) or away from the supporting point of smallest ``M_i`` (Todd & Yıldırım
    2007) by the exact line search

    .. math::  u \leftarrow (1 - \tau) u + \tau e_j, \qquad
               \tau = \frac{M_j - (d+1)}{(d+1)(M_j - 1)},

    until ``M_i ≤ (1+ε)(d+1)`` for all points and ``M_i ≥ (1−ε)(d+1)`` where ``u_i > 0``. The
    ellipsoid is ``c = Σ u_i x_i``, ``shape = κ d Σ_u`` with ``Σ_u = Σ u_i (x_i − c)(x_i − c)ᵀ``
    and ``κ = max_i (x_i − c)ᵀ (dΣ_u)⁻¹ (x_i − c) ≤ 1 + ε(d+1)/d``, so every point is inside.

    Certificate (weak duality): any ellipsoid ``(c_E, S)`` containing the points has
    ``tr(S⁻¹Σ_u) ≤ Σ u_i (x_i − c_E)ᵀ S⁻¹ (x_i − c_E) ≤ 1`` (the weighted mean minimises the
    weighted second moment), hence ``det(dΣ_u) ≤ det S`` (AM–GM on the eigenvalues of
    ``S⁻¹Σ_u``): the answer's volume is at most ``κ^{d/2}`` times the minimum.

    Parameters
    ----------
    points : (n, d) array, ``d ≥ 1``; the points must span ``d`` dimensions.
    tol : ``ε`` above (> 0).
    max_iter : iteration cap; reaching it warns (:class:`InaccurateSolutionWarning`, with the
        certified volume factor ``κ^{d/2}``) and returns the enclosing ellipsoid reached.

    Returns
    -------
    Ellipsoid
        ``{p : (p − center)ᵀ shape⁻¹ (p − center) ≤ 1}`` containing every point.

    Raises
    ------
    ModelError : non-finite points, fewer than ``d + 1`` of them, or a flat set (they span fewer
        than ``d`` dimensions: its minimum-volume ellipsoid is degenerate).
    """
    tol = check_number("tol", tol, 0, strict=True)
    max_iter = check_number("max_iter", max_iter, 1, integer=True)
    x = np.asarray(points, dtype=float)
    if x.ndim != 2 or x.shape[1] < 1 or not np.all(np.isfinite(x)):
        raise ModelError(f"points must be a finite (n, d) array, got shape {x.shape}")
    n, d = x.shape
    mean = x.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((x - mean) ** 2, axis=1))))
    sv = np.linalg.svd(x - mean, compute_uv=False) if n > d else np.zeros(d)
    if n <= d or spread == 0 or sv[-1] <= 1e-9 * sv[0]:
        raise ModelError(f"the {n} points span fewer than {d} dimensions: their minimum-volume "
                         "enclosing ellipsoid is degenerate")
    y = (x - mean) / spread                       # unit-RMS, centred: X(u) well conditioned
    if d > 1:
        y = y[ConvexHull(y).vertices]             # the MVEE of the hull's vertices
    n = y.shape[0]
    q = np.vstack([y.T, np.ones(n)])
    u = np.full(n, 1.0 / n)
    x_inv = np.linalg.inv((q * u) @ q.T)
    m = np.einsum("ij,ij->j", q, x_inv @ q)
    converged = False
    for _ in range(max_iter):
        j_up = int(np.argmax(m))
        j_down = int(np.argmin(np.where(u > 0, m, np.inf)))
        up, down = m[j_up] / (d + 1) - 1.0, 1.0 - m[j_down] / (d + 1)
        if max(up, down) <= tol:
            exact = np.einsum("ij,ij->j", q, np.linalg.solve((q * u) @ q.T, q))
            if np.allclose(exact, m, rtol=0.0, atol=0.1 * tol):
                converged = True
                break
            x_inv, m = np.linalg.inv((q * u) @ q.T), exact   # rank-one drift: restart exact
            continue
        j = j_up if up >= down else j_down
        tau = (m[j] - (d + 1)) / ((d + 1) * (m[j] - 1.0))
        drop = tau <= -u[j] / (1.0 - u[j])        # away step to the face: u_j leaves support
        if drop:
            tau = -u[j] / (1.0 - u[j])
        u *= 1.0 - tau
        u[j] = 0.0 if drop else u[j] + tau
        # Sherman–Morrison for X ← (1−τ)X + τ q_j q_jᵀ, and M_i with it
        v = x_inv @ q[:, j]
        w = v @ q
        denom = 1.0 - tau + tau * m[j]
        x_inv = (x_inv - (tau / denom) * np.outer(v, v)) / (1.0 - tau)
        m = (m - (tau / denom) * w ** 2) / (1.0 - tau)
    c = y.T @ u
    sigma = (y.T * u) @ y - np.outer(c, c)
    shape = d * sigma
    r = y - c
    kappa = float(np.max(np.einsum("ij,ij->i", r, np.linalg.solve(shape, r.T).T)))
    if not converged:
        warnings.warn(f"Khachiyan's algorithm stopped after max_iter={max_iter} iterations "
                      f"before tol={tol:g}: the enclosing ellipsoid's volume is within a factor "
                      f"{max(kappa, 1.0) ** (d / 2):.6g} of the minimum",
                      InaccurateSolutionWarning, stacklevel=2)
    shape *= max(kappa, 1.0)
    return Ellipsoid(mean + spread * c, spread ** 2 * shape)


def pad(ellipsoid: Ellipsoid, padding: float) -> Ellipsoid:
    """``ellipsoid`` with ``padding`` (m, ≥ 0) added to each semi-axis (same centre and axes)."""
    padding = check_number("padding", padding, 0)
    lam, vec = np.linalg.eigh(ellipsoid.shape)
    axes = np.sqrt(np.maximum(lam, 0.0)) + padding
    return Ellipsoid.from_semi_axes(ellipsoid.center, axes, vec)


def semi_axes(ellipsoid: Ellipsoid) -> np.ndarray:
    """The semi-axes (m), ascending."""
    return np.sqrt(np.maximum(np.linalg.eigvalsh(ellipsoid.shape), 0.0))


def volume(ellipsoid: Ellipsoid) -> float:
    """``4/3 π abc`` (m³)."""
    return float(4.0 / 3.0 * np.pi * np.prod(semi_axes(ellipsoid)))


# ------------------------------------------------------------------------------------ meshes
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_ASCII_VERTEX = re.compile(rf"vertex\s+({_FLOAT})\s+({_FLOAT})\s+({_FLOAT})".encode())


def read_mesh(path: str | Path) -> np.ndarray:
    """The vertices (n, 3) of a mesh file, in the file's units (distinct rows, any order).

    STL (binary: ``84 + 50·n`` bytes; else ASCII ``solid … vertex x y z``) and OBJ (``v x y z``
    lines) are read here; other formats by ``coal.MeshLoader`` (assimp). :class:`ModelError`
    names the file when it is missing, malformed, empty or of an unreadable format.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"mesh file {str(path)!r} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".stl":
        raw = path.read_bytes()
        count = int.from_bytes(raw[80:84], "little") if len(raw) >= 84 else -1
        if len(raw) == 84 + 50 * count:
            v = np.frombuffer(raw, _STL_RECORD, count, 84)["vertices"].reshape(-1, 3)
        elif raw.lstrip().startswith(b"solid"):
            v = np.array(_ASCII_VERTEX.findall(raw), dtype=float).reshape(-1, 3)
        else:
            raise ModelError(f"{str(path)!r} is neither a binary STL ({len(raw)} bytes, header "
                             f"says {count} triangles) nor an ASCII one (no 'solid')")
    elif suffix == ".obj":
        rows = [line.split()[1:4] for line in path.read_text(errors="replace").splitlines()
                if line.startswith("v ")]
        try:
            v = np.array(rows, dtype=float).reshape(-1, 3)
        except ValueError as exc:
            raise ModelError(f"{str(path)!r}: malformed OBJ vertex line ({exc})") from exc
    else:
        v = _read_with_coal(path)
    v = np.asarray(v, dtype=float)
    if v.size == 0 or not np.all(np.isfinite(v)):
        raise ModelError(f"mesh file {str(path)!r} has no (finite) vertices")
    return np.unique(v, axis=0)


def _read_with_coal(path: Path) -> np.ndarray:
    try:
        import coal
    except ImportError as exc:
        raise ModelError(f"cannot read {str(path)!r}: consistid reads STL and OBJ itself and "
                         f"other formats ({path.suffix}) through coal, which is not installed"
                         ) from exc
    try:
        mesh = coal.MeshLoader().load(str(path), np.ones(3))
        return np.array(mesh.vertices(), dtype=float)
    except Exception as exc:  # coal/assimp raise plain RuntimeError / ValueError
        raise ModelError(f"cannot read mesh {str(path)!r} (format {path.suffix or '?'}): "
                         f"{exc}") from exc


# ------------------------------------------------------------------------------------ URDF
def resolve_mesh_path(uri: str, urdf: Path, package_dirs: Iterable[str | Path] = ()) -> Path:
    """The file a URDF ``<mesh filename>`` names (module docstring); :class:`ModelError` lists
    the places searched when none exists."""
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        candidates = []
        for root in map(Path, package_dirs):
            candidates.append(root / package / rest)
            if root.name == package:
                candidates.append(root / rest)
        if package == "example-robot-data":
            try:
                candidates.append(example_robot_data_dir().parent / rest)
            except ModelError:
                pass  # not installed: the error below lists what was searched
        candidates += [parent / rest for parent in urdf.resolve().parents
                       if parent.name == package]
    else:
        path = Path(uri[len("file://"):] if uri.startswith("file://") else uri)
        candidates = [path if path.is_absolute() else urdf.parent / path]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(c) for c in candidates) or "nowhere (no package_dirs)"
    raise ModelError(f"mesh {uri!r} not found (searched {searched}); pass package_dirs=[...] "
                     "with the folder that contains the package")


def _floats(element, attr: str, default: str, count: int, where: str) -> np.ndarray:
    text = element.get(attr, default) if element is not None else default
    try:
        values = np.array(text.split(), dtype=float)
    except ValueError:
        values = np.array([])
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise ModelError(f"{where}: {attr}={text!r} must be {count} finite numbers")
    return values


def _sphere_points() -> np.ndarray:
    """Unit-sphere Fibonacci points scaled so that their hull contains the unit sphere (each
    hull face at distance ≥ 1 from the centre)."""
    k = np.arange(SPHERE_POINTS) + 0.5
    z = 1.0 - 2.0 * k / SPHERE_POINTS
    phi = np.pi * (1.0 + 5 ** 0.5) * k
    rho = np.sqrt(1.0 - z ** 2)
    p = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
    return p / np.min(-ConvexHull(p).equations[:, 3])


def geometry_points(geometry, link: str, urdf: Path,
                    package_dirs: Sequence[str | Path] = ()) -> np.ndarray:
    """Points (n, 3), in the collision element's frame, whose convex hull contains one URDF
    ``<geometry>`` (box, cylinder, sphere exactly; a mesh's vertices, scaled)."""
    where = f"link {link!r} <collision>"
    shapes = [child for child in geometry] if geometry is not None else []
    if len(shapes) != 1:
        raise ModelError(f"{where}: <geometry> must hold exactly one shape, found "
                         f"{[s.tag for s in shapes]}")
    shape = shapes[0]
    if shape.tag == "box":
        half = _floats(shape, "size", "", 3, f"{where} <box>") / 2.0
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
        return corners * half
    if shape.tag == "cylinder":
        radius = _floats(shape, "radius", "", 1, f"{where} <cylinder>")[0]
        length = _floats(shape, "length", "", 1, f"{where} <cylinder>")[0]
        angle = 2.0 * np.pi * np.arange(CYLINDER_SIDES) / CYLINDER_SIDES
        ring = radius / np.cos(np.pi / CYLINDER_SIDES) * np.column_stack([np.cos(angle),
                                                                           np.sin(angle)])
        return np.vstack([np.column_stack([ring, np.full(CYLINDER_SIDES, h)])
                          for h in (-length / 2.0, length / 2.0)])
    if shape.tag == "sphere":
        return _floats(shape, "radius", "", 1, f"{where} <sphere>")[0] * _sphere_points()
    if shape.tag == "mesh":
        uri = shape.get("filename")
        if not uri:
            raise ModelError(f"{where}: <mesh> has no filename")
        try:
            path = resolve_mesh_path(uri, urdf, package_dirs)
        except ModelError as exc:
            raise ModelError(f"{where}: {exc}") from exc
        scale = _floats(shape, "scale", "1 1 1", 3, f"{where} <mesh>")
        return read_mesh(path) * scale
    raise ModelError(f"{where}: geometry <{shape.tag}> is not supported (box, cylinder, sphere, "
                     "mesh)")


def collision_points(model: RobotModel, package_dirs: Sequence[str | Path] | None = None
                     ) -> dict[str, np.ndarray]:
    """Every body's collision points (n, 3) in its body (joint) frame (module docstring), by
    body name; bodies without ``<collision>`` geometry are absent. Links fixed to the base
    (not part of any moving body) are not read.

    Raises
    ------
    ModelError : the model has no source URDF, a link has no frame in the model, or a geometry
        cannot be read (named).
    """
    if model.source is None:
        raise ModelError(f"{model.name}: no source URDF to read collision geometry from")
    if model.source_format == "mjcf":
        raise ModelError(f"{model.name}: collision ellipsoids are read from a URDF's <collision> "
                         f"elements; {Path(model.source).name} is an MJCF (pass ellipsoids= "
                         "explicitly, or use constraints='pseudo-inertia')")
    urdf = model.source
    dirs = list(package_dirs or ())
    pm = model.pin_model
    points: dict[str, list[np.ndarray]] = {}
    for link in parse_urdf(urdf).getroot().iter("link"):
        collisions = link.findall("collision")
        name = link.get("name", "?")
        if not collisions:
            continue
        if not pm.existFrame(name, pin.FrameType.BODY):
            raise ModelError(f"link {name!r} of {urdf.name} has no frame in {model.name}")
        frame = pm.frames[pm.getFrameId(name, pin.FrameType.BODY)]
        if frame.parentJoint == 0:
            continue
        body = model.body_names[frame.parentJoint - 1]
        for element in collisions:
            where = f"link {name!r} <collision>"
            origin = element.find("origin")
            rotation = pin.rpy.rpyToMatrix(*_floats(origin, "rpy", "0 0 0", 3, where))
            offset = _floats(origin, "xyz", "0 0 0", 3, where)
            local = geometry_points(element.find("geometry"), name, urdf, dirs)
            in_link = local @ rotation.T + offset
            placement = frame.placement
            points.setdefault(body, []).append(in_link @ placement.rotation.T
                                               + placement.translation)
    return {b: np.vstack(points[b]) for b in model.body_names if b in points}


def collision_ellipsoids(model: RobotModel, package_dirs: Sequence[str | Path] | None = None,
                         padding: float = 0.0, tol: float = MVEE_TOL) -> dict[str, Ellipsoid]:
    r"""The minimum-volume ellipsoid around each body's collision geometry, in its body frame.

    Parameters
    ----------
    model : a model read from a URDF (``model.source``).
    package_dirs : folders searched for ``package://`` meshes (module docstring).
    padding : metres added to every semi-axis (≥ 0), e.g. for geometry simplified inwards.
    tol : Khachiyan's tolerance (:func:`minimum_volume_ellipsoid`).

    Returns
    -------
    dict
        ``{body: Ellipsoid}`` for the bodies that have collision geometry, in
        ``model.body_names`` order. Bodies without any are left out, with a
        :class:`~consistid.errors.GeometryWarning` naming them, so that callers give them
        another level (``ellipsoids="collision"`` in the SDP gives them ``"pseudo-inertia"``).

    Raises
    ------
    ModelError : as :func:`collision_points`, or a body whose geometry is flat (it spans fewer
        than 3 dimensions).
    """
    padding = check_number("padding", padding, 0)
    out = {}
    for body, pts in collision_points(model, package_dirs).items():
        try:
            ellipsoid = minimum_volume_ellipsoid(pts, tol)
        except ModelError as exc:
            raise ModelError(f"body {body!r}: its collision geometry: {exc}") from exc
        out[body] = pad(ellipsoid, padding) if padding > 0 else ellipsoid
    missing = [b for b in model.body_names if b not in out]
    if missing:
        warnings.warn(f"{model.name}: bodies {missing} have no <collision> geometry, so no "
                      "bounding ellipsoid", GeometryWarning, stacklevel=2)
    return out
