"""DART (dartpy): the mechanism as a skeleton of revolute and prismatic joints whose
loops are closed by joint constraints in the world's constraint solver
(:mod:`.model`), stepped in free motion (:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.ladder import FAILURE
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["Dart"]


_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: the driven joints' velocity actuators commanded before every step "
    "to reach the law at the step's end, 25, 50, 100 steps per sample (fewer where the step would fall "
    "below 1e-4 s); observed orders over models/ 2.8-3.0 in positions and angles, 1.0-1.6 in rates "
    "(fourbar 4.8e-5, 7.0e-6, 9.2e-7 m); DART's accelerations are not compared" + CONVERGENCE_NOTE,
)


_SMALL_STEPS = Finding(
    "DART's loop constraints blow up at small time steps",
    "A slider-crank closed by a RevoluteJointConstraint (DART's defaults, crank at 100 rad/s) stays finite "
    "for 0.01 s at dt = 1e-4 to 5e-5 s and turns non-finite after 19 to 44 steps at dt = 4e-5 to 1e-5 s, "
    "free or with a velocity actuator on the crank (dartpy 6.20); on models/slider-crank.toml dart-dynamic's "
    "runs at 1.6e-5 s (100 steps a sample) did so. Its ladders keep the step at 1e-4 s or more where the "
    "samples allow; a run at a step below 5e-5 s that comes apart or turns non-finite has this as its reason",
    (FAILURE,),
    kinds=("dynamic", "free"),
    closed_loops=True,
    reproducer="reproducers/dart_small_step_blow_up.py",
    steps_below=5e-5,
)


class Dart(Engine):
    """DART (Gazebo's default engine): free motion with its loops closed by joint constraints."""

    name = "dart"
    title = "DART"
    requires = ("dartpy",)
    implementation = "xcheck.engines.dart.modes"
    distributions = ("dartpy",)
    install = "pip install xcheck[dart]"
    modes = (
        Mode(
            "dart-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": None, "alpha": None},
            style=dict(color="tab:brown", lw=1, ls="-"),
        ),
        Mode("dart-free", "free", FREE_MOTION, style=dict(color="tab:brown", lw=1, ls="-"), cost=0.02),
    )
    findings = (_SMALL_STEPS,)
    color = "tab:brown"
    notes = (
        "Revolute and prismatic joints: a DART Skeleton of RevoluteJoint and PrismaticJoint (xcheck's body frames "
        "as its body nodes, every coordinate 0 at the start) with each loop cut at a revolute closed by a "
        "RevoluteJointConstraint or a BallJointConstraint in the world's constraint solver; gravity. Stepped by "
        "semi-implicit Euler with the constraints as a velocity-level LCP (Dantzig, PGS fallback), their drift "
        "corrected by ERP and softened by CFM (DART's defaults). Not converted (not applicable): pin-in-slot "
        "joints, loops cut at a prismatic joint, springs, dampers and loads."
    )
