"""The canonical mechanism model: an immutable description, SI units inside.

Solvers and engine adapters read from it; nothing converts back into it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..errors import ModelError
from ..joints import Joint, PinInSlot, Prismatic, Revolute
from ..units import Units
from ._free_motion import FreeMotionSpec, RotationalSpring, Spring

__all__ = [
    "GROUND",
    "Body",
    "Revolute",
    "Prismatic",
    "PinInSlot",
    "Joint",
    "MotionLaw",
    "Driver",
    "Instant",
    "Assembly",
    "Load",
    "LoadLaw",
    "LOAD_LAWS",
    "Mechanism",
]

#: Name of the fixed body. Its frame is the global frame.
GROUND = "ground"


def _frozen_points(points: Mapping[str, np.ndarray]) -> Mapping[str, np.ndarray]:
    frozen = {}
    for label, xy in points.items():
        arr = np.array(xy, dtype=float).reshape(2)
        arr.flags.writeable = False
        frozen[label] = arr
    return MappingProxyType(frozen)


@dataclass(frozen=True)
class Body:
    """A rigid body with named points.

    Attributes
    ----------
    name : str
    points : mapping of str to ndarray, shape (2,), m
        Named points in the body frame.
    mass : float or None, kg
    com : ndarray, shape (2,), m, or None
        Centre of mass in the body frame.
    inertia : float or None, kg m^2
        Moment of inertia about the centre of mass.
    """

    name: str
    points: Mapping[str, np.ndarray]
    mass: float | None = None
    com: np.ndarray | None = None
    inertia: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "points", _frozen_points(self.points))


@dataclass(frozen=True)
class MotionLaw:
    """An input as a function of time, SI units (rad or m, per s, per s^2).

    ``constant-rate``: q = start + rate t; ``constant-acceleration``:
    q = start + rate t + acceleration t^2 / 2; ``harmonic``:
    q = centre + amplitude sin(2 pi frequency t + phase).

    ``turns`` is True for a joint angle: its values are then taken modulo a
    full turn by :meth:`state_at` (q and q + 2 pi are one position).
    """

    kind: str
    start: float = 0.0
    rate: float = 0.0
    acceleration: float = 0.0
    centre: float = 0.0
    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    turns: bool = False

    KINDS = ("constant-rate", "constant-acceleration", "harmonic")

    def at_time(self, t):
        """Input value, rate and acceleration at time(s) ``t`` (s).

        Returns
        -------
        q, qd, qdd : ndarray, shape of ``t`` (floats for a number ``t``)
        """
        # a number (an engine's step loop asks at every step) is computed as floats: the same
        # operations in the same order as on an array, so the same values, without NumPy's overhead
        if not isinstance(t, (float, int)):
            t = np.asarray(t, dtype=float)
        else:
            t = float(t)
        if self.kind == "harmonic":
            w = 2.0 * math.pi * self.frequency
            arg = w * t + self.phase
            return (
                self.centre + self.amplitude * np.sin(arg),
                self.amplitude * w * np.cos(arg),
                -self.amplitude * w * w * np.sin(arg),
            )
        acc = self.acceleration if self.kind == "constant-acceleration" else 0.0
        return (
            self.start + self.rate * t + 0.5 * acc * t * t,
            self.rate + acc * t + 0.0 * t,
            acc + 0.0 * t,
        )

    def time_at(self, value: float) -> float | None:
        """The time nearest t = 0 (before or after) at which the input equals
        ``value``; None if it never does."""
        if self.kind == "harmonic":
            if self.amplitude == 0.0:
                return 0.0 if value == self.centre else None
            ratio = (value - self.centre) / self.amplitude
            if abs(ratio) > 1.0 + 1e-12:  # a turning point computed in floating point may overshoot
                return None
            ratio = max(-1.0, min(1.0, ratio))
            w = 2.0 * math.pi * self.frequency
            period = 2.0 * math.pi / w
            candidates = []
            for arg in (math.asin(ratio), math.pi - math.asin(ratio)):
                t = ((arg - self.phase) / w) % period
                candidates += [t, t - period]
            return min(candidates, key=lambda t: (abs(t), -t))
        acc = self.acceleration if self.kind == "constant-acceleration" else 0.0
        dq = value - self.start
        if acc == 0.0:
            if self.rate == 0.0:
                return 0.0 if dq == 0.0 else None
            return dq / self.rate
        disc = self.rate**2 + 2.0 * acc * dq
        if disc < 0.0:
            return None
        roots = [(-self.rate + s * math.sqrt(disc)) / acc for s in (1.0, -1.0)]
        return min(roots, key=lambda t: (abs(t), -t))

    @property
    def static(self) -> bool:
        """True for a law that stands still: every value is a static position."""
        if self.kind == "harmonic":
            return self.amplitude == 0.0
        return self.rate == 0.0 and (self.kind != "constant-acceleration" or self.acceleration == 0.0)

    def _time_modulo_turn(self, value: float) -> float | None:
        """The time nearest t = 0 at which the input equals ``value`` plus any
        whole number of turns (ties: the later time); None if never."""
        two_pi = 2.0 * math.pi
        if self.kind == "harmonic":
            low, high = self.centre - abs(self.amplitude), self.centre + abs(self.amplitude)
            turns = range(math.ceil((low - value) / two_pi - 1e-12), math.floor((high - value) / two_pi + 1e-12) + 1)
            if len(turns) > 1000:  # an amplitude of more than a thousand turns: the nearest ones suffice
                k0 = round((self.centre - value) / two_pi)
                turns = range(k0 - 500, k0 + 501)
        else:  # the law moves one way near t = 0: the turn nearest the start and its neighbours suffice
            k0 = round((self.start - value) / two_pi)
            turns = range(k0 - 1, k0 + 2)
        times = [t for t in (self.time_at(value + two_pi * k) for k in turns) if t is not None]
        return min(times, key=lambda t: (abs(t), -t)) if times else None

    def state_at(self, value: float) -> tuple[float, float, float] | None:
        """(q, qd, qdd) when the input passes ``value`` nearest t = 0; None if never.

        A law that stands still (:attr:`static`) gives a static position,
        ``(value, 0, 0)``, at any value. With ``turns``, the law may pass
        ``value`` plus any whole number of turns; ``q`` is ``value`` as given.
        Of two times equally near t = 0 (a harmonic law passes each value twice
        a period) the later one is taken.
        """
        if self.static:
            return (value, 0.0, 0.0)
        t = self._time_modulo_turn(value) if self.turns else self.time_at(value)
        if t is None:
            return None
        _, qd, qdd = self.at_time(t)
        if self.kind == "harmonic" and abs(value - self.centre) >= abs(self.amplitude) * (1.0 - 1e-12):
            qd = 0.0  # a turning point: the rate vanishes exactly
        return (value, float(qd), float(qdd))


@dataclass(frozen=True)
class Driver:
    """An input: the relative angle (revolute) or slide (prismatic, pin-in-slot)
    of one joint, prescribed by a motion law.

    The angle of a revolute is ``phi_b - phi_a`` of its bodies' frames; the
    slide is the joint's slide displacement (see :class:`Prismatic`).
    """

    name: str
    joint: str
    quantity: str  # "angle" (rad) or "slide" (m)
    law: MotionLaw


@dataclass(frozen=True)
class Instant:
    """A state at which a worked solution states its results.

    ``inputs`` maps each driver's name to (q, qd, qdd) in SI units. An
    instant whose value a driver's motion never reaches keeps the fault in
    ``problem`` (field, expected, found) instead of failing the load, so that
    a file stays usable with ``--at``; :meth:`states` raises it when the
    instant is used.
    """

    label: str
    inputs: Mapping[str, tuple[float, float, float]]
    problem: tuple[str, str, str] | None = None

    def states(self, mechanism: "Mechanism") -> list[tuple[float, float, float]]:
        """(q, qd, qdd) per driver in the mechanism's driver order, SI.

        Raises
        ------
        ModelError
            If a value of the instant is one its driver's motion never reaches.
        """
        if self.problem is not None:
            raise ModelError(mechanism.path, *self.problem)
        return [self.inputs[d.name] for d in mechanism.drivers]


@dataclass(frozen=True)
class Assembly:
    """How to pick the assembly branch.

    ``at`` holds the drivers' values (SI) at which the branch sketches are
    drawn; each branch maps point labels to rough global positions (m).
    The first branch is the default.
    """

    at: Mapping[str, float]
    branches: Mapping[str, Mapping[str, np.ndarray]]


def _frozen_vector(value) -> np.ndarray:
    arr = np.array(value, dtype=float).reshape(2)
    arr.flags.writeable = False
    return arr


#: time-law kinds of a load, as codes (the compiled free-motion integrator reads the codes)
LOAD_LAWS = {"harmonic": 1, "ramp": 2}


@dataclass(frozen=True)
class LoadLaw:
    """How a load varies in time: its force and torque times a factor s(t).

    Attributes
    ----------
    kind : str
        ``"harmonic"``: s = offset + sin(2 pi frequency t + phase);
        ``"ramp"``: s = min(t / duration, 1).
    frequency : float, Hz
    phase : float, rad
    offset : float
    duration : float, s
    """

    kind: str
    frequency: float = 0.0
    phase: float = 0.0
    offset: float = 0.0
    duration: float = 1.0

    def factor(self, t):
        """s(t) for a time or an array of times (s)."""
        t = np.asarray(t, dtype=float)
        if self.kind == "harmonic":
            return self.offset + np.sin(2.0 * np.pi * self.frequency * t + self.phase)
        return np.minimum(t / self.duration, 1.0)

    def parameters(self) -> tuple[float, float, float, float]:
        """(kind code, then frequency, phase, offset for a harmonic law or duration, 0, 0 for a ramp)."""
        if self.kind == "harmonic":
            return float(LOAD_LAWS["harmonic"]), self.frequency, self.phase, self.offset
        return float(LOAD_LAWS["ramp"]), self.duration, 0.0, 0.0

    def describe(self) -> str:
        if self.kind == "harmonic":
            return f"harmonic law ({self.frequency:g} Hz)"
        return f"ramp law ({self.duration:g} s)"


@dataclass(frozen=True)
class Load:
    """An applied load on a moving body (used by the dynamics only).

    Attributes
    ----------
    name : str
    body : str
    point : ndarray, shape (2,), m
        Where the force acts, in the body frame (the body frame's origin for
        a pure torque).
    force : ndarray, shape (2,), N
        Constant in the global frame (it does not turn with the body).
    torque : float, N m
        A couple on the body, counter-clockwise positive.
    label : str or None
        The point's label when the file names one.
    law : LoadLaw or None
        None: constant. Otherwise the force and torque are times ``law.factor(t)``
        (free motion; a driven motion's states have no time).
    """

    name: str
    body: str
    point: np.ndarray
    force: np.ndarray
    torque: float = 0.0
    label: str | None = None
    law: LoadLaw | None = None

    def __post_init__(self):
        object.__setattr__(self, "point", _frozen_vector(self.point))
        object.__setattr__(self, "force", _frozen_vector(self.force))


@dataclass(frozen=True)
class Mechanism:
    """A planar mechanism as one immutable description (SI units).

    Attributes
    ----------
    name, title, source, notes : str
    path : str
        The file it was read from (for messages).
    units : Units
        The display units of the file and of tables.
    bodies : tuple of Body
        ``bodies[0]`` is the ground (name :data:`GROUND`), the others move.
    joints : tuple of Joint
    drivers : tuple of Driver
    assembly : Assembly
    instants : tuple of Instant
    gravity : ndarray, shape (2,), m/s^2
        Acceleration of gravity in the global frame; zero when the file gives none.
    loads : tuple of Load
        Constant applied forces and torques (dynamics only).
    springs : tuple of Spring
        Linear spring-dampers between two points.
    rotational_springs : tuple of RotationalSpring
        Rotational spring-dampers across revolute and pin-in-slot joints.
    free_motion : FreeMotionSpec or None
        How the mechanism is released to move freely (``[free_motion]``), if it is.
    """

    name: str
    title: str
    source: str
    notes: str
    path: str
    units: Units
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    drivers: tuple[Driver, ...]
    assembly: Assembly
    instants: tuple[Instant, ...] = field(default=())
    gravity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    loads: tuple[Load, ...] = field(default=())
    springs: tuple[Spring, ...] = field(default=())
    rotational_springs: tuple[RotationalSpring, ...] = field(default=())
    free_motion: FreeMotionSpec | None = None

    def __post_init__(self):
        object.__setattr__(self, "gravity", _frozen_vector(self.gravity))

    @property
    def ground(self) -> Body:
        return self.bodies[0]

    @property
    def moving_bodies(self) -> tuple[Body, ...]:
        return self.bodies[1:]

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(name)

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)

    @property
    def without_mass(self) -> tuple[str, ...]:
        """Names of the moving bodies that have no mass properties (empty when
        the dynamics can be computed)."""
        return tuple(b.name for b in self.moving_bodies if b.mass is None or b.inertia is None)

    @property
    def point_owners(self) -> dict[str, str]:
        """Each point label and the first body (ground first) that has it."""
        owners: dict[str, str] = {}
        for b in self.bodies:
            for label in b.points:
                owners.setdefault(label, b.name)
        return owners

    @property
    def size(self) -> float:
        """Characteristic length (m): the largest extent of any body's points,
        or of the ground points, whichever is larger. Scales tolerances."""
        extent = 0.0
        for b in self.bodies:
            pts = np.array(list(b.points.values())) if b.points else np.zeros((1, 2))
            spread = pts - pts[0]
            extent = max(extent, float(np.max(np.hypot(spread[:, 0], spread[:, 1]), initial=0.0)))
        return extent if extent > 0.0 else 1.0

    def grubler(self) -> int:
        """Degrees of freedom by the Grübler-Kutzbach count: 3 (n - 1) - sum of rows."""
        return 3 * (len(self.bodies) - 1) - sum(j.rows for j in self.joints)
