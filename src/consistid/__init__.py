"""consistid: physically consistent inertial parameter identification for robot manipulators.

>>> import consistid as ci
>>> model = ci.RobotModel.example("panda")
>>> run = ci.simulate.excitation_run(model, duration=20.0)
>>> res = ci.identify(model, run.dataset, method="ols")
"""

from . import simulate
from .base import BaseParameters, compute_base_parameters
from .constraints import Ellipsoid
from .dataset import Dataset
from .diagnose import Diagnosis, diagnose
from .errors import (ConfigError, ConsistidError, DatasetError, ExcitationError,
                     IdentificationError, InaccurateSolutionWarning, InconsistentParametersError,
                     InfeasibleError, InfeasibleExcitationError, JointCountError, JointNameError,
                     MissingColumnsError, ModelError, OptionError, PoorExcitationError,
                     PoorExcitationWarning, TrackingWarning, UnrealizableCoefficientsError)
from .excitation import (BoundaryConditions, ExcitationDesign, ExcitationLimits, FourierTrajectory,
                         design_excitation)
from .identify import identify
from .model import RobotModel
from .mounting import MountingEstimate, estimate_mounting
from .parameters import is_physically_consistent
from .priors import Neighbourhood
from .payload import Payload, estimate_payload, payload_from_base_change
from .recordings import load_recording
from .recover import RecoveryResult, recover_standard
from .regressor import RegressorSpec, regressor
from .result import IdentificationResult
from .sdp import default_prior_weight

__version__ = "0.1.0"

__all__ = [
    "BaseParameters", "BoundaryConditions", "ConfigError", "ConsistidError", "Dataset",
    "DatasetError", "ExcitationError", "JointNameError",
    "Diagnosis", "diagnose",
    "Ellipsoid", "ExcitationDesign", "ExcitationLimits", "FourierTrajectory",
    "InfeasibleExcitationError", "IdentificationError", "IdentificationResult",
    "InaccurateSolutionWarning", "InconsistentParametersError", "InfeasibleError",
    "JointCountError", "MissingColumnsError", "ModelError", "MountingEstimate", "Neighbourhood",
    "OptionError",
    "Payload", "PoorExcitationError", "PoorExcitationWarning", "RecoveryResult",
    "RegressorSpec", "RobotModel", "TrackingWarning", "UnrealizableCoefficientsError",
    "compute_base_parameters",
    "default_prior_weight", "design_excitation", "estimate_mounting", "estimate_payload",
    "identify",
    "is_physically_consistent", "load_recording",
    "payload_from_base_change", "recover_standard", "regressor", "simulate",
]
