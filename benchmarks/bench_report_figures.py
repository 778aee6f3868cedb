"""CPU time of each figure of a mechanism's report.

Each mechanism is run first (``xcheck.run``, the results cache used), then each
figure of its report is drawn once to warm the process (matplotlib's import,
its fonts and text caches), then ``--repeats`` times: the least CPU time of a
drawing (``time.process_time``; the machine may be shared) is printed per
figure, with the sum, and the SHA-256 of each figure's bytes (the same on any
machine: compare with the committed report's files).

Run: ``.venv/bin/python benchmarks/bench_report_figures.py [NAME ...] [--engines all] [--repeats 5]``
"""

from __future__ import annotations

import argparse
import hashlib
import time

import xcheck
from xcheck.report import _IMAGES, _figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=["fourbar"], help="mechanisms (default: fourbar)")
    parser.add_argument("--engines", default=None, help="as xcheck run's --engines (default: its default modes)")
    parser.add_argument("--repeats", type=int, default=5, help="drawings timed per figure (default 5)")
    options = parser.parse_args()
    print(f"{'mechanism':<18} {'figure':<16} {'CPU s':>6}  sha256")
    for name in options.names:
        run = xcheck.run(name, engines=options.engines)
        total = 0.0
        for file, function, _ in _IMAGES:
            draw = getattr(_figures, function)
            data = draw(run)
            if data is None:
                continue
            seconds = []
            for _ in range(options.repeats):
                start = time.process_time()
                draw(run)
                seconds.append(time.process_time() - start)
            total += min(seconds)
            print(f"{name:<18} {file:<16} {min(seconds):6.3f}  {hashlib.sha256(data).hexdigest()[:12]}")
        print(f"{name:<18} {'all':<16} {total:6.3f}")


if __name__ == "__main__":
    main()
