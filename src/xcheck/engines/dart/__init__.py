"""DART (dartpy): the mechanism as a skeleton of revolute and prismatic joints whose
loops are closed by joint constraints in the world's constraint solver
(:mod:`.model`), stepped in free motion (:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["Dart"]


class Dart(Engine):
    """DART (Gazebo's default engine): free motion with its loops closed by joint constraints."""

    name = "dart"
    title = "DART"
    requires = ("dartpy",)
    implementation = "xcheck.engines.dart.modes"
    distributions = ("dartpy",)
    install = "pip install xcheck[dart]"
    modes = (Mode("dart-free", "free", FREE_MOTION, style=dict(color="tab:brown", lw=1, ls="-")),)
    color = "tab:brown"
    notes = (
        "Revolute and prismatic joints: a DART Skeleton of RevoluteJoint and PrismaticJoint (xcheck's body frames "
        "as its body nodes, every coordinate 0 at the start) with each loop cut at a revolute closed by a "
        "RevoluteJointConstraint or a BallJointConstraint in the world's constraint solver; gravity. Stepped by "
        "semi-implicit Euler with the constraints as a velocity-level LCP (Dantzig, PGS fallback), their drift "
        "corrected by ERP and softened by CFM (DART's defaults). Not converted (not applicable): pin-in-slot "
        "joints, loops cut at a prismatic joint, springs, dampers and loads."
    )
