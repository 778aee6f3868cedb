"""Exudyn's modes, as the engine contract calls them: ``exudyn-free`` (the series
and one run of :mod:`.free`) and :func:`.dynamic.run_dynamic` (``exudyn-dynamic``), and
:func:`.export.export_files` (the Exudyn script of ``xcheck export``)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .export import export_files
from .free import FREE_SERIES, prepare_free, run_free_once

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once", "run_dynamic", "export_files"]
