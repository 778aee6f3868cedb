"""PyBullet's modes, as the engine contract calls them: ``pybullet-free`` (the
series and one run of :mod:`.free`) and ``pybullet-dynamic`` (the series and one
run of :mod:`.dynamic`)."""

from __future__ import annotations

from .dynamic import dynamic_series, prepare_dynamic, run_dynamic_once
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]
