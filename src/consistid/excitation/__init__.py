"""Excitation trajectories and their optimal design.

:mod:`.trajectory`
    parameterisations (Fourier series + quintic, B-splines, the plain periodic Fourier series)
:mod:`.limits`
    joint, torque and Cartesian limits, evaluated as margins
:mod:`.criteria`
    condition number, D- and E-optimality of the base regressor, with gradients
:mod:`.design`
    :func:`design_excitation` (multi-start constrained optimisation) and :func:`assess_excitation`
"""

from .criteria import CRITERIA, prior_column_scale
from .design import (ExcitationDesign, ExcitationQuality, StartResult, assess_excitation,
                     design_excitation, make_parameterisation, random_excitation)
from .limits import (CartesianBox, ConstraintReport, ExcitationLimits, FloorPlane, KeepOutSphere,
                     Margin, end_effector_frame)
from .trajectory import (DEFAULT_ACCELERATION_LIMIT, BoundaryConditions, BSplineParameterisation,
                         FourierPolynomial, FourierTrajectory, Parameterisation, Trajectory)

__all__ = [
    "CRITERIA", "DEFAULT_ACCELERATION_LIMIT", "BSplineParameterisation", "BoundaryConditions",
    "CartesianBox", "ConstraintReport", "ExcitationDesign", "ExcitationLimits",
    "ExcitationQuality", "FloorPlane", "FourierPolynomial", "FourierTrajectory", "KeepOutSphere",
    "Margin", "Parameterisation", "StartResult", "Trajectory", "assess_excitation",
    "design_excitation", "end_effector_frame", "make_parameterisation", "prior_column_scale",
    "random_excitation",
]
