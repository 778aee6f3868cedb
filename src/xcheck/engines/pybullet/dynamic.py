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

Its series: :func:`dynamic_series`.
"""

from __future__ import annotations

import math

import numpy as np

from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import driven_run, empty_states, loop_gap, stepped_samples, world_point
from xcheck.joints import LineJoint
from xcheck.kinematics import Kinematics, rotate
from xcheck.ladder import DrivenProblem, Run, Rung, Series
from xcheck.model import GROUND
from xcheck.topology import spanning_tree

from .model import CONSTRAINT_FORCE, Multibody, Setting, build, p, set_state, velocity

__all__ = ["MODE", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]

MODE = "pybullet-dynamic"
#: the body quantities PyBullet gives
QUANTITIES = ("position", "angle", "velocity", "omega")


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


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: residual threshold 0 (the solver iterates its 50 sweeps; the free
    mode's "best") at 25, 50 and 100 steps per sample, compared; PyBullet's defaults at
    the finest."""
    interval = problem.interval
    return tuple(
        Series(name, setting.integrator, setting, timestep=interval / per, rungs=rungs)
        for name, setting, per, rungs in (("best", Setting(50, 0.0), 25, 3), ("default", Setting(50), 100, 1))
    )


def prepare_dynamic(problem: DrivenProblem) -> Kinematics:
    """The mechanism with unit masses where it has none, built once to refuse what the
    multibody cannot hold.

    Raises
    ------
    NotApplicable
        What :func:`.model.build` cannot hold.
    """
    massive = Kinematics(with_unit_mass(problem.kinematics.mechanism))
    client = p.connect(p.DIRECT)
    try:
        build(massive, client)
    finally:
        p.disconnect(client)
    return massive


def run_dynamic_once(massive: Kinematics, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): the
    motors held on the laws' value and rate at each step's end."""
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    setting: Setting = rung.series.options
    dt, per, samples = rung.timestep, rung.counts[0], problem.samples
    times = problem.times
    moving = [b.name for b in mech.moving_bodies]
    bodies, points, inputs, rates, gaps = empty_states(mech, samples, QUANTITIES)
    client = p.connect(p.DIRECT)
    try:
        mb = build(massive, client)
        setting.apply(client, dt)
        p.setGravity(float(mech.gravity[0]), float(mech.gravity[1]), 0.0, physicsClientId=client)
        set_state(mb, massive, problem.start.q[0], problem.start.qd[0])
        motors = _sign(mb, kinematics)
        laws = [(motors[d.name], d.law) for d in mech.drivers]

        def record(j: int) -> str:
            frames = mb.frames()
            if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
                return f"went non-finite at t = {times[j]:.6g} s"
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
            return problem.came_apart(float(times[j]), float(gaps[j]))

        def step(n: int) -> None:
            t_next = (n + 1) * dt
            for (link, sign), law in laws:
                value, rate, _ = (float(v) for v in law.at_time(t_next))
                p.setJointMotorControl2(
                    mb.uid,
                    link,
                    p.POSITION_CONTROL,
                    targetPosition=sign * value,
                    targetVelocity=sign * rate,
                    force=CONSTRAINT_FORCE,  # the motor's bound: none a mechanism reaches
                    physicsClientId=client,
                )
            p.stepSimulation(physicsClientId=client)

        failure, reached = stepped_samples(samples, per, step, record)
    finally:
        p.disconnect(client)
    settings = {
        "integrator": rung.series.integrator,
        "timestep": dt,
        "series": rung.series.key,
        "steps_per_sample": per,
    }
    notes = (
        f"PyBullet driven dynamics, {rung.series.integrator}, dt = {dt:.4g} s; inputs as PyBullet realised "
        "them (input accelerations: the motion laws'; PyBullet gives no accelerations)."
    )
    return driven_run(MODE, mech, times, (bodies, points, inputs, rates, gaps), reached, failure, settings, notes)
