"""Native planar kinematics in Cartesian body coordinates (the general method)."""

from ._newton import CONVERGED_TOLERANCE, converged_tolerance
from ._solve import NEAR_SINGULAR, SINGULAR, InputRange, Kinematics, Solution, Status
from ._system import ConstraintSystem, rotate

__all__ = [
    "CONVERGED_TOLERANCE",
    "NEAR_SINGULAR",
    "SINGULAR",
    "ConstraintSystem",
    "InputRange",
    "Kinematics",
    "Solution",
    "Status",
    "converged_tolerance",
    "rotate",
]
