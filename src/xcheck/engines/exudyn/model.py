"""Exudyn's model of a mechanism, shared by its free and driven modes and its
script writer: 2-D rigid bodies joined by Exudyn's index-3 joints, integrated
by Exudyn's implicit generalized-alpha solver (:class:`Setting`).

The model (:func:`build_system`): one ``NodeRigidBody2D`` + ``ObjectRigidBody2D``
per moving body, its node at the centre of mass (Exudyn's reference point is the
centre of mass; xcheck's body coordinates are the frame origin, so every marker
sits at ``point - com`` in the body frame); a revolute joint is an
``ObjectJointRevolute2D`` between two ``MarkerBodyPosition`` s; a prismatic joint
an ``ObjectJointPrismatic2D`` between ``MarkerBodyRigid`` s with its rotation
locked at the file's angle, a pin-in-slot the same joint with
``constrainRotation`` off (the line is fixed in ``body_a``: marker 1 and its
normal are ``body_a`` 's, marker 0 is the pin). Gravity is a force m g at each
centre of mass, the constant loads ``LoadForceVector`` (global direction) at
their point and ``LoadTorqueVector``, the springs ``ObjectConnectorSpringDamper``
(the same law: k (l - l0) + c dl/dt along the line of the two points), the
rotational springs ``ObjectConnectorCoordinateSpringDamper`` s on the two
bodies' angle coordinates, a load's time law Exudyn's load user function. A point
mass (inertia 0) gets :data:`xcheck.engines.POINT_MASS_INERTIA` of m size^2.
A massless moving body cannot be held (its mass matrix is singular):
:class:`~xcheck.engines.NotApplicable`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from xcheck.engines._contract import NotApplicable, positive_inertia
from xcheck.joints import GearPair, LineJoint, Revolute, converter
from xcheck.kinematics import rotate
from xcheck.model import GROUND, Mechanism

__all__ = [
    "NEWTON_ROUND_OFF",
    "ExudynModel",
    "Setting",
    "build_system",
    "energy",
    "joint_gaps",
    "matched",
    "newton_floor",
    "refuse",
    "solver_settings",
]


#: Newton's absolute tolerance is at least this many units in the last place of the mechanism's
#: largest generalized force: its residual (N and N m) cannot fall below its round-off, and on a
#: crank-rocker of tonnes at 1 km it stalled above 1e-10 of its first iterate (Newton failed)
NEWTON_ROUND_OFF = 100.0


def newton_floor(mech: Mechanism, floors: dict[str, float]) -> float:
    """The least absolute tolerance Newton's residual can meet: :data:`NEWTON_ROUND_OFF`
    eps times the mechanism's moment scale, N m (:func:`xcheck.dynamics.force_floors` of
    its masses and ``floors``, :func:`xcheck.results.scale_floors`)."""
    from xcheck.dynamics import force_floors

    return NEWTON_ROUND_OFF * float(np.finfo(float).eps) * force_floors(mech, floors)["N m"]


@dataclass(frozen=True)
class Setting:
    """Exudyn's generalized-alpha solver as a run uses it.

    Attributes
    ----------
    spectral_radius : float
        rho_infinity of the generalized-alpha method (1: no numerical damping).
    index2 : bool
        Constraints at velocity level (index 2) instead of position level (index 3),
        with Newmark's trapezoidal rule (Exudyn's TrapezoidalIndex2; the spectral
        radius plays no part).
    newton_tolerance : float or None
        Newton's relative and absolute tolerance (None: Exudyn's, 1e-8 relative,
        1e-10 absolute).
    """

    spectral_radius: float
    index2: bool = False
    newton_tolerance: float | None = None

    @property
    def integrator(self) -> str:
        if self.index2:  # Exudyn's TrapezoidalIndex2 solver
            text = "trapezoidal (Newmark 1/4, 1/2), index 2"
        else:
            text = f"gen-alpha rho {self.spectral_radius:g}, index 3"
        return text + (f", Newton tol {self.newton_tolerance:g}" if self.newton_tolerance else "")


@dataclass
class ExudynModel:
    """An Exudyn system of a mechanism and what reads it back.

    Attributes
    ----------
    container : exudyn.SystemContainer
    mbs : exudyn.MainSystem
    nodes : dict of str to int
        Per moving body, its node.
    com : dict of str to ndarray, shape (2,)
        Per moving body, its centre of mass in the body frame, m.
    reference : dict of str to ndarray, shape (3,)
        Per moving body, the node's reference coordinates (x, y of the centre of mass, phi).
    """

    container: Any
    mbs: Any
    nodes: dict
    com: dict
    reference: dict


def refuse(mech: Mechanism) -> None:
    """NotApplicable if Exudyn cannot hold the mechanism as built here."""
    if mech.without_mass:
        raise NotApplicable(f"no mass data for {', '.join(mech.without_mass)}")
    massless = [b.name for b in mech.moving_bodies if not (b.mass or 0.0) > 0.0]
    if massless:
        raise NotApplicable(
            f"massless body {massless[0]}: Exudyn's RigidBody2D needs a positive mass (its mass matrix is singular)"
        )
    for joint in mech.joints:
        converter(_JOINTS, joint, "Exudyn")


def _revolute(mech: Mechanism, joint: Revolute, ei, mbs, nodes, reference, position_marker, rigid_marker):
    """A revolute: Exudyn's 2-D revolute joint between its two points."""
    markers = [position_marker(body, label) for body, label in joint.anchors()]
    return ei.ObjectJointRevolute2D(markerNumbers=markers, visualization=ei.VObjectJointRevolute2D(show=False))


def _prismatic(mech: Mechanism, joint: LineJoint, ei, mbs, nodes, reference, position_marker, rigid_marker):
    """A line joint: Exudyn's 2-D prismatic joint, (p_line - p_pin) . A_a n = 0 with marker 0 the pin
    (body_b) and marker 1 the line (body_a); a prismatic joint also keeps the pin's axis A_b t0 (= A_a d
    at the locked angle) normal to A_a n (constrainRotation)."""
    d = np.asarray(joint.direction, dtype=float)
    normal = np.array([-d[1], d[0]])
    axis = rotate(-(joint.locked_angle or 0.0), d)
    pin = rigid_marker(joint.body_b, mech.body(joint.body_b).points[joint.point])
    line = rigid_marker(joint.body_a, mech.body(joint.body_a).points[joint.line_point])
    return ei.ObjectJointPrismatic2D(
        markerNumbers=[pin, line],
        axisMarker0=[float(axis[0]), float(axis[1]), 0.0],
        normalMarker1=[float(normal[0]), float(normal[1]), 0.0],
        constrainRotation=joint.locked_angle is not None,
        visualization=ei.VObjectJointPrismatic2D(show=False),
    )


def _gear(mech: Mechanism, gear: GearPair, ei, mbs, nodes, reference, position_marker, rigid_marker):
    """A gear pair: Exudyn's coordinate constraint, factor1 q_j - q_i = offset, between two nodes'
    angle coordinates q (displacements from their reference angles): ratio phi_j - phi_i = phase
    (:meth:`~xcheck.joints.GearPair.angle_coupling`)."""
    i, j, ratio, phase = gear.angle_coupling("Exudyn's coordinate constraint couples two coordinates")
    markers = [mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=nodes[body], coordinate=2)) for body in (i, j)]
    offset = phase - ratio * reference[j][2] + reference[i][2]
    return ei.CoordinateConstraint(markerNumbers=markers, factor1=ratio, offset=offset)


#: a joint as an Exudyn object, by its type
_JOINTS: dict[type, Callable] = {Revolute: _revolute, LineJoint: _prismatic, GearPair: _gear}


def _pin_gap(joint: Revolute, where, angles: dict, size: float) -> np.ndarray:
    gap = where(joint.body_a, joint.point_a) - where(joint.body_b, joint.point_b)
    return np.hypot(gap[:, 0], gap[:, 1])


def _line_gap(joint: LineJoint, where, angles: dict, size: float) -> np.ndarray:
    phi_a = angles[joint.body_a] if joint.body_a != GROUND else 0.0
    d = rotate(phi_a, np.asarray(joint.direction, dtype=float)) if joint.body_a != GROUND else joint.direction
    d = np.broadcast_to(np.asarray(d, dtype=float), (len(next(iter(angles.values()))), 2))
    off = where(joint.body_b, joint.point) - where(joint.body_a, joint.line_point)
    value = np.abs(off[:, 0] * d[:, 1] - off[:, 1] * d[:, 0])
    if joint.locked_angle is not None:
        phi_b = angles[joint.body_b] if joint.body_b != GROUND else 0.0
        value = np.maximum(value, size * np.abs(np.asarray(phi_b - phi_a) - joint.locked_angle))
    return value


def _mesh_gap(gear: GearPair, where, angles: dict, size: float) -> np.ndarray:
    """The arcs the pitch circles have slipped by, m."""
    total = -gear.sigma * gear.radius_b * gear.phase
    for body, k in zip(gear.bodies, gear.coefficients()):
        total = total + k * (angles[body] if body != GROUND else 0.0)
    return np.abs(np.broadcast_to(total, (len(next(iter(angles.values()))),)))


#: how far a joint has come apart, by its type
_GAPS: dict[type, Callable] = {Revolute: _pin_gap, LineJoint: _line_gap, GearPair: _mesh_gap}


def _mass(body, size: float) -> tuple[float, float]:
    """A body's mass (kg) and its moment of inertia about the centre of mass as Exudyn
    holds it (kg m^2; a point mass gets :data:`~xcheck.engines.POINT_MASS_INERTIA`)."""
    mass = float(body.mass or 0.0)
    return mass, positive_inertia(mass, float(body.inertia or 0.0), size)


def build_system(mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> ExudynModel:
    """The Exudyn system of the mechanism, its nodes at the state (q, qd).

    Parameters
    ----------
    q, qd : ndarray, shape (3 m,)
        x, y (m) of each moving body's frame origin and phi (rad), and their rates.

    Raises
    ------
    NotApplicable
        What Exudyn cannot represent (see :func:`refuse`).
    """
    import exudyn as exu
    import exudyn.itemInterface as ei

    refuse(mech)
    size = mech.size
    container = exu.SystemContainer()
    mbs = container.AddSystem()
    ground = mbs.AddObject(ei.ObjectGround(visualization=ei.VObjectGround(show=False)))
    bodies, nodes, com, reference = {GROUND: ground}, {}, {}, {}
    for i, body in enumerate(mech.moving_bodies):
        c = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        x, y, phi = (float(v) for v in q[3 * i : 3 * i + 3])
        vx, vy, omega = (float(v) for v in qd[3 * i : 3 * i + 3])
        arm = rotate(phi, c)
        centre = np.array([x, y]) + arm
        velocity = np.array([vx, vy]) + omega * np.array([-arm[1], arm[0]])
        reference[body.name] = np.array([centre[0], centre[1], phi])
        node = mbs.AddNode(
            ei.NodeRigidBody2D(
                referenceCoordinates=[centre[0], centre[1], phi],
                initialCoordinates=[0.0, 0.0, 0.0],
                initialVelocities=[velocity[0], velocity[1], omega],
                visualization=ei.VNodeRigidBody2D(show=False),
            )
        )
        bodies[body.name] = mbs.AddObject(
            ei.ObjectRigidBody2D(
                nodeNumber=node,
                mass=_mass(body, size)[0],
                inertia=_mass(body, size)[1],  # about the centre of mass, the node
                visualization=ei.VObjectRigidBody2D(show=False),
            )
        )
        nodes[body.name], com[body.name] = node, c

    def local(body: str, xy) -> list[float]:
        offset = np.asarray(xy, dtype=float) - (com[body] if body in com else 0.0)
        return [float(offset[0]), float(offset[1]), 0.0]

    def position_marker(body: str, label: str):
        point = mech.body(body).points[label]
        return mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=bodies[body], localPosition=local(body, point)))

    def rigid_marker(body: str, xy):
        return mbs.AddMarker(ei.MarkerBodyRigid(bodyNumber=bodies[body], localPosition=local(body, xy)))

    for joint in mech.joints:
        mbs.AddObject(
            converter(_JOINTS, joint, "Exudyn")(mech, joint, ei, mbs, nodes, reference, position_marker, rigid_marker)
        )
    gravity = np.asarray(mech.gravity, dtype=float)
    if np.any(gravity != 0.0):
        for body in mech.moving_bodies:
            centre = mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=bodies[body.name], localPosition=[0.0, 0.0, 0.0]))
            weight = _mass(body, size)[0] * gravity
            mbs.AddLoad(ei.LoadForceVector(markerNumber=centre, loadVector=[weight[0], weight[1], 0.0]))
    for load in mech.loads:
        if load.body not in nodes:
            continue  # a load on the ground does no work
        timed = {} if load.law is None else {"loadVectorUserFunction": _timed(load.law)}
        if np.any(np.asarray(load.force) != 0.0):
            at = mbs.AddMarker(
                ei.MarkerBodyPosition(bodyNumber=bodies[load.body], localPosition=local(load.body, load.point))
            )
            force = [float(load.force[0]), float(load.force[1]), 0.0]
            mbs.AddLoad(ei.LoadForceVector(markerNumber=at, loadVector=force, **timed))
        if load.torque != 0.0:
            at = rigid_marker(load.body, load.point)
            mbs.AddLoad(ei.LoadTorqueVector(markerNumber=at, loadVector=[0.0, 0.0, float(load.torque)], **timed))
    if mech.rotational_springs:  # on the two angle coordinates (displacements from the reference angles)
        fixed = mbs.AddMarker(
            ei.MarkerNodeCoordinate(
                nodeNumber=mbs.AddNode(ei.NodePointGround(visualization=ei.VNodePointGround(show=False))), coordinate=0
            )
        )
        turns = {
            name: mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=node, coordinate=2)) for name, node in nodes.items()
        }
        for twist in mech.rotational_springs:
            turned = (reference[twist.body_b][2] if twist.body_b in nodes else 0.0) - (
                reference[twist.body_a][2] if twist.body_a in nodes else 0.0
            )
            mbs.AddObject(
                ei.ObjectConnectorCoordinateSpringDamper(
                    markerNumbers=[turns.get(twist.body_a, fixed), turns.get(twist.body_b, fixed)],
                    stiffness=float(twist.stiffness),
                    damping=float(twist.damping),
                    offset=float(twist.rest_angle) - turned,
                    visualization=ei.VObjectConnectorCoordinateSpringDamper(show=False),
                )
            )
    owners = mech.point_owners
    for spring in mech.springs:
        ends = [position_marker(owners[label], label) for label in spring.points]
        mbs.AddObject(
            ei.ObjectConnectorSpringDamper(
                markerNumbers=ends,
                referenceLength=float(spring.rest_length),
                stiffness=float(spring.stiffness),
                damping=float(spring.damping),
                visualization=ei.VObjectConnectorSpringDamper(show=False),
            )
        )
    return ExudynModel(container, mbs, nodes, com, reference)


def _timed(law):
    """Exudyn's load user function of a load law: the load vector times ``law.factor(t)``."""

    def load(mbs, t, vector):
        return [float(law.factor(t)) * float(v) for v in vector]

    load.law = law  # type: ignore[attr-defined]  # read by the exported script (.export)
    return load


def solver_settings(setting: Setting, dt: float, duration: float, every: float, floor: float = 0.0):
    """Exudyn's simulation settings of a run (no files, no output, sensors every ``every`` s),
    Newton's absolute tolerance at least ``floor`` (:func:`newton_floor`)."""
    import exudyn as exu

    s: Any = exu.SimulationSettings()  # its stubs lack solutionSettings and others
    s.timeIntegration.numberOfSteps = int(round(duration / dt))
    s.timeIntegration.endTime = duration
    s.timeIntegration.verboseMode = 0
    s.timeIntegration.adaptiveStep = False  # every step is the row's (a reduced step writes off the outputs)
    s.timeIntegration.generalizedAlpha.spectralRadius = setting.spectral_radius
    s.timeIntegration.generalizedAlpha.useIndex2Constraints = setting.index2
    s.timeIntegration.generalizedAlpha.useNewmark = setting.index2  # with index 2: Exudyn's TrapezoidalIndex2
    if setting.newton_tolerance is not None:
        s.timeIntegration.newton.relativeTolerance = setting.newton_tolerance
        s.timeIntegration.newton.absoluteTolerance = setting.newton_tolerance
    newton = s.timeIntegration.newton
    newton.absoluteTolerance = max(float(newton.absoluteTolerance), floor)
    s.solution.file.write = False
    s.solution.sensors.writePeriod = every
    s.linearSolver.solverType = exu.LinearSolverType.EigenDense
    return s


def joint_gaps(mech: Mechanism, points: dict, angles: dict) -> np.ndarray:
    """The largest joint violation at each sample, m (N,): revolute points apart,
    a pin off its line, a prismatic joint's angle error times the size."""
    size = mech.size
    gaps = None
    ground = {label: np.asarray(xy, dtype=float) for label, xy in mech.ground.points.items()}

    def where(body: str, label: str) -> np.ndarray:
        if body == GROUND:
            return ground[label][None, :]
        c = points[(body, label)]
        return c

    for joint in mech.joints:
        value = converter(_GAPS, joint, "Exudyn")(joint, where, angles, size)
        gaps = value if gaps is None else np.maximum(gaps, value)
    return np.zeros(len(next(iter(angles.values())))) if gaps is None else gaps


def energy(mech: Mechanism, model: ExudynModel, coords: dict, rates: dict, angles: dict, points: dict) -> np.ndarray:
    """T + V of gravity, springs and rotational springs minus the constant loads' potential, J (N,)."""
    gravity = np.asarray(mech.gravity, dtype=float)
    total = 0.0
    for body in mech.moving_bodies:
        centre, velocity = coords[body.name], rates[body.name]
        mass, inertia = _mass(body, mech.size)
        total = total + 0.5 * mass * (velocity[:, 0] ** 2 + velocity[:, 1] ** 2)
        total = total + 0.5 * inertia * velocity[:, 2] ** 2 - mass * (centre[:, :2] @ gravity)
    owners = mech.point_owners
    for spring in mech.springs:
        ends = [points[(owners[label], label)] for label in spring.points]
        ends = [np.broadcast_to(e, (len(angles[next(iter(angles))]), 2)) for e in ends]
        gap = ends[1] - ends[0]
        total = total + 0.5 * spring.stiffness * (np.hypot(gap[:, 0], gap[:, 1]) - spring.rest_length) ** 2
    for twist in mech.rotational_springs:
        turned = (angles[twist.body_b] if twist.body_b in angles else 0.0) - (
            angles[twist.body_a] if twist.body_a in angles else 0.0
        )
        total = total + 0.5 * twist.stiffness * (turned - twist.rest_angle) ** 2
    for load in mech.loads:
        if load.body in model.nodes:
            p = points[("load", load.name)]
            total = total - p @ np.asarray(load.force, dtype=float) - load.torque * angles[load.body]
    return np.asarray(total, dtype=float)


def matched(data: np.ndarray, wanted: np.ndarray, tolerance: float) -> np.ndarray:
    """Rows of a sensor's stored data (time first) at the wanted times, in order, up to the
    first wanted time it did not reach (an adaptive step after a failed Newton step may
    write in between)."""
    if data.ndim != 2 or not len(data):
        return np.zeros(0, dtype=int)
    rows = []
    for t in wanted:
        at = np.flatnonzero(np.abs(data[:, 0] - t) <= tolerance)
        if not len(at):
            break
        rows.append(int(at[-1]))
    return np.asarray(rows, dtype=int)
