"""Online identification and adaptive control.

:mod:`~consistid.online.rls` (:class:`RecursiveEstimator`: recursive least squares on the base
parameters, forgetting, anti-windup), :mod:`~consistid.online.change` (change detection on the
whitened innovation), :mod:`~consistid.online.projection` (the running estimate projected onto
the physically consistent set; cvxpy is loaded there, on the first projection),
:mod:`~consistid.online.slotine_li` (the Slotine–Li regressor and adaptive controller),
:mod:`~consistid.online.adaptive_run` (the controller on the MuJoCo robot) and
:mod:`~consistid.online.scenario` (simulated runs with a payload change, the ground truth).
"""

from .adaptive_run import AdaptiveRun, adaptive_run
from .change import Cusum, WindowedChiSquare
from .rls import Change, RecursiveEstimator, RecursiveTrace
from .scenario import ChangeRun, payload_change_run
from .slotine_li import SlotineLiController, slotine_li_regressor

__all__ = ["AdaptiveRun", "Change", "ChangeRun", "Cusum", "RecursiveEstimator", "RecursiveTrace",
           "SlotineLiController", "WindowedChiSquare", "adaptive_run", "payload_change_run",
           "slotine_li_regressor"]
