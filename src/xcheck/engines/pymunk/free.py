"""pymunk in free motion (mode ``pymunk-free``): the constraint scene of
:func:`.scene.build_scene` with no driver, released at the native reference's
initial state and stepped with pymunk's semi-implicit Euler and iterative
impulses; the ladder and its judgement are :func:`xcheck.ladder.free_study`'s.

The series: pymunk's defaults (10 iterations, its error correction) and at its
best (error_bias 0, 100 iterations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xcheck.engines._frames import FrameRecorder
from xcheck.ladder import FreeProblem, Run, Rung, Series

from .scene import build_scene

__all__ = ["FreeSetting", "FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "pymunk-free"


@dataclass(frozen=True)
class FreeSetting:
    """pymunk's solver: ``iterations`` per step and each constraint's
    ``error_bias`` (None: pymunk's default, 0.9 of the error left per 1/60 s)."""

    iterations: int
    error_bias: float | None


FREE_SERIES = tuple(
    Series(name, f"semi-implicit Euler, {setting.iterations} iterations", setting)
    for name, setting in (("default", FreeSetting(10, None)), ("best", FreeSetting(100, 0.0)))
)


def prepare_free(problem: FreeProblem):
    """The reference's solution, whose first state every run starts from."""
    return problem.reference.motion.solution()


def run_free_once(start, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    setting: FreeSetting = rung.series.options
    kinematics = problem.kinematics
    dt = rung.timestep
    scene = build_scene(kinematics, start, iterations=setting.iterations, error_bias=setting.error_bias, free=True)
    recorder = FrameRecorder(problem, gap=lambda frames: scene.joint_gaps()[0])

    def frames():
        return {
            name: (np.array([body.position.x, body.position.y]), body.angle)
            for name, body in scene.bodies.items()
            if name in recorder.bodies
        }

    failure, n = recorder.record(frames(), 0), 0
    for j, count in enumerate(rung.counts, start=1):
        if failure:
            break
        for _ in range(count):
            scene.step(n * dt, dt)
            n += 1
        failure = recorder.record(frames(), j)
    settings = {
        **rung.settings,
        "iterations": setting.iterations,
        "error_bias": setting.error_bias,
    }
    notes = f"pymunk free motion, {rung.series.setting} solver, dt = {dt:g} s."
    return Run(recorder.trajectory(MODE, settings, notes), failure)
