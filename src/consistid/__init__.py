"""consistid: physically consistent inertial parameter identification for robot manipulators.

>>> import consistid as ci
>>> model = ci.RobotModel.example("panda")
>>> run = ci.simulate.excitation_run(model, duration=20.0)
>>> res = ci.identify(model, run.dataset, method="ols")

The public names are loaded when first used (PEP 562), so ``import consistid`` does not pay for
Pinocchio, cvxpy, MuJoCo or matplotlib until they are needed. The subpackages, bottom to top:
:mod:`~consistid.robot`, :mod:`~consistid.data`, :mod:`~consistid.identification`,
:mod:`~consistid.estimation`, :mod:`~consistid.excitation`, :mod:`~consistid.simulate`,
:mod:`~consistid.kinematics`, :mod:`~consistid.online`, :mod:`~consistid.friction`,
:mod:`~consistid.diagnosis`, :mod:`~consistid.cli` (``docs/architecture.md``).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from typing import TYPE_CHECKING, Any

from . import errors

#: every exception and warning class of :mod:`consistid.errors`, at the top level
_ERRORS = {name: value for name, value in vars(errors).items()
           if isinstance(value, type) and issubclass(value, (Exception, Warning))
           and value.__module__ == errors.__name__}
globals().update(_ERRORS)

__version__ = "0.1.0"

#: public name → the module that defines it
_EXPORTS: dict[str, str] = {
    "RobotModel": "robot.model",
    "InertialParameters": "robot.inertia",
    "is_physically_consistent": "robot.inertia",
    "Ellipsoid": "robot.shapes",
    "Dataset": "data.dataset",
    "load_recording": "data.recordings",
    "RegressorSpec": "identification.regressor",
    "regressor": "identification.regressor",
    "BaseParameters": "identification.base",
    "compute_base_parameters": "identification.base",
    "identify": "identification.identify",
    "DataStream": "identification.streaming",
    "on_dask": "identification.distributed",
    "IdentificationResult": "identification.result",
    "Neighbourhood": "identification.priors",
    "default_prior_weight": "identification.sdp",
    "SDPOptions": "identification.sdp",
    "recover_standard": "estimation.recover",
    "RecoveryResult": "estimation.recover",
    "estimate_payload": "estimation.payload",
    "payload_from_base_change": "estimation.payload",
    "Payload": "estimation.payload",
    "estimate_mounting": "estimation.mounting",
    "MountingEstimate": "estimation.mounting",
    "BoundaryConditions": "excitation",
    "ExcitationDesign": "excitation",
    "ExcitationLimits": "excitation",
    "FourierTrajectory": "excitation",
    "design_excitation": "excitation",
    "diagnose": "diagnosis.diagnose",
    "Diagnosis": "diagnosis.diagnose",
    "calibrate_kinematics": "kinematics",
    "RecursiveEstimator": "online",
    "estimate_breakaway": "friction",
    "compare_friction_models": "friction",
    "SlotineLiController": "online",
    "identify_drive_gains": "drives.gains",
    "DriveGains": "drives.gains",
    "Transmission": "drives.transmission",
    "identify_coupled": "drives.coupled",
    "CoupledResult": "drives.coupled",
    "calibrate_simulator": "simulator",
    "SimulatorCalibration": "simulator",
    "validate_rollout": "simulator",
    "RolloutValidation": "simulator",
    "RolloutOptions": "simulator",
    "PDGains": "simulator",
    "ComputedTorque": "simulator",
}

#: subpackages reachable as attributes (``ci.simulate.record``)
_SUBPACKAGES = ("robot", "data", "identification", "estimation", "excitation", "simulate",
                "diagnosis", "kinematics", "online", "friction", "simulator", "cli", "drives")

__all__ = sorted([*_EXPORTS, "simulate", "errors", *_ERRORS])


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    elif name in _SUBPACKAGES:
        value = importlib.import_module(f".{name}", __name__)
        _load_submodules_on_use(value)
    else:
        raise AttributeError(f"module 'consistid' has no attribute {name!r}")
    globals()[name] = value
    for sub in _SUBPACKAGES:   # imported on the way (ci.data by ci.Dataset): ci.data.recordings
        if f"{__name__}.{sub}" in sys.modules:
            _load_submodules_on_use(sys.modules[f"{__name__}.{sub}"])
    return value


def _load_submodules_on_use(package: Any) -> None:
    """Let ``package``'s submodules load on first use, as its public names do:
    ``ci.data.recordings.from_arrays`` works after ``import consistid`` alone (PEP 562: a
    module's ``__getattr__`` is asked for the names it lacks; a package's own one is asked
    first)."""
    own = vars(package).get("__getattr__")
    if getattr(own, "loads_submodules", False):
        return

    def __getattr__(name: str) -> Any:
        if own is not None:
            try:
                return own(name)
            except AttributeError:
                pass
        if not name.startswith("_") and importlib.util.find_spec(
                f"{package.__name__}.{name}") is not None:
            return importlib.import_module(f".{name}", package.__name__)
        raise AttributeError(f"module {package.__name__!r} has no attribute {name!r}")

    __getattr__.loads_submodules = True          # type: ignore[attr-defined]
    package.__getattr__ = __getattr__


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | set(_SUBPACKAGES))


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from . import simulate
    from .data.dataset import Dataset
    from .data.recordings import load_recording
    from .diagnosis.diagnose import Diagnosis, diagnose
    from .drives.coupled import CoupledResult, identify_coupled
    from .drives.gains import DriveGains, identify_drive_gains
    from .drives.transmission import Transmission
    from .estimation.mounting import MountingEstimate, estimate_mounting
    from .estimation.payload import Payload, estimate_payload, payload_from_base_change
    from .estimation.recover import RecoveryResult, recover_standard
    from .excitation import (BoundaryConditions, ExcitationDesign, ExcitationLimits,
                             FourierTrajectory, design_excitation)
    from .identification.base import BaseParameters, compute_base_parameters
    from .friction import compare_friction_models, estimate_breakaway
    from .identification.distributed import on_dask
    from .identification.identify import identify
    from .identification.streaming import DataStream
    from .kinematics import calibrate_kinematics
    from .online import RecursiveEstimator, SlotineLiController
    from .identification.priors import Neighbourhood
    from .identification.regressor import RegressorSpec, regressor
    from .identification.result import IdentificationResult
    from .identification.sdp import SDPOptions, default_prior_weight
    from .robot.inertia import InertialParameters, is_physically_consistent
    from .robot.model import RobotModel
    from .robot.shapes import Ellipsoid
    from .simulator import (ComputedTorque, PDGains, RolloutOptions, RolloutValidation,
                            SimulatorCalibration, calibrate_simulator, validate_rollout)
