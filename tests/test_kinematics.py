"""The general solver against closed forms, finite differences and its own
invariants (loop closure, branch, limit positions, mobility)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import DATA, MODEL_NAMES

from xcheck import Kinematics, Status
from xcheck.model import parse_mechanism
from xcheck.output import solution_json

SLIDER_DRIVEN = (DATA / "slider-driven.toml").read_text()
INVERTED = (DATA / "inverted.toml").read_text()


def _orientation(solution, first, second, third):
    """Sign of the turn first -> second -> third (+1 counter-clockwise)."""
    a, b, c = (solution.point(label)["position"] for label in (first, second, third))
    u, v = b - a, c - b
    return np.sign(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def _sweep_in_time(kin: Kinematics, times: np.ndarray):
    """Solve at the drivers' motion laws evaluated at ``times`` (s)."""
    laws = [d.law.at_time(times) for d in kin.mechanism.drivers]
    q, qd, qdd = (np.stack([law[i] for law in laws], axis=1) for i in range(3))
    return kin.solve(q, qd, qdd)


def _finite_difference_errors(kin: Kinematics, times: np.ndarray, h: float):
    """Largest relative gaps between solver rates and central differences (step h)."""
    mid, ahead, behind = (_sweep_in_time(kin, times + d) for d in (0.0, h, -h))
    for s in (mid, ahead, behind):
        assert s.success

    def rel(fd, exact):
        return np.max(np.abs(fd - exact)) / np.max(np.abs(exact))

    errors = {"qd": rel((ahead.q - behind.q) / (2 * h), mid.qd), "qdd": rel((ahead.qd - behind.qd) / (2 * h), mid.qdd)}
    for label in kin.mechanism.point_owners:
        if label in kin.mechanism.ground.points:
            continue
        pa, pb, pm = ahead.point(label), behind.point(label), mid.point(label)
        errors[f"v_{label}"] = rel((pa["position"] - pb["position"]) / (2 * h), pm["velocity"])
        errors[f"a_{label}"] = rel((pa["velocity"] - pb["velocity"]) / (2 * h), pm["acceleration"])
    return errors


MECHANISMS = {name: None for name in MODEL_NAMES}


def _kin(kinematics, name):
    if name == "slider-driven":
        return Kinematics(parse_mechanism(SLIDER_DRIVEN, "slider-driven"))
    if name == "inverted":
        return Kinematics(parse_mechanism(INVERTED, "inverted"))
    return kinematics(name)


# time windows that stay inside each mechanism's feasible range
WINDOWS = {
    "fourbar": (0.0, 1.5),
    "two-body-arm": (0.0, 0.2),
    "slider-crank": (0.0, 0.08),
    "slider-driven": (0.0, 0.2),
    "inverted": (0.0, 1.0),
}
STEPS = {"fourbar": 1e-3, "two-body-arm": 1e-4, "slider-crank": 1e-5, "slider-driven": 1e-4, "inverted": 1e-3}


@pytest.mark.parametrize("name", list(WINDOWS))
def test_rates_match_central_differences(kinematics, name):
    """Velocities and accelerations (bodies and points) against central finite
    differences of positions and velocities along a timed sweep: the gap is
    the differences' own O(h^2) error, so halving h divides it by about 4."""
    kin = _kin(kinematics, name)
    start, stop = WINDOWS[name]
    times = np.linspace(start, stop, 41)
    h = STEPS[name]
    coarse = _finite_difference_errors(kin, times, h)
    fine = _finite_difference_errors(kin, times, h / 2)
    for key in coarse:
        assert fine[key] < 1e-5, (key, fine[key])
        if coarse[key] > 1e-10:  # above round-off: second-order convergence
            assert 3.0 < coarse[key] / fine[key] < 5.0, (key, coarse[key], fine[key])


@pytest.mark.parametrize("name", list(WINDOWS))
def test_jacobian_and_gamma_against_finite_differences(kinematics, name):
    """Phi_q against central differences of Phi, and gamma against
    -(d/dt)(Phi_q) qd, at solved states; relative gap below 1e-7."""
    kin = _kin(kinematics, name)
    system = kin.system
    start, stop = WINDOWS[name]
    s = _sweep_in_time(kin, np.linspace(start, stop, 5))
    eps = 1e-6
    for i in range(5):
        q, qd, c = s.q[i], s.qd[i], s.inputs[i]
        jac = system.jacobian(q[None])[0]
        numeric = np.empty_like(jac)
        for j in range(system.n):
            dq = np.zeros(system.n)
            dq[j] = eps
            numeric[:, j] = (
                system.residual((q + dq)[None], c[None])[0] - system.residual((q - dq)[None], c[None])[0]
            ) / (2 * eps)
        assert np.max(np.abs(numeric - jac)) <= 1e-7 * np.max(np.abs(jac))
        # gamma = -(Phi_q qd)_q qd + input accelerations on driver rows
        djac = (system.jacobian((q + eps * qd)[None])[0] - system.jacobian((q - eps * qd)[None])[0]) / (2 * eps)
        expected = -djac @ qd
        expected[system.n_kinematic :] += s.input_accelerations[i]
        gamma = system.gamma(q[None], qd[None], s.input_accelerations[i][None])[0]
        assert np.max(np.abs(gamma - expected)) <= 1e-6 * max(1.0, np.max(np.abs(gamma)))


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_loop_closure_over_feasible_sweep(kinematics, name):
    """Every sample of a 2000-sample sweep over the feasible range assembles,
    with a constraint violation below 1e-12 of the mechanism's size."""
    kin = kinematics(name)
    ref = kin.reference_inputs()
    sweeps = []
    for k in range(len(ref)):
        rng = kin.input_range(k)
        low = rng.low if rng.low is not None else ref[k] - math.pi
        high = rng.high if rng.high is not None else ref[k] + math.pi
        c = np.tile(ref, (2000, 1))
        c[:, k] = np.linspace(low + 1e-6, high - 1e-6, 2000)
        sweeps.append(c)
    for c in sweeps:
        s = kin.solve(c)
        assert np.all(s.status <= Status.NEAR_SINGULAR)
        assert np.max(s.residual) < 1e-12 * kin.system.size
        phi = kin.system.residual(s.q, c)
        assert np.max(kin.system.residual_metres(phi)) < 1e-12 * kin.system.size


def test_fourbar_limit_positions_closed_form(kinematics):
    """The seed four-bar is not Grashof: the crank stops where B, C, D line up,
    |BD| = d + s, i.e. cos(phi) = (r^2 + l^2 - (d + s)^2) / (2 r l)."""
    r, d, s, l = 0.45, 0.45, 0.5, 0.6
    limit = math.acos((r * r + l * l - (d + s) ** 2) / (2 * r * l))
    rng = kinematics("fourbar").input_range("crank")
    assert rng.low == pytest.approx(-limit, abs=1e-8)
    assert rng.high == pytest.approx(limit, abs=1e-8)
    assert not rng.full_turn


def test_fourbar_limit_is_flagged_and_beyond_does_not_assemble(kinematics):
    kin = kinematics("fourbar")
    high = kin.input_range("crank").high
    s = kin.solve([high - 1e-3, high, high + 1e-3])
    assert Status(s.status[0]) == Status.OK
    assert Status(s.status[1]) in (Status.NEAR_SINGULAR, Status.SINGULAR)
    assert Status(s.status[2]) == Status.NOT_CONVERGED
    text = json.dumps(solution_json(s), allow_nan=False)  # raises on any NaN
    state = json.loads(text)["states"][2]
    assert state["status"] == "not-converged" and state["bodies"]["coupler"]["position"] is None


@pytest.mark.parametrize("branch,sign", [("upper", 1.0), ("lower", -1.0)])
def test_fourbar_both_branches_held_along_sweep(kinematics, branch, sign):
    """C stays on its side of the line B->D over the whole feasible range."""
    kin = kinematics("fourbar")
    rng = kin.input_range("crank", branch)
    s = kin.solve(np.linspace(rng.low + 1e-6, rng.high - 1e-6, 3000), branch=branch)
    assert s.success
    assert np.all(_orientation(s, "B", "D", "C") == sign)


def test_fourbar_sweep_back_and_forth_stays_on_branch(kinematics):
    """Down to the lower limit, up to the upper one and back: one branch throughout."""
    kin = kinematics("fourbar")
    rng = kin.input_range("crank")
    c = np.concatenate(
        [
            np.linspace(0.0, rng.low + 1e-7, 500),
            np.linspace(rng.low + 1e-7, rng.high - 1e-7, 1000),
            np.linspace(rng.high - 1e-7, 0.0, 500),
        ]
    )
    s = kin.solve(c)
    assert s.success and np.all(_orientation(s, "B", "D", "C") == 1.0)
    np.testing.assert_allclose(s.q[0], s.q[-1], atol=1e-12)


def test_slider_crank_closed_form(kinematics):
    """Offset slider-crank: x_B = r cos t + sqrt(l^2 - (e - r sin t)^2) and its
    time derivatives at constant crank speed, over two full turns."""
    kin = kinematics("slider-crank")
    r, l, e, w = 0.1, 0.35, 0.04, 100.0
    theta = np.linspace(0.0, 4 * np.pi, 4001)
    s = kin.solve(theta, np.full_like(theta, w))
    assert s.success
    u = e - r * np.sin(theta)
    root = np.sqrt(l * l - u * u)
    x = r * np.cos(theta) + root
    dx = -r * np.sin(theta) + u * r * np.cos(theta) / root  # per rad
    du = -r * np.cos(theta)
    d2x = (
        -r * np.cos(theta)
        + (du * r * np.cos(theta) - u * r * np.sin(theta)) / root
        + (u * r * np.cos(theta)) * (u * du) / root**3
    )
    b = s.point("B")
    np.testing.assert_allclose(b["position"][:, 0], x, rtol=0, atol=1e-14)
    np.testing.assert_allclose(b["position"][:, 1], e, rtol=0, atol=1e-14)
    np.testing.assert_allclose(b["velocity"][:, 0], dx * w, rtol=0, atol=1e-12 * w * r)
    np.testing.assert_allclose(b["acceleration"][:, 0], d2x * w * w, rtol=0, atol=1e-12 * w * w * r)
    assert kin.input_range("crank").full_turn


def test_slider_driven_dead_centres():
    """Driven by its slider, the slider-crank stops at the dead centres
    x = sqrt((l +- r)^2 - e^2), where the crank and rod line up."""
    kin = Kinematics(parse_mechanism(SLIDER_DRIVEN, "slider-driven"))
    r, l, e = 0.1, 0.35, 0.04
    rng = kin.input_range("slide")
    assert rng.low == pytest.approx(math.sqrt((l - r) ** 2 - e**2), abs=1e-9)
    assert rng.high == pytest.approx(math.sqrt((l + r) ** 2 - e**2), abs=1e-9)


@pytest.mark.parametrize("name,dof", [("fourbar", 1), ("two-body-arm", 2), ("slider-crank", 1)])
def test_mobility(kinematics, name, dof):
    assert kinematics(name).mobility() == {"grubler": dof, "rank": dof, "drivers": dof}


def test_mobility_counts_pin_in_slot_as_one_constraint():
    kin = Kinematics(parse_mechanism(INVERTED, "inverted"))
    # 4 moving bodies: 12 - (4 revolutes x 2 + prismatic 2 + pin-in-slot 1) = 1
    assert kin.mobility() == {"grubler": 1, "rank": 1, "drivers": 1}


def test_batch_and_one_by_one_agree(kinematics):
    """Solving a sweep at once or sample by sample gives the same numbers."""
    kin = kinematics("fourbar")
    c = np.radians(np.linspace(-120, 120, 25))
    batch = kin.solve(c, np.ones_like(c), np.full_like(c, 0.5))
    for i in range(0, 25, 6):
        single = kin.solve(c[i : i + 1], [1.0], [0.5])
        np.testing.assert_allclose(single.q[0], batch.q[i], atol=1e-13)
        np.testing.assert_allclose(single.qdd[0], batch.qdd[i], rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize(
    "law",
    [
        dict(kind="constant-rate", start=0.3, rate=-2.0),
        dict(kind="constant-acceleration", start=0.3, rate=2.0, acceleration=-1.5),
        dict(kind="harmonic", centre=0.1, amplitude=0.7, frequency=1.3, phase=0.2),
    ],
)
def test_a_law_at_one_number_of_time_is_its_value_as_an_array_bit_for_bit(law):
    """An engine's step loop asks a motion law at one time (a float, computed without
    arrays): the same values, signed zeros included, as at that time as an array."""
    from xcheck.model import MotionLaw

    motion = MotionLaw(**law)
    for t in [*np.linspace(-3.0, 3.0, 601), 0.0, -0.0, 2]:
        one, array = motion.at_time(float(t)), motion.at_time(np.array(t, dtype=float))
        assert [(float(v), math.copysign(1.0, v)) for v in one] == [(float(v), math.copysign(1.0, v)) for v in array]


def test_a_second_kinematics_of_a_mechanism_takes_the_walk_of_the_first(monkeypatch):
    """A feasible-range walk is kept for the process: another Kinematics of the same
    mechanism (read again) gets the same range, configurations and sweep, to every
    bit, without walking; one that starts from another configuration walks anew; the
    latest walks only are kept."""
    import collections

    from conftest import MODELS

    from xcheck.kinematics import _solve
    from xcheck.model import load_mechanism

    walks = []
    real = _solve.continue_to
    monkeypatch.setattr(_solve, "continue_to", lambda *a, **k: walks.append(1) or real(*a, **k))
    monkeypatch.setattr(_solve, "_WALKS", collections.OrderedDict())
    first, second, moved = (Kinematics(load_mechanism(MODELS / "slider-crank.toml")) for _ in range(3))
    span, key = first.input_range(0), (first._branch_name(None), 0)
    walked = len(walks)
    assert walked > 0 and second.input_range(0) == span and len(walks) == walked
    for (c1, q1), (c2, q2) in zip(first._walked[key], second._walked[key], strict=True):
        assert c1 == c2 and np.array_equal(q1, q2)
    inputs = np.linspace(0.0, 6.0, 40)[:, None]
    one, two = first.solve(inputs), second.solve(inputs)
    assert np.array_equal(one.q, two.q) and np.array_equal(one.qd, two.qd) and np.array_equal(one.qdd, two.qdd)
    moved._assembled[key[0]] = moved.assemble(key[0]) + np.r_[1e-12, np.zeros(moved.system.n - 1)]
    moved.input_range(0)
    assert len(walks) > walked
    monkeypatch.setattr(_solve, "_WALKS_KEPT", 1)
    Kinematics(load_mechanism(MODELS / "fourbar.toml")).input_range(0)
    assert len(_solve._WALKS) == 1
