"""xcheck._numba.run_compiled: a kernel compiled for its arguments' types, by one
process at a time per kernel family (a lock on the folder of the kernel's module),
then called."""

from __future__ import annotations

import threading
from pathlib import Path

from numba import njit

import xcheck
from xcheck._numba import run_compiled
from xcheck.fileio import directory_lock


def test_a_kernel_is_compiled_once_for_its_arguments_then_called():
    @njit
    def scaled(x, flag):
        return 2.0 * x if flag else x

    assert run_compiled(scaled, 1.5, True) == 3.0
    assert run_compiled(scaled, 2.5, False) == 2.5
    assert len(scaled.overloads) == 1  # the same types: compiled once
    assert run_compiled(lambda x: x + 1, 1) == 2  # a plain function standing in for a kernel


def test_a_kernel_waits_while_another_process_compiles_its_family_only():
    @njit
    def square(x):
        return x * x

    results: list[float] = []
    with directory_lock(Path(xcheck.__file__).parent / "kinematics"):  # another family compiling
        beside = threading.Thread(target=lambda: results.append(run_compiled(square, 2.0)), daemon=True)
        beside.start()
        beside.join(timeout=60)
        assert results == [4.0]  # compiled while the other family's lock is held
    results.clear()
    with directory_lock(Path(__file__).parent):  # as another process compiling this family
        caller = threading.Thread(target=lambda: results.append(run_compiled(square, 3)))
        caller.start()
        caller.join(timeout=0.5)
        assert caller.is_alive() and not results and len(square.overloads) == 1
    caller.join(timeout=60)
    assert results == [9] and len(square.overloads) == 2  # int64 beside float64


class _Dispatcher:
    """A compiled kernel as a dispatcher hands back an exception raised while it ran:
    a SystemError whose cause is that exception."""

    overloads = {(): None}

    def __init__(self, cause: BaseException):
        self.cause = cause

    def __call__(self):
        raise SystemError("CPUDispatcher returned a result with an exception set") from self.cause


def test_ctrl_c_in_a_kernel_is_a_keyboard_interrupt_and_other_errors_stay():
    import pytest

    with pytest.raises(KeyboardInterrupt):
        run_compiled(_Dispatcher(KeyboardInterrupt()))
    with pytest.raises(SystemError, match="exception set"):
        run_compiled(_Dispatcher(ValueError("not an interrupt")))
