"""MuJoCo: the mechanism as an MJCF file (:mod:`.mjcf`), MuJoCo as a kinematic
oracle (:mod:`.oracle`), as a simulator (:mod:`.dynamic`) and in free motion
(:mod:`.free`), its inverse dynamics (:mod:`.inverse`); :mod:`.modes` runs them
and compares."""

from __future__ import annotations

import math

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, ROUND_OFF, Tolerance

__all__ = ["MuJoCo"]

_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    1.5e-2,
    "converges to the exact answer: RK4, stiff solref = "
    "2 dt, order 2 in positions and angles, 1 in rates; accelerations (qacc) carry MuJoCo's "
    "constraint stabilisation, which does not vanish as dt -> 0 (observed orders -0.9 to 0.1 over "
    "models/ and the test mechanisms): bound about 4 x the worst measured there (3.5e-3)" + CONVERGENCE_NOTE,
)


_FREE = Tolerance(
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    "benchmark: no verdict; the ladder against the native reference is the result",
)


class MuJoCo(Engine):
    """MuJoCo through its MJCF file: kinematic oracle, driven dynamics and free motion."""

    name = "mujoco"
    title = "MuJoCo"
    requires = ("mujoco",)
    implementation = "xcheck.engines.mujoco.modes"
    distributions = ("mujoco",)
    install = "pip install mujoco"
    modes = (
        Mode("mujoco-kinematic", "kinematic", ROUND_OFF, style=dict(color="tab:blue", lw=0, marker="+", ms=5)),
        # measured between the two finest steps over the models and the test mechanisms:
        # tight RK4 2.0 (positions, angles), 1.0 (rates); qacc does not converge
        Mode(
            "mujoco-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": None, "alpha": None},
            style=dict(color="tab:blue", lw=1, ls="--"),
        ),
        Mode("mujoco-free", "free", _FREE, style=dict(color="tab:blue", lw=1, ls=":"), cost=0.12),
    )
    force_tolerance = 1e-12
    force_basis = "mj_inverse at the native states: round-off (measured at most 1.7e-13)"
    export_format, export_directory = "mjcf", "mjcf"
    color = "tab:blue"
    notes = (
        "Revolute, prismatic and pin-in-slot joints; a loop is closed by an equality (connect or weld) on "
        "a carrier body where it is cut at a slider; inputs driven by position and velocity servos. Free motion: "
        "the servos off, springs as spatial tendons, constant loads through the passive-force callback."
    )
