"""Newton's modes, as the engine contract calls them: the free ladder of :mod:`.free` (``newton-free``)."""

from __future__ import annotations

from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]
