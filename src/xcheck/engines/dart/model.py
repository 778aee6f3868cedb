"""DART's model of a mechanism: a ``dart.simulation.World`` holding one
``Skeleton`` whose body nodes are xcheck's body frames, hung from their parents
(or the world) by revolute joints (about z) and prismatic joints (along the joint
frame's x) placed by :func:`xcheck.engines._tree.tree_frames`, every coordinate
0 at the state the model is built at. Each loop cut at a revolute is a joint
constraint in the world's constraint solver at the cut's point: a
``RevoluteJointConstraint`` (the point and the z axes held: 5 rows, 3 of them
redundant in the plane) or a ``BallJointConstraint`` (the point: 3 rows). DART
steps semi-implicit Euler with the constraints solved as a velocity-level LCP
(Dantzig, PGS as its fallback), their drift corrected by error reduction
(ERP) and softened by constraint force mixing (CFM). Gravity is the world's.

Each tree joint is converted by the converter of its type. Not converted
(:class:`~xcheck.engines.NotApplicable`): pin-in-slot joints, loops cut at a
prismatic joint and gear pairs (:func:`~xcheck.engines._tree.tree_frames`),
springs, dampers and loads (not built here).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from xcheck.dynamics._forces import require_mass_data
from xcheck.engines._contract import positive_inertia
from xcheck.engines._tree import TreeFrames, gravity_only, tree_frames
from xcheck.joints import Prismatic, Revolute, converter
from xcheck.kinematics import rotate
from xcheck.model import GROUND, Mechanism

__all__ = ["DartModel", "build"]


@dataclass
class DartModel:
    """The mechanism in a DART world.

    Attributes
    ----------
    world : dartpy.simulation.World
    skeleton : dartpy.dynamics.Skeleton
    tree : TreeFrames
    bodies : dict of str to BodyNode
        Moving body -> its body node (its frame: xcheck's body frame).
    joints : dict of str to Joint
        Tree joint name -> DART's joint.
    """

    world: Any
    skeleton: Any
    tree: TreeFrames
    bodies: dict[str, Any]
    joints: dict[str, Any]

    def frames(self) -> dict[str, tuple]:
        """Per moving body: origin (2,) m and angle rad, continuous from the build state."""
        origins = {name: np.asarray(body.getWorldTransform().translation())[:2] for name, body in self.bodies.items()}
        coordinates = {name: float(joint.getPosition(0)) for name, joint in self.joints.items()}
        return self.tree.frames(coordinates, origins)


def _isometry(point, angle: float):
    import dartpy as dart

    transform = dart.math.Isometry3()
    c, s = np.cos(angle), np.sin(angle)
    transform.set_rotation(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))
    transform.set_translation([float(point[0]), float(point[1]), 0.0])
    return transform


def _revolute(dart, skeleton) -> tuple[Any, Callable]:
    """A revolute tree joint: DART's properties, its axis the frames' z, and the skeleton's maker."""
    props = dart.dynamics.RevoluteJointProperties()
    props.mAxis = [0.0, 0.0, 1.0]
    return props, skeleton.createRevoluteJointAndBodyNodePair


def _prismatic(dart, skeleton) -> tuple[Any, Callable]:
    """A prismatic tree joint: DART's properties, its axis the frames' x, and the skeleton's maker."""
    props = dart.dynamics.PrismaticJointProperties()
    props.mAxis = [1.0, 0.0, 0.0]
    return props, skeleton.createPrismaticJointAndBodyNodePair


#: each tree joint type's converter: (dartpy, the skeleton) -> (joint properties, the skeleton's joint-and-body maker)
_JOINTS: dict[type, Callable] = {Revolute: _revolute, Prismatic: _prismatic}


def build(mech: Mechanism, q: np.ndarray, qd: np.ndarray, dt: float, cut: str = "revolute") -> DartModel:
    """The mechanism as a DART world with time step ``dt`` (s), at native body coordinates
    ``q`` and rates ``qd`` (x, y, phi per moving body; m, rad, m/s, rad/s), each loop cut
    closed by a ``cut`` ("revolute" or "ball") joint constraint.

    Raises
    ------
    NotApplicable
        What the model cannot hold (:func:`~xcheck.engines._tree.gravity_only`,
        :func:`~xcheck.engines._tree.tree_frames`).
    ModelError
        If a moving body has no mass data.
    """
    import dartpy as dart

    require_mass_data(mech)
    gravity_only(mech, "DART")
    tree = tree_frames(mech, q, "DART")
    world = dart.simulation.World()
    gravity = np.asarray(mech.gravity, dtype=float)
    world.setGravity([float(gravity[0]), float(gravity[1]), 0.0])
    world.setTimeStep(dt)
    skeleton = dart.dynamics.Skeleton(mech.name)
    size = mech.size
    bodies: dict[str, Any] = {}
    joints: dict[str, Any] = {}
    for frames in tree.joints:
        props, create = converter(_JOINTS, mech.joint(frames.name), "DART")(dart, skeleton)
        props.mName = frames.name
        props.mT_ParentBodyToJoint = _isometry(frames.parent_point, frames.parent_angle)
        props.mT_ChildBodyToJoint = _isometry(frames.child_point, frames.child_angle)
        parent = None if frames.parent == GROUND else bodies[frames.parent]
        joint, node = create(parent, props, dart.dynamics.BodyNodeProperties())
        node.setName(frames.child)
        body = mech.body(frames.child)
        assert body.mass is not None and body.inertia is not None
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        inertia = positive_inertia(float(body.mass), float(body.inertia), size)
        node.setInertia(dart.dynamics.Inertia(float(body.mass), [com[0], com[1], 0.0], np.eye(3) * inertia))
        bodies[frames.child], joints[frames.name] = node, joint
    world.addSkeleton(skeleton)
    rates = tree.rates(mech, q, qd)
    skeleton.setPositions(np.zeros(skeleton.getNumDofs()))
    skeleton.setVelocities([rates[name] for name in joints])
    index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}
    solver = world.getConstraintSolver()
    for body_a, point_a, body_b, point_b in tree.cuts:
        ends = [(name, point) for name, point in ((body_a, point_a), (body_b, point_b)) if name != GROUND]
        name, point = ends[0]
        k = index[name]
        where = q[k : k + 2] + rotate(float(q[k + 2]), point)  # the cut's point in the world at the build state
        pos = [float(where[0]), float(where[1]), 0.0]
        nodes = [bodies[n] for n, _ in ends]
        if cut == "revolute":
            axes = [[0.0, 0.0, 1.0]] * len(nodes)
            constraint = dart.constraint.RevoluteJointConstraint(*nodes, pos, *axes)
        else:
            constraint = dart.constraint.BallJointConstraint(*nodes, pos)
        solver.addConstraint(constraint)
    return DartModel(world, skeleton, tree, bodies, joints)
