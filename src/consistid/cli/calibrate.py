r"""``consistid calibrate CONFIG``: a kinematic calibration from a TOML file.

Example (``examples/panda/calibrate.toml``)::

    root = "."                              # relative paths start here (relative to this file)

    [model]
    example = "panda"                       # or urdf = "robot.urdf", locked_joints = [...]

    [calibrate]
    data = "calibration_poses.csv"          # joint columns and x, y, z [, qx, qy, qz, qw] or d
    frame = "panda_hand_tcp"                # default: the end effector
    parameters = ["joints", "tool", "base"] # keywords, names or patterns (default "all")
    sigma = [1e-4, 8.7e-4]                  # m [, rad]; leave out to estimate it
    # loss = "soft_l1"   outliers = "reject"   base = [[...4×4...]]   anchor = [x, y, z]
    urdf = "panda_calibrated.urdf"          # outputs (optional)
    report = "calibration.html"

The data file is a CSV with a header — one column per joint (the model's joint names, or
``q1 … qn``), then ``x, y, z`` (positions), ``x, y, z, qx, qy, qz, qw`` (poses) or ``d``
(distances) — or an NPZ with arrays ``q`` and one of ``positions``, ``poses`` ((N, 7) or
(N, 4, 4)) or ``distances``.

File rules (as every ``consistid`` command): outputs are checked before the calibration runs; an
output that is one of the run's inputs (the configuration, the data, the URDF) is refused even
with ``force``; an existing output needs ``force``; files are written to a temporary name in the
same folder and renamed into place.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..data.npzfile import open_npz
from ..data.formats.csv import read_text, reads_decimal_comma, sniff_delimiter
from ..errors import (ConfigError, DataQualityWarning, DatasetError, MissingColumnsError,
                      OutputPathError)
from ..kinematics.calibrate import calibrate_kinematics
from ..kinematics.result import CalibrationResult
from ..robot.model import RobotModel, model_without_dynamics
from .config import read_toml
from .files import atomic_path, check_output


MODEL_KEYS = ("urdf", "example", "locked_joints", "gravity", "name", "strip_dynamics")
CALIBRATE_KEYS = ("data", "frame", "parameters", "sigma", "loss", "f_scale", "outliers",
                  "outlier_alpha", "base", "anchor", "max_nfev", "urdf", "report")
#: keys passed to :func:`calibrate_kinematics` as they are
OPTION_KEYS = ("frame", "parameters", "sigma", "loss", "f_scale", "outliers", "outlier_alpha",
               "base", "anchor", "max_nfev")
OUTPUT_KEYS = ("urdf", "report")
MEASUREMENT_COLUMNS = {"pose": ("x", "y", "z", "qx", "qy", "qz", "qw"),
                       "position": ("x", "y", "z"), "distance": ("d",)}


@dataclass(frozen=True)
class CalibrationConfig:
    """A parsed ``consistid calibrate`` configuration.

    Attributes
    ----------
    path : the TOML file; ``root`` where relative paths start.
    model : the nominal robot; ``q`` (N, nv) and ``measurements`` read from ``data``.
    options : keyword arguments of :func:`calibrate_kinematics`.
    outputs : ``{"urdf": Path, "report": Path}`` as configured (absolute).
    """

    path: Path
    root: Path
    model: RobotModel
    data: Path
    q: np.ndarray = field(repr=False)
    measurements: np.ndarray = field(repr=False)
    options: dict[str, Any]
    outputs: dict[str, Path]

    @property
    def inputs(self) -> list[Path]:
        """Every file the run reads: never written over."""
        out = [self.path, self.data]
        if self.model.source is not None:
            out.append(Path(self.model.source))
        return out

    def run(self) -> CalibrationResult:
        return calibrate_kinematics(self.model, self.q, self.measurements, **self.options)


def _resolve(root: Path, value: Any, what: str, source: Path) -> Path:
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{source.name}: {what} must be a path string, got {value!r}")
    p = Path(value).expanduser()
    return p if p.is_absolute() else (root / p).resolve()


def _model(table: dict[str, Any], root: Path, source: Path) -> RobotModel:
    unknown = sorted(set(table) - set(MODEL_KEYS))
    if unknown:
        raise ConfigError(f"{source.name}: unknown key(s) {unknown} in [model]; allowed: "
                          f"{list(MODEL_KEYS)}")
    if "example" in table:
        if set(table) != {"example"}:
            raise ConfigError(f"{source.name}: [model] example = {table['example']!r} takes "
                              f"no other key; got {sorted(set(table) - {'example'})}")
        return RobotModel.example(table["example"])
    if "urdf" not in table:
        raise ConfigError(f"{source.name}: [model] needs urdf = \"robot.urdf\" or example = "
                          "\"panda\"")
    urdf = _resolve(root, table["urdf"], "[model] urdf", source)
    kwargs = {k: table[k] for k in ("locked_joints", "gravity", "name") if k in table}
    if table.get("strip_dynamics", False):
        return model_without_dynamics(urdf, **kwargs)[0]
    return RobotModel.from_urdf(urdf, **kwargs)


def read_calibration_data(path: Path, model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """``(q, measurements)`` from a CSV or NPZ file (module docstring for the columns);
    :class:`MissingColumnsError` names what is missing."""
    if path.is_dir():
        raise ConfigError(f"calibration data file {str(path)!r} is a folder; [calibrate] data "
                          "names the .csv or .npz file of poses in it")
    if not path.is_file():
        raise ConfigError(f"calibration data file {str(path)!r} does not exist")
    if path.suffix.lower() == ".npz":
        with open_npz(path) as f:          # headers checked: no pickles, no forged sizes
            if "q" not in f.files:
                raise MissingColumnsError(f"{path.name}: needs an array 'q' (N, {model.nv})")
            found = [k for k in ("poses", "positions", "distances") if k in f.files]
            if len(found) != 1:
                raise MissingColumnsError(f"{path.name}: needs exactly one of the arrays "
                                          f"'poses', 'positions', 'distances'; has {f.files}")
            return np.array(f["q"], dtype=float), np.array(f[found[0]], dtype=float)
    if path.suffix.lower() != ".csv":
        raise ConfigError(f"{path.name}: calibration data must be .csv or .npz")
    header, table = _read_table(path)
    index = {re.sub(r"\s*\[[^\]]*\]$", "", h): i for i, h in enumerate(header)}
    joints = list(model.joint_names)
    if not all(j in index for j in joints):
        joints = [f"q{i + 1}" for i in range(model.nv)]
    missing = [j for j in joints if j not in index]
    if missing:
        raise MissingColumnsError(f"{path.name}: no joint columns {missing} (name them after the "
                                  f"model's joints {model.joint_names} or q1 … q{model.nv}; a "
                                  "unit may follow in brackets: 'q1 [deg]')")
    q = table[:, [index[j] for j in joints]] * [_unit(path, header[index[j]], ANGLE_UNITS)
                                                for j in joints]
    _check_q(path, q, model)
    for kind, cols in MEASUREMENT_COLUMNS.items():
        if all(c in index for c in cols):
            scale = [_unit(path, header[index[c]], LENGTH_UNITS if c in "xyzd" else {"": 1.0})
                     for c in cols]
            values = table[:, [index[c] for c in cols]] * scale
            _check_lengths(path, values[:, :3])
            return q, (values[:, 0] if kind == "distance" else values)
    raise MissingColumnsError(f"{path.name}: no measurement columns: give x, y, z "
                              "(positions), x, y, z, qx, qy, qz, qw (poses) or d (distances)")


#: Units a calibration CSV header may give in brackets (``q1 [deg]``, ``x [mm]``): to SI.
ANGLE_UNITS = {"": 1.0, "rad": 1.0, "deg": np.pi / 180.0, "degree": np.pi / 180.0,
               "degrees": np.pi / 180.0, "°": np.pi / 180.0}
LENGTH_UNITS = {"": 1.0, "m": 1.0, "mm": 1e-3, "cm": 1e-2}
#: Measured positions farther than this (m) from the measurement frame's origin warn
#: (millimetres read as metres).
MAX_REACH = 20.0


def _read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header names (units kept) and numbers of a calibration CSV: the delimiter sniffed as for
    logs (decimal commas with any delimiter but ``,``), a UTF-8 byte-order mark ignored."""
    try:
        text = read_text(path, path.name)
    except DatasetError as exc:
        raise ConfigError(str(exc)) from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise ConfigError(f"{path.name} is empty")
    delimiter = sniff_delimiter("\n".join(lines[:20]), path.name)
    header = [h.strip().strip('"') for h in lines[0].split(delimiter)]
    rows = lines[1:]
    if not rows:
        raise ConfigError(f"{path.name}: a header but no rows")
    if reads_decimal_comma(delimiter, rows[0]):
        rows = [ln.replace(",", ".") for ln in rows]
    try:
        table = np.loadtxt(rows, delimiter=delimiter, ndmin=2)
    except ValueError as exc:
        raise ConfigError(f"{path.name}: not a numeric CSV after the header (delimiter "
                          f"{delimiter!r}; {exc})") from exc
    if table.shape[0] == 0:                     # only comment lines below the header
        raise ConfigError(f"{path.name}: a header but no rows")
    if table.shape[1] != len(header):
        raise ConfigError(f"{path.name}: {len(header)} header names but {table.shape[1]} "
                          "columns")
    return header, table


def _unit(path: Path, name: str, units: dict[str, float]) -> float:
    """The factor to SI of the unit in brackets at the end of column ``name`` (none: 1);
    :class:`ConfigError` for a unit not in ``units``."""
    m = re.search(r"\[([^\]]*)\]$", name)
    unit = m.group(1).strip().lower() if m else ""
    if unit not in units:
        raise ConfigError(f"{path.name}, column {name!r}: unit [{unit}] is not one of "
                          f"{[u for u in units if u] or 'none (a unitless column)'}; convert "
                          "the column")
    return units[unit]


def _check_q(path: Path, q: np.ndarray, model: RobotModel) -> None:
    """Warn (DataQualityWarning) when joint positions leave the model's limits by more than a
    tenth of the range (at least 0.1): degrees read as radians?"""
    lim = model.limits
    found = []
    for j, name in enumerate(model.joint_names):
        lo, hi = lim.lower[j], lim.upper[j]
        if not (np.isfinite(lo) and np.isfinite(hi)):
            continue
        slack = max(0.1 * (hi - lo), 0.1)
        if q[:, j].min() < lo - slack or q[:, j].max() > hi + slack:
            found.append(f"{name!r} spans [{q[:, j].min():.4g}, {q[:, j].max():.4g}] against "
                         f"its limits [{lo:.4g}, {hi:.4g}]")
    if found:
        warnings.warn(f"{path.name}: joint positions beyond the limits: {'; '.join(found[:4])}"
                      f"{' …' if len(found) > 4 else ''}. Are they in degrees? Name the unit in "
                      f"the header ('{model.joint_names[0]} [deg]') or convert them to radians",
                      DataQualityWarning, stacklevel=4)


def _check_lengths(path: Path, xyz: np.ndarray) -> None:
    """Warn (DataQualityWarning) when measured positions lie beyond :data:`MAX_REACH`."""
    far = float(np.max(np.abs(xyz))) if xyz.size else 0.0
    if far > MAX_REACH:
        warnings.warn(f"{path.name}: measured positions reach {far:.4g} m from the measurement "
                      f"frame (more than {MAX_REACH:g} m): are they in millimetres? Name the "
                      "unit in the header ('x [mm]') or convert them to metres",
                      DataQualityWarning, stacklevel=4)


def load_calibration_config(path: str | Path, *, urdf: str | Path | None = None,
                            report: str | Path | None = None) -> CalibrationConfig:
    """Parse a ``consistid calibrate`` TOML file (module docstring); ``urdf``/``report``
    override the configured outputs. Unknown tables or keys raise :class:`ConfigError`."""
    path, root, tables = read_toml(path, ("model", "calibrate"))
    for name in ("model", "calibrate"):
        if not isinstance(tables.get(name), dict):
            raise ConfigError(f"{path.name}: missing table [{name}]")
    model = _model(dict(tables["model"]), root, path)
    t = dict(tables["calibrate"])
    unknown = sorted(set(t) - set(CALIBRATE_KEYS))
    if unknown:
        raise ConfigError(f"{path.name}: unknown key(s) {unknown} in [calibrate]; allowed: "
                          f"{list(CALIBRATE_KEYS)}")
    if "data" not in t:
        raise ConfigError(f"{path.name}: [calibrate] needs data = \"poses.csv\" (joint columns "
                          "and measurement columns)")
    data = _resolve(root, t["data"], "[calibrate] data", path)
    q, measurements = read_calibration_data(data, model)
    options = {k: t[k] for k in OPTION_KEYS if k in t}
    if "base" in options:
        options["base"] = np.asarray(options["base"], dtype=float)
    outputs = {k: _resolve(root, t[k], f"[calibrate] {k}", path) for k in OUTPUT_KEYS if k in t}
    for key, value in (("urdf", urdf), ("report", report)):
        if value is not None:
            outputs[key] = Path(value).expanduser().resolve()
    return CalibrationConfig(path.resolve(), root, model, data, q, measurements, options,
                             outputs)


def run_calibrate(config_path: str | Path, *, urdf: str | Path | None = None,
                  report: str | Path | None = None, force: bool = False
                  ) -> tuple[CalibrationResult, dict[str, Path]]:
    """Run the calibration a TOML file describes; write its outputs.

    Parameters
    ----------
    config_path : the configuration (module docstring).
    urdf, report : override ``[calibrate] urdf`` / ``report``.
    force : replace existing outputs (never an input).

    Returns
    -------
    (result, written) : the :class:`CalibrationResult` and ``{"urdf": path, "report": path}``
    of the files written.
    """
    config = load_calibration_config(config_path, urdf=urdf, report=report)
    for key, out in config.outputs.items():                  # before the work
        check_output(out, inputs=config.inputs, force=force, what=f"[calibrate] {key}")
    if "report" in config.outputs and config.outputs["report"].suffix.lower() not in (".html",
                                                                                      ".htm"):
        raise OutputPathError(f"[calibrate] report {str(config.outputs['report'])!r} must be "
                              "an .html file")
    result = config.run()
    written = {}
    for key, write in (("urdf", result.to_urdf), ("report", result.report)):
        if key in config.outputs:
            with atomic_path(config.outputs[key]) as tmp:
                write(tmp)
            written[key] = config.outputs[key]
    return result, written
