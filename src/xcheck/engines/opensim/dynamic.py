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

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.engines._driven import driven_result, driven_start, driven_trajectory, empty_states, refined_steps
from xcheck.engines._frames import loop_gap
from xcheck.engines._tree import tree_frames
from xcheck.kinematics import Kinematics
from xcheck.results import ModeResult, Trajectory

from .model import OpenSimModel, build, opensim

__all__ = ["ERRORS", "MODE", "SAMPLES", "STEPS_PER_SAMPLE", "run_dynamic", "simulate"]

MODE = "opensim-dynamic"
#: time steps per sample of the ladder, finest first
STEPS_PER_SAMPLE = (16, 8, 4)
#: samples compared per run
SAMPLES = 40
#: the compared quantities (:func:`~xcheck.engines._driven.driven_result`'s ``errors``)
ERRORS = {
    "position": "abs",
    "angle": "abs",
    "velocity": "rel",
    "omega": "rel",
    "acceleration": "rel",
    "alpha": "rel",
}


def law_function(law, sign: float):
    """The OpenSim function of time of ``sign`` (law(t) - law(0)), rad or m."""
    osim = opensim()
    start = float(law.at_time(0.0)[0])
    if law.kind == "harmonic":
        omega = 2.0 * math.pi * law.frequency
        return osim.Sine(sign * law.amplitude, omega, law.phase, sign * (law.centre - start))
    acceleration = law.acceleration if law.kind == "constant-acceleration" else 0.0
    coefficients = osim.Vector(3, 0.0)
    for k, value in enumerate((0.5 * acceleration, law.rate, law.start - start)):
        coefficients.set(k, sign * float(value))
    return osim.PolynomialFunction(coefficients)


def _vec2(v) -> np.ndarray:
    return np.array([v.get(0), v.get(1)])


def simulate(kinematics: Kinematics, massive: Kinematics, window, q0, qd0, per: int) -> tuple[dict, Trajectory | None]:
    """One run of :data:`SAMPLES` x ``per`` fixed Merson steps over the window: (row, Trajectory or None)."""
    import time

    osim = opensim()
    mech = kinematics.mechanism
    dt = window.duration / (SAMPLES * per)
    row = {"setting": "default", "integrator": "Runge-Kutta-Merson, fixed step, prescribed drivers", "timestep": dt}
    row["status"] = "ok"
    begin = time.process_time()
    signs = tree_frames(mech, q0, "OpenSim").driver_signs(mech)
    functions = {name: law_function(d.law, sign) for (name, sign), d in zip(signs, mech.drivers)}
    om: OpenSimModel = build(massive.mechanism, q0, qd0, prescribed=functions)
    model = om.model
    manager = osim.Manager(model)
    manager.setIntegratorMethod(osim.Manager.IntegratorMethod_RungeKuttaMerson)
    manager.setIntegratorFixedStepSize(dt)
    manager.setRecordStatesTrajectory(False)
    manager.setWriteToStorage(False)
    manager.setPerformAnalyses(False)
    state = om.state
    state.setTime(0.0)
    manager.initialize(state)
    quantities = dict.fromkeys(ERRORS)
    bodies, points, inputs, rates, gaps = empty_states(mech, SAMPLES, quantities)
    for states in (*bodies.values(), *points.values()):  # accelerations are vectors too
        states["acceleration"] = np.full((SAMPLES, 2), np.nan)
    accelerations = np.full_like(inputs, np.nan)
    start = np.array([float(d.law.at_time(0.0)[0]) for d in mech.drivers])
    owners = mech.point_owners
    origin = osim.Vec3(0.0, 0.0, 0.0)
    for j in range(SAMPLES):
        t = (j + 1) * per * dt
        try:
            state = manager.integrate(t)
        except RuntimeError as error:  # Simbody gave up: the run stops here
            row["status"] = " ".join(str(error).split())[:200]
            break
        model.realizeAcceleration(state)
        frames = om.frames(state)
        if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
            row["status"] = f"went non-finite at t = {t:.6g} s"
            break
        for name, body in om.bodies.items():
            states = bodies[name]
            states["position"][j], states["angle"][j] = frames[name]
            states["velocity"][j] = _vec2(body.findStationVelocityInGround(state, origin))
            states["omega"][j] = body.getAngularVelocityInGround(state).get(2)
            states["acceleration"][j] = _vec2(body.findStationAccelerationInGround(state, origin))
            states["alpha"][j] = body.getAngularAccelerationInGround(state).get(2)
        for label, states in points.items():
            body = om.bodies[owners[label]]
            local = mech.body(owners[label]).points[label]
            station = osim.Vec3(float(local[0]), float(local[1]), 0.0)
            states["position"][j] = _vec2(body.findStationLocationInGround(state, station))
            states["velocity"][j] = _vec2(body.findStationVelocityInGround(state, station))
            states["acceleration"][j] = _vec2(body.findStationAccelerationInGround(state, station))
        for k, (name, sign) in enumerate(signs):
            coordinate = om.coordinates[name]
            inputs[j, k] = start[k] + sign * coordinate.getValue(state)
            rates[j, k] = sign * coordinate.getSpeedValue(state)
            accelerations[j, k] = sign * coordinate.getAccelerationValue(state)
        gaps[j] = loop_gap(frames, om.tree.cuts)
    row["cpu_seconds"] = time.process_time() - begin
    if row["status"] != "ok":
        return row, None
    settings = {"integrator": row["integrator"], "timestep": dt, "series": "default", "steps_per_sample": per}
    notes = (
        f"OpenSim driven dynamics, {row['integrator']}, dt = {dt:.4g} s; inputs, rates and accelerations "
        "as OpenSim realised them."
    )
    filled = (bodies, points, inputs, rates, gaps)
    trajectory = driven_trajectory(MODE, kinematics, window, filled, accelerations, settings, notes)
    return row, trajectory


def run_dynamic(
    kinematics: Kinematics, branch: str | None = None, steps=STEPS_PER_SAMPLE, refine: int = 0
) -> ModeResult:
    """Simulate the driven mechanism in OpenSim at :data:`STEPS_PER_SAMPLE` fixed Merson steps
    per sample and compare each run with the native solution; ``refine`` k > 0 runs only the
    finest 2^k steps per sample (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        As :func:`~xcheck.engines._driven.driven_result` makes it.

    Raises
    ------
    NotApplicable
        What :func:`.model.build` cannot hold.
    """
    mech = kinematics.mechanism
    if refine:
        steps = refined_steps(steps[0], refine)
    massive = Kinematics(dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=()))
    try:
        window, q0, qd0 = driven_start(kinematics, branch)
        tree_frames(mech, q0, "OpenSim")
        runs = [simulate(kinematics, massive, window, q0, qd0, per) for per in steps]
    except NotApplicable:
        raise
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        return ModeResult(MODE, mech.name, False, f"{MODE}: {type(error).__name__}: {error}".splitlines()[0])
    return driven_result(MODE, kinematics, runs, ERRORS, branch)
