"""Speed of the consistent SDP against least squares and the naive SDP (issue 3).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/sdp_speed.py [--naive-samples N]
[--figaroh-venv DIR]``.

Data: the issue's well-excited Panda set (truth = URDF ±20 %, 30 s at 500 Hz = 15 000 samples,
105 000 torque rows, σ = 0.1 N·m, rigid body only). Regressor build time is excluded everywhere
(it is measured once and subtracted from ``identify``), medians of ``--repeat`` runs:

* ``identify(method="sdp")``: pseudo-inertia LMIs + log-det prior at the default weight,
  including base parameters, compression (QR of [Y | τ] in chunks), the OLS σ pass, the SDP;
* ``numpy pivoted QR + lstsq``: ``scipy.linalg.qr(Y, pivoting=True)`` (LAPACK geqp3) to find the
  base columns, then ``numpy.linalg.lstsq`` on them: unconstrained, inconsistent OLS;
* ``naive SDP``: the same SDP handed to cvxpy with all rows (``‖Yθ − τ‖²/σ²``, raw LMIs, log-det
  prior). Its time grows faster than linearly, so by default it runs on the first
  ``--naive-samples`` samples only (the table says how many);
* FIGAROH 1.0.2 ``physical_fit.build_problem`` + ``solve_direct_effort_fit`` (cvxopt via PICOS),
  only with ``--figaroh-venv DIR``: a throwaway venv with ``pip install figaroh picos cvxopt``
  (FIGAROH is not a consistid dependency); skipped otherwise.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import cvxpy as cp
import numpy as np
import scipy.linalg

import consistid as ci
from consistid.identification import constraints, priors
from consistid.identification.base import compute_base_parameters
from consistid.identification.compression import compress
from consistid.robot.inertia import perturb
from consistid.identification.regressor import RegressorSpec, dataset_regressor, iter_regressor
from consistid.identification.summary import table
from consistid.identification.sdp import default_prior_weight, identify_sdp

SIGMA = 0.1

FIGAROH_SCRIPT = textwrap.dedent("""
    import json, sys, time, numpy as np
    from figaroh.identification import physical_fit as pf
    d = np.load(sys.argv[1], allow_pickle=False)
    names, joints = list(d["names"]), list(d["joints"])
    times = []
    for _ in range(int(sys.argv[2])):
        t0 = time.perf_counter()
        problem = pf.build_problem(d["Y"], d["tau"], names, joints, prior=d["prior"])
        record = pf.solve_direct_effort_fit(problem, solver="cvxopt")
        times.append(time.perf_counter() - t0)
    theta = None if record.theta is None else record.theta.tolist()
    print(json.dumps({"times": times, "status": record.solver_status,
                      "accepted": bool(record.accepted), "theta": theta}))
""")


def median_time(fn, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def naive_sdp(model: ci.RobotModel, y: np.ndarray, tau: np.ndarray) -> tuple[str, np.ndarray]:
    theta = cp.Variable(model.n_inertial)
    cons, terms = [], []
    for i in range(model.n_bodies):
        x, p0 = theta[10 * i:10 * i + 10], model.prior_parameters[10 * i:10 * i + 10]
        cons += constraints.pseudo_inertia_lmi(x)
        terms.append(priors.logdet_divergence(x, p0))
    objective = (cp.sum_squares(y @ theta - tau) / SIGMA ** 2
                 + default_prior_weight() * cp.sum(cp.hstack(terms)))
    problem = cp.Problem(cp.Minimize(objective), cons)
    problem.solve(solver="CLARABEL")
    return problem.status, theta.value


def run_figaroh(venv: Path, model: ci.RobotModel, y: np.ndarray, tau: np.ndarray,
                repeat: int) -> dict | str:
    python = venv / "bin" / "python"
    if not python.is_file():
        return f"skipped: {python} not found"
    names = [f"{key}_{joint}" for joint in model.joint_names
             for key in ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")]
    with tempfile.TemporaryDirectory() as tmp:
        data, script = Path(tmp) / "data.npz", Path(tmp) / "run.py"
        np.savez(data, Y=y, tau=tau, names=np.array(names), joints=np.array(model.joint_names),
                 prior=model.prior_parameters)
        script.write_text(FIGAROH_SCRIPT)
        proc = subprocess.run([str(python), str(script), str(data), str(repeat)],
                              capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        return "failed: " + (proc.stderr.strip().splitlines() or ["?"])[-1]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=500.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--naive-samples", type=int, default=4000,
                        help="samples handed to the naive SDP (0: skip; -1: all)")
    parser.add_argument("--figaroh-venv", type=Path, default=None)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    model = ci.RobotModel.example("panda")
    truth = perturb(model.prior_parameters, 0.2, np.random.default_rng(args.seed))
    data = ci.simulate.excitation_run(model, truth, args.duration, args.rate,
                                      torque_noise=SIGMA, seed=args.seed + 1).dataset
    held = ci.simulate.excitation_run(model, truth, 10.0, args.rate, torque_noise=SIGMA,
                                      seed=args.seed + 2).dataset
    spec = RegressorSpec.make(model, None)
    n_rows = data.n_samples * model.nv

    t_stream, _ = median_time(lambda: [None for _ in iter_regressor(model, data, spec)],
                              args.repeat)
    t_full, y = median_time(lambda: dataset_regressor(model, data, spec), 1)
    tau = data.tau.ravel()

    ci.identify(model, data, method="sdp", friction=None)  # warm-up (imports, first compile)
    t_identify, res = median_time(lambda: ci.identify(model, data, method="sdp", friction=None),
                                  args.repeat)
    base = compute_base_parameters(model, spec)
    t_compress, problem = median_time(lambda: compress(model, data, spec), args.repeat)
    t_sdp, _ = median_time(lambda: identify_sdp(model, problem, base, spec), args.repeat)

    def qr_lstsq():
        _, r, piv = scipy.linalg.qr(y, mode="economic", pivoting=True)
        d = np.abs(np.diag(r))
        cols = np.sort(piv[:int(np.sum(d > 1e-8 * d[0]))])
        return cols, np.linalg.lstsq(y[:, cols], tau, rcond=None)[0]

    y_held = dataset_regressor(model, held, spec)

    def held_rms(theta: np.ndarray) -> float:
        return float(np.sqrt(np.mean((y_held @ theta - held.tau.ravel()) ** 2)) / SIGMA)

    t_qr, (cols, beta) = median_time(qr_lstsq, args.repeat)
    rms_qr = np.sqrt(np.mean((y[:, cols] @ beta - tau) ** 2))

    rows = [("identify(method='sdp') − regressor build", n_rows,
             f"{t_identify - t_stream:.3f}", res.solver.status,
             f"{np.sqrt(np.mean(res.rms(held) ** 2)) / SIGMA:.4f}"),
            ("  of which: compression (incl. build) − build", n_rows,
             f"{t_compress - t_stream:.3f}", "", ""),
            ("  of which: identify_sdp on the compressed problem", n_rows, f"{t_sdp:.3f}",
             f"compile {res.solver.compile_time:.3f} s, solve {res.solver.solve_time:.3f} s", ""),
            ("numpy pivoted QR + lstsq (full regressor)", n_rows, f"{t_qr:.3f}", "inconsistent",
             f"train RMS/σ {rms_qr / SIGMA:.4f}")]
    if args.naive_samples:
        k = data.n_samples if args.naive_samples < 0 else min(args.naive_samples, data.n_samples)
        t_naive, (status, theta) = median_time(
            lambda: naive_sdp(model, y[:k * model.nv], tau[:k * model.nv]), 1)
        rows.append((f"naive SDP, all rows in cvxpy ({k} samples)", k * model.nv,
                     f"{t_naive:.3f}", status, f"{held_rms(theta):.4f}"))
    if args.figaroh_venv is not None:
        fig = run_figaroh(args.figaroh_venv, model, y, tau, args.repeat)
        if isinstance(fig, str):
            rows.append(("FIGAROH physical_fit (direct effort fit)", n_rows, fig, "", ""))
        else:
            rows.append(("FIGAROH 1.0.2 build_problem + solve_direct_effort_fit", n_rows,
                         f"{statistics.median(fig['times']):.3f}",
                         f"{fig['status']}, accepted={fig['accepted']}",
                         "" if fig["theta"] is None else f"{held_rms(np.array(fig['theta'])):.4f}"))
    else:
        rows.append(("FIGAROH physical_fit", n_rows, "skipped (no --figaroh-venv)", "", ""))

    print(f"Panda, {data.n_samples} samples ({args.duration:g} s at {args.rate:g} Hz), "
          f"{model.n_inertial} standard / {base.n_base} base parameters, σ = {SIGMA} N·m; "
          f"regressor build (excluded): streamed {t_stream:.3f} s, full {t_full:.3f} s; "
          f"medians of {args.repeat}")
    print(table(["method", "rows", "time [s]", "status", "held-out RMS/σ"], rows))
    print(f"\nSDP / (QR + lstsq) = {(t_identify - t_stream) / t_qr:.2f};  "
          f"program size (independent of N): {res.details['program_size']}")


if __name__ == "__main__":
    sys.exit(main())
