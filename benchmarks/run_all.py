"""The benchmark suite: accuracy (Monte Carlo), peers on the same data, speed and scale.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/run_all.py [--smoke | --quick] [--jobs 2]
[--dask tcp://scheduler:8786] [--out docs]``. Writes ``<out>/benchmarks.md``,
``<out>/benchmarks/results.json`` and PNG figures beside it.

Sizes: ``--smoke`` (CI, ≲ 60 s), ``--quick`` (≲ 5 min on 2 cores), default the full run (≥ 50
runs per cell, N up to 10⁷). The page states which ran, when and on what machine.

Protocol (in the spirit of BIRDy, Leboutet et al. 2021, doi:10.1109/TRO.2020.3043058):

* **Truth**: the URDF's bodies perturbed by ±20 % (:func:`consistid.robot.inertia.perturb`: mass,
  CoM and inertia about the CoM scaled separately, consistent by construction); the prior is the
  URDF. With friction: Coulomb 0.5–2 N·m and viscous 0.2–1 N·m·s/rad per joint, drawn per run.
* **Scenarios**: ``well`` (an excitation designed once per robot with
  :func:`consistid.design_excitation`, 5 harmonics over 10 s, criterion cond, 2 starts; new truth
  and noise per run; ``--smoke`` uses a random Fourier trajectory instead), ``poor`` (2 s,
  20 % amplitude), ``noisy`` (σ × 10), ``outliers`` (1 % of samples ±20 σ spikes),
  ``coloured`` (AR(1), φ = 0.9, τ = 19 samples), ``friction`` (Coulomb and viscous friction in
  the truth, fitted), ``mujoco`` (the MuJoCo robot, exact states and its
  torques plus white noise). Held out: another random trajectory of the same robot.
* **Methods**: OLS, WLS, Huber/IRLS (benchmark-only: least squares re-weighted by Huber's ψ with
  a MAD scale on the compressed problem, 5 passes), SDP at each consistency level (mass-inertia,
  pseudo-inertia; "triangle" is the pseudo-inertia LMI) with the log-det prior, SDP with the
  Euclidean prior, SDP with constraints and no prior.
* **Metrics**: held-out torque RMS / σ (1 is the floor); base-parameter error against the truth
  (‖β̂ − β‖/‖β‖); coverage: the share of base parameters whose reported 95 % interval holds the
  truth; standard-parameter error (inertial part, relative); bodies not ⪰ 0; time of the whole
  ``identify`` call.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import textwrap
import time
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import scipy.linalg

import consistid as ci
from consistid.identification.base import compute_base_parameters
from consistid.identification.compression import compress, floor_sigma
from consistid.identification.regressor import RegressorSpec, dataset_regressor, iter_regressor
from consistid.robot.inertia import perturb

SIGMA = 0.1
#: numpy QR + lstsq needs the whole (N·nv, p) regressor: only up to this N in the scale table.
QR_MAX_SAMPLES = 200_000
ROBOTS = ("planar2r", "ur5", "panda", "xarm7")
SCENARIOS = ("well", "poor", "noisy", "outliers", "coloured", "friction", "mujoco")
METHODS = ("ols", "wls", "huber", "sdp-mass-inertia", "sdp-pseudo-inertia", "sdp-euclidean",
           "sdp-no-prior")

PLANAR_2R = """<?xml version="1.0"?>
<robot name="planar2r">
  <link name="base"/>
  <link name="link1"><inertial><origin xyz="0.4 0 0"/><mass value="2.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.045" iyz="0" izz="0.05"/></inertial></link>
  <link name="link2"><inertial><origin xyz="0.3 0 0"/><mass value="1.5"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.035"/></inertial></link>
  <joint name="joint1" type="revolute"><parent link="base"/><child link="link1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="5" effort="100"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.8 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="5" effort="100"/></joint>
</robot>
"""


@dataclass(frozen=True)
class Size:
    name: str
    runs: int              # Monte Carlo runs per (robot, scenario) cell
    duration: float        # training seconds (well-excited scenarios)
    rate: float
    robots: tuple[str, ...]
    scenarios: tuple[str, ...]
    methods: tuple[str, ...]
    n_scale: tuple[int, ...]           # samples for the in-memory scale table
    n_stream: tuple[int, ...]          # samples for the streaming (subprocess, peak RSS) table
    design: bool                       # designed excitation for "well"
    naive_samples: int


SIZES = {
    "smoke": Size("smoke", 2, 4.0, 100.0, ("planar2r", "ur5"), ("well", "poor", "mujoco"),
                  ("ols", "wls", "huber", "sdp-pseudo-inertia"), (1000, 3000), (20_000,),
                  False, 300),
    "quick": Size("quick", 4, 8.0, 100.0, ROBOTS, SCENARIOS, METHODS,
                  (1000, 10_000, 100_000), (100_000, 1_000_000), True, 1000),
    "full": Size("full", 50, 10.0, 200.0, ROBOTS, SCENARIOS, METHODS,
                 (1000, 10_000, 100_000, 1_000_000), (100_000, 1_000_000, 10_000_000), True,
                 2000),
}

_MODELS: dict[str, ci.RobotModel] = {}


def robot(name: str) -> ci.RobotModel:
    if name not in _MODELS:
        if name == "planar2r":
            path = Path(os.environ.get("TMPDIR", "/tmp")) / f"consistid_planar2r_{os.getpid()}.urdf"
            path.write_text(PLANAR_2R)
            _MODELS[name] = ci.RobotModel.from_urdf(path, gravity=(0.0, -9.81, 0.0))
        else:
            _MODELS[name] = ci.RobotModel.example(name)
    return _MODELS[name]


# ------------------------------------------------------------------------------ Monte Carlo
def scenario_data(name: str, scenario: str, seed: int, size: Size,
                  designed: dict | None) -> dict:
    """Training and held-out data of one run, the truth, the regressor columns fitted and σ."""
    model = robot(name)
    rng = np.random.default_rng(seed)
    truth = perturb(model.prior_parameters, 0.2, rng)
    friction = ("coulomb", "viscous", "offset") if scenario in ("friction", "mujoco") else None
    spec = RegressorSpec.make(model, friction)
    fc = rng.uniform(0.5, 2.0, model.nv) if scenario == "friction" else np.zeros(model.nv)
    fv = rng.uniform(0.2, 1.0, model.nv) if scenario == "friction" else np.zeros(model.nv)
    theta = np.concatenate([truth, np.zeros(spec.n_joint_columns)])
    if friction:
        names = ci.identification.regressor.parameter_names(model, spec)
        for j, joint in enumerate(model.joint_names):
            theta[names.index(f"{joint}.fc")] = fc[j]
            theta[names.index(f"{joint}.fv")] = fv[j]
    sigma = SIGMA * (10.0 if scenario == "noisy" else 1.0)
    duration = 2.0 if scenario == "poor" else size.duration
    amplitude = 0.2 if scenario == "poor" else 0.8
    traj = ci.FourierTrajectory.random(model, 5, 10.0, rng, amplitude=amplitude)
    if scenario == "well" and designed is not None and name in designed:
        traj = designed[name]
    held_traj = ci.FourierTrajectory.random(model, 5, 10.0, rng)
    if scenario == "mujoco":
        from consistid.simulate import Effects, record

        def run(trajectory, dur):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ci.TrackingWarning)
                rec = record(model, trajectory, Effects(torque_noise=sigma), truth,
                             duration=dur, rate=size.rate, seed=int(rng.integers(2**31)))
            return rec.true_dataset()

        train, held = run(traj, duration), run(held_traj, 5.0)
    else:
        def run(trajectory, dur, noisy=True):
            data = trajectory.sample(size.rate, dur)
            y = dataset_regressor(model, data, spec)
            tau = (y @ theta).reshape(-1, model.nv)
            if scenario == "coloured" and noisy:
                noise = ci.simulate.experiments.ar1_noise(tau.shape, 0.9, sigma, rng)
            else:
                noise = sigma * rng.standard_normal(tau.shape)
            if scenario == "outliers" and noisy:
                hit = rng.random(tau.shape[0]) < 0.01
                noise[hit] += 20 * sigma * rng.choice([-1.0, 1.0], size=(hit.sum(), model.nv))
            return data.with_torque(tau + noise)

        train, held = run(traj, duration), run(held_traj, 5.0, noisy=False)
    return dict(model=model, train=train, held=held, theta=theta, spec=spec, friction=friction,
                sigma=sigma)


def huber_irls(model, data, friction, passes=5, c=1.345):
    """Benchmark-only Huber M-estimator by IRLS on the compressed problem, MAD scale per joint
    (Huber 1964; Holland & Welsch 1977). Its ± is the weighted least squares one at the last
    weights (an approximation; the coverage says how good)."""
    start = time.perf_counter()
    spec = RegressorSpec.make(model, friction)
    base = compute_base_parameters(model, spec)
    cols = base.independent
    problem = compress(model, data, spec)
    weights = None
    for _ in range(passes + 1):
        r, z, _ = problem.stacked(columns=cols)
        beta = scipy.linalg.solve_triangular(r, z)
        theta = np.zeros(problem.n_columns)
        theta[cols] = beta
        res = data.tau - (dataset_regressor(model, data, spec) @ theta).reshape(-1, model.nv)
        mad = 1.4826 * np.median(np.abs(res - np.median(res, axis=0)), axis=0)
        s = floor_sigma(mad, problem)
        u = np.abs(res) / s
        weights = np.minimum(1.0, c / np.maximum(u, 1e-300)) / s ** 2
        problem = compress(model, data, spec, weights=weights)
    r, z, _ = problem.stacked(columns=cols)
    beta = scipy.linalg.solve_triangular(r, z)
    r_inv = scipy.linalg.solve_triangular(r, np.eye(r.shape[0]))
    chi2 = float(np.sum(problem.sum_squares(np.eye(problem.n_columns)[:, cols] @ beta)))
    dof = max(data.n_samples * model.nv - base.n_base, 1)
    cov = r_inv @ r_inv.T * chi2 / dof
    theta = np.zeros(problem.n_columns)
    theta[cols] = beta
    prior = np.concatenate([model.prior_parameters, np.zeros(spec.n_joint_columns)])
    standard = prior + np.linalg.lstsq(base.matrix, beta - base.matrix @ prior, rcond=None)[0]
    return dict(beta=beta, cov=cov, standard=standard, base=base, spec=spec,
                time=time.perf_counter() - start, status="optimal (IRLS)")


def fit(method: str, d: dict) -> dict:
    model, train, friction = d["model"], d["train"], d["friction"]
    if method == "huber":
        return huber_irls(model, train, friction)
    kw: dict = {"friction": friction}
    if method in ("ols", "wls"):
        kw["method"] = method
    else:
        kw["method"] = "sdp"
        level = {"sdp-mass-inertia": "mass-inertia"}.get(method, "pseudo-inertia")
        kw["constraints"] = level
        kw["prior"] = {"sdp-euclidean": "euclidean", "sdp-no-prior": None}.get(method, "logdet")
    t0 = time.perf_counter()
    res = ci.identify(model, train, **kw)
    return dict(beta=res.base_parameters, cov=res.base_covariance, standard=res.parameters,
                base=res.base, spec=res.spec, time=time.perf_counter() - t0,
                status=res.solver.status)


def one_run(name: str, scenario: str, seed: int, size: Size, designed: dict | None,
            methods: tuple[str, ...]) -> list[dict]:
    """Every method on one run's data: a list of metric rows."""
    d = scenario_data(name, scenario, seed, size, designed)
    model, held, theta, sigma = d["model"], d["held"], d["theta"], d["sigma"]
    y_held = dataset_regressor(model, held, d["spec"])
    rows = []
    for method in methods:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = fit(method, d)
        except ci.ConsistidError as exc:
            rows.append(dict(robot=name, scenario=scenario, seed=seed, method=method,
                             error=f"{type(exc).__name__}: {str(exc)[:120]}"))
            continue
        base = out["base"]
        beta_true = base.project(theta)
        std = np.sqrt(np.clip(np.diag(out["cov"]), 0, None))
        inside = np.abs(out["beta"] - beta_true) <= 1.96 * std
        pred = (y_held @ out["standard"]).reshape(-1, model.nv)
        held_rms = float(np.sqrt(np.mean((pred - held.tau) ** 2)) / sigma)
        n_in = model.n_inertial
        report = ci.is_physically_consistent(out["standard"][:n_in], "pseudo-inertia",
                                             model.body_names)
        rows.append(dict(
            robot=name, scenario=scenario, seed=seed, method=method, status=out["status"],
            held_rms_over_sigma=held_rms,
            base_error=float(np.linalg.norm(out["beta"] - beta_true)
                             / np.linalg.norm(beta_true)),
            coverage=float(np.mean(inside)),
            standard_error=float(np.linalg.norm(out["standard"][:n_in] - theta[:n_in])
                                 / np.linalg.norm(theta[:n_in])),
            bodies_not_psd=int(sum(not b.ok for b in report.bodies)),
            time=out["time"], n_samples=d["train"].n_samples))
    return rows


def design(name: str):
    return ci.design_excitation(robot(name), harmonics=5, period=10.0, seed=0, n_starts=2,
                                friction=None).trajectory


def monte_carlo(size: Size, jobs: int, dask: str | None) -> list[dict]:
    import joblib

    designed = {}
    if size.design:  # one design per robot, in parallel like the cells
        found = joblib.Parallel(n_jobs=jobs)(joblib.delayed(design)(n) for n in size.robots)
        designed = dict(zip(size.robots, found))
    tasks = [(r, s, 1000 * k + 17 * i) for i, r in enumerate(size.robots)
             for s in size.scenarios for k in range(size.runs)]
    call = joblib.delayed(one_run)
    if dask:
        from distributed import Client

        with Client(dask), joblib.parallel_config(backend="dask"):
            chunks = joblib.Parallel()(call(r, s, seed, size, designed, size.methods)
                                       for r, s, seed in tasks)
    else:
        chunks = joblib.Parallel(n_jobs=jobs)(call(r, s, seed, size, designed, size.methods)
                                              for r, s, seed in tasks)
    return [row for chunk in chunks for row in chunk]


def summarise(rows: list[dict]) -> list[dict]:
    cells: dict[tuple, list[dict]] = {}
    for row in rows:
        cells.setdefault((row["robot"], row["scenario"], row["method"]), []).append(row)
    out = []
    for (r, s, m), group in cells.items():
        ok = [g for g in group if "error" not in g]
        cell = dict(robot=r, scenario=s, method=m, runs=len(group), failed=len(group) - len(ok))
        for key in ("held_rms_over_sigma", "base_error", "coverage", "standard_error",
                    "bodies_not_psd", "time"):
            v = np.array([g[key] for g in ok], dtype=float)
            cell[key] = (float(np.median(v)) if v.size else float("nan"))
            cell[key + "_q"] = ((float(np.percentile(v, 10)), float(np.percentile(v, 90)))
                                if v.size else (float("nan"),) * 2)
        cell["coverage_mean"] = (float(np.mean([g["coverage"] for g in ok])) if ok
                                 else float("nan"))
        cell["coverage_se"] = (float(np.std([g["coverage"] for g in ok], ddof=1)
                                     / np.sqrt(len(ok))) if len(ok) > 1 else float("nan"))
        out.append(cell)
    return out


def coverage_table(cells: list[dict]) -> str:
    """The coverage of the 95 % intervals per cell, mean over runs ± its standard error
    (the runs' spread / √runs), as text."""
    lines = [f"{'robot':9s}{'scenario':10s}{'method':20s}{'runs':>5s}  coverage ± s.e."]
    for c in sorted(cells, key=lambda c: (ROBOTS.index(c["robot"]),
                                          SCENARIOS.index(c["scenario"]),
                                          METHODS.index(c["method"]))):
        lines.append(f"{c['robot']:9s}{c['scenario']:10s}{c['method']:20s}{c['runs']:5d}  "
                     f"{c['coverage_mean']:.3f} ± {c['coverage_se']:.3f}")
    return "\n".join(lines)


# ------------------------------------------------------------------------------ peers
FIGAROH_NOTE = "FIGAROH 1.0.2 physical_fit.build_problem + solve_direct_effort_fit (cvxopt)"


def peers(size: Size) -> list[dict]:
    """Panda, one well-excited run: consistid against numpy QR + lstsq, the naive cvxpy SDP
    with all rows, and FIGAROH, on the same data."""
    import cvxpy as cp

    from consistid.identification import constraints, priors
    from consistid.identification.sdp import default_prior_weight

    d = scenario_data("panda", "well", 7, size, None)
    model, train, held, theta = d["model"], d["train"], d["held"], d["theta"]
    spec = RegressorSpec.make(model, None)
    y = dataset_regressor(model, train, spec)
    tau = train.tau.ravel()
    y_held = dataset_regressor(model, held, spec)
    base = compute_base_parameters(model, spec)
    beta_true = base.project(theta)

    def row(name, seconds, status, standard=None, beta=None, note="", rows=None):
        held_rms = (float(np.sqrt(np.mean((y_held @ standard - held.tau.ravel()) ** 2)) / SIGMA)
                    if standard is not None else float("nan"))
        if beta is None and standard is not None:
            beta = base.project(standard)
        err = (float(np.linalg.norm(beta - beta_true) / np.linalg.norm(beta_true))
               if beta is not None else float("nan"))
        bad = (sum(not b.ok for b in ci.is_physically_consistent(
            standard[:model.n_inertial], "pseudo-inertia", model.body_names).bodies)
            if standard is not None else -1)
        return dict(method=name, time=seconds, status=status, held_rms_over_sigma=held_rms,
                    base_error=err, bodies_not_psd=bad, rows=int(rows or tau.size), note=note)

    out = []
    for method in ("ols", "sdp"):
        ci.identify(model, train, method=method, friction=None)   # warm-up: imports, caches
        t0 = time.perf_counter()
        res = ci.identify(model, train, method=method, friction=None)
        out.append(row(f"consistid identify(method={method!r})", time.perf_counter() - t0,
                       res.solver.status, res.parameters, res.base_parameters))
    t0 = time.perf_counter()
    _, r, piv = scipy.linalg.qr(y, mode="economic", pivoting=True)
    dg = np.abs(np.diag(r))
    cols = np.sort(piv[:int(np.sum(dg > 1e-8 * dg[0]))])
    sol = np.linalg.lstsq(y[:, cols], tau, rcond=None)[0]
    t_qr = time.perf_counter() - t0
    full = np.zeros(y.shape[1])
    full[cols] = sol
    out.append(row("numpy pivoted QR + lstsq (all rows)", t_qr, "inconsistent by design", full,
                   note="regressor excluded from the time"))
    k = min(size.naive_samples, train.n_samples)
    th = cp.Variable(model.n_inertial)
    cons, terms = [], []
    for i in range(model.n_bodies):
        x = th[10 * i:10 * i + 10]
        cons += constraints.pseudo_inertia_lmi(x)
        terms.append(priors.logdet_divergence(x, model.prior_parameters[10 * i:10 * i + 10]))
    obj = (cp.sum_squares(y[:k * model.nv] @ th - tau[:k * model.nv]) / SIGMA ** 2
           + default_prior_weight() * cp.sum(cp.hstack(terms)))
    prob = cp.Problem(cp.Minimize(obj), cons)
    t0 = time.perf_counter()
    try:
        prob.solve(solver="CLARABEL")
        out.append(row(f"naive cvxpy SDP, all rows ({k} samples)", time.perf_counter() - t0,
                       prob.status, th.value, note=f"first {k} samples only",
                       rows=k * model.nv))
    except cp.error.SolverError as exc:
        out.append(row(f"naive cvxpy SDP, all rows ({k} samples)", time.perf_counter() - t0,
                       f"failed: {exc}", rows=k * model.nv))
    out.append(figaroh_row(model, y, tau, row))
    return out


def figaroh_row(model, y, tau, row) -> dict:
    try:
        from figaroh.identification import physical_fit as pf
    except Exception as exc:  # noqa: BLE001 - any import failure is the row's reason
        return dict(method="FIGAROH", time=float("nan"), status=f"not run: cannot import "
                    f"figaroh ({type(exc).__name__}: {str(exc)[:80]}); pip install figaroh",
                    held_rms_over_sigma=float("nan"), base_error=float("nan"),
                    bodies_not_psd=-1, rows=int(tau.size), note="")
    names = [f"{key}_{joint}" for joint in model.joint_names
             for key in ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")]
    t0 = time.perf_counter()
    try:
        problem = pf.build_problem(y, tau, names, list(model.joint_names),
                                   prior=model.prior_parameters)
        record = pf.solve_direct_effort_fit(problem, solver="cvxopt")
    except Exception as exc:  # noqa: BLE001 - the peer's failure is the row
        return dict(method=FIGAROH_NOTE, time=time.perf_counter() - t0,
                    status=f"failed: {type(exc).__name__}: {str(exc)[:100]}",
                    held_rms_over_sigma=float("nan"), base_error=float("nan"),
                    bodies_not_psd=-1, rows=int(tau.size), note="")
    seconds = time.perf_counter() - t0
    theta = None if record.theta is None else np.asarray(record.theta, dtype=float)
    return row(FIGAROH_NOTE, seconds, f"{record.solver_status}, accepted={record.accepted}",
               theta, note="all rows, its own physical-consistency constraints")


# ------------------------------------------------------------------------------ scale
def rnea_samples(model: ci.RobotModel, n: int, seed: int):
    """``(Dataset, t_rnea)``: n samples of a random Fourier motion, torques from pin.rnea with
    the prior + white noise, and the time rnea took (the floor)."""
    import pinocchio as pin

    traj = ci.FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed))
    rate = 500.0
    data = traj.sample(rate, (n - 0.5) / rate)
    m, pdata = model.pin_model, model.pin_model.createData()
    tau = np.empty_like(data.q)
    t0 = time.perf_counter()
    for k in range(data.n_samples):
        tau[k] = pin.rnea(m, pdata, data.q[k], data.dq[k], data.ddq[k])
    t_rnea = time.perf_counter() - t0
    tau += SIGMA * np.random.default_rng(seed + 1).standard_normal(tau.shape)
    return data.with_torque(tau), t_rnea


def scale_vs_n(size: Size) -> list[dict]:
    model = robot("panda")
    warm, _ = rnea_samples(model, 500, 2)
    for method in ("ols", "sdp"):   # imports and first compilation are not part of the figures
        ci.identify(model, warm, method=method, friction=None, covariance="iid")
    out = []
    for n in size.n_scale:
        data, t_rnea = rnea_samples(model, n, 3)
        row = dict(n=data.n_samples, rnea=t_rnea)
        spec = RegressorSpec.make(model, None)
        t0 = time.perf_counter()
        for _ in iter_regressor(model, data, spec):   # chunked: no N-row matrix
            pass
        row["regressor"] = time.perf_counter() - t0
        for method in ("ols", "sdp"):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ci.identify(model, data, method=method, friction=None, covariance="iid")
            row[method] = time.perf_counter() - t0
        row["qr_lstsq"] = float("nan")
        if n <= QR_MAX_SAMPLES:  # beyond, the N·nv × p matrix and its copies need GBs
            t0 = time.perf_counter()
            y = dataset_regressor(model, data, spec)
            _, r, piv = scipy.linalg.qr(y, mode="economic", pivoting=True)
            dg = np.abs(np.diag(r))
            cols = np.sort(piv[:int(np.sum(dg > 1e-8 * dg[0]))])
            np.linalg.lstsq(y[:, cols], data.tau.ravel(), rcond=None)
            row["qr_lstsq"] = time.perf_counter() - t0
            del y
        out.append(row)
    return out


def scale_vs_dof() -> list[dict]:
    from consistid.robot.model import example_robot_data_dir

    models = [(n, robot(n)) for n in ("planar2r", "ur5", "panda")]
    talos = example_robot_data_dir() / "talos_data/robots/talos_reduced.urdf"
    if talos.is_file():
        import re

        # The grippers' joints are locked and their <mimic> tags (some on fixed joints, which
        # consistid refuses) dropped from a copy: the rest is a 30-odd-body fixed-base tree.
        text = re.sub(r"<mimic[^>]*/>", "", talos.read_text())
        moving = re.findall(r'<joint name="([^"]+)"[^>]*type="(?:revolute|continuous|prismatic)"',
                            text)
        copy = Path(os.environ.get("TMPDIR", "/tmp")) / f"consistid_talos_{os.getpid()}.urdf"
        copy.write_text(text.replace('filename="package://', 'filename="'
                                     + str(talos.parents[2]) + "/"))
        try:
            models.append(("talos_reduced (fixed base, grippers locked)",
                           ci.RobotModel.from_urdf(copy, locked_joints=[
                               j for j in moving if j.startswith("gripper_")])))
        except ci.ConsistidError as exc:
            print(f"talos_reduced not loaded: {exc}", file=sys.stderr)
    out = []
    for name, model in models:
        data, t_rnea = rnea_samples(model, 5000, 4)
        row = dict(robot=name, nv=model.nv, bodies=model.n_bodies, n=data.n_samples, rnea=t_rnea)
        for method in ("ols", "sdp"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    ci.identify(model, data.select(slice(0, 1000)), method=method,
                                friction=None, covariance="iid")   # warm-up
                    t0 = time.perf_counter()
                    ci.identify(model, data, method=method, friction=None, covariance="iid")
                    row[method] = time.perf_counter() - t0
                except ci.ConsistidError as exc:
                    row[method] = float("nan")
                    row[f"{method}_error"] = f"{type(exc).__name__}: {str(exc)[:80]}"
        out.append(row)
    return out


STREAM_CHILD = textwrap.dedent("""
    import json, resource, sys, time
    import numpy as np, pinocchio as pin
    import consistid as ci
    n, chunk = int(sys.argv[1]), int(sys.argv[2])
    model = ci.RobotModel.example("panda")
    traj = ci.FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(0))
    m, d = model.pin_model, model.pin_model.createData()
    rng = np.random.default_rng(1)
    def chunks():
        for start in range(0, n, chunk):
            t = (start + np.arange(min(chunk, n - start))) / 500.0
            q, dq, ddq = traj.evaluate(t)
            tau = np.array([pin.rnea(m, d, q[k], dq[k], ddq[k]) for k in range(t.size)])
            tau += 0.1 * rng.standard_normal(tau.shape)
            yield ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau)
    t0 = time.perf_counter()
    res = ci.identify(model, chunks(), method=sys.argv[3], friction=None)
    seconds = time.perf_counter() - t0
    # VmHWM: this process's own peak (ru_maxrss would carry the forking parent's over exec)
    hwm = [line for line in open("/proc/self/status") if line.startswith("VmHWM")]
    peak = (int(hwm[0].split()[1]) if hwm
            else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    print(json.dumps({"n": res.n_samples, "seconds": seconds, "status": res.solver.status,
                      "peak_rss_mb": peak / 1024,
                      "covariance": res.details["covariance"],
                      "data_mb": n * 29 * 8 / 1e6}))
""")


def streaming(size: Size) -> list[dict]:
    """10³…10⁷ Panda samples through identify(generator of 50 000-sample chunks), each in a
    fresh subprocess: its peak RSS (ru_maxrss) and time, data made on the fly (pin.rnea)."""
    out = []
    for n in size.n_stream:
        proc = subprocess.run([sys.executable, "-c", STREAM_CHILD, str(n), "50000", "sdp"],
                              capture_output=True, text=True, timeout=3600,
                              env={**os.environ, "OPENBLAS_NUM_THREADS": "1",
                                   "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
        if proc.returncode:
            out.append(dict(n=n, error=(proc.stderr.strip().splitlines() or ["?"])[-1]))
        else:
            out.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return out


def exponent(ns, ts) -> float:
    ns, ts = np.asarray(ns, float), np.asarray(ts, float)
    ok = np.isfinite(ts) & (ts > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(ns[ok]), np.log(ts[ok]), 1)[0])


# ------------------------------------------------------------------------------ output
def figures(out_dir: Path, cells: list[dict], scale: list[dict], stream: list[dict]) -> list[str]:
    from matplotlib.figure import Figure

    names = []
    fig = Figure(figsize=(10, 4.5))
    axes = fig.subplots(1, 2)
    methods = sorted({c["method"] for c in cells}, key=lambda m: METHODS.index(m))
    scenarios = [s for s in SCENARIOS if any(c["scenario"] == s for c in cells)]
    for ax, key, label in ((axes[0], "held_rms_over_sigma", "held-out RMS / σ (median)"),
                           (axes[1], "coverage_mean", "coverage of 95 % intervals (mean)")):
        width = 0.8 / max(len(methods), 1)
        for k, m in enumerate(methods):
            vals = [np.nanmedian([c[key] for c in cells if c["method"] == m
                                  and c["scenario"] == s] or [np.nan]) for s in scenarios]
            ax.bar(np.arange(len(scenarios)) + k * width, vals, width, label=m)
        ax.set_xticks(np.arange(len(scenarios)) + 0.4 - width / 2, scenarios, rotation=30)
        ax.set_ylabel(label)
        if key == "held_rms_over_sigma":
            ax.set_yscale("log")
        else:
            ax.axhline(0.95, color="k", lw=0.8)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "accuracy.png", dpi=110)
    names.append("accuracy.png")

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    if scale:
        ns = [r["n"] for r in scale]
        for key in ("rnea", "regressor", "ols", "sdp", "qr_lstsq"):
            ax.loglog(ns, [r[key] for r in scale], "o-", label=key)
    good = [r for r in stream if "seconds" in r]
    if good:
        ax.loglog([r["n"] for r in good], [r["seconds"] for r in good], "s--",
                  label="sdp, streamed")
    ax.set_xlabel("samples (Panda)")
    ax.set_ylabel("seconds")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "scale.png", dpi=110)
    names.append("scale.png")
    return names


def fmt(v, spec=".3g"):
    return "–" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def markdown(meta: dict, cells: list[dict], peer_rows: list[dict], scale: list[dict],
             dof: list[dict], stream: list[dict], figs: list[str]) -> str:
    size = meta["size"]
    lines = [
        "# Benchmarks", "",
        f"Written by `benchmarks/run_all.py{'' if size == 'full' else ' --' + size}"
        f"{meta.get('overrides', '')}` on {meta['date']} in "
        f"{meta['seconds'] / 60:.1f} min; machine: {meta['machine']}; one BLAS thread; "
        f"{meta['jobs']} joblib worker(s). Sizes that ran: {meta['sizes']}.", "",
        *([f"Not the full run: `python benchmarks/run_all.py` (no size flag) does "
           f"{SIZES['full'].runs} runs per cell with {SIZES['full'].duration:g} s at "
           f"{SIZES['full'].rate:g} Hz, N up to {max(SIZES['full'].n_scale):.0e} in memory and "
           f"{max(SIZES['full'].n_stream):.0e} streamed.", ""] if size != "full" else []),
        "Protocol (module docstring of `benchmarks/run_all.py`): truth = URDF ±20 % "
        "(consistent by construction), prior = URDF, σ = 0.1 N·m white unless the scenario "
        "says otherwise; cells are medians over the runs, [10th, 90th percentile] in brackets. "
        "Coverage is the share of base parameters whose reported 95 % interval holds the truth "
        "(mean over runs ± its standard error, the runs' spread / √runs; 0.95 is honest: with "
        "few base parameters, e.g. 6 for the 2R arm, 50 runs leave ± 0.01).", "",
        "## Accuracy (Monte Carlo)", ""]
    header = ["robot", "scenario", "method", "runs", "held-out RMS/σ", "base error",
              "coverage 95 %", "std. param error", "bodies not ⪰ 0", "time [s]"]
    rows = []
    for c in sorted(cells, key=lambda c: (ROBOTS.index(c["robot"]),
                                          SCENARIOS.index(c["scenario"]),
                                          METHODS.index(c["method"]))):
        q = c["held_rms_over_sigma_q"]
        rows.append([c["robot"], c["scenario"], c["method"],
                     f"{c['runs']}" + (f" ({c['failed']} failed)" if c["failed"] else ""),
                     f"{fmt(c['held_rms_over_sigma'])} [{fmt(q[0])}, {fmt(q[1])}]",
                     fmt(c["base_error"]),
                     fmt(c["coverage_mean"], ".3f") + (f" ± {c['coverage_se']:.3f}"
                                                       if "coverage_se" in c else ""),
                     fmt(c["standard_error"]), fmt(c["bodies_not_psd"], ".0f"),
                     fmt(c["time"])])
    lines += ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    white = [c for c in cells if c["scenario"] == "well" and c["method"] in ("ols", "wls")]
    if white:
        cov = [c["coverage_mean"] for c in white]
        lines += ["", f"**Coverage in the well-excited white-noise cells (OLS, WLS)**: "
                  f"{min(cov):.3f} … {max(cov):.3f} (target 0.90–0.98)."]
    lines += ["", "Reading the table:", "",
              "* The SDP's ± is that of the unconstrained weighted fit at its answer (the "
              "`IdentificationResult` docstring): the prior and the constraints pull the estimate "
              "towards the truth, so its coverage is above 0.95 wherever they are active; it is "
              "an honest bound there, not a calibrated interval.",
              "* `sdp-mass-inertia` and `sdp-pseudo-inertia` agree with the log-det prior, whose "
              "domain already keeps every pseudo-inertia ≻ 0 (the `identify_sdp` docstring); "
              "without a prior (`sdp-no-prior`) the constraints alone decide the directions the "
              "data leave free, hence its larger standard-parameter error.",
              "* Huber/IRLS is benchmark-only (the library's robust fit is "
              "`identify(method='sdp', loss='huber')`); its ± counts rows as independent, so it "
              "is too narrow on coloured noise. OLS/WLS use the default coloured covariance.",
              "* `poor`: 2 s of small motion; OLS/WLS have no prior to decide what the data do not "
              "see, hence held-out errors of tens of σ and unrealizable bodies."]
    lines += ["", "## Peers on the same data (Panda, one well-excited run)", ""]
    header = ["method", "rows", "time [s]", "status", "held-out RMS/σ", "base error",
              "bodies not ⪰ 0", "note"]
    lines += ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for r in peer_rows:
        lines.append("| " + " | ".join([r["method"], str(r["rows"]), fmt(r["time"]),
                                        r["status"], fmt(r["held_rms_over_sigma"]),
                                        fmt(r["base_error"]),
                                        fmt(float(r["bodies_not_psd"]), ".0f")
                                        if r["bodies_not_psd"] >= 0 else "–",
                                        r.get("note", "")]) + " |")
    lines += ["", "## Speed and scale", "",
              "Panda, in memory, rigid body only, `covariance='iid'`; the floor is `pin.rnea` "
              "on the same samples.", ""]
    header = ["N", "rnea [s]", "regressor [s]", "identify ols [s]", "identify sdp [s]",
              "numpy QR + lstsq [s]", "sdp / rnea"]
    lines += ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for r in scale:
        lines.append("| " + " | ".join([str(r["n"]), fmt(r["rnea"]), fmt(r["regressor"]),
                                        fmt(r["ols"]), fmt(r["sdp"]), fmt(r["qr_lstsq"]),
                                        fmt(r["sdp"] / r["rnea"])]) + " |")
    if len(scale) > 1:
        ns = [r["n"] for r in scale]
        lines += ["", "Growth exponents (slope of log time against log N): " + ", ".join(
            f"{k} {exponent(ns, [r[k] for r in scale]):.2f}"
            for k in ("rnea", "regressor", "ols", "sdp", "qr_lstsq")) + "."]
    lines += ["", "Against the number of bodies (5 000 samples):", ""]
    header = ["robot", "joints", "bodies", "rnea [s]", "identify ols [s]", "identify sdp [s]",
              "sdp / rnea"]
    lines += ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for r in dof:
        lines.append("| " + " | ".join([r["robot"], str(r["nv"]), str(r["bodies"]),
                                        fmt(r["rnea"]), fmt(r["ols"]), fmt(r["sdp"]),
                                        fmt(r["sdp"] / r["rnea"])]) + " |")
    if len(dof) > 1:
        lines += ["", f"Growth exponent of identify(sdp) against bodies: "
                  f"{exponent([r['bodies'] for r in dof], [r['sdp'] for r in dof]):.2f}."]
    lines += ["", "Streaming: `identify(model, generator of 50 000-sample Datasets, "
              "method='sdp')`, each N in a fresh process; data made on the fly with `pin.rnea` "
              "(the time includes making them: Fourier evaluation and a Python loop of rnea); "
              "peak RSS of the whole process (`VmHWM`: Python, Pinocchio, cvxpy and the chunk "
              "being made included).",
              ""]
    header = ["N", "time [s]", "µs / sample", "peak RSS [MB]", "data size if stacked [MB]",
              "status"]
    lines += ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for r in stream:
        if "error" in r:
            lines.append(f"| {r['n']} | failed: {r['error']} | | | | |")
            continue
        lines.append("| " + " | ".join([str(r["n"]), fmt(r["seconds"]),
                                        fmt(1e6 * r["seconds"] / r["n"]),
                                        fmt(r["peak_rss_mb"], ".0f"), fmt(r["data_mb"], ".0f"),
                                        r["status"]]) + " |")
    good = [r for r in stream if "seconds" in r]
    if len(good) > 1:
        lines += ["", f"Growth exponent of the streamed time: "
                  f"{exponent([r['n'] for r in good], [r['seconds'] for r in good]):.2f}."]
    lines += [""] + [f"![{f}](benchmarks/{f})" for f in figs] + [""]
    return "\n".join(lines)


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--smoke", action="store_true", help="CI size (≲ 60 s)")
    group.add_argument("--quick", action="store_true", help="≲ 5 min on 2 cores")
    parser.add_argument("--jobs", type=int, default=2, help="joblib workers (Monte Carlo)")
    parser.add_argument("--dask", default=None, help="scheduler address: Monte Carlo cells go "
                        "to that cluster through joblib's Dask backend")
    parser.add_argument("--runs", type=int, default=None, help="override runs per cell")
    parser.add_argument("--robots", nargs="+", choices=ROBOTS, default=None,
                        help="override the Monte Carlo robots")
    parser.add_argument("--scenarios", nargs="+", choices=SCENARIOS, default=None,
                        help="override the Monte Carlo scenarios")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=None,
                        help="override the Monte Carlo methods")
    parser.add_argument("--monte-carlo-only", action="store_true",
                        help="run the Monte Carlo only and print its coverage table; "
                        "writes nothing")
    parser.add_argument("--stream-sizes", type=int, nargs="+", default=None,
                        help="override the streamed sample counts (e.g. 100000 10000000)")
    parser.add_argument("--reuse-streaming", type=Path, default=None,
                        help="results.json of an earlier run: take its streaming rows (and say "
                        "so) instead of measuring them again")
    parser.add_argument("--keep-runs", action="store_true",
                        help="also write every run's metrics to results.json (MBs)")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="rebuild the page and figures from a results.json, measuring nothing")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs")
    args = parser.parse_args(argv)
    name = "smoke" if args.smoke else "quick" if args.quick else "full"
    size = SIZES[name]
    if args.runs:
        size = Size(**{**size.__dict__, "runs": args.runs})
    if args.stream_sizes:
        size = Size(**{**size.__dict__, "n_stream": tuple(args.stream_sizes)})
    for key in ("robots", "scenarios", "methods"):
        if getattr(args, key):
            size = Size(**{**size.__dict__, key: tuple(getattr(args, key))})
    if args.monte_carlo_only:
        print(coverage_table(summarise(monte_carlo(size, args.jobs, args.dask))))
        return 0
    overridden = [f"--{k} {v}" for k, v in (
        ("runs", args.runs),
        ("stream-sizes", " ".join(map(str, args.stream_sizes or ()))),
        *((k, " ".join(getattr(args, k) or ())) for k in ("robots", "scenarios", "methods")))
        if v]
    start = time.perf_counter()
    out_dir = args.out / "benchmarks"
    out_dir.mkdir(parents=True, exist_ok=True)

    def step(label, fn, *a):
        t0 = time.perf_counter()
        value = fn(*a)
        print(f"[{time.perf_counter() - start:7.1f} s] {label}: {time.perf_counter() - t0:.1f} s",
              flush=True)
        return value

    if args.from_json:
        saved = json.loads(args.from_json.read_text())
        figs = figures(out_dir, saved["cells"], saved["scale_n"], saved["streaming"])
        text = markdown(saved["meta"], saved["cells"], saved["peers"], saved["scale_n"],
                        saved["scale_dof"], saved["streaming"], figs)
        (args.out / "benchmarks.md").write_text(text)
        if not args.keep_runs:
            saved.pop("runs", None)
        (out_dir / "results.json").write_text(json.dumps(saved, default=float))
        print(text)
        return 0
    rows = step("Monte Carlo", monte_carlo, size, args.jobs, args.dask)
    cells = summarise(rows)
    peer_rows = step("peers", peers, size)
    scale = step("scale vs N", scale_vs_n, size)
    dof = step("scale vs bodies", scale_vs_dof) if name != "smoke" else []
    if args.reuse_streaming:
        earlier = json.loads(args.reuse_streaming.read_text())
        stream = earlier["streaming"]
        reused = (f"; streaming rows reused from the run of {earlier['meta']['date']} "
                  f"(`{earlier['meta']['size']}{earlier['meta'].get('overrides', '')}`)")
    else:
        stream = step("streaming", streaming, size)
        reused = ""
    figs = figures(out_dir, cells, scale, stream)
    meta = dict(size=name, overrides="".join(" " + o for o in overridden),
                date=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                machine=machine(), jobs=args.jobs if not args.dask else f"dask {args.dask}",
                seconds=time.perf_counter() - start,
                sizes=(f"{size.runs} runs per cell, {len(size.robots)} robots "
                       f"({', '.join(size.robots)}), scenarios {', '.join(size.scenarios)}, "
                       f"training {size.duration:g} s at {size.rate:g} Hz "
                       f"({'designed' if size.design else 'random Fourier'} excitation for "
                       f"'well'), N = {list(size.n_scale)} in memory, "
                       f"{[r['n'] for r in stream]} streamed{reused}"))
    (out_dir / "results.json").write_text(json.dumps(
        dict(meta=meta, cells=cells, peers=peer_rows, scale_n=scale, scale_dof=dof,
             streaming=stream, **({"runs": rows} if args.keep_runs else {})), default=float))
    text = markdown(meta, cells, peer_rows, scale, dof, stream, figs)
    (args.out / "benchmarks.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
