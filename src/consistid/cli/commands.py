"""The ``consistid`` command.

``consistid demo`` runs the main job on a bundled default: a simulated excitation run of the
Panda arm (ground truth = URDF parameters perturbed by ±20 %), identified and printed; with
``--output DIR`` the report, result and parameter table are written into ``DIR`` (as
``identify --output``: existing files need ``--force``), without it no file is written.
``demo`` and ``simulate`` take any URDF (``--urdf PATH``). ``consistid identify CONFIG --output
DIR`` writes the result as JSON, the parameter table as CSV, the identified URDF and MJCF and the
HTML report.

Progress bars (``tqdm``) appear on a terminal; ``-q`` silences them and the step messages.
Error messages give option hints in TOML syntax (:mod:`consistid.cli.hints`), the syntax of the
configuration files.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import importlib.metadata
import os
import platform
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

import consistid as ci
from consistid.errors import (ConfigError, ConsistidError, OutputPathError, check_number,
                             check_option, check_seed)
from consistid.robot.export import MERGED
from consistid.robot.model import EXAMPLE_ROBOTS

from . import online_demo
from .calibrate import run_calibrate
from .config import config_inputs, load_config
from .excite import load_excitation_config
from .files import atomic_dir, atomic_path, check_inputs, check_output, check_output_dir
from .hints import cli_text, toml_hints, toml_value
from ..data.npzfile import open_npz
from ..filesafety import Terminated, release_output_locks, sigterm_interrupts
from ..progress import silenced

#: ``errno`` of a write that the filesystem refused (:func:`main` names it, exit 2).
WRITE_FAILURES = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO})

#: Set by ``-q``: no progress bars, no step messages on stderr (errors are still printed).
QUIET = False


def _log(msg: str) -> None:
    if not QUIET:
        print(msg, file=sys.stderr, flush=True)


def _progress(line: Callable[[object], str] = str) -> bool | None | Callable[[object], None]:
    """``progress=`` for the library: nothing under ``-q``; a bar on a terminal; in a log (stderr
    not a terminal) one line per step, ``line(step)``."""
    if QUIET:
        return False
    if sys.stderr is not None and sys.stderr.isatty():
        return None
    return lambda step: _log(f"      {line(step)}")


def _cli_model(args: argparse.Namespace) -> "ci.RobotModel":
    """The robot of ``--urdf PATH`` (with ``--lock JOINT`` …) or of ``--robot NAME``."""
    if args.urdf:
        return ci.RobotModel.from_urdf(args.urdf, locked_joints=args.lock or ())
    if args.lock:
        raise ConfigError("--lock applies to --urdf; the example robots lock their grippers "
                          "already")
    if args.robot not in EXAMPLE_ROBOTS:
        raise ConfigError(f"--robot {args.robot} is not an example robot; they are "
                          f"{', '.join(EXAMPLE_ROBOTS)}. For another arm: --urdf PATH")
    return ci.RobotModel.example(args.robot)


#: What ``consistid demo --output DIR`` writes (without ``--output`` it writes nothing).
DEMO_OUTPUTS = ("report.html", "result.json", "parameters.csv")


def demo(args: argparse.Namespace) -> int:
    """Simulate, identify, print; with ``--output DIR`` also write :data:`DEMO_OUTPUTS`."""
    for name, value, minimum, strict in (("--duration", args.duration, 0, True),
                                         ("--rate", args.rate, 0, True),
                                         ("--noise", args.noise, 0, False)):
        check_number(name, value, minimum, strict=strict)   # before any folder is made
    check_seed("--seed", args.seed)
    model = _cli_model(args)
    _check_demo_bodies(model, args.urdf)                 # before any folder is made
    inputs = [args.urdf] if args.urdf else []
    folder = (check_output_dir(args.output, DEMO_OUTPUTS, inputs=inputs, force=args.force,
                               what="--output") if args.output else None)
    return _demo(args, model, folder)


def _check_demo_bodies(model: "ci.RobotModel", urdf: str | None) -> None:
    """:class:`ConfigError` naming the bodies the demo cannot use: it draws its "true" robot
    around the URDF's bodies (±20 %, which needs a mass and a centre of mass) and uses them as
    the SDP's log-det prior (which needs realisable bodies)."""
    from consistid.robot.inertia import check_body

    bad = []
    for i, body in enumerate(model.body_names):
        verdict = check_body(model.prior_parameters[10 * i:10 * i + 10], "triangle", body,
                             tol=1e-9)
        if not verdict.ok:
            bad.append(verdict.reason)
    if bad:
        source = f"--urdf {urdf}" if urdf else model.name
        raise ConfigError(f"{source}: the demo simulates a robot around the URDF's bodies and "
                          "uses them as the SDP's prior, so every moving body needs a positive "
                          f"mass and a physical inertia; not so: {'; '.join(bad[:4])}. Fix the "
                          "<inertial> of those links (or run `consistid identify` on your logs, "
                          "with prior = \"euclidean\" in [identify])")


def _demo(args: argparse.Namespace, model: "ci.RobotModel", folder: Path | None) -> int:
    """The demo's work (:func:`demo`), its files written into ``folder`` when one is named."""
    from consistid.robot.inertia import perturb

    rng = np.random.default_rng(args.seed)
    truth = perturb(model.prior_parameters, 0.2, rng)
    _log(f"[1/4] simulating {args.duration:.0f} s of excitation on {model.name} "
         f"(truth = URDF ±20 %, torque noise σ = {args.noise} N·m)")
    run = ci.simulate.excitation_run(model, truth, duration=args.duration, rate=args.rate,
                                     torque_noise=args.noise, seed=args.seed)
    held = ci.simulate.excitation_run(model, truth, duration=10.0, rate=args.rate,
                                      torque_noise=args.noise, seed=args.seed + 1)
    from consistid.identification.summary import table

    results, rows, held_rms = {}, [], {}
    with _kept_warnings() as found:        # the two fits warn alike on the held-out run: once
        for step, method, what in (
                (2, "ols", "ordinary least squares on base parameters"),
                (3, "sdp", "consistent SDP: pseudo-inertia LMIs, log-det prior")):
            _log(f"[{step}/4] identifying ({what})")
            t0 = time.perf_counter()
            res = results[method] = ci.identify(model, run.dataset, method=method,
                                                friction=None)
            elapsed = time.perf_counter() - t0
            _log(f"      done in {elapsed:.2f} s")
            err = (res.base_parameters - res.base.project(truth)) / res.base_std
            held_rms[method] = res.rms(held.dataset) / args.noise
            rows.append((method.upper(), f"{np.sqrt(np.mean(held_rms[method] ** 2)):.4f}",
                         f"{sum(b.ok for b in res.consistency.bodies)}/{model.n_bodies}",
                         f"{np.mean(np.abs(err) < 3) * 100:.0f} %", f"{elapsed:.2f}"))
    _log("[4/4] report")
    print(results["sdp"].summary())
    print("\nheld-out RMS / σ per joint (SDP): "
          f"{np.array2string(held_rms['sdp'], precision=3)}")
    print("\n" + table(["method", "held-out RMS/σ", "bodies consistent",
                        "base params within 3σ of truth", "time [s]"], rows))
    print(f"OLS (nearest standard set): {results['ols'].consistency}")
    if folder is None:
        _log(f"\nno file written; consistid demo --output DIR writes {', '.join(DEMO_OUTPUTS)}"
             " into DIR")
        return 0
    sdp = results["sdp"].with_provenance(config={"command": "demo", **{
        k: v for k, v in vars(args).items() if k != "func"}})
    with atomic_dir(folder) as tmp, _kept_warnings(already=found):
        sdp.report(tmp / "report.html", data=run.dataset, held_out=held.dataset)
        sdp.save(tmp / "result.json")
        sdp.to_csv(tmp / "parameters.csv")
    print(f"\nreport: {folder / 'report.html'}")
    return 0


def identify(args: argparse.Namespace) -> int:
    """Identify from the recordings of a TOML configuration (:mod:`consistid.cli.config`)."""
    from consistid.cli.config import (config_drive_gains, config_identify, config_inputs,
                                      config_model, config_recordings, estimates_tilt,
                                      load_config)
    from consistid.identification.scoring import score, scores_table

    config = load_config(args.config)
    with _kept_warnings() as found:
        model = config_model(config, allow_tilt=True)
        options = config_identify(config)
        inputs = config_inputs(config, model)
        folder = (check_output_dir(args.output, IDENTIFY_OUTPUTS, inputs=inputs,
                                   force=args.force, what="--output") if args.output else None)
        train, held = config_recordings(config, model)
        inputs = check_inputs(inputs)          # recordable (bag folders too), before the fit
        gains = config_drive_gains(config)
        if gains is not None and estimates_tilt(config):
            raise ConfigError(f'{config.path.name}: [drives] gains = "identify" logs currents, '
                              "on which the base tilt cannot be estimated: remove [model] "
                              "tilt, and give gravity = [...] if the base is tilted")
        _log(str(train))
        if held is not None:
            _log(str(held))
        if estimates_tilt(config):
            _log("estimating the base tilt (gravity direction) on the training recordings")
            mounting = ci.estimate_mounting(model, train.dataset,
                                            **{k: options[k] for k in ("friction", "armature")
                                               if k in options})
            print(f"{mounting}\n")
            model = mounting.model
        _log(f"identifying {model.name} on {train.dataset.n_samples} samples "
             f"({', '.join(_toml_pair(k, v) for k, v in options.items()) or 'defaults'})")
        t0 = time.perf_counter()
        if gains is None:
            res = ci.identify(model, train.dataset, **options)
        else:
            train, held, res = _identify_gains(config, model, train, held, gains, options)
        _log(f"      done in {time.perf_counter() - t0:.2f} s")
        scored = [score(res, train.dataset, "train")]    # its warnings (extrapolation) too
        if held is not None:
            scored.append(score(res, held.dataset, "held-out"))
    if found:
        res = dataclasses.replace(res, details={
            **res.details, **{f"warning {k + 1}": text for k, text in enumerate(found)}})
    print(cli_text(res.summary(max_rows=None if args.all else 20)))
    print("\nTorque fit: relative error per joint and total (%), RMS (N·m)")
    print(scores_table(scored))
    if folder is not None:
        res = res.with_provenance(inputs, config={"root": str(config.root), **config.tables})
        with _kept_warnings(already=found):           # the report's predictions warn again
            _write_identification(res, folder, train.dataset,
                                  None if held is None else held.dataset)
    return 0


def _identify_gains(config, model: "ci.RobotModel", train, held, gains: dict,
                    options: dict) -> tuple:
    """``[drives] gains = "identify"``: the drive gains from the ``[data] train`` logs
    (unloaded) and the ``[drives] loaded`` logs (:func:`consistid.identify_drive_gains`, the
    ``[identify]`` keywords passed on); returns the train and held-out recordings converted to
    joint torques with them, and the identification."""
    from consistid.cli.config import config_drives, config_recordings

    loaded_config = dataclasses.replace(config, tables={
        **config.tables, "data": {**config.table("data"), "train": gains["loaded"],
                                  "held_out": []}})
    loaded, _ = config_recordings(loaded_config, model)
    _log(str(loaded))
    try:
        found = ci.identify_drive_gains(
            model, train.dataset, loaded.dataset, payload_mass=gains["payload_mass"],
            payload_body=gains["payload_body"], transmission=config_drives(config), **options)
    except ci.OptionError as exc:
        raise ConfigError(f"{config.path.name}: [drives]/[identify] {exc}") from exc
    print(cli_text(found.summary().split("\n\n")[0]) + "\n")
    train = dataclasses.replace(train, dataset=found.to_torque(train.dataset))
    if held is not None:
        held = dataclasses.replace(held, dataset=found.to_torque(held.dataset))
    return train, held, found.result


@contextlib.contextmanager
def _kept_warnings(already: Sequence[str] = ()) -> Iterator[list[str]]:
    """Record the warnings raised in the block (a result's data read, the result computed:
    degrees beyond the joint limits, a flipped torque sign, a gravity in mm/s², poor excitation
    …); when it ends, show each once that the filters in force let through (not a library's
    DeprecationWarning that Python ignores by default) and append its ``"Category: message"``
    text to the yielded list — for the result, so that its summary and the files written from
    it carry them, not only the terminal. A text in ``already`` (shown before) is not
    shown again."""
    found: list[str] = []
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as recorded:
            warnings.simplefilter("always")
            try:
                yield found
            finally:
                caught = list(recorded)
    finally:
        with warnings.catch_warnings(record=True) as shown:     # the filters in force decide
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        for w in shown:                 # in the CLI's terms (cli_text: no Python calls)
            text = cli_text(f"{w.category.__name__}: {w.message}")
            if text not in found and text not in already:
                found.append(text)
                warnings.showwarning(cli_text(str(w.message)), w.category, w.filename,
                                     w.lineno)


def _toml_pair(key: str, value: object) -> str:
    """``key = value`` as the configuration spells it (``repr`` for what TOML cannot)."""
    return f"{key} = {toml_value(value) or repr(value)}"


#: What ``consistid identify --output DIR`` writes.
IDENTIFY_OUTPUTS = ("result.json", "parameters.csv", "robot.urdf", "robot.xml", "report.html")


def _write_identification(res: "ci.IdentificationResult", folder: Path, train: "ci.Dataset",
                          held: "ci.Dataset | None") -> None:
    """:data:`IDENTIFY_OUTPUTS` into ``folder``, all renamed into place at the end. A model
    file that cannot be written (an inconsistent body, no source URDF) is named with the
    reason, and the rest is written. ``robot.xml`` of a model read from the user's MJCF is a
    copy of that file with the identified values written in (:func:`_write_mjcf`)."""
    notes = []
    with atomic_dir(folder) as tmp:
        res.save(tmp / "result.json")
        res.to_csv(tmp / "parameters.csv")
        for name, write in (("robot.urdf", lambda path: res.to_urdf(path) and None),
                            ("robot.xml", lambda path: _write_mjcf(res, path))):
            try:
                what = write(tmp / name)
            except (ci.InconsistentParametersError, ci.ModelError) as exc:
                notes.append(f"{name} not written: {exc}")
                continue
            notes += [f"{name}: {what}"] if what else []
        res.report(tmp / "report.html", data=train, held_out=held)
        written = sorted(p.name for p in tmp.iterdir())
    for line in notes:
        _log(line)
    _log(f"wrote {', '.join(written)} into {folder}")
    print(f"\nreport: {folder / 'report.html'}")


def _write_mjcf(res: "ci.IdentificationResult", path: Path) -> str:
    """Write ``robot.xml`` at ``path`` and say what it is: for a model read from the user's
    MJCF, a copy of that file with the identified values written in (every other byte kept but
    the ``<compiler>``'s ``meshdir``/``texturedir``, made absolute so that its meshes and
    textures resolve from the output folder); otherwise a new MJCF without geometry."""
    source = res.model.source if res.model.source_format == "mjcf" else None
    if source is None:
        res.to_mjcf(path)
        return "a new MJCF of the identified model, without geometry (no MJCF was given)"
    res.to_mjcf(path, source=source, absolute_assets=True)
    return (f"a copy of {source} with the identified values written in; its <compiler> "
            "meshdir/texturedir name that file's asset folders by absolute path")


def excite(args: argparse.Namespace) -> int:
    """Design an optimal excitation trajectory (:mod:`consistid.cli.excite`), write CSV."""
    config = load_excitation_config(args.config)
    inputs = check_inputs(config_inputs(load_config(args.config), config.model))
    output = check_output(args.output or config.output, inputs=inputs, force=args.force,
                          what="--output" if args.output else "[excite] output")
    _log(f"designing an excitation trajectory for {config.model.name} "
         f"({config.options.get('n_starts', 4)} starts)")
    design = config.run(progress=_progress())
    print(design)
    with atomic_path(output) as tmp:
        design.save_csv(tmp, config.rate)
    _log(f"wrote {output} ({config.rate:g} Hz, one period of {design.period:g} s)")
    return 0


#: Image formats ``--plot`` writes (matplotlib's, by the file's suffix).
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".eps")


def simulate(args: argparse.Namespace) -> int:
    """A MuJoCo arm with effects the nominal model lacks; the nominal residual per joint
    (:mod:`consistid.cli.residual_demo`)."""
    from consistid.cli.residual_demo import DEFAULT_EFFECTS, run

    if args.plot and Path(args.plot).suffix.lower() not in PLOT_SUFFIXES:
        raise OutputPathError(f"--plot {args.plot!r}: {Path(args.plot).suffix or 'no suffix'} "
                              "is not an image format; name a .png file (or "
                              f"{', '.join(s for s in PLOT_SUFFIXES if s != '.png')})")
    check_seed("--seed", args.seed)
    plot = (check_output(args.plot, force=args.force, what="--plot") if args.plot else None)
    demo_run = run(_cli_model(args), args.effect or DEFAULT_EFFECTS, duration=args.duration,
                   torque_noise=args.noise, seed=args.seed, progress=_log)
    print(demo_run)
    if plot is not None:
        with atomic_path(plot) as tmp:
            demo_run.plot(tmp)
        _log(f"wrote {plot}")
    return 0


RECOVER_KEYS = ("coefficients", "friction", "armature", "mode", "prior", "margin", "slack",
                "urdf", "merged")
PAYLOAD_KEYS = ("loaded", "route", "frame", "body", "ellipsoid", "mass_range")
PAYLOAD_ROUTES = ("torque", "base-change")


def recover(args: argparse.Namespace) -> int:
    """Consistent standard parameters from base coefficients
    (:mod:`consistid.estimation.recover`): from a
    ``coefficients`` file (npz: ``beta`` [, ``covariance``]) or by OLS on the ``[data]`` logs."""
    from consistid.cli.config import config_inputs, config_model, config_recordings, load_config
    from consistid.identification.regressor import DEFAULT_FRICTION

    config = load_config(args.config)
    model = config_model(config)
    t = config.table("recover", RECOVER_KEYS, required=False)
    for key, kind in (("coefficients", "string"), ("urdf", "string"), ("merged", "string"),
                      ("mode", "string"), ("prior", "string"), ("margin", "number"),
                      ("armature", "boolean")):
        if key in t and not (key == "armature" and isinstance(t[key], list)):
            config.expect("recover", key, t[key], kind)
    if "merged" in t:
        check_option("[recover] merged", t["merged"], MERGED)
        if "urdf" not in t:
            raise ConfigError(f"{config.path.name}: [recover] merged = {t['merged']!r} says how "
                              "to write the URDF, and there is no urdf = \"out.urdf\" to write")
    urdf = (check_output(config.resolve(t["urdf"]), inputs=config_inputs(config, model),
                         force=args.force, what="[recover] urdf") if "urdf" in t else None)
    options = {k: t[k] for k in ("mode", "prior", "margin", "slack") if k in t}
    # the same columns in both branches: identify's default unless [recover] says otherwise
    friction, armature = t.get("friction", DEFAULT_FRICTION), t.get("armature", False)
    if "coefficients" in t:
        beta, cov, names = _coefficients(config.resolve(t["coefficients"]), t["coefficients"])
        if names is not None:
            _check_base_names(model, names, friction, armature, t["coefficients"])
        rec = ci.recover_standard(model, beta, covariance=cov, friction=friction,
                                  armature=armature, **options)
    else:
        train, _ = config_recordings(config, model)
        _log(f"identifying base coefficients by OLS on {train.dataset.n_samples} samples")
        res = ci.identify(model, train.dataset, method="ols", friction=friction,
                          armature=armature)
        rec = ci.recover_standard(model, res, **options)
    print(cli_text(rec.summary(max_rows=None if args.all else 20)))
    if urdf is not None:
        with atomic_path(urdf) as tmp:
            rec.to_urdf(tmp, t.get("merged", "auto"))
        _log(f"wrote {urdf}")
    return 0


def _coefficients(path, written: str
                  ) -> tuple[np.ndarray, np.ndarray | None, list[str] | None]:
    """``beta``, the optional ``covariance`` and the optional ``base_names`` (the regrouping each
    coefficient stands for) of a ``[recover] coefficients`` .npz file."""
    if path.is_dir():
        raise ConfigError(f"[recover] coefficients = {written!r}: {str(path)!r} is a folder, not "
                          "the .npz file of coefficients")
    if not path.is_file():
        raise ConfigError(f"[recover] coefficients = {written!r}: file {str(path)!r} does not "
                          "exist")
    try:
        with open_npz(path) as f:          # headers checked: no pickles, no forged sizes
            if "beta" not in f.files:
                raise ConfigError(f"[recover] coefficients = {written!r}: needs an array 'beta'"
                                  f"; it has {sorted(f.files)}")
            beta = f["beta"]
            cov = f["covariance"] if "covariance" in f.files else None
            names = [str(n) for n in f["base_names"]] if "base_names" in f.files else None
    except (OSError, ValueError, EOFError) as exc:    # not an npz, a pickled array …
        raise ConfigError(f"[recover] coefficients = {written!r}: not a readable .npz file "
                          f"({exc})") from None
    return beta, cov, names


def _check_base_names(model: "ci.RobotModel", names: list[str], friction: object,
                      armature: object, written: str) -> None:
    """Coefficients that name their base parameters (``base_names``) must be in the base map
    ``recover_standard`` will use: which columns pivoted QR keeps depends on the settings (and
    may on the BLAS), and coefficients read in another map would be recovered silently wrong."""
    from consistid.identification.regressor import RegressorSpec

    expected = ci.compute_base_parameters(model, RegressorSpec.make(model, friction,
                                                                    armature)).names
    if list(names) != list(expected):
        k = next((i for i, (a, b) in enumerate(zip(names, expected)) if a != b),
                 min(len(names), len(expected)))
        raise ConfigError(
            f"[recover] coefficients = {written!r}: its base_names are not consistid's base map "
            f"for these [recover] friction/armature settings ({len(names)} names, "
            f"{len(expected)} expected; first difference at index {k}: "
            f"{names[k] if k < len(names) else '(none)'!r} in the file, "
            f"{expected[k] if k < len(expected) else '(none)'!r} expected). Check friction and "
            "armature, or express the coefficients in this map (consistid identify --all lists it)")


def payload(args: argparse.Namespace) -> int:
    """Payload from unloaded ``[data]`` logs and ``[payload] loaded`` logs
    (:mod:`consistid.estimation.payload`); the robot is identified as ``[identify]`` says
    (default OLS)."""
    import dataclasses
    from consistid.cli.config import (config_ellipsoid, config_identify, config_model,
                                  config_recordings, load_config)

    config = load_config(args.config)
    model = config_model(config)
    t = config.table("payload", PAYLOAD_KEYS)
    route = t.get("route", "torque")
    check_option("[payload] route", route, PAYLOAD_ROUTES)
    if not t.get("loaded"):
        raise ConfigError(f"{config.path.name}: [payload] needs loaded = [\"file.npz\", ...] "
                          "(the logs recorded with the payload)")
    config.expect("payload", "loaded", t["loaded"], "string or array of strings")
    for key in ("frame", "body"):
        if key in t:
            config.expect("payload", key, t[key], "string")
    ellipsoid = (config_ellipsoid(config, "payload.ellipsoid", t["ellipsoid"])
                 if "ellipsoid" in t else None)
    options = {"method": "ols", **config_identify(config)}
    loaded_config = dataclasses.replace(config, tables={
        **config.tables, "data": {**config.table("data"), "train": t["loaded"],
                                  "held_out": []}})
    unloaded, _ = config_recordings(config, model)
    loaded, _ = config_recordings(loaded_config, model)
    _log("identifying the unloaded robot ("
         f"{', '.join(_toml_pair(k, v) for k, v in options.items())})")
    robot = ci.identify(model, unloaded.dataset, **options)
    target = (loaded.dataset if route == "torque"
              else ci.identify(model, loaded.dataset, **options))
    result = ci.estimate_payload(model, target, robot=robot, frame=t.get("frame"),
                                 body=t.get("body"), ellipsoid=ellipsoid,
                                 mass_range=t.get("mass_range"))
    print(result)
    return 0


#: ``[diagnose]`` keys passed to :func:`consistid.diagnose` as they are …
DIAGNOSE_OPTIONS = ("effects", "sigma", "torque_resolution", "alpha", "min_gain", "tie",
                    "max_steps", "split", "inertia_solver", "min_excess")
#: … and all ``[diagnose]`` keys (``nominal_urdf`` and ``output`` are read by the command).
DIAGNOSE_KEYS = DIAGNOSE_OPTIONS + ("nominal_urdf", "output")


def diagnose(args: argparse.Namespace) -> int:
    """Sim-to-real gap diagnosis of the ``[model]`` (or ``[diagnose] nominal_urdf``) against the
    ``[data]`` logs (:mod:`consistid.diagnose`); the report goes to ``[diagnose] output``."""
    from consistid.cli.config import config_inputs, config_model, config_recordings, load_config
    from consistid.robot.model import model_without_dynamics

    config = load_config(args.config)
    with _kept_warnings() as found:
        model = config_model(config)
    t = config.table("diagnose", DIAGNOSE_KEYS, required=False)
    for key, kind in (("nominal_urdf", "string"), ("output", "string"),
                      ("effects", "string or array of strings"), ("split", "number"),
                      ("alpha", "number"), ("min_gain", "number"), ("min_excess", "number"),
                      ("tie", "number"),
                      ("max_steps", "integer"), ("inertia_solver", "string")):
        if key in t:
            config.expect("diagnose", key, t[key], kind)
    for key in ("sigma", "torque_resolution"):             # N·m, one number or one per joint
        if key in t and not isinstance(t[key], list):
            config.expect("diagnose", key, t[key], "number")
        elif key in t:
            config.expect("diagnose", key, t[key], "array of numbers")
    output = args.output or t.get("output")
    if output:
        output = _report_target(output if args.output else config.resolve(output),
                                config_inputs(config, model), args.force,
                                "--output" if args.output else "[diagnose] output")
    with _kept_warnings() as more:
        train, held = config_recordings(config, model)
        options = {k: t[k] for k in DIAGNOSE_OPTIONS if k in t}
        nominal = None
        if "nominal_urdf" in t:  # same joints, locks and gravity as [model], other inertias
            nominal = model_without_dynamics(config.resolve(t["nominal_urdf"]),
                                             locked_joints=model.locked_joints,
                                             gravity=model.gravity)[0]
        _log(f"diagnosing {model.name}: {train.dataset.n_samples} training samples, "
             f"{'held-out logs' if held is not None else 'time split'}")
        t0 = time.perf_counter()
        diag = ci.diagnose(model, train.dataset, nominal=nominal,
                           held_out=None if held is None else held.dataset,
                           progress=_progress(), **options)
        _log(f"      done in {time.perf_counter() - t0:.2f} s")
    found += [w for w in more if w not in found]
    if found:
        diag = dataclasses.replace(diag, notes=(*diag.notes, *(f"warning: {w}" for w in found)))
    print(diag.summary())
    if output:
        if output.suffix in (".html", ".txt"):
            with atomic_path(output) as tmp:
                diag.report(tmp)
        else:
            with atomic_dir(output) as tmp:
                diag.report(tmp)
        _log(f"wrote {output}")
    return 0


def _report_target(path, inputs: list, force: bool, what: str) -> Path:
    """A report file (``.html``/``.txt``) or folder, checked before the work
    (:mod:`consistid.cli.files`). A folder receives ``report.txt``, ``report.html`` and PNG
    plots: any such file already there needs ``--force``, and none may be an input."""
    path = Path(path)
    if path.suffix in (".html", ".txt"):
        return check_output(path, inputs=inputs, force=force, what=what)
    folder = check_output_dir(path, ("report.txt", "report.html"), inputs=inputs, force=force,
                              what=what)
    if folder.is_dir():
        plots = sorted(f.name for f in folder.iterdir() if f.suffix == ".png")
        check_output_dir(folder, plots, inputs=inputs, force=force, what=what)
    return folder


def calibrate(args: argparse.Namespace) -> int:
    """Kinematic calibration from a TOML configuration (:mod:`consistid.cli.calibrate`;
    it applies the file rules of :mod:`consistid.cli.files`: outputs checked first, inputs never
    written over, existing files only with ``--force``, atomic writes)."""
    result, written = run_calibrate(args.config, urdf=args.urdf,
                                                  report=args.report, force=args.force)
    print(cli_text(result.summary(max_rows=None if args.all else 30)))
    for path in written.values():
        _log(f"wrote {path}")
    return 0


def rollout(args: argparse.Namespace) -> int:
    """Rollout validation from a TOML configuration (:mod:`consistid.cli.rollout`)."""
    from .rollout import run_rollout  # heavy: MuJoCo, loaded with the command

    validation, _ = run_rollout(args.config, output=args.output, force=args.force, log=_log)
    print(validation.summary())
    return 0


COMMANDS: dict[str, tuple[Callable[[argparse.Namespace], int], str]] = {
    "demo": (demo, "simulate an excitation run, identify it, print a report"),
    "identify": (identify, "identify a robot from the logs named in a TOML config"),
    "excite": (excite, "design an optimal excitation trajectory from a TOML config, write CSV"),
    "simulate": (simulate, "run a MuJoCo arm with unmodelled effects, show the nominal residual"),
    "recover": (recover, "consistent standard parameters from base coefficients (TOML config)"),
    "payload": (payload, "estimate a payload from unloaded and loaded logs (TOML config)"),
    "diagnose": (diagnose, "sim-to-real gap diagnosis of a model against logs (TOML config)"),
    "calibrate": (calibrate, "kinematic calibration from measured poses (TOML config)"),
    "rollout": (rollout, "replay logs in your MuJoCo simulator before and "
                                            "after identification and calibration (TOML config)"),
    "online": (online_demo.run, "recursive estimation with a payload change, and Slotine–Li "
                                "adaptive control on the MuJoCo robot (demo)"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="consistid",
        description="Physically consistent identification of robot dynamics, and sim-to-real gap "
                    "diagnosis. Each command takes a TOML configuration (see examples/), except "
                    "demo and simulate.")
    parser.add_argument("--version", action="version", version=version_text())
    _add_quiet(parser, top=True)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help=COMMANDS["demo"][1])
    _add_robot(p)
    p.add_argument("--duration", type=float, default=30.0, help="seconds of excitation")
    p.add_argument("--rate", type=float, default=500.0, help="sampling rate in Hz")
    p.add_argument("--noise", type=float, default=0.1, help="torque noise σ in N·m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--output", metavar="DIR",
                   help=f"folder to write {', '.join(DEMO_OUTPUTS)} into (created if missing; "
                        "existing files need --force; without it the demo writes no file)")
    _add_force(p)
    p = sub.add_parser("identify", help=COMMANDS["identify"][1])
    p.add_argument("config", help="TOML file with [model], [data] and [identify] tables")
    p.add_argument("--all", action="store_true", help="list every base parameter")
    p.add_argument("--output", metavar="DIR",
                   help=f"folder to write {', '.join(IDENTIFY_OUTPUTS)} into (created if "
                        "missing; existing files need --force)")
    _add_force(p)
    p = sub.add_parser("excite", help=COMMANDS["excite"][1])
    p.add_argument("config", help="TOML file with [model] and [excite] tables")
    p.add_argument("--output", help="CSV path (default: [excite] output)")
    _add_force(p)
    p = sub.add_parser("simulate", help=COMMANDS["simulate"][1])
    _add_robot(p)
    p.add_argument("--effect", action="append", metavar="NAME=VALUE",
                   help="an effect on every joint, repeatable (viscous, coulomb, armature, "
                        "elasticity, offset, gain, delay, payload=MASS …); default "
                        "coulomb=1.0 and payload=1.0")
    p.add_argument("--duration", type=float, default=20.0, help="seconds logged at 1 kHz")
    p.add_argument("--noise", type=float, default=0.05, help="torque noise σ in N·m")
    p.add_argument("--plot", metavar="PNG", help="write the residuals to this PNG")
    _add_force(p)
    p.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("recover", help=COMMANDS["recover"][1])
    p.add_argument("config", help="TOML file with [model], [recover] and [data] or "
                                  "[recover] coefficients")
    p.add_argument("--all", action="store_true", help="list every moved coefficient")
    _add_force(p)
    p = sub.add_parser("payload", help=COMMANDS["payload"][1])
    p.add_argument("config", help="TOML file with [model], [data] (unloaded) and [payload]")
    p = sub.add_parser("diagnose", help=COMMANDS["diagnose"][1])
    p.add_argument("config", help="TOML file with [model], [data] and optionally [diagnose]")
    p.add_argument("--output", help="report directory, .html or .txt (default: [diagnose] "
                                    "output; none: text to stdout only)")
    _add_force(p)
    p = sub.add_parser("calibrate", help=COMMANDS["calibrate"][1])
    p.add_argument("config", help="TOML file with [model] and [calibrate] tables")
    p.add_argument("--urdf", help="calibrated URDF path (default: [calibrate] urdf)")
    p.add_argument("--report", help="HTML report path (default: [calibrate] report)")
    p.add_argument("--all", action="store_true", help="list every parameter")
    _add_force(p)
    p = sub.add_parser("rollout", help=COMMANDS["rollout"][1])
    p.add_argument("config", help="TOML file with [model], [data] and optionally [identify], "
                                  "[rollout]")
    p.add_argument("--output", help="HTML report (default: [rollout] output)")
    _add_force(p)
    online_demo.add_arguments(sub.add_parser("online", help=COMMANDS["online"][1]))
    for p in sub.choices.values():
        _add_quiet(p)
    return parser


def _add_robot(parser: argparse.ArgumentParser) -> None:
    """``--robot NAME`` (an example-robot-data arm) or ``--urdf PATH`` (any URDF) with
    ``--lock JOINT`` (repeatable: joints merged into their parent, e.g. a gripper's)."""
    parser.add_argument("--robot", default="panda",
                        help="example-robot-data arm (default panda; ignored with --urdf)")
    parser.add_argument("--urdf", metavar="PATH", help="any URDF instead of --robot")
    parser.add_argument("--lock", action="append", metavar="JOINT",
                        help="with --urdf: a joint to lock (repeatable)")


def _add_quiet(parser: argparse.ArgumentParser, top: bool = False) -> None:
    """``-q``: before or after the subcommand (the subcommand's default does not override)."""
    parser.add_argument("-q", "--quiet", action="store_true",
                        default=False if top else argparse.SUPPRESS,
                        help="no progress bars or step messages (results and errors only)")


def version_text() -> str:
    """``consistid X (pinocchio …, cvxpy …, clarabel …, mujoco …, numpy …, python …)``."""
    parts = []
    for name, dist in (("pinocchio", "pin"), ("cvxpy", "cvxpy"), ("clarabel", "clarabel"),
                       ("mujoco", "mujoco"), ("numpy", "numpy")):
        try:
            parts.append(f"{name} {importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            parts.append(f"{name} not installed")
    return f"consistid {ci.__version__} ({', '.join(parts)}, python {platform.python_version()})"


def _add_force(parser: argparse.ArgumentParser) -> None:
    """``--force``: replace existing outputs (never an input; :mod:`consistid.cli.files`)."""
    parser.add_argument("--force", action="store_true",
                        help="replace existing output files (inputs are never overwritten)")


def main(argv: Sequence[str] | None = None) -> int:
    global QUIET
    args = build_parser().parse_args(argv)
    QUIET = bool(args.quiet)
    # A library warning reads like an error line (command, category, message, TOML hints),
    # without Python's "file.py:61:" and source line, which mean nothing on a command line.
    # formatwarning, not showwarning: a caller that records warnings still gets them.
    previous = warnings.formatwarning
    warnings.formatwarning = lambda message, category, *_, **__: (
        f"consistid {args.command}: warning: {category.__name__}: {toml_hints(str(message))}\n")
    try:
        with silenced(QUIET), sigterm_interrupts():   # -q: no bar from any library call either
            return COMMANDS[args.command][0](args)
    except KeyboardInterrupt as exc:
        # SIGINT or SIGTERM: the temporaries are gone (``finally`` clauses), outputs untouched
        # or whole (consistid.filesafety); the shell's 128 + signal number
        sig = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
        print(f"consistid {args.command}: interrupted ({sig.name}); no output was left "
              "half-written", file=sys.stderr, flush=True)
        return 128 + int(sig)
    except ConsistidError as exc:
        print(f"consistid {args.command}: error: {toml_hints(str(exc))}", file=sys.stderr,
              flush=True)
        return 2
    except BrokenPipeError:
        # `consistid … | head`: the reader left. Stop quietly, as Unix tools do; what is still
        # buffered goes to /dev/null, or Python's exit would print a traceback for it (Python
        # docs, "Note on SIGPIPE").
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as exc:
        if exc.errno not in WRITE_FAILURES:
            raise
        # a full disk, a file-size limit, a read-only or failing filesystem: the writers'
        # temporaries are gone (``finally``), the outputs untouched (consistid.filesafety)
        where = f" {exc.filename}" if exc.filename else ""
        print(f"consistid {args.command}: error: could not write{where}: {exc.strerror}; no "
              "output was left half-written: free space (or raise the limit) or choose an "
              "output on another filesystem", file=sys.stderr, flush=True)
        return 2
    finally:
        warnings.formatwarning = previous
        release_output_locks()


if __name__ == "__main__":
    sys.exit(main())
