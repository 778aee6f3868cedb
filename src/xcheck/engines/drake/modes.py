"""Drake's modes, as the engine contract calls them: :func:`.free.run_free`
(``drake-free``) and :func:`.dynamic.run_dynamic` (``drake-dynamic``)."""

from __future__ import annotations

from .dynamic import run_dynamic
from .free import run_free

__all__ = ["run_free", "run_dynamic"]
