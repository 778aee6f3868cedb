"""The base every joint type derives from: what a joint has and the hooks a
type fills in (after sympy's ``physics.mechanics.joint``: the base validates
and wires, each type adds its geometry and small hooks).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, ClassVar, TypeVar

import numpy as np

from ..errors import NotApplicable
from ._terms import Term

if TYPE_CHECKING:
    from ..kinematics import Solution

__all__ = ["Joint", "Action", "Locate", "converter"]

#: (body name, point label or None) -> (the body's index, -1 for the ground; the point in its
#: frame (2,), m, or its origin where no label is given)
Locate = Callable[[str, "str | None"], tuple[int, np.ndarray]]


@dataclass(frozen=True)
class Action:
    """What a unit value of a reaction or an effort does to one body: a force
    ``scale * direction`` at ``at`` (global frame), or, with no direction, a
    couple ``scale`` (counter-clockwise), for the per-body Newton-Euler form.

    Attributes
    ----------
    body : str
    scale : float
    direction, at : ndarray, shape (N, 2), or None
        Unit direction and point of application, m; None for a couple.
    """

    body: str
    scale: float
    direction: np.ndarray | None = None
    at: np.ndarray | None = None


@dataclass(frozen=True)
class Joint:
    """A joint between two bodies.

    ``body_a`` comes first: the order fixes the sign of its driven quantity and
    of its reactions (``body_a`` acts on ``body_b``; see :mod:`xcheck.dynamics`).
    A type adds its geometry as fields, sets the class attributes below and
    implements the hooks; everything else (the solvers, the dynamics, the
    file reader's checks, the engines' topology) asks the joint.

    Class attributes
    ----------------
    kind : str
        Its ``type`` in a mechanism file.
    rows : int
        Constraint rows: the degrees of freedom it removes.
    driven_quantity : str or None
        What a driver on it prescribes: ``"angle"`` (rad), ``"slide"`` (m), or
        None where it cannot be driven.
    quantities : tuple of str
        Its reactions' quantities (``xcheck.dynamics.JOINT_QUANTITIES``).
    pivots : bool
        Its bodies turn relative to each other about a point of both: a
        rotational spring or a joint torque may act across it.
    connects : bool
        It joins its bodies: a path from one to the other for an engine's
        kinematic tree, a side of a closed loop. False for a coupling of their
        motions that joins nothing (a gear pair): never a tree joint, always a
        constraint, no loop of its own.
    tree_rank : int
        An engine that builds a kinematic tree takes the connecting joints of
        lower rank first (after the driven ones) and closes the loops at the rest.
    tree_axes : tuple of str
        What it is as a tree joint, from the parent side: ``"hinge"`` (a turn
        about z at its point) and ``"slide"`` (along its line), in order; empty
        where it is never a tree joint.
    """

    name: str
    body_a: str
    body_b: str

    kind: ClassVar[str]
    rows: ClassVar[int]
    driven_quantity: ClassVar[str | None] = None
    quantities: ClassVar[tuple[str, ...]] = ()
    pivots: ClassVar[bool] = False
    connects: ClassVar[bool] = True
    tree_rank: ClassVar[int] = 0
    tree_axes: ClassVar[tuple[str, ...]] = ()

    @property
    def bodies(self) -> tuple[str, ...]:
        """The bodies whose motion it constrains."""
        return (self.body_a, self.body_b)

    def anchors(self) -> tuple[tuple[str, str], ...]:
        """Its joint points as (body, label): two of one body must be apart."""
        raise NotImplementedError

    @property
    def locked_angle(self) -> float | None:
        """``phi_b - phi_a`` (rad) where it keeps its bodies' relative angle (an
        engine closing a loop cut at it welds rather than pins), else None."""
        return None

    @property
    def tree_points(self) -> tuple[str, str]:
        """The labels of ``body_a`` and ``body_b`` that coincide where its tree
        coordinates are zero (a pin's two points; a line's point and the sliding point)."""
        raise NotImplementedError(f"a {self.kind} joint is no tree joint")

    def coordinate(self, state) -> tuple[float, float]:
        """Its driven quantity (rad or m) and rate at one state: ``state(body, label)``
        gives a body point's (position (2,), velocity (2,)) and the body's (angle,
        angular rate), with ``label`` None for the frame's origin (any engine's
        state read back the same way)."""
        raise TypeError(f"a {self.kind} joint has no coordinate")

    def needs_in_tree(self) -> tuple[str, ...]:
        """The joints (by name) an engine's kinematic tree must hold for it: a
        coupling of joint coordinates needs those joints as tree joints."""
        return ()

    def shared_label(self) -> str | None:
        """The label it joins on both bodies, where it pins the same label of each."""
        return None

    # -- kinematics -------------------------------------------------------
    def terms(self, locate: Locate) -> list[Term]:
        """Its constraint terms, ``rows`` rows in all."""
        raise NotImplementedError

    def driver_term(self, locate: Locate, driver: int) -> Term:
        """The term that makes its driven quantity equal driver ``driver``'s input."""
        raise TypeError(f"a {self.kind} joint cannot be driven")

    # -- dynamics ---------------------------------------------------------
    def reactions(self, multipliers: np.ndarray, solution: Solution) -> dict[str, np.ndarray]:
        """Its reactions from the multipliers of its rows, (N, rows), in
        M q'' - Phi_q^T lambda = Q: quantity -> (N, 2) or (N,), SI."""
        raise NotImplementedError

    def reaction_actions(self, solution: Solution) -> list[list[Action]]:
        """Per unknown of its reactions in the Newton-Euler form, what a unit
        value of it does to the bodies; :meth:`reactions_from_unknowns` reads them."""
        raise NotImplementedError

    def reactions_from_unknowns(self, unknowns: np.ndarray, solution: Solution) -> dict[str, np.ndarray]:
        """Its reactions from the Newton-Euler unknowns, (N, len(reaction_actions))."""
        raise NotImplementedError

    def driver_actions(self, solution: Solution) -> list[Action]:
        """What a unit driving effort does to the bodies (Newton-Euler form)."""
        raise TypeError(f"a {self.kind} joint cannot be driven")


T = TypeVar("T")


def converter(table: Mapping[type, T | str], joint: Joint, engine: str) -> T:
    """An engine's converter for a joint, found by its type: the entry of
    ``table`` for the joint's class, or its nearest base class that has one.

    Raises
    ------
    NotApplicable
        Where the entry is a string: the reason the engine cannot hold such a
        joint, formatted with the joint's ``name`` and ``kind`` where it names
        them (``"a loop is cut at the {kind} joint {name!r}: ..."``), else after
        "joint NAME is a KIND joint: "; or where there is no entry.
    """
    for cls in type(joint).__mro__:
        if cls in table:
            entry = table[cls]
            if isinstance(entry, str):
                if "{name" in entry or "{kind" in entry:
                    raise NotApplicable(entry.format(name=joint.name, kind=joint.kind))
                raise NotApplicable(f"joint {joint.name!r} is a {joint.kind} joint: {entry}")
            return entry
    raise NotApplicable(f"joint {joint.name!r} is a {joint.kind} joint, which {engine} here has no converter for")
