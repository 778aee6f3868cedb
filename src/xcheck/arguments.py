"""The rules for the arguments a user gives, each in one place.

The command line and the Python API check the same argument through the same
function here, naming it as the user wrote it (``--samples`` on the command
line, ``samples`` in Python), so that a bad value gets the same one-line
:class:`~xcheck.errors.InputError` (a :class:`ValueError`) wherever it is given,
before any work is done.

>>> from xcheck import arguments
>>> arguments.samples(21)
21
>>> arguments.samples(-5)
Traceback (most recent call last):
...
xcheck.errors.InputError: samples: expected a whole number from 3 to 100000, found -5
"""

from __future__ import annotations

import math
import numbers
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = [
    "MAX_SAMPLES",
    "MIN_SAMPLES",
    "DEFAULT_SAMPLES",
    "MAX_PROCESSES",
    "JOBS_ENV",
    "MAX_STATES",
    "MAX_SEED",
    "whole_number",
    "samples",
    "processes",
    "seed",
    "number",
    "duration",
    "MAX_DURATION",
    "path",
    "text",
    "flag",
    "finite",
    "writable_directory",
    "shown",
]

#: Most samples of a sweep: a sweep's cost grows with them (every engine mode
#: steps through each), and 100000 already resolves a full turn to 0.004 deg.
MAX_SAMPLES = 100_000
#: Samples of a comparison's sweeps where none are asked for: every 2 degrees of a crank's turn
DEFAULT_SAMPLES = 181
#: Fewest samples of a comparison's sweeps (a sweep alone may have 2: its ends)
MIN_SAMPLES = 3
#: Most worker processes a command may start
MAX_PROCESSES = 256
#: Most states one solve at given inputs takes (``xcheck solve --at``, ``solve(at=...)``):
#: each is solved and printed, 10000 in about 6 s; a sweep over more is ``xcheck
#: run --samples`` or ``sweep()``
MAX_STATES = 10_000
#: Largest seed of a campaign: its rows store it as a 64-bit integer
MAX_SEED = 2**63 - 1


def whole_number(value: object, name: str, low: int, high: int) -> int:
    """``value`` as an int, if it is a whole number from ``low`` to ``high``.

    An int, a NumPy integer or a float without a fraction is accepted; a bool,
    a string, NaN or anything else is refused.

    Raises
    ------
    InputError
        ``"{name}: expected a whole number from {low} to {high}, found {value}"``.
    """
    number: int | None = None
    if isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_)):
        number = int(value)
    elif isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        real = float(value)
        if math.isfinite(real) and real == int(real):
            number = int(real)
    if number is None or not low <= number <= high:
        raise InputError(f"{name}: expected a whole number from {low} to {high}, found {shown(value)}")
    return number


def samples(value: object, name: str = "samples", low: int = MIN_SAMPLES) -> int:
    """The samples of a sweep: a whole number from ``low`` to :data:`MAX_SAMPLES`."""
    return whole_number(value, name, low, MAX_SAMPLES)


#: the environment variable that sets the default number of worker processes
JOBS_ENV = "XCHECK_JOBS"


def processes(value: object, name: str = "jobs") -> int:
    """A number of worker processes (1 to :data:`MAX_PROCESSES`); None: ``$XCHECK_JOBS``
    where it is set (a container's or a shared machine's part of the cores, which
    the CPU count does not know), else one per CPU core."""
    if value is None:
        text = os.environ.get(JOBS_ENV, "").strip()
        if not text:
            return os.cpu_count() or 1
        name = f"${JOBS_ENV}"
        try:
            value = int(text)
        except ValueError:
            expected = f"expected a whole number from 1 to {MAX_PROCESSES}"
            raise InputError(f"{name}: {expected}, found {shown(text)}") from None
    return whole_number(value, name, 1, MAX_PROCESSES)


def seed(value: object, name: str = "seed") -> int:
    """A campaign's seed: a whole number from 0 to :data:`MAX_SEED`."""
    return whole_number(value, name, 0, MAX_SEED)


def number(value: object, name: str, low: float = -math.inf, high: float = math.inf, unit: str = "") -> float:
    """``value`` as a float, if it is a finite real number above ``low`` and at most ``high``.

    A bool, a string, a complex number, NaN or anything else is refused.

    Raises
    ------
    InputError
        ``"{name}: expected a finite number above {low} and at most {high}, found {value}"``.
    """
    real = _real(value)
    if not (math.isfinite(real) and low < real <= high):
        unit = f" {unit}" if unit else ""
        bounds = [
            f"above {low:g}{unit}" if low > -math.inf else "",
            f"at most {high:g}{unit}" if high < math.inf else "",
        ]
        raise InputError(
            f"{name}: expected a finite number {' and '.join(b for b in bounds if b)}".rstrip()
            + f", found {shown(value)}"
        )
    return real


#: Longest simulated time of a free motion, s
MAX_DURATION = 1e6


def duration(value: object, name: str = "duration") -> float:
    """A simulated time, s: a finite number above 0 and at most :data:`MAX_DURATION`.

    Raises
    ------
    InputError
        ``"{name}: expected a time above 0 s and at most 1e6 s, found {value}"``.
    """
    real = _real(value)
    if not 0.0 < real <= MAX_DURATION:
        raise InputError(f"{name}: expected a time above 0 s and at most 1e6 s, found {shown(value)}")
    return real


def path(value: object, name: str) -> Path:
    """``value`` as a :class:`~pathlib.Path`, if it is a non-empty ``str`` or ``os.PathLike`` naming one.

    Raises
    ------
    InputError
        ``"{name}: expected a path (str or os.PathLike), found {value}"``.
    """
    text = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    if not isinstance(text, str) or not text or "\0" in text:
        raise InputError(f"{name}: expected a path (str or os.PathLike), found {shown(value)}")
    return Path(text)


def text(value: object, name: str, allowed: Sequence[str] | None = None) -> str:
    """``value`` if it is a string (one of ``allowed`` where given).

    Raises
    ------
    InputError
        ``"{name}: expected a string, found {value}"`` (or one of ``allowed``).
    """
    if not isinstance(value, str) or (allowed is not None and value not in allowed):
        expected = f"one of {', '.join(allowed)}" if allowed is not None else "a string"
        raise InputError(f"{name}: expected {expected}, found {shown(value)}")
    return value


def flag(value: object, name: str) -> bool:
    """``value`` if it is a bool (NumPy's too).

    Raises
    ------
    InputError
        ``"{name}: expected True or False, found {value}"``.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name}: expected True or False, found {shown(value)}")
    return bool(value)


def finite(values: np.ndarray, name: str, given: object = None) -> np.ndarray:
    """``values`` if every one is finite.

    Raises
    ------
    InputError
        ``"{name}: expected finite values, found {given}"`` (``given``: what
        the user wrote, default ``values``).
    """
    if not np.isfinite(values).all():
        raise InputError(f"{name}: expected finite values, found {shown(values if given is None else given)}")
    return values


def writable_directory(path: str | Path, name: str, purpose: str) -> Path:
    """``path`` as a directory that exists (made here if it did not) and can be written.

    Raises
    ------
    InputError
        ``"{name} {path}: expected a directory for {purpose} ..., found ..."``:
        a file, a path through a file, or one this user may not write.
    """
    path = Path(path)
    expected = f"{name} {path}: expected a directory for {purpose}"
    if path.exists() and not path.is_dir():
        raise InputError(f"{expected}, found a file")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{expected}, found that it cannot be made ({err.strerror or err})") from None
    try:  # writing is the one sure test (root may write where os.access says no; a read-only mount refuses)
        fd, probe = tempfile.mkstemp(prefix=".xcheck-probe-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise InputError(f"{expected}, found one that cannot be written ({err.strerror or err})") from None
    return path


def _real(value: object) -> float:
    """``value`` as a float if it is a real number (not a bool), else NaN."""
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        return float(value)
    return math.nan


def shown(value: object, limit: int = 80) -> str:
    """A value as a message shows it: its repr, cut to ``limit`` characters."""
    if isinstance(value, np.ndarray) and value.size > 6:
        text = np.array2string(value, threshold=6, edgeitems=2)
    else:
        text = repr(value.tolist() if isinstance(value, (np.ndarray, np.generic)) else value)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
