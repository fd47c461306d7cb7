"""consistid: physically consistent inertial parameter identification for robot manipulators.

>>> import consistid as ci
>>> model = ci.RobotModel.example("panda")
>>> run = ci.simulate.excitation_run(model, duration=20.0)
>>> res = ci.identify(model, run.dataset, method="ols")
"""

from . import simulate
from .base import BaseParameters, compute_base_parameters
from .dataset import Dataset
from .errors import (ConsistidError, DatasetError, IdentificationError, InfeasibleError,
                     JointCountError, MissingColumnsError, ModelError, OptionError,
                     PoorExcitationError)
from .excitation import FourierTrajectory
from .identify import identify
from .model import RobotModel
from .parameters import is_physically_consistent
from .regressor import RegressorSpec, regressor
from .result import IdentificationResult

__version__ = "0.1.0"

__all__ = [
    "BaseParameters", "ConsistidError", "Dataset", "DatasetError", "FourierTrajectory",
    "IdentificationError", "IdentificationResult", "InfeasibleError", "JointCountError",
    "MissingColumnsError", "ModelError", "OptionError", "PoorExcitationError", "RegressorSpec",
    "RobotModel", "compute_base_parameters", "identify", "is_physically_consistent", "regressor",
    "simulate",
]
