"""MuJoCo in free motion (mode ``mujoco-free``): the mechanism released from the
native reference's initial state, compared with the reference.

The MJCF file is the writer's (:func:`.mjcf.mjcf_text`); its servos are
switched off (actuation disabled, gains and biases zeroed, controls 0), so the
drivers play no part. Gravity is the file's; each linear spring of the
mechanism becomes a spatial tendon between its two sites (MuJoCo's tendon
stiffness, spring length and damping: the same force law). The constant
``[[loads]]`` are applied at every evaluation of the dynamics (each RK4 stage)
through MuJoCo's passive-force callback (``mjcb_passive``, ``mj_applyFT`` at the
load's point, the force fixed in the global frame), set for the run only.

A ladder of settings as a user would run them: the file's constraint softness
(MuJoCo's defaults) and stiff loops (:data:`.dynamic.TIGHT`'s: solref = 2 dt,
solimp 0.9999), with each integrator (Euler, implicitfast, RK4) and several
time steps. A run that blows up is a row with its status, never an exception.
Loop drift is MuJoCo's own measure (the largest ``efc_pos`` of the loop
equalities at the sampled states); energy drift is the largest |E(t) - E(0)|
of MuJoCo's energy (``mjENBL_ENERGY``: kinetic, gravity and tendon springs),
empty where loads or dampers do work.

Measured on the IFToMM double four-bar (A02, 10 s, 2 cores): with the default
softness every integrator and step stays on the parallelogram branch but runs
out of phase (loops open by 9e-4 m, largest error 2 m, no convergence); stiff
loops converge at about first order (RK4 1.2e-4 m at 2.5e-4 s, 2.3e-5 m at
6.25e-5 s; Euler and implicitfast alike, 1.3e-4 m), loops closed to 3e-9 m;
the whole default ladder costs about 5 s CPU.
"""

from __future__ import annotations

import copy
import math
import time

import mujoco
import numpy as np
import pandas as pd

from xcheck.errors import XcheckError
from xcheck.joints import LineJoint
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND, Mechanism
from xcheck.results import ModeResult, Trajectory, convergence_study
from xcheck.simulation import free_errors, ladder_steps, left_branch

from .dynamic import Setting
from .mjcf import Layout, joint_coordinates, layout, mjcf_text
from .oracle import Oracle

__all__ = ["FREE_MODE", "SETTINGS", "TIMESTEPS", "LEFT_BRANCH", "joint_velocities", "free_model", "run_free"]

FREE_MODE = "mujoco-free"

#: The ladder's settings: the file's softness (MuJoCo's defaults) and stiff loops, each integrator.
SETTINGS = (
    Setting("default", "Euler", False),
    Setting("default", "implicitfast", False),
    Setting("default", "RK4", False),
    Setting("stiff", "Euler", True),
    Setting("stiff", "implicitfast", True),
    Setting("stiff", "RK4", True),
)
#: The ladder's time steps, s.
TIMESTEPS = (1e-3, 5e-4, 2.5e-4)
#: A run farther than this fraction of the mechanism's size from every configuration the reference
#: passes has left the reference's branch (a run out of phase on the branch has not).
LEFT_BRANCH = 0.1
#: About this many reference outputs are compared (every k-th).
COMPARED = 200


def joint_velocities(mechanism: Mechanism, lay: Layout, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """MuJoCo ``qvel`` of body coordinates and rates: the time derivative of
    :func:`.mjcf.joint_coordinates`.

    Parameters
    ----------
    q, qd : ndarray, shape (3 m,)
        x, y (m), phi (rad) of each moving body and their rates (m/s, rad/s).

    Returns
    -------
    ndarray, shape (nv,)
        Hinges: ``omega_b - omega_a`` (rad/s); slides: the rate of the slide displacement (m/s).
    """
    frames = {GROUND: (np.zeros(2), 0.0, np.zeros(2), 0.0)}
    for i, body in enumerate(mechanism.moving_bodies):
        frames[body.name] = (
            np.asarray(q[3 * i : 3 * i + 2], dtype=float),
            float(q[3 * i + 2]),
            np.asarray(qd[3 * i : 3 * i + 2], dtype=float),
            float(qd[3 * i + 2]),
        )

    def world(body: str, label: str) -> tuple[np.ndarray, np.ndarray]:
        r, phi, v, w = frames[body]
        arm = rotate(phi, mechanism.body(body).points[label])
        return r + arm, v + w * np.array([-arm[1], arm[0]])

    qvel = []
    for mj in lay.joints:
        joint = mj.joint
        if mj.kind == "hinge":
            qvel.append(frames[joint.body_b][3] - frames[joint.body_a][3])
        else:
            assert isinstance(joint, LineJoint)  # a slide belongs to a line joint
            phi_a, w_a = frames[joint.body_a][1], frames[joint.body_a][3]
            direction = rotate(phi_a, joint.direction)
            turning = w_a * np.array([-direction[1], direction[0]])
            (p_b, v_b), (p_a, v_a) = world(joint.body_b, joint.point), world(joint.body_a, joint.line_point)
            qvel.append(float(turning @ (p_b - p_a) + direction @ (v_b - v_a)))
    return np.array(qvel)


def free_model(kinematics: Kinematics) -> tuple[mujoco.MjModel, Layout]:
    """The compiled MJCF of the mechanism for free motion: springs as tendons, actuation off.

    Raises
    ------
    XcheckError
        If the writer cannot express the mechanism.
    ValueError
        If MuJoCo rejects the file.
    """
    mech = kinematics.mechanism
    lay = layout(mech)
    text = mjcf_text(kinematics)  # the springs are its spatial tendons
    model = mujoco.MjModel.from_xml_string(text)
    model.actuator_gainprm[:] = 0.0
    model.actuator_biasprm[:] = 0.0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    return model, lay


def _sampling(reference, timestep: float) -> tuple[np.ndarray, int, str]:
    """(indices of the compared reference outputs, steps between them, "" or why ``timestep`` does not fit)."""
    times = reference.motion.times
    every = max(1, math.ceil((len(times) - 1) / COMPARED))
    index = np.arange(0, len(times), every)
    interval = float(times[every] - times[0]) if len(times) > every else float(times[-1] - times[0])
    steps = round(interval / timestep)
    if steps < 1 or abs(steps * timestep - interval) > 1e-9 * max(interval, 1e-300):
        return index, 0, f"the step {timestep:g} s does not divide the sampling interval {interval:g} s"
    return index, steps, ""


def _run(kinematics, model, lay, oracle, reference, setting: Setting, timestep: float, qpos0, qvel0) -> tuple:
    """One run of the ladder: (summary row, Trajectory or None)."""
    mech = kinematics.mechanism
    model = copy.deepcopy(model)
    settings = setting.apply(model, timestep)
    index, every, misfit = _sampling(reference, timestep)
    times = reference.motion.times[index]
    duration = float(times[-1] - times[0])
    row = {
        "setting": setting.name,
        "integrator": setting.integrator,
        "timestep": timestep,
        "steps": every * (len(index) - 1),
        "status": "ok",
        "cpu_seconds": math.nan,
        "cpu_per_simulated_second": math.nan,
        "position_error": math.nan,
        "final_error": math.nan,
        "angle_error": math.nan,
        "loop_drift": math.nan,
        "energy_drift": math.nan,
    }
    if misfit:
        row["status"] = misfit
        return row, None
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos0, qvel0
    loads = _loads(mech, model, reference.motion.q[0])
    passive = mujoco.get_mjcb_passive()
    n = len(index)
    qpos, qvel, qacc = (np.full((n, model.nv), np.nan) for _ in range(3))
    energy = np.full(n, np.nan)
    warnings: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(warnings.append)  # an unstable simulation is the run's status
    if loads is not None:
        mujoco.set_mjcb_passive(loads)
    failure, s = "", 0
    begin = time.process_time()
    try:
        for s in range(n):
            if s:
                mujoco.mj_step(model, data, nstep=every)
            mujoco.mj_forward(model, data)
            if warnings:
                failure = f"diverged by t = {times[s]:.4g} s: {warnings[0].strip()}"
                break
            if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
                failure = f"NaN by t = {times[s]:.4g} s"
                break
            qpos[s], qvel[s], qacc[s] = data.qpos, data.qvel, data.qacc
            energy[s] = data.energy[0] + data.energy[1]
        else:
            s = n
    finally:
        mujoco.set_mju_user_warning(previous)
        mujoco.set_mjcb_passive(passive)
    cpu = time.process_time() - begin
    row["cpu_seconds"] = cpu
    row["cpu_per_simulated_second"] = cpu / max(float(times[max(s - 1, 0)] - times[0]), duration * 1e-9, 1e-300)
    if s < 2:
        row["status"] = failure or "no step went through"
        return row, None
    good = slice(0, s)
    trajectory = _trajectory(kinematics, oracle, reference, settings, qpos[good], qvel[good], qacc[good], times[good])
    drift = np.array([oracle.violation(q) for q in qpos[good]])
    trajectory.diagnostics = {"constraint_violation": drift, "energy": energy[good]}
    row["loop_drift"] = float(drift.max())
    if not (mech.loads or mech.rotational_springs or any(spring.damping for spring in mech.springs)):  # E conserved
        row["energy_drift"] = float(np.max(np.abs(energy[good] - energy[0])))
    if failure:
        row["status"] = failure
        return row, None
    errors = free_errors(reference, trajectory)
    row.update(
        position_error=errors["position_error"], final_error=errors["final_error"], angle_error=errors["angle_error"]
    )
    left = left_branch(reference, trajectory, LEFT_BRANCH * mech.size)
    if left:  # the errors stay in the row: what the run did until then
        row["status"] = left
        return row, None
    return row, trajectory


def _loads(mechanism: Mechanism, model: mujoco.MjModel, q0: np.ndarray):
    """The passive-force callback applying the mechanism's loads (time laws at
    ``d.time``) and its rotational spring-dampers, or None without either.

    A rotational spring's angle phi_b - phi_a is kept continuous from its value
    at the native initial state ``q0`` (body coordinates), to the nearest turn
    from one call to the next (MuJoCo's body orientations are quaternions);
    its rate is the difference of the bodies' angular velocities (``cvel``).
    """
    if not mechanism.loads and not mechanism.rotational_springs:
        return None
    terms = [
        (
            model.body(load.body).id,
            np.array([*load.point, 0.0]),
            np.array([*load.force, 0.0]),
            np.array([0.0, 0.0, float(load.torque)]),
            load.law,
        )
        for load in mechanism.loads
    ]
    index = {b.name: i for i, b in enumerate(mechanism.moving_bodies)}

    def start_angle(name: str) -> float:
        return float(q0[3 * index[name] + 2]) if name in index else 0.0

    twists = [
        (
            model.body(t.body_a).id if t.body_a != GROUND else 0,
            model.body(t.body_b).id if t.body_b != GROUND else 0,
            t.stiffness,
            t.rest_angle,
            t.damping,
        )
        for t in mechanism.rotational_springs
    ]
    last = [start_angle(t.body_b) - start_angle(t.body_a) for t in mechanism.rotational_springs]
    origin = np.zeros(3)

    def angle(d: mujoco.MjData, body: int) -> float:
        return math.atan2(d.xmat[body][3], d.xmat[body][0]) if body else 0.0

    def apply(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        for body, point, force, torque, law in terms:
            at = d.xpos[body] + d.xmat[body].reshape(3, 3) @ point
            factor = 1.0 if law is None else float(law.factor(d.time))  # RK4 sets d.time at its stages
            mujoco.mj_applyFT(m, d, factor * force, factor * torque, at, body, d.qfrc_passive)
        for k, (a, b, stiffness, rest, damping) in enumerate(twists):
            twist = angle(d, b) - angle(d, a)
            twist += 2.0 * math.pi * round((last[k] - twist) / (2.0 * math.pi))
            last[k] = twist
            rate = float(d.cvel[b][2] - d.cvel[a][2])
            torque_b = np.array([0.0, 0.0, -stiffness * (twist - rest) - damping * rate])
            for body, moment in ((b, torque_b), (a, -torque_b)):
                if body:
                    mujoco.mj_applyFT(m, d, origin, moment, d.xpos[body], body, d.qfrc_passive)

    return apply


def _trajectory(kinematics, oracle: Oracle, reference, settings: dict, qpos, qvel, qacc, times) -> Trajectory:
    """The sampled states in the canonical frames, body angles continuous from the reference's first one."""
    mech = kinematics.mechanism
    bodies, points = oracle.states(qpos, qvel, qacc)
    start = reference.motion.q[0]
    for i, body in enumerate(mech.moving_bodies):
        angle = np.unwrap(bodies[body.name]["angle"])
        turns = round((float(start[3 * i + 2]) - angle[0]) / (2.0 * math.pi))
        bodies[body.name]["angle"] = angle + 2.0 * math.pi * turns
    dofs = oracle.input_dofs
    series = f"{settings['setting']} {settings['integrator']}"
    return Trajectory(
        FREE_MODE,
        qpos[:, dofs],
        qvel[:, dofs],
        qacc[:, dofs],
        bodies,
        points,
        np.asarray(times, dtype=float),
        {**settings, "series": series, "samples": len(times)},
        {},
        f"Free motion, {series}, dt = {settings['timestep']:g} s: servos off (actuation disabled), from the "
        "reference's initial state; accelerations are qacc (with MuJoCo's constraint stabilisation).",
    )


def run_free(
    kinematics: Kinematics,
    reference,
    branch: str | None = None,
    timesteps=TIMESTEPS,
    settings=SETTINGS,
) -> ModeResult:
    """MuJoCo's free motion of the mechanism against the native reference.

    Parameters
    ----------
    kinematics : Kinematics
    reference : FreeReference
        The native reference (:func:`xcheck.dynamics.simulate`); its initial
        state is MuJoCo's, its output times (every k-th, about 200) are compared.
    branch : str, optional
        Unused: the reference's initial state fixes the branch.
    timesteps : sequence of float
        The ladder's time steps, s.
    settings : sequence of Setting
        The ladder's settings (:data:`SETTINGS`).

    Returns
    -------
    ModeResult
        See :meth:`xcheck.engines.Engine.run_free`; ``summary`` also has
        angle_error (rad) and observed_order (of position_error against the
        previous step of the same setting and integrator).
    """
    mech = kinematics.mechanism
    try:
        model, lay = free_model(kinematics)
    except XcheckError as error:
        return ModeResult(FREE_MODE, mech.name, False, f"MJCF writer: {' '.join(str(error).split())}")
    except ValueError as error:
        return ModeResult(FREE_MODE, mech.name, False, f"MuJoCo rejects the MJCF: {error}".splitlines()[0])
    oracle = Oracle(model, mech, lay)
    q0, qd0 = reference.motion.q[0], reference.motion.qd[0]
    qpos0, qvel0 = joint_coordinates(mech, lay, q0), joint_velocities(mech, lay, q0, qd0)
    residual, jacobian = oracle.constraints(qpos0)
    closure = float(np.max(np.abs(residual), initial=0.0))
    rate = float(np.max(np.abs(jacobian @ qvel0), initial=0.0))
    if closure > 1e-9 * mech.size or rate > 1e-9 * max(float(np.max(np.abs(qd0))), 1.0) * mech.size:
        return ModeResult(
            FREE_MODE,
            mech.name,
            False,
            f"the initial state does not close MuJoCo's loops (position {closure:.3g} m, velocity {rate:.3g} m/s)",
        )
    rows, trajectories = [], []
    for setting in settings:
        for dt in ladder_steps(reference, timesteps):
            row, trajectory = _run(kinematics, model, lay, oracle, reference, setting, float(dt), qpos0, qvel0)
            rows.append(row)
            if trajectory is not None:
                trajectories.append((row["position_error"], trajectory))
    summary = pd.DataFrame(rows)
    # errors within the reference's stated error are not measured: no order
    floor = float(np.max(reference.estimate))
    study = convergence_study(
        summary.setting + " " + summary.integrator,
        summary.timestep,
        summary.position_error,
        summary.status,
        floor=floor,
    )
    order = study.set_index(["series", "timestep"])["order"]
    summary["observed_order"] = [
        float(order.get((f"{r.setting} {r.integrator}", r.timestep), math.nan)) for r in summary.itertuples()
    ]
    trajectories.sort(key=lambda pair: pair[0])
    if not trajectories:
        first = summary.iloc[0]
        return ModeResult(
            FREE_MODE,
            mech.name,
            False,
            f"no run went through ({first.setting} {first.integrator} dt = {first.timestep:g} s: {first.status})",
            [],
            summary,
            study,
        )
    return ModeResult(FREE_MODE, mech.name, True, "", [t for _, t in trajectories], summary, study)
