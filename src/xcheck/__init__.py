"""xcheck: exact kinematics of planar mechanisms, cross-checked against physics engines."""

__version__ = "0.2.0"

from .errors import InputError, ModelError, XcheckError  # noqa: E402
from .kinematics import Kinematics, Solution, Status  # noqa: E402
from .model import Mechanism, load_mechanism  # noqa: E402

__all__ = ["InputError", "Kinematics", "Mechanism", "ModelError", "Solution", "Status", "XcheckError",
           "__version__", "load_mechanism"]
