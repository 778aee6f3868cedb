"""MuJoCo's free motion (mode ``mujoco-free``) against the native reference on
the IFToMM benchmarks A01 (pendulum) and A02 (double four-bar), over 2 s.

Bounds come from the ladders measured here (MuJoCo 3, 2 cores), stated at each
assertion with the measured figures."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from conftest import DATA, MODELS, invoke, run_free

mujoco = pytest.importorskip("mujoco")

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.dynamics._free import simulate  # noqa: E402
from xcheck.engines.mujoco.dynamic import Setting  # noqa: E402
from xcheck.engines.mujoco.free import free_series  # noqa: E402
from xcheck.engines.mujoco.mjcf import layout, mjcf_text  # noqa: E402
from xcheck.engines.mujoco.model import free_model, joint_velocities  # noqa: E402
from xcheck.ladder import free_errors  # noqa: E402

STEPS = (1e-3, 5e-4, 2.5e-4)
MODE = "mujoco-free"


def _reference(name: str, duration: float):
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / f"{name}.toml"))
    return kin, simulate(kin, None, duration=duration)


@pytest.fixture(scope="module")
def a01():
    return _reference("iftomm-a01", 2.0)


@pytest.fixture(scope="module")
def a02():
    return _reference("iftomm-a02", 2.0)


def _rows(result, setting: str, integrator: str):
    rows = result.summary[(result.summary.setting == setting) & (result.summary.integrator == integrator)]
    return rows.sort_values("timestep", ascending=False)


def _orders(rows) -> np.ndarray:
    errors, steps = rows.position_error.to_numpy(), rows.timestep.to_numpy()
    return np.log(errors[:-1] / errors[1:]) / np.log(steps[:-1] / steps[1:])


def test_initial_velocity_closes_the_loops(a02):
    """qvel from the native body rates satisfies MuJoCo's velocity constraints."""
    from xcheck.engines.mujoco.mjcf import joint_coordinates
    from xcheck.engines.mujoco.oracle import Oracle

    kin, ref = a02
    model, lay = free_model(kin)
    q0, qd0 = ref.motion.q[0], ref.motion.qd[0]
    residual, jacobian = Oracle(model, kin.mechanism, lay).constraints(joint_coordinates(kin.mechanism, lay, q0))
    qvel = joint_velocities(kin.mechanism, layout(kin.mechanism), q0, qd0)
    assert np.max(np.abs(residual)) < 1e-12
    assert np.max(np.abs(jacobian @ qvel)) < 1e-12
    assert np.any(qvel != 0.0)


def test_pendulum_euler_is_first_order_and_rk4_meets_the_reference(a01):
    kin, ref = a01
    series = (free_series(Setting("default", "Euler", False)), free_series(Setting("default", "RK4", False)))
    result = run_free(MODE, kin, ref, series=series)
    assert result.ok, result.reason
    assert set(result.summary.status) == {"ok"}
    # measured: Euler 2.21e-3, 1.11e-3, 5.54e-4 m (order 1.00, 1.00)
    euler = _rows(result, "default", "Euler")
    assert np.all(np.abs(_orders(euler) - 1.0) < 0.1)
    # measured: RK4 2.6e-12 m at 1e-3 s (the reference's own error and the point mass's 1e-12 m^2 inertia)
    rk4 = _rows(result, "default", "RK4")
    assert rk4.position_error.iloc[0] < 1e-10
    # no loop: nothing drifts (measured exactly 0)
    assert result.summary.loop_drift.max() == 0.0
    # the best run comes first
    best = free_errors(ref, result.trajectories[0])["position_error"]
    assert best == pytest.approx(result.summary.position_error.min())


def test_double_fourbar_stiff_converges_and_default_softness_does_not(a02):
    kin, ref = a02
    series = (free_series(Setting("default", "Euler", False)), free_series(Setting("stiff", "RK4", True)))
    result = run_free(MODE, kin, ref, series=series)
    assert result.ok, result.reason
    assert set(result.summary.status) == {"ok"}
    stiff = _rows(result, "stiff", "RK4")
    # measured: 6.55e-6, 2.63e-6, 1.03e-6 m (orders 1.31, 1.36): solref = 2 dt makes the loops' softness
    # fall with the step, so RK4 converges at about first order, not fourth
    orders = _orders(stiff)
    assert np.all((orders > 1.0) & (orders < 1.8)), orders
    assert stiff.position_error.iloc[-1] < 2e-6
    # measured loop drift 3.9e-8, 1.3e-8, 2.2e-9 m
    assert np.all(np.diff(stiff.loop_drift.to_numpy()) < 0)
    assert stiff.loop_drift.iloc[-1] < 1e-8
    # measured: MuJoCo's default softness (solref 0.02 s) 3.17e-2, 3.14e-2, 3.13e-2 m: a phase error of
    # the soft loops that no step removes (orders 0.01, 0.005), with the loops open by 9.6e-4 m
    default = _rows(result, "default", "Euler")
    assert np.all(default.position_error > 1e-2)
    assert np.all(np.abs(_orders(default)) < 0.1)
    assert np.all(default.loop_drift > 1e-4)
    assert result.trajectories[0].settings["series"] == "stiff RK4"
    # continuous angles, as the reference's (measured angle error 1.0e-6 rad)
    best = result.trajectories[0]
    index = np.searchsorted(ref.motion.times, best.times - 1e-9)
    native = ref.motion.solution()
    for name, states in best.bodies.items():
        assert np.max(np.abs(states["angle"] - native.body(name)["angle"][index])) < 2e-6


class _Absurd(Setting):
    """Loops as springs of 1e12 N/m without damping (solref < 0): explicit integration blows up."""

    def apply(self, model, timestep):
        settings = super().apply(model, timestep)
        model.eq_solref[:] = (-1e12, 0.0)
        return settings


def test_a_run_that_blows_up_is_a_row(a02):
    kin, ref = a02
    absurd, stiff = (free_series(_Absurd("absurd", "Euler", False)), free_series(Setting("stiff", "RK4", True)))
    series = [
        dataclasses.replace(absurd, timestep=1e-2, rungs=1),
        dataclasses.replace(stiff, timestep=1e-2, rungs=1),
        dataclasses.replace(stiff, name="stiff RK4 at 3 ms", timestep=3e-3, rungs=1),
    ]
    result = run_free(MODE, kin, ref, series=series)
    rows = result.summary
    blown = rows[(rows.setting == "absurd") & (rows.timestep == 1e-2)]
    # measured: the loops 1.77 m open at the first compared output (0.02 s), before MuJoCo warns
    assert blown.status.str.startswith("came apart at t = 0.02 s").all(), list(blown.status)
    assert blown.order.isna().all()
    # 3e-3 s does not divide the 0.01 s between compared outputs: a row saying so
    misfit = rows[rows.timestep == 3e-3]
    assert misfit.status.str.contains("does not divide").all()
    assert result.ok  # stiff RK4 at 1e-2 s went through
    assert len(result.trajectories) == 1
    only = run_free(MODE, kin, ref, series=series[:1])
    assert not only.ok and only.reason.startswith("no run went through (absurd Euler dt = 0.01 s: came apart")


def test_cli_simulate_lists_the_mode_with_its_ladder():
    result = invoke(
        "simulate",
        "iftomm-a01",
        "--duration",
        "1",
        "--engines",
        "mujoco",
        "--json",
        "--no-report",
        "--models",
        str(MODELS),
    )
    assert result.returncode == 0, result.stderr
    document = json.loads(result.stdout)
    mode = document["engines"]["mujoco-free"]
    assert mode["ok"] is True
    ladder = mode["ladder"]
    assert {(r["setting"], r["integrator"]) for r in ladder} == {
        (s, i) for s in ("default", "stiff") for i in ("Euler", "implicitfast", "RK4")
    }
    assert {r["timestep"] for r in ladder} == set(STEPS)
    assert all(r["status"] == "ok" and r["position_error"] < 1e-2 for r in ladder)


def test_loads_act_at_every_stage(tmp_path, a01):
    """A torque and a force at a point off the link turn the pendulum; RK4 meets the reference."""
    text = (MODELS / "benchmarks" / "iftomm-a01.toml").read_text()
    load = '\n[[loads]]\nbody = "link"\npoint = [0.5, 0.2]\nforce = [3, 1]\ntorque = 2\n\n[free_motion]'
    path = tmp_path / "loaded.toml"
    path.write_text(text.replace("\n[free_motion]", load))
    kin = Kinematics(load_mechanism(path))
    ref = simulate(kin, None, duration=1.0)
    result = run_free(MODE, kin, ref, series=(free_series(Setting("default", "RK4", False)),), rungs=1)
    assert result.ok, result.reason
    # measured over 2 s: 3.0e-11 m at 1e-3 s (the reference's stated error about 2e-11 m)
    assert result.summary.position_error.iloc[0] < 1e-9
    assert np.isnan(result.summary.energy_drift.iloc[0])  # the loads' work is not known to MuJoCo
    plain = a01[1].motion.solution().point("P1")["position"][: len(ref.motion.times)]
    assert np.max(np.hypot(*(ref.motion.solution().point("P1")["position"] - plain).T)) > 0.1
    assert mujoco.get_mjcb_passive() is None  # the callback was for the run only


def test_exported_mjcf_carries_the_springs():
    """The MJCF (``xcheck export``, and the file the free and dynamic modes load) holds
    the file's springs as spatial tendons: at the spring-block's assembly (0.15 m from O,
    k = 200 N/m, rest 0.1 m) MuJoCo's passive force on the slide is -k (0.15 - 0.1) = -10 N."""
    import mujoco

    kin = Kinematics(load_mechanism(DATA / "spring-block.toml"))
    model = mujoco.MjModel.from_xml_string(mjcf_text(kin))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert model.ntendon == 1 and model.tendon_stiffness[0] == 200.0 and model.tendon_damping[0] == 4.0
    assert data.ten_length[0] == pytest.approx(0.15, abs=1e-14)
    assert data.qfrc_passive[0] == pytest.approx(-10.0, rel=1e-12)
