"""The simulated "real robot": effects a nominal model lacks, the MuJoCo robot, simulated runs.

:mod:`~consistid.simulate.effects` describes the effects (friction, payload, elasticity, sensor
noise, delay …), :mod:`~consistid.simulate.mujoco_robot` builds the MuJoCo model with
``MjSpec``, and :mod:`~consistid.simulate.experiments` runs excitation experiments with a known
ground truth (regressor-only runs and MuJoCo recordings); :mod:`~consistid.simulate.loggers`
makes logs as real loggers write them (stamps in bursts, coloured noise, encoder counts);
:mod:`~consistid.simulate.mujoco_logs` holds the MuJoCo logs with a known truth that tests and
benchmarks share (a PD-tracked log of the MJCF itself, an arm with dry and viscous friction).
"""

from .effects import Effects, MountedPayload
from .experiments import (MAX_TRACKING_ERROR, DesiredMotion, SimulatedRecording, SimulatedRun,
                          TrackingController, ar1_noise, excitation_run, nominal_residual, record)
from .loggers import burst_stamps, jittered_log

__all__ = ["MAX_TRACKING_ERROR", "DesiredMotion", "Effects", "MountedPayload",
           "SimulatedRecording", "SimulatedRun", "TrackingController", "ar1_noise",
           "burst_stamps", "excitation_run", "jittered_log", "nominal_residual", "record"]
