"""Logs in: jittered clocks, interval-averaged torques, and the cost of each file format.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/logs.py [--robot panda] [--duration 30]``.

A MuJoCo arm (no dynamic effects, inertias the URDF's ±20 %, torque noise 0.05 N·m) tracks a
5-harmonic Fourier excitation with physics and logging at 10 kHz; from that log three ~1 kHz
logs are cut, as loggers write them:

``uniform``     every 10th sample (1 ms steps);
``jittered``    steps drawn around 1 ms (σ 10 %, ≥ 0.7 ms) with 2 % long ones up to 8.8 ms,
                rounded to the 0.1 ms of the source (the log of issue 13);
``averaged``    uniform 1 ms, but each torque the mean of the 10 physics samples of its
                interval, stamped at the interval's end (read with and without
                ``timestamp="end"``).

Each goes through the default call ``Dataset.from_recording(t, q, tau)``. Printed: RMS error of
``q̇``, ``q̈`` against MuJoCo's true states (interpolated to the output stamps from 10 kHz),
the relative error of OLS base parameters, and the torque's RMS difference from the
instantaneous log's (interpolated to the output stamps). Then the time to read the uniform log
(with a gripper joint the model lacks) from each format by ``load_recording``, as a ratio to
``.npz``; all formats give the same dataset (checked).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.io

import consistid as ci
from consistid.data.recordings import from_arrays, load_recording
from consistid.errors import PoorExcitationWarning
from consistid.excitation import FourierTrajectory
from consistid.identification.summary import table
from consistid.robot.inertia import perturb
from consistid.simulate import Effects, record

PERIOD, HARMONICS = 10.0, 5


def jittered_indices(n_src: int, rng: np.random.Generator) -> np.ndarray:
    """Indices into a 10 kHz log whose steps look like issue 13's ~1 kHz logger."""
    steps = np.clip(rng.normal(10, 1, n_src // 5), 7, None)
    long = rng.random(steps.size) < 0.02
    steps[long] = rng.uniform(20, 88, long.sum())
    idx = np.concatenate([[0], np.cumsum(np.rint(steps).astype(int))])
    return idx[idx < n_src]


def truth_at(t: np.ndarray, rec) -> tuple[np.ndarray, np.ndarray]:
    return (np.column_stack([np.interp(t, rec.t, c) for c in rec.true_dq.T]),
            np.column_stack([np.interp(t, rec.t, c) for c in rec.true_ddq.T]))


def write_all(folder: Path, t: np.ndarray, q: np.ndarray, tau: np.ndarray,
              names: list[str]) -> dict[str, Path]:
    import pandas as pd
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    gq = np.column_stack([q, np.full(t.size, 0.04)])
    gt = np.column_stack([tau, np.zeros(t.size)])
    allnames = [*names, "gripper_joint"]
    frame = pd.DataFrame({"time": t, **{f"{n}.q": gq[:, j] for j, n in enumerate(allnames)},
                          **{f"{n}.effort": gt[:, j] for j, n in enumerate(allnames)}})
    paths = {"npz": folder / "log.npz", "csv": folder / "log.csv",
             "parquet": folder / "log.parquet", "mat": folder / "log.mat",
             "mcap": folder / "bag_mcap", "db3": folder / "bag_db3"}
    np.savez(paths["npz"], t=t, q=q, tau=tau, joint_names=np.array(names))
    frame.to_csv(paths["csv"], index=False, float_format="%.17g")
    frame.to_parquet(paths["parquet"])
    scipy.io.savemat(paths["mat"], {"t": t, "q": gq, "tau": gt,
                                    "joint_names": np.array(allnames, dtype=object)})
    ts = get_typestore(Stores.ROS2_HUMBLE)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    ns = np.rint(t * 1e9).astype(np.int64)
    for key, plugin in (("mcap", StoragePlugin.MCAP), ("db3", StoragePlugin.SQLITE3)):
        with Writer(paths[key], version=9, storage_plugin=plugin) as w:
            c = w.add_connection("/joint_states", js.__msgtype__, typestore=ts)
            for k in range(t.size):
                msg = js(header=header(stamp=stamp(sec=int(ns[k] // 10**9),
                                                   nanosec=int(ns[k] % 10**9)), frame_id=""),
                         name=allnames, position=gq[k], velocity=np.zeros(0), effort=gt[k])
                w.write(c, int(ns[k]), ts.serialize_cdr(msg, js.__msgtype__))
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--duration", type=float, default=30.0, help="seconds logged")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    warnings.simplefilter("ignore", PoorExcitationWarning)

    model = ci.RobotModel.example(args.robot)
    traj = FourierTrajectory.random(model, HARMONICS, PERIOD, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    truth = perturb(model.prior_parameters, 0.2, rng)
    t0 = time.perf_counter()
    rec = record(model, traj, Effects(torque_noise=0.05), true_parameters=truth,
                 duration=args.duration, rate=10000.0, physics_rate=10000.0, seed=args.seed)
    print(f"{model.name}: {args.duration:g} s at 10 kHz simulated in "
          f"{time.perf_counter() - t0:.1f} s; ~1 kHz logs cut from it\n")

    uniform = np.arange(0, rec.n_samples, 10)
    jit = jittered_indices(rec.n_samples, rng)
    steps = np.diff(rec.t[jit]) * 1e3
    print(f"jittered log: {jit.size} samples, steps {steps.min():.1f}–{steps.max():.1f} ms, "
          f"median {np.median(steps):.2f} ms, {np.sum(steps > 5):d} steps > 5 ms\n")
    n_win = uniform.size - 1
    averaged_tau = rec.tau[1:10 * n_win + 1].reshape(n_win, 10, -1).mean(axis=1)
    logs = {
        "uniform": (rec.t[uniform], rec.q[uniform], rec.tau[uniform], {}),
        "jittered": (rec.t[jit], rec.q[jit], rec.tau[jit], {}),
        "averaged, stamped at end": (rec.t[uniform[1:]], rec.q[uniform[1:]], averaged_tau, {}),
        "averaged, timestamp='end'": (rec.t[uniform[1:]], rec.q[uniform[1:]], averaged_tau,
                                      {"timestamp": "end"}),
    }
    reference = ci.Dataset.from_recording(*logs["uniform"][:3])
    rows = []
    beta = None
    for name, (t, q, tau, options) in logs.items():
        t1 = time.perf_counter()
        data = ci.Dataset.from_recording(t, q, tau, **options)
        ms = (time.perf_counter() - t1) * 1e3
        dq, ddq = truth_at(data.t, rec)
        res = ci.identify(model, data, method="ols", friction=None)
        beta = res.base.project(truth) if beta is None else beta
        inside = (data.t >= reference.t[0]) & (data.t <= reference.t[-1])
        ref_tau = np.column_stack([np.interp(data.t[inside], reference.t, c)
                                   for c in reference.tau.T])
        dtau = np.sqrt(np.mean((data.tau[inside] - ref_tau) ** 2))
        rows.append([name, data.n_samples, np.sqrt(np.mean((data.dq - dq) ** 2)),
                     np.sqrt(np.mean((data.ddq - ddq) ** 2)),
                     np.linalg.norm(res.base_parameters - beta) / np.linalg.norm(beta), dtau, ms])
    print(table(["log", "samples", "RMS dq err", "RMS ddq err", "‖β̂−β‖/‖β‖",
                 "RMS τ − uniform τ", "chain ms"], rows, ".3g"))

    with tempfile.TemporaryDirectory() as tmp:
        paths = write_all(Path(tmp), rec.t[uniform] + 1.7e9, rec.q[uniform], rec.tau[uniform],
                          list(model.joint_names))
        times, first = {}, None
        for fmt, path in paths.items():
            runs = []
            for _ in range(3):
                t1 = time.perf_counter()
                got = load_recording(path, model=model)
                runs.append(time.perf_counter() - t1)
            times[fmt] = statistics.median(runs)
            if first is None:
                first = got.dataset
            else:
                assert np.allclose(got.dataset.q, first.q, atol=1e-6), fmt
        chain = from_arrays(rec.t[uniform], rec.q[uniform], rec.tau[uniform], model=model)
        assert np.allclose(chain.dataset.q, first.q, atol=1e-6)
        def size(p: Path) -> float:
            files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
            return sum(f.stat().st_size for f in files) / 1e6

        rows = [[fmt, f"{size(paths[fmt]):.1f}", s * 1e3, s / times["npz"]]
                for fmt, s in times.items()]
        print(f"\nload_recording of the uniform log ({uniform.size} samples, {model.nv} + 1 "
              "joints; includes the signal chain), median of 3:")
        print(table(["format", "MB", "ms", "× npz"], rows, ".3g"))


if __name__ == "__main__":
    main()
