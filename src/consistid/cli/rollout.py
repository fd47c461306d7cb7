r"""``consistid rollout CONFIG``: how far the gap shrinks in the user's simulator.

The ``[model]``, ``[data]`` and ``[identify]`` tables as for ``consistid identify``, and::

    [rollout]
    mjcf = "robot.xml"          # your MJCF (read, never written); default the robot's own
    timestep = 0.002            # s; with mjcf, default the file's
    integrator = "implicitfast" # "Euler", "implicit", "implicitfast", "RK4"; with mjcf, the file's
    window = 1.0                # s, open-loop replays restart from the log this often
    controller = "pd"           # "pd" (logged torque fed forward) or "computed_torque"
    bandwidth = 20.0            # rad/s of the controller (or kp = [...], kd = [...] per joint:
                                # N·m/rad, N·m·s/rad under "pd"; 1/s², 1/s under
                                # "computed_torque", where they shape the error's dynamics)
    damping_ratio = 1.0
    calibrate = true            # also calibrate_simulator on the training logs
    terms = ["armature", "damping", "frictionloss"]  # … of these ("gain", "delay" too)
    refine_inertia = false      # … and refine the inertias by output error
    output = "rollout.html"     # report (optional)

``terms`` and ``refine_inertia`` need ``calibrate = true``; ``"gain"`` and ``"delay"`` need
``controller = "pd"``. Every key is checked before the identification starts.

The training logs are identified (``[identify]``), then the first held-out log (else the first
training log) is replayed in the simulator with the nominal model, the identification and, with
``calibrate = true``, the calibrated simulator. The output is checked before the work and
written atomically (:mod:`consistid.cli.files`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ConfigError, OptionError
from ..identification.identify import identify
from ..simulator import (ComputedTorque, PDGains, RolloutOptions, calibrate_simulator,
                         validate_rollout)
from ..simulator.terms import ALL_TERMS, TERMS, check_terms
from .config import (RunConfig, config_identify, config_inputs, config_model,
                     config_recordings, load_config)
from .files import atomic_path, check_output

#: Keys of the ``[rollout]`` table.
ROLLOUT_KEYS = ("mjcf", "timestep", "integrator", "window", "controller", "bandwidth",
                "damping_ratio", "kp", "kd", "calibrate", "terms", "refine_inertia", "output",
                "threads")
_KINDS = {"mjcf": "string", "controller": "string", "terms": "array of strings",
          "timestep": "number", "integrator": "string", "window": "number",
          "bandwidth": "number", "damping_ratio": "number", "kp": "array of numbers",
          "kd": "array of numbers", "calibrate": "boolean", "refine_inertia": "boolean",
          "output": "string", "threads": "integer"}

#: ``[rollout] controller`` values.
CONTROLLERS = {"pd": PDGains, "computed_torque": ComputedTorque}


def rollout_options(config: RunConfig, table: dict[str, Any]) -> RolloutOptions:
    """The :class:`RolloutOptions` of a ``[rollout]`` table (types checked in TOML terms)."""
    for key, value in table.items():
        config.expect("rollout", key, value, _KINDS[key])
    kind = table.get("controller", "pd")
    if kind not in CONTROLLERS:
        raise ConfigError(f"{config.path.name}: [rollout] controller = {kind!r}; choose one of "
                          f"{sorted(CONTROLLERS)}")
    gains = CONTROLLERS[kind](**{k: (tuple(table[k]) if k in ("kp", "kd") else table[k])
                                 for k in ("bandwidth", "damping_ratio", "kp", "kd")
                                 if k in table})
    mjcf = "mjcf" in table
    return RolloutOptions(timestep=table.get("timestep", None if mjcf else 0.002),
                          integrator=table.get("integrator", None if mjcf else "implicitfast"),
                          window=table.get("window", 1.0), controller=gains,
                          threads=table.get("threads", 1))


def rollout_terms(config: RunConfig, table: dict[str, Any], options: RolloutOptions
                  ) -> tuple[str, ...] | None:
    """The simulator terms to calibrate (``None``: no calibration), checked before any work:
    known and distinct (:func:`~consistid.simulator.terms.check_terms`), gain and delay only
    under ``controller = "pd"``, and ``terms``/``refine_inertia`` only with
    ``calibrate = true`` (else they would be ignored; ``refine_inertia = false`` is harmless)."""
    name = config.path.name
    if not table.get("calibrate", False):
        given = ["terms"] * ("terms" in table) + ["refine_inertia"] * bool(
            table.get("refine_inertia", False))
        if given:
            raise ConfigError(f"{name}: [rollout] {' and '.join(given)} set, but they apply "
                              "to the calibration only: add calibrate = true to [rollout], "
                              f"or remove {' and '.join(given)}")
        return None
    try:
        terms = check_terms(table.get("terms", TERMS))
    except OptionError:
        raise ConfigError(f"{name}: [rollout] terms = {list(table['terms'])}; give distinct "
                          f"terms among {list(ALL_TERMS)}") from None
    if isinstance(options.controller, ComputedTorque) and {"gain", "delay"} & set(terms):
        raise ConfigError(f"{name}: [rollout] terms = {list(terms)} with controller = "
                          "\"computed_torque\": gain and delay act on the logged torque and are "
                          "calibrated under the PD replay; set controller = \"pd\" in [rollout] "
                          "or leave gain and delay out of terms")
    return terms


def run_rollout(config_path: str, *, output: str | None = None, force: bool = False,
                log: Any = print) -> tuple[Any, Any]:
    """Run ``consistid rollout`` (module docstring); returns the validation and, when asked,
    the calibration."""
    config = load_config(config_path)
    model = config_model(config)
    table = config.table("rollout", ROLLOUT_KEYS, required=False)
    options = rollout_options(config, table)
    terms = rollout_terms(config, table, options)
    mjcf = config.resolve(table["mjcf"]) if "mjcf" in table else None
    if mjcf is not None and not mjcf.is_file():
        raise ConfigError(f"{config.path.name}: [rollout] mjcf = {table['mjcf']!r} does not "
                          f"exist ({mjcf})")
    inputs = config_inputs(config, model) + ([mjcf] if mjcf else [])
    target = output or (config.resolve(table["output"]) if "output" in table else None)
    if target is not None:
        what = "--output" if output else "[rollout] output"
        if str(target).lower().endswith((".html", ".htm")) is False:
            raise ConfigError(f"{config.path.name}: {what} {str(target)!r} must be an .html "
                              "file")
        target = check_output(target, inputs=inputs, force=force, what=what)
    train, held = config_recordings(config, model)
    res = identify(model, train.dataset, **config_identify(config))
    replay = _first_log((held or train).dataset)
    models: dict[str, Any] = {"nominal": model, "identified": res}
    cal = None
    if terms is not None:
        cal = calibrate_simulator(res, _first_log(train.dataset), mjcf=mjcf,
                                  timestep=options.timestep or 0.002,
                                  integrator=options.integrator or "implicitfast",
                                  controller=options.controller,
                                  refine_inertia=table.get("refine_inertia", False),
                                  terms=terms,
                                  threads=options.threads)
        log(cal.summary())
        models["calibrated"] = cal
    validation = validate_rollout(replay, models, mjcf=mjcf, options=options)
    if target is not None:
        with atomic_path(target) as tmp:
            validation.report(tmp)
        log(f"wrote {target}")
    return validation, cal


def _first_log(data: Any) -> Any:
    """The first recording of a stacked dataset (a replay runs one continuous log)."""
    seg = np.asarray(data.segment)
    return data.select(seg == seg[0]) if np.unique(seg).size > 1 else data
