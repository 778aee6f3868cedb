"""Benchmark of the general solver: samples per second for position, velocity
and acceleration of the seed four-bar, on one core.

Run:  make bench   (or: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_solver.py)
"""

from __future__ import annotations

import os

# one core: set before numpy loads its BLAS
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402

MODELS = Path(__file__).resolve().parents[1] / "models"


def bench(name: str, samples: int, repeats: int) -> dict:
    """Best and median wall time of one sweep over the feasible range of the first input."""
    kin = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
    rng = kin.input_range(0)
    ref = kin.reference_inputs()[0]
    low = rng.low + 1e-6 if rng.low is not None else ref - np.pi
    high = rng.high - 1e-6 if rng.high is not None else ref + np.pi
    c = np.tile(kin.reference_inputs(), (samples, 1))
    c[:, 0] = np.linspace(low, high, samples)
    rates = np.ones_like(c)
    kin.solve(c[:1000], rates[:1000])  # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        solution = kin.solve(c, rates)
        times.append(time.perf_counter() - start)
    assert solution.success, "the benchmark sweep must solve"
    return {
        "name": name,
        "samples": samples,
        "best": min(times),
        "median": float(np.median(times)),
        "max_residual": float(solution.residual.max()),
        "mean_iterations": float(solution.iterations.mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("mechanisms", nargs="*", default=["fourbar", "slider-crank", "two-body-arm"])
    args = parser.parse_args()
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"numpy {np.__version__}, one thread"
    )
    print(
        f"{'mechanism':14} {'samples':>8} {'best s':>8} {'median s':>9} {'samples/s':>11} "
        f"{'iterations':>10} {'max residual m':>15}"
    )
    for name in args.mechanisms:
        r = bench(name, args.samples, args.repeats)
        print(
            f"{r['name']:14} {r['samples']:8d} {r['best']:8.3f} {r['median']:9.3f} "
            f"{r['samples'] / r['best']:11.0f} {r['mean_iterations']:10.2f} {r['max_residual']:15.1e}"
        )


if __name__ == "__main__":
    main()
