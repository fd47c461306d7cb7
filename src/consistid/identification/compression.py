r"""Compression of a least-squares problem to per-joint R factors, so that solvers never see N rows.

For joint ``j`` let ``A_j = [Y_j | τ_j]`` (one row per sample, ``p + 1`` columns). Its R factor
``A_j = Q_j R̄_j`` with

.. math::  \bar R_j = \begin{bmatrix} R_j & z_j \\ 0 & \rho_j \end{bmatrix}

gives every quantity a least-squares fit needs, exactly:
``‖Y_j θ − τ_j‖² = ‖R_j θ − z_j‖² + ρ_j²``. The factors are accumulated chunk by chunk
(``R̄ ← qr([R̄; A_chunk])``), so memory is ``O(nv·p²)`` whatever the number of samples, and a
weighted problem with per-joint noise ``σ_j`` is ``qr([R̄_1/σ_1; …; R̄_nv/σ_nv])``.
This is the "compression" that makes the SDP size independent of N (Golub & Van Loan,
*Matrix Computations*, §6.5 on updating QR).

A dataset that records an identification cut-off (``Dataset.identification_filter``, set by the
signal chain) is compressed *parallel filtered*: every column of ``Y_j`` and ``τ_j`` go through
the same zero-phase low-pass per run of evenly spaced samples, in padded windows
(:mod:`consistid.data.parallel`: memory ``O(chunk + rate/f_p)``), before their rows are folded
in; with ``H`` linear, ``Hτ = (HY)θ + He``, so the fit is that of the same ``θ``. Every
quantity of the problem (``ρ_j``, ``tau_sum_squares``, row weights) is then that of the
filtered rows.

Weighting by ``1/σ_j`` needs ``σ_j > 0``: :func:`floor_sigma` floors every estimated ``σ_j`` at
:data:`SIGMA_FLOOR` times joint ``j``'s torque RMS (noise-free data fit to round-off, and would
otherwise get infinite weights). WLS, the SDP and its Huber/IRLS passes all use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from ..data.dataset import Dataset
from ..data.parallel import Window, plan
from ..errors import OptionError
from ..robot.model import RobotModel
from .base import BaseParameters
from .regressor import (RegressorSpec, check_states, column_support, default_chunk, joint_signal,
                        rigid_body_regressor)

#: Per-joint σ is floored at this fraction of the joint's torque RMS (noise-free data).
SIGMA_FLOOR = 1e-6


def _r_factor(a: np.ndarray, size: int) -> np.ndarray:
    r = np.linalg.qr(a, mode="r")
    if r.shape[0] < size:
        r = np.vstack([r, np.zeros((size - r.shape[0], size))])
    return r


@dataclass(frozen=True, eq=False)
class CompressedProblem:
    """Per-joint R factors ``R̄_j`` of ``[Y_j | τ_j]``, shape ``(nv, p + 1, p + 1)``;
    ``filtered``: of rows through an identification low-pass (parallel filtering, module
    docstring), some or all."""

    factors: np.ndarray
    n_samples: int
    tau_sum_squares: np.ndarray
    filtered: bool = False

    @property
    def nv(self) -> int:
        return int(self.factors.shape[0])

    @property
    def n_columns(self) -> int:
        return int(self.factors.shape[1] - 1)

    def stacked(self, sigma: np.ndarray | None = None, columns: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(R, z, ρ²)`` of the whole (optionally σ-weighted, column-restricted) problem.

        ``‖Σ^{-1/2}(Y[:, columns] θ − τ)‖² = ‖R θ − z‖² + ρ²``.
        """
        sigma = np.ones(self.nv) if sigma is None else np.asarray(sigma, dtype=float)
        cols = np.arange(self.n_columns) if columns is None else np.asarray(columns)
        keep = np.append(cols, self.n_columns)
        # only each factor's non-zero rows (structurally zero columns leave zero rows): the
        # same R, for the flops of the rows that carry data
        a = np.vstack([self.factors[j][np.any(self.factors[j] != 0.0, axis=1)][:, keep]
                       / sigma[j] for j in range(self.nv)])
        r = _r_factor(a, keep.size)
        return r[:-1, :-1], r[:-1, -1], float(r[-1, -1] ** 2)

    def minus(self, theta: np.ndarray) -> "CompressedProblem":
        """The compressed problem of the torques ``τ − Y θ`` (e.g. what a known robot leaves
        to a payload): ``z_j ← z_j − R_j θ``, ``ρ_j`` unchanged, since
        ``‖Y_j v − (τ_j − Y_j θ)‖² = ‖R_j (v + θ) − z_j‖² + ρ_j²``. No pass over the data."""
        theta = np.asarray(theta, dtype=float)
        factors = self.factors.copy()
        factors[:, :-1, -1] -= self.factors[:, :-1, :-1] @ theta
        return CompressedProblem(factors, self.n_samples, self.sum_squares(theta), self.filtered)

    def sum_squares(self, theta: np.ndarray, columns: np.ndarray | None = None) -> np.ndarray:
        """Per-joint residual sum of squares ``‖Y_j[:, columns] θ − τ_j‖²``, shape (nv,)."""
        cols = np.arange(self.n_columns) if columns is None else np.asarray(columns)
        # Only the full-column factor gives the exact residual: ‖R θ − z‖² + ρ² with θ padded.
        full = np.zeros(self.n_columns)
        full[cols] = theta
        r = self.factors
        return (np.sum((r[:, :-1, :-1] @ full - r[:, :-1, -1]) ** 2, axis=1)
                + r[:, -1, -1] ** 2)


def compress(model: RobotModel, dataset: Dataset, spec: RegressorSpec,
             chunk: int | None = None, weights: np.ndarray | None = None,
             base: BaseParameters | None = None) -> CompressedProblem:
    """Accumulate the per-joint R factors of ``[Y_j | τ_j]`` over a dataset (O(p²) memory).

    ``chunk`` samples per regressor buffer; default
    :func:`~consistid.identification.regressor.default_chunk` (4096, fewer for a large robot).
    ``weights`` (N, nv) ≥ 0 scale each row's squared residual (row ``k`` of joint ``j`` is
    multiplied by ``√w_kj``), as iteratively re-weighted least squares needs.

    The data pass, per chunk: the rigid-body regressor written into one reused buffer
    ``(chunk, nv, 10·nbodies)``, then per joint its supported columns
    (:func:`~consistid.identification.regressor.column_support`: rigid-body columns gathered,
    its own per-joint signals computed, the torque) written once into a column-major block and
    folded into that joint's compact factor by :func:`update_factor`. The compact factors are
    scattered into ``(p + 1) × (p + 1)`` ones at the end (upper triangular, zero rows at the
    structurally zero columns: see :func:`accumulate`).

    ``base``: the base parameters of ``(model, spec)`` (same gravity). Then each joint's QR runs
    on its supported *independent* columns only (about half the flops on the Panda and on
    Talos): the dependent columns are linear combinations of the independent ones in every row,
    ``Y = Y_b B`` (:mod:`consistid.identification.base`), so joint ``j``'s rows satisfy
    ``Y_j = Y_{j,I} B_I`` with ``I`` its supported independent columns and ``B_I`` those rows of
    ``B``, and ``[Y_j | τ_j]``'s factor is that of ``[Y_{j,I} | τ_j]`` times
    ``diag(B_I, 1)``, brought back to upper triangular form by a QR of ``k × (p + 1)``
    (:func:`expand_factor`). ``R̄ᵀR̄`` is the Gram matrix of all columns, exact on the
    independent ones, and to ``B``'s round-off on the dependent ones.
    """
    chunk = default_chunk(model, spec) if chunk is None else chunk
    tau = dataset.require_torque()
    dataset.check_joints(model.nv, model.joint_names)
    if weights is not None:
        weights = np.asarray(weights, dtype=float)
        if weights.shape != tau.shape or not np.all(np.isfinite(weights)) or np.any(weights < 0):
            raise OptionError(f"row weights must be finite, ≥ 0 and of shape {tau.shape}, got "
                              f"shape {weights.shape}")
        root = np.sqrt(weights)
    support = column_support(model, spec)
    p = support.shape[1]
    if base is not None:
        if base.n_standard != p:
            raise OptionError(f"base parameters of {base.n_standard} columns given for a "
                              f"regressor of {p}: compute them for this model and spec")
        independent = np.zeros(p, dtype=bool)
        independent[base.independent] = True
        support = support & independent
    keeps = [np.append(np.flatnonzero(support[j]), p) for j in range(model.nv)]
    n_in = model.n_inertial
    # per joint: its kept rigid-body columns, and its kept per-joint columns (signal suffixes)
    rigid_cols = [keep[keep < n_in] for keep in keeps]
    signals = [[spec.columns[c - n_in][2] for c in keep[(keep >= n_in) & (keep < p)]]
               for keep in keeps]
    compact = [np.zeros((k.size, k.size), order="F") for k in keeps]
    n_total = dataset.n_samples
    cutoff, order = dataset.identification_filter or (None, 4)
    windows = [w for w in plan(dataset.t, dataset.segment, cutoff, chunk)
               if weights is None or np.any(weights[w.kept])]    # rows of weight 0 add nothing
    rows = max((w.rows.stop - w.rows.start for w in windows), default=1)
    rigid = np.empty((rows, model.nv, n_in))                            # one reused buffer
    # one reused column-major block per joint (a fresh one per chunk and joint page-faults a
    # megabyte each time)
    blocks = [np.empty((rows, keep.size), order="F") for keep in keeps]
    filtered_squares = np.zeros(model.nv)
    for w in windows:
        s = w.rows
        q, dq, ddq = check_states(model, dataset.q[s], dataset.dq[s], dataset.ddq[s])
        y = rigid_body_regressor(model, q, dq, ddq, out=rigid[: s.stop - s.start])
        for j, keep in enumerate(keeps):
            block = _joint_block(y, j, rigid_cols[j], signals[j], (q, dq, ddq), dataset, s,
                                 blocks[j] if y.shape[0] == rows else None)
            block[:, -1] = tau[s, j]
            block = _filtered(block, w, cutoff, order)
            filtered_squares[j] += np.sum(block[:, -1] ** 2) if w.rate is not None else 0.0
            if weights is not None:
                block *= root[w.kept, j][:, None]
            compact[j] = update_factor(compact[j], block)
    factors = np.zeros((model.nv, p + 1, p + 1))
    for j, keep in enumerate(keeps):
        if base is None:
            factors[j][np.ix_(keep, keep)] = np.triu(compact[j])
        else:
            factors[j] = expand_factor(np.triu(compact[j]), keep, base)
    squares = np.sum(tau ** 2, axis=0)
    if cutoff is not None:          # the filtered torques' (unfiltered windows: as they are)
        unfiltered = [w.kept for w in windows if w.rate is None]
        squares = filtered_squares + sum((np.sum(tau[k] ** 2, axis=0) for k in unfiltered),
                                         np.zeros(model.nv))
    return CompressedProblem(factors, n_total, squares, cutoff is not None)


def _joint_block(y: np.ndarray, j: int, rigid_cols: np.ndarray, signals: list[str],
                 states: tuple[np.ndarray, np.ndarray, np.ndarray], dataset: Dataset, s: slice,
                 out: np.ndarray | None) -> np.ndarray:
    """Joint ``j``'s rows of ``[Y | ·]`` over the samples ``s`` (its kept rigid-body columns,
    then its per-joint signals; the last column left for the torque), column-major, in ``out``
    when given."""
    q, dq, ddq = states
    block = out if out is not None else np.empty((y.shape[0], rigid_cols.size + len(signals) + 1),
                                                 order="F")
    r = rigid_cols.size
    for a in range(0, y.shape[0], GATHER_ROWS):   # gathered and transposed in cache
        block[a:a + GATHER_ROWS, :r] = y[a:a + GATHER_ROWS, j, rigid_cols]
    for i, suffix in enumerate(signals):
        block[:, r + i] = joint_signal(suffix, q[:, j], dq[:, j], ddq[:, j],
                                       None if dataset.dq_sign is None else dataset.dq_sign[s, j])
    return block


def _filtered(block: np.ndarray, window: Window, cutoff: float | None, order: int
              ) -> np.ndarray:
    """The window's kept rows of ``block``, through the identification low-pass when the window
    is filtered (column-major for LAPACK)."""
    if window.rate is None:
        return block[window.core]
    return np.asfortranarray(window.apply(block, cutoff, order))    # a copy only if not F


def expand_factor(r: np.ndarray, keep: np.ndarray, base: BaseParameters) -> np.ndarray:
    """The ``(p + 1) × (p + 1)`` upper triangular factor of ``[Y_j | τ_j]`` from ``r``, that of
    ``[Y_{j,I} | τ_j]`` with ``I = keep[:-1]`` independent columns (``keep[-1] = p``, the
    torque): ``r · diag(B_I, 1)`` (``B_I`` the rows of ``B`` whose independent column is in
    ``I``, so that ``Y_j = Y_{j,I} B_I``) brought to upper triangular form by a QR, zero rows
    below ``keep.size``. See :func:`compress`."""
    p = base.n_standard
    rows = np.searchsorted(base.independent, keep[:-1])      # B's row of each kept column
    expanded = np.zeros((keep.size, p + 1))
    expanded[:, :p] = r[:, :-1] @ base.matrix[rows]
    expanded[:, p] = r[:, -1]
    out = np.zeros((p + 1, p + 1))
    out[:keep.size] = np.linalg.qr(expanded, mode="r")     # keep.size ≤ p + 1 rows
    return out


#: Rows per gather of a joint's rigid-body columns into its column-major block in
#: :func:`compress` (the strided source and the transposed target of 512 rows stay in cache:
#: 40 % less time than one gather of the whole chunk on the Panda and on Talos).
GATHER_ROWS = 512
#: Inner block size of ``dtpqrt`` (LAPACK's ``nb``).
QR_NB = 16


def update_factor(r: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The upper triangular ``R'`` of ``[R; rows]``: ``R'ᵀR' = RᵀR + rowsᵀrows``.

    ``r`` (k, k) upper triangular, column-major (it is overwritten and returned), ``rows``
    (n, k), column-major to avoid a copy (it is overwritten too). LAPACK's ``dtpqrt``, the QR
    of a triangle stacked on a rectangle (blocked Householder, Golub & Van Loan §5.2, that
    skips the triangle's zeros).
    """
    r, _, _, info = lapack.dtpqrt(0, min(QR_NB, r.shape[0]), r, rows, overwrite_a=1,
                                  overwrite_b=1)
    if info != 0:
        raise ValueError(f"LAPACK dtpqrt failed (info {info})")
    return r


def accumulate(factors: np.ndarray, columns: np.ndarray, tau: np.ndarray,
               weights: np.ndarray | None = None, support: np.ndarray | None = None) -> None:
    """One chunk into the per-joint R factors, in place: ``R̄_j ← qr([R̄_j; √w_j·[Y_j | τ_j]])``.

    ``factors`` (nv, p + 1, p + 1), ``columns`` (n, nv, p), ``tau`` and ``weights`` (n, nv).
    ``support`` (nv, p), optional: the columns that can be non-zero in each joint's rows
    (:func:`~consistid.identification.regressor.column_support`). The QR then runs on those
    columns only, and its factor is scattered back: compact row ``i`` to row ``s_i`` of the
    full factor, the residual row to row ``p``. With ``s_i`` increasing the result is still
    upper triangular, with zero rows at the structurally zero columns, and ``R̄ᵀR̄`` is
    unchanged — the same factor, for the flops of the non-zero columns.
    """
    size, n = factors.shape[1], columns.shape[0]
    for j in range(factors.shape[0]):
        keep = (np.arange(size) if support is None
                else np.append(np.flatnonzero(support[j]), size - 1))
        k = keep.size
        # [R̄_j; √w·[Y_j | τ_j]] written once into a column-major buffer that LAPACK's geqrf
        # factorises in place (numpy's qr would copy the stacked block again)
        buf = np.empty((k + n, k), order="F")
        grid = np.ix_(keep, keep)
        buf[:k] = factors[j][grid]
        buf[k:, :k - 1] = columns[:, j, keep[:-1]]
        buf[k:, k - 1] = tau[:, j]
        if weights is not None:
            buf[k:] *= np.sqrt(weights[:, j])[:, None]
        lwork = int(lapack.dgeqrf_lwork(k + n, k)[0])
        qr, _, _, info = lapack.dgeqrf(buf, lwork=lwork, overwrite_a=1)
        if info != 0:
            raise ValueError(f"LAPACK dgeqrf failed (info {info}) on joint {j}'s rows")
        factors[j][grid] = np.triu(qr[:k])


def floor_sigma(sigma: np.ndarray, problem: CompressedProblem) -> np.ndarray:
    """``max(σ_j, SIGMA_FLOOR · max(RMS(τ_j), 1e-300))`` per joint, so that ``1/σ_j`` weights
    stay finite on noise-free data."""
    rms = np.sqrt(problem.tau_sum_squares / max(problem.n_samples, 1))
    return np.maximum(np.asarray(sigma, dtype=float), SIGMA_FLOOR * np.maximum(rms, 1e-300))


def joint_sigma(sum_squares: np.ndarray, n_samples: int, n_parameters: int,
                tau: np.ndarray | None = None) -> np.ndarray:
    """Per-joint noise standard deviation from residual sums of squares (Gautier 1997):
    ``σ_j = sqrt(‖ρ_j‖² / (N − τ_j b/nv))``, the ``b`` fitted parameters' degrees of freedom
    shared evenly among the ``nv`` joints (the denominator is kept ≥ 1). ``τ_j`` (default 1) is
    the residual's autocorrelation time
    (:func:`consistid.identification.statistics.autocorrelation_time`):
    with errors correlated over ``τ_j`` samples a fit absorbs ``≈ τ_j`` times more of their
    variance per parameter (``E‖ρ_j‖² = tr((1 − P) Σ_j) ≈ σ_j² (N − τ_j b/nv)`` for columns that
    vary slowly against the correlation). Not floored: see :func:`floor_sigma`."""
    sum_squares = np.asarray(sum_squares, dtype=float)
    tau = np.ones_like(sum_squares) if tau is None else np.asarray(tau, dtype=float)
    return np.sqrt(sum_squares / np.maximum(n_samples - tau * n_parameters / sum_squares.size,
                                            1.0))
