"""The cost of one step of the native free-motion reference, part by part.

A step of the compiled integrator (``dynamics/_free_compiled.py``) is four
accelerations (RK4) and a projection onto the constraints. Each part is timed
in a numba loop, so that Python's call overhead is not counted, at the release
state of a free-motion benchmark (default: A02, the double four-bar), then a
whole integration at the reference's finest step.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_free_step.py [FILE]``
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.dynamics import _free_compiled as compiled  # noqa: E402
from xcheck.dynamics._free import RANK_CUTOFF, _Dynamics, release_state  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REPEATS = 20_000


@njit
def _accelerations(model, structure, scratch, buffers, q, qd, count):
    total = 0.0
    for _ in range(count):
        total += compiled._acceleration(model, structure, scratch, buffers, 1.0, q, qd, 0.0)[0]
    return total


@njit
def _projections(model, structure, scratch, buffers, q, qd, count):
    total = 0.0
    for _ in range(count):
        total += compiled._project(model, structure, scratch, buffers, q, qd)[3]
    return total


@njit
def _fill(model, buffers, q):
    compiled._mass_of(model, q, buffers[0])
    compiled._jacobian_of(model, q, buffers[1])


@njit
def _solves(mass, jac, load, gap, measure, scale_rows, d, mass_scale, structure, scratch, count):
    total = 0.0
    for _ in range(count):
        x = compiled._solve(
            mass, jac, load, gap, measure, RANK_CUTOFF, 1.0, scale_rows, d, mass_scale, structure, scratch
        )[0]
        total += x[0]
    return total


def _per_call(function, *args) -> float:
    """µs per call of ``function``'s loop body (compiled first, then timed)."""
    function(*args, 10)
    start = time.perf_counter()
    function(*args, REPEATS)
    return (time.perf_counter() - start) / REPEATS * 1e6


def main() -> None:
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "models" / "benchmarks" / "iftomm-a02.toml"
    kin = Kinematics(load_mechanism(path))
    start = release_state(kin)
    packed = compiled.Packed(_Dynamics(kin))
    model, structure = packed.arrays(), packed.structure()
    n, rows = len(start.q), len(model[20])
    buffers = (np.zeros((n, n)), np.zeros((rows, n)), np.empty(rows), np.empty(rows), np.empty(n))
    side = rows if structure[5][0] > 0 else 0
    scratch = (np.zeros((side, side)), np.empty((side, side)))
    q, qd = np.asarray(start.q, dtype=float).copy(), np.asarray(start.qd, dtype=float).copy()
    off = q + 1e-7 * kin.mechanism.size  # off the constraints: the projection corrects the positions too
    _fill(model, buffers, q)
    zero_load, zero_gap = np.zeros(n), np.zeros(rows)
    solve = (buffers[0], buffers[1], zero_load, zero_gap)
    scales = (model[20], model[21], model[22], structure, scratch)
    print(f"{path.name}: n = {n} coordinates, {rows} constraint rows; µs per call, in a numba loop")
    state = (model, structure, scratch, buffers)
    parts = [
        ("acceleration (four a step)", _per_call(_accelerations, *state, q, qd)),
        ("constrained solve, no measure", _per_call(_solves, *solve, False, *scales)),
        ("constrained solve with the measure", _per_call(_solves, *solve, True, *scales)),
        ("projection, on the constraints", _per_call(_projections, *state, q, qd)),
        ("projection, positions corrected too", _per_call(_projections, *state, off, qd)),
    ]
    step, steps = 0.3125e-3, 8000
    compiled.integrate(model, structure, q, qd, step, 8, 10, 8 * step)
    begin = time.perf_counter()
    compiled.integrate(model, structure, q, qd, step, 8, steps // 8, 8 * step)
    parts.append((f"whole step ({steps} steps of {step * 1e3:g} ms)", (time.perf_counter() - begin) / steps * 1e6))
    for name, micro in parts:
        print(f"  {name:40s} {micro:8.1f}")


if __name__ == "__main__":
    main()
