"""PyBullet: the mechanism as a Featherstone multibody (a tree of revolute and
prismatic links on a fixed base) whose loops are closed by point-to-point
constraints, in free motion (:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["PyBullet"]


class PyBullet(Engine):
    """PyBullet (Bullet's multibody and iterative constraint solver): free motion."""

    name = "pybullet"
    title = "PyBullet"
    requires = ("pybullet",)
    implementation = "xcheck.engines.pybullet.free"
    distributions = ("pybullet",)
    install = "pip install xcheck[pybullet]"
    modes = (Mode("pybullet-free", "free", FREE_MOTION, style=dict(color="tab:brown", lw=1, ls="--")),)
    color = "tab:brown"
    notes = (
        "Revolute and prismatic joints: a tree of links (createMultiBody, fixed base: the ground; revolutes "
        "about z, prismatic joints in the plane) and point-to-point constraints (createConstraint "
        "JOINT_POINT2POINT) at the revolute loop cuts, stepped by semi-implicit Euler with an iterative "
        "constraint solver. Gravity, constant loads and linear spring-dampers (external forces applied before "
        "each step). Not converted (not applicable): pin-in-slot joints and loops cut at a prismatic joint. "
        "PyBullet's URDF cannot hold the loops (bulletphysics/bullet3#2922), so there is no model file. Free "
        "motion only: no driven mode."
    )
