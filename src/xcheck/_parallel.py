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
import multiprocessing.connection
import os
import signal
import threading
import types
from collections.abc import Callable, Hashable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

__all__ = ["process_pool", "picklable_mechanisms", "known_to_workers", "submit", "collect", "WORKER_DIED"]

Key = TypeVar("Key", bound=Hashable)

#: the reason of a mode whose worker process died
WORKER_DIED = (
    "its worker process died before returning (an engine that crashed the process, or a script that starts "
    "workers outside `if __name__ == '__main__':`): run it with jobs=1 (--jobs 1) to see which"
)


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


class Pool(ProcessPoolExecutor):
    """A :class:`~concurrent.futures.ProcessPoolExecutor` that counts its workers
    that started (``started.value``: those that ran the initializer)."""

    def __init__(self, jobs: int, context, broken: dict[str, str]):
        self.started = context.Value("i", 0)
        super().__init__(
            max_workers=jobs, mp_context=context, initializer=_start_worker, initargs=(broken, self.started)
        )


def process_pool(jobs: int) -> Pool:
    """A pool of ``jobs`` spawned worker processes that can send mechanisms and runs both
    ways, and that end with the process that started them."""
    from . import engines

    picklable_mechanisms()
    # a plug-in this process could not load is not tried again in each worker (its import may hang)
    return Pool(jobs, multiprocessing.get_context("spawn"), engines.load_problems())


def _start_worker(broken: dict[str, str] | None = None, started=None) -> None:
    """The pool's initializer: mechanisms picklable, plug-ins the parent could
    not load (``broken``: name -> reason) left alone, Ctrl-C, a watch on the
    parent, and the pool's count of started workers (``started``) raised.

    Ctrl-C reaches the whole foreground process group: the parent ends the run
    (exit code 130), and a worker is ended by the signal's default action, at
    once and silently, instead of printing a KeyboardInterrupt traceback from
    wherever it was. A worker waits for its next task on a pipe whose writing end
    it holds itself, so when the parent is killed (SIGKILL, or a crash) it would
    wait forever, a Python process with NumPy, pandas and xcheck loaded; instead
    it exits. Its BLAS runs on one thread (:func:`_one_blas_thread`)."""
    from .engines._registry import skip_entry_points

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    picklable_mechanisms()
    _one_blas_thread()
    skip_entry_points(broken or {})
    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent.sentinel,), daemon=True).start()
    if started is not None:
        with started.get_lock():
            started.value += 1


#: the limits set in a worker process (kept: they hold while this object does)
_limits = None


def _one_blas_thread() -> None:
    """One BLAS (OpenBLAS, MKL) thread in this worker: the pool has a process per
    core, and BLAS threads on top of them wait for each other on the same cores
    (iftomm-a02-n40's MJCF: 78 CPU s with two threads per process, 4.1 with one)."""
    global _limits
    from threadpoolctl import threadpool_limits

    _limits = threadpool_limits(limits=1, user_api="blas")


def _exit_with(sentinel: int) -> None:
    """Wait until the parent process is gone, then end this one at once."""
    multiprocessing.connection.wait([sentinel])
    os._exit(1)


def known_to_workers(mode: str) -> bool:
    """Whether a spawned worker knows this mode: a built-in or entry-point engine's,
    not one that :func:`xcheck.engines.register` added in this process (nor one
    since unregistered), whose modes must run here."""
    from . import engines

    try:
        engine = engines.engine_of(mode)
    except ValueError:
        return False
    return not engines.registered_at_run_time(engine.name)


def submit(pool: ProcessPoolExecutor, calls: dict[Key, tuple[Callable, tuple]]) -> dict[Future, Key]:
    """Each of ``calls`` (key to a function and its arguments) submitted to
    ``pool``: future to key, for :func:`collect`."""
    return {pool.submit(function, *arguments): key for key, (function, arguments) in calls.items()}


def collect(
    futures: dict[Future, Key],
    failed: Callable,
    done: Callable | None = None,
    calls: dict[Key, tuple[Callable, tuple]] | None = None,
    jobs: int = 1,
) -> dict[Key, Any]:
    """The results of ``futures`` (future to its key: a mode's name, a mechanism's
    index) by key, as they finish; a result that does not come back is
    ``failed(key, reason)`` (a dead worker: :data:`WORKER_DIED`); ``done(key)``
    after each.

    A worker that dies (an engine that crashes its process) takes the whole
    pool with it, and every task still in it: with ``calls`` (as given to
    :func:`submit`), each of those runs again in a worker of its own, ``jobs``
    at once, so that only the task that crashes its process fails."""
    results: dict[Key, Any] = {}
    broken = []
    for future in as_completed(futures):
        key = futures[future]
        if calls is not None and key in calls and isinstance(future.exception(), BrokenProcessPool):
            broken.append(key)
            continue
        results[key] = _result(future, key, failed)
        if done is not None:
            done(key)
    if broken and calls is not None:
        results.update(_each_alone(broken, calls, failed, done, jobs))
    return results


def _result(future: Future, key, failed: Callable):
    """A finished future's result, or ``failed(key, reason)``."""
    try:
        return future.result()
    except BrokenProcessPool:
        return failed(key, WORKER_DIED)
    except Exception as err:  # noqa: BLE001 - a result that could not come back (pickling) is the task's
        return failed(key, f"{type(err).__name__}: {err}".splitlines()[0])


def _each_alone(keys: list, calls: dict, failed: Callable, done: Callable | None, jobs: int) -> dict:
    """Each of ``keys``' calls in a pool of one worker of its own, ``jobs`` at
    once. Where such a worker dies before it started (a script that starts
    workers outside its main guard: every worker dies so), the calls not yet
    started are not tried."""
    results: dict = {}
    pending = list(keys)
    running: dict[Future, tuple[Any, Pool]] = {}
    while pending or running:
        while pending and len(running) < max(1, jobs):
            key = pending.pop(0)
            pool = process_pool(1)
            function, arguments = calls[key]
            running[pool.submit(function, *arguments)] = (key, pool)
        finished, _ = wait(running, return_when=FIRST_COMPLETED)
        for future in finished:
            key, pool = running.pop(future)
            pool.shutdown()
            results[key] = _result(future, key, failed)
            ended = [key]
            if isinstance(future.exception(), BrokenProcessPool) and pool.started.value == 0:
                results.update((other, failed(other, WORKER_DIED)) for other in pending)
                ended += pending
                pending = []
            for each in ended:
                if done is not None:
                    done(each)
    return results
