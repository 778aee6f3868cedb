"""Errors that reach the user as one line.

Every check of user input raises :class:`ModelError` (or another
:class:`XcheckError`); the CLI prints ``str(error)`` and exits with code 2.
"""

from __future__ import annotations

__all__ = ["XcheckError", "ModelError", "InputError", "NotApplicable"]


class XcheckError(Exception):
    """Base of the errors that the CLI reports as one line and exit code 2."""


class ModelError(XcheckError, ValueError):
    """A mechanism file that cannot be used.

    Parameters
    ----------
    path : str
        The file, as the user named it.
    field : str
        The dotted field inside the file (``joints[2].bodies``); empty for the
        file as a whole.
    expected, found : str
        What the field should hold and what it holds.
    """

    def __init__(self, path: str, field: str, expected: str, found: str):
        self.path, self.field, self.expected, self.found = str(path), field, expected, found
        where = f"{self.path}: {field}" if field else self.path
        super().__init__(f"{where}: expected {expected}, found {found}")


class InputError(XcheckError, ValueError):
    """A request (input values, a name, an option) that cannot be answered."""


class NotApplicable(Exception):
    """A method (an engine's mode, a formulation, an export format) that does not
    apply to a mechanism: not a failure, a result with its ``reason`` (one line)."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason
