r"""TOML run configurations: a robot model and recordings, for the ``consistid`` commands.

A configuration names the URDF and the logs once, so that ``consistid identify CONFIG`` (and
other commands that read the same ``[model]`` / ``[data]`` tables) run on a user's robot without
code. Example (``examples/kuka_lwr4/identify.toml``)::

    root = "../.."                        # where relative paths start, relative to this file

    [model]
    urdf = "../shared/data/kuka_lwr4/kuka_lwr4.urdf"   # or: example = "panda" (no other key)
    strip_dynamics = false                # true: load a copy without <dynamics> tags
    # locked_joints = ["finger_joint"]     gravity = [0.0, 0.0, -9.81]
    tilt = "estimate"                     # the base's tilt from the train data (identify only)

    [data]
    dir = "../shared/data/kuka_lwr4"      # prefix of the files below (optional)
    keys = "flobaroid"                    # or "auto", "consistid", or {t = "times", q = ..., ...}
    joint_names = ["lwr_0_joint", "lwr_1_joint", ...]
    trim_start = 2.0                      # seconds dropped at the start of each recording
    trim_end = 0.0
    duplicates = "average"
    train = ["measurements_2.npz", "measurements_3.npz"]   # [["pos.csv", "eff.csv"]]: one
                                          # log split over files (positions, torques …)
    held_out = ["measurements_1.npz"]
    # any log format (consistid.data.formats): train = ["run1.csv", "run2.parquet",
    # "bag_folder", "run.mcap", "run.bag", "run.mat"], with, where they apply:
    # joints = ["joint1", ...]   (default the model's; other joints' columns, e.g. a gripper,
    #                             are dropped and listed)
    # columns = {t = "stamp", q = "pos_{joint}", tau = "eff_{joint}"}   (tables: CSV, Parquet)
    # topic = "/joint_states"    stamp = "header" | "receive"          (ROS bags, MCAP)
    # delimiter = ";"            (CSV; default sniffed)
    # time_unit = "ms"           (or "auto"; default seconds, implausible stamps refused)
    # timestamp = "end"          (torques averaged over each interval, stamped at its end)
    # derivatives = "auto"       (or "logged", "estimate")
    # angle_unit = "deg"         (q, dq, ddq of headers without a unit; default "rad", checked)
    # velocities = "logged"      (use the logged dq, ddq derived from it; default "auto")
    # [data.signals]             the signal chain for logs without dq/ddq: cutoff = 20.0, ...

    [identify]                            # keyword arguments of consistid.identify
    method = "sdp"
    friction = ["coulomb", "viscous", "offset"]
    # neighbourhood = {mass = 0.2, com = 0.02, inertia = 0.3}
    # ellipsoids = {lwr_6_link = {center = [0, 0, 0.05], semi_axes = [0.1, 0.1, 0.1]}}
    # or, with constraints = "ellipsoid": ellipsoids = "collision"  (from the URDF's geometry)

Relative paths are resolved against ``root``, itself relative to the configuration file's folder
(default: that folder), never against the current directory, so a configuration works from
anywhere. Unknown tables (:data:`TABLES`) and unknown keys raise
:class:`~consistid.errors.ConfigError` naming the table and the key.

``tilt = "estimate"`` (``consistid identify`` only) estimates the base's tilt, i.e. the direction
of ``gravity`` (default the level ``(0, 0, −9.81)``), from the ``train`` recordings with the
``[identify]`` friction and armature columns
(:func:`consistid.estimation.mounting.estimate_mounting`),
prints it, and identifies on the tilted model.
"""

from __future__ import annotations

import inspect
import sys
import warnings
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from ..drives.transmission import Transmission
from ..errors import ConfigError, DataQualityWarning, OptionError
from ..robot.model import EXAMPLE_ROBOTS, RobotModel
from ..data.chain import PreprocessOptions
from ..data.recordings import Recording, load_recording
from .files import same_file

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

#: The top-level tables a configuration may have (besides the ``root`` key), one per command.
TABLES = ("model", "data", "identify", "diagnose", "recover", "payload", "excite", "drives",
          "rollout")
MODEL_KEYS = ("urdf", "example", "strip_dynamics", "locked_joints", "gravity", "tilt", "name",
              "mjcf")
DATA_KEYS = ("dir", "keys", "joint_names", "trim_start", "trim_end", "duplicates", "train",
             "held_out", "joints", "columns", "topic", "stamp", "delimiter", "time_unit",
             "timestamp", "derivatives", "signals", "angle_unit", "velocities")
#: Keys of ``[drives]``: a motor-side log (motor angles, motor currents) and its transmission
#: (:class:`consistid.drives.transmission.Transmission`); ``gains = "identify"`` with
#: ``loaded`` logs and their ``payload_mass`` in place of ``torque_constants``
#: (:func:`consistid.identify_drive_gains`).
DRIVES_KEYS = ("ratios", "torque_constants", "coupling", "gains", "loaded", "payload_mass",
               "payload_body")
#: Keys of ``[data.signals]``: the signal chain's options (the fields of
#: :class:`consistid.data.chain.PreprocessOptions`, one schema for the API and the TOML) for
#: logs without logged velocities and accelerations; ``duplicates``, ``timestamp`` and
#: ``time_unit`` are ``[data]`` keys, as they apply to every log.
SIGNAL_KEYS = tuple(f.name for f in fields(PreprocessOptions)
                    if f.name not in ("duplicates", "timestamp", "time_unit"))


@dataclass(frozen=True)
class RunConfig:
    """A parsed configuration.

    Attributes
    ----------
    path : the configuration file.
    root : the folder relative paths start from.
    tables : the raw TOML tables (``model``, ``data``, ``identify``, ``diagnose`` …).
    """

    path: Path
    root: Path
    tables: Mapping[str, Any]

    def table(self, name: str, allowed: Iterable[str] | None = None,
              required: bool = True) -> dict[str, Any]:
        """A top-level table; with ``allowed``, unknown keys raise :class:`ConfigError`."""
        value = self.tables.get(name)
        if value is None:
            if required:
                raise ConfigError(f"{self.path.name}: missing table [{name}]")
            return {}
        return self.check_table(name, value, allowed)

    def check_table(self, name: str, value: Any, allowed: Iterable[str] | None = None
                    ) -> dict[str, Any]:
        """``value`` as a table called ``[name]`` (also nested ones such as ``excite.limits``);
        with ``allowed``, unknown keys raise :class:`ConfigError` naming the table and key."""
        if not isinstance(value, Mapping):
            raise ConfigError(f"{self.path.name}: [{name}] must be a table, got {value!r}")
        if allowed is not None:
            allowed = list(allowed)
            unknown = sorted(set(value) - set(allowed))
            if unknown:
                raise ConfigError(f"{self.path.name}: unknown key(s) {unknown} in [{name}]; "
                                  f"allowed: {sorted(allowed)}")
        return dict(value)

    def expect(self, table: str, key: str, value: Any, kind: str) -> Any:
        """``value`` (of ``[table] key``) if it has the TOML type ``kind``, else
        :class:`ConfigError` written in TOML terms. ``kind``: ``"string"``, ``"boolean"``,
        ``"number"`` (integer or float), ``"integer"``, ``"array of strings"``, ``"array of
        numbers"``, ``"string or array of strings"``, ``"string or table"``, ``"table"``."""
        def number(v: Any) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool)

        checks = {
            "string": lambda v: isinstance(v, str),
            "boolean": lambda v: isinstance(v, bool),
            "number": number,
            "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
            "array of strings": lambda v: isinstance(v, list) and all(isinstance(x, str)
                                                                      for x in v),
            "array of numbers": lambda v: isinstance(v, list) and all(number(x) for x in v),
            "string or array of strings": lambda v: isinstance(v, str) or (
                isinstance(v, list) and all(isinstance(x, str) for x in v)),
            "logs": lambda v: isinstance(v, str) or (isinstance(v, list) and all(
                isinstance(x, str) or (isinstance(x, list) and x
                                       and all(isinstance(y, str) for y in x)) for x in v)),
            "string or table": lambda v: isinstance(v, (str, Mapping)),
            "table": lambda v: isinstance(v, Mapping),
        }
        if not checks[kind](value):
            example = {"string": '"text"', "boolean": "true", "number": "1.5",
                       "integer": "3", "array of strings": '["a", "b"]',
                       "array of numbers": "[0.0, 1.0]",
                       "string or array of strings": '"a" or ["a", "b"]',
                       "logs": '"a.csv" or ["a.csv", ["pos.csv", "vel.csv", "eff.csv"]]',
                       "string or table": '"name" or {t = "time", ...}',
                       "table": '{t = "time", ...}'}[kind]
            kind = ("string or array of log names (a split log: an array of its files)"
                    if kind == "logs" else kind)
            article = "an" if kind[0] in "aeiou" else "a"
            raise ConfigError(f"{self.path.name}: [{table}] {key} must be {article} {kind} (e.g. "
                              f"{key} = {example}), got {key} = {_toml(value)}")
        return value

    def resolve(self, value: str, *, under: str | None = None) -> Path:
        """A path from the configuration: absolute as is, else relative to ``root`` (then to
        ``under``, itself relative to ``root``, when given)."""
        p = Path(value).expanduser()
        if p.is_absolute():
            return p
        base = self.root if under is None else self.resolve(under)
        return (base / p).resolve()


def _toml(value: Any) -> str:
    """``value`` written as TOML would write it (for messages)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace('"', '\\"') + '"'
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def read_toml(path: str | Path, allowed: Sequence[str]
              ) -> tuple[Path, Path, dict[str, Any]]:
    """``(path, root, tables)`` of a TOML configuration: the file must exist and parse, ``root``
    (default ``"."``, relative to the file) be a path string, and every other top-level key be
    one of the ``allowed`` tables — each failure a :class:`ConfigError` naming the file."""
    path = Path(path)
    if path.is_dir():
        found = sorted(p.name for p in path.glob("*.toml"))
        raise ConfigError(f"configuration file {str(path)!r} is a folder, not a TOML file"
                          + (f"; it holds {found[:6]}" if found else ""))
    if not path.is_file():
        raise ConfigError(f"configuration file {str(path)!r} does not exist")
    try:
        with open(path, "rb") as fh:
            tables = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path.name} is not valid TOML: {exc}") from exc
    root = tables.pop("root", ".")
    if not isinstance(root, str):
        raise ConfigError(f"{path.name}: root must be a path string, got {root!r}")
    unknown = sorted(set(tables) - set(allowed))
    if unknown:
        raise ConfigError(f"{path.name}: unknown table(s) or top-level key(s) {unknown}; "
                          f"allowed: root and the tables {list(allowed)}")
    return path.resolve(), (path.resolve().parent / root).resolve(), tables


def load_config(path: str | Path) -> RunConfig:
    """Read a TOML configuration (module docstring for the layout)."""
    return RunConfig(*read_toml(path, TABLES))


def config_inputs(config: RunConfig, model: RobotModel | None = None) -> list[Path]:
    """Every file the configuration reads: itself, ``[model] urdf``, the ``[data]``,
    ``[payload] loaded`` and ``[drives] loaded`` logs, ``[recover] coefficients``,
    ``[diagnose] nominal_urdf`` (and ``model.source`` when given). Outputs must never be one
    of these (:mod:`consistid.cli.files`). Values of the wrong type are skipped here (their own
    readers name them)."""
    out = [config.path]
    if model is not None and model.source is not None:
        out.append(Path(model.source))

    def add(value: Any, under: str | None = None) -> None:
        values = [value] if isinstance(value, str) else value if isinstance(value, list) else []
        for v in values:
            if isinstance(v, list):                     # the files of a split log
                add(v, under)
            elif isinstance(v, str) and v:
                try:
                    out.append(config.resolve(v, under=under))
                except (TypeError, ValueError, OSError):
                    pass

    tables = {k: v for k, v in config.tables.items() if isinstance(v, Mapping)}
    data_dir = tables.get("data", {}).get("dir")
    data_dir = data_dir if isinstance(data_dir, str) else None
    add(tables.get("model", {}).get("urdf"))
    add(tables.get("data", {}).get("train"), data_dir)
    add(tables.get("data", {}).get("held_out"), data_dir)
    add(tables.get("payload", {}).get("loaded"), data_dir)
    add(tables.get("drives", {}).get("loaded"), data_dir)
    add(tables.get("recover", {}).get("coefficients"))
    add(tables.get("diagnose", {}).get("nominal_urdf"))
    return out


def estimates_tilt(config: RunConfig) -> bool:
    """Whether ``[model] tilt = "estimate"`` (module docstring)."""
    return "tilt" in config.table("model", MODEL_KEYS)


def config_model(config: RunConfig, allow_tilt: bool = False) -> RobotModel:
    """The robot of the ``[model]`` table, level as configured. ``tilt = "estimate"`` is
    accepted only with ``allow_tilt`` (a command that estimates it from the data)."""
    t = config.table("model", MODEL_KEYS)
    for key, kind in (("urdf", "string"), ("example", "string"), ("name", "string"),
                      ("strip_dynamics", "boolean"), ("locked_joints", "array of strings"),
                      ("tilt", "string"), ("mjcf", "string")):
        if key in t:
            config.expect("model", key, t[key], kind)
    tilt = t.pop("tilt", None)
    if tilt is not None and (tilt != "estimate" or not allow_tilt):
        raise ConfigError(f"{config.path.name}: [model] tilt = \"estimate\" is the only value, "
                          "for `consistid identify` only (other commands: give gravity = [gx, "
                          f"gy, gz] as identify printed it); got tilt = {tilt!r}")
    gravity = t.get("gravity")
    if gravity is not None and not (
            isinstance(gravity, list) and len(gravity) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in gravity)):
        raise ConfigError(f"{config.path.name}: [model] gravity must be three numbers [gx, gy, "
                          f"gz] (m/s², base frame), got {gravity!r}")
    if "example" in t:  # an example-robot-data arm by name (RobotModel.example)
        if t["example"] not in EXAMPLE_ROBOTS:
            raise ConfigError(f"{config.path.name}: [model] example = {_toml(t['example'])} is "
                              f"not an example robot; they are {_toml(list(EXAMPLE_ROBOTS))} "
                              "(or give urdf = \"path/to/robot.urdf\")")
        if set(t) != {"example"}:
            raise ConfigError(f"{config.path.name}: [model] example = {t['example']!r} takes no "
                              f"other key; got {sorted(set(t) - {'example'})}")
        return RobotModel.example(t["example"])
    if "mjcf" in t:  # a MuJoCo model (RobotModel.from_mjcf)
        clash = sorted({"urdf", "strip_dynamics"} & set(t))
        if clash:
            raise ConfigError(f"{config.path.name}: [model] mjcf = {_toml(t['mjcf'])} takes no "
                              f"{' or '.join(clash)} key (a URDF's); give one robot file")
        options = {k: t[k] for k in ("locked_joints", "gravity", "name") if k in t}
        return RobotModel.from_mjcf(config.resolve(t["mjcf"]), **options)
    if "urdf" not in t:
        raise ConfigError(f"{config.path.name}: [model] needs urdf = \"path/to/robot.urdf\" "
                          "(or mjcf = \"path/to/robot.xml\")")
    urdf = config.resolve(t["urdf"])
    kwargs: dict[str, Any] = {"locked_joints": t.get("locked_joints", ())}
    for key in ("gravity", "name"):
        if key in t:
            kwargs[key] = t[key]
    if t.get("strip_dynamics", False):
        from ..robot.model import model_without_dynamics

        return model_without_dynamics(urdf, **kwargs)[0]
    return RobotModel.from_urdf(urdf, **kwargs)


def config_recordings(config: RunConfig, model: RobotModel | None = None
                      ) -> tuple[Recording, Recording | None]:
    """The ``train`` recordings (stacked as segments) and the ``held_out`` ones (or ``None``)
    of the ``[data]`` table, each trimmed and matched to ``model``'s joints."""
    t = config.table("data", DATA_KEYS)
    for key, kind in (("dir", "string"), ("keys", "string or table"),
                      ("joint_names", "array of strings"), ("trim_start", "number"),
                      ("trim_end", "number"), ("duplicates", "string"),
                      ("train", "logs"), ("held_out", "logs"),
                      ("joints", "array of strings"), ("columns", "table"),
                      ("topic", "string"), ("stamp", "string"), ("delimiter", "string"),
                      ("time_unit", "string"), ("timestamp", "string or table"),
                      ("derivatives", "string"), ("angle_unit", "string"),
                      ("velocities", "string")):
        if key in t:
            config.expect("data", key, t[key], kind)
    if not t.get("train"):
        raise ConfigError(f"{config.path.name}: [data] needs train = [\"file.npz\", ...]")
    for key in ("trim_start", "trim_end"):
        if key in t and t[key] < 0:
            raise ConfigError(f"{config.path.name}: [data] {key} must be seconds ≥ 0 (dropped "
                              f"from each log), got {key} = {_toml(t[key])}")
    if "dir" in t:
        _check_folder(config, "dir", t["dir"])
    options = {k: t[k] for k in ("joint_names", "trim_start", "trim_end", "duplicates",
                                 "joints", "columns", "topic", "stamp", "delimiter",
                                 "time_unit", "timestamp", "derivatives", "angle_unit",
                                 "velocities")
               if k in t}
    if "signals" in t:
        options.update(config.check_table("data.signals", t["signals"], SIGNAL_KEYS))
    drives = config_drives(config)
    if drives is not None:
        if model is not None and drives.n != model.nv:
            raise ConfigError(f"{config.path.name}: [drives] ratios has {drives.n} entries but "
                              f"{model.name} has {model.nv} joints ({', '.join(model.joint_names)})"
                              ": one gear ratio and torque constant per motor, in that order")
        options["drives"] = drives
    keys = t.get("keys", "auto")

    def read(files: Any, what: str) -> Recording:
        if isinstance(files, str):
            files = [files]
        config.expect("data", what, files, "logs")
        flat = [g for f in files for g in ([f] if isinstance(f, str) else f)]
        found = iter(_distinct_logs(config, what, flat, t.get("dir")))
        paths = [next(found) if isinstance(f, str) else [next(found) for _ in f]
                 for f in files]           # a list inside the list: a log split over files
        recs = [load_recording(p, keys, model=model, **options) for p in paths]
        return recs[0] if len(recs) == 1 else Recording.concatenate(recs)

    held = t.get("held_out")
    if held:
        _warn_shared(config, t["train"], held, t.get("dir"))
    return read(t["train"], "train"), (read(held, "held_out") if held else None)


def config_drives(config: RunConfig) -> Transmission | None:
    """The ``[drives]`` table as a :class:`~consistid.drives.transmission.Transmission`, or
    ``None`` without one: the ``[data]`` logs then hold motor angles and motor currents (A),
    converted to the joint side with the datasheet gear ratios and torque constants. Errors
    name the TOML key."""
    t = config.table("drives", DRIVES_KEYS, required=False)
    if not t:
        return None
    name = config.path.name
    identified = config_drive_gains(config) is not None
    for key in ("ratios",) if identified else ("ratios", "torque_constants"):
        if key not in t:
            raise ConfigError(f"{name}: [drives] needs {key} = [...] (one per motor, in the "
                              "joints' order; torque constants in N·m/A at the motor)")
        config.expect("drives", key, t[key], "array of numbers")
    coupling = t.get("coupling")
    if coupling is not None and not (isinstance(coupling, list) and all(
            isinstance(row, list) and config.expect("drives", "coupling", row,
                                                    "array of numbers") for row in coupling)):
        raise ConfigError(f"{name}: [drives] coupling must be an array of rows, one per motor "
                          f"(e.g. coupling = [[1, 0], [1, 1]]), got coupling = {_toml(coupling)}")
    try:
        return Transmission(t["ratios"], coupling=coupling,
                            torque_constants=None if identified else t["torque_constants"])
    except OptionError as exc:
        raise ConfigError(f"{name}: [drives] {exc}") from exc


def config_drive_gains(config: RunConfig) -> dict[str, Any] | None:
    """With ``[drives] gains = "identify"``, the keywords of
    :func:`consistid.identify_drive_gains` the table gives (``loaded``: its logs, read as
    ``[data] train`` is; ``payload_mass``; ``payload_body``); otherwise ``None``. Errors name
    the TOML key."""
    t = config.table("drives", DRIVES_KEYS, required=False)
    if not t or "gains" not in t:
        return None
    name = config.path.name
    if t["gains"] != "identify":
        raise ConfigError(f"{name}: [drives] gains = {_toml(t['gains'])}: the one value is "
                          'gains = "identify" (unknown gains, from an unloaded and a loaded '
                          "run); datasheet gains go in torque_constants = [...]")
    if "torque_constants" in t:
        raise ConfigError(f'{name}: [drives] gains = "identify" and torque_constants both '
                          "given: keep torque_constants (datasheet gains) or gains = "
                          '"identify" (unknown ones), not both')
    if not t.get("loaded"):
        raise ConfigError(f'{name}: [drives] gains = "identify" needs loaded = ["file.npz", '
                          "...]: the same kind of excitation run with a load of known mass "
                          "(currents alone fix the gains only up to one common scale)")
    config.expect("drives", "loaded", t["loaded"], "string or array of strings")
    if "payload_mass" not in t:
        raise ConfigError(f'{name}: [drives] gains = "identify" needs payload_mass = <kg>: '
                          "the weighed mass of the load in the loaded logs")
    config.expect("drives", "payload_mass", t["payload_mass"], "number")
    if "payload_body" in t:
        config.expect("drives", "payload_body", t["payload_body"], "string")
    return {"loaded": t["loaded"], "payload_mass": t["payload_mass"],
            "payload_body": t.get("payload_body")}


def _distinct_logs(config: RunConfig, what: str, files: list[str], under: str | None
                   ) -> list[Path]:
    """The paths of ``[data] what``, refusing an empty name and a log listed twice (under any
    spelling: stacked twice, its samples would count twice and every σ shrink by √2)."""
    paths: list[Path] = []
    for k, name in enumerate(files):
        if not name.strip():
            raise ConfigError(f"{config.path.name}: [data] {what} has an empty file name (entry "
                              f"{k + 1} of {_toml(files)}); remove it or name the log")
        path = config.resolve(name, under=under)
        earlier = [j for j, p in enumerate(paths) if same_file(p, path)]
        if earlier:
            raise ConfigError(f"{config.path.name}: [data] {what} lists the log {str(path)!r} "
                              f"twice (entries {earlier[0] + 1} and {k + 1}: "
                              f"{_toml(files[earlier[0]])}, {_toml(name)}); stacked twice, its "
                              "samples would count twice and every σ would shrink by √2: list "
                              "each log once")
        paths.append(path)
    return paths


def _check_folder(config: RunConfig, key: str, value: str) -> None:
    """:class:`ConfigError` when ``[data] key`` (a folder under ``root``) is missing or a file,
    naming ``root`` when that is what is missing."""
    folder = config.resolve(value)
    if folder.is_dir():
        return
    if folder.exists():
        raise ConfigError(f"{config.path.name}: [data] {key} = {_toml(value)} is the file "
                          f"{str(folder)!r}, not a folder (the logs' folder; leave {key} out "
                          "to read them from root)")
    where = (f"root {str(config.root)!r} does not exist (root is relative to the "
             "configuration file's folder)" if not config.root.is_dir()
             else f"the folder {str(folder)!r} does not exist")
    raise ConfigError(f"{config.path.name}: [data] {key} = {_toml(value)}: {where}")


def _warn_shared(config: RunConfig, train: Any, held: Any, under: str | None) -> None:
    """Warn (:class:`DataQualityWarning`) when a ``held_out`` log is also a ``train`` log: its
    score would not be a held-out score."""
    def paths(v: Any) -> list[Path]:
        values = [v] if isinstance(v, str) else v if isinstance(v, list) else []
        return [config.resolve(f, under=under) for f in values if isinstance(f, str)]

    shared = [h for h in paths(held) if any(same_file(h, tr) for tr in paths(train))]
    if shared:
        warnings.warn(f"{config.path.name}: [data] held_out names train log(s) "
                      f"{[p.name for p in shared]}: the model is scored on data it was fitted "
                      "to, so the held-out RMS says nothing about new data; hold out another "
                      "recording (or leave held_out out)", DataQualityWarning, stacklevel=3)


def identify_keys() -> tuple[str, ...]:
    """The keys of ``[identify]``: the keyword arguments of :func:`consistid.identify` and the
    fields of :class:`~consistid.identification.sdp.SDPOptions` (one schema for the API and the
    TOML file)."""
    from ..identification.identify import identify
    from ..identification.sdp import SDPOptions

    own = [n for n, p in inspect.signature(identify).parameters.items()
           if n not in ("model", "dataset") and p.kind is not p.VAR_KEYWORD]
    return tuple(own + [f.name for f in fields(SDPOptions) if f.name not in own])


def config_identify(config: RunConfig) -> dict[str, Any]:
    """The keyword arguments of ``[identify]`` for :func:`consistid.identify` (unknown keys raise
    :class:`ConfigError`). TOML tables become objects: ``neighbourhood = {mass, com, inertia}``
    a :class:`~consistid.identification.priors.Neighbourhood`, ``ellipsoids = {body = {center,
    semi_axes}}``
    :class:`~consistid.robot.shapes.Ellipsoid` objects (``ellipsoids = "collision"`` passes on:
    the URDF's collision ellipsoids, :func:`consistid.robot.shapes.collision_ellipsoids`)."""
    options = config.table("identify", identify_keys(), required=False)
    armature = options.get("armature")
    if armature is not None and not (
            isinstance(armature, bool) or (isinstance(armature, list) and all(
                isinstance(a, (str, int)) and not isinstance(a, bool) for a in armature))):
        raise ConfigError(f"{config.path.name}: [identify] armature must be true, false or an "
                          "array of joint names (e.g. armature = [\"joint1\", \"joint2\"]), "
                          f"got armature = {_toml(armature)}")
    excluded = options.get("exclude_joints")
    if excluded is not None and not (isinstance(excluded, list) and all(
            isinstance(a, (str, int)) and not isinstance(a, bool) for a in excluded)):
        raise ConfigError(f"{config.path.name}: [identify] exclude_joints must be an array of "
                          "joint names (e.g. exclude_joints = [\"joint6\"]: their torque rows "
                          f"are left out), got exclude_joints = {_toml(excluded)}")
    if "neighbourhood" in options:
        from ..identification.priors import Neighbourhood

        t = config.check_table("identify.neighbourhood", options["neighbourhood"],
                               ("mass", "com", "inertia"))
        options["neighbourhood"] = Neighbourhood(**t)
    if "ellipsoids" in options and options["ellipsoids"] != "collision":
        options["ellipsoids"] = {
            body: config_ellipsoid(config, f"identify.ellipsoids.{body}", value)
            for body, value in config.check_table("identify.ellipsoids",
                                                  options["ellipsoids"]).items()}
    return options


def config_ellipsoid(config: RunConfig, name: str, value: Any) -> Any:
    """An :class:`~consistid.robot.shapes.Ellipsoid` from ``{center = [x, y, z], semi_axes = [a, b,
    c]}`` (table ``[name]``)."""
    from ..robot.shapes import Ellipsoid

    t = config.check_table(name, value, ("center", "semi_axes"))
    if set(t) != {"center", "semi_axes"}:
        raise ConfigError(f"{config.path.name}: [{name}] must be {{center = [x, y, z], "
                          f"semi_axes = [a, b, c]}}, got {value!r}")
    return Ellipsoid.from_semi_axes(t["center"], t["semi_axes"])
