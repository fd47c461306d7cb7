"""Figures and HTML pages of the online results (:class:`~consistid.online.adaptive_run.
AdaptiveRun`, :class:`~consistid.online.rls.RecursiveEstimator`): one self-contained page each,
plots embedded as PNG. matplotlib is imported where a figure is drawn."""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

STYLE = ("body{font-family:sans-serif}table{border-collapse:collapse}"
         "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}")


def adaptive_figure(run):
    """Tracking error norm and the estimate's torque error versus time, and the RMS per period
    (``run``: an :class:`~consistid.online.adaptive_run.AdaptiveRun`)."""
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy)

    fig = Figure(figsize=(8, 7))
    ax = fig.add_subplot(3, 1, 1)
    ax.plot(run.t, 1e3 * np.linalg.norm(run.q - run.q_desired, axis=1), lw=0.6)
    ax.set_ylabel("‖q − q_d‖ [mrad]")
    ax = fig.add_subplot(3, 1, 2)
    ax.plot(run.estimate_t, run.estimate_error, lw=0.8)
    ax.set_ylabel("estimate torque error [N·m]")
    ax.set_xlabel("t [s]")
    for axis in fig.axes:
        if run.payload_time is not None:
            axis.axvline(run.payload_time, color="red", lw=0.8, ls="--")
    ax = fig.add_subplot(3, 1, 3)
    ax.bar(np.arange(1, run.periods + 1), 1e3 * run.period_rms())
    ax.set_xlabel("period")
    ax.set_ylabel("RMS tracking error [mrad]")
    fig.tight_layout()
    return fig


def page(title: str, summary: str, figure=None) -> str:
    """A self-contained HTML page: the text summary and, if given, the figure as a PNG."""
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
             f"</title><style>{STYLE}</style></head><body><h3>{html.escape(title)}</h3>"]
    if figure is not None:
        buf = io.BytesIO()
        figure.savefig(buf, format="png", dpi=90)
        parts.append("<img src='data:image/png;base64,"
                     + base64.b64encode(buf.getvalue()).decode("ascii") + "'/>")
    parts.append(f"<pre>{html.escape(summary)}</pre></body></html>\n")
    return "".join(parts)


def fragment(summary: str) -> str:
    """The summary as an HTML fragment (Jupyter's ``_repr_html_``)."""
    return f"<pre>{html.escape(summary)}</pre>"


def write(path: str | Path, text: str, default_name: str) -> Path:
    """Write ``text`` to ``path`` (a ``.html`` file, or a folder that gets ``default_name``)."""
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        path.mkdir(parents=True, exist_ok=True)
        path = path / default_name
    path.write_text(text, encoding="utf-8")
    return path
