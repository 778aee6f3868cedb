"""OpenSim in free motion (mode ``opensim-free``): the model of :func:`.model.build`
released at the native reference's initial state and integrated by Simbody
through OpenSim's ``Manager``, which projects the state back onto the
constraints after each step (to the constraint tolerance, the accuracy unless
set); the ladder and its judgement are :func:`xcheck.ladder.free_study`'s.

The series:

- ``merson``: Runge-Kutta-Merson at the ladder's fixed step (order 4);
- ``euler``: explicit Euler at the fixed step (order 1, its loops held by the
  projection alone);
- ``accuracy``: Runge-Kutta-Merson choosing its own steps by its error
  control, at an accuracy of 1e-5 at the ladder's 1 ms, divided by 16 at each
  halving (1e-5, 6.25e-7, 3.9e-8; the ``accuracy`` column): OpenSim's own
  knob, its ladder laid on the step's so that one rule judges it (an error
  that follows the accuracy falls at order 4 against the nominal step).

Verlet is left out (on the free four-bar of the tests it stops at 0.06 s at
accuracy 1e-8, Simbody's "integrator step failed"; at 1e-4 it runs), and CPodes
too (no result within a minute at accuracy 1e-8 on the same four-bar).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from xcheck.engines._frames import FrameRecorder
from xcheck.ladder import FreeProblem, Run, Rung, Series, conservative

from .model import build

__all__ = ["FREE_SERIES", "FreeSetting", "prepare_free", "run_free_once"]

MODE = "opensim-free"
#: the accuracy of the error-controlled series at a ladder step of 1 ms (halved steps: / 16 each)
ACCURACY_AT_1MS = 1e-5


@dataclass(frozen=True)
class FreeSetting:
    """Simbody's integrator (``Manager.IntegratorMethod_NAME``) and whether it runs at the
    ladder's fixed step (else error-controlled, at most that step)."""

    method: str
    fixed: bool


FREE_SERIES = (
    Series("merson", "Runge-Kutta-Merson, fixed step", FreeSetting("RungeKuttaMerson", True)),
    Series("euler", "explicit Euler, fixed step", FreeSetting("ExplicitEuler", True)),
    Series(
        "accuracy",
        "Runge-Kutta-Merson, error-controlled, accuracy 1e-5 (dt / 1 ms)^4",
        FreeSetting("RungeKuttaMerson", False),
    ),
)


def prepare_free(problem: FreeProblem) -> None:
    """Build the model once (refusing what it cannot hold) before the first run's clock starts.

    Raises
    ------
    NotApplicable
        From :func:`.model.build`.
    """
    build(problem.kinematics.mechanism, *problem.start)


def accuracy(timestep: float) -> float:
    """The error-controlled series' accuracy at a ladder step (s)."""
    return ACCURACY_AT_1MS * (timestep / 1e-3) ** 4


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    setting: FreeSetting = rung.series.options
    mech = problem.kinematics.mechanism
    dt = rung.timestep
    om = build(mech, *problem.start)
    model = om.model
    if setting.fixed:
        manager = om.started_manager(setting.method, fixed_step=dt)
    else:
        manager = om.started_manager(setting.method, accuracy=accuracy(dt))
    state = om.state
    known = conservative(mech) and not mech.loads
    recorder = FrameRecorder(problem, om.tree.cuts)

    def record(j: int, state) -> str:
        model.realizeVelocity(state)
        frames = om.frames(state)
        energy = model.calcKineticEnergy(state) + model.calcPotentialEnergy(state) if known else math.nan
        return recorder.record(frames, j, float(energy))

    failure = record(0, state)
    steps = 0
    for j, count in enumerate(rung.counts, start=1):
        if failure:
            break
        steps += count
        try:
            state = manager.integrate(steps * dt)
        except RuntimeError as error:  # Simbody gave up (a step it could not take): the run stops here
            failure = " ".join(str(error).split())[:200]
            break
        failure = record(j, state)
    settings = {
        **rung.settings,
        "accuracy": math.nan if setting.fixed else accuracy(dt),
    }
    notes = f"OpenSim free motion, {rung.series.integrator}, dt = {dt:g} s."
    columns = {} if setting.fixed else {"accuracy": accuracy(dt)}
    return Run(recorder.trajectory(MODE, settings, notes), failure, columns=columns)
