"""Pinocchio: the mechanism as a kinematic tree with loop constraints
(:mod:`.model`, written as URDF by :mod:`.urdf`), Pinocchio as a kinematic
oracle (:mod:`.oracle`), in driven dynamics (:mod:`.dynamic`), in free motion
(:mod:`.free`) and inverse dynamics (:mod:`.inverse`); :mod:`.modes` runs them and compares."""

from __future__ import annotations

import math

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, ROUND_OFF, Tolerance

__all__ = ["Pinocchio"]

_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: RK4 over 200, "
    "400, 800 steps per window, order 4 in every quantity" + CONVERGENCE_NOTE,
)
FREE_TOLERANCE = Tolerance(
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    "benchmark: no verdict; the ladder against the native reference is the result",
)


#: Stated for its reproducer: xcheck's Baumgarte series work around it, its rk4 rows show it as they are.
_SINGULAR_PASS = Finding(
    "Pinocchio's constraintDynamics without Baumgarte breaks down at a singular pass",
    "Integrated by RK4 at dt = 1 ms on constraintDynamics (proximal accuracy 1e-14, mu 1e-12) with no "
    "Baumgarte correction, the double four-bar (IFToMM A02) keeps its energy to 3e-10 J through two "
    "singular passes, to 2e-5 J through the third, and at the fourth (3.17 s) its energy jumps and it "
    "leaves the parallelogram branch (xcheck's model, cut elsewhere, turns NaN there); with Baumgarte "
    "gains (Kp 100, Kd 20) it keeps its energy to 2e-10 J for 10 s (pin 4.1.0). xcheck's rk4 rows show "
    "it on A02; its Baumgarte series work around it",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/pinocchio_singular_pass.py",
)


class Pinocchio(Engine):
    """Pinocchio: kinematic oracle and constraintDynamics."""

    name = "pinocchio"
    title = "Pinocchio"
    requires = ("pinocchio",)
    implementation = "xcheck.engines.pinocchio.modes"
    distributions = ("pin",)
    install = "pip install pin"
    modes = (
        Mode("pinocchio-kinematic", "kinematic", ROUND_OFF, style=dict(color="tab:orange", lw=0, marker="1", ms=6)),
        # RK4: observed orders 3.9 to 4.1 in every category over the models and the test mechanisms
        Mode(
            "pinocchio-dynamic",
            "dynamic",
            _DYNAMIC,
            orders=dict.fromkeys(("position", "angle", "velocity", "omega", "acceleration", "alpha"), 4.0),
            style=dict(color="tab:orange", lw=1, ls=":"),
            cost=1.8,
        ),
        Mode("pinocchio-free", "free", FREE_TOLERANCE, style=dict(color="tab:orange", lw=1, ls="-."), cost=0.29),
    )
    force_tolerance = 1e-12
    force_basis = "the multipliers of the loop closures at the native states: round-off (measured at most 1.7e-13)"
    export_format, export_directory = "urdf", "urdf"
    findings = (_SINGULAR_PASS,)
    color = "tab:orange"
    notes = (
        "A spanning tree of revolute and prismatic joints (URDF) with the loops closed by CONTACT_3D/6D "
        "constraints, cut at a slider on a carrier body; pin-in-slot through its carrier."
    )
