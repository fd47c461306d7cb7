"""Kinematic calibration: joint origins, axes and zero offsets from measured frame poses.

:mod:`.parameters`
    the named corrections (per joint: zero offset, origin translation and rotation, axis tilt;
    the measured frame; the measurement system or the distance anchor) and forward kinematics
:mod:`.measurements`
    positions / poses / distances, their covariances, residuals and derivatives
:mod:`.identifiability`
    which parameters the data fix; the rest as named null combinations held at the URDF's values
:mod:`.calibrate`
    :func:`calibrate_kinematics` (scipy ``least_squares``, robust losses, outlier rejection)
:mod:`.poses`
    :func:`select_poses`: D-optimal / minimum-condition configurations within limits
:mod:`.result`, :mod:`.export`
    :class:`CalibrationResult` and the byte-stable URDF writer
:mod:`.config`
    :func:`run_calibrate`, the ``consistid calibrate CONFIG`` command's work
"""

from .calibrate import calibrate_kinematics
from .identifiability import Unidentifiable
from .measurements import Measurements
from .parameters import GROUPS, KinematicParameters
from .poses import PoseSelection, select_poses
from .result import CalibrationResult

__all__ = ["GROUPS", "CalibrationResult", "KinematicParameters", "Measurements",
           "PoseSelection", "Unidentifiable", "calibrate_kinematics", "select_poses"]
