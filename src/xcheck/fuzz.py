"""Random mechanisms as a campaign: ``xcheck fuzz``.

:func:`generate` draws assemblable mechanisms of the supported kinds (four-bars,
slider-cranks, Scotch yokes) from a seed and writes each as a real mechanism
file, so that every failure has a reproducer. :func:`fuzz` runs every requested
mode on each (:func:`xcheck.runner.run_mechanism`, no report) on a local process
pool or a Dask distributed cluster and writes one row per case and mode to
Parquet, one part file per batch (temporary file and rename), so that a rerun
with the same output folder skips the cases already done. :func:`summary` and
:func:`failure_classes` read the rows back.

Case ``i`` of seed ``s`` is drawn from ``numpy.random.default_rng([s, i])``
alone: the same seed gives the same files whatever ``--count``, and the same
results but for the timings.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
import time
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError, XcheckError
from .fileio import write_atomic

__all__ = [
    "KINDS",
    "Case",
    "generate",
    "case_file",
    "run_case",
    "fuzz",
    "read_rows",
    "summary",
    "failure_classes",
    "failure_report",
    "COLUMNS",
]

#: the kinds of mechanism :func:`generate` draws
KINDS = ("fourbar", "slider-crank", "scotch-yoke")

#: the columns of a results row (Parquet)
COLUMNS = (
    "seed",
    "index",
    "case",
    "kind",
    "shape",
    "law",
    "masses",
    "scale",
    "parameters",
    "file",
    "mode",
    "engine",
    "outcome",
    "origin",
    "reason",
    "category",
    "relative",
    "tolerance",
    "ratio",
    "seconds",
)

_LENGTH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_RATE_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "rpm": 2.0 * math.pi / 60.0}


@dataclass(frozen=True)
class Case:
    """One generated mechanism.

    Attributes
    ----------
    seed, index : int
        The campaign's seed and the case's number in it.
    kind : str
        One of :data:`KINDS`.
    shape : str
        What the draw aimed at (``grashof``, ``non-grashof``, ``near-parallelogram``,
        ``near-change-point``, ``extreme-ratio``, ...).
    law : str
        The driver's motion law.
    masses : bool
        Whether every moving body has mass properties.
    scale : float
        The ground link's (or crank's) length, m.
    parameters : dict
        The lengths (m), angles (rad) and rates (SI) drawn.
    text : str
        The mechanism file.
    """

    seed: int
    index: int
    kind: str
    shape: str
    law: str
    masses: bool
    scale: float
    parameters: dict
    text: str

    @property
    def name(self) -> str:
        """The mechanism's name and file stem."""
        return f"fuzz-{self.kind}-s{self.seed}-{self.index:05d}"


# ----------------------------------------------------------------------------- drawing


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(10.0 ** rng.uniform(math.log10(low), math.log10(high)))


def _small(rng: np.random.Generator) -> float:
    """A signed relative perturbation from 1e-6 to 1e-2."""
    return float(rng.choice([-1.0, 1.0]) * _log_uniform(rng, 1e-6, 1e-2))


def _fourbar_lengths(rng: np.random.Generator, shape: str) -> tuple[float, float, float, float]:
    """(crank r, coupler d, rocker s, ground l) relative to l = 1."""
    while True:
        if shape == "near-parallelogram":
            r = float(rng.uniform(0.2, 0.8))
            return r, 1.0 + _small(rng), r * (1.0 + _small(rng)), 1.0
        if shape == "near-change-point":  # r + l = d + s (1 + eps): Grashof or just not
            r, d = float(rng.uniform(0.1, 0.6)), float(rng.uniform(0.6, 1.4))
            s = (r + 1.0 - d) * (1.0 + _small(rng))
            if s > r:
                return r, d, s, 1.0
            continue
        if shape == "extreme-ratio":
            r = _log_uniform(rng, 1e-3, 2e-2)
            return r, float(rng.uniform(0.8, 1.5)), float(rng.uniform(0.8, 1.5)), 1.0
        r, d, s = (float(v) for v in rng.uniform(0.1, 1.8, 3))
        lengths = sorted((r, d, s, 1.0))
        grashof = lengths[0] + lengths[3] < lengths[1] + lengths[2]
        if shape == "grashof" and grashof and r == lengths[0]:
            return r, d, s, 1.0  # crank-rocker
        if shape == "double-crank" and grashof and lengths[0] == 1.0:
            return r, d, s, 1.0
        if shape == "non-grashof" and not grashof and _fourbar_range(r, d, s, 1.0) is not None:
            return r, d, s, 1.0


def _fourbar_range(r: float, d: float, s: float, l: float) -> tuple[float, float] | None:
    """The crank angles (rad) where the loop closes: None if none, (0, 2 pi) for
    a full turn, else one interval (the upper one when there are two)."""
    c1 = (r * r + l * l - (d - s) ** 2) / (2.0 * r * l)  # cos(theta) <= c1
    c2 = (r * r + l * l - (d + s) ** 2) / (2.0 * r * l)  # cos(theta) >= c2
    if c2 >= c1 or c2 >= 1.0 or c1 <= -1.0:
        return None
    if c1 >= 1.0 and c2 <= -1.0:
        return 0.0, 2.0 * math.pi
    if c1 >= 1.0:
        return -math.acos(c2), math.acos(c2)
    if c2 <= -1.0:
        return math.acos(c1), 2.0 * math.pi - math.acos(c1)
    return math.acos(c1), math.acos(c2)


def _slider_range(r: float, rod: float, e: float) -> tuple[float, float]:
    """The crank angles (rad) where the rod reaches the slider's line y = e:
    (0, 2 pi) for a full turn, else the interval holding the rightmost reach."""
    low, high = (e - rod) / r, (e + rod) / r  # sin(theta) in [low, high]
    if low <= -1.0 and high >= 1.0:
        return 0.0, 2.0 * math.pi
    if high >= 1.0:
        return math.asin(low), math.pi - math.asin(low)
    if low <= -1.0:
        return -math.pi - math.asin(high), math.asin(high)
    return math.asin(low), math.asin(high)


def _law(rng: np.random.Generator, span: tuple[float, float]) -> tuple[str, dict, float]:
    """A motion law for a crank over ``span`` (rad): (kind, SI values, q at t = 0).
    A bounded span is started in its middle 40 %; a harmonic law stays in its middle 70 %."""
    low, high = span
    full = high - low >= 2.0 * math.pi
    kind = str(rng.choice(["constant-rate", "constant-acceleration", "harmonic"]))
    start = float(rng.uniform(low, high)) if full else float(low + (high - low) * rng.uniform(0.3, 0.7))
    sign = float(rng.choice([-1.0, 1.0]))
    if kind == "constant-rate":
        return kind, {"start": start, "rate": sign * _log_uniform(rng, 0.1, 100.0)}, start
    if kind == "constant-acceleration":
        rate = 0.0 if rng.uniform() < 0.3 else sign * _log_uniform(rng, 0.1, 30.0)
        accel = float(rng.choice([-1.0, 1.0])) * _log_uniform(rng, 0.1, 100.0)
        return kind, {"start": start, "rate": rate, "acceleration": accel}, start
    centre = float(rng.uniform(low, high)) if full else 0.5 * (low + high)
    amplitude = float(rng.uniform(0.2, 3.0)) if full else float((high - low) * rng.uniform(0.05, 0.35))
    phase = 0.0 if rng.uniform() < 0.5 else float(rng.uniform(-math.pi, math.pi))
    values = {"centre": centre, "amplitude": amplitude, "frequency": _log_uniform(rng, 0.1, 10.0), "phase": phase}
    return kind, values, centre + amplitude * math.sin(phase)


class _Writer:
    """Numbers in a file's units: lengths in ``length``, angles in ``angle``, rates in ``rate``."""

    def __init__(self, rng: np.random.Generator):
        self.length = str(rng.choice(list(_LENGTH_UNITS)))
        self.angle = str(rng.choice(["deg", "rad"]))
        self.rate = str(rng.choice(list(_RATE_UNITS)))

    def L(self, metres: float) -> str:
        return repr(metres / _LENGTH_UNITS[self.length])

    def point(self, x: float, y: float) -> str:
        return f"[{self.L(x)}, {self.L(y)}]"

    def A(self, radians: float) -> str:
        return repr(math.degrees(radians) if self.angle == "deg" else radians)

    def W(self, per_second: float) -> str:
        return repr(per_second / _RATE_UNITS[self.rate])

    def header(self, name: str, title: str, notes: str) -> list[str]:
        return [
            f"# Generated by xcheck fuzz: {notes}",
            "[mechanism]",
            f'name = "{name}"',
            f'title = "{title}"',
            'source = "xcheck fuzz"',
            "",
            "[units]",
            f'length = "{self.length}"',
            f'angle = "{self.angle}"',
            f'angular_rate = "{self.rate}"',
            "",
        ]

    def driver(self, joint: str, kind: str, values: dict) -> list[str]:
        lines = ["[[drivers]]", 'name = "crank"', f'joint = "{joint}"', f'motion = "{kind}"']
        for key, value in values.items():
            if key in ("start", "centre", "amplitude", "phase"):
                lines.append(f"{key} = {self.A(value)}")
            elif key in ("rate", "acceleration"):
                lines.append(f"{key} = {self.W(value)}")
            else:
                lines.append(f"{key} = {value!r}")
        return lines + [""]


def _bar(w: _Writer, body: str, ends: tuple[str, str], length: float, density: float | None) -> list[str]:
    lines = [f"[bodies.{body}]", f'ends = ["{ends[0]}", "{ends[1]}"]', f"length = {w.L(length)}"]
    if density is not None:
        mass = density * length
        lines += [f"mass = {mass!r}", f"inertia = {mass * length * length / 12.0!r}"]
    return lines + [""]


def _block(w: _Writer, body: str, label: str, size: float, density: float | None) -> list[str]:
    lines = [f"[bodies.{body}]", f"points = {{ {label} = [0, 0] }}"]
    if density is not None:
        mass = density * size
        lines += [f"mass = {mass!r}", f"inertia = {mass * size * size / 6.0!r}"]
    return lines + [""]


def _revolute(a: str, b: str, point: str) -> list[str]:
    return ["[[joints]]", 'type = "revolute"', f'bodies = ["{a}", "{b}"]', f'point = "{point}"', ""]


def _slide(name: str, kind: str, a: str, b: str, line: str, direction: str, point: str) -> list[str]:
    return [
        "[[joints]]",
        f'name = "{name}"',
        f'type = "{kind}"',
        f'bodies = ["{a}", "{b}"]',
        f'line = "{line}"',
        f"direction = {direction}",
        f'point = "{point}"',
        "",
    ]


def _dynamics(rng: np.random.Generator, masses: bool) -> tuple[list[str], bool]:
    gravity = masses and rng.uniform() < 0.5
    return (["[dynamics]", "gravity = [0, -9.81]", ""] if gravity else []), gravity


def _fourbar(rng: np.random.Generator, name: str, scale: float, masses: bool, w: _Writer) -> tuple[str, dict, str]:
    shape = str(
        rng.choice(
            ["grashof", "double-crank", "non-grashof", "near-parallelogram", "near-change-point", "extreme-ratio"]
        )
    )
    r, d, s, l = (v * scale for v in _fourbar_lengths(rng, shape))
    span = _fourbar_range(r, d, s, l)
    assert span is not None  # the draws are feasible
    law, values, q0 = _law(rng, span)
    bx, by = r * math.cos(q0), r * math.sin(q0)
    ex, ey = l - bx, -by  # B -> D
    e = math.hypot(ex, ey)
    along = (d * d - s * s + e * e) / (2.0 * e)
    across = math.sqrt(max(d * d - along * along, 0.0))
    cx, cy = bx + (along * ex - across * ey) / e, by + (along * ey + across * ex) / e  # C left of B -> D
    density = _log_uniform(rng, 0.5, 50.0) if masses else None
    dyn, gravity = _dynamics(rng, masses)
    lines = w.header(name, "Random four-bar", f"four-bar, {shape}, {law}")
    lines += ["[ground]", f"points = {{ A = [0, 0], D = {w.point(l, 0.0)} }}", ""]
    lines += _bar(w, "crank", ("A", "B"), r, density)
    lines += _bar(w, "coupler", ("B", "C"), d, density)
    lines += _bar(w, "rocker", ("D", "C"), s, density)
    lines += _revolute("ground", "crank", "A") + _revolute("crank", "coupler", "B")
    lines += _revolute("coupler", "rocker", "C") + _revolute("ground", "rocker", "D")
    lines += dyn + w.driver("A", law, values)
    lines += ["[assembly.branches.left]", f"C = {w.point(cx, cy)}", ""]
    parameters = {"crank": r, "coupler": d, "rocker": s, "ground": l, "gravity": gravity, "law": values}
    return shape, parameters, "\n".join(lines)


def _slider_crank(rng: np.random.Generator, name: str, scale: float, masses: bool, w: _Writer) -> tuple[str, dict, str]:
    shape = str(rng.choice(["full-turn", "rocking", "near-dead-centre", "extreme-ratio"]))
    r = scale
    e = r * float(rng.uniform(-0.8, 0.8)) if rng.uniform() < 0.7 else 0.0
    if shape == "full-turn":
        rod = (r + abs(e)) * float(rng.uniform(1.2, 5.0))
    elif shape == "rocking":
        rod = (r + abs(e)) * float(rng.uniform(0.4, 0.9))
        rod = max(rod, abs(e) - r * 0.5 + 1e-3 * r) if abs(e) > rod else rod
    elif shape == "near-dead-centre":
        rod = (r + abs(e)) * (1.0 + _small(rng))
    else:
        rod = (r + abs(e)) * _log_uniform(rng, 30.0, 1000.0)
    if abs(e) >= rod + 0.5 * r:  # the rod must reach the line with room to move
        e = math.copysign(rod * 0.5, e)
    span = _slider_range(r, rod, e)
    law, values, q0 = _law(rng, span)
    ax, ay = r * math.cos(q0), r * math.sin(q0)
    bx = ax + math.sqrt(max(rod * rod - (e - ay) ** 2, 0.0))
    density = _log_uniform(rng, 0.5, 50.0) if masses else None
    dyn, gravity = _dynamics(rng, masses)
    lines = w.header(name, "Random slider-crank", f"slider-crank, {shape}, {law}")
    lines += ["[ground]", f"points = {{ O = [0, 0], E = {w.point(0.0, e)} }}", ""]
    lines += _bar(w, "crank", ("O", "A"), r, density)
    lines += _bar(w, "rod", ("A", "B"), rod, density)
    lines += _block(w, "slider", "B", 0.2 * r, density)
    lines += _revolute("ground", "crank", "O") + _revolute("crank", "rod", "A") + _revolute("rod", "slider", "B")
    lines += _slide("slide", "prismatic", "ground", "slider", "E", w.A(0.0), "B")
    lines += dyn + w.driver("O", law, values)
    lines += ["[assembly.branches.right]", f"B = {w.point(bx, e)}", ""]
    parameters = {"crank": r, "rod": rod, "offset": e, "gravity": gravity, "law": values}
    return shape, parameters, "\n".join(lines)


def _scotch_yoke(rng: np.random.Generator, name: str, scale: float, masses: bool, w: _Writer) -> tuple[str, dict, str]:
    shape = "full-turn"
    r = scale
    law, values, q0 = _law(rng, (0.0, 2.0 * math.pi))
    density = _log_uniform(rng, 0.5, 50.0) if masses else None
    dyn, gravity = _dynamics(rng, masses)
    lines = w.header(name, "Random Scotch yoke", f"Scotch yoke, {law}")
    lines += ["[ground]", "points = { O = [0, 0] }", ""]
    lines += _bar(w, "crank", ("O", "P"), r, density)
    lines += _block(w, "yoke", "Y", r, density)
    lines += _revolute("ground", "crank", "O")
    lines += _slide("guide", "prismatic", "ground", "yoke", "O", w.A(0.0), "Y")
    lines += _slide("slot", "pin-in-slot", "yoke", "crank", "Y", w.A(0.5 * math.pi), "P")
    lines += dyn + w.driver("O", law, values)
    px, py = r * math.cos(q0), r * math.sin(q0)
    lines += ["[assembly.branches.default]", f"P = {w.point(px, py)}", f"Y = {w.point(px, 0.0)}", ""]
    return shape, {"crank": r, "gravity": gravity, "law": values}, "\n".join(lines)


_DRAW: dict[str, Callable] = {"fourbar": _fourbar, "slider-crank": _slider_crank, "scotch-yoke": _scotch_yoke}


def generate(seed: int, index: int, kinds: Sequence[str] = KINDS) -> Case:
    """Case ``index`` of the campaign ``seed``: a random assemblable mechanism
    of one of ``kinds``, at a scale from 1 cm to 1 km, with or without masses.

    Raises
    ------
    InputError
        If a kind is unknown.
    """
    unknown = [k for k in kinds if k not in _DRAW]
    if unknown or not kinds:
        raise InputError(f"--kinds: expected kinds among {', '.join(KINDS)}, found {','.join(kinds) or 'none'!r}")
    rng = np.random.default_rng([seed, index])
    kind = str(rng.choice(list(kinds)))
    scale = _log_uniform(rng, 0.01, 1000.0)
    masses = bool(rng.uniform() < 0.5)
    writer = _Writer(rng)
    name = f"fuzz-{kind}-s{seed}-{index:05d}"
    shape, parameters, text = _DRAW[kind](rng, name, scale, masses, writer)
    law = text.split('motion = "', 1)[1].split('"', 1)[0]
    return Case(seed, index, kind, shape, law, masses, scale, parameters, text)


def case_file(case: Case, out: str | Path) -> Path:
    """Write ``case``'s mechanism file under ``out``/cases/ (atomically); its path."""
    path = Path(out) / "cases" / f"{case.name}.toml"
    if not path.is_file() or path.read_text(encoding="utf-8") != case.text:
        write_atomic(path, case.text)
    return path


# ----------------------------------------------------------------------------- running


def _reason_text(text: str, limit: int = 300) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def run_case(case: Case, path: str, modes: Sequence[str], samples: int) -> list[dict]:
    """Run ``modes`` on the case (its text, named by ``path``, the file written
    on the client); one row per mode (and per force source
    when the bodies have masses). Never raises: a refusal or crash of the whole
    case gives one row per mode with outcome ``refused`` or ``crashed``.

    Outcomes: ``passed``, ``failed`` (ran, outside its tolerance), ``error``
    (the mode could not produce a result; ``reason`` is the engine's or the
    exception's), ``not-applicable`` (the engine says why), ``refused`` (xcheck
    refused the generated file), ``crashed`` (an unexpected exception).
    """
    from .kinematics import Kinematics
    from .model import parse_mechanism
    from .runner import run_mechanism

    base = {
        "seed": case.seed,
        "index": case.index,
        "case": case.name,
        "kind": case.kind,
        "shape": case.shape,
        "law": case.law,
        "masses": case.masses,
        "scale": case.scale,
        "parameters": json.dumps(case.parameters, sort_keys=True),
        "file": str(path),
    }

    def row(mode: str, outcome: str, origin: str = "", reason: str = "", **figures) -> dict:
        engine = "xcheck" if mode in ("native", "newton-euler", "energy") else mode.split("-")[0]
        if mode.startswith("formulation"):
            engine = "xcheck"
        return {
            **base,
            "mode": mode,
            "engine": engine,
            "outcome": outcome,
            "origin": origin,
            "reason": _reason_text(reason),
            "category": figures.get("category", ""),
            "relative": float(figures.get("relative", math.nan)),
            "tolerance": float(figures.get("tolerance", math.nan)),
            "ratio": float(figures.get("ratio", math.nan)),
            "seconds": float(figures.get("seconds", 0.0)),
        }

    start = time.perf_counter()
    try:
        kinematics = Kinematics(parse_mechanism(case.text, str(path)))  # the text: a remote worker may not see the file
        kinematics.assemble()
        run = run_mechanism(kinematics, modes, samples)
    except XcheckError as err:
        return [row(m, "refused", "xcheck", str(err), seconds=time.perf_counter() - start) for m in modes]
    except Exception as err:  # noqa: BLE001 - a crash is data
        reason = f"{type(err).__name__}: {err}"
        return [row(m, "crashed", "xcheck", reason, seconds=time.perf_counter() - start) for m in modes]
    rows = []
    for mode in modes:
        if mode in run.not_applicable:
            rows.append(row(mode, "not-applicable", "engine", run.not_applicable[mode]))
            continue
        outcome = run.outcomes[mode]
        worst = _worst(outcome.categories)
        if not outcome.ok:
            origin = "engine" if outcome.result is not None else "exception"
            rows.append(row(mode, "error", origin, outcome.reason, seconds=outcome.seconds, **worst))
        elif outcome.passed:
            rows.append(row(mode, "passed", "", outcome.reason, seconds=outcome.seconds, **worst))
        else:
            failing = outcome.categories[~outcome.categories.passed.astype(bool)]
            categories = ", ".join(failing.category) if not failing.empty else "no categories"
            text = outcome.reason or f"outside the tolerance in {categories}"
            finding = outcome.finding
            explanation = (
                f"the engine's stated finding: {finding}" if finding else _engine_explanation(outcome, failing, mode)
            )
            origin, text = ("engine", explanation) if explanation else ("disagreement", text)
            rows.append(row(mode, "failed", origin, text, seconds=outcome.seconds, **worst))
    if not run.force_table.empty:
        for _, forces in run.force_table.iterrows():
            source = str(forces.engine)
            ok = bool(forces.ok)
            relative, bound = float(forces.max_rel), float(forces.tolerance)
            figures = {
                "category": "forces",
                "relative": relative,
                "tolerance": bound,
                "ratio": relative / bound if bound > 0 else math.nan,
            }
            label = source if source == "newton-euler" else f"{source}-forces"
            if not ok:
                rows.append(row(label, "error", "engine", str(forces.reason), **figures))
            else:
                passed = bool(forces.passed)
                origin = "" if passed else _force_origin(forces)
                text = "" if passed else str(forces.get("basis", "") or "")
                rows.append(row(label, "passed" if passed else "failed", origin, text, **figures))
    if run.energy is not None:
        energy = run.energy
        relative, bound = float(energy["relative"]), float(energy["tolerance"])
        figures = {"category": "power", "relative": relative, "tolerance": bound, "ratio": relative / bound}
        passed = bool(energy["passed"])
        rows.append(row("energy", "passed" if passed else "failed", "" if passed else "disagreement", "", **figures))
    return rows


def _unobserved_order(outcome, failing: pd.DataFrame) -> str:
    """For a dynamic mode failed only because no coarser run of its series ran
    through (so no order can be observed), that reason with the first coarser
    run's own status; "" otherwise."""
    if failing.empty or "basis" not in failing or not failing.basis.str.startswith("no coarser run").all():
        return ""
    study = outcome.result.study if outcome.result is not None else None
    broken = ""
    if study is not None and not study.empty:
        statuses = [str(s) for s in study.status if str(s) != "ok"]
        broken = f" ({statuses[0]})" if statuses else ""
    return f"no coarser run of the compared series ran through{broken}: the order cannot be observed"


def _engine_explanation(outcome, failing: pd.DataFrame, mode: str) -> str:
    """Why a dynamic mode's failing categories are its engine's stated result, or ""
    if one of them is not: each either has no order to observe because the engine's
    own coarser runs broke down (:func:`_unobserved_order`), or is a measured
    limitation (:func:`_engine_limitation`). Both kinds can meet in one mode (fuzz
    case s3-00052: MuJoCo's coarser runs left the branch, so its positions and rates
    have no verdict, while its qacc is beyond the fixed bound)."""
    if failing.empty or "basis" not in failing:
        return ""
    unobserved = failing.basis.str.startswith("no coarser run")
    if unobserved.all():
        return _unobserved_order(outcome, failing)
    limitation = _engine_limitation(failing[~unobserved], mode)
    if not limitation or not unobserved.any():
        return limitation
    return f"{', '.join(failing.category[unobserved])}: {_unobserved_order(outcome, failing[unobserved])}; {limitation}"


def _engine_limitation(failing: pd.DataFrame, mode: str) -> str:
    """Why a dynamic mode's failure is its engine's measured limitation, or "" if it
    is not: every failing category either beyond the fixed bound of a quantity the
    mode states does not converge (such as MuJoCo's qacc, which carries its
    constraint stabilisation), or short of its stated order after the runner's
    :data:`~xcheck.runner.REFINEMENTS` finer runs, or where a finer run failed."""
    from .runner import REFINEMENTS

    if failing.empty or "basis" not in failing:
        return ""
    fixed = failing.basis.str.startswith("fixed bound")
    by_order = failing.basis.str.startswith("observed order")
    broke = ""
    if "refinement_failure" in failing and by_order.any():
        broke = str(failing.refinement_failure[by_order].iloc[0])
    refined = "refinements" in failing and bool((failing.refinements[by_order] == REFINEMENTS).all())
    if not (fixed | by_order).all() or (by_order.any() and not (broke or refined)):
        return ""
    parts = []
    if fixed.any():
        parts.append(
            f"{', '.join(failing.category[fixed])}: beyond the fixed bound of a quantity the mode states does not "
            "converge with the step (its tolerance's reason, `xcheck engines`)"
        )
    if by_order.any():
        parts.append(
            f"{', '.join(failing.category[by_order])}: the error falls short of the mode's stated order"
            + (
                f", and a finer run failed ({broke})"
                if broke
                else f" even with its finest step halved {REFINEMENTS} times"
            )
            + f" (observed orders: `xcheck run FILE --engines {mode}`, basis)"
        )
    return "; ".join(parts)


def _force_origin(forces: pd.Series) -> str:
    """A failed force source's origin: its engine's where the runner halved its
    step (:func:`xcheck.runner._refine_forces`) :data:`~xcheck.runner.REFINEMENTS`
    times and the error still fell short of its order, or a finer run failed;
    else a disagreement."""
    from .runner import REFINEMENTS

    failure = forces.get("refinement_failure")
    if isinstance(failure, str) and failure:
        return "engine"
    refinements = forces.get("refinements")
    return "engine" if refinements is not None and refinements == REFINEMENTS else "disagreement"


def _worst(categories: pd.DataFrame) -> dict:
    """The category with the largest error relative to its tolerance."""
    if categories.empty:
        return {}
    tolerance = categories.tolerance.astype(float).to_numpy()
    relative = categories.relative.astype(float).to_numpy()
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(tolerance > 0, relative / tolerance, np.inf)
    ratio = np.where(np.isnan(ratio), np.inf, ratio)
    i = int(np.argmax(ratio))
    return {
        "category": str(categories.category.iloc[i]),
        "relative": float(relative[i]),
        "tolerance": float(tolerance[i]),
        "ratio": float(ratio[i]),
    }


def _run_batch(cases: list[Case], paths: list[str], modes: Sequence[str], samples: int) -> list[dict]:
    """:func:`run_case` on several cases (one task of the pool or cluster)."""
    rows: list[dict] = []
    for case, path in zip(cases, paths):
        rows.extend(run_case(case, path, modes, samples))
    return rows


def _write_part(out: Path, rows: list[dict]) -> Path:
    """One Parquet part file of ``rows``, through a temporary file and a rename."""
    import pyarrow as pa  # type: ignore[import-untyped]
    import pyarrow.parquet as pq  # type: ignore[import-untyped]

    folder = out / "results"
    folder.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(pd.DataFrame(rows, columns=list(COLUMNS)), preserve_index=False)
    first = min(r["index"] for r in rows)
    path = folder / f"part-{first:06d}-{uuid.uuid4().hex[:8]}.parquet"
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    os.close(fd)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_rows(out: str | Path) -> pd.DataFrame:
    """Every row written under ``out``/results/, sorted by case and mode order."""
    import pyarrow.parquet as pq

    folder = Path(out) / "results"
    parts = sorted(folder.glob("part-*.parquet")) if folder.is_dir() else []
    if not parts:
        return pd.DataFrame(columns=list(COLUMNS))
    frame = pd.concat([pq.read_table(p).to_pandas() for p in parts], ignore_index=True)
    frame["_order"] = frame.groupby("case").cumcount()
    frame = frame.sort_values(["seed", "index", "_order"]).drop(columns="_order").reset_index(drop=True)
    return frame


def campaign_modes() -> tuple[str, ...]:
    """The modes a campaign runs when none are named: :func:`xcheck.runner.default_modes`
    but those whose cost on each random mechanism would dominate it
    (:attr:`xcheck.engines.Mode.campaigns`); named, they run."""
    from . import engines
    from .runner import default_modes

    return tuple(m for m in default_modes() if m == "native" or engines.mode(m).campaigns)


def fuzz(
    out: str | Path,
    count: int = 100,
    seed: int = 0,
    kinds: Sequence[str] = KINDS,
    modes: Sequence[str] | None = None,
    samples: int = 181,
    workers: int | None = None,
    scheduler: str | None = None,
    client=None,
    batch: int = 4,
    progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """Generate ``count`` cases of ``seed``, run ``modes`` on each and write the rows.

    Cases already in ``out``/results/ are skipped (resume). The work runs on a
    local process pool of ``workers`` processes (default: the CPU count; 1, or
    a mode of an engine registered at run time: in this process), on the Dask
    cluster at ``scheduler``, or on a given ``dask.distributed.Client``.

    Parameters
    ----------
    modes : sequence of str, optional
        Modes or groups (:func:`xcheck.select_modes`); None: :func:`campaign_modes`.
    batch : int
        Cases per task and per Parquet part; on a local pool of several
        processes fewer where needed to give each process four tasks or more,
        so that the last batches do not leave a process idle for long (20 cases
        in batches of 4 on 2 processes ran 12 cases on one and 8 on the other).
    progress : callable, optional
        Called with (cases done, cases to do) after each batch.

    Returns
    -------
    DataFrame
        Every row under ``out`` (this run's and earlier ones'), :data:`COLUMNS`.
    """
    from .api import select_modes

    out = Path(out)
    chosen = campaign_modes() if modes is None else select_modes(modes)
    done = set(read_rows(out).case)
    cases = [generate(seed, i, kinds) for i in range(count)]
    todo = [c for c in cases if c.name not in done]
    paths = [str(case_file(c, out)) for c in cases]
    by_name = dict(zip((c.name for c in cases), paths))
    processes = workers or os.cpu_count() or 1
    local_pool = client is None and scheduler is None and processes > 1 and not _registered_here(chosen)
    if local_pool:
        batch = max(1, min(batch, len(todo) // (4 * processes)))
    batches = [todo[i : i + batch] for i in range(0, len(todo), batch)]
    finished = 0

    def record(rows: list[dict], size: int) -> None:
        nonlocal finished
        if rows:
            _write_part(out, rows)
        finished += size
        if progress is not None:
            progress(finished, len(todo))

    arguments = [(b, [by_name[c.name] for c in b], chosen, samples) for b in batches]
    if client is not None or scheduler is not None:
        _run_dask(arguments, record, client, scheduler)
    elif not local_pool or len(batches) <= 1:
        for args in arguments:
            record(_run_batch(*args), len(args[0]))
    else:
        from ._parallel import process_pool  # spawned afresh: a fork would inherit JAX's threads

        with process_pool(processes) as pool:
            pending = {pool.submit(_run_batch, *args): len(args[0]) for args in arguments}
            while pending:
                complete, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in complete:
                    record(future.result(), pending.pop(future))
    return read_rows(out)


def _registered_here(modes) -> bool:
    """Whether a mode is one a spawned worker does not know
    (:func:`xcheck._parallel.known_to_workers`): the campaign then runs in this process."""
    from ._parallel import known_to_workers

    return any(m != "native" and not known_to_workers(m) for m in modes)


def _run_dask(arguments: list[tuple], record: Callable[[list[dict], int], None], client, scheduler: str | None) -> None:
    """The batches on a Dask distributed cluster (``client``, or one connected to ``scheduler``)."""
    from dask.distributed import Client, as_completed

    own = client is None
    if own:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError(
                f"--scheduler {scheduler}: expected the address of a running Dask scheduler, found {err}"
            ) from None
    try:
        sizes = {client.submit(_run_batch, *args, pure=False): len(args[0]) for args in arguments}
        for future in as_completed(list(sizes)):
            record(future.result(), sizes[future])
    finally:
        if own:
            client.close()


# ----------------------------------------------------------------------------- reading


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Per mode: cases, passed, failed (outside tolerance), errors (no result,
    refused, crashed), not applicable; modes in the rows' order."""
    order = list(dict.fromkeys(rows["mode"]))
    table = []
    for mode in order:
        part = rows[rows["mode"] == mode]
        counts = part.outcome.value_counts()
        table.append(
            {
                "mode": mode,
                "cases": int(part.case.nunique()),
                "passed": int(counts.get("passed", 0)),
                "failed": int(counts.get("failed", 0)),
                "error": int(counts.get("error", 0) + counts.get("refused", 0) + counts.get("crashed", 0)),
                "not applicable": int(counts.get("not-applicable", 0)),
            }
        )
    return pd.DataFrame(table, columns=["mode", "cases", "passed", "failed", "error", "not applicable"])


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def reason_class(row) -> str:
    """A failure's class: its reason with the numbers, paths and names blanked
    (``#``); a tolerance failure by its worst category."""
    if row["outcome"] == "failed" and row["origin"] == "disagreement":
        return f"outside tolerance: {row['category'] or 'unknown'}"
    text = str(row["reason"]).replace(str(row["file"]), "FILE").replace(str(row["case"]), "NAME")
    return _NUMBER.sub("#", text)[:160]


def failure_classes(rows: pd.DataFrame) -> pd.DataFrame:
    """Failures grouped by (mode, origin, reason class): count, shapes, and the
    reproducer (the shortest mechanism file of the class)."""
    bad = rows[rows.outcome.isin(["failed", "error", "refused", "crashed"])].copy()
    columns = ["mode", "origin", "outcome", "class", "count", "shapes", "reproducer", "example"]
    if bad.empty:
        return pd.DataFrame(columns=columns)
    bad["class"] = bad.apply(reason_class, axis=1)
    bad["size"] = [Path(f).stat().st_size if Path(f).is_file() else 0 for f in bad.file]
    table = []
    for (mode, origin, outcome, klass), part in bad.groupby(["mode", "origin", "outcome", "class"], sort=False):
        smallest = part.sort_values(["masses", "size", "index"]).iloc[0]
        shapes = ", ".join(f"{k}/{s}" for k, s in sorted(set(zip(part.kind, part["shape"]))))
        table.append(
            {
                "mode": mode,
                "origin": origin,
                "outcome": outcome,
                "class": klass,
                "count": len(part),
                "shapes": shapes,
                "reproducer": str(smallest.file),
                "example": str(smallest.reason)
                or f"{smallest.category}: {smallest.relative:.3g} > {smallest.tolerance:.3g}",
            }
        )
    return pd.DataFrame(table, columns=columns).sort_values(["mode", "count"], ascending=[True, False])


_ORIGINS = {
    "engine": "the engine's own limitation, as it states it",
    "exception": "an exception inside the mode (xcheck's adapter or the engine: to investigate)",
    "disagreement": "ran, but outside its tolerance (to investigate)",
    "xcheck": "xcheck refused or crashed on a generated file (xcheck's own fault or the generator's)",
}


def failure_report(rows: pd.DataFrame, command: str) -> str:
    """The Markdown failure-class report of a campaign."""
    classes = failure_classes(rows)
    lines = [
        "# xcheck fuzz: failure classes",
        "",
        f"Command: `{command}`",
        "",
        f"{rows.case.nunique()} cases, {len(rows)} rows (one per case and mode).",
        "",
        "## Per mode",
        "",
        "| mode | cases | passed | failed | error | not applicable |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for _, r in summary(rows).iterrows():
        lines.append(f"| {r['mode']} | {r.cases} | {r.passed} | {r.failed} | {r.error} | {r['not applicable']} |")
    lines += ["", "## Failure classes", ""]
    if classes.empty:
        lines.append("No failures.")
    else:
        lines += ["Origins: " + "; ".join(f"**{k}**: {v}" for k, v in _ORIGINS.items()) + ".", ""]
        lines += [
            "| mode | origin | class | count | kinds/shapes | reproducer | example |",
            "|---|---|---|---:|---|---|---|",
        ]
        for _, c in classes.iterrows():
            cells = [c["mode"], c.origin, c["class"], str(c["count"]), c.shapes, f"`{c.reproducer}`", c.example]
            lines.append("| " + " | ".join(str(x).replace("|", "\\|") for x in cells) + " |")
    return "\n".join(lines) + "\n"
