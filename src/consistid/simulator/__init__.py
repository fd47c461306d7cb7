"""What a simulator user needs: a log replayed in their MuJoCo simulator (open and closed loop,
their step and integrator) and the simulator-only terms calibrated by batched rollouts.

:func:`~.rollout.validate_rollout` measures the gap where a simulator user sees it;
:func:`~.calibrate.calibrate_simulator` shrinks it, starting from the consistent estimate.
"""

from .calibrate import SimulatorCalibration, calibrate_simulator
from .options import ComputedTorque, PDGains, RolloutOptions
from .rollout import RolloutValidation, validate_rollout

__all__ = ["ComputedTorque", "PDGains", "RolloutOptions", "RolloutValidation",
           "SimulatorCalibration", "calibrate_simulator", "validate_rollout"]
