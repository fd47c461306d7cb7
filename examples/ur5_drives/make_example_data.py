"""Write the motor-side logs that examples/ur5_drives/identify.toml reads (data/).

    python examples/ur5_drives/make_example_data.py            # writes examples/ur5_drives/data/
    python examples/ur5_drives/make_example_data.py OUT_DIR    # writes elsewhere

A simulated UR5 (MuJoCo, :func:`consistid.simulate.drives.record_drives`) that logs what a
current-controlled arm logs: motor angles (17-bit encoders on the motor shafts, gear ratios
101, the fifth motor turning the other way) and motor currents (torque constants 0.13 N·m/A on
the large motors, 0.1 on the wrist; σ = 0.02 A noise), with motor-side viscous friction
(2e-4 N·m·s/rad at the motor, ``r² f_v`` ≈ 2 N·m·s/rad at the joint). Random Fourier
trajectories (5 harmonics, 10 s period) at 250 Hz: ``ur5_motor_train.npz`` (12 s, seed 1) and
``ur5_motor_held_out.npz`` (8 s, seed 2), arrays ``t``, ``motor_q``, ``current``; and for
``identify_gains.toml`` (unknown gains) ``ur5_motor_loaded.npz`` (12 s, seed 3), the same kind
of excitation with a 2.5 kg load on the flange (:data:`LOAD`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import consistid as ci
from consistid.excitation import FourierTrajectory
from consistid.simulate import Effects, MountedPayload
from consistid.simulate.drives import SimulatedDrives, record_drives

RATIOS = [101.0, 101.0, 101.0, 101.0, -101.0, 101.0]
TORQUE_CONSTANTS = [0.13, 0.13, 0.13, 0.1, 0.1, 0.1]
#: The load of the loaded run (weighed: 2.5 kg; its centre of mass and inertia unknown to the
#: identification).
LOAD = MountedPayload(2.5, com=[0.02, -0.03, 0.08], inertia=np.diag([0.01, 0.012, 0.008]))


def main(out: Path) -> None:
    model = ci.RobotModel.example("ur5")
    drives = SimulatedDrives(ci.Transmission(RATIOS, torque_constants=TORQUE_CONSTANTS),
                             viscous=2e-4, current_noise=0.02, encoder_counts=2 ** 17)
    out.mkdir(parents=True, exist_ok=True)
    for name, seed, duration, load in (("ur5_motor_train", 1, 12.0, None),
                                       ("ur5_motor_held_out", 2, 8.0, None),
                                       ("ur5_motor_loaded", 3, 12.0, LOAD)):
        traj = FourierTrajectory.random(model, 5, 10.0, np.random.default_rng(seed))
        rec = record_drives(model, traj, drives, Effects(payload=load), seed=seed,
                            duration=duration, rate=250.0)
        np.savez_compressed(out / f"{name}.npz", t=rec.t, motor_q=rec.motor_q,
                            current=np.round(rec.currents, 5))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent / "data")
