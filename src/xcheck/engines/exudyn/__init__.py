"""Exudyn: the mechanism as 2-D rigid bodies with exact index-3 joints
(:mod:`.free`), integrated in free motion by Exudyn's generalized-alpha solver."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["Exudyn"]


class Exudyn(Engine):
    """Exudyn (redundant coordinates, index-3 DAE): free motion of the released mechanism."""

    name = "exudyn"
    title = "Exudyn"
    requires = ("exudyn",)
    implementation = "xcheck.engines.exudyn.free"
    distributions = ("exudyn",)
    install = "pip install xcheck[exudyn]"
    modes = (Mode("exudyn-free", "free", FREE_MOTION, style=dict(color="tab:purple", lw=1, ls="--")),)
    color = "tab:purple"
    notes = (
        "2-D rigid bodies (NodeRigidBody2D at the centre of mass) joined by RevoluteJoint2D and "
        "PrismaticJoint2D (a pin-in-slot: the same joint without its rotation lock), gravity, constant "
        "forces and torques, linear spring-dampers; constraints exact at position level (index 3) and "
        "solved by Newton in the implicit generalized-alpha integrator. Not: a massless moving body "
        "(singular mass matrix); Exudyn's explicit integrators refuse these joints. Its index-3 "
        "defaults pass the double four-bar's singular positions on the branch at second order; "
        "index-2 constraints or Newton to 1e-12 stop there (the Jacobian loses rank, as with "
        "redundant constraints, jgerstmayr/EXUDYN#39), and spectral radius 1 grows unstable."
    )
