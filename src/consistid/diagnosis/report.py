"""The diagnosis report: a text summary, plots (matplotlib, Agg backend) and an HTML page with the
plots embedded as PNG.

Plots
-----
``residual_vs_velocity.png``
    Nominal residual against joint velocity, one panel per joint: friction shows as a step at
    ``q̇ = 0`` (Coulomb) or a slope (viscous), an offset as a shift of both branches.
``residual_spectrum.png``
    Residual power spectral density per joint with the noise floor: effects driven by the motion
    live in the low band, a delay or an elastic joint rises with frequency.
``joint_bars.png``
    Held-out RMS per joint: nominal, after the diagnosed effects, with every candidate at once
    (the library floor), and the noise floor.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..identification.summary import table

if TYPE_CHECKING:
    from .diagnose import Diagnosis


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def diagnosis_text(diag: "Diagnosis") -> str:
    """The report as plain text: verdict, ranking, per-effect details, where the gap lies."""
    names = diag.joint_names
    w = diag.where
    lines = [f"consistid diagnosis of {diag.model_name!r} (nominal model vs measured torques)",
             f"held-out data   {diag.held_out_source}",
             f"noise floor     {diag.noise_source}", ""]
    if diag.effects:
        lines.append(f"Effects found ({len(diag.effects)}), ranked by held-out residual "
                     "reduction:")
        rows = []
        for k, e in enumerate(diag.effects, 1):
            rows.append((k, e.name, ", ".join(e.joints) or "-", _pct(e.total_shrink),
                         e.n_parameters, f"{e.delta_bic:.4g}",
                         ", ".join(e.alternatives) or "-"))
        lines += [table(["#", "effect", "joints", "held-out shrink", "params", "ΔBIC",
                         "indistinguishable from"], rows), ""]
    else:
        lines += ["No effect selected: no candidate reduces the held-out residual enough to "
                  "generalise.", ""]
    if diag.at_noise_floor:
        verdict = "the remaining gap is at the noise floor"
    elif diag.at_library_floor:
        verdict = ("the selected effects explain all that the candidate library can; the rest "
                   "lies outside the library, or the noise floor is underestimated (low-pass "
                   "filtered torques: pass sigma)")
    else:
        verdict = ("a gap that the candidates could still reduce remains (below the selection's "
                   "relevance or significance thresholds)")
    lines.append(f"Verdict: {verdict}.")
    lines += ["", table(["joint", "nominal RMS", "final RMS", "library floor", "noise floor",
                         "final / noise"],
                        [(n, a, b, lf, s, r) for n, a, b, lf, s, r in
                         zip(names, diag.rms_nominal, diag.rms_final, diag.library_floor,
                             diag.noise_floor, diag.gap_to_noise)]), ""]
    for k, e in enumerate(diag.effects, 1):
        lines.append(f"[{k}] {e.name} — {e.signature}")
        shown = [j for j in range(len(names)) if names[j] in e.joints] or \
            list(range(len(names)))
        lines.append(table(["joint", "held-out RMS before", "after", "shrink"],
                           [(names[j], e.rms_before[j], e.rms_after[j], _pct(e.shrink[j]))
                            for j in shown]))
        lines += ["  " + str(p) for p in e.parameters]
        lines.append("")
    lines.append("Where the nominal residual lies (all data):")
    lines.append(table(["joint", "RMS", "share", "relative", "drift [N·m/s]"],
                       [(n, w.rms[j], _pct(w.share[j]), _pct(w.relative[j]),
                         f"{w.drift[j]:.3g} ± {w.drift_std[j]:.2g}")
                        for j, n in enumerate(names)]))
    lines.append("")
    lines.append("Residual RMS per regime [N·m] (fraction of samples):")
    lines.append(table(["regime", *names],
                       [(reg, *[f"{w.regime_rms[i, j]:.3g} ({_pct(w.regime_fraction[i, j])})"
                                if w.regime_fraction[i, j] > 0 else "-"
                                for j in range(len(names))])
                        for i, reg in enumerate(w.regimes)]))
    lines.append("")
    bands = [f"{a:g}–{b:.3g} Hz" for a, b in zip(w.band_edges[:-1], w.band_edges[1:])]
    lines.append(f"Residual RMS per frequency band [N·m] (nominal torque band < "
                 f"{w.signal_band:.3g} Hz):")
    lines.append(table(["band", *names], [(b, *w.band_rms[i]) for i, b in enumerate(bands)],
                       floatfmt=".3g"))
    if diag.steps:
        last = diag.steps[-1]
        lines += ["", f"Selection stopped: {last.reason} (next candidate {last.chosen})."
                  if not last.accepted else "", ]
    if diag.notes:
        lines += ["Notes:"] + [f"  - {n}" for n in diag.notes]
    return "\n".join(line for line in lines).rstrip() + "\n"


# --------------------------------------------------------------------------------- plots
def _figures(diag: "Diagnosis") -> dict[str, object]:
    from matplotlib.figure import Figure     # no pyplot, no backend switch: no global state

    w, names = diag.where, diag.joint_names
    nv = len(names)
    cols = min(nv, 4)
    rows = int(np.ceil(nv / cols))
    figs = {}
    fig = Figure(figsize=(3.2 * cols, 2.6 * rows), layout="constrained")
    for j in range(nv):
        ax = fig.add_subplot(rows, cols, j + 1)
        ax.plot(w.velocity[:, j], w.residual_sample[:, j], ".", ms=1.5, alpha=0.5)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(names[j], fontsize=9)
        ax.set_xlabel("q̇ [rad/s]", fontsize=8)
        ax.set_ylabel("τ − τ_nom [N·m]", fontsize=8)
        ax.tick_params(labelsize=7)
    figs["residual_vs_velocity"] = fig
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.add_subplot()
    for j in range(nv):
        line, = ax.loglog(w.freqs[1:], w.psd[1:, j], lw=1, label=names[j])
        nyq = w.freqs[-1]
        ax.axhline(diag.noise_floor[j] ** 2 / nyq, color=line.get_color(), ls=":", lw=0.8)
    ax.axvline(w.signal_band, color="k", ls="--", lw=0.8, label="nominal torque band")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("residual PSD [(N·m)²/Hz]")
    ax.legend(fontsize=7, ncol=2)
    figs["residual_spectrum"] = fig
    fig = Figure(figsize=(7, 3.5), layout="constrained")
    ax = fig.add_subplot()
    x = np.arange(nv)
    for k, (values, label) in enumerate(((diag.rms_nominal, "nominal"),
                                         (diag.rms_final, "with diagnosed effects"),
                                         (diag.library_floor, "every candidate (library floor)"),
                                         (diag.noise_floor, "noise floor"))):
        ax.bar(x + 0.2 * (k - 1.5), values, 0.2, label=label)
    ax.set_xticks(x, names, rotation=30, fontsize=8)
    ax.set_ylabel("held-out RMS [N·m]")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    figs["joint_bars"] = fig
    return figs


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def diagnosis_html(diag: "Diagnosis") -> str:
    """The report as one self-contained HTML page (plots embedded as base64 PNG)."""
    return _html(diag, diagnosis_text(diag), _pngs(diag))


def _pngs(diag: "Diagnosis") -> dict[str, bytes]:
    """Each plot of :func:`_figures` rendered once as PNG bytes."""
    return {name: _png(fig) for name, fig in _figures(diag).items()}


def _html(diag: "Diagnosis", text: str, pngs: dict[str, bytes]) -> str:
    """The HTML page of :func:`diagnosis_html` from the already built text and PNG plots."""
    imgs = "\n".join(
        f'<h3>{html.escape(k.replace("_", " "))}</h3><img alt="{k}" '
        f'src="data:image/png;base64,{base64.b64encode(png).decode()}"/>'
        for k, png in pngs.items())
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>consistid diagnosis: {html.escape(diag.model_name)}</title>"
            "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
            "pre{font-size:12px;background:#f6f6f6;padding:8px;overflow-x:auto}</style>"
            f"</head><body><h1>Sim-to-real diagnosis: {html.escape(diag.model_name)}</h1>"
            f"<pre>{html.escape(text)}</pre>{imgs}</body></html>\n")


def write_report(diag: "Diagnosis", path: str | Path) -> Path:
    """Write ``path``: ``.html`` (self-contained), ``.txt``, or a directory holding
    ``report.html``, ``report.txt`` and the plots as PNG files. Returns ``path``."""
    path = Path(path)
    if path.suffix == ".html":
        path.write_text(diagnosis_html(diag), encoding="utf-8")
    elif path.suffix == ".txt":
        path.write_text(diagnosis_text(diag), encoding="utf-8")
    else:
        path.mkdir(parents=True, exist_ok=True)
        text, pngs = diagnosis_text(diag), _pngs(diag)
        (path / "report.txt").write_text(text, encoding="utf-8")
        (path / "report.html").write_text(_html(diag, text, pngs), encoding="utf-8")
        for name, png in pngs.items():
            (path / f"{name}.png").write_bytes(png)
    return path
