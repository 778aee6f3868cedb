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
from collections.abc import Callable

import mujoco
import numpy as np

from xcheck.dynamics import Forces, applied_loads, determined_states
from xcheck.joints import GearPair, LineJoint, Revolute, converter
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND

from .mjcf import Layout, carrier_name, coupling, joint_coordinates, mass_properties, weld_site
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
    cuts = [converter(_CUTS, cut, "MuJoCo")(cut, dyn, lay) for cut in lay.topology.cuts]
    carriers = any(cut.carrier for cut in cuts)
    unknowns = sum(cut.count for cut in cuts)
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
        columns = [column[:, None] for cut in cuts for column in cut.columns(dyn, data)]
        matrix = np.hstack([*columns, oracle.selector.T])
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
        for cut in cuts:
            values = x[offset : offset + cut.count]
            offset += cut.count
            cut.apply(values, dyn, data)
            for quantity, value in cut.reactions(values, dyn, data, body_ids).items():
                joints[cut.joint.name][quantity][i] = value
        mujoco.mj_rnePostConstraint(dyn, data)

        for tj in lay.topology.tree:
            body = body_ids[tj.child]
            wrench = data.cfrc_int[body]  # [torque, force] about the subtree's centre of mass, world axes
            reference = data.subtree_com[dyn.body_rootid[body]]
            sign = -1.0 if tj.reversed else 1.0  # cfrc_int: parent on child; we want body_a on body_b
            effort = tau[driven[tj.joint.name]] if tj.joint.name in driven else 0.0
            read = converter(_TREE, tj.joint, "MuJoCo")
            for quantity, value in read(tj.joint, sign * wrench, reference, effort, dyn, data, body_ids).items():
                joints[tj.joint.name][quantity][i] = value
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


class _Cut:
    """A loop cut at a revolute: a force at its two points' sites (the base of
    the cuts whose unknowns are a force at two sites)."""

    carrier = False
    moment = False

    def __init__(self, joint, dyn: mujoco.MjModel, lay: Layout):
        self.joint = joint
        self.sites = self._sites(joint, dyn)
        self.count = 3 if self.moment else 2
        self._jac = [(np.zeros((3, dyn.nv)), np.zeros((3, dyn.nv))) for _ in range(2)]

    def _sites(self, joint, dyn: mujoco.MjModel) -> tuple[int, int]:
        a, b = (dyn.site(f"{body}.{label}").id for body, label in joint.anchors())
        return a, b

    def columns(self, dyn: mujoco.MjModel, data: mujoco.MjData) -> list[np.ndarray]:
        """Its unknowns' generalised forces (nv, each): a force on site a's body (its opposite on b's), a couple."""
        for site, (jacp, jacr) in zip(self.sites, self._jac):
            mujoco.mj_jacSite(dyn, data, jacp, jacr, site)
        (jacp_a, jacr_a), (jacp_b, jacr_b) = self._jac
        columns = list((jacp_a[:2] - jacp_b[:2]))
        return columns + [jacr_a[2] - jacr_b[2]] if self.moment else columns

    def apply(self, x: np.ndarray, dyn: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Its solved force and couple as xfrc_applied on the bodies it joins."""
        f = np.array([x[0], x[1], 0.0])
        couple = np.array([0.0, 0.0, x[2] if self.moment else 0.0])
        for site, sign in zip(self.sites, (1.0, -1.0)):
            body = dyn.site_bodyid[site]
            if body == 0:
                continue
            data.xfrc_applied[body, :3] += sign * f
            arm = data.site_xpos[site] - data.xipos[body]
            data.xfrc_applied[body, 3:] += np.cross(arm, sign * f) + sign * couple

    def reactions(self, x: np.ndarray, dyn: mujoco.MjModel, data: mujoco.MjData, body_ids: dict) -> dict:
        return {"reaction": -x[:2]}  # x acts on body_a: body_a on body_b is -x


class _CarrierCut(_Cut):
    """A loop cut at a pin-in-slot or prismatic joint: a force (and, welded to a
    block, a couple) between its carrier, massless here, and the pin or block."""

    carrier = True

    def __init__(self, joint: LineJoint, dyn: mujoco.MjModel, lay: Layout):
        self.moment = joint.locked_angle is not None
        carrier = dyn.body(carrier_name(joint)).id
        dyn.body_mass[carrier], dyn.body_inertia[carrier] = 0.0, 0.0
        super().__init__(joint, dyn, lay)

    def _sites(self, joint, dyn: mujoco.MjModel) -> tuple[int, int]:
        other = weld_site(joint) if self.moment else f"{joint.body_b}.{joint.point}"
        return dyn.site(carrier_name(joint)).id, dyn.site(other).id

    def reactions(self, x: np.ndarray, dyn: mujoco.MjModel, data: mujoco.MjData, body_ids: dict) -> dict:
        out = super().reactions(x, dyn, data, body_ids)  # x acts on body_a through the carrier
        u = rotate(_angle(data, body_ids, self.joint.body_a), self.joint.direction)
        out["normal"] = -x[:2] @ np.array([-u[1], u[0]])
        return out | ({"moment": -x[2]} if self.moment else {})  # about the sliding point, where both sites are


class _Coupling:
    """A gear pair's unknown: its joint equality's force, a generalised force
    on its gears' revolutes (:func:`~xcheck.engines.mujoco.mjcf.coupling`)."""

    carrier = False
    count = 1

    def __init__(self, gear: GearPair, dyn: mujoco.MjModel, lay: Layout):
        self.joint = gear
        self.k, _, self.s_b = coupling(gear, lay)
        self.column = np.zeros(dyn.nv)
        self.column[dyn.joint(gear.pin_b).dofadr[0]] = 1.0
        self.column[dyn.joint(gear.pin_a).dofadr[0]] = -self.k
        self.centres = [dyn.site(f"{body}.{label}").id for body, label in gear._centres()]

    def columns(self, dyn: mujoco.MjModel, data: mujoco.MjData) -> list[np.ndarray]:
        return [self.column]

    def tooth_force(self, x: np.ndarray) -> float:
        """The tooth force (N): x is the row q_b - k q_a's force, a torque s_b x on gear b about its
        centre (relative to the carrier), which the tooth force makes at radius r_b."""
        return float(self.s_b * x[0] / self.joint.radius_b)

    def apply(self, x: np.ndarray, dyn: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Its couples on the gears and the carrier (the coupling's row's coefficients times sigma F)."""
        force = self.tooth_force(x)
        for body, coefficient in zip(self.joint.bodies, self.joint.coefficients()):
            if body != GROUND:
                data.xfrc_applied[dyn.body(body).id, 5] += coefficient * self.joint.sigma * force

    def reactions(self, x: np.ndarray, dyn: mujoco.MjModel, data: mujoco.MjData, body_ids: dict) -> dict:
        force = self.tooth_force(x)
        _, t = self.joint.pitch_point(*(data.site_xpos[site][:2] for site in self.centres))
        return {"tooth_force": force, "reaction": force * t[0]}


#: a loop cut's unknowns, by the cut joint's type
_CUTS: dict[type, type] = {Revolute: _Cut, LineJoint: _CarrierCut, GearPair: _Coupling}


def _pin(joint, wrench, reference, effort, dyn, data, body_ids) -> dict:
    """A tree revolute's reaction: the force its parent transmits (body_a on body_b)."""
    return {"reaction": wrench[3:5].copy()}


def _line(joint, wrench, reference, effort, dyn, data, body_ids) -> dict:
    """A tree line joint's reaction: the force normal to its line (less a driven slide's effort along it)
    and, prismatic, the couple about the sliding point."""
    force = wrench[3:5].copy()
    at = _site_position(dyn, data, joint.body_b, joint.point)
    moment = wrench[2] + _cross(reference[:2] - at, force)
    u = rotate(_angle(data, body_ids, joint.body_a), joint.direction)
    force = force - effort * u
    out = {"reaction": force, "normal": force @ np.array([-u[1], u[0]])}
    return out | ({"moment": moment} if joint.locked_angle is not None else {})


#: a tree joint's reactions from the wrench its parent transmits, by its type
_TREE: dict[type, Callable[..., dict]] = {Revolute: _pin, LineJoint: _line}


def _angle(data: mujoco.MjData, body_ids: dict, body: str) -> float:
    if body == GROUND:
        return 0.0
    xmat = data.xmat[body_ids[body]]
    return float(np.arctan2(xmat[3], xmat[0]))


def _site_position(model: mujoco.MjModel, data: mujoco.MjData, body: str, label: str) -> np.ndarray:
    return data.site_xpos[model.site(f"{body}.{label}").id][:2].copy()
