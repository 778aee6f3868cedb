"""OpenSim: Model.assemble moves an assembled slider-crank to its other branch, 60 m away.

An offset slider-crank near its dead centre (crank 418.605 m about O = (0, 0),
rod 656.915 m, the slider's line 238.309 m above O: the rod only just reaches
it), three 1 kg bodies, two PinJoints and a SliderJoint along x, its loop closed
by a PointOnLineConstraint along z between the rod's end and the slider. The
crank's coordinate is prescribed by a constant; the rod's and the slider's
coordinates are set to the exact pose on the branch whose slider lies right of
the crank's pin (closed to round-off), and ``Model.assemble`` is called
(``updateAssemblyConditions`` first). The state is already assembled: it should
stay where it is. Measured with opensim 4.6: built with its coordinates' default
values at that pose, it stays; built with the defaults at the pose of crank
angle 2.4943 rad (where xcheck builds the model), the assembler moves it to the
other branch at crank 4.7702 and 4.7802 rad (the slider 60.6 and 71.1 m away,
the loop closed there too), not at 4.7642 or 4.7932 rad.

Run: ``python opensim_assembler_other_branch.py``. Prints where the slider lands
beside where it started; exits 0 while the defect shows, 1 once it no longer does.
"""

import math
import sys

import opensim as osim

CRANK, ROD, OFFSET = 418.6052631744128, 656.9152329087625, 238.30922419513954
#: the crank angle (rad) whose pose the far-built model's defaults hold
FAR = 2.49430475
ANGLES = (4.7642, 4.7702, 4.7802, 4.7932)


def pose(theta: float, branch: float = 1.0) -> tuple[float, float]:
    """The slider's x (m) and the rod's angle (rad) at crank angle ``theta`` on a branch (+1: slider right)."""
    ax, ay = CRANK * math.cos(theta), CRANK * math.sin(theta)
    x = ax + branch * math.sqrt(ROD**2 - (OFFSET - ay) ** 2)
    return x, math.atan2(OFFSET - ay, x - ax)


def rod(name: str, length: float) -> osim.Body:
    inertia = length**2 / 12.0
    return osim.Body(name, 1.0, osim.Vec3(length / 2, 0, 0), osim.Inertia(inertia, inertia, inertia, 0, 0, 0))


def assembled(theta: float, built_at: float) -> float:
    """Where the slider (x, m) lands when the exact pose at crank ``theta`` is assembled in a model
    whose default coordinate values are the pose at ``built_at``."""
    osim.Logger.setLevel(osim.Logger.Level_Off)
    model = osim.Model()
    crank, link = rod("crank", CRANK), rod("rod", ROD)
    slider = osim.Body("slider", 1.0, osim.Vec3(0), osim.Inertia(1, 1, 1, 0, 0, 0))
    for body in (crank, link, slider):
        model.addBody(body)
    ground, zero = model.getGround(), osim.Vec3(0)
    joints = [
        osim.PinJoint("O", ground, zero, zero, crank, zero, zero),
        osim.PinJoint("A", crank, osim.Vec3(CRANK, 0, 0), zero, link, zero, zero),
        osim.SliderJoint("slide", ground, osim.Vec3(0, OFFSET, 0), zero, slider, zero, zero),
    ]
    x0, phi0 = pose(built_at)
    for joint, value in zip(joints, (built_at, phi0 - built_at, x0)):
        model.addJoint(joint)
        joint.upd_coordinates(0).setDefaultValue(value)
    model.addConstraint(osim.PointOnLineConstraint(link, osim.Vec3(0, 0, 1), osim.Vec3(ROD, 0, 0), slider, zero))
    driven = joints[0].upd_coordinates(0)
    driven.set_prescribed(True)
    driven.setPrescribedFunction(osim.Constant(theta))
    state = model.initSystem()
    x, phi = pose(theta)
    joints[1].getCoordinate().setValue(state, phi - theta, False)
    joints[2].getCoordinate().setValue(state, x, False)
    model.updateAssemblyConditions(state)
    model.assemble(state)
    return joints[2].getCoordinate().getValue(state)


if __name__ == "__main__":
    from importlib.metadata import version

    print(f"opensim {version('opensim')}: an assembled slider-crank near its dead centre, assembled again")
    moved = {}
    for theta in ANGLES:
        start, other = pose(theta)[0], pose(theta, -1.0)[0]
        near, far = assembled(theta, theta), assembled(theta, FAR)
        moved[theta] = abs(far - start)
        print(f"  crank {theta} rad: expected the slider to stay at x = {start:.6g} m (other branch: {other:.6g} m)")
        print(f"    measured: defaults at this pose {near:.6g} m; defaults at crank {FAR} rad {far:.6g} m")
    shown = any(distance > 1.0 for distance in moved.values())
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
