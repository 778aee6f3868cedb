"""Benchmark of the general solver: samples per second for position, velocity
and acceleration on one core, the compiled sweep against the NumPy reference
and a hand-written NumPy closed form of the four-bar, and the peak memory of a
sweep as the number of samples grows.

Run:  make bench   (or: OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_solver.py)

Timings are CPU seconds of this process (``time.process_time``: on a machine
shared with other work, wall time mostly measures the others) and alternate
the variants in one process (medians of ``--repeats``), so that their ratios
hold even when the absolute figures drift. Peak memory is measured in a fresh subprocess per size with
tracemalloc (NumPy's allocations included): the whole peak during ``solve`` and
the part above the returned arrays (the working memory).
"""

from __future__ import annotations

import os

# one core: set before numpy loads its BLAS
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402

MODELS = Path(__file__).resolve().parents[1] / "models"
MIB = 2.0**20


def sweep(kin: Kinematics, samples: int):
    """Inputs over the feasible range of the first input, rates 1, accelerations 0.5."""
    rng = kin.input_range(0)
    ref = kin.reference_inputs()[0]
    low = rng.low + 1e-6 if rng.low is not None else ref - np.pi
    high = rng.high - 1e-6 if rng.high is not None else ref + np.pi
    c = np.tile(kin.reference_inputs(), (samples, 1))
    c[:, 0] = np.linspace(low, high, samples)
    return c, np.ones_like(c), np.full_like(c, 0.5)


def fourbar_closed_form(theta, omega, alpha, r=0.45, d=0.45, s=0.5, ground=0.6, sign=1.0):
    """The four-bar's angles, rates and accelerations in closed form (NumPy).

    Crank AB (r) at theta from A = 0, coupler BC (d), rocker DC (s), D = (ground, 0);
    the coupler's and rocker's angles from the triangle B C D, their rates and
    accelerations from the differentiated loop equation. Returns six (N,) arrays.
    """
    b = r * np.exp(1j * theta)
    bd = ground - b
    e = np.abs(bd)
    turn = sign * np.arccos((d * d + e * e - s * s) / (2.0 * d * e))
    c = b + d * (bd / e) * np.exp(1j * turn)
    phi2, phi3 = np.angle(c - b), np.angle(c - ground)
    e1, e2, e3 = np.exp(1j * theta), np.exp(1j * phi2), np.exp(1j * phi3)
    sin23 = np.sin(phi2 - phi3)
    omega2 = -r * omega * np.sin(theta - phi3) / (d * sin23)
    omega3 = r * omega * np.sin(theta - phi2) / (s * -sin23)
    # i d a2 e2 - i s a3 e3 = -(i r a1 e1 - r w1^2 e1 - d w2^2 e2 + s w3^2 e3) =: z
    z = -(1j * r * alpha * e1 - r * omega**2 * e1 - d * omega2**2 * e2 + s * omega3**2 * e3)
    alpha2 = np.imag(z * np.conj(1j * e3)) / (d * np.imag(1j * e2 * np.conj(1j * e3)))
    alpha3 = np.imag(z * np.conj(1j * e2)) / (-s * np.imag(1j * e3 * np.conj(1j * e2)))
    return phi2, phi3, omega2, omega3, alpha2, alpha3


def timings(name: str, samples: int, repeats: int, reference: bool) -> dict:
    """Median wall times of the compiled sweep, the reference and (four-bar) the closed form."""
    kin = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
    c, rates, accelerations = sweep(kin, samples)
    kin.solve(c[:1000], rates[:1000], accelerations[:1000], compiled=True)  # warm-up: compile or load the kernels
    variants = {"compiled": lambda: kin.solve(c, rates, accelerations, compiled=True)}
    if reference:
        variants["reference"] = lambda: kin.solve(c, rates, accelerations, compiled=False)
    if name == "fourbar":
        variants["closed form"] = lambda: fourbar_closed_form(c[:, 0], rates[:, 0], accelerations[:, 0])
    times: dict[str, list[float]] = {key: [] for key in variants}
    for _ in range(repeats):
        for key, run in variants.items():
            start = time.process_time()
            result = run()
            times[key].append(time.process_time() - start)
            if key == "compiled":
                assert result.success, "the benchmark sweep must solve"
                solution = result
    return {
        "name": name,
        "samples": samples,
        "median": {key: float(np.median(v)) for key, v in times.items()},
        "max_residual": float(solution.residual.max()),
        "mean_iterations": float(solution.iterations.mean()),
    }


def _peak_child(name: str, samples: int, compiled: bool) -> None:
    """(Subprocess) print the tracemalloc peak of one sweep and the returned arrays' size."""
    import tracemalloc

    kin = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
    c, rates, accelerations = sweep(kin, 1000)
    kin.solve(c, rates, accelerations, compiled=compiled)  # warm-up: atlas, kernels
    c, rates, accelerations = sweep(kin, samples)
    tracemalloc.start()
    start = time.process_time()
    solution = kin.solve(c, rates, accelerations, compiled=compiled)
    seconds = time.process_time() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    fields = ("q", "qd", "qdd", "status", "residual", "singularity", "iterations")
    returned = sum(getattr(solution, f).nbytes for f in fields)
    print(json.dumps({"peak": peak, "returned": returned, "seconds": seconds}))


def peak_memory(name: str, samples: int, compiled: bool) -> dict:
    """Peak memory of one sweep, measured in a fresh interpreter."""
    script = Path(__file__).resolve()
    out = subprocess.run(
        [sys.executable, str(script), "--peak-child", name, str(samples), "1" if compiled else "0"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-reference", action="store_true", help="time the compiled sweep only")
    parser.add_argument(
        "--memory", type=str, default="10000,100000,1000000", help="sizes for the peak-memory table ('' for none)"
    )
    parser.add_argument("--peak-child", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("mechanisms", nargs="*", default=["fourbar", "slider-crank", "two-body-arm"])
    args = parser.parse_args()
    if args.peak_child:
        name, samples, compiled = args.peak_child
        _peak_child(name, int(samples), compiled == "1")
        return
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"numpy {np.__version__}, one thread, CPU time, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(
        f"{'mechanism':14} {'samples':>8} {'compiled/s':>11} {'reference/s':>12} {'speed-up':>9} "
        f"{'closed form/s':>14} {'closed/compiled':>15} {'iterations':>10} {'max residual m':>15}"
    )
    for name in args.mechanisms:
        r = timings(name, args.samples, args.repeats, not args.no_reference)
        rate = {key: args.samples / t for key, t in r["median"].items()}
        fast, ref, closed = rate["compiled"], rate.get("reference"), rate.get("closed form")
        ref_text, up_text = ("", "") if ref is None else (f"{ref:.0f}", f"{fast / ref:.1f}x")
        closed_text, ratio_text = ("", "") if closed is None else (f"{closed:.0f}", f"{closed / fast:.1f}x")
        print(
            f"{r['name']:14} {r['samples']:8d} {fast:11.0f} {ref_text:>12} {up_text:>9} "
            f"{closed_text:>14} {ratio_text:>15} {r['mean_iterations']:10.2f} {r['max_residual']:15.1e}"
        )
    sizes = [int(float(v)) for v in args.memory.split(",") if v]
    if sizes:
        name = args.mechanisms[0]
        print(f"\npeak memory of one {name} sweep (tracemalloc, fresh process; working = peak - returned arrays)")
        print(
            f"{'samples':>9} {'variant':>9} {'samples/s':>10} {'peak MiB':>9} {'returned MiB':>13} {'working MiB':>12}"
        )
        for samples in sizes:
            for compiled in (True, False):
                if not compiled and (args.no_reference or samples > 1_000_000):
                    continue
                m = peak_memory(name, samples, compiled)
                print(
                    f"{samples:9d} {'compiled' if compiled else 'reference':>9} {samples / m['seconds']:10.0f} "
                    f"{m['peak'] / MIB:9.1f} {m['returned'] / MIB:13.1f} {(m['peak'] - m['returned']) / MIB:12.1f}"
                )


if __name__ == "__main__":
    main()
