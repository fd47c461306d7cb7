"""The result of a kinematic calibration: corrected model, uncertainty, what was not seen."""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
import scipy.stats

from ..errors import DatasetError
from ..identification.result import SolverReport
from ..identification.summary import table
from ..robot.model import RobotModel
from .export import write_calibrated_urdf
from .identifiability import Unidentifiable
from .measurements import as_measurements, joint_coordinates, residuals

if TYPE_CHECKING:
    from .parameters import KinematicParameters


def _fmt(value: float, unit: str) -> str:
    """A correction for tables: metres as mm, radians as degrees."""
    if not np.isfinite(value):
        return "—"
    return f"{value * 1e3:+.4f} mm" if unit == "m" else f"{np.degrees(value):+.5f}°"


def _std(value: float, unit: str) -> str:
    if not np.isfinite(value):
        return "held"
    return f"{value * 1e3:.4f} mm" if unit == "m" else f"{np.degrees(value):.5f}°"


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Calibrated kinematics, with the numbers needed to trust them.

    Attributes
    ----------
    model : the corrected :class:`RobotModel` (its ``pin_model`` carries the calibrated joint
        placements, zero offsets folded in, axes and the measured frame's placement): feed it to
        :func:`consistid.identify`. It has no source URDF; :meth:`to_urdf` writes one.
    nominal : the model calibrated (the URDF).
    frame, kind : the measured frame and the measurement kind.
    parameter_names : the selected parameters; ``values`` their corrections (m, rad).
    std : (p,) standard deviations; ``nan`` for parameters held at the URDF value
        (``identified`` False: each is an exact combination of identified ones, listed in
        ``unidentifiable``).
    covariance : (p, p) ``(JᵀΣ⁻¹J)⁻¹`` over the identified ones; ``nan`` rows/columns for held.
    unidentifiable : the null directions, as named combinations
        (:class:`~consistid.kinematics.identifiability.Unidentifiable`); ``null_space`` (p, k).
    null_residual : largest ``‖J n‖/‖J_d‖`` of those directions at the solution (≈ 1e-12: they
        are exact).
    base, base_initial : 4×4 pose of the robot base in the measurement frame, estimated and
        initial (None for distances); ``anchor`` the anchor point (distances).
    residuals_before, residuals_after : (N, m) predicted − measured with the URDF (measurement
        frame fitted) and with the calibration; every measurement, rejected ones included.
    mahalanobis : (N,) ``√(rᵢᵀ Σᵢ⁻¹ rᵢ)`` after calibration; ``rejected`` the dropped indices.
    noise_covariance : (N, m, m) the covariances used; ``sigma_source`` given or estimated.
    chi2_reduced : weighted RSS / (n − r): ≈ 1 when σ describes the residuals.
    condition_number : of the whitened, column-normalised Jacobian of the identified ones.
    solver : :class:`~consistid.identification.result.SolverReport`.
    held_at_solution : parameters a generic robot shows but these data, at the URDF and at
        this solution, do not (or only with σ above ``calibrate.WEAK_STD``: special geometry,
        e.g. a measured point exactly on the last joint's axis); held at the URDF's values too.
    """

    model: RobotModel
    nominal: RobotModel
    frame: str
    kind: str
    parameter_names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    identified: np.ndarray
    unidentifiable: tuple[Unidentifiable, ...]
    null_space: np.ndarray
    null_residual: float
    base: np.ndarray | None
    base_initial: np.ndarray | None
    anchor: np.ndarray | None
    residuals_before: np.ndarray
    residuals_after: np.ndarray
    mahalanobis: np.ndarray
    rejected: tuple[int, ...]
    noise_covariance: np.ndarray
    sigma_source: str
    chi2_reduced: float
    condition_number: float
    n_measurements: int
    solver: SolverReport
    chart: "KinematicParameters" = field(repr=False)
    full_values: np.ndarray = field(repr=False)
    held_at_solution: tuple[str, ...] = ()

    # ----------------------------------------------------------------------------- values
    @property
    def corrections(self) -> dict[str, float]:
        """``{name: correction}`` of every selected parameter (held ones are 0)."""
        return dict(zip(self.parameter_names, self.values.tolist()))

    @property
    def identified_names(self) -> tuple[str, ...]:
        return tuple(n for n, k in zip(self.parameter_names, self.identified) if k)

    @cached_property
    def correlation(self) -> np.ndarray:
        """(p, p) correlations of the estimates (``nan`` for held parameters)."""
        s = self.std
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(s, s)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Two-sided ``1 − alpha`` intervals of the corrections, (p, 2); ``nan`` for held."""
        z = scipy.stats.norm.ppf(1 - alpha / 2)
        return np.column_stack([self.values - z * self.std, self.values + z * self.std])

    def units(self) -> list[str]:
        return [self.chart.units(n) for n in self.parameter_names]

    # ----------------------------------------------------------------------------- errors
    def _blocks(self, res: np.ndarray) -> dict[str, np.ndarray]:
        """Per-measurement error norms: position (m) / orientation (rad) / distance (m)."""
        if self.kind == "distance":
            return {"distance": np.abs(res[:, 0])}
        out = {"position": np.linalg.norm(res[:, :3], axis=1)}
        if self.kind == "pose":
            out["orientation"] = np.linalg.norm(res[:, 3:], axis=1)
        return out

    @property
    def errors_before(self) -> dict[str, np.ndarray]:
        """Per-measurement error norms with the URDF (measurement frame fitted)."""
        return self._blocks(self.residuals_before)

    @property
    def errors_after(self) -> dict[str, np.ndarray]:
        return self._blocks(self.residuals_after)

    def residuals(self, q: object, measurements: object) -> np.ndarray:
        """Predicted − measured (N, m) on other (held-out) configurations and measurements of
        the same kind, with the calibrated model and measurement frame / anchor."""
        qa = joint_coordinates(self.nominal, q)
        meas = as_measurements(measurements, qa.shape[0])
        if meas.kind != self.kind:
            raise DatasetError(f"{meas.kind} measurements given to a calibration from "
                               f"{self.kind} measurements")
        pos, rot, _ = self.chart.frame_kinematics(self.full_values, qa, False)
        return residuals(meas, pos, rot, self._base_se3(), self.anchor)

    def rms(self, q: object, measurements: object) -> dict[str, float]:
        """Per-component RMS of :meth:`residuals` by block (m, rad), e.g. to compare with σ."""
        res = self.residuals(q, measurements)
        out = {}
        for name, cols in (("position", slice(0, 3)), ("orientation", slice(3, 6)),
                           ("distance", slice(0, 1))):
            if (name == "distance") == (self.kind == "distance") and res.shape[1] > cols.start:
                out[name] = float(np.sqrt(np.mean(res[:, cols] ** 2)))
        return out

    def _base_se3(self) -> pin.SE3:
        return (pin.SE3.Identity() if self.base is None
                else pin.SE3(self.base[:3, :3], self.base[:3, 3]))

    # ----------------------------------------------------------------------------- output
    def to_urdf(self, path: str | Path) -> Path:
        """Write the nominal URDF with the calibrated joint origins and axes (and the measured
        frame's fixed joint); every other byte stays (:mod:`consistid.kinematics.export`).
        ``RobotModel.from_urdf(path, locked_joints=…)`` then gives :attr:`model`'s kinematics."""
        return write_calibrated_urdf(self, path)

    def _rows(self) -> list[tuple[str, str, str, str, str]]:
        """Identified parameters first (in name order), then the held ones."""
        rows, held = [], []
        for name, v, s, k in zip(self.parameter_names, self.values, self.std, self.identified):
            unit = self.chart.units(name)
            row = (name, self.chart.describe(name), _fmt(v, unit) if k else "0 (held)",
                   _std(s, unit), f"{abs(v / s):.1f}" if k and s > 0 else "")
            (rows if k else held).append(row)
        return rows + held

    def _notes(self) -> list[str]:
        notes = [f"identified {int(self.identified.sum())} of {len(self.parameter_names)} "
                 f"selected parameters; {len(self.unidentifiable)} unidentifiable combinations "
                 "held at the URDF's values (below)",
                 f"noise σ {self.sigma_source}; χ²/dof = {self.chi2_reduced:.3g} (≈ 1 when σ "
                 "describes the residuals)",
                 f"cond(J) = {self.condition_number:.4g} (whitened, columns normalised)"]
        units = np.array(self.units())
        for unit, label in (("m", "length"), ("rad", "angle")):
            pick = np.flatnonzero(self.identified & (units == unit))
            if pick.size:
                worst = pick[int(np.argmax(self.std[pick]))]
                notes.append(f"least certain {label}: {self.parameter_names[worst]} ± "
                             f"{_std(self.std[worst], unit)} (median σ "
                             f"{_std(float(np.median(self.std[pick])), unit)})")
        if self.held_at_solution:
            notes.append(f"held because the data do not see them at the solution (special "
                         f"geometry, e.g. the measured point on a joint axis): "
                         f"{', '.join(self.held_at_solution)}")
        if self.rejected:
            worst = ", ".join(f"{i} (d = {self.mahalanobis[i]:.1f}σ)" for i in self.rejected[:10])
            notes.append(f"{len(self.rejected)} outlier(s) rejected and not fitted: {worst}"
                         f"{' …' if len(self.rejected) > 10 else ''}")
        else:
            notes.append("no outlier rejected")
        if any(n.startswith("base.") for n in self.identified_names):
            notes.append("the measurement frame was estimated, so it absorbed the first joint's "
                         "origin (held): the robot's tilt relative to gravity is not known from "
                         "these measurements. For dynamics, register the tracker to the base "
                         "(parameters without 'base', base=T) or estimate the tilt from torques "
                         "(consistid.estimate_mounting(result.model, data))")
        if self.chart.fixed_axes:
            notes.append("axes of continuous joints are not turned (no such Pinocchio joint); "
                         "their tilt is a combination of origin rotations")
        if self.null_residual > 1e-6:
            notes.append(f"the held directions are not exact at the solution (relative "
                         f"residual {self.null_residual:.2g}): the data see them weakly")
        return notes

    def _error_rows(self) -> list[tuple[str, str, str, str]]:
        rows = []
        for key in self.errors_before:
            unit = "rad" if key == "orientation" else "m"
            b, a = self.errors_before[key], self.errors_after[key]
            keep = np.setdiff1d(np.arange(b.size), self.rejected)
            scale, label = (1e3, "mm") if unit == "m" else (np.degrees(1.0), "°")
            rows.append((f"{key} [{label}]", f"{np.sqrt(np.mean(b[keep] ** 2)) * scale:.4g}",
                         f"{np.sqrt(np.mean(a[keep] ** 2)) * scale:.4g}",
                         f"{a[keep].max() * scale:.4g}"))
        return rows

    def summary(self, max_rows: int | None = None) -> str:
        """Parameters (correction ± σ), errors before/after, unidentifiable directions, notes."""
        rows = self._rows()
        shown = rows if max_rows is None else rows[:max_rows]
        lines = [f"consistid kinematic calibration of {self.nominal.name!r} at {self.frame!r}: "
                 f"{self.n_measurements} {self.kind} measurements",
                 f"solver        {self.solver}", "",
                 table(["parameter", "what", "correction", "± std", "|c|/σ"], shown)]
        if len(shown) < len(rows):
            lines.append(f"… {len(rows) - len(shown)} more rows (summary(max_rows=None))")
        lines += ["", "error norm per measurement (RMS over the fitted ones):",
                  table(["", "URDF", "calibrated", "max calibrated"], self._error_rows())]
        if self.base is not None:
            lines += ["", "measurement frame (robot base in it): "
                      + np.array2string(self.base[:3], precision=5, suppress_small=True)
                      .replace("\n", "")]
        if self.anchor is not None:
            lines += ["", f"anchor (base frame, m): {np.round(self.anchor, 6).tolist()}"]
        if self.unidentifiable:
            lines += ["", "unidentifiable (each combination changes no measurement):"]
            lines += [f"  {u}" for u in self.unidentifiable[: (max_rows or None)]]
            if max_rows is not None and len(self.unidentifiable) > max_rows:
                lines.append(f"  … {len(self.unidentifiable) - max_rows} more")
        lines += ["", "Notes:"] + [f"  - {n}" for n in self._notes()]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary(max_rows=25)

    def _html_tables(self) -> str:
        def tab(header, rows):
            head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
            body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r)
                           + "</tr>" for r in rows)
            return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"

        parts = [f"<h3>Kinematic calibration of {html.escape(self.nominal.name)} at "
                 f"{html.escape(self.frame)}: {self.n_measurements} {self.kind} measurements"
                 "</h3>", f"<p>{html.escape(str(self.solver))}</p>",
                 tab(["parameter", "what", "correction", "± std", "|c|/σ"], self._rows()),
                 "<h4>Error norm per measurement (RMS)</h4>",
                 tab(["", "URDF", "calibrated", "max calibrated"], self._error_rows())]
        if self.unidentifiable:
            parts += ["<h4>Unidentifiable combinations (held at the URDF's values)</h4><ul>"
                      + "".join(f"<li><code>{html.escape(str(u))}</code></li>"
                                for u in self.unidentifiable) + "</ul>"]
        parts += ["<h4>Notes</h4><ul>" + "".join(f"<li>{html.escape(n)}</li>"
                                                 for n in self._notes()) + "</ul>"]
        return "\n".join(parts)

    def _repr_html_(self) -> str:
        return self._html_tables()

    def figure(self):
        """A matplotlib ``Figure``: error norm per measurement, URDF vs calibrated."""
        from matplotlib.figure import Figure

        blocks = list(self.errors_before)
        fig = Figure(figsize=(8, 2.6 * len(blocks)))
        for i, key in enumerate(blocks):
            ax = fig.add_subplot(len(blocks), 1, i + 1)
            scale, label = (1e3, "mm") if key != "orientation" else (np.degrees(1.0), "deg")
            idx = np.arange(self.n_measurements)
            ax.bar(idx - 0.2, self.errors_before[key] * scale, 0.4, label="URDF")
            ax.bar(idx + 0.2, self.errors_after[key] * scale, 0.4, label="calibrated")
            for r in self.rejected:
                ax.axvline(r, color="red", lw=0.8, ls="--")
            ax.set_ylabel(f"{key} error [{label}]")
            ax.legend(loc="upper right")
        fig.axes[-1].set_xlabel("measurement (red: rejected outlier)")
        fig.tight_layout()
        return fig

    def report(self, path: str | Path) -> Path:
        """Write an HTML report (tables, the per-measurement error plot embedded) to ``path``
        (a ``.html`` file, or a folder that gets ``calibration.html``); returns the file."""
        path = Path(path)
        if path.suffix.lower() not in (".html", ".htm"):
            path.mkdir(parents=True, exist_ok=True)
            path = path / "calibration.html"
        buf = io.BytesIO()
        self.figure().savefig(buf, format="png", dpi=90)
        img = base64.b64encode(buf.getvalue()).decode("ascii")
        text = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>consistid kinematic "
                "calibration</title><style>body{font-family:sans-serif}table{border-collapse:"
                "collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}"
                "</style></head><body>" + self._html_tables()
                + f"<h4>Error per measurement</h4><img src='data:image/png;base64,{img}'/>"
                + f"<pre>{html.escape(self.residual_table())}</pre>"
                + f"<h4>Text summary</h4><pre>{html.escape(self.summary())}</pre>"
                + "</body></html>\n")
        path.write_text(text, encoding="utf-8")
        return path

    def residual_table(self) -> str:
        """Per measurement: error before / after and Mahalanobis distance (text)."""
        rows = []
        for i in range(self.n_measurements):
            b = {k: v[i] for k, v in self.errors_before.items()}
            a = {k: v[i] for k, v in self.errors_after.items()}
            rows.append((i, *(f"{b[k] * 1e3:.4g}" if k != "orientation"
                              else f"{np.degrees(b[k]):.4g}" for k in b),
                         *(f"{a[k] * 1e3:.4g}" if k != "orientation"
                           else f"{np.degrees(a[k]):.4g}" for k in a),
                         f"{self.mahalanobis[i]:.2f}", "rejected" if i in self.rejected else ""))
        keys = list(self.errors_before)
        units = {"position": "mm", "orientation": "°", "distance": "mm"}
        head = (["#"] + [f"{k} URDF [{units[k]}]" for k in keys]
                + [f"{k} calibrated [{units[k]}]" for k in keys] + ["d [σ]", ""])
        return table(head, rows)

