"""pymunk: the mechanism as a 2-D constraint scene (:mod:`.scene`), simulated
with its inputs driven (:mod:`.modes`), its impulses as reactions
(:mod:`.inverse`), what it simulated drawn by :mod:`.figure`."""

from __future__ import annotations

import numpy as np

from xcheck.engines._contract import Engine, Finding, Mode, positive_inertia
from xcheck.ladder import FAILURE, REACTIONS
from xcheck.model import Mechanism
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


#: The largest moment of inertia about its centre of mass, as a fraction of m d^2 (d: the
#: driven pin to the centre of mass), at which pymunk's pivot was measured not to hold a
#: body whose rotation a motor holds (1e-3 fails, 3e-3 holds: the finding's reproducer).
POINT_MASS_FRACTION = 1e-3


def _driven_point_mass(mechanism: Mechanism) -> bool:
    """Whether a driver turns a revolute joint of a moving body whose moment of inertia
    about its centre of mass is at most :data:`POINT_MASS_FRACTION` m d^2, d its
    distance from the pin (the moment pymunk is given, :func:`positive_inertia`)."""
    for driver in mechanism.drivers:
        if driver.quantity != "angle":  # a motor turns a pin; a slide is driven otherwise
            continue
        for name, point in mechanism.joint(driver.joint).anchors():
            body = mechanism.body(name)
            if name == mechanism.ground.name or body.mass is None or body.com is None or body.inertia is None:
                continue
            lever = float(np.hypot(*(np.asarray(body.points[point]) - body.com)))
            moment = positive_inertia(body.mass, body.inertia, mechanism.size)
            if moment <= POINT_MASS_FRACTION * body.mass * lever * lever:
                return True
    return False


_POINT_MASS_MOTOR = Finding(
    "pymunk's pivot does not hold a point mass whose rotation a motor holds",
    "A body of 1 kg whose moment about its centre of mass is 1e-12 kg m^2 (a point mass) hangs 1 m from a "
    "PivotJoint, level with it, under gravity, a SimpleMotor holding its angular velocity at 0; at 0.25 ms "
    "steps, 500 iterations, every error corrected in full, it falls freely: 0.30 m in 0.25 s, its angle "
    "still 0. At 1e-6 and 1e-3 kg m^2 the state blows up; from 3e-3 kg m^2 (a rod's 1/12 included) it "
    "stays put, and without the motor the pendulum swings on its pivot (held to 2e-7 m; pymunk 7.3.1, "
    "Chipmunk 2.0.1). xcheck's pymunk reactions drive every input by a motor: on IFToMM's pendulum "
    "(tests/data/pendulum.toml, a point mass held still by its driver) its scene comes apart at 0.25 s, "
    "0.30 m open",
    (FAILURE,),
    kinds=(REACTIONS,),
    reproducer="reproducers/pymunk_point_mass_motor.py",
    mechanisms=_driven_point_mass,
    mechanisms_text=(
        f"a driven pin's moving body whose moment about its centre of mass is at most {POINT_MASS_FRACTION:g} m d^2"
    ),
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
    findings = (_POINT_MASS_MOTOR,)
    color = "tab:green"
    force_style = {"lw": 0, "marker": ".", "ms": 4}  # impulses scatter step to step
    notes = (
        "Pivot, groove and slide joints between 2-D bodies; a prismatic joint as a groove plus a rotary "
        "lock; pymunk's constraints are soft and iterative."
    )
