"""The signal chain's automatic cut-off on jittered, noisy logs with a known motion band, and
what the cut-off factor costs in identification.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/cutoff.py [--seeds 2] [--kuka FOLDER]
[--factors] [--friction] [--identify] [--coverage RUNS]``.

Each case is a 30 s log of a 5-harmonic Fourier excitation (band = harmonics / period, period
4 or 10 s) on an arm, sampled every 1 ms and stamped by a logger that writes in bursts (stamp =
arrival after a 0–4 ms delay, at least 0.5 ms after the one before: steps 0.5 to ~5 ms), its
last joint moving 2 % of its range, with position noise (2e-4 rad, white or AR(1) φ = 0.95)
and 17-bit counts (:func:`consistid.simulate.jittered_log`). Printed per case: the estimated
bandwidth over the band, the chosen cut-off (the identification's, where τ and Y are
low-passed alike) and the derivative cut-off over the band, and the largest |q̈| over the
trajectory's own (the issue's symptom: 1 970 rad/s²). ``--seeds 4`` gives 32 cases.

``--kuka FOLDER``: the same on the real KUKA LWR4+ logs (``measurements_*.npz``: 200 Hz,
steps 3.2–6.8 ms, positions already low-pass filtered upstream); then OLS and the SDP on the
positions and torques through the chain (logged velocities set aside; measurements_2 + 3, first
2 s dropped), parallel filtering on and off: held-out relative error on measurements_1 through
the same chain, and the identification's time.

``--identify``: the base-parameter error of ``identify`` (OLS) on the datasets of the default
chain, parallel filtering on (τ and Y at the identification cut-off) and off (the samples at the
derivative cut-off, 10 × the band: before), on the MuJoCo arms of ``--factors`` (no friction;
inertial base parameters ‖β̂ − β‖/‖β‖), with the share of base parameters whose 95 % interval
holds the truth, the held-out RMS on true states and torques, and the identification's time.

``--coverage RUNS``: coverage of the 95 % intervals on white-noise torques (``τ = Y(q)θ`` of the
true trajectory + σ = 0.1 N·m, positions with 1e-5 rad noise, 30 s at 500 Hz, inertias ±20 %)
through the default chain, ``RUNS`` seeds per arm (Panda, UR5), OLS and the SDP, parallel
filtering on and off.

``--factors``: what the cut-off factor costs. MuJoCo arms (inertias the URDF's ±20 %,
σq = 1e-4 rad, σ_τ = 0.1 N·m; 30 s at 1 kHz stamped in bursts; a 10 s held-out run judged on
its true states and torques) identified by OLS at cut-off = 2, 3, 4, 6, 10 × the band
(0.5 Hz), the same 3 s trimmed at both ends for every factor:

* ``same``: one low-pass on ``q`` and ``τ`` at the cut-off (the chain's, ``cutoff=``);
* ``τ 10×``: ``q`` at the cut-off, ``τ`` and ``sign(q̇)`` at 10 × the band (two runs of the
  chain);
* ``parallel``: ``q`` at 10 × the band, then the columns of ``Y`` and ``τ`` through the same
  low-pass at the cut-off (Gautier 1997), computed here.

``--friction``: the same with Coulomb 0.3 N·m and viscous 0.2 N·m·s/rad on every joint (MuJoCo
``frictionloss`` and ``damping``), regressor with both; printed as well: the largest relative
error of the identified Coulomb coefficients.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.data.chain import PreprocessOptions, run_chain
from consistid.excitation import FourierTrajectory
from consistid.simulate import jittered_log

ARMS = ("panda", "ur5", "xarm7", "kinova")
FACTORS = (2.0, 3.0, 4.0, 6.0, 10.0)


def case(arm: str, seed: int, noise: str) -> tuple[str, float, float, float, float]:
    rng = np.random.default_rng(seed)
    model = ci.RobotModel.example(arm)
    period = (4.0, 10.0)[seed % 2]
    traj = FourierTrajectory.random(model, 5, period, seed=seed)
    t, stamps, q = jittered_log(traj, rng, "ar1" if noise == "AR(1)" else "white")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = run_chain(stamps, q, np.zeros_like(q))
    band = 5 / period
    truth = traj.evaluate(t)[2]
    truth[:, -1] = 0.02 * truth[:, -1]
    err = float(np.max(np.abs(out.ddq)) / np.max(np.abs(truth)))
    steps = np.diff(stamps) * 1e3
    return (f"{steps.min():.2f}–{steps.max():.2f}", band, out.bandwidth / band,
            out.cutoff / band, out.derivative_cutoff / band, err)


def kuka(folder: Path) -> None:
    print("\nreal KUKA LWR4+ logs (positions filtered upstream; no known band)")
    print(f"{'file':<20} {'steps [ms]':>12} {'bandwidth [Hz]':>15} {'cut-off [Hz]':>13} "
          f"{'derivative [Hz]':>16} {'max |ddq| [rad/s²]':>19}")
    data = {}
    for path in sorted(folder.glob("measurements_*.npz")):
        d = np.load(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = run_chain(d["times"], d["positions"], d["torques"])
        steps = np.diff(d["times"]) * 1e3
        print(f"{path.name:<20} {steps.min():>5.2f}–{steps.max():<6.2f} {out.bandwidth:>15.3g} "
              f"{out.cutoff:>13.3g} {out.derivative_cutoff:>16.3g} "
              f"{np.abs(out.ddq).max():>19.3g}")
        ds = ci.Dataset.from_chain(out)
        data[path.stem[-1]] = ds.select(ds.t >= ds.t[0] + 2.0)
    if not all(k in data for k in "123"):
        return
    model = ci.RobotModel.from_urdf(folder / "kuka_lwr4.urdf")
    train = ci.Dataset.concatenate([data["2"], data["3"]])
    held = data["1"]
    friction = ("coulomb", "viscous", "offset")
    print("identified on measurements_2 + 3 through the chain, held out measurements_1: "
          "relative error ‖τ − τ̂‖/‖τ‖ and time")
    errors = {}
    for method in ("ols", "sdp"):
        for on in (False, True):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, train, method=method, friction=friction,
                                  parallel_filter=on)
            elapsed = time.perf_counter() - t0
            e = float(np.linalg.norm(held.tau - res.predict(held)) / np.linalg.norm(held.tau))
            errors[method, on] = (e, elapsed)
            print(f"  {method.upper():<4} parallel {'on ' if on else 'off'}: {100 * e:.3f} % "
                  f"({elapsed:.2f} s)")
    for on in (False, True):
        ratio = errors["sdp", on][0] / errors["ols", on][0]
        print(f"  parallel {'on ' if on else 'off'}: SDP/OLS held-out {ratio:.3f}")
    ols, sdp = (errors[m, True][1] / errors[m, False][1] for m in ("ols", "sdp"))
    print(f"  identification time on/off: OLS {ols:.2f} ×, SDP {sdp:.2f} ×")


def _simulated(arm: str, seed: int, friction: bool):
    from consistid.robot.inertia import perturb
    from consistid.simulate import Effects, record

    model = ci.RobotModel.example(arm)
    truth = perturb(model.prior_parameters, 0.2, np.random.default_rng(seed))
    effects = Effects(position_noise=1e-4, torque_noise=0.1,
                      **(dict(coulomb=0.3, viscous=0.2) if friction else {}))
    runs = []
    for s, duration in ((seed, 30.0), (seed + 10, 10.0)):
        traj = FourierTrajectory.random(model, 5, 10.0, seed=s)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runs.append(record(model, traj, effects, true_parameters=truth, duration=duration,
                               physics_rate=2000.0, seed=s))
    return model, truth, runs


def _chain(t: np.ndarray, q: np.ndarray, tau: np.ndarray, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return run_chain(t, q, tau, PreprocessOptions(**options))


def factor_rows(arm: str, seed: int, friction: bool = False, band: float = 0.5,
                trim: float = 3.0) -> dict[float, dict[str, tuple[float, float, float]]]:
    """Per factor and variant (module docstring): ``(‖β̂ − β‖/‖β‖ of the inertial base
    parameters, held-out RMS in N·m, largest relative Coulomb error or NaN)``."""
    from consistid.data.filters import lowpass
    from consistid.identification.base import compute_base_parameters
    from consistid.identification.regressor import RegressorSpec, regressor

    model, truth, (rec, hold) = _simulated(arm, seed, friction)
    spec = RegressorSpec.make(model, friction=("coulomb", "viscous") if friction else None)
    base = compute_base_parameters(model, spec)
    theta = np.concatenate([truth, np.full(model.nv, 0.3), np.full(model.nv, 0.2)]
                           if friction else [truth])
    beta = base.project(theta)
    inertial = base.independent < model.n_inertial
    coulomb = np.isin(base.independent, model.n_inertial + np.arange(model.nv))
    held_y = base.base_columns(regressor(model, hold.true_q, hold.true_dq, hold.true_ddq, spec))
    held_tau = hold.true_tau.reshape(-1)
    _, stamps = ci.simulate.burst_stamps(rec.t.size, np.random.default_rng(seed))

    def score(y: np.ndarray, tau: np.ndarray) -> tuple[float, float, float]:
        b = np.linalg.lstsq(base.base_columns(y), tau.reshape(-1), rcond=None)[0]
        rel = np.linalg.norm((b - beta)[inertial]) / np.linalg.norm(beta[inertial])
        rms = float(np.sqrt(np.mean((held_y @ b - held_tau) ** 2)))
        fc = float(np.max(np.abs(b[coulomb] / 0.3 - 1))) if friction else float("nan")
        return float(rel), rms, fc

    def chain_score(cutoff: float, torque_cutoff: float) -> tuple[float, float, float]:
        out = _chain(stamps, rec.q, rec.tau, trim=trim, cutoff=cutoff)
        torques = _chain(stamps, rec.q, rec.tau, trim=trim, cutoff=torque_cutoff)
        assert np.array_equal(out.t, torques.t)
        return score(regressor(model, out.q, out.dq, out.ddq, spec, dq_sign=torques.dq_sign),
                     torques.tau)

    wide = _chain(stamps, rec.q, rec.tau, cutoff=10 * band, trim=0.0, filter_torque=False)
    n = wide.t.size
    y_wide = regressor(model, wide.q, wide.dq, wide.ddq, spec).reshape(n, -1)
    keep = (wide.t >= wide.t[0] + trim - 1e-6) & (wide.t <= wide.t[-1] - trim + 1e-6)
    rows = {}
    for factor in FACTORS:
        cut = factor * band
        parallel = (lowpass(y_wide, cut, wide.rate)[keep].reshape(-1, y_wide.shape[1] // model.nv),
                    lowpass(wide.tau, cut, wide.rate)[keep])
        rows[factor] = {"same": chain_score(cut, cut),
                        "τ 10×": chain_score(cut, 10 * band),
                        "parallel": score(*parallel)}
    return rows


def factors(seeds: int, friction: bool) -> None:
    what = "Coulomb 0.3 + viscous 0.2 on every joint" if friction else "no friction"
    print(f"\ncut-off factor: OLS on MuJoCo arms ({what}), 5 harmonics of 10 s (band 0.5 Hz), "
          "1 kHz stamped in bursts; per variant ‖β̂−β‖/‖β‖ (inertial) / held-out RMS [N·m]"
          + (" / worst Coulomb error" if friction else ""))
    for arm in ARMS:
        for seed in range(seeds):
            for factor, row in factor_rows(arm, seed, friction).items():
                cells = [f"{k}: {r:.2e} / {m:.4f}" + (f" / {c:.1%}" if friction else "")
                         for k, (r, m, c) in row.items()]
                print(f"  {arm:<7} seed {seed} {factor:>4g}× " + " | ".join(cells), flush=True)


def identify_rows(arm: str, seed: int) -> dict[bool, tuple[float, float, float, float]]:
    """Per parallel filtering off/on: ``(‖β̂ − β‖/‖β‖ inertial, share covered, held-out RMS,
    seconds)`` of OLS on the default chain's dataset of a jittered MuJoCo log."""
    from consistid.data.signals import preprocess
    from consistid.identification.identify import base_parameters_of
    from consistid.identification.regressor import RegressorSpec

    model, truth, (rec, hold) = _simulated(arm, seed, False)
    _, stamps = ci.simulate.burst_stamps(rec.t.size, np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pre = preprocess(stamps, rec.q, rec.tau)
    base = base_parameters_of(model, RegressorSpec.make(model, None))
    beta = base.project(truth)
    inertial = base.independent < model.n_inertial
    held = ci.Dataset(t=hold.t, q=hold.true_q, dq=hold.true_dq, ddq=hold.true_ddq,
                      tau=hold.true_tau)
    out = {}
    for on in (False, True):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = ci.identify(model, pre.dataset, method="ols", friction=None, parallel_filter=on)
        elapsed = time.perf_counter() - t0
        d = res.base_parameters - beta
        out[on] = (float(np.linalg.norm(d[inertial]) / np.linalg.norm(beta[inertial])),
                   float(np.mean(np.abs(d) <= 1.96 * res.base_std)),
                   float(np.sqrt(np.mean((res.predict(held) - held.tau) ** 2))), elapsed)
    return out


def identify_table(seeds: int) -> None:
    print("\nidentify (OLS) on the default chain's dataset of jittered MuJoCo logs (inertias "
          "±20 %, σq 1e-4, στ 0.1, band 0.5 Hz): parallel off (10 × band) vs on (3 × band)")
    print(f"{'arm':<7} {'seed':>4} {'error off':>10} {'error on':>10} {'cover off':>9} "
          f"{'cover on':>8} {'held rms off':>12} {'held rms on':>11} {'time on/off':>11}")
    for arm in ARMS:
        for seed in range(seeds):
            r = identify_rows(arm, seed)
            print(f"{arm:<7} {seed:>4} {r[False][0]:>10.2e} {r[True][0]:>10.2e} "
                  f"{r[False][1]:>9.2f} {r[True][1]:>8.2f} {r[False][2]:>12.4f} "
                  f"{r[True][2]:>11.4f} {r[True][3] / r[False][3]:>11.2f}", flush=True)


def coverage_run(arm: str, seed: int) -> dict[tuple[str, bool], np.ndarray]:
    """``|β̂ − β| / σ̂`` per base parameter for OLS and the SDP, parallel filtering off/on, on a
    white-noise case through the chain (module docstring)."""
    from consistid.data.signals import preprocess
    from consistid.identification.identify import base_parameters_of
    from consistid.identification.regressor import RegressorSpec, regressor
    from consistid.robot.inertia import perturb

    rng = np.random.default_rng(seed)
    model = ci.RobotModel.example(arm)
    truth = perturb(model.prior_parameters, 0.2, rng)
    spec = RegressorSpec.make(model, None)
    traj = FourierTrajectory.random(model, 5, 10.0, rng)
    s = traj.sample(500.0, 30.0)
    tau = (regressor(model, s.q, s.dq, s.ddq, spec) @ truth).reshape(-1, model.nv)
    tau += 0.1 * rng.standard_normal(tau.shape)
    q = s.q + 1e-5 * rng.standard_normal(s.q.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = preprocess(s.t, q, tau).dataset
    beta = base_parameters_of(model, spec).project(truth)
    out = {}
    for method in ("ols", "sdp"):
        for on in (False, True):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ci.identify(model, data, method=method, friction=None, parallel_filter=on)
            out[method, on] = np.abs(res.base_parameters - beta) / res.base_std
    return out


def coverage_table(runs: int) -> None:
    print(f"\ncoverage of 95 % intervals, white-noise torques through the chain, {runs} runs "
          "per arm (median |error|/σ in brackets; 0.67 when honest)")
    for arm in ("panda", "ur5"):
        z: dict = {}
        for seed in range(runs):
            for key, v in coverage_run(arm, seed).items():
                z.setdefault(key, []).append(v)
        for (method, on), v in z.items():
            v = np.concatenate(v)
            print(f"  {arm:<6} {method.upper():<4} parallel {'on ' if on else 'off'}: "
                  f"{np.mean(v <= 1.96):.3f} ({np.median(v):.2f})", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2, help="cases per arm and noise")
    parser.add_argument("--kuka", type=Path, help="folder of the KUKA LWR4+ .npz logs")
    parser.add_argument("--factors", action="store_true")
    parser.add_argument("--friction", action="store_true")
    parser.add_argument("--identify", action="store_true")
    parser.add_argument("--coverage", type=int, default=0, metavar="RUNS")
    args = parser.parse_args()
    print("jittered 1 kHz logs (burst stamps), slow last joint, position noise + 17-bit counts")
    print(f"{'arm':<7} {'seed':>4} {'noise':<6} {'steps [ms]':>11} {'band [Hz]':>9} "
          f"{'bandwidth/band':>14} {'cut-off/band':>12} {'derivative/band':>15} "
          f"{'max|ddq|/true':>13}")
    ratios, cuts = [], []
    for arm in ARMS:
        for seed in range(args.seeds):
            for noise in ("white", "AR(1)"):
                steps, band, bw, cut, deriv, err = case(arm, seed, noise)
                ratios.append(bw)
                cuts.append(cut)
                print(f"{arm:<7} {seed:>4} {noise:<6} {steps:>11} {band:>9.3g} {bw:>14.3f} "
                      f"{cut:>12.2f} {deriv:>15.2f} {err:>13.3g}", flush=True)
    if ratios:
        print(f"bandwidth / band over {len(ratios)} cases: {min(ratios):.3f}–{max(ratios):.3f}")
        print(f"chosen cut-off / band over {len(cuts)} cases: {min(cuts):.3f}–{max(cuts):.3f} "
              f"(asked: within [1, 4])")
    if args.kuka:
        kuka(args.kuka)
    if args.factors or args.friction:
        factors(args.seeds, args.friction)
    if args.identify:
        identify_table(args.seeds)
    if args.coverage:
        coverage_table(args.coverage)


if __name__ == "__main__":
    main()
