"""Joints that keep a point on a line: the prismatic joint and the pin in a slot."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._base import Action, Joint
from ._terms import Projection, relative_angle, rotate

__all__ = ["LineJoint", "Prismatic", "PinInSlot"]


@dataclass(frozen=True)
class LineJoint(Joint):
    """Point ``point`` of ``body_b`` stays on a line fixed in ``body_a``.

    The line passes through ``line_point`` of ``body_a`` with the unit
    direction ``direction`` (body_a frame). Driven quantity: the slide
    ``direction . (r_point - r_line_point)``, m. Reactions: the force normal to
    the line at the sliding point, ``reaction`` (N, 2) and ``normal`` (N,) along
    the line's left normal.
    """

    line_point: str
    direction: np.ndarray
    point: str

    driven_quantity = "slide"
    tree_rank = 0  # a loop is cut here only where it has no revolute to cut

    def __post_init__(self):
        d = np.array(self.direction, dtype=float).reshape(2)
        d = d / math.hypot(*d)
        d.flags.writeable = False
        object.__setattr__(self, "direction", d)

    def anchors(self):
        return ((self.body_b, self.point),)  # the line's points only place the line

    @property
    def tree_points(self):
        return (self.line_point, self.point)

    def coordinate(self, state):
        r_line, v_line, phi_a, omega_a = state(self.body_a, self.line_point)
        r_point, v_point, _, _ = state(self.body_b, self.point)
        u = rotate(phi_a, self.direction)
        gap = np.asarray(r_point) - np.asarray(r_line)
        turning = omega_a * np.array([-u[1], u[0]])
        return float(u @ gap), float(turning @ gap + u @ (np.asarray(v_point) - np.asarray(v_line)))

    @property
    def normal(self) -> np.ndarray:
        """The line's left normal in ``body_a``'s frame, (2,)."""
        return np.array([-self.direction[1], self.direction[0]])

    def _ends(self, locate):
        (a, s_q), (b, s_p) = locate(self.body_a, self.line_point), locate(self.body_b, self.point)
        return a, s_q, b, s_p

    def terms(self, locate):
        a, s_q, b, s_p = self._ends(locate)
        return [Projection(a, s_q, self.normal, b, s_p)]

    def driver_term(self, locate, driver):
        a, s_q, b, s_p = self._ends(locate)
        return Projection(a, s_q, self.direction, b, s_p, driver=driver)

    def line_frame(self, solution) -> tuple[np.ndarray, np.ndarray]:
        """The line's global unit direction u and left normal n = R u, (N, 2) each."""
        u = rotate(solution.body(self.body_a)["angle"], self.direction)
        return u, np.stack([-u[:, 1], u[:, 0]], axis=1)

    def reactions(self, multipliers, solution):
        normal = self.line_frame(solution)[1]
        return {"reaction": multipliers[:, 0, None] * normal, "normal": multipliers[:, 0]}

    def reaction_actions(self, solution):
        normal, at = self.line_frame(solution)[1], solution.point(self.point, self.body_b)["position"]
        return [[Action(self.body_b, 1.0, normal, at), Action(self.body_a, -1.0, normal, at)]]

    def reactions_from_unknowns(self, unknowns, solution):
        normal = self.line_frame(solution)[1]
        return {"reaction": unknowns[:, 0, None] * normal, "normal": unknowns[:, 0]}

    def driver_actions(self, solution):
        direction, at = self.line_frame(solution)[0], solution.point(self.point, self.body_b)["position"]
        return [Action(self.body_b, 1.0, direction, at), Action(self.body_a, -1.0, direction, at)]


@dataclass(frozen=True)
class Prismatic(LineJoint):
    """A block sliding along a line, relative rotation locked at ``angle`` rad
    (``phi_b - phi_a``). Reactions besides the normal force: ``moment`` (N,),
    the couple ``body_a`` exerts on ``body_b``."""

    angle: float = 0.0

    kind = "prismatic"
    rows = 2
    tree_axes = ("slide",)
    quantities = ("reaction", "normal", "moment")

    @property
    def locked_angle(self) -> float | None:
        return self.angle

    def terms(self, locate):
        a, _, b, _ = self._ends(locate)
        return [*super().terms(locate), relative_angle(a, b, self.angle)]

    def reactions(self, multipliers, solution):
        # phi_b - phi_a = angle: a couple +lambda on b
        return super().reactions(multipliers, solution) | {"moment": multipliers[:, 1]}

    def reaction_actions(self, solution):
        return [*super().reaction_actions(solution), [Action(self.body_b, 1.0), Action(self.body_a, -1.0)]]

    def reactions_from_unknowns(self, unknowns, solution):
        return super().reactions_from_unknowns(unknowns, solution) | {"moment": unknowns[:, 1]}


@dataclass(frozen=True)
class PinInSlot(LineJoint):
    """A pin sliding along a slot, relative rotation free."""

    kind = "pin-in-slot"
    rows = 1
    tree_axes = ("slide", "hinge")
    quantities = ("reaction", "normal")
    pivots = True
