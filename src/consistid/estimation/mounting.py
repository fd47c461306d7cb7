r"""The robot's mounting: the direction of gravity in its base frame, estimated from torques.

A URDF states gravity as ``g₀ = (0, 0, −9.81)`` in the base frame; a robot bolted to a table or a
box that is off level by a degree sees ``g = R g₀`` instead. The joint torques are linear in the
base acceleration ``−g`` (Pinocchio's regressor takes it as the root's spatial acceleration), so

.. math::  Y(q, \dot q, \ddot q;\, g) = Y(q, \dot q, \ddot q;\, 0) + \textstyle\sum_{k=1}^{3} g_k\,
           Y(q, 0, 0;\, e_k)

exactly, and the torque model ``τ = Y(g) θ`` is bilinear in ``(g, θ)``. For fixed ``g`` the best
``θ`` is a least-squares solve, so the tilt is found by minimising the *profile* residual
(variable projection: G. H. Golub, V. Pereyra, "The differentiation of pseudo-inverses and
nonlinear least squares problems whose variables separate", SIAM J. Numer. Anal. 10(2),
413–432, 1973)

.. math::  \hat a = \arg\min_a \min_\theta \lVert Y(g(a))\,\theta - \tau \rVert^2,
           \qquad g(a) = R_v(a_2)\, R_u(a_1)\, g_0,

over two angles ``a`` (rad) about two axes ``u, v`` orthogonal to ``g₀`` (:func:`tilt_axes`:
the base ``x`` and ``y`` axes when ``g₀`` points along ``−z``: roll, then pitch), ``|g|``
fixed. The data enter once: per joint, the R factor of
``[Y(0) | Y_g,x | Y_g,y | Y_g,z | τ]`` (the compression of
:mod:`consistid.identification.compression`), so every
evaluation of the profile costs a small dense solve whatever the number of samples.

The least squares frees every parameter combination the *level* model identifies (its base
parameters); the combinations only a tilt makes identifiable stay at the URDF's values. On an
arm whose first axis is vertical these are that first link's horizontal mass moments: a tilt
loads the first joint with their gravity torque, a sinusoid in ``q₁``. Left free, they would
give the fit at any tilt, however small, a free once-per-revolution torque on that joint that
the level fit lacks, so the profile would jump at zero and pull the estimate off a level base
(a level simulated Panda: 4 σ in one of 20 runs; held at the URDF's, error/σ has an RMS of
0.9 over the 20). Its covariance is the sandwich ``G⁻¹ (Σ_j τ_j v_j G_j) G⁻¹`` with ``G_j =
J_jᵀJ_j``
joint ``j``'s Gauss–Newton matrix (``J_j`` the profile residual's Jacobian in the angles, by
central differences; ``G = Σ_j G_j`` is half the profile Hessian), ``v_j`` the joint's residual
variance and ``τ_j`` its autocorrelation time
(:func:`consistid.identification.statistics.coloured_covariance`,
:func:`consistid.identification.statistics.autocorrelation_time`): filtered torque logs have
correlated
residuals, and counting their rows as independent would make the ± far too small. ``τ_j`` is
estimated from ``N`` samples and biased low when the correlation is long (``N/τ_j`` of the order
of the parameters): the ± is then optimistic (``benchmarks/mounting.py`` measures it).

What it shows on the KUKA LWR4+ logs (``benchmarks/real_kuka.py``): about 1° of tilt, which the
inertial parameters cannot imitate once two different trajectories must be fitted together.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import scipy.optimize

from ..identification.compression import CompressedProblem, accumulate, joint_sigma
from ..data.checks import check_for_identification
from ..data.dataset import Dataset, as_dataset
from ..errors import DatasetError, ModelError, OptionError, PoorExcitationWarning
from ..report.html import Page
from ..report.result import Reported
from ..threads import single_blas_thread
from ..robot.model import RobotModel, require_model
from ..identification.regressor import (DEFAULT_FRICTION, FrictionArg, RegressorSpec,
                                        prior_vector, regressor, rigid_body_regressor)
from ..identification.statistics import coloured_covariance
from ..identification.streaming import (DataStream, as_stream, is_one_pass, is_stream, merge,
                                        residual_statistics)

#: Finite-difference step (rad) for the profile residual's Jacobian.
JACOBIAN_STEP = 1e-4
#: Relative tolerance of the rank decisions in the profile least squares (column-scaled).
RCOND = 1e-10
#: A direction of the tilt whose profile curvature is below this fraction of the largest is one
#: the data do not determine.
FLAT = 1e-6


def tilt_axes(gravity: np.ndarray) -> np.ndarray:
    """Two unit axes ``u, v`` orthogonal to ``g₀``, shape (2, 3): ``u`` the base axis most
    orthogonal to ``g₀`` (made exactly orthogonal), ``v = u × ĝ₀``. For ``g₀ ∥ −z``: ``x, y``."""
    g = np.asarray(gravity, dtype=float) / np.linalg.norm(gravity)
    e = np.eye(3)[int(np.argmin(np.abs(g)))]
    u = e - (e @ g) * g
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(u, g)])


def gravity_from_tilt(gravity: np.ndarray, angles: tuple[float, float]) -> np.ndarray:
    """``R_v(a₂) R_u(a₁) g₀``: the model's gravity ``g₀`` turned by the base's tilt ``a`` (rad)
    about the axes of :func:`tilt_axes` (for ``g₀ ∥ −z``: roll about ``x``, then pitch about
    ``y``)."""
    g0 = np.asarray(gravity, dtype=float)
    u, v = tilt_axes(g0)
    return pin.exp3(angles[1] * v) @ pin.exp3(angles[0] * u) @ g0


def _axis_name(axis: np.ndarray) -> str:
    for name, e in zip("xyz", np.eye(3)):
        for sign in ("", "-"):
            if np.allclose(axis, e if not sign else -e, atol=1e-12):
                return sign + name
    return "(" + ", ".join(f"{c:+.3f}" for c in axis) + ")"


@dataclass(frozen=True, eq=False)
class MountingEstimate(Reported):
    """The estimated gravity direction of a robot's base, and what it changes.

    Attributes
    ----------
    gravity : (3,) estimated gravity in the base frame (m/s²), ``|gravity| = |g₀|``.
    reference_gravity : (3,) the model's gravity ``g₀`` (the level mounting).
    angles : (2,) how far gravity is turned (rad) about ``axes[0]`` then ``axes[1]``:
        ``g = R_v R_u g₀`` (:func:`gravity_from_tilt`; roll about ``x`` and pitch about ``y`` for
        ``g₀ ∥ −z``). The base itself is turned the other way: a base rolled by ``+ε`` about
        ``x`` sees gravity turned by ``−ε``.
    axes : (2, 3) the tilt axes ``u, v`` (:func:`tilt_axes`).
    covariance : (2, 2) covariance of ``angles`` (rad²), widened for correlated residuals.
    autocorrelation_time : (nv,) residual autocorrelation time per joint (samples).
    relative_error : ``(URDF gravity, estimated)`` least-squares relative torque error
        ``‖Yθ̂ − τ‖/‖τ‖`` on the data the estimate was made from.
    model : the robot with the estimated gravity (:meth:`RobotModel.with_gravity`).
    """

    gravity: np.ndarray
    reference_gravity: np.ndarray
    angles: np.ndarray
    axes: np.ndarray
    covariance: np.ndarray
    autocorrelation_time: np.ndarray
    relative_error: tuple[float, float]
    model: RobotModel

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of ``angles`` (rad)."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def tilt(self) -> float:
        """Angle (rad) between the estimated gravity and the URDF's."""
        g, g0 = self.gravity, self.reference_gravity
        c = float(g @ g0) / float(np.linalg.norm(g) * np.linalg.norm(g0))
        return math.acos(max(-1.0, min(1.0, c)))

    @property
    def estimate(self) -> np.ndarray:
        """The estimated vector: ``angles`` (rad); ``std``, ``covariance``, ``conf_int`` are
        its."""
        return self.angles

    def summary(self) -> str:
        return str(self)

    def page(self) -> Page:
        """The HTML report: the tilt ± σ with 95 % intervals, gravity and the fit."""
        page = Page(f"consistid base tilt: {self.model.name}", str(self))
        lo_hi = np.degrees(self.conf_int())
        page.table(["gravity turned about", "angle [°]", "± σ [°]", "95 % interval [°]"],
                   [(_axis_name(ax), np.degrees(a), np.degrees(s), f"{lo:+.4f} … {hi:+.4f}")
                    for ax, a, s, (lo, hi) in zip(self.axes, self.angles, self.std, lo_hi)])
        before, after = self.relative_error
        page.key_values([("gravity (base frame) [m/s²]", np.array2string(self.gravity,
                                                                          precision=4)),
                         ("model's gravity [m/s²]", np.array2string(self.reference_gravity,
                                                                    precision=4)),
                         ("tilt from the model's [°]", math.degrees(self.tilt)),
                         ("relative torque error, model's gravity", f"{100 * before:.3f} %"),
                         ("relative torque error, estimated gravity", f"{100 * after:.3f} %")])
        page.table(["joint", "residual autocorrelation time [samples]"],
                   zip(self.model.joint_names, self.autocorrelation_time))
        return page

    def __str__(self) -> str:
        angles = ", ".join(f"{a:+.3f}° ± {s:.3f}° about {_axis_name(ax)}" for a, s, ax in
                           zip(np.degrees(self.angles), np.degrees(self.std), self.axes))
        before, after = self.relative_error
        return (f"base tilt: gravity turned {angles} in the base frame "
                f"({math.degrees(self.tilt):.3f}° from the model's; the base itself is turned by "
                f"the opposite angles), gravity ({', '.join(f'{v:+.4f}' for v in self.gravity)}) "
                f"m/s²; least-squares relative torque error {100 * before:.3f} % → "
                f"{100 * after:.3f} %")


def _compress(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
              chunk: int = 2048) -> np.ndarray:
    """Per-joint R factors of ``[Y(0) | Y_g,x | Y_g,y | Y_g,z | τ]`` (module docstring)."""
    tau = dataset.require_torque()
    dataset.check_joints(model.nv, model.joint_names)
    weightless = model.with_gravity(np.zeros(3))
    unit = [model.with_gravity(e) for e in np.eye(3)]
    n_in, p = model.n_inertial, model.n_inertial + spec.n_joint_columns
    width = p + 3 * n_in + 1
    factors = np.zeros((model.nv, width, width))
    for start in range(0, dataset.n_samples, chunk):
        s = slice(start, min(start + chunk, dataset.n_samples))
        q, dq, ddq = dataset.q[s], dataset.dq[s], dataset.ddq[s]
        rest = np.zeros_like(dq)
        blocks = [regressor(weightless, q, dq, ddq, spec, dq_sign=None if dataset.dq_sign is None
                            else dataset.dq_sign[s]).reshape(-1, model.nv, p)]
        blocks += [rigid_body_regressor(m, q, rest, rest) for m in unit]
        accumulate(factors, np.concatenate(blocks, axis=2), tau[s])
    return factors


def _compress_data(model: RobotModel, data: Dataset | DataStream,
                   spec: RegressorSpec) -> CompressedProblem:
    """:func:`_compress` of a dataset, or of a stream part by part (factors merged by a QR of
    the stacked factors, :func:`consistid.identification.streaming.merge`)."""
    if isinstance(data, Dataset):
        return CompressedProblem(_compress(model, data, spec), data.n_samples,
                                 np.sum(data.require_torque() ** 2, axis=0))
    out = None
    for _, part in data.parts(model):
        one = CompressedProblem(_compress(model, part, spec), part.n_samples,
                                np.sum(part.tau ** 2, axis=0))
        out = one if out is None else merge(out, one)
    if out is None:
        raise DatasetError("the data stream is empty: it yielded no Dataset or file")
    return out


def _design(factors: np.ndarray, n_in: int, p: int, gravity: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """The compressed ``(A(g), b)`` of ``‖Y(g) θ − τ‖²``: per joint ``(w, p)`` and ``(w,)``."""
    nv, width, _ = factors.shape
    a = factors[:, :, :p].copy()
    moving = factors[:, :, p:p + 3 * n_in].reshape(nv, width, 3, n_in)
    a[:, :, :n_in] += np.einsum("k,jrkc->jrc", gravity, moving)
    return a, factors[:, :, -1]


@dataclass(frozen=True, eq=False)
class _LevelSpace:
    """``θ = θ₀ + D V δ``: the parameter directions the level model identifies (``V``, an
    orthonormal basis of the column-scaled level regressor's row space, ``D`` the scaling) are
    free; the others stay at the prior ``θ₀``."""

    prior: np.ndarray
    basis: np.ndarray      # D V, (p, r)

    @classmethod
    def of(cls, factors: np.ndarray, n_in: int, p: int, gravity: np.ndarray,
           prior: np.ndarray) -> "_LevelSpace":
        a, _ = _design(factors, n_in, p, gravity)
        stacked = a.reshape(-1, p)
        scale = np.linalg.norm(stacked, axis=0)
        scale[scale == 0] = 1.0
        _, sv, vt = np.linalg.svd(stacked / scale, full_matrices=False)
        keep = sv > RCOND * sv[0]
        return cls(prior, vt[keep].T / scale[:, None])

    @property
    def rank(self) -> int:
        return int(self.basis.shape[1])


def _profile(factors: np.ndarray, n_in: int, p: int, gravity: np.ndarray, space: _LevelSpace
             ) -> tuple[np.ndarray, np.ndarray]:
    """Least squares at a given gravity over the level model's identifiable directions:
    ``(θ̂, compressed residual per joint (nv, w))``; joint ``j``'s residual sum of squares is
    ``‖residual[j]‖²``."""
    a, b = _design(factors, n_in, p, gravity)
    rest = b - a @ space.prior
    design = np.einsum("jrc,ck->jrk", a, space.basis)
    delta = np.linalg.lstsq(design.reshape(-1, space.rank), rest.reshape(-1), rcond=RCOND)[0]
    theta = space.prior + space.basis @ delta
    return theta, np.einsum("jrc,c->jr", a, theta) - b


@single_blas_thread
def estimate_mounting(model: RobotModel, dataset: Dataset | DataStream,
                      friction: FrictionArg = DEFAULT_FRICTION,
                      armature: bool = False) -> MountingEstimate:
    """Estimate the tilt of the robot's base (the direction of gravity) from measured torques.

    The samples are used as they are: a dataset's identification cut-off (parallel filtering in
    ``consistid.identify``) is not applied here, whose least squares reads the samples at the
    chain's derivative cut-off.

    Parameters
    ----------
    model : the robot; its gravity ``g₀`` is the level mounting the tilt is measured from.
    dataset : measured motion and torques (several recordings: :meth:`Dataset.concatenate`),
        or a re-readable stream of them (a list of files, a
        :class:`~consistid.identification.streaming.DataStream` on a function), read one at a
        time, twice (the second reading for the residual's autocorrelation).
        Motions that load the joints against gravity in varied poses determine the tilt; the
        estimate is least squares over the level model's parameter combinations (module
        docstring), so use the regressor columns you identify with.
    friction, armature : per-joint columns, as in :func:`consistid.identify`.

    Returns
    -------
    MountingEstimate
        The tilt, its covariance, the relative errors before/after and the tilted model. Use its
        ``.model`` for :func:`consistid.identify`.

    Raises
    ------
    ModelError when the model has no gravity; JointCountError / JointNameError / DatasetError
    for data that do not fit the model. Warns :class:`PoorExcitationWarning` when the data do
    not determine the tilt (the profile residual is flat in some direction).
    """
    g0 = require_model(model).gravity
    if is_stream(dataset):
        if is_one_pass(dataset):
            raise OptionError("estimate_mounting reads the data twice (the residual's "
                              "autocorrelation for its ±), and this stream (an iterator or "
                              "generator) can be read once: pass a list of files or "
                              "DataStream(function returning a fresh iterable)")
        dataset = as_stream(dataset)
    else:
        dataset = as_dataset(dataset)
    if isinstance(dataset, Dataset):  # magnitudes, motion, dead channels, glitches
        check_for_identification(dataset, model.joint_names,
                                 (model.limits.lower, model.limits.upper, model.limits.effort))
    if not np.any(g0):
        raise ModelError(f"{model.name} has zero gravity: there is no mounting tilt to estimate")
    spec = RegressorSpec.make(model, friction, armature)
    compressed = _compress_data(model, dataset, spec)
    factors, n_samples = compressed.factors, compressed.n_samples
    n_in, p = model.n_inertial, model.n_inertial + spec.n_joint_columns
    total = float(np.sum(compressed.tau_sum_squares))

    space = _LevelSpace.of(factors, n_in, p, g0, prior_vector(model, spec))

    def residual(a: np.ndarray) -> np.ndarray:
        return _profile(factors, n_in, p, gravity_from_tilt(g0, a), space)[1]

    def rss(a: np.ndarray) -> float:
        return float(np.sum(residual(a) ** 2))

    rss0 = rss(np.zeros(2))
    step = math.radians(1.0)
    fit = scipy.optimize.minimize(
        rss, np.zeros(2), method="Nelder-Mead",
        options={"xatol": 1e-9, "fatol": max(1e-13 * rss0, 1e-16 * total), "maxiter": 2000,
                 "initial_simplex": [[0.0, 0.0], [step, 0.0], [0.0, step]]})
    # The profile is not convex on the sphere: a robot hung from the ceiling or mounted on a
    # wall is a tilt of 90–180°, a basin a local search from the level mounting does not
    # reach. A 30° grid over the sphere (84 profile evaluations, each a small dense solve)
    # restarts the search where it beats the local optimum; on data near level the grid never
    # does, and the result is the local one unchanged.
    grid = [np.array([u, v]) for u in np.radians(np.arange(-180.0, 180.0, 30.0))
            for v in np.radians(np.arange(-90.0, 91.0, 30.0))]
    values = [rss(g) for g in grid]
    best = int(np.argmin(values))
    if values[best] < fit.fun:
        half = math.radians(15.0)
        start = grid[best]
        restart = scipy.optimize.minimize(
            rss, start, method="Nelder-Mead",
            options={"xatol": 1e-9, "fatol": max(1e-13 * rss0, 1e-16 * total),
                     "maxiter": 2000, "initial_simplex": [start, start + [half, 0.0],
                                                          start + [0.0, half]]})
        if restart.fun < fit.fun:
            fit = restart
    a = np.asarray(fit.x, dtype=float)
    a[0] = math.remainder(a[0], 2 * math.pi)      # roll in (−π, π]
    # Gauss–Newton: per joint, the profile residual's Jacobian in the compressed rows (their
    # Gram equals the samples', Q_j being fixed); Σ_j G_j is half the profile Hessian
    jac = np.stack([(residual(a + d) - residual(a - d)) / (2 * JACOBIAN_STEP)
                    for d in JACOBIAN_STEP * np.eye(2)], axis=-1)
    grams = np.einsum("jrk,jrl->jkl", jac, jac)
    eig, vec = np.linalg.eigh(grams.sum(axis=0))
    flat = eig <= FLAT * max(eig.max(), 1e-300)
    chart = [float(np.linalg.norm(gravity_from_tilt(g0, a + JACOBIAN_STEP * v)
                                  - gravity_from_tilt(g0, a - JACOBIAN_STEP * v)))
             / (2 * JACOBIAN_STEP * float(np.linalg.norm(g0))) for v in vec[:, flat].T]
    if flat.any():  # keep the model's tilt along what nothing determines (0 there)
        a = a - vec[:, flat] @ (vec[:, flat].T @ a)
    if flat.any() and max(chart) < 1e-3:
        # the angles' chart is singular (gravity along a tilt axis, a 90° mounting): turning
        # about the second axis moves no gravity, so the flat direction is the chart's, not
        # the data's; gravity itself is determined
        warnings.warn(f"the mounting tilt is {math.degrees(abs(a[0])):.4g}° about "
                      f"{_axis_name(tilt_axes(g0)[0])}: gravity lies along the second tilt "
                      "axis, where the two angles are singular (the second one turns nothing). "
                      "Gravity is determined: "
                      f"{np.array2string(gravity_from_tilt(g0, a), precision=4)} m/s² (use "
                      ".gravity or .model); the angles' ± is reported infinite",
                      PoorExcitationWarning, stacklevel=2)
    elif flat.any():  # the data cannot see a tilt in these directions: the model's is kept
        warnings.warn(f"the data do not determine the mounting tilt in {int(flat.sum())} of 2 "
                      f"directions (profile curvature {2 * eig}); the model's gravity is kept "
                      "there and its ± is infinite", PoorExcitationWarning, stacklevel=2)
    elif not fit.success:
        warnings.warn(f"mounting tilt: the optimiser did not converge ({fit.message})",
                      PoorExcitationWarning, stacklevel=2)
    gravity = gravity_from_tilt(g0, a)
    theta, res = _profile(factors, n_in, p, gravity, space)
    rss_joint = np.sum(res ** 2, axis=1)
    tilted = model.with_gravity(gravity)
    tau_corr = residual_statistics(tilted, spec, theta, dataset).autocorrelation_time()
    # sandwich over the directions the data see: G⁻¹ (Σ_j τ_j v_j G_j) G⁻¹, v_j each joint's
    # residual variance (statistics.coloured_covariance)
    seen = vec[:, ~flat]
    bread = (seen / eig[~flat]) @ seen.T
    variances = joint_sigma(rss_joint, n_samples, space.rank + 2, tau_corr) ** 2
    cov = coloured_covariance(bread, grams, np.ones(model.nv), tau_corr, variances)
    unseen = np.abs(vec[:, flat]).max(axis=1, initial=0.0) > 1e-6
    cov[unseen, :] = cov[:, unseen] = np.inf
    return MountingEstimate(gravity=gravity, reference_gravity=g0, angles=a,
                            axes=tilt_axes(g0), covariance=cov, autocorrelation_time=tau_corr,
                            relative_error=(math.sqrt(rss0 / total),
                                            math.sqrt(float(np.sum(rss_joint)) / total)),
                            model=tilted)
