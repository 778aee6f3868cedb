"""pymunk: the mechanism as a 2-D constraint scene, simulated and compared.

pymunk (Chipmunk2D) has no kinematic tree: every joint of the canonical model
becomes a constraint between two rigid bodies, and the space's iterative
impulse solver keeps them together while it integrates the bodies' motion
(semi-implicit Euler). The mode ``pymunk-dynamic`` drives the inputs by their
motion laws over :func:`xcheck.motion.simulation_window`, samples the bodies,
and reports the error against the native solution for several time steps and
solver iteration counts (the error trend), with how far the joints came apart.

The scene, joint by joint:

* revolute: ``PivotJoint`` at the two bodies' points;
* prismatic: ``GrooveJoint`` (the point of ``body_b`` on a finite segment of
  the line fixed in ``body_a``) plus ``GearJoint(a, b, angle, 1)``, which holds
  ``phi_b - phi_a = angle``;
* pin-in-slot: ``GrooveJoint`` alone.

Grooves are finite: each spans the slide range of the native solution over the
simulated window plus a margin on each side. Bodies have no shapes, so nothing
collides. A pymunk body's ``position`` is the origin of the model's body frame
and its ``center_of_gravity`` the model's centre of mass (local), so positions
and angles map one to one.

The inputs:

* an angle driven at a constant rate on a revolute to the ground: the body is
  ``KINEMATIC`` with that angular velocity and its centre of gravity on the
  pivot, so pymunk turns it exactly;
* any other angle (an acceleration profile, or a revolute between two moving
  bodies): a ``SimpleMotor`` whose rate is set before each step to the law's
  rate at the end of that step; the angle then follows by integration;
* a slide on a prismatic joint to the ground: the sliding body is
  ``KINEMATIC``, its velocity set before each step to the secant of the motion
  law over the step, so that its position is exact at every step's end;
* a slide of a pin-in-slot, or between two moving bodies: a ``PinJoint``
  between the point and a fixed anchor on the line, far behind the slide
  range, whose length is set before each step to the law's value at the end
  of the next step and corrected fully in one step (a servo on the slide).

Every trajectory carries the inputs as pymunk realised them (read from the
bodies), so :func:`xcheck.compare.differences` solves the native model at the
very inputs pymunk reached.
"""

from __future__ import annotations

import io
import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import pymunk as pm  # the library: absolute import, not this module (xcheck.engines.pymunk)

from xcheck.compare import ModeResult, Trajectory, differences
from xcheck.fileio import write_atomic
from xcheck.kinematics import Kinematics, Solution, Status
from xcheck.model import GROUND, Mechanism, PinInSlot, Prismatic, Revolute
from xcheck.motion import SimulationWindow, simulation_window

__all__ = ["MODE", "DEFAULT_MASS", "DEFAULT_SETTINGS", "Scene", "Setting", "build_scene", "run_dynamic",
           "scene_figure", "trajectory_errors"]

#: The mode this module provides.
MODE = "pymunk-dynamic"
#: Mass (kg) of a body whose model gives none.
DEFAULT_MASS = 1.0
#: Groove margin beyond the native slide range on each side: this fraction of
#: the range plus this fraction of the mechanism's size.
_GROOVE_MARGIN = (0.25, 0.05)
#: The slide servo's fixed anchor sits this many mechanism sizes behind the
#: line point, so the servo's length never passes through zero.
_SERVO_BACKOFF = 2.0


def _rotate(angle: float, xy) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * xy[0] - s * xy[1], s * xy[0] + c * xy[1]])


def _groove_free_com(mechanism: Mechanism, name: str, centroid: np.ndarray) -> np.ndarray | None:
    """A centre of mass (local, m) at which pymunk's groove joints on this body
    are exact, or None if there is none.

    pymunk's ``GrooveJoint`` solves the pin's 2-D point impulse with the
    effective mass K of both bodies and then keeps only its component along
    the groove's normal. That is the right 1-D impulse only when K has the
    groove's normal as an eigenvector; otherwise the joint holds the relative
    velocity along a skewed direction: the pin leaves its groove in proportion
    to its sliding speed, and the scene can meet a false singularity (task-2-2
    blew up with the centres of mass at the bodies' centroids). K is diagonal
    in the groove's frame when the line's body has its centre of mass on the
    line and the pin's body at the pin; this picks such a point when one
    exists: the common pin if the body carries pins (and it lies on every line
    the body carries), else the centroid's projection on the body's common line.
    """
    lines = [j for j in mechanism.joints if isinstance(j, (Prismatic, PinInSlot)) and j.body_a == name]
    pins = [mechanism.body(name).points[j.point] for j in mechanism.joints
            if isinstance(j, (Prismatic, PinInSlot)) and j.body_b == name]
    if not lines and not pins:
        return None
    body = mechanism.body(name)
    tol = 1e-9 * mechanism.size

    def on_line(xy, joint) -> bool:
        r = xy - body.points[joint.line_point]
        return abs(joint.direction[0] * r[1] - joint.direction[1] * r[0]) <= tol

    if pins:
        if any(np.linalg.norm(pin - pins[0]) > tol for pin in pins):
            return None
        return pins[0] if all(on_line(pins[0], j) for j in lines) else None
    base, u = body.points[lines[0].line_point], lines[0].direction
    candidate = base + float(u @ (centroid - base)) * u
    return candidate if all(on_line(candidate, j) for j in lines) else None


def _mass_properties(mechanism: Mechanism, name: str, guides=()) -> tuple[float, np.ndarray, float, list[str]]:
    """Mass (kg), centre of mass (local, m) and moment about it (kg m^2) of a
    moving body, with the model's values where it has them.

    Defaults: mass :data:`DEFAULT_MASS`; centre of mass where pymunk's groove
    joints on the body are exact (see :func:`_groove_free_com`), else at the
    mean of the body's points and the ends of the grooves it carries
    (``guides``, local, m); moment of a uniform slender rod, m L^2 / 12, with
    L the largest distance between two of those points, at least a tenth of
    the mechanism's size (a one-point slider block still needs a moment). A
    guide is part of its body, so its length counts.

    Returns
    -------
    mass, com, moment, defaulted
        ``defaulted`` names the properties that took a default.
    """
    body = mechanism.body(name)
    defaulted = []
    mass = body.mass
    if mass is None:
        mass, defaulted = DEFAULT_MASS, defaulted + ["mass"]
    points = np.array(list(body.points.values()) + [np.asarray(g, dtype=float) for g in guides] or [[0.0, 0.0]])
    com = body.com
    if com is None:
        centroid = points.mean(axis=0)
        exact = _groove_free_com(mechanism, name, centroid)
        com = centroid if exact is None else exact
        defaulted.append("com" if exact is None else "com (on its groove line or pin)")
    inertia = body.inertia
    if inertia is None:
        span = max((float(np.linalg.norm(p - q)) for p in points for q in points), default=0.0)
        length = max(span, 0.1 * mechanism.size)
        inertia, defaulted = mass * length * length / 12.0, defaulted + ["inertia"]
    if not (math.isfinite(mass) and mass > 0.0 and math.isfinite(inertia) and inertia > 0.0):
        raise ValueError(f"body {name}: expected a positive finite mass and moment of inertia, "
                         f"found mass {mass} kg, inertia {inertia} kg m^2")
    return float(mass), np.asarray(com, dtype=float), float(inertia), defaulted


@dataclass
class _Drive:
    """How one driver is realised in the scene.

    ``kind`` is "kinematic-rate", "motor", "kinematic-slide" or "slide-servo";
    ``before_step(t, dt)`` prepares the step from t to t + dt.
    """

    driver_index: int
    kind: str
    body: pm.Body | None = None
    constraint: pm.Constraint | None = None
    sign: float = 1.0
    direction: np.ndarray | None = None  # world direction of a kinematic slide
    law: object = None

    def before_step(self, t: float, dt: float) -> None:
        if self.kind == "motor":
            # SimpleMotor holds b.w - a.w = -rate at the end of the step
            _, qd, _ = self.law.at_time(t + dt)
            self.constraint.rate = -float(qd)
        elif self.kind == "kinematic-slide":
            step = (float(self.law.at_time(t + dt)[0]) - float(self.law.at_time(t)[0])) / dt
            v = self.sign * step * self.direction
            self.body.velocity = (float(v[0]), float(v[1]))
        elif self.kind == "slide-servo":
            # the velocity solved in this step moves the bodies in the next one
            self.constraint.distance = self.sign * float(self.law.at_time(t + 2.0 * dt)[0])


@dataclass
class Scene:
    """A mechanism as a pymunk space.

    Attributes
    ----------
    mechanism : Mechanism
    space : pymunk.Space
    bodies : dict of str to pymunk.Body
        Every body of the model by name; the ground is the space's static body.
    constraints : dict of str to list of pymunk.Constraint
        The constraints standing for each joint (empty for a joint between two
        bodies whose motion is prescribed), and ``"driver:<name>"`` entries for
        motors and slide servos.
    grooves : dict of str to (str, ndarray (2,), ndarray (2,))
        Per prismatic / pin-in-slot joint: the body carrying the line and the
        groove's two ends in its frame, m.
    drives : list of _Drive
    defaults : dict of str to list of str
        Per moving body, the mass properties that took a default.
    """

    mechanism: Mechanism
    space: pm.Space
    bodies: dict
    constraints: dict
    grooves: dict
    drives: list
    defaults: dict

    def step(self, t: float, dt: float) -> None:
        """Advance the space from t to t + dt (s)."""
        for drive in self.drives:
            if drive.kind != "kinematic-rate":
                drive.before_step(t, dt)
        self.space.step(dt)

    def world_point(self, body: str, label: str) -> np.ndarray:
        """Global position (m) of a body's named point, from pymunk's transform."""
        p = self.bodies[body].local_to_world(tuple(self.mechanism.body(body).points[label]))
        return np.array([p.x, p.y])

    def point_velocity(self, body: str, label: str) -> np.ndarray:
        v = self.bodies[body].velocity_at_local_point(tuple(self.mechanism.body(body).points[label]))
        return np.array([v.x, v.y])

    def joint_gaps(self) -> tuple[float, float]:
        """How far the joints have come apart: the largest distance (m) between
        points that should coincide or from a point to its line, and the largest
        error (rad) of a prismatic joint's locked angle."""
        gap, lock = 0.0, 0.0
        for joint in self.mechanism.joints:
            if isinstance(joint, Revolute):
                d = self.world_point(joint.body_a, joint.point_a) - self.world_point(joint.body_b, joint.point_b)
                gap = max(gap, float(math.hypot(*d)))
                continue
            a = self.bodies[joint.body_a]
            u = _rotate(a.angle, joint.direction)
            r = self.world_point(joint.body_b, joint.point) - self.world_point(joint.body_a, joint.line_point)
            gap = max(gap, abs(float(u[0] * r[1] - u[1] * r[0])))
            if isinstance(joint, Prismatic):
                err = self.bodies[joint.body_b].angle - a.angle - joint.angle
                lock = max(lock, abs((err + math.pi) % (2.0 * math.pi) - math.pi))
        return gap, lock

    def inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """The drivers' values and rates as the bodies realise them, each (k,), SI."""
        mech = self.mechanism
        q, qd = np.empty(len(mech.drivers)), np.empty(len(mech.drivers))
        for k, driver in enumerate(mech.drivers):
            joint = mech.joint(driver.joint)
            a, b = self.bodies[joint.body_a], self.bodies[joint.body_b]
            if driver.quantity == "angle":
                q[k], qd[k] = b.angle - a.angle, b.angular_velocity - a.angular_velocity
                continue
            u = _rotate(a.angle, joint.direction)
            r = self.world_point(joint.body_b, joint.point) - self.world_point(joint.body_a, joint.line_point)
            v = self.point_velocity(joint.body_b, joint.point) - self.point_velocity(joint.body_a, joint.line_point)
            q[k] = u @ r
            qd[k] = u @ v + a.angular_velocity * (u[0] * r[1] - u[1] * r[0])
        return q, qd


def _place(body: pm.Body, origin, angle: float, origin_velocity, omega: float) -> None:
    """Put a pymunk body's frame origin at ``origin`` with ``angle`` and the
    origin moving at ``origin_velocity`` (pymunk's velocity is that of the
    centre of gravity). The angle goes first: its setter turns the body about
    the centre of gravity."""
    body.angle = float(angle)
    body.position = (float(origin[0]), float(origin[1]))
    arm = _rotate(angle, body.center_of_gravity)
    v = np.asarray(origin_velocity, dtype=float) + omega * np.array([-arm[1], arm[0]])
    body.velocity = (float(v[0]), float(v[1]))
    body.angular_velocity = float(omega)


def _slide_extent(mechanism: Mechanism, solution: Solution, joint) -> tuple[float, float]:
    """Smallest and largest slide (m) of a line joint over a native solution."""
    ok = solution.status <= Status.NEAR_SINGULAR
    la = solution.body(joint.body_a)
    r = (solution.point(joint.point, joint.body_b)["position"]
         - solution.point(joint.line_point, joint.body_a)["position"])[ok]
    phi = la["angle"][ok]
    u = np.stack([np.cos(phi) * joint.direction[0] - np.sin(phi) * joint.direction[1],
                  np.sin(phi) * joint.direction[0] + np.cos(phi) * joint.direction[1]], axis=1)
    s = np.einsum("ij,ij->i", u, r)
    return float(s.min()), float(s.max())


def build_scene(kinematics: Kinematics, native: Solution, *, iterations: int = 10,
                error_bias: float | None = None) -> Scene:
    """The mechanism as a pymunk space, at the first sample of ``native``.

    Parameters
    ----------
    kinematics : Kinematics
    native : Solution
        The native solution over the window to simulate; its first sample is
        the initial state (positions and velocities) and its slide ranges size
        the grooves. Every sample must have assembled.
    iterations : int
        The space's solver iterations per step.
    error_bias : float, optional
        Each constraint's ``error_bias``: the fraction of a joint's error left
        uncorrected after one second (pymunk's default, 0.9 per 1/60 s, when
        None).

    Returns
    -------
    Scene
    """
    mech = kinematics.mechanism
    if not np.all(native.status <= Status.NEAR_SINGULAR):
        raise ValueError("the native solution does not assemble over the whole window")
    space = pm.Space()
    space.iterations = int(iterations)
    bodies = {GROUND: space.static_body}
    defaults = {}
    drives: list[_Drive] = []

    # prescribed bodies: a constant-rate angle on a revolute to the ground, a
    # slide on a prismatic joint to the ground
    prescribed: dict[str, _Drive] = {}
    for k, driver in enumerate(mech.drivers):
        joint = mech.joint(driver.joint)
        on_ground = GROUND in (joint.body_a, joint.body_b) and joint.body_a != joint.body_b
        moving = joint.body_b if joint.body_a == GROUND else joint.body_a
        sign = 1.0 if joint.body_a == GROUND else -1.0
        if (driver.quantity == "angle" and on_ground and driver.law.kind == "constant-rate"
                and moving not in prescribed):
            prescribed[moving] = _Drive(k, "kinematic-rate", sign=sign, law=driver.law)
        elif driver.quantity == "slide" and on_ground and isinstance(joint, Prismatic) and moving not in prescribed:
            # the slide grows when body_b moves along the line (line in body_a)
            # or when body_a moves against it (line in the moving body)
            prescribed[moving] = _Drive(k, "kinematic-slide", sign=sign, law=driver.law)

    grooves = {}
    for joint in mech.joints:
        if isinstance(joint, (Prismatic, PinInSlot)):
            low, high = _slide_extent(mech, native, joint)
            pad = _GROOVE_MARGIN[0] * (high - low) + _GROOVE_MARGIN[1] * mech.size
            base = mech.body(joint.body_a).points[joint.line_point]
            grooves[joint.name] = (joint.body_a, base + (low - pad) * joint.direction,
                                   base + (high + pad) * joint.direction)

    first = 0
    for body in mech.moving_bodies:
        frame = native.body(body.name)
        origin, angle = frame["position"][first], float(frame["angle"][first])
        drive = prescribed.get(body.name)
        if drive is None:
            guides = [end for carrier, *ends in grooves.values() if carrier == body.name for end in ends]
            mass, com, inertia, defaulted = _mass_properties(mech, body.name, guides)
            pb = pm.Body(mass, inertia)
            pb.center_of_gravity = (float(com[0]), float(com[1]))
            defaults[body.name] = defaulted
        else:
            pb = pm.Body(body_type=pm.Body.KINEMATIC)
            drive.body = pb
            if drive.kind == "kinematic-rate":
                # turning about the centre of gravity is exact in pymunk: put it on the pivot
                joint = mech.joint(mech.drivers[drive.driver_index].joint)
                pivot = joint.point_b if joint.body_b == body.name else joint.point_a
                pb.center_of_gravity = tuple(float(x) for x in body.points[pivot])
            else:
                joint = mech.joint(mech.drivers[drive.driver_index].joint)
                line_angle = 0.0 if joint.body_a == GROUND else angle
                drive.direction = _rotate(line_angle, joint.direction)
            drives.append(drive)
        _place(pb, origin, angle, frame["velocity"][first], float(frame["omega"][first]))
        if drive is not None and drive.kind == "kinematic-rate":
            pb.angular_velocity = drive.sign * drive.law.rate
        space.add(pb)
        bodies[body.name] = pb

    def dynamic(*names):
        return any(bodies[n].body_type == pm.Body.DYNAMIC for n in names)

    constraints: dict[str, list] = {}
    for joint in mech.joints:
        a, b = bodies[joint.body_a], bodies[joint.body_b]
        made = []
        if dynamic(joint.body_a, joint.body_b):
            if isinstance(joint, Revolute):
                made.append(pm.PivotJoint(a, b, tuple(mech.body(joint.body_a).points[joint.point_a]),
                                          tuple(mech.body(joint.body_b).points[joint.point_b])))
            else:
                _, start, end = grooves[joint.name]
                made.append(pm.GrooveJoint(a, b, tuple(start), tuple(end),
                                           tuple(mech.body(joint.body_b).points[joint.point])))
                if isinstance(joint, Prismatic):
                    made.append(pm.GearJoint(a, b, float(joint.angle), 1.0))
        constraints[joint.name] = made

    for k, driver in enumerate(mech.drivers):
        joint = mech.joint(driver.joint)
        if any(d.driver_index == k for d in drives):
            continue
        a, b = bodies[joint.body_a], bodies[joint.body_b]
        if driver.quantity == "angle":
            motor = pm.SimpleMotor(a, b, -float(driver.law.at_time(0.0)[1]))
            drives.append(_Drive(k, "motor", constraint=motor, law=driver.law))
            constraints[f"driver:{driver.name}"] = [motor]
        else:
            # a distance constraint from a fixed anchor behind the line point: its
            # length is the slide plus the back-off, never near zero
            backoff = _SERVO_BACKOFF * mech.size
            anchor = mech.body(joint.body_a).points[joint.line_point] - backoff * joint.direction
            servo = pm.PinJoint(a, b, tuple(anchor), tuple(mech.body(joint.body_b).points[joint.point]))
            servo.error_bias = 0.0  # full correction in one step: the length is a set point
            servo.distance = backoff + float(driver.law.at_time(0.0)[0])
            drives.append(_Drive(k, "slide-servo", constraint=servo, law=_Shifted(driver.law, backoff)))
            constraints[f"driver:{driver.name}"] = [servo]
    for made in constraints.values():
        for c in made:
            c.collide_bodies = False
            if error_bias is not None and not (isinstance(c, pm.PinJoint) and c.error_bias == 0.0):
                c.error_bias = float(error_bias)
            space.add(c)
    drives.sort(key=lambda d: d.driver_index)
    return Scene(mech, space, bodies, constraints, grooves, drives, defaults)


@dataclass(frozen=True)
class _Shifted:
    """A motion law shifted by a constant (the slide servo's length)."""

    law: object
    offset: float

    def at_time(self, t):
        q, qd, qdd = self.law.at_time(t)
        return q + self.offset, qd, qdd



@dataclass(frozen=True)
class Setting:
    """One simulation of the scene.

    Attributes
    ----------
    steps_per_sample : int
        Time steps between two samples; the time step is the window's length
        over ``samples * steps_per_sample``.
    iterations : int
        The space's solver iterations per step.
    error_bias : float or None
        Every joint constraint's ``error_bias`` (fraction of a joint's error
        left after one second): 0 corrects the whole error in one step; None
        keeps pymunk's default (0.9 left per 1/60 s).
    """

    steps_per_sample: int
    iterations: int
    error_bias: float | None = 0.0

    @property
    def correction(self) -> str:
        return "pymunk default" if self.error_bias is None else f"error_bias {self.error_bias:g}"


#: The settings :func:`run_dynamic` runs by default, the comparison's first:
#: three time steps at 500 iterations with full correction (error_bias 0),
#: then the finest step with 50 iterations and with pymunk's defaults (10
#: iterations, default error_bias). Full correction makes the position error
#: second order in the time step where pymunk's default leaves it first order;
#: it needs enough iterations to converge or the scene goes unstable (task-2-6
#: and the inverted slider-crank needed more than 200: 500 leaves a margin).
DEFAULT_SETTINGS = (
    Setting(200, 500), Setting(100, 500), Setting(50, 500),
    Setting(200, 50),
    Setting(200, 10, None),
)


@dataclass
class _Run:
    """The outcome of one simulation."""

    setting: Setting
    dt: float
    trajectory: Trajectory | None = None
    failure: str = ""
    run_time: float = 0.0


def _simulate(kinematics: Kinematics, native: Solution, window: SimulationWindow, samples: int,
              setting: Setting, fd_steps: int, gap_bound: float, speed_bound: float) -> _Run:
    """Step one scene over the window and sample it (see :func:`run_dynamic`)."""
    mech = kinematics.mechanism
    per = setting.steps_per_sample
    dt = window.duration / (samples * per)
    run = _Run(setting, dt)
    start = time.perf_counter()
    scene = build_scene(kinematics, native, iterations=setting.iterations, error_bias=setting.error_bias)
    m = min(fd_steps, per)
    sample_steps = per * np.arange(1, samples + 1)
    wanted: dict[int, list] = {}
    for i, k in enumerate(sample_steps):
        for offset, slot in ((-m, 0), (0, 1), (m, 2)):
            wanted.setdefault(int(k + offset), []).append((i, slot))
    moving = [b.name for b in mech.moving_bodies]
    owners = mech.point_owners
    labels = list(owners)
    nb, npt, k_in = len(moving), len(labels), len(mech.drivers)
    pos, ang = np.full((samples, nb, 2), np.nan), np.full((samples, nb), np.nan)
    vel, omg = np.full((3, samples, nb, 2), np.nan), np.full((3, samples, nb), np.nan)
    ppos, pvel = np.full((samples, npt, 2), np.nan), np.full((3, samples, npt, 2), np.nan)
    q_in, qd_in = np.full((samples, k_in), np.nan), np.full((3, samples, k_in), np.nan)
    gaps, locks = np.full(samples, np.nan), np.full(samples, np.nan)
    pm_bodies = [scene.bodies[name] for name in moving]
    for n in range(1, int(sample_steps[-1] + m) + 1):
        scene.step((n - 1) * dt, dt)
        if n not in wanted:
            continue
        q_now, qd_now = scene.inputs()
        body_v = [(v.x, v.y) for v in (b.velocity_at_local_point((0.0, 0.0)) for b in pm_bodies)]
        body_w = [b.angular_velocity for b in pm_bodies]
        point_v = [scene.point_velocity(owners[label], label) for label in labels]
        for i, slot in wanted[n]:
            vel[slot, i], omg[slot, i], pvel[slot, i], qd_in[slot, i] = body_v, body_w, point_v, qd_now
            if slot != 1:
                continue
            pos[i] = [(b.position.x, b.position.y) for b in pm_bodies]
            ang[i] = [b.angle for b in pm_bodies]
            ppos[i] = [scene.world_point(owners[label], label) for label in labels]
            q_in[i] = q_now
            gaps[i], locks[i] = scene.joint_gaps()
            speed = float(np.max(np.linalg.norm(pvel[1, i], axis=1), initial=0.0))
            finite = all(np.isfinite(x).all() for x in (pos[i], ang[i], vel[1, i], omg[1, i], pvel[1, i]))
            if not (finite and math.isfinite(gaps[i])):
                run.failure = f"went non-finite (NaN or infinite state) at t = {n * dt:.6g} s"
            elif gaps[i] > gap_bound:
                run.failure = (f"came apart at t = {n * dt:.6g} s: joints {gaps[i]:.3g} m apart "
                               f"(bound {gap_bound:.3g} m)")
            elif speed > speed_bound:
                run.failure = (f"blew up at t = {n * dt:.6g} s: a point moves at {speed:.3g} m/s "
                               f"(bound {speed_bound:.3g} m/s, 10 times the native top speed)")
        if run.failure:
            break
    run.run_time = time.perf_counter() - start
    if run.failure:
        return run
    h = m * dt
    times = sample_steps * dt
    bodies = {name: {"position": pos[:, j], "angle": ang[:, j], "velocity": vel[1, :, j],
                     "omega": omg[1, :, j], "acceleration": (vel[2, :, j] - vel[0, :, j]) / (2.0 * h),
                     "alpha": (omg[2, :, j] - omg[0, :, j]) / (2.0 * h)} for j, name in enumerate(moving)}
    points = {label: {"position": ppos[:, j], "velocity": pvel[1, :, j],
                      "acceleration": (pvel[2, :, j] - pvel[0, :, j]) / (2.0 * h)} for j, label in enumerate(labels)}
    drives = ", ".join(f"{mech.drivers[d.driver_index].name}: {d.kind}" for d in scene.drives)
    defaulted = "; ".join(f"{name}: {', '.join(props)}" for name, props in scene.defaults.items() if props)
    run.trajectory = Trajectory(
        source=MODE, inputs=q_in, input_rates=qd_in[1], input_accelerations=(qd_in[2] - qd_in[0]) / (2.0 * h),
        bodies=bodies, points=points, times=times,
        settings={"engine": f"pymunk {pm.version} (Chipmunk {pm.chipmunk_version})",
                  "integrator": "semi-implicit Euler, iterative impulse solver", "time_step": dt,
                  "iterations": setting.iterations, "steps_per_sample": per,
                  "error_bias": setting.correction, "drives": drives, "difference_step": h},
        diagnostics={"joint_gap": gaps, "lock_error": locks,
                     "input_error": q_in - window.inputs(kinematics, times)[0]},
        notes=(f"Accelerations are central differences of pymunk's velocities, {h:.6g} s ({m} time "
               f"step{'s' if m > 1 else ''}) either side of each sample. Inputs are read from the bodies as "
               f"pymunk realised them ({drives}). Mass properties that took defaults (mass {DEFAULT_MASS:g} kg, "
               f"centre of mass at the mean of the body's points, slender-rod moment): {defaulted or 'none'}."),
    )
    return run


#: Column of :func:`trajectory_errors` -> (rows' quantity, kind of error).
_ERROR_COLUMNS = {
    "position_error": ("position", "abs"), "angle_error": ("angle", "abs"),
    "velocity_error": ("velocity", "rel"), "omega_error": ("omega", "rel"),
    "acceleration_error": ("acceleration", "rel"), "alpha_error": ("alpha", "rel"),
}


def trajectory_errors(kinematics: Kinematics, trajectory: Trajectory) -> dict[str, float]:
    """The largest differences of a trajectory from the native solution.

    Returns
    -------
    dict
        ``position_error`` (m) and ``angle_error`` (rad): largest absolute
        difference over bodies and points; ``velocity_error``, ``omega_error``,
        ``acceleration_error``, ``alpha_error``: largest absolute difference
        over the largest native magnitude of that quantity in the mechanism
        (dimensionless); ``joint_gap`` (m) and ``lock_error`` (rad): largest
        over the samples. A quantity no row has is left out.
    """
    table = differences(kinematics, trajectory)
    out = {}
    for column, (quantity, kind) in _ERROR_COLUMNS.items():
        rows = table[table["quantity"] == quantity]
        if rows.empty:
            continue
        worst = float(rows["max_abs"].max())
        if kind == "rel":
            scale = float(rows["scale"].max())
            worst = worst / scale if scale > 0.0 else worst
        out[column] = worst
    out["joint_gap"] = float(np.max(trajectory.diagnostics["joint_gap"]))
    out["lock_error"] = float(np.max(trajectory.diagnostics["lock_error"]))
    return out


def _summary(kinematics: Kinematics, runs: list[_Run]) -> pd.DataFrame:
    """One row per setting; the observed order of the position error between
    a setting and the next coarser one of the same iterations and correction."""
    mech = kinematics.mechanism
    rows = []
    for run in runs:
        row = {"setting": len(rows), "error_bias": run.setting.correction, "iterations": run.setting.iterations,
               "time_step": run.dt, "status": run.failure or "ok"}
        if run.trajectory is not None:
            row.update(trajectory_errors(kinematics, run.trajectory))
            drift = np.max(np.abs(run.trajectory.diagnostics["input_error"]), axis=0)
            row.update({f"input_error:{d.name}": float(e) for d, e in zip(mech.drivers, drift)})
        row["run_time"] = run.run_time
        rows.append(row)
    table = pd.DataFrame(rows)
    table["order"] = np.nan
    if "position_error" in table:
        for _, group in table.groupby(["error_bias", "iterations"]):
            group = group[group["status"] == "ok"].sort_values("time_step")
            for (i, fine), (_, coarse) in zip(group.iterrows(), list(group.iterrows())[1:]):
                if fine["position_error"] > 0.0 and coarse["position_error"] > 0.0:
                    table.loc[i, "order"] = (math.log(coarse["position_error"] / fine["position_error"])
                                             / math.log(coarse["time_step"] / fine["time_step"]))
    return table


def _native_window(kinematics: Kinematics, branch: str | None, count: int = 401):
    """The simulation window and the native solution over it."""
    window = simulation_window(kinematics, branch)
    native = kinematics.solve(*window.inputs(kinematics, window.times(count)), branch=branch)
    if not np.all(native.status <= Status.NEAR_SINGULAR):
        bad = int(np.argmax(native.status > Status.NEAR_SINGULAR))
        raise ValueError(f"the native solver does not assemble the mechanism at t = "
                         f"{window.times(count)[bad]:.6g} s of the window ({Status(native.status[bad]).message})")
    return window, native


def run_dynamic(kinematics: Kinematics, *, settings=DEFAULT_SETTINGS, samples: int = 40,
                fd_steps: int = 1, gap_bound: float | None = None, branch: str | None = None) -> ModeResult:
    """Simulate the mechanism in pymunk and compare it with the native solution.

    The drivers follow their motion laws over
    :func:`xcheck.motion.simulation_window`, from the native state at t = 0.
    Each setting is one simulation, sampled at ``samples`` equally spaced
    times after t = 0.

    Parameters
    ----------
    kinematics : Kinematics
    settings : sequence of Setting
        The first is the one the comparison uses (by default the finest time
        step with 500 iterations and full error correction); the others give
        the error's trend with time step, iterations and pymunk's default
        correction.
    samples : int
        Sample times per simulation.
    fd_steps : int
        Time steps either side of a sample for the central differences of
        velocity that give accelerations.
    gap_bound : float, optional
        A simulation whose joints come further apart than this (m) has
        failed; default 5 % of the mechanism's size. One whose points move
        faster than 10 times the native top speed has failed too.
    branch : str, optional
        Assembly branch.

    Returns
    -------
    ModeResult
        ``trajectories``: one per setting that ran through; ``summary``: one row
        per setting (see :func:`trajectory_errors` for the error columns, plus
        ``input_error:<driver>``, the largest difference of the realised input
        from its motion law in rad or m, ``order``, the observed order of the
        position error in the time step, and ``run_time`` in s). ``ok`` is
        False, with the reason in one line, when the first setting fails or the
        scene cannot be built; nothing is raised.
    """
    mech = kinematics.mechanism
    settings = tuple(settings)
    try:
        if not settings:
            raise ValueError("expected at least one setting, found none")
        window, native = _native_window(kinematics, branch)
        bound = 0.05 * mech.size if gap_bound is None else float(gap_bound)
        speeds = [np.linalg.norm(native.point(label)["velocity"], axis=1) for label in mech.point_owners]
        top = max(float(np.max(s)) for s in speeds)
        speed_bound = 10.0 * max(top, mech.size / window.duration)
        runs = [_simulate(kinematics, native, window, samples, s, fd_steps, bound, speed_bound) for s in settings]
        summary = _summary(kinematics, runs)
    except Exception as err:  # the other modes still run: report, never raise
        reason = " ".join(str(err).split()) or type(err).__name__
        return ModeResult(MODE, mech.name, False, f"{MODE}: {reason}")
    first = runs[0]
    if first.trajectory is None:
        return ModeResult(MODE, mech.name, False, f"{MODE}: the scene {first.failure} "
                          f"(time step {first.dt:.3g} s, {first.setting.iterations} iterations)", [], summary)
    return ModeResult(MODE, mech.name, True, "", [r.trajectory for r in runs if r.trajectory is not None], summary)


def _snapshot(scene: Scene) -> dict:
    """What the figure draws, read from pymunk's bodies: per body its points
    (global, m), the revolutes' pins, the grooves' ends, the sliders."""
    mech = scene.mechanism
    shot = {"bodies": {b.name: {label: scene.world_point(b.name, label) for label in b.points}
                       for b in mech.bodies},
            "pins": [], "grooves": [], "inputs": scene.inputs()[0], "gap": scene.joint_gaps()[0]}
    for joint in mech.joints:
        if isinstance(joint, Revolute):
            shot["pins"].append((scene.world_point(joint.body_b, joint.point_b), GROUND in (joint.body_a, joint.body_b)))
        else:
            body, start, end = scene.grooves[joint.name]
            ends = [scene.bodies[body].local_to_world(tuple(p)) for p in (start, end)]
            shot["grooves"].append((np.array([[p.x, p.y] for p in ends]), isinstance(joint, Prismatic),
                                    scene.world_point(joint.body_b, joint.point), scene.bodies[joint.body_b].angle))
    return shot


def _draw(ax, mech: Mechanism, shot: dict, colours, scale: float) -> None:
    """One panel of :func:`scene_figure` (coordinates divided by ``scale``)."""
    from matplotlib.patches import Polygon, Rectangle
    from matplotlib.transforms import Affine2D
    from scipy.spatial import ConvexHull, QhullError

    block = 0.06 * mech.size / scale
    for ends, prismatic, point, angle in shot["grooves"]:
        ends = ends / scale
        ax.plot(ends[:, 0], ends[:, 1], color="0.55", lw=6, alpha=0.45, solid_capstyle="round", zorder=1)
        ax.plot(ends[:, 0], ends[:, 1], color="0.3", lw=0.8, ls="--", zorder=1)
        if prismatic:  # a block riding the line, turned with its body
            xy = point / scale
            box = Rectangle((xy[0] - block / 2, xy[1] - block / 2), block, block, fill=False, lw=1.2,
                            ec="0.2", zorder=4)
            box.set_transform(Affine2D().rotate_around(xy[0], xy[1], angle) + ax.transData)
            ax.add_patch(box)
    for k, body in enumerate(mech.moving_bodies):
        pts = np.array(list(shot["bodies"][body.name].values())) / scale
        colour = colours[k % len(colours)]
        if len(pts) >= 3:
            try:
                hull = pts[ConvexHull(pts).vertices]
            except QhullError:  # all in a line
                hull = None
            if hull is not None:
                ax.add_patch(Polygon(hull, closed=True, fc=colour, ec=colour, alpha=0.3, lw=2, zorder=2))
        if len(pts) >= 2:
            far = max(((i, j) for i in range(len(pts)) for j in range(len(pts))),
                      key=lambda ij: np.linalg.norm(pts[ij[0]] - pts[ij[1]]))
            ax.plot(pts[list(far), 0], pts[list(far), 1], color=colour, lw=3, alpha=0.8, zorder=2,
                    solid_capstyle="round", label=body.name)
        else:
            ax.plot(pts[:, 0], pts[:, 1], "s", color=colour, ms=8, zorder=3, label=body.name)
        for label, xy in shot["bodies"][body.name].items():
            ax.annotate(label, xy / scale, xytext=(4, 4), textcoords="offset points", fontsize=7, zorder=6)
    for xy, grounded in shot["pins"]:
        xy = xy / scale
        ax.plot(*xy, marker="^" if grounded else "o", ms=9 if grounded else 6, mfc="white", mec="black", zorder=5)
    ground = np.array(list(shot["bodies"][GROUND].values()) or np.zeros((0, 2))) / scale
    if len(ground):
        ax.plot(ground[:, 0], ground[:, 1], "k+", ms=6, zorder=5)
        carried = {label for b in mech.moving_bodies for label in b.points}
        for label, xy in zip(shot["bodies"][GROUND], ground):
            if label not in carried:
                ax.annotate(label, xy, xytext=(4, 4), textcoords="offset points", fontsize=7, zorder=6)
    ax.grid(True, lw=0.3, alpha=0.5)


def scene_figure(kinematics: Kinematics, path, *, times=None, count: int = 4,
                 setting: Setting = DEFAULT_SETTINGS[0], samples: int = 40, branch: str | None = None) -> None:
    """A picture of the pymunk scene at a few instants, for the report.

    The scene is stepped as in :func:`run_dynamic` with ``setting`` and drawn
    from pymunk's own body positions: each body as the hull of its points
    (a bar between its two ends, a square for a one-point slider), pins as
    circles (triangles on the ground), grooves as grey bands, prismatic
    blocks as squares turned with their body. Coordinates and inputs are in
    the mechanism's display units. The PNG is written whole or not at all.

    Parameters
    ----------
    kinematics : Kinematics
    path : str or Path
        The PNG to write.
    times : sequence of float, optional
        Instants (s) inside the simulation window; default ``count`` of them
        equally spaced from 0 to its end.
    setting : Setting
        Time step (through ``samples``), iterations and correction.

    Raises
    ------
    ValueError
        If the window cannot be simulated or a time lies outside it.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    mech = kinematics.mechanism
    units = mech.units
    window, native = _native_window(kinematics, branch)
    times = window.times(count) if times is None else np.asarray(times, dtype=float)
    if times.size == 0 or np.any(times < 0.0) or np.any(times > window.duration):
        raise ValueError(f"expected times within the simulation window 0 .. {window.duration:.6g} s, "
                         f"found {np.round(times, 6).tolist()}")
    dt = window.duration / (samples * setting.steps_per_sample)
    scene = build_scene(kinematics, native, iterations=setting.iterations, error_bias=setting.error_bias)
    shots, n = [], 0
    for t in np.sort(times):
        while n < round(t / dt):
            scene.step(n * dt, dt)
            n += 1
        shots.append((n * dt, _snapshot(scene)))

    every = np.concatenate([np.array(list(b.values())).reshape(-1, 2) for _, shot in shots
                            for b in shot["bodies"].values()]
                           + [g[0] for _, shot in shots for g in shot["grooves"]]) / units.length_factor
    low, high = every.min(axis=0), every.max(axis=0)
    pad = 0.08 * max(float(np.max(high - low)), mech.size / units.length_factor)
    aspect = (high[1] - low[1] + 2 * pad) / (high[0] - low[0] + 2 * pad)
    fig = Figure(figsize=(4.2 * len(shots), 1.4 + 4.0 * min(max(aspect, 0.4), 1.5)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(shots), squeeze=False)[0]
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink",
               "tab:olive", "tab:cyan"]
    for ax, (t, shot) in zip(axes, shots):
        _draw(ax, mech, shot, colours, units.length_factor)
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_aspect("equal", adjustable="box")
        shown = []
        for driver, value in zip(mech.drivers, shot["inputs"]):
            if driver.quantity == "angle":
                shown.append(f"{driver.name} = {value / units.angle_factor:.4g} {units.angle}")
            else:
                shown.append(f"{driver.name} = {value / units.length_factor:.4g} {units.length}")
        ax.set_title(f"t = {t:.4g} s: {', '.join(shown)}\njoint gap {shot['gap']:.2g} m", fontsize=9)
        ax.set_xlabel(f"x ({units.length})")
    axes[0].set_ylabel(f"y ({units.length})")
    axes[0].legend(fontsize=7, loc="best")
    drives = ", ".join(f"{mech.drivers[d.driver_index].name}: {d.kind}" for d in scene.drives)
    fig.suptitle(f"{mech.title or mech.name}: the pymunk scene ({drives}; time step {dt:.3g} s, "
                 f"{setting.iterations} iterations, {setting.correction})", fontsize=10)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    write_atomic(path, buffer.getvalue())
