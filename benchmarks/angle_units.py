"""Degrees read as radians, detected by the torque, both ways (consistid.data.units).

For each example arm, 3 seeds × 3 motion amplitudes (0.02, 0.08, 0.5 of the joint ranges' Fourier
amplitude): a MuJoCo run with inertias ±20 % off the URDF, Coulomb and viscous friction the
URDF lacks and torque noise, read as radians (must not be flagged), the same radians log with
its gravity torque subtracted (a gravity-compensated or commanded log: no RNEA torque, must not
be flagged) and the same run written in degrees (should be flagged). Prints per arm how many
radian logs were flagged (false alarms, both kinds), how many degree logs the torque evidence
caught, and how many the position checks alone caught.

Run: ``python benchmarks/angle_units.py``.
"""

from __future__ import annotations

import warnings

import numpy as np

import consistid as ci
from consistid.data.units import (degree_suspects, degree_torque_evidence, model_limits,
                                  revolute_joints)
from consistid.robot.inertia import perturb
from consistid.simulate import Effects, record

ARMS = ("ur3", "ur5", "ur10", "panda", "xarm7", "kinova", "z1")
SEEDS, AMPLITUDES = (0, 1, 2), (0.02, 0.08, 0.5)


def one(model: ci.RobotModel, seed: int, amplitude: float) -> tuple[bool, bool, bool, bool]:
    """(radian log flagged, gravity-compensated radian log flagged, degree log flagged by the
    torque, … by the positions alone)."""
    truth = perturb(model.prior_parameters, 0.2, np.random.default_rng(seed))
    traj = ci.FourierTrajectory.random(model, harmonics=4, period=6.0, seed=seed,
                                       amplitude=amplitude)
    rec = record(model, traj, Effects(coulomb=1.0, viscous=0.5, torque_noise=0.1),
                 true_parameters=truth, duration=6.0, rate=100.0, seed=seed)
    rad = ci.Dataset.from_recording(rec.t, rec.q, rec.tau)
    deg = ci.Dataset.from_recording(rec.t, np.degrees(rec.q), rec.tau)
    compensated = rad.tau - model.rnea(rad.q, 0 * rad.dq, 0 * rad.ddq)
    return (degree_torque_evidence(model, rad.q, rad.dq, rad.ddq, rad.tau) is not None,
            degree_torque_evidence(model, rad.q, rad.dq, rad.ddq, compensated) is not None,
            degree_torque_evidence(model, deg.q, deg.dq, deg.ddq, deg.tau) is not None,
            bool(degree_suspects(deg.q, deg.dq, None, revolute_joints(model),
                                 model_limits(model))))


def main() -> None:
    print(f"{'arm':8s} {'radian logs flagged':>20s} {'compensated flagged':>20s} "
          f"{'degree logs (torque)':>21s} {'degree logs (positions)':>24s}")
    for arm in ARMS:
        model = ci.RobotModel.example(arm)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found = np.array([one(model, s, a) for s in SEEDS for a in AMPLITUDES])
        n = len(found)
        print(f"{arm:8s} {found[:, 0].sum():>17d}/{n} {found[:, 1].sum():>17d}/{n} "
              f"{found[:, 2].sum():>18d}/{n} {found[:, 3].sum():>21d}/{n}")


if __name__ == "__main__":
    main()
