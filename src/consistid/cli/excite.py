"""Excitation designs described by a TOML file (``consistid excite CONFIG``).

The ``[model]`` table and the path rules are those of every consistid configuration
(:mod:`consistid.cli.config`). Example::

    [model]
    example = "panda"               # an example robot, or: urdf = "arm.urdf"
    # locked_joints = ["finger_joint"]   gravity = [0.0, 0.0, -9.81]

    [excite]
    trajectory = "fourier"          # or "bspline" (then via_points = 10, degree = 4)
    harmonics = 5
    period = 10.0                   # s
    criterion = "cond"              # "d-opt", "e-opt"
    friction = ["coulomb", "viscous", "offset"]   # columns to be identified ([] for none;
                                                  # a string is one term)
    seed = 0
    n_starts = 4
    max_iter = 100
    rate = 500.0                    # Hz of the CSV
    output = "excitation.csv"       # relative to the configuration's root

    [excite.limits]                 # overrides of the URDF limits (scalars or one per joint)
    acceleration = [15, 7.5, 10, 12.5, 15, 20, 20]
    torque = true                   # URDF efforts; false: unchecked
    floor = { z_min = 0.2 }
    sphere = { radius = 0.3 }
    workspace = { lower = [-0.9, -0.9, 0.2], upper = [0.9, 0.9, 1.3] }

    [excite.boundary]               # optional: q_start, q_end, dq_start, ... (BoundaryConditions)

Unknown keys raise :class:`~consistid.errors.ConfigError` naming the table and the key.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .config import RunConfig, config_model, load_config
from ..errors import ConfigError
from ..robot.model import RobotModel
from ..excitation.design import ExcitationDesign, StartResult, design_excitation
from ..excitation.limits import CartesianBox, ExcitationLimits, FloorPlane, KeepOutSphere
from ..excitation.trajectory import BoundaryConditions

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
#: ``[excite]`` keys of one trajectory kind only (given with the other, they are refused).
BSPLINE_ONLY = ("via_points", "degree")
FOURIER_ONLY = ("harmonics",)
SHAPES: dict[str, tuple[type, set[str]]] = {
    "workspace": (CartesianBox, {"lower", "upper", "frames"}),
    "floor": (FloorPlane, {"z_min", "frames"}),
    "sphere": (KeepOutSphere, {"radius", "centre", "frames"}),
}


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


def _shape(config: RunConfig, key: str, value: Any) -> Any:
    cls, allowed = SHAPES[key]
    sub = config.check_table(f"excite.limits.{key}", value, allowed)
    if "frames" in sub:
        sub["frames"] = tuple(sub["frames"])
    try:
        return cls(**sub)
    except TypeError as exc:
        raise ConfigError(f"{config.path.name}: [excite.limits.{key}]: {exc}") from exc


def load_excitation_config(path: str | Path) -> ExcitationConfig:
    """Read and check a TOML excitation config (module docstring for the layout)."""
    config = load_config(path)
    model = config_model(config)
    ex = config.table("excite", EXCITE_KEYS, required=False)
    lim = config.check_table("excite.limits", ex.get("limits", {}), LIMIT_KEYS)
    limits = ExcitationLimits.from_model(
        model, **{k: lim[k] for k in ("acceleration", "velocity", "torque", "lower", "upper")
                  if k in lim},
        **{k: _shape(config, k, lim[k]) for k in SHAPES if k in lim})
    options: dict[str, Any] = {k: ex[k] for k in PASSED_ON if k in ex}
    kind = ex.get("trajectory", "fourier")
    unused = [k for k in (BSPLINE_ONLY if kind == "fourier" else FOURIER_ONLY) if k in ex]
    if unused:
        raise ConfigError(f"{config.path.name}: [excite] {', '.join(unused)} set, but they "
                          f"do not apply to trajectory = {kind!r} (they would be ignored); "
                          "remove them or choose the other trajectory")
    if "friction" in ex:
        friction = ex["friction"]
        options["friction"] = ((friction,) if isinstance(friction, str)   # one term
                               else tuple(friction)) or None
    if "boundary" in ex:
        boundary = config.check_table("excite.boundary", ex["boundary"], BOUNDARY_KEYS)
        for key, value in boundary.items():
            if not isinstance(value, list):
                config.expect("excite.boundary", key, value, "number")
            else:
                config.expect("excite.boundary", key, value, "array of numbers")
        options["boundary"] = BoundaryConditions(**boundary)
    options["limits"] = limits
    output = config.expect("excite", "output", ex.get("output", "excitation.csv"), "string")
    rate = config.expect("excite", "rate", ex.get("rate", 500.0), "number")
    if not (0 < rate < float("inf")):
        raise ConfigError(f"{config.path.name}: [excite] rate must be > 0 (Hz), got rate = {rate}")
    return ExcitationConfig(model, options, config.resolve(output), float(rate))
