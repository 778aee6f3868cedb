"""PyBullet: the mechanism as a Featherstone multibody (a tree of revolute and
prismatic links on a fixed base) whose loops are closed by point-to-point
constraints, in free motion (:mod:`.free`) and driven by its joint motors (:mod:`.dynamic`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["PyBullet"]

_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: the driven joints held by PyBullet's position motor, 25, 50, 100 "
    "steps per sample; observed orders over models/ 1.92-2.03 in positions and angles (the error is the "
    "loops' opening, 4e-7 .. 4e-6 m at the finest step), 0.99-1.17 in rates (semi-implicit Euler); "
    "PyBullet gives no accelerations" + CONVERGENCE_NOTE,
)


class PyBullet(Engine):
    """PyBullet (Bullet's multibody and iterative constraint solver): driven dynamics and free motion."""

    name = "pybullet"
    title = "PyBullet"
    requires = ("pybullet",)
    implementation = "xcheck.engines.pybullet.modes"
    distributions = ("pybullet",)
    install = "pip install xcheck[pybullet]"
    modes = (
        Mode(
            "pybullet-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": None, "alpha": None},
            style=dict(color="tab:brown", lw=1, ls="--"),
        ),
        Mode("pybullet-free", "free", FREE_MOTION, style=dict(color="tab:brown", lw=1, ls="--"), cost=0.03),
    )
    color = "tab:brown"
    notes = (
        "Revolute and prismatic joints: a tree of links (createMultiBody, fixed base: the ground; revolutes "
        "about z, prismatic joints in the plane) and point-to-point constraints (createConstraint "
        "JOINT_POINT2POINT) at the revolute loop cuts, stepped by semi-implicit Euler with an iterative "
        "constraint solver. Gravity, constant loads and linear spring-dampers (external forces applied before "
        "each step). Not converted (not applicable): pin-in-slot joints and loops cut at a prismatic joint. "
        "PyBullet's URDF cannot hold the loops (bulletphysics/bullet3#2922), so there is no model file. Driven "
        "dynamics: the driven joints (tree joints) held on the motion laws by PyBullet's position motor; positions "
        "and velocities (it gives no accelerations)."
    )
