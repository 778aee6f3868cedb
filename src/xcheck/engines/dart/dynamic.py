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

Measured: see :func:`run_dynamic`.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.engines._driven import driven_result, driven_start, driven_trajectory, empty_states, refined_steps
from xcheck.engines._frames import loop_gap, world_point
from xcheck.engines._tree import tree_frames
from xcheck.kinematics import Kinematics
from xcheck.model import GROUND
from xcheck.results import ModeResult, Trajectory

from .model import DartModel, build

__all__ = ["ERRORS", "MODE", "SAMPLES", "STEPS_PER_SAMPLE", "run_dynamic", "simulate"]

MODE = "dart-dynamic"
#: time steps per sample of the ladder, finest first
STEPS_PER_SAMPLE = (100, 50, 25)
#: the finest step a ladder takes, s: below about 2e-5 s DART's loop constraints blow up on a
#: fast mechanism (a stated finding), so a short window gets fewer steps per sample
SMALLEST_STEP = 1e-4
#: samples compared per run
SAMPLES = 40
#: the compared quantities (:func:`~xcheck.engines._driven.driven_result`'s ``errors``)
ERRORS = {"position": "abs", "angle": "abs", "velocity": "rel", "omega": "rel"}


def _states(model: DartModel) -> dict[str, tuple]:
    """Per moving body: origin (2,) m, angle rad (continuous), origin velocity (2,) m/s, rate rad/s."""
    frames = model.frames()
    out = {}
    for name, node in model.bodies.items():
        velocity = np.asarray(node.getLinearVelocity())[:2]
        omega = float(np.asarray(node.getAngularVelocity())[2])
        out[name] = (*frames[name], velocity, omega)
    return out


def _velocity(states, name: str, point: np.ndarray) -> np.ndarray:
    """Velocity of a body point, m/s: v_origin + w x (r - origin)."""
    if name == GROUND:
        return np.zeros(2)
    origin, _, velocity, omega = states[name]
    arm = world_point(states, name, point) - origin
    return velocity + omega * np.array([-arm[1], arm[0]])


def simulate(kinematics: Kinematics, massive: Kinematics, window, q0, qd0, per: int) -> tuple[dict, Trajectory | None]:
    """One run of :data:`SAMPLES` x ``per`` steps over the window: (row, Trajectory or None)."""
    import dartpy as dart

    mech = kinematics.mechanism
    dt = window.duration / (SAMPLES * per)
    row = {"setting": "default", "integrator": "semi-implicit Euler, LCP, velocity actuators", "timestep": dt}
    row["status"] = "ok"
    begin = time.process_time()
    model = build(massive.mechanism, q0, qd0, dt)
    drivers = model.tree.driver_signs(mech)
    joints = [model.joints[name] for name, _ in drivers]
    for joint in joints:
        joint.setActuatorType(dart.dynamics.ActuatorType.VELOCITY)
    start = np.array([float(d.law.at_time(0.0)[0]) for d in mech.drivers])
    signs = np.array([sign for _, sign in drivers])
    bodies, points, inputs, rates, gaps = empty_states(mech, SAMPLES, ERRORS)
    for n in range(SAMPLES * per):
        target = np.array([float(d.law.at_time((n + 1) * dt)[0]) for d in mech.drivers])
        for k, joint in enumerate(joints):
            joint.setCommand(0, float((signs[k] * (target[k] - start[k]) - joint.getPosition(0)) / dt))
        model.world.step()
        if (n + 1) % per:
            continue
        j = (n + 1) // per - 1
        states = _states(model)
        if not all(np.isfinite(s[0]).all() and math.isfinite(s[1]) for s in states.values()):
            row["status"] = f"went non-finite at t = {(n + 1) * dt:.6g} s"
            break
        for name, (origin, phi, velocity, omega) in states.items():
            bodies[name]["position"][j], bodies[name]["angle"][j] = origin, phi
            bodies[name]["velocity"][j], bodies[name]["omega"][j] = velocity, omega
        for label in points:
            owner = mech.point_owners[label]
            local = np.asarray(mech.body(owner).points[label], dtype=float)
            points[label]["position"][j] = world_point(states, owner, local)
            points[label]["velocity"][j] = _velocity(states, owner, local)
        for k, joint in enumerate(joints):
            inputs[j, k] = start[k] + signs[k] * float(joint.getPosition(0))
            rates[j, k] = signs[k] * float(joint.getVelocity(0))
        gaps[j] = loop_gap(states, model.tree.cuts)
    row["cpu_seconds"] = time.process_time() - begin
    if row["status"] != "ok":
        return row, None
    settings = {"integrator": row["integrator"], "timestep": dt, "series": "default", "steps_per_sample": per}
    notes = (
        f"DART driven dynamics, {row['integrator']}, dt = {dt:.4g} s; inputs as DART realised them "
        "(input accelerations: the motion laws'; DART's are not compared)."
    )
    trajectory = driven_trajectory(
        MODE, kinematics, window, (bodies, points, inputs, rates, gaps), None, settings, notes
    )
    return row, trajectory


def fitted_steps(steps, interval: float) -> tuple[int, ...]:
    """The steps per sample of a ladder whose samples are ``interval`` (s) apart: ``steps``
    halved together while the finest step is below :data:`SMALLEST_STEP` and the
    coarsest takes 6 or more."""
    steps = tuple(int(n) for n in steps)
    while steps[0] * SMALLEST_STEP > interval and steps[-1] >= 6:
        steps = tuple(n // 2 for n in steps)
    return steps


def run_dynamic(
    kinematics: Kinematics, branch: str | None = None, steps=STEPS_PER_SAMPLE, refine: int = 0
) -> ModeResult:
    """Simulate the driven mechanism in DART at :data:`STEPS_PER_SAMPLE` steps per sample
    (:func:`fitted_steps`) and compare each run with the native solution; ``refine`` k > 0
    runs only the finest 2^k steps per sample (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        As :func:`~xcheck.engines._driven.driven_result` makes it.

    Raises
    ------
    NotApplicable
        What :func:`.model.build` cannot hold.
    """
    import dartpy  # noqa: F401 - imported before the first run's clock starts

    mech = kinematics.mechanism
    massive = Kinematics(dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=()))
    try:
        window, q0, qd0 = driven_start(kinematics, branch)
        tree_frames(mech, q0, "DART")
        steps = fitted_steps(steps, window.duration / SAMPLES)
        if refine:
            steps = refined_steps(steps[0], refine)
        runs = [simulate(kinematics, massive, window, q0, qd0, per) for per in steps]
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        if isinstance(error, NotApplicable):
            raise
        return ModeResult(MODE, mech.name, False, f"{MODE}: {type(error).__name__}: {error}".splitlines()[0])
    return driven_result(MODE, kinematics, runs, ERRORS, branch)
