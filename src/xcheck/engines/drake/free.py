"""Drake in free motion (mode ``drake-free``): the plant of :func:`.model.build`
released at the native reference's initial state and stepped by Drake's
discrete SAP solver; the ladder and its judgement are
:func:`xcheck.ladder.free_study`'s.

The series: the plant as a user builds it (``default``:
``MultibodyPlant(time_step)``, Drake's defaults) and at its best (``best``: the
same plant at a quarter of the steps). The time step is the one knob that
reaches the loops: the ball constraint's near-rigid parameter is fixed inside
Drake (beta 0.1, ``SapBallConstraint``), the plant's
``set_sap_near_rigid_threshold`` and ``set_discrete_contact_approximation``
act on contact only (on A02 over 2 s, kSap with beta 0 gave the defaults'
(lagged, beta 1) errors, drift and energy to every printed digit; over 1 s, so
did beta 1e-3 and 10 and the kSimilar approximation), and SAP's solver
tolerances are not in pydrake. The discrete scheme is first order (the new
velocities implicit in the constraints, joint damping and the near-rigid
compliance, the positions from the new velocities).

Measured with pydrake 1.51.1 (``xcheck simulate NAME --engines drake-free``, 2
shared cores), largest error over the outputs at dt = 1, 0.5, 0.25 ms (best:
0.25, 0.125, 0.0625 ms; A03 10, 5, 2.5 us and a quarter of them), CPU seconds
per simulated second:

- A01 pendulum, 10 s: 2.215e-3, 1.107e-3, 5.54e-4 m, best down to 1.38e-4 m,
  order 1.00 (PyBullet's semi-implicit Euler to four digits); energy drift
  1.35e-2 .. 8.4e-4 J; 0.013 .. 0.18 s.
- A02 double four-bar, 10 s, ten singular passes: on the parallelogram branch
  throughout, loops closed to 9e-8 .. 2.2e-9 m, energy drift 9.1e-2 .. 6.0e-3 J
  (first order), but the position error does not fall with the step: 6.9e-4,
  2.1e-4, 5.2e-4 m, best 5.2e-4, 3.1e-4, 8.6e-4 m (orders 1.7, -1.3, 0.7, -1.5);
  0.18 .. 2.7 s. Up to the first pass (0.714 s) the error falls as dt^2
  (7.2e-7, 1.8e-7, 4.5e-8 m at 0.7 s, dt = 0.5, 0.25, 0.125 ms); by 1.2 s, just
  before the second pass (1.228 s), it stops falling (6.9e-7, 3.5e-7, 2.9e-7
  m), and from then on a part that no step removes dominates and grows through
  the slow swing that follows (2.8 .. 3.4e-6 m at 2 s, 3.0 .. 3.6e-5 m at 3 s
  for each step). Cutting the loops elsewhere changes nothing in kind: a chain
  tree cut at the two ground pivots O2, O3 (through the anchor) converges to
  1.0 s (9.7e-7, 3.1e-7, 6.6e-8 m) and is erratic by 1.2 s (6.6e-7, 3.2e-7,
  1.27e-6 m: the finest step the worst). Where it comes from is not
  established: the loops' constraint rows turn dependent at the singular
  positions, where the fixed near-rigid regularisation and SAP's stopping
  tolerance (neither reachable from pydrake) may set the answer rather than
  the step.
- A03 Andrews' squeezer, 0.03 s: 3.42e-4, 1.71e-4, 8.54e-5 m, best down to
  2.13e-5 m, order 1.00 (PyBullet's figures); loops open by 1.1e-6 .. 4.4e-9 m
  (order 2); 23 .. 281 s.
"""

from __future__ import annotations

import math

from xcheck.engines._frames import FrameRecorder
from xcheck.ladder import FREE_STEPS, FreeProblem, Run, Rung, Series, conservative
from xcheck.topology import spanning_tree

from .model import apply_loads, build, drake, energy, refuse, set_state

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "drake-free"
FREE_SERIES = (Series("default", "discrete SAP"), Series("best", "discrete SAP, steps / 4", timestep=FREE_STEPS[0] / 4))


def prepare_free(problem: FreeProblem) -> None:
    """Refuse what the Drake model cannot hold, and import pydrake before the first run's clock starts.

    Raises
    ------
    NotApplicable
        :func:`.model.refuse`'s.
    """
    mech = problem.kinematics.mechanism
    refuse(mech, spanning_tree(mech))
    drake()


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    from pydrake.systems.analysis import Simulator

    kinematics = problem.kinematics
    mech = kinematics.mechanism
    dt = rung.timestep
    known = conservative(mech)  # the energy is E less the constant loads' potential
    timed = any(load.law is not None for load in mech.loads)
    model = build(kinematics, dt)
    set_state(model, kinematics, *problem.start)
    apply_loads(model, 0.0)
    simulator = Simulator(model.plant, model.context)
    model.context = simulator.get_mutable_context()
    recorder = FrameRecorder(problem, model.cuts)

    def record(j: int) -> str:
        frames = model.frames()
        return recorder.record(frames, j, energy(model, frames) if known else math.nan)

    failure, done = record(0), 0  # steps taken
    for j, count in enumerate(rung.counts, start=1):
        if failure:
            break
        n = done + count
        # Drake's discrete update at t = m dt takes the state from step m to m + 1: advancing
        # to half a step before n dt takes exactly n steps, whatever the round-off in m dt
        if timed:  # the loads at each step's start
            for m in range(done, n):
                apply_loads(model, m * dt)
                simulator.AdvanceTo((m + 0.5) * dt)
        else:
            simulator.AdvanceTo((n - 0.5) * dt)
        done = n
        failure = record(j)
    settings = rung.settings
    notes = f"Drake free motion, {rung.series.integrator}, dt = {dt:g} s."
    return Run(recorder.trajectory(MODE, settings, notes), failure)
