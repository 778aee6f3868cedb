"""Drake's model of a mechanism, shared by its free and driven modes: a
``MultibodyPlant(time_step=dt)`` whose loops are closed by ball constraints,
stepped by Drake's discrete SAP solver.

The tree is :func:`xcheck.topology.spanning_tree`'s: the ground is Drake's
world body, each moving body a ``RigidBody`` whose frame is xcheck's body
frame (origin and orientation), hung from its parent by a ``RevoluteJoint``
about z between frames at the joint's point on either body (its coordinate
is the child's angle minus the parent's) or a ``PrismaticJoint`` whose frames
sit at the line point and the sliding point, the child's turned by the locked
angle (its coordinate is xcheck's slide displacement). Each cut revolute is a
ball constraint (``AddBallConstraint``) between its two points: a revolute
cut says that two points coincide, which is what a ball constraint holds (its
z row is idle, the tree keeps the plane). A distance constraint
(``AddDistanceConstraint``) holds a rigid massless rod of positive length
between two points, which is no joint of the canonical model (a binary link
there has mass and is a body), so it is not used. Gravity is Drake's
gravity field in the plane, the linear spring-dampers ``LinearSpringDamper``
(the same law, k (l - l0) + c dl/dt), a rotational spring-damper across a
tree revolute a ``RevoluteSpring`` on that joint plus the joint's viscous
damping, the loads ``ExternallyAppliedSpatialForce`` s on the plant's applied
spatial force input (a time law: its value at each step's start, as Drake's
discrete update samples its inputs). Not converted
(:class:`~xcheck.engines.NotApplicable`): a pin-in-slot joint (Drake has no
such joint; a massless carrier link is not built here), a loop cut at a
prismatic joint (a weld constraint on a carrier, not built here), a
rotational spring across a cut joint (Drake's springs act on joint
coordinates) and a spring of rest length 0 (``LinearSpringDamper`` needs a
positive free length).

pydrake 1.51.1 crashes the process (a segmentation fault in its SAP driver) on
a ball constraint between the world body and a body, either way round
(reproduced with two links and one constraint); a loop cut at the ground is
therefore closed on a body welded to the world at its frame (``ground-anchor``),
which runs.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from xcheck.dynamics._forces import require_mass_data
from xcheck.engines._contract import NotApplicable
from xcheck.engines._frames import native_point_state, world_point
from xcheck.joints import GearPair, LineJoint, PinInSlot, Prismatic, Revolute, converter
from xcheck.kinematics import Kinematics
from xcheck.model import GROUND, Mechanism
from xcheck.topology import Topology, spanning_tree

__all__ = ["DrakeModel", "apply_loads", "build", "drake", "energy", "refuse", "set_state"]


@dataclass
class DrakeModel:
    """The mechanism in a finalized MultibodyPlant and a context of it.

    Attributes
    ----------
    plant : pydrake.multibody.plant.MultibodyPlant
    context : pydrake.systems.framework.Context
    bodies : dict of str to RigidBody
        Moving body -> Drake's body (its frame: xcheck's body frame).
    joints : dict of str to Joint
        Moving body -> its tree joint (RevoluteJoint or PrismaticJoint).
    parents : dict of str to str
        Moving body -> its parent in the tree (GROUND for the world).
    turns : dict of str to float
        Moving body -> its angle minus its parent's at joint coordinate 0, rad
        (0 for a revolute, +-the locked angle for a prismatic joint).
    cuts : list of (str, ndarray, str, ndarray)
        Per ball constraint: (body, point in its frame, body, point in its frame).
    loads : list
        (Drake body index, point (3,) in the body frame, force (2,) N, torque N m, law or None)
        per load on a moving body.
    """

    plant: Any
    context: Any
    bodies: dict[str, Any]
    joints: dict[str, Any]
    parents: dict[str, str]
    turns: dict[str, float]
    cuts: list[tuple[str, np.ndarray, str, np.ndarray]]
    loads: list[tuple[Any, np.ndarray, np.ndarray, float, Any]]

    def frames(self) -> dict[str, tuple[np.ndarray, float, np.ndarray, float]]:
        """Per moving body: frame origin (2,) m, angle rad (continuous: parents' angles plus
        joint coordinates), origin velocity (2,) m/s and rate rad/s."""
        out: dict[str, tuple[np.ndarray, float, np.ndarray, float]] = {}
        for name, body in self.bodies.items():  # parents first (tree order)
            joint = self.joints[name]
            base = out.get(self.parents[name])
            phi0, omega0 = (0.0, 0.0) if base is None else (base[1], base[3])
            pose = self.plant.EvalBodyPoseInWorld(self.context, body)
            velocity = self.plant.EvalBodySpatialVelocityInWorld(self.context, body)
            if joint.type_name() == "revolute":
                phi = phi0 + joint.get_angle(self.context)
            else:
                phi = phi0 + self.turns[name]
            omega = float(velocity.rotational()[2])
            out[name] = (
                np.asarray(pose.translation()[:2]),
                float(phi),
                np.asarray(velocity.translational()[:2]),
                omega,
            )
        return out


def drake():
    """pydrake's modules this engine uses (imported when a mode runs)."""
    import pydrake.systems.analysis  # noqa: F401 - the simulator, imported with the rest
    from pydrake.math import RigidTransform, RotationMatrix
    from pydrake.multibody import plant, tree

    return plant, tree, RigidTransform, RotationMatrix


def refuse(mech: Mechanism, topology: Topology) -> None:
    """:class:`NotApplicable` with the reason if the Drake model here cannot hold the mechanism."""
    for each in mech.joints:
        if each.connects:
            converter(_TREE_JOINTS, each, "Drake")
    for closing in topology.cuts:
        converter(_CLOSURES, closing, "Drake")
    cut = {j.name for j in topology.cuts}
    across = [s for s in mech.rotational_springs if s.joint in cut]
    if across:
        raise NotApplicable(
            f"rotational spring {across[0].name!r} acts across the cut joint {across[0].joint!r}: Drake's "
            "RevoluteSpring acts on a tree joint's coordinate"
        )
    short = [s for s in mech.springs if not s.rest_length > 0.0]
    if short:
        raise NotApplicable(
            f"spring {short[0].name!r} has rest length 0: Drake's LinearSpringDamper needs a positive free length"
        )


def _revolute(tj, j: Revolute, frame, tree_module, damping: dict, xyz):
    """A revolute: Drake's revolute joint between frames at the pin in each body's orientation
    (its angle the child's minus the parent's)."""
    l_parent, l_child = j.tree_points[::-1] if tj.reversed else j.tree_points
    joint = tree_module.RevoluteJoint(
        j.name, frame(j.name, tj.parent, l_parent), frame(j.name, tj.child, l_child), [0.0, 0.0, 1.0],
        damping.get(j.name, 0.0),
    )  # fmt: skip
    return joint, 0.0


def _prismatic(tj, j: Prismatic, frame, tree_module, damping: dict, xyz):
    """A prismatic joint: Drake's prismatic joint along the line, the sliding body's frame turned by its
    locked angle."""
    d = np.asarray(j.direction, dtype=float)
    if not tj.reversed:  # the line is the parent's: the child's point slides along it
        on_parent, on_child = frame(j.name, j.body_a, j.line_point), frame(j.name, j.body_b, j.point, -j.angle)
        axis, turn = d, j.angle
    else:  # the line is the child's: frames in the line's orientation, the slide reversed
        on_parent, on_child = frame(j.name, j.body_b, j.point, -j.angle), frame(j.name, j.body_a, j.line_point)
        axis, turn = -d, -j.angle
    return tree_module.PrismaticJoint(j.name, on_parent, on_child, xyz(axis)), turn


#: a tree joint as a Drake joint, by its type: (the joint, its child's angle minus its parent's at zero)
_TREE_JOINTS: dict[type, Callable | str] = {
    Revolute: _revolute,
    Prismatic: _prismatic,
    PinInSlot: "joint {name!r} is a pin-in-slot: Drake has no pin-in-slot joint and xcheck's Drake model has "
    "revolute and prismatic joints only (a massless carrier link is not built)",
}


def _ball(plant, cut: Revolute, mech: Mechanism, anchor, of, joints: dict, topology: Topology, xyz):
    """A loop cut at a revolute: a ball constraint between its two points."""
    (a, pa), (b, pb) = ((body, np.asarray(mech.body(body).points[label], dtype=float)) for body, label in cut.anchors())
    plant.AddBallConstraint(anchor if a == GROUND else of(a), xyz(pa), anchor if b == GROUND else of(b), xyz(pb))
    return (a, pa, b, pb)


def _coupler(plant, gear: GearPair, mech: Mechanism, anchor, of, joints: dict, topology: Topology, xyz):
    """A gear pair: Drake's coupler constraint q_pin_b = rho q_pin_a + offset between its gears'
    revolutes, whose angles are the gears' rotations relative to the carrier up to a sign s
    (-1 where the carrier is the child): rho = -sigma s_a s_b r_a / r_b, offset = s_b phase."""
    tree = {tj.joint.name: tj for tj in topology.tree}
    rho, _, s_b = gear.tree_coupling(
        lambda pin, body: None if pin not in tree else 1.0 if tree[pin].child == body else -1.0,
        "Drake's coupler constraint",
    )
    plant.AddCouplerConstraint(joints[tree[gear.pin_b].child], joints[tree[gear.pin_a].child], rho, s_b * gear.phase)
    return None


#: how a loop cut at each joint type is closed (its two points, or None)
_CLOSURES: dict[type, Callable | str] = {
    Revolute: _ball,
    LineJoint: "a loop is cut at the {kind} joint {name!r}: xcheck's Drake model closes loops with ball constraints "
    "only (a carrier welded by AddWeldConstraint is not built)",
    GearPair: _coupler,
}


def build(kinematics: Kinematics, dt: float, pd: Mapping[str, tuple[float, float]] | None = None) -> DrakeModel:
    """The mechanism as a finalized MultibodyPlant with time step ``dt`` (s) and a
    default context (see the module's notes).

    Parameters
    ----------
    pd : mapping of str to (float, float), optional
        Tree joint name -> (Kp, Kd): a ``JointActuator`` of that name on the joint, no
        effort limit, with SAP's implicit PD controller of these gains (N m/rad and
        N m s/rad, or N/m and N s/m), its desired state on the plant's desired-state
        input port (the driven mode's drivers).

    Raises
    ------
    NotApplicable
        What the Drake model cannot hold (:func:`refuse`).
    ModelError
        If a moving body has no mass data.
    """
    plant_module, tree_module, RigidTransform, RotationMatrix = drake()
    mech = kinematics.mechanism
    require_mass_data(mech)
    topology = spanning_tree(mech)
    refuse(mech, topology)
    plant = plant_module.MultibodyPlant(time_step=dt)
    world = plant.world_body()

    def xyz(xy) -> np.ndarray:
        return np.array([float(xy[0]), float(xy[1]), 0.0])

    bodies: dict[str, Any] = {}
    for body in mech.moving_bodies:
        assert body.mass is not None and body.inertia is not None
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        inertia = float(body.inertia)  # about z; x and y play no part in the plane (equal: a valid tensor)
        spatial = tree_module.SpatialInertia.MakeFromCentralInertia(
            float(body.mass), xyz(com), tree_module.RotationalInertia(inertia, inertia, inertia)
        )
        bodies[body.name] = plant.AddRigidBody(body.name, spatial)

    def of(name: str):
        return world if name == GROUND else bodies[name]

    def frame(joint: str, name: str, label: str, turn: float = 0.0):
        """A joint's frame on a body at one of its points, turned by ``turn`` (rad)."""
        pose = RigidTransform(RotationMatrix.MakeZRotation(turn), xyz(mech.body(name).points[label]))
        return plant.AddFrame(tree_module.FixedOffsetFrame(f"{joint}@{name}", of(name).body_frame(), pose))

    damping: dict[str, float] = {}
    for twist in mech.rotational_springs:
        damping[twist.joint] = damping.get(twist.joint, 0.0) + float(twist.damping)
    joints: dict[str, Any] = {}
    parents: dict[str, str] = {}
    turns: dict[str, float] = {}
    for tj in topology.tree:
        j = tj.joint
        joint, turn = converter(_TREE_JOINTS, j, "Drake")(tj, j, frame, tree_module, damping, xyz)
        joints[tj.child] = plant.AddJoint(joint)
        if pd and j.name in pd:
            actuator = plant.AddJointActuator(j.name, joints[tj.child])
            actuator.set_controller_gains(tree_module.PdControllerGains(p=pd[j.name][0], d=pd[j.name][1]))
        parents[tj.child] = tj.parent
        turns[tj.child] = float(turn)
    bodies = {name: bodies[name] for name in joints}  # tree order: parents first
    for twist in mech.rotational_springs:  # across a tree revolute (refuse() keeps the rest out)
        tj = next(t for t in topology.tree if t.joint.name == twist.joint)
        # the spring's angle phi_b - phi_a is the joint coordinate (child minus parent) or its opposite
        sign = 1.0 if twist.body_b == tj.child else -1.0
        plant.AddForceElement(
            tree_module.RevoluteSpring(joints[tj.child], sign * float(twist.rest_angle), float(twist.stiffness))
        )
    owners = mech.point_owners
    for spring in mech.springs:
        (a, pa), (b, pb) = ((owners[label], mech.body(owners[label]).points[label]) for label in spring.points)
        plant.AddForceElement(
            tree_module.LinearSpringDamper(
                of(a),
                xyz(pa),
                of(b),
                xyz(pb),
                float(spring.rest_length),
                float(spring.stiffness),
                float(spring.damping),
            )
        )
    cuts = []
    anchor = world
    if any(GROUND in (cut.body_a, cut.body_b) for cut in topology.cuts):
        # pydrake 1.51.1 segfaults in the SAP driver on a ball constraint with the world body
        # (an invalid tree index); a body welded to the world at its frame holds the ground's points
        anchor = plant.AddRigidBody("ground-anchor", tree_module.SpatialInertia.SolidSphereWithMass(1.0, 1.0))
        plant.AddJoint(
            tree_module.WeldJoint("ground-anchor", world.body_frame(), anchor.body_frame(), RigidTransform())
        )
    for cut in topology.cuts:
        ends = converter(_CLOSURES, cut, "Drake")(plant, cut, mech, anchor, of, joints, topology, xyz)
        if ends is not None:
            cuts.append(ends)
    plant.mutable_gravity_field().set_gravity_vector(xyz(mech.gravity))
    plant.Finalize()
    loads = [
        (bodies[load.body].index(), xyz(load.point), np.asarray(load.force, dtype=float), float(load.torque), load.law)
        for load in mech.loads
        if load.body in bodies
    ]
    context = plant.CreateDefaultContext()
    return DrakeModel(plant, context, bodies, joints, parents, turns, cuts, loads)


def apply_loads(model: DrakeModel, t: float) -> None:
    """Fix the plant's applied spatial forces at their values at time ``t`` (s)."""
    plant_module, tree_module, _, _ = drake()
    from pydrake.multibody import math as drake_math

    spatial_force: Any = drake_math.SpatialForce  # its stubs misspell ndarray's type parameters
    forces = []
    for index, point, force, torque, law in model.loads:
        factor = 1.0 if law is None else float(law.factor(t))
        applied = plant_module.ExternallyAppliedSpatialForce()
        applied.body_index = index
        applied.p_BoBq_B = point
        applied.F_Bq_W = spatial_force(
            np.array([0.0, 0.0, factor * torque]), np.array([factor * force[0], factor * force[1], 0.0])
        )
        forces.append(applied)
    model.plant.get_applied_spatial_force_input_port().FixValue(model.context, forces)


def set_state(model: DrakeModel, kinematics: Kinematics, q: np.ndarray, qd: np.ndarray) -> None:
    """Put the plant at native body coordinates ``q`` and rates ``qd`` (x, y, phi per moving body,
    in ``mechanism.moving_bodies`` order; m, rad, m/s, rad/s) and check that it is there.

    Raises
    ------
    RuntimeError
        If Drake's state is not the native one (to 1e-9 of the size, or of the speed).
    """
    mech = kinematics.mechanism
    index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}

    state = functools.partial(native_point_state, index, q, qd)

    context = model.context
    for name, joint in model.joints.items():
        if joint.type_name() == "revolute":
            _, _, phi, omega = state(name)
            _, _, phi0, omega0 = state(model.parents[name])
            joint.set_angle(context, phi - phi0)
            joint.set_angular_rate(context, omega - omega0)
            continue
        value, rate = mech.joint(joint.name()).coordinate(
            lambda body, label: state(body, None if label is None else mech.body(body).points[label])
        )
        joint.set_translation(context, value)
        joint.set_translation_rate(context, rate)
    size = mech.size
    for name, (origin, phi, velocity, omega) in model.frames().items():
        k = index[name]
        miss = max(float(np.hypot(*(origin - q[k : k + 2]))), abs(phi - q[k + 2]) * size)
        if miss > 1e-9 * size:
            raise RuntimeError(f"Drake's {name} starts {miss:.3g} m from the native start")
        speed = max(float(np.hypot(*qd[k : k + 2])), abs(qd[k + 2]) * size, 1.0)
        off = max(float(np.hypot(*(velocity - qd[k : k + 2]))), abs(omega - qd[k + 2]) * size)
        if off > 1e-9 * speed:
            raise RuntimeError(f"Drake's {name} starts with a velocity {off:.3g} m/s from the native one")


def energy(model: DrakeModel, frames) -> float:
    """Drake's kinetic and potential energy (gravity, springs) minus the constant loads'
    potential -(F . r + tau phi), J."""
    total = float(model.plant.CalcKineticEnergy(model.context) + model.plant.CalcPotentialEnergy(model.context))
    names = {body.index(): name for name, body in model.bodies.items()}
    for index, point, force, torque, _ in model.loads:
        name = names[index]
        total -= float(force @ world_point(frames, name, point[:2])) + torque * frames[name][1]
    return total
