"""The signal chain's automatic cut-off on jittered, noisy logs with a known motion band, and
what the cut-off factor costs in identification.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/cutoff.py [--seeds 2] [--kuka FOLDER]
[--factors] [--friction]``.

Each case is a 30 s log of a 5-harmonic Fourier excitation (band = harmonics / period, period
4 or 10 s) on an arm, sampled every 1 ms and stamped by a logger that writes in bursts (stamp =
arrival after a 0–4 ms delay, at least 0.5 ms after the one before: steps 0.5 to ~5 ms), its
last joint moving 2 % of its range, with position noise (2e-4 rad, white or AR(1) φ = 0.95)
and 17-bit counts (:func:`consistid.simulate.jittered_log`). Printed per case: the estimated
bandwidth and the cut-off over the band, and the largest |q̈| over the trajectory's own (the
issue's symptom: 1 970 rad/s²).

``--kuka FOLDER``: the same on the real KUKA LWR4+ logs (``measurements_*.npz``: 200 Hz,
steps 3.2–6.8 ms, positions already low-pass filtered upstream).

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
            out.cutoff / band, err)


def kuka(folder: Path) -> None:
    print("\nreal KUKA LWR4+ logs (positions filtered upstream; no known band)")
    print(f"{'file':<20} {'steps [ms]':>12} {'bandwidth [Hz]':>15} {'cut-off [Hz]':>13} "
          f"{'max |ddq| [rad/s²]':>19}")
    for path in sorted(folder.glob("measurements_*.npz")):
        d = np.load(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = run_chain(d["times"], d["positions"], d["torques"])
        steps = np.diff(d["times"]) * 1e3
        print(f"{path.name:<20} {steps.min():>5.2f}–{steps.max():<6.2f} {out.bandwidth:>15.3g} "
              f"{out.cutoff:>13.3g} {np.abs(out.ddq).max():>19.3g}")


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2, help="cases per arm and noise")
    parser.add_argument("--kuka", type=Path, help="folder of the KUKA LWR4+ .npz logs")
    parser.add_argument("--factors", action="store_true")
    parser.add_argument("--friction", action="store_true")
    args = parser.parse_args()
    print("jittered 1 kHz logs (burst stamps), slow last joint, position noise + 17-bit counts")
    print(f"{'arm':<7} {'seed':>4} {'noise':<6} {'steps [ms]':>11} {'band [Hz]':>9} "
          f"{'bandwidth/band':>14} {'cut-off/band':>12} {'max|ddq|/true':>13}")
    ratios = []
    for arm in ARMS:
        for seed in range(args.seeds):
            for noise in ("white", "AR(1)"):
                steps, band, bw, cut, err = case(arm, seed, noise)
                ratios.append(bw)
                print(f"{arm:<7} {seed:>4} {noise:<6} {steps:>11} {band:>9.3g} {bw:>14.3f} "
                      f"{cut:>12.2f} {err:>13.3g}", flush=True)
    if ratios:
        print(f"bandwidth / band over {len(ratios)} cases: {min(ratios):.3f}–{max(ratios):.3f}")
    if args.kuka:
        kuka(args.kuka)
    if args.factors or args.friction:
        factors(args.seeds, args.friction)


if __name__ == "__main__":
    main()
