"""Newton in free motion (mode ``newton-free``): the model of :func:`.model.build`
released at the native reference's initial state and stepped by each of Newton's
solvers that takes a loop joint; the ladder and its judgement are
:func:`xcheck.ladder.free_study`'s.

The series, one per solver, each at its defaults on the CPU (warp, float32):
``mujoco`` (``SolverMuJoCo`` on MuJoCo's C library, contacts off), ``xpbd``
(``SolverXPBD``), ``featherstone`` (``SolverFeatherstone``: it ignores loop
joints, a finding; its rows show the loops coming apart) and ``semi-implicit``
(``SolverSemiImplicit``). ``SolverSteel`` is not a series (built as two
articulations, the four-bar's loop joint was refused: its parent must be in the
child's articulation). Each solver's warp kernels compile on its first use on a
machine (a minute or more, cached after in warp's kernel cache).
"""

from __future__ import annotations

from xcheck.engines._frames import FrameRecorder
from xcheck.engines._tree import gravity_only, tree_frames
from xcheck.ladder import FreeProblem, Run, Rung, Series

from .model import build, newton, solver

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "newton-free"
FREE_SERIES = (
    Series("mujoco", "SolverMuJoCo (MuJoCo C), float32", "mujoco"),
    Series("xpbd", "SolverXPBD, float32", "xpbd"),
    Series("featherstone", "SolverFeatherstone, float32", "featherstone"),
    Series("semi-implicit", "SolverSemiImplicit, float32", "semi-implicit"),
)


def prepare_free(problem: FreeProblem) -> None:
    """Refuse what the Newton model cannot hold, and import Newton before the first run's clock starts.

    Raises
    ------
    NotApplicable
        :func:`~xcheck.engines._tree.gravity_only`'s and :func:`~xcheck.engines._tree.tree_frames`'s.
    """
    mech = problem.kinematics.mechanism
    gravity_only(mech, "Newton")
    tree_frames(mech, problem.start[0], "Newton")
    newton()


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    module, _ = newton()
    dt = rung.timestep
    built = build(problem.kinematics.mechanism, *problem.start)
    model = built.model
    state, next_state, control = model.state(), model.state(), model.control()
    state.joint_q.zero_()
    state.joint_qd.assign(built.rates)
    module.eval_fk(model, state.joint_q, state.joint_qd, state)
    stepper = solver(rung.series.options, model)
    recorder = FrameRecorder(problem, built.tree.cuts)
    frames = built.frames(state)
    failure = recorder.record(frames, 0)
    for j, count in enumerate(rung.counts, start=1):
        if failure:
            break
        for _ in range(count):
            state.clear_forces()
            stepper.step(state, next_state, control, None, dt)
            state, next_state = next_state, state
        frames = built.frames(state, frames)
        failure = recorder.record(frames, j)
    settings = rung.settings
    notes = f"Newton free motion, {rung.series.integrator}, dt = {dt:g} s."
    return Run(recorder.trajectory(MODE, settings, notes), failure)
