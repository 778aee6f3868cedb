"""pymunk in free motion (mode ``pymunk-free``): the constraint scene with no
driver, released at the native reference's initial state and stepped with
pymunk's semi-implicit Euler and iterative impulses, compared with the
reference at its output times.

The ladder: pymunk's defaults (10 iterations, its error correction) and at
its best (error_bias 0, 100 iterations), each at time steps of 1, 0.5 and
0.25 ms. A run that goes non-finite or comes apart (a joint gap above a
tenth of the mechanism's size) is a row with its time, not an exception.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from xcheck.dynamics._free import FreeReference
from xcheck.kinematics import Kinematics
from xcheck.results import ModeResult, Trajectory, convergence_study
from xcheck.simulation import empty_path, finish_free_run, free_row, ladder_steps, outputs_per_step

from .scene import build_scene

__all__ = ["FreeSetting", "FREE_SETTINGS", "FREE_STEPS", "run_free"]

MODE = "pymunk-free"
#: samples compared with the reference (about; a whole number of outputs apart)
COMPARED = 200
#: a joint gap above this fraction of the size: the scene came apart
APART = 0.1


@dataclass(frozen=True)
class FreeSetting:
    """pymunk's solver: ``iterations`` per step and each constraint's
    ``error_bias`` (None: pymunk's default, 0.9 of the error left per 1/60 s)."""

    name: str
    iterations: int
    error_bias: float | None


FREE_SETTINGS = (FreeSetting("default", 10, None), FreeSetting("best", 100, 0.0))
FREE_STEPS = (1e-3, 5e-4, 2.5e-4)


def run_free(
    kinematics: Kinematics,
    reference: FreeReference,
    branch: str | None = None,
    *,
    settings=FREE_SETTINGS,
    steps=FREE_STEPS,
) -> ModeResult:
    """pymunk's free motion against the reference (see the module's docstring and
    :meth:`xcheck.engines.Engine.run_free`)."""
    mech = kinematics.mechanism
    motion = reference.motion
    every = max(1, (len(motion.times) - 1) // COMPARED)
    index = np.arange(0, len(motion.times), every)
    start = motion.solution()
    rows, trajectories = [], []
    for setting in settings:
        for dt in ladder_steps(reference, steps):
            row, trajectory = _run(kinematics, reference, start, index, setting, dt)
            rows.append(row)
            if trajectory is not None:
                trajectories.append((row["position_error"], trajectory))
    summary = pd.DataFrame(rows)
    study = convergence_study(summary["setting"], summary["timestep"], summary["position_error"], summary["status"])
    trajectories.sort(key=lambda pair: pair[0])
    ok = bool(trajectories)
    reason = "" if ok else f"no run went through: {rows[0]['status']}"
    return ModeResult(MODE, mech.name, ok, reason, [t for _, t in trajectories], summary, study)


def _run(kinematics, reference, start, index, setting: FreeSetting, dt: float) -> tuple[dict, Trajectory | None]:
    mech = kinematics.mechanism
    motion = reference.motion
    row = free_row(setting.name, f"semi-implicit Euler, {setting.iterations} iterations", dt)
    per_output, why = outputs_per_step(reference, dt)
    if why:
        row["status"] = why
        return row, None
    begin = time.process_time()
    scene = build_scene(kinematics, start, iterations=setting.iterations, error_bias=setting.error_bias, free=True)
    moving = [b.name for b in mech.moving_bodies]
    owners = mech.point_owners
    bodies, points = empty_path(mech, len(index))
    drift, wanted = 0.0, {int(i): j for j, i in enumerate(index)}
    total = int(index[-1]) * per_output
    for n in range(total + 1):
        if n % per_output == 0 and n // per_output in wanted:
            j = wanted[n // per_output]
            for name in moving:
                body = scene.bodies[name]
                bodies[name]["position"][j] = (body.position.x, body.position.y)
                bodies[name]["angle"][j] = body.angle
            for label, owner in owners.items():
                points[label]["position"][j] = scene.world_point(owner, label)
            gap = scene.joint_gaps()[0]
            drift = max(drift, gap)
            if not (math.isfinite(gap) and all(np.isfinite(b["position"][j]).all() for b in bodies.values())):
                row["status"] = f"went non-finite at t = {n * dt:.6g} s"
                break
            if gap > APART * mech.size:
                row["status"] = f"came apart at t = {n * dt:.6g} s (joints {gap:.3g} m apart)"
                break
        if n < total:
            scene.step(n * dt, dt)
    seconds = time.process_time() - begin
    row.update(
        steps=total,
        cpu_seconds=seconds,
        cpu_per_simulated_second=seconds / max(float(motion.times[-1]), 1e-300),
        loop_drift=drift,
    )
    if row["status"] != "ok":
        return row, None
    settings = {
        "setting": setting.name,
        "integrator": row["integrator"],
        "timestep": dt,
        "series": setting.name,
        "iterations": setting.iterations,
        "error_bias": setting.error_bias,
    }
    notes = f"pymunk free motion, {setting.name} solver, dt = {dt:g} s."
    return finish_free_run(MODE, reference, index, (bodies, points), settings, notes, row, APART * mech.size)
