"""The native solver at inputs of millions of radians.

Angles are continuous, never wrapped, so a double holds an input of 3.4e6 rad
only to 4.7e-10 rad and the loops cannot close better than about eps |phi| times
a length. Fuzz case s1-00419 (a double crank) hung here: PyBullet, blown up,
realised such inputs, the fixed convergence fraction (1e-10 of the size) rejected
every exact solution, and continuation rescued each sample in steps of one unit
in the last place. The convergence bound now grows with the largest body angle
(``kinematics._newton.converged_tolerance``) and continuation stops once its step
is a few units in the last place of the inputs.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA

from xcheck.kinematics import Kinematics, Status, _newton
from xcheck.model import parse_mechanism

EPS = np.finfo(float).eps
CASE = DATA / "fuzz-fourbar-double-crank-large-angles.toml"


@pytest.fixture(scope="module")
def kinematics() -> Kinematics:
    return Kinematics(parse_mechanism(CASE.read_text(), str(CASE)))


def closed_form_c(kinematics: Kinematics, theta: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Joint C of the four-bar in long double: the intersection of the circles about
    the crank's end B (radius the coupler) and about D (radius the rocker), the one
    nearer the native ``near`` (N, 2)."""
    m = kinematics.mechanism
    ld = np.longdouble
    ends = {"crank": "AB", "coupler": "BC", "rocker": "DC"}
    crank, coupler, rocker = (
        ld(np.hypot(*np.subtract(m.body(name).points[b], m.body(name).points[a]))) for name, (a, b) in ends.items()
    )
    d = np.asarray(m.body("ground").points["D"], dtype=ld)
    theta = theta.astype(ld)
    b = np.stack([crank * np.cos(theta), crank * np.sin(theta)], axis=1)
    chord = d - b
    distance = np.hypot(chord[:, 0], chord[:, 1])
    along = (coupler**2 - rocker**2 + distance**2) / (2 * distance)
    across = np.sqrt(coupler**2 - along**2)
    unit = chord / distance[:, None]
    normal = np.stack([-unit[:, 1], unit[:, 0]], axis=1)
    foot = b + along[:, None] * unit
    candidates = [foot + across[:, None] * normal, foot - across[:, None] * normal]
    gaps = [np.hypot(*(c.astype(float) - near).T) for c in candidates]
    return np.where((gaps[0] <= gaps[1])[:, None], candidates[0], candidates[1]).astype(float)


@pytest.mark.parametrize("compiled", [False, True], ids=["reference", "compiled"])
def test_inputs_of_millions_of_radians_assemble_to_their_precision(kinematics, compiled):
    theta = np.sort(10 ** np.random.default_rng(0).uniform(3, 9, 400))
    solution = kinematics.solve(theta, np.full_like(theta, 2.0), compiled=compiled)
    assert np.all(solution.status == Status.OK)
    size = kinematics.system.size
    largest_angle = np.max(np.abs(solution.q[:, 2::3]), axis=1)
    # measured: at most 0.36 eps |phi| size (3000 inputs from 1e3 to 1e9 rad), within
    # the bound that counts as assembled, 16 eps |phi| size
    assert np.all(solution.residual <= 16 * EPS * largest_angle * size)
    position = solution.point("C")["position"]
    error = np.hypot(*(position - closed_form_c(kinematics, theta, position)).T)
    # C is held to the precision of the body angles it hangs from: measured at most
    # 0.17 eps |phi| size against the closed form
    assert np.all(error <= 4 * EPS * largest_angle * size)
    # whole turns of the input give the same configuration; the reduction is itself
    # inexact by about eps |theta| (2 pi is not a double): measured 1.9 eps |phi| size
    again = kinematics.solve(theta - 2 * np.pi * np.round(theta / (2 * np.pi)), compiled=compiled)
    assert np.all(np.hypot(*(position - again.point("C")["position"]).T) <= 8 * EPS * largest_angle * size)


def test_continuation_stops_when_its_steps_reach_the_inputs_last_place(kinematics, monkeypatch):
    """A Newton solve that only accepts steps below 1e-9 rad, at an input of 3.4e6 rad
    (held to 4.7e-10 rad), used to be walked one unit in the last place at a time:
    3.4e7 steps for 0.034 rad. The walk now stops, unreached, within a few dozen."""
    start = np.array([3449879.65662606])
    solution = kinematics.solve(start)
    assert solution.status[0] == Status.OK
    newton = _newton.newton
    state = {"c": start.copy(), "calls": 0}

    def newton_with_tiny_steps(system, guess, c, max_iter=30):
        state["calls"] += 1
        assert state["calls"] < 1000, "continuation no longer stops"
        q, residual, iterations, _ = newton(system, guess, c, max_iter)
        ok = np.abs(c[:, 0] - state["c"][0]) <= 1e-9
        if ok[0]:
            state["c"] = c[0].copy()
        return q, residual, iterations, ok

    monkeypatch.setattr(_newton, "newton", newton_with_tiny_steps)
    _, _, reached, _ = _newton.continue_to(kinematics.system, solution.q[0], start, start + 0.034)
    assert not reached
    assert state["calls"] < 100
