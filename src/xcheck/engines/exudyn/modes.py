"""Exudyn's modes, as the engine contract calls them: ``exudyn-free`` (the series
and one run of :mod:`.free`) and ``exudyn-dynamic`` (the series and one run of :mod:`.dynamic`), and
:func:`.export.export_files` (the Exudyn script of ``xcheck export``)."""

from __future__ import annotations

from .dynamic import dynamic_series, prepare_dynamic, run_dynamic_once
from .export import export_files
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = [
    "FREE_SERIES",
    "prepare_free",
    "run_free_once",
    "dynamic_series",
    "prepare_dynamic",
    "run_dynamic_once",
    "export_files",
]
