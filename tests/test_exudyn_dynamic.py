"""Exudyn in driven dynamics (exudyn-dynamic) against the native solution.

Measured here with Exudyn 1.13.6 (2026-11-25, ``xcheck run all --engines exudyn``):
positions and angles at round-off on every model with angle drivers (at most
3.6e-15 of the size, 8.4e-15 rad: the index-3 constraints hold to Newton's 1e-10);
velocities of order 2.0 (fourbar: 1.40e-5, 3.49e-6, 8.73e-7 relative at 25, 50,
100 steps per sample); accelerations 5.7e-3, 7.0e-4, 1.2e-5 relative, the
coarser steps carrying generalized-alpha's start-up transient.
"""

from __future__ import annotations

import math

import pytest
from conftest import DATA, MODELS, run_dynamic

pytest.importorskip("exudyn")

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.engines import NotApplicable, with_unit_mass  # noqa: E402


def _kinematics(name: str) -> Kinematics:
    kin = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
    kin.assemble()
    return kin


def test_fourbar_positions_at_round_off_velocities_at_second_order():
    result = run_dynamic("exudyn-dynamic", _kinematics("fourbar"))
    assert result.ok, result.reason
    summary = result.summary
    assert (summary["status"] == "ok").all(), summary
    assert summary["position_error"].max() <= 1e-13  # measured 1.1e-15 m (size about 1 m)
    assert summary["angle_error"].max() <= 1e-13  # measured 2.7e-15 rad
    assert summary["input_error"].max() <= 1e-13  # the driver constraint holds the motion law
    best = summary[summary["setting"] == "best"].sort_values("timestep", ascending=False)
    errors = list(best["velocity_error"])
    assert all(1.9 <= math.log2(errors[i] / errors[i + 1]) <= 2.1 for i in range(2)), errors
    assert errors[-1] <= 1e-6  # measured 8.73e-7 relative
    compared = result.trajectories[0].settings
    assert compared["series"] == "best" and compared["timestep"] == best["timestep"].min()


def test_a_slide_driver_is_not_applicable():
    with pytest.raises(NotApplicable, match="driver r_y: a slide"):
        run_dynamic("exudyn-dynamic", _kinematics("task-2-2"))


def test_newton_on_a_heavy_kilometre_four_bar_stops_at_its_round_off():
    """A crank-rocker of 3 to 9 t at 1 km (moments about 2e10 N m): Newton's residual in N
    and N m cannot fall to 1e-10 (eps times the moments is 5e-6), and Newton failed at the
    first step. With its absolute tolerance at least NEWTON_ROUND_OFF eps times the moment
    scale every run converges, positions at round-off (measured 2.5e-13 to 2.8e-13 m, of 1000 m) and
    rates at second order; on every bundled model that floor is below 1e-10 (slider-crank,
    the heaviest: 1.8e-11), so their runs are as before."""
    from xcheck.dynamics import force_floors
    from xcheck.engines.exudyn.model import NEWTON_ROUND_OFF, Setting, newton_floor, solver_settings
    from xcheck.ladder import DrivenProblem
    from xcheck.results import scale_floors

    kin = Kinematics(load_mechanism(DATA / "km-fourbar.toml"))
    problem = DrivenProblem.of(kin)
    floors = scale_floors(kin.mechanism, *problem.window.inputs(kin, problem.times)[1:])
    floor = newton_floor(kin.mechanism, floors)
    assert floor == pytest.approx(NEWTON_ROUND_OFF * 2.220446049250313e-16 * force_floors(kin.mechanism, floors)["N m"])
    assert 1e-4 < floor < 1e-2
    assert (
        solver_settings(
            Setting(0.9, newton_tolerance=1e-10), 1e-3, 1.0, 0.1, floor
        ).timeIntegration.newton.absoluteTolerance
        == floor
    )
    result = run_dynamic("exudyn-dynamic", kin)
    assert result.ok and (result.summary["status"] == "ok").all(), result.summary
    best = result.summary[result.summary["setting"] == "best"].sort_values("timestep", ascending=False)
    assert best["position_error"].max() <= 1e-10 * kin.mechanism.size
    errors = list(best["velocity_error"])
    assert all(1.8 <= math.log2(errors[i] / errors[i + 1]) <= 2.2 for i in range(2)), errors
    for name in ("fourbar", "slider-crank", "two-body-arm"):
        model = _kinematics(name)
        ahead = DrivenProblem.of(model)
        ahead_floors = scale_floors(model.mechanism, *ahead.window.inputs(model, ahead.times)[1:])
        assert newton_floor(with_unit_mass(model.mechanism), ahead_floors) < 1e-10, name
