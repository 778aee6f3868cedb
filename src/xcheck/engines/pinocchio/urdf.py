"""URDF text of a mechanism's kinematic tree and JSON of its loop closures.

URDF describes trees only, so the files are two: ``NAME.urdf`` (the tree, with
the same joints, placements, inertias and frame names as the programmatic
Pinocchio model) and ``NAME.loops.json`` (each loop cut: the two point links
that must coincide, and the inputs). Exported, the computed numbers are
canonical (:func:`xcheck.precision.number`: 12 significant digits of their
scale, so every machine writes the same text); in memory they read back bit for bit.

Link layout, for every tree joint: the moving joint hangs a massless link
``"<joint>.link"`` whose frame is the joint frame; the body link (named after
the body, frame = the mechanism's body frame, carrying the inertia) hangs from
it by a fixed joint ``"<body>.fixed"``; every named point is a link
``"<body>.<label>"`` on a fixed joint ``"<body>.<label>.fixed"``. Pinocchio's
URDF parser turns those fixed links into frames of the same names.

In the file every name is a ROS name (:func:`ros_name`: ``"crank.B"`` is
``"crank__B"``); the file ends with a comment listing the renamed names, and
the JSON's ``"names"`` maps each model name to the file's. Every link has a
visual (no collision geometry, no mass), and the JSON's ``"assembly"`` gives
each joint's value at the assembly.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable

import numpy as np

from xcheck.joints import LineJoint, Revolute, converter
from xcheck.model import GROUND
from xcheck.precision import number, numbers

from .model import TreeSpec, block_frame, carrier_joint, fixed_joint, point_frame

__all__ = ["export_texts", "LOOPS_SUFFIX", "ros_name", "UrdfNames", "ROS_NAME"]

LOOPS_SUFFIX = ".loops.json"
#: What the file's link, joint and robot names match (what ROS tools accept).
ROS_NAME = re.compile(r"[A-Za-z0-9_]+")
#: Radius of the visuals (cylinders between a body's points, spheres at points), times the mechanism's size.
VISUAL_FRACTION = 0.01


def ros_name(name: str) -> str:
    """A model name as a ROS name: ``.`` becomes ``__``, every other character
    outside ``[A-Za-z0-9_]`` becomes ``_`` (``"crank.A"`` -> ``"crank__A"``)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", name.replace(".", "__")) or "_"


class UrdfNames:
    """The file's names: :func:`ros_name` of each model name, made unique in the
    order the names are first asked for (a clash gets ``_2``, ``_3``, ...), so
    the mapping is deterministic."""

    def __init__(self) -> None:
        self.renamed: dict[str, str] = {}
        self._taken: set[str] = set()

    def __call__(self, name: str) -> str:
        if name not in self.renamed:
            base = candidate = ros_name(name)
            n = 1
            while candidate in self._taken:
                n += 1
                candidate = f"{base}_{n}"
            self.renamed[name] = candidate
            self._taken.add(candidate)
        return self.renamed[name]


def _num(x: float, scale: float = 0.0) -> str:
    """A number of the file (:func:`xcheck.precision.number`: canonical when exported)."""
    return repr(number(x, scale))


def _vec(*values: float, scale: float = 0.0) -> str:
    """A vector of the file, each component on the scale of the largest (or ``scale``)."""
    return " ".join(repr(v) for v in numbers(values, scale))


def _origin(xyz, rpy, size: float) -> str:
    """An ``<origin>``'s attributes: a position (m, on the scale of the mechanism's size) and angles (rad)."""
    return f'xyz="{_vec(*xyz, scale=size)}" rpy="{_vec(*rpy, scale=math.pi)}"'


def _comment(text: str) -> str:
    return text.replace("--", "- -")


def _fixed(lines: list[str], n: UrdfNames, size: float, parent: str, child: str, xy, angle: float = 0.0) -> None:
    lines += [
        f'  <joint name="{n(fixed_joint(child))}" type="fixed">',
        f'    <parent link="{n(parent)}"/>',
        f'    <child link="{n(child)}"/>',
        f"    <origin {_origin((xy[0], xy[1], 0.0), (0.0, 0.0, angle), size)}/>",
        "  </joint>",
    ]


def _inertial(body, size: float) -> list[str]:
    izz = body.inertia
    return [
        "    <inertial>",
        f'      <origin xyz="{_vec(body.com[0], body.com[1], 0.0, scale=size)}" rpy="0.0 0.0 0.0"/>',
        f'      <mass value="{_num(body.mass)}"/>',
        f'      <inertia ixx="{_num(0.5 * izz)}" ixy="0.0" ixz="0.0" iyy="{_num(0.5 * izz)}" '
        f'iyz="0.0" izz="{_num(izz)}"/>',
        "    </inertial>",
    ]


def _visual(
    geometry: str, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0), colour: str = "link", size: float = 0.0
) -> list[str]:
    return [
        "    <visual>",
        f"      <origin {_origin(xyz, rpy, size)}/>",
        f"      <geometry>{geometry}</geometry>",
        f'      <material name="{colour}"/>',
        "    </visual>",
    ]


def _sphere(radius: float, colour: str = "point") -> list[str]:
    return _visual(f'<sphere radius="{_num(radius)}"/>', colour=colour)


def _bars(points: list[np.ndarray], radius: float, size: float) -> list[str]:
    """Visuals of a body: a cylinder between each pair of consecutive points (a
    box at a body of one point); only the picture, not the mass."""
    out: list[str] = []
    if len(points) == 1:
        p = points[0]
        out += _visual(f'<box size="{_vec(6 * radius, 4 * radius, 2 * radius)}"/>', (p[0], p[1], 0.0), size=size)
    for p, q in zip(points, points[1:]):
        length = float(np.hypot(*(q - p)))
        if length == 0.0:
            continue
        mid = 0.5 * (p + q)
        yaw = math.atan2(q[1] - p[1], q[0] - p[0])
        geometry = f'<cylinder radius="{_num(radius)}" length="{_num(length)}"/>'
        out += _visual(geometry, (mid[0], mid[1], 0.0), (0.0, 0.5 * math.pi, yaw), size=size)
    return out or _sphere(radius, "link")


def _link(lines: list[str], n: UrdfNames, name: str, body: list[str]) -> None:
    lines += [f'  <link name="{n(name)}">', *body, "  </link>"]


def _blocks(lines: list[str], n: UrdfNames, spec: TreeSpec, body: str, radius: float) -> None:
    """The block frames of prismatic cuts on ``body``: fixed links turned by -angle."""
    for owner, name, xy, angle in spec.blocks:
        if owner == body:
            _fixed(lines, n, spec.mechanism.size, body, name, xy, angle)
            _link(lines, n, name, _visual(f'<box size="{_vec(4 * radius, 2 * radius, 2 * radius)}"/>'))


def urdf_text(spec: TreeSpec, n: UrdfNames | None = None) -> str:
    """The tree of ``spec`` as URDF (see the module notes for the layout).

    ``n`` maps model names to the file's (a fresh :class:`UrdfNames` if None);
    the file ends with a comment listing every name it changed.
    """
    n = UrdfNames() if n is None else n
    mech = spec.mechanism
    loops_file = f"{mech.name}{LOOPS_SUFFIX}"
    defaults = [b.name for b in spec.bodies if b.default]
    header = [
        f"Generated by xcheck from the mechanism {mech.name!r} by its URDF export; do not edit.",
        "A planar mechanism in the x-y plane, SI units (m, kg, rad); joints turn about z.",
        "URDF holds the kinematic tree only. Each closed loop is cut at a revolute joint,",
        f"listed in {loops_file}: close it with a point constraint between its two point links,",
        "e.g. in Pinocchio, for each loop: f1, f2 = (model.frames[model.getFrameId(loop[k],",
        "pin.FrameType.BODY)] for k in ('frame1', 'frame2')); pin.RigidConstraintModel(",
        "pin.ContactType.CONTACT_3D, model, f1.parentJoint, f1.placement, f2.parentJoint,",
        "f2.placement, pin.LOCAL_WORLD_ALIGNED); a planar loop's z row is zero (proximal mu > 0).",
        f"{loops_file} also gives the joint values at the assembly ('assembly': the reference",
        "inputs, every loop closed): start there, the joints' zero is not an assembled pose.",
        "Names: the model's names with '.' written '__' and any other character outside",
        "[A-Za-z0-9_] written '_' (ROS names); the comment at the end lists each renamed name.",
        "Links: '<joint>__link' is the frame at a joint; a body's link is the body frame of the",
        "mechanism model; '<body>__<label>' are its named points. A pin-in-slot is two joints,",
        "'<joint>__slide' and '<joint>__turn'. Hinges are 'continuous' (Pinocchio parses them as",
        "RUBZ joints with (cos, sin) coordinates). Prismatic limits are required by URDF but",
        "not part of the mechanism: the loops bound the travel (effort and velocity 0: not given).",
        "Inertia: Izz about the centre of mass; Ixx = Iyy = Izz / 2 (a lamina; no effect in the plane).",
        "Visuals (no collision geometry): cylinders between a body's consecutive points, spheres at",
        "the points and joints, boxes for one-point bodies, carriers and blocks; they carry no mass.",
    ]
    if any(isinstance(cut, LineJoint) for cut in spec.cuts):
        header += [
            "A loop with no undriven revolute is cut at a pin-in-slot or prismatic joint J: the prismatic",
            "joint 'J__carrier' (a carrier along J's line on its first body) is closed to the pin's point",
            "link by a CONTACT_3D, or to the block's link 'J__block' by a CONTACT_6D (x, y and rotation z",
            "act), as listed in the loops file. Carrier masses are taken from the bodies they are held to",
            "(pin-in-slot: a point mass at the pin, the pin body's centre of mass and inertia moved to keep",
            "its totals; prismatic: half the block): the mass distribution is the mechanism's.",
        ]
    if defaults:
        header += [
            "Default mass properties (the mechanism gives none) for " + ", ".join(defaults) + ":",
            "1 kg at the centroid of the body's points, Izz = m L^2 / 12 with L the largest distance",
            "between two of its points, at least a tenth of the mechanism's size.",
        ]
    size = mech.size
    radius = VISUAL_FRACTION * size
    lines = (
        ['<?xml version="1.0"?>', "<!--"]
        + [f"  {_comment(h)}" for h in header]
        + [
            "-->",
            f'<robot name="{n(mech.name)}">',
            '  <material name="link"><color rgba="0.3 0.5 0.8 1.0"/></material>',
            '  <material name="point"><color rgba="0.9 0.3 0.2 1.0"/></material>',
            '  <material name="ground"><color rgba="0.4 0.4 0.4 1.0"/></material>',
        ]
    )
    _link(lines, n, GROUND, _visual(f'<box size="{_vec(2 * radius, 2 * radius, radius)}"/>', colour="ground"))
    for label, xy in mech.ground.points.items():
        _fixed(lines, n, size, GROUND, point_frame(GROUND, label), xy)
        _link(lines, n, point_frame(GROUND, label), _sphere(1.5 * radius, "ground"))
    _blocks(lines, n, spec, GROUND, radius)
    carriers = {c.link: c for c in spec.carriers}
    hung = {b.link: b for b in spec.bodies}
    points: dict[str, list[tuple[str, np.ndarray]]] = {}
    for body_name, label, xy in spec.points:
        points.setdefault(body_name, []).append((label, xy))
    for js in spec.joints:
        kind = "continuous" if js.kind == "revolute" else "prismatic"
        lines += [
            f'  <joint name="{n(js.name)}" type="{kind}">',
            f'    <parent link="{n(js.parent)}"/>',
            f'    <child link="{n(js.link)}"/>',
            f"    <origin {_origin((js.origin[0], js.origin[1], 0.0), (0.0, 0.0, js.angle), size)}/>",
            f'    <axis xyz="{_vec(*js.axis, scale=1.0)}"/>',
        ]
        if kind == "prismatic":
            limit = _num(10.0 * size)
            lines.append(f'    <limit lower="-{limit}" upper="{limit}" effort="0" velocity="0"/>')
        lines.append("  </joint>")
        marker = (
            _visual(f'<cylinder radius="{_num(radius)}" length="{_num(4 * radius)}"/>', colour="point")
            if kind == "continuous"
            else _visual(f'<box size="{_vec(3 * radius, 2 * radius, radius)}"/>', colour="point")
        )
        if js.link in carriers:
            _link(lines, n, js.link, [*_inertial(carriers[js.link], size), *marker])
        else:
            _link(lines, n, js.link, marker)
        body = hung.get(js.link)
        if body is None:
            continue
        _fixed(lines, n, size, js.link, body.name, body.offset)
        own = points.get(body.name, [])
        _link(lines, n, body.name, [*_inertial(body, size), *_bars([xy for _, xy in own], radius, size)])
        for label, xy in own:
            _fixed(lines, n, size, body.name, point_frame(body.name, label), xy)
            _link(lines, n, point_frame(body.name, label), _sphere(1.5 * radius))
        _blocks(lines, n, spec, body.name, radius)
    changed = [(old, new) for old, new in n.renamed.items() if old != new]
    if changed:
        lines += ["<!--", "  Names: model name -> name in this file"]
        lines += [f"  {_comment(old)} -> {new}" for old, new in changed]
        lines.append("-->")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def loops_json(spec: TreeSpec, n: UrdfNames | None = None, assembly: dict[str, float] | None = None) -> str:
    """The loop closures, inputs and assembled joint values of ``spec`` as JSON text.

    Parameters
    ----------
    n : UrdfNames, optional
        The URDF's names (those of :func:`urdf_text`).
    assembly : dict, optional
        Model joint name -> its value at the assembly (rad or m); written as
        ``"assembly"`` under the URDF's joint names.
    """
    n = UrdfNames() if n is None else n
    mech = spec.mechanism
    doc: dict[str, object] = {
        "mechanism": mech.name,
        "urdf": f"{mech.name}.urdf",
        "about": "Loop closures of the URDF tree: in each loop, the origins of links frame1 and frame2 "
        "coincide (a revolute joint cut open). Only the x and y rows act: the mechanism is planar. "
        "Inputs: the driven joints; input = sign * joint coordinate (rad or m). Gravity: the "
        "mechanism's, in the plane (m/s^2; URDF has no field for it; zero when the model gives none). "
        "Assembly: each URDF joint's value (rad: the angle of a continuous joint, whose Pinocchio "
        "coordinates are its cos and sin; m: a prismatic joint's travel) with the inputs at their "
        "reference values and every loop closed; 'names' maps the model's names to the URDF's."
        + (
            ""
            if not any(isinstance(cut, LineJoint) for cut in spec.cuts)
            else " A loop of kind pin-in-slot or prismatic is a joint of that kind cut open: frame1 is its "
            "carrier (a prismatic joint along the line), held to the pin by CONTACT_3D (x, y act) or to "
            "the block frame by CONTACT_6D (x, y and rotation z act)."
        ),
        "gravity": [*numbers(mech.gravity), 0.0],
        "loops": [_loop(cut, n) for cut in spec.cuts],
        "inputs": [
            {"driver": name, "joint": n(joint), "sign": int(sign), "quantity": mech.drivers[k].quantity}
            for k, (name, joint, sign) in enumerate(spec.drivers)
        ],
    }
    if assembly is not None:
        doc["assembly"] = {
            n(js.name): number(assembly[js.name], math.pi if js.kind == "revolute" else mech.size) for js in spec.joints
        }
    doc["names"] = dict(sorted(n.renamed.items()))
    return json.dumps(doc, indent=2) + "\n"


def _loop(cut, n: UrdfNames) -> dict:
    """One loop closure of the JSON: the two links whose frames are held together."""
    return converter(_LOOPS, cut, "Pinocchio's URDF")(cut, n)


def _pin_loop(cut: Revolute, n: UrdfNames) -> dict:
    """A revolute cut open: its two points' frames held together (CONTACT_3D)."""
    frames = [n(point_frame(body, label)) for body, label in cut.anchors()]
    return {
        "cut": cut.name,
        "frame1": frames[0],
        "frame2": frames[1],
        "contact_type": "CONTACT_3D",
        "reference_frame": "LOCAL_WORLD_ALIGNED",
    }


def _carrier_loop(cut: LineJoint, n: UrdfNames) -> dict:
    """A line joint cut open: its carrier held to the block (CONTACT_6D) or to the pin (CONTACT_3D)."""
    if cut.locked_angle is not None:
        frame2, kind = block_frame(cut), "CONTACT_6D"
    else:
        frame2, kind = point_frame(cut.body_b, cut.point), "CONTACT_3D"
    return {
        "cut": cut.name,
        "kind": cut.kind,
        "frame1": n(f"{carrier_joint(cut)}.link"),
        "frame2": n(frame2),
        "contact_type": kind,
        "reference_frame": "LOCAL_WORLD_ALIGNED",
    }


#: a loop closure of the JSON, by the cut joint's type
_LOOPS: dict[type, Callable] = {Revolute: _pin_loop, LineJoint: _carrier_loop}


def export_texts(spec: TreeSpec, assembly: dict[str, float] | None = None) -> dict[str, str]:
    """{``NAME.urdf``: URDF text, ``NAME.loops.json``: JSON text}, with one name mapping.

    ``assembly``: model joint name -> value at the assembly (rad or m), for the JSON.
    """
    name = spec.mechanism.name
    n = UrdfNames()
    urdf = urdf_text(spec, n)
    return {f"{name}.urdf": urdf, f"{name}{LOOPS_SUFFIX}": loops_json(spec, n, assembly)}
