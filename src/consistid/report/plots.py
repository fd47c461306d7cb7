r"""Plots that several reports draw, as matplotlib ``Figure`` objects (no pyplot, no global state).

``torque_fit``
    measured (thin black line) and predicted (dashed orange) torque against time, one panel
    per joint: the prediction never hides the measurement.
``residual_over_time``
    the residual τ − τ̂ against time per joint, with the bands ±σ and ±2σ of the noise σ the
    identification assumed: drift, bursts at reversals and a growing error show there.
``parameter_errorbars``
    each estimate with its ±2σ bar against the prior (CAD) value, every parameter on its own
    scale (divided by the largest of its |estimate|, |prior| and 2σ).
``residual_histograms``
    the residual's distribution per joint, with the normal density of the noise σ the
    identification assumed: a residual wider than it, skewed or with two modes (Coulomb friction
    left out) shows there.
``residual_spectra``
    Welch's power spectral density of the residual per joint (Welch 1967,
    doi:10.1109/TAU.1967.1161901) with each joint's white-noise level
    :math:`\sigma_j^2 / (f_s/2)` (one-sided PSD of white noise of variance σ² sampled at
    :math:`f_s`): a residual above it at low frequency is
    model error, one above it at high frequency unmodelled dynamics or a delay.
``grouped_bars``
    values per joint for several series, with a reference level per joint drawn as a line across
    each joint's group (e.g. a noise floor); the legend is placed below the axes so that it never
    hides a bar.

Every figure is at most 10 inches wide, so that at the reports' 100 dpi its PNG is no wider
than the page (1000 px; the page shrinks it further on a narrow screen).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

#: Width (inches) of a full-width figure; at 100 dpi, 1000 px.
WIDTH = 10.0
#: Most points drawn per line (longer series are decimated evenly for the picture only).
MAX_POINTS = 4000


def _figure(width: float, height: float) -> Any:
    from matplotlib.figure import Figure  # heavy: loaded with the first plot

    return Figure(figsize=(min(width, WIDTH), height), layout="constrained")


def _grid(n: int, max_cols: int = 3) -> tuple[int, int]:
    cols = min(n, max_cols)
    return int(np.ceil(n / cols)), cols


def _thin(n: int) -> np.ndarray:
    step = max(1, int(np.ceil(n / MAX_POINTS)))
    return np.arange(0, n, step)


def _joint_panels(joint_names: Sequence[str], row_height: float, max_cols: int = 3
                  ) -> tuple[Any, int, list[Any]]:
    """A figure of one panel per joint (at most ``max_cols`` columns, ``row_height`` inches a
    row, small tick labels), its number of columns, and the panels in joint order."""
    n = len(joint_names)
    rows, cols = _grid(n, max_cols)
    fig = _figure(WIDTH, row_height * rows + 0.5)
    axes = [fig.add_subplot(rows, cols, j + 1) for j in range(n)]
    for ax in axes:
        ax.tick_params(labelsize=7)
    return fig, cols, axes


def _edge_labels(ax: Any, j: int, n: int, cols: int, ylabel: str, xlabel: str) -> None:
    """Axis labels on panel ``j`` of ``n`` in a grid of ``cols`` columns: y on the left
    column, x on the bottom row."""
    if j % cols == 0:
        ax.set_ylabel(ylabel, fontsize=8)
    if j >= n - cols:
        ax.set_xlabel(xlabel, fontsize=8)


def _legend_below(fig: Any, ncol: int, title: str) -> Any:
    """``fig`` with the first panel's legend below the panels and ``title`` above them."""
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=8,
               frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def torque_fit(t: np.ndarray, measured: np.ndarray, predicted: np.ndarray,
               joint_names: Sequence[str], title: str = "") -> Any:
    """Measured (thin black, drawn on top) and predicted (dashed orange, thicker, below)
    torque against time, one panel per joint; the panel title gives the residual RMS."""
    n = len(joint_names)
    fig, cols, axes = _joint_panels(joint_names, 2.1)
    keep = _thin(len(t))
    for j, (name, ax) in enumerate(zip(joint_names, axes)):
        ax.plot(t[keep], predicted[keep, j], color="tab:orange", lw=1.6, ls=(0, (4, 2)),
                label="predicted", zorder=2)
        ax.plot(t[keep], measured[keep, j], color="k", lw=0.5, label="measured", zorder=3)
        rms = float(np.sqrt(np.mean((measured[:, j] - predicted[:, j]) ** 2)))
        ax.set_title(f"{name}  (RMS {rms:.3g} N·m)", fontsize=8)
        _edge_labels(ax, j, n, cols, "τ [N·m]", "t [s]")
    return _legend_below(fig, 2, title)


def residual_over_time(t: np.ndarray, residual: np.ndarray, joint_names: Sequence[str],
                       sigma: np.ndarray | None = None, title: str = "") -> Any:
    """The residual τ − τ̂ against time, one panel per joint; with ``sigma``, the ±σ band
    shaded and ±2σ dotted (white noise stays inside ±2σ about 95 % of the time)."""
    n = len(joint_names)
    fig, cols, axes = _joint_panels(joint_names, 1.9)
    keep = _thin(len(t))
    for j, (name, ax) in enumerate(zip(joint_names, axes)):
        ax.plot(t[keep], residual[keep, j], color="tab:red", lw=0.5, label="τ − τ̂")
        if sigma is not None and sigma[j] > 0:
            ax.axhspan(-sigma[j], sigma[j], color="0.85", zorder=0, label="±σ")
            for s in (-2 * sigma[j], 2 * sigma[j]):
                ax.axhline(s, color="k", lw=0.6, ls=":")
            ax.plot([], [], color="k", lw=0.6, ls=":", label="±2σ")
        ax.axhline(0, color="k", lw=0.4)
        ax.set_title(name, fontsize=8)
        _edge_labels(ax, j, n, cols, "τ − τ̂ [N·m]", "t [s]")
    return _legend_below(fig, 3, title)


#: Parameters per column of :func:`parameter_errorbars` before it starts a second column.
BARS_PER_COLUMN = 40
#: Half-width of :func:`parameter_errorbars`' axis (a bar reaching past it is cut, marked ▸).
BARS_LIMIT = 2.5


def parameter_errorbars(names: Sequence[str], estimate: np.ndarray, std: np.ndarray,
                        prior: np.ndarray, title: str = "") -> Any:
    """Each estimate (dot) with its ±2σ bar and the prior's value (cross), one row per
    parameter. Every row has its own scale ``s_i = max(|estimate_i|, |prior_i|, 2σ_i)``
    (values divided by it, so every finite bar fits in [−2, 2]): a prior outside the bar is a
    parameter the data moved away from the prior; a bar as wide as ±1 around 0 is one the data
    barely determine; σ = inf (not informed) is drawn red across the axis."""
    estimate, std, prior = (np.asarray(a, dtype=float) for a in (estimate, std, prior))
    n = len(names)
    ncols = int(np.ceil(n / BARS_PER_COLUMN)) if n else 1
    per = int(np.ceil(n / ncols)) if n else 1
    fig = _figure(WIDTH, 0.17 * per + 1.2)
    finite = np.isfinite(std)
    scale = np.maximum(np.abs(estimate), np.abs(prior))
    scale = np.where(finite, np.maximum(scale, 2 * np.where(finite, std, 0.0)), scale)
    scale = np.where(scale > 0, scale, 1.0)
    lim = BARS_LIMIT
    for c in range(ncols):
        ax = fig.add_subplot(1, ncols, c + 1)
        idx = np.arange(c * per, min(n, (c + 1) * per))
        y = -np.arange(len(idx), dtype=float)
        x, p = estimate[idx] / scale[idx], prior[idx] / scale[idx]
        err = 2 * std[idx] / scale[idx]
        cut = ~np.isfinite(err) | (np.abs(x) + err > lim)
        err = np.where(np.isfinite(err), err, 2 * lim)
        lo, hi = np.minimum(err, x + lim), np.minimum(err, lim - x)
        for mask, colour in ((~cut, "tab:blue"), (cut, "tab:red")):
            if mask.any():
                ax.errorbar(x[mask], y[mask], xerr=[lo[mask], hi[mask]], fmt="o", ms=3,
                            color=colour, ecolor=colour, elinewidth=1, capsize=2)
        ax.plot(p, y, "x", color="k", ms=5, mew=1)
        ax.axvline(0, color="0.6", lw=0.5)
        ax.set_xlim(-lim, lim)
        ax.set_yticks(y, [str(names[i]) for i in idx], fontsize=6)
        ax.set_ylim(y[-1] - 0.8 if len(y) else -1, 0.8)
        ax.tick_params(axis="x", labelsize=7)
        ax.set_xlabel("value / max(|estimate|, |prior|, 2σ)", fontsize=8)
        ax.grid(True, axis="x", lw=0.3)
    handles = [
        fig.axes[0].errorbar([], [], xerr=[], fmt="o", ms=3, color="tab:blue")[0],
        fig.axes[0].errorbar([], [], xerr=[], fmt="o", ms=3, color="tab:red")[0],
        fig.axes[0].plot([], [], "x", color="k")[0]]
    fig.legend(handles, ["estimate ± 2σ", "σ = inf (not informed) or cut", "prior"],
               loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def residual_histograms(residual: np.ndarray, joint_names: Sequence[str],
                        sigma: np.ndarray | None = None, title: str = "") -> Any:
    """Histogram (density) of the residual per joint; with ``sigma``, the normal density
    ``N(0, σ_j²)`` over it."""
    n = len(joint_names)
    fig, cols, axes = _joint_panels(joint_names, 1.9, 4)
    for j, (name, ax) in enumerate(zip(joint_names, axes)):
        r = residual[:, j]
        ax.hist(r, bins=min(60, max(10, int(np.sqrt(r.size)))), density=True,
                color="tab:blue", alpha=0.6, label="residual")
        if sigma is not None and sigma[j] > 0:
            lim = max(float(np.max(np.abs(r))), 4 * float(sigma[j]))
            x = np.linspace(-lim, lim, 200)
            ax.plot(x, np.exp(-0.5 * (x / sigma[j]) ** 2) / (sigma[j] * np.sqrt(2 * np.pi)),
                    color="k", lw=1, label="N(0, σ²)")
        ax.set_title(name, fontsize=8)
        if j >= n - cols:
            ax.set_xlabel("τ − τ̂ [N·m]", fontsize=8)
    return _legend_below(fig, 2, title)


def residual_spectra(residual: np.ndarray, rate: float, joint_names: Sequence[str],
                     sigma: np.ndarray | None = None, title: str = "") -> Any:
    """Welch PSD of the residual per joint (one curve each) with the white-noise level of
    ``sigma`` as a dotted line in the same colour; the legend sits below the axes."""
    import scipy.signal  # heavy: loaded with the first spectrum

    fig = _figure(WIDTH, 4.2)
    ax = fig.add_subplot()
    nper = int(min(residual.shape[0], max(64, 2 ** int(np.log2(max(residual.shape[0] // 8,
                                                                     1))))))
    f, psd = scipy.signal.welch(residual, fs=rate, nperseg=nper, axis=0)
    for j, name in enumerate(joint_names):
        line, = ax.loglog(f[1:], psd[1:, j], lw=1, label=name)
        if sigma is not None and sigma[j] > 0:
            ax.axhline(sigma[j] ** 2 / (rate / 2), color=line.get_color(), ls=":", lw=0.9)
    if sigma is not None:
        ax.plot([], [], color="k", ls=":", lw=0.9, label="white noise of σ (per joint)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("residual PSD [(N·m)²/Hz]")
    ax.grid(True, which="major", lw=0.3)
    fig.legend(loc="outside lower center", ncol=min(len(joint_names) + 1, 5), fontsize=7,
               frameon=False)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def grouped_bars(labels: Sequence[str], series: Sequence[tuple[str, np.ndarray]],
                 reference: tuple[str, np.ndarray] | None = None, ylabel: str = "",
                 log: bool = False, title: str = "") -> Any:
    """Bars per label for each series (side by side), with ``reference`` drawn as a black line
    across each label's group; legend below the axes, outside them."""
    n, k = len(labels), len(series)
    fig = _figure(min(WIDTH, 3.0 + 0.9 * n), 4.0)
    ax = fig.add_subplot()
    x = np.arange(n)
    width = 0.8 / max(k, 1)
    for i, (name, values) in enumerate(series):
        ax.bar(x + width * (i - (k - 1) / 2), values, width, label=name)
    if reference is not None:
        name, values = reference
        for j in range(n):
            ax.hlines(values[j], x[j] - 0.45, x[j] + 0.45, colors="k", lw=1.6,
                      label=name if j == 0 else None)
    ax.set_xticks(x, labels, rotation=30 if n > 4 else 0, ha="right" if n > 4 else "center",
                  fontsize=8)
    ax.set_ylabel(ylabel)
    if log:
        ax.set_yscale("log")
    if title:
        ax.set_title(title, fontsize=10)
    fig.legend(loc="outside lower center", ncol=min(k + 1, 4), fontsize=8, frameon=False)
    return fig
