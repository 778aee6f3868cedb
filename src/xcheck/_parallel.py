"""Worker processes for ``xcheck run``: mechanisms (``run all --jobs``) or the
modes of one mechanism (``run <name> --jobs``) at once.

Workers are never forked from a process that has loaded an engine: an engine
such as JAX holds threads that a forked child would inherit in an unknown
state. On Linux the ``xcheck`` command forks its workers from itself, when it
first needs them (:func:`start_workers`), where it has loaded no engine and runs no
thread but its own main one and its progress bar's (which stops drawing while a
worker is forked, :data:`terminal_lock`): a worker then starts with Python, NumPy,
pandas and xcheck already imported, in milliseconds. Otherwise the command forks them from a fork
server, a process started for them that imports only those; a program that calls
xcheck (a script, a notebook, the tests) has them started afresh ("spawn"), as its
environment may change between runs and a forked child keeps the one it started
with. Engines registered at run time (:func:`xcheck.engines.register`) exist only
in the process that registered them; those from entry points load in every worker.
"""

from __future__ import annotations

import atexit
import contextlib
import copyreg
import importlib
import logging
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import threading
import types
from collections.abc import Callable, Hashable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, NoReturn, TypeVar

__all__ = [
    "terminal_lock",
    "QUIET_ACROSS_FORKS",
    "process_pool",
    "workers_kept",
    "start_workers",
    "picklable_mechanisms",
    "known_to_workers",
    "submit",
    "collect",
    "run_as_command",
    "import_all",
    "exit_at_once",
    "nothing_left_running",
    "WORKER_DIED",
]

Key = TypeVar("Key", bound=Hashable)

#: held by a thread of this process while it draws on the terminal, and by whichever thread
#: forks a process, across the fork: a worker never starts with the lock of stderr taken by a
#: thread that it does not have (the lock would never be released there)
terminal_lock = threading.Lock()
os.register_at_fork(
    before=terminal_lock.acquire, after_in_parent=terminal_lock.release, after_in_child=terminal_lock.release
)
#: the name of a thread that writes only while it holds :data:`terminal_lock`: one that a
#: worker may be forked beside (a progress bar's)
QUIET_ACROSS_FORKS = "xcheck-progress"

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
    """A :class:`~concurrent.futures.ProcessPoolExecutor` that knows whether a worker
    started (``started.value`` 1: one ran the initializer) and how its workers start
    (``start_method``: "fork", "forkserver" or "spawn"), and that stays open at the end
    of its ``with`` block while it is kept (:func:`workers_kept`)."""

    def __init__(self, jobs: int, context, broken: dict[str, str]):
        # shared memory without a lock: a named semaphore would outlive a process that ends at once
        self.started = context.RawValue("i", 0)
        self.start_method = context.get_start_method()
        self.jobs = jobs
        self.kept = False
        self.closed = False
        super().__init__(
            max_workers=jobs, mp_context=context, initializer=_start_worker, initargs=(broken, self.started)
        )

    def __exit__(self, kind, value, traceback):
        if self.kept and kind is None:
            return False
        return super().__exit__(kind, value, traceback)

    def submit(self, fn, /, *args, **kwargs) -> Future:
        """As :meth:`ProcessPoolExecutor.submit`, a worker it starts starting with SIGINT
        ignored (:func:`_spawning`)."""
        with _spawning():
            return super().submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self.closed = True
        super().shutdown(wait, cancel_futures=cancel_futures)

    def usable(self, jobs: int) -> bool:
        """Whether it is open, none of its workers died, and it has ``jobs`` workers or more."""
        return not self.closed and not getattr(self, "_broken", False) and self.jobs >= jobs


@contextlib.contextmanager
def _spawning() -> Iterator[None]:
    """SIGINT ignored in this process while it starts worker processes (from the main
    thread; elsewhere nothing changes): a worker inherits that, so Ctrl-C while it still
    imports does not print a KeyboardInterrupt traceback from the middle of its imports;
    its initializer (:func:`_start_worker`) gives SIGINT its default action."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


#: the pools :func:`process_pool` keeps for the next call, innermost :func:`workers_kept` last
_kept: list[list[Pool]] = []


@contextlib.contextmanager
def workers_kept() -> Iterator[None]:
    """Within it, the pool :func:`process_pool` starts stays open at the end of its
    ``with`` block and is handed out again to the next call for no more workers,
    their start and imports done (the modes of a run, then its report's figures);
    it is shut down at the end."""
    _kept.append([])
    try:
        yield
    finally:
        for pool in _kept.pop():
            pool.shutdown(cancel_futures=True)


def start_workers(jobs: int, modules: tuple[str, ...] = ("xcheck.runner",), preload: tuple[str, ...] = ()) -> None:
    """Start the kept pool's ``jobs`` workers now (within :func:`workers_kept`): spawned
    ones each import ``modules`` while this process goes on, so that the first tasks
    find them ready. Where workers are forked from this process (:func:`_context`),
    they inherit what it has imported: they are forked now to import ``preload``
    (what some of them will need) while this process goes on, and with no
    ``preload`` when the first task is sent. Where they are forked from a fork
    server, the server is started instead, importing ``modules`` and ``preload``
    once: a worker is then forked from it in milliseconds when its first task comes
    (starting one now would wait here for the server's imports)."""
    if not _kept:
        raise RuntimeError("start_workers: expected to be called within workers_kept()")
    pool = process_pool(jobs, (*modules, *preload))
    if pool.start_method == "fork":
        for _ in range(jobs if preload else 0):
            pool.submit(import_all, preload)
        return
    if pool.start_method == "forkserver":
        from multiprocessing import forkserver

        with _spawning():  # the server, and so every worker it forks, starts with SIGINT ignored
            forkserver.ensure_running()
        return
    for _ in range(jobs):
        pool.submit(import_all, modules)


def import_all(modules: tuple[str, ...]) -> None:
    """Import each of ``modules`` (names), in this process: a worker's warm-up, or
    work to fill a wait."""
    for module in modules:
        importlib.import_module(module)


def process_pool(jobs: int, preload: tuple[str, ...] = ()) -> Pool:
    """A pool of ``jobs`` worker processes (:func:`_context`) that can send mechanisms and
    runs both ways, and that end with the process that started them: the pool kept open
    (:func:`workers_kept`) where it has as many workers or more. ``preload``: modules
    the workers will import, which a fork server, where it is yet to start, imports
    once for all of them."""
    kept = _kept[-1] if _kept else None
    if kept and kept[-1].usable(jobs):
        return kept[-1]
    pool = _new_pool(jobs, preload)
    if kept is not None:
        pool.kept = True
        kept.append(pool)
    return pool


def _new_pool(jobs: int, preload: tuple[str, ...] = ()) -> Pool:
    """A pool of ``jobs`` worker processes of its own (:func:`process_pool`)."""
    from . import engines

    picklable_mechanisms()
    # a plug-in this process could not load is not tried again in each worker (its import may hang)
    problems = engines.load_problems()
    context = _context(("xcheck.runner", *preload))
    if context.get_start_method() == "fork":
        import_all(("xcheck.runner",))  # what every worker needs, imported once, before they are forked
    return Pool(jobs, context, problems)


def _context(modules: tuple[str, ...]):
    """How worker processes start where this process is the ``xcheck`` command on Linux:
    forked from it where that is safe (:func:`_forkable`), else from a fork server that
    imports the command line and ``modules`` when it starts (the first call decides
    them). Anywhere else they are spawned afresh (on macOS a fork of a process that has
    loaded NumPy's BLAS, Accelerate, is not safe to use it)."""
    if not _the_command() or not sys.platform.startswith("linux"):
        return multiprocessing.get_context("spawn")
    if _forkable():
        return multiprocessing.get_context("fork")
    context = multiprocessing.get_context("forkserver")
    # the command line: each child imports the main module (a console script, which the server's
    # own preload of "__main__" leaves out), finding it imported
    context.set_forkserver_preload(list(dict.fromkeys(["xcheck.cli", *modules])))  # no effect once the server runs
    return context


def _forkable() -> bool:
    """Whether a worker may be forked from this process: it has loaded no engine's
    library (:attr:`xcheck.engines.Engine.requires`; some, such as JAX, run threads
    of their own) and runs no Python thread but its main one and those that write
    only under :data:`terminal_lock` (named :data:`QUIET_ACROSS_FORKS`). OpenBLAS's
    threads, which NumPy may have started, are made safe across a fork by OpenBLAS."""
    from . import engines

    if any(package in sys.modules for engine in engines.engines() for package in engine.requires):
        return False
    main = threading.main_thread()
    return all(thread is main or thread.name == QUIET_ACROSS_FORKS for thread in threading.enumerate())


def _start_worker(broken: dict[str, str] | None = None, started=None) -> None:
    """The pool's initializer: mechanisms picklable, plug-ins the parent could
    not load (``broken``: name -> reason) left alone, Ctrl-C, a watch on the
    parent, and the pool's flag of a started worker (``started``) set. It writes
    to its process's own stdout and stderr: a worker forked while a progress bar was
    drawn would otherwise write through the bar's stand-ins for them, redrawing it.

    Ctrl-C reaches the whole foreground process group: the parent ends the run
    (exit code 130), and a worker is ended by the signal's default action, at
    once and silently, instead of printing a KeyboardInterrupt traceback from
    wherever it was. A worker waits for its next task on a pipe whose writing end
    it holds itself, so when the parent is killed (SIGKILL, or a crash) it would
    wait forever, a Python process with NumPy, pandas and xcheck loaded; instead
    it exits. Its BLAS runs on one thread (:func:`_one_blas_thread`). When the
    pool shuts it down, it ends without the interpreter's teardown
    (:func:`exit_at_once`): the pool waits for its workers to end."""
    from .engines._registry import skip_entry_points

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.stdout, sys.stderr = sys.__stdout__ or sys.stdout, sys.__stderr__ or sys.stderr
    picklable_mechanisms()
    _one_blas_thread()
    skip_entry_points(broken or {})
    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent.sentinel,), daemon=True).start()
    if started is not None:
        started.value = 1
    # runs after the exit handlers of what the tasks import (last in, first out), before the rest
    atexit.register(_exit_when_done)


def _exit_when_done() -> None:
    """A worker's end (at exit): :func:`exit_at_once` where nothing of it still runs."""
    if nothing_left_running():
        exit_at_once(0)


def nothing_left_running() -> bool:
    """Whether this process has no child process and no thread but daemons left
    (what :func:`exit_at_once` would otherwise cut short)."""
    threads = [t for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon]
    return not threads and not multiprocessing.active_children()


def run_as_command(app: Callable[[], object]) -> None:
    """Run the command-line ``app``. Where this process is the ``xcheck`` command
    (its script, ``python -m xcheck``), not a program that calls it, it ends at
    once when the command is done and nothing of it still runs (:func:`exit_at_once`)."""
    try:
        app()
    except SystemExit as end:
        if _the_command() and (end.code is None or isinstance(end.code, int)) and nothing_left_running():
            exit_at_once(end.code or 0)
        raise


def _the_command() -> bool:
    """Whether this process is the ``xcheck`` command: its main module is the
    console script or this package's ``__main__``."""
    top = sys.modules.get("__main__")
    spec = getattr(top, "__spec__", None)
    if spec is not None:
        return spec.name == f"{__package__}.__main__"
    return Path(getattr(top, "__file__", None) or "").stem == "xcheck"


def exit_at_once(code: int = 0) -> NoReturn:
    """End this process with exit code ``code``, its output and loggers flushed,
    without the interpreter's teardown: the destructors of every loaded module
    and engine library, which with the engines loaded take longer than many of
    their runs. Only once everything the process writes is written."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing more can reach it
            pass
    logging.shutdown()
    os._exit(code)


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
            pool = _new_pool(1)  # a worker of its own, never a kept one
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
