"""CPU time of compiling xcheck's numba kernels on a machine whose numba cache is empty.

Each case runs in fresh processes with ``NUMBA_CACHE_DIR`` set to an empty folder:

- ``dense``: the four-bar's compiled sweeps (dense Phi_q), 181 samples a sweep;
- ``banded``: the same, then the chain of seven four-bar windows (banded Phi_q) in the same process;
- ``free``: the free-motion reference's compiled RK4 integrator on IFToMM A02, 0.1 s;
- ``together``: a ``dense`` and a ``free`` process started together (two kernel families);
- ``same``: two ``dense`` processes started together (one family: the second loads what the
  first compiled).

Printed per process: CPU seconds (user + system) and wall seconds; the machine may be shared,
so compare CPU, and read the wall times of ``together`` against the load printed beside them.

Run: ``.venv/bin/python benchmarks/bench_numba_compile.py [CASE ...]`` (default: all)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "dense": [["dense"]],
    "banded": [["dense", "banded"]],
    "free": [["free"]],
    "together": [["dense"], ["free"]],
    "same": [["dense"], ["dense"]],
}
WORK = """
import sys, time
import numpy as np
from xcheck import Kinematics, load_mechanism
from xcheck.dynamics._free import release_state, simulate_free

wall, cpu = time.time(), time.process_time()
for part in sys.argv[1:]:
    if part == "free":
        kin = Kinematics(load_mechanism("{root}/models/benchmarks/iftomm-a02.toml"))
        simulate_free(kin, release_state(kin), 0.1, 0.01, 2.5e-3)
        continue
    name = "models/fourbar.toml" if part == "dense" else "tests/data/fourbar-chain-7.toml"
    kin = Kinematics(load_mechanism("{root}/" + name))
    for d in range(kin.system.n_drivers):
        c = np.tile(kin.reference_inputs(), (181, 1))
        c[:, d] += np.linspace(-1.0, 1.0, 181)
        kin.solve(c, compiled=True)
print(f"{{'+'.join(sys.argv[1:]):<14}} CPU {{time.process_time() - cpu:6.2f}} s   wall {{time.time() - wall:6.2f}} s")
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", default=list(CASES), help=f"of {', '.join(CASES)} (default: all)")
    options = parser.parse_args()
    unknown = sorted(set(options.cases) - set(CASES))
    if unknown:
        parser.error(f"unknown case {', '.join(unknown)}: expected some of {', '.join(CASES)}")
    code = WORK.format(root=ROOT)
    for case in options.cases:
        with tempfile.TemporaryDirectory() as cache:
            environment = dict(os.environ, NUMBA_CACHE_DIR=cache, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
            print(f"{case}: load {os.getloadavg()[0]:.1f}", flush=True)
            start = time.time()
            processes = [
                subprocess.Popen([sys.executable, "-c", code, *parts], env=environment) for parts in CASES[case]
            ]
            for process in processes:
                process.wait()
            print(f"  all done after {time.time() - start:.2f} s wall", flush=True)


if __name__ == "__main__":
    main()
