"""PyBullet in free motion (mode ``pybullet-free``): the multibody of
:func:`.model.build` released at the native reference's initial state and
stepped by PyBullet; the ladder and its judgement are
:func:`xcheck.ladder.free_study`'s.

The series: PyBullet's solver defaults (50 iterations,
``solverResidualThreshold`` 1e-7) and at its best (residual threshold 0: the
solver runs all its iterations). On the IFToMM double four-bar over 2 s, 200
or 500 iterations and ``erp`` 0 or 1 gave the same errors as 50 iterations to
1e-12 m. On Andrews' squeezer (0.03 s, 10 .. 2.5 us) 200 iterations changed
nothing either; ``erp`` (``changeConstraint`` and
``setPhysicsEngineParameter``) 0.8 closed the loops 4 times tighter (7.1e-7 ..
4.4e-8 m) at the same error (3.42e-4 .. 8.5e-5 m), ``erp`` 0 left them open by
1.8e-4 .. 4.6e-5 m with errors 1.5 times larger.

Measured (``xcheck simulate NAME --engines native,pybullet-free``, 2 cores,
dt = 1, 0.5, 0.25 ms; A03 10, 5, 2.5 us): A01 (10 s) 2.2e-3, 1.1e-3, 5.5e-4 m
with either setting, first order; A02 (10 s, ten singular passes) best
2.9e-5, 7.3e-6, 1.8e-6 m, order 2.0, loops closed to 2e-13 m, on the
parallelogram branch throughout; default 2.7e-2, 4.0e-2, 6.5e-3 m (no order),
loops open by 3e-6 .. 9e-7 m; A03 (0.03 s) 3.4e-4, 1.7e-4, 8.5e-5 m, first
order, loops open by 2.8e-6 .. 1.8e-7 m, either setting.
"""

from __future__ import annotations

import math

from xcheck.engines._frames import FrameRecorder
from xcheck.ladder import FreeProblem, Run, Rung, Series, conservative

from .model import Forces, Setting, build, energy, p, set_state

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "pybullet-free"
FREE_SERIES = tuple(
    Series(name, setting.integrator, setting)
    for name, setting in (("default", Setting(50)), ("best", Setting(50, 0.0)))
)


def prepare_free(problem: FreeProblem) -> None:
    """Build the multibody once, to refuse what it cannot hold before any run.

    Raises
    ------
    NotApplicable
        A pin-in-slot joint, a loop cut at a prismatic joint (:func:`.model.build`).
    """
    client = p.connect(p.DIRECT)
    try:
        build(problem.kinematics, client)
    finally:
        p.disconnect(client)


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    setting: Setting = rung.series.options
    dt = rung.timestep
    q0, qd0 = problem.start
    moving = [b.name for b in mech.moving_bodies]
    known = conservative(mech)  # the energy is E less the constant loads' potential
    client = p.connect(p.DIRECT)
    try:
        mb = build(kinematics, client)
        setting.apply(client, dt, mb.constraints)
        p.setGravity(float(mech.gravity[0]), float(mech.gravity[1]), 0.0, physicsClientId=client)
        set_state(mb, kinematics, q0, qd0)
        forces = Forces(kinematics, mb)
        recorder = FrameRecorder(problem, mb.cuts)

        def record(frames, j: int) -> str:
            turned = {name: frames[name][1] for name in moving}
            return recorder.record(frames, j, energy(kinematics, mb, frames, turned) if known else math.nan)

        frames = mb.frames()
        failure, n = record(frames, 0), 0
        for j, count in enumerate(rung.counts, start=1):
            if failure:
                break
            for _ in range(count):
                if forces.active:
                    forces.apply(frames, n * dt)
                p.stepSimulation(physicsClientId=client)
                n += 1
                frames = mb.frames() if forces.active else frames
            frames = frames if forces.active else mb.frames()
            failure = record(frames, j)
    finally:
        p.disconnect(client)
    settings = {
        **rung.settings,
        "iterations": setting.iterations,
        "residual": setting.residual,
        "erp": setting.erp,
    }
    notes = f"PyBullet free motion, {rung.series.setting} solver, dt = {dt:g} s."
    return Run(recorder.trajectory(MODE, settings, notes), failure)
