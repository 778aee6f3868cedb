"""OpenSim's modes, as the engine contract calls them: ``opensim-kinematic`` (:mod:`.kinematic`),
``opensim-free`` (the series and one run of :mod:`.free`) and ``opensim-dynamic`` (the series
and one run of :mod:`.dynamic`)."""

from __future__ import annotations

from .dynamic import dynamic_series, prepare_dynamic, run_dynamic_once
from .free import FREE_SERIES, prepare_free, run_free_once
from .inverse import inverse_forces
from .kinematic import run_kinematic

__all__ = [
    "FREE_SERIES",
    "dynamic_series",
    "prepare_dynamic",
    "inverse_dynamics",
    "prepare_free",
    "run_dynamic_once",
    "run_free_once",
    "run_kinematic",
]


def inverse_dynamics(kinematics, branch: str | None = None, samples: int | None = None, solution=None):
    """Joint reactions and driver efforts from OpenSim at the native states of the simulation
    window (:func:`.inverse.inverse_forces`)."""
    return inverse_forces(kinematics, branch, samples, solution)
