"""pymunk: the mechanism as a 2-D constraint scene (:mod:`.scene`), simulated
with its inputs driven (:mod:`.modes`), its impulses as reactions
(:mod:`.inverse`), what it simulated drawn by :mod:`.figure`."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import CONVERGENCE_NOTE, CONVERGES, FREE_MOTION, Tolerance

__all__ = ["Pymunk"]

_DYNAMIC = Tolerance(
    CONVERGES,
    CONVERGES,
    CONVERGES,
    CONVERGES,
    "converges to the exact answer: semi-implicit "
    "Euler, error_bias 0, 500 iterations, window/2000, /4000, /8000 steps: order 2 in positions "
    "and angles, 1 in rates and accelerations (central differences of velocities)" + CONVERGENCE_NOTE,
)


class Pymunk(Engine):
    """pymunk (Chipmunk2D): driven dynamics of the constraint scene."""

    name = "pymunk"
    title = "pymunk"
    requires = ("pymunk",)
    implementation = "xcheck.engines.pymunk.modes"
    distributions = ("pymunk",)
    install = "pip install pymunk"
    modes = (
        Mode(
            "pymunk-dynamic",
            "dynamic",
            _DYNAMIC,
            orders={"position": 2.0, "angle": 2.0, "velocity": 1.0, "omega": 1.0, "acceleration": 1.0, "alpha": 1.0},
            style=dict(color="tab:green", lw=1, ls="-."),
        ),
        Mode("pymunk-free", "free", FREE_MOTION, style=dict(color="tab:green", lw=1, ls="-."), cost=0.02),
    )
    force_tolerance = 7e-2
    force_order = 1.0
    force_basis = (
        "impulses over a step of the driven simulation, first order in the time step (measured at "
        "most 3.2e-2, about half the bound)"
    )
    color = "tab:green"
    force_style = {"lw": 0, "marker": ".", "ms": 4}  # impulses scatter step to step
    notes = (
        "Pivot, groove and slide joints between 2-D bodies; a prismatic joint as a groove plus a rotary "
        "lock; pymunk's constraints are soft and iterative."
    )
