"""MuJoCo's inverse dynamics of a prescribed motion: joint reactions and input efforts.

At each state the kinematics are MuJoCo's own (the kinematic oracle: Newton
projection on the connect rows, velocities, accelerations with mj_jacDot
drift). Then, on a copy of the model with constraints disabled (so that
MuJoCo's soft-constraint model does not enter):

* ``mj_rne`` gives the generalised force M qacc + c(q, qvel) (gravity
  included) that the motion needs;
* the applied loads' generalised force comes from ``mj_applyFT``;
* the unknowns are the force of each loop cut (2 components, at the cut's
  two sites, Jacobians from ``mj_jacSite``; a prismatic cut's weld also a
  moment) and the input joints' forces: [J_cut^T  S^T] [f; tau] = rne - loads,
  square (tree dofs, carriers' slides included = the cuts' rows + inputs);
* the carriers of pin-in-slot and prismatic cuts are given zero mass and the
  bodies they took their mass from get the model's mass properties back (the
  equalities are disabled, so nothing needs the carriers' mass here): the
  carrier transmits the cut force to the line's body through its slide;
* with the cut forces and loads as ``xfrc_applied``, ``mj_rnePostConstraint``
  gives ``cfrc_int``, the force each body's parent transmits through its
  joint(s): the tree joints' reactions and a prismatic joint's couple.

The MJCF writer's input joints have ``qpos`` equal to the driven quantity, so
``tau`` is the driver's effort directly.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from xcheck.dynamics import Forces, applied_loads, determined_states
from xcheck.joints import LineJoint
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND, PinInSlot, Prismatic, Revolute

from .mjcf import Layout, carrier_name, joint_coordinates, mass_properties, weld_site
from .oracle import Oracle

__all__ = ["inverse_forces"]


def _cross(u, v) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def inverse_forces(
    kinematics: Kinematics,
    model: mujoco.MjModel,
    lay: Layout,
    branch: str | None = None,
    samples: int | None = None,
    solution=None,
) -> Forces:
    """Reactions and efforts from MuJoCo over the native states ``solution``
    (default: :func:`~xcheck.dynamics.window_states` with ``samples`` states).

    Raises
    ------
    ValueError
        If a state does not close MuJoCo's loops or is not determined.
    """
    mech = kinematics.mechanism
    solution = determined_states(kinematics, branch, samples, solution)
    oracle = Oracle(model, mech, lay)
    inputs, rates, accelerations = solution.inputs, solution.input_rates, solution.input_accelerations
    start = joint_coordinates(mech, lay, solution.q[0])
    projection = oracle.project(start, inputs[0], inputs)
    if projection.stopped is not None:
        raise ValueError(f"MuJoCo's continuation left the assembly branch: it {projection.reason}")
    if not projection.converged.all():
        i = int(np.argmin(projection.converged))
        raise ValueError(
            f"MuJoCo's Newton projection did not close the loops at sample {i} "
            f"(violation {projection.residual[i]:.3g} m)"
        )

    dyn = copy.deepcopy(model)
    dyn.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    dyn.tendon_stiffness[:], dyn.tendon_damping[:] = 0.0, 0.0  # the springs enter as applied loads (below)
    for name, props in mass_properties(mech).items():  # the model's, not the file's carrier split
        body = dyn.body(name).id
        dyn.body_mass[body], dyn.body_inertia[body] = props.mass, props.inertia
        dyn.body_ipos[body], dyn.body_iquat[body] = [*props.com, 0.0], [1.0, 0.0, 0.0, 0.0]
    data = mujoco.MjData(dyn)
    nv, n = dyn.nv, inputs.shape[0]
    cuts = lay.topology.cuts
    cut_sites = []  # per cut: (site on body_a's side, site on body_b, with a moment?)
    for c in cuts:
        if isinstance(c, Revolute):
            cut_sites.append((dyn.site(f"{c.body_a}.{c.point_a}").id, dyn.site(f"{c.body_b}.{c.point_b}").id, False))
            continue
        carrier = dyn.body(carrier_name(c)).id
        dyn.body_mass[carrier], dyn.body_inertia[carrier] = 0.0, 0.0
        other = f"{c.body_b}.{c.point}" if isinstance(c, PinInSlot) else weld_site(c)
        cut_sites.append((dyn.site(carrier_name(c)).id, dyn.site(other).id, isinstance(c, Prismatic)))
    carriers = any(not isinstance(c, Revolute) for c in cuts)
    unknowns = sum(3 if moment else 2 for _, _, moment in cut_sites)
    loads = [(load, dyn.body(load.body).id) for load in applied_loads(solution)]  # springs' pulls included
    body_ids = {b.name: dyn.body(b.name).id for b in mech.moving_bodies}
    joints, drivers = {}, {d.name: {"effort": np.full(n, np.nan)} for d in mech.drivers}
    for joint in mech.joints:
        joints[joint.name] = {q: np.full((n, 2) if q == "reaction" else n, np.nan) for q in joint.quantities}
    driven = {d.joint: k for k, d in enumerate(mech.drivers)}
    residual = np.zeros(n)
    jacp_a, jacp_b, jacr_a, jacr_b = (np.zeros((3, nv)) for _ in range(4))
    rne = np.zeros(nv)
    for i in range(n):
        qpos = projection.qpos[i]
        qvel = oracle.velocity(qpos, rates[i])
        qacc = oracle.acceleration(qpos, qvel, accelerations[i])
        data.qpos[:], data.qvel[:] = qpos, qvel
        data.xfrc_applied[:] = 0.0
        if carriers:  # positions and com quantities only: a massless carrier makes M singular (not needed here)
            mujoco.mj_kinematics(dyn, data)
            mujoco.mj_comPos(dyn, data)
            mujoco.mj_comVel(dyn, data)
        else:
            mujoco.mj_fwdPosition(dyn, data)
            mujoco.mj_fwdVelocity(dyn, data)
        data.qacc[:] = qacc
        mujoco.mj_rne(dyn, data, 1, rne)
        applied = np.zeros(nv)
        load_wrenches = []
        for load, body in loads:
            at = data.xpos[body] + data.xmat[body].reshape(3, 3) @ np.array([*load.point, 0.0])
            force, torque = np.array([*load.force[i], 0.0]), np.array([0.0, 0.0, load.torque[i]])
            mujoco.mj_applyFT(dyn, data, force, torque, at, body, applied)
            load_wrenches.append((body, force, torque, at))
        columns = []
        for site_a, site_b, moment in cut_sites:
            mujoco.mj_jacSite(dyn, data, jacp_a, jacr_a, site_a)
            mujoco.mj_jacSite(dyn, data, jacp_b, jacr_b, site_b)
            columns.append((jacp_a[:2] - jacp_b[:2]).T)  # force on site a's body; its opposite on b's
            if moment:  # a couple on site a's body; its opposite on b's
                columns.append((jacr_a[2:] - jacr_b[2:]).T)
        columns.append(oracle.selector.T)
        matrix = np.hstack(columns)
        rhs = rne - applied
        x = np.linalg.solve(matrix, rhs)
        residual[i] = np.linalg.norm(matrix @ x - rhs) / max(float(np.linalg.norm(rhs)), 1e-300)
        tau = x[unknowns:]
        for k, d in enumerate(mech.drivers):
            drivers[d.name]["effort"][i] = tau[k]

        # the cut forces and the loads as Cartesian forces at the bodies' centres of mass
        for body, force, torque, at in load_wrenches:
            data.xfrc_applied[body, :3] += force
            data.xfrc_applied[body, 3:] += torque + np.cross(at - data.xipos[body], force)
        offset = 0
        for cut, (site_a, site_b, has_moment) in zip(cuts, cut_sites):
            f = np.array([x[offset], x[offset + 1], 0.0])
            couple = np.array([0.0, 0.0, x[offset + 2] if has_moment else 0.0])
            offset += 3 if has_moment else 2
            for site, sign in ((site_a, 1.0), (site_b, -1.0)):
                body = dyn.site_bodyid[site]
                if body == 0:
                    continue
                data.xfrc_applied[body, :3] += sign * f
                arm = data.site_xpos[site] - data.xipos[body]
                data.xfrc_applied[body, 3:] += np.cross(arm, sign * f) + sign * couple
            out = joints[cut.name]
            out["reaction"][i] = -f[:2]  # f acts on body_a (through the carrier): body_a on body_b is -f
            if isinstance(cut, LineJoint):
                u = rotate(_angle(data, body_ids, cut.body_a), cut.direction)
                out["normal"][i] = -f[:2] @ np.array([-u[1], u[0]])
                if has_moment:  # about the sliding point, where both sites are
                    out["moment"][i] = -couple[2]
        mujoco.mj_rnePostConstraint(dyn, data)

        for tj in lay.topology.tree:
            joint, child = tj.joint, tj.child
            body = body_ids[child]
            wrench = data.cfrc_int[body]  # [torque, force] about the subtree's centre of mass, world axes
            reference = data.subtree_com[dyn.body_rootid[body]]
            force = wrench[3:5].copy()
            sign = -1.0 if tj.reversed else 1.0  # cfrc_int: parent on child; we want body_a on body_b
            out = joints[joint.name]
            if isinstance(joint, Revolute):
                out["reaction"][i] = sign * force
                continue
            assert isinstance(joint, LineJoint)
            at = _site_position(dyn, data, joint.body_b, joint.point)
            moment = wrench[2] + _cross(reference[:2] - at, force)
            force_ab, moment_ab = sign * force, sign * moment
            u = rotate(_angle(data, body_ids, joint.body_a), joint.direction)
            normal = np.array([-u[1], u[0]])
            if joint.name in driven:
                force_ab = force_ab - tau[driven[joint.name]] * u
            out["reaction"][i] = force_ab
            out["normal"][i] = force_ab @ normal
            if isinstance(joint, Prismatic):
                out["moment"][i] = moment_ab
    return Forces(
        "mujoco",
        inputs,
        rates,
        accelerations,
        joints,
        drivers,
        diagnostics={"residual": residual, "constraint_violation": projection.residual},
        settings={"states": n, "gravity": [float(g) for g in dyn.opt.gravity]},
        notes="MuJoCo's kinematic oracle at each native state, then mj_rne (M qacc + bias, gravity "
        "included) on the model with constraints disabled; loop-cut forces and input efforts "
        "from [J_cut^T S^T] x = rne - loads (mj_jacSite, mj_applyFT); tree joints' reactions "
        "from cfrc_int (mj_rnePostConstraint with the cut forces and loads as xfrc_applied).",
    )


def _angle(data: mujoco.MjData, body_ids: dict, body: str) -> float:
    if body == GROUND:
        return 0.0
    xmat = data.xmat[body_ids[body]]
    return float(np.arctan2(xmat[3], xmat[0]))


def _site_position(model: mujoco.MjModel, data: mujoco.MjData, body: str, label: str) -> np.ndarray:
    return data.site_xpos[model.site(f"{body}.{label}").id][:2].copy()
