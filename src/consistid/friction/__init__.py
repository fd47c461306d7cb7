"""Joint friction beyond Coulomb and viscous: nonlinear laws identified with the rigid body,
break-away (static) friction, and ramp experiments.

:mod:`~consistid.friction.models` the laws (Stribeck, Gaz sigmoid, smooth tanh Coulomb);
:mod:`~consistid.friction.fit` their identification by variable projection, reached through
``consistid.identify(model, data, friction="stribeck" | {joint: law} | ...)``;
:mod:`~consistid.friction.selection` which law held-out data prefer per joint;
:mod:`~consistid.friction.breakaway` the break-away torque per joint from logs or from a simulated
ramp experiment; :mod:`~consistid.friction.ramp` ramp experiments as a schedule and CSV that a
robot can run.
"""

from .breakaway import BreakawayEstimate, BreakawayEvent, estimate_breakaway, simulate_ramps
from .fit import NonlinearFrictionResult, identify_nonlinear, is_nonlinear, parse_friction
from .models import MODELS, FrictionModel, GazSigmoid, Stribeck, TanhCoulomb, get_model
from .ramp import Ramp, RampPlan, ramp_plan
from .selection import FrictionComparison, compare_friction_models

__all__ = ["MODELS", "BreakawayEstimate", "BreakawayEvent", "FrictionComparison",
           "FrictionModel", "GazSigmoid", "compare_friction_models",
           "NonlinearFrictionResult", "Ramp", "RampPlan", "Stribeck", "TanhCoulomb",
           "estimate_breakaway", "get_model", "identify_nonlinear", "is_nonlinear",
           "parse_friction", "ramp_plan", "simulate_ramps"]
