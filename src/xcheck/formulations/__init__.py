"""The seeds' other formulations as independent native solvers.

The general solver (:mod:`xcheck.kinematics`) is seed 000's formulation III
(Cartesian body coordinates). This package adds:

- ``"formulation-I"``: one generalized coordinate and direct substitution
  (seed 000, formulation I) for a four-bar or an offset slider-crank driven at
  its crank, recognised from the model's topology and geometry;
- ``"formulation-II"``: relative coordinates solved loop after loop by the
  complex-number method (seed 000, formulation II; seed 004), with the loops
  derived from the model, for every mechanism that can be solved two unknowns
  at a time (dyadic).

Each is a function ``(kinematics, inputs, rates, accelerations, branch=None)
-> Trajectory`` (registry :data:`FORMULATIONS`) that raises
:class:`~xcheck.engines.NotApplicable` with a one-line reason when the mechanism is outside
its reach. Compare a result with the general solver by
:func:`xcheck.results.differences`.
"""

from __future__ import annotations

from ..errors import NotApplicable
from ..kinematics import Kinematics
from ..results import ModeResult
from ._closed_form import recognise, solve_closed_form
from ._vector_loops import LoopPlan, plan_loops, solve_vector_loops

__all__ = [
    "FORMULATIONS",
    "LoopPlan",
    "applicability",
    "formulation",
    "plan_loops",
    "recognise",
    "run_formulation",
]

#: name -> function(kinematics, inputs, rates, accelerations, branch=None) -> Trajectory
FORMULATIONS = {
    "formulation-I": solve_closed_form,
    "formulation-II": solve_vector_loops,
}

_CHECKS = {
    "formulation-I": recognise,
    "formulation-II": plan_loops,
}


def formulation(name: str):
    """The function of a formulation; ValueError listing the names if unknown."""
    if name not in FORMULATIONS:
        raise ValueError(f"expected a formulation ({', '.join(FORMULATIONS)}), found {name!r}")
    return FORMULATIONS[name]


def applicability(kinematics: Kinematics) -> dict[str, str | None]:
    """For each formulation, None if it applies to the mechanism, else the
    reason it does not (one line). Structural only: nothing is solved."""
    result: dict[str, str | None] = {}
    for name, check in _CHECKS.items():
        try:
            check(kinematics.mechanism)
            result[name] = None
        except NotApplicable as err:
            result[name] = err.reason
    return result


def run_formulation(
    name: str, kinematics: Kinematics, inputs, rates=None, accelerations=None, branch: str | None = None
) -> ModeResult:
    """A formulation as a :class:`~xcheck.results.ModeResult`: ``ok`` False
    with ``reason`` "not applicable: ..." when it does not apply; one
    trajectory otherwise. Other errors propagate."""
    mech = kinematics.mechanism.name
    try:
        trajectory = formulation(name)(kinematics, inputs, rates, accelerations, branch=branch)
    except NotApplicable as err:
        return ModeResult(name, mech, False, f"not applicable: {err.reason}")
    return ModeResult(name, mech, True, trajectories=[trajectory])
