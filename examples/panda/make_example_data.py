"""Write the logs that the Panda example configurations read (examples/panda/data/).

    python examples/panda/make_example_data.py            # writes examples/panda/data/
    python examples/panda/make_example_data.py OUT_DIR    # writes elsewhere (e.g. to compare)

A simulated "real" Panda (MuJoCo, :func:`consistid.simulate.record`) that is *not* its URDF:

* inertial parameters = the URDF's, each body's mass, CoM and inertia scaled by factors drawn
  from [0.9, 1.1] (:func:`consistid.robot.inertia.perturb`, seed 7);
* Coulomb friction 0.6–1.2 N·m and viscous friction 0.3–0.8 N·m·s/rad per joint, a torque
  sensor offset of 0.3 N·m on joint 2, white torque noise σ = 0.05 N·m and 19-bit encoders.

It follows random Fourier trajectories (5 harmonics, 10 s period) under the default computed
torque controller; each log keeps what a real robot's logger would give (time, measured
positions, measured torques; no velocities or accelerations) at 100 Hz:

=========================  ====  ==============================================================
file                       s     what
=========================  ====  ==============================================================
``panda_train.csv``        20    unloaded, trajectory seed 1: identify / diagnose / payload /
                                 recover train on it. Columns ``t, q_<joint>…, tau_<joint>…``
``panda_held_out.csv``     10    unloaded, trajectory seed 2: held-out scoring
``panda_loaded.npz``       20    with a 1.5 kg payload on the hand (CoM 6 cm along its z axis),
                                 trajectory seed 3; arrays ``t, q, tau, joint_names``
``panda_coefficients.npz``       base coefficients ``beta`` (and their ``covariance``) fitted by
                                 OLS on panda_train.csv, as another tool would hand them over
                                 (``base_names`` says which regrouping each one is)
``truth.json``                   what the simulation used (the answer the examples should find)
=========================  ====  ==============================================================

Everything is seeded, so a rerun writes the same numbers (up to MuJoCo's last digits on another
platform; the CSV keeps 7 significant digits). The files are small (~0.6 MB) and committed, so
the examples run at once; rerun this script after changing it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.robot.inertia import perturb
from consistid.simulate import Effects, MountedPayload, record

RATE = 100.0            # Hz of the logs (the physics and the controller run at 1 kHz)
PERIOD, HARMONICS = 10.0, 5
PAYLOAD = dict(mass=1.5, com=(0.0, 0.0, 0.06), frame="panda_hand",
               inertia=np.diag([2.0e-3, 2.0e-3, 1.5e-3]))
FRICTION = ("coulomb", "viscous", "offset")


def effects(model: ci.RobotModel, payload: MountedPayload | None = None) -> Effects:
    """The effects the URDF lacks (the same on every log; ``payload`` on the loaded one)."""
    nv = model.nv
    return Effects(coulomb=np.linspace(1.2, 0.6, nv), viscous=np.linspace(0.8, 0.3, nv),
                   torque_offset={"panda_joint2": 0.3}, torque_noise=0.05,
                   quantisation=2 * np.pi / 2 ** 19, payload=payload)


def simulate(model: ci.RobotModel, truth: np.ndarray, seed: int, duration: float,
             payload: MountedPayload | None = None):
    traj = ci.FourierTrajectory.random(model, harmonics=HARMONICS, period=PERIOD, seed=seed,
                                       amplitude=0.6)
    return record(model, traj, effects(model, payload), true_parameters=truth,
                  duration=duration, rate=RATE, seed=seed)


def write_csv(path: Path, rec, joints: list[str]) -> None:
    """A logger-style CSV: a header naming each column after its joint."""
    header = ",".join(["t"] + [f"q_{j}" for j in joints] + [f"tau_{j}" for j in joints])
    table = np.column_stack([rec.t, rec.q, rec.tau])
    fmt = ["%.3f"] + ["%.7g"] * (2 * len(joints))
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt=fmt)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    model = ci.RobotModel.example("panda")
    joints = list(model.joint_names)
    truth = perturb(model.prior_parameters, 0.1, np.random.default_rng(7))

    train = simulate(model, truth, seed=1, duration=20.0)
    held = simulate(model, truth, seed=2, duration=10.0)
    loaded = simulate(model, truth, seed=3, duration=20.0, payload=MountedPayload(**PAYLOAD))
    write_csv(out / "panda_train.csv", train, joints)
    write_csv(out / "panda_held_out.csv", held, joints)
    np.savez_compressed(out / "panda_loaded.npz", t=loaded.t, q=loaded.q.astype(np.float32),
                        tau=loaded.tau.astype(np.float32), joint_names=np.array(joints))

    # Base coefficients as another tool would hand them over: OLS on the training log.
    data = ci.load_recording(out / "panda_train.csv", model=model).dataset
    ols = ci.identify(model, data, method="ols", friction=FRICTION)
    np.savez_compressed(out / "panda_coefficients.npz", beta=ols.base_parameters,
                        covariance=ols.base_covariance,
                        base_names=np.array(ols.base.names))

    eff = train.effects
    (out / "truth.json").write_text(json.dumps({
        "robot": model.name, "joints": joints,
        "inertial_parameters": dict(zip(model.parameter_names, truth.round(6).tolist())),
        "coulomb": eff.coulomb.round(6).tolist(), "viscous": eff.viscous.round(6).tolist(),
        "torque_offset": eff.torque_offset.tolist(), "torque_noise": 0.05,
        "payload": {"mass": PAYLOAD["mass"], "com": list(PAYLOAD["com"]),
                    "frame": PAYLOAD["frame"],
                    "inertia_diagonal": np.diag(PAYLOAD["inertia"]).tolist()},
        "rate": RATE, "tracking_error_max": float(max(r.tracking_error.max()
                                                      for r in (train, held, loaded))),
    }, indent=1) + "\n")
    for f in sorted(out.iterdir()):
        print(f"wrote {f} ({f.stat().st_size / 1024:.0f} kB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("data"))
