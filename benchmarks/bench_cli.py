"""Time a command line: ``python benchmarks/bench_cli.py N COMMAND...`` runs it N
times and prints the median wall time (``perf_counter``) and the median CPU time
(user + system of the command and every process it started, from ``getrusage``;
:func:`bench_main_job.adopt_orphans`), with the load average. On a
shared machine the CPU time is the figure to compare (README, Speed).

Example: ``PYTHONPATH=src python benchmarks/bench_cli.py 5 python -m xcheck solve fourbar``.
With ``--cold`` first, each run gets a new empty ``$XCHECK_CACHE_DIR`` (an empty cache
folder): ``python benchmarks/bench_cli.py --cold 5 xcheck run fourbar --no-report --json``.
"""

import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from bench_main_job import adopt_orphans, reap_orphans


def main() -> None:
    cold = sys.argv[1] == "--cold"
    arguments = sys.argv[2:] if cold else sys.argv[1:]
    n, command = int(arguments[0]), arguments[1:]
    walls, cpus = [], []
    adopt_orphans()
    for _ in range(n):
        folder = tempfile.mkdtemp(prefix="xcheck-cold-") if cold else None
        env = {**os.environ, "XCHECK_CACHE_DIR": folder} if folder else None
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
        walls.append(time.perf_counter() - start)
        reap_orphans()
        if folder:
            shutil.rmtree(folder, ignore_errors=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        if done.returncode not in (0, 1):
            print("exit code", done.returncode, done.stderr.decode()[-500:])
    print(
        f"{' '.join(command)}: wall median {statistics.median(walls):.2f} s "
        f"(min {min(walls):.2f}, max {max(walls):.2f}); "
        f"CPU median {statistics.median(cpus):.2f} s (min {min(cpus):.2f}); n={n}; load {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
