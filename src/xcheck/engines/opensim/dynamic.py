"""OpenSim in driven dynamics (mode ``opensim-dynamic``): the model of
:func:`.model.build` with each driven joint's coordinate prescribed by its motion
law as an OpenSim function of time (Simbody's prescribed motion: a
``PolynomialFunction`` for a constant rate or acceleration, a ``Sine`` for a
harmonic law), integrated by Runge-Kutta-Merson at fixed steps over
:func:`xcheck.motion.simulation_window` from the native state at t = 0, the state
projected onto the constraints after each step, and compared with the native
solution at the inputs OpenSim realised (its coordinates, their rates and
accelerations). Positions, velocities and accelerations are OpenSim's
(``findStation{Location,Velocity,Acceleration}InGround`` after
``realizeAcceleration``).

The drivers prescribe the motion, so masses and forces only weigh the solver: a
body without mass data gets 1 kg and m size^2 / 12
(:func:`xcheck.engines.with_unit_mass`), and springs and loads, which change
the drivers' efforts and not the motion, are left out.

Measured: see :data:`xcheck.engines.opensim.OpenSim`'s tolerance basis.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import driven_run, empty_states, loop_gap
from xcheck.kinematics import Kinematics
from xcheck.ladder import DrivenProblem, Run, Rung, Series

from .model import OpenSimModel, build, opensim, opensim_tree

__all__ = [
    "INTEGRATOR",
    "MODE",
    "STEPS_PER_SAMPLE",
    "dynamic_series",
    "law_function",
    "polynomial",
    "prepare_dynamic",
    "record_state",
    "run_dynamic_once",
]

MODE = "opensim-dynamic"
INTEGRATOR = "Runge-Kutta-Merson, fixed step, prescribed drivers"
#: time steps per compared sample of the ladder's coarsest run, and its runs (doubling the steps)
STEPS_PER_SAMPLE = 4
RUNGS = 3
#: the body quantities OpenSim's runs give (:func:`xcheck.engines._frames.empty_states`)
QUANTITIES = ("position", "angle", "velocity", "omega", "acceleration", "alpha")


def polynomial(coefficients) -> object:
    """The OpenSim ``PolynomialFunction`` of time with ``coefficients``, highest power first."""
    osim = opensim()
    vector = osim.Vector(len(coefficients), 0.0)
    for k, value in enumerate(coefficients):
        vector.set(k, float(value))
    return osim.PolynomialFunction(vector)


def law_function(law, sign: float):
    """The OpenSim function of time of ``sign`` (law(t) - law(0)), rad or m."""
    osim = opensim()
    start = float(law.at_time(0.0)[0])
    if law.kind == "harmonic":
        omega = 2.0 * math.pi * law.frequency
        return osim.Sine(sign * law.amplitude, omega, law.phase, sign * (law.centre - start))
    acceleration = law.acceleration if law.kind == "constant-acceleration" else 0.0
    return polynomial([sign * value for value in (0.5 * acceleration, law.rate, law.start - start)])


def _vec2(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1)])


def record_state(om: OpenSimModel, mech, state, frames: dict[str, tuple], arrays: tuple[dict, dict], j: int) -> None:
    """Sample ``j`` of the body and point arrays (:func:`xcheck.engines._frames.empty_states`'s,
    accelerations as vectors) from OpenSim's ``state`` realised to acceleration, ``frames``
    its :meth:`~.model.OpenSimModel.frames`: positions, velocities and accelerations are
    OpenSim's (``findStation{Location,Velocity,Acceleration}InGround``)."""
    osim = opensim()
    bodies, points = arrays
    origin = osim.Vec3(0.0, 0.0, 0.0)
    for name, body in om.bodies.items():
        states = bodies[name]
        states["position"][j], states["angle"][j] = frames[name]
        states["velocity"][j] = _vec2(body.findStationVelocityInGround(state, origin))
        states["omega"][j] = body.getAngularVelocityInGround(state).get(2)
        states["acceleration"][j] = _vec2(body.findStationAccelerationInGround(state, origin))
        states["alpha"][j] = body.getAngularAccelerationInGround(state).get(2)
    owners = mech.point_owners
    for label, states in points.items():
        body = om.bodies[owners[label]]
        local = mech.body(owners[label]).points[label]
        station = osim.Vec3(float(local[0]), float(local[1]), 0.0)
        states["position"][j] = _vec2(body.findStationLocationInGround(state, station))
        states["velocity"][j] = _vec2(body.findStationVelocityInGround(state, station))
        states["acceleration"][j] = _vec2(body.findStationAccelerationInGround(state, station))


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: fixed Merson steps, :data:`STEPS_PER_SAMPLE` per sample, doubling."""
    return (Series("default", INTEGRATOR, timestep=problem.interval / STEPS_PER_SAMPLE, rungs=RUNGS),)


def prepare_dynamic(problem: DrivenProblem) -> Kinematics:
    """The mechanism with unit masses where it has none and without springs and loads
    (the drivers prescribe the motion).

    Raises
    ------
    NotApplicable
        What :func:`.model.opensim_tree` and :func:`.model.build` cannot hold.
    """
    opensim()
    mech = problem.kinematics.mechanism
    opensim_tree(mech, problem.start.q[0])
    return Kinematics(dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=()))


def run_dynamic_once(massive: Kinematics, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): fixed Merson
    steps of ``rung.timestep`` with the drivers prescribed, the states at the compared times."""
    mech = problem.kinematics.mechanism
    dt, per, samples, times = rung.timestep, rung.counts[0], problem.samples, problem.times
    q0, qd0 = problem.start.q[0], problem.start.qd[0]
    signs = opensim_tree(mech, q0).driver_signs(mech)
    functions = {name: law_function(d.law, sign) for (name, sign), d in zip(signs, mech.drivers)}
    om: OpenSimModel = build(massive.mechanism, q0, qd0, prescribed=functions)
    model = om.model
    manager = om.started_manager("RungeKuttaMerson", fixed_step=dt)
    state = om.state
    bodies, points, inputs, rates, gaps = empty_states(mech, samples, QUANTITIES)
    accelerations = np.full_like(inputs, np.nan)
    start = np.array([float(d.law.at_time(0.0)[0]) for d in mech.drivers])
    failure, reached = "", 0
    for j in range(samples):
        t = float(times[j])
        try:
            state = manager.integrate(t)
        except RuntimeError as error:  # Simbody gave up: the run stops here
            failure = " ".join(str(error).split())[:200]
            break
        model.realizeAcceleration(state)
        frames = om.frames(state)
        if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
            failure = f"went non-finite at t = {t:.6g} s"
            break
        record_state(om, mech, state, frames, (bodies, points), j)
        for k, (name, sign) in enumerate(signs):
            coordinate = om.coordinates[name]
            inputs[j, k] = start[k] + sign * coordinate.getValue(state)
            rates[j, k] = sign * coordinate.getSpeedValue(state)
            accelerations[j, k] = sign * coordinate.getAccelerationValue(state)
        gaps[j] = loop_gap(frames, om.tree.cuts)
        reached = j + 1
        failure = problem.came_apart(t, float(gaps[j]))
        if failure:
            break
    settings = {"integrator": INTEGRATOR, "timestep": dt, "series": rung.series.key, "steps_per_sample": per}
    notes = (
        f"OpenSim driven dynamics, {INTEGRATOR}, dt = {dt:.4g} s; inputs, rates and accelerations "
        "as OpenSim realised them."
    )
    filled = (bodies, points, inputs, rates, gaps)
    return driven_run(MODE, mech, times, filled, reached, failure, settings, notes, accelerations)
