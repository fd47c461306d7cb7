"""Write examples/panda/calibration_poses.csv: 50 simulated laser-tracker poses of a Panda whose
joint origins are off by up to 2 mm / 0.5° and whose encoder zeros are off by up to 0.5°.

    python examples/panda/make_calibration_data.py

The poses are the 50 D-optimal ones of ``consistid.kinematics.select_poses``; the tracker frame
is 1.2 m in front of the robot, turned 30° about z; noise 0.1 mm and 0.05°. The truth is printed
(and is not in the CSV): compare it with ``consistid calibrate examples/panda/calibrate.toml``.
"""

from pathlib import Path

import numpy as np
import pinocchio as pin

import consistid as ci
from consistid.kinematics import KinematicParameters, select_poses

FRAME = "panda_hand_tcp"

model = ci.RobotModel.example("panda")
chart = KinematicParameters(model, FRAME, "pose")
rng = np.random.default_rng(2026)
truth = np.zeros(chart.size)
for i, name in enumerate(chart.names[:chart.n_kinematic]):
    if name.endswith((".axis_u", ".axis_v")):
        continue
    truth[i] = rng.uniform(-2e-3, 2e-3) if chart.units(name) == "m" else \
        np.radians(rng.uniform(-0.5, 0.5))
robot = chart.robot_model(truth)
tracker = pin.SE3(pin.exp3(np.array([0.0, 0.0, np.radians(30)])), np.array([1.2, 0.1, -0.3]))
plan = select_poses(model, 50, FRAME, "pose", seed=0)
pm, data = robot.pin_model, robot.pin_model.createData()
rows = []
for q in plan.q:
    pin.framesForwardKinematics(pm, data, q)
    m = tracker * data.oMf[pm.getFrameId(FRAME)]
    m = pin.SE3(m.rotation @ pin.exp3(rng.normal(0, np.radians(0.05), 3)),
                m.translation + rng.normal(0, 1e-4, 3))
    rows.append(np.concatenate([q, pin.SE3ToXYZQUAT(m)]))
out = Path(__file__).with_name("calibration_poses.csv")
header = ",".join(model.joint_names + ["x", "y", "z", "qx", "qy", "qz", "qw"])
np.savetxt(out, np.array(rows), delimiter=",", header=header, comments="", fmt="%.10f")
print(f"wrote {out}")
for name, value in zip(chart.names, truth):
    if value:
        print(f"  {name:24s} {value * 1e3:+.4f} {'mm' if chart.units(name) == 'm' else 'mrad'}")
