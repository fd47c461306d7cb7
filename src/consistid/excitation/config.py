"""Excitation designs described by a TOML file (``consistid excite CONFIG``).

Example (relative paths are relative to the file's folder)::

    [model]
    robot = "panda"                 # an example robot, or: urdf = "arm.urdf"
    # locked_joints = ["finger_joint"]   gravity = [0.0, 0.0, -9.81]

    [excite]
    trajectory = "fourier"          # or "bspline" (then via_points = 10, degree = 4)
    harmonics = 5
    period = 10.0                   # s
    criterion = "cond"              # "d-opt", "e-opt"
    friction = ["coulomb", "viscous", "offset"]   # columns to be identified ([] for none)
    seed = 0
    n_starts = 4
    max_iter = 100
    rate = 500.0                    # Hz of the CSV
    output = "excitation.csv"

    [excite.limits]                 # overrides of the URDF limits (scalars or one per joint)
    acceleration = [15, 7.5, 10, 12.5, 15, 20, 20]
    torque = true                   # URDF efforts; false: unchecked
    floor = { z_min = 0.2 }
    sphere = { radius = 0.3 }
    workspace = { lower = [-0.9, -0.9, 0.2], upper = [0.9, 0.9, 1.3] }

    [excite.boundary]               # optional: q_start, q_end, dq_start, ... (BoundaryConditions)

Unknown keys raise :class:`~consistid.errors.OptionError` naming the table and the key.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..errors import OptionError
from ..model import RobotModel
from .design import ExcitationDesign, StartResult, design_excitation
from .limits import CartesianBox, ExcitationLimits, FloorPlane, KeepOutSphere
from .trajectory import BoundaryConditions

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

MODEL_KEYS = {"robot", "urdf", "locked_joints", "gravity", "name"}
EXCITE_KEYS = {"trajectory", "harmonics", "period", "criterion", "friction", "armature", "seed",
               "n_starts", "max_iter", "method", "via_points", "degree", "column_scale",
               "torque_weight", "noise_std", "n_grid", "n_check", "safety", "rate", "output",
               "limits", "boundary"}
LIMIT_KEYS = {"acceleration", "velocity", "torque", "lower", "upper", "workspace", "floor",
              "sphere"}
BOUNDARY_KEYS = {"q_start", "q_end", "dq_start", "dq_end", "ddq_start", "ddq_end"}
PASSED_ON = ("trajectory", "harmonics", "period", "criterion", "armature", "seed", "n_starts",
             "max_iter", "method", "via_points", "degree", "column_scale", "torque_weight",
             "noise_std", "n_grid", "n_check", "safety")


def _table(where: str, value: Any, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise OptionError(f"{where} must be a table, got {value!r}")
    unknown = sorted(set(value) - allowed)
    if unknown:
        raise OptionError(f"unknown key(s) {unknown} in {where}; allowed: {sorted(allowed)}")
    return dict(value)


def _constraint(where: str, value: Any, cls: type, allowed: set[str]) -> Any:
    if value is None:
        return None
    sub = _table(where, value, allowed)
    if "frames" in sub:
        sub["frames"] = tuple(sub["frames"])
    try:
        return cls(**sub)
    except TypeError as exc:
        raise OptionError(f"{where}: {exc}") from exc


@dataclass(frozen=True)
class ExcitationConfig:
    """A parsed config: the robot, the keyword arguments of :func:`design_excitation`, the CSV
    path and rate."""

    model: RobotModel
    options: dict[str, Any]
    output: Path
    rate: float

    def run(self, progress: Callable[[StartResult], None] | None = None) -> ExcitationDesign:
        return design_excitation(self.model, progress=progress, **self.options)


def _model(where: str, t: dict[str, Any], here: Path) -> RobotModel:
    if ("robot" in t) == ("urdf" in t):
        raise OptionError(f"{where}: give exactly one of robot = \"panda\" (example robot) or "
                          "urdf = \"path/to/robot.urdf\"")
    if "robot" in t:
        return RobotModel.example(t["robot"])
    kwargs = {k: t[k] for k in ("locked_joints", "gravity", "name") if k in t}
    return RobotModel.from_urdf(here / t["urdf"], **kwargs)


def load_config(path: str | Path) -> ExcitationConfig:
    """Read and check a TOML excitation config (module docstring for the layout)."""
    path = Path(path)
    if not path.is_file():
        raise OptionError(f"config file {str(path)!r} does not exist")
    with open(path, "rb") as fh:
        try:
            cfg = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise OptionError(f"{path.name} is not valid TOML: {exc}") from exc
    here = path.resolve().parent
    model = _model(f"{path.name} [model]",
                   _table(f"{path.name} [model]", cfg.get("model"), MODEL_KEYS), here)
    ex = _table(f"{path.name} [excite]", cfg.get("excite", {}), EXCITE_KEYS)
    lim = _table(f"{path.name} [excite.limits]", ex.get("limits", {}), LIMIT_KEYS)
    limits = ExcitationLimits.from_model(
        model, **{k: lim[k] for k in ("acceleration", "velocity", "torque", "lower", "upper")
                  if k in lim},
        workspace=_constraint("[excite.limits] workspace", lim.get("workspace"), CartesianBox,
                              {"lower", "upper", "frames"}),
        floor=_constraint("[excite.limits] floor", lim.get("floor"), FloorPlane,
                          {"z_min", "frames"}),
        sphere=_constraint("[excite.limits] sphere", lim.get("sphere"), KeepOutSphere,
                           {"radius", "centre", "frames"}))
    options: dict[str, Any] = {k: ex[k] for k in PASSED_ON if k in ex}
    if "friction" in ex:
        options["friction"] = tuple(ex["friction"]) or None
    if "boundary" in ex:
        options["boundary"] = BoundaryConditions(
            **_table(f"{path.name} [excite.boundary]", ex["boundary"], BOUNDARY_KEYS))
    options["limits"] = limits
    return ExcitationConfig(model, options, here / ex.get("output", "excitation.csv"),
                            float(ex.get("rate", 500.0)))
