"""Calling xcheck's numba-compiled kernels: each family compiled by one process at a time."""

from __future__ import annotations

from pathlib import Path

from .fileio import directory_lock

__all__ = ["run_compiled"]


def run_compiled(function, *args):
    """``function(*args)`` (a numba dispatcher of xcheck), compiled for the arguments'
    types first, or loaded from numba's cache, by one process at a time per kernel
    family (the package folder its module lives in: the kinematics' kernels, the free
    motion's): processes started together (a test run's workers, a parallel run's)
    wait for the first to compile a family, then load what it cached, rather than each
    compiling the same code again, while kernels of another family compile beside it.
    Anything else (a plain function standing in for a kernel) is called as it is.

    Ctrl-C while compiled code runs reaches the caller as KeyboardInterrupt (the
    dispatcher reports it as a SystemError "returned a result with an exception set")."""
    if not hasattr(function, "overloads"):
        return function(*args)
    types = tuple(function.typeof_pyval(value) for value in args)
    if types not in function.overloads:
        # a family's kernels call one another's, and only one another's: one lock each
        with directory_lock(Path(function.py_func.__code__.co_filename).parent):
            function.compile(types)
    try:
        return function(*args)
    except SystemError as err:
        if isinstance(err.__cause__ or err.__context__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise
