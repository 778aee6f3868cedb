"""xcheck: exact kinematics and dynamics of planar mechanisms, and how far physics engines agree with them.

``import xcheck`` gives the whole public surface:

- :func:`load` a mechanism (a bundled name or a file) and solve, sweep, draw or
  animate it;
- :func:`run` every engine mode against the exact solution (``xcheck run``);
- :func:`simulate` its free motion (``xcheck simulate``);
- :func:`select_modes`, :func:`printed_answers`, and the model and solver types.
"""

__version__ = "0.3.0"

from .errors import InputError, ModelError, XcheckError  # noqa: E402
from .kinematics import Kinematics, Solution, Status  # noqa: E402
from .model import Mechanism, load_mechanism  # noqa: E402

__all__ = [
    "InputError",
    "Kinematics",
    "Mechanism",
    "ModelError",
    "Solution",
    "Status",
    "XcheckError",
    "__version__",
    "load",
    "load_mechanism",
    "printed_answers",
    "run",
    "select_modes",
    "simulate",
]

#: the functions of :mod:`xcheck.api` offered here, imported on first use (they
#: pull in the runner and its libraries, which ``import xcheck`` alone does not need)
_API = ("load", "printed_answers", "run", "select_modes", "simulate")
#: names a newcomer may try, and the one name of the thing they want
_RENAMED = {"compare": "run", "compare_engines": "run"}


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, name)
    if name == "api":
        import importlib

        return importlib.import_module(".api", __name__)
    if name in _RENAMED:
        raise AttributeError(
            f"module 'xcheck' has no attribute {name!r}: xcheck.{_RENAMED[name]}(...) compares the engines "
            "with the exact solution (its .summary is the table, one row per mode)"
        )
    raise AttributeError(f"module 'xcheck' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API, "api"})
