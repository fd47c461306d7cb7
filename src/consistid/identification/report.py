"""The HTML report of an identification: verdict, fit per joint, plots, parameters ± σ, margins.

Sections (:func:`identification_page`):

1. **Verdict** — the solver's status, physical consistency of every body, the condition number
   of the base regressor (:data:`~consistid.identification.base.COND_WARN`), notes.
2. **Fit per joint** — noise σ, training RMS, and on each dataset given the RMS and the relative
   error ``‖τ − τ̂‖ / ‖τ‖``.
3. **Plots** (when data are given) — measured vs predicted torque per joint on the training and
   the held-out data, residual histograms against ``N(0, σ²)``, residual spectra against each
   joint's white-noise level (:mod:`consistid.report.plots`).
4. **Base parameters** — estimate ± σ, relative σ, the prior's value and the grouping each one
   stands for (what ``*`` means: the parameter absorbs others).
5. **Bodies** — each body's mass, centre of mass, consistency and margin (smallest eigenvalue of
   the pseudo-inertia ``J``: ``J ≻ 0`` is density realisability, Wensing, Kim & Slotine 2017,
   doi:10.1109/LRA.2017.2729659), then the per-joint terms and every standard parameter.
6. **Provenance** — package versions, input files and their SHA-256, the configuration.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from .base import COND_WARN
from ..data.dataset import Dataset
from ..report import plots
from ..report.html import Page, esc

if TYPE_CHECKING:
    from .result import IdentificationResult

#: Solver statuses that count as a clean solve.
CLEAN_STATUSES = ("optimal",)


def _rate(data: Dataset) -> float:
    dt = np.diff(data.t)
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if dt.size else 1.0


def verdict(res: "IdentificationResult") -> tuple[str, list[str]]:
    """``("ok" | "warn" | "bad", lines)``: what a reader must know before using the numbers."""
    lines, level = [], "ok"
    status = res.solver.status
    if status not in CLEAN_STATUSES:
        level = "bad" if "inaccurate" not in status else "warn"
        lines.append(f"The solver ended with status {status!r} ({res.solver.name}): do not use "
                     "these numbers without checking them.")
    else:
        lines.append(f"The solver ended with status {status!r} ({res.solver.name}).")
    cons = res.consistency
    if cons.ok:
        lines.append(f"Every body is physically consistent (pseudo-inertia ≻ 0, "
                     f"{len(cons.bodies)} bodies).")
    else:
        level = "bad" if level == "bad" else "warn"
        bad = [b.body for b in cons.bodies if not b.ok]
        lines.append(f"{len(bad)} of {len(cons.bodies)} bodies are not physically consistent "
                     f"({', '.join(bad)}): a simulator cannot use them as they are.")
    uninformed = tuple(getattr(res, "uninformed", ()))
    if uninformed:
        level = "bad" if level == "bad" else "warn"
        lines.append(f"{len(uninformed)} base-parameter direction(s) are not informed by the "
                     f"data (σ = inf): {'; '.join(uninformed[:4])}"
                     + (" …" if len(uninformed) > 4 else "")
                     + ". Their values come from the prior or the constraints alone.")
    weak = tuple(getattr(res, "weakly_informed", ()))
    if weak:
        level = "bad" if level == "bad" else "warn"
        lines.append(f"{len(weak)} direction(s) are only weakly informed by the data: "
                     f"{'; '.join(weak[:3])}" + (" …" if len(weak) > 3 else "")
                     + ". Predictions beyond the training envelope extrapolate along them.")
    excluded = tuple(getattr(res, "excluded_joints", ()))
    if excluded:
        level = "bad" if level == "bad" else "warn"
        lines.append(f"Torque rows left out: {res.details.get('excluded_joints', excluded)}.")
    if res.condition_number > COND_WARN:
        level = "bad" if level == "bad" else "warn"
        lines.append(f"cond(W_b) = {res.condition_number:.4g} > {COND_WARN:.0e}: some base "
                     "parameters are poorly excited (see their relative σ).")
    if not res.model.has_default_gravity:
        g = ", ".join(f"{v:+.4f}" for v in res.model.gravity)
        lines.append(f"Gravity in the base frame is ({g}) m/s²: these parameters hold with it "
                     "(a URDF does not carry gravity).")
    return level, lines


def _fit_rows(res: "IdentificationResult", sets: Sequence[tuple[str, Dataset]]
              ) -> tuple[list[str], list[list[Any]]]:
    """Per-joint RMS and relative error ``‖τ − τ̂‖ / ‖τ‖`` on each data set, then their totals
    over the joints whose rows were fitted (an excluded joint's cells say so: no rows fitted,
    its channel perhaps dead)."""
    header = ["joint", "noise σ [N·m]", "RMS at the fit [N·m]"]
    kept = np.array([n not in res.excluded_joints for n in res.model.joint_names])
    columns = []
    for label, data in sets:
        r, tau = res.residual(data), data.require_torque()
        norm = np.linalg.norm(tau, axis=0)
        rel = np.linalg.norm(r, axis=0) / np.where(kept, norm, 1.0)
        total = float(np.linalg.norm(r[:, kept]) / np.linalg.norm(tau[:, kept]))
        columns.append((np.sqrt(np.mean(r ** 2, axis=0)), rel, total))
        header += [f"{label} RMS [N·m]", f"{label} rel. error"]
    rows = []
    for j, name in enumerate(res.model.joint_names):
        row: list[Any] = [name, res.sigma[j], res.train_rms[j]]
        for rms, rel, _ in columns:
            row += [rms[j], f"{100 * rel[j]:.2f} %"] if kept[j] else ["excluded", "excluded"]
        rows.append(row)
    if columns:
        row = ["all joints" if kept.all() else "kept joints", "", ""]
        for rms, _, total in columns:
            row += [float(np.sqrt(np.mean(rms[kept] ** 2))), f"{100 * total:.2f} %"]
        rows.append(row)
    return header, rows


def base_rows(res: "IdentificationResult", max_rows: int | None = None) -> list[list[Any]]:
    """One row per base parameter: name, estimate, σ, σ % (``inf`` where the estimate is 0),
    the prior's value, the grouping it stands for."""
    prior = res.base.project(res.prior)
    rows = []
    for i, (name, grouping) in enumerate(zip(res.base.names, res.base.groupings)):
        rel = "at bound" if res.at_bound[i] else (float(res.relative_std[i]), ".3g")
        rows.append([name, res.base_parameters[i], res.base_std[i], rel,
                     prior[i], grouping])
        if max_rows is not None and len(rows) >= max_rows:
            break
    return rows


BASE_HEADER = ["base parameter", "estimate", "± σ", "σ %", "prior", "stands for"]

STAR_TEXT = ("Torques determine only linear combinations of the standard parameters: the base "
             "parameters (Gautier 1991). A name marked * regroups others: β = π_i + Σ_d k_d·π_d, "
             "the standard parameter it is named after plus the ones listed in “stands for”, "
             "which the data cannot tell apart from it. A name without * is the standard "
             "parameter itself. σ is the standard deviation of the estimate from the data "
             "(for the SDP: of the unconstrained fit at the answer). σ % reads \"at bound\" "
             "where a bound ≥ 0 (friction, armature) holds the estimate at 0.")


def body_rows(res: "IdentificationResult") -> tuple[list[list[Any]], list[str]]:
    """Per body: mass, CoM, consistent?, pseudo-inertia margin, principal moments, reason."""
    rows, classes = [], []
    for b, check in enumerate(res.consistency.bodies):
        p = res.inertial_parameters[10 * b:10 * b + 10]
        com = p[1:4] / p[0] if p[0] > 0 else np.full(3, np.nan)
        moments = ("-" if check.principal_moments is None
                   else ", ".join(f"{v:.4g}" for v in check.principal_moments))
        rows.append([check.body, p[0], f"({com[0]:.4g}, {com[1]:.4g}, {com[2]:.4g})",
                     check.ok, check.min_pseudo_inertia_eigenvalue, moments,
                     check.reason or "-"])
        classes.append("" if check.ok else "bad")
    return rows, classes


BODY_HEADER = ["body", "mass [kg]", "centre of mass [m]", "consistent",
               "margin: λ_min(J) [kg·m²]", "principal moments at CoM [kg·m²]", "violation"]


def _joint_term_rows(res: "IdentificationResult") -> tuple[list[str], list[list[Any]]]:
    n = res.model.n_inertial
    names, values = res.parameter_names[n:], res.parameters[n:]
    by_joint: dict[str, dict[str, float]] = {}
    suffixes: list[str] = []
    for name, value in zip(names, values):
        joint, _, suffix = name.rpartition(".")
        by_joint.setdefault(joint, {})[suffix] = float(value)
        if suffix not in suffixes:
            suffixes.append(suffix)
    rows = [[j, *[by_joint.get(j, {}).get(s, "") for s in suffixes]]
            for j in res.model.joint_names if j in by_joint]
    return ["joint", *suffixes], rows


def _notes(res: "IdentificationResult") -> list[str]:
    return [f"{key}: {value}" for key, value in res.details.items()
            if np.isscalar(value) and not isinstance(value, bytes)]


def identification_page(res: "IdentificationResult", data: Dataset | None = None,
                        held_out: Dataset | None = None, figures: bool = True,
                        max_rows: int | None = None) -> Page:
    """The report as a :class:`~consistid.report.html.Page` (module docstring).

    Parameters
    ----------
    data : the training data (for the measured-vs-predicted plots and the fit table).
    held_out : data not used in the fit.
    figures : draw the plots (``False`` for a quick page, e.g. Jupyter's ``_repr_html_``).
    max_rows : show at most this many base parameters (default all).
    """
    model = res.model
    page = Page(f"consistid identification: {model.name}",
                f"method {res.method}, {res.n_samples} samples × {model.nv} joints, "
                f"{res.spec.describe()}")
    level, lines = verdict(res)
    page.raw(f'<div class="verdict {level}">' + "".join(f"<p>{esc(x)}</p>" for x in lines)
             + "</div>")
    page.key_values([
        ("solver", str(res.solver)),
        ("base parameters", f"{res.base.n_base} of {res.base.n_standard} standard"),
        ("cond(W_b)", f"{res.condition_number:.4g}"),
        ("covariance", res.details.get("covariance", "iid (rows independent)")),
        ("prior", res.details.get("prior", "none (least squares)")),
    ], caption="Solve")

    sets = [(label, d) for label, d in (("train", data), ("held-out", held_out))
            if d is not None]
    page.heading("Fit per joint", anchor="fit")
    header, rows = _fit_rows(res, sets)
    page.table(header, rows)
    if figures and sets:
        page.heading("Measured vs predicted torque", anchor="torque")
        residuals = []
        for label, d in sets:
            tau, pred = d.require_torque(), res.predict(d)
            residuals.append((label, d, tau - pred))
            page.figure(f"torque_{label.replace('-', '_')}",
                        plots.torque_fit(d.t, tau, pred, model.joint_names),
                        f"{label} data: measured (grey) and predicted (blue) joint torque")
        page.heading("Residuals", anchor="residuals")
        for label, d, r in residuals:
            page.figure(f"histogram_{label.replace('-', '_')}",
                        plots.residual_histograms(r, model.joint_names, res.sigma),
                        f"{label} residual τ − τ̂ per joint, with the normal density of the "
                        "noise σ the identification used (black)")
            page.figure(f"spectrum_{label.replace('-', '_')}",
                        plots.residual_spectra(r, _rate(d), model.joint_names, res.sigma),
                        f"{label} residual power spectral density (Welch) per joint; dotted: "
                        "white noise of each joint's σ")

    page.heading("Base parameters", anchor="base")
    page.paragraph(STAR_TEXT)
    rows = base_rows(res, max_rows)
    page.table(BASE_HEADER, rows)
    if len(rows) < res.base.n_base:
        page.paragraph(f"… {res.base.n_base - len(rows)} more (report(max_rows=None) shows all)")
    if res.base.unidentifiable:
        page.paragraph("Standard parameters that do not act on the torques at all (the prior "
                       "decides them): " + ", ".join(res.base.unidentifiable))

    page.heading("Bodies: consistency and margins", anchor="bodies")
    page.paragraph("A body is physically consistent when its pseudo-inertia J = [[Σ, h], [hᵀ, m]] "
                   "(Σ = ½ tr(I)·1 − I, h = m·c) is positive definite: then some density "
                   "distribution has these parameters. The margin is J's smallest eigenvalue.")
    rows, classes = body_rows(res)
    page.table(BODY_HEADER, rows, row_classes=classes)
    header, rows = _joint_term_rows(res)
    if rows:
        page.table(header, rows, caption="Per-joint terms (fc Coulomb N·m, fv viscous "
                   "N·m·s/rad, fo offset N·m, ps1/pc1 once-per-revolution N·m, Ia armature kg·m²)")
    if figures:
        page.raw("<details><summary>every standard parameter</summary>")
        page.table(["standard parameter", "estimate", "prior (URDF)"],
                   [[n, v, p] for n, v, p in zip(res.parameter_names, res.parameters,
                                                 res.prior)])
        page.raw("</details>")

    notes = _notes(res)
    if notes:
        page.heading("Notes", anchor="notes")
        page.bullets(notes)
    prov = res.provenance
    if prov:
        page.heading("Provenance", anchor="provenance")
        pairs = [("created", prov.get("created", "?")), ("platform", prov.get("platform", "?"))]
        pairs += [(f"version of {k}", v) for k, v in prov.get("packages", {}).items()]
        page.key_values(pairs)
        inputs = prov.get("inputs", [])
        if inputs:
            page.table(["input file", "bytes", "SHA-256"],
                       [(r["path"], r["bytes"], r["sha256"]) for r in inputs])
        if prov.get("config") is not None:
            page.raw("<details><summary>configuration</summary><pre>"
                     + esc(json.dumps(prov["config"], indent=1, default=str)) + "</pre></details>")
    return page


def standard_set_page(answer: Any, title: str) -> Page:
    """A quick page for any answer carrying a full standard vector (e.g. a
    :class:`~consistid.estimation.recover.RecoveryResult`): each body's consistency and margin,
    the per-joint terms, and its text summary when it has one."""
    page = Page(title)
    page.heading("Bodies: consistency and margins", anchor="bodies")
    rows, classes = body_rows(answer)
    page.table(BODY_HEADER, rows, row_classes=classes)
    header, rows = _joint_term_rows(answer)
    if rows:
        page.table(header, rows, caption="Per-joint terms")
    summary = getattr(answer, "summary", None)
    if callable(summary):
        page.heading("Summary", anchor="summary")
        page.raw(f"<pre>{esc(summary())}</pre>")
    return page
