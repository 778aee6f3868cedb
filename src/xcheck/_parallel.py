"""Worker processes for ``xcheck run``: mechanisms (``run all --jobs``) or the
modes of one mechanism (``run <name> --jobs``) at once.

Workers are started afresh ("spawn"): an engine such as JAX holds threads that
a forked child would inherit in an unknown state. Engines registered at run
time (:func:`xcheck.engines.register`) exist only in the process that
registered them; those from entry points load in every worker.
"""

from __future__ import annotations

import copyreg
import multiprocessing
import types
from concurrent.futures import ProcessPoolExecutor

__all__ = ["process_pool", "picklable_mechanisms"]


def picklable_mechanisms() -> None:
    """Let runs and mechanisms travel between processes: a :class:`~xcheck.model.Mechanism`
    keeps mappings as read-only views (``types.MappingProxyType``), which pickle
    does not know; they travel as dicts and come back as views. Called in the
    parent and, as the pool's initializer, in every worker."""
    copyreg.pickle(types.MappingProxyType, _view_as_dict)


def _view_as_dict(view: types.MappingProxyType):
    return _read_only, (dict(view),)


def _read_only(items: dict) -> types.MappingProxyType:
    """A read-only view of ``items`` (how a pickled mapping view comes back)."""
    return types.MappingProxyType(items)


def process_pool(jobs: int) -> ProcessPoolExecutor:
    """A pool of ``jobs`` spawned worker processes that can send mechanisms and runs both ways."""
    picklable_mechanisms()
    context = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=picklable_mechanisms)
