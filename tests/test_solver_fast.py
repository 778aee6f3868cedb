"""The compiled sweep of Kinematics.solve against the batched NumPy reference,
sample by sample.

Tolerances, from a round-off model checked by measurement. The two paths
factorise the same matrices by LU in a different order of operations
(LAPACK's getrf/getri against a plain loop), so Newton stops at the round-off
floor (a residual of a few eps * size) at configurations that differ by about
eps * |q| / s, with s the singularity measure (1 / condition number); the rates
see that difference through the inverse once more, so qd and qdd differ by about
eps * |x| / s^2, and s itself by about eps / s. Measured on every mechanism
below (sweeps 2 % past each feasible range, 3000 samples) and on the four-bar,
five-bar, rocker and task-2-7 at 100 000 samples, the largest ratio of the
difference to these scales was 0.64 for q, 1.4 for qd and qdd, 0.45 for s; the
residuals differed by at most 4 eps * size. The tests allow 16 for each.
Statuses and NaN patterns were identical everywhere; iteration counts too,
except for 3 of 200 000 four-bar samples whose residuals sat at the round-off
floor (below 4.4 eps * size) where the reference took one step more.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from xcheck import Kinematics, load_mechanism
from xcheck.kinematics._solve import COMPILED_FROM

ROOT = Path(__file__).resolve().parents[1]
EPS = np.finfo(float).eps
MODELS = sorted((ROOT / "models").glob("*.toml"))
DATA = [
    ROOT / "tests" / "data" / f"{name}.toml"
    for name in (
        "double-fourbar",
        "elliptic-trammel",
        "fivebar",
        "inverted",
        "para",
        "rocker-driven",
        "slider-driven",
        "slotted-rod",
        "wedge",
        "arm-block",
        "geared-fivebar",
        "planetary-train",
    )
]


def _sweeps(kin: Kinematics, samples: int):
    """(branch, inputs, rates, accelerations) sweeping each input 2 % past its
    feasible range (or 1.2 turns of a crank), the others at the reference."""
    k = kin.system.n_drivers
    ref = kin.reference_inputs()
    for branch in kin.branches:
        for d in range(k):
            rng = kin.input_range(d, branch)
            low = rng.low - 0.02 * rng.span if rng.low is not None else ref[d] - 1.2 * math.pi
            high = rng.high + 0.02 * rng.span if rng.high is not None else ref[d] + 1.2 * math.pi
            c = np.tile(ref, (samples, 1))
            c[:, d] = np.linspace(low, high, samples)
            rates = np.tile(np.linspace(0.5, 1.5, k), (samples, 1))
            accelerations = np.tile(np.linspace(-1.0, 2.0, k), (samples, 1))
            yield branch, c, rates, accelerations


def walk_once(kin: Kinematics) -> Kinematics:
    """``kin`` with each sweep's waypoint walk computed once and given to every solve
    of the same inputs, each its own copy. The compiled and the reference solve both
    predict a sweep of several inputs by the same code (continuation through waypoints,
    ``Kinematics._predictions``) from the same inputs, which costs most of such a sweep
    (the five-bar: 1.5 of 1.55 CPU s a solve): a test comparing the two paths compares
    what follows the prediction, and walks once."""
    walks: dict = {}
    predictions = kin._predictions

    def shared(branch: str, c: np.ndarray, waypoint_spacing: float):
        key = (branch, c.shape, c.tobytes(), waypoint_spacing)
        if key not in walks:
            walks[key] = predictions(branch, c, waypoint_spacing)
        found = walks[key]
        return None if found is None else tuple(np.copy(part) for part in found)

    kin._predictions = shared
    return kin


def assert_same_solution(kin: Kinematics, fast, ref) -> None:
    """The compiled solution equals the reference within the measured round-off."""
    size = kin.system.size
    assert np.array_equal(fast.status, ref.status)
    differ = fast.iterations != ref.iterations
    floor = 16 * EPS * size
    assert np.all((fast.residual[differ] <= floor) & (ref.residual[differ] <= floor))
    finite = np.isfinite(ref.residual)
    assert np.array_equal(finite, np.isfinite(fast.residual))
    assert np.all(np.abs(fast.residual[finite] - ref.residual[finite]) <= floor)
    conditioning = 1.0 / np.maximum(ref.singularity, np.finfo(float).tiny)
    assert np.all(np.abs(fast.singularity - ref.singularity) <= 16 * EPS * conditioning)
    for field in ("q", "qd", "qdd"):
        ours, theirs = getattr(fast, field), getattr(ref, field)
        assert np.array_equal(np.isnan(ours), np.isnan(theirs)), field
        rows = np.all(np.isfinite(theirs), axis=1)
        magnitude = np.max(np.abs(theirs[rows]), axis=1)
        if field == "q":
            magnitude = np.maximum(magnitude, size)
        error = np.max(np.abs(ours[rows] - theirs[rows]), axis=1)
        amplification = conditioning[rows] if field == "q" else conditioning[rows] ** 2
        bound = 16 * EPS * magnitude * amplification
        assert np.all(error <= bound), (field, float(np.max(error / bound)))


@pytest.mark.parametrize("path", MODELS + DATA, ids=lambda p: p.stem)
def test_compiled_sweep_matches_the_reference(path):
    kin = walk_once(Kinematics(load_mechanism(path)))
    checked = 0
    for branch, c, rates, accelerations in _sweeps(kin, 600):
        fast = kin.solve(c, rates, accelerations, branch=branch, compiled=True)
        ref = kin.solve(c, rates, accelerations, branch=branch, compiled=False)
        assert_same_solution(kin, fast, ref)
        checked += int(np.sum(ref.status <= 1))
    assert checked > 0  # some samples assembled: the comparison is not vacuous


def test_samples_past_a_limit_are_rejected_alike():
    """The four-bar's sweep past its limits: not-converged samples in both,
    NaN rows, and the samples inside solved."""
    kin = Kinematics(load_mechanism(ROOT / "models" / "fourbar.toml"))
    branch, c, rates, accelerations = next(_sweeps(kin, 600))
    fast = kin.solve(c, rates, accelerations, branch=branch, compiled=True)
    outside = fast.status == 3
    assert 0 < outside.sum() < len(c) // 2
    assert np.all(np.isnan(fast.q[outside])) and np.all(np.isfinite(fast.q[~outside]))


def test_strided_inputs_give_the_same_solution():
    """Inputs that are views (not contiguous) reach the kernels as copies."""
    kin = Kinematics(load_mechanism(ROOT / "models" / "two-body-arm.toml"))
    branch, c, rates, accelerations = next(_sweeps(kin, 400))
    wide = np.repeat(c, 2, axis=1)[:, ::2]
    assert not wide.flags.c_contiguous
    a = kin.solve(wide, rates, accelerations, branch=branch, compiled=True)
    b = kin.solve(np.ascontiguousarray(c), rates, accelerations, branch=branch, compiled=True)
    assert np.array_equal(a.q, b.q, equal_nan=True) and np.array_equal(a.qdd, b.qdd, equal_nan=True)


@pytest.mark.parametrize("name", ["models/fourbar.toml", "models/slider-crank.toml"])
def test_samples_rejected_in_the_batch_are_walked_to_alike(name, monkeypatch):
    """The continuation fallback (step 3) and the rates of the samples it
    reaches: with the batch's correction limit made tiny, every sample is
    rejected in the batch and walked to from its anchor, in both paths."""
    import xcheck.kinematics._solve as solve_module
    from xcheck.kinematics import _compiled

    monkeypatch.setattr(solve_module, "MAX_CORRECTION", 1e-300)
    walked = []
    finish = _compiled.finish
    monkeypatch.setattr(_compiled, "finish", lambda *args: walked.append(len(args[5])) or finish(*args))
    kin = Kinematics(load_mechanism(ROOT / name))
    branch, c, rates, accelerations = next(_sweeps(kin, 60))
    fast = kin.solve(c, rates, accelerations, branch=branch, compiled=True)
    ref = kin.solve(c, rates, accelerations, branch=branch, compiled=False)
    assert sum(walked) > 40  # the fallback ran, for most samples
    assert_same_solution(kin, fast, ref)


@pytest.mark.slow
def test_scattered_inputs_of_several_drivers_match():
    """Inputs in random order across the five-bar's plane of inputs (waypoint walks)."""
    kin = Kinematics(load_mechanism(ROOT / "tests" / "data" / "fivebar.toml"))
    rng = np.random.default_rng(1)
    c = kin.reference_inputs() + rng.uniform(-1.5, 1.5, size=(200, 2))
    rates, accelerations = rng.normal(size=c.shape), rng.normal(size=c.shape)
    fast = kin.solve(c, rates, accelerations, compiled=True)
    ref = kin.solve(c, rates, accelerations, compiled=False)
    assert 0 < np.sum(ref.status == 3) < 100  # some past a limit, most assembled
    assert_same_solution(kin, fast, ref)


def test_small_sweeps_run_the_reference_by_default():
    """Below COMPILED_FROM samples the default is the reference, bit for bit
    (the committed reports solve a few hundred samples)."""
    kin = Kinematics(load_mechanism(ROOT / "models" / "fourbar.toml"))
    branch, c, rates, accelerations = next(_sweeps(kin, 300))
    default = kin.solve(c, rates, accelerations, branch=branch)
    ref = kin.solve(c, rates, accelerations, branch=branch, compiled=False)
    for field in ("q", "qd", "qdd", "residual", "singularity"):
        assert np.array_equal(getattr(default, field), getattr(ref, field), equal_nan=True), field
    assert 300 < COMPILED_FROM


@pytest.mark.slow
def test_compiled_sweep_matches_the_reference_at_scale():
    """100 000 four-bar samples: the round-off floor's iteration counts."""
    kin = Kinematics(load_mechanism(ROOT / "models" / "fourbar.toml"))
    branch, c, rates, accelerations = next(_sweeps(kin, 100_000))
    fast = kin.solve(c, rates, accelerations, branch=branch, compiled=True)
    ref = kin.solve(c, rates, accelerations, branch=branch, compiled=False)
    assert_same_solution(kin, fast, ref)


def test_an_exactly_singular_jacobian_takes_the_minimum_norm_step():
    """Newton's step where LU meets an exact zero pivot: the least-squares,
    minimum-norm solution, as the reference's. Every body of the four-bar at
    the origin at angle 0 makes Phi_q exactly singular (rank 8 of 9); the step
    equals pinv(Phi_q) phi to 2.3 eps of its size (measured; 16 allowed, as above)."""
    from xcheck.kinematics import _compiled

    kin = Kinematics(load_mechanism(ROOT / "models" / "fourbar.toml"))
    system, packed = kin.system, _compiled.Packed(kin.system)
    kind, bodies, geometry, _, _, row = packed.terms()
    q = np.zeros(system.n)
    phi = system.residual(q[None], kin.reference_inputs()[None])[0]
    jacobian = system.jacobian(q[None])[0]
    assert _compiled._lu(jacobian.copy(), np.empty(system.n, dtype=np.int64)) == 0.0
    pose = _compiled._new_pose(system.n)
    _compiled._pose(q, pose)
    step = np.full(system.n, np.nan)
    _compiled._least_squares_step(pose, kind, bodies, geometry, row, phi, system.n, step)
    expected = np.linalg.pinv(jacobian) @ phi
    assert np.max(np.abs(step - expected)) <= 16 * EPS * np.max(np.abs(expected))
