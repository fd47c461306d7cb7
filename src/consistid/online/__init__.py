"""Online identification and adaptive control.

:mod:`~consistid.online.rls` (:class:`RecursiveEstimator`: recursive least squares on the base
parameters, forgetting, anti-windup), :mod:`~consistid.online.change` (change detection on the
whitened innovation), :mod:`~consistid.online.projection` (the running estimate projected onto
the physically consistent set), :mod:`~consistid.online.slotine_li` (the Slotine–Li regressor
and adaptive controller) and :mod:`~consistid.online.adaptive_run` (the controller on the MuJoCo
robot).
"""

from .change import Cusum, WindowedChiSquare
from .rls import Change, RecursiveEstimator, RecursiveTrace

__all__ = ["Change", "Cusum", "RecursiveEstimator", "RecursiveTrace", "WindowedChiSquare"]
