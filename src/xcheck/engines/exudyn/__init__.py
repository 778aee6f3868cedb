"""Exudyn: the mechanism as 2-D rigid bodies with exact index-3 joints
(:mod:`.free`), integrated by Exudyn's generalized-alpha solver in free motion
(:mod:`.free`) and with its joint-angle drivers prescribed (:mod:`.dynamic`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["Exudyn"]

_DYNAMIC = Tolerance(
    1e-10,
    1e-10,
    CONVERGES,
    CONVERGES,
    "positions and angles from the index-3 constraints, exact to Newton's tolerance (1e-10): bound "
    "1e-10 of the size or rad (measured at most 2.2e-15 m, 8.4e-15 rad over the models); velocities "
    "and accelerations converge: generalized-alpha (rho 0.9) over 25, 50, 100 steps per sample, "
    "order 2.0 in velocities; accelerations order 2 (task-2-1: 2.0), higher between the coarser "
    "steps, where the method's start-up transient (decaying as rho^n) adds to the truncation" + CONVERGENCE_NOTE,
)

#: Exudyn's driven accelerations at small steps: the coordinates' round-off over the step squared.
_ACCELERATION_ROUND_OFF = Finding(
    "Exudyn's index-3 generalized-alpha accelerations grow as the time step falls",
    "Newton solves a step for the accelerations, so a coordinate held by an index-3 constraint carries "
    "its round-off (a unit in its last place, eps |q|) into them over beta h^2, summed over past steps by "
    "the method's damping of a constrained coordinate (a double root -rho_inf): a wheel driven at "
    "2 t + 1.5 t^2 rad (alpha exactly 3 rad/s^2; Exudyn 1.13.6, rho_inf 0.9, Newton 1e-10) misses it by "
    "8.2e-7, 2.7e-6, 1.5e-5, 7.1e-5 rad/s^2 at h = 4e-4 .. 5e-5 s, 360 to 580 times eps |q| / h^2, "
    "whatever Newton's tolerance (1e-8 .. 1e-13); rho_inf 0 still leaves 6.7 times. It holds in an open "
    "chain as in a closed one; xcheck sees it where the motion leaves no truncation error above it and a "
    "coordinate is not tied bit for bit to a driven one (a driven input's own acceleration is its "
    "reference): the planetary train of tests/data/planetary-fixed-sun.toml, its planet geared 3 to 1 to "
    "its constant-acceleration arm, alpha 6.1e-6 of the largest angular acceleration against a noise "
    "floor of 1.3e-8, growing as the step halves",
    ("acceleration", "alpha"),
    kinds=("dynamic",),
    reproducer="reproducers/exudyn_index3_acceleration_round_off.py",
)


class Exudyn(Engine):
    """Exudyn (redundant coordinates, index-3 DAE): driven dynamics and free motion."""

    name = "exudyn"
    title = "Exudyn"
    requires = ("exudyn",)
    implementation = "xcheck.engines.exudyn.modes"
    distributions = ("exudyn",)
    install = "pip install xcheck[exudyn]"
    modes = (
        Mode(
            "exudyn-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": None, "angle": None, "velocity": 2.0, "omega": 2.0, "acceleration": 2.0, "alpha": 2.0},
            style=dict(color="tab:purple", lw=1, ls="--"),
            cost=3.0,
        ),
        Mode("exudyn-free", "free", FREE_MOTION, style=dict(color="tab:purple", lw=1, ls="--"), cost=0.12),
    )
    findings = (_ACCELERATION_ROUND_OFF,)
    export_format, export_directory = "exudyn", "exudyn"
    color = "tab:purple"
    notes = (
        "2-D rigid bodies (NodeRigidBody2D at the centre of mass) joined by RevoluteJoint2D and "
        "PrismaticJoint2D (a pin-in-slot: the same joint without its rotation lock), gravity, forces and "
        "torques (constant or with a time law), linear and rotational spring-dampers; constraints "
        "exact at position level (index 3) and "
        "solved by Newton in the implicit generalized-alpha integrator; joint-angle drivers as "
        "coordinate constraints with a time-dependent offset. Not: slide drivers (the slide is not a "
        "node coordinate), a massless moving body in free motion (singular mass matrix); Exudyn's "
        "explicit integrators refuse these joints. Its index-3 defaults pass the double four-bar's "
        "singular positions on the branch at second order; index-2 constraints or Newton to 1e-12 "
        "stop there (the Jacobian loses rank, as with redundant constraints, jgerstmayr/EXUDYN#39), "
        "and spectral radius 1 grows unstable."
    )
