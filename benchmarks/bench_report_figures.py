"""CPU time of each figure of a mechanism's report.

Each mechanism is run first (``xcheck.run``, the results cache used). Then, as
a report draws them, each figure is drawn once in a fresh process, in the
report's order (the first to need matplotlib's fonts or its mathtext parser
pays for them; importing matplotlib is not counted), ``--repeats`` times: the
"cold" column is the least CPU time of a figure (``time.process_time``; the
machine may be shared). The "warm" column is the least CPU time of the same
drawing repeated in one process after a first one. Printed per figure, with the
sums, and the SHA-256 of each figure's bytes (the same on any machine: compare
with the committed report's files). With ``--breakdown``, one more fresh
process draws the figures once more and splits each one's CPU time by what
spends it (text, axes, legends, encoding, ...; each part without the parts
inside it), where what limits them shows.

Run: ``.venv/bin/python benchmarks/bench_report_figures.py [NAME ...] [--engines all] [--repeats 5] [--breakdown]``
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import xcheck
from xcheck.report import _IMAGES, _figures

#: a fresh process: the run from a pickle, then each figure once, in the report's order, as the
#: report draws it (its figure cache left out)
_COLD = """
import json, pickle, sys, time
with open(sys.argv[1], "rb") as file:
    run = pickle.load(file)
from xcheck.report import _IMAGES, _figure, _figures  # matplotlib imported before the clock starts
seconds = {}
for _, function, _ in _IMAGES:
    start = time.process_time()
    _figure(function, run)
    seconds[function] = time.process_time() - start
print(json.dumps(seconds))
"""


#: a fresh process: the run from a pickle, then each figure once, in the report's order, its CPU
#: time split among the matplotlib and Pillow calls that spend it (each without the others inside it)
_BREAKDOWN = """
import collections, json, pickle, sys, time
import matplotlib.axes, matplotlib.axis, matplotlib.collections, matplotlib.legend, matplotlib.lines
import matplotlib.patches, matplotlib.text, PIL.Image
with open(sys.argv[1], "rb") as file:
    run = pickle.load(file)
from xcheck import engines
from xcheck.report import _IMAGES, _figure, _figures
engines.engines()  # the registry loaded, as in the processes that ran the modes and draw a report
parts, inside = collections.defaultdict(float), []

def counted(part, owner, name):
    method = getattr(owner, name)
    def timed(*args, **kwargs):
        start = time.process_time()
        inside.append(0.0)
        try:
            return method(*args, **kwargs)
        finally:
            nested, spent = inside.pop(), time.process_time() - start
            parts[part] += spent - nested
            if inside:
                inside[-1] += spent
    setattr(owner, name, timed)

for part, owner, name in [
    ("text drawn (layout, glyphs)", matplotlib.text.Text, "draw"),
    ("text measured", matplotlib.text.Text, "get_window_extent"),
    ("axes made", matplotlib.axes.Axes, "__init__"),
    ("legends (but their text)", matplotlib.legend.Legend, "draw"),
    ("axes' axis drawn (but text)", matplotlib.axis.Axis, "draw"),
    ("lines drawn", matplotlib.lines.Line2D, "draw"),
    ("patches drawn", matplotlib.patches.Patch, "draw"),
    ("collections drawn", matplotlib.collections.Collection, "draw"),
    ("poses made (draw_pose)", _figures, "draw_pose"),
    ("PNG and GIF encoding", PIL.Image.Image, "save"),
    ("GIF quantisation", PIL.Image.Image, "quantize"),
]:
    counted(part, owner, name)
found = {}
for _, function, _ in _IMAGES:
    parts.clear()
    start = time.process_time()
    _figure(function, run)
    spent = time.process_time() - start
    found[function] = {**parts, "the rest (building, ticks, canvas)": spent - sum(parts.values()), "all": spent}
print(json.dumps(found))
"""


def breakdown(run) -> dict[str, dict[str, float]]:
    """Per figure function, its CPU time by part (:data:`_BREAKDOWN`), drawn in a fresh process."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.pickle"
        path.write_bytes(pickle.dumps(run))
        done = subprocess.run([sys.executable, "-c", _BREAKDOWN, str(path)], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def print_breakdown(name: str, found: dict[str, dict[str, float]]) -> None:
    """The parts of each figure's CPU time, largest first over all figures, as a table."""
    functions = list(found)
    parts = sorted(
        {part for split in found.values() for part in split if part != "all"},
        key=lambda part: -sum(split.get(part, 0.0) for split in found.values()),
    )
    print(f"\n{name}: CPU s by part, one fresh process")
    print(f"{'part':<36}" + "".join(f" {function[:11]:>11}" for function in functions) + f" {'all':>7}")
    for part in [*parts, "all"]:
        values = [found[function].get(part, 0.0) for function in functions]
        print(f"{part:<36}" + "".join(f" {value:11.3f}" for value in values) + f" {sum(values):7.3f}")


def cold_seconds(run, repeats: int) -> dict[str, float]:
    """Per figure function, its least CPU time over ``repeats`` fresh processes."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.pickle"
        path.write_bytes(pickle.dumps(run))
        found: dict[str, float] = {}
        for _ in range(repeats):
            done = subprocess.run([sys.executable, "-c", _COLD, str(path)], capture_output=True, text=True, check=True)
            for function, value in json.loads(done.stdout.splitlines()[-1]).items():
                found[function] = min(value, found.get(function, value))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=["fourbar"], help="mechanisms (default: fourbar)")
    parser.add_argument("--engines", default=None, help="as xcheck run's --engines (default: its default modes)")
    parser.add_argument("--repeats", type=int, default=5, help="drawings timed per figure (default 5)")
    parser.add_argument("--breakdown", action="store_true", help="also split each figure's CPU time by part")
    options = parser.parse_args()
    print(f"{'mechanism':<18} {'figure':<16} {'cold s':>6} {'warm s':>6}  sha256")
    for name in options.names:
        run = xcheck.run(name, engines=options.engines)
        cold = cold_seconds(run, options.repeats)
        cold_total = warm_total = 0.0
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
            cold_total += cold[function]
            warm_total += min(seconds)
            digest = hashlib.sha256(data).hexdigest()[:12]
            print(f"{name:<18} {file:<16} {cold[function]:6.3f} {min(seconds):6.3f}  {digest}")
        print(f"{name:<18} {'all':<16} {cold_total:6.3f} {warm_total:6.3f}")
        if options.breakdown:
            print_breakdown(name, breakdown(run))


if __name__ == "__main__":
    main()
