"""The banded path of the compiled sweep (issue 17: growth with mechanism size):
the band LU, its solves and the condition estimate against LAPACK, and sweeps of
chains above ``BANDED_FROM`` coordinates against the dense NumPy reference.

Tolerances. The band LU picks the same pivots as LAPACK's dense ``getrf`` (the
same candidates, the first largest), so the factors, solves and the estimate
differ by round-off only: measured at most 2e-15 relative on the random band
matrices below (condition numbers up to about 1e4), the estimate equal to
LAPACK's ``gecon`` to 1e-13. On the chains, the round-off model of
``test_solver_fast`` holds unchanged for q, qd and qdd; the singularity measure
is an estimate (a lower bound on ||A^-1||_1, so never below the exact measure),
measured equal to the exact value to 1e-12 on every sample of the chains' sweeps.
Forced onto the banded path (``BANDED_FROM`` 1), the bundled mechanisms and the
test files of ``test_solver_fast`` (every kind of constraint term, both signs of
the permutations) gave the reference's statuses and NaN rows, q, qd and qdd within
0.14 of that round-off model, and an estimated measure from 1 to 3.07 times the
exact one (task-2-4; Higham's estimate is usually within a factor 3); the test
allows 4.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from scipy.linalg import lapack
from test_solver_fast import DATA, MODELS, _sweeps, walk_once

from xcheck import Kinematics, load_mechanism
from xcheck.kinematics import _banded, _compiled
from xcheck.kinematics._compiled import BANDED_FROM

ROOT = Path(__file__).resolve().parents[1]
EPS = np.finfo(float).eps
sys.path.insert(0, str(ROOT / "benchmarks"))
from make_iftomm_a02_n40 import text as chain_text  # noqa: E402


def _random_band(rng, n: int, kl: int, ku: int) -> np.ndarray:
    """A dense (n, n) matrix with kl diagonals below and ku above, random entries."""
    a = rng.standard_normal((n, n))
    i, j = np.indices((n, n))
    a[(j - i > ku) | (i - j > kl)] = 0.0
    return a


def _to_band(a: np.ndarray, kl: int, ku: int) -> np.ndarray:
    """The storage of :mod:`._banded`: row i's columns i - kl .. i + kl + ku."""
    n = a.shape[0]
    band = np.zeros((n, 2 * kl + ku + 1))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            band[i, j - i + kl] = a[i, j]
    return band


@pytest.mark.parametrize(("n", "kl", "ku"), [(1, 0, 0), (7, 2, 3), (40, 3, 4), (60, 5, 1), (25, 0, 6)])
def test_band_lu_solves_as_lapack(n, kl, ku):
    rng = np.random.default_rng(n + 10 * kl + 100 * ku)
    for _ in range(5):
        a = _random_band(rng, n, kl, ku)
        lu = _to_band(a, kl, ku)
        piv = np.empty(n, dtype=np.int64)
        sign = _banded.band_lu(lu, kl, ku, piv)
        assert sign == np.sign(np.linalg.det(a))
        _, dense_piv = scipy.linalg.lu_factor(a)
        assert np.array_equal(piv, dense_piv)  # the same pivots as getrf
        b = rng.standard_normal(n)
        x = b.copy()
        _banded.band_solve(lu, kl, ku, piv, x)
        expected = np.linalg.solve(a, b)
        assert np.max(np.abs(x - expected)) <= 1e3 * EPS * np.linalg.cond(a) * np.max(np.abs(expected))
        y = b.copy()
        _banded.band_solve_transposed(lu, kl, ku, piv, y)
        expected = np.linalg.solve(a.T, b)
        assert np.max(np.abs(y - expected)) <= 1e3 * EPS * np.linalg.cond(a) * np.max(np.abs(expected))


@pytest.mark.parametrize(("n", "kl", "ku"), [(2, 1, 1), (9, 2, 2), (45, 3, 4), (120, 4, 5)])
def test_condition_estimate_is_lapacks_and_a_lower_bound(n, kl, ku):
    rng = np.random.default_rng(7 * n)
    for _ in range(10):
        a = _random_band(rng, n, kl, ku)
        band = _to_band(a, kl, ku)
        sums = np.empty(n)
        norm = _banded.band_norm1(band, kl, sums)
        assert norm == pytest.approx(np.linalg.norm(a, 1), rel=1e-15)
        piv = np.empty(n, dtype=np.int64)
        _banded.band_lu(band, kl, ku, piv)
        estimate = _banded.inverse_norm1_estimate(band, kl, ku, piv, np.empty(n), np.empty(n))
        exact = np.linalg.norm(np.linalg.inv(a), 1)
        assert estimate <= exact * (1 + 1e-12)
        factors, _ = scipy.linalg.lu_factor(a)
        rcond, info = lapack.dgecon(factors, norm)
        assert info == 0 and 1.0 / (norm * estimate) == pytest.approx(rcond, rel=1e-13)


def test_a_zero_or_nan_pivot_is_reported_as_the_dense_lu_does():
    a = np.diag([1.0, 0.0, 2.0])
    piv = np.empty(3, dtype=np.int64)
    assert _banded.band_lu(_to_band(a, 1, 1), 1, 1, piv) == 0.0
    a[0, 0] = np.nan
    assert np.isnan(_banded.band_lu(_to_band(a, 1, 1), 1, 1, piv))


def _matches_the_reference(kin: Kinematics, fast, ref, largest_ratio: float) -> int:
    """Assert a banded sweep equals the dense reference's: statuses, NaN rows and
    iterations (but at the round-off floor), q, qd and qdd within the round-off
    model of test_solver_fast, and a singularity measure from the exact one (the
    estimate bounds ||A^-1|| from below) to ``largest_ratio`` times it. Returns
    the number of samples with rates."""
    assert np.array_equal(fast.status, ref.status)
    assert np.array_equal(np.isnan(fast.q), np.isnan(ref.q))
    differ = fast.iterations != ref.iterations
    floor = 16 * EPS * kin.system.size
    assert np.all((fast.residual[differ] <= floor) & (ref.residual[differ] <= floor))
    solved = np.isfinite(ref.qd).all(axis=1)
    s = ref.singularity[solved]
    ratio = fast.singularity[solved] / s
    assert np.all((ratio >= 1 - 1e-12) & (ratio <= largest_ratio))
    for field, power in (("q", 1), ("qd", 2), ("qdd", 2)):
        a, b = getattr(fast, field)[solved], getattr(ref, field)[solved]
        scale = np.max(np.abs(b), axis=1, keepdims=True)
        assert np.all(np.abs(a - b) <= 16 * EPS * scale / s[:, None] ** power), field
    return int(solved.sum())


def _chain(tmp_path, windows: int) -> Kinematics:
    path = tmp_path / f"chain-{windows}.toml"
    path.write_text(chain_text(windows, f"chain-{windows}"), encoding="utf-8")
    return Kinematics(load_mechanism(path))


@pytest.mark.parametrize("source", ["fourbar-chain-7", "chain-12"])
def test_a_long_chain_is_banded_and_its_sweep_matches_the_reference(tmp_path, source):
    """Swept 2 % past the crank's feasible range (limit positions at both ends,
    so singular, near-singular and unreachable samples are in it)."""
    if source == "chain-12":
        kin = _chain(tmp_path, 12)
    else:
        kin = Kinematics(load_mechanism(ROOT / "tests" / "data" / f"{source}.toml"))
    assert kin.system.n >= BANDED_FROM
    rng = kin.input_range(0)
    low, high = rng.low, rng.high
    if rng.full_turn:
        low, high = 0.0, 2 * np.pi
    c = np.linspace(low - 0.02 * (high - low), high + 0.02 * (high - low), 1500)[:, None]
    rates, accelerations = np.full_like(c, 0.7), np.full_like(c, -1.3)
    fast = kin.solve(c, rates, accelerations, compiled=True)
    layout, band = kin._packed.structure()
    assert layout is not None and band[0] + band[1] <= 8  # a chain: a few diagonals, whatever n
    ref = kin.solve(c, rates, accelerations, compiled=False)
    # on a chain the estimate was exact: the measure within 1e-12 of the exact one
    assert _matches_the_reference(kin, fast, ref, largest_ratio=1 + 1e-12) > 1000


def test_a_chain_listed_in_scrambled_order_is_as_banded(tmp_path):
    """The band comes from reverse Cuthill-McKee on the bodies, not from the order
    a file lists them in: the same chain with its bodies and joints listed in a
    shuffled order is as narrow, and solves to the same configurations."""
    straight = chain_text(12, "chain")
    blocks = straight.split("\n\n")
    rng = np.random.default_rng(3)
    for head in ("[bodies.", "[[joints]]"):
        at = [k for k, block in enumerate(blocks) if block.startswith(head)]
        for k, block in zip(at, rng.permutation([blocks[k] for k in at])):
            blocks[k] = block
    shuffled = "\n\n".join(blocks)
    assert shuffled != straight
    c = np.linspace(0.3, 1.2, 5)[:, None]
    poses = []
    for label, text in (("straight", straight), ("shuffled", shuffled)):
        path = tmp_path / f"{label}.toml"
        path.write_text(text, encoding="utf-8")
        kin = Kinematics(load_mechanism(path))
        solution = kin.solve(c, compiled=True)
        assert kin._packed.layout is not None and kin._packed.band[0] + kin._packed.band[1] <= 8
        poses.append({name: solution.q[:, 3 * k : 3 * k + 3] for k, name in enumerate(kin.system.body_names)})
    assert poses[0].keys() == poses[1].keys()
    for name, q in poses[0].items():
        assert np.allclose(poses[1][name], q, rtol=0, atol=1e-12), name


def test_a_wide_band_stays_dense(tmp_path, monkeypatch):
    """Where the bodies' order leaves a band wider than n / 2 (a body joined to
    many; here the chain's bodies in a scrambled order stand in for one), the
    Jacobian stays dense and the condition number exact."""
    from scipy.sparse import csgraph

    kin = _chain(tmp_path, 12)
    scrambled = np.random.default_rng(5).permutation(kin.system.n // 3)
    monkeypatch.setattr(csgraph, "reverse_cuthill_mckee", lambda graph, symmetric_mode: scrambled)
    c = np.linspace(0.3, 1.2, 7)[:, None]
    fast = kin.solve(c, compiled=True)
    assert kin._packed.layout is None
    ref = kin.solve(c, compiled=False)
    assert np.array_equal(fast.status, ref.status)
    assert np.all(np.abs(fast.singularity - ref.singularity) <= 16 * EPS / ref.singularity)


@pytest.mark.parametrize("path", MODELS + DATA, ids=lambda p: p.stem)
def test_every_kind_of_term_on_the_banded_path_matches_the_reference(path, monkeypatch):
    """The bundled mechanisms are below BANDED_FROM; forced onto the banded path
    they exercise prismatic and angle terms, drivers of both kinds and both signs
    of the permutations, which the revolute chains above do not."""
    monkeypatch.setattr(_compiled, "BANDED_FROM", 1)
    monkeypatch.setattr(_compiled, "BAND_WIDTH_LIMIT", 100.0)
    kin = walk_once(Kinematics(load_mechanism(path)))
    for branch, c, rates, accelerations in _sweeps(kin, 1000):
        fast = kin.solve(c, rates, accelerations, branch=branch, compiled=True)
        assert kin._packed.layout is not None
        ref = kin.solve(c, rates, accelerations, branch=branch, compiled=False)
        _matches_the_reference(kin, fast, ref, largest_ratio=4.0)
