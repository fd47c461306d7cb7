"""How close identification runs to the floor: issue 17's table, every figure a ratio measured in
one run, one BLAS thread.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/floor.py [--samples 100000]
[--talos-samples 100000] [--large]``.

The floor of a regressor-based method is ``pinocchio.rnea`` over the same samples (a Python loop
of ``pin.rnea`` calls, as a user would write it): every ratio below divides a time by the rnea
time measured in the same run on the same samples, just before it (medians over ``--repeat``
pairs), so the load of a shared machine cancels as far as it can; each ratio is printed for
wall-clock times and, in parentheses, for the CPU times of this process (``time.process_time``:
one thread, so the same when the machine is idle, and less disturbed by other jobs), and
the ratio of the minima over the repetitions (``timeit``'s statistic). Rows:

* ``consistid.regressor``: the streamed regressor (4096-sample buffer, rigid body + Coulomb,
  viscous, offset), and the Pinocchio call alone (``computeJointTorqueRegressor`` in a loop);
* compression: regressor + per-joint QR (:func:`consistid.identification.compression.compress`)
  on each joint's supported independent columns, as ``identify`` runs it (``base=``);
* residual pass for ``covariance="coloured"``: ``τ − Yθ`` by rnea of the identified model plus
  the autocorrelation (:func:`~consistid.identification.streaming.residual_statistics`);
* ``identify(method="sdp")``, the whole call (defaults: log-det prior, pseudo-inertia LMIs,
  coloured covariance), Panda and the 32-body fixed-base Talos (example-robot-data
  ``talos_reduced.urdf``, every joint moving; its fixed gripper joints carry ``<mimic>`` tags
  that ``RobotModel.from_urdf`` refuses, so the Pinocchio model is wrapped directly). The SDP's
  structure is compiled once per model and options (:mod:`consistid.identification.program`):
  the figure is a call after a first one on other data of the same model, as in a Monte Carlo
  loop; the first call's compile is printed beside it;
* a poorly excited SDP (Panda, 2 s at 500 Hz of 20 %-amplitude motion: 7 000 rows, rigid body,
  σ = 0.1 N·m): ``identify_sdp`` on the compressed problem, compiled program cached, and
  compiled afresh (cache cleared), against numpy pivoted QR + lstsq on the same rows
  (``scipy.linalg.qr(pivoting=True)`` then ``numpy.linalg.lstsq`` on the kept columns);
* ``diagnose`` on a 30 s, 500 Hz MuJoCo Panda log (Coulomb friction 1 N·m on every joint, white
  noise 0.05 N·m), against the MuJoCo simulation of that log;
* ``estimate_mounting`` (Panda, 2 000 samples) in a subprocess with the BLAS's default threading
  and in one with one thread;
* peak memory of ``identify(model, <generator of Datasets>)`` (streamed, 10⁵-sample parts, the
  generator making each part) in a subprocess: 10⁶ samples by default, 10⁷ with ``--large``;
  the peak of the allocations ``tracemalloc`` traces during the call (numpy registers its
  buffers there; Pinocchio's and Clarabel's own, O(1) in N, are not counted), against the size
  of the whole data set.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import textwrap
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402  (after the thread settings)
import pinocchio as pin  # noqa: E402
import scipy.linalg  # noqa: E402

import consistid as ci  # noqa: E402
from consistid.excitation import FourierTrajectory  # noqa: E402
from consistid.identification import program  # noqa: E402
from consistid.identification.base import compute_base_parameters  # noqa: E402
from consistid.identification.compression import compress  # noqa: E402
from consistid.identification.identify import base_parameters_of  # noqa: E402
from consistid.identification.regressor import RegressorSpec, dataset_regressor, iter_regressor  # noqa: E402
from consistid.identification.sdp import identify_sdp  # noqa: E402
from consistid.identification.streaming import residual_statistics  # noqa: E402
from consistid.identification.summary import table  # noqa: E402
from consistid.robot.model import example_robot_data_dir  # noqa: E402
from sdp_speed import median_time as timed  # noqa: E402  (this folder's sdp_speed.py)

SIGMA = 0.1
FRICTION = ("coulomb", "viscous", "offset")


class Ratio:
    """A time ratio, wall clock and CPU time of this process (``time.process_time``, less
    sensitive to other jobs on a shared machine), and optionally the ratio of the two minima
    over the repetitions (``timeit``'s statistic: what the code costs when nothing interferes;
    the rnea loop's own time varies by up to 1.5× between repetitions here); formats as
    ``"wall (CPU cpu; minima best)"``."""

    def __init__(self, wall: float, cpu: float, best: float | None = None) -> None:
        self.wall, self.cpu, self.best = wall, cpu, best

    def __format__(self, spec: str) -> str:
        best = "" if self.best is None else f"; minima {self.best:{spec}}"
        return f"{self.wall:{spec}} (CPU {self.cpu:{spec}}{best})"


def paired(fn, floor, repeat: int):
    """Median time of ``fn`` and median of its ratios to ``floor`` timed just before it, each
    repetition a pair (a shared machine's load drifts less within a pair than over a run); the
    ratio as a :class:`Ratio` of wall-clock and of CPU times."""
    times, floors, walls, cpus, out = [], [], [], [], None
    for _ in range(repeat):
        c0 = time.process_time()
        t_floor, _ = timed(floor, 1)
        c1 = time.process_time()
        t, out = timed(fn, 1)
        c2 = time.process_time()
        times.append(t)
        floors.append(t_floor)
        walls.append(t / t_floor)
        cpus.append((c2 - c1) / max(c1 - c0, 1e-9))
    return statistics.median(times), Ratio(statistics.median(walls), statistics.median(cpus),
                                           min(times) / min(floors)), out


def talos() -> ci.RobotModel:
    path = example_robot_data_dir() / "talos_data" / "robots" / "talos_reduced.urdf"
    return ci.RobotModel(pin.buildModelFromUrdf(str(path)), name="talos", source=path)


def rnea_loop(model: ci.RobotModel, data: ci.Dataset) -> np.ndarray:
    m, d = model.pin_model, model.pin_model.createData()
    out = np.empty_like(data.q)
    for k in range(data.n_samples):
        out[k] = pin.rnea(m, d, data.q[k], data.dq[k], data.ddq[k])
    return out


def pinocchio_regressor_loop(model: ci.RobotModel, data: ci.Dataset) -> None:
    m, d = model.pin_model, model.pin_model.createData()
    for k in range(data.n_samples):
        pin.computeJointTorqueRegressor(m, d, data.q[k], data.dq[k], data.ddq[k])


def simulated(model: ci.RobotModel, samples: int, seed: int) -> ci.Dataset:
    """Excitation data with friction in the truth (what identify's default columns fit)."""
    spec = RegressorSpec.make(model, FRICTION)
    rng = np.random.default_rng(seed)
    truth = np.concatenate([model.prior_parameters,
                            rng.uniform(0.2, 1.0, spec.n_joint_columns)])
    return ci.simulate.excitation_run(model, truth, samples / 500.0, 500.0, torque_noise=SIGMA,
                                      friction=FRICTION, seed=seed).dataset


def data_pass_rows(model: ci.RobotModel, samples: int, repeat: int) -> list[tuple]:
    """Regressor, compression, residual pass and the whole identify call, as × rnea."""
    data = simulated(model, samples, seed=1)
    other = simulated(model, min(samples, 20_000), seed=2)
    spec = RegressorSpec.make(model, FRICTION)

    def floor():
        return rnea_loop(model, data)

    t_rnea, _ = timed(floor, repeat)
    t_pin, r_pin, _ = paired(lambda: pinocchio_regressor_loop(model, data), floor, repeat)
    t_reg, r_reg, _ = paired(lambda: [None for _ in iter_regressor(model, data, spec)], floor,
                             repeat)
    base = base_parameters_of(model, spec)               # cached per model, as identify does
    t_comp, r_comp, _ = paired(lambda: compress(model, data, spec, base=base), floor, repeat)
    t0 = time.perf_counter()
    ci.identify(model, other)                 # first call: compiles the SDP's structure
    t_first = time.perf_counter() - t0
    t_id, r_id, res = paired(lambda: ci.identify(model, data), floor, repeat)
    t_res, r_res, _ = paired(lambda: residual_statistics(model, res.spec, res.parameters, data),
                             floor, repeat)
    name = f"{model.name} ({model.n_bodies} bodies), {samples} samples"
    return [(name, "pin.rnea loop (the floor)", f"{t_rnea:.3f}", "1.00"),
            ("", "pin.computeJointTorqueRegressor loop", f"{t_pin:.3f}", f"{r_pin:.2f}"),
            ("", "consistid regressor (streamed, + friction)", f"{t_reg:.3f}", f"{r_reg:.2f}"),
            ("", "compression (regressor + per-joint QR, base columns)", f"{t_comp:.3f}",
             f"{r_comp:.2f}"),
            ("", "residual pass (coloured covariance)", f"{t_res:.3f}", f"{r_res:.2f}"),
            ("", "identify(method='sdp'), whole call, compiled", f"{t_id:.3f}", f"{r_id:.2f}"),
            ("", f"  (first call on the model, compiling; {other.n_samples} samples)",
             f"{t_first:.3f}", ""),
            ("", f"  solver: {res.solver.status}, solve {res.solver.solve_time * 1e3:.0f} ms, "
             f"setup {res.solver.compile_time * 1e3:.0f} ms", "", "")]


def small_sdp_rows(repeat: int) -> list[tuple]:
    """A poorly excited 7 000-row SDP against numpy pivoted QR + lstsq on the same rows."""
    model = ci.RobotModel.example("panda")
    small = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(3), amplitude=0.2)
    data = ci.simulate.excitation_run(model, None, 2.0, 500.0, torque_noise=SIGMA, seed=3,
                                      trajectory=small).dataset
    spec = RegressorSpec.make(model, None)
    base = compute_base_parameters(model, spec)
    problem = compress(model, data, spec)
    y, tau = dataset_regressor(model, data, spec), data.tau.ravel()

    def qr_lstsq():
        _, r, piv = scipy.linalg.qr(y, mode="economic", pivoting=True)
        d = np.abs(np.diag(r))
        cols = np.sort(piv[:int(np.sum(d > 1e-8 * d[0]))])
        return np.linalg.lstsq(y[:, cols], tau, rcond=None)[0]

    def fresh():   # nothing cached: the structure canonicalised again
        program.clear_cache()
        return identify_sdp(model, problem, base, spec)

    t_qr, _ = timed(qr_lstsq, repeat * 3)
    identify_sdp(model, problem, base, spec)                       # compile once
    t_cached, res = timed(lambda: identify_sdp(model, problem, base, spec), repeat * 3)
    t_fresh, _ = timed(fresh, repeat)
    rows = y.shape[0]
    return [(f"poorly excited Panda, {rows} rows", "numpy pivoted QR + lstsq", f"{t_qr:.4f}",
             "1.00"),
            ("", "identify_sdp, compiled program cached", f"{t_cached:.4f}",
             f"{t_cached / t_qr:.2f}"),
            ("", "identify_sdp, compiled afresh (cache cleared)", f"{t_fresh:.4f}",
             f"{t_fresh / t_qr:.2f}"),
            ("", f"  Clarabel: {res.solver.status}, solve {res.solver.solve_time * 1e3:.1f} ms, "
             f"{res.solver.iterations} iterations", "", "")]


def diagnose_rows() -> list[tuple]:
    from consistid.simulate import Effects, record

    model = ci.RobotModel.example("panda")
    traj = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(4))
    t0, c0 = time.perf_counter(), time.process_time()
    rec = record(model, traj, Effects(coulomb=1.0, torque_noise=0.05), duration=30.0, rate=500.0)
    t_sim, c_sim = time.perf_counter() - t0, time.process_time() - c0
    data = ci.Dataset.from_recording(rec.t, rec.q, rec.tau)
    t0, c0 = time.perf_counter(), time.process_time()
    diag = ci.diagnose(model, data)
    t_diag, c_diag = time.perf_counter() - t0, time.process_time() - c0
    top = diag.effects[0].name if diag.effects else "none"
    return [("Panda, 30 s at 500 Hz (MuJoCo, Coulomb 1 N·m)", "MuJoCo simulation of the log",
             f"{t_sim:.3f}", "1.00"),
            ("", f"diagnose (top effect: {top}; target ≤ 3 s)",
             f"{t_diag:.3f} (CPU {c_diag:.3f})", f"{Ratio(t_diag / t_sim, c_diag / c_sim):.1f}")]


MOUNTING = textwrap.dedent("""
    import time, numpy as np, consistid as ci
    model = ci.RobotModel.example("panda")
    data = ci.simulate.excitation_run(model, duration=10.0, rate=200.0, torque_noise=0.2,
                                      seed=0).dataset
    ci.estimate_mounting(model, data)
    t0 = time.perf_counter(); ci.estimate_mounting(model, data)
    print(time.perf_counter() - t0)
""")

STREAM = textwrap.dedent("""
    import sys, time, tracemalloc, numpy as np, consistid as ci
    from consistid.identification.base import random_states
    from consistid.identification.regressor import batch_rnea
    model = ci.RobotModel.example("panda")
    total, part = int(sys.argv[1]), 100_000
    def parts():
        rng = np.random.default_rng(0)
        for k in range(total // part):
            q, dq, ddq = random_states(model, part, rng)
            tau = batch_rnea(model, model.pin_model, q, dq, ddq)
            tau += 0.1 * rng.standard_normal(tau.shape)
            yield ci.Dataset(t=np.arange(part) * 2e-3, q=q, dq=dq, ddq=ddq, tau=tau)
    tracemalloc.start()
    t0 = time.perf_counter()
    res = ci.identify(model, parts(), friction=None)
    elapsed = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    print(peak, elapsed, res.solver.status)
""")


def subprocess_rows(large: bool) -> list[tuple]:
    rows = []
    times = {}
    for label, env in (("default threading", {k: v for k, v in os.environ.items()
                                              if not k.endswith("_NUM_THREADS")}),
                       ("one BLAS thread", {**os.environ, "OPENBLAS_NUM_THREADS": "1",
                                            "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})):
        out = subprocess.run([sys.executable, "-c", MOUNTING], env=env, capture_output=True,
                             text=True, timeout=1800)
        times[label] = float(out.stdout.split()[-1]) if out.returncode == 0 else float("nan")
    one = times["one BLAS thread"]
    rows.append(("estimate_mounting, Panda, 2 000 samples", "one BLAS thread", f"{one:.3f}",
                 "1.00"))
    rows.append(("", "default threading", f"{times['default threading']:.3f}",
                 f"{times['default threading'] / one:.2f}"))
    n = 10_000_000 if large else 1_000_000
    out = subprocess.run([sys.executable, "-c", STREAM, str(n)], capture_output=True, text=True,
                         timeout=7200)
    data_bytes = n * 7 * 4 * 8 + n * 8 * 2          # q, dq, ddq, tau; t and segment
    if out.returncode != 0:
        rows.append((f"streamed identify, {n:.0e} samples", "failed",
                     out.stderr.strip().splitlines()[-1][:60], ""))
    else:
        peak, elapsed, status = out.stdout.split()
        rows.append((f"streamed identify, {n:.0e} samples (generator, 1e5 per part)",
                     f"peak traced allocations ({status}, {float(elapsed):.1f} s)",
                     f"{int(peak) / 2**20:.0f} MB",
                     f"{int(peak) / data_bytes:.3f} × data ({data_bytes / 2**30:.2f} GB)"))
    if not large:
        rows.append(("", "10⁷ samples: run with --large", "", ""))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--talos-samples", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--large", action="store_true", help="peak memory at 1e7 samples")
    ap.add_argument("--skip", nargs="*", default=(),
                    choices=("panda", "talos", "small", "diagnose", "subprocess"))
    args = ap.parse_args()
    rows: list[tuple] = []
    if "panda" not in args.skip:
        rows += data_pass_rows(ci.RobotModel.example("panda"), args.samples, args.repeat)
    if "talos" not in args.skip:
        rows += data_pass_rows(talos(), args.talos_samples, max(1, args.repeat - 2))
    if "small" not in args.skip:
        rows += small_sdp_rows(args.repeat)
    if "diagnose" not in args.skip:
        rows += diagnose_rows()
    if "subprocess" not in args.skip:
        rows += subprocess_rows(args.large)
    print(f"issue 17, one BLAS thread (OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}"
          f"), medians of {args.repeat}; ratios within one run")
    print(table(["case", "what", "time [s]", "ratio"], rows))


if __name__ == "__main__":
    sys.exit(main())
