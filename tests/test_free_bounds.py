"""Every free-motion run is bounded before it starts, and a run that fails is a result: a
duration between output steps refused with the nearest valid ones (the CLI and the API
alike), a motion beyond the work budget or the outputs' bound refused up front with the
figure it would need, a run that goes non-finite the ladder's entry with its reason."""

from __future__ import annotations

import types

import numpy as np
import pytest
from conftest import DATA, MODELS, invoke

import xcheck
from xcheck import Kinematics, load_mechanism
from xcheck.errors import InputError

SPRING = DATA / "free-slider-crank-spring.toml"  # outputs every 0.01 s, 2 s


def _one_error_line(result) -> str:
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("xcheck: error: "), result.stderr
    return lines[0]


@pytest.mark.parametrize("duration, nearest", [("0.014", "0.01 s or 0.02 s"), ("0.015", "0.01 s or 0.02 s")])
def test_a_duration_between_output_steps_is_refused_with_the_nearest(duration, nearest):
    line = _one_error_line(invoke("simulate", str(SPRING), "--duration", duration, "--engines", "native"))
    expected = f"expected a whole number of output steps (0.01 s), e.g. {nearest}, found {duration} s"
    assert line.endswith(expected), line
    with pytest.raises(InputError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        xcheck.simulate(SPRING, duration=float(duration))


def test_a_motion_beyond_the_work_budget_is_refused_up_front_with_the_figure(tmp_path):
    """1 s at outputs every microsecond: two million outputs, each two evaluations at least."""
    path = tmp_path / "fine.toml"
    text = SPRING.read_text(encoding="utf-8")
    path.write_text(text.replace("duration = 2\noutput_step = 0.01", "duration = 1\noutput_step = 1e-6"), "utf-8")
    line = _one_error_line(invoke("simulate", str(path), "--engines", "native", "--no-report"))
    assert "expected a motion the DOP853 reference can follow within its work budget (1e+08" in line, line
    assert "found one its first two runs would need" in line and "1000000 outputs" in line, line


def test_a_duration_beyond_the_outputs_bound_is_refused():
    line = _one_error_line(invoke("simulate", str(SPRING), "--duration", "1e6", "--engines", "native"))
    assert "expected at most 2e+07 output values" in line and "found 100000001 outputs over 1e+06 s" in line, line


def test_a_run_that_goes_non_finite_is_the_ladders_entry_and_the_ladder_goes_on(monkeypatch):
    """The first (coarsest) run blows up: its entry says where, and the finer runs converge."""
    import xcheck.dynamics._free as free

    errors = {0.004: None, 0.002: 1e-6, 0.001: 1e-7, 0.0005: 1e-8}  # m; None: the run blew up

    def fake(kinematics, start, duration, output_step, step, compiled=True):
        q = np.zeros((3, kinematics.system.n))
        error = errors[round(step, 9)]
        failure = "the state went non-finite at t = 0.5 s" if error is None else ""
        q[:, 0] = 0.0 if error is None else error
        times = np.arange(3) * 0.5
        return types.SimpleNamespace(q=q, step=step, seconds=0.0, times=times, statistics={}, failure=failure)

    monkeypatch.setattr(free, "simulate_free", fake)
    kin = Kinematics(load_mechanism(MODELS / "benchmarks/iftomm-a02.toml"))
    reference = free.free_reference(kin, free.release_state(kin), 1.0, 0.5, tolerance=1e-7, first_step=0.004)
    statuses = [entry["status"] for entry in reference.ladder]
    assert statuses[:4] == ["the state went non-finite at t = 0.5 s"] + ["ok"] * 3
    assert len(statuses) == 6 and all(s.startswith("round-off") for s in statuses[4:])  # the kept run, moved twice
    assert reference.converged and reference.motion.step == 0.0005


def test_a_dop853_runs_budget_counts_its_projections_and_least_squares_solves():
    """A02 over 2 s, two singular passes: the run's work counts each step's projection (and
    the dense least-squares solves near the passes) beside its evaluations, so a budget of its
    evaluations alone stops it, with its reason."""
    from xcheck.dynamics._adaptive import integrate_adaptive
    from xcheck.dynamics._free import PROJECTION_ITERATIONS, _Dynamics, release_state
    from xcheck.dynamics._free_compiled import Packed

    kin = Kinematics(load_mechanism(MODELS / "benchmarks/iftomm-a02.toml"))
    start, packed = release_state(kin), Packed(_Dynamics(kin))
    run = integrate_adaptive(packed, start.q, start.qd, 200, 0.01, 1e-10, 10**6)
    assert not run.failure and len(run.passes) == 2 and run.crossings >= 2
    projections = run.accepted + 201  # after every step and at every output
    assert run.cost >= run.evaluations + 3 * (1 + PROJECTION_ITERATIONS) * projections, (run.cost, run.evaluations)
    short = integrate_adaptive(packed, start.q, start.qd, 200, 0.01, 1e-10, run.evaluations)
    assert short.failure.startswith("its work budget was spent at t = "), short.failure
    assert short.cost >= run.evaluations and len(short.q) < 201
