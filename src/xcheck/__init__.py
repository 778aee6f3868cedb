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
    "compare_engines",
    "load",
    "load_mechanism",
    "printed_answers",
    "select_modes",
    "simulate",
]

#: the functions of xcheck.api offered here, by their name here
_API = {
    "load": "load",
    "printed_answers": "printed_answers",
    "select_modes": "select_modes",
    "simulate": "simulate",
    # ``xcheck.results`` is the module of the comparison's arithmetic (imported
    # by the runner): the function that compares engines is offered under this name
    "compare_engines": "compare",
}


def __getattr__(name: str):
    """The functions of :mod:`xcheck.api`, imported on first use (they pull in
    the runner and its libraries, which ``import xcheck`` alone does not need)."""
    if name in _API:
        from . import api

        return getattr(api, _API[name])
    raise AttributeError(f"module 'xcheck' has no attribute {name!r}")
