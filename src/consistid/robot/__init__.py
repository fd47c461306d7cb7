"""The robot: what is known before any data — kinematics, the CAD inertias, their files.

* :mod:`.model` — :class:`~consistid.robot.model.RobotModel` (a Pinocchio model with names,
  locked joints, gravity and the prior parameters), from a URDF or example-robot-data.
* :mod:`.inertia` — one body's standard parameters (:class:`InertialParameters`), the
  pseudo-inertia and the physical-consistency checks.
* :mod:`.joint_terms` — names of the per-joint terms (friction, offset, armature).
* :mod:`.urdf` — reading URDF ``<dynamics>`` tags; :mod:`.export` — writing identified values
  back into the URDF.
* :mod:`.mjcf_in` — reading an MJCF (compiled by MuJoCo); :mod:`.mjcf` — a new MJCF of the
  model; :mod:`.mjcf_edit` — identified values written into the user's MJCF
  (:mod:`.xml_spans`: the byte spans it edits).
* :mod:`.shapes` — bounding ellipsoids of the bodies from their collision geometry.
"""
