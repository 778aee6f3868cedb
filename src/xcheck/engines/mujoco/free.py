"""MuJoCo in free motion (mode ``mujoco-free``): the mechanism released from the
native reference's initial state; the ladder and its judgement are
:func:`xcheck.ladder.free_study`'s.

The MJCF file is the writer's (:func:`.model.free_model`); its servos are
switched off (actuation disabled, gains and biases zeroed, controls 0), so the
drivers play no part. Gravity is the file's; each linear spring of the
mechanism becomes a spatial tendon between its two sites (MuJoCo's tendon
stiffness, spring length and damping: the same force law). The constant
``[[loads]]`` are applied at every evaluation of the dynamics (each RK4 stage)
through MuJoCo's passive-force callback (``mjcb_passive``, ``mj_applyFT`` at the
load's point, the force fixed in the global frame), set for the run only.

The series, as a user would run them: the file's constraint softness (MuJoCo's
defaults) and stiff loops (:data:`.dynamic.TIGHT`'s: solref = 2 dt, solimp
0.9999), each with each integrator (Euler, implicitfast, RK4). A run that blows
up (a MuJoCo warning, a non-finite state) stops there. Loop drift is MuJoCo's
own measure (the largest ``efc_pos`` of the loop equalities at the sampled
states); energy is MuJoCo's (``mjENBL_ENERGY``: kinetic, gravity and tendon
springs), left out where loads or rotational springs act (it does not hold
their potential).

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
from dataclasses import dataclass

import mujoco
import numpy as np

from xcheck.kinematics import Kinematics
from xcheck.ladder import FreeProblem, Run, Rung, Series
from xcheck.model import GROUND, Mechanism
from xcheck.results import Trajectory

from .dynamic import Setting
from .mjcf import Layout, joint_coordinates
from .model import free_model, joint_velocities
from .oracle import Oracle

__all__ = ["FREE_MODE", "FREE_SERIES", "FreeModel", "free_series", "prepare_free", "run_free_once", "states"]

FREE_MODE = "mujoco-free"


def free_series(setting: Setting) -> Series:
    """The series of a setting: named by its name and integrator ("stiff RK4")."""
    return Series(setting.name, setting.integrator, setting, name=f"{setting.name} {setting.integrator}")


#: The ladder's series: the file's softness (MuJoCo's defaults) and stiff loops, each integrator.
FREE_SERIES = tuple(
    free_series(Setting(softness, integrator, stiff))
    for softness, stiff in (("default", False), ("stiff", True))
    for integrator in ("Euler", "implicitfast", "RK4")
)


@dataclass
class FreeModel:
    """What every free run shares: the compiled model, its layout and oracle, and
    the start (qpos0, qvel0) mapped from the reference's initial state."""

    model: mujoco.MjModel
    layout: Layout
    oracle: Oracle
    qpos0: np.ndarray
    qvel0: np.ndarray


def prepare_free(problem: FreeProblem) -> FreeModel:
    """The free model (:func:`.model.free_model`) and the start in MuJoCo's coordinates.

    Raises
    ------
    ValueError
        If the MJCF cannot be written or compiled, or the initial state does not
        close MuJoCo's loops.
    """
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    model, lay = free_model(kinematics)
    oracle = Oracle(model, mech, lay)
    q0, qd0 = problem.start
    qpos0, qvel0 = joint_coordinates(mech, lay, q0), joint_velocities(mech, lay, q0, qd0)
    residual, jacobian = oracle.constraints(qpos0)
    closure = float(np.max(np.abs(residual), initial=0.0))
    rate = float(np.max(np.abs(jacobian @ qvel0), initial=0.0))
    if closure > 1e-9 * mech.size or rate > 1e-9 * max(float(np.max(np.abs(qd0))), 1.0) * mech.size:
        raise ValueError(
            f"the initial state does not close MuJoCo's loops (position {closure:.3g} m, velocity {rate:.3g} m/s)"
        )
    return FreeModel(model, lay, oracle, qpos0, qvel0)


def run_free_once(prepared: FreeModel, problem: FreeProblem, rung: Rung, model: mujoco.MjModel | None = None) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`); ``model``
    instead of the prepared one (MJX compares MuJoCo at its own solver)."""
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    model = copy.deepcopy(prepared.model if model is None else model)
    setting: Setting = rung.series.options
    settings = setting.apply(model, rung.timestep)
    times = problem.times
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = prepared.qpos0, prepared.qvel0
    loads = _loads(mech, model, problem.start[0])
    passive = mujoco.get_mjcb_passive()
    n = len(times)
    qpos, qvel, qacc = (np.full((n, model.nv), np.nan) for _ in range(3))
    energy, gaps = np.full(n, np.nan), np.full(n, np.nan)
    warnings: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(warnings.append)  # an unstable simulation is the run's failure
    if loads is not None:
        mujoco.set_mjcb_passive(loads)
    failure, s = "", 0
    begin = time.process_time()
    try:
        for s in range(n):
            if s:
                mujoco.mj_step(model, data, nstep=rung.counts[s - 1])
            mujoco.mj_forward(model, data)
            if warnings:
                failure = f"diverged by t = {times[s]:.4g} s: {warnings[0].strip()}"
                break
            if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
                failure = f"went non-finite by t = {times[s]:.4g} s"
                break
            qpos[s], qvel[s], qacc[s] = data.qpos, data.qvel, data.qacc
            energy[s], gaps[s] = data.energy[0] + data.energy[1], prepared.oracle.violation(data.qpos)
            failure = problem.came_apart(float(times[s]), gaps[s])
            if failure:
                s += 1
                break
        else:
            s = n
    finally:
        mujoco.set_mju_user_warning(previous)
        mujoco.set_mjcb_passive(passive)
    cpu = time.process_time() - begin
    if not s:
        return Run(None, failure or "no output reached", cpu)
    good = slice(0, s)
    series = rung.series.key
    trajectory = states(kinematics, prepared.oracle, problem, qpos[good], qvel[good], qacc[good])
    trajectory.settings = {**settings, "series": series, "samples": s}
    trajectory.diagnostics = {"constraint_violation": gaps[good]}
    if not (mech.loads or mech.rotational_springs):  # MuJoCo's energy holds neither's potential
        trajectory.diagnostics["energy"] = energy[good]
    trajectory.notes = (
        f"Free motion, {series}, dt = {rung.timestep:g} s: servos off (actuation disabled), from the reference's "
        "initial state; accelerations are qacc (with MuJoCo's constraint stabilisation)."
    )
    return Run(trajectory, failure, cpu)


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


def states(kinematics: Kinematics, oracle: Oracle, problem: FreeProblem, qpos, qvel, qacc) -> Trajectory:
    """MuJoCo's states at the first ``len(qpos)`` compared outputs as a Trajectory in the
    canonical frames, body angles continuous from the reference's first ones."""
    mech = kinematics.mechanism
    bodies, points = oracle.states(qpos, qvel, qacc)
    start = problem.start[0]
    for i, body in enumerate(mech.moving_bodies):
        angle = np.unwrap(bodies[body.name]["angle"])
        turns = round((float(start[3 * i + 2]) - angle[0]) / (2.0 * math.pi))
        bodies[body.name]["angle"] = angle + 2.0 * math.pi * turns
    dofs = oracle.input_dofs
    times = problem.times[: len(qpos)]
    return Trajectory(FREE_MODE, qpos[:, dofs], qvel[:, dofs], qacc[:, dofs], bodies, points, times)
