"""OpenSim's modes, as the engine contract calls them: ``opensim-kinematic`` (:mod:`.kinematic`),
``opensim-free`` (the series and one run of :mod:`.free`) and ``opensim-dynamic`` (the series
and one run of :mod:`.dynamic`)."""

from __future__ import annotations

from .dynamic import dynamic_series, prepare_dynamic, run_dynamic_once
from .free import FREE_SERIES, prepare_free, run_free_once
from .kinematic import run_kinematic

__all__ = [
    "FREE_SERIES",
    "dynamic_series",
    "prepare_dynamic",
    "prepare_free",
    "run_dynamic_once",
    "run_free_once",
    "run_kinematic",
]
