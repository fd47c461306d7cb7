"""Wall time of ``simulate.record``: a 30 s excitation of a 7-DoF arm at 1 kHz physics.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/mujoco_speed.py [--robot panda] [--repeat 3]``.
Target: a few seconds at most. Prints the median of ``--repeat`` runs per effect set (the
physics loop is Python: controller RNEA + ``mj_step`` per step, ~30 µs on this machine).
"""

from __future__ import annotations

import argparse
import statistics
import time

import consistid as ci
from consistid.excitation import FourierTrajectory
from consistid.identification.summary import table
from consistid.simulate import Effects, MountedPayload, record

CASES = {
    "no effects": Effects(),
    "viscous + Coulomb (frictionloss)": Effects(viscous=0.3, coulomb=1.0),
    "Coulomb tanh (v_s = 0.5 rad/s)": Effects(coulomb=1.0, coulomb_model="tanh",
                                              coulomb_speed=0.5),
    "payload + armature": Effects(armature=0.1, payload=MountedPayload(1.0, (0, 0, 0.1))),
    "elastic joints (K = 5000)": Effects(stiffness=5000.0),
    "all sensor effects": Effects(torque_offset=0.3, torque_gain=0.02, delay=0.003,
                                  torque_noise=0.05, position_noise=1e-5,
                                  quantisation=1e-5),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    model = ci.RobotModel.example(args.robot)
    traj = FourierTrajectory.random(model, 5, 10.0, seed=0)
    rows = []
    for name, effects in CASES.items():
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            record(model, traj, effects, duration=args.duration)
            times.append(time.perf_counter() - t0)
        steps = (args.duration + 1.0) * 1000  # + 1 s settling
        median = statistics.median(times)
        rows.append([name, median, median / steps * 1e6])
    print(f"{model.name} ({model.nv} DoF), {args.duration:g} s logged at 1 kHz, physics 1 kHz, "
          f"median of {args.repeat}")
    print(table(["effects", "wall s", "µs / step"], rows, ".3g"))


if __name__ == "__main__":
    main()
