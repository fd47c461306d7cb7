r"""Kinematic calibration: joint origins, axes and zero offsets from measured frame poses.

.. math::  \hat\Gamma = \arg\min_\Gamma \sum_i \rho\!\left(\| L_i^{-1}\,
           (f(q_i, \Gamma) - z_i) \|^2\right)

over the identifiable parameters :math:`\Gamma` (:mod:`.parameters`, :mod:`.identifiability`),
with ``f`` Pinocchio's forward kinematics of the corrected model (:mod:`.parameters`), ``z_i``
the measurements, ``Σ_i = L_i L_iᵀ`` their covariances (:mod:`.measurements`) and ``ρ`` a loss
(``"linear"``: least squares; ``"soft_l1"``, ``"huber"``, ``"cauchy"`` … for robustness). The
nonlinear least squares (Hollerbach & Wampler 1996, doi:10.1177/027836499601500604; the Maestro
write-up solves the same problem with IPOPT) is scipy's trust-region reflective
``least_squares`` with the analytic Jacobian. The covariance of the estimate is the Gauss–Newton
``(JᵀJ)⁻¹`` of the whitened residuals at the solution (Cramér–Rao for Gaussian noise).

Outliers (``outliers="reject"``): a measurement whose Mahalanobis distance
``d_i² = r_iᵀ Σ_i⁻¹ r_i`` exceeds the ``1 − outlier_alpha`` quantile of ``χ²_m`` (times a robust
scale ``median(d²)/median(χ²_m)`` when ``sigma`` was not given) is dropped and the problem solved
again, until none is; the result lists every dropped index and its distance.
"""

from __future__ import annotations

import time
import warnings
from typing import Iterable

import numpy as np
import pinocchio as pin
import scipy.optimize
import scipy.stats

from ..errors import (
    DataQualityWarning,
    DatasetError,
    IdentificationError,
    ModelMisfitWarning,
    OptionError,
    PoorExcitationError,
    PoorExcitationWarning,
    check_number,
    check_option,
)
from ..excitation.limits import end_effector_frame
from ..identification.solver import SolverReport
from ..robot.model import RobotModel, require_model
from .identifiability import normalised, null_directions, sequential_selection, structural_selection
from .measurements import (
    Measurements,
    as_measurements,
    joint_coordinates,
    kabsch,
    mahalanobis,
    noise_covariance,
    residual_jacobian,
    residuals,
    trilaterate,
    whitening,
)
from .parameters import KinematicParameters
from .result import CalibrationResult

LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
OUTLIERS = ("reject", "keep")
#: noise scales assumed where none is given yet (first pass of the σ estimate): m, rad
DEFAULT_SCALE = {"position": 1e-4, "orientation": 1e-3, "distance": 1e-4}
#: a kept parameter whose standard deviation given the ones before it (in the priority order)
#: exceeds this (m or rad) at the current values is held at the URDF's value in the solve: such
#: a direction is flat to within the noise over a range where the model is far from linear (e.g.
#: the last joint's zero offset seen from a point on its axis), and a trust region wanders in it
#: instead of converging; it is freed again when the solution makes it identifiable
WEAK_STD = 0.05


def _as_se3(value: object, what: str) -> pin.SE3:
    if isinstance(value, pin.SE3):
        return pin.SE3(value)
    a = np.asarray(value, dtype=float)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)) or \
            np.abs(a[:3, :3].T @ a[:3, :3] - np.eye(3)).max() > 1e-6:
        raise OptionError(f"{what} must be a 4×4 homogeneous transform (or pinocchio.SE3), got "
                          f"{value!r:.80}")
    return pin.SE3(a[:3, :3], a[:3, 3])


class _Problem:
    """The weighted residuals and Jacobian over a set of free parameter indices."""

    def __init__(self, chart: KinematicParameters, q: np.ndarray, meas: Measurements,
                 white: np.ndarray, base0: pin.SE3, anchor0: np.ndarray | None) -> None:
        self.chart, self.q, self.meas, self.white = chart, q, meas, white
        self.base0, self.anchor0 = base0, anchor0

    def split(self, values: np.ndarray) -> tuple[pin.SE3, np.ndarray, np.ndarray | None]:
        c = self.chart
        extra = values[c.n_kinematic:]
        base = c.base_transform(values, self.base0)
        theta = np.zeros(3) if c.kind == "distance" else extra[3:6]
        anchor = None if c.kind != "distance" else self.anchor0 + extra[:3]
        return base, theta, anchor

    def raw(self, values: np.ndarray, derivatives: bool = False
            ) -> tuple[np.ndarray, np.ndarray | None]:
        base, theta, anchor = self.split(values)
        pos, rot, tw = self.chart.frame_kinematics(values, self.q, derivatives)
        res = residuals(self.meas, pos, rot, base, anchor)
        jac = (residual_jacobian(self.meas, pos, rot, tw, base, theta, anchor)
               if derivatives else None)
        return res, jac

    def weighted(self, values: np.ndarray, free: np.ndarray, derivatives: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | None]:
        res, jac = self.raw(values, derivatives)
        r = np.einsum("nij,nj->ni", self.white, res).ravel()
        if jac is None:
            return r, None
        j = np.einsum("nij,njk->nik", self.white, jac[:, :, free]).reshape(r.size, free.size)
        return r, j

    def solve(self, values: np.ndarray, free: np.ndarray, loss: str, f_scale: float,
              max_nfev: int) -> tuple[np.ndarray, scipy.optimize.OptimizeResult]:
        def full(z: np.ndarray) -> np.ndarray:
            v = values.copy()
            v[free] += z
            return v

        # the unknowns are the increments from ``values``: scipy's trust region starts with the
        # radius ‖x₀‖ (scaled), which a nearly-zero start (corrections of 1e-9) would make tiny
        sol = scipy.optimize.least_squares(
            lambda z: self.weighted(full(z), free, False)[0], np.zeros(free.size),
            jac=lambda z: self.weighted(full(z), free, True)[1], method="trf", loss=loss,
            f_scale=f_scale, x_scale="jac", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12,
            gtol=1e-10)
        return full(sol.x), sol


def _conditional_std(jac: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Per column of the whitened Jacobian ``jac``, the standard deviation of that parameter
    given the columns before it in ``order`` that were not themselves too weak
    (``1 / ‖residual of the column after projection‖``; ``inf`` for a vanishing column)."""
    a, norms = normalised(jac)
    std = np.full(jac.shape[1], np.inf)
    basis = np.zeros((jac.shape[0], 0))
    for c in order:
        if norms[c] == 0:
            continue
        r = a[:, c] - basis @ (basis.T @ a[:, c])
        r -= basis @ (basis.T @ r)
        nr = np.linalg.norm(r)
        if nr * norms[c] > 0:
            std[c] = 1.0 / (nr * norms[c])
        if nr > 1e-7 and std[c] <= WEAK_STD:
            basis = np.column_stack([basis, r / nr])
    return std


def _weak(prob: _Problem, values: np.ndarray, cols: np.ndarray, order: np.ndarray
          ) -> np.ndarray:
    """Mask over ``cols`` (parameter indices, priority ``order`` over them) of the directions
    too weak at ``values`` to be solved for (:data:`WEAK_STD`)."""
    jac = prob.weighted(values, cols)[1]
    return ~(_conditional_std(jac, order) <= WEAK_STD)


def _blocks(kind: str) -> list[tuple[str, slice]]:
    if kind == "distance":
        return [("distance", slice(0, 1))]
    if kind == "position":
        return [("position", slice(0, 3))]
    return [("position", slice(0, 3)), ("orientation", slice(3, 6))]


#: Below this many residual degrees of freedom an estimated σ (``sigma=None``) is flagged.
MIN_SIGMA_DOF = 20


def _default_cov(kind: str, n: int) -> np.ndarray:
    std = np.concatenate([[DEFAULT_SCALE[b]] * (s.stop - s.start) for b, s in _blocks(kind)])
    return np.broadcast_to(np.diag(std ** 2), (n, std.size, std.size)).copy()


def _estimate_cov(kind: str, res: np.ndarray, n_free: int) -> np.ndarray:
    """Per-block noise variance from residuals, ``RSS_b / (n_b − r·n_b/n)`` (the block's share
    of the degrees of freedom)."""
    total = res.size
    std = []
    for _, s in _blocks(kind):
        block = res[:, s]
        dof = max(block.size - n_free * block.size / total, 1.0)
        std += [np.sqrt(np.sum(block ** 2) / dof)] * (s.stop - s.start)
    return np.broadcast_to(np.diag(np.square(std)), (res.shape[0], len(std), len(std))).copy()


#: An orientation error that no kinematic offset leaves after a calibration (rad, RMS): the
#: offsets a calibration corrects are milliradians; 0.1 rad is 5.7°.
ORIENTATION_MISFIT = 0.1


def _warn_orientation_misfit(residuals: np.ndarray) -> None:
    """Warn (:class:`ModelMisfitWarning`) when the calibrated orientation error (columns 3–5 of
    the pose residuals, rad) stays beyond :data:`ORIENTATION_MISFIT` RMS: the fit did not
    describe the data, and the usual cause is a unit (degrees) or a wrong measured frame."""
    if not residuals.size:
        return
    rms = float(np.sqrt(np.mean(np.sum(residuals[:, 3:6] ** 2, axis=1))))
    if rms > ORIENTATION_MISFIT:
        warnings.warn(
            f"after calibration the orientation error is still {rms:.3g} rad RMS "
            f"({np.degrees(rms):.3g}°): no kinematic offset explains that; are q or the "
            "measured orientations in degrees (give radians, unit quaternions), or is the "
            "measured frame another one than frame=? The calibrated values are not to be "
            "trusted", ModelMisfitWarning, stacklevel=3)


def _check_length_unit(chart: KinematicParameters, q: np.ndarray, positions: np.ndarray,
                       factor: float = 2.0) -> None:
    """Refuse measured positions whose spread differs from the URDF's prediction by more than
    ``factor``: a rigid change of measurement frame keeps distances between points, and
    corrections of millimetres change the spread by far less, so a ratio of ~1000 or ~0.001
    means millimetres for metres (or the reverse) rather than a robot that differs from its
    URDF. Skipped when the configurations barely move the frame (< 1 cm RMS)."""
    pos, _, _ = chart.frame_kinematics(np.zeros(chart.size), q, False)
    spread_model = float(np.sqrt(np.mean(np.sum((pos - pos.mean(axis=0)) ** 2, axis=1))))
    spread_meas = float(np.sqrt(np.mean(np.sum((positions - positions.mean(axis=0)) ** 2,
                                               axis=1))))
    if spread_model < 1e-2:
        return
    ratio = spread_meas / spread_model
    if not 1.0 / factor <= ratio <= factor:
        raise DatasetError(
            f"the measured positions spread {spread_meas:.4g} (RMS about their mean) where the "
            f"URDF predicts {spread_model:.4g} m for the same q: {ratio:.3g}× apart. A rigid "
            "measurement frame keeps distances, so the measurements are probably in another "
            "unit (give metres: mm / 1000) or belong to other joint configurations")


def _check_distance_unit(chart: KinematicParameters, q: np.ndarray, distances: np.ndarray,
                         factor: float = 2.0) -> None:
    """Refuse distances whose range exceeds what the frame can make: by the triangle
    inequality ``|d_i − d_j| ≤ ‖p_i − p_j‖`` for any anchor, so ``max d − min d`` is at most the
    largest distance between two of the frame's positions (the URDF's, to ``factor``: a
    calibration moves them by millimetres). Millimetres for metres break it a thousandfold."""
    pos, _, _ = chart.frame_kinematics(np.zeros(chart.size), q, False)
    reach = float(np.max(np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)))
    spread = float(np.ptp(distances))
    if spread > factor * reach + 1e-3:
        raise DatasetError(
            f"the measured distances range over {spread:.4g} where the frame's positions for the "
            f"same q are at most {reach:.4g} m apart: |d_i − d_j| ≤ ‖p_i − p_j‖ for any anchor, "
            "so the distances are probably in another unit (give metres: mm / 1000) or belong "
            "to other joint configurations")


def calibrate_kinematics(model: RobotModel, q: object, measurements: object,
                         frame: str | None = None,
                         parameters: str | Iterable[str] = "all", sigma: object = None, *,
                         base: object = None, anchor: object = None, loss: str = "linear",
                         f_scale: float = 1.0, outliers: str = "reject",
                         outlier_alpha: float = 1e-4, max_nfev: int = 100
                         ) -> CalibrationResult:
    """Calibrate the joint origins, axes and zero offsets of ``model`` from measured poses.

    Parameters
    ----------
    model : the nominal robot (URDF); its values are where every correction starts and where
        unidentifiable combinations stay.
    q : (N, nv) joint coordinates as the encoders read them (or (N, nq) Pinocchio
        configurations).
    measurements : (N, 3) positions, (N, 7) / (N, 4, 4) poses of ``frame`` in the measurement
        system, or (N,) distances from an anchor (:mod:`consistid.kinematics.measurements`).
    frame : the measured frame (default: the end effector,
        :func:`consistid.excitation.end_effector_frame`).
    parameters : which corrections to estimate: a keyword (``"all"``, ``"zero"``,
        ``"translation"``, ``"orientation"``, ``"origin"``, ``"axis"``, ``"joints"``, ``"tool"``,
        ``"base"``, ``"anchor"``), names or shell patterns, or a list of them
        (:mod:`consistid.kinematics.parameters`). ``["zero", "translation", "base"]``: zero
        offsets and link lengths, in an unknown tracker frame.
    sigma : measurement noise: a number (m; positions, distances), for poses
        ``(σ_position m, σ_orientation rad)``, per-component σ, an (m, m) covariance or (N, m, m)
        covariances. ``None``: estimated per block (position / orientation) from the residuals
        (two passes), and said so.
    base : initial 4×4 pose of the robot base in the measurement frame (default: the rigid
        fit of the URDF's positions to the measured ones when ``base.*`` is estimated, else
        the identity: measurements in the robot's base frame).
    anchor : initial anchor point (base frame, m) for distances (default: linear
        trilateration when ``anchor.*`` is estimated; required otherwise).
    loss, f_scale : scipy's robust loss and its scale (in units of σ), default least squares.
    outliers : ``"reject"`` (drop and re-solve, listed in the result) or ``"keep"`` (only
        flag them).
    outlier_alpha : false-rejection probability per measurement of the χ² test.
    max_nfev : function evaluations allowed per solve.

    Returns
    -------
    CalibrationResult : ``.model`` the corrected :class:`RobotModel`, ``.std``,
        ``.unidentifiable``, ``.summary()``, ``.report(path)``, ``.to_urdf(path)``.

    Raises
    ------
    DatasetError, JointCountError : measurements or ``q`` of the wrong shape, non-finite, or of
        different counts (names the index).
    ModelError : ``frame`` does not exist.
    OptionError : an unknown parameter name or option.
    PoorExcitationError : fewer measurements than identifiable combinations, or poses that do
        not identify what the measurement kind could (names the parameters lost).
    IdentificationError : the solver stopped without converging.
    """
    t_start = time.perf_counter()
    model = require_model(model)
    check_option("loss", loss, LOSSES)
    check_option("outliers", outliers, OUTLIERS)
    f_scale = check_number("f_scale", f_scale, 0.0, strict=True)
    outlier_alpha = check_number("outlier_alpha", outlier_alpha, 0.0, strict=True)
    if outlier_alpha >= 1:
        raise OptionError(f"outlier_alpha must be in (0, 1), got {outlier_alpha!r}")
    max_nfev = int(check_number("max_nfev", max_nfev, 1, integer=True))
    qa = joint_coordinates(model, q)
    if qa.shape[0] == 0:
        raise DatasetError("q is empty (0 configurations); give one row of joint angles (rad) "
                           "per measurement")
    meas = as_measurements(measurements, qa.shape[0])
    frame = end_effector_frame(model) if frame is None else frame
    chart = KinematicParameters(model, frame, meas.kind)
    if meas.kind != "distance":
        _check_length_unit(chart, qa, meas.positions)
    else:
        _check_distance_unit(chart, qa, meas.distances)
    sel = chart.select(parameters)
    names = [chart.names[i] for i in sel]
    n, m = meas.n, meas.width
    given_cov = noise_covariance(meas.kind, sigma, n)

    # --- initial measurement frame / anchor
    zero = np.zeros(chart.size)
    extra_sel = sel[sel >= chart.n_kinematic]
    base0 = pin.SE3.Identity() if base is None else _as_se3(base, "base")
    anchor0 = None
    if meas.kind == "distance":
        if anchor is not None:
            anchor0 = np.asarray(anchor, dtype=float)
            if anchor0.shape != (3,) or not np.all(np.isfinite(anchor0)):
                raise OptionError(f"anchor must be 3 finite numbers (m, base frame), got "
                                  f"{anchor!r}")
        elif extra_sel.size:
            pos, _, _ = chart.frame_kinematics(zero, qa, False)
            anchor0 = trilaterate(pos, meas.distances)
        else:
            raise OptionError("distance measurements need the anchor: anchor=(x, y, z) in the "
                              "base frame, or estimate it (parameters including 'anchor')")
    elif base is None and extra_sel.size and n >= 3:
        pos, _, _ = chart.frame_kinematics(zero, qa, False)
        base0 = kabsch(pos, meas.positions)
    base_initial = pin.SE3(base0)

    # --- which parameters the measurement kind identifies (generic configurations, at a point
    # near the URDF that moves only the selected parameters: the family of robots considered)
    order = chart.priority(sel)
    generic_values = chart.generic_point(sel)
    cov0 = given_cov if given_cov is not None else _default_cov(meas.kind, n)
    generic = chart.random_configurations
    gmeas = _generic_measurements(chart, generic, generic_values, meas.kind, base0,
                                  anchor0)
    gprob = _Problem(chart, generic, gmeas, np.broadcast_to(whitening(cov0[:1]),
                                                            (len(generic), m, m)),
                     base0, anchor0)
    kept = structural_selection(gprob.weighted(zero, sel)[1],
                                gprob.weighted(generic_values, sel)[1], order)
    r = int(kept.sum())
    if r == 0:
        raise PoorExcitationError(
            f"none of the selected parameters {names[:6]}{' …' if len(names) > 6 else ''} "
            f"changes a {meas.kind} measurement of {frame!r} (e.g. a point has no orientation): "
            "select others")
    if n * m < r:
        raise PoorExcitationError(
            f"{n} {meas.kind} measurements give {n * m} residuals, fewer than the {r} "
            f"parameter combinations they can identify ({len(sel)} selected, {len(sel) - r} "
            f"redundant): measure at least {-(-r // m)} configurations, better 3–5× that "
            "(consistid.kinematics.select_poses picks informative ones)")

    # --- do these configurations identify what the kind can?
    white = whitening(cov0)
    prob = _Problem(chart, qa, meas, white, base0, anchor0)
    _check_data_rank(prob, generic_values, sel, kept, order, names, n, meas.kind)
    free = sel[kept]

    # --- before: the URDF's kinematics, measurement frame / anchor fitted
    values = zero.copy()
    extra_free = free[free >= chart.n_kinematic]
    if extra_free.size:
        values, _ = prob.solve(values, extra_free, "linear", 1.0, max_nfev)
    before_values = values.copy()

    # --- directions (nearly) flat at the start (the URDF on a special geometry, e.g. the
    # measured point on the last joint's axis): held at the URDF's values while solving, freed
    # when the solution makes them identifiable, else reported as held
    kept_idx = np.flatnonzero(kept)
    kept_order = np.argsort(np.argsort(order)[kept_idx])
    held_now = np.zeros(len(sel), dtype=bool)
    held_now[kept_idx] = _weak(prob, values, sel[kept_idx], kept_order)
    if held_now.any():
        _check_weak_data(gprob, n, sel, kept, held_now, kept_order, names)
    free = sel[kept & ~held_now]

    # --- solve; estimate σ; reject outliers
    active = np.arange(n)
    rejected: list[int] = []
    sigma_source = "given"
    cov = cov0.copy()
    updates = 0                      # σ re-estimates since the last change of the data
    while True:
        sub = _Problem(chart, qa[active], meas.subset(active), whitening(cov[active]),
                       base0, anchor0)
        values, sol = sub.solve(values, free, loss, f_scale, max_nfev)
        if sol.status == 0:
            raise IdentificationError(_not_converged(sub, values, sol, sel, kept, order,
                                                     names))
        if sol.status < 0:
            raise IdentificationError(f"least_squares failed: {sol.message}")
        if held_now.any():
            # the held directions the solution makes identifiable are freed and solved for
            held_idx = np.flatnonzero(held_now)
            cols = np.flatnonzero(kept & ~held_now).tolist() + held_idx.tolist()
            weak = _weak(sub, values, sel[cols], np.arange(len(cols)))[-held_idx.size:]
            if not weak.all():
                held_now[held_idx[~weak]] = False
                free = sel[kept & ~held_now]
                continue
        res_active, _ = sub.raw(values)
        if given_cov is None and updates < 2:
            cov[:] = _estimate_cov(meas.kind, res_active, free.size)[0]
            sigma_source = "estimated from the residuals (per block, after the first fit)"
            updates += 1
            continue
        if outliers != "reject":
            break
        d2 = mahalanobis(res_active, whitening(cov[active])) ** 2
        limit = scipy.stats.chi2.ppf(1 - outlier_alpha, m)
        if given_cov is None:
            limit *= max(np.median(d2) / scipy.stats.chi2.median(m), 1e-300)
        elif _bulk_exceeds(d2, m, outlier_alpha):
            # most residuals, not a few, exceed the given σ (warned below): rejecting
            # against it would drop good data one by one; scale the test to the median
            limit *= np.median(d2) / scipy.stats.chi2.median(m)
        worst = int(np.argmax(d2))
        if d2[worst] <= limit:
            break
        # one at a time, the worst first (Baarda's data snooping): a blunder pulls the fit and
        # inflates its neighbours' residuals, which the next fit no longer does
        rejected.append(int(active[worst]))
        active = np.delete(active, worst)
        if active.size * m < free.size:
            raise PoorExcitationError(
                f"rejecting outliers left {active.size} measurements ({active.size * m} "
                f"residuals) for {r} identifiable combinations; the data disagree with the "
                f"model more than σ allows (rejected {sorted(rejected)})")
        updates = 1                  # one more σ estimate without the outliers

    if given_cov is not None:
        d2 = mahalanobis(res_active, whitening(cov[active])) ** 2
        if _bulk_exceeds(d2, m, outlier_alpha):
            ratio = float(np.sqrt(np.median(d2) / scipy.stats.chi2.median(m)))
            warnings.warn(
                f"the residuals of most of the {active.size} measurements exceed the given "
                f"sigma (median ≈ {ratio:.3g} × it): sigma is too small, or the model misses "
                f"an effect; every ± is about {ratio:.3g}× too small"
                f"{' and outliers were judged against the median' if outliers == 'reject' else ''}"
                "; give the tracker's real noise, or sigma=None to estimate it",
                DataQualityWarning, stacklevel=2)

    # --- uncertainty and the unidentifiable directions at the solution
    final = _Problem(chart, qa[active], meas.subset(active), whitening(cov[active]), base0,
                     anchor0)
    start_held = tuple(names[i] for i in np.flatnonzero(held_now))
    if start_held:
        kept = kept & ~held_now
        r = int(kept.sum())
    res_w, jac_w = final.weighted(values, sel, True)
    # a kept parameter the data cannot see *at the solution* (the robot sits on a special
    # geometry, e.g. the measured point exactly on the last axis): hold it there too
    kept_idx = np.flatnonzero(kept)
    here = sequential_selection(jac_w[:, kept_idx], np.argsort(np.argsort(order)[kept_idx]),
                                tol=1e-7)
    vanished = tuple(names[i] for i in kept_idx[~here])
    if vanished:
        kept = kept.copy()
        kept[kept_idx[~here]] = False
        values[sel[~kept]] = 0.0
        r = int(kept.sum())
        values, sol = final.solve(values, sel[kept], loss, f_scale, max_nfev)
        if sol.status <= 0:
            raise IdentificationError(f"least_squares did not converge after holding "
                                      f"{list(vanished)}: {sol.message}")
        res_w, jac_w = final.weighted(values, sel, True)
    jk = jac_w[:, kept]
    a, norms = normalised(jk)
    sv = np.linalg.svd(a, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
    cov_k = np.linalg.inv(jk.T @ jk)
    p = len(sel)
    covariance = np.full((p, p), np.nan)
    covariance[np.ix_(kept, kept)] = cov_k
    dof = res_w.size - r
    chi2_red = float(res_w @ res_w / dof) if dof > 0 else np.nan
    if given_cov is None and dof < MIN_SIGMA_DOF:
        # σ from the residuals with few degrees of freedom: its own relative error is about
        # 1/√(2·dof), so every ± (and χ²/dof, 1 by construction) is that uncertain
        warnings.warn(f"the measurement noise was estimated from {int(dof)} residual degrees of "
                      f"freedom only (relative error ≈ {1 / np.sqrt(2 * max(dof, 1)):.0%}): "
                      "the standard deviations are that uncertain; give sigma= or measure "
                      "more poses", PoorExcitationWarning, stacklevel=2)
    unident, null, worst = null_directions(jac_w, kept, names)

    all_q = _Problem(chart, qa, meas, whitening(cov), base0, anchor0)
    res_before, _ = all_q.raw(before_values)
    res_after, _ = all_q.raw(values)
    dist = mahalanobis(res_after, whitening(cov))
    base_final, _, anchor_final = all_q.split(values)
    if meas.kind == "pose":
        _warn_orientation_misfit(res_after[np.setdiff1d(np.arange(n), sorted(rejected))])
    corrected = chart.robot_model(values)
    solver = SolverReport(f"scipy least_squares (trf, loss={loss})",
                          f"converged ({sol.message})", time.perf_counter() - t_start,
                          iterations=int(sol.nfev))
    return CalibrationResult(
        model=corrected, nominal=model, frame=frame, kind=meas.kind,
        parameter_names=tuple(names), values=values[sel].copy(),
        std=np.sqrt(np.diag(covariance)), covariance=covariance, identified=kept.copy(),
        unidentifiable=unident, null_space=null, null_residual=worst,
        base=None if meas.kind == "distance" else base_final.homogeneous,
        base_initial=None if meas.kind == "distance" else base_initial.homogeneous,
        anchor=anchor_final, residuals_before=res_before, residuals_after=res_after,
        mahalanobis=dist, rejected=tuple(sorted(rejected)), noise_covariance=cov,
        sigma_source=sigma_source, chi2_reduced=chi2_red, condition_number=cond,
        n_measurements=n, solver=solver, chart=chart, full_values=values,
        held_at_solution=start_held + vanished)


def _not_converged(prob: _Problem, values: np.ndarray, sol: scipy.optimize.OptimizeResult,
                   sel: np.ndarray, kept: np.ndarray, order: np.ndarray, names: list[str]
                   ) -> str:
    """The message for a solve that hit ``max_nfev``: the nearly unidentifiable parameters
    when there are (more evaluations do not help there), else raise max_nfev."""
    kept_idx = np.flatnonzero(kept)
    std = _conditional_std(prob.weighted(values, sel[kept_idx])[1],
                           np.argsort(np.argsort(order)[kept_idx]))
    worst = np.argsort(-std)[:4]
    weak = [f"{names[kept_idx[i]]} (σ≈{std[i]:.2g})" for i in worst if std[i] > 0.1 * WEAK_STD]
    head = (f"least_squares stopped after {sol.nfev} evaluations without converging "
            f"({sol.message}, ‖gradient‖ = {np.abs(sol.grad).max():.2g})")
    if weak:
        return (f"{head}; the data barely see {', '.join(weak)}: the cost is nearly flat along "
                "them, so more evaluations will not help; fix them (parameters=... without "
                "them), or measure configurations that move them (select_poses)")
    return f"{head}; raise max_nfev, check the measurement frame (base=) or the frame name"


def _generic_measurements(chart: KinematicParameters, q: np.ndarray, values: np.ndarray,
                          kind: str, base0: pin.SE3, anchor0: np.ndarray | None
                          ) -> Measurements:
    """Noise-free measurements of the generic point ``values``
    (:meth:`~consistid.kinematics.parameters.KinematicParameters.generic_point`) at ``q``, where
    structural identifiability is judged (the residual is 0, so the Jacobian is the model's)."""
    pos, rot, _ = chart.frame_kinematics(values, q, False)
    if kind == "distance":
        return Measurements(kind, distances=np.linalg.norm(pos - anchor0, axis=1))
    p = pos @ base0.rotation.T + base0.translation
    if kind == "position":
        return Measurements(kind, positions=p)
    return Measurements(kind, positions=p,
                        rotations=np.einsum("ij,njk->nik", base0.rotation, rot))


def _check_data_rank(prob: _Problem, values: np.ndarray, sel: np.ndarray, kept: np.ndarray,
                     order: np.ndarray, names: list[str], n: int, kind: str) -> None:
    """:class:`PoorExcitationError` when the configurations identify fewer combinations than
    generic ones would (names the parameters they lose)."""
    jac = prob.weighted(values, sel)[1]
    kept_idx = np.flatnonzero(kept)
    data_kept = sequential_selection(jac[:, kept_idx],
                                     np.argsort(np.argsort(order)[kept_idx]), tol=1e-6)
    if data_kept.all():
        return
    lost = [names[i] for i in np.flatnonzero(kept)[~data_kept]]
    raise PoorExcitationError(
        f"the {n} configurations identify {int(data_kept.sum())} of the {int(kept.sum())} "
        f"parameter combinations that {kind} measurements can: {len(lost)} are not seen "
        f"({', '.join(lost[:8])}{' …' if len(lost) > 8 else ''}); spread the configurations "
        "over the workspace (consistid.kinematics.select_poses)")


def _check_weak_data(gprob: _Problem, n: int, sel: np.ndarray, kept: np.ndarray,
                     held: np.ndarray, kept_order: np.ndarray, names: list[str]) -> None:
    """:class:`PoorExcitationError` when a direction is too weak to solve for (σ above
    :data:`WEAK_STD`) in these configurations but not in as many generic ones at the URDF.

    Holding is meant for the URDF's own special geometry (the measured point on a joint axis),
    where every configuration is blind; held because the configurations are (nearly
    identical poses), the held parameter is a real error the identified ones absorb, and their
    σ, conditional on it being 0, would be too small by orders of magnitude. The generic
    conditional σ is scaled by ``√(N_generic / N)`` to the same number of measurements.
    """
    kept_idx = np.flatnonzero(kept)
    std = _conditional_std(gprob.weighted(np.zeros(gprob.chart.size), sel[kept_idx])[1],
                           kept_order) * np.sqrt(len(gprob.q) / n)
    lost = [names[i] for i, s in zip(kept_idx, std) if held[i] and s <= WEAK_STD]
    if lost:
        raise PoorExcitationError(
            f"the {n} configurations barely see {', '.join(lost[:8])}"
            f"{' …' if len(lost) > 8 else ''} (σ > {WEAK_STD:g} given the others), which "
            f"{n} configurations spread over the workspace would identify; spread the "
            "configurations (consistid.kinematics.select_poses) or leave these out of "
            "parameters=")


def _bulk_exceeds(d2: np.ndarray, m: int, alpha: float) -> bool:
    """Whether more squared Mahalanobis distances ``d2`` exceed the χ²(m) median than a correct
    σ allows: a sign test, each exceeding it with probability ½ (outliers, a few, only add);
    false alarm probability ``alpha``."""
    above = int(np.count_nonzero(d2 > scipy.stats.chi2.median(m)))
    return above > scipy.stats.binom.ppf(1 - alpha, d2.size, 0.5)
