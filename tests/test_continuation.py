"""The engines' kinematic continuation (:mod:`xcheck.engines._continuation`):
an engine's own Newton walked along a sweep stays on its branch next to a
dead centre, and says where it cannot go on instead of jumping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DATA, ROOT

from xcheck import Kinematics, load_mechanism
from xcheck.engines._continuation import follow

EPSILON = 1e-4  # the toy's branches y = +-sqrt(x^2 + EPSILON^2) are 2e-4 apart at x = 0


def _hyperbola(q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The toy's residual: loop y^2 - x^2 - EPSILON^2, input x - c."""
    return np.array([q[1] ** 2 - q[0] ** 2 - EPSILON**2, q[0] - c[0]])


def _hyperbola_matrix(q: np.ndarray) -> np.ndarray:
    return np.array([[-2.0 * q[0], 2.0 * q[1]], [1.0, 0.0]])


def _circle(q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Residual of a point on the unit circle driven by its x: a fold at x = 1."""
    return np.array([q[0] ** 2 + q[1] ** 2 - 1.0, q[0] - c[0]])


def _circle_matrix(q: np.ndarray) -> np.ndarray:
    return np.array([[2.0 * q[0], 2.0 * q[1]], [1.0, 0.0]])


def _newton(residual, matrix):
    def solve(q: np.ndarray, c: np.ndarray):
        q = np.array(q, dtype=float)
        for iteration in range(30):
            r = residual(q, c)
            if np.max(np.abs(r)) <= 1e-15:
                return q, float(abs(r[0])), iteration, True
            q = q - np.linalg.solve(matrix(q), r)
        r = residual(q, c)
        return q, float(abs(r[0])), 30, bool(np.max(np.abs(r)) <= 1e-10)

    return solve


def test_a_walk_past_two_close_branches_stays_on_its_own():
    """The upper branch of y^2 = x^2 + 1e-8, x from -1 to 1 in steps of 0.036: one
    tangent step per sample from x = -0.018 lands at y = -0.018, where Newton
    finds the lower branch (the old adapters' jump); the walk halves its step
    instead and stays on y = +sqrt(x^2 + 1e-8), derived by hand."""
    x = np.linspace(-1.0, 1.0, 56)
    naive = _newton(_hyperbola, _hyperbola_matrix)  # the old scheme, for contrast: it must jump
    q, c = np.array([-1.0, math.hypot(1.0, EPSILON)]), np.array([-1.0])
    for value in x[1:]:
        tangent = np.linalg.solve(_hyperbola_matrix(q), [0.0, 1.0])
        q = naive(q + tangent * (value - c[0]), np.array([value]))[0]
        c = np.array([value])
    assert q[1] < 0.0
    walk = follow(
        _newton(_hyperbola, _hyperbola_matrix),
        _hyperbola_matrix,
        1,
        np.array([-1.0, math.hypot(1.0, EPSILON)]),
        np.array([-1.0]),
        x[:, None],
        np.ones(1),
        np.ones(2),
    )
    assert walk.stopped is None and walk.converged.all()
    assert np.max(np.abs(walk.qpos[:, 1] - np.hypot(x, EPSILON))) <= 1e-14
    assert walk.steps.max() > 1  # it did take smaller steps next to x = 0


def test_a_walk_into_a_fold_stops_and_says_where():
    """A point on the unit circle driven by its x past x = 1 (a limit position):
    the walk stops within a few MIN_STEP of the fold with its reason, leaves the
    samples past it unreached (NaN), and never reports the lower half."""
    x = np.array([0.5, 0.9, 0.99, 1.01, 1.1])
    walk = follow(
        _newton(_circle, _circle_matrix),
        _circle_matrix,
        1,
        np.array([0.0, 1.0]),
        np.array([0.0]),
        x[:, None],
        np.ones(1),
        np.ones(2),
    )
    assert walk.stopped == 3
    assert "stopped at inputs (" in walk.reason
    assert walk.converged[:3].all() and not walk.converged[3:].any()
    assert np.isnan(walk.qpos[3:]).all()
    assert np.allclose(walk.qpos[:3, 1], np.sqrt(1.0 - x[:3] ** 2), atol=1e-14, rtol=0.0)


def test_a_walk_whose_solver_takes_only_tiny_steps_stops_within_its_budget():
    """A solver that converges only over steps below 1e-7 (one failing systematically):
    the walk's steps shrink and would creep on; with a budget of 40 solves it stops
    between the samples, saying so, instead of taking 2e5 steps to the next one."""
    circle = _newton(_circle, _circle_matrix)

    def timid(q: np.ndarray, c: np.ndarray):
        moved = abs(float(c[0]) - float(timid.at))
        q, violation, iterations, ok = circle(q, c)
        if ok and moved < 1e-7:
            timid.at = float(c[0])
            return q, violation, iterations, True
        return q, violation, iterations, False

    timid.at = 0.0
    x = np.array([0.0, 0.02])
    walk = follow(
        timid, _circle_matrix, 1, np.array([0.0, 1.0]), np.zeros(1), x[:, None], np.ones(1), np.ones(2), budget=40
    )
    assert walk.stopped == 1 and walk.converged[0] and not walk.converged[1]
    assert "40 solves from the last sample did not reach the next" in walk.reason
    assert 0.0 < timid.at < 1e-5


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["mujoco", "pinocchio", "opensim"])
def test_kinematic_oracles_follow_the_branch_next_to_a_dead_centre(engine):
    """tests/data/near-dead-centre.toml: the other branch is 15 mm away at crank =
    270 deg and a sample falls 0.3 deg from it. The slider follows the right
    branch B_x = r cos(theta) + sqrt(L^2 - (e - r sin(theta))^2) at every sample
    (before the fix MuJoCo and Pinocchio jumped there: errors of 1.9 sizes;
    OpenSim's assembler, from its neighbour's coordinates, 8.0e-3 of the size)."""
    import importlib

    if engine == "opensim":
        pytest.importorskip("opensim")
    run_kinematic = importlib.import_module(f"xcheck.engines.{engine}.modes").run_kinematic
    kinematics = Kinematics(load_mechanism(DATA / "near-dead-centre.toml"))
    result = run_kinematic(kinematics, 181)
    assert result.ok, result.reason
    trajectory = result.trajectories[0]
    theta = trajectory.inputs[:, 0]
    assert np.min(np.abs(np.mod(theta, 2 * math.pi) - 1.5 * math.pi)) < math.radians(0.31)
    r, rod, e = 1.0, 3.00001, 2.0
    expected = r * np.cos(theta) + np.sqrt(rod**2 - (e - r * np.sin(theta)) ** 2)
    slider = trajectory.bodies["slider"]["position"]
    assert np.max(np.abs(slider[:, 0] - expected)) <= 1e-10 * kinematics.system.size
    assert np.max(np.abs(slider[:, 1] - e)) <= 1e-10 * kinematics.system.size


@pytest.mark.slow
def test_mujoco_simulation_across_the_dead_centre_says_it_left_the_branch():
    """MuJoCo's soft loops carry tests/data/near-dead-centre.toml onto the other branch
    just past the dead centre (crank at 270 deg at t = 69.7 deg / 10 rad/s = 0.122 s):
    the mode fails with that reason and the time, not as a disagreement of 2 sizes."""
    from xcheck import engines

    kinematics = Kinematics(load_mechanism(DATA / "near-dead-centre.toml"))
    result = engines.engine("mujoco").dynamic_ladder("mujoco-dynamic", kinematics).run()
    assert not result.ok
    assert "left the assembly branch at t = " in result.reason
    t = float(result.reason.split("left the assembly branch at t = ")[1].split(" s")[0])
    assert math.radians(270.0 - 200.3) / 10.0 <= t <= 0.2


@pytest.mark.slow
def test_drakes_pd_across_the_dead_centre_says_it_left_the_branch():
    """Drake's PD carries tests/data/near-dead-centre.toml onto the other branch near the
    dead centre as MuJoCo does: its driven mode fails with that reason
    (xcheck.ladder.off_branch, the one rule for every driven mode), not with a
    disagreement of 2 sizes that xcheck would own."""
    from xcheck import engines

    pytest.importorskip("pydrake")
    kinematics = Kinematics(load_mechanism(DATA / "near-dead-centre.toml"))
    result = engines.engine("drake").dynamic_ladder("drake-dynamic", kinematics).run()
    assert not result.ok
    assert "left the assembly branch at t = " in result.reason, result.reason
    t = float(result.reason.split("left the assembly branch at t = ")[1].split(" s")[0])
    assert math.radians(270.0 - 200.3) / 10.0 <= t <= 0.2


@pytest.mark.slow
def test_pybullets_unbounded_loop_holds_the_branch_across_the_dead_centre():
    """PyBullet's loop constraint and motor, with no force bound, hold
    tests/data/near-dead-centre.toml on its branch through the dead centre, where the loop's
    force grows without bound: its driven mode passes, each of its settings on the branch
    (bounded at PyBullet's default 500 N the loop gave way there and the run left the
    branch)."""
    from xcheck import engines

    pytest.importorskip("pybullet")
    kinematics = Kinematics(load_mechanism(DATA / "near-dead-centre.toml"))
    result = engines.engine("pybullet").dynamic_ladder("pybullet-dynamic", kinematics).run()
    assert result.ok, result.reason
    from xcheck.ladder import off_branch

    for run in result.trajectories:
        native = kinematics.solve(run.inputs)
        points = {label: quantities["position"] for label, quantities in run.points.items()}
        assert off_branch(kinematics, native, points, run.times) == "", run.settings


def test_off_branch_names_the_first_sample_off_the_branch():
    """xcheck.ladder.off_branch (pymunk's forces, every driven mode): points on the
    native configuration give "", a point moved 0.2 of the size from sample 3 on gives
    that sample's time and gap; a move of 0.05 of the size is a gap, not a branch."""
    from xcheck.ladder import APART as LEFT_BRANCH
    from xcheck.ladder import off_branch

    kinematics = Kinematics(load_mechanism(ROOT / "models" / "fourbar.toml"))
    inputs = np.linspace(-1.0, 1.0, 7)[:, None]
    native = kinematics.solve(inputs)
    size = kinematics.mechanism.size
    points = {label: native.point(label)["position"].copy() for label in ("B", "C")}
    times = np.arange(7) * 0.5
    assert off_branch(kinematics, native, points, times) == ""
    points["C"][3:, 1] += 0.5 * LEFT_BRANCH * size
    assert off_branch(kinematics, native, points, times) == ""
    points["C"][3:, 1] += 1.5 * LEFT_BRANCH * size
    status = off_branch(kinematics, native, points, times)
    assert status.startswith("left the assembly branch at t = 1.5 s: a point ")
    assert status.endswith("m from the native configuration at the inputs realised")
    assert float(status.split("a point ")[1].split(" m")[0]) == pytest.approx(2.0 * LEFT_BRANCH * size, rel=1e-3)


def _crank_point(q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """A crank's angle q[0] and its tip (q[1], q[2]) on the unit circle, driven by the angle."""
    return np.array([q[1] - math.cos(q[0]), q[2] - math.sin(q[0]), q[0] - c[0]])


def _crank_point_matrix(q: np.ndarray) -> np.ndarray:
    return np.array([[math.sin(q[0]), 1.0, 0.0], [-math.cos(q[0]), 0.0, 1.0], [1.0, 0.0, 0.0]])


def _half_winding(q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """A coordinate q[1] = q[0] / 2: after a turn of the input it has changed by half a turn."""
    return np.array([q[1] - 0.5 * q[0], q[0] - c[0]])


def _half_winding_matrix(q: np.ndarray) -> np.ndarray:
    return np.array([[-0.5, 1.0], [1.0, 0.0]])


def test_a_walk_over_a_hundred_turns_skips_the_whole_turns():
    """From 0 to 100 turns + 0.5 rad in one sample: the walk goes one turn in steps of
    at most 2 deg (180 steps), sees the configuration repeat, skips 99 turns, and walks
    the last 0.5 rad; it lands on (cos, sin) of the target with the angle continuous."""
    target = 200.0 * math.pi + 0.5
    walk = follow(
        _newton(_crank_point, _crank_point_matrix),
        _crank_point_matrix,
        2,
        np.array([0.0, 1.0, 0.0]),
        np.array([0.0]),
        np.array([[target]]),
        np.ones(1),
        np.ones(3),
        period=2.0 * math.pi,
    )
    assert walk.stopped is None, walk.reason
    assert walk.steps[0] <= 180 + 15 + 5  # one turn, 0.5 rad at <= 2 deg, a few halvings
    assert walk.qpos[0, 0] == pytest.approx(target, rel=1e-14)
    assert walk.qpos[0, 1:] == pytest.approx([math.cos(target), math.sin(target)], abs=1e-12)


def test_a_walk_whose_configuration_does_not_repeat_after_a_turn_goes_all_the_way():
    """A coordinate that changes by half a turn per turn of the input: no skip, every
    step walked (10 turns at <= 2 deg: at least 1800 steps), and the answer exact."""
    target = 20.0 * math.pi
    walk = follow(
        _newton(_half_winding, _half_winding_matrix),
        _half_winding_matrix,
        1,
        np.array([0.0, 0.0]),
        np.array([0.0]),
        np.array([[target]]),
        np.ones(1),
        np.ones(2),
        period=2.0 * math.pi,
    )
    assert walk.stopped is None, walk.reason
    assert walk.steps[0] >= 1800
    assert walk.qpos[0] == pytest.approx([target, 0.5 * target], rel=1e-13)
