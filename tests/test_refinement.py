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
from xcheck.ladder import convergence_study
from xcheck.results import ModeResult, trajectory_from_solution
from xcheck.runner import REFINEMENTS
from xcheck.tolerances import Tolerance

#: the toy's time steps (s), coarsest first; each refinement halves the finest
LADDER = (4e-3, 2e-3, 1e-3)


def pre_asymptotic(step: float) -> float:
    """A first-order error (relative to the size) whose default ladder shows order
    log2(6/5) = 0.26 between its two finest steps, then order 1 below them."""
    return {4e-3: 8e-5, 2e-3: 6e-5}.get(step, 5e-5 * step / 1e-3)


def low_order(step: float) -> float:
    """An error that falls at order 0.2 at every step: short of 1 whatever the step."""
    return 5e-5 * (step / 1e-3) ** 0.2


class Laddered(engines.Engine):
    """A driven-dynamics toy: the native sweep with every position moved along x by
    ``error(step)`` x size, for each step of its ladder (or of a refinement)."""

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

    def run(self, mode, kinematics, *, native, samples, branch=None, refine=0):
        steps = (LADDER[-1] / 2**refine,) if refine else LADDER[::-1]
        trajectories = []
        for step in steps:
            trajectory = trajectory_from_solution(native, source=mode)
            shift = np.array([self.error(step) * kinematics.system.size, 0.0])
            for states in (*trajectory.bodies.values(), *trajectory.points.values()):
                states["position"] = states["position"] + shift
            trajectory.settings.update(timestep=step, series="toy")
            trajectories.append(trajectory)
        study = convergence_study(["toy"] * len(steps), steps, [self.error(s) for s in steps], ["ok"] * len(steps))
        return ModeResult(mode, kinematics.mechanism.name, True, trajectories=trajectories, study=study)


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
    assert position.step == pytest.approx(LADDER[-1] / 2) and position.coarse_step == pytest.approx(LADDER[-1])
    assert position.observed_order == pytest.approx(1.0, abs=1e-6)
    assert position.relative == pytest.approx(pre_asymptotic(LADDER[-1] / 2), rel=1e-6)
    assert "halved once" in position.basis and "position 0.263; position 1" in position.basis
    # the study carries the default ladder and the refinement
    assert sorted(outcome.result.study.timestep) == pytest.approx(sorted([*LADDER, LADDER[-1] / 2]))


def test_a_lower_order_stays_short_and_is_the_engines_limitation(toys):
    run = api.run(MODELS / "fourbar.toml", "lower-dynamic", samples=21)
    outcome = run.outcomes["lower-dynamic"]
    categories = outcome.categories
    failing = categories[~categories.passed.astype(bool)]
    assert not outcome.passed and list(failing.category) == ["position"]
    assert int(failing.refinements.iloc[0]) == REFINEMENTS
    assert failing.observed_order.iloc[0] == pytest.approx(0.2, abs=1e-6)
    assert failing.step.iloc[0] == pytest.approx(LADDER[-1] / 2**REFINEMENTS)
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
    """``refine=1`` runs the compared series once, at half the default ladder's
    finest step, and that run stays within the mode's verdict on the four-bar."""
    from xcheck.kinematics import Kinematics
    from xcheck.model import load_mechanism

    engine = engines.engine_of(mode)
    if engine.available():
        pytest.skip(engine.available())
    kinematics = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
    kinematics.assemble()
    native = kinematics.solve(np.zeros((1, 1)), np.zeros((1, 1)))
    default = engine.run(mode, kinematics, native=native, samples=21)
    finer = engine.run(mode, kinematics, native=native, samples=21, refine=1)
    assert default.ok and finer.ok, finer.reason
    step, series = (default.trajectories[0].settings[k] for k in ("timestep", "series"))
    runs = [(t.settings["timestep"], t.settings["series"]) for t in finer.trajectories]
    assert runs[0] == (pytest.approx(step / 2, rel=1e-12), series)
    assert all(s == pytest.approx(step / 2, rel=1e-12) for s, _ in runs)  # no other run of the ladder
