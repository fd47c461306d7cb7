"""Write the small simulated logs of the UR5, UR10, xArm7 and Kinova examples, each in the layout
its robot's own logger writes (examples/<arm>/data/).

    python examples/make_arm_logs.py            # writes examples/{ur5,ur10,xarm7,kinova}/data/
    python examples/make_arm_logs.py OUT_DIR    # writes OUT_DIR/<arm>/ instead

Each "real" arm is MuJoCo (:func:`consistid.simulate.record`) with its URDF's inertias scaled by
factors drawn from [0.9, 1.1] (:func:`consistid.robot.inertia.perturb`, seed 7), Coulomb and
viscous friction, white torque noise σ = 0.05 N·m and 19-bit encoders, following a random
Fourier trajectory (5 harmonics, 8 s period; a stiff tracking controller, 100 rad/s) at
100 Hz: 6 s to train on (seed 1), 3 s held out (seed 2). The arms are example-robot-data's:
``ur5`` and ``ur10`` (the CB-series arms — example-robot-data has no UR5e/UR10e), ``xarm7``,
and ``kinova`` (a Kinova Jaco2 j2s6s200 — it has no Gen3; no KUKA iiwa either). The layouts:

========  ===================================================  ==========================
arm       file layout (what consistid recognises without a      time
          column mapping, consistid.data.formats.presets)
========  ===================================================  ==========================
ur5       RTDE recorder: space-separated ``timestamp``,         s since the controller
          ``actual_q_0..5``, ``actual_qd_0..5``,                 started
          ``actual_current_0..5`` (A), ``target_moment_0..5``
ur10      ur_rtde's recorder: comma-separated ``timestamp``,    s since the controller
          ``target_q_0..5``, ``actual_q_0..5``,                  started
          ``actual_qd_0..5``, ``target_moment_0..5``,
          ``actual_current_as_torque_0..5``
xarm7     ``rostopic echo -p /joint_states``: ``%time``,        ns (Unix)
          ``field.header.stamp``, ``field.name0..6``,
          ``field.position0..``, ``field.velocity0..``,
          ``field.effort0..``
kinova    the same JointState export, joints listed in another  ns (Unix)
          order than the URDF's, plus two finger joints
========  ===================================================  ==========================

Everything is seeded; the files are small (< 0.4 MB per arm) and committed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.robot.inertia import perturb
from consistid.simulate import Effects, TrackingController, record

RATE, PERIOD, HARMONICS = 100.0, 8.0, 5
DURATIONS = {"train": 6.0, "held_out": 3.0}
NS0 = 1_764_000_000_000_000_000


def simulate(model: ci.RobotModel, truth: np.ndarray, seed: int, duration: float):
    nv = model.nv
    effects = Effects(coulomb=np.linspace(1.0, 0.4, nv), viscous=np.linspace(0.6, 0.2, nv),
                      torque_noise=0.05, quantisation=2 * np.pi / 2 ** 19)
    traj = ci.FourierTrajectory.random(model, harmonics=HARMONICS, period=PERIOD, seed=seed,
                                       amplitude=0.5)
    return record(model, traj, effects, true_parameters=truth, duration=duration, rate=RATE,
                  seed=seed, controller=TrackingController(bandwidth=100.0))


def write(path: Path, columns: dict, sep: str = ",") -> None:
    """A table: number columns written with 7 significant digits (stamps as integers or ms),
    joint-name columns as text."""
    n = len(next(iter(columns.values())))
    with open(path, "w") as fh:
        fh.write(sep.join(columns) + "\n")
        for k in range(n):
            cells = []
            for name, v in columns.items():
                x = v[k]
                cells.append(x if isinstance(x, str)
                             else str(int(x)) if name in ("%time", "field.header.stamp")
                             else f"{x:.4f}" if name == "timestamp" else f"{x:.7g}")
            fh.write(sep.join(cells) + "\n")


def rtde(rec) -> dict:
    cols = {"timestamp": 3120.5 + rec.t}
    dq = np.gradient(rec.q, rec.t, axis=0)             # the controller's velocity estimate
    for name, a in (("actual_q", rec.q), ("actual_qd", dq), ("actual_current", rec.tau / 9.0),
                    ("target_moment", rec.tau)):
        cols.update({f"{name}_{j}": a[:, j] for j in range(rec.q.shape[1])})
    return cols


def ur_rtde(rec) -> dict:
    """The ur_rtde library's recorder (``RTDEReceiveInterface.startFileRecording``): comma
    separated, with ``actual_current_as_torque`` (PolyScope ≥ 5.23) beside the commanded
    ``target_moment`` (here the measured torque one 2 ms controller step earlier)."""
    cols = {"timestamp": 871.25 + rec.t}
    dq = np.gradient(rec.q, rec.t, axis=0)
    commanded = np.vstack([rec.tau[:1], rec.tau[:-1]])
    for name, a in (("target_q", rec.q), ("actual_q", rec.q), ("actual_qd", dq),
                    ("target_moment", commanded), ("actual_current_as_torque", rec.tau)):
        cols.update({f"{name}_{j}": a[:, j] for j in range(rec.q.shape[1])})
    return cols


def joint_states(rec, names: list[str], order: np.ndarray, extra: int = 0) -> dict:
    """A JointState export: the joints in ``order``, then ``extra`` finger joints."""
    n = rec.t.size
    ns = NS0 + np.round(rec.t * 1e9).astype(np.int64)
    dq = np.gradient(rec.q, rec.t, axis=0)
    full_names = [names[i] for i in order] + [f"finger_joint_{k + 1}" for k in range(extra)]
    pad = np.zeros((n, extra))
    signals = {"position": np.column_stack([rec.q[:, order], pad + 0.3]),
               "velocity": np.column_stack([dq[:, order], pad]),
               "effort": np.column_stack([rec.tau[:, order], pad + 0.1])}
    cols = {"%time": ns + 35_000, "field.header.seq": np.arange(n), "field.header.stamp": ns,
            "field.header.frame_id": [""] * n}
    cols.update({f"field.name{k}": [name] * n for k, name in enumerate(full_names)})
    for signal, a in signals.items():
        cols.update({f"field.{signal}{k}": a[:, k] for k in range(a.shape[1])})
    return cols


def main(out: Path) -> None:
    for arm, layout in (("ur5", "rtde"), ("ur10", "ur_rtde"), ("xarm7", "joint_states"),
                        ("kinova", "shuffled")):
        model = ci.RobotModel.example(arm)
        truth = perturb(model.prior_parameters, 0.1, np.random.default_rng(7))
        folder = out / arm / "data" if out == EXAMPLES else out / arm
        folder.mkdir(parents=True, exist_ok=True)
        names = list(model.joint_names)
        for seed, (part, duration) in enumerate(DURATIONS.items(), start=1):
            rec = simulate(model, truth, seed, duration)
            if layout == "rtde":
                write(folder / f"robot_data_{part}.csv", rtde(rec), sep=" ")
            elif layout == "ur_rtde":
                write(folder / f"robot_data_{part}.csv", ur_rtde(rec))
            else:
                order = (np.arange(model.nv) if layout == "joint_states"
                         else np.random.default_rng(seed).permutation(model.nv))
                write(folder / f"joint_states_{part}.csv",
                      joint_states(rec, names, order, extra=2 if layout == "shuffled" else 0))
        for f in sorted(folder.iterdir()):
            print(f"wrote {f} ({f.stat().st_size / 1024:.0f} kB)")


EXAMPLES = Path(__file__).resolve().parent

if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else EXAMPLES)
