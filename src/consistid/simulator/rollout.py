r"""Rollout validation: how well a model replays a log in the user's simulator.

:func:`validate_rollout` replays one log (:mod:`.replay`) with several models — the nominal
:class:`~consistid.robot.model.RobotModel`, an :class:`~consistid.IdentificationResult`, a
:class:`~consistid.simulator.calibrate.SimulatorCalibration` — in the same simulator (the
user's MJCF, or the dynamics-only MJCF of the robot), at the user's step and integrator, with
the same PD gains, and reports per joint:

* closed loop: the RMS tracking error ``e = q − q_log`` (rad) and the RMS correction torque
  ``c`` (N·m), the torque the simulated robot needs beyond the logged one;
* open loop: the RMS drift ``q − q_log`` within each window of ``W`` s (mean over windows).

The first model is "before", the last "after": :class:`RolloutValidation` says how far the gap
shrinks in the user's simulator.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..data.dataset import Dataset
from ..errors import (DataQualityWarning, DatasetError, JointCountError, ModelMisfitWarning,
                      OptionError, ResultFileError)
from ..filesafety import replacing
from ..identification.persistence import decode, encode
from ..identification.resultschema import read_document
from ..report.html import Page, findings_html
from ..report.result import Reported
from ..robot.model import RobotModel
from .engine import Simulator, build_simulator, integrator_name
from .fields import field, number, vector
from .options import INTEGRATORS, ComputedTorque, RolloutOptions
from .replay import LogGrid, closed_loop_under, open_loop


@dataclass(frozen=True, eq=False)
class Replay:
    """One model's replay. ``q_error``, ``tau_error``, ``drift``: (nv,) RMS per joint (rad,
    N·m, rad); ``drift_max``: (nv,) the worst window's; ``diverged``: the closed loop left the
    log (then its errors are NaN)."""

    label: str
    q_error: np.ndarray
    tau_error: np.ndarray
    drift: np.ndarray
    drift_max: np.ndarray
    diverged: bool

    def row(self) -> dict[str, Any]:
        return {"model": self.label, "q_error_mrad": 1e3 * _rms(self.q_error),
                "tau_error_Nm": _rms(self.tau_error), "open_loop_mrad": 1e3 * _rms(self.drift),
                "diverged": self.diverged}


def _check_window(window: float, timestep: float) -> None:
    """:class:`OptionError` for an open-loop window shorter than two simulator steps: the
    replay would reset the state before it could drift, and report a drift of about 0."""
    if window < 2.0 * timestep:
        raise OptionError(f"RolloutOptions.window={window:g} s is shorter than two simulator "
                          f"steps (timestep {timestep:g} s): the open-loop replay would reset "
                          "before it drifts; give a window of a fraction of a second or more")


def _rms(per_joint: np.ndarray) -> float:
    """The RMS over joints of per-joint RMS values."""
    return float(np.sqrt(np.mean(np.square(per_joint))))


@dataclass(frozen=True, eq=False)
class RolloutValidation(Reported):
    """Replays of one log by several models in one simulator (module docstring).

    Attributes
    ----------
    replays : one :class:`Replay` per model, "before" first, "after" last.
    joint_names : the robot's joints.
    timestep, integrator, window : the simulator's step (s), integrator, open-loop window (s).
    kp, kd : (nv,) the closed-loop gains every model was replayed with (N·m/rad and
        N·m·s/rad under PD; 1/s² and 1/s under computed torque).
    duration : seconds replayed.
    controller : ``"PD"`` (the logged torque fed forward) or ``"computed torque"``.
    """

    replays: tuple[Replay, ...]
    joint_names: tuple[str, ...]
    timestep: float
    integrator: str
    window: float
    kp: np.ndarray
    kd: np.ndarray
    duration: float
    controller: str = "PD"

    @property
    def shrink(self) -> dict[str, float]:
        """``after / before`` of the closed-loop q and τ errors and of the open-loop drift."""
        a, b = self.replays[-1].row(), self.replays[0].row()
        return {k: a[k] / b[k] if b[k] > 0 else float("nan")
                for k in ("q_error_mrad", "tau_error_Nm", "open_loop_mrad")}

    def table(self) -> list[dict[str, Any]]:
        """One row per model: RMS over joints of the closed-loop q error (mrad), correction
        torque (N·m), open-loop drift (mrad), and whether it diverged."""
        return [r.row() for r in self.replays]

    def joint_table(self) -> list[dict[str, Any]]:
        """One row per (model, joint)."""
        return [{"model": r.label, "joint": j, "q_error_mrad": 1e3 * r.q_error[i],
                 "tau_error_Nm": r.tau_error[i], "open_loop_mrad": 1e3 * r.drift[i]}
                for r in self.replays for i, j in enumerate(self.joint_names)]

    def summary(self) -> str:
        lines = [f"Rollout validation: {self.duration:.3g} s replayed at {self.timestep:g} s "
                 f"{self.integrator}; closed loop under {self.controller} (mean K_p "
                 f"{np.mean(self.kp):.3g}), open loop reset every {self.window:g} s",
                 f"{'model':<22}{'q error mrad':>14}{'τ error N·m':>14}{'open loop mrad':>16}"]
        for r in self.table():
            flag = "  DIVERGED" if r["diverged"] else ""
            lines.append(f"{r['model']:<22}{r['q_error_mrad']:>14.4g}{r['tau_error_Nm']:>14.4g}"
                         f"{r['open_loop_mrad']:>16.4g}{flag}")
        if len(self.replays) > 1:
            s = self.shrink
            lines.append(f"after/before: q error ×{s['q_error_mrad']:.3g}, τ error "
                         f"×{s['tau_error_Nm']:.3g}, open loop ×{s['open_loop_mrad']:.3g}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def findings(self) -> list[tuple[str, str]]:
        """The report's first box as ``(level, text)`` pairs
        (:func:`consistid.report.html.findings_html`): a diverged replay ("bad"); the last model
        replaying worse than the first overall ("bad") or on some joints ("warn"); else how far
        the closed-loop q error and open-loop drift shrink, and the joint drifting most."""
        found = [("bad", f"{r.label} diverged in closed loop (its figures are NaN): the "
                         "simulated robot left the log; check its gains and step")
                 for r in self.replays if r.diverged]
        first, last = self.replays[0], self.replays[-1]
        if len(self.replays) > 1 and not (first.diverged or last.diverged):
            s = self.shrink
            # the last model's open loop diverged (NaN) where the first's did not: worse
            lost = np.isnan(last.drift) & ~np.isnan(first.drift)
            worse = [j for k, j in enumerate(self.joint_names)
                     if last.q_error[k] > first.q_error[k] or last.drift[k] > first.drift[k]
                     or lost[k]]
            grew = any(s[k] > 1 for k in ("q_error_mrad", "open_loop_mrad"))  # NaN: not grown
            level = "bad" if lost.any() or grew else "warn" if worse else "ok"
            found.append((level, f"{last.label} vs {first.label}: closed-loop q error "
                                 f"×{s['q_error_mrad']:.3g}, open-loop drift "
                                 f"×{s['open_loop_mrad']:.3g}, correction torque "
                                 f"×{s['tau_error_Nm']:.3g}"
                                 + (f"; worse than {first.label} on {', '.join(worse)}"
                                    if worse else "")))
        if np.isfinite(last.drift).any():
            k = int(np.nanargmax(last.drift))
            found.append(("ok", f"Largest open-loop drift left ({last.label}): "
                                f"{self.joint_names[k]}, {1e3 * last.drift[k]:.4g} mrad RMS per "
                                f"{self.window:g} s window."))
        return found

    def page(self) -> Page:
        page = Page("consistid rollout validation", self.summary().splitlines()[0])
        page.raw(findings_html(self.findings()))
        page.table(["model", "q error (mrad)", "τ error (N·m)", "open loop (mrad)", "diverged"],
                   [tuple(r.values()) for r in self.table()])
        page.table(["model", "joint", "q error (mrad)", "τ error (N·m)", "open loop (mrad)"],
                   [tuple(r.values()) for r in self.joint_table()], keys=(0, 1))
        return page

    def save(self, path: str | Path) -> Path:
        """Write the figures as JSON (``*.json``; non-finite numbers tagged as in result
        files), atomically (:func:`consistid.filesafety.replacing`: never half-written);
        :meth:`load` reads them back."""
        path = Path(path)
        if path.suffix.lower() != ".json":
            raise OptionError(f"save path {str(path)!r}: give a .json file")
        doc = {"format": FORMAT, "joint_names": list(self.joint_names),
               "timestep": self.timestep, "integrator": self.integrator,
               "window": self.window, "kp": self.kp.tolist(), "kd": self.kd.tolist(),
               "duration": self.duration, "controller": self.controller,
               "replays": [{"label": r.label, "q_error": r.q_error.tolist(),
                            "tau_error": r.tau_error.tolist(), "drift": r.drift.tolist(),
                            "drift_max": r.drift_max.tolist(), "diverged": r.diverged}
                           for r in self.replays]}
        text = json.dumps(encode(doc), indent=1, allow_nan=False)
        with replacing(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return path

    @classmethod
    def load(cls, path: str | Path) -> "RolloutValidation":
        """Read :meth:`save`'s file back; :class:`~consistid.errors.ResultFileError` naming the
        file and the field for one that is not (not JSON, beyond a result file's size and
        nesting limits, a field missing or of another type, shape or sign)."""
        path = Path(path)
        doc = read_document(path, path.name)
        try:
            doc = decode(doc)
        except (ValueError, TypeError, KeyError, AttributeError) as exc:
            raise ResultFileError(f"{path.name}: a tagged value does not decode: {exc}") from exc
        return validation_from_document(doc, path.name)


#: The ``format`` of a saved :class:`RolloutValidation`.
FORMAT = "consistid.rollout"
#: Per-joint figures of a saved replay, and whether each may be NaN (a diverged replay's).
_REPLAY_FIELDS = {"q_error": True, "tau_error": True, "drift": True, "drift_max": True}


def validation_from_document(doc: Any, where: str) -> RolloutValidation:
    """The :class:`RolloutValidation` of a decoded document, every field checked."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ResultFileError(f"{where} is not a saved rollout validation (format "
                              f"{FORMAT!r} missing)")
    joints = field(doc, "joint_names", list, where)
    if not joints or not all(isinstance(j, str) and 0 < len(j) <= 1000 for j in joints) \
            or len(set(joints)) != len(joints):
        raise ResultFileError(f"{where}: field 'joint_names' must list the joints' names, each "
                              "once")
    nv = len(joints)
    scalars = {k: number(doc, k, where) for k in ("timestep", "window", "duration")}
    integrator = field(doc, "integrator", str, where)
    if integrator not in INTEGRATORS:
        raise ResultFileError(f"{where}: field 'integrator' is {integrator!r:.40}, not one of "
                              f"{INTEGRATORS}")
    controller = field(doc, "controller", str, where)
    if controller not in ("PD", "computed torque"):
        raise ResultFileError(f"{where}: field 'controller' is {controller!r:.40}, not 'PD' "
                              "or 'computed torque'")
    gains = [vector(doc, k, nv, where, nan=False) for k in ("kp", "kd")]
    replays = field(doc, "replays", list, where)
    if not replays:
        raise ResultFileError(f"{where}: field 'replays' is empty")
    out = []
    for k, r in enumerate(replays):
        at = f"{where}: replays[{k}]"
        label = field(r, "label", str, at)
        arrays = [vector(r, f, nv, at, nan=n) for f, n in _REPLAY_FIELDS.items()]
        out.append(Replay(label, *arrays, field(r, "diverged", bool, at)))
    return RolloutValidation(tuple(out), tuple(joints), scalars["timestep"], integrator,
                             scalars["window"], *gains, scalars["duration"], controller)


def simulator_of(source: Any, *, mjcf: str | Path | None, options: RolloutOptions
                 ) -> Simulator:
    """The simulator of a model source: a :class:`RobotModel` (its own inertias, no joint
    terms), or anything with ``model``, ``parameters`` and ``parameter_names`` (an
    identification result), or a :class:`~consistid.simulator.calibrate.SimulatorCalibration`
    (its ``simulator(...)``)."""
    if hasattr(source, "simulator") and callable(source.simulator):
        return source.simulator(mjcf=mjcf, timestep=options.timestep,
                                integrator=options.integrator)
    if isinstance(source, RobotModel):
        return build_simulator(source, mjcf=mjcf, timestep=options.timestep,
                               integrator=options.integrator)
    if all(hasattr(source, a) for a in ("model", "parameters", "parameter_names")):
        return build_simulator(source.model, source.parameters, source.parameter_names,
                               mjcf=mjcf, timestep=options.timestep,
                               integrator=options.integrator)
    raise OptionError(f"cannot replay a {type(source).__name__}: give a RobotModel, an "
                      "IdentificationResult or a SimulatorCalibration")


def replay_one(sim: Simulator, label: str, log: LogGrid, kp: np.ndarray, kd: np.ndarray,
               options: RolloutOptions) -> Replay:
    """One model's closed- and open-loop replay as a :class:`Replay`."""
    closed = closed_loop_under(options.controller, sim, [sim.mj_model], log, kp, kd,
                               options.threads)
    drift = open_loop(sim, log, options.window, options.threads)
    diverged = bool(closed.diverged[0])
    nan = np.full(sim.nv, np.nan)
    with warnings.catch_warnings():             # every window diverged: NaN, said below
        warnings.simplefilter("ignore", RuntimeWarning)
        per_window = np.sqrt(np.nanmean(drift ** 2, axis=1))
        mean, worst = (np.sqrt(np.nanmean(per_window ** 2, axis=0)),
                       np.nanmax(per_window, axis=0))
    if diverged or not np.all(np.isfinite(mean)):
        what = "closed loop" if diverged else "open loop (every window)"
        warnings.warn(f"validate_rollout: the {what} replay of {label!r} diverged (a non-finite "
                      f"state, MuJoCo reset an unstable step, or a tracking error beyond "
                      "1 rad): its figures are NaN. Check the log's torques and units, the "
                      "controller gains for the timestep (a smaller bandwidth= or timestep=), "
                      "and the model", ModelMisfitWarning, stacklevel=3)
    return Replay(label, nan if diverged else np.sqrt(np.mean(closed.error[0] ** 2, axis=0)),
                  nan if diverged else np.sqrt(np.mean(closed.correction[0] ** 2, axis=0)),
                  mean, worst, diverged)


def validate_rollout(data: Dataset, models: Mapping[str, Any], *,
                     mjcf: str | Path | None = None,
                     options: RolloutOptions | None = None) -> RolloutValidation:
    """Replay ``data`` in the user's simulator with each of ``models`` (module docstring).

    Parameters
    ----------
    data : one continuous recording with torques (a held-out one, to judge a fit).
    models : ``{label: source}``, "before" first and "after" last; a source is a
        :class:`RobotModel` (e.g. the nominal), an identification result, or a
        :class:`~consistid.simulator.calibrate.SimulatorCalibration`.
    mjcf : the user's MJCF file, loaded as is (its actuators replaced by the replay's PD);
        default the dynamics-only MJCF of each model.
    options : :class:`RolloutOptions` (step, integrator, window, gains).

    Returns
    -------
    RolloutValidation
    """
    options = options or RolloutOptions()
    if not isinstance(options, RolloutOptions):
        raise OptionError(f"validate_rollout: options must be a RolloutOptions, got "
                          f"{type(options).__name__}")
    if not isinstance(data, Dataset):
        raise DatasetError(f"validate_rollout: data must be a Dataset (one recording with "
                           f"torques), got {type(data).__name__}")
    if not isinstance(models, Mapping):
        raise OptionError(f"validate_rollout: models must be a mapping {{label: model}}, got "
                          f"{type(models).__name__}")
    if not models:
        raise OptionError("validate_rollout: models is empty; give {label: model}")
    sims = {label: simulator_of(src, mjcf=mjcf, options=options)
            for label, src in models.items()}
    first = next(iter(sims.values()))
    for label, sim in sims.items():
        if sim.nv != data.nv:
            raise JointCountError(f"validate_rollout: models[{label!r}] has {sim.nv} joints, "
                                  f"the data {data.nv}: replay a log of that robot")
    timestep = float(first.mj_model.opt.timestep)
    _check_window(options.window, timestep)
    log = LogGrid.from_dataset(data, timestep)
    if log.t[-1] - log.t[0] < options.window:
        warnings.warn(f"validate_rollout: the log lasts {log.t[-1] - log.t[0]:.3g} s, less "
                      f"than one open-loop window (window={options.window:g} s): the figures "
                      "rest on one short replay; replay a longer log", DataQualityWarning,
                      stacklevel=2)
    stride = max(1, log.t.size // 50)
    kp, kd = options.controller.resolve(first.mass_diagonal(log.q[::stride]))
    replays = tuple(replay_one(sim, label, log, kp, kd, options) for label, sim in sims.items())
    integrator = integrator_name(int(first.mj_model.opt.integrator))
    kind = "computed torque" if isinstance(options.controller, ComputedTorque) else "PD"
    return RolloutValidation(replays, first.joint_names, timestep, integrator, options.window,
                             kp, kd, float(log.t[-1] - log.t[0]), kind)
