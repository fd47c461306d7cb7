r"""Measurements of a robot frame for kinematic calibration: validation, weights, residuals.

Three kinds, chosen by the array's shape:

``(N, 3)`` positions
    the frame's origin in the measurement system (laser tracker, camera, CMM), m;
``(N, 7)`` or ``(N, 4, 4)`` poses
    position and orientation: ``x, y, z, qx, qy, qz, qw`` (Pinocchio's ``SE3ToXYZQUAT`` order)
    or homogeneous matrices;
``(N,)`` distances
    from a fixed anchor point (ball-bar pivot, tracker station), m.

Residuals are *predicted minus measured*: ``p̂ − p`` for positions, ``log(R_measᵀ R̂)`` (rad, in
the measured frame's axes) for orientations, ``d̂ − d`` for distances. Each measurement's
residual ``r_i`` is weighted by the inverse of its covariance ``Σ_i`` (Fisher weighting: with
``Σ_i = L_i L_iᵀ`` the solver sees ``L_i⁻¹ r_i``, Gauss–Markov; the same weighting as the inertial
WLS/SDP), so ``Σ_i`` is the covariance of the measurement noise: ``σ² I`` for an isotropic
tracker, a full 3×3 for one that measures range better than bearing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from ..errors import DatasetError, JointCountError, OptionError
from ..robot.model import RobotModel

COMPONENTS = {"position": ("x", "y", "z"), "pose": ("x", "y", "z", "rx", "ry", "rz"),
              "distance": ("d",)}


@dataclass(frozen=True, eq=False)
class Measurements:
    """Validated measurements.

    Attributes
    ----------
    kind : ``"position"``, ``"pose"`` or ``"distance"``.
    positions : (N, 3) or None.
    rotations : (N, 3, 3) or None (poses only).
    distances : (N,) or None.
    """

    kind: str
    positions: np.ndarray | None = None
    rotations: np.ndarray | None = None
    distances: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int((self.distances if self.kind == "distance" else self.positions).shape[0])

    @property
    def width(self) -> int:
        """Residuals per measurement (3, 6 or 1)."""
        return len(COMPONENTS[self.kind])

    def subset(self, rows: np.ndarray) -> "Measurements":
        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[rows]

        return Measurements(self.kind, pick(self.positions), pick(self.rotations),
                            pick(self.distances))


def as_measurements(values: object, n: int | None = None) -> Measurements:
    """:class:`Measurements` from an array (module docstring for the shapes).

    Raises :class:`DatasetError` naming the index for a wrong shape, a NaN, a rotation that is
    not one, or a count that differs from ``n`` (the number of joint configurations).
    """
    if isinstance(values, Measurements):
        m = values
    else:
        try:
            a = np.asarray(values, dtype=float)
        except (TypeError, ValueError) as exc:
            raise DatasetError(f"measurements must be a numeric array, got "
                               f"{type(values).__name__}") from exc
        shapes = ("(N, 3) positions, (N, 7) poses (x, y, z, qx, qy, qz, qw), (N, 4, 4) "
                  "homogeneous poses or (N,) distances")
        if a.ndim == 1:
            kind = "distance"
        elif a.ndim == 2 and a.shape[1] in (3, 7):
            kind = "position" if a.shape[1] == 3 else "pose"
        elif a.ndim == 3 and a.shape[1:] == (4, 4):
            kind = "pose"
        else:
            raise DatasetError(f"measurements have shape {a.shape}; give {shapes}")
        if a.shape[0] == 0:
            raise DatasetError("measurements are empty (0 rows); give one measurement per "
                               "joint configuration")
        flat = a.reshape(a.shape[0], -1) if a.ndim > 1 else a[:, None]
        bad = np.argwhere(~np.isfinite(flat))
        if bad.size:
            i, c = bad[0]
            where = f"[{i}, {c}]" if a.ndim > 1 else f"[{i}]"
            raise DatasetError(f"measurements{where} is {float(flat[i, c])} ({len(bad)} non-finite "
                               "entries): drop or re-measure those poses")
        if kind == "distance":
            if np.any(a < 0):
                i = int(np.flatnonzero(a < 0)[0])
                raise DatasetError(f"measurements[{i}] = {a[i]!r} is a negative distance")
            m = Measurements(kind, distances=a)
        elif kind == "position":
            m = Measurements(kind, positions=a)
        elif a.ndim == 2:
            quat = a[:, 3:]
            norm = np.linalg.norm(quat, axis=1)
            bad = np.flatnonzero(np.abs(norm - 1) > 1e-3)
            if bad.size:
                i = int(bad[0])
                raise DatasetError(f"measurements[{i}, 3:7] is a quaternion of norm "
                                   f"{norm[i]:.6g}, not a unit one (x, y, z, qx, qy, qz, qw)")
            rot = np.array([pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
                            for x, y, z, w in quat])
            m = Measurements(kind, positions=a[:, :3].copy(), rotations=rot)
        else:
            rot = a[:, :3, :3]
            err = np.abs(np.einsum("nji,njk->nik", rot, rot) - np.eye(3)).max(axis=(1, 2))
            last = np.abs(a[:, 3] - [0, 0, 0, 1]).max(axis=1)
            bad = np.flatnonzero((err > 1e-6) | (last > 1e-9) | (np.linalg.det(rot) < 0))
            if bad.size:
                i = int(bad[0])
                raise DatasetError(f"measurements[{i}] is not a homogeneous pose (rotation "
                                   f"error {err[i]:.2g}, last row {a[i, 3].tolist()})")
            m = Measurements(kind, positions=a[:, :3, 3].copy(), rotations=rot.copy())
    if n is not None and m.n != n:
        raise DatasetError(f"{m.n} measurements for {n} joint configurations (q): one "
                           "measurement per configuration")
    return m


def check_within_limits(model: RobotModel, q: np.ndarray, slack: float = 0.1) -> None:
    """Refuse joint angles beyond the URDF's limits by more than ``slack`` rad: the usual cause
    is degrees given for radians, and the fit would otherwise fail to converge or, worse,
    converge to corrections of whole turns."""
    lim = model.limits
    out = (q < lim.lower - slack) | (q > lim.upper + slack)
    if out.any():
        k, j = (int(i) for i in np.argwhere(out)[0])
        hint = (" (they look like degrees: q is in radians, np.radians(q))"
                if np.abs(q).max() > 2 * np.pi + slack else "")
        raise DatasetError(
            f"q[{k}, {model.joint_names[j]!r}] = {q[k, j]:.4g} rad lies outside the joint's "
            f"limits [{lim.lower[j]:.4g}, {lim.upper[j]:.4g}] rad ({int(out.sum())} entries "
            f"outside){hint}")


def joint_coordinates(model: RobotModel, q: object) -> np.ndarray:
    """``q`` as (N, nv) angles, validated: :class:`JointCountError` for a wrong width,
    :class:`DatasetError` naming ``q[i, 'joint']`` for a non-finite entry. A model with
    continuous joints also accepts Pinocchio's (N, nq) configurations (cos θ, sin θ)."""
    try:
        a = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"q must be a numeric (N, {model.nv}) array") from exc
    if a.ndim != 2:
        raise DatasetError(f"q has shape {a.shape}; expected (N, {model.nv}) joint coordinates")
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        i, j = bad[0]
        label = model.joint_names[j] if a.shape[1] == model.nv else str(j)
        raise DatasetError(f"q[{i}, {label!r}] is {float(a[i, j])} ({len(bad)} non-finite "
                           "entries)")
    pm = model.pin_model
    if a.shape[1] == model.nv:
        check_within_limits(model, a)
        return a
    if a.shape[1] == pm.nq:
        out = np.empty((a.shape[0], model.nv))
        for j in range(1, pm.njoints):
            jm = pm.joints[j]
            out[:, jm.idx_v] = (a[:, jm.idx_q] if jm.nq == 1
                                else np.arctan2(a[:, jm.idx_q + 1], a[:, jm.idx_q]))
        return out
    raise JointCountError(f"q has {a.shape[1]} columns but {model.name} has {model.nv} joints "
                          f"({', '.join(model.joint_names)})")


def noise_covariance(kind: str, sigma: object, n: int) -> np.ndarray | None:
    """Per-measurement covariances ``(N, m, m)`` from ``sigma``, or None (to be estimated).

    ``sigma`` may be a number (position or distance σ, m), for poses a pair
    ``(σ_position m, σ_orientation rad)``, ``m`` per-component σ, an ``(m, m)`` covariance for
    all, or ``(N, m, m)`` covariances per measurement. Raises :class:`OptionError` naming the
    entry that is not positive (definite) or finite.
    """
    if sigma is None:
        return None
    w = len(COMPONENTS[kind])
    try:
        s = np.asarray(sigma, dtype=float)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"sigma must be numbers, got {sigma!r:.80}") from exc
    if s.ndim == 0 or (kind == "pose" and s.shape == (2,)) or s.shape == (w,):
        if s.ndim == 0 and kind == "pose":
            raise OptionError("sigma for poses is (σ_position m, σ_orientation rad), e.g. "
                              "(1e-4, 1e-3); one number would mix metres and radians")
        std = (np.repeat(s, 3) if s.shape == (2,) else np.broadcast_to(s, (w,)))
        if not np.all(np.isfinite(std)) or np.any(std <= 0):
            raise OptionError(f"sigma must be finite and > 0, got {sigma!r}")
        cov = np.diag(std ** 2)
        return np.broadcast_to(cov, (n, w, w)).copy()
    if s.shape == (w, w):
        s = np.broadcast_to(s, (n, w, w))
    if s.shape != (n, w, w):
        raise OptionError(f"sigma has shape {s.shape}; for {kind} measurements give a number"
                          f"{' pair (σ_position, σ_orientation)' if kind == 'pose' else ''}, "
                          f"({w},) per-component σ, a ({w}, {w}) covariance or ({n}, {w}, {w}) "
                          "covariances")
    for i in range(n):
        c = s[i]
        if not np.all(np.isfinite(c)) or not np.allclose(c, c.T, rtol=1e-9, atol=0) \
                or np.linalg.eigvalsh(c)[0] <= 0:
            raise OptionError(f"sigma[{i}] is not a finite symmetric positive definite "
                              "covariance")
    return np.array(s, dtype=float)


def whitening(cov: np.ndarray) -> np.ndarray:
    """``L_i⁻¹`` for ``Σ_i = L_i L_iᵀ``, shape (N, m, m)."""
    return np.linalg.inv(np.linalg.cholesky(cov))


def kabsch(model_points: np.ndarray, measured: np.ndarray) -> pin.SE3:
    """The rigid transform ``T`` minimising ``Σ‖T p_i − y_i‖²`` (Kabsch 1976,
    doi:10.1107/S0567739476001873): the initial measurement frame."""
    a, b = model_points.mean(axis=0), measured.mean(axis=0)
    h = (model_points - a).T @ (measured - b)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return pin.SE3(rot, b - rot @ a)


def trilaterate(points: np.ndarray, distances: np.ndarray) -> np.ndarray:
    """The point ``a`` with ``‖p_i − a‖ ≈ d_i``, linear least squares on
    ``‖p‖² − 2pᵀa + ‖a‖² = d²`` (unknowns ``a`` and ``‖a‖²``): the initial anchor."""
    lhs = np.column_stack([-2 * points, np.ones(len(points))])
    rhs = distances ** 2 - np.sum(points ** 2, axis=1)
    return np.linalg.lstsq(lhs, rhs, rcond=None)[0][:3]


def residuals(meas: Measurements, positions: np.ndarray, rotations: np.ndarray,
              base: pin.SE3, anchor: np.ndarray | None) -> np.ndarray:
    """Predicted minus measured, (N, m) (module docstring)."""
    p = positions @ base.rotation.T + base.translation
    if meas.kind == "distance":
        return (np.linalg.norm(positions - anchor, axis=1) - meas.distances)[:, None]
    if meas.kind == "position":
        return p - meas.positions
    rot = np.einsum("ij,njk->nik", base.rotation, rotations)
    ang = np.array([pin.log3(rm.T @ r) for rm, r in zip(meas.rotations, rot)])
    return np.hstack([p - meas.positions, ang])


def residual_jacobian(meas: Measurements, positions: np.ndarray, rotations: np.ndarray,
                      twists: np.ndarray, base: pin.SE3, base_theta: np.ndarray,
                      anchor: np.ndarray | None) -> np.ndarray:
    """Derivative of :func:`residuals` w.r.t. every parameter (joints, tool, then base or
    anchor), shape (N, m, p); ``twists`` from
    :meth:`~consistid.kinematics.parameters.KinematicParameters.frame_kinematics`."""
    n, _, nk = twists.shape
    if meas.kind == "distance":
        d = positions - anchor
        u = d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
        jac = np.einsum("na,nak->nk", u, twists[:, :3])
        return np.concatenate([jac, -u], axis=1)[:, None, :]
    rb = base.rotation
    jr = pin.Jexp3(base_theta)
    width = 3 if meas.kind == "position" else 6
    out = np.zeros((n, width, nk + 6))
    out[:, :3, :nk] = np.einsum("ij,njk->nik", rb, twists[:, :3])
    out[:, :3, nk:nk + 3] = np.eye(3)
    for k in range(n):
        out[k, :3, nk + 3:] = -rb @ pin.skew(positions[k]) @ jr
    if meas.kind == "pose":
        for k in range(n):
            r_pred = rb @ rotations[k]
            jl = pin.Jlog3(meas.rotations[k].T @ r_pred)
            out[k, 3:, :nk] = jl @ rotations[k].T @ twists[k, 3:]
            out[k, 3:, nk + 3:] = jl @ rotations[k].T @ jr
    return out


def mahalanobis(res: np.ndarray, white: np.ndarray) -> np.ndarray:
    """``√(r_iᵀ Σ_i⁻¹ r_i)`` per measurement."""
    return np.linalg.norm(np.einsum("nij,nj->ni", white, res), axis=1)


def describe(meas: Measurements) -> str:
    return {"position": "positions", "pose": "poses", "distance": "distances"}[meas.kind]


def component_names(kind: str) -> Sequence[str]:
    return COMPONENTS[kind]
