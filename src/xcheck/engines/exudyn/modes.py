"""Exudyn's modes, as the engine contract calls them: :func:`.free.run_free`
(``exudyn-free``) and :func:`.dynamic.run_dynamic` (``exudyn-dynamic``), and
:func:`.export.export_files` (the Exudyn script of ``xcheck export``)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .export import export_files
from .free import run_free

__all__ = ["run_free", "run_dynamic", "export_files"]
