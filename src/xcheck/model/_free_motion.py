"""Free motion in the mechanism file: ``[free_motion]`` (the release) and
``[[springs]]`` (linear spring-dampers between two points).

See docs/mechanism-format.md. Everything is stored in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..joints import JOINT_TYPES, Joint

if TYPE_CHECKING:
    from ..units import Units
    from ._load import _Reader
    from ._mechanism import Body, Driver

__all__ = [
    "Spring",
    "RotationalSpring",
    "FreeMotionSpec",
    "read_springs",
    "read_rotational_springs",
    "read_free_motion",
]


@dataclass(frozen=True)
class Spring:
    """A linear spring and damper between two points.

    Attributes
    ----------
    name : str
    points : tuple of two str
        The labels of its ends.
    stiffness : float, N/m
    rest_length : float, m
    damping : float, N s/m
        The force along the spring is k (l - l0) + c dl/dt (tension positive).
    """

    name: str
    points: tuple[str, str]
    stiffness: float
    rest_length: float
    damping: float = 0.0


@dataclass(frozen=True)
class RotationalSpring:
    """A rotational spring and damper across a revolute or pin-in-slot joint.

    Attributes
    ----------
    name : str
    joint : str
    body_a, body_b : str
        The joint's bodies; the spring's angle is phi_b - phi_a (continuous).
    stiffness : float, N m/rad
    rest_angle : float, rad
    damping : float, N m s/rad
        The torque on ``body_b`` is -k (phi_b - phi_a - rest_angle) - c (omega_b -
        omega_a); ``body_a`` gets its opposite.
    """

    name: str
    joint: str
    body_a: str
    body_b: str
    stiffness: float
    rest_angle: float
    damping: float = 0.0


@dataclass(frozen=True)
class FreeMotionSpec:
    """The release of a mechanism to move freely (its drivers play no part).

    Attributes
    ----------
    duration, output_step : float, s
    at : mapping of str to float
        The drivers' values (rad or m) at which the mechanism is assembled at t = 0.
    rates : mapping of str to float
        Initial rates of drivers' coordinates (rad/s or m/s); the rest of the
        velocity follows from the constraints.
    point : str or None
        With ``point_velocity``: the initial velocity (m/s) of that point instead.
    tolerance : float
        The reference's accuracy, relative to the mechanism's size.
    """

    duration: float
    output_step: float
    at: dict[str, float]
    rates: dict[str, float] = field(default_factory=dict)
    point: str | None = None
    point_velocity: np.ndarray | None = None
    tolerance: float = 1e-9


def read_springs(reader: _Reader, value: Any, bodies: list[Body], units: Units) -> list[Spring]:
    """``[[springs]]``: name, points = [label, label], stiffness (N/m),
    rest_length (length unit), damping (N s/m, default 0)."""
    if not isinstance(value, list):
        reader.fail("springs", "a list of [[springs]]", _describe(value))
    labels = {label for b in bodies for label in b.points}
    springs: list[Spring] = []
    for i, spec in enumerate(value):
        where = f"springs[{i}]"
        spec = reader.table(spec, where, ("name", "points", "stiffness", "rest_length", "damping"))
        ends = spec.get("points")
        if not (isinstance(ends, list) and len(ends) == 2 and all(isinstance(e, str) for e in ends)):
            reader.fail(f"{where}.points", 'two point labels ["A", "B"]', _describe(ends))
        for end in ends:
            if end not in labels:
                reader.fail(
                    f"{where}.points", f"point labels of the mechanism ({', '.join(sorted(labels))})", repr(end)
                )
        if ends[0] == ends[1]:
            reader.fail(f"{where}.points", "two different points", repr(ends))
        stiffness = reader.number(spec.get("stiffness"), f"{where}.stiffness")
        if stiffness < 0.0:
            reader.fail(f"{where}.stiffness", "a stiffness of at least 0 N/m", repr(spec.get("stiffness")))
        rest = reader.number(spec.get("rest_length", 0.0), f"{where}.rest_length", units.length_factor)
        if rest < 0.0:
            reader.fail(f"{where}.rest_length", "a length of at least 0", repr(spec.get("rest_length")))
        damping = reader.number(spec.get("damping", 0.0), f"{where}.damping")
        if damping < 0.0:
            reader.fail(f"{where}.damping", "a damping of at least 0 N s/m", repr(spec.get("damping")))
        name = reader.text(spec.get("name", f"spring {i + 1}"), f"{where}.name")
        if any(s.name == name for s in springs):
            reader.fail(f"{where}.name", "a name no other spring has", repr(name))
        springs.append(Spring(name, (ends[0], ends[1]), stiffness, rest, damping))
    return springs


def pivot_joint(reader: _Reader, value: Any, field: str, joints: list[Joint]) -> Joint:
    """The joint named ``value``, one whose bodies turn about a pivot (a rotational
    spring or a joint torque acts across it); otherwise the reader fails at ``field``."""
    by_name = {j.name: j for j in joints}
    if not isinstance(value, str) or value not in by_name or not by_name[value].pivots:
        kinds = " or ".join(kind for kind, cls in JOINT_TYPES.items() if cls.pivots)
        pivots = [j.name for j in joints if j.pivots]
        why = f" (a {by_name[value].kind} joint does not turn about a pivot)" if value in by_name else ""
        reader.fail(field, f"a {kinds} joint ({', '.join(pivots) or 'none'})", _describe(value) + why)
    return by_name[value]


def read_rotational_springs(reader: _Reader, value: Any, joints: list, units: Units) -> list[RotationalSpring]:
    """``[[rotational_springs]]``: name, joint (a revolute or pin-in-slot joint),
    stiffness (N m/rad), rest_angle (angle unit, default 0), damping (N m s/rad, default 0)."""
    if not isinstance(value, list):
        reader.fail("rotational_springs", "a list of [[rotational_springs]]", _describe(value))
    springs: list[RotationalSpring] = []
    for i, spec in enumerate(value):
        where = f"rotational_springs[{i}]"
        spec = reader.table(spec, where, ("name", "joint", "stiffness", "rest_angle", "damping"))
        j = pivot_joint(reader, spec.get("joint"), f"{where}.joint", joints)
        stiffness = reader.number(spec.get("stiffness"), f"{where}.stiffness")
        if stiffness < 0.0:
            reader.fail(f"{where}.stiffness", "a stiffness of at least 0 N m/rad", repr(spec.get("stiffness")))
        rest = reader.number(spec.get("rest_angle", 0.0), f"{where}.rest_angle", units.angle_factor)
        damping = reader.number(spec.get("damping", 0.0), f"{where}.damping")
        if damping < 0.0:
            reader.fail(f"{where}.damping", "a damping of at least 0 N m s/rad", repr(spec.get("damping")))
        name = reader.text(spec.get("name", f"rotational spring {i + 1}"), f"{where}.name")
        if any(s.name == name for s in springs):
            reader.fail(f"{where}.name", "a name no other rotational spring has", repr(name))
        springs.append(RotationalSpring(name, j.name, j.body_a, j.body_b, stiffness, rest, damping))
    return springs


def read_free_motion(
    reader: _Reader, value: Any, drivers: list[Driver], bodies: list[Body], units: Units, assembly_at: dict[str, float]
) -> FreeMotionSpec:
    """``[free_motion]``: duration (s), output_step (s, default duration / 1000),
    at (drivers' values, display units; default [assembly].at), velocity (drivers'
    rates, display rate units) or point_velocity = { point, value = [vx, vy] }
    (velocity unit), tolerance (default 1e-9)."""
    from ._load import _Reader

    spec = reader.table(
        value, "free_motion", ("duration", "output_step", "at", "velocity", "point_velocity", "tolerance")
    )
    duration = reader.number(spec.get("duration"), "free_motion.duration")
    if duration <= 0.0:
        reader.fail("free_motion.duration", "a duration above 0 s", repr(spec.get("duration")))
    output_step = reader.number(spec.get("output_step", duration / 1000.0), "free_motion.output_step")
    if not 0.0 < output_step <= duration:
        reader.fail(
            "free_motion.output_step",
            f"a step above 0 s and at most the duration ({duration:g} s)",
            repr(spec.get("output_step")),
        )
    if abs(duration / output_step - round(duration / output_step)) > 1e-9 * duration / output_step:
        reader.fail(
            "free_motion.output_step",
            f"a whole fraction of the duration ({duration:g} s)",
            repr(spec.get("output_step")),
        )
    outputs = duration / output_step
    if round(outputs) > MAX_OUTPUTS:
        # whole up to 1e15 outputs (where a float still counts them exactly), then 3 digits
        count = f"{round(outputs)}" if outputs < 1e15 else f"{outputs:.3g}"
        reader.fail(
            "free_motion.output_step",
            f"at most {MAX_OUTPUTS} outputs over the duration",
            f"{count} ({duration:.12g} s / {output_step:.12g} s)",
        )
    by_name = {d.name: d for d in drivers}
    at = dict(assembly_at)
    for key, given in reader.table(spec.get("at", {}), "free_motion.at").items():
        if key not in by_name:
            reader.fail(f"free_motion.at.{key}", f"a driver ({', '.join(by_name)})", repr(key))
        at[key] = reader.number(given, f"free_motion.at.{key}", _Reader.input_scales(by_name[key].quantity, units)[0])
    rates = {}
    for key, given in reader.table(spec.get("velocity", {}), "free_motion.velocity").items():
        if key not in by_name:
            reader.fail(f"free_motion.velocity.{key}", f"a driver ({', '.join(by_name)})", repr(key))
        rates[key] = reader.number(
            given, f"free_motion.velocity.{key}", _Reader.input_scales(by_name[key].quantity, units)[1]
        )
    point, velocity = None, None
    if "point_velocity" in spec:
        if rates:
            reader.fail("free_motion.point_velocity", "either 'velocity' (drivers' rates) or 'point_velocity'", "both")
        pv = reader.table(spec["point_velocity"], "free_motion.point_velocity", ("point", "value"))
        labels = {label for b in bodies for label in b.points}
        point = pv.get("point")
        if not isinstance(point, str) or point not in labels:
            reader.fail("free_motion.point_velocity.point", "a point label of the mechanism", _describe(point))
        velocity = reader.vector(pv.get("value"), "free_motion.point_velocity.value", units.velocity_factor)
    tolerance = reader.number(spec.get("tolerance", 1e-9), "free_motion.tolerance")
    if not 1e-13 <= tolerance <= 1e-2:
        reader.fail("free_motion.tolerance", "a relative accuracy between 1e-13 and 1e-2", repr(spec.get("tolerance")))
    return FreeMotionSpec(duration, output_step, at, rates, point, velocity, tolerance)


#: the most outputs a free motion may ask for (each holds the whole state)
MAX_OUTPUTS = 1_000_000


def _describe(value: Any) -> str:
    from ._load import _describe as describe

    return describe(value)
