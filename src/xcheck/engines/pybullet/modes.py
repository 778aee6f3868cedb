"""PyBullet's modes, as the engine contract calls them: ``pybullet-free`` (the
series and one run of :mod:`.free`) and :func:`.dynamic.run_dynamic`
(``pybullet-dynamic``)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once", "run_dynamic"]
