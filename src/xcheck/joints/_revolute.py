"""The revolute joint: a pin."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._base import Action, Joint
from ._terms import Coincidence, relative_angle

__all__ = ["Revolute"]


@dataclass(frozen=True)
class Revolute(Joint):
    """A pin joint: point ``point_a`` of ``body_a`` coincides with ``point_b`` of ``body_b``.

    Driven quantity: the relative angle ``phi_b - phi_a`` of the bodies' frames.
    Reaction: the force ``body_a`` exerts on ``body_b`` at the pin, (N, 2).
    """

    point_a: str
    point_b: str

    kind = "revolute"
    rows = 2
    driven_quantity = "angle"
    quantities = ("reaction",)
    pivots = True
    tree_rank = 1  # loops are cut at revolutes: a point constraint closes them
    tree_axes = ("hinge",)

    @property
    def tree_points(self):
        return (self.point_a, self.point_b)

    def coordinate(self, state):
        (_, _, phi_a, omega_a), (_, _, phi_b, omega_b) = state(self.body_a, None), state(self.body_b, None)
        return phi_b - phi_a, omega_b - omega_a

    def anchors(self):
        return ((self.body_a, self.point_a), (self.body_b, self.point_b))

    def shared_label(self):
        return self.point_a if self.point_a == self.point_b else None

    def terms(self, locate):
        (a, s_a), (b, s_b) = locate(self.body_a, self.point_a), locate(self.body_b, self.point_b)
        return [Coincidence(a, s_a, b, s_b)]

    def driver_term(self, locate, driver):
        a, b = locate(self.body_a, self.point_a)[0], locate(self.body_b, self.point_b)[0]
        return relative_angle(a, b, 0.0, driver=driver)

    def reactions(self, multipliers, solution):
        # Phi = r_a + A_a s_a - r_b - A_b s_b: the constraint force on b is -lambda
        return {"reaction": -multipliers[:, 0:2]}

    def reaction_actions(self, solution):
        at = solution.point(self.point_b, self.body_b)["position"]
        columns = []
        for axis in range(2):
            e = np.zeros_like(at)
            e[:, axis] = 1.0
            columns.append([Action(self.body_b, 1.0, e, at), Action(self.body_a, -1.0, e, at)])
        return columns

    def reactions_from_unknowns(self, unknowns, solution):
        return {"reaction": unknowns[:, 0:2]}

    def driver_actions(self, solution):
        return [Action(self.body_b, 1.0), Action(self.body_a, -1.0)]
