"""A mechanism as a tree of joint frames zeroed at a given state, for engines that
build bodies hung from their parents by joints (OpenSim, DART, Newton).

Each engine body is xcheck's body frame (origin and orientation). A tree joint
(:func:`xcheck.topology.spanning_tree`) is a frame on its parent and a frame on
its child that coincide up to the joint's motion: a turn about z by the
coordinate (revolute) or a slide along the frames' x by it (prismatic). The
frames are placed so that every coordinate is 0 at the state they are built
from: an engine that assumes its model assembled at q = 0 (Newton's MuJoCo
backend places loop anchors there) is then right, and the others start from
q = 0 with the rates :meth:`TreeFrames.rates` gives. The loop cuts are the
revolutes the tree leaves out, each a pair of body points, and the gear pairs
couplings of their gears' coordinates; each tree joint and cut is converted by
the converter of its type (:func:`xcheck.joints.converter`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from xcheck.engines._frames import native_point_state
from xcheck.errors import NotApplicable
from xcheck.joints import GearPair, Joint, Prismatic, Revolute, converter
from xcheck.kinematics import rotate
from xcheck.model import GROUND, Mechanism
from xcheck.topology import spanning_tree

__all__ = ["Coupling", "JointFrames", "TreeFrames", "gravity_only", "tree_frames"]


@dataclass(frozen=True)
class JointFrames:
    """One tree joint as an engine builds it.

    Attributes
    ----------
    name : str
        The joint's name.
    kind : str
        "revolute" or "prismatic".
    parent, child : str
        Body names (the parent is nearer the ground, possibly GROUND).
    parent_point, child_point : ndarray, shape (2,)
        The joint frame's origin in the parent's and the child's body frame, m.
    parent_angle, child_angle : float
        The joint frame's angle in the parent's and the child's body frame, rad.
    """

    name: str
    kind: str
    parent: str
    child: str
    parent_point: np.ndarray
    child_point: np.ndarray
    parent_angle: float
    child_angle: float


@dataclass(frozen=True)
class Coupling:
    """A gear pair as a coupling of two revolute tree joints' coordinates, both 0 at
    the build state: ``dependent = ratio * independent``.

    Attributes
    ----------
    name : str
        The gear pair's name.
    independent, dependent : str
        The tree joints (the gears' revolutes on the carrier).
    ratio : float
    """

    name: str
    independent: str
    dependent: str
    ratio: float


@dataclass(frozen=True)
class TreeFrames:
    """The tree's joints (parents first) and the loop cuts, zeroed at a state.

    Attributes
    ----------
    joints : tuple of JointFrames
    cuts : tuple of (str, ndarray, str, ndarray)
        Per cut revolute: (body, point (2,) in its frame, body, point (2,)).
    couplings : tuple of Coupling
        The gear pairs.
    """

    joints: tuple[JointFrames, ...]
    cuts: tuple[tuple[str, np.ndarray, str, np.ndarray], ...]
    couplings: tuple[Coupling, ...] = ()

    def rates(self, mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> dict[str, float]:
        """Each tree joint's coordinate rate (rad/s or m/s) at native body coordinates ``q``
        and rates ``qd`` (x, y, phi per moving body in ``moving_bodies`` order)."""
        index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}

        state = functools.partial(native_point_state, index, q, qd)

        out = {}
        for joint in self.joints:
            r_p, v_p, phi_p, w_p = state(joint.parent, joint.parent_point)
            r_c, v_c, _, w_c = state(joint.child, joint.child_point)
            if joint.kind == "revolute":
                out[joint.name] = w_c - w_p
                continue
            u = rotate(phi_p + joint.parent_angle, np.array([1.0, 0.0]))
            out[joint.name] = float(w_p * np.array([-u[1], u[0]]) @ (r_c - r_p) + u @ (v_c - v_p))
        return out

    def driver_signs(self, mech: Mechanism) -> list[tuple[str, float]]:
        """Per driver: its tree joint's name and the sign of the joint coordinate against the
        driver's value (every coordinate is 0 at the build state: value = value there + sign q)."""
        frames = {j.name: j for j in self.joints}
        out = []
        for driver in mech.drivers:
            joint, tree_joint = mech.joint(driver.joint), frames[driver.joint]
            if isinstance(joint, Prismatic):  # the line on the parent: the coordinate is the slide's
                forward = tree_joint.parent == joint.body_a
            else:  # the child's angle less the parent's: phi_b - phi_a where the child is body_b
                forward = tree_joint.child == joint.body_b
            out.append((driver.joint, 1.0 if forward else -1.0))
        return out

    def frames(self, coordinates: dict[str, float], origins: dict[str, np.ndarray]) -> dict[str, tuple]:
        """Per moving body: (origin (2,), angle) with the angle continuous from the
        state the frames were built at: the parent's plus the joint's turn.

        Parameters
        ----------
        coordinates : mapping of str to float
            Each tree joint's coordinate (rad or m), as the engine holds it.
        origins : mapping of str to ndarray
            Each moving body's frame origin (2,) in the world, as the engine reports it, m.
        """
        angles = {GROUND: 0.0}
        out: dict[str, tuple] = {}
        for joint in self.joints:
            turn = coordinates[joint.name] if joint.kind == "revolute" else 0.0
            angles[joint.child] = angles[joint.parent] + joint.parent_angle - joint.child_angle + turn
            out[joint.child] = (np.asarray(origins[joint.child], dtype=float)[:2], angles[joint.child])
        return out


def _revolute_frames(mech: Mechanism, tj, angle, position) -> JointFrames:
    """A revolute tree joint's frames: at its points, the child's turned to the parent's."""
    j = tj.joint
    l_parent, l_child = (j.point_b, j.point_a) if tj.reversed else (j.point_a, j.point_b)
    return JointFrames(
        j.name,
        "revolute",
        tj.parent,
        tj.child,
        np.asarray(mech.body(tj.parent).points[l_parent], dtype=float),
        np.asarray(mech.body(tj.child).points[l_child], dtype=float),
        angle(tj.child) - angle(tj.parent),
        0.0,
    )


def _prismatic_frames(mech: Mechanism, tj, angle, position) -> JointFrames:
    """A prismatic tree joint's frames: along its line, the line's frame moved to the start."""
    j = tj.joint
    heading = math.atan2(j.direction[1], j.direction[0])
    line = np.asarray(mech.body(j.body_a).points[j.line_point], dtype=float)
    point = np.asarray(mech.body(j.body_b).points[j.point], dtype=float)
    gap = position(j.body_b, j.point) - position(j.body_a, j.line_point)
    slide = float(rotate(angle(j.body_a), j.direction) @ gap)
    if not tj.reversed:  # the line is the parent's: its frame moved along the line to the start
        parent_point, child_point = line + slide * np.asarray(j.direction), point
        parent_angle, child_angle = heading, heading - j.angle
    else:  # the line is the child's: the frames in the line's orientation, the child's moved back
        parent_point, child_point = point, line + slide * np.asarray(j.direction)
        parent_angle, child_angle = heading - j.angle, heading
    return JointFrames(j.name, "prismatic", tj.parent, tj.child, parent_point, child_point, parent_angle, child_angle)


def _revolute_cut(mech: Mechanism, cut: Revolute, signs) -> tuple[str, np.ndarray, str, np.ndarray]:
    """A loop cut at a revolute: its two body points."""
    return (
        cut.body_a,
        np.asarray(mech.body(cut.body_a).points[cut.point_a], dtype=float),
        cut.body_b,
        np.asarray(mech.body(cut.body_b).points[cut.point_b], dtype=float),
    )


def _gear_coupling(gear: GearPair, sign, engine: str) -> Coupling:
    """A gear pair as a coupling of its gears' revolutes' coordinates (0 at the build
    state, where the mesh holds: no offset), by :meth:`GearPair.tree_coupling`."""
    ratio, _, _ = gear.tree_coupling(sign, f"xcheck's {engine} model")
    return Coupling(gear.name, gear.pin_a, gear.pin_b, ratio)


def _converters(engine: str, couplings: bool) -> tuple[dict, dict]:
    """The tree joints' and the cuts' converters by joint type, for ``engine``."""
    tree: dict[type, Callable | str] = {
        Revolute: _revolute_frames,
        Prismatic: _prismatic_frames,
        Joint: f"xcheck's {engine} model has revolute and prismatic tree joints only",
    }
    cuts: dict[type, Callable | str] = {
        Revolute: _revolute_cut,
        GearPair: (lambda mech, gear, sign: _gear_coupling(gear, sign, engine))
        if couplings
        else f"xcheck's {engine} model couples no joint coordinates",
        Joint: f"a loop is cut at the {{kind}} joint {{name!r}}: xcheck's {engine} model closes loops at "
        "revolutes only",
    }
    return tree, cuts


def tree_frames(mech: Mechanism, q: np.ndarray, engine: str, couplings: bool = False) -> TreeFrames:
    """The mechanism's tree with every joint coordinate 0 at native body coordinates
    ``q`` (x, y, phi per moving body in ``moving_bodies`` order; m, rad): each tree
    joint and each cut by the converter of its type; ``couplings``: whether the
    engine couples joint coordinates (a gear pair), ``engine`` names it in reasons.

    Raises
    ------
    NotApplicable
        Where a tree joint is neither revolute nor prismatic, a loop is cut at a joint
        other than a revolute, or a gear pair needs a coupling the engine lacks.
    """
    index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}
    topology = spanning_tree(mech)
    tree_table, cut_table = _converters(engine, couplings)
    tree_converters = [converter(tree_table, tj.joint, engine) for tj in topology.tree]
    cut_converters = [converter(cut_table, cut, engine) for cut in topology.cuts]

    def angle(name: str) -> float:
        return 0.0 if name == GROUND else float(q[index[name] + 2])

    def position(name: str, label: str) -> np.ndarray:
        point = np.asarray(mech.body(name).points[label], dtype=float)
        return point if name == GROUND else q[index[name] : index[name] + 2] + rotate(angle(name), point)

    joints = tuple(convert(mech, tj, angle, position) for convert, tj in zip(tree_converters, topology.tree))
    children = {frames.name: frames.child for frames in joints}

    def sign(joint: str, body: str) -> float | None:
        """The sign of a revolute tree joint's coordinate against ``body``'s turn relative to the
        other body; None where the joint closes a loop."""
        return None if joint not in children else 1.0 if children[joint] == body else -1.0

    closed = [convert(mech, cut, sign) for convert, cut in zip(cut_converters, topology.cuts)]
    return TreeFrames(
        joints,
        tuple(c for c in closed if not isinstance(c, Coupling)),
        tuple(c for c in closed if isinstance(c, Coupling)),
    )


def gravity_only(mech: Mechanism, engine: str) -> None:
    """:class:`NotApplicable` with the reason if the mechanism has forces other than gravity,
    for an engine model that holds gravity alone (``engine`` names it in the reason)."""
    forces = [("spring", s.name) for s in mech.springs]
    forces += [("rotational spring", s.name) for s in mech.rotational_springs]
    forces += [("load", load.name) for load in mech.loads]
    if forces:
        kind, name = forces[0]
        raise NotApplicable(f"{kind} {name!r}: xcheck's {engine} model applies gravity only")
