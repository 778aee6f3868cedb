"""PyBullet in free motion (pybullet-free) against the native reference, on the
IFToMM pendulum (A01) and double four-bar (A02) over 2 s, and on a loaded
four-bar of revolutes (tests/data/fourbar-loaded.toml: gravity, a force at a
coupler point, a torque, a spring-damper; 1 s).

Measured here with PyBullet 3.2.7 (2026-11-25), dt = 1, 0.5, 0.25 ms:
A01: 2.21e-3, 1.11e-3, 5.54e-4 m with either setting (first order, semi-implicit
Euler; no loop: drift 0). A02 (two singular passes in 2 s): default solver
(50 iterations, residual threshold 1e-7) 3.5e-4, 1.3e-4, 1.9e-5 m, loops open by
6.2e-6 .. 9.6e-7 m; best (residual threshold 0) 3.70e-6, 9.37e-7, 2.63e-7 m
(order 2.0, 1.8), loops within 2.5e-7 .. 2.8e-7 m; both stay on the parallelogram
branch. The loaded four-bar: 2.46e-3, 1.19e-3, 5.90e-4 m (order 1.04, 1.02).
"""

from __future__ import annotations

import math

import pytest
from conftest import DATA, MODELS

pytest.importorskip("pybullet")

from xcheck import Kinematics, engines, load_mechanism  # noqa: E402
from xcheck.dynamics._free import simulate  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.pybullet.free import build, p, run_free  # noqa: E402
from xcheck.simulation import simulate_all  # noqa: E402


def _reference(path, duration: float | None = None):
    kin = Kinematics(load_mechanism(path))
    kin.assemble()
    return kin, simulate(kin, duration=duration)


def _errors(summary, setting: str) -> list[float]:
    part = summary[summary["setting"] == setting].sort_values("timestep", ascending=False)
    return list(part["position_error"])


def _orders(errors: list[float]) -> list[float]:
    return [math.log2(errors[i] / errors[i + 1]) for i in range(len(errors) - 1)]


def test_registered_as_a_free_mode():
    engine = engines.engine("pybullet")
    assert [(m.name, m.kind) for m in engine.modes] == [("pybullet-free", "free")]
    assert engine.available() == ""


def test_pendulum_converges_at_first_order():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a01.toml", 2.0)
    result = run_free(kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all()
    for setting in ("default", "best"):
        errors = _errors(result.summary, setting)
        assert all(0.8 <= order <= 1.2 for order in _orders(errors)), (setting, errors)
        assert errors[-1] <= 1e-3  # measured 5.54e-4 m at 0.25 ms
    assert (result.summary["loop_drift"] == 0.0).all()  # a tree: no loop to open


@pytest.mark.slow
def test_double_fourbar_stays_on_the_branch_through_singular_passes():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a02.toml", 2.0)
    assert len(reference.motion.singular_passes) >= 2
    result = run_free(kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all(), result.summary["status"].tolist()
    best = _errors(result.summary, "best")
    assert best[0] <= 1e-5 and best[-1] <= 1e-6, best  # measured 3.70e-6 and 2.63e-7 m
    assert all(order >= 1.5 for order in _orders(best)), best  # measured 2.0, 1.8
    drift = result.summary[result.summary["setting"] == "best"]["loop_drift"]
    assert drift.max() <= 1e-6  # measured 2.8e-7 m
    default = _errors(result.summary, "default")
    assert all(d > b for d, b in zip(default, best)), (default, best)  # the default cut-off costs accuracy


@pytest.mark.slow
def test_loads_springs_and_dampers_converge_at_first_order():
    kin, reference = _reference(DATA / "fourbar-loaded.toml")
    result = run_free(kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all()
    errors = _errors(result.summary, "best")
    assert all(0.8 <= order <= 1.2 for order in _orders(errors)), errors
    assert errors[-1] <= 1.2e-3  # measured 5.90e-4 m at 0.25 ms


def test_prismatic_and_pin_in_slot_are_refused():
    kin = Kinematics(load_mechanism(MODELS / "slider-crank.toml"))
    client = p.connect(p.DIRECT)
    try:
        with pytest.raises(NotApplicable, match="'slide' is prismatic"):
            build(kin, client)
    finally:
        p.disconnect(client)
    kin = Kinematics(load_mechanism(DATA / "free-mixed.toml"))
    kin.assemble()
    result = simulate_all(kin, modes=["pybullet-free"], duration=0.02)
    assert "pin-in-slot" in result.not_applicable["pybullet-free"]
    assert "pybullet-free" not in result.outcomes
