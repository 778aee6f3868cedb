"""The mechanism as a kinematic tree plus loop closures, for tree-based engines.

MuJoCo and Pinocchio describe a mechanism as a tree of joints; each closed loop
is cut at one revolute joint and closed again by a point constraint. This module
picks the tree: driven joints first (an engine drives tree joints), then
prismatic and pin-in-slot joints (a loop cannot be closed at them by a point
constraint), then revolutes in file order; every joint left over is a cut.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import ModelError
from .model import GROUND, Joint, Mechanism, Revolute

__all__ = ["TreeJoint", "Topology", "spanning_tree"]


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
    """``tree`` lists joints parents-first; ``cuts`` are the revolutes that close loops."""

    tree: tuple[TreeJoint, ...]
    cuts: tuple[Revolute, ...]

    def parent_of(self, body: str) -> TreeJoint:
        for tj in self.tree:
            if tj.child == body:
                return tj
        raise KeyError(body)


def spanning_tree(mechanism: Mechanism) -> Topology:
    """Split the joints into a tree rooted at the ground and loop-closing revolutes.

    Raises
    ------
    ModelError
        If a body is not connected to the ground, or a loop has no revolute
        joint at which it could be cut.
    """
    driven = {d.joint: d.name for d in mechanism.drivers}
    order = sorted(range(len(mechanism.joints)),
                   key=lambda i: (mechanism.joints[i].name not in driven,
                                  isinstance(mechanism.joints[i], Revolute), i))
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
        elif isinstance(joint, Revolute):
            cuts.append(joint)
        else:
            raise ModelError(mechanism.path, f"joints[{i}]",
                             "a loop that can be cut at a revolute joint (engines close loops with point "
                             "constraints)", f"a loop closed only by {joint.kind} joints")

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
        raise ModelError(mechanism.path, f"bodies.{loose[0]}", "a body connected to the ground through joints",
                         "a body with no path of joints to the ground")
    return Topology(tuple(tree), tuple(cuts))
