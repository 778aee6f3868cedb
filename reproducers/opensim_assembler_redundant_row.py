"""OpenSim: with a prescribed coordinate, Model.assemble leaves a loop closed by a PointConstraint open, silently.

A planar four-bar (ground pivots O = (0, 0) and Q = (0.2, 0) m, crank 0.1 m,
coupler 0.3 m, rocker 0.22 m, uniform 1 kg rods) of three PinJoints about z, its
loop closed between the coupler's and the rocker's ends, built assembled at a
crank angle of 45 deg. The crank's coordinate is prescribed as 45 deg + t
(LinearFunction), and at t = 0.1, 0.3, 0.5, 1.0 s the model is assembled
(``updateAssemblyConditions``, ``assemble``). A mechanism of one degree of
freedom with its only free coordinate prescribed has one pose, which the
assembler should find or refuse with an error. Measured with opensim 4.6:
with the loop closed by a ``PointConstraint`` (three rows, the z row redundant
in a planar model) ``assemble`` returns without an error and the loop stays open
by centimetres to decimetres; closed by a ``PointOnLineConstraint`` along z (the
same two planar rows, none redundant) the loop closes to round-off at every t.

Run: ``python opensim_assembler_redundant_row.py``. Prints the loop's gap after
each assembly beside the expected one; exits 0 while the defect shows, 1 once it
no longer does.
"""

import math
import sys

import numpy as np
import opensim as osim

O, Q = np.array([0.0, 0.0]), np.array([0.2, 0.0])
CRANK, COUPLER, ROCKER = 0.1, 0.3, 0.22
START = math.radians(45.0)
TIMES = (0.1, 0.3, 0.5, 1.0)
#: the gap (m) an assembly that closes the loop leaves at most
CLOSED = 1e-8


def assembled(theta: float) -> tuple[float, float]:
    """The coupler's and the rocker's angles (rad) of the four-bar at crank angle ``theta``, upper branch."""
    a = O + CRANK * np.array([math.cos(theta), math.sin(theta)])
    d = Q - a
    distance = float(np.hypot(*d))
    along = (COUPLER**2 - ROCKER**2 + distance**2) / (2 * distance)
    b = a + along * d / distance + math.sqrt(COUPLER**2 - along**2) * np.array([-d[1], d[0]]) / distance
    return math.atan2(b[1] - a[1], b[0] - a[0]), math.atan2(b[1] - Q[1], b[0] - Q[0])


def rod(name: str, length: float) -> osim.Body:
    inertia = length**2 / 12.0
    return osim.Body(name, 1.0, osim.Vec3(length / 2, 0, 0), osim.Inertia(inertia, inertia, inertia, 0, 0, 0))


def gaps(planar: bool) -> list[float]:
    """The loop's gap (m) after assembling at each of :data:`TIMES`."""
    osim.Logger.setLevel(osim.Logger.Level_Off)
    model = osim.Model()
    crank, coupler, rocker = rod("crank", CRANK), rod("coupler", COUPLER), rod("rocker", ROCKER)
    for body in (crank, coupler, rocker):
        model.addBody(body)
    ground = model.getGround()
    zero = osim.Vec3(0)
    joints = [
        osim.PinJoint("O", ground, zero, zero, crank, zero, zero),
        osim.PinJoint("A", crank, osim.Vec3(CRANK, 0, 0), zero, coupler, zero, zero),
        osim.PinJoint("Q", ground, osim.Vec3(Q[0], Q[1], 0), zero, rocker, zero, zero),
    ]
    coupler_angle, rocker_angle = assembled(START)
    for joint, value in zip(joints, (START, coupler_angle - START, rocker_angle)):
        model.addJoint(joint)
        joint.upd_coordinates(0).setDefaultValue(value)
    end_b, end_r = osim.Vec3(COUPLER, 0, 0), osim.Vec3(ROCKER, 0, 0)
    if planar:
        loop = osim.PointOnLineConstraint(coupler, osim.Vec3(0, 0, 1), end_b, rocker, end_r)
    else:
        loop = osim.PointConstraint(coupler, end_b, rocker, end_r)
    model.addConstraint(loop)
    driven = joints[0].upd_coordinates(0)
    driven.set_prescribed(True)
    driven.setPrescribedFunction(osim.LinearFunction(1.0, START))
    state = model.initSystem()
    out = []
    for t in TIMES:
        state.setTime(t)
        model.updateAssemblyConditions(state)
        model.assemble(state)
        model.realizePosition(state)
        b = coupler.findStationLocationInGround(state, end_b)
        r = rocker.findStationLocationInGround(state, end_r)
        out.append(math.hypot(b.get(0) - r.get(0), b.get(1) - r.get(1)))
    return out


if __name__ == "__main__":
    from importlib.metadata import version

    print(f"opensim {version('opensim')}: a four-bar's crank prescribed as 45 deg + t, assembled at t = {TIMES} s")
    point, line = gaps(planar=False), gaps(planar=True)
    shown_values = ", ".join(f"{g:.2g}" for g in point)
    print(f"  PointConstraint:            expected: the loop's gap below {CLOSED:g} m, or an error")
    print(f"                              measured: gaps {shown_values} m, no error")
    print(f"  PointOnLineConstraint (z):  expected: the loop's gap below {CLOSED:g} m")
    print(f"                              measured: gaps {', '.join(f'{g:.2g}' for g in line)} m")
    shown = max(point) > 1e3 * CLOSED and max(line) < CLOSED
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
