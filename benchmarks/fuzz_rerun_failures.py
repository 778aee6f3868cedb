"""Run again, with the code as it is now, the cases of an earlier ``xcheck fuzz``
campaign that had a failed, error, refused or crashed row, into a new folder.

A fix to a failure class is checked on the campaign's own reproducers without
running the whole campaign again: the same seed and index give the same mechanism
file (:func:`xcheck.fuzz.generate`), every mode runs on it, and the new rows go to
``NEW/results`` (Parquet, as ``xcheck fuzz`` writes them), with ``NEW/failures.md``.

Usage: python benchmarks/fuzz_rerun_failures.py OLD NEW [--workers N] [--disagreements]
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from xcheck.api import select_modes
from xcheck.fuzz import _run_batch, _write_part, case_file, failure_report, generate, read_rows, summary

BAD = ("failed", "error", "refused", "crashed")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--disagreements", action="store_true", help="only cases with a disagreement row")
    args = parser.parse_args()
    rows = read_rows(args.old)
    chosen = rows.outcome.isin(BAD) & ((rows.origin == "disagreement") | (not args.disagreements))
    bad = rows[chosen][["seed", "index", "kind"]].drop_duplicates()
    if bad.empty:
        print(f"{args.old}: no failed case")
        return 0
    done = set(read_rows(args.new).case) if args.new.exists() else set()
    cases = [generate(int(s), int(i)) for s, i, _ in bad.itertuples(index=False)]
    for case in cases:  # the campaign's default kinds: the same draw gives the same file
        old_file = args.old / "cases" / f"{case.name}.toml"
        if old_file.read_text(encoding="utf-8") != case.text:
            print(f"{old_file}: expected the file generate() draws again, found another (other --kinds?)")
            return 2
    cases = [c for c in cases if c.name not in done]
    modes = select_modes(None)
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(_run_batch, [c], [str(case_file(c, args.new))], modes, 181) for c in cases]
        for n, future in enumerate(futures, 1):
            _write_part(args.new, future.result())
            print(f"{n}/{len(cases)}", file=sys.stderr)
    new = read_rows(args.new)
    (args.new / "failures.md").write_text(failure_report(new, " ".join(sys.argv)), encoding="utf-8")
    print(summary(new).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
