"""The MJX engine's modes: free motion (the series and one run of :mod:`.free`)
and driven dynamics (:mod:`.dynamic`)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once", "run_dynamic"]
