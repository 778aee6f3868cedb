"""OpenSim's inverse dynamics of a prescribed motion: joint reactions and driver
efforts from Simbody's constrained acceleration solve.

At each native state the drivers are prescribed (one by time itself, several by the
quadratic in time with the state's input values, rates and accelerations), OpenSim's
assembler and speed projection give the state, and the accelerations are realised with the drivers
free, each pushed by the effort that gives its input's acceleration
(:func:`.kinematic.assembled_states`, from the previous state's coordinates, or
from the state's native configuration where the previous one is far).
Then, all OpenSim's own:

* a tree joint's reaction is ``Joint.calcReactionOnChildExpressedInGround``'s
  force on its child (the opposite where the child is the joint's first body);
* a driven revolute's effort is that reaction's moment about z, the torque
  its actuator applies (signed as the driver's coordinate);
* a loop cut's reaction is from its ``PointOnLineConstraint``'s record values:
  per constrained body the force and moment it exerts on the constraint, the
  opposite of what the constraint applies to it, expressed in the frame of the
  two bodies' nearest common ancestor in the tree (Simbody's constraint
  ancestor), turned into the ground frame.

Not converted (:class:`~xcheck.engines.NotApplicable`): prismatic joints and gear
pairs (their normal forces, moments and tooth forces are not read out), and what
the OpenSim model cannot hold (:func:`.model.refuse`).
"""

from __future__ import annotations

import functools

import numpy as np

from xcheck.dynamics import Forces, determined_states, require_mass_data
from xcheck.engines._contract import NotApplicable
from xcheck.joints import Revolute
from xcheck.kinematics import Kinematics
from xcheck.model import GROUND
from xcheck.topology import spanning_tree

from .kinematic import assembled_states
from .model import component_name, opensim_tree, refuse

__all__ = ["inverse_forces"]


def inverse_forces(
    kinematics: Kinematics, branch: str | None = None, samples: int | None = None, solution=None
) -> Forces:
    """Reactions and efforts from OpenSim over the native states ``solution``
    (default: :func:`~xcheck.dynamics.window_states` with ``samples`` states).

    Raises
    ------
    NotApplicable
        Where a joint is not a revolute, or the model cannot hold the mechanism's forces.
    ValueError
        If a state is not determined, or OpenSim's assembler does not close the loops there.
    """
    mech = kinematics.mechanism
    require_mass_data(mech)
    refuse(mech)
    other = next((j for j in mech.joints if not isinstance(j, Revolute)), None)
    if other is not None:
        raise NotApplicable(
            f"joint {other.name!r} is a {other.kind} joint: xcheck reads OpenSim's reactions of revolutes only"
        )
    solution = determined_states(kinematics, branch, samples, solution)
    inputs, rates, accelerations = solution.inputs, solution.input_rates, solution.input_accelerations
    n = len(inputs)
    q_ref = solution.q[0]
    tree = opensim_tree(mech, q_ref)
    cuts = spanning_tree(mech).cuts  # as the model's constraints loop0, loop1, ... close them
    joints = {j.name: {"reaction": np.zeros((n, 2))} for j in mech.joints}
    drivers = {d.name: {"effort": np.zeros(n)} for d in mech.drivers}
    signs = dict(tree.driver_signs(mech))
    ancestors = [_common_ancestor(tree, joint.body_a, joint.body_b) for joint in cuts]
    names = {b.name: component_name(b.name, k) for k, b in enumerate(mech.moving_bodies)}
    try:
        seeds = functools.partial(_coordinates, mech, tree, solution.q, q_ref)
        walked = assembled_states(mech, q_ref, inputs[0], (inputs, rates, accelerations), (range(n),), seeds)
        for i, om, state, _, _ in walked:
            model = om.model
            joint_set, constraint_set = model.getJointSet(), model.getConstraintSet()
            for k, frames in enumerate(tree.joints):
                spatial = joint_set.get(k).calcReactionOnChildExpressedInGround(state)
                moment, force = spatial.get(0), spatial.get(1)
                on_b = 1.0 if frames.child == mech.joint(frames.name).body_b else -1.0
                joints[frames.name]["reaction"][i] = on_b * np.array([force.get(0), force.get(1)])
                for driver in mech.drivers:
                    if driver.joint == frames.name:
                        drivers[driver.name]["effort"][i] = signs[frames.name] * moment.get(2)
            for k, joint in enumerate(cuts):  # the constraints in the order of the tree's cuts
                record = constraint_set.get(f"loop{k}").getRecordValues(state)
                # the first body's entry: the force it exerts on the constraint, which passes it to body_b
                force = np.array([record.get(0), record.get(1)])
                if ancestors[k] != GROUND:
                    turn = model.getBodySet().get(names[ancestors[k]]).getTransformInGround(state).R()
                    force = np.array([[turn.get(0, 0), turn.get(0, 1)], [turn.get(1, 0), turn.get(1, 1)]]) @ force
                joints[joint.name]["reaction"][i] = force
    except RuntimeError as error:
        raise ValueError(" ".join(str(error).split())) from None
    return Forces(
        "opensim",
        inputs,
        rates,
        accelerations,
        joints,
        drivers,
        settings={"samples": n, "cuts": "PointOnLineConstraint"},
        notes=(
            "OpenSim: each state assembled with the drivers prescribed, speeds projected, accelerations realised "
            "with the drivers pushed by the efforts that give their inputs' accelerations; "
            "tree joints' reactions from Joint.calcReactionOnChildExpressedInGround (a driven revolute's effort "
            "its moment about z), loop cuts' from their PointOnLineConstraints' record values."
        ),
    )


def _coordinates(mech, tree, q: np.ndarray, q_ref: np.ndarray, i: int) -> dict[str, float]:
    """The revolute tree joints' coordinates (rad, 0 at ``q_ref``) at native state ``i``
    of ``q`` (N, 3 per moving body): the child's turn against the parent's since ``q_ref``."""
    index = {b.name: 3 * k + 2 for k, b in enumerate(mech.moving_bodies)}

    def turned(body: str) -> float:
        return 0.0 if body == GROUND else float(q[i, index[body]] - q_ref[index[body]])

    return {joint.name: turned(joint.child) - turned(joint.parent) for joint in tree.joints}


def _common_ancestor(tree, body_a: str, body_b: str) -> str:
    """The nearest body of the tree (``tree.joints``: parents first) that both
    ``body_a`` and ``body_b`` hang from, either of them included; ground at the root."""
    parents = {frames.child: frames.parent for frames in tree.joints}

    def line(body: str) -> list[str]:
        chain = [body]
        while chain[-1] in parents:
            chain.append(parents[chain[-1]])
        return chain

    above_b = set(line(body_b))
    return next((body for body in line(body_a) if body in above_b), GROUND)
