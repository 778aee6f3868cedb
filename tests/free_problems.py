"""Free-motion problems whose answers are derived independently of xcheck.

Three mechanism files in tests/data, each released to move freely, and for each
its equations of motion reduced to its degrees of freedom by Lagrange's equations
(no body coordinates, no constraint multipliers, none of xcheck's code):

- ``free-crank-rocker``: a Grashof four-bar with offset centres of mass, released
  from rest under gravity; it swings back and forth for 5 s. One coordinate, the
  crank angle; the coupler and rocker angles in closed form (the triangle B-C-D).
- ``free-slider-crank-spring``: an offset slider-crank with a flywheel crank and
  a spring on the slider, started at 32 rad/s; it turns ten times in 2 s. One
  coordinate, the crank angle; the slider and rod in closed form.
- ``free-double-pendulum``: two compound pendulums, released at rest from the
  horizontal, 2 s. Two coordinates, the links' angles from the downward vertical;
  the textbook equations.
- ``free-fourbar-released``: a four-bar of uniform rods released from rest under
  gravity, 1 s (the engines' free-motion figures are measured on it). One
  coordinate, the crank angle, as the crank-rocker's.

For one degree of freedom theta, with every body's frame (x, y, phi) a closed-form
function of theta, T = (1/2) M(theta) theta'^2 with M = sum of m |r_G'|^2 + I phi'^2
(' is d/dtheta, r_G the centre of mass), and Lagrange's equation reads

    M theta'' + C theta'^2 = Q,   C = sum of m r_G' . r_G'' + I phi' phi'',
    Q = sum of m g . r_G' - sum over springs of k (l - l0) l'.

The first and second derivatives along theta come from a second-order jet
(:class:`Jet`: truncated Taylor arithmetic), so no derivative is written by hand.
The same code runs in mpmath's extended precision (:func:`extended_states`:
Gragg-Bulirsch-Stoer extrapolation at 32 digits, whose states at every output are
stored in tests/data/free-references.json and read by :func:`reference`) and in
float64 (:func:`float_reference`: scipy's DOP853; at rtol 1e-13 it is 5e-11 m off
on the crank-rocker after 5 s, whose swing's period depends on its amplitude, so a
float64 answer cannot judge a reference that reaches round-off).
"""

from __future__ import annotations

import functools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

import numpy as np
from scipy.integrate import solve_ivp

DATA = Path(__file__).resolve().parent / "data"
G = 9.81

FLOAT = SimpleNamespace(
    number=float, sin=math.sin, cos=math.cos, sqrt=math.sqrt, atan2=math.atan2, acos=math.acos, pi=math.pi
)


def extended(digits: int) -> SimpleNamespace:
    """mpmath's functions at ``digits`` significant digits (the precision is set globally)."""
    import mpmath

    mpmath.mp.dps = digits
    return SimpleNamespace(
        number=mpmath.mpf,
        sin=mpmath.sin,
        cos=mpmath.cos,
        sqrt=mpmath.sqrt,
        atan2=mpmath.atan2,
        acos=mpmath.acos,
        pi=mpmath.pi,
    )


class Jet:
    """A value with its first and second derivative along one coordinate."""

    __slots__ = ("v", "d1", "d2", "lib")

    def __init__(self, v, d1, d2, lib):
        self.v, self.d1, self.d2, self.lib = v, d1, d2, lib

    def _lift(self, other) -> Jet:
        if isinstance(other, Jet):
            return other
        zero = self.lib.number(0)
        return Jet(self.lib.number(other), zero, zero, self.lib)

    def __add__(self, other):
        o = self._lift(other)
        return Jet(self.v + o.v, self.d1 + o.d1, self.d2 + o.d2, self.lib)

    __radd__ = __add__

    def __neg__(self):
        return Jet(-self.v, -self.d1, -self.d2, self.lib)

    def __sub__(self, other):
        return self + (-self._lift(other))

    def __rsub__(self, other):
        return self._lift(other) - self

    def __mul__(self, other):
        o = self._lift(other)
        return Jet(
            self.v * o.v, self.v * o.d1 + self.d1 * o.v, self.v * o.d2 + 2 * self.d1 * o.d1 + self.d2 * o.v, self.lib
        )

    __rmul__ = __mul__

    def reciprocal(self) -> Jet:
        v = 1 / self.v
        return Jet(v, -self.d1 * v * v, 2 * self.d1 * self.d1 * v * v * v - self.d2 * v * v, self.lib)

    def __truediv__(self, other):
        return self * self._lift(other).reciprocal()

    def __rtruediv__(self, other):
        return self._lift(other) * self.reciprocal()


def sin(a: Jet) -> Jet:
    s, c = a.lib.sin(a.v), a.lib.cos(a.v)
    return Jet(s, c * a.d1, c * a.d2 - s * a.d1 * a.d1, a.lib)


def cos(a: Jet) -> Jet:
    s, c = a.lib.sin(a.v), a.lib.cos(a.v)
    return Jet(c, -s * a.d1, -s * a.d2 - c * a.d1 * a.d1, a.lib)


def sqrt(a: Jet) -> Jet:
    r = a.lib.sqrt(a.v)
    return Jet(r, a.d1 / (2 * r), a.d2 / (2 * r) - a.d1 * a.d1 / (4 * r * r * r), a.lib)


def atan2(y: Jet, x: Jet) -> Jet:
    """The angle of (x, y): phi' = (x y' - y x') / r^2, phi'' its derivative."""
    r2 = x.v * x.v + y.v * y.v
    num = x.v * y.d1 - y.v * x.d1
    num1 = x.v * y.d2 - y.v * x.d2  # (x y' - y x')' = x y'' - y x''
    r2_1 = 2 * (x.v * x.d1 + y.v * y.d1)
    return Jet(x.lib.atan2(y.v, x.v), num / r2, (num1 * r2 - num * r2_1) / (r2 * r2), x.lib)


def acos(a: Jet) -> Jet:
    w = a.lib.sqrt(1 - a.v * a.v)
    return Jet(a.lib.acos(a.v), -a.d1 / w, -a.d2 / w - a.v * a.d1 * a.d1 / (w * w * w), a.lib)


@dataclass(frozen=True)
class Body:
    """Mass data as the file has them: mass (kg), inertia about the centre of mass (kg m^2),
    the centre of mass in the body frame (m)."""

    mass: float
    inertia: float
    com: tuple[float, float] = (0.0, 0.0)


def _rotate(phi: Jet, s: tuple[float, float]) -> tuple[Jet, Jet]:
    c, n = cos(phi), sin(phi)
    return c * s[0] - n * s[1], n * s[0] + c * s[1]


class OneCoordinate:
    """A mechanism of one degree of freedom whose body frames are closed-form
    functions of one angle: Lagrange's equation as in the module's docstring."""

    name = ""
    bodies: dict[str, Body] = {}
    #: per spring: (its end on the ground, (x, y)), the body and point in its frame, k, l0
    springs: tuple = ()
    start: tuple[float, float] = (0.0, 0.0)  # theta (rad), theta' (rad/s)

    def frames(self, theta: Jet) -> dict[str, tuple[Jet, Jet, Jet]]:
        """Each moving body's frame: origin x, y (m) and angle phi (rad), as jets in theta."""
        raise NotImplementedError

    def derivative(self, t, y, lib) -> list:
        zero, one = lib.number(0), lib.number(1)
        theta = Jet(y[0], one, zero, lib)
        frames = self.frames(theta)
        mass, coriolis, force = zero, zero, zero
        for name, body in self.bodies.items():
            x, yy, phi = frames[name]
            ax, ay = _rotate(phi, body.com)
            gx, gy = x + ax, yy + ay
            m, inertia = lib.number(body.mass), lib.number(body.inertia)
            mass += m * (gx.d1 * gx.d1 + gy.d1 * gy.d1) + inertia * phi.d1 * phi.d1
            coriolis += m * (gx.d1 * gx.d2 + gy.d1 * gy.d2) + inertia * phi.d1 * phi.d2
            force += -m * lib.number(G) * gy.d1
        for ground, body, point, stiffness, rest in self.springs:
            x, yy, phi = frames[body]
            ax, ay = _rotate(phi, point)
            dx, dy = x + ax - lib.number(ground[0]), yy + ay - lib.number(ground[1])
            length = sqrt(dx * dx + dy * dy)
            force += -lib.number(stiffness) * (length.v - lib.number(rest)) * length.d1
        return [y[1], (force - coriolis * y[1] * y[1]) / mass]

    def poses(self, state, lib=FLOAT) -> dict[str, tuple]:
        """Each body's (x, y, phi) at the state (theta, theta')."""
        frames = self.frames(Jet(state[0], lib.number(1), lib.number(0), lib))
        return {name: (x.v, y.v, phi.v) for name, (x, y, phi) in frames.items()}


class CrankRocker(OneCoordinate):
    """tests/data/free-crank-rocker.toml: ground pivots A (0, 0) and D (0.75, -0.05),
    crank AB 0.2 m, coupler BC 0.7 m, rocker DC 0.5 m (C above the line BD);
    released at rest with the crank at 60 deg."""

    name = "free-crank-rocker"
    bodies = {
        "crank": Body(1.0, 0.004, (0.02, 0.01)),
        "coupler": Body(2.0, 0.1, (0.05, 0.08)),
        "rocker": Body(1.5, 0.03125),
    }
    start = (math.radians(60.0), 0.0)
    a, b, c, d = 0.2, 0.7, 0.5, (0.75, -0.05)

    def frames(self, theta):
        bx, by = self.a * cos(theta), self.a * sin(theta)
        ex, ey = self.d[0] - bx, self.d[1] - by
        s2 = ex * ex + ey * ey
        phi3 = atan2(ey, ex) + acos((self.b**2 - self.c**2 + s2) / (2 * self.b * sqrt(s2)))
        cx, cy = bx + self.b * cos(phi3), by + self.b * sin(phi3)
        phi4 = atan2(cy - self.d[1], cx - self.d[0])
        return {
            "crank": (bx / 2, by / 2, theta),
            "coupler": ((bx + cx) / 2, (by + cy) / 2, phi3),
            "rocker": ((cx + self.d[0]) / 2, (cy + self.d[1]) / 2, phi4),
        }


class FourBarReleased(CrankRocker):
    """tests/data/free-fourbar-released.toml: ground pivots O (0, 0) and Q (0.2, 0),
    crank OA 0.1 m, coupler AB 0.3 m, rocker QB 0.22 m (B above the line AQ), uniform
    1 kg rods; released at rest with the crank at 45 deg."""

    name = "free-fourbar-released"
    bodies = {
        "crank": Body(1.0, 0.1**2 / 12.0),
        "coupler": Body(1.0, 0.3**2 / 12.0),
        "rocker": Body(1.0, 0.22**2 / 12.0),
    }
    start = (math.radians(45.0), 0.0)
    a, b, c, d = 0.1, 0.3, 0.22, (0.2, 0.0)  # the crank-rocker's triangle B-C-D is the four-bar's A-B-Q


class SliderCrankSpring(OneCoordinate):
    """tests/data/free-slider-crank-spring.toml: crank OA 0.1 m about O (0, 0), rod AB
    0.35 m, the slider's pin B on the line y = 0.02 m (B right of A); a spring of 1000
    N/m, rest length 0.25 m, from the ground point S (0.6, 0.02) to B; started with the
    crank at 30 deg turning at 32 rad/s."""

    name = "free-slider-crank-spring"
    bodies = {
        "crank": Body(0.5, 0.05),
        "rod": Body(0.8, 0.008, (0.03, 0.0)),
        "slider": Body(1.2, 0.001),
    }
    springs = (((0.6, 0.02), "slider", (0.0, 0.0), 1000.0, 0.25),)
    start = (math.radians(30.0), 32.0)
    r, l, e = 0.1, 0.35, 0.02

    def frames(self, theta):
        ax, ay = self.r * cos(theta), self.r * sin(theta)
        rise = self.e - ay
        bx = ax + sqrt(self.l**2 - rise * rise)
        zero = theta * 0
        return {
            "crank": (ax / 2, ay / 2, theta),
            "rod": ((ax + bx) / 2, (ay + self.e) / 2, atan2(rise, bx - ax)),
            "slider": (bx, zero + self.e, zero),
        }


class DoublePendulum:
    """tests/data/free-double-pendulum.toml: link 1 (1 m, 1 kg, I = 0.1 kg m^2, its
    centre of mass 0.55 m from O) pinned at O (0, 0); link 2 (0.8 m, 0.7 kg, I = 0.05,
    its centre of mass 0.3 m from P) pinned at its tip P. Angles th1, th2 from the
    downward vertical; released at rest with link 1 horizontal (th1 = 90 deg) and
    link 2 at 45 deg above it (th2 = 135 deg):

        (m1 c1^2 + I1 + m2 L1^2) th1'' + m2 L1 c2 cos(th1 - th2) th2''
            + m2 L1 c2 sin(th1 - th2) th2'^2 + (m1 c1 + m2 L1) g sin th1 = 0,
        m2 L1 c2 cos(th1 - th2) th1'' + (m2 c2^2 + I2) th2''
            - m2 L1 c2 sin(th1 - th2) th1'^2 + m2 c2 g sin th2 = 0.
    """

    name = "free-double-pendulum"
    m1, i1, c1, length1 = 1.0, 0.1, 0.55, 1.0
    m2, i2, c2, length2 = 0.7, 0.05, 0.3, 0.8
    start = (math.radians(90.0), math.radians(135.0), 0.0, 0.0)

    def derivative(self, t, y, lib) -> list:
        num = lib.number
        m1, i1, c1, l1 = num(self.m1), num(self.i1), num(self.c1), num(self.length1)
        m2, i2, c2, g = num(self.m2), num(self.i2), num(self.c2), num(G)
        th1, th2, w1, w2 = y
        cd, sd = lib.cos(th1 - th2), lib.sin(th1 - th2)
        a11, a12, a22 = m1 * c1 * c1 + i1 + m2 * l1 * l1, m2 * l1 * c2 * cd, m2 * c2 * c2 + i2
        r1 = -m2 * l1 * c2 * sd * w2 * w2 - (m1 * c1 + m2 * l1) * g * lib.sin(th1)
        r2 = m2 * l1 * c2 * sd * w1 * w1 - m2 * c2 * g * lib.sin(th2)
        det = a11 * a22 - a12 * a12
        return [w1, w2, (a22 * r1 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det]

    def poses(self, state, lib=FLOAT) -> dict[str, tuple]:
        """Each link's frame (its middle, angle of O -> P and P -> Q from the x axis)."""
        th1, th2 = state[0], state[1]
        half = lib.pi / 2
        px, py = self.length1 * lib.sin(th1), -self.length1 * lib.cos(th1)
        return {
            "link1": (px / 2, py / 2, th1 - half),
            "link2": (px + self.length2 / 2 * lib.sin(th2), py - self.length2 / 2 * lib.cos(th2), th2 - half),
        }


PROBLEMS: dict[str, Any] = {
    p.name: p for p in (CrankRocker(), SliderCrankSpring(), DoublePendulum(), FourBarReleased())
}


def path(name: str) -> Path:
    """The problem's mechanism file."""
    return DATA / f"{name}.toml"


def _initial(problem) -> list[float]:
    """The initial state: the coordinates, then their rates."""
    return [float(v) for v in problem.start]


def _as_poses(problem, states: np.ndarray, lib=FLOAT) -> dict[str, np.ndarray]:
    """Per body, (N, 3): x, y (m), phi (rad) at each state (N, 2 dof)."""
    rows = [problem.poses(state, lib) for state in states]
    return {name: np.array([[float(v) for v in row[name]] for row in rows]) for name in rows[0]}


def float_reference(name: str, times: np.ndarray) -> dict[str, np.ndarray]:
    """The problem's body frames at ``times`` (s) from scipy's DOP853 at rtol 1e-13 on
    the reduced equations in float64: per body (N, 3), x, y (m) and phi (rad); see the
    module's docstring for its own error."""
    times = np.asarray(times, dtype=float)
    problem = PROBLEMS[name]
    solution = solve_ivp(
        lambda t, y: problem.derivative(t, list(y), FLOAT),
        (0.0, float(times[-1])),
        _initial(problem),
        method="DOP853",
        rtol=1e-13,
        atol=1e-15,
        t_eval=times,
    )
    return _as_poses(problem, solution.y.T)


#: the states of :func:`extended_reference` at every output, written by ``python
#: tests/free_problems.py`` (25 significant digits, the coordinates then their rates)
STORED = DATA / "free-references.json"


@functools.lru_cache(maxsize=None)
def _stored(name: str) -> tuple[np.ndarray, np.ndarray]:
    entry = json.loads(STORED.read_text(encoding="utf-8"))[name]
    times = np.arange(len(entry["states"])) * entry["output_step"]
    return times, np.array([[float(v) for v in state] for state in entry["states"]])


def reference(name: str, times: np.ndarray) -> dict[str, np.ndarray]:
    """The problem's body frames at ``times`` (s; output times of its file): per body
    (N, 3), x, y (m) and phi (rad), from the stored extended-precision states."""
    stored_times, states = _stored(name)
    index = np.rint(np.asarray(times, dtype=float) / (stored_times[1] - stored_times[0])).astype(int)
    if not np.allclose(stored_times[index], times, rtol=0.0, atol=1e-9):
        raise ValueError(f"{name}: the stored states are at multiples of {stored_times[1]:g} s")
    return _as_poses(PROBLEMS[name], states[index])


def gbs_step(derivative: Callable, t, y: list, step, levels: int, lib) -> tuple[list, Any]:
    """One Gragg-Bulirsch-Stoer step of ``step`` (s) from (t, y): Gragg's modified
    midpoint rule with 2, 4, ..., 2 ``levels`` substeps, extrapolated to zero step in
    h^2 (Aitken-Neville); (the new state, the last two columns' largest difference)."""
    start = derivative(t, y, lib)
    table: list[list[list]] = []
    for j in range(1, levels + 1):
        n = 2 * j
        h = step / n
        z0 = list(y)
        z1 = [a + h * b for a, b in zip(y, start)]
        for m in range(1, n):
            f = derivative(t + m * h, z1, lib)
            z0, z1 = z1, [a + 2 * h * b for a, b in zip(z0, f)]
        f = derivative(t + step, z1, lib)
        row = [[(a + b + h * c) / 2 for a, b, c in zip(z1, z0, f)]]
        for i in range(1, j):
            ratio = lib.number(n * n) / ((n - 2 * i) ** 2)
            row.append([a + (a - b) / (ratio - 1) for a, b in zip(row[i - 1], table[-1][i - 1])])
        table.append(row)
    best, previous = table[-1][-1], table[-1][-2]
    return best, max(abs(a - b) for a, b in zip(best, previous))


def extended_states(name: str, times: np.ndarray, digits: int = 32, step: float = 0.005, levels: int = 9):
    """The problem's states (coordinates, then rates) at ``times`` (s) in mpmath at ``digits``
    digits: Gragg-Bulirsch-Stoer steps of ``step`` (s; it must divide the spacing of
    ``times``) with ``levels`` levels (order 2 levels). Returns (the states as lists of
    mpf, the largest difference of a step's last two extrapolations)."""
    lib = extended(digits)
    problem = PROBLEMS[name]
    y = [lib.number(v) for v in _initial(problem)]
    t, worst = lib.number(0), lib.number(0)
    states = []
    h = lib.number(step)
    for target in np.asarray(times, dtype=float):
        steps = int(round((target - float(t)) / step))
        for _ in range(steps):
            y, difference = gbs_step(problem.derivative, t, y, h, levels, lib)
            t += h
            worst = max(worst, difference)
        states.append(y)
    return states, float(worst)


def extended_reference(name: str, times: np.ndarray, **settings) -> dict[str, np.ndarray]:
    """:func:`reference` computed afresh by :func:`extended_states` (``settings`` its)."""
    states, _ = extended_states(name, times, **settings)
    return _as_poses(PROBLEMS[name], np.array([[float(v) for v in s] for s in states]))


def body_error(kinematics, q: np.ndarray, poses: dict[str, np.ndarray]) -> np.ndarray:
    """Per output, the largest |difference| of a body's frame origin (m) or angle
    (rad times the mechanism's size) between xcheck's body coordinates ``q`` (N, n)
    and ``poses``: the measure of xcheck's stated free-motion error."""
    size = kinematics.system.size
    out = np.zeros(len(q))
    for name, pose in poses.items():
        k = 3 * kinematics.system.body_index[name]
        out = np.maximum(out, np.abs(q[:, k : k + 2] - pose[:, :2]).max(axis=1))
        out = np.maximum(out, np.abs(q[:, k + 2] - pose[:, 2]) * size)
    return out


def write_stored(names=None) -> None:
    """Integrate each problem (default: all) over its file's duration by
    :func:`extended_states` and write the states at its outputs to :data:`STORED`."""
    import tomllib

    import mpmath

    stored = json.loads(STORED.read_text(encoding="utf-8")) if STORED.exists() else {}
    for name in names or PROBLEMS:
        spec = tomllib.loads(path(name).read_text(encoding="utf-8"))["free_motion"]
        step = float(spec["output_step"])
        times = np.arange(int(round(float(spec["duration"]) / step)) + 1) * step
        states, worst = extended_states(name, times)
        stored[name] = {
            "method": "Gragg-Bulirsch-Stoer, 9 levels, steps of 0.005 s, mpmath at 32 digits",
            "largest_extrapolation_difference": worst,
            "output_step": step,
            "states": [[mpmath.nstr(v, 25) for v in state] for state in states],
        }
        print(f"{name}: {len(states)} states, largest extrapolation difference {worst:.3g}", file=sys.stderr)
    STORED.write_text(json.dumps(stored, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    write_stored(sys.argv[1:])
