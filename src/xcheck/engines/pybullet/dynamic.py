"""PyBullet in driven dynamics (mode ``pybullet-dynamic``): the multibody of
:func:`.free.build` with each driven joint (always a tree joint: the spanning
tree takes the driven joints first) held on the drivers' motion laws by
PyBullet's joint motor (``POSITION_CONTROL``: target position and velocity of
the next step, unbounded force), stepped over :func:`xcheck.motion.simulation_window`
from the native state at t = 0, and compared with the native solution at the
inputs PyBullet realised.

The drivers prescribe the motion, so masses only weigh the solver: a body
without mass data gets 1 kg and m size^2 / 12 about its frame origin
(:func:`xcheck.engines.with_unit_mass`). PyBullet gives positions and
velocities, not accelerations (there is no joint-acceleration output; a
finite difference would be xcheck's answer, not PyBullet's): accelerations are
not compared. What the free mode cannot hold (a pin-in-slot, a loop cut at a
prismatic joint) is :class:`~xcheck.engines.NotApplicable` here too.

Measured: see :data:`SETTINGS`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.engines._driven import driven_result, empty_states, ladder
from xcheck.engines._frames import loop_gap, world_point
from xcheck.joints import LineJoint
from xcheck.kinematics import Kinematics, Status, rotate
from xcheck.ladder import Series
from xcheck.model import GROUND
from xcheck.motion import simulation_window
from xcheck.results import ModeResult, Trajectory
from xcheck.topology import spanning_tree

from .model import Multibody, Setting, build, p, set_state, velocity

__all__ = ["MODE", "SETTINGS", "STEPS_PER_SAMPLE", "run_dynamic"]

MODE = "pybullet-dynamic"
#: the compared series: residual threshold 0 (the solver iterates its 50 sweeps; the
#: free mode's "best") first, then PyBullet's defaults
SETTINGS = (
    Series("best", Setting(50, 0.0).integrator, Setting(50, 0.0)),
    Series("default", Setting(50).integrator, Setting(50)),
)
#: time steps per sample of the ladder, finest first
STEPS_PER_SAMPLE = (100, 50, 25)
#: samples compared per run
SAMPLES = 40
#: the motor's force bound, N or N m: no bound a mechanism of the files reaches
MOTOR_FORCE = 1e12

_ERRORS = {"position": "abs", "angle": "abs", "velocity": "rel", "omega": "rel"}


def _sign(mb: Multibody, kinematics: Kinematics) -> dict[str, tuple[int, float]]:
    """Per driver: its link (the tree joint's child) and the sign of the joint
    coordinate against the driver's value (-1 where the tree hangs body_a from body_b)."""
    mech = kinematics.mechanism
    tree = {tj.joint.name: tj for tj in spanning_tree(mech).tree}
    out = {}
    for driver in mech.drivers:
        tj = tree[driver.joint]
        reversed_angle = driver.quantity == "angle" and tj.child != tj.joint.body_b
        out[driver.name] = (mb.links[tj.child], -1.0 if reversed_angle else 1.0)
    return out


def _inputs(kinematics: Kinematics, frames) -> tuple[np.ndarray, np.ndarray]:
    """The drivers' values and rates at a state (SI), as the native solver defines them."""
    mech = kinematics.mechanism
    values, rates = [], []
    for driver in mech.drivers:
        joint = mech.joint(driver.joint)

        def state(name):
            return (0.0, 0.0) if name == GROUND else (frames[name][1], frames[name][3])

        if driver.quantity == "angle":
            (pa, wa), (pb, wb) = state(joint.body_a), state(joint.body_b)
            values.append(pb - pa)
            rates.append(wb - wa)
            continue
        assert isinstance(joint, LineJoint)  # a slide driver: a prismatic joint or a pin-in-slot
        line = np.asarray(mech.body(joint.body_a).points[joint.line_point], dtype=float)
        point = np.asarray(mech.body(joint.body_b).points[joint.point], dtype=float)
        phi_a, omega_a = state(joint.body_a)
        u = rotate(phi_a, joint.direction)
        gap = world_point(frames, joint.body_b, point) - world_point(frames, joint.body_a, line)
        values.append(float(u @ gap))
        rates.append(
            float(
                omega_a * np.array([-u[1], u[0]]) @ gap
                + u @ (velocity(frames, joint.body_b, point) - velocity(frames, joint.body_a, line))
            )
        )
    return np.array(values), np.array(rates)


def _simulate(kinematics: Kinematics, massive: Kinematics, window, q0, qd0, series: Series, per: int):
    """One run: (row, Trajectory or None)."""
    mech = kinematics.mechanism
    duration = window.duration
    dt = duration / (SAMPLES * per)
    setting: Setting = series.options
    row = {
        "setting": series.setting,
        "integrator": series.integrator,
        "timestep": dt,
        "status": "ok",
    }
    moving = [b.name for b in mech.moving_bodies]
    bodies, points, inputs, rates, gaps = empty_states(mech, SAMPLES, _ERRORS)
    begin = time.process_time()
    client = p.connect(p.DIRECT)
    try:
        mb = build(massive, client)
        setting.apply(client, dt)
        p.setGravity(float(mech.gravity[0]), float(mech.gravity[1]), 0.0, physicsClientId=client)
        set_state(mb, massive, q0, qd0)
        motors = _sign(mb, kinematics)
        laws = [(motors[d.name], d.law) for d in mech.drivers]
        for n in range(SAMPLES * per):
            t_next = (n + 1) * dt
            for (link, sign), law in laws:
                value, rate, _ = (float(v) for v in law.at_time(t_next))
                p.setJointMotorControl2(
                    mb.uid,
                    link,
                    p.POSITION_CONTROL,
                    targetPosition=sign * value,
                    targetVelocity=sign * rate,
                    force=MOTOR_FORCE,
                    physicsClientId=client,
                )
            p.stepSimulation(physicsClientId=client)
            if (n + 1) % per:
                continue
            j = (n + 1) // per - 1
            frames = mb.frames()
            if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
                row["status"] = f"went non-finite at t = {t_next:.6g} s"
                break
            for name in moving:
                origin, phi, v_com, omega, com = frames[name]
                arm = origin - com
                bodies[name]["position"][j] = origin
                bodies[name]["angle"][j] = phi
                bodies[name]["velocity"][j] = v_com + omega * np.array([-arm[1], arm[0]])
                bodies[name]["omega"][j] = omega
            for label in points:
                owner = mech.point_owners[label]
                local = np.asarray(mech.body(owner).points[label], dtype=float)
                points[label]["position"][j] = world_point(frames, owner, local)
                points[label]["velocity"][j] = velocity(frames, owner, local)
            inputs[j], rates[j] = _inputs(kinematics, frames)
            gaps[j] = loop_gap(frames, mb.cuts)
    finally:
        p.disconnect(client)
    row["cpu_seconds"] = time.process_time() - begin
    if row["status"] != "ok":
        return row, None
    times = window.times(SAMPLES + 1)[1:]
    accelerations = np.stack([d.law.at_time(times)[2] for d in mech.drivers], axis=1)
    trajectory = Trajectory(
        MODE,
        inputs,
        rates,
        accelerations,
        bodies,
        points,
        times,
        {"integrator": row["integrator"], "timestep": dt, "series": series.key, "steps_per_sample": per},
        diagnostics={"input_error": inputs - window.inputs(kinematics, times)[0], "constraint_violation": gaps},
        notes=f"PyBullet driven dynamics, {row['integrator']}, dt = {dt:.4g} s; inputs as PyBullet realised them "
        "(input accelerations: the motion laws'; PyBullet gives no accelerations).",
    )
    return row, trajectory


def run_dynamic(kinematics: Kinematics, branch: str | None = None, refine: int = 0) -> ModeResult:
    """Simulate the driven mechanism in PyBullet at :data:`SETTINGS` x
    :data:`STEPS_PER_SAMPLE` and compare each run with the native solution;
    ``refine`` k > 0 runs only the first setting at 2^k times its finest step
    count (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        ``trajectories``: the runs that went through, the finest of the first
        setting first; ``summary``: per run setting, timestep (s), status,
        cpu_seconds, the largest errors (position m, angle rad; velocity, omega
        relative to the native magnitude), input_error (the motor's lag behind the
        law, SI) and loop_gap (m); ``study``: :func:`~xcheck.results.convergence_study`
        of the position error.

    Raises
    ------
    NotApplicable
        What :func:`.free.build` cannot hold.
    """
    mech = kinematics.mechanism
    massive = Kinematics(with_unit_mass(mech))
    client = p.connect(p.DIRECT)
    try:
        build(massive, client)  # refuses what it cannot hold before any run
    finally:
        p.disconnect(client)
    try:
        window = simulation_window(kinematics, branch)
        q, qd, qdd = window.inputs(kinematics, np.zeros(1))
        start = kinematics.solve(q, qd, qdd, branch=branch)
        if start.status[0] > Status.NEAR_SINGULAR:
            raise ValueError("the native solver does not assemble the mechanism at t = 0")
        runs = [
            _simulate(kinematics, massive, window, start.q[0], start.qd[0], setting, per)
            for setting, per in ladder(SETTINGS, STEPS_PER_SAMPLE, refine)
        ]
    except NotApplicable:
        raise
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        return ModeResult(MODE, mech.name, False, f"{MODE}: {type(error).__name__}: {error}".splitlines()[0])
    return driven_result(MODE, kinematics, runs, _ERRORS, branch)
