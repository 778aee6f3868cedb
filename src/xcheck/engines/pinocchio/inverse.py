"""Pinocchio's inverse dynamics of a prescribed motion: joint reactions and
input efforts from RNEA on the tree with the loop-closure forces.

At each state the kinematics are Pinocchio's own (the oracle: Newton
projection onto the loops from the native configuration, velocities, and
accelerations with the drift of the frames' classical accelerations). Then:

* ``rnea(q, v, a, fext)`` with the applied loads as external forces gives the
  generalised force the motion needs (gravity in the model's ``gravity``);
* it equals J_cut^T f + S^T e: the loop cuts' forces f (x and y rows of the
  loop Jacobian, force on the cut's first anchor, its opposite on the second;
  a prismatic cut's CONTACT_6D also a couple, its rotation z row) and the
  drivers' efforts e (S: the signed input selector), a square system. The
  first anchor of a pin-in-slot or prismatic cut is its massless carrier, which
  passes the force on to the line's body;
* ``rnea`` again with the cut forces added to ``fext``: ``data.f[j]`` is the
  spatial force joint j transmits from its parent to its subtree: the tree
  joints' reactions and a prismatic joint's couple.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from xcheck.dynamics import Forces, applied_loads, determined_states
from xcheck.joints import LineJoint, Revolute, converter
from xcheck.kinematics import Kinematics
from xcheck.model import GROUND

from .model import build_model, joint_coordinates, point_frame, tree_spec
from .oracle import Oracle

__all__ = ["inverse_forces"]


def _force(linear_xy, point_xy, torque: float = 0.0) -> pin.Force:
    """A planar force at a world point as a spatial force about the world origin."""
    linear = np.array([linear_xy[0], linear_xy[1], 0.0])
    moment = point_xy[0] * linear_xy[1] - point_xy[1] * linear_xy[0] + torque
    return pin.Force(linear, np.array([0.0, 0.0, moment]))


def inverse_forces(
    kinematics: Kinematics, branch: str | None = None, samples: int | None = None, solution=None
) -> Forces:
    """Reactions and efforts from Pinocchio over the native states ``solution``
    (default: :func:`~xcheck.dynamics.window_states` with ``samples`` states).

    Raises
    ------
    ValueError
        If a state does not close Pinocchio's loops or is not determined.
    """
    mech = kinematics.mechanism
    solution = determined_states(kinematics, branch, samples, solution)
    pm = build_model(tree_spec(mech, carrier_mass=False))  # the cut force acts on the line body directly
    model = pm.model
    oracle = Oracle(pm)
    data = model.createData()
    size = kinematics.system.size
    inputs, rates, accelerations = solution.inputs, solution.input_rates, solution.input_accelerations
    n, nv = inputs.shape[0], model.nv
    selector = pm.input_selector()
    cuts = pm.spec.cuts
    # per cut: its rows of the loop Jacobian that carry unknowns (x, y; a CONTACT_6D's rotation z too)
    rows = [[start, start + 1] + ([start + 5] if n == 6 else []) for start, n in pm.constraint_rows()]
    offsets = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(int)
    unknowns = int(offsets[-1])
    # per tree joint: the Pinocchio joint nearest the child (a pin-in-slot's second one) and its bodies
    last = {}
    for js in pm.spec.joints:
        last[js.tree_joint] = js
    tree = {name: (model.getJointId(js.name), js.bodies) for name, js in last.items()}
    body_joint = {name: model.frames[fid].parentJoint for name, fid in pm.body_frames.items()}
    point_ids = pm.point_frames

    joints = {j.name: {q: np.full((n, 2) if q == "reaction" else n, np.nan) for q in j.quantities} for j in mech.joints}
    drivers = {d.name: {"effort": np.full(n, np.nan)} for d in mech.drivers}
    driven = {d.joint: k for k, d in enumerate(mech.drivers)}
    residual, closure = np.zeros(n), np.zeros(n)
    loads = applied_loads(solution)  # the file's loads and the springs' pulls, per state
    for i in range(n):
        q, loop, _, converged = oracle.project(joint_coordinates(pm, solution.q[i]), inputs[i], size)
        if not converged:
            raise ValueError(
                f"Pinocchio's Newton projection did not close the loops at sample {i} (violation {loop:.3g} m)"
            )
        closure[i] = loop
        v = oracle.rates(q, rates[i])
        a = oracle.acceleration(q, v, accelerations[i])
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)

        def external(forces_world):
            """Per-joint external forces (local frames) from (joint id, world spatial force) pairs."""
            fext = pin.StdVec_Force()
            for _ in range(model.njoints):
                fext.append(pin.Force.Zero())
            for jid, f in forces_world:
                fext[jid] = fext[jid] + data.oMi[jid].actInv(f)
            return fext

        applied = []
        for load in loads:
            frame = data.oMf[pm.body_frames[load.body]]
            at = frame.act(np.array([*load.point, 0.0]))[:2]
            applied.append((body_joint[load.body], _force(load.force[i], at, load.torque[i])))
        tau = pin.rnea(model, data, q, v, a, external(applied)).copy()
        oracle.loop_residual(q)
        loop_jacobian = oracle.loop_jacobian(q)
        columns = [loop_jacobian[rows[c]].T for c in range(len(cuts))] + [selector.T]
        matrix = np.hstack(columns) if columns else np.zeros((nv, 0))
        x = np.linalg.solve(matrix, tau)
        efforts = x[unknowns:]
        for k, d in enumerate(mech.drivers):
            drivers[d.name]["effort"][i] = efforts[k]

        cut_forces = []
        for c, cut in enumerate(cuts):
            f = x[offsets[c] : offsets[c] + 2]
            couple = x[offsets[c] + 2] if cut.locked_angle is not None else 0.0
            out = joints[cut.name]
            out["reaction"][i] = -f  # f acts on body_a: body_a on body_b is -f
            found = converter(_CUT_FORCES, cut, "Pinocchio")(cut, f, couple, pm, data, point_ids, body_joint, c)
            cut_forces += found[0]
            for quantity, value in found[1].items():
                out[quantity][i] = value
        remaining = pin.rnea(model, data, q, v, a, external(applied + cut_forces))
        residual[i] = np.linalg.norm(remaining - selector.T @ efforts) / max(float(np.linalg.norm(tau)), 1e-300)

        for joint in mech.joints:
            if joint.name not in tree:
                continue
            jid, (parent, _) = tree[joint.name]
            world = data.oMi[jid].act(data.f[jid])  # parent on the subtree, about the world origin
            sign = 1.0 if parent == joint.body_a else -1.0
            force = sign * world.linear[:2]
            effort = efforts[driven[joint.name]] if joint.name in driven else 0.0
            read = converter(_TREE_REACTIONS, joint, "Pinocchio")
            for quantity, value in read(joint, force, sign * world.angular[2], effort, pm, data, point_ids).items():
                joints[joint.name][quantity][i] = value
    return Forces(
        "pinocchio",
        inputs,
        rates,
        accelerations,
        joints,
        drivers,
        diagnostics={"residual": residual, "constraint_violation": closure},
        settings={"states": n, "gravity": [float(g) for g in model.gravity.linear]},
        notes="Pinocchio's kinematic oracle at each native state, then rnea (gravity and the applied "
        "loads as external forces); loop-cut forces and input efforts from [J_cut^T S^T] x = rnea; "
        "tree joints' reactions from data.f of a second rnea with the cut forces added.",
    )


def _pin_cut(cut, f, couple, pm, data, point_ids, body_joint, c) -> tuple[list, dict]:
    """A loop cut at a revolute: f on body_a's point, -f on body_b's (as external forces)."""
    forces = []
    for (body, label), sign in zip(cut.anchors(), (1.0, -1.0)):
        if body != GROUND:
            at = data.oMf[point_ids[point_frame(body, label)]].translation[:2]
            forces.append((body_joint[body], _force(sign * f, at)))
    return forces, {}


def _carrier_cut(cut, f, couple, pm, data, point_ids, body_joint, c) -> tuple[list, dict]:
    """A loop cut at a line joint: anchor 1 on the carrier, anchor 2 on body_b, both at the sliding point;
    its normal force and, welded (prismatic), its couple about the sliding point."""
    cm, forces = pm.constraints[c], []
    for jid, placement, sign in ((cm.joint1_id, cm.joint1_placement, 1.0), (cm.joint2_id, cm.joint2_placement, -1.0)):
        if jid != 0:
            at = (data.oMi[jid] * placement).translation[:2]
            forces.append((jid, _force(sign * f, at, sign * couple)))
    u = _line_direction(cut, pm, data)
    found = {"normal": -f @ np.array([-u[1], u[0]])}
    return forces, found | ({"moment": -couple} if cut.locked_angle is not None else {})


#: a loop cut's forces (external forces on the bodies) and its reactions besides the force, by its type
_CUT_FORCES: dict[type, Callable] = {Revolute: _pin_cut, LineJoint: _carrier_cut}


def _line_direction(joint, pm, data) -> np.ndarray:
    """A line joint's direction in the world, (2,)."""
    line = np.eye(3) if joint.body_a == GROUND else data.oMf[pm.body_frames[joint.body_a]].rotation
    return line[:2, :2] @ joint.direction


def _pin_reaction(joint, force, moment, effort, pm, data, point_ids) -> dict:
    """A tree revolute's reaction: the force its parent transmits (body_a on body_b)."""
    return {"reaction": force}


def _line_reaction(joint, force, moment, effort, pm, data, point_ids) -> dict:
    """A tree line joint's reaction: the force normal to its line (less a driven slide's effort along it) and,
    prismatic, the couple about the sliding point (``moment``: about the world origin)."""
    at = data.oMf[point_ids[point_frame(joint.body_b, joint.point)]].translation[:2]
    moment = moment - (at[0] * force[1] - at[1] * force[0])
    u = _line_direction(joint, pm, data)
    force = force - effort * u
    found = {"reaction": force, "normal": force @ np.array([-u[1], u[0]])}
    return found | ({"moment": moment} if joint.locked_angle is not None else {})


#: a tree joint's reactions from the force and couple its parent transmits, by its type
_TREE_REACTIONS: dict[type, Callable] = {Revolute: _pin_reaction, LineJoint: _line_reaction}
