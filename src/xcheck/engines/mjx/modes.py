"""The MJX engine's modes: free motion (:mod:`.free`) and driven dynamics (:mod:`.dynamic`)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .free import run_free

__all__ = ["run_dynamic", "run_free"]
