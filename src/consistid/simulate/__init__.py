"""The simulated "real robot": effects a nominal model lacks, the MuJoCo robot, simulated runs.

:mod:`~consistid.simulate.effects` describes the effects (friction, payload, elasticity, sensor
noise, delay …), :mod:`~consistid.simulate.mujoco_robot` builds the MuJoCo model with
``MjSpec``, and :mod:`~consistid.simulate.experiments` runs excitation experiments with a known
ground truth (regressor-only runs and MuJoCo recordings).
"""

from .effects import Effects, MountedPayload
from .experiments import (MAX_TRACKING_ERROR, DesiredMotion, SimulatedRecording, SimulatedRun,
                          TrackingController, ar1_noise, excitation_run, nominal_residual, record)

__all__ = ["MAX_TRACKING_ERROR", "DesiredMotion", "Effects", "MountedPayload",
           "SimulatedRecording", "SimulatedRun", "TrackingController", "ar1_noise",
           "excitation_run", "nominal_residual", "record"]
