"""The HTML report of an identification: verdict, fit per joint, plots, parameters ± σ, margins.

Sections (:func:`identification_page`):

1. **Findings** — one box whose colour and headline are the worst finding: a poorly predicted
   joint (relative error ``‖τ_j − τ̂_j‖ / ‖τ_j‖`` above :data:`POOR_FIT`, on the held-out data
   when given), the solver's status, physical consistency of every body, directions the data do
   not or only weakly inform, the condition number of the base regressor
   (:data:`~consistid.identification.base.COND_WARN`), and every warning raised while the page
   was built (e.g. extrapolation beyond the training envelope) — each text once.
2. **Fit per joint** — noise σ, training RMS, and on each dataset given the RMS and the relative
   error ``‖τ − τ̂‖ / ‖τ‖``.
3. **Plots** (when data are given) — measured vs predicted torque per joint on the training and
   the held-out data, the residual over time against ±σ, ±2σ, residual histograms against
   ``N(0, σ²)`` with a table that says why each sits inside or outside it, residual spectra
   against each joint's white-noise level (:mod:`consistid.report.plots`).
4. **Base parameters** — estimate ± σ, relative σ, the prior's value and the grouping each one
   stands for (what ``*`` means: the parameter absorbs others), and a plot of the estimates
   with ±2σ bars against the prior.
5. **Bodies** — each body's mass, centre of mass, consistency and margin (smallest eigenvalue of
   the pseudo-inertia ``J``: ``J ≻ 0`` is density realisability, Wensing, Kim & Slotine 2017,
   doi:10.1109/LRA.2017.2729659), then the per-joint terms and every standard parameter.
6. **Provenance** — package versions, input files and their SHA-256, the configuration.
"""

from __future__ import annotations

import json
import warnings
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from .base import COND_WARN
from .summary import recorded_warnings
from ..data.dataset import Dataset
from ..report import plots
from ..report.html import LEVELS, Page, esc, findings_html, unique

if TYPE_CHECKING:
    from .result import IdentificationResult

#: Solver statuses that count as a clean solve.
CLEAN_STATUSES = ("optimal",)
#: A joint whose relative error ``‖τ_j − τ̂_j‖ / ‖τ_j‖`` exceeds this is "poorly predicted"
#: (10 %: the model leaves about 1 % of the joint's torque energy unexplained, more than a
#: rigid-body model with friction leaves on a well-excited arm). Stated in the report.
POOR_FIT = 0.10
#: Above this relative error, with a residual above the noise, the finding is "bad" (red)
#: rather than "warn".
BAD_FIT = 0.30
#: A residual spread within these factors of σ "matches" the noise curve.
SPREAD_BAND = (0.7, 1.5)


def _rate(data: Dataset) -> float:
    dt = np.diff(data.t)
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if dt.size else 1.0


def verdict_findings(res: "IdentificationResult") -> list[tuple[str, str]]:
    """``(level, text)`` per fact a reader must know before using the numbers: the solver's
    status, consistency, uninformed and weakly informed directions, left-out torque rows, the
    condition number, a non-default gravity (levels as in :data:`~consistid.report.html.LEVELS`).
    """
    out = []
    status = res.solver.status
    if status not in CLEAN_STATUSES:
        out.append(("bad" if "inaccurate" not in status else "warn",
                    f"The solver ended with status {status!r} ({res.solver.name}): do not use "
                    "these numbers without checking them."))
    else:
        out.append(("ok", f"The solver ended with status {status!r} ({res.solver.name})."))
    cons = res.consistency
    if cons.ok:
        out.append(("ok", f"Every body is physically consistent (pseudo-inertia ≻ 0, "
                          f"{len(cons.bodies)} bodies)."))
    else:
        bad = [b.body for b in cons.bodies if not b.ok]
        out.append(("warn", f"{len(bad)} of {len(cons.bodies)} bodies are not physically "
                            f"consistent ({', '.join(bad)}): a simulator cannot use them as "
                            "they are."))
    uninformed = tuple(getattr(res, "uninformed", ()))
    if uninformed:
        out.append(("warn", f"{len(uninformed)} base-parameter direction(s) are not informed "
                            f"by the data (σ = inf): {'; '.join(uninformed[:4])}"
                            + (" …" if len(uninformed) > 4 else "")
                            + ". Their values come from the prior or the constraints alone."))
    weak = tuple(getattr(res, "weakly_informed", ()))
    if weak:
        out.append(("warn", f"{len(weak)} direction(s) are only weakly informed by the data: "
                            f"{'; '.join(weak[:3])}" + (" …" if len(weak) > 3 else "")
                            + ". Predictions beyond the training envelope extrapolate along "
                              "them."))
    excluded = tuple(getattr(res, "excluded_joints", ()))
    if excluded:
        out.append(("warn", "Torque rows left out: "
                            f"{res.details.get('excluded_joints', excluded)}."))
    if res.condition_number > COND_WARN:
        out.append(("warn", f"cond(W_b) = {res.condition_number:.4g} > {COND_WARN:.0e}: some "
                            "base parameters are poorly excited (see their relative σ)."))
    if not res.model.has_default_gravity:
        g = ", ".join(f"{v:+.4f}" for v in res.model.gravity)
        out.append(("ok", f"Gravity in the base frame is ({g}) m/s²: these parameters hold "
                          "with it (a URDF does not carry gravity)."))
    return out


def verdict(res: "IdentificationResult") -> tuple[str, list[str]]:
    """``("ok" | "warn" | "bad", lines)``: the worst level of :func:`verdict_findings` and
    their texts."""
    found = verdict_findings(res)
    level = max((lv for lv, _ in found), key=LEVELS.index, default="ok")
    return level, [text for _, text in found]


def fit_findings(res: "IdentificationResult", sets: Sequence[tuple[str, Dataset]]
                 ) -> list[tuple[str, str]]:
    """The poorly predicted joints (relative error above :data:`POOR_FIT`) on the last of
    ``sets`` (the held-out data when given): ``(level, text)`` for the worst one, saying whether
    its residual is at the noise level (its torque is small against its noise: "warn") or above
    it (the model misses something: "bad" beyond :data:`BAD_FIT`), then one line naming the
    others."""
    if not sets:
        return []
    label, data = sets[-1]
    rel, _ = res.relative_error(data)
    rms = res.rms(data)
    poor = [j for j in np.argsort(-rel) if rel[j] > POOR_FIT]
    if not poor:
        return []
    j = poor[0]
    name, ratio = res.model.joint_names[j], rms[j] / res.sigma[j]
    at_noise = ratio <= SPREAD_BAND[1]     # the model cannot do better there: a warning only
    why = ("its residual is about the noise σ: its torque is small against the noise"
           if at_noise else
           f"its residual is {ratio:.3g} × the noise σ: the model misses something there "
           "(see the residual over time and the spectrum)")
    out = [("bad" if rel[j] > BAD_FIT and not at_noise else "warn",
            f"Poorly predicted joint {name}: {100 * rel[j]:.1f} % relative error on the "
            f"{label} data (RMS {rms[j]:.3g} N·m; threshold {100 * POOR_FIT:.0f} %); {why}.")]
    if len(poor) > 1:
        others = ", ".join(f"{res.model.joint_names[k]} {100 * rel[k]:.1f} %" for k in poor[1:])
        out.append(("warn", f"Also above {100 * POOR_FIT:.0f} % relative error on the {label} "
                            f"data: {others}."))
    return out


def spread_rows(res: "IdentificationResult", residual: np.ndarray, label: str
                ) -> list[list[Any]]:
    """Per joint: the residual's RMS against σ and why its histogram sits
    inside, on or outside the noise curve ``N(0, σ²)``."""
    rows = []
    for j, name in enumerate(res.model.joint_names):
        spread = float(np.sqrt(np.mean(residual[:, j] ** 2)))   # RMS: an offset counts
        ratio = spread / res.sigma[j] if res.sigma[j] > 0 else float("inf")
        if ratio < SPREAD_BAND[0]:
            why = ("inside the curve: the residual is narrower than σ — σ was floored or given, "
                   "or the torques are low-pass filtered (filtering removes noise, so σ "
                   "overstates it)")
        elif ratio <= SPREAD_BAND[1]:
            why = ("on the curve: the residual is as wide as the noise σ (σ is estimated from "
                   "the unconstrained least-squares residual on the training data)")
        elif label == "train":
            why = ("outside the curve: this answer fits the training data worse than the "
                   "unconstrained least squares σ comes from — the consistency constraints or "
                   "the prior hold it back: a model error they refuse to absorb, or a "
                   "poorly excited direction")
        else:
            why = ("outside the curve: the residual is wider than the noise — model error "
                   "(friction, payload, a delay) or motion the training data did not cover")
        rows.append([name, spread, res.sigma[j], (ratio, ".3g"), why])
    return rows


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


def _category(caught: Sequence[Any], text: str) -> type[Warning]:
    """The class of the first recorded warning whose ``Class: message`` is ``text``."""
    for w in caught:
        if f"{w.category.__name__}: {w.message}" == text:
            return w.category
    return UserWarning


def _notes(res: "IdentificationResult") -> list[str]:
    return [f"{key}: {value}" for key, value in res.details.items()
            if np.isscalar(value) and not isinstance(value, bytes)]


def identification_page(res: "IdentificationResult", data: Dataset | None = None,
                        held_out: Dataset | None = None, figures: bool = True,
                        max_rows: int | None = None,
                        extra: Sequence[tuple[str, str]] = ()) -> Page:
    """The report as a :class:`~consistid.report.html.Page` (module docstring); ``extra``
    ``(level, text)`` findings of a caller's result join the first box (drive gains).

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
    sets = [(label, d) for label, d in (("train", data), ("held-out", held_out))
            if d is not None]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        predicted = [(label, d, d.require_torque(), res.predict(d)) for label, d in sets]
        findings = fit_findings(res, sets)
        fit_header, fit_rows = _fit_rows(res, sets)
    raised = unique(f"{w.category.__name__}: {w.message}" for w in caught)
    for text in raised:                      # each once, for the caller too
        warnings.warn(text.split(": ", 1)[1], _category(caught, text), stacklevel=3)
    facts = verdict_findings(res)
    # those recorded with the result (details['warning k']: the command line's, at load time)
    recorded = recorded_warnings(res.details)
    # the solver failing outranks everything; then the fit, the warnings, the other facts
    findings = (facts[:1] + findings + [("warn", text) for text in unique([*recorded, *raised])]
                + facts[1:] + list(extra))
    page.raw(findings_html(findings))
    page.key_values([
        ("solver", str(res.solver)),
        ("base parameters", f"{res.base.n_base} of {res.base.n_standard} standard"),
        ("cond(W_b)", f"{res.condition_number:.4g}"),
        ("covariance", res.details.get("covariance", "iid (rows independent)")),
        ("prior", res.details.get("prior", "none (least squares)")),
    ], caption="Solve")

    page.heading("Fit per joint", anchor="fit")
    page.table(fit_header, fit_rows)
    if figures and sets:
        page.heading("Measured vs predicted torque", anchor="torque")
        residuals = []
        for label, d, tau, pred in predicted:
            residuals.append((label, d, tau - pred))
            page.figure(f"torque_{label.replace('-', '_')}",
                        plots.torque_fit(d.t, tau, pred, model.joint_names),
                        f"{label} data: measured (thin black) and predicted (dashed orange) "
                        "joint torque")
        page.heading("Residuals", anchor="residuals")
        for label, d, r in residuals:
            key = label.replace('-', '_')
            page.figure(f"residual_{key}",
                        plots.residual_over_time(d.t, r, model.joint_names, res.sigma),
                        f"{label} residual τ − τ̂ over time per joint; grey band ±σ, dotted "
                        "±2σ of the noise σ the identification used")
            page.figure(f"histogram_{key}",
                        plots.residual_histograms(r, model.joint_names, res.sigma),
                        f"{label} residual τ − τ̂ per joint, with the normal density of the "
                        "noise σ the identification used (black)")
            page.table(["joint", "residual RMS [N·m]", "noise σ [N·m]", "RMS / σ",
                        "why the histogram sits there"],
                       spread_rows(res, r, label),
                       caption=f"{label}: the residual's spread against the noise curve")
            page.figure(f"spectrum_{label.replace('-', '_')}",
                        plots.residual_spectra(r, _rate(d), model.joint_names, res.sigma),
                        f"{label} residual power spectral density (Welch) per joint; dotted: "
                        "white noise of each joint's σ")

    page.heading("Base parameters", anchor="base")
    page.paragraph(STAR_TEXT)
    rows = base_rows(res, max_rows)
    page.table(BASE_HEADER, rows)
    if figures:
        n = len(rows)
        page.figure("parameters", plots.parameter_errorbars(
            res.base.names[:n], res.base_parameters[:n], res.base_std[:n],
            res.base.project(res.prior)[:n]),
            "base parameters: estimate ± 2σ (dot and bar) against the prior (cross), each row "
            "divided by the largest of |estimate|, |prior| and 2σ (a bar reaching ±1 around 0: "
            "the data barely determine it); red: σ = inf, the data do not inform it")
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

    shown = " ".join(text for _, text in findings)
    notes = [n for n in _notes(res)      # a long value the first box already gives: once
             if not (len(n.split(": ", 1)[-1]) >= 12 and n.split(": ", 1)[-1] in shown)]
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
