"""Do the diagnosis's friction σ cover the truth, and does it tell ``identify``'s story? Coulomb
and viscous friction as ``diagnose`` reports them (the set-valued refit of each joint's friction
law where it made one, else the point-valued fit), over seeds of the Panda example's simulated
robot and of the same effects on other arms; and, with ``--identify``, how far
``identify(method="sdp")`` on the same training log lies from them.

Each seed simulates, as ``examples/panda/make_example_data.py`` does (inertias 10 % off,
Coulomb 1.2–0.6 N·m and viscous 0.8–0.3 N·m·s/rad over the joints, a 0.3 N·m offset on the
second joint, σ = 0.05 N·m, 19-bit encoders, 100 Hz), a 20 s training and a 10 s held-out log
on new trajectories, through the default signal chain, and diagnoses them. Printed per
parameter: value ± σ, the simulated truth and ``z = (value − truth) / σ``; then per kind
(Coulomb or viscous, set-valued or point-valued) the mean and RMS of ``z`` (RMS ≈ 1 when σ
covers), the coverage of the 95 % intervals (``|z| ≤ 1.96``) and how many lie beyond 3. With
``--identify``: per parameter ``d = |diagnose − identify| / √(σ_d² + σ_i²)`` and its RMS
(``--example``: on the shipped example's logs, ``examples/panda/diagnose.toml``).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagnosis_friction_coverage.py
[--arm panda|ur5|xarm7|kinova] [--seeds 1-6] [--identify] [--example]``.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples" / "panda"))

import consistid as ci  # noqa: E402
from consistid.robot.inertia import perturb  # noqa: E402
from consistid.simulate import Effects, record  # noqa: E402

import make_example_data as example  # noqa: E402


def simulate(model: ci.RobotModel, truth: np.ndarray, friction: dict[str, np.ndarray],
             seed: int, duration: float) -> ci.Dataset:
    """``example.simulate`` on any arm: its effects, the offset on the arm's second joint."""
    effects = Effects(coulomb=friction["coulomb"], viscous=friction["viscous"],
                      torque_offset={model.joint_names[1]: 0.3}, torque_noise=0.05,
                      quantisation=2 * np.pi / 2 ** 19)
    traj = ci.FourierTrajectory.random(model, harmonics=example.HARMONICS,
                                       period=example.PERIOD, seed=seed, amplitude=0.6)
    rec = record(model, traj, effects, true_parameters=truth, duration=duration,
                 rate=example.RATE, seed=seed)
    return ci.Dataset.from_recording(rec.t, rec.q, rec.tau)


def identify_friction(model: ci.RobotModel, train: ci.Dataset) -> dict[str, tuple[float, float]]:
    """``{"<joint>.fc": (value, σ), …}``: ``identify(method="sdp")``'s friction on ``train``."""
    res = ci.identify(model, train, method="sdp")
    return {n: (float(v), float(s)) for n, v, s in
            zip(res.base.names, res.base_parameters, res.base_std)
            if n.endswith((".fc", ".fv"))}


def diagnosed(model: ci.RobotModel, train: ci.Dataset, held: ci.Dataset | None,
              truth: dict[str, np.ndarray] | None, agree: dict | None, label: str,
              rows: list) -> None:
    """Diagnose, print each friction parameter, append ``(name, kind, z, d)`` to ``rows``."""
    diag = ci.diagnose(model, train, held_out=held)
    for e in diag.effects:
        for p in e.parameters if e.name in ("coulomb", "viscous") else ():
            kind = "set-valued" if "set-valued" in p.note else "point-valued"
            line = f"{label} {e.name:8} {p.joint:20} {p.value:.3f} ± {p.std:.3f}"
            z = d = np.nan
            if truth is not None:
                true = truth[e.name][model.joint_names.index(p.joint)]
                z = (p.value - true) / p.std
                line += f"  truth {true:.3f}  z {z:+.1f}"
            if agree is not None:
                key = f"{p.joint}.{'fc' if e.name == 'coulomb' else 'fv'}"
                if key in agree:
                    v, s = agree[key]
                    d = abs(p.value - v) / np.hypot(p.std, s)
                    line += f"  identify {v:.3f} ± {s:.3f}  d {d:.1f}"
            print(line + f"  {kind}", flush=True)
            rows.append((e.name, kind, z, d))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-6", help="first-last seed")
    parser.add_argument("--arm", default="panda")
    parser.add_argument("--identify", action="store_true", help="compare with identify")
    parser.add_argument("--example", action="store_true",
                        help="the shipped Panda example's logs instead of new seeds")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    rows: list = []
    if args.example:
        from consistid.cli.config import config_model, config_recordings, load_config

        config = load_config(ROOT / "examples" / "panda" / "diagnose.toml")
        model = config_model(config)
        train, held = (r.dataset for r in config_recordings(config, model))
        truth = json.loads((ROOT / "examples" / "panda" / "data" / "truth.json").read_text())
        friction = {k: np.asarray(truth[k]) for k in ("coulomb", "viscous")}
        diagnosed(model, train, held, friction, identify_friction(model, train), "example",
                  rows)
    else:
        first, last = map(int, args.seeds.split("-"))
        model = ci.RobotModel.example(args.arm)
        truth = perturb(model.prior_parameters, 0.1, np.random.default_rng(7))
        friction = {"coulomb": np.linspace(1.2, 0.6, model.nv),
                    "viscous": np.linspace(0.8, 0.3, model.nv)}
        for s in range(first, last + 1):
            train, held = (simulate(model, truth, friction, 10 * s + k, d)
                           for k, d in ((1, 20.0), (2, 10.0)))
            agree = identify_friction(model, train) if args.identify else None
            diagnosed(model, train, held, friction, agree, str(s), rows)
    print("\nparameter       fit           n  mean z  RMS z  cover95  |z| > 3  RMS d  max d")
    for name in ("coulomb", "viscous"):
        for kind in ("set-valued", "point-valued"):
            z = np.array([v for n, k, v, _ in rows if n == name and k == kind])
            d = np.array([v for n, k, _, v in rows if n == name and k == kind])
            d = d[np.isfinite(d)]
            if z.size:
                dd = (f"{np.sqrt(np.mean(d ** 2)):6.2f} {d.max():6.2f}" if d.size else "")
                print(f"{name:15} {kind:12} {z.size:3} {z.mean():+7.2f} "
                      f"{np.sqrt(np.mean(z ** 2)):6.2f} {np.mean(abs(z) <= 1.96):8.2f} "
                      f"{int(np.sum(abs(z) > 3)):6} {dd}")


if __name__ == "__main__":
    main()
