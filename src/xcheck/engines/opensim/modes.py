"""OpenSim's modes, as the engine contract calls them: the free ladder of :mod:`.free`
(``opensim-free``) and :func:`.dynamic.run_dynamic` (``opensim-dynamic``)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_dynamic", "run_free_once"]
