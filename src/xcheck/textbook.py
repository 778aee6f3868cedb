"""Printed answers of worked solutions, checked against the exact solution.

A comparisons file (``comparisons/NAME.toml``) lists the values that a textbook
prints for mechanism ``NAME``: each with the quantity it means (in the small
vocabulary below), the value exactly as printed (a string, so that its
precision is known), its unit and where it is printed. :func:`check_printed`
compares each with the exact solution of the printed data (the native solver
at the model's instant) and gives one verdict of three:

``agrees``
    within the printed precision: at most half a unit of the last printed digit;
``rounding``
    further off, but within 1 % of the exact value: what rounded
    intermediate values do;
``disagrees``
    more than 1 % off.

Angles are compared modulo a turn (360 deg): the computed angle is taken at
the turn nearest the printed one, and ``turns`` says how many turns that is
from the angle's canonical range ((-180, 180] deg; [0, 360) for interior
angles).

Quantity vocabulary (labels are the model's point labels, NAME its bodies):

=========================================  ==========================================
``point P x|y``                             position of point P
``point P vx|vy|v``                         velocity components and magnitude
``point P ax|ay|a``                         acceleration components and magnitude
``body NAME x|y|angle``                     frame origin and angle phi of a moving body
``body NAME vx|vy|v|omega``                 its velocity and angular velocity
``body NAME ax|ay|a|alpha``                 its acceleration and angular acceleration
``vector P Q length|angle``                 length and angle of the vector from P to Q
``vector P Q length-rate|angle-rate``       their first time derivatives
``vector P Q length-acceleration``          second time derivative of the length
``vector P Q angle-acceleration``           second time derivative of the angle
``interior P Q R``                          angle at P from the ray P->Q counter-clockwise
                                            to the ray P->R, in [0, 360) deg
``dof``                                     degrees of freedom (rank of the constraint
                                            Jacobian at the assembly; unit ``1``)
=========================================  ==========================================

The file format is described in ``comparisons/README.md``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import NoReturn

import numpy as np

from .errors import ModelError
from .kinematics import Kinematics, Status
from .model import Mechanism

__all__ = [
    "AGREES",
    "ROUNDING",
    "DISAGREES",
    "ROUNDING_PERCENT",
    "Printed",
    "Comparisons",
    "load_comparisons",
    "comparisons_of",
    "parse_comparisons",
    "check_printed",
    "quantity_values",
    "verdict",
]

AGREES, ROUNDING, DISAGREES = "agrees", "rounding", "disagrees"
#: Beyond the printed precision but within this relative deviation (percent of
#: the exact value): the size of error that rounded intermediate values cause.
ROUNDING_PERCENT = 1.0

#: SI per unit, by dimension. "s^-1" and "s^-2" are rad/s and rad/s^2 as
#: printed by books that leave the radian out.
_UNITS = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"deg": math.pi / 180.0, "rad": 1.0},
    "velocity": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3},
    "acceleration": {"m/s^2": 1.0, "cm/s^2": 1e-2, "mm/s^2": 1e-3},
    "angular rate": {"rad/s": 1.0, "s^-1": 1.0, "deg/s": math.pi / 180.0, "rpm": math.pi / 30.0},
    "angular acceleration": {"rad/s^2": 1.0, "s^-2": 1.0, "deg/s^2": math.pi / 180.0},
    "count": {"1": 1.0},
}
_POINT = {
    "x": "length",
    "y": "length",
    "vx": "velocity",
    "vy": "velocity",
    "v": "velocity",
    "ax": "acceleration",
    "ay": "acceleration",
    "a": "acceleration",
}
_BODY = {**_POINT, "angle": "angle", "omega": "angular rate", "alpha": "angular acceleration"}
_VECTOR = {
    "length": "length",
    "angle": "angle",
    "length-rate": "velocity",
    "angle-rate": "angular rate",
    "length-acceleration": "acceleration",
    "angle-acceleration": "angular acceleration",
}
_GRAMMAR = (
    "'point P x|y|vx|vy|v|ax|ay|a', 'body NAME x|y|angle|vx|vy|v|omega|ax|ay|a|alpha', "
    "'vector P Q length|angle|length-rate|angle-rate|length-acceleration|angle-acceleration', "
    "'interior P Q R' or 'dof'"
)
#: Raises the ModelError for (field, expected, found).
_Fail = Callable[[str, str, str], NoReturn]
#: a value as printed: sign, digits, optional decimal comma or point and digits
_PRINTED = re.compile(r"-?(\d+([.,]\d*)?|[.,]\d+)")
_TOP_KEYS = ("comparisons", "printed")
_HEAD_KEYS = ("mechanism", "document", "instant", "branch", "notes")
_ENTRY_KEYS = ("quantity", "symbol", "printed", "unit", "where", "note", "instant", "branch")


@dataclass(frozen=True)
class Printed:
    """One printed value.

    Attributes
    ----------
    quantity : str
        A phrase of the vocabulary, e.g. ``"vector B E length"``.
    kind, subject, component : str, tuple of str, str
        The parsed phrase: ``("vector", ("B", "E"), "length")``.
    dimension : str
        Key of the unit table (``"length"``, ``"angle"``, ...).
    text : str
        The value exactly as printed (decimal comma or point).
    value : float
        ``text`` as a number, in ``unit``.
    unit : str
    symbol : str
        The book's name for it (``"r5"``), may be empty.
    source : str
        Document and place (example, equation or table).
    note : str
        Why a value disagrees, or a remark on the convention; may be empty.
    instant, branch : str
        The model's instant label and assembly branch it is compared at.
    field : str
        ``printed[i]``, for messages.
    """

    quantity: str
    kind: str
    subject: tuple[str, ...]
    component: str
    dimension: str
    text: str
    value: float
    unit: str
    symbol: str
    source: str
    note: str
    instant: str
    branch: str
    field: str

    @property
    def scale(self) -> float:
        """SI per unit of this value."""
        return _UNITS[self.dimension][self.unit]


@dataclass(frozen=True)
class Comparisons:
    """The printed values of one worked solution for one mechanism."""

    path: str
    mechanism: str
    document: str
    notes: str
    entries: tuple[Printed, ...]


def comparisons_of(mechanism: Mechanism, comparisons: str | Path | None = None) -> Comparisons | None:
    """A mechanism's comparisons file (``NAME.toml`` in ``comparisons``, else in the
    directory :func:`xcheck.catalog.comparisons_dir` names), read and checked against
    it (:func:`load_comparisons`): its printed answers, not yet computed
    (:func:`check_printed`); None where it has none.

    Raises
    ------
    XcheckError
        If the comparisons file, or ``comparisons``, is bad.
    """
    from . import arguments
    from .catalog import comparisons_dir, comparisons_path

    path = Path(mechanism.path)
    if comparisons is not None:
        comparisons = arguments.path(comparisons, "comparisons")
    found = comparisons_path(path, comparisons_dir(path, comparisons))
    return None if found is None else load_comparisons(found, mechanism)


def load_comparisons(path: str | Path, mechanism: Mechanism) -> Comparisons:
    """Read and check a comparisons file against the mechanism it is for.

    Raises
    ------
    ModelError
        If the file cannot be read or fails a check (unknown quantity, a
        printed value without a unit, an instant or branch the model lacks,
        ...): one line naming the file and the entry.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ModelError(str(path), "", "a readable comparisons file", err.strerror or str(err)) from err
    except UnicodeDecodeError as err:
        raise ModelError(
            str(path), "", "a UTF-8 text file", f"bytes that are not UTF-8 at byte offset {err.start}"
        ) from err
    return parse_comparisons(text, mechanism, str(path))


def parse_comparisons(text: str, mechanism: Mechanism, path: str = "<string>") -> Comparisons:
    """Parse and check the TOML text of a comparisons file (see :func:`load_comparisons`)."""

    def fail(field: str, expected: str, found: str) -> NoReturn:
        raise ModelError(path, field, expected, found)

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        fail("", "valid TOML", f"a syntax error: {err}")
    _check_keys(data, "", _TOP_KEYS, fail)
    head = data.get("comparisons")
    if not isinstance(head, dict):
        fail("comparisons", "a [comparisons] table", "none" if head is None else repr(head))
    _check_keys(head, "comparisons", _HEAD_KEYS, fail)
    name = head.get("mechanism")
    if name != mechanism.name:
        fail("comparisons.mechanism", f"the mechanism's name {mechanism.name!r}", repr(name))
    document = _string(head, "document", "comparisons", fail, required=True)
    notes = _string(head, "notes", "comparisons", fail)
    instants = [inst.label for inst in mechanism.instants]
    branches = list(mechanism.assembly.branches)
    default_instant = head.get("instant", instants[0] if len(instants) == 1 else None)
    if "instant" in head and default_instant not in instants:
        fail(
            "comparisons.instant",
            f"an instant label of the model ({', '.join(map(repr, instants)) or 'none'})",
            repr(default_instant),
        )
    default_branch = head.get("branch", branches[0])
    if default_branch not in branches:
        fail("comparisons.branch", f"a branch of the model ({', '.join(branches)})", repr(default_branch))

    values = data.get("printed")
    if not isinstance(values, list) or not values:
        fail("printed", "a list of [[printed]] values", "none" if values is None else repr(values))
    entries = []
    for i, spec in enumerate(values):
        field = f"printed[{i}]"
        if not isinstance(spec, dict):
            fail(field, "a table", repr(spec))
        _check_keys(spec, field, _ENTRY_KEYS, fail)
        quantity = _string(spec, "quantity", field, fail, required=True)
        kind, subject, component, dimension = _parse_quantity(quantity, mechanism, f"{field}.quantity", fail)
        printed = spec.get("printed")
        if not isinstance(printed, str) or not _PRINTED.fullmatch(printed.strip()):
            fail(f"{field}.printed", 'the value as printed, as a string (e.g. "275,29" or "-3.296")', repr(printed))
        if "unit" not in spec:
            fail(f"{field}.unit", f"the printed value's unit (one of {', '.join(_UNITS[dimension])})", "none")
        unit = spec["unit"]
        if unit not in _UNITS[dimension]:
            fail(f"{field}.unit", f"a unit of {dimension} (one of {', '.join(_UNITS[dimension])})", repr(unit))
        where = _string(spec, "where", field, fail, required=True)
        instant = spec.get("instant", default_instant)
        if kind == "dof":  # a property of the assembly, not of an instant
            instant = instant if instant in instants else ""
        elif instant not in instants:
            fail(
                f"{field}.instant",
                f"an instant label of the model ({', '.join(map(repr, instants)) or 'none'})",
                "none" if instant is None else repr(instant),
            )
        branch = spec.get("branch", default_branch)
        if branch not in branches:
            fail(f"{field}.branch", f"a branch of the model ({', '.join(branches)})", repr(branch))
        printed = printed.strip()
        entries.append(
            Printed(
                quantity=quantity,
                kind=kind,
                subject=subject,
                component=component,
                dimension=dimension,
                text=printed,
                value=float(printed.replace(",", ".")),
                unit=unit,
                symbol=_string(spec, "symbol", field, fail),
                source=f"{document}, {where}",
                note=_string(spec, "note", field, fail),
                instant=instant,
                branch=branch,
                field=field,
            )
        )
    return Comparisons(path, name, document, notes, tuple(entries))


def _check_keys(table: dict, field: str, allowed: tuple[str, ...], fail: _Fail) -> None:
    for key in table:
        if key not in allowed:
            fail(f"{field}.{key}" if field else key, f"one of the keys {', '.join(allowed)}", f"unknown key {key!r}")


def _string(table: dict, key: str, field: str, fail: _Fail, required: bool = False) -> str:
    if key not in table:
        if required:
            fail(f"{field}.{key}", "a non-empty string", "none")
        return ""
    value = table[key]
    if not isinstance(value, str) or (required and not value.strip()):
        fail(f"{field}.{key}", "a non-empty string" if required else "a string", repr(value))
    return value


def _parse_quantity(text: str, mech: Mechanism, field: str, fail: _Fail):
    """(kind, subject, component, dimension) of a vocabulary phrase."""
    words = text.split()
    labels = mech.point_owners
    moving = [b.name for b in mech.moving_bodies]

    def need_point(label: str) -> None:
        if label not in labels:
            fail(field, f"a point of {mech.name} ({', '.join(labels)})", f"{label!r} in {text!r}")

    if words == ["dof"]:
        return "dof", (), "", "count"
    if len(words) == 3 and words[0] == "point":
        need_point(words[1])
        if words[2] in _POINT:
            return "point", (words[1],), words[2], _POINT[words[2]]
    elif len(words) == 3 and words[0] == "body":
        if words[1] not in moving:
            fail(field, f"a moving body of {mech.name} ({', '.join(moving)})", f"{words[1]!r} in {text!r}")
        if words[2] in _BODY:
            return "body", (words[1],), words[2], _BODY[words[2]]
    elif len(words) == 4 and words[0] == "vector":
        need_point(words[1])
        need_point(words[2])
        if words[1] == words[2]:
            fail(field, "a vector between two different points", repr(text))
        if words[3] in _VECTOR:
            return "vector", (words[1], words[2]), words[3], _VECTOR[words[3]]
    elif len(words) == 4 and words[0] == "interior":
        for label in words[1:]:
            need_point(label)
        if len(set(words[1:])) != 3:
            fail(field, "an interior angle at three different points", repr(text))
        return "interior", tuple(words[1:]), "angle", "angle"
    fail(field, f"a quantity {_GRAMMAR}", repr(text))


def verdict(printed: str, computed: float) -> tuple[float | None, float, str]:
    """Deviation of a printed value from the exact one, and the verdict.

    Parameters
    ----------
    printed : str
        The value as printed ("275,29"); its last digit sets the precision.
    computed : float
        The exact value, in the printed value's unit.

    Returns
    -------
    deviation_percent : float or None
        100 (printed - computed) / |computed|; None when computed is 0.
    deviation_digits : float
        (printed - computed) in units of the last printed digit.
    verdict : str
        :data:`AGREES` (|deviation_digits| <= 0.5), else :data:`ROUNDING`
        (|deviation_percent| <= :data:`ROUNDING_PERCENT`), else :data:`DISAGREES`.
    """
    text = Decimal(printed.replace(",", "."))
    # exact decimal arithmetic, so that a value at exactly half a unit is not
    # pushed over the line by the subtraction's round-off
    gap = text - Decimal(computed)
    exponent = text.as_tuple().exponent
    if not isinstance(exponent, int):  # "n", "N" or "F": not a finite number
        raise ValueError(f"printed value {printed!r} is not a finite number")
    digits = float(gap.scaleb(-exponent))
    percent = 100.0 * float(gap) / abs(computed) if computed != 0.0 else None
    if abs(digits) <= 0.5:
        result = AGREES
    elif percent is not None and abs(percent) <= ROUNDING_PERCENT:
        result = ROUNDING
    else:
        result = DISAGREES
    return percent, digits, result


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def quantity_values(solution, entry: Printed) -> np.ndarray:
    """The exact value of an entry's quantity at every sample of a solution.

    Parameters
    ----------
    solution : Solution
        N samples.
    entry : Printed

    Returns
    -------
    ndarray, shape (N,)
        SI units (m, rad, s); angles in their canonical range ((-pi, pi],
        [0, 2 pi) for interior angles).
    """
    kind, subject, component = entry.kind, entry.subject, entry.component
    if kind in ("point", "body"):
        state = solution.point(subject[0]) if kind == "point" else solution.body(subject[0])
        if component == "angle":
            return np.angle(np.exp(1j * state["angle"]))
        if component in ("omega", "alpha"):
            return state[component]
        key = {
            "x": "position",
            "y": "position",
            "vx": "velocity",
            "vy": "velocity",
            "v": "velocity",
            "ax": "acceleration",
            "ay": "acceleration",
            "a": "acceleration",
        }[component]
        vec = state[key]
        if component in ("v", "a"):
            return np.hypot(vec[:, 0], vec[:, 1])
        return vec[:, 0 if component in ("x", "vx", "ax") else 1]
    if kind == "interior":
        at, first, second = (solution.point(label)["position"] for label in subject)
        u, v = first - at, second - at
        return np.mod(np.arctan2(_cross(u, v), np.sum(u * v, axis=1)), 2.0 * math.pi)
    # vector from P to Q: d = L e(theta); derivatives by differentiating d = L e
    p, q = solution.point(subject[0]), solution.point(subject[1])
    d, dd, ddd = (q[key] - p[key] for key in ("position", "velocity", "acceleration"))
    length = np.hypot(d[:, 0], d[:, 1])
    if component == "length":
        return length
    if component == "angle":
        return np.arctan2(d[:, 1], d[:, 0])
    length_rate = np.sum(d * dd, axis=1) / length
    angle_rate = _cross(d, dd) / length**2
    values = {
        "length-rate": length_rate,
        "angle-rate": angle_rate,
        "length-acceleration": np.sum(d * ddd, axis=1) / length + length * angle_rate**2,
        "angle-acceleration": _cross(d, ddd) / length**2 - 2.0 * length_rate * angle_rate / length,
    }
    return values[component]


def check_printed(kinematics: Kinematics, comparisons: Comparisons) -> list[dict]:
    """Compare every printed value with the exact solution of the printed data.

    Each entry is evaluated at its instant (the model's instant: input values
    and rates as printed) on its branch.

    Returns
    -------
    list of dict
        Per entry, in file order: ``quantity``, ``symbol``, ``printed`` (float,
        in ``unit``), ``printed_text``, ``computed`` (float, in ``unit``;
        angles at the turn nearest the printed value), ``unit``,
        ``deviation_percent`` (None when the exact value is 0),
        ``deviation_digits``, ``verdict``, ``turns`` (angles: turns between the
        compared and the canonical angle; else 0), ``note``, ``source``,
        ``instant``, ``branch``.

    Raises
    ------
    ModelError
        If an entry's instant does not assemble with determined velocities.
    """
    mech = kinematics.mechanism
    instants = {inst.label: inst for inst in mech.instants}
    solutions = {}
    results = []
    for entry in comparisons.entries:
        if entry.kind == "dof":
            exact = float(kinematics.mobility(kinematics.assemble(entry.branch))["rank"])
        else:
            key = (entry.instant, entry.branch)
            if key not in solutions:
                state = np.array(instants[entry.instant].states(mech))
                solution = kinematics.solve(
                    state[None, :, 0], state[None, :, 1], state[None, :, 2], branch=entry.branch
                )
                status = Status(int(solution.status[0]))
                if status > Status.NEAR_SINGULAR:
                    raise ModelError(
                        comparisons.path,
                        f"{entry.field}.instant",
                        "an instant where the mechanism assembles with determined velocities",
                        f"{entry.instant!r} on branch {entry.branch}: {status.label}",
                    )
                solutions[key] = solution
            exact = float(quantity_values(solutions[key], entry)[0])
        turns = 0
        if entry.dimension == "angle":
            turns = round((entry.value * entry.scale - exact) / (2.0 * math.pi))
            exact += turns * 2.0 * math.pi
        computed = exact / entry.scale
        percent, digits, result = verdict(entry.text, computed)
        results.append(
            {
                "quantity": entry.quantity,
                "symbol": entry.symbol,
                "printed": entry.value,
                "printed_text": entry.text,
                "computed": computed,
                "unit": entry.unit,
                "deviation_percent": percent,
                "deviation_digits": digits,
                "verdict": result,
                "turns": turns,
                "note": entry.note,
                "source": entry.source,
                "instant": entry.instant,
                "branch": entry.branch,
            }
        )
    return results
