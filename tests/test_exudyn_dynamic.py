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
from conftest import MODELS, run_dynamic

pytest.importorskip("exudyn")

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402


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
