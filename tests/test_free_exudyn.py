"""Exudyn in free motion (exudyn-free) against the native reference: the IFToMM
pendulum (A01) and double four-bar (A02) over 2 s, and tests/data/free-mixed.toml
(a pin-in-slot, a prismatic joint on a moving body, offset centres of mass,
constant, ramped and harmonic forces and torques, a torque across a joint, two
spring-dampers and a rotational one) over its 0.5 s.

Measured here with Exudyn 1.13.6 (2026-11-25, ``xcheck simulate iftomm-a01
--duration 2 --engines native,exudyn-free``): on A01 Exudyn's defaults
(generalized-alpha, spectral radius 0.9, index 3) 2.38e-5, 5.95e-6, 1.49e-6 m at
dt = 1, 0.5, 0.25 ms (order 2.00), loops closed to 1.2e-12 .. 7.5e-14 m; index-2
constraints 1.47e-5 .. 9.2e-7 m with the loops drifting 2.2e-6 .. 1.4e-7 m. On
A02, through its singular passes at 0.71 and 1.23 s, the defaults 2.97e-5,
7.42e-6, 1.86e-6 m (order 2.00), Newton to 1e-10 the same errors with the loops
closed to 9e-16 m, while Newton to 1e-12 fails at the first singular pass
(t = 0.714 s) at every step. On free-mixed the defaults 2.06e-3, 5.16e-4,
1.29e-4 m (order 2.00; a fast, stiff mechanism), loops 1.7e-14 m at 0.5 ms.
"""

from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import DATA, MODELS, run_free

pytest.importorskip("exudyn")

from xcheck import Kinematics, engines, load_mechanism  # noqa: E402
from xcheck.dynamics._free import simulate  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.exudyn.free import FREE_SERIES  # noqa: E402
from xcheck.engines.exudyn.model import refuse  # noqa: E402

MODE = "exudyn-free"


def _reference(path, duration: float | None = None):
    kin = Kinematics(load_mechanism(path))
    kin.assemble()
    return kin, simulate(kin, duration=duration)


def _orders(part) -> list[float]:
    errors = list(part.sort_values("timestep", ascending=False)["position_error"])
    return [math.log2(errors[i] / errors[i + 1]) for i in range(len(errors) - 1)]


def _row(summary, setting: str, timestep: float):
    return summary[(summary["setting"] == setting) & (summary["timestep"] == timestep)].iloc[0]


def test_registered_as_a_free_mode():
    engine = engines.engine("exudyn")
    assert engine.available() == ""
    assert [(m.name, m.kind) for m in engine.modes] == [("exudyn-dynamic", "dynamic"), ("exudyn-free", "free")]
    assert engines.engine_of("exudyn-free") is engine


@pytest.fixture(scope="module")
def pendulum():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a01.toml", 2.0)
    return run_free(MODE, kin, reference)


def test_pendulum_converges_at_second_order(pendulum):
    summary = pendulum.summary
    assert pendulum.ok and (summary["status"] == "ok").all(), summary
    for setting, part in summary.groupby("setting"):
        assert all(1.9 <= p <= 2.1 for p in _orders(part)), (setting, list(part["position_error"]))
    default = _row(summary, "default", 2.5e-4)
    assert default["position_error"] <= 1.6e-6  # measured 1.49e-6 m
    assert default["loop_drift"] <= 1e-12  # measured 7.5e-14 m: exact index-3 joints
    index2 = _row(summary, "index-2", 2.5e-4)
    assert 5e-8 <= index2["loop_drift"] <= 2e-7  # measured 1.4e-7 m: velocity-level constraints drift
    assert list(pendulum.study.columns) == ["series", "timestep", "position_error", "status", "order", "verdict"]
    assert len(summary) == len(FREE_SERIES) * 3


def test_double_fourbar_passes_the_singular_positions_on_its_branch():
    kin, reference = _reference(MODELS / "benchmarks" / "iftomm-a02.toml", 2.0)
    assert len([t for t in reference.motion.singular_passes if t < 2.0]) == 2  # 0.71 and 1.23 s
    chosen = [s for s in FREE_SERIES if s.key in ("default", "newton-1e-12")]
    result = run_free(MODE, kin, reference, series=chosen)
    summary = result.summary
    default = summary[summary["setting"] == "default"]
    assert (default["status"] == "ok").all(), default
    assert all(1.9 <= p <= 2.1 for p in _orders(default)), list(default["position_error"])
    assert _row(summary, "default", 2.5e-4)["position_error"] <= 2e-6  # measured 1.86e-6 m
    # Newton cannot reach 1e-12 at the first singular pass at 0.5 and 0.25 ms; at 1 ms it depends on the
    # initial state's last bits (it fails from the native state before polishing, and runs through from
    # the polished one, 2.97e-5 m off as the default setting): a fragile setting, not a converging one
    newton = summary[summary["setting"] == "newton-1e-12"]
    failed = newton[newton["status"] != "ok"]
    assert {5e-4, 2.5e-4} <= set(failed["timestep"]), newton
    assert all(status.startswith("Newton failed at t = 0.71") for status in failed["status"]), newton
    assert result.study[result.study["series"] == "newton-1e-12"]["order"].isna().all()


def test_every_joint_type_springs_dampers_and_loads_with_laws_converge_at_second_order():
    kin, reference = _reference(DATA / "free-mixed.toml")
    chosen = [s for s in FREE_SERIES if s.key == "default"]
    summary = run_free(MODE, kin, reference, series=chosen).summary
    assert (summary["status"] == "ok").all(), summary
    assert all(1.9 <= p <= 2.1 for p in _orders(summary)), list(summary["position_error"])
    assert _row(summary, "default", 2.5e-4)["position_error"] <= 1.5e-4  # measured 1.29e-4 m
    assert summary["loop_drift"].max() <= 1e-12  # measured 1.7e-14 m at 0.5 ms
    assert summary["energy_drift"].isna().all()  # dampers and time laws do work: no energy balance without it


def test_a_massless_body_is_not_applicable():
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a02.toml"))
    mech = kin.mechanism
    bodies = tuple(dataclasses.replace(b, mass=0.0) if b.name == "coupler1" else b for b in mech.bodies)
    massless = Kinematics(dataclasses.replace(mech, bodies=bodies))
    with pytest.raises(NotApplicable, match="massless body coupler1"):
        refuse(massless.mechanism)  # what the mode's prepare_free calls before any run


def test_spring_and_damper_on_a_guide_converge_at_second_order():
    """tests/data/spring-block.toml (a block on a prismatic guide to the ground, spring
    and damper, 2 s): measured 1.55e-6, 3.88e-7, 9.71e-8 m at 1, 0.5, 0.25 ms (order
    2.00; pymunk-free is first order there, 6.3e-5 m at 0.25 ms)."""
    kin, reference = _reference(DATA / "spring-block.toml")
    chosen = [s for s in FREE_SERIES if s.key == "default"]
    summary = run_free(MODE, kin, reference, series=chosen).summary
    assert (summary["status"] == "ok").all(), summary
    assert all(1.9 <= p <= 2.1 for p in _orders(summary)), list(summary["position_error"])
    assert _row(summary, "default", 2.5e-4)["position_error"] <= 1.1e-7  # measured 9.71e-8 m
