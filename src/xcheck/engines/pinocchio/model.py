"""The mechanism as a Pinocchio model: a kinematic tree plus loop-closure constraints.

One description, :class:`TreeSpec`, is read from the canonical mechanism model
and turned either into a ``pin.Model`` built programmatically
(:func:`build_model`) or into URDF text (:mod:`.urdf`). Both have the
same joints, placements, inertias and frame names, so a test can check one
against the other.

Conventions (planar mechanism in the x-y plane, rotation about z):

* Each tree joint of :func:`xcheck.topology.spanning_tree` becomes a Pinocchio
  joint whose frame sits *at the joint* (the pin, or the line point / sliding
  point of a slider) and turns with the child body. A revolute is
  ``JointModelRZ`` (one coordinate: the child's angle minus the parent's); a
  prismatic is ``JointModelPrismaticUnaligned`` with the rotation ``angle``
  locked in the placement; a pin-in-slot is a prismatic and an ``RZ`` joint
  through a massless intermediate body ("carrier"), the slide first when the
  slot is in the parent, the hinge first when the slot is in the child.
* The mechanism's body frame of a moving body is the frame named after the
  body (type BODY) on its last joint; its named points are OP frames named
  ``"<body>.<label>"`` (the ground's on the universe joint).
* Each cut revolute becomes a ``RigidConstraintModel`` of type CONTACT_3D
  between its two points, expressed LOCAL_WORLD_ALIGNED. Its z row is
  identically zero for a planar mechanism.
* A loop with no undriven revolute is cut at a pin-in-slot or prismatic joint
  (:mod:`xcheck.topology`). Its line's body gets a carrier: a
  prismatic joint ``"<joint>.carrier"`` along the line (coordinate: the joint's
  slide displacement), after the tree joints, with the mass it takes from the
  body it is held to (:func:`xcheck.topology.carrier_share`; the mass
  distribution stays the model's). A pin-in-slot cut is a
  CONTACT_3D between the carrier's link origin and the pin; a prismatic cut a
  CONTACT_6D between it and the frame ``"<joint>.block"`` of the block (at the
  sliding point, turned by -angle so that the frames align when
  phi_b - phi_a = angle); its rows x, y and rotation z act.
* A body without mass properties gets defaults (see :func:`mass_properties`).
* Gravity is the mechanism's, in the plane (zero when it gives none).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from xcheck.errors import ModelError
from xcheck.joints import GearPair, LineJoint, PinInSlot, Prismatic, Revolute, converter
from xcheck.kinematics import rotate
from xcheck.model import GROUND, Body, Joint, Mechanism
from xcheck.topology import TreeJoint, carrier_share, spanning_tree

__all__ = [
    "JointSpec",
    "BodySpec",
    "DriverCoordinate",
    "TreeSpec",
    "PinocchioMechanism",
    "tree_spec",
    "build_model",
    "mass_properties",
    "joint_coordinates",
    "carrier_joint",
    "block_frame",
    "depth_first",
]


@dataclass(frozen=True)
class JointSpec:
    """One Pinocchio joint.

    Attributes
    ----------
    name : str
        Joint name (the mechanism joint's, or ``"<joint>.slide"`` and
        ``"<joint>.turn"`` for the two joints of a pin-in-slot).
    kind : str
        ``"revolute"`` (about z) or ``"prismatic"``.
    parent : str
        The frame it hangs from: a body name (the body frame) or the link of an
        earlier joint (``"<joint>.link"``).
    origin : ndarray, shape (2,), m
        Joint frame origin in the parent frame at zero joint coordinate.
    angle : float, rad
        Rotation of the joint frame about z relative to the parent frame.
    axis : ndarray, shape (3,)
        Unit axis in the joint frame: (0, 0, 1) for a revolute, in-plane for a
        prismatic.
    link : str
        Name of the (massless) link whose frame is the joint frame.
    tree_joint : str
        The mechanism joint it belongs to.
    bodies : tuple of (str, str)
        (parent, child) bodies of that tree joint.
    """

    name: str
    kind: str
    parent: str
    origin: np.ndarray
    angle: float
    axis: np.ndarray
    link: str
    tree_joint: str
    bodies: tuple[str, str]


@dataclass(frozen=True)
class BodySpec:
    """A moving body hung from the link of its last joint.

    Attributes
    ----------
    name : str
    link : str
        The joint link it is fixed to.
    offset : ndarray, shape (2,), m
        Origin of the body frame in the link frame (same orientation).
    mass : float, kg
    com : ndarray, shape (2,), m
        Centre of mass in the body frame.
    inertia : float, kg m^2
        Moment of inertia about the z axis through the centre of mass.
    default : bool
        True when the mass properties are defaults, not from the model.
    """

    name: str
    link: str
    offset: np.ndarray
    mass: float
    com: np.ndarray
    inertia: float
    default: bool


@dataclass(frozen=True)
class DriverCoordinate:
    """Where a driver's input is in the Pinocchio coordinates.

    The input equals ``sign * q[index]`` (and the same for v and a): nq = nv
    for every joint used here.
    """

    driver: str
    joint: str
    index: int
    sign: float


@dataclass(frozen=True)
class TreeSpec:
    """The tree, frames and loop closures of one mechanism, engine-neutral.

    Attributes
    ----------
    mechanism : Mechanism
    joints : tuple of JointSpec
        Parents first.
    bodies : tuple of BodySpec
        Moving bodies in ``mechanism.moving_bodies`` order.
    points : tuple of (str, str, ndarray)
        (body, label, local position (2,) m) of every named point, ground first.
    cuts : tuple of Joint
        Loop-closing joints: a revolute's point ``point_a`` of ``body_a`` on
        ``point_b`` of ``body_b``; a pin-in-slot's or prismatic's carrier on
        ``body_b`` (see the module notes).
    drivers : tuple of (str, str, float)
        Per driver: its name, the joint carrying its input, and the sign.
    """

    mechanism: Mechanism
    joints: tuple[JointSpec, ...]
    bodies: tuple[BodySpec, ...]
    points: tuple[tuple[str, str, np.ndarray], ...]
    cuts: tuple[Joint, ...]
    drivers: tuple[tuple[str, str, float], ...]
    #: (body, frame name, position (2,) m, angle rad) of each prismatic cut's block frame
    blocks: tuple[tuple[str, str, np.ndarray, float], ...] = ()
    #: mass properties of the carriers that have mass (name: the carrier joint; link: its link)
    carriers: tuple[BodySpec, ...] = ()


def point_frame(body: str, label: str) -> str:
    """Frame name of a named point: ``"<body>.<label>"``."""
    return f"{body}.{label}"


def mass_properties(body: Body, size: float) -> tuple[float, np.ndarray, float, bool]:
    """Mass (kg), centre of mass (2,) m, inertia about it (kg m^2), and whether defaulted.

    A body without mass properties gets 1 kg at the centroid of its named
    points and the inertia of a uniform slender bar as long as the largest
    distance L between two of its points, m L^2 / 12, with L at least a tenth
    of the mechanism's size (so a one-point slider block has inertia too).
    """
    if body.mass is not None:
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        assert body.inertia is not None  # the loader reads mass and inertia together
        return float(body.mass), com, float(body.inertia), False
    pts = np.array(list(body.points.values()))
    span = max((float(np.linalg.norm(p - r)) for p in pts for r in pts), default=0.0)
    span = max(span, 0.1 * size)
    return 1.0, pts.mean(axis=0), span * span / 12.0, True


def _unit3(xy) -> np.ndarray:
    return np.array([float(xy[0]), float(xy[1]), 0.0])


_Z = np.array([0.0, 0.0, 1.0])


def _revolute_steps(mechanism: Mechanism, tj: TreeJoint, j: Revolute):
    """A revolute: one revolute Pinocchio joint at the pin; its coordinate, signed as the driver's."""
    l_parent, l_child = j.tree_points[::-1] if tj.reversed else j.tree_points
    s_parent = mechanism.body(tj.parent).points[l_parent]
    s_child = mechanism.body(tj.child).points[l_child]
    return [("revolute", j.name, s_parent, 0.0, _Z)], s_parent, s_child, (j.name, -1.0 if tj.reversed else 1.0)


def _line_ends(mechanism: Mechanism, j: LineJoint):
    return mechanism.body(j.body_a).points[j.line_point], mechanism.body(j.body_b).points[j.point], j.direction


def _prismatic_steps(mechanism: Mechanism, tj: TreeJoint, j: Prismatic):
    """A prismatic joint: one prismatic Pinocchio joint, its frame at the line's point of the
    parent turned by the locked angle (or at the child's line point, axis reversed)."""
    s_line, s_point, d = _line_ends(mechanism, j)
    if not tj.reversed:  # frame at the sliding point, turned by the locked angle
        steps = [("prismatic", j.name, s_line, j.angle, _unit3(rotate(-j.angle, d)))]
        return steps, s_line, s_point, (j.name, 1.0)
    steps = [("prismatic", j.name, s_point, -j.angle, -_unit3(d))]  # frame at the line point of the child
    return steps, s_point, s_line, (j.name, 1.0)


def _slot_steps(mechanism: Mechanism, tj: TreeJoint, j: PinInSlot):
    """A pin-in-slot: a slide and a hinge through a massless link."""
    s_line, s_point, d = _line_ends(mechanism, j)
    slide = (f"{j.name}.slide", 1.0)
    if not tj.reversed:
        steps = [
            ("prismatic", f"{j.name}.slide", s_line, 0.0, _unit3(d)),
            ("revolute", f"{j.name}.turn", np.zeros(2), 0.0, _Z),
        ]
        return steps, s_line, s_point, slide
    steps = [
        ("revolute", f"{j.name}.turn", s_point, 0.0, _Z),
        ("prismatic", f"{j.name}.slide", np.zeros(2), 0.0, -_unit3(d)),
    ]
    return steps, s_point, s_line, slide


#: a tree joint's Pinocchio joints, by its type: (steps, its point on the parent and on the child, the driven
#: coordinate and its sign)
_TREE_STEPS: dict[type, Callable] = {Revolute: _revolute_steps, Prismatic: _prismatic_steps, PinInSlot: _slot_steps}


def tree_spec(mechanism: Mechanism, carrier_mass: bool = True) -> TreeSpec:
    """The Pinocchio description of a mechanism (see the module notes).

    Parameters
    ----------
    carrier_mass : bool
        Give the carriers of pin-in-slot and prismatic cuts the mass that
        :func:`xcheck.topology.carrier_share` takes from the bodies they are
        held to (the mass distribution stays the model's). A massless carrier
        at the end of the tree makes the joint-space inertia singular, which
        ``constraintDynamics`` cannot factor; inverse dynamics (RNEA) works
        with massless carriers and reads the cut's force directly.

    Raises
    ------
    ModelError
        If the mechanism's joints have no spanning tree, or two generated
        frame names clash.
    """
    topology = spanning_tree(mechanism)
    joints: list[JointSpec] = []
    attach: dict[str, tuple[str, np.ndarray]] = {}  # child body -> (joint link, its joint point)
    drivers: dict[str, tuple[str, float]] = {}
    for tj in topology.tree:
        j, parent, child = tj.joint, tj.parent, tj.child
        steps, s_parent, s_child, coordinate = converter(_TREE_STEPS, j, "Pinocchio")(mechanism, tj, j)
        if tj.driver:
            drivers[tj.driver] = coordinate
        frame = parent
        for kind, name, origin, angle, axis in steps:
            link = f"{name}.link"
            joints.append(
                JointSpec(
                    name, kind, frame, np.array(origin, dtype=float), float(angle), axis, link, j.name, (parent, child)
                )
            )
            frame = link
        attach[child] = (frame, np.array(s_child, dtype=float))

    blocks = []
    for cut in topology.cuts:  # carriers of the cuts at pin-in-slot and prismatic joints
        if not isinstance(cut, LineJoint):
            continue
        line = mechanism.body(cut.body_a).points[cut.line_point]
        name = carrier_joint(cut)
        joints.append(
            JointSpec(
                name,
                "prismatic",
                cut.body_a,
                np.array(line, dtype=float),
                0.0,
                _unit3(cut.direction),
                f"{name}.link",
                cut.name,
                (cut.body_a, cut.body_a),
            )
        )
        if cut.locked_angle is not None:
            blocks.append(
                (
                    cut.body_b,
                    block_frame(cut),
                    np.array(mechanism.body(cut.body_b).points[cut.point], dtype=float),
                    -float(cut.locked_angle),
                )
            )

    size = mechanism.size
    props = {body.name: mass_properties(body, size) for body in mechanism.moving_bodies}
    carriers = []
    for cut in topology.cuts if carrier_mass else ():
        if not isinstance(cut, LineJoint):
            continue
        held = props.get(cut.body_b)
        line_mass = props[cut.body_a][0] if cut.body_a in props else 1.0
        (mass, com, inertia), rest = carrier_share(mechanism, cut, None if held is None else held[:3], line_mass)
        name = carrier_joint(cut)
        carriers.append(BodySpec(name, f"{name}.link", np.zeros(2), mass, com, inertia, False))
        if rest is not None:
            assert held is not None  # carrier_share leaves a rest only to a moving body
            props[cut.body_b] = (*rest, held[3])
    bodies = []
    for body in mechanism.moving_bodies:
        link, s_child = attach[body.name]
        mass, com, inertia, default = props[body.name]
        bodies.append(BodySpec(body.name, link, -s_child, mass, com, inertia, default))
    points = tuple(
        (b.name, label, np.array(xy, dtype=float)) for b in mechanism.bodies for label, xy in b.points.items()
    )
    spec = TreeSpec(
        mechanism,
        tuple(joints),
        tuple(bodies),
        points,
        topology.cuts,
        tuple((d.name, *drivers[d.name]) for d in mechanism.drivers),
        tuple(blocks),
        tuple(carriers),
    )
    links = (
        [GROUND]
        + [j.link for j in spec.joints]
        + [b.name for b in spec.bodies]
        + [point_frame(b, lbl) for b, lbl, _ in spec.points]
        + [name for _, name, _, _ in spec.blocks]
    )
    joint_names = [j.name for j in spec.joints] + [fixed_joint(link) for link in links[1:]]
    for kind, names in (("link", links), ("joint", joint_names)):
        clash = sorted({n for n in names if names.count(n) > 1})
        if clash:
            raise ModelError(
                mechanism.path,
                "bodies",
                f"body, joint and point names that give distinct Pinocchio/URDF {kind} names",
                f"{clash[0]!r} more than once",
            )
    return spec


def carrier_joint(joint: Joint) -> str:
    """Name of the carrier joint of a cut pin-in-slot or prismatic joint: ``"<joint>.carrier"``."""
    return f"{joint.name}.carrier"


def block_frame(joint: Joint) -> str:
    """Name of the block frame a prismatic cut's carrier is held to: ``"<joint>.block"``."""
    return f"{joint.name}.block"


def fixed_joint(link: str) -> str:
    """Name of the URDF fixed joint that hangs a body or point link: ``"<link>.fixed"``."""
    return f"{link}.fixed"


def _se3(angle: float, xy: np.ndarray) -> pin.SE3:
    c, s = math.cos(angle), math.sin(angle)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return pin.SE3(rotation, _unit3(xy))


def spatial_inertia(body: BodySpec) -> pin.Inertia:
    """The body's spatial inertia in its body frame: a lamina in the x-y plane
    (Ixx = Iyy = Izz / 2 about the centre of mass; only Izz acts in planar motion)."""
    izz = body.inertia
    return pin.Inertia(body.mass, _unit3(body.com), np.diag([0.5 * izz, 0.5 * izz, izz]))


@dataclass(frozen=True)
class PinocchioMechanism:
    """A mechanism as a Pinocchio model (the description; data is made apart).

    Attributes
    ----------
    spec : TreeSpec
    model : pin.Model
    constraints : list of pin.RigidConstraintModel
        One per cut, LOCAL_WORLD_ALIGNED, in ``spec.cuts`` order: CONTACT_3D
        (revolute, pin-in-slot) or CONTACT_6D (prismatic).
    body_frames : dict of str to int
        Moving body -> frame id of its body frame.
    point_frames : dict of str to int
        ``"<body>.<label>"`` -> frame id.
    drivers : tuple of DriverCoordinate
    """

    spec: TreeSpec
    model: pin.Model
    constraints: list
    body_frames: dict
    point_frames: dict
    drivers: tuple[DriverCoordinate, ...]

    @property
    def mechanism(self) -> Mechanism:
        return self.spec.mechanism

    def constraint_datas(self) -> list:
        """Fresh workspaces for the constraints (one per constraint model)."""
        return [cm.createData() for cm in self.constraints]

    def constraint_rows(self) -> list[tuple[int, int]]:
        """(first row, rows) of each constraint in the stacked loop rows: 3 for a
        CONTACT_3D (x, y, z), 6 for a CONTACT_6D (x, y, z, then rotation x, y, z)."""
        out, offset = [], 0
        for cm in self.constraints:
            rows = 6 if cm.type == pin.ContactType.CONTACT_6D else 3
            out.append((offset, rows))
            offset += rows
        return out

    def input_selector(self) -> np.ndarray:
        """S, shape (k, nv): the drivers' inputs are ``S q`` (and their rates ``S v``)."""
        selector = np.zeros((len(self.drivers), self.model.nv))
        for k, dc in enumerate(self.drivers):
            selector[k, dc.index] = dc.sign
        return selector


def depth_first(spec: TreeSpec) -> list[JointSpec]:
    """The joints in depth-first order (each joint's subtree right after it, siblings
    in ``spec.joints`` order). Pinocchio numbers the velocity coordinates in the
    order joints are added, and its sparse Cholesky of ``constraintDynamics``
    takes each subtree's coordinates to be contiguous (``model.check()``): in
    breadth-first order (``spec.joints``) a tree with two branches gets wrong
    constrained accelerations (measured on the double four-bar: J a 1.4 m/s^2
    off the loops)."""
    hung = {b.link: b.name for b in spec.bodies}
    owner = {}  # frame name (link or hung body) -> index of the joint that carries it
    for i, js in enumerate(spec.joints):
        owner[js.link] = i
        if js.link in hung:
            owner[hung[js.link]] = i
    children: dict[int, list[int]] = {}
    for i, js in enumerate(spec.joints):
        children.setdefault(owner.get(js.parent, -1), []).append(i)
    order: list[int] = []
    stack = list(reversed(children.get(-1, [])))
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children.get(i, [])))
    return [spec.joints[i] for i in order]


def build_model(spec: TreeSpec) -> PinocchioMechanism:
    """Build the Pinocchio model of a :class:`TreeSpec` through the API
    (``addJoint``, ``appendBodyToJoint``, ``addBodyFrame``, ``addFrame``)."""
    model = pin.Model()
    model.name = spec.mechanism.name
    # the mechanism's gravity, in the plane (zero when it gives none; Pinocchio's default -z
    # would act normal to the plane and do no work, but would load the joints out of plane)
    model.gravity = pin.Motion(np.array([*spec.mechanism.gravity, 0.0]), np.zeros(3))
    frame_joint = {GROUND: (0, pin.SE3.Identity())}  # frame name -> (joint id, placement in joint)
    frame_id = {GROUND: 0}  # ... -> id of the Pinocchio frame standing for it
    hung = {b.link: b for b in spec.bodies}
    body_frames, point_frames = {}, {}
    for js in depth_first(spec):
        parent_joint, parent_placement = frame_joint[js.parent]
        if js.kind == "revolute":
            joint_model = pin.JointModelRZ()
        else:
            joint_model = pin.JointModelPrismaticUnaligned(js.axis.copy())
        jid = model.addJoint(parent_joint, joint_model, parent_placement * _se3(js.angle, js.origin), js.name)
        joint_frame = model.addJointFrame(jid, frame_id[js.parent])
        frame_joint[js.link], frame_id[js.link] = (jid, pin.SE3.Identity()), joint_frame
        if js.link in hung:  # the child body's frame, with its inertia
            child = hung[js.link]
            placement = _se3(0.0, child.offset)
            model.appendBodyToJoint(jid, spatial_inertia(child), placement)
            body_frames[child.name] = model.addBodyFrame(child.name, jid, placement, joint_frame)
            frame_joint[child.name], frame_id[child.name] = (jid, placement), body_frames[child.name]
    for carrier in spec.carriers:
        model.appendBodyToJoint(frame_joint[carrier.link][0], spatial_inertia(carrier), pin.SE3.Identity())
    for body, label, xy in spec.points:
        jid, placement = frame_joint[body]
        parent_frame = 0 if body == GROUND else body_frames[body]
        name = point_frame(body, label)
        point_frames[name] = model.addFrame(
            pin.Frame(name, jid, parent_frame, placement * _se3(0.0, xy), pin.FrameType.OP_FRAME), False
        )
    block_frames = {}
    for body, name, xy, angle in spec.blocks:
        jid, placement = frame_joint[body]
        parent_frame = 0 if body == GROUND else body_frames[body]
        block_frames[name] = model.addFrame(
            pin.Frame(name, jid, parent_frame, placement * _se3(angle, xy), pin.FrameType.OP_FRAME), False
        )
    constraints = []
    for cut in spec.cuts:
        anchors = []
        kind, frames = converter(_CONTACTS, cut, "Pinocchio")(cut, frame_id, point_frames, block_frames)
        for fid in frames:
            frame = model.frames[fid]
            anchors += [frame.parentJoint, frame.placement]
        cm = pin.RigidConstraintModel(kind, model, *anchors, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        cm.name = cut.name
        constraints.append(cm)
    index = {model.names[j]: model.idx_qs[j] for j in range(1, model.njoints)}
    drivers = tuple(DriverCoordinate(name, joint, index[joint], sign) for name, joint, sign in spec.drivers)
    return PinocchioMechanism(spec, model, constraints, body_frames, point_frames, drivers)


def _pin_contact(cut: Revolute, frame_id: dict, point_frames: dict, block_frames: dict):
    """A loop cut at a revolute: a 3-D contact between its two points' frames."""
    frames = [point_frames[point_frame(body, label)] for body, label in cut.anchors()]
    return pin.ContactType.CONTACT_3D, frames


def _weld_contact(cut: Prismatic, frame_id: dict, point_frames: dict, block_frames: dict):
    """A loop cut at a prismatic joint: a 6-D contact between its carrier and the block."""
    return pin.ContactType.CONTACT_6D, [frame_id[f"{carrier_joint(cut)}.link"], block_frames[block_frame(cut)]]


def _slot_contact(cut: PinInSlot, frame_id: dict, point_frames: dict, block_frames: dict):
    """A loop cut at a pin-in-slot: a 3-D contact between its carrier and the pin."""
    frames = [frame_id[f"{carrier_joint(cut)}.link"], point_frames[point_frame(cut.body_b, cut.point)]]
    return pin.ContactType.CONTACT_3D, frames


#: how a loop cut at each joint type is closed
_CONTACTS: dict[type, Callable | str] = {
    Revolute: _pin_contact,
    Prismatic: _weld_contact,
    PinInSlot: _slot_contact,
    GearPair: "Pinocchio's constraint models (contacts, anchors, joint limits and friction) couple no joint "
    "coordinates (a mimic joint would; xcheck's Pinocchio model does not build one)",
}


def joint_coordinates(pm: PinocchioMechanism, q_bodies: np.ndarray) -> np.ndarray:
    """Pinocchio joint coordinates (nq,) from the native body coordinates.

    Parameters
    ----------
    q_bodies : ndarray, shape (3 * moving bodies,)
        (x, y, phi) per moving body, ``mechanism.moving_bodies`` order (m, rad).

    Notes
    -----
    A hinge's coordinate is the child's angle minus the parent's (not wrapped:
    the native driver rows hold the input angles exactly, so a driven hinge
    equals its input); a slide's is the slide displacement
    ``direction . (r_point - r_line_point)`` (m), in the line body's frame.
    """
    mech = pm.mechanism
    names = [b.name for b in mech.moving_bodies]

    def pose(body):
        if body == GROUND:
            return np.zeros(2), 0.0
        k = 3 * names.index(body)
        return q_bodies[k : k + 2], float(q_bodies[k + 2])

    def state(body, label):
        r, phi = pose(body)
        return (r if label is None else r + rotate(phi, mech.body(body).points[label])), np.zeros(2), phi, 0.0

    q = np.zeros(pm.model.nq)
    model = pm.model
    for js in pm.spec.joints:
        idx = model.idx_qs[model.getJointId(js.name)]
        if js.kind == "revolute":
            parent, child = js.bodies
            q[idx] = pose(child)[1] - pose(parent)[1]
        else:
            # a prismatic Pinocchio joint: its line joint's (or, a carrier's, its cut's) slide displacement
            q[idx] = mech.joint(js.tree_joint).coordinate(state)[0]
    return q
