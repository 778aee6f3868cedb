"""Newton (on NVIDIA warp): the mechanism as articulated links whose loops are closed
by loop joints (:mod:`.model`), stepped in free motion by each of its solvers
(:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Finding, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["Newton"]

#: Featherstone's rows on closed loops come apart: it steps the articulations alone.
_FEATHERSTONE = Finding(
    "Newton's SolverFeatherstone ignores loop joints",
    "SolverFeatherstone steps the articulations as if the loop joints (joints left out of add_articulation, "
    "as Newton's documentation describes loops) did not exist, with no warning: on a four-bar released "
    "from rest the loop opens by 0.5 m within 1 s at dt = 1 ms, while SolverXPBD holds it within 8e-4 m "
    "(newton 1.8.0); its rows on closed loops come apart",
    ("position", "angle"),
    kinds=("free",),
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


class Newton(Engine):
    """Newton: free motion with each solver that takes a loop joint, on the CPU."""

    name = "newton"
    title = "Newton"
    requires = ("newton", "warp")
    implementation = "xcheck.engines.newton.modes"
    distributions = ("newton", "warp-lang", "mujoco-warp")
    install = "pip install xcheck[newton]"
    modes = (
        Mode(
            "newton-free",
            "free",
            FREE_MOTION,
            style=dict(color="tab:gray", lw=1, ls=":"),
            on_request=True,
            on_request_reason=(
                "its solvers' warp kernels compile for 1 to 3 minutes each on a machine that has not run them "
                "(cached after), more than a default run is allowed"
            ),
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
        "ignores loop joints) and SolverSemiImplicit. Not converted (not applicable): pin-in-slot joints, loops "
        "cut at a prismatic joint, springs, dampers and loads."
    )
