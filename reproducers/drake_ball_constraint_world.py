"""pydrake: a ball constraint between the world body and a body crashes the process.

A four-bar made of two links hung from the world by revolute joints (crank
0.1 m about O, coupler 0.3 m) whose coupler tip is held to the world point
(0.2, 0.22) by ``MultibodyPlant.AddBallConstraint`` (the four-bar's rocker
replaced by a fixed point). Stepped by the discrete SAP solver (the only one
that takes ball constraints), the run should advance and keep the tip on the
point. Measured with pydrake 1.51.1: the process dies with a segmentation fault
in the first step, with the world body as either the first or the second body
of the constraint; the same mechanism with the point on a body welded to the
world runs (the tip stays within 1e-6 m of it).

Run: ``python drake_ball_constraint_world.py``. Prints the measured outcome of
each variant beside the expected one; exits 0 while the defect shows, 1 once it
no longer does.
"""

import subprocess
import sys

import numpy as np


def run(variant: str) -> None:
    """Build the four-bar with the ball constraint on ``variant``'s body pair and step it 0.1 s."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import FixedOffsetFrame, RevoluteJoint, SpatialInertia, UnitInertia, WeldJoint
    from pydrake.systems.analysis import Simulator

    plant = MultibodyPlant(time_step=1e-3)
    world = plant.world_body()

    def rod(name: str, length: float):
        inertia = SpatialInertia(1.0, np.zeros(3), UnitInertia.ThinRod(length, [1.0, 0.0, 0.0]))
        return plant.AddRigidBody(name, inertia)

    crank, coupler = rod("crank", 0.1), rod("coupler", 0.3)  # each body's frame at its first end
    plant.AddJoint(RevoluteJoint("O", world.body_frame(), crank.body_frame(), [0.0, 0.0, 1.0]))
    hinge = plant.AddFrame(FixedOffsetFrame("A", crank.body_frame(), RigidTransform([0.1, 0.0, 0.0])))
    plant.AddJoint(RevoluteJoint("A", hinge, coupler.body_frame(), [0.0, 0.0, 1.0]))
    point = np.array([0.2, 0.22, 0.0])
    if variant == "welded":
        anchor = plant.AddRigidBody("anchor", SpatialInertia.SolidSphereWithMass(1.0, 1.0))
        plant.AddJoint(WeldJoint("anchor", world.body_frame(), anchor.body_frame(), RigidTransform()))
        plant.AddBallConstraint(coupler, [0.3, 0.0, 0.0], anchor, point)
    elif variant == "world second":
        plant.AddBallConstraint(coupler, [0.3, 0.0, 0.0], world, point)
    else:
        plant.AddBallConstraint(world, point, coupler, [0.3, 0.0, 0.0])
    plant.mutable_gravity_field().set_gravity_vector([0.0, -9.81, 0.0])
    plant.Finalize()
    context = plant.CreateDefaultContext()
    # the assembled pose: crank at 60 deg, the coupler's tip on the point
    crank_angle = np.radians(60.0)
    a = 0.1 * np.array([np.cos(crank_angle), np.sin(crank_angle)])
    gap = point[:2] - a
    plant.GetJointByName("O").set_angle(context, crank_angle)
    plant.GetJointByName("A").set_angle(context, np.arctan2(gap[1], gap[0]) - crank_angle)
    simulator = Simulator(plant, context)
    simulator.AdvanceTo(0.1)
    tip = plant.EvalBodyPoseInWorld(simulator.get_context(), coupler).multiply([0.3, 0.0, 0.0])
    print(f"ran to 0.1 s, the tip {np.linalg.norm(tip - point):.3g} m from the point")


VARIANTS = ("welded", "world first", "world second")

if __name__ == "__main__":
    if len(sys.argv) > 1:
        run(sys.argv[1])
        sys.exit(0)
    from importlib.metadata import version

    print(f"pydrake {version('drake')}: a ball constraint holding a four-bar's coupler tip to a fixed point")
    crashed = {}
    for variant in VARIANTS:
        child = subprocess.run([sys.executable, __file__, variant], capture_output=True, text=True, timeout=300)
        outcome = child.stdout.strip() or f"process died (exit status {child.returncode})"
        crashed[variant] = child.returncode != 0
        print(f"  {variant:13s} expected: runs, tip within 1e-6 m   measured: {outcome}")
    shown = not crashed["welded"] and (crashed["world first"] or crashed["world second"])
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
