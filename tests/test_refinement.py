"""Refinement: a dynamic mode (or a force source) whose error falls short of its
stated order is run again with its finest step halved (``runner.REFINEMENTS``
times at most) before it is judged, so that a ladder not yet in its asymptotic
range near a singular configuration is told from a lower order; what stays short,
or breaks down at the finer step, is the engine's measured limitation (fuzz).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DATA, MODELS

from xcheck import api, engines
from xcheck.fuzz import _engine_limitation, _force_origin
from xcheck.ladder import Run, Series
from xcheck.results import trajectory_from_solution
from xcheck.runner import REFINEMENTS
from xcheck.tolerances import Tolerance

#: the toy's coarsest time step (s) and its runs; each refinement halves the finest
COARSEST, RUNGS = 4e-3, 3


def pre_asymptotic(k: int) -> float:
    """A first-order error (relative to the size) at rung ``k`` (0 the coarsest) whose
    default ladder shows order log2(6/5) = 0.26 between its two finest steps, then
    order 1 below them."""
    return {0: 8e-5, 1: 6e-5}.get(k, 5e-5 * 2.0 ** (2 - k))


def low_order(k: int) -> float:
    """An error that falls at order 0.2 at every step: short of 1 whatever the step."""
    return 5e-5 * 2.0 ** (-0.2 * (k - 2))


class Laddered(engines.Engine):
    """A driven-dynamics toy on the core's ladder: one series from COARSEST over RUNGS
    runs, each run the native solution at the compared times with every position
    moved along x by ``error(k)`` x size, k its rung (0 the coarsest)."""

    name = "ladder"
    title = "a toy ladder"
    error = staticmethod(pre_asymptotic)
    modes = (
        engines.Mode(
            "ladder-dynamic",
            "dynamic",
            Tolerance(math.nan, math.nan, math.nan, math.nan, "the toy: judged by its order"),
            orders={c: 1.0 for c in ("position", "velocity", "acceleration", "angle", "omega", "alpha")},
        ),
    )

    def dynamic_series(self, mode, problem):
        return (Series("toy", "none", timestep=COARSEST, rungs=RUNGS),)

    def run_dynamic_once(self, mode, prepared, problem, rung):
        k = round(math.log2(problem.rung(rung.series, 0).timestep / rung.timestep))
        kinematics = problem.kinematics
        native = kinematics.solve(*problem.window.inputs(kinematics, problem.times))
        trajectory = trajectory_from_solution(native, source=mode)
        shift = np.array([self.error(k) * kinematics.system.size, 0.0])
        for states in (*trajectory.bodies.values(), *trajectory.points.values()):
            states["position"] = states["position"] + shift
        trajectory.times = problem.times
        trajectory.settings.update(timestep=rung.timestep, series=rung.series.key)
        return Run(trajectory)


class LowOrder(Laddered):
    name = "lower"
    error = staticmethod(low_order)
    modes = (engines.Mode("lower-dynamic", "dynamic", Laddered.modes[0].tolerance, Laddered.modes[0].orders),)


@pytest.fixture
def toys():
    registered = [engines.register(engine) for engine in (Laddered, LowOrder)]
    yield registered
    for engine in registered:
        engines.unregister(engine.name)


def test_a_pre_asymptotic_ladder_is_refined_and_then_passes(toys):
    run = api.run(MODELS / "fourbar.toml", "ladder-dynamic", samples=21)
    outcome = run.outcomes["ladder-dynamic"]
    position = outcome.categories.set_index("category").loc["position"]
    assert outcome.passed, position.basis
    assert position.refinements == 1
    assert position.step == pytest.approx(position.coarse_step / 2)  # the finest step halved
    assert position.observed_order == pytest.approx(1.0, abs=1e-6)
    assert position.relative == pytest.approx(pre_asymptotic(RUNGS), rel=1e-6)
    assert "halved once" in position.basis and "position 0.263; position 1" in position.basis
    # the study carries the default ladder and the refinement
    steps = sorted(outcome.result.study.timestep, reverse=True)
    assert len(steps) == RUNGS + 1 and steps == pytest.approx([steps[0] / 2**k for k in range(RUNGS + 1)])


def test_a_lower_order_stays_short_and_is_the_engines_limitation(toys):
    run = api.run(MODELS / "fourbar.toml", "lower-dynamic", samples=21)
    outcome = run.outcomes["lower-dynamic"]
    categories = outcome.categories
    failing = categories[~categories.passed.astype(bool)]
    assert not outcome.passed and list(failing.category) == ["position"]
    assert int(failing.refinements.iloc[0]) == REFINEMENTS
    assert failing.observed_order.iloc[0] == pytest.approx(0.2, abs=1e-6)
    steps = sorted(outcome.result.study.timestep, reverse=True)
    assert failing.step.iloc[0] == pytest.approx(steps[0] / 2 ** (RUNGS - 1 + REFINEMENTS))
    assert "stated order" in _engine_limitation(failing, "lower-dynamic")


def test_pymunk_reactions_beyond_their_bound_pass_by_their_convergence():
    """Fuzz case s1-00168 (a Scotch yoke at 19 m): pymunk's reactions 0.25 off at its
    step, 0.12 at half of it (order 1.0, as its impulses' first order predicts)."""
    run = api.run(DATA / "fuzz-scotch-yoke-pymunk-reactions.toml", "pymunk-dynamic", samples=21)
    row = run.force_table.set_index("engine").loc["pymunk"]
    assert row.ok and row.passed, row.basis
    assert row.refinements == 1 and "halved once: 0.248, 0.122" in row.basis
    assert 0.07 < row.max_rel < row.tolerance


def test_the_report_says_why_the_reactions_passed(tmp_path):
    from typer.testing import CliRunner

    from xcheck.cli import app

    path = DATA / "fuzz-scotch-yoke-pymunk-reactions.toml"
    args = ["run", str(path), "--engines", "pymunk-dynamic", "--samples", "21", "--no-gif", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = (tmp_path / "fuzz-scotch-yoke-pymunk-reactions.md").read_text(encoding="utf-8")
    assert "`pymunk`: beyond its bound 0.07 at its step; the error with the step halved once: 0.248, 0.122" in report


def test_pymunk_reactions_that_break_down_when_refined_are_its_limitation():
    """Fuzz case s1-00083 (a slider-crank whose rod is far longer than its crank):
    pymunk's reactions 8.6e6 times the native scale, and its scene comes apart at
    half the step: the engine's limitation, with the reason."""
    run = api.run(DATA / "fuzz-slider-crank-pymunk-breaks.toml", "pymunk-dynamic", samples=21)
    row = run.force_table.set_index("engine").loc["pymunk"]
    assert row.ok and not row.passed
    assert "came apart" in row.refinement_failure and "came apart" in row.basis
    assert _force_origin(row) == "engine"


@pytest.mark.parametrize(
    "mode",
    ["mujoco-dynamic", "pinocchio-dynamic", "pymunk-dynamic", "exudyn-dynamic", "pybullet-dynamic", "drake-dynamic"],
)
def test_every_driven_engine_runs_a_refinement_at_half_its_finest_step(mode):
    """A ladder's ``refine(1)`` runs the compared series once more, at half the
    ladder's finest step, and that run is the compared one, with the ladder's
    runs after it, on the four-bar."""
    from xcheck.kinematics import Kinematics
    from xcheck.model import load_mechanism

    engine = engines.engine_of(mode)
    if engine.available():
        pytest.skip(engine.available())
    kinematics = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
    kinematics.assemble()
    ladder = engine.dynamic_ladder(mode, kinematics)
    default = ladder.run()
    finer = ladder.refine(1)
    assert default.ok and finer.ok, finer.reason
    step, series = (default.trajectories[0].settings[k] for k in ("timestep", "series"))
    runs = [(t.settings["timestep"], t.settings["series"]) for t in finer.trajectories]
    assert runs[0] == (pytest.approx(step / 2, rel=1e-12), series)
    assert len(finer.summary) == len(default.summary) + 1


class OwnLadder(engines.Engine):
    """A plug-in that runs its own driven ladder in ``run`` (no ``run_dynamic_once``):
    the native sweep, positions moved by ``low_order`` at each of three steps."""

    name = "ownladder"
    modes = (engines.Mode("ownladder-dynamic", "dynamic", Laddered.modes[0].tolerance, Laddered.modes[0].orders),)

    def run(self, mode, kinematics, *, native, samples, branch=None):
        from xcheck.ladder import convergence_study
        from xcheck.results import ModeResult

        steps = (1e-3, 2e-3, 4e-3)
        trajectories = []
        for k, step in zip((2, 1, 0), steps):
            trajectory = trajectory_from_solution(native, source=mode)
            shift = np.array([low_order(k) * kinematics.system.size, 0.0])
            for states in (*trajectory.bodies.values(), *trajectory.points.values()):
                states["position"] = states["position"] + shift
            trajectory.settings.update(timestep=step, series="own")
            trajectories.append(trajectory)
        errors = [low_order(k) for k in (2, 1, 0)]
        study = convergence_study(["own"] * 3, steps, errors, ["ok"] * 3)
        return ModeResult(mode, kinematics.mechanism.name, True, trajectories=trajectories, study=study)


def test_an_engine_with_its_own_ladder_is_judged_and_not_refined():
    """The runner asks an engine without ``run_dynamic_once`` for its ``run`` only (no
    argument beyond the contract's) and says why it did not refine a short order."""
    engines.register(OwnLadder)
    try:
        run = api.run(MODELS / "fourbar.toml", "ownladder-dynamic", samples=21)
    finally:
        engines.unregister("ownladder")
    outcome = run.outcomes["ownladder-dynamic"]
    assert outcome.ok, outcome.reason
    position = outcome.categories.set_index("category").loc["position"]
    assert not position.passed and position.observed_order == pytest.approx(0.2, abs=1e-6)
    assert "not refined: the engine runs its own ladder (it has no run_dynamic_once)" in position.basis
