"""DART in free motion (mode ``dart-free``): the world of :func:`.model.build`
released at the native reference's initial state and stepped by DART (semi-implicit
Euler, the loop constraints as a velocity-level LCP with ERP drift correction);
the ladder and its judgement are :func:`xcheck.ladder.free_study`'s.

The series: each loop cut closed by a ``RevoluteJointConstraint`` (``revolute``,
what a user closing a revolute loop reaches for) and by a ``BallJointConstraint``
(``ball``), both at DART's defaults (ERP 0.01, CFM 1e-5, Dantzig's LCP solver).
"""

from __future__ import annotations

from xcheck.engines._frames import FrameRecorder
from xcheck.engines._tree import gravity_only, tree_frames
from xcheck.ladder import FreeProblem, Run, Rung, Series

from .model import build

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "dart-free"
FREE_SERIES = (
    Series("revolute", "semi-implicit Euler, LCP, RevoluteJointConstraint cuts", "revolute"),
    Series("ball", "semi-implicit Euler, LCP, BallJointConstraint cuts", "ball"),
)


def prepare_free(problem: FreeProblem) -> None:
    """Refuse what the DART model cannot hold, and import dartpy before the first run's clock starts.

    Raises
    ------
    NotApplicable
        :func:`~xcheck.engines._tree.gravity_only`'s and :func:`~xcheck.engines._tree.tree_frames`'s.
    """
    import dartpy  # noqa: F401 - imported before the clocks start

    mech = problem.kinematics.mechanism
    gravity_only(mech, "DART")
    tree_frames(mech, problem.start[0], "DART")


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    dt = rung.timestep
    model = build(problem.kinematics.mechanism, *problem.start, dt, cut=rung.series.options)
    recorder = FrameRecorder(problem, model.tree.cuts)

    def record(j: int) -> str:
        energy = model.skeleton.computeKineticEnergy() + model.skeleton.computePotentialEnergy()
        return recorder.record(model.frames(), j, float(energy))

    failure = record(0)
    for j, count in enumerate(rung.counts, start=1):
        if failure:
            break
        for _ in range(count):
            model.world.step()
        failure = record(j)
    settings = rung.settings
    notes = f"DART free motion, {rung.series.integrator}, dt = {dt:g} s."
    return Run(recorder.trajectory(MODE, settings, notes), failure)
