"""Time a command line: ``python benchmarks/bench_cli.py N COMMAND...`` runs it N
times and prints the median wall time (``perf_counter``) and the median CPU time
(user + system of the command and every process it started, from ``getrusage``;
:func:`bench_main_job.adopt_orphans`), with the load average. On a
shared machine the CPU time is the figure to compare (README, Speed).

Example: ``PYTHONPATH=src python benchmarks/bench_cli.py 5 python -m xcheck solve fourbar``
"""

import os
import resource
import statistics
import subprocess
import sys
import time

from bench_main_job import adopt_orphans, reap_orphans


def main() -> None:
    n, command = int(sys.argv[1]), sys.argv[2:]
    walls, cpus = [], []
    adopt_orphans()
    for _ in range(n):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        walls.append(time.perf_counter() - start)
        reap_orphans()
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
