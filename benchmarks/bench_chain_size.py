"""Benchmark of the general solver's growth with mechanism size: CPU time per sample
(position, velocity and acceleration) of IFToMM A02's chain of four-bar windows
(``make_iftomm_a02_n40.text``: 2 W + 1 bars, n = 3 (2 W + 1) coordinates) for
several numbers of windows W, on one core, compiled sweep and NumPy reference.

Run:  OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_chain_size.py 1 2 5 10 20 33 50
      (``--no-reference``: the compiled sweep only; the reference takes minutes at 50)

From ``BANDED_FROM`` coordinates (30, ten bodies) the compiled sweep factorises the
Jacobian as a band matrix and estimates the condition number (``kinematics._banded``).

Each chain is swept over the middle 90 % of its crank's feasible range (between
the singular all-horizontal positions), 4000 samples, median of 3 in CPU seconds
(``time.process_time``) after a warm-up solve.
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_iftomm_a02_n40 import text  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402

SAMPLES = 4000


def per_sample(kin: Kinematics, inputs: np.ndarray, compiled: bool, repeats: int = 3) -> tuple[float, int]:
    """(median CPU microseconds per sample, samples solved) of one sweep."""
    kin.solve(inputs[:50], np.ones(50), compiled=compiled)  # warm-up: numba's cache, the branch map
    times = []
    for _ in range(repeats):
        start = time.process_time()
        solution = kin.solve(inputs, np.ones_like(inputs), compiled=compiled)
        times.append(time.process_time() - start)
    return float(np.median(times)) / len(inputs) * 1e6, int(np.sum(solution.status <= 1))


def main(windows: list[int], reference: bool = True) -> None:
    print("| windows | bodies | coordinates n | compiled µs/sample | reference µs/sample | solved |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for w in windows:
            path = Path(folder) / f"chain-{w}.toml"
            path.write_text(text(w, f"chain-{w}"))
            kin = Kinematics(load_mechanism(path))
            feasible = kin.input_range(0)
            low, high = (0.0, 2 * np.pi) if feasible.full_turn else (feasible.low, feasible.high)
            inputs = np.linspace(low + 0.05 * (high - low), high - 0.05 * (high - low), SAMPLES)
            compiled, solved = per_sample(kin, inputs, True)
            shown = f"{per_sample(kin, inputs, False)[0]:.1f}" if reference else "—"
            print(f"| {w} | {2 * w + 1} | {kin.system.n} | {compiled:.1f} | {shown} | {solved}/{SAMPLES} |")


if __name__ == "__main__":
    arguments = [a for a in sys.argv[1:] if a != "--no-reference"]
    main([int(a) for a in arguments] or [1, 2, 5, 10, 20, 33, 50], reference="--no-reference" not in sys.argv)
