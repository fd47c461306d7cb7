"""The diagnosis report: a text summary, plots (matplotlib figures, no pyplot) and one
self-contained HTML page (:mod:`consistid.report.html`: real tables, the plots embedded as PNG
and no wider than the page, the noise floor drawn on the bars and legends outside the axes).

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

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..filesafety import replacing
from ..identification.summary import table, warning_lines
from ..report import plots
from ..report.html import Page, findings_html, unique
from .remainder import REMAINDER_RATIO

if TYPE_CHECKING:
    from .diagnose import Diagnosis


#: What the held-out table's last column is (the column the verdict judges).
JUDGED_NOTE = ("judged / noise: the held-out RMS as the verdict judges it (dry friction "
               "set-valued at rest: a held joint's torque within its friction cone is no error; "
               "samples the model cannot predict left out), over the floor the held-out "
               "recordings' own low-pass leaves (no less than the noise floor); above "
               f"{REMAINDER_RATIO:g} the joint is flagged or undetermined; \"not judged\": no "
               "sample of the joint could be (each within a delay or the low-pass's settling "
               "time of its recording's ends).")


def _judged(ratio: float) -> float | str:
    """A cell of the judged / noise column: the ratio, or "not judged" (NaN: no sample)."""
    return "not judged" if np.isnan(ratio) else ratio


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _notes_not_warned(diag: "Diagnosis") -> list[str]:
    """The notes that are not warnings (``warning: …``, the command line's), each once, and
    without those a warning already says word for word (the diagnosis notes what it warns)."""
    warned = [n for n in diag.notes if n.startswith("warning: ")]
    return [n for n in unique(n for n in diag.notes if not n.startswith("warning: "))
            if not any(" ".join(n.split()) in " ".join(w.split()) for w in warned)]


def diagnosis_text(diag: "Diagnosis") -> str:
    """The report as plain text: verdict, ranking, per-effect details, where the gap lies."""
    names = diag.joint_names
    w = diag.where
    warned = [n.split(": ", 1)[1] for n in diag.notes if n.startswith("warning: ")]
    lines = [f"consistid diagnosis of {diag.model_name!r} (nominal model vs measured torques)",
             f"held-out data   {diag.held_out_source}",
             f"noise floor     {diag.noise_source}", *warning_lines(warned, numbered=False), ""]
    if diag.effects:
        lines.append(f"Effects found ({len(diag.effects)}), ranked by how much the held-out "
                     "residual grows without each; held-out shrink: what each removes of the "
                     "residual the ones above it leave (so not in order):")
        rows = []
        for k, e in enumerate(diag.effects, 1):
            rival = (f"{e.runner_up} ({100 * (1 - e.margin):.0f} % as much)"
                     if getattr(e, "runner_up", "") and e.margin < 0.5 else "-")
            rows.append((k, e.name, ", ".join(e.joints) or "-", _pct(e.total_shrink),
                         f"{getattr(e, 'confidence', '')} ({getattr(e, 'margin', 1.0):.2f}, "
                         f"p={e.p_value:.2g})", e.n_parameters, f"{e.delta_bic:.4g}",
                         ", ".join(e.alternatives) or "-", rival))
        lines += [table(["#", "effect", "joints", "held-out shrink", "confidence (margin, p)",
                         "params", "ΔBIC", "indistinguishable from", "runner-up"], rows), ""]
    else:
        lines += ["No effect selected: no candidate reduces the held-out residual enough to "
                  "generalise.", ""]
    lines.append(_verdict(diag)[1])
    lines += ["", table(["joint", "nominal RMS", "final RMS", "library floor", "noise floor",
                         "final / noise", "judged / noise"],
                        [(n, a, b, lf, s, r, _judged(k)) for n, a, b, lf, s, r, k in
                         zip(names, diag.rms_nominal, diag.rms_final, diag.library_floor,
                             diag.noise_floor, diag.gap_to_noise, diag.left_to_noise)]),
              JUDGED_NOTE, ""]
    for k, e in enumerate(diag.effects, 1):
        lines.append(f"[{k}] {e.name} — {e.signature}")
        shown = [j for j in range(len(names)) if names[j] in e.joints] or \
            list(range(len(names)))
        lines.append(table(["joint", "held-out RMS before", "after", "shrink"],
                           [(names[j], e.rms_before[j], e.rms_after[j], _pct(e.shrink[j]))
                            for j in shown]))
        lines += ["  " + str(p) for p in e.parameters]
        lines.append("")
    remainder = getattr(diag, "remainder", None)
    if remainder is not None:
        lines += [remainder.summary(), ""]
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
    if diag.rollout is not None:
        lines += ["", "How far the gap shrinks in your simulator:", diag.rollout.summary()]
    notes = _notes_not_warned(diag)
    if notes:
        lines += ["Notes:"] + [f"  - {n}" for n in notes]
    return "\n".join(line for line in lines).rstrip() + "\n"


# --------------------------------------------------------------------------------- plots
def _figures(diag: "Diagnosis") -> dict[str, object]:
    """The report's three plots (module docstring), each no wider than the page."""
    from matplotlib.figure import Figure     # no pyplot, no backend switch: no global state

    w, names = diag.where, diag.joint_names
    nv = len(names)
    cols = min(nv, 4)
    rows = int(np.ceil(nv / cols))
    figs = {}
    fig = Figure(figsize=(min(2.5 * cols, 10.0), 2.2 * rows), layout="constrained")
    for j in range(nv):
        ax = fig.add_subplot(rows, cols, j + 1)
        ax.plot(w.velocity[:, j], w.residual_sample[:, j], ".", ms=1.5, alpha=0.5)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(names[j], fontsize=9)
        ax.set_xlabel("q̇ [rad/s]", fontsize=8)
        ax.set_ylabel("τ − τ_nom [N·m]", fontsize=8)
        ax.tick_params(labelsize=7)
    figs["residual_vs_velocity"] = fig
    fig = Figure(figsize=(9, 4.4), layout="constrained")
    ax = fig.add_subplot()
    nyq = w.freqs[-1]
    for j in range(nv):
        line, = ax.loglog(w.freqs[1:], w.psd[1:, j], lw=1, label=names[j])
        ax.axhline(diag.noise_floor[j] ** 2 / nyq, color=line.get_color(), ls=":", lw=0.9)
    ax.plot([], [], color="k", ls=":", lw=0.9, label="noise floor (per joint, same colour)")
    ax.axvline(w.signal_band, color="k", ls="--", lw=0.8, label="nominal torque band")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("residual PSD [(N·m)²/Hz]")
    fig.legend(loc="outside lower center", ncol=min(nv + 2, 5), fontsize=7, frameon=False)
    figs["residual_spectrum"] = fig
    figs["joint_bars"] = plots.grouped_bars(
        names, [("nominal", diag.rms_nominal), ("with diagnosed effects", diag.rms_final),
                ("every candidate (library floor)", diag.library_floor)],
        reference=("noise floor", diag.noise_floor), ylabel="held-out RMS [N·m]", log=True)
    return figs


FIGURE_CAPTIONS = {
    "residual_vs_velocity": "Nominal residual against joint velocity: a step at q̇ = 0 is "
                            "Coulomb friction, a slope viscous friction, a shift an offset.",
    "residual_spectrum": "Residual power spectral density per joint; dotted: each joint's noise "
                         "floor; dashed: the band of the nominal torque.",
    "joint_bars": "Held-out RMS per joint: the nominal model, with the diagnosed effects, with "
                  "every candidate at once (library floor); black line: the noise floor.",
}


def _effect_rows(diag: "Diagnosis") -> list[list[object]]:
    rows = []
    for k, e in enumerate(diag.effects, 1):
        confidence = getattr(e, "confidence", "")
        margin = getattr(e, "margin", None)
        rows.append([k, e.name, ", ".join(e.joints) or "-", _pct(e.total_shrink),
                     f"{confidence} (margin {margin:.2f})" if margin is not None and confidence
                     else "-",
                     e.n_parameters, e.delta_bic, (e.p_value, ".2g"),
                     ", ".join(e.alternatives) or "-"])
    return rows


def _verdict(diag: "Diagnosis") -> tuple[str, str]:
    remainder = getattr(diag, "remainder", None)
    if remainder is not None:
        level = "warn" if remainder.flagged or remainder.undetermined else "ok"
        return level, f"Verdict: {remainder.verdict}."
    if diag.at_noise_floor:
        return "ok", "Verdict: the remaining gap is at the noise floor."
    if diag.at_library_floor:
        return "warn", ("Verdict: the selected effects explain all that the candidate library "
                        "can; the rest lies outside the library, or the noise floor is "
                        "underestimated (low-pass filtered torques: pass sigma).")
    return "warn", ("Verdict: a gap that the candidates could still reduce remains (below the "
                    "selection's relevance or significance thresholds).")


def diagnosis_page(diag: "Diagnosis", figures: bool = True) -> Page:
    """The report as a :class:`~consistid.report.html.Page`: verdict, ranked effects with their
    confidence, per-joint RMS against the floors, each effect's parameters ± σ, the
    unexplained remainder, where the nominal residual lies, and the plots."""
    names = diag.joint_names
    w = diag.where
    page = Page(f"Sim-to-real diagnosis: {diag.model_name}",
                "nominal model vs measured torques")
    level, text = _verdict(diag)
    findings = [(level, text)]
    # the ratio the verdict judges where the diagnosis has one, else final RMS / noise floor
    ratio = np.asarray(getattr(diag, "left_to_noise", diag.gap_to_noise), dtype=float)
    if ratio.size and np.isfinite(ratio).any() and level != "ok":
        j = int(np.nanargmax(ratio))
        findings.append((level, f"Largest gap left: {names[j]}, {ratio[j]:.3g} × its noise "
                                f"floor (held-out RMS {diag.rms_final[j]:.3g} N·m)."))
    findings += [("warn", n) for n in diag.notes if n.startswith("warning: ")]  # near the top
    findings += [("ok", n) for n in _notes_not_warned(diag)]                  # … each once
    page.raw(findings_html(findings))
    page.key_values([("held-out data", diag.held_out_source),
                     ("noise floor", diag.noise_source)])
    page.heading("Effects found", anchor="effects")
    if diag.effects:
        page.paragraph("Ranked by how much the held-out residual grows when the effect is "
                       "removed from the selected ones.")
        page.table(["#", "effect", "joints", "held-out shrink", "confidence", "params", "ΔBIC",
                    "p", "indistinguishable from"], _effect_rows(diag))
    else:
        page.paragraph("No effect selected: no candidate reduces the held-out residual enough "
                       "to generalise.")
    page.heading("Held-out RMS per joint", anchor="joints")
    page.table(["joint", "nominal RMS [N·m]", "final RMS [N·m]", "library floor [N·m]",
                "noise floor [N·m]", "final / noise", "judged / noise"],
               [[n, a, b, lf, s, r, _judged(k)] for n, a, b, lf, s, r, k in
                zip(names, diag.rms_nominal, diag.rms_final, diag.library_floor,
                    diag.noise_floor, diag.gap_to_noise, diag.left_to_noise)])
    page.paragraph(JUDGED_NOTE)
    if figures:
        figs = _figures(diag)
        page.figure("joint_bars", figs.pop("joint_bars"), FIGURE_CAPTIONS["joint_bars"])
    for k, e in enumerate(diag.effects, 1):
        page.heading(f"[{k}] {e.name}", level=3)
        page.paragraph(e.signature)
        shown = [j for j in range(len(names)) if names[j] in e.joints] or \
            list(range(len(names)))
        page.table(["joint", "held-out RMS before [N·m]", "after [N·m]", "shrink"],
                   [[names[j], e.rms_before[j], e.rms_after[j], _pct(e.shrink[j])]
                    for j in shown])
        page.bullets(str(p) for p in e.parameters)
    remainder = getattr(diag, "remainder", None)
    if remainder is not None:
        page.heading("Unexplained remainder", anchor="remainder")
        page.paragraph(remainder.verdict)
        regimes = sorted({r for j in remainder.joints for r in j.regimes})
        page.table(["joint", "left [N·m]", "noise floor [N·m]", "ratio", "unexplained [N·m]",
                    "p", "flagged", *[f"{r} [N·m]" for r in regimes], "pointers"],
                   [[j.joint, j.rms, j.floor, j.ratio, j.excess, (j.p_value, ".2g"), j.flagged,
                     *[j.regimes.get(r, float("nan")) for r in regimes],
                     "; ".join(j.pointers) or "-"] for j in remainder.joints],
                   row_classes=["bad" if j.flagged else "" for j in remainder.joints],
                   floatfmt=".3g", keys=())
    page.heading("Where the nominal residual lies", anchor="where")
    page.table(["joint", "RMS [N·m]", "share", "relative", "drift [N·m/s]"],
               [[n, w.rms[j], _pct(w.share[j]), _pct(w.relative[j]),
                 f"{w.drift[j]:.3g} ± {w.drift_std[j]:.2g}"] for j, n in enumerate(names)])
    page.table(["regime", *names],
               [[reg, *[f"{w.regime_rms[i, j]:.3g} ({_pct(w.regime_fraction[i, j])})"
                        if w.regime_fraction[i, j] > 0 else "-" for j in range(len(names))]]
                for i, reg in enumerate(w.regimes)],
               caption="Residual RMS per regime [N·m] (fraction of samples)")
    bands = [f"{a:g}–{b:.3g} Hz" for a, b in zip(w.band_edges[:-1], w.band_edges[1:])]
    page.table(["band", *names], [[b, *w.band_rms[i]] for i, b in enumerate(bands)],
               caption=f"Residual RMS per frequency band [N·m] (nominal torque band < "
                       f"{w.signal_band:.3g} Hz)", floatfmt=".3g")
    if figures:
        for name, fig in figs.items():
            page.figure(name, fig, FIGURE_CAPTIONS[name])
    if diag.steps:
        last = diag.steps[-1]
        if not last.accepted:
            page.paragraph(f"Selection stopped: {last.reason} (next candidate {last.chosen}).")
    if diag.rollout is not None:
        page.heading("How far the gap shrinks in your simulator", anchor="rollout")
        page.raw(diag.rollout.page().fragment())
    return page


def diagnosis_html(diag: "Diagnosis") -> str:
    """The report as one self-contained HTML page (plots embedded as base64 PNG)."""
    return diagnosis_page(diag).render()


def write_report(diag: "Diagnosis", path: str | Path) -> Path:
    """Write ``path``: ``.html`` (self-contained), ``.txt``, or a directory holding
    ``report.html``, ``report.txt`` and the plots as PNG files. Returns ``path``."""
    path = Path(path)
    if path.suffix == ".txt":
        with replacing(path) as tmp:
            tmp.write_text(diagnosis_text(diag), encoding="utf-8")
        return path
    diagnosis_page(diag).write(path, diagnosis_text(diag))
    return path
