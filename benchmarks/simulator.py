"""consistid in the user's simulator: rollout tracking before and after ``calibrate_simulator``.

The "real robot" is ``consistid.simulate.record`` (MuJoCo at 1 kHz, semi-implicit Euler, dry
friction as a stiff friction-loss constraint) on a Panda whose inertias are off the nominal by
up to ±20 % per body, with armature, viscous and Coulomb friction and torque noise σ = 0.1 N·m,
logged at 500 Hz and filtered by ``Dataset.from_recording``. Runs: a rich 25 s excitation
(5 harmonics), a poor 3 s one (2 harmonics, a third of a period) and a 10 s held-out run.
The user's simulator: the robot's MJCF at 2 ms ``implicitfast``; closed-loop replays under the
default PD (ω = 20 rad/s), open-loop replays reset every second (``consistid.simulator``).

Columns: CPU time (``time.process_time``: one thread, robust to a shared machine) relative to
the consistid SDP; held-out inverse-dynamics τ RMS / σ (worst
joint; the truth's for reference); held-out closed-loop q error (mrad) and correction torque
(N·m), RMS over joints; under computed torque (``ComputedTorque``, ω = 20 rad/s) the torque
error (N·m; every model tracks there, its own inverse dynamics linearising it); open-loop drift
(mrad); every body consistent.

``mujoco.sysid`` (MuJoCo 4.0) on the same runs: ``simulator_sysid.py`` (minutes per fit; run
once per run type).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/simulator.py [--seeds 0 1 2] [--runs poor]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

import consistid as ci
from consistid.identification.regressor import regressor
from consistid.identification.summary import table
from consistid.simulate import Effects, record
from consistid.simulator import (ComputedTorque, RolloutOptions, calibrate_simulator,
                                 validate_rollout)

SIGMA = 0.1
RUNS = {"rich": dict(duration=25.0, harmonics=5), "poor": dict(duration=3.0, harmonics=2)}


@dataclasses.dataclass
class Truth:
    model: ci.RobotModel
    inertial: np.ndarray
    armature: np.ndarray
    viscous: np.ndarray
    coulomb: np.ndarray

    def vector(self, names) -> np.ndarray:
        """The truth in the order of ``names`` (an identification's parameter names)."""
        per_joint = {"Ia": self.armature, "fv": self.viscous, "fc": self.coulomb}
        out = np.zeros(len(names))
        out[: self.model.n_inertial] = self.inertial
        for k, n in enumerate(names[self.model.n_inertial:], self.model.n_inertial):
            joint, term = n.rsplit(".", 1)
            out[k] = per_joint.get(term, np.zeros(self.model.nv))[
                self.model.joint_names.index(joint)]
        return out


def make_truth(model: ci.RobotModel, rng: np.random.Generator) -> Truth:
    scale = np.repeat(1 + 0.2 * rng.uniform(-1, 1, model.n_bodies), 10)
    return Truth(model, model.prior_parameters * scale, rng.uniform(0.05, 0.15, model.nv),
                 rng.uniform(0.1, 0.5, model.nv), rng.uniform(0.1, 0.5, model.nv))


def log(truth: Truth, duration: float, harmonics: int, seed: int) -> ci.Dataset:
    m = truth.model
    traj = ci.FourierTrajectory.random(m, harmonics, 10.0, np.random.default_rng(seed))
    eff = Effects(viscous=truth.viscous, coulomb=truth.coulomb, armature=truth.armature,
                  torque_noise=SIGMA)
    rec = record(m, traj, eff, true_parameters=truth.inertial, duration=duration, rate=500.0,
                 seed=seed)
    return ci.Dataset.from_recording(rec.t, rec.q, rec.tau,
                                     joint_names=tuple(m.joint_names))


def truth_rms(truth: Truth, res, data: ci.Dataset) -> np.ndarray:
    y = regressor(truth.model, data.q, data.dq, data.ddq, res.spec)
    pred = (y @ truth.vector(res.parameter_names)).reshape(-1, truth.model.nv)
    return np.sqrt(np.mean((data.tau - pred) ** 2, axis=0))


class _Fixed:
    def __init__(self, model, parameters, names):
        self.model, self.parameters, self.parameter_names = model, parameters, names


def one(seed: int, run: str) -> list[list]:
    model = ci.RobotModel.example("panda")
    rng = np.random.default_rng(seed)
    truth = make_truth(model, rng)
    train = log(truth, seed=100 * seed + 1, **RUNS[run])
    held = log(truth, 10.0, 5, seed=100 * seed + 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()
        res = ci.identify(model, train, method="sdp", friction=("coulomb", "viscous"),
                          armature=True)
        t_sdp = time.process_time() - t0
        cals, walls = {}, {}
        variants = [("consistid + calibrate", False)]
        if run == "poor":            # output-error refinement of the inertias: for poor data
            variants.append(("consistid + calibrate + inertia", True))
        for label, refine in variants:
            t0 = time.process_time()
            cals[label] = calibrate_simulator(res, train, refine_inertia=refine)
            walls[label] = t_sdp + time.process_time() - t0
    true_fit = _Fixed(model, truth.vector(res.parameter_names), res.parameter_names)
    models = {"truth": true_fit, "consistid SDP": res, **cals}
    rms = {"truth": truth_rms(truth, res, held), "consistid SDP": res.rms(held),
           **{k: c.as_result().rms(held) for k, c in cals.items()}}
    times = {"truth": float("nan"), "consistid SDP": t_sdp,
             **walls}
    consistent = {"truth": True, "consistid SDP": res.is_consistent,
                  **{k: c.is_consistent for k, c in cals.items()}}
    v = validate_rollout(held, models)
    ct = validate_rollout(held, models, options=RolloutOptions(controller=ComputedTorque()))
    rows = []
    for r, c in zip(v.replays, ct.replays):
        row = r.row()
        rows.append([run, seed, r.label, times[r.label] / t_sdp, np.max(rms[r.label]) / SIGMA,
                     row["q_error_mrad"], row["tau_error_Nm"], c.row()["tau_error_Nm"],
                     row["open_loop_mrad"], "yes" if consistent[r.label] else "NO"])
    for c in cals.values():
        print(run, seed, c.summary().splitlines()[0], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--runs", nargs="+", default=list(RUNS), choices=list(RUNS))
    args = parser.parse_args()
    rows = [row for run in args.runs for seed in args.seeds
            for row in one(seed, run)]
    print(table(["run", "seed", "model", "time / SDP", "held-out τ RMS/σ (max)",
                 "closed-loop q mrad", "closed-loop τ N·m", "computed-torque τ N·m",
                 "open-loop mrad", "consistent"],
                rows, ".3g"))


if __name__ == "__main__":
    main()
