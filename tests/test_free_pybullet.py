"""PyBullet in free motion (pybullet-free) against the native reference, on the
IFToMM pendulum (A01) and double four-bar (A02) over 2 s, and on a loaded
four-bar of revolutes (tests/data/fourbar-loaded.toml: gravity, a force at a
coupler point, a torque, a spring-damper; 1 s) and a block on a prismatic guide
(tests/data/spring-block.toml) or an inclined sleeve (tests/data/sleeve.toml).

Measured here with PyBullet 3.2.7 (2026-11-25), dt = 1, 0.5, 0.25 ms:
A01: 2.21e-3, 1.11e-3, 5.54e-4 m with either setting (first order, semi-implicit
Euler; no loop: drift 0). A02 (two singular passes in 2 s, at 0.714 and 1.228 s):
default solver (50 iterations, residual threshold 1e-7) 3.5e-4, 1.3e-4, 1.9e-5 m,
loops open by 6.2e-6 .. 9.6e-7 m; best (residual threshold 0) 3.66e-6, 9.15e-7,
2.29e-7 m (order 2.0), loops closed to 2.0e-13 .. 1.2e-14 m; both stay on the
parallelogram branch. The loaded four-bar: 2.46e-3, 1.19e-3, 5.90e-4 m (order
1.04, 1.02), loops open by 6.3e-5 .. 4e-6 m with either setting.
"""

from __future__ import annotations

import math

import pytest
from conftest import DATA, MODELS, assert_first_order, run_free

pytest.importorskip("pybullet")

from xcheck import Kinematics, engines, load_mechanism  # noqa: E402
from xcheck.dynamics._free import simulate  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.pybullet import model  # noqa: E402
from xcheck.engines.pybullet.model import p  # noqa: E402
from xcheck.simulation import simulate_all  # noqa: E402
from xcheck.topology import Topology, spanning_tree  # noqa: E402

MODE = "pybullet-free"


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
    assert [(m.name, m.kind) for m in engine.modes] == [("pybullet-dynamic", "dynamic"), ("pybullet-free", "free")]
    assert engine.available() == ""


def test_pendulum_converges_at_first_order():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a01.toml", 2.0)
    result = run_free(MODE, kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all()
    for setting in ("default", "best"):
        errors = _errors(result.summary, setting)
        assert all(0.8 <= order <= 1.2 for order in _orders(errors)), (setting, errors)
        assert errors[-1] <= 1e-3  # measured 5.54e-4 m at 0.25 ms
    assert (result.summary["loop_drift"] == 0.0).all()  # a tree: no loop to open
    assert result.summary["order"].dropna().between(0.9, 1.1).all()  # the ladder table shows the order


@pytest.mark.slow
def test_double_fourbar_stays_on_the_branch_through_singular_passes():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a02.toml", 2.0)
    assert len(reference.motion.singular_passes) >= 2
    result = run_free(MODE, kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all(), result.summary["status"].tolist()
    best = _errors(result.summary, "best")
    assert best[0] <= 1e-5 and best[-1] <= 6e-7, best  # measured 3.66e-6 and 2.29e-7 m
    assert all(1.8 <= order <= 2.2 for order in _orders(best)), best  # measured 2.0, 2.0
    drift = result.summary[result.summary["setting"] == "best"]["loop_drift"]
    assert drift.max() <= 1e-12  # measured 2.0e-13 m: no residual cut-off closes the loops to round-off
    default = _errors(result.summary, "default")
    assert all(d > b for d, b in zip(default, best)), (default, best)  # the default cut-off costs accuracy


@pytest.mark.slow
def test_loads_springs_and_dampers_converge_at_first_order():
    kin, reference = _reference(DATA / "fourbar-loaded.toml")
    result = run_free(MODE, kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all()
    errors = _errors(result.summary, "best")
    assert all(0.8 <= order <= 1.2 for order in _orders(errors)), errors
    assert errors[-1] <= 1.2e-3  # measured 5.90e-4 m at 0.25 ms


@pytest.mark.parametrize(
    ("name", "bound"),
    [
        ("spring-block", 1.2e-4),  # measured 2.46e-4, 1.23e-4, 6.2e-5 m (order 1.00)
        ("sleeve", 3.4e-4),  # measured 6.70e-4, 3.35e-4, 1.67e-4 m (order 1.00)
    ],
)
def test_prismatic_joints_on_the_tree_converge_at_first_order(name, bound):
    """tests/data/spring-block.toml (a block on a ground guide, spring k = 200 N/m and
    damper c = 4 N s/m, 2 s) and tests/data/sleeve.toml (a rod through an inclined
    sleeve: the line on the moving body, locked angle -30 deg, 1 s)."""
    kin, reference = _reference(DATA / f"{name}.toml")
    result = run_free(MODE, kin, reference)
    assert result.ok and (result.summary["status"] == "ok").all()
    errors = _errors(result.summary, "best")
    assert all(0.9 <= order <= 1.1 for order in _orders(errors)), errors
    assert errors[-1] <= bound  # at 0.25 ms


def test_pin_in_slot_and_sliding_cuts_are_refused(monkeypatch):
    kin = Kinematics(load_mechanism(DATA / "free-mixed.toml"))
    kin.assemble()
    result = simulate_all(kin, modes=["pybullet-free"], duration=0.02)
    assert "'slot' is a pin-in-slot" in result.not_applicable["pybullet-free"]
    assert "pybullet-free" not in result.outcomes
    kin = Kinematics(load_mechanism(MODELS / "slider-crank.toml"))
    topology = spanning_tree(kin.mechanism)
    slide = next(tj for tj in topology.tree if tj.joint.name == "slide")
    tree = tuple(tj for tj in topology.tree if tj is not slide)
    monkeypatch.setattr(model, "spanning_tree", lambda mechanism: Topology(tree, (*topology.cuts, slide.joint)))
    client = p.connect(p.DIRECT)
    try:
        with pytest.raises(NotApplicable, match="cut at the prismatic joint 'slide'"):
            model.build(kin, client)
    finally:
        p.disconnect(client)


@pytest.mark.parametrize("name", ["torsion-pendulum", "shaken-block"])
def test_rotational_springs_and_time_laws_converge_at_first_order(name):
    """A rotational spring-damper (torsion-pendulum) and a harmonic force along a
    prismatic guide (shaken-block) applied as external torques and forces before each
    step. Measured (2026-11-25): 2.58e-4, 1.29e-4, 6.44e-5 m and 2.42e-4, 1.21e-4,
    6.05e-5 m at dt = 1, 0.5, 0.25 ms with either setting: MuJoCo's Euler to three digits."""
    kin = Kinematics(load_mechanism(DATA / f"{name}.toml"))
    kin.assemble()
    assert_first_order(run_free(MODE, kin, simulate(kin)), 7e-5)  # 7e-5 m at 0.25 ms
