"""SDFormat text of a mechanism as Drake loads it (``Parser(plant).AddModels``):
the tree of :mod:`.free` and its loop cuts as ``drake:ball_constraint`` s.

Drake's SDFormat holds what URDF cannot: a ball constraint between two links
(Drake's extension element), so one file carries the whole mechanism. Each
link's pose is the body's frame at the assembly (the model frame is the
world's), so every joint coordinate is 0 there; a link ``ground``, welded to
the world, carries the ground's points (a ball constraint on the world body
crashes pydrake 1.51.1, see :mod:`.free`). A joint's frame is at its point on
the child, its name the mechanism's joint's with ``.joint`` (SDFormat wants
links and joints named apart). A body without mass properties gets the Pinocchio export's defaults
(:func:`xcheck.engines.pinocchio.model.mass_properties`), listed in the file.
Gravity (a world property in SDFormat), springs and loads have no element
Drake parses here; the file's comment states them. Exported, the computed
numbers are canonical (:func:`xcheck.precision.number`: 12 significant digits
of their scale); in memory they read back bit for bit. A pin-in-slot joint or a loop cut
at a prismatic joint is not converted, as in free motion
(:class:`~xcheck.engines.NotApplicable`).
"""

from __future__ import annotations

from collections.abc import Callable
from xml.sax.saxutils import escape

import numpy as np

from xcheck.joints import GearPair, Prismatic, Revolute, converter
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND
from xcheck.precision import number, numbers
from xcheck.topology import spanning_tree

from .model import refuse

__all__ = ["export_files", "sdf_text"]


def _name(text: str) -> str:
    """A name as XML text or attribute value."""
    return escape(text, {'"': "&quot;"})


def _num(value: float, scale: float = 0.0) -> str:
    """A number of the file (:func:`xcheck.precision.number`: canonical when exported)."""
    return repr(number(value, scale))


def _vec(*values: float, scale: float = 0.0) -> str:
    """A vector of the file, each component on the scale of the largest (or ``scale``)."""
    return " ".join(repr(v) for v in numbers(values, scale))


def _pose(x: float, y: float, phi: float, size: float) -> str:
    """A ``<pose>``: the position (m, on the scale of the mechanism's size) and the angle about z (rad)."""
    return f"{_vec(x, y, 0.0, scale=size)} {_vec(0.0, 0.0, phi, scale=np.pi)}"


def sdf_text(kinematics: Kinematics) -> str:
    """The SDFormat text of the mechanism at its assembly (see the module notes).

    Raises
    ------
    NotApplicable
        What the Drake model cannot hold (:func:`xcheck.engines.drake.model.refuse`).
    """
    from xcheck.engines.pinocchio.model import mass_properties

    mech = kinematics.mechanism
    size = mech.size
    topology = spanning_tree(mech)
    refuse(mech, topology)
    q = kinematics.assemble()
    pose = {b.name: q[3 * i : 3 * i + 3] for i, b in enumerate(mech.moving_bodies)}
    pose[GROUND] = np.zeros(3)
    notes = [
        f"{mech.name}: written by xcheck export (format sdf); load with pydrake's",
        "Parser(plant).AddModels(path) into a discrete MultibodyPlant (ball constraints need SAP).",
        "Link poses: each body at the assembly, so every joint coordinate is 0 there.",
        "The link 'ground' (welded to the world) carries the ground's points.",
        "Inertia: Izz about the centre of mass; Ixx = Iyy = Izz (no effect in the plane).",
        f"Not in the file: gravity {_vec(*mech.gravity)} m/s^2 (set it on the plant's gravity field)",
    ]
    notes += [
        f"  spring {s.name}: {s.points[0]}-{s.points[1]}, k {s.stiffness:g} N/m, "
        f"l0 {s.rest_length:g} m, c {s.damping:g} N s/m"
        for s in mech.springs
    ]
    notes += [
        f"  rotational spring {t.name} at {t.joint}: k {t.stiffness:g} N m/rad, c {t.damping:g} N m s/rad"
        for t in mech.rotational_springs
    ]
    notes += [
        f"  load {load.name} on {load.body}: force {_vec(*load.force)} N, torque {load.torque:g} N m"
        + ("" if load.law is None else f", {load.law.describe()}")
        for load in mech.loads
    ]
    lines = ['<?xml version="1.0"?>', '<sdf version="1.9" xmlns:drake="http://drake.mit.edu">', "  <!--"]
    lines += [f"    {_name(line)}".replace("--", "- -") for line in notes]  # no "--" inside a comment
    defaults = []
    body_lines = [f'  <model name="{_name(mech.name)}">', '    <link name="ground"/>']
    body_lines += ['    <joint name="ground-weld" type="fixed"><parent>world</parent><child>ground</child></joint>']
    for body in mech.moving_bodies:
        mass, com, inertia, default = mass_properties(body, mech.size)
        if default:
            defaults.append(body.name)
        x, y, phi = (float(v) for v in pose[body.name])
        body_lines += [
            f'    <link name="{_name(body.name)}">',
            f"      <pose>{_pose(x, y, phi, size)}</pose>",
            "      <inertial>",
            f"        <pose>{_pose(com[0], com[1], 0.0, size)}</pose>",
            f"        <mass>{_num(mass)}</mass>",
            f"        <inertia><ixx>{_num(inertia)}</ixx><iyy>{_num(inertia)}</iyy><izz>{_num(inertia)}</izz>"
            "<ixy>0.0</ixy><ixz>0.0</ixz><iyz>0.0</iyz></inertia>",
            "      </inertial>",
            "    </link>",
        ]
    if defaults:
        lines += [f"    Default mass properties (the mechanism gives none) for {', '.join(defaults)}."]
    lines += ["  -->"]
    for cut in topology.cuts:  # what the file cannot hold, said before it is written
        converter(_LOOPS, cut, "Drake's SDF")
    for tj in topology.tree:
        j = tj.joint
        at, kind, axis = converter(_JOINTS, j, "Drake's SDF")(tj, j)
        point = mech.body(tj.child).points[at]
        parent = "ground" if tj.parent == GROUND else tj.parent
        body_lines += [
            f'    <joint name="{_name(j.name)}.joint" type="{kind}">',
            f"      <pose>{_pose(point[0], point[1], 0.0, size)}</pose>",
            f"      <parent>{_name(parent)}</parent>",
            f"      <child>{_name(tj.child)}</child>",
            f"      <axis><xyz>{_vec(*axis, scale=1.0)}</xyz></axis>",
            "    </joint>",
        ]
    for cut in topology.cuts:
        body_lines += converter(_LOOPS, cut, "Drake's SDF")(mech, cut, size)
    return "\n".join([*lines, *body_lines, "  </model>", "</sdf>", ""])


def _revolute(tj, j: Revolute) -> tuple[str, str, np.ndarray]:
    """A revolute: an SDF revolute joint at the child's pin point, about z."""
    return (j.point_a if tj.reversed else j.point_b), "revolute", np.array([0.0, 0.0, 1.0])


def _prismatic(tj, j: Prismatic) -> tuple[str, str, np.ndarray]:
    """A prismatic joint: an SDF prismatic joint at the child's point, along the line in the child's frame
    (body_a's direction, turned back by the locked angle on body_b)."""
    d = np.asarray(j.direction, dtype=float) if tj.reversed else rotate(-j.angle, j.direction)
    return (j.line_point if tj.reversed else j.point), "prismatic", np.array([d[0], d[1], 0.0])


#: a tree joint in the SDF, by its type: (its point on the child, SDF type, axis)
_JOINTS: dict[type, Callable] = {Revolute: _revolute, Prismatic: _prismatic}


def _ball(mech, cut: Revolute, size: float) -> list[str]:
    """A loop cut at a revolute: Drake's ball constraint between its two points."""
    a, b = ("ground" if n == GROUND else n for n in (cut.body_a, cut.body_b))
    pa, pb = (mech.body(body).points[label] for body, label in cut.anchors())
    return [
        "    <!-- loop cut at " + _name(cut.name).replace("--", "- -") + " -->",
        "    <drake:ball_constraint>",
        f"      <drake:ball_constraint_body_A>{_name(a)}</drake:ball_constraint_body_A>",
        f"      <drake:ball_constraint_body_B>{_name(b)}</drake:ball_constraint_body_B>",
        f"      <drake:ball_constraint_p_AP>{_vec(pa[0], pa[1], 0.0, scale=size)}</drake:ball_constraint_p_AP>",
        f"      <drake:ball_constraint_p_BQ>{_vec(pb[0], pb[1], 0.0, scale=size)}</drake:ball_constraint_p_BQ>",
        "    </drake:ball_constraint>",
    ]


#: a loop cut in the SDF, by its type
_LOOPS: dict[type, Callable | str] = {
    Revolute: _ball,
    GearPair: "Drake's SDF parser here makes no coupler constraint of SDFormat's <mimic> (xcheck's Drake modes "
    "build the coupler themselves)",
}


def export_files(kinematics: Kinematics) -> dict[str, str]:
    """``{NAME.sdf: text}`` (see :func:`sdf_text`)."""
    return {f"{kinematics.mechanism.name}.sdf": sdf_text(kinematics)}
