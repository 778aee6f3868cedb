"""DART: a slider-crank closed by a RevoluteJointConstraint blows up at small time steps.

A slider-crank: crank 0.1 m (0.5 kg) about O (0, 0) turning at 100 rad/s, rod
0.35 m (1 kg), slider (0.8 kg) on a line 0.04 m above O; crank and slider hang
from the world (revolute, prismatic along x), the rod from the crank, and the
rod-slider pin is a ``RevoluteJointConstraint`` in the world's constraint solver
(DART's defaults); no gravity, no actuator. A smaller time step should follow
the motion more closely. Measured with dartpy 6.20: at dt = 1e-4 and 5e-5 s the
crank turns on for 0.01 s; at dt = 4e-5, 1.6e-5 and 1e-5 s the state turns
non-finite after 44, 21 and 19 steps (DART's warnings: "Non-finite relative
transform detected").

Run: ``python dart_small_step_blow_up.py``. Prints, for each step, where the run
turned non-finite beside the expected outcome; exits 0 while the defect shows,
1 once it no longer does.
"""

import math
import sys

import dartpy as dart
import numpy as np

CRANK, ROD, OFFSET = 0.1, 0.35, 0.04


def isometry(x: float, y: float, angle: float = 0.0):
    transform = dart.math.Isometry3()
    c, s = math.cos(angle), math.sin(angle)
    transform.set_rotation(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))
    transform.set_translation([x, y, 0.0])
    return transform


def build(dt: float):
    """The slider-crank at crank angle 0, the crank at 100 rad/s, the rest at the matching rates."""
    world = dart.simulation.World()
    world.setGravity([0.0, 0.0, 0.0])
    world.setTimeStep(dt)
    skeleton = dart.dynamics.Skeleton("slider-crank")
    rise = OFFSET  # B above A by the offset at crank angle 0
    rod_angle = math.asin(rise / ROD)
    b_x = CRANK + ROD * math.cos(rod_angle)

    def body(node, mass: float, length: float) -> None:
        inertia = mass * max(length, 0.05) ** 2 / 12.0
        node.setInertia(dart.dynamics.Inertia(mass, [0.0, 0.0, 0.0], np.eye(3) * inertia))

    crank_props = dart.dynamics.RevoluteJointProperties()
    crank_props.mName, crank_props.mAxis = "O", [0.0, 0.0, 1.0]
    crank_props.mT_ChildBodyToJoint = isometry(-CRANK / 2, 0.0)
    crank_joint, crank = skeleton.createRevoluteJointAndBodyNodePair(
        None, crank_props, dart.dynamics.BodyNodeProperties()
    )
    body(crank, 0.5, CRANK)
    slide_props = dart.dynamics.PrismaticJointProperties()
    slide_props.mName, slide_props.mAxis = "slide", [1.0, 0.0, 0.0]
    slide_props.mT_ParentBodyToJoint = isometry(b_x, OFFSET)
    slide_joint, slider = skeleton.createPrismaticJointAndBodyNodePair(
        None, slide_props, dart.dynamics.BodyNodeProperties()
    )
    body(slider, 0.8, 0.05)
    rod_props = dart.dynamics.RevoluteJointProperties()
    rod_props.mName, rod_props.mAxis = "A", [0.0, 0.0, 1.0]
    rod_props.mT_ParentBodyToJoint = isometry(CRANK / 2, 0.0, rod_angle)
    rod_props.mT_ChildBodyToJoint = isometry(-ROD / 2, 0.0)
    rod_joint, rod = skeleton.createRevoluteJointAndBodyNodePair(crank, rod_props, dart.dynamics.BodyNodeProperties())
    body(rod, 1.0, ROD)
    world.addSkeleton(skeleton)
    # rates: A moves at 100 rad/s x 0.1 m along +y; B slides along x: w_rod ROD cos = -10 (y), v_B = -w_rod ROD sin
    w_rod = -CRANK * 100.0 / (ROD * math.cos(rod_angle))
    v_b = -w_rod * ROD * math.sin(rod_angle)
    crank_joint.setVelocity(0, 100.0)
    slide_joint.setVelocity(0, v_b)
    rod_joint.setVelocity(0, w_rod - 100.0)
    pin = dart.constraint.RevoluteJointConstraint(rod, slider, [b_x, OFFSET, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])
    world.getConstraintSolver().addConstraint(pin)
    return world, skeleton


def run(dt: float, duration: float = 0.01) -> str:
    """ "" if the run stays finite for ``duration`` (s), else when it turned non-finite."""
    world, skeleton = build(dt)
    for n in range(int(round(duration / dt))):
        world.step()
        if not np.all(np.isfinite(skeleton.getPositions())):
            return f"non-finite after {n + 1} steps (t = {(n + 1) * dt:.3g} s)"
    return ""


if __name__ == "__main__":
    from importlib.metadata import version

    print(f"dartpy {version('dartpy')}: a slider-crank closed by a RevoluteJointConstraint, 0.01 s")
    print("  expected: finite at every step, the closer to the motion the smaller the step")
    outcomes = {dt: run(dt) for dt in (1e-4, 5e-5, 4e-5, 1.6e-5, 1e-5)}
    for dt, outcome in outcomes.items():
        print(f"  measured, dt = {dt:g} s: {outcome or 'finite for 0.01 s'}")
    shown = not outcomes[1e-4] and not outcomes[5e-5] and all(outcomes[dt] for dt in (4e-5, 1.6e-5, 1e-5))
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
