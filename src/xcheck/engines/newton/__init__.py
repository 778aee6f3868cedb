"""Newton (on NVIDIA warp): the mechanism as articulated links whose loops are closed
by loop joints (:mod:`.model`), stepped by each of its solvers in driven dynamics,
the driven bodies kinematic (:mod:`.dynamic`), and in free motion (:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["Newton"]

#: Featherstone's rows on closed loops come apart: it steps the articulations alone.
_FEATHERSTONE = Finding(
    "Newton's SolverFeatherstone ignores loop joints",
    "SolverFeatherstone steps the articulations as if the loop joints (joints left out of add_articulation, "
    "as Newton's documentation describes loops) did not exist, with no warning: on a four-bar released "
    "from rest the loop opens by 0.5 m within 1 s at dt = 1 ms, while SolverXPBD holds it within 8e-4 m "
    "(newton 1.8.0); driven (the crank a kinematic body) it opens by 6.6e-2 m by 0.53 s at 1.6 and 0.8 ms; "
    "its rows on closed loops come apart",
    ("position", "angle"),
    kinds=("free", "dynamic"),
    closed_loops=True,
    reproducer="reproducers/newton_featherstone_loop_joint.py",
    series=("featherstone",),
)
#: Worked around in xcheck's model (its coordinates are 0 at the start), stated for the maintainers.
_MUJOCO_ANCHORS = Finding(
    "Newton's MuJoCo backend anchors loop joints at q = 0",
    "SolverMuJoCo places a loop joint's anchors as if the model were assembled with every joint coordinate "
    "0: a four-bar started assembled at other coordinates opens its loop by 1.9e-2 m in 0.1 s, against "
    "3.5e-4 m for the same four-bar built with q = 0 at the start (newton 1.8.0, mujoco-warp 3.17, MuJoCo "
    "4.0); silently wrong. xcheck's Newton model puts every coordinate's 0 at the start, so its rows do "
    "not show it",
    ("position", "angle"),
    kinds=(),
    closed_loops=True,
    reproducer="reproducers/newton_mujoco_loop_anchor.py",
)


_ON_REQUEST = (
    "its solvers' warp kernels compile the first time they run on a machine (about 40 CPU s for the four, "
    "cached after), more than a default run is allowed"
)
_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: the driven bodies Newton's kinematic bodies, set to the laws before every "
    "step; the compared series SolverXPBD at 25, 50, 100 steps per sample, observed orders over models/ "
    "1.6-2.1 in positions and angles, 0.6-3.1 in rates (fourbar 2.1e-4, 5.4e-5, 1.4e-5 m); SolverMuJoCo's "
    "soft loop constraints converge at order 1 on the four-bar and not at all on the slider-crank" + CONVERGENCE_NOTE,
)


class Newton(Engine):
    """Newton: driven dynamics and free motion with each solver that takes a loop joint, on the CPU."""

    name = "newton"
    title = "Newton"
    requires = ("newton", "warp")
    implementation = "xcheck.engines.newton.modes"
    distributions = ("newton", "warp-lang", "mujoco-warp")
    install = "pip install xcheck[newton]"
    modes = (
        Mode(
            "newton-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": None, "alpha": None},
            style=dict(color="tab:gray", lw=1, ls="-"),
            on_request=True,
            on_request_reason=_ON_REQUEST,
            campaigns=False,
            cost=13.0,
        ),
        Mode(
            "newton-free",
            "free",
            FREE_MOTION,
            style=dict(color="tab:gray", lw=1, ls=":"),
            on_request=True,
            on_request_reason=_ON_REQUEST,
            campaigns=False,
        ),
    )
    findings = (_FEATHERSTONE, _MUJOCO_ANCHORS)
    color = "tab:gray"
    notes = (
        "Revolute and prismatic joints: Newton links (xcheck's body frames) hung by revolute and prismatic joints "
        "in one articulation, every coordinate 0 at the start, each loop cut at a revolute a revolute joint "
        "left out of the articulation (Newton's loop joint); gravity; the CPU, warp's float32. Stepped at fixed "
        "steps by SolverMuJoCo (MuJoCo's C library; needs mujoco-warp), SolverXPBD, SolverFeatherstone (which "
        "ignores loop joints) and SolverSemiImplicit. Driven: each driven body a kinematic body (Newton's "
        "prescribed motion), set to the laws before every step. Not converted (not applicable): pin-in-slot "
        "joints, loops cut at a prismatic joint, springs, dampers and loads, and drivers between two moving "
        "bodies (Newton lets only a body hung from the ground be kinematic)."
    )
