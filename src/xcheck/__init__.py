"""xcheck: exact kinematics of planar mechanisms, cross-checked against physics engines."""

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
    "select_modes",
]

_API = ("load", "printed_answers", "select_modes")


def __getattr__(name: str):
    """The functions of :mod:`xcheck.api`, imported on first use (they pull in
    the runner and its libraries, which ``import xcheck`` alone does not need)."""
    if name in _API:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'xcheck' has no attribute {name!r}")
