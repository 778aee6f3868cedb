"""Display units and the numeric expressions allowed in mechanism files.

Everything inside xcheck is SI (m, rad, s, kg). Mechanism files and tables use
the display units named here; conversion happens only at those edges.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable
from dataclasses import dataclass

__all__ = [
    "LENGTH_UNITS",
    "ANGLE_UNITS",
    "ANGULAR_RATE_UNITS",
    "Units",
    "evaluate_expression",
]

#: metres per unit
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
#: radians per unit
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
#: rad/s per unit (angular accelerations use the same unit per second)
ANGULAR_RATE_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "rpm": 2.0 * math.pi / 60.0}
#: m/s per unit, for display of point velocities
VELOCITY_UNITS = {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3}
#: m/s^2 per unit, for display of point accelerations
ACCELERATION_UNITS = {"m/s^2": 1.0, "cm/s^2": 1e-2, "mm/s^2": 1e-3}


@dataclass(frozen=True)
class Units:
    """The units a mechanism file is written in and its tables are shown in.

    Attributes
    ----------
    length, angle, angular_rate, velocity, acceleration : str
        Keys of the tables above. ``velocity`` and ``acceleration`` are for
        display only; in the file, slide rates are in ``length`` per second.
    """

    length: str = "m"
    angle: str = "deg"
    angular_rate: str = "rad/s"
    velocity: str = "m/s"
    acceleration: str = "m/s^2"

    @property
    def length_factor(self) -> float:
        """Metres per display length unit."""
        return LENGTH_UNITS[self.length]

    @property
    def angle_factor(self) -> float:
        """Radians per display angle unit."""
        return ANGLE_UNITS[self.angle]

    @property
    def angular_rate_factor(self) -> float:
        """rad/s per display angular-rate unit."""
        return ANGULAR_RATE_UNITS[self.angular_rate]

    @property
    def velocity_factor(self) -> float:
        return VELOCITY_UNITS[self.velocity]

    @property
    def acceleration_factor(self) -> float:
        return ACCELERATION_UNITS[self.acceleration]

    def show_input(self, quantity: str, value: float, digits: int = 6) -> str:
        """An input's SI value (rad for an "angle", m for a "slide") in display units."""
        if quantity == "angle":
            return f"{value / self.angle_factor:.{digits}g} {self.angle}"
        return f"{value / self.length_factor:.{digits}g} {self.length}"

    @property
    def angular_acceleration(self) -> str:
        """Display name of angular accelerations: the rate unit per second, but
        the angle unit per s^2 for a file whose rates are in rpm ("rpm/s" is no
        unit anyone reads)."""
        return {"rad/s": "rad/s^2", "deg/s": "deg/s^2", "rpm": f"{self.angle}/s^2"}[self.angular_rate]

    @property
    def angular_acceleration_factor(self) -> float:
        """rad/s^2 per display angular-acceleration unit (:attr:`angular_acceleration`)."""
        return self.angle_factor if self.angular_rate == "rpm" else self.angular_rate_factor


_BINARY: dict[type[ast.operator], Callable[[float, float], float]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNARY: dict[type[ast.unaryop], Callable[[float], float]] = {ast.UAdd: operator.pos, ast.USub: operator.neg}
_FUNCTIONS: dict[str, Callable[..., float]] = {
    "sqrt": math.sqrt,
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "asin": math.asin,
    "acos": math.acos,
    "atan": math.atan,
    "atan2": math.atan2,
    "radians": math.radians,
    "degrees": math.degrees,
}
_CONSTANTS = {"pi": math.pi}


def evaluate_expression(text: str) -> float:
    """Evaluate an arithmetic expression such as ``"600/sqrt(2)"``.

    Numbers, ``+ - * / **``, parentheses, ``pi`` and the functions sqrt, sin,
    cos, tan, asin, acos, atan, atan2, radians, degrees (trigonometry in
    radians) are allowed; nothing else is evaluated.

    Raises
    ------
    ValueError
        If the text is not such an expression, or it has no finite value.
    """

    def value(node: ast.AST) -> float:
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return _BINARY[type(node.op)](value(node.left), value(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            return _UNARY[type(node.op)](value(node.operand))
        if isinstance(node, ast.Name) and node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in _FUNCTIONS
            and not node.keywords
        ):
            return float(_FUNCTIONS[node.func.id](*(value(a) for a in node.args)))
        raise ValueError(f"unsupported element {ast.unparse(node)[:40]!r}")

    try:
        result = value(ast.parse(text, mode="eval").body)
    except SyntaxError as err:
        raise ValueError(err.msg) from err  # without the "(<unknown>, line 1)" of str(err)
    except OverflowError as err:
        raise ValueError("the value is too large") from err
    except (RecursionError, MemoryError) as err:
        raise ValueError("the expression is nested too deeply") from err
    except (TypeError, ZeroDivisionError) as err:
        raise ValueError(str(err)) from err
    if isinstance(result, complex):  # e.g. (-1) ** 0.5
        raise ValueError("the value is not a real number")
    if not math.isfinite(result):
        raise ValueError("the value is not finite")
    return result
