"""Online identification and adaptive control.

:mod:`~consistid.online.rls` (:class:`RecursiveEstimator`: recursive least squares on the base
parameters, forgetting, anti-windup), :mod:`~consistid.online.change` (change detection on the
whitened innovation), :mod:`~consistid.online.projection` (the running estimate projected onto
the physically consistent set), :mod:`~consistid.online.slotine_li` (the Slotine–Li regressor
and adaptive controller), :mod:`~consistid.online.adaptive_run` (the controller on the MuJoCo
robot) and :mod:`~consistid.online.scenario` (simulated runs with a payload change, the ground
truth).

The estimator and the detectors load with the package; the other names load on first use
(PEP 562), so that an estimator in a control loop does not import cvxpy, MuJoCo or the
excitation design.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .change import Cusum, WindowedChiSquare
from .rls import Change, RecursiveEstimator, RecursiveTrace

#: name → the module (of this package) that defines it, imported on first use
_LAZY = {"AdaptiveRun": "adaptive_run", "adaptive_run": "adaptive_run",
         "ChangeRun": "scenario", "payload_change_run": "scenario",
         "SlotineLiController": "slotine_li", "slotine_li_regressor": "slotine_li",
         "ConsistencyProjector": "projection", "ProjectedEstimate": "projection"}

__all__ = sorted(["Change", "Cusum", "RecursiveEstimator", "RecursiveTrace",
                  "WindowedChiSquare", *_LAZY])


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'consistid.online' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value
    return value


if TYPE_CHECKING:
    from .adaptive_run import AdaptiveRun, adaptive_run
    from .projection import ConsistencyProjector, ProjectedEstimate
    from .scenario import ChangeRun, payload_change_run
    from .slotine_li import SlotineLiController, slotine_li_regressor
