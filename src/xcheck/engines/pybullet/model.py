"""PyBullet's model of a mechanism, shared by its free and driven modes: a
Featherstone multibody (``createMultiBody``) whose loops are closed by
point-to-point constraints (``createConstraint(JOINT_POINT2POINT)``), stepped
by PyBullet's semi-implicit Euler with its iterative constraint solver
(:class:`Setting`).

The tree is :func:`xcheck.topology.spanning_tree`'s: the ground is the fixed
base, each moving body a link hung from its parent by a revolute joint about z
or a prismatic joint in the plane (turned by its locked angle); the link frame
sits at the joint's point on the body with the body's orientation (a
revolute's coordinate is the child's angle minus the parent's, a prismatic's
the slide displacement). Each cut revolute is a point-to-point constraint
between its two points (its z row is idle: the tree keeps the plane). A
pin-in-slot joint, or a loop cut at a prismatic joint, is not converted
(:class:`~xcheck.engines.NotApplicable`). PyBullet's defaults that are not
the model are set off: the joint velocity motors (force 0), the multibody's
linear and angular damping (0.04 by default) and the joint speed limit (100
rad/s by default; Andrews' crank turns faster). Gravity is the mechanism's, in
the plane; the loads (a time law at each step's start), the springs and the
rotational springs are external forces and torques applied before every step
(PyBullet clears them after each).

Two PyBullet 3.2.7 pitfalls, measured: ``changeDynamics`` with
``localInertiaDiagonal`` and ``linearDamping``, ``angularDamping`` or
``maxJointVelocity`` in one call sets the inertia to zero (so the inertia gets
a call of its own, checked with ``getDynamicsInfo``); ``getLinkState``'s link
frame position ([4]) is rounded to float32 (a 1e-8 relative floor), so
positions are taken from the centre of mass ([0]) and the joint angles.
"""

from __future__ import annotations

import functools
import importlib
import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from xcheck.dynamics._forces import require_mass_data
from xcheck.engines._contract import positive_inertia
from xcheck.engines._frames import native_point_state, world_point
from xcheck.joints import GearPair, LineJoint, PinInSlot, Prismatic, Revolute, converter
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND, Mechanism
from xcheck.topology import Topology, spanning_tree


def _import_quietly():
    """pybullet, imported with its build-time line (printed by its C code on
    file descriptor 2) kept off xcheck's output; an import error still raises."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            return importlib.import_module("pybullet")
    finally:
        os.dup2(saved, 2)
        os.close(saved)


p = _import_quietly()

__all__ = ["CONSTRAINT_FORCE", "Setting", "Multibody", "build", "set_state", "Forces", "velocity", "energy", "p"]

#: the gear constraint's error reduction (PyBullet's default, 0, corrects no slip of the mesh)
GEAR_ERP = 1.0
#: joint speed limit set on every link (PyBullet's default, 100 rad/s, is not the model's)
MAX_JOINT_VELOCITY = 1e6
#: the force bound of every loop and gear constraint, N: none a mechanism reaches (PyBullet's
#: default, 500 N, let the loops of a crank-rocker of tonnes come apart)
CONSTRAINT_FORCE = 1e30


@dataclass(frozen=True)
class Setting:
    """PyBullet's solver: ``iterations`` per step (``numSolverIterations``),
    ``residual`` (``solverResidualThreshold``; None: PyBullet's default) and the
    constraints' error reduction ``erp`` (None: PyBullet's default)."""

    iterations: int
    residual: float | None = None
    erp: float | None = None

    @property
    def integrator(self) -> str:
        """The integrator and solver as a row shows them."""
        return (
            f"semi-implicit Euler, {self.iterations} iterations"
            + ("" if self.residual is None else f", residual threshold {self.residual:g}")
            + ("" if self.erp is None else f", erp {self.erp:g}")
        )

    def apply(self, client: int, dt: float, constraints=()) -> None:
        """Set the step ``dt`` (s) and this solver on the client and its loop constraints."""
        parameters = dict(fixedTimeStep=dt, numSolverIterations=self.iterations, numSubSteps=0)
        if self.residual is not None:
            parameters["solverResidualThreshold"] = self.residual
        if self.erp is not None:
            parameters["erp"] = self.erp
        p.setPhysicsEngineParameter(**parameters, physicsClientId=client)
        for cid in constraints:
            if self.erp is not None:
                p.changeConstraint(cid, erp=self.erp, physicsClientId=client)


@dataclass
class Multibody:
    """The mechanism in one PyBullet client.

    Attributes
    ----------
    client : int
        The physics client (DIRECT).
    uid : int
        The multibody.
    links : dict of str to int
        Moving body -> link index (= joint index).
    parents : dict of str to str
        Moving body -> its parent body in the tree (GROUND for the base).
    pivots : dict of str to ndarray (2,)
        Moving body -> the point of its tree joint in its body frame, m (the link frame's origin).
    turns : dict of str to float
        Moving body -> its angle minus its parent's at joint coordinate 0, rad (a prismatic's locked angle).
    sliding : list of bool
        Per link: whether its joint is prismatic (else revolute).
    coms : dict of str to ndarray (2,)
        Moving body -> its centre of mass in its body frame, m.
    cuts : list of (str, ndarray, str, ndarray)
        Per loop constraint: (body, point in its frame, body, point in its frame).
    constraints : list of int
        The constraint ids.
    """

    client: int
    uid: int
    links: dict[str, int]
    parents: dict[str, str]
    pivots: dict[str, np.ndarray]
    turns: dict[str, float]
    sliding: list[bool]
    coms: dict[str, np.ndarray]
    cuts: list[tuple[str, np.ndarray, str, np.ndarray]]
    constraints: list[int]

    def angles(self) -> dict[str, tuple[float, float]]:
        """Each moving body's angle (rad, continuous: the sum of joint coordinates) and rate (rad/s)."""
        states = p.getJointStates(self.uid, list(self.links.values()), physicsClientId=self.client)
        joint = {name: (states[i][0], states[i][1]) for i, name in enumerate(self.links)}
        out: dict[str, tuple[float, float]] = {}
        for name, k in self.links.items():  # parents first (tree order)
            base = out.get(self.parents[name], (0.0, 0.0))
            turn = self.turns[name]
            out[name] = (
                (base[0] + turn, base[1])
                if self.sliding[k]
                else (base[0] + turn + joint[name][0], base[1] + joint[name][1])
            )
        return out

    def frames(self) -> dict[str, tuple[np.ndarray, float, np.ndarray, float, np.ndarray]]:
        """Per moving body: body-frame origin (2,) m, angle rad, centre-of-mass velocity (2,) m/s, rate
        rad/s and centre-of-mass position (2,) m."""
        index = list(self.links.values())
        states = p.getLinkStates(
            self.uid, index, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=self.client
        )
        angles = self.angles()
        out = {}
        for i, name in enumerate(self.links):
            phi, omega = angles[name]
            # from the centre of mass (getLinkState's link-frame position, [4], is rounded to float32)
            origin = np.asarray(states[i][0][:2]) - rotate(phi, self.coms[name])
            out[name] = (origin, phi, np.asarray(states[i][6][:2]), omega, np.asarray(states[i][0][:2]))
        return out


def build(kinematics: Kinematics, client: int) -> Multibody:
    """The mechanism as a PyBullet multibody in ``client`` (see the module notes).

    Raises
    ------
    NotApplicable
        If the mechanism has a pin-in-slot joint or a loop cut at a prismatic joint.
    ModelError
        If a moving body has no mass data.
    """
    mech = kinematics.mechanism
    for joint in mech.joints:  # what cannot be converted, said before any work
        if joint.connects:
            converter(_LINKS, joint, "PyBullet")
    require_mass_data(mech)
    topology = spanning_tree(mech)
    closures = [converter(_LOOPS, cut, "PyBullet") for cut in topology.cuts]
    size = kinematics.system.size
    links: dict[str, int] = {}
    parents: dict[str, str] = {}
    pivots: dict[str, np.ndarray] = {}
    turns: dict[str, float] = {}
    coms: dict[str, np.ndarray] = {}
    masses, positions, orientations, inertial, parent_index, inertias, types, axes = ([] for _ in range(8))
    for tj in _depth_first(topology.tree):
        body = mech.body(tj.child)
        l_parent, l_child, turn, kind, axis = converter(_LINKS, tj.joint, "PyBullet")(tj, tj.joint)
        s_parent = np.asarray(mech.body(tj.parent).points[l_parent], dtype=float)
        s_child = np.asarray(body.points[l_child], dtype=float)
        offset = pivots[tj.parent] if tj.parent != GROUND else np.zeros(2)
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        assert body.mass is not None and body.inertia is not None
        links[tj.child] = len(links)
        parents[tj.child] = tj.parent
        pivots[tj.child] = s_child
        turns[tj.child] = float(turn)
        coms[tj.child] = com
        masses.append(float(body.mass))
        positions.append([*(s_parent - offset), 0.0])
        orientations.append([0.0, 0.0, math.sin(turn / 2.0), math.cos(turn / 2.0)])
        inertial.append([*(com - s_child), 0.0])
        parent_index.append(0 if tj.parent == GROUND else links[tj.parent] + 1)
        inertias.append(positive_inertia(float(body.mass), float(body.inertia), size))
        types.append(kind)
        axes.append(axis)
    n = len(links)
    uid = p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=-1,
        baseVisualShapeIndex=-1,
        basePosition=[0.0, 0.0, 0.0],
        baseOrientation=[0.0, 0.0, 0.0, 1.0],
        linkMasses=masses,
        linkCollisionShapeIndices=[-1] * n,
        linkVisualShapeIndices=[-1] * n,
        linkPositions=positions,
        linkOrientations=orientations,
        linkInertialFramePositions=inertial,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
        linkParentIndices=parent_index,
        linkJointTypes=types,
        linkJointAxis=axes,
        useMaximalCoordinates=0,
        physicsClientId=client,
    )
    found = [p.getJointInfo(uid, k, physicsClientId=client)[16] for k in range(n)]
    if found != [i - 1 for i in parent_index]:  # PyBullet orders links depth-first: so were they given
        raise RuntimeError(f"PyBullet reordered the links: parents {found}, expected {[i - 1 for i in parent_index]}")
    p.changeDynamics(uid, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
    for k, inertia in enumerate(inertias):  # about z; the other axes only need to be positive
        # the inertia in a call of its own: with linearDamping, angularDamping or
        # maxJointVelocity in the same call, PyBullet 3.2.7 sets it to zero
        p.changeDynamics(uid, k, localInertiaDiagonal=[inertia] * 3, physicsClientId=client)
        p.changeDynamics(uid, k, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0, physicsClientId=client)
        p.changeDynamics(uid, k, maxJointVelocity=MAX_JOINT_VELOCITY, physicsClientId=client)
        held = p.getDynamicsInfo(uid, k, physicsClientId=client)[2][2]
        if not math.isclose(held, inertia, rel_tol=1e-12):
            raise RuntimeError(f"PyBullet holds the inertia {held:g} kg m^2 for {inertia:g} on link {k}")
    p.setJointMotorControlArray(uid, list(range(n)), p.VELOCITY_CONTROL, forces=[0.0] * n, physicsClientId=client)
    cuts, constraints = [], []
    for cut, close in zip(topology.cuts, closures):
        cid, ends = close(mech, cut, uid, links, topology, client)
        constraints.append(cid)
        if ends is not None:
            cuts.append(ends)
    return Multibody(
        client, uid, links, parents, pivots, turns, [t == p.JOINT_PRISMATIC for t in types], coms, cuts, constraints
    )


def _revolute_link(tj, j: Revolute):
    """A revolute: a revolute link, its frame at the pin with the body's orientation."""
    l_parent, l_child = j.tree_points[::-1] if tj.reversed else j.tree_points
    return l_parent, l_child, 0.0, p.JOINT_REVOLUTE, [0.0, 0.0, 1.0]


def _prismatic_link(tj, j: Prismatic):
    """A prismatic joint: a prismatic link, the child's joint point on the parent's, turned by the locked angle."""
    if not tj.reversed:  # the line is the parent's: the child's point slides along it
        l_parent, l_child, turn, direction = j.line_point, j.point, j.angle, rotate(-j.angle, j.direction)
    else:  # the line is the child's: its line point slides back along it from the parent's point
        l_parent, l_child, turn, direction = j.point, j.line_point, -j.angle, -np.asarray(j.direction)
    return l_parent, l_child, turn, p.JOINT_PRISMATIC, [float(direction[0]), float(direction[1]), 0.0]


#: a tree joint's link, by its type: (its point on the parent and on the child, turn, PyBullet joint type, axis)
_LINKS: dict[type, Callable | str] = {
    Revolute: _revolute_link,
    Prismatic: _prismatic_link,
    PinInSlot: "joint {name!r} is a pin-in-slot: xcheck's PyBullet model has revolute and prismatic links only "
    "(a pin-in-slot would need a massless intermediate link, not converted)",
}


def _point2point(mech: Mechanism, cut: Revolute, uid: int, links: dict, topology: Topology, client: int):
    """A loop cut at a revolute: a point-to-point constraint between its two points
    (each in its link's frame, the link's centre of mass)."""
    ends = []
    for name, label in cut.anchors():
        point = np.asarray(mech.body(name).points[label], dtype=float)
        if name == GROUND:
            ends.append((-1, point, name, point))
        else:
            body = mech.body(name)
            com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
            ends.append((links[name], point - com, name, point))  # frame: the link's centre of mass
    (la, fa, na, pa), (lb, fb, nb, pb) = ends
    cid = p.createConstraint(
        uid, la, uid, lb, p.JOINT_POINT2POINT, [0.0, 0.0, 0.0], [*fa, 0.0], [*fb, 0.0], physicsClientId=client
    )
    p.changeConstraint(cid, maxForce=CONSTRAINT_FORCE, physicsClientId=client)
    return cid, (na, pa, nb, pb)


def _gear(mech: Mechanism, gear: GearPair, uid: int, links: dict, topology: Topology, client: int):
    """A gear pair: PyBullet's gear constraint between its gears' revolute links, q_A + ratio q_B =
    target. Each link's coordinate is its child's angle minus its parent's, the gear's rotation
    relative to the carrier up to a sign (-1 where the carrier is the child): the mesh is
    q_pin_b = s_b phase + k q_pin_a (:meth:`~xcheck.joints.GearPair.tree_coupling`): ratio -k."""
    tree = {tj.joint.name: tj for tj in topology.tree}
    k, _, s_b = gear.tree_coupling(
        lambda pin, body: None if pin not in tree else 1.0 if tree[pin].child == body else -1.0,
        "PyBullet's gear constraint",
    )
    pin_links = [links[tree[pin].child] for pin in (gear.pin_a, gear.pin_b)]
    cid = p.createConstraint(
        uid, pin_links[1], uid, pin_links[0], p.JOINT_GEAR, [0.0, 0.0, 1.0], [0.0] * 3, [0.0] * 3,
        physicsClientId=client,
    )  # fmt: skip
    # its position error corrected at every step (erp 1): with PyBullet's default (0) the velocity rows
    # alone let the mesh slip, which the ladder shows (positions at order 1 instead of 2)
    p.changeConstraint(
        cid,
        gearRatio=-k,
        relativePositionTarget=s_b * gear.phase,
        maxForce=CONSTRAINT_FORCE,
        erp=GEAR_ERP,
        physicsClientId=client,
    )
    return cid, None


#: how a loop cut at each joint type is closed: (the constraint's id, the cut's two points or None)
_LOOPS: dict[type, Callable | str] = {
    Revolute: _point2point,
    LineJoint: "a loop is cut at the {kind} joint {name!r}: xcheck's PyBullet model closes loops with "
    "point-to-point constraints only (PyBullet's multibody slider constraint is not converted)",
    GearPair: _gear,
}


def _depth_first(tree) -> list:
    """The tree joints in depth-first order from the ground, children in tree order
    (PyBullet's order of the links of a multibody)."""
    children: dict[str, list] = {}
    for tj in tree:
        children.setdefault(tj.parent, []).append(tj)
    out: list = []

    def visit(body: str) -> None:
        for tj in children.get(body, []):
            out.append(tj)
            visit(tj.child)

    visit(GROUND)
    return out


def set_state(mb: Multibody, kinematics: Kinematics, q: np.ndarray, qd: np.ndarray) -> None:
    """Put the multibody at native body coordinates ``q`` and rates ``qd`` (x, y, phi per moving
    body, in ``mechanism.moving_bodies`` order): revolute coordinates are the relative angles,
    prismatic ones the slide displacement ``direction . (r_point - r_line_point)`` in ``body_a``'s frame.
    """
    mech = kinematics.mechanism
    index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}

    state = functools.partial(native_point_state, index, q, qd)

    def points(body: str, label: str) -> np.ndarray:
        return mech.body(body).points[label]

    topology = spanning_tree(mech)
    for tj in topology.tree:
        name, j = tj.child, tj.joint
        if j.tree_axes == ("hinge",):  # a revolute link: the child's angle minus its parent's
            _, _, phi, omega = state(name)
            _, _, phi0, omega0 = state(tj.parent)
            value, rate = phi - phi0 - mb.turns[name], omega - omega0
        else:  # a prismatic link: its joint's slide displacement
            value, rate = j.coordinate(lambda body, label: state(body, None if label is None else points(body, label)))
        p.resetJointState(
            mb.uid, mb.links[name], targetValue=float(value), targetVelocity=float(rate), physicsClientId=mb.client
        )
    frames = mb.frames()
    size = kinematics.system.size
    for name, k in index.items():  # the conversion checked: PyBullet's state is the native one
        origin, phi, v_com, omega, _ = frames[name]
        body = mech.body(name)
        _, v_native, _, _ = state(name, np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float))
        miss = max(float(np.hypot(*(origin - q[k : k + 2]))), abs(phi - q[k + 2]) * size)
        if miss > 1e-9 * size:
            raise RuntimeError(f"PyBullet's {name} starts {miss:.3g} m from the native start")
        speed = max(float(np.hypot(*qd[k : k + 2])), abs(qd[k + 2]) * size, 1.0)
        off = max(float(np.hypot(*(v_com - v_native))), abs(omega - qd[k + 2]) * size)
        if off > 1e-9 * speed:
            raise RuntimeError(f"PyBullet's {name} starts with a velocity {off:.3g} m/s from the native one")


class Forces:
    """The loads (time laws at the step's start), the springs and the rotational springs,
    applied before every step (PyBullet clears them after it)."""

    def __init__(self, kinematics: Kinematics, mb: Multibody):
        mech = kinematics.mechanism
        self.mb = mb
        self.loads = [
            (load.body, np.asarray(load.point, float), np.asarray(load.force, float), float(load.torque), load.law)
            for load in mech.loads
            if load.body in mb.links
        ]
        self.twists = [(t.body_a, t.body_b, t.stiffness, t.rest_angle, t.damping) for t in mech.rotational_springs]
        owners = mech.point_owners
        self.springs = [
            (
                owners[s.points[0]],
                np.asarray(mech.body(owners[s.points[0]]).points[s.points[0]], float),
                owners[s.points[1]],
                np.asarray(mech.body(owners[s.points[1]]).points[s.points[1]], float),
                s.stiffness,
                s.rest_length,
                s.damping,
            )
            for s in mech.springs
        ]
        self.active = bool(self.loads or self.springs or self.twists)

    def apply(self, frames, t: float) -> None:
        """Apply everything at the state ``frames`` (:meth:`Multibody.frames`) and time t (s)."""
        mb = self.mb
        for name, point, force, torque, law in self.loads:
            if law is not None:
                factor = float(law.factor(t))
                force, torque = factor * force, factor * torque
            if np.any(force):
                at = world_point(frames, name, point)
                p.applyExternalForce(
                    mb.uid, mb.links[name], [*force, 0.0], [*at, 0.0], p.WORLD_FRAME, physicsClientId=mb.client
                )
            if torque:
                p.applyExternalTorque(
                    mb.uid, mb.links[name], [0.0, 0.0, torque], p.WORLD_FRAME, physicsClientId=mb.client
                )
        for first, s1, second, s2, stiffness, rest, damping in self.springs:
            r1, r2 = world_point(frames, first, s1), world_point(frames, second, s2)
            d = r2 - r1
            length = float(np.hypot(d[0], d[1]))
            unit = d / length if length > 0.0 else np.zeros(2)
            tension = stiffness * (length - rest)
            if damping:
                tension += damping * float(unit @ (velocity(frames, second, s2) - velocity(frames, first, s1)))
            for name, at, force in ((first, r1, tension * unit), (second, r2, -tension * unit)):
                if name != GROUND:
                    p.applyExternalForce(
                        mb.uid, mb.links[name], [*force, 0.0], [*at, 0.0], p.WORLD_FRAME, physicsClientId=mb.client
                    )
        for first, second, stiffness, rest, damping in self.twists:
            # the bodies' angles are continuous (sums of joint angles along the tree)
            (phi_a, w_a), (phi_b, w_b) = ((0.0, 0.0) if n == GROUND else frames[n][1:4:2] for n in (first, second))
            torque = -stiffness * (phi_b - phi_a - rest) - damping * (w_b - w_a)  # on the second body
            for name, sign in ((second, 1.0), (first, -1.0)):
                if name != GROUND:
                    p.applyExternalTorque(
                        mb.uid, mb.links[name], [0.0, 0.0, sign * torque], p.WORLD_FRAME, physicsClientId=mb.client
                    )


def velocity(frames, name: str, point: np.ndarray) -> np.ndarray:
    """Velocity of a body point, m/s: v_com + w x (r - r_com)."""
    if name == GROUND:
        return np.zeros(2)
    _, _, v_com, omega, com = frames[name]
    arm = world_point(frames, name, point) - com
    return v_com + omega * np.array([-arm[1], arm[0]])


def energy(kinematics: Kinematics, mb: Multibody, frames, turned: dict[str, float]) -> float:
    """Kinetic + gravitational + spring energy (linear and rotational) minus the constant loads' potential, J."""
    mech = kinematics.mechanism
    g = np.asarray(mech.gravity, dtype=float)
    total = 0.0
    for name in mb.links:
        body = mech.body(name)
        origin, phi, v_com, omega, _ = frames[name]
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        mass, inertia = float(body.mass or 0.0), float(body.inertia or 0.0)
        total += 0.5 * mass * float(v_com @ v_com) + 0.5 * inertia * omega * omega
        total -= mass * float(g @ (origin + rotate(phi, com)))
    for load in mech.loads:
        if load.body in mb.links:
            at = world_point(frames, load.body, np.asarray(load.point, float))
            total -= float(np.asarray(load.force, float) @ at) + float(load.torque) * turned[load.body]
    owners = mech.point_owners
    for s in mech.springs:
        a, b = (world_point(frames, owners[x], np.asarray(mech.body(owners[x]).points[x], float)) for x in s.points)
        total += 0.5 * s.stiffness * (float(np.hypot(*(b - a))) - s.rest_length) ** 2
    for t in mech.rotational_springs:
        angle = (turned[t.body_b] if t.body_b != GROUND else 0.0) - (turned[t.body_a] if t.body_a != GROUND else 0.0)
        total += 0.5 * t.stiffness * (angle - t.rest_angle) ** 2
    return total
