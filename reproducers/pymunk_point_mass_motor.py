"""pymunk (Chipmunk): a pivot does not hold a point mass whose rotation a motor holds.

A body of 1 kg whose moment about its centre of mass is tiny (a point mass: 1e-12
kg m^2) hangs 1 m from a fixed pivot (``PivotJoint``), level with it, under
gravity (9.81 m/s^2 down); a ``SimpleMotor`` to the static body holds its angular
velocity at 0, so the mass should stay where it is: the pivot carries its weight
and the motor the weight's moment, 9.81 N m. Stepped at 0.25 ms with 500
iterations and every constraint's error corrected in full (``error_bias`` 0), the
mass falls freely instead: after 0.25 s it is 0.30 m below the pivot's circle,
g t^2 / 2, its angle still 0. Sequential impulses pass the pivot's impulse, 1 m
from the centre of mass, to the motor as a turn of 1e12 rad/s per N s, which the
motor takes back; the two never agree. With a moment of 1e-6 or 1e-3 kg m^2 the
state blows up; with a rod's (1/12 kg m^2) the mass stays put; without the
motor the pendulum swings on its pivot (held to 2e-7 m). xcheck's point masses
get 1e-12 m size^2 (pymunk needs a moment above 0), and its pymunk reactions
drive every input by a motor: on IFToMM's pendulum held still, the scene comes
apart.

Run: ``python pymunk_point_mass_motor.py``. Prints the mass's fall beside the
expected (none); exits 0 while the defect shows (a fall over 0.1 m with the point
mass and a hold within 1e-12 m with the rod's moment), 1 once it no longer does.
"""

import sys

import numpy as np
import pymunk as pm

STEP, STEPS = 2.5e-4, 1000


def fall(moment: float, motor: bool = True) -> float:
    """After STEPS steps, how far (m) the mass has moved from where the motor holds it, or
    without the motor how far it is off the pivot's 1 m circle."""
    space = pm.Space()
    space.gravity = (0.0, -9.81)
    space.iterations = 500
    body = pm.Body(1.0, moment)
    body.position = (-1.0, 0.0)
    space.add(body)
    pivot = pm.PivotJoint(space.static_body, body, (0.0, 0.0))
    pivot.error_bias = 0.0
    space.add(pivot)
    if motor:
        hold = pm.SimpleMotor(space.static_body, body, 0.0)
        hold.error_bias = 0.0
        space.add(hold)
    for _ in range(STEPS):
        space.step(STEP)
    if motor:
        return float(np.hypot(body.position[0] + 1.0, body.position[1]))
    return abs(float(np.hypot(*body.position)) - 1.0)


def main() -> int:
    print(f"pymunk {pm.version} (Chipmunk {pm.chipmunk_version}): 1 kg held 1 m from a pivot by a motor, 0.25 s")
    falls = {}
    for moment in (1e-12, 1e-6, 1e-3, 1.0 / 12.0):
        falls[moment] = fall(moment)
        print(f"moment {moment:.3g} kg m^2: measured {falls[moment]:.3g} m from where it is held, expected 0")
    swing = fall(1e-12, motor=False)
    print(f"moment 1e-12 kg m^2, no motor (a free pendulum): measured {swing:.3g} m off the pivot's circle, expected 0")
    shown = falls[1e-12] > 0.1 and falls[1.0 / 12.0] < 1e-12
    print("defect shown" if shown else "defect not shown: the pivot holds the point mass")
    return 0 if shown else 1


if __name__ == "__main__":
    sys.exit(main())
