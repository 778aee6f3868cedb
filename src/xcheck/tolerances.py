"""Tolerances: what a mode must meet, and the bounds every engine shares.

A :class:`Tolerance` bounds each quantity category of a mode's difference from
the native solution; :data:`ROUND_OFF` is the bound of a kinematic oracle
(an engine's own kinematics must reproduce the exact solution), :data:`EXACT`
that of an independent exact method, :data:`CONVERGES` marks a category a
dynamic mode's own convergence study judges (see :mod:`xcheck.runner`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Tolerance",
    "EPSILON",
    "CONDITIONING_FACTOR",
    "ENGINE_CONDITIONING_FACTOR",
    "conditioned_round_off",
    "length_ratio",
    "power_round_off",
    "ROUND_OFF",
    "EXACT",
    "CONVERGES",
    "CONVERGENCE_NOTE",
    "convergence_round_off",
]


@dataclass(frozen=True)
class Tolerance:
    """What a mode must meet.

    ``position`` is a fraction of the mechanism's size, ``angle`` in rad,
    ``velocity`` (velocities and angular velocities) and ``acceleration``
    (accelerations and angular accelerations) fractions of the largest
    magnitude of that quantity in the mechanism, but at least of its physical
    floor (:func:`xcheck.results.scale_floors`); ``basis`` says where the
    numbers come from.
    """

    position: float
    angle: float
    velocity: float
    acceleration: float
    basis: str
    conditioned: bool = False
    conditioning_factor: float = 10.0

    def limit(self, category: str, condition: float = 1.0) -> float:
        """The bound of a category; with ``conditioned``, at least the round-off
        that the sweep's conditioning allows (:func:`conditioned_round_off` with
        ``conditioning_factor``)."""
        base = {
            "position": self.position,
            "angle": self.angle,
            "velocity": self.velocity,
            "omega": self.velocity,
            "acceleration": self.acceleration,
            "alpha": self.acceleration,
        }[category]
        if not self.conditioned:
            return base
        return max(base, conditioned_round_off(category, condition, self.conditioning_factor))


#: Unit round-off of float64, and the factor on it in conditioned_round_off.
EPSILON = float(np.finfo(float).eps)
CONDITIONING_FACTOR = 10.0
#: The factor for an engine's own solve in double precision (a kinematic oracle's
#: Newton, the states of an engine's inverse dynamics): Newton stops at a residual
#: of a few eps * size of round-off, which leaves its configuration about kappa
#: times that off and its accelerations about kappa^2 times (what the native
#: solver's polishing removes, :func:`xcheck.kinematics._newton.polish`). Measured
#: (xcheck fuzz, seed 1): the native solver's own double-precision Newton before
#: polishing 49 eps kappa^2 (s1-00441, kappa = 393), Pinocchio's oracle 45
#: (s1-00190, kappa = 206, its Newton stopping at 1e-14 of the size), MuJoCo's
#: reactions 14 (s1-00158): twice the largest.
ENGINE_CONDITIONING_FACTOR = 100.0


def conditioned_round_off(category: str, condition: float, factor: float = CONDITIONING_FACTOR) -> float:
    """The round-off an exact method may show at a configuration whose scaled
    constraint Jacobian has condition number ``condition`` (kappa).

    Forward error <= kappa x backward error (about EPSILON): positions and
    angles come from a solve with the Jacobian (10 EPSILON kappa); rates from
    the velocity solve and accelerations from a second solve whose right-hand
    side carries the velocities' error, so both are allowed 10 EPSILON kappa^2.
    Measured on a parallelogram 1 % from its change points (kappa = 323, the
    worst of tests/data/para.toml): angular accelerations 3.4e-11 (1.5
    EPSILON kappa^2), angular rates 5.4e-13 (7.7 EPSILON kappa); the models'
    worst conditioning is kappa = 156 (task-2-1), where the exact methods'
    rates stay below 5e-14 and the bound is 5.4e-11.
    """
    power = 1 if category in ("position", "angle") else 2
    return factor * EPSILON * condition**power


def length_ratio(mechanism) -> float:
    """The mechanism's size over its shortest length: the smallest distance
    between two distinct points of one moving body, at least 1.

    A body whose rate is this ratio smaller than the others' (a rod 1000 times
    its crank's length turns 1000 times slower) has that rate only to
    round-off of the others', which a large inertia carries into the power.
    """
    size = float(mechanism.size)
    shortest = size
    for body in mechanism.moving_bodies:
        points = np.array(list(body.points.values()), dtype=float).reshape(-1, 2)
        for i in range(len(points) - 1):
            gaps = np.hypot(*(points[i + 1 :] - points[i]).T)
            gaps = gaps[gaps > 1e-9 * size]  # coincident labels are one place
            if gaps.size:
                shortest = min(shortest, float(gaps.min()))
    return max(1.0, size / shortest)


def power_round_off(condition: float, ratio: float, factor: float = CONDITIONING_FACTOR) -> float:
    """The round-off of the native power balance (relative to its largest
    term) at conditioning ``condition`` (kappa) and length ratio ``ratio``
    (:func:`length_ratio`): 10 eps kappa^2 ratio.

    A body of length L driven by a crank r turns at rates r/L of the crank's,
    known to eps kappa^2 of the crank's (accelerations, two solves), and its
    inertia m L^2 makes that a power error of eps kappa^2 L/r of the largest
    term. Measured on an offset slider-crank (fuzz case s1-00111, rod/crank
    ratio 3 to 10 000, kappa = 9): 4.2e-15, 2.6e-14 (10), 1.6e-13 (100),
    1.6e-12 (1000), 3.3e-11 (10 000): 0.08 to 0.18 eps kappa^2 ratio.
    """
    return factor * EPSILON * condition**2 * ratio


CONDITIONED = (
    "; at least 10 eps kappa (positions, angles) and 10 eps kappa^2 (rates), kappa the largest "
    "condition number of the scaled constraint Jacobian over the compared states"
)
ROUND_OFF = Tolerance(
    1e-10,
    1e-10,
    1e-9,
    1e-9,
    "round-off: the engine's own kinematics must reproduce the "
    "exact solution (measured at most 3.4e-14 of the size, 1.2e-12 relative, over all models); at least "
    "100 eps kappa (positions, angles) and 100 eps kappa^2 (rates), kappa the largest condition number of "
    "the scaled constraint Jacobian over the compared states: the engine's Newton in double precision "
    "(measured up to 49 eps kappa^2)",
    conditioned=True,
    conditioning_factor=ENGINE_CONDITIONING_FACTOR,
)
EXACT = Tolerance(
    1e-12,
    1e-12,
    1e-12,
    1e-12,
    "independent exact method: round-off (measured at most "
    "5.1e-14 relative over all models, 1.6e-13 on the test mechanisms)" + CONDITIONED,
    conditioned=True,
)
#: a dynamic mode's category judged by its convergence (the mode's expected orders), not a fixed bound
CONVERGES = math.nan
#: the end of the basis of a tolerance judged by convergence
CONVERGENCE_NOTE = (
    "; each error at most the coarser step's times (h_f / h_c)^(order - 0.5) plus the engine's "
    "noise floor (its kinematic round-off bound)"
)


def convergence_round_off(category: str, step: float = math.inf, extent: float = 0.0, rate: float = 1.0) -> float:
    """The noise floor below which a dynamic mode's error in ``category``
    shows no order: there the error is the engine's round-off, not truncation.

    At least the bound an engine's own kinematics must meet (:data:`ROUND_OFF`:
    1e-10 of the size or rad, 1e-9 relative for rates). A run that holds its
    constraints on positions at every time step ``step`` (s) carries its
    coordinates' round-off, eps x ``extent`` (the largest coordinate, rad or of
    the size), into its velocities over the step and into its accelerations
    over the step squared: relative to the rate scale ``rate`` (1/s), eps
    extent / (rate step) and eps extent / (rate step)^2, which grow as the step
    falls (pymunk's planet on tests/data/planetary-fixed-sun.toml, full error
    correction: its angular velocity off by a unit in the last place of its
    angle over the step, its acceleration, differenced over +-step, by exactly
    that over 2 step^2, 1.0e-7 .. 8.2e-7 rad/s^2 for angles of 2 .. 32 rad at
    4.6e-5 s).
    """
    fixed = ROUND_OFF.limit(category)
    power = {"velocity": 1, "omega": 1, "acceleration": 2, "alpha": 2}.get(category, 0)
    if not power or not (step > 0.0 and rate > 0.0):
        return fixed
    return max(fixed, float(np.finfo(float).eps) * extent / (rate * step) ** power)


#: a free-motion mode: a benchmark against the native reference, no verdict
FREE_MOTION = Tolerance(
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    "benchmark: no verdict; the ladder against the native reference is the result",
)
