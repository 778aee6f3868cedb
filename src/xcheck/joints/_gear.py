"""The gear pair: two gears whose rotations relative to a carrier are coupled."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import NotApplicable
from ._base import Action, Joint
from ._terms import Angles

__all__ = ["GearPair"]


@dataclass(frozen=True)
class GearPair(Joint):
    """Gears ``body_a`` and ``body_b`` meshing on a ``carrier`` (the ground, or an
    arm both turn on), their pitch circles rolling without slip.

    Each gear turns on the carrier about a revolute joint at its centre
    (``pin_a``, ``pin_b``: the joints; ``centre_a``, ``centre_b``: their points
    on the gears); the pitch radii
    ``radius_a`` and ``radius_b`` (m) add up to the centres' distance for an
    external mesh, differ by it for an internal one (a pinion in a ring).
    With ``sigma`` +1 (external) or -1 (internal), the constraint (1 row, m) is
    the arc the two pitch circles roll through relative to the carrier:

        r_a (phi_a - phi_c) + sigma r_b (phi_b - phi_c - phase) = 0,

    so that phi_b - phi_c = phase - sigma (r_a / r_b) (phi_a - phi_c) (Willis:
    (omega_b - omega_c) / (omega_a - omega_c) = -sigma r_a / r_b), with
    ``phase`` (rad) body b's frame angle relative to the carrier's where body
    a's is zero. It cannot be driven (drive a gear's revolute).

    The coupling acts as torques on the two gears and the carrier (the model
    MuJoCo's, Drake's and pymunk's couplings share): its reactions are the
    tooth force it stands for, ``tooth_force`` (N, positive where it turns
    ``body_b`` counter-clockwise relative to the carrier) and ``reaction``
    (N, 2), that force as a vector at the pitch point (pressure angle 0), gear
    a on gear b. The gears' revolutes carry no share of it: a bearing's load
    is its revolute's reaction plus the tooth force moved to the gear's centre.
    """

    carrier: str
    pin_a: str
    pin_b: str
    centre_a: str
    centre_b: str
    radius_a: float
    radius_b: float
    phase: float = 0.0
    internal: bool = False

    kind = "gear"
    rows = 1
    quantities = ("reaction", "tooth_force")
    connects = False  # a coupling: an engine closes it by a constraint, never as a tree joint

    @property
    def sigma(self) -> float:
        """+1 for an external mesh, -1 for an internal one."""
        return -1.0 if self.internal else 1.0

    @property
    def bodies(self) -> tuple[str, ...]:
        return (self.body_a, self.body_b, self.carrier)

    @property
    def ratio(self) -> float:
        """(omega_b - omega_c) / (omega_a - omega_c): -r_a / r_b external, +r_a / r_b internal."""
        return -self.sigma * self.radius_a / self.radius_b

    def needs_in_tree(self):
        return (self.pin_a, self.pin_b)  # their coordinates are the gears' rotations relative to the carrier

    def anchors(self):
        return ()  # its centres are its gears' revolutes' points

    def coefficients(self) -> tuple[float, float, float]:
        """The row's coefficients of phi_a, phi_b, phi_c (m)."""
        s = self.sigma
        return self.radius_a, s * self.radius_b, -(self.radius_a + s * self.radius_b)

    def tree_coupling(self, sign: Callable[[str, str], float | None], coupling: str) -> tuple[float, float, float]:
        """The mesh in its gears' revolutes' coordinates q_a, q_b, as an engine's
        coupling of two tree joints holds it: q_b = s_b phase + k q_a.

        Parameters
        ----------
        sign : callable
            ``sign(pin, gear)``: +1 where the revolute ``pin``'s coordinate is
            the gear's rotation relative to the carrier, -1 where it is the
            carrier's relative to the gear, None where the revolute closes a
            loop (no coordinate of the engine's tree).
        coupling : str
            The engine's coupling, for the reason it cannot hold the pair.

        Returns
        -------
        (k, s_a, s_b)
            k = -sigma s_a s_b r_a / r_b and the two revolutes' signs.

        Raises
        ------
        NotApplicable
            Where a gear's revolute closes a loop.
        """
        signs = []
        for pin, gear in ((self.pin_a, self.body_a), (self.pin_b, self.body_b)):
            s = sign(pin, gear)
            if s is None:
                raise NotApplicable(
                    f"gear pair {self.name!r}: its gear {gear}'s revolute {pin!r} closes a loop, and {coupling} "
                    "couples the coordinates of tree joints only"
                )
            signs.append(s)
        return -self.sigma * signs[0] * signs[1] * self.radius_a / self.radius_b, signs[0], signs[1]

    def angle_coupling(self, coupling: str) -> tuple[str, str, float, float]:
        """The mesh as a relation of two moving bodies' absolute angles, as an
        engine's coupling of two bodies holds it: ratio phi_j - phi_i = phase,
        the third of the gears and the carrier being the ground.

        Returns
        -------
        (i, j, ratio, phase)
            The two bodies, ``-k_j / k_i`` and ``-offset / k_i`` (rad) of the
            row k_i phi_i + k_j phi_j = offset.

        Raises
        ------
        NotApplicable
            Where the pair couples three moving bodies (``coupling`` says what
            the engine's couples).
        """
        from ..model import GROUND  # the model imports the joint types

        moving = [(body, k) for body, k in zip(self.bodies, self.coefficients()) if body != GROUND]
        if len(moving) > 2:
            raise NotApplicable(
                f"gear pair {self.name!r} couples three moving bodies ({', '.join(b for b, _ in moving)}): {coupling}"
            )
        (i, k_i), (j, k_j) = moving
        return i, j, -k_j / k_i, -self.sigma * self.radius_b * self.phase / k_i

    def terms(self, locate):
        a, b, c = (locate(body, None)[0] for body in self.bodies)
        offset = self.sigma * self.radius_b * self.phase
        return [Angles(a, b, c, self.coefficients(), offset, is_angle=False)]

    # -- dynamics ---------------------------------------------------------
    def pitch_point(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pitch point P and the unit direction t in which a positive tooth
        force pushes gear b there (turning it counter-clockwise), from the gears'
        centres ``a`` and ``b`` (N, 2), m: P divides the line of centres as the
        radii do, t = R (P - B) / r_b; (N, 2) each."""
        a, b = np.atleast_2d(a), np.atleast_2d(b)
        s, ra, rb = self.sigma, self.radius_a, self.radius_b
        p = (rb * a + s * ra * b) / (rb + s * ra)
        t = (p - b) / rb
        return p, np.stack([-t[:, 1], t[:, 0]], axis=1)

    def reactions(self, multipliers, solution):
        # the row's generalised force on phi_b is sigma r_b lambda: the torque of sigma lambda at radius r_b
        force = self.sigma * multipliers[:, 0]
        return self.reactions_from_unknowns(force[:, None], solution)

    def reaction_actions(self, solution):
        s, ra, rb = self.sigma, self.radius_a, self.radius_b
        return [[Action(self.body_b, rb), Action(self.body_a, s * ra), Action(self.carrier, -(rb + s * ra))]]

    def reactions_from_unknowns(self, unknowns, solution):
        force = unknowns[:, 0]
        _, t = self.pitch_point(*(solution.point(label, body)["position"] for body, label in self._centres()))
        return {"reaction": force[:, None] * t, "tooth_force": force}

    def _centres(self) -> tuple[tuple[str, str], tuple[str, str]]:
        return (self.body_a, self.centre_a), (self.body_b, self.centre_b)
