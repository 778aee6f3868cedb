"""The native free-motion reference against its speed goals: its CPU time and its true error.

- IFToMM A02 (the double four-bar, ten singular passes in 10 s): the DOP853 reference at the
  file's tolerance, at 1e-11 of its 2 m size and at the goal's (1e-11 m, 5e-12 of the size),
  and at 1e-11 of the size again from the reduction's exact start (3.3e-16 from the release
  state), its CPU time (the ladder's runs, the release excluded) and its true error, each
  followed by its check's (the ladder of Gauss-Legendre collocation at the same tolerance,
  and its agreement with the reference), against the double four-bar reduced
  to one degree of freedom, theta'' = -(3.5 / 3) g cos(theta) (mpmath's Taylor method, 30 digits);
  goal: at most 1e-11 m in at most 1 CPU s.
- iftomm-a02-n40 (81 bars, 243 coordinates) over its file's 20 s: the release's CPU time (the
  branch's map), the reference's (its ladder within its work budget), whether it converged, its
  stated error and its cranks' true error against the chain's reduction,
  theta'' = -((41/2 + 40) / (41/3 + 40)) g cos(theta) (as tests/test_free_motion.py); then its
  single runs at local tolerances 1e-10 to 1e-15, each within the ladder's whole budget;
  goal: converged to 1e-9 of its size in at most 60 CPU s.

- passes: where A02's round-off comes from: single DOP853 runs from the exact state (the
  reduction's, in 30 digits) 0.2 s before a singular pass to 0.2 s after it, and over a stretch
  without one, at local tolerances 1e-11 to 1e-15: their errors in position and velocity at the end.

- conditioning: A02's accelerations near the pass at 0.714 s (1e-2 to 1e-5 s after it) at
  the reduction's state rounded to float64: the Jacobian's smallest singular value, the
  error of the float64 solve, that of the same float64 equations solved in 50 digits, and how
  far the exact accelerations move for a state 1e-13 m off the constraints (along the
  Jacobian's weakest row direction).

- segments: where A02's round-off enters: single DOP853 runs at 1e-14 over each 0.2 s of its
  10 s from the reduction's exact state and from that state moved 4 ulps: how far apart
  their cranks' angles and rates end, over stretches with a singular pass and without.

- starts: A02's ladder at 1e-11 of its size from 40 starts moved 4 ulps: whether its stated
  error bounds its true error at every output from each (and would, with one round-off
  run's spread added unscaled).

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_free_reference.py [a02] [n40] [passes]
[conditioning] [segments] [starts]``
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import mpmath as mp  # noqa: E402
import numpy as np  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.dynamics._adaptive import simulate_adaptive  # noqa: E402
from xcheck.dynamics._free import adaptive_reference, release_state  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
G = 9.81


def _reduction(k: float):
    """The cranks' angle and rate of a double four-bar chain on its parallelogram branch as
    functions of time (mpmath's Taylor series method at 30 digits)."""
    mp.mp.dps = 30
    rate = mp.mpf(k) * mp.mpf("9.81")
    return mp.odefun(lambda t, y: [y[1], -rate * mp.cos(y[0])], 0, [mp.pi / 2, mp.mpf(-1)])


def reduced_theta(k: float, times: np.ndarray) -> np.ndarray:
    """The cranks' angle of a double four-bar chain on its parallelogram branch (rad, (N,)):
    theta'' = -k g cos(theta) from theta = 90 deg at -1 rad/s, by mpmath's Taylor series
    method at 30 digits (float64's DOP853 at rtol 1e-13 is 1.7e-11 rad off at 5 s on A02)."""
    solution = _reduction(k)
    return np.array([float(solution(mp.mpf(float(t)))[0]) for t in times])


def _a02_state(solution, t: float) -> tuple[np.ndarray, np.ndarray]:
    """A02's body coordinates and rates at ``t`` (s) from its reduction (three cranks, then
    two couplers), rounded to float64."""
    theta, w = solution(mp.mpf(t))
    c, s = float(mp.cos(theta)), float(mp.sin(theta))
    q = [[i + c / 2, s / 2, float(theta)] for i in range(3)] + [[i + 0.5 + c, s, 0.0] for i in range(2)]
    qd = [[-s * float(w) / 2, c * float(w) / 2, float(w)]] * 3 + [[-s * float(w), c * float(w), 0.0]] * 2
    return np.ravel(q), np.ravel(qd)


def passes() -> None:
    """A02's error across single singular passes and over a stretch without one."""
    from xcheck.dynamics._adaptive import integrate_adaptive
    from xcheck.dynamics._free import _Dynamics
    from xcheck.dynamics._free_compiled import Packed

    kin, _, _, size, _ = _released("iftomm-a02", "where the round-off comes from")
    packed, solution = Packed(_Dynamics(kin)), _reduction(3.5 / 3.0)

    def exact(t: float) -> tuple[np.ndarray, np.ndarray]:
        return _a02_state(solution, t)

    def off(a: np.ndarray, b: np.ndarray) -> float:  # angles times the size
        delta = np.abs(a - b)
        delta[2::3] *= size
        return float(delta.max())

    for begin, end, what in [(0.5, 0.9, "across the pass at 0.714 s"), (1.6, 2.0, "no pass"),
                             (2.45, 2.85, "across the pass at 2.657 s")]:  # fmt: skip
        q0, qd0 = exact(begin)
        q1, qd1 = exact(end)
        for tolerance in [1e-11, 1e-12, 1e-13, 1e-14, 1e-15]:
            run = integrate_adaptive(packed, q0, qd0, 40, (end - begin) / 40, tolerance, 10**6)
            print(
                f"  {begin:g}-{end:g} s, {what}, at {tolerance:g}: {run.accepted} steps, {run.failure or 'ok'}; "
                f"off by {off(run.q[-1], q1):.2g} m, {off(run.qd[-1], qd1):.2g} m/s"
            )


def conditioning() -> None:
    """A02's accelerations near a singular pass: where their error comes from."""
    from xcheck.dynamics._free import _Dynamics

    kin, _, _, _, _ = _released("iftomm-a02", "what the accelerations near a pass are sensitive to")
    dyn, k = _Dynamics(kin), 3.5 / 3.0
    solution = _reduction(k)
    crossing = mp.findroot(lambda t: mp.sin(solution(t)[0]), mp.mpf("0.714"))

    def exact_acceleration(q: np.ndarray, qd: np.ndarray) -> np.ndarray:  # M, J, gamma in float64, solved in 50 digits
        mp.mp.dps = 50
        mass, jac, gamma, load = dyn._mass(q), dyn.joints.jacobian(q), dyn.joints.gamma(q, qd), dyn.forces(q, qd)
        n, m = jac.shape[1], jac.shape[0]
        system, rhs = mp.zeros(n + m, n + m), mp.matrix(list(load) + list(gamma))
        for i in range(n):
            for j in range(n):
                system[i, j] = mass[i, j]
        for r in range(m):
            for j in range(n):
                system[n + r, j] = system[j, n + r] = jac[r, j]
        x = mp.lu_solve(system, rhs)
        mp.mp.dps = 30
        return np.array([float(x[i]) for i in range(n)])

    for after in [1e-2, 1e-3, 1e-4, 1e-5]:
        t = crossing + mp.mpf(after)
        q, qd = _a02_state(solution, t)
        theta, w = solution(t)
        a = -k * mp.mpf("9.81") * mp.cos(theta)
        c, s = mp.cos(theta), mp.sin(theta)
        crank = [-(c * w * w + s * a) / 2, (-s * w * w + c * a) / 2, a]
        coupler = [-(c * w * w + s * a), -s * w * w + c * a, 0]
        true = np.array([float(v) for v in crank * 3 + coupler * 2])
        u, singular, _ = np.linalg.svd(dyn.joints.jacobian(q))
        off = dyn.joints.jacobian(q).T @ u[:, -1]
        moved = exact_acceleration(q + 1e-13 * off / np.abs(off).max(), qd)
        print(
            f"  {after:g} s after the pass: smallest singular value {singular[-1]:.2g}; accelerations off by "
            f"{np.abs(dyn.acceleration(q, qd) - true).max():.2g} (float64), "
            f"{np.abs(exact_acceleration(q, qd) - true).max():.2g} (the float64 equations in 50 digits); "
            f"a state 1e-13 m off the constraints moves them by {np.abs(moved - true).max():.2g} m/s^2"
        )


def _released(name: str, goal: str):
    """The benchmark's mechanism released (its CPU printed with the goal): the
    kinematics, the start, the free-motion spec, the size (m) and the cranks'
    angle columns."""
    begin = time.process_time()
    kin = Kinematics(load_mechanism(ROOT / "models" / "benchmarks" / f"{name}.toml"))
    kin.assemble()
    start = release_state(kin)
    release = time.process_time() - begin
    spec = kin.mechanism.free_motion
    assert spec is not None
    size = kin.system.size
    cranks = [3 * i + 2 for i, body in enumerate(kin.mechanism.moving_bodies) if body.name.startswith("crank")]
    print(f"{name}: {kin.system.n} coordinates, {spec.duration:g} s; release {release:.2f} CPU s; goal: {goal}")
    return kin, start, spec, size, cranks


def run(
    name: str, k: float, tolerances: list[float | None], goal: str, exact_start: float | None = None, check=False
) -> None:
    """The reference's ladder at each tolerance (None: the file's); with ``exact_start``, at
    that tolerance once more from the reduction's start rounded to float64 (A02 only); with
    ``check``, the check's ladder after each (:func:`_check`)."""
    from xcheck.dynamics._free import FreeState

    kin, start, spec, size, cranks = _released(name, goal)
    starts = [(tolerance, start, "") for tolerance in tolerances]
    if exact_start is not None:
        q0, qd0 = _a02_state(_reduction(k), 0.0)
        off = max(float(np.abs(q0 - start.q).max()), float(np.abs(qd0 - start.qd).max()))
        starts.append((exact_start, FreeState(q0, qd0), f", from the exact start ({off:.2g} off the release)"))
    for tolerance, start, where in starts:
        tolerance = spec.tolerance if tolerance is None else tolerance
        begin = time.process_time()
        reference = adaptive_reference(kin, start, spec.duration, spec.output_step, tolerance)
        cpu = time.process_time() - begin
        motion = reference.motion
        theta = reduced_theta(k, motion.times)
        off = np.maximum.accumulate(np.abs(motion.q[:, cranks] - theta[:, None]).max(axis=1)) * size
        state = "converged" if reference.converged else "NOT converged"
        print(
            f"  tolerance {tolerance:g} of the size{where}: {state}, {cpu:.2f} CPU s over {len(reference.ladder)} "
            f"runs ({sum(e['steps'] for e in reference.ladder)} steps); stated {reference.estimate.max():.3g} m, "
            f"true {off.max():.3g} m (cranks' angles x the size); true / stated at most "
            f"{(off / reference.estimate).max():.2g} over the outputs"
        )
        if not reference.converged:
            print(f"    {reference.basis.rsplit('; stopped: ', 1)[-1]}")
        if check:
            _check(kin, start, spec, reference, theta, cranks, size)


def _check(kin, start, spec, reference, theta, cranks, size) -> None:
    """The check's ladder (Gauss-Legendre collocation) at the reference's tolerance: its CPU
    time, stated and true error, and its agreement with the reference."""
    from xcheck.dynamics._collocation import collocation_reference
    from xcheck.dynamics._reference import compare_runs

    begin = time.process_time()
    check = collocation_reference(kin, start, spec.duration, spec.output_step, reference.tolerance)
    cpu = time.process_time() - begin
    off = np.maximum.accumulate(np.abs(check.motion.q[:, cranks] - theta[:, None]).max(axis=1)) * size
    agreement = compare_runs(kin, reference, check)
    print(
        f"    check (Gauss-Legendre collocation): {'converged' if check.converged else 'NOT converged'}, {cpu:.2f} "
        f"CPU s over {len(check.ladder)} runs; stated {check.estimate.max():.3g} m, true {off.max():.3g} m, true / "
        f"stated at most {(off / check.estimate).max():.2g}; agrees with DOP853 to {agreement.agreement.max():.3g} "
        f"m ({agreement.relative:.2g} of the size)"
    )


def runs(name: str, k: float, tolerances: list[float], goal: str) -> None:
    from xcheck.dynamics._reference import WORK_BUDGET, difference, work_units

    kin, start, spec, size, cranks = _released(name, goal)
    previous = None
    budget = int(WORK_BUDGET / work_units(kin))
    theta = reduced_theta(k, np.arange(round(spec.duration / spec.output_step) + 1) * spec.output_step)
    for tolerance in tolerances:
        begin = time.process_time()
        motion = simulate_adaptive(kin, start, spec.duration, spec.output_step, tolerance, budget)
        cpu = time.process_time() - begin
        reached = len(motion.times)  # a run that stopped early: its outputs so far
        true = float(np.abs(motion.q[:, cranks] - theta[:reached, None]).max()) * size
        gap = math.nan
        if previous is not None and not motion.failure:
            gap = float(difference(kin, motion, previous).max())
        print(
            f"  DOP853 at {tolerance:g}: {motion.failure or 'ok'}, {cpu:.2f} CPU s, {motion.statistics['steps']} "
            f"steps; difference from the run before {gap:.3g} m ({gap / size:.2g} of the size), true {true:.3g} m"
        )
        if not motion.failure:
            previous = motion


def segments(length: float = 0.2) -> None:
    """Where A02's round-off enters: single DOP853 runs at 1e-14 over each ``length`` (s) of
    its 10 s from the reduction's exact state rounded to float64, and from that state moved 4
    ulps in four patterns of signs: the spread of the five runs' cranks' angle and rate at the
    segment's end, for segments with a singular pass and without."""
    from xcheck.dynamics._free import FreeState, consistent_state
    from xcheck.dynamics._reference import perturbed_start

    kin, _, _, _, cranks = _released("iftomm-a02", "where the round-off enters, and how much")
    solution = _reduction(3.5 / 3.0)
    crossings = [float(mp.findroot(lambda t: mp.sin(solution(t)[0]), mp.mpf(guess))) for guess in
                 [0.714, 1.228, 2.657, 3.171, 4.599, 5.113, 6.542, 7.056, 8.484, 8.998]]  # fmt: skip
    spread: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    for begin in np.arange(0.1, 10.0 - length + 1e-9, length):
        q0, qd0 = _a02_state(solution, begin)
        theta, rate = (float(v) for v in solution(mp.mpf(begin + length)))
        exact = consistent_state(kin, q0, qd0)
        ends = []
        for start in [exact, *(perturbed_start(kin, exact, pattern) for pattern in range(4))]:
            run = simulate_adaptive(kin, FreeState(start.q, start.qd), length, length / 4, 1e-14, 10**7)
            ends.append((run.q[-1, cranks].mean() - theta, run.qd[-1, cranks].mean() - rate))
        near = any(begin < t < begin + length for t in crossings)
        spread[near].append(tuple(np.ptp(np.array(ends), axis=0)))
    for near, what in [(True, "with a singular pass"), (False, "without one")]:
        angle, rate = np.array(spread[near]).T
        print(
            f"  {len(angle)} segments of {length:g} s {what}: the five runs' spread at the end up to "
            f"{angle.max():.2g} rad (median {np.median(angle):.2g}) and {rate.max():.2g} rad/s (median "
            f"{np.median(rate):.2g})"
        )


def starts(count: int = 40) -> None:
    """A02's ladder at 1e-11 of its size from ``count`` starts moved 4 ulps (each in its own
    pattern of signs, projected onto the constraints): whether its stated error bounds its
    true error at every output from each, and how the true and stated errors scatter; and
    whether it would with one round-off run's spread added unscaled instead (those runs
    repeated: the same runs as the ladder's)."""
    from xcheck.dynamics._free import FreeState
    from xcheck.dynamics._reference import ROUND_OFF_FACTOR, ROUND_OFF_RUNS, perturbed_start, spread_of

    kin, start, spec, size, cranks = _released("iftomm-a02", "a stated error that bounds from any start")
    theta = reduced_theta(3.5 / 3.0, np.arange(round(spec.duration / spec.output_step) + 1) * spec.output_step)
    rows = []
    for pattern in range(1000, 1000 + 2 * count, 2):  # (an odd pattern is the opposite of the even one)
        moved = perturbed_start(kin, start, pattern)
        begin = time.process_time()
        reference = adaptive_reference(kin, FreeState(moved.q, moved.qd), spec.duration, spec.output_step, 1e-11)
        cpu = time.process_time() - begin
        kept, setting = reference.motion, reference.ladder[-1]["setting"]
        true = np.maximum.accumulate(np.abs(kept.q[:, cranks] - theta[:, None]).max(axis=1)) * size
        spreads = [
            spread_of(kin, simulate_adaptive(kin, perturbed_start(kin, moved, i), spec.duration, spec.output_step,
                                             setting, 10**8), kept)
            for i in range(ROUND_OFF_RUNS)
        ]  # fmt: skip
        one = reference.estimate - ROUND_OFF_FACTOR * np.max(spreads, axis=0) + spreads[0]
        rows.append((float((true / reference.estimate).max()), float(true.max()), float(reference.estimate.max()),
                     reference.converged, cpu, float((true / one).max())))  # fmt: skip
    ratio, true, stated, converged, cpu, single = (np.array(column) for column in zip(*rows, strict=True))
    print(
        f"  {count} starts moved 4 ulps, ladders at 1e-11 of the size: true / stated at most {ratio.max():.2f} "
        f"(median {np.median(ratio):.2f}; above 1 from {(ratio > 1).sum()}); true {true.min():.2g} to "
        f"{true.max():.2g} m (median {np.median(true):.2g}), stated {stated.min():.2g} to {stated.max():.2g} m; "
        f"converged from {converged.sum()}; {np.median(cpu):.2f} CPU s each (median). With one round-off run's "
        f"spread unscaled: true / stated at most {single.max():.2f}, above 1 from {(single > 1).sum()}"
    )


if __name__ == "__main__":
    which = sys.argv[1:] or ["a02", "n40"]
    if "a02" in which:
        run("iftomm-a02", 3.5 / 3.0, [None, 1e-11, 5e-12], "<= 1e-11 m true error in <= 1 CPU s", 1e-11, check=True)
    if "n40" in which:
        k = (41 / 2 + 40) / (41 / 3 + 40)
        goal = "converged to 1e-9 of the size in <= 60 CPU s"
        run("iftomm-a02-n40", k, [None], goal)
        runs("iftomm-a02-n40", k, [1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15], goal)
    if "passes" in sys.argv[1:]:
        passes()
    if "conditioning" in sys.argv[1:]:
        conditioning()
    if "segments" in sys.argv[1:]:
        segments()
    if "starts" in sys.argv[1:]:
        starts()
