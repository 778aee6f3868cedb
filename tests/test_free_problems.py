"""The free-motion problems of tests/free_problems.py: their stored extended-precision
answers, the files against their reductions, and the native reference against both.

Measured (the native RK4 ladder at each file's tolerance, 1e-9 of the size): true
error 3.9e-11 m (crank-rocker), 2.1e-12 m (slider-crank), 1.8e-11 m (double
pendulum), stated 7.1e-10, 4.7e-11 and 2.7e-10 m; the stated error bounds the true
one at every output by a factor of at least 10, 14.7 and 3.2.
"""

from __future__ import annotations

import math

import free_problems as fp
import numpy as np
import pytest
from conftest import MODELS

from xcheck import Kinematics, load_mechanism
from xcheck.dynamics._free import release_state, simulate


def _kinematics(name: str) -> Kinematics:
    kin = Kinematics(load_mechanism(fp.path(name)))
    kin.assemble()
    return kin


@pytest.mark.parametrize("name", sorted(fp.PROBLEMS))
def test_stored_states_are_the_extended_integration(name):
    """The stored states' first 0.05 s again, by other settings (40 digits, steps of
    0.01 s, 11 levels): they agree to the stored digits."""
    times = np.arange(6) * 0.01
    states, worst = fp.extended_states(name, times, digits=40, step=0.01, levels=11)
    _, stored = fp._stored(name)
    again = np.array([[float(v) for v in state] for state in states])
    assert worst < 1e-22  # each step far below the 25 digits stored
    assert np.abs(again - stored[: len(times)]).max() <= 1e-20 * max(1.0, np.abs(stored).max())


@pytest.mark.parametrize("name", sorted(fp.PROBLEMS))
def test_files_release_the_reductions_start(name):
    """xcheck's release state of the file is the reduction's start: every body's frame and
    its velocity (the jets' first derivative times the rates) to round-off."""
    kin = _kinematics(name)
    start = release_state(kin)
    problem = fp.PROBLEMS[name]
    poses = fp.reference(name, np.zeros(1))
    assert fp.body_error(kin, start.q[None], poses)[0] <= 1e-14 * kin.system.size
    h = 1e-6  # the velocity by the poses' central difference along the motion (error ~ h^2)
    state = np.array(problem.start, dtype=float)
    dof = len(state) // 2
    ahead, behind = state.copy(), state.copy()
    ahead[:dof] += h * state[dof:]
    behind[:dof] -= h * state[dof:]
    for body, i in kin.system.body_index.items():
        if i < 0:
            continue
        rate = (np.array(problem.poses(ahead)[body]) - np.array(problem.poses(behind)[body])) / (2.0 * h)
        assert np.abs(start.qd[3 * i : 3 * i + 3] - rate).max() <= 1e-7 * max(1.0, np.abs(rate).max()), body


def _energy(name: str, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, V) (J) of the reduction at each state (N, 2 dof), from its own mass data."""
    problem = fp.PROBLEMS[name]
    if name == "free-double-pendulum":
        p = problem
        th1, th2, w1, w2 = states.T
        kinetic = 0.5 * (p.m1 * p.c1**2 + p.i1 + p.m2 * p.length1**2) * w1**2 + 0.5 * (p.m2 * p.c2**2 + p.i2) * w2**2
        kinetic += p.m2 * p.length1 * p.c2 * np.cos(th1 - th2) * w1 * w2
        height = -(p.m1 * p.c1 + p.m2 * p.length1) * np.cos(th1) - p.m2 * p.c2 * np.cos(th2)
        return kinetic, fp.G * height
    out = []
    for theta, rate in states:
        frames = problem.frames(fp.Jet(theta, 1.0, 0.0, fp.FLOAT))
        kinetic, potential = 0.0, 0.0
        for body, data in problem.bodies.items():
            x, y, phi = frames[body]
            ax, ay = fp._rotate(phi, data.com)
            gx, gy = x + ax, y + ay
            kinetic += 0.5 * rate**2 * (data.mass * (gx.d1**2 + gy.d1**2) + data.inertia * phi.d1**2)
            potential += data.mass * fp.G * gy.v
        for ground, body, point, stiffness, rest in problem.springs:
            x, y, phi = frames[body]
            ax, ay = fp._rotate(phi, point)
            length = math.hypot(x.v + ax.v - ground[0], y.v + ay.v - ground[1])
            potential += 0.5 * stiffness * (length - rest) ** 2
        out.append((kinetic, potential))
    return np.array(out)[:, 0], np.array(out)[:, 1]


@pytest.mark.parametrize("name", sorted(fp.PROBLEMS))
def test_reductions_keep_their_energy(name):
    """The reduced equations are Lagrange's for their T and V: T + V of the stored states
    stays constant to round-off of the largest kinetic energy (measured: 5e-16 to 1.5e-15)."""
    _, states = fp._stored(name)
    kinetic, potential = _energy(name, states)
    assert np.ptp(kinetic + potential) <= 1e-13 * kinetic.max()


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(fp.PROBLEMS))
def test_native_reference_states_an_honest_error(name):
    """The native reference at the file's tolerance: converged, within it of the true
    answer, and its stated error bounds the true one at every output."""
    kin = _kinematics(name)
    reference = simulate(kin)
    motion = reference.motion
    true = fp.body_error(kin, motion.q, fp.reference(name, motion.times))
    assert reference.converged
    assert true.max() <= reference.tolerance * kin.system.size
    assert np.all(true <= reference.estimate)
    assert np.abs(motion.energy_error).max() <= 1e-8 * np.abs(motion.energy).max()


def test_the_slider_crank_with_a_spring_exits_0_with_an_error_that_bounds_the_true_one():
    """The slider-crank turning ten times in 2 s: `simulate` exits 0 (DOP853 converged, its
    check consistent), and the stated error bounds the true one at every output.
    Measured: stated 3.2e-10 m, true 2.7e-11 m; the check agrees to 2.7e-11 m."""
    from conftest import invoke

    name = "free-slider-crank-spring"
    done = invoke("simulate", str(fp.path(name)), "--engines", "native", "--json", "--no-report")
    assert done.returncode == 0, done.stderr
    kin = _kinematics(name)
    reference = simulate(kin, check=True)
    true = fp.body_error(kin, reference.motion.q, fp.reference(name, reference.motion.times))
    assert reference.converged and reference.check is not None and reference.check.consistent
    assert np.all(true <= reference.estimate)


def _pendulum_error(kin: Kinematics, motion) -> np.ndarray:
    """IFToMM A01's point P1 against its elliptic closed form (m, per output)."""
    from test_free_motion import pendulum_exact

    return np.abs(motion.solution().point("P1")["position"] - pendulum_exact(motion.times)).max(axis=1)


def _problem_error(name: str):
    return lambda kin, motion: fp.body_error(kin, motion.q, fp.reference(name, motion.times))


@pytest.mark.parametrize("name", ["iftomm-a01", *sorted(fp.PROBLEMS)])
def test_both_native_methods_agree_and_each_states_an_honest_error(name):
    """DOP853 and its check, Gauss-Legendre collocation, at 1e-11 of the size: each one's
    stated error bounds its true error at every output, and they agree to 1e-11 of the size.
    Measured (agreement, of the size, and true / stated errors of DOP853 and the check, m):
    A01 2.6e-13, 1.5e-13 / 2.7e-12, 9.2e-14 / 5.8e-13; crank-rocker 3.1e-12, 1.6e-12 /
    1.1e-11 (not converged), 7.6e-13 / 2.9e-12; double pendulum 3.3e-13, 3.3e-13 / 5.1e-12,
    6e-15 / 2.3e-13; four-bar 4.9e-13, 1.5e-13 / 1.1e-12, 1.3e-14 / 9.7e-14; slider-crank
    2.8e-13, 1.1e-13 / 3.1e-12, 1.1e-13 / 4.8e-13."""
    if name == "iftomm-a01":
        kin, true = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a01.toml")), _pendulum_error
        kin.assemble()
    else:
        kin, true = _kinematics(name), _problem_error(name)
    reference = simulate(kin, check=True, tolerance=1e-11)
    check = reference.check
    assert check is not None and check.consistent is not False and check.reference.converged
    for run in (reference, check.reference):
        assert np.all(true(kin, run.motion) <= run.estimate), run.method
    assert check.relative <= 1e-11


def test_both_native_methods_agree_across_ten_singular_passes():
    """IFToMM A02 (ten singular passes in 10 s) at 1e-11 of its size: the check converges and
    agrees with DOP853 to 1e-11 of the size. Measured: 3.6e-12 m (1.8e-12 of the 2 m size),
    the check stating 9.3e-12 m against a true 1.6e-12 m (``benchmarks/bench_free_reference.py
    a02``: against the reduction in 30 digits); DOP853 states 3.9e-11 m, not converged,
    against a true 2.1e-12 m."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a02.toml"))
    kin.assemble()
    check = simulate(kin, check=True, tolerance=1e-11).check
    assert check is not None and check.reference.converged and check.consistent is not False
    assert check.relative <= 1e-11
