"""The mechanism as a pymunk space (private to :mod:`xcheck.engines.pymunk`).

pymunk (Chipmunk2D) has no kinematic tree: every joint of the canonical model
becomes a constraint between two rigid bodies, and the space's iterative
impulse solver keeps them together while it integrates the bodies' motion
(semi-implicit Euler). Joint by joint:

* revolute: ``PivotJoint`` at the two bodies' points;
* prismatic: ``GrooveJoint`` (the point of ``body_b`` on a finite segment of
  the line fixed in ``body_a``) plus ``GearJoint(a, b, angle, 1)``, which holds
  ``phi_b - phi_a = angle``;
* pin-in-slot: ``GrooveJoint`` alone.

Grooves are finite: each spans the slide range of the native solution over the
simulated window plus a margin on each side. Bodies have no shapes, so nothing
collides. A pymunk body's ``position`` is the origin of the model's body frame
and its ``center_of_gravity`` the model's centre of mass (local), so positions
and angles map one to one; where the model gives no mass properties the
defaults of :func:`_mass_properties` apply (and are reported).

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
  range, whose length is set before each step to the law's value one step
  ahead and corrected fully in one step (a servo on the slide).

With ``kinematic_inputs=False`` no body is prescribed: every angle is driven
by a motor and every slide by a slide servo, so that every joint is a
constraint whose impulse pymunk reports (the inverse dynamics use this).
The space has the mechanism's gravity; its applied loads are applied before
every step (pymunk clears forces after each step).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pymunk as pm

from xcheck.engines._contract import positive_inertia
from xcheck.joints import GearPair, LineJoint, Revolute, converter
from xcheck.kinematics import Kinematics, Solution, Status, rotate
from xcheck.model import GROUND, Mechanism, MotionLaw
from xcheck.motion import SimulationWindow, simulation_window

__all__ = ["DEFAULT_MASS", "Scene", "build_scene", "native_window"]

#: Mass (kg) of a body whose model gives none.
DEFAULT_MASS = 1.0
#: Groove margin beyond the native slide range on each side: this fraction of
#: the range plus this fraction of the mechanism's size.
_GROOVE_MARGIN = (0.25, 0.05)
#: The slide servo's fixed anchor sits this many mechanism sizes behind the
#: line point, so the servo's length never passes through zero.
_SERVO_BACKOFF = 2.0


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
    lines = [j for j in mechanism.joints if isinstance(j, LineJoint) and j.body_a == name]
    pins = [
        mechanism.body(name).points[j.point] for j in mechanism.joints if isinstance(j, LineJoint) and j.body_b == name
    ]
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
    defaulted: list[str] = []
    mass = body.mass
    if mass is None:
        mass, defaulted = DEFAULT_MASS, defaulted + ["mass"]
    points = np.array(list(body.points.values()) + [np.asarray(g, dtype=float) for g in guides] or [np.zeros(2)])
    com = body.com
    if com is None:
        centroid = points.mean(axis=0)
        exact = _groove_free_com(mechanism, name, centroid)
        com = centroid if exact is None else exact
        defaulted.append("com" if exact is None else "com (on its groove line or pin)")
    inertia = body.inertia
    if inertia is not None:
        inertia = positive_inertia(mass, inertia, mechanism.size)  # a point mass: pymunk needs a moment > 0
    else:
        span = max((float(np.linalg.norm(p - q)) for p in points for q in points), default=0.0)
        length = max(span, 0.1 * mechanism.size)
        inertia, defaulted = mass * length * length / 12.0, defaulted + ["inertia"]
    if not (math.isfinite(mass) and mass > 0.0 and math.isfinite(inertia) and inertia > 0.0):
        raise ValueError(
            f"body {name}: expected a positive finite mass and moment of inertia, "
            f"found mass {mass} kg, inertia {inertia} kg m^2"
        )
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
    law: MotionLaw | _Shifted | None = None

    def before_step(self, t: float, dt: float) -> None:
        assert self.law is not None  # every drive is made with its law
        if self.kind == "motor":
            # SimpleMotor holds b.w - a.w = -rate at the end of the step
            assert isinstance(self.constraint, pm.SimpleMotor)
            _, qd, _ = self.law.at_time(t + dt)
            self.constraint.rate = -float(qd)
        elif self.kind == "kinematic-slide":
            assert self.body is not None and self.direction is not None  # set by build_scene
            step = (float(self.law.at_time(t + dt)[0]) - float(self.law.at_time(t)[0])) / dt
            v = self.sign * step * self.direction
            self.body.velocity = (float(v[0]), float(v[1]))
        elif self.kind == "slide-servo":
            # the velocity solved in this step moves the bodies in the next one
            assert isinstance(self.constraint, pm.PinJoint)
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

    def skewed_grooves(self) -> str:
        """Where a groove joint is not exact in pymunk (see :func:`_groove_free_com`):
        a moving line body's centre of mass off its line, or a moving pin
        body's away from its pin; "" if nowhere. One line, for failure reasons."""
        mech, tol = self.mechanism, 1e-9 * self.mechanism.size
        found = []
        for joint in mech.joints:
            if not isinstance(joint, LineJoint):
                continue
            line_body, pin_body = self.bodies[joint.body_a], self.bodies[joint.body_b]
            if line_body.body_type == pm.Body.DYNAMIC:
                r = np.array(line_body.center_of_gravity) - mech.body(joint.body_a).points[joint.line_point]
                off = abs(joint.direction[0] * r[1] - joint.direction[1] * r[0])
                if off > tol:
                    found.append(f"{joint.body_a}'s centre of mass {off:.3g} m off the line of {joint.name!r}")
            if pin_body.body_type == pm.Body.DYNAMIC:
                off = float(
                    np.linalg.norm(np.array(pin_body.center_of_gravity) - mech.body(joint.body_b).points[joint.point])
                )
                if off > tol:
                    found.append(f"{joint.body_b}'s centre of mass {off:.3g} m from its pin {joint.point!r}")
        if not found:
            return ""
        return (
            "pymunk's GrooveJoint holds a groove exactly only with the line body's centre of mass on the "
            "line and the pin body's at the pin; here " + "; ".join(found)
        )

    def step(self, t: float, dt: float) -> None:
        """Advance the space from t to t + dt (s)."""
        for drive in self.drives:
            if drive.kind != "kinematic-rate":
                drive.before_step(t, dt)
        for load in self.mechanism.loads:
            body = self.bodies[load.body]
            if body.body_type == pm.Body.DYNAMIC:
                factor = 1.0 if load.law is None else float(load.law.factor(t))  # the step's start
                at = body.local_to_world(tuple(float(x) for x in load.point))
                body.apply_force_at_world_point(tuple(factor * float(f) for f in load.force), at)
                body.torque += factor * float(load.torque)
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
        points that should coincide, from a point to its line, or between a gear
        pair's pitch arcs, and the largest error (rad) of a locked angle."""
        gap, lock = 0.0, 0.0
        for joint in self.mechanism.joints:
            apart, off = converter(_GAPS, joint, "pymunk")(self, joint)
            gap, lock = max(gap, apart), max(lock, off)
        return gap, lock

    def state(self, body: str, label: str | None):
        """A body point's (position, velocity) and the body's (angle, angular rate),
        the frame origin's where ``label`` is None (:meth:`xcheck.joints.Joint.coordinate`)."""
        b = self.bodies[body]
        if label is None:
            frame = _frame_origin(b)
            return frame[0], frame[1], b.angle, b.angular_velocity
        return self.world_point(body, label), self.point_velocity(body, label), b.angle, b.angular_velocity

    def inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """The drivers' values and rates as the bodies realise them, each (k,), SI."""
        mech = self.mechanism
        q, qd = np.empty(len(mech.drivers)), np.empty(len(mech.drivers))
        for k, driver in enumerate(mech.drivers):
            q[k], qd[k] = mech.joint(driver.joint).coordinate(self.state)
        return q, qd


def _frame_origin(body: pm.Body) -> tuple[np.ndarray, np.ndarray]:
    """A pymunk body's frame origin: position and velocity (m, m/s)."""
    p, v = body.local_to_world((0.0, 0.0)), body.velocity_at_local_point((0.0, 0.0))
    return np.array([p.x, p.y]), np.array([v.x, v.y])


def _pin_gap(scene: Scene, joint: Revolute) -> tuple[float, float]:
    d = scene.world_point(joint.body_a, joint.point_a) - scene.world_point(joint.body_b, joint.point_b)
    return float(math.hypot(*d)), 0.0


def _line_gap(scene: Scene, joint: LineJoint) -> tuple[float, float]:
    a = scene.bodies[joint.body_a]
    u = rotate(a.angle, joint.direction)
    r = scene.world_point(joint.body_b, joint.point) - scene.world_point(joint.body_a, joint.line_point)
    lock = 0.0
    if joint.locked_angle is not None:
        err = scene.bodies[joint.body_b].angle - a.angle - joint.locked_angle
        lock = abs((err + math.pi) % (2.0 * math.pi) - math.pi)
    return abs(float(u[0] * r[1] - u[1] * r[0])), lock


def _mesh_gap(scene: Scene, gear: GearPair) -> tuple[float, float]:
    """The arcs the pitch circles have slipped by (m): the gear pair's row."""
    angles = [0.0 if body == GROUND else scene.bodies[body].angle for body in gear.bodies]
    (a, b, c), (ka, kb, kc) = angles, gear.coefficients()
    return abs(ka * a + kb * b + kc * c - gear.sigma * gear.radius_b * gear.phase), 0.0


#: how far a joint has come apart, by its type
_GAPS: dict[type, Callable] = {Revolute: _pin_gap, LineJoint: _line_gap, GearPair: _mesh_gap}


def _pivot(mech: Mechanism, joint: Revolute, bodies: dict, grooves: dict) -> list[pm.Constraint]:
    """A revolute: a pivot joint at its two points."""
    points = (mech.body(body).points[label] for body, label in joint.anchors())
    return [pm.PivotJoint(bodies[joint.body_a], bodies[joint.body_b], *(tuple(p) for p in points))]


def _groove(mech: Mechanism, joint: LineJoint, bodies: dict, grooves: dict) -> list[pm.Constraint]:
    """A pin-in-slot: a groove on the line's body; a prismatic joint also locks the angle (a gear joint, ratio 1)."""
    a, b = bodies[joint.body_a], bodies[joint.body_b]
    _, start, end = grooves[joint.name]
    made: list[pm.Constraint] = [
        pm.GrooveJoint(a, b, tuple(start), tuple(end), tuple(mech.body(joint.body_b).points[joint.point]))
    ]
    if joint.locked_angle is not None:
        made.append(pm.GearJoint(a, b, float(joint.locked_angle), 1.0))
    return made


def _gear(mech: Mechanism, gear: GearPair, bodies: dict, grooves: dict) -> list[pm.Constraint]:
    """A gear pair: pymunk's gear joint, which keeps ratio phi_j - phi_i = phase of two
    bodies' absolute angles (:meth:`~xcheck.joints.GearPair.angle_coupling`)."""
    i, j, ratio, phase = gear.angle_coupling("pymunk's GearJoint couples two bodies' absolute angles")
    return [pm.GearJoint(bodies[i], bodies[j], phase, ratio)]


#: a joint's pymunk constraints, by its type
_CONSTRAINTS: dict[type, Callable] = {Revolute: _pivot, LineJoint: _groove, GearPair: _gear}


def _place(body: pm.Body, origin, angle: float, origin_velocity, omega: float) -> None:
    """Put a pymunk body's frame origin at ``origin`` with ``angle`` and the
    origin moving at ``origin_velocity`` (pymunk's velocity is that of the
    centre of gravity). The angle goes first: its setter turns the body about
    the centre of gravity."""
    body.angle = float(angle)
    body.position = (float(origin[0]), float(origin[1]))
    arm = rotate(angle, body.center_of_gravity)
    v = np.asarray(origin_velocity, dtype=float) + omega * np.array([-arm[1], arm[0]])
    body.velocity = (float(v[0]), float(v[1]))
    body.angular_velocity = float(omega)


def _slide_extent(mechanism: Mechanism, solution: Solution, joint) -> tuple[float, float]:
    """Smallest and largest slide (m) of a line joint over a native solution."""
    ok = solution.status <= Status.NEAR_SINGULAR
    la = solution.body(joint.body_a)
    r = (
        solution.point(joint.point, joint.body_b)["position"]
        - solution.point(joint.line_point, joint.body_a)["position"]
    )[ok]
    phi = la["angle"][ok]
    u = np.stack(
        [
            np.cos(phi) * joint.direction[0] - np.sin(phi) * joint.direction[1],
            np.sin(phi) * joint.direction[0] + np.cos(phi) * joint.direction[1],
        ],
        axis=1,
    )
    s = np.einsum("ij,ij->i", u, r)
    return float(s.min()), float(s.max())


def build_scene(
    kinematics: Kinematics,
    native: Solution,
    *,
    iterations: int = 10,
    error_bias: float | None = None,
    kinematic_inputs: bool = True,
    free: bool = False,
) -> Scene:
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
    kinematic_inputs : bool
        Prescribe the bodies whose input allows it (see the module notes);
        False drives every input by a motor or a slide servo.
    free : bool
        No driver at all: the mechanism moves freely (free motion).

    Returns
    -------
    Scene
    """
    mech = kinematics.mechanism
    if not np.all(native.status <= Status.NEAR_SINGULAR):
        raise ValueError("the native solution does not assemble over the whole window")
    space = pm.Space()
    space.iterations = int(iterations)
    space.gravity = (float(mech.gravity[0]), float(mech.gravity[1]))
    bodies = {GROUND: space.static_body}
    defaults = {}
    drives: list[_Drive] = []

    # prescribed bodies: a constant-rate angle on a revolute to the ground, a
    # slide on a prismatic joint to the ground
    prescribed: dict[str, _Drive] = {}
    for k, driver in enumerate(mech.drivers if kinematic_inputs and not free else ()):
        joint = mech.joint(driver.joint)
        on_ground = GROUND in (joint.body_a, joint.body_b) and joint.body_a != joint.body_b
        moving = joint.body_b if joint.body_a == GROUND else joint.body_a
        sign = 1.0 if joint.body_a == GROUND else -1.0
        if driver.quantity == "angle" and on_ground and driver.law.kind == "constant-rate" and moving not in prescribed:
            prescribed[moving] = _Drive(k, "kinematic-rate", sign=sign, law=driver.law)
        elif driver.quantity == "slide" and on_ground and joint.locked_angle is not None and moving not in prescribed:
            # the slide grows when body_b moves along the line (line in body_a)
            # or when body_a moves against it (line in the moving body)
            prescribed[moving] = _Drive(k, "kinematic-slide", sign=sign, law=driver.law)

    grooves = {}
    for joint in mech.joints:
        if isinstance(joint, LineJoint):
            low, high = _slide_extent(mech, native, joint)
            pad = _GROOVE_MARGIN[0] * (high - low) + _GROOVE_MARGIN[1] * mech.size
            base = mech.body(joint.body_a).points[joint.line_point]
            grooves[joint.name] = (
                joint.body_a,
                base + (low - pad) * joint.direction,
                base + (high + pad) * joint.direction,
            )

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
                pivot = body.points[joint.tree_points[1 if joint.body_b == body.name else 0]]  # see prescribed
                pb.center_of_gravity = (float(pivot[0]), float(pivot[1]))
            else:
                joint = mech.joint(mech.drivers[drive.driver_index].joint)
                assert isinstance(joint, LineJoint)  # see prescribed: a prismatic joint
                line_angle = 0.0 if joint.body_a == GROUND else angle
                drive.direction = rotate(line_angle, joint.direction)
            drives.append(drive)
        _place(pb, origin, angle, frame["velocity"][first], float(frame["omega"][first]))
        if drive is not None and drive.kind == "kinematic-rate":
            assert isinstance(drive.law, MotionLaw)
            pb.angular_velocity = drive.sign * drive.law.rate
        space.add(pb)
        bodies[body.name] = pb

    def dynamic(*names):
        return any(bodies[n].body_type == pm.Body.DYNAMIC for n in names)

    constraints: dict[str, list] = {}
    for joint in mech.joints:
        a, b = bodies[joint.body_a], bodies[joint.body_b]
        made: list[pm.Constraint] = []
        if dynamic(*joint.bodies):
            made = converter(_CONSTRAINTS, joint, "pymunk")(mech, joint, bodies, grooves)
        constraints[joint.name] = made

    for k, driver in enumerate(() if free else mech.drivers):
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
            assert isinstance(joint, LineJoint)  # a slide is on a line joint
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
    _add_springs(mech, space, bodies)
    drives.sort(key=lambda d: d.driver_index)
    return Scene(mech, space, bodies, constraints, grooves, drives, defaults)


def _add_springs(mech: Mechanism, space: pm.Space, bodies: dict) -> None:
    """The file's linear spring-dampers as pymunk ``DampedSpring`` s (the same law,
    tension k (l - l0) + c dl/dt, with pymunk's implicit damping) and its rotational
    ones as ``DampedRotarySpring`` s; a spring with both ends on one body, or on
    bodies whose motion is prescribed or fixed, moves nothing and is left out."""
    owners = mech.point_owners
    for spring in mech.springs:
        (first, p), (second, r) = ((owners[label], mech.body(owners[label]).points[label]) for label in spring.points)
        ends = (bodies[first], bodies[second])
        if first == second or all(b.body_type != pm.Body.DYNAMIC for b in ends):
            continue
        damped = pm.DampedSpring(
            bodies[first],
            bodies[second],
            (float(p[0]), float(p[1])),
            (float(r[0]), float(r[1])),
            float(spring.rest_length),
            float(spring.stiffness),
            float(spring.damping),
        )
        damped.collide_bodies = False
        space.add(damped)
    for twist in mech.rotational_springs:
        a, b = bodies[twist.body_a], bodies[twist.body_b]
        if a.body_type != pm.Body.DYNAMIC and b.body_type != pm.Body.DYNAMIC:
            continue
        # Chipmunk's relative angle is angle_a - angle_b and its torque on b is k (relative - rest):
        # with rest = -rest_angle that is the file's -k (angle_b - angle_a - rest_angle)
        rotary = pm.DampedRotarySpring(a, b, -float(twist.rest_angle), float(twist.stiffness), float(twist.damping))
        rotary.collide_bodies = False
        space.add(rotary)


@dataclass(frozen=True)
class _Shifted:
    """A motion law shifted by a constant (the slide servo's length)."""

    law: MotionLaw
    offset: float

    def at_time(self, t):
        q, qd, qdd = self.law.at_time(t)
        return q + self.offset, qd, qdd


def native_window(
    kinematics: Kinematics, branch: str | None = None, count: int = 401
) -> tuple[SimulationWindow, Solution]:
    """The simulation window and the native solution at ``count`` equally
    spaced times over it; ValueError if the native solver does not assemble
    the mechanism all along."""
    window = simulation_window(kinematics, branch)
    q, qd, qdd = window.inputs(kinematics, window.times(count))
    native = kinematics.solve(q, qd, qdd, branch=branch)
    if not np.all(native.status <= Status.NEAR_SINGULAR):
        bad = int(np.argmax(native.status > Status.NEAR_SINGULAR))
        raise ValueError(
            f"the native solver does not assemble the mechanism at t = "
            f"{window.times(count)[bad]:.6g} s of the window ({Status(native.status[bad]).message})"
        )
    return window, native
