"""Reading and checking mechanism files (TOML).

The file format is documented in ``docs/mechanism-format.md``. Every check
happens here, before any solving; a failed check raises :class:`ModelError`
naming the file, the field, what was expected and what was found.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from .. import arguments
from ..arguments import MAX_STATES
from ..errors import ModelError
from ..fileio import reserved_name
from ..joints import JOINT_TYPES, GearPair
from ..units import (
    ACCELERATION_UNITS,
    ANGLE_UNITS,
    ANGULAR_RATE_UNITS,
    LENGTH_UNITS,
    VELOCITY_UNITS,
    Units,
    evaluate_expression,
)
from ._free_motion import pivot_joint, read_free_motion, read_rotational_springs, read_springs
from ._mechanism import (
    GROUND,
    Assembly,
    Body,
    Driver,
    Instant,
    Joint,
    Load,
    LoadLaw,
    Mechanism,
    MotionLaw,
    PinInSlot,
    Prismatic,
    Revolute,
)

__all__ = ["load_mechanism", "parse_mechanism", "MAX_BODIES", "MAX_FILE_BYTES", "MAX_INSTANTS"]

_TOP_KEYS = (
    "mechanism",
    "units",
    "ground",
    "bodies",
    "joints",
    "drivers",
    "assembly",
    "instants",
    "dynamics",
    "loads",
    "springs",
    "rotational_springs",
    "free_motion",
)
_JOINT_TYPES = tuple(JOINT_TYPES)
#: the keys of a gear pair in [[joints]], and those of the other joint types
_GEAR_KEYS = ("carrier", "radii", "teeth", "mesh", "phase")
_JOINT_KEYS = ("point", "points", "line", "direction", "angle", *_GEAR_KEYS)
#: pitch radii and the centres' distance agree to this share of the distance
_MESH_TOLERANCE = 1e-6
#: tomllib's message: "<what> (at line L, column C)" or "<what> (at end of document)"
_TOML_LOCATION = re.compile(r"(?P<what>.*) \(at (?P<where>line \d+, column \d+|end of document)\)", re.S)


def load_mechanism(path: str | Path) -> Mechanism:
    """Read and check a mechanism file.

    Raises
    ------
    ModelError
        If the file cannot be read, is not valid TOML, or fails a check.
    """
    path = arguments.path(path, "path")
    expected = f"a mechanism file of at most {MAX_FILE_BYTES} bytes"
    try:
        # a FIFO nothing writes to would block open() for ever: opened without
        # waiting, it reads as empty; one being written to reads as it comes
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        if hasattr(os, "set_blocking"):
            os.set_blocking(descriptor, True)
        with os.fdopen(descriptor, "rb") as file:
            size = os.fstat(file.fileno()).st_size
            if size > MAX_FILE_BYTES:  # refused before reading, let alone parsing
                raise ModelError(str(path), "", expected, f"{size} bytes")
            data = file.read(MAX_FILE_BYTES + 1)  # a pipe or device has no size to look at
    except OSError as err:
        raise ModelError(str(path), "", "a readable mechanism file", err.strerror or str(err)) from err
    if len(data) > MAX_FILE_BYTES:
        raise ModelError(str(path), "", expected, f"more than {MAX_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8-sig")  # a BOM, as Windows editors write one, is not content
    except UnicodeDecodeError as err:
        raise ModelError(
            str(path), "", "a UTF-8 text file", f"bytes that are not UTF-8 at byte offset {err.start}"
        ) from err
    # line ends as text mode reads them
    return parse_mechanism(text.replace("\r\n", "\n").replace("\r", "\n"), str(path))


def parse_mechanism(text: str, path: str = "<string>") -> Mechanism:
    """Parse and check the TOML text of a mechanism file (see :func:`load_mechanism`)."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ModelError(path, "", "valid TOML", "tables or arrays nested too deeply to read") from None
    except tomllib.TOMLDecodeError as err:
        # tomllib ends its message with "(at line L, column C)" or "(at end of
        # document)": that location is the field of a syntax error.
        match = _TOML_LOCATION.fullmatch(str(err))
        if match:
            raise ModelError(path, match["where"], "valid TOML", f"a syntax error: {match['what']}") from err
        raise ModelError(path, "", "valid TOML", f"a syntax error: {err}") from err
    return _Reader(path).mechanism(data)


def _describe(value: Any) -> str:
    if value is None:
        return "none"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


#: Largest coordinate (m) and largest driver speed or acceleration at the
#: mechanism's size (SI) that a file may give: squares and products of such
#: values stay far inside float64 (1e308).
MAGNITUDE_LIMIT = 1e100

#: Largest mechanism file (bytes). The largest real mechanism files are a few
#: kB; this leaves room for long notes and thousands of instants, and keeps a
#: stray multi-megabyte file from being parsed at all.
MAX_FILE_BYTES = 1_000_000

#: Most moving bodies a mechanism may have. Real planar mechanisms have tens.
#: Loading is linear in the count, but assembling works with dense matrices of
#: three rows per body and grows faster than its square (measured on a chain of
#: bodies pinned at one point: 200 bodies 4 s, 400 bodies 14 s, 1000 bodies
#: 270 s), so this keeps every mechanism that loads solvable within seconds.
MAX_BODIES = 200

#: Most [[instants]] of a file: as many states as one solve at given inputs takes
MAX_INSTANTS = MAX_STATES

#: What a mechanism's name may be: it becomes a file name (reports/NAME.md, models/mjcf/NAME.xml).
_SAFE_NAME = re.compile(r"[A-Za-z0-9_-](?:[A-Za-z0-9 ._-]{0,98}[A-Za-z0-9._-])?")


class _Unreached(Exception):
    """An instant's value that its driver's motion never reaches: (field, expected, found)."""


class _Reader:
    """Turns the parsed TOML into a :class:`Mechanism`, one checked field at a time."""

    def __init__(self, path: str):
        self.path = path
        #: (body, label) -> the field that gives the point, for messages
        self.point_fields: dict[tuple[str, str], str] = {}

    def fail(self, field: str, expected: str, found: str) -> NoReturn:
        raise ModelError(self.path, field, expected, found)

    # -- primitives -------------------------------------------------------
    def table(self, value: Any, field: str, allowed: tuple[str, ...] | None = None) -> dict:
        if not isinstance(value, dict):
            self.fail(field, "a table", _describe(value))
        if allowed is not None:
            for key in value:
                if key not in allowed:
                    self.fail(
                        f"{field}.{key}" if field else key,
                        f"one of the keys {', '.join(allowed)}",
                        f"unknown key {key!r}",
                    )
        return value

    def text(self, value: Any, field: str) -> str:
        if not isinstance(value, str) or not value.strip():
            self.fail(field, "a non-empty string", _describe(value))
        return value

    def string(self, value: Any, field: str) -> str:
        if not isinstance(value, str):
            self.fail(field, "a string", _describe(value))
        return value

    def choice(self, value: Any, field: str, options) -> str:
        if value not in options:
            self.fail(field, f"one of {', '.join(map(repr, options))}", _describe(value))
        return value

    def number(self, value: Any, field: str, scale: float = 1.0, positive: bool = False) -> float:
        if isinstance(value, bool):
            self.fail(field, "a number", _describe(value))
        if isinstance(value, (int, float)):
            result = float(value)
        elif isinstance(value, str):
            try:
                result = evaluate_expression(value)
            except ValueError as err:
                self.fail(field, "a number or an arithmetic expression", f"{_describe(value)} ({err})")
        else:
            self.fail(field, "a number", _describe(value))
        if not math.isfinite(result):
            self.fail(field, "a finite number", _describe(value))
        if positive and result <= 0.0:
            self.fail(field, "a positive number", _describe(value))
        return result * scale

    def vector(self, value: Any, field: str, scale: float) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 2:
            self.fail(field, "a pair [x, y]", _describe(value))
        return np.array([self.number(v, f"{field}[{i}]", scale) for i, v in enumerate(value)])

    def points(self, value: Any, field: str, scale: float) -> dict[str, np.ndarray]:
        table = self.table(value, field)
        return {label: self.vector(xy, f"{field}.{label}", scale) for label, xy in table.items()}

    # -- sections ---------------------------------------------------------
    def mechanism(self, data: dict) -> Mechanism:
        self.table(data, "", _TOP_KEYS)
        for key, form in (
            ("mechanism", "[mechanism]"),
            ("bodies", "[bodies.NAME]"),
            ("joints", "[[joints]]"),
            ("drivers", "[[drivers]]"),
        ):
            if key not in data:
                self.fail(key, f"a {form} section", "none")
        meta = self.table(data["mechanism"], "mechanism", ("name", "title", "source", "notes"))
        name = self.text(meta.get("name"), "mechanism.name")
        if not _SAFE_NAME.fullmatch(name):
            # the name names the report and the exported files: it must stay a plain file name
            self.fail(
                "mechanism.name",
                "a name of ASCII letters, digits, spaces, '-', '_' and '.', neither starting "
                "with '.' or a space nor ending with a space, at most 100 characters (it names the report "
                "and the exported files)",
                repr(name) if len(name) <= 60 else repr(name[:57]) + "...",
            )
        reserved = reserved_name(name)
        if reserved is not None:
            self.fail("mechanism.name", "a name that names its own report beside the others", f"{name!r}: {reserved}")
        title = self.text(meta.get("title", name), "mechanism.title")
        source = self.string(meta.get("source", ""), "mechanism.source")
        notes = self.string(meta.get("notes", ""), "mechanism.notes")
        units = self.units(data.get("units", {}))
        length = units.length_factor

        bodies = [
            Body(
                GROUND,
                self.points(
                    self.table(data.get("ground", {}), "ground", ("points",)).get("points", {}), "ground.points", length
                ),
            )
        ]
        self.point_fields.update({(GROUND, lbl): f"ground.points.{lbl}" for lbl in bodies[0].points})
        sketches: dict[str, np.ndarray] = {}
        body_specs = self.table(data["bodies"], "bodies")
        if len(body_specs) > MAX_BODIES:
            self.fail("bodies", f"at most {MAX_BODIES} moving bodies", str(len(body_specs)))
        for body_name, spec in body_specs.items():
            body, sketch = self.body(body_name, spec, units)
            bodies.append(body)
            sketches.update(sketch)
        if len(bodies) == 1:
            self.fail("bodies", "at least one moving body", "none")
        by_name = {b.name: b for b in bodies}

        joints = self.joints(data["joints"], by_name, units)
        self.check_shared_labels(bodies, joints)
        self.check_joint_points(bodies, joints)
        drivers = self.drivers(data["drivers"], joints, units)
        self.check_magnitudes(bodies, drivers)
        assembly = self.assembly(data.get("assembly", {}), drivers, by_name, units, sketches)
        instants = self.instants(data.get("instants", []), drivers, units)
        gravity = self.dynamics(data.get("dynamics", {}))
        loads = self.loads(data.get("loads", []), by_name, units, joints)
        springs = read_springs(self, data.get("springs", []), bodies, units)
        rotational_springs = read_rotational_springs(self, data.get("rotational_springs", []), joints, units)
        free_motion = (
            read_free_motion(self, data["free_motion"], drivers, bodies, units, dict(assembly.at))
            if "free_motion" in data
            else None
        )
        return Mechanism(
            name=name,
            title=title,
            source=source,
            notes=notes,
            path=self.path,
            units=units,
            bodies=tuple(bodies),
            joints=tuple(joints),
            drivers=tuple(drivers),
            assembly=assembly,
            instants=tuple(instants),
            gravity=gravity,
            loads=tuple(loads),
            springs=tuple(springs),
            rotational_springs=tuple(rotational_springs),
            free_motion=free_motion,
        )

    def units(self, value: Any) -> Units:
        spec = self.table(value, "units", ("length", "angle", "angular_rate", "velocity", "acceleration"))
        length = self.choice(spec.get("length", "m"), "units.length", tuple(LENGTH_UNITS))
        default_v = f"{length}/s" if f"{length}/s" in VELOCITY_UNITS else "m/s"
        return Units(
            length=length,
            angle=self.choice(spec.get("angle", "deg"), "units.angle", tuple(ANGLE_UNITS)),
            angular_rate=self.choice(
                spec.get("angular_rate", "rad/s"), "units.angular_rate", tuple(ANGULAR_RATE_UNITS)
            ),
            velocity=self.choice(spec.get("velocity", default_v), "units.velocity", tuple(VELOCITY_UNITS)),
            acceleration=self.choice(
                spec.get("acceleration", default_v + "^2"), "units.acceleration", tuple(ACCELERATION_UNITS)
            ),
        )

    def body(self, name: str, value: Any, units: Units) -> tuple[Body, dict[str, np.ndarray]]:
        """One body; also returns the global sketch positions its ``sketch`` form gives."""
        field = f"bodies.{name}"
        if name == GROUND:
            self.fail(field, "a body name other than 'ground' (use the [ground] section)", repr(name))
        spec = self.table(value, field, ("points", "ends", "length", "sketch", "axis", "mass", "com", "inertia"))
        length = units.length_factor
        forms = [k for k in ("ends", "sketch") if k in spec]
        if len(forms) > 1:
            self.fail(field, "one of 'ends' or 'sketch'", "both")
        points: dict[str, np.ndarray] = {}
        sketch: dict[str, np.ndarray] = {}
        if "ends" in spec:
            ends = spec["ends"]
            if not (
                isinstance(ends, list)
                and len(ends) == 2
                and all(isinstance(e, str) for e in ends)
                and ends[0] != ends[1]
            ):
                self.fail(f"{field}.ends", "two different point labels", _describe(ends))
            if "length" not in spec:
                self.fail(f"{field}.length", "the distance between the ends", "none")
            half = 0.5 * self.number(spec["length"], f"{field}.length", length, positive=True)
            points = {ends[0]: np.array([-half, 0.0]), ends[1]: np.array([half, 0.0])}
            self.point_fields.update({(name, lbl): f"{field}.ends" for lbl in ends})
        elif "length" in spec:
            self.fail(f"{field}.length", "'length' only together with 'ends'", "'length' without 'ends'")
        if "sketch" in spec:
            sketch = self.points(spec["sketch"], f"{field}.sketch", length)
            if not sketch:
                self.fail(f"{field}.sketch", "at least one point", "an empty table")
            self.point_fields.update({(name, lbl): f"{field}.sketch.{lbl}" for lbl in sketch})
            origin, angle = next(iter(sketch.values())), 0.0
            if "axis" in spec:
                axis = spec["axis"]
                if not (
                    isinstance(axis, list) and len(axis) == 2 and all(isinstance(a, str) and a in sketch for a in axis)
                ):
                    self.fail(f"{field}.axis", f"two labels of the sketch ({', '.join(sketch)})", _describe(axis))
                origin, tip = sketch[axis[0]], sketch[axis[1]]
                if np.allclose(origin, tip, rtol=0.0, atol=1e-12):
                    self.fail(f"{field}.axis", "two points at different positions", "coincident points")
                angle = math.atan2(*(tip - origin)[::-1])
            c, s = math.cos(angle), math.sin(angle)
            to_local = np.array([[c, s], [-s, c]])
            points = {lbl: to_local @ (xy - origin) for lbl, xy in sketch.items()}
        elif "axis" in spec:
            self.fail(f"{field}.axis", "'axis' only together with 'sketch'", "'axis' without 'sketch'")
        extra = self.points(spec.get("points", {}), f"{field}.points", length)
        for label in extra:
            if label in points:
                self.fail(f"{field}.points.{label}", "a label not already given by 'ends' or 'sketch'", "a duplicate")
        points.update(extra)
        self.point_fields.update({(name, lbl): f"{field}.points.{lbl}" for lbl in extra})
        if not points:
            self.fail(field, "named points ('points', 'ends' or 'sketch')", "none")

        mass = com = inertia = None
        if any(k in spec for k in ("mass", "com", "inertia")):
            mass = self.number(spec.get("mass"), f"{field}.mass", positive=True)
            inertia = self.number(spec.get("inertia"), f"{field}.inertia")
            if inertia < 0.0:  # 0: a point mass (about its centre of mass)
                self.fail(
                    f"{field}.inertia",
                    "a moment of inertia of at least 0 (0 for a point mass)",
                    _describe(spec.get("inertia")),
                )
            com_spec = spec.get("com", [0.0, 0.0])
            if isinstance(com_spec, str):
                if com_spec not in points:
                    self.fail(f"{field}.com", f"a point of {name} ({', '.join(points)}) or [x, y]", repr(com_spec))
                com = points[com_spec]
            else:
                com = self.vector(com_spec, f"{field}.com", length)
        return Body(name, points, mass, com, inertia), sketch

    def joints(self, value: Any, bodies: dict[str, Body], units: Units) -> list:
        if not isinstance(value, list) or not value:
            self.fail("joints", "a list of [[joints]]", _describe(value))
        joints: list = []
        gears = []  # read once the revolutes they turn on are known
        for i, spec in enumerate(value):
            field = f"joints[{i}]"
            spec = self.table(spec, field, ("name", "type", "bodies", *_JOINT_KEYS))
            kind = self.choice(spec.get("type"), f"{field}.type", _JOINT_TYPES)
            pair = spec.get("bodies")
            if not (isinstance(pair, list) and len(pair) == 2):
                self.fail(f"{field}.bodies", "two body names", _describe(pair))
            for k, b in enumerate(pair):
                if not isinstance(b, str) or b not in bodies:
                    self.fail(f"{field}.bodies[{k}]", f"a body ({', '.join(bodies)})", repr(b))
            if pair[0] == pair[1]:
                self.fail(f"{field}.bodies", "two different bodies", f"{pair[0]!r} twice")
            a, b = bodies[pair[0]], bodies[pair[1]]
            if kind != "gear":
                for key in _GEAR_KEYS:
                    if key in spec:
                        self.fail(f"{field}.{key}", f"no {key} on a {kind} joint (it is a gear pair's)", repr(key))
            if kind == "gear":
                gears.append((i, spec, field, a, b))
                joints.append(None)
            elif kind == "revolute":
                joints.append(self.revolute(spec, field, a, b))
            else:
                joints.append(self.line_joint(spec, field, kind, a, b, units))
        for i, spec, field, a, b in gears:
            joints[i] = self.gear(spec, field, a, b, bodies, [j for j in joints if j is not None], units)
        names: set[str] = set()
        for i, joint in enumerate(joints):
            if joint.name in names:
                self.fail(f"joints[{i}].name", "a name no other joint has", repr(joint.name))
            names.add(joint.name)
        return joints

    def point_of(self, label: Any, body: Body, field: str) -> str:
        if not isinstance(label, str) or label not in body.points:
            self.fail(field, f"a point of {body.name} ({', '.join(body.points) or 'none'})", _describe(label))
        return label

    def revolute(self, spec: dict, field: str, a: Body, b: Body) -> Revolute:
        for key in ("line", "direction", "angle"):
            if key in spec:
                self.fail(f"{field}.{key}", "no line for a revolute joint", repr(key))
        if "points" in spec:
            pts = spec["points"]
            if not (isinstance(pts, list) and len(pts) == 2):
                self.fail(f"{field}.points", "two point labels [on first body, on second body]", _describe(pts))
            pa, pb = pts
            pa = self.point_of(pa, a, f"{field}.points[0]")
            pb = self.point_of(pb, b, f"{field}.points[1]")
        else:
            pa = self.point_of(spec.get("point"), a, f"{field}.point")
            pb = self.point_of(spec.get("point"), b, f"{field}.point")
        name = spec.get("name", pa)
        return Revolute(self.text(name, f"{field}.name"), a.name, b.name, pa, pb)

    def line_joint(self, spec: dict, field: str, kind: str, a: Body, b: Body, units: Units):
        if "points" in spec:
            self.fail(f"{field}.points", "'point' (the sliding point on the second body)", "'points'")
        point = self.point_of(spec.get("point"), b, f"{field}.point")
        line = spec.get("line")
        if isinstance(line, list):
            if len(line) != 2 or "direction" in spec:
                self.fail(
                    f"{field}.line", "two points of the first body, or one point with 'direction'", _describe(line)
                )
            p0 = self.point_of(line[0], a, f"{field}.line[0]")
            p1 = self.point_of(line[1], a, f"{field}.line[1]")
            direction = a.points[p1] - a.points[p0]
            if math.hypot(*direction) <= 1e-12:
                self.fail(
                    f"{field}.line",
                    "two points at different positions (a line of non-zero length)",
                    f"{p0} and {p1} coincide",
                )
        else:
            p0 = self.point_of(line, a, f"{field}.line")
            if "direction" not in spec:
                self.fail(f"{field}.direction", "the line's angle in the first body's frame", "none")
            theta = self.number(spec["direction"], f"{field}.direction", units.angle_factor)
            direction = np.array([math.cos(theta), math.sin(theta)])
        name = self.text(spec.get("name", point), f"{field}.name")
        if kind == "prismatic":
            angle = self.number(spec.get("angle", 0.0), f"{field}.angle", units.angle_factor)
            return Prismatic(name, a.name, b.name, p0, direction, point, angle)
        if "angle" in spec:
            self.fail(f"{field}.angle", "no locked angle on a pin-in-slot joint", repr(spec["angle"]))
        return PinInSlot(name, a.name, b.name, p0, direction, point)

    def gear(self, spec: dict, field: str, a: Body, b: Body, bodies: dict[str, Body], joints: list, units: Units):
        """A gear pair: its gears ``a`` and ``b`` each turn on the carrier about a
        revolute joint, whose points are the gears' centres; pitch radii (or tooth
        counts, the radii then following from the centres' distance), mesh, phase."""
        for key in ("point", "points", "line", "direction", "angle"):
            if key in spec:
                self.fail(f"{field}.{key}", "the keys of a gear pair (carrier, radii or teeth, mesh, phase)", repr(key))
        carrier = spec.get("carrier", GROUND)
        if not isinstance(carrier, str) or carrier not in bodies:
            self.fail(f"{field}.carrier", f"a body ({', '.join(bodies)})", _describe(carrier))
        if carrier in (a.name, b.name):
            self.fail(f"{field}.carrier", f"a body other than the gears {a.name} and {b.name}", repr(carrier))
        centres = []  # per gear: (its pin's name, its centre's label, the centre's label on the carrier)
        for gear in (a, b):
            pins = [j for j in joints if isinstance(j, Revolute) and {j.body_a, j.body_b} == {gear.name, carrier}]
            if not pins:
                self.fail(
                    f"{field}.carrier",
                    f"the body gear {gear.name} turns on about a revolute joint at its centre",
                    f"{carrier!r}, with no revolute joint between {gear.name} and {carrier}",
                )
            pin = pins[0]
            ends = (pin.point_a, pin.point_b) if pin.body_a == gear.name else (pin.point_b, pin.point_a)
            centres.append((pin.name, *ends))
        on_carrier = bodies[carrier].points
        distance = float(np.hypot(*(on_carrier[centres[1][2]] - on_carrier[centres[0][2]])))
        if distance <= 1e-12:
            self.fail(f"{field}.bodies", "gears whose centres are apart", f"both centred at {centres[0][2]}")
        mesh = self.choice(spec.get("mesh", "external"), f"{field}.mesh", ("external", "internal"))
        sign = 1.0 if mesh == "external" else -1.0
        if ("radii" in spec) == ("teeth" in spec):
            self.fail(
                f"{field}.radii",
                "either radii (the pitch radii) or teeth (tooth counts)",
                "both" if "radii" in spec else "neither",
            )

        def shown(length: float) -> str:
            return units.show_input("slide", length, digits=10)

        if "teeth" in spec:
            teeth = [
                self.number(z, f"{field}.teeth[{k}]", positive=True)
                for k, z in enumerate(self.pair(spec["teeth"], f"{field}.teeth"))
            ]
            if mesh == "internal" and teeth[0] == teeth[1]:
                self.fail(
                    f"{field}.teeth",
                    "two different tooth counts for an internal mesh (a pinion in a ring)",
                    f"{teeth[0]:g} twice",
                )
            radii = [distance * z / abs(teeth[0] + sign * teeth[1]) for z in teeth]
        else:
            radii = [
                self.number(r, f"{field}.radii[{k}]", units.length_factor, positive=True)
                for k, r in enumerate(self.pair(spec["radii"], f"{field}.radii"))
            ]
            reach = abs(radii[0] + sign * radii[1])
            if abs(reach - distance) > _MESH_TOLERANCE * distance:
                how = "sum" if mesh == "external" else "difference"
                self.fail(
                    f"{field}.radii",
                    f"pitch radii whose {how} is the distance of the centres {centres[0][2]} and {centres[1][2]} "
                    f"on {carrier}, {shown(distance)} ({mesh} mesh)",
                    f"{shown(radii[0])} and {shown(radii[1])}",
                )
        phase = self.number(spec.get("phase", 0.0), f"{field}.phase", units.angle_factor)
        name = self.text(spec.get("name", f"{a.name}-{b.name}"), f"{field}.name")
        (pin_a, centre_a, _), (pin_b, centre_b, _) = centres
        return GearPair(
            name,
            a.name,
            b.name,
            carrier,
            pin_a,
            pin_b,
            centre_a,
            centre_b,
            radii[0],
            radii[1],
            phase,
            mesh == "internal",
        )

    def pair(self, value: Any, field: str) -> list:
        if not (isinstance(value, list) and len(value) == 2):
            self.fail(field, "two values [first gear, second gear]", _describe(value))
        return value

    def check_shared_labels(self, bodies: list[Body], joints: list) -> None:
        """A label on two bodies must be a revolute joining them at that label
        (directly or through other bodies pinned at the same label).

        Linear in the number of bodies and joints: one union-find per label.
        """
        owners: dict[str, list[str]] = {}
        for b in bodies:
            for label in b.points:
                owners.setdefault(label, []).append(b.name)
        groups = {label: _UnionFind() for label, names in owners.items() if len(names) > 1}
        for j in joints:
            label = j.shared_label()
            if label in groups:
                groups[label].union(j.body_a, j.body_b)
        for label, group in groups.items():
            first, *others = owners[label]
            root = group.find(first)
            # the first body not linked to the first owner: the same pair a pairwise check finds first
            second = next((name for name in others if group.find(name) != root), None)
            if second is not None:
                self.fail(
                    "joints",
                    f"a revolute joint at {label!r} between {first} and {second} (they share the label)",
                    "none: rename one of the points",
                )

    def check_joint_points(self, bodies: list[Body], joints: list) -> None:
        """Two different joint points of one body must not coincide: that is a
        link of zero length (one place of a body takes one label).

        Linear in the number of joint points: each point is compared only with
        the points in its own and the neighbouring cells of a grid about as
        fine as the tolerance.
        """
        used: dict[str, dict[str, None]] = {b.name: {} for b in bodies}  # ordered sets
        for j in joints:
            for body, label in j.anchors():
                used[body][label] = None
        for b in bodies:
            labels = list(used[b.name])
            cells: dict[tuple, list[int]] = {}
            for k, label in enumerate(labels):
                cells.setdefault(_cell(b.points[label]), []).append(k)
            for i, first in enumerate(labels):
                cx, cy = _cell(b.points[first])
                near = sorted(
                    k for dx in (-1, 0, 1) for dy in (-1, 0, 1) for k in cells.get((cx + dx, cy + dy), ()) if k > i
                )
                for k in near:
                    second = labels[k]
                    if np.all(np.abs(b.points[first] - b.points[second]) <= _COINCIDENT):
                        self.fail(
                            self.point_fields.get((b.name, second), f"bodies.{b.name}"),
                            f"joint point {second!r} of {b.name} apart from its joint point {first!r} "
                            "(a link of non-zero length; for one place use one label)",
                            f"{first} and {second} coincide",
                        )

    def drivers(self, value: Any, joints: list, units: Units) -> list[Driver]:
        if not isinstance(value, list) or not value:
            self.fail("drivers", "a list of [[drivers]]", _describe(value))
        by_name = {j.name: j for j in joints}
        drivers: list[Driver] = []
        driven: set[str] = set()
        names: set[str] = set()
        for i, spec in enumerate(value):
            field = f"drivers[{i}]"
            spec = self.table(
                spec,
                field,
                (
                    "name",
                    "joint",
                    "motion",
                    "start",
                    "rate",
                    "acceleration",
                    "centre",
                    "amplitude",
                    "frequency",
                    "phase",
                ),
            )
            joint_name = spec.get("joint")
            if not isinstance(joint_name, str) or joint_name not in by_name:
                self.fail(f"{field}.joint", f"a joint ({', '.join(by_name)})", _describe(joint_name))
            if joint_name in driven:
                self.fail(f"{field}.joint", "a joint no other driver drives", repr(joint_name))
            driven.add(joint_name)
            joint = by_name[joint_name]
            quantity = joint.driven_quantity
            if quantity is None:
                drivable = [j.name for j in joints if j.driven_quantity is not None]
                self.fail(
                    f"{field}.joint",
                    f"a joint that can be driven ({', '.join(drivable) or 'none'})",
                    f"{joint_name!r}, a {joint.kind} joint",
                )
            q_scale, rate_scale = self.input_scales(quantity, units)
            kind = self.choice(spec.get("motion", "constant-rate"), f"{field}.motion", MotionLaw.KINDS)
            allowed = {
                "constant-rate": ("start", "rate"),
                "constant-acceleration": ("start", "rate", "acceleration"),
                "harmonic": ("centre", "amplitude", "frequency", "phase"),
            }[kind]
            for key in ("start", "rate", "acceleration", "centre", "amplitude", "frequency", "phase"):
                if key in spec and key not in allowed:
                    self.fail(f"{field}.{key}", f"only {', '.join(allowed)} for motion {kind!r}", repr(key))

            def get(key, scale, default=0.0, spec=spec, field=field):
                return self.number(spec.get(key, default), f"{field}.{key}", scale)

            if kind == "harmonic":
                law = MotionLaw(
                    kind,
                    centre=get("centre", q_scale),
                    amplitude=get("amplitude", q_scale),
                    frequency=self.number(spec.get("frequency"), f"{field}.frequency", positive=True),
                    phase=get("phase", units.angle_factor),
                    turns=quantity == "angle",
                )
            else:
                law = MotionLaw(
                    kind,
                    start=get("start", q_scale),
                    rate=get("rate", rate_scale),
                    acceleration=get("acceleration", rate_scale),
                    turns=quantity == "angle",
                )
            name = self.text(spec.get("name", joint_name), f"{field}.name")
            if name in names:
                self.fail(f"{field}.name", "a name no other driver has", repr(name))
            names.add(name)
            drivers.append(Driver(name, joint_name, quantity, law))
        return drivers

    def check_magnitudes(self, bodies: list[Body], drivers: list[Driver]) -> None:
        """Refuse sizes and motions whose products overflow float64.

        The kinematics squares velocities (omega^2 r) and the dynamics
        multiplies masses by accelerations; every coordinate and every driver's
        speed and acceleration at the mechanism's size must stay within
        :data:`MAGNITUDE_LIMIT` so that no product overflows into an
        infinity that would pass as "not determined".
        """
        for body in bodies:
            for label, xy in body.points.items():
                if not np.all(np.abs(xy) <= MAGNITUDE_LIMIT):
                    self.fail(
                        self.point_fields.get((body.name, label), f"bodies.{body.name}.points.{label}"),
                        f"coordinates within {MAGNITUDE_LIMIT:g} m",
                        f"{xy.tolist()} m",
                    )
        size = max((float(np.max(np.abs(xy))) for body in bodies for xy in body.points.values()), default=1.0)
        size = max(size, 1e-300)
        for i, driver in enumerate(drivers):
            law = driver.law
            per = size if driver.quantity == "angle" else 1.0  # an angle's rates move points by size x rate
            if law.kind == "harmonic":
                w = 2.0 * math.pi * law.frequency
                keys = {"amplitude": abs(law.amplitude) * max(w, w * w, 1.0), "centre": abs(law.centre)}
            else:
                keys = {"start": abs(law.start), "rate": abs(law.rate), "acceleration": abs(law.acceleration)}
            for key, value in keys.items():
                scaled = value * (per if key != "start" and key != "centre" else 1.0)
                if not (math.isfinite(scaled) and scaled <= MAGNITUDE_LIMIT):
                    self.fail(
                        f"drivers[{i}].{key}",
                        f"a motion whose speeds and accelerations at the "
                        f"mechanism's size stay within {MAGNITUDE_LIMIT:g} (SI), so that their products "
                        "cannot overflow",
                        f"{value:g} (SI)",
                    )

    @staticmethod
    def input_scales(quantity: str, units: Units) -> tuple[float, float]:
        """SI per display unit of an input's value and of its rate (per s)."""
        if quantity == "angle":
            return units.angle_factor, units.angular_rate_factor
        return units.length_factor, units.length_factor

    def assembly(
        self,
        value: Any,
        drivers: list[Driver],
        bodies: dict[str, Body],
        units: Units,
        body_sketches: dict[str, np.ndarray],
    ) -> Assembly:
        spec = self.table(value, "assembly", ("at", "branches"))
        at_spec = self.table(spec.get("at", {}), "assembly.at")
        at = {}
        for d in drivers:
            if d.name in at_spec:
                at[d.name] = self.number(
                    at_spec[d.name], f"assembly.at.{d.name}", self.input_scales(d.quantity, units)[0]
                )
            else:
                at[d.name] = float(d.law.at_time(0.0)[0])
        for key in at_spec:
            if key not in at:
                self.fail(f"assembly.at.{key}", f"a driver ({', '.join(at)})", repr(key))
        labels = {lbl for b in bodies.values() for lbl in b.points}
        branches = {}
        for branch, sketch in self.table(spec.get("branches", {}), "assembly.branches").items():
            points = self.points(sketch, f"assembly.branches.{branch}", units.length_factor)
            for label in points:
                if label not in labels:
                    self.fail(f"assembly.branches.{branch}.{label}", "a point label of the mechanism", repr(label))
            branches[branch] = {**body_sketches, **points}
        if not branches:
            branches["default"] = dict(body_sketches)
        return Assembly(at, branches)

    def instants(self, value: Any, drivers: list[Driver], units: Units) -> list[Instant]:
        if not isinstance(value, list):
            self.fail("instants", "a list of [[instants]]", _describe(value))
        if len(value) > MAX_INSTANTS:
            self.fail("instants", f"at most {MAX_INSTANTS} [[instants]]", str(len(value)))
        instants = []
        for i, spec in enumerate(value):
            field = f"instants[{i}]"
            spec = self.table(spec, field)
            label = self.text(spec.get("label", f"instant {i + 1}"), f"{field}.label")
            for key in spec:
                if key != "label" and key not in {d.name for d in drivers}:
                    self.fail(
                        f"{field}.{key}", f"'label' or a driver ({', '.join(d.name for d in drivers)})", repr(key)
                    )
            inputs, problem = {}, None
            for d in drivers:
                if d.name not in spec:
                    self.fail(f"{field}.{d.name}", f"the value of driver {d.name!r}", "none")
                try:
                    inputs[d.name] = self.instant_input(spec[d.name], f"{field}.{d.name}", d, units)
                except _Unreached as unreached:  # raised when the instant is used, not at load
                    problem = problem or unreached.args
                    inputs[d.name] = (math.nan, math.nan, math.nan)
            instants.append(Instant(label, inputs, problem))
        return instants

    def instant_input(self, value: Any, field: str, driver: Driver, units: Units):
        q_scale, rate_scale = self.input_scales(driver.quantity, units)
        if isinstance(value, dict):
            self.table(value, field, ("q", "qd", "qdd"))
            if "q" not in value:
                self.fail(f"{field}.q", "the input value", "none")
            q = self.number(value["q"], f"{field}.q", q_scale)
            if "qd" in value or "qdd" in value:
                return (
                    q,
                    self.number(value.get("qd", 0.0), f"{field}.qd", rate_scale),
                    self.number(value.get("qdd", 0.0), f"{field}.qdd", rate_scale),
                )
        else:
            q = self.number(value, field, q_scale)
        try:
            state = driver.law.state_at(q)
        except OverflowError:  # absurd rates or accelerations
            state = (math.inf, math.inf, math.inf)
        if state is None:
            raise _Unreached(
                field,
                f"a value that the motion of driver {driver.name!r} reaches, or explicit qd/qdd",
                _describe(value),
            )
        if not all(math.isfinite(v) for v in state):
            raise _Unreached(
                field,
                f"a value at which the motion of driver {driver.name!r} has a finite rate "
                "and acceleration, or explicit qd/qdd",
                f"{_describe(value)} (the motion law overflows)",
            )
        return state

    def dynamics(self, value: Any) -> np.ndarray:
        """Gravity (m/s^2, global frame, SI whatever [units] says); zero if not given."""
        spec = self.table(value, "dynamics", ("gravity",))
        return self.vector(spec.get("gravity", [0.0, 0.0]), "dynamics.gravity", 1.0)

    def loads(self, value: Any, bodies: dict[str, Body], units: Units, joints: list[Joint]) -> list[Load]:
        """Constant loads: a force (N, global frame) at a point of a moving body
        (a label, or [x, y] in the body frame in the length unit) and/or a torque (N m);
        or a torque across a revolute or pin-in-slot joint (an actuator between its
        bodies: the torque on its second body, the opposite on its first)."""
        if not isinstance(value, list):
            self.fail("loads", "a list of [[loads]]", _describe(value))
        loads: list[Load] = []
        names: set[str] = set()
        moving = [name for name in bodies if name != GROUND]
        for i, spec in enumerate(value):
            field = f"loads[{i}]"
            spec = self.table(spec, field, ("name", "body", "joint", "point", "force", "torque", "law"))
            law = self.load_law(spec["law"], f"{field}.law", units) if "law" in spec else None
            if "joint" in spec:
                for pair in self.joint_torque(spec, field, joints, i, law):
                    if pair.name in names:
                        self.fail(f"{field}.name", "a name no other load has", repr(pair.name))
                    names.add(pair.name)
                    loads.append(pair)
                continue
            body_name = spec.get("body")
            if not isinstance(body_name, str) or body_name not in bodies or body_name == GROUND:
                self.fail(f"{field}.body", f"a moving body ({', '.join(moving)})", _describe(body_name))
            body = bodies[body_name]
            if "force" not in spec and "torque" not in spec:
                self.fail(field, "a 'force' [Fx, Fy] (N), a 'torque' (N m), or both", "neither")
            force = self.vector(spec.get("force", [0.0, 0.0]), f"{field}.force", 1.0)
            torque = self.number(spec.get("torque", 0.0), f"{field}.torque")
            label, point = None, np.zeros(2)
            if "force" in spec:
                where = spec.get("point")
                if where is None:
                    self.fail(
                        f"{field}.point",
                        f"where the force acts: a point of {body_name} "
                        f"({', '.join(body.points)}) or [x, y] in its frame",
                        "none",
                    )
                if isinstance(where, str):
                    label = self.point_of(where, body, f"{field}.point")
                    point = body.points[label]
                else:
                    point = self.vector(where, f"{field}.point", units.length_factor)
            elif "point" in spec:
                self.fail(
                    f"{field}.point",
                    "a point only with a 'force' (a torque acts on the whole body)",
                    _describe(spec["point"]),
                )
            name = self.text(spec.get("name", f"load {i + 1}"), f"{field}.name")
            if name in names:
                self.fail(f"{field}.name", "a name no other load has", repr(name))
            names.add(name)
            loads.append(Load(name, body_name, point, force, torque, label, law))
        return loads

    def load_law(self, value: Any, field: str, units: Units) -> LoadLaw:
        """``law = { kind = "harmonic", frequency (Hz), phase (angle unit, default 0), offset
        (default 0) }`` or ``{ kind = "ramp", duration (s) }``: the load times s(t)."""
        spec = self.table(value, field, ("kind", "frequency", "phase", "offset", "duration"))
        kind = self.choice(spec.get("kind"), f"{field}.kind", ("harmonic", "ramp"))
        allowed = ("kind", "frequency", "phase", "offset") if kind == "harmonic" else ("kind", "duration")
        extra = [key for key in spec if key not in allowed]
        if extra:
            self.fail(f"{field}.{extra[0]}", f"only {', '.join(allowed[1:])} in a {kind} law", repr(extra[0]))
        if kind == "ramp":
            duration = self.number(spec.get("duration"), f"{field}.duration")
            if not duration > 0.0:
                self.fail(f"{field}.duration", "a ramp duration above 0 s", repr(spec.get("duration")))
            return LoadLaw("ramp", duration=duration)
        frequency = self.number(spec.get("frequency"), f"{field}.frequency")
        if frequency < 0.0:
            self.fail(f"{field}.frequency", "a frequency of at least 0 Hz", repr(spec.get("frequency")))
        phase = self.number(spec.get("phase", 0.0), f"{field}.phase", units.angle_factor)
        offset = self.number(spec.get("offset", 0.0), f"{field}.offset")
        return LoadLaw("harmonic", frequency=frequency, phase=phase, offset=offset)

    def joint_torque(self, spec: dict, field: str, joints: list[Joint], i: int, law: LoadLaw | None) -> list[Load]:
        """A ``[[loads]]`` entry with ``joint``: the torque on the joint's second body and
        its opposite (named "NAME (reaction)") on the first, each where it is a moving body."""
        extra = [key for key in ("body", "point", "force") if key in spec]
        if extra:
            self.fail(
                f"{field}.{extra[0]}",
                "only a 'torque' with 'joint' (an actuator between the joint's bodies)",
                f"'{extra[0]}' as well",
            )
        joint = pivot_joint(self, spec.get("joint"), f"{field}.joint", joints)
        if "torque" not in spec:
            self.fail(f"{field}.torque", "a torque (N m) across the joint", "none")
        torque = self.number(spec["torque"], f"{field}.torque")
        name = self.text(spec.get("name", f"load {i + 1}"), f"{field}.name")
        pairs = [(joint.body_b, name, torque), (joint.body_a, f"{name} (reaction)", -torque)]
        zero = np.zeros(2)
        return [Load(label, body, zero, zero, value, None, law) for body, label, value in pairs if body != GROUND]


class _UnionFind:
    """Disjoint sets of names, with path halving."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}

    def find(self, name: str) -> str:
        parent = self.parent
        parent.setdefault(name, name)
        while parent[name] != name:
            parent[name] = parent[parent[name]]
            name = parent[name]
        return name

    def union(self, a: str, b: str) -> None:
        self.parent[self.find(a)] = self.find(b)


#: Two joint points of one body closer than this in both coordinates (m) coincide.
_COINCIDENT = 1e-12


def _cell(xy: np.ndarray) -> tuple:
    """The grid cell (of side twice :data:`_COINCIDENT`, so that coincident
    points lie in the same or neighbouring cells) of a point; far from the
    origin, where floats are coarser than a cell, the coordinates themselves."""
    cell = []
    for v in xy:
        q = float(v) / (2 * _COINCIDENT)
        cell.append(math.floor(q) if math.isfinite(q) else float(v))
    return tuple(cell)
