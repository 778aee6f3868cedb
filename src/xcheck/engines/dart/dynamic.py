"""DART in driven dynamics (mode ``dart-dynamic``): the world of :func:`.model.build`
with each driven joint (a tree joint: the spanning tree takes the driven joints
first) a ``VELOCITY`` actuator, stepped over :func:`xcheck.motion.simulation_window`
from the native state at t = 0 and compared with the native solution at the
inputs DART realised (its joint coordinates and rates).

DART ignores an actuator's command unless it is set before every step. Each step's
command is the velocity that takes the joint to the law's value at the step's end,
(q_law(t + dt) - q) / dt: DART's velocity actuator holds that velocity over the
step (semi-implicit Euler: the position follows it), so the realised input is the
law's at every step to round-off, and its rate the step's mean rate (compared as
realised). The loops close through the joint constraints of the free mode
(revolute cuts, DART's defaults). The drivers prescribe the motion, so masses
and forces only weigh the solver: a body without mass data gets 1 kg and m
size^2 / 12 (:func:`xcheck.engines.with_unit_mass`), and springs and loads,
which the DART model does not hold, are left out (they change the drivers'
efforts, not the motion). DART's accelerations are not compared.

Measured: see :data:`xcheck.engines.dart.Dart`'s tolerance basis and its tests.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import driven_run, empty_states, loop_gap, record_moving_states, stepped_samples
from xcheck.engines._tree import tree_frames
from xcheck.kinematics import Kinematics
from xcheck.ladder import DrivenProblem, Run, Rung, Series

from .model import DartModel, build

__all__ = [
    "INTEGRATOR",
    "MODE",
    "SMALLEST_STEP",
    "STEPS_PER_SAMPLE",
    "dynamic_series",
    "fitted_steps",
    "prepare_dynamic",
    "run_dynamic_once",
]

MODE = "dart-dynamic"
INTEGRATOR = "semi-implicit Euler, LCP, velocity actuators"
#: time steps per compared sample of the ladder's runs, finest first
STEPS_PER_SAMPLE = (100, 50, 25)
#: the finest step a ladder takes, s: below about 2e-5 s DART's loop constraints blow up on a
#: fast mechanism (a stated finding), so a short window gets fewer steps per sample
SMALLEST_STEP = 1e-4
#: the body quantities DART's runs give (:func:`xcheck.engines._frames.empty_states`)
QUANTITIES = ("position", "angle", "velocity", "omega")


def _states(model: DartModel) -> dict[str, tuple]:
    """Per moving body: origin (2,) m, angle rad (continuous), origin velocity (2,) m/s, rate rad/s."""
    frames = model.frames()
    out = {}
    for name, node in model.bodies.items():
        velocity = np.asarray(node.getLinearVelocity())[:2]
        omega = float(np.asarray(node.getAngularVelocity())[2])
        out[name] = (*frames[name], velocity, omega)
    return out


def fitted_steps(steps, interval: float) -> tuple[int, ...]:
    """The steps per sample of a ladder whose samples are ``interval`` (s) apart: ``steps``
    halved together while the finest step is below :data:`SMALLEST_STEP` and the
    coarsest takes 6 or more."""
    steps = tuple(int(n) for n in steps)
    while steps[0] * SMALLEST_STEP > interval and steps[-1] >= 6:
        steps = tuple(n // 2 for n in steps)
    return steps


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: DART's defaults at :data:`STEPS_PER_SAMPLE` steps per sample,
    fewer where the finest step would fall below :data:`SMALLEST_STEP` (:func:`fitted_steps`)."""
    steps = fitted_steps(STEPS_PER_SAMPLE, problem.interval)
    return (Series("default", INTEGRATOR, timestep=problem.interval / steps[-1], rungs=len(steps)),)


def prepare_dynamic(problem: DrivenProblem) -> Kinematics:
    """The mechanism with unit masses where it has none and without springs and loads
    (the drivers prescribe the motion), dartpy imported before the first run's clock starts.

    Raises
    ------
    NotApplicable
        What :func:`xcheck.engines._tree.tree_frames` and :func:`.model.build` cannot hold.
    """
    import dartpy  # noqa: F401 - imported before the first run's clock starts

    mech = problem.kinematics.mechanism
    tree_frames(mech, problem.start.q[0], "DART")
    return Kinematics(dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=()))


def run_dynamic_once(massive: Kinematics, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): each driven
    joint's velocity actuator commanded before every step with the velocity that takes it
    to the law's value at the step's end."""
    import dartpy as dart

    mech = problem.kinematics.mechanism
    dt, per, samples, times = rung.timestep, rung.counts[0], problem.samples, problem.times
    model = build(massive.mechanism, problem.start.q[0], problem.start.qd[0], dt)
    drivers = model.tree.driver_signs(mech)
    joints = [model.joints[name] for name, _ in drivers]
    for joint in joints:
        joint.setActuatorType(dart.dynamics.ActuatorType.VELOCITY)
    start = np.array([float(d.law.at_time(0.0)[0]) for d in mech.drivers])
    signs = np.array([sign for _, sign in drivers])
    bodies, points, inputs, rates, gaps = empty_states(mech, samples, QUANTITIES)

    def record(j: int) -> str:
        states = _states(model)
        if not record_moving_states(mech, states, (bodies, points), j):
            return f"went non-finite at t = {times[j]:.6g} s"
        for k, joint in enumerate(joints):
            inputs[j, k] = start[k] + signs[k] * float(joint.getPosition(0))
            rates[j, k] = signs[k] * float(joint.getVelocity(0))
        gaps[j] = loop_gap(states, model.tree.cuts)
        return problem.came_apart(float(times[j]), float(gaps[j]))

    def step(n: int) -> None:
        target = np.array([float(d.law.at_time((n + 1) * dt)[0]) for d in mech.drivers])
        for k, joint in enumerate(joints):
            joint.setCommand(0, float((signs[k] * (target[k] - start[k]) - joint.getPosition(0)) / dt))
        model.world.step()

    failure, reached = stepped_samples(samples, per, step, record)
    settings = {"integrator": INTEGRATOR, "timestep": dt, "series": rung.series.key, "steps_per_sample": per}
    notes = (
        f"DART driven dynamics, {INTEGRATOR}, dt = {dt:.4g} s; inputs as DART realised them "
        "(input accelerations: the motion laws'; DART's are not compared)."
    )
    return driven_run(MODE, mech, times, (bodies, points, inputs, rates, gaps), reached, failure, settings, notes)
