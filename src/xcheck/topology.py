"""The mechanism as a kinematic tree plus loop closures, for tree-based engines.

MuJoCo and Pinocchio describe a mechanism as a tree of joints; each closed loop
is cut at one joint and closed again by an equality constraint. This module
picks the tree: driven joints first (an engine drives tree joints), then the
joints a coupling needs in the tree (a gear pair's gears' revolutes), then by
the joint types' ``tree_rank`` (prismatic and pin-in-slot joints before
revolutes), each group in file order; every joint left over is a cut, and a
coupling that joins nothing (a gear pair) is always one. So a loop is cut at a revolute (closed by a
point constraint) whenever it has a non-driven one; a loop closed only through
driven, prismatic and pin-in-slot joints is cut at its last prismatic or
pin-in-slot joint, which the engines close through a "carrier" (a slide along
the joint's line on ``body_a``, held to ``body_b`` by a point constraint for a
pin-in-slot, by a weld for a prismatic joint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ModelError
from .joints import LineJoint
from .kinematics import rotate
from .model import GROUND, Joint, Mechanism

__all__ = ["TreeJoint", "Topology", "spanning_tree", "carrier_share"]


@dataclass(frozen=True)
class TreeJoint:
    """A joint of the tree.

    Attributes
    ----------
    joint : Joint
        The model's joint.
    parent, child : str
        Body names; the parent is nearer the ground.
    reversed : bool
        True when the joint's second body (``joint.body_b``) is the parent,
        i.e. the line of a prismatic or pin-in-slot joint is fixed in the child.
    driver : str or None
        The driver of this joint, if it is an input.
    """

    joint: Joint
    parent: str
    child: str
    reversed: bool
    driver: str | None


@dataclass(frozen=True)
class Topology:
    """``tree`` lists joints parents-first; ``cuts`` are the joints that close loops
    (revolutes where a loop has a non-driven one)."""

    tree: tuple[TreeJoint, ...]
    cuts: tuple[Joint, ...]

    def parent_of(self, body: str) -> TreeJoint:
        for tj in self.tree:
            if tj.child == body:
                return tj
        raise KeyError(body)


def spanning_tree(mechanism: Mechanism) -> Topology:
    """Split the joints into a tree rooted at the ground and loop-closing cuts.

    Raises
    ------
    ModelError
        If a body is not connected to the ground, or a loop has only driven joints.
    """
    driven = {d.joint: d.name for d in mechanism.drivers}
    needed = {name for joint in mechanism.joints for name in joint.needs_in_tree()}
    order = sorted(
        (i for i, joint in enumerate(mechanism.joints) if joint.connects),
        key=lambda i: (mechanism.joints[i].name not in driven, mechanism.joints[i].name not in needed,
                       mechanism.joints[i].tree_rank, i),
    )  # fmt: skip
    root = {b.name: b.name for b in mechanism.bodies}

    def find(body: str) -> str:
        while root[body] != body:
            root[body] = root[root[body]]
            body = root[body]
        return body

    tree_edges, cuts = [], []
    for i in order:
        joint = mechanism.joints[i]
        ra, rb = find(joint.body_a), find(joint.body_b)
        if ra != rb:
            root[ra] = rb
            tree_edges.append(joint)
        elif joint.name in driven:
            raise ModelError(
                mechanism.path,
                f"joints[{i}]",
                "a loop with a joint that is not driven (engines drive tree joints and cut loops at undriven ones)",
                "a loop of driven joints only",
            )
        else:
            cuts.append(joint)
    cuts += [joint for joint in mechanism.joints if not joint.connects]  # couplings: always constraints

    tree, placed, pending = [], {GROUND}, list(tree_edges)
    while pending:
        progress = False
        for joint in list(pending):
            if joint.body_a in placed or joint.body_b in placed:
                reversed_ = joint.body_a not in placed
                parent, child = (joint.body_b, joint.body_a) if reversed_ else (joint.body_a, joint.body_b)
                tree.append(TreeJoint(joint, parent, child, reversed_, driven.get(joint.name)))
                placed.add(child)
                pending.remove(joint)
                progress = True
        if not progress:
            break
    loose = [b.name for b in mechanism.moving_bodies if b.name not in placed]
    if loose:
        raise ModelError(
            mechanism.path,
            f"bodies.{loose[0]}",
            "a body connected to the ground through joints",
            "a body with no path of joints to the ground",
        )
    return Topology(tuple(tree), tuple(cuts))


def carrier_share(
    mechanism: Mechanism, cut: LineJoint, held: tuple[float, np.ndarray, float] | None, line_mass: float
) -> tuple[tuple[float, np.ndarray, float], tuple[float, np.ndarray, float] | None]:
    """The mass a cut's carrier takes from the body it is held to, keeping the
    mechanism's mass distribution exact.

    An engine that needs mass on a carrier (a body with a joint) takes it from
    ``body_b``: the carrier is held to ``body_b`` at the sliding point, so

    * a prismatic carrier moves rigidly with the block: it takes half of it
      (mass, centre of mass, inertia); the block keeps the other half;
    * a pin-in-slot carrier moves with the pin point (it turns with the slot):
      it is a point mass m_c at the pin p, and the pin's body (m, c, I) keeps
      m - m_c at c' = (m c - m_c p) / (m - m_c) with I' = I - m m_c |p - c|^2
      / (m - m_c), so that both together have the body's mass, centre of mass
      and inertia; m_c = min(m / 2, I m / (2 m |p - c|^2 + I)) keeps I' >= I / 2.

    A carrier held to the ground stands still; it gets half ``line_mass``.

    Parameters
    ----------
    cut : LineJoint
        A prismatic joint (with a ``locked_angle``) or a pin in a slot.
    held : (mass kg, com (2,) m, inertia kg m^2) or None
        ``body_b``'s mass properties in its frame; None for the ground.
    line_mass : float, kg
        ``body_a``'s mass (used only when ``body_b`` is the ground).

    Returns
    -------
    carrier : (mass, com (2,), inertia)
        In the carrier frame: origin at the sliding point, axes of ``body_a``.
        A pin-in-slot carrier's inertia is 0.
    rest : (mass, com (2,), inertia) or None
        What ``body_b`` keeps (its frame); None for the ground.
    """
    if held is None:
        m = 0.5 * line_mass
        return (m, np.zeros(2), 0.0 if cut.locked_angle is None else m * mechanism.size**2), None
    m, c, inertia = float(held[0]), np.asarray(held[1], dtype=float), float(held[2])
    p = mechanism.body(cut.body_b).points[cut.point]
    if cut.locked_angle is not None:
        return (0.5 * m, rotate(cut.locked_angle, c - p), 0.5 * inertia), (0.5 * m, c, 0.5 * inertia)
    d2 = float((p - c) @ (p - c))
    mc = min(0.5 * m, inertia * m / (2.0 * m * d2 + inertia))
    return (mc, np.zeros(2), 0.0), (m - mc, (m * c - mc * p) / (m - mc), inertia - m * mc * d2 / (m - mc))
