"""Plain-text tables for results (plots live beside the code that owns the figure)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from ..report.html import unique
from .base import COND_WARN
from .weak import WEAK_RATIO

if TYPE_CHECKING:
    from .result import IdentificationResult


def table(header: Sequence[str], rows: Sequence[Sequence[object]], floatfmt: str = ".4g") -> str:
    """A fixed-width text table; floats formatted with ``floatfmt``."""
    def cell(v: object) -> str:
        if isinstance(v, (float, np.floating)):
            return format(float(v), floatfmt)
        return str(v)

    cells = [[cell(v) for v in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h)
              for i, h in enumerate(header)]
    line = "  ".join(h.ljust(w) for h, w in zip(header, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))
            for r in cells]
    return "\n".join(out)


def _relative_cell(res: "IdentificationResult", i: int) -> str:
    """The σ % cell of base parameter ``i``: "at bound" where a non-negativity bound holds it
    (σ over an estimate of ~1e-12 would print as a huge, meaningless percentage)."""
    if res.at_bound[i]:
        return "at bound"
    rel = res.relative_std[i]
    return f"{rel:.1f}" if np.isfinite(rel) else "inf"


def recorded_warnings(details: Mapping[str, object]) -> list[str]:
    """The warnings recorded with a result (``details['warning k']``: the command line's at load
    time, the drive gains' estimate), in their order."""
    return [str(v) for k, v in details.items() if str(k).startswith("warning")]


def warning_lines(texts: Sequence[str], numbered: bool = True) -> list[str]:
    """A text summary's warnings block, as the HTML report's first box has them: each text
    once (:func:`consistid.report.html.unique`), right under the summary's header, as
    ``warning k: …`` (``numbered``) or ``warning: …``."""
    texts = unique(texts)
    label = [f"warning {k + 1}" if numbered else "warning" for k in range(len(texts))]
    return ["", f"Warnings ({len(texts)}, each once):",
            *(f"  - {a}: {t}" for a, t in zip(label, texts))] if texts else []


def identification_summary(res: "IdentificationResult", max_rows: int | None = None) -> str:
    """Base parameters (prior, estimate, ±σ, %σ), per-joint fit, consistency and notes; the
    warnings recorded with the result (``details['warning …']``, e.g. by the command line)
    each once under the header."""
    warned = recorded_warnings(res.details)
    prior_beta = res.base.project(res.prior)
    rows = [(res.base.names[i], prior_beta[i], res.base_parameters[i], res.base_std[i],
             _relative_cell(res, i)) for i in range(res.base.n_base)]
    shown = rows if max_rows is None else rows[:max_rows]
    lines = [f"consistid identification of {res.model.name!r}: method={res.method}, "
             f"{res.n_samples} samples × {res.model.nv} joints, {res.spec.describe()}",
             f"solver        {res.solver}",
             f"base params   {res.base.n_base} of {res.base.n_standard} "
             f"(cond(W_b) = {res.condition_number:.4g})", *warning_lines(warned), "",
             table(["base parameter", "prior", "estimate", "± std", "std %"], shown)]
    if len(shown) < len(rows):
        lines.append(f"… {len(rows) - len(shown)} more rows (summary(max_rows=None) shows all)")
    if np.any(res.at_bound[:len(shown)]):
        lines.append("at bound: held at 0 by its bound ≥ 0 (res.details['active_constraints']), "
                     "so its σ % (σ over an estimate of about 0) says nothing")
    if any(name.endswith("*") for name in res.base.names):
        lines.append("* regroups others the data cannot tell apart from it (res.base.groupings "
                     "lists them; so do the report and parameters.csv)")
    lines += ["", table(["joint", "train RMS [N·m]", "noise σ [N·m]"],
                        [(n, r, s) for n, r, s in zip(res.model.joint_names, res.train_rms,
                                                      res.sigma)])]
    notes = []
    cons = res.consistency
    notes.append(f"physical consistency: {cons}")
    if not res.model.has_default_gravity:   # e.g. a tilt from consistid.estimate_mounting
        g = res.model.gravity
        notes.append(f"gravity in the base frame ({', '.join(f'{v:+.4f}' for v in g)}) m/s²: "
                     "these parameters hold with it (a URDF does not carry gravity)")
    for key, value in res.details.items():
        if str(key).startswith("warning"):
            continue                                  # under the header, once
        if isinstance(value, (float, np.floating)):
            notes.append(f"{key}: {value:.6g}")
        elif np.isscalar(value):
            notes.append(f"{key}: {value}")
    if res.condition_number > COND_WARN:
        notes.append("the condition number is large: some base parameters are poorly excited")
    lines += ["", "Notes:"] + [f"  - {n}" for n in unique(notes)]
    uninformed = getattr(res, "uninformed", ())
    if uninformed:
        source = ("the prior alone" if res.details.get("prior") not in (None, "None")
                  else "the constraints alone (no prior: arbitrary within them)")
        lines += ["", f"Not informed by the data ({len(uninformed)} direction(s); their values "
                      f"come from {source}, ± std = inf):"]
        lines += [f"  - {u}" for u in uninformed]
    weak = getattr(res, "weakly_informed", ())
    if weak:
        lines += ["", f"Weakly informed by the data ({len(weak)}; 1σ moves predictions by more "
                      f"than {WEAK_RATIO:.0%} of the torque on the trained motions run either "
                      "way, or a joint moved one way only; predict warns beyond res.envelope):"]
        lines += [f"  - {w}" for w in weak]
    return "\n".join(lines)
