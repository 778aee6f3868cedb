"""The main job's figures, each beside its goal: ``xcheck run`` cold (an empty
cache folder) and warm (nothing changed), on the four-bar, a user's six-bar and
every bundled mechanism; ``xcheck simulate`` with every engine; the quick test
loop and ``.ci/run`` on a fresh clone.

Usage: ``python benchmarks/bench_main_job.py [--out DIR] [--no-suite]``
(``make bench`` runs it with ``--out $BENCH_OUT/main-job``). Each command runs
in a subprocess, with ``$XCHECK_CACHE_DIR`` a folder of its own (cold: empty;
warm: what a cold run left) and its reports under ``--out``: three times where
a run takes seconds (a new empty folder for each cold run), the median shown,
once for ``run all`` cold, the test loop and ``.ci/run``. Its wall time, its CPU
time (user + system of it and its children) and the load average before and
after are printed with it, then a table of every figure beside its goal.
``--no-suite`` leaves out the test suite's two rows (about 15 minutes).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
XCHECK = str(BIN / "xcheck")
SIX_BAR = "docs/examples/stephenson-six-bar.toml"


def adopt_orphans() -> None:
    """Make this process a child subreaper (Linux): a process that a command leaves
    behind, such as the fork server of its workers, which ends after the command,
    becomes this process's child, so that :func:`timed` can wait for it and count
    its CPU time and its children's."""
    if sys.platform.startswith("linux"):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER


def reap_orphans(patience: float = 60.0) -> None:
    """Wait for every child this process has left (the orphans it adopted), at most
    ``patience`` seconds; one still running then is named, and not counted."""
    deadline = time.monotonic() + patience
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0 and time.monotonic() > deadline:
            print(f"  (a process the command left still runs after {patience:g} s: not counted)", flush=True)
            return
        if pid == 0:
            time.sleep(0.01)


def timed(command: list[str], cwd: Path, env: dict) -> tuple[float, float, int, float, float]:
    """(wall s, CPU s, exit code, load before, load after) of one run of ``command``: its CPU
    time that of every process it started (:func:`adopt_orphans`)."""
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall = time.perf_counter() - start
    reap_orphans()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    if done.returncode not in (0, 1):
        print(f"  exit code {done.returncode}: {done.stderr.decode(errors='replace')[-800:]}", flush=True)
    return wall, cpu, done.returncode, load, os.getloadavg()[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(tempfile.gettempdir()) / "xcheck-bench" / "main-job")
    parser.add_argument("--no-suite", action="store_true", help="leave out the test suite's rows")
    options = parser.parse_args()
    adopt_orphans()
    out = options.out
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    rows: list[tuple[str, str, float, float, str]] = []

    def measure(label: str, command: list[str], goal: float, caches: list[Path | None], cwd: Path = ROOT) -> None:
        """Run ``command`` once per folder of ``caches`` (None: the environment's cache), the medians kept."""
        runs = []
        for folder in caches:
            env = {**os.environ}
            if folder is not None:
                env["XCHECK_CACHE_DIR"] = str(folder)
            runs.append(timed(command, cwd, env))
        wall, cpu = statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)
        code = max(r[2] for r in runs)
        met = "yes" if wall <= goal and all(r[2] in (0, 1) for r in runs) else "no"
        shown = " ".join(command).replace(str(BIN) + "/", "")
        each = f" (median of {len(runs)}: {', '.join(f'{r[0]:.2f}' for r in runs)} s)" if len(runs) > 1 else ""
        print(
            f"{shown}\n  {label}: wall {wall:.1f} s{each}, CPU {cpu:.1f} s, exit {code}; goal <= {goal:g} s: "
            f"{met}; load {runs[0][3]:.1f} -> {runs[-1][4]:.1f}",
            flush=True,
        )
        rows.append((label, f"<= {goal:g} s", wall, cpu, met))

    def cache(name: str) -> Path:
        folder = out / "caches" / name
        folder.mkdir(parents=True, exist_ok=True)
        return folder

    def colds(name: str, count: int = 3) -> list[Path | None]:
        """``count`` new empty cache folders, the last named ``name`` (a warm run's after)."""
        return [cache(f"{name}-{i}") for i in range(1, count)] + [cache(name)]

    reports = str(out / "reports")
    command = [XCHECK, "run", "fourbar", "--out", reports]
    measure("run fourbar (report), cold", command, 4.0, colds("fourbar"))
    measure("run fourbar (report), warm", command, 1.0, [cache("fourbar")] * 3)
    command = [XCHECK, "run", "fourbar", "--no-report", "--json"]
    measure("run fourbar --no-report --json, cold", command, 3.0, colds("fourbar-json"))
    command = [XCHECK, "run", SIX_BAR, "--out", reports]
    measure("run FILE, a user's six-bar (Stephenson III, 5 moving bodies), cold", command, 8.0, colds("six-bar"))
    command = [XCHECK, "run", "all", "--out", reports]
    measure("run all (reports), cold", command, 40.0, [cache("all")])
    measure("run all (reports), warm", command, 5.0, [cache("all")] * 3)
    command = [XCHECK, "simulate", "iftomm-a01", "--out", reports]
    measure("simulate iftomm-a01 (every engine), cold", command, 10.0, colds("a01"))
    if not options.no_suite:
        quick = [str(BIN / "python"), "-m", "pytest", "-q", "-n", "auto", "-m", "not slow", "-p", "no:cacheprovider"]
        measure("pytest -m 'not slow'", quick, 180.0, [None])
        clone = out / "clone"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        env_free = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "XCHECK_CACHE_DIR")}
        wall, cpu, code, before, after = timed([str(clone / ".ci" / "run")], clone, env_free)
        met = "yes" if wall <= 600.0 and code == 0 else "no"
        loads = f"load {before:.1f} -> {after:.1f}"
        print(f".ci/run on a fresh clone\n  wall {wall:.0f} s, CPU {cpu:.0f} s, exit {code}; {loads}")
        rows.append((".ci/run on a fresh clone (installs included)", "<= 600 s", wall, cpu, met))
        shutil.rmtree(clone, ignore_errors=True)
    print("\n| figure | goal | wall s | CPU s | met |\n|---|---|---|---|---|")
    for label, goal, wall, cpu, met in rows:
        print(f"| {label} | {goal} | {wall:.1f} | {cpu:.1f} | {met} |")


if __name__ == "__main__":
    main()
