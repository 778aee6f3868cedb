"""The mechanism as an MJCF file: a tree of hinge and slide joints, loops closed
by site-based ``connect`` constraints, the input joints driven by servos.

The writer only reads the canonical model (nothing converts back). Conventions
of the file, which the adapter relies on:

- Every MuJoCo body frame coincides with the model's body frame, so body
  positions and angles compare directly with the native solver's.
- Each joint coordinate is the model's own joint quantity: a hinge's ``qpos``
  is ``phi_b - phi_a`` (axis -z when the tree runs from body_b to body_a), a
  slide's is the joint's slide displacement ``direction . (r_point - r_line_point)``.
- A pin-in-slot joint in the tree is a slide and a hinge in one body, slide
  first when the slot is in the parent, hinge first when it is in the child
  (MuJoCo applies a body's joints in order). MuJoCo rejects the massless
  intermediate body of the textbook construction ("mass and inertia of moving
  bodies must be larger than mjMINVAL"); two joints in one body are exact.
- A loop cut at a revolute is closed by a ``connect`` between its two sites. A
  loop cut at a pin-in-slot or prismatic joint (one with no undriven revolute,
  see :mod:`xcheck.topology`) is closed through a carrier body
  ``"<joint>.carrier"``: a child of the line's body (``body_a``) with one slide
  ``"<joint>.carrier"`` along the line (its ``qpos`` the joint's slide
  displacement), held by a ``connect`` to the pin (pin-in-slot) or by a site
  ``weld`` to the sliding body turned by the locked angle (prismatic).
- MuJoCo needs mass on the carrier, so it is taken from the body it is held to
  and the total is exact (:func:`carrier_split`): a prismatic carrier moves
  rigidly with its block and takes half of the block's mass, centre of mass and
  inertia; a pin-in-slot carrier is a point mass at the pin (it moves with the
  pin point but turns with the slot), taken from the pin's body with its centre
  of mass and inertia moved so that the body plus the point mass have the
  body's mass properties. The carrier's only own term is a rotational inertia
  of 1e-9 m size^2 (at least 1e-14 kg m^2; MuJoCo refuses zero).
  Where the pin or block is the ground, the carrier stands still (a mass from
  the line's body; it does no work).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from xcheck.engines._contract import positive_inertia
from xcheck.errors import XcheckError
from xcheck.joints import GearPair, LineJoint, converter
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND, Joint, Mechanism, PinInSlot, Prismatic, Revolute
from xcheck.motion import simulation_window
from xcheck.precision import number, numbers
from xcheck.topology import Topology, TreeJoint, carrier_share, spanning_tree

__all__ = [
    "DEFAULT_MASS",
    "SERVO_FREQUENCY",
    "TIGHT_INTEGRATOR",
    "TIGHT_TIMESTEP",
    "TIGHT_SOLREF",
    "TIGHT_SOLIMP",
    "TIGHT_TOLERANCE",
    "MUJOCO_SOLREF",
    "MUJOCO_SOLIMP",
    "MUJOCO_TOLERANCE",
    "CARRIER_INERTIA",
    "CARRIER_INERTIA_FLOOR",
    "MassProperties",
    "MjJoint",
    "Layout",
    "layout",
    "mass_properties",
    "carrier_name",
    "carrier_note",
    "weld_site",
    "carrier_split",
    "coupling",
    "file_mass_properties",
    "joint_coordinates",
    "mjcf_text",
]

#: Mass (kg) of a body whose model gives no mass properties.
DEFAULT_MASS = 1.0
#: Radius of gyration of a default body's disc term, as a fraction of the
#: mechanism's size, so that a one-point body (a slider block) has inertia too.
DEFAULT_DISC_FRACTION = 0.05
#: Natural frequency (rad/s) of each input's servo, critically damped. With
#: MuJoCo's default 2 ms Euler step, omega dt = 0.5: stable (the limit is 1).
SERVO_FREQUENCY = 250.0
#: The file's solver settings: those of the dynamic mode's tight runs at their
#: largest timestep (:data:`xcheck.engines.mujoco.dynamic.TIGHT`: RK4, equality
#: solref = 2 dt with damping ratio 1, solimp 0.9999, solver tolerance 1e-12).
TIGHT_INTEGRATOR = "RK4"
TIGHT_TIMESTEP = 1e-3
TIGHT_SOLREF = (2.0 * TIGHT_TIMESTEP, 1.0)
TIGHT_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
TIGHT_TOLERANCE = 1e-12
#: MuJoCo's own defaults (what a file without settings gets): the dynamic
#: mode's 'default' runs.
MUJOCO_SOLREF = (0.02, 1.0)
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
MUJOCO_TOLERANCE = 1e-8
#: Rotational inertia of a pin-in-slot carrier, times its mass and the
#: mechanism's size squared (MuJoCo refuses a body with zero inertia) ...
CARRIER_INERTIA = 1e-9
#: ... and at least this, kg m^2 (MuJoCo's floor, mjMINVAL, is 1e-15).
CARRIER_INERTIA_FLOOR = 1e-14


def _text(x: float) -> str:
    """A float as the shortest text that reads back to the same double."""
    text = repr(float(x) + 0.0)  # no negative zero
    return text[:-2] if text.endswith(".0") else text


def _num(x: float, scale: float = 0.0) -> str:
    """A number of the file (:func:`xcheck.precision.number`: canonical when exported)."""
    return _text(number(x, scale))


def _vec(*values: float, scale: float = 0.0) -> str:
    """A vector of the file, each component on the scale of the largest (or ``scale``)."""
    return " ".join(_text(v) for v in numbers(values, scale))


@dataclass(frozen=True)
class MassProperties:
    """Mass (kg), centre of mass (body frame, (2,) m), inertia about it (kg m^2),
    and whether they are the writer's defaults."""

    mass: float
    com: np.ndarray
    inertia: float
    default: bool


def mass_properties(mechanism: Mechanism) -> dict[str, MassProperties]:
    """Each moving body's mass properties: the model's, or defaults.

    The default is :data:`DEFAULT_MASS` at the centroid of the body's points
    with the inertia of a uniform rod as long as the body's largest point
    distance L, plus a disc term: ``m (L^2 / 12 + (0.05 size)^2 / 2)``.
    """
    out = {}
    radius = DEFAULT_DISC_FRACTION * mechanism.size
    for body in mechanism.moving_bodies:
        if body.mass is not None:
            assert body.inertia is not None  # the loader reads mass and inertia together
            com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
            inertia = positive_inertia(body.mass, body.inertia, mechanism.size)  # a point mass: MuJoCo needs > 0
            out[body.name] = MassProperties(body.mass, com, inertia, False)
            continue
        pts = np.array(list(body.points.values()))
        length = max((float(np.linalg.norm(p - q)) for p in pts for q in pts), default=0.0)
        m = DEFAULT_MASS
        out[body.name] = MassProperties(m, pts.mean(axis=0), m * (length**2 / 12.0 + radius**2 / 2.0), True)
    return out


def carrier_name(joint) -> str:
    """Name of the carrier body, its slide joint and its site: ``"<joint>.carrier"``."""
    return f"{joint.name}.carrier"


def carrier_split(
    mechanism: Mechanism, cut, held: MassProperties | None, line_body: MassProperties | None
) -> tuple[MassProperties, MassProperties | None]:
    """(carrier's mass properties in its own frame, what is left to the held body).

    :func:`xcheck.topology.carrier_share`, plus, for a pin-in-slot carrier, a
    rotational inertia of :data:`CARRIER_INERTIA` m_c size^2 (at least
    :data:`CARRIER_INERTIA_FLOOR`), which MuJoCo requires and nothing offsets.

    Parameters
    ----------
    cut : PinInSlot or Prismatic
        The loop cut; the carrier slides on ``body_a`` and is held to ``body_b``.
    held, line_body : MassProperties or None
        ``body_b``'s and ``body_a``'s current mass properties; None for the ground.
    """
    carrier, rest = carrier_share(
        mechanism,
        cut,
        None if held is None else (held.mass, held.com, held.inertia),
        line_body.mass if line_body is not None else DEFAULT_MASS,
    )
    mass, com, inertia = carrier
    if cut.locked_angle is None:  # a pin's carrier turns with the slot: MuJoCo needs it some inertia
        inertia = _carrier_inertia(mass, mechanism.size**2)
    if rest is None:
        return MassProperties(mass, com, inertia, False), None
    assert held is not None  # carrier_share leaves a rest only to a moving body
    return MassProperties(mass, com, inertia, False), MassProperties(*rest, held.default)


def _carrier_inertia(mass: float, size2: float) -> float:
    return max(CARRIER_INERTIA * mass * size2, CARRIER_INERTIA_FLOOR)


def carrier_note(mechanism: Mechanism, topology: Topology) -> str:
    """One or two sentences on the carriers of a file, for a mode's notes ("" if none)."""
    _, carriers = file_mass_properties(mechanism, topology)
    if not carriers:
        return ""
    pins = {
        name: props
        for name, props in carriers.items()
        if mechanism.joint(name.removesuffix(".carrier")).locked_angle is None
    }
    text = (
        f"Loops with no undriven revolute are closed through carrier bodies ({', '.join(carriers)}) whose "
        "mass is taken from the bodies they are held to, so the mass distribution is the model's."
    )
    if pins:
        largest = max(props.inertia for props in pins.values())
        text += (
            f" The only term not in the model: the pin-in-slot carriers' rotational inertia (at most "
            f"{largest:.3g} kg m^2, turning with the slot's body), a moment of that times the slot's "
            "angular acceleration."
        )
    return text


def weld_site(joint) -> str:
    """Name of the site on the block that a prismatic cut's carrier is welded to: ``"<joint>.block"``."""
    return f"{joint.name}.block"


def file_mass_properties(mechanism: Mechanism, topology: Topology) -> tuple[dict, dict]:
    """(bodies' mass properties as written, carriers' by carrier name): the
    model's (or defaults) with each carrier's share taken from its held body."""
    bodies = mass_properties(mechanism)
    carriers = {}
    for cut in topology.cuts:
        if not isinstance(cut, LineJoint):
            continue
        carrier, rest = carrier_split(mechanism, cut, bodies.get(cut.body_b), bodies.get(cut.body_a))
        carriers[carrier_name(cut)] = carrier
        if rest is not None:
            bodies[cut.body_b] = rest
    return bodies, carriers


@dataclass(frozen=True)
class MjJoint:
    """One MuJoCo joint: its name, ``"hinge"`` or ``"slide"``, the model joint it
    belongs to and the body that carries it."""

    name: str
    kind: str
    joint: Joint
    body: str


@dataclass(frozen=True)
class Layout:
    """How the model maps onto the MJCF file.

    Attributes
    ----------
    topology : Topology
    joints : tuple of MjJoint
        In ``qpos`` order (MuJoCo numbers joints depth-first through the tree).
    driver_joints : tuple of str
        The MuJoCo joint of each driver, in driver order.
    """

    topology: Topology
    joints: tuple[MjJoint, ...]
    driver_joints: tuple[str, ...]


def _site(body: str, label: str) -> str:
    return f"{body}.{label}"


def _mj_name(joint: Joint, kind: str) -> str:
    """The MuJoCo joint of a tree joint's axis ``kind``: the joint's name, or
    ``"<joint>.<kind>"`` where it has two (a pin-in-slot: a slide and a hinge)."""
    return joint.name if len(joint.tree_axes) == 1 else f"{joint.name}.{kind}"


def _tree_joints(tj: TreeJoint) -> list[tuple[str, str]]:
    """(MuJoCo joint name, kind) of a tree joint, in the order the body applies them:
    its axes from the parent side (:attr:`~xcheck.joints.Joint.tree_axes`)."""
    axes = tj.joint.tree_axes[::-1] if tj.reversed else tj.joint.tree_axes
    return [(_mj_name(tj.joint, kind), kind) for kind in axes]


def _children(topology: Topology) -> dict[str, list[TreeJoint]]:
    """Tree joints by parent body, in tree order."""
    children: dict[str, list[TreeJoint]] = {}
    for tj in topology.tree:
        children.setdefault(tj.parent, []).append(tj)
    return children


def _carried(topology: Topology, body: str) -> list:
    """The pin-in-slot and prismatic cuts whose line is on ``body`` (their carriers hang from it)."""
    return [cut for cut in topology.cuts if isinstance(cut, LineJoint) and cut.body_a == body]


def layout(mechanism: Mechanism) -> Layout:
    """The MJCF layout of a mechanism.

    Raises
    ------
    ModelError
        If the joints have no spanning tree (see :func:`spanning_tree`).
    """
    topology = spanning_tree(mechanism)
    children = _children(topology)
    joints: list[MjJoint] = []

    def visit(body: str) -> None:
        for tj in children.get(body, []):
            joints.extend(MjJoint(name, kind, tj.joint, tj.child) for name, kind in _tree_joints(tj))
            visit(tj.child)
        for cut in _carried(topology, body):
            joints.append(MjJoint(carrier_name(cut), "slide", cut, carrier_name(cut)))

    visit(GROUND)
    driver_joints = []
    for driver in mechanism.drivers:
        joint = mechanism.joint(driver.joint)
        driver_joints.append(_mj_name(joint, "hinge" if driver.quantity == "angle" else "slide"))
    return Layout(topology, tuple(joints), tuple(driver_joints))


def joint_coordinates(mechanism: Mechanism, lay: Layout, q: np.ndarray) -> np.ndarray:
    """MuJoCo ``qpos`` of body coordinates.

    Parameters
    ----------
    q : ndarray, shape (3 m,)
        x (m), y (m), phi (rad) of each moving body, ``mechanism.moving_bodies`` order.

    Returns
    -------
    ndarray, shape (nq,)
        Hinges: ``phi_b - phi_a`` (rad); slides: the slide displacement (m).
    """
    frames = {GROUND: (np.zeros(2), 0.0)}
    for i, body in enumerate(mechanism.moving_bodies):
        frames[body.name] = (np.asarray(q[3 * i : 3 * i + 2]), float(q[3 * i + 2]))

    def state(body: str, label: str | None):
        r, phi = frames[body]
        at = r if label is None else r + rotate(phi, mechanism.body(body).points[label])
        return at, np.zeros(2), phi, 0.0

    qpos = []
    for mj in lay.joints:
        joint = mj.joint
        if mj.kind == "hinge":
            qpos.append(frames[joint.body_b][1] - frames[joint.body_a][1])
        else:  # a slide: its joint's (or, a carrier's, its cut's) slide displacement
            qpos.append(joint.coordinate(state)[0])
    return np.array(qpos)


def _servo_inertia(kinematics: Kinematics, masses: dict[str, MassProperties]) -> list[float]:
    """The inertia (kg m^2 or kg) each input's servo is tuned for.

    Per driver j, the smallest over the simulation window (or the reference
    configuration, if the window cannot be found) of ``1 / (M^-1)_jj``, M the
    drivers' k x k effective mass matrix (kinetic energy at unit input rates).
    Tuning every servo for its smallest inertia keeps the servo stable where
    the mechanism is lightest; ``1 / (M^-1)_jj`` bounds the coupled servos'
    highest frequency by sqrt(k) times the nominal one.
    """
    mech = kinematics.mechanism
    k = len(mech.drivers)
    try:
        window = simulation_window(kinematics)
        c = window.inputs(kinematics, window.times(201))[0]
    except XcheckError:
        c = kinematics.reference_inputs()[None]
    velocities = []  # per driver j: per body, (v_com (N, 2), omega (N,)) at unit rate of input j
    for j in range(k):
        rates = np.zeros_like(c)
        rates[:, j] = 1.0
        solution = kinematics.solve(c, rates)
        per_body = []
        for body in mech.moving_bodies:
            state, props = solution.body(body.name), masses[body.name]
            arm = rotate(state["angle"], props.com)
            v_com = state["velocity"] + state["omega"][:, None] * np.stack([-arm[:, 1], arm[:, 0]], axis=1)
            per_body.append((props, v_com, state["omega"]))
        velocities.append(per_body)
    mass = np.zeros((c.shape[0], k, k))
    for i in range(k):
        for j in range(k):
            for (props, v_i, w_i), (_, v_j, w_j) in zip(velocities[i], velocities[j]):
                mass[:, i, j] += props.mass * np.sum(v_i * v_j, axis=1) + props.inertia * w_i * w_j
    good = np.all(np.isfinite(mass), axis=(1, 2))
    apparent = 1.0 / np.diagonal(np.linalg.inv(mass[good]), axis1=1, axis2=2)
    # to 12 digits first, so that the gains' rounding to 3 digits is the same on every machine:
    # iftomm-a02's 3.0 kg m^2 gives kp = 187 500, a tie that round-off of 3.0 tipped to 187 000
    return [_round(float(v), 12) for v in apparent.min(axis=0)]


def _round(x: float, digits: int = 3) -> float:
    return float(f"{x:.{digits - 1}e}")


def _compose(a: tuple[float, np.ndarray], b: tuple[float, np.ndarray]) -> tuple[float, np.ndarray]:
    """The planar rigid motion ``a`` after ``b``; a motion is (angle (rad), translation (2,) m): x -> A(angle) x + t."""
    return a[0] + b[0], rotate(a[0], b[1]) + a[1]


def _joint_motion(kind: str, anchor: np.ndarray, axis: np.ndarray, value: float) -> tuple[float, np.ndarray]:
    """The motion of a body frame by one MuJoCo joint at ``value`` (rad or m), in the frame it is written in.

    A hinge turns about ``anchor`` (``axis[0]`` the sign of its z axis); a slide moves along ``axis``.
    """
    if kind == "hinge":
        turn = float(np.sign(axis[0])) * value
        return turn, anchor - rotate(turn, anchor)
    return 0.0, value * axis


def _assembled(
    pose: tuple[float, np.ndarray], moves: list[tuple[str, str, np.ndarray, np.ndarray]], refs: dict[str, float]
) -> tuple[tuple[float, np.ndarray], list[tuple[str, str, np.ndarray, np.ndarray]]]:
    """A body's pose and joints written at the joints' reference values.

    MuJoCo places a body at ``P T_1(q_1 - ref_1) ... T_n(q_n - ref_n)``: P its
    written pose, T_k its joints in order, each in the frame the previous ones
    leave. The frame written at zero coordinates, ``P0 T_1(q_1) ... T_n(q_n)``,
    is the same motion for every q when P = P0 T_1(r_1) ... T_n(r_n) and joint k
    is written conjugated by ``C_k = T_{k+1}(r_{k+1}) ... T_n(r_n)`` (a hinge's
    anchor and a slide's axis mapped by C_k^-1; the last joint is unchanged).

    Parameters
    ----------
    pose : (float, ndarray (2,))
        P0: the body frame's angle (rad) and position (m) in its parent's frame at zero coordinates.
    moves : list of (name, kind, anchor (2,) m, axis (2,))
        The body's joints in order, written in the body frame (a hinge's axis[0]: the sign of z).
    refs : dict
        Reference value of each joint (rad or m).
    """
    total = pose
    for name, kind, anchor, axis in moves:
        total = _compose(total, _joint_motion(kind, anchor, axis, refs[name]))
    moved = []
    suffix: tuple[float, np.ndarray] = (0.0, np.zeros(2))  # C_k
    for name, kind, anchor, axis in reversed(moves):
        back = rotate(-suffix[0], anchor - suffix[1])  # C_k^-1 (anchor)
        direction = axis if kind == "hinge" else rotate(-suffix[0], axis)
        moved.append((name, kind, back, direction))
        suffix = _compose(_joint_motion(kind, anchor, axis, refs[name]), suffix)
    return total, moved[::-1]


def _connect(cut: Revolute, lay: Layout, refs: dict) -> tuple[str, dict]:
    """A loop cut at a revolute: a connect between its two points' sites."""
    return "connect", {"site1": _site(cut.body_a, cut.point_a), "site2": _site(cut.body_b, cut.point_b)}


def _hold(cut: PinInSlot, lay: Layout, refs: dict) -> tuple[str, dict]:
    """A loop cut at a pin-in-slot: the carrier on the slot connected to the pin."""
    return "connect", {"site1": carrier_name(cut), "site2": _site(cut.body_b, cut.point)}


def _weld(cut: Prismatic, lay: Layout, refs: dict) -> tuple[str, dict]:
    """A loop cut at a prismatic joint: the carrier on the line welded to the block."""
    return "weld", {"site1": carrier_name(cut), "site2": weld_site(cut)}


def coupling(gear: GearPair, lay: Layout) -> tuple[float, float, float]:
    """A gear pair in its gears' revolutes' coordinates, which are the gears'
    rotations relative to the carrier up to a sign s per pin (a pin's ``qpos``
    is ``phi_b - phi_a`` of its own joint): (k, s_a, s_b) of
    :meth:`~xcheck.joints.GearPair.tree_coupling`, q_pin_b = s_b phase + k q_pin_a.

    Raises
    ------
    NotApplicable
        Where a gear's revolute closes a loop: a joint equality couples tree joints only.
    """
    hinges = {mj.name for mj in lay.joints if mj.kind == "hinge"}
    revolutes = {tj.joint.name: tj.joint for tj in lay.topology.tree}
    return gear.tree_coupling(
        lambda pin, body: None if pin not in hinges else 1.0 if revolutes[pin].body_b == body else -1.0,
        "MuJoCo's joint equality",
    )


def _couple(gear: GearPair, lay: Layout, refs: dict) -> tuple[str, dict]:
    """A gear pair: a joint equality between its gears' revolutes (:func:`coupling`);
    MuJoCo keeps q_b - ref_b = c0 + k (q_a - ref_a), so c0 = s_b phase + k ref_a - ref_b."""
    k, _, s_b = coupling(gear, lay)
    c0 = s_b * gear.phase + k * refs[gear.pin_a] - refs[gear.pin_b]
    return "joint", {"joint1": gear.pin_b, "joint2": gear.pin_a, "polycoef": _vec(c0, k, 0.0, 0.0, 0.0)}


#: how a loop cut at each joint type is closed (the gear pair is always such a "cut")
_CLOSURES: dict[type, Any] = {Revolute: _connect, PinInSlot: _hold, Prismatic: _weld, GearPair: _couple}


def _comment(text: str) -> ET.Element[Any]:
    return ET.Comment(" " + text.strip().replace("--", "-") + " ")


def mjcf_text(kinematics: Kinematics) -> str:
    """The MJCF file of a mechanism (UTF-8 text).

    Raises
    ------
    ModelError
        If the mechanism's joints have no spanning tree.
    """
    mech = kinematics.mechanism
    lay = layout(mech)
    masses = mass_properties(mech)
    written, carriers = file_mass_properties(mech, lay.topology)
    size = mech.size
    radius = _round(0.01 * size)  # visual only
    # the assembly: every joint's ref, so that qpos0 (and the keyframe) is the assembled configuration
    qpos = joint_coordinates(mech, lay, kinematics.assemble())
    refs = {mj.name: float(v) for mj, v in zip(lay.joints, qpos)}

    def _ref(name: str, kind: str) -> str:
        """A joint's value at the assembly: an angle (on the scale of pi) or a slide (of the size)."""
        return _num(refs[name], np.pi if kind == "hinge" else size)

    root = ET.Element("mujoco", model=mech.name)
    defaults = [name for name, p in masses.items() if p.default]
    header = [
        f"{mech.title} ({mech.name}), written by xcheck from {Path(mech.path).name}; regenerate, do not edit.",
        "SI units; angles in radians. Body frames are the model's body frames. Hinge qpos = phi_b - phi_a "
        "of the model joint (axis -z where the tree runs from body_b to body_a); slide qpos = the joint's "
        "slide displacement. A pin-in-slot is a slide and a hinge in one body.",
        "Loops are cut at revolutes and closed by site connect constraints"
        + (
            ""
            if not carriers
            else "; a loop with no undriven revolute is cut at a pin-in-slot or prismatic joint J and closed through "
            "a carrier body 'J.carrier' with a slide along J's line (qpos = J's slide displacement), held to the "
            "pin by a connect or to the block by a site weld. Carrier masses are taken from the held bodies "
            "(pin-in-slot: a point mass at the pin, the pin body's centre of mass and inertia moved to keep its "
            "totals; prismatic: half the block), so the mass distribution is the model's; a pin-in-slot carrier "
            f"adds only a rotational inertia of {_num(CARRIER_INERTIA)} m size^2, at least "
            f"{_num(CARRIER_INERTIA_FLOOR)} kg m^2 (MuJoCo needs one)"
        )
        + ". "
        + (
            f"Gravity {_vec(*mech.gravity, 0.0)} m/s^2: the model's."
            if np.any(mech.gravity)
            else "Gravity is zero: the model gives none (the kinematic comparison does not depend on loads)."
        )
        + (
            f" The model's applied loads ({', '.join(load.name for load in mech.loads)}) are not in the file: "
            "xcheck's inverse dynamics applies them (xfrc_applied), its free motion through mjcb_passive."
            if mech.loads
            else ""
        )
        + (
            " The model's springs are spatial tendons (stiffness, springlength, damping: tension k (l - l0) + "
            "c dl/dt, the same law)."
            if mech.springs
            else ""
        )
        + (
            f" Its rotational springs ({', '.join(t.name for t in mech.rotational_springs)}) are not in the file: "
            "xcheck's free motion applies them through mjcb_passive."
            if mech.rotational_springs
            else ""
        )
        + " Links never collide (contype = conaffinity = 0).",
        "Mass properties: "
        + (
            "the model's."
            if not defaults
            else f"defaults for {', '.join(defaults)} (the model gives none): "
            f"{_num(DEFAULT_MASS)} kg at the centroid of the body's points, inertia "
            f"m (L^2/12 + r^2/2), L the body's largest point distance, r = "
            f"{_num(DEFAULT_DISC_FRACTION)} x mechanism size."
        ),
        "Each input is driven by a position servo (kp, ctrl = the motion law's value) plus a velocity servo "
        f"(kv, ctrl = the law's rate): critically damped at {_num(SERVO_FREQUENCY)} rad/s for the input's "
        "smallest apparent inertia over the simulation window (gains rounded to 3 digits).",
        f"Solver settings: the tight ones xcheck's dynamic mode verifies against the exact solution (its "
        f"'tight' runs): {TIGHT_INTEGRATOR}, timestep {_num(TIGHT_TIMESTEP)} s (the largest of its tight "
        f"runs), equality solref = 2 timestep, damping ratio 1 ({_vec(*TIGHT_SOLREF)}), solimp "
        f"{_vec(*TIGHT_SOLIMP)} (the largest impedance), solver tolerance {_num(TIGHT_TOLERANCE)}. A smaller "
        "timestep needs solref = 2 timestep with it (MuJoCo's refsafe floor). MuJoCo's defaults (Euler, 2 ms, "
        "solref 0.02 1, solimp 0.9 0.95) let the loops open visibly: xcheck's 'default' runs measure that.",
        "Each joint's ref is its value at the assembly (the reference inputs), so qpos0 is the assembled "
        "configuration: the file opens assembled, and qpos keeps the meaning above. Keyframe 'reference': "
        "the same configuration.",
    ]
    for line in header:
        root.append(_comment(line))
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true")
    ET.SubElement(
        root,
        "option",
        gravity=_vec(*mech.gravity, 0.0),
        timestep=_num(TIGHT_TIMESTEP),
        integrator=TIGHT_INTEGRATOR,
        tolerance=_num(TIGHT_TOLERANCE),
    )
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "equality", solref=_vec(*TIGHT_SOLREF), solimp=_vec(*TIGHT_SOLIMP))
    ET.SubElement(default, "geom", contype="0", conaffinity="0", rgba="0.3 0.5 0.8 1")
    ET.SubElement(default, "site", size=_num(_round(1.5 * radius)), rgba="0.9 0.3 0.2 1")

    def add_weld_sites(el: ET.Element, body: str) -> None:
        """The sites that prismatic cuts weld to: at the sliding point, turned by -angle (so that the
        weld holds phi_b - phi_a = angle)."""
        for cut in lay.topology.cuts:
            if isinstance(cut, LineJoint) and cut.locked_angle is not None and cut.body_b == body:
                xy = mech.body(body).points[cut.point]
                attrs = {"name": weld_site(cut), "pos": _vec(xy[0], xy[1], 0.0, scale=size)}
                if cut.locked_angle != 0.0:
                    attrs["axisangle"] = _vec(0.0, 0.0, 1.0, -cut.locked_angle)
                ET.SubElement(el, "site", attrs)

    worldbody = ET.SubElement(root, "worldbody")
    for label, xy in mech.ground.points.items():
        ET.SubElement(worldbody, "site", name=_site(GROUND, label), pos=_vec(xy[0], xy[1], 0.0, scale=size))
    add_weld_sites(worldbody, GROUND)

    children = _children(lay.topology)

    def add_body(parent_el: ET.Element, tj: TreeJoint) -> None:
        joint, body = tj.joint, mech.body(tj.child)
        parent = mech.body(tj.parent)
        # the two points that coincide at zero joint coordinates: the pin's, or the
        # line point (body_a) and the sliding point (body_b)
        point_a, point_b = joint.tree_points
        angle = joint.locked_angle or 0.0  # phi_b - phi_a, locked
        if tj.reversed:
            s_parent, s_child, angle = parent.points[point_b], body.points[point_a], -angle
        else:
            s_parent, s_child = parent.points[point_a], body.points[point_b]
        pos, anchor = s_parent - rotate(angle, s_child), s_child
        # the body's joints at zero coordinates ...
        moves = []
        for name, kind in _tree_joints(tj):
            if kind == "hinge":
                axis = np.array([-1.0 if tj.reversed else 1.0, 0.0])  # (sign of z, unused)
            else:
                assert isinstance(joint, LineJoint)  # a slide belongs to a line joint
                # the line's direction in the child frame (reversed: the child carries the line
                # and moves against it)
                axis = -joint.direction if tj.reversed else rotate(-angle, joint.direction)
            moves.append((name, kind, np.asarray(anchor, dtype=float), np.asarray(axis, dtype=float)))
        # ... written at the assembly: the body's pose at its reference coordinates, each
        # joint's anchor and axis expressed in that frame (see _assembled)
        (angle, pos), moved = _assembled((angle, pos), moves, refs)
        attrs = {"name": body.name, "pos": _vec(pos[0], pos[1], 0.0, scale=size)}
        if number(angle, np.pi) != 0.0:  # an angle at round-off of 0 is 0, on every machine
            attrs["axisangle"] = _vec(0.0, 0.0, 1.0, angle)
        el = ET.SubElement(parent_el, "body", attrs)
        for name, kind, at, axis in moved:
            j_attrs = {"name": name, "type": kind, "pos": _vec(at[0], at[1], 0.0, scale=size), "ref": _ref(name, kind)}
            if kind == "hinge":
                j_attrs["axis"] = "0 0 -1" if axis[0] < 0 else "0 0 1"
            else:
                j_attrs["axis"] = _vec(axis[0], axis[1], 0.0)
            ET.SubElement(el, "joint", j_attrs)
        props = written[body.name]
        ET.SubElement(
            el,
            "inertial",
            pos=_vec(props.com[0], props.com[1], 0.0, scale=size),
            mass=_num(props.mass),
            diaginertia=_vec(props.inertia, props.inertia, props.inertia),
        )
        labels = list(body.points)
        pts = [body.points[lbl] for lbl in labels]
        if len(pts) == 1:
            ET.SubElement(
                el,
                "geom",
                type="box",
                pos=_vec(pts[0][0], pts[0][1], 0.0, scale=size),
                size=_vec(3 * radius, 2 * radius, radius),
            )
        for p, q in zip(pts, pts[1:]):
            ET.SubElement(
                el, "geom", type="capsule", size=_num(radius), fromto=_vec(p[0], p[1], 0.0, q[0], q[1], 0.0, scale=size)
            )
        for label, xy in zip(labels, pts):
            ET.SubElement(el, "site", name=_site(body.name, label), pos=_vec(xy[0], xy[1], 0.0, scale=size))
        add_weld_sites(el, body.name)
        for child in children.get(body.name, []):
            add_body(el, child)
        add_carriers(el, body.name)

    def add_carriers(parent_el: ET.Element, body: str) -> None:
        for cut in _carried(lay.topology, body):
            name, line = carrier_name(cut), mech.body(body).points[cut.line_point]
            at = line + refs[name] * np.asarray(cut.direction, dtype=float)  # the carrier at the assembly
            el = ET.SubElement(parent_el, "body", name=name, pos=_vec(at[0], at[1], 0.0, scale=size))
            ET.SubElement(
                el,
                "joint",
                name=name,
                type="slide",
                pos="0 0 0",
                axis=_vec(cut.direction[0], cut.direction[1], 0.0),
                ref=_ref(name, "slide"),
            )
            props = carriers[name]
            ET.SubElement(
                el,
                "inertial",
                pos=_vec(props.com[0], props.com[1], 0.0, scale=size),
                mass=_num(props.mass),
                diaginertia=_vec(props.inertia, props.inertia, props.inertia),
            )
            ET.SubElement(el, "site", name=name, pos="0 0 0")

    for tj in children.get(GROUND, []):
        add_body(worldbody, tj)
    add_carriers(worldbody, GROUND)

    if lay.topology.cuts:
        equality = ET.SubElement(root, "equality")
        for cut in lay.topology.cuts:
            tag, attrs = converter(_CLOSURES, cut, "MuJoCo")(cut, lay, refs)
            ET.SubElement(equality, tag, {"name": cut.name, **attrs})

    if mech.springs:  # spatial tendons between the ends' sites: MuJoCo's tendon spring-damper is the same law
        tendon = ET.SubElement(root, "tendon")
        owners = mech.point_owners
        for spring in mech.springs:
            el = ET.SubElement(
                tendon,
                "spatial",
                name=f"{spring.name}.spring",
                stiffness=_num(float(spring.stiffness)),
                springlength=_num(float(spring.rest_length)),
                damping=_num(float(spring.damping)),
            )
            for label in spring.points:
                ET.SubElement(el, "site", site=_site(owners[label], label))

    actuator = ET.SubElement(root, "actuator")
    for driver, mj_joint, inertia in zip(mech.drivers, lay.driver_joints, _servo_inertia(kinematics, masses)):
        kp = _round(inertia * SERVO_FREQUENCY**2)
        kv = _round(2.0 * inertia * SERVO_FREQUENCY)
        ET.SubElement(actuator, "position", name=f"{driver.name}.position", joint=mj_joint, kp=_num(kp))
        ET.SubElement(actuator, "velocity", name=f"{driver.name}.velocity", joint=mj_joint, kv=_num(kv))

    keyframe = ET.SubElement(root, "keyframe")
    ET.SubElement(keyframe, "key", name="reference", qpos=" ".join(_ref(mj.name, mj.kind) for mj in lay.joints))

    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"
