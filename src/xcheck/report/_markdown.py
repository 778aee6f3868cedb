"""The Markdown report of a comparison run and the index of all reports."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import engines
from ..api import limit_warnings
from ..kinematics import Status
from ..output import range_text
from ..runner import CATEGORIES, RunResult, convergence_table, tolerance, versions

__all__ = ["report_markdown", "index_markdown", "verdict_counts", "worst_text", "textbook_text"]

_CATEGORY_UNIT = {
    "position": "of size",
    "angle": "rad",
    "velocity": "rel.",
    "omega": "rel.",
    "acceleration": "rel.",
    "alpha": "rel.",
}


def _g(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if value == 0:
        return "0"
    return f"{value:.{digits}g}"


def _table(headers: list[str], rows: list[list[str]], align: str | None = None) -> str:
    align = align or "l" * len(headers)
    marks = {"l": "---", "r": "---:", "c": ":---:"}
    lines = ["| " + " | ".join(headers) + " |", "| " + " | ".join(marks[a] for a in align) + " |"]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|").replace("\n", " ") for c in row) + " |" for row in rows]
    return "\n".join(lines)


def verdict_counts(textbook: list[dict]) -> dict[str, int]:
    return {v: sum(r["verdict"] == v for r in textbook) for v in ("agrees", "rounding", "disagrees")}


def _comparison_section(run: RunResult) -> str:
    headers = ["mode", "result"] + [f"{c} ({_CATEGORY_UNIT[c]})" for c in CATEGORIES] + ["worst at"]
    rows = []
    for mode, outcome in run.outcomes.items():
        if not outcome.ok:
            rows.append([f"`{mode}`", f"**failed**: {outcome.reason}"] + ["—"] * len(CATEGORIES) + [""])
            continue
        cells = []
        table = outcome.categories.set_index("category") if not outcome.categories.empty else None
        for c in CATEGORIES:
            if table is None or c not in table.index:
                cells.append("—")
                continue
            row = table.loc[c]
            mark = "" if row.passed else " ✗"
            cells.append(f"{_g(row.relative, 2)} / {_g(row.tolerance, 2)}{mark}")
        worst = ""
        if table is not None:
            ratios = table.relative / table.tolerance
            c = str(ratios.idxmax())
            x = float(table.at[c, "worst_input"])  # type: ignore[arg-type]  # pandas-stubs: a cell is any scalar
            worst = f"{c}: {table.at[c, 'worst']!s} at {run.mechanism.drivers[0].name} = {_input_text(run, x)}"
        result = {"pass": "pass", "finding": "finding", "fail": "**FAIL**"}[outcome.verdict]
        if outcome.reason:
            result += f" ({outcome.reason})"
        rows.append([f"`{mode}`", result] + cells + [worst])
    text = _table(headers, rows, "ll" + "r" * len(CATEGORIES) + "l")
    for mode, finding in run.findings.items():
        text += f"\n\n`{mode}` fails (✗) only where its engine is known to be wrong: {finding}."
    text += (
        "\n\nEach cell: the largest difference from the native solution / the tolerance. Positions are "
        "relative to the mechanism's size, angles in rad, rates relative to the largest magnitude of that "
        "quantity over all bodies and points, but at least its scale floor (below). `native` is checked "
        "against its own equations (loop closure, velocity and acceleration equations). A dynamic mode's "
        "tolerance is the largest error its own convergence at the expected order allows (the verdict's "
        "basis is under the dynamic modes). ✗ marks a difference beyond its tolerance."
    )
    if run.not_applicable:
        text += "\n\nNot applicable here: " + "; ".join(f"`{m}`: {r}" for m, r in run.not_applicable.items()) + "."
    text += "\n\nTolerances and their basis:\n\n" + _table(
        ["mode", "position", "angle", "velocity", "acceleration", "basis"],
        [
            [f"`{m}`", _g(t.position, 2), _g(t.angle, 2), _g(t.velocity, 2), _g(t.acceleration, 2), t.basis]
            for m, t in ((m, tolerance(m)) for m in run.outcomes)
        ],
    )
    f = run.floors
    if f:
        text += (
            f"\n\nScale floors (rates relative to at least these, from the mechanism's size L = "
            f"{_g(f['size'])} m and its inputs' characteristic rate w = {_g(f['rate'])} rad/s and "
            f"angular acceleration a = max(w², inputs') = {_g(f['angular_acceleration'])} rad/s²): omega "
            f"{_g(f['omega'])} rad/s, alpha {_g(f['alpha'])} rad/s², velocity w·L = {_g(f['velocity'])} m/s, "
            f"acceleration a·L = {_g(f['acceleration'])} m/s²."
        )
    return text


def _input_text(run: RunResult, value: float) -> str:
    driver, units = run.mechanism.drivers[0], run.mechanism.units
    if driver.quantity == "angle":
        return f"{value / units.angle_factor:.4g} {units.angle}"
    return f"{value / units.length_factor:.4g} {units.length}"


def _textbook_section(run: RunResult) -> str:
    if not run.textbook:
        stem = Path(run.mechanism.path).stem
        return (
            "No printed answers were given for this mechanism. To check a worked solution against it, "
            f"write the printed values in `comparisons/{stem}.toml` beside the `models/` folder that holds "
            f"`{stem}.toml` (or beside the file itself), in the format of xcheck's `comparisons/README.md`; "
            "`--comparisons DIR` names another folder."
        )
    counts = verdict_counts(run.textbook)
    rows = []
    for r in run.textbook:
        rows.append(
            [
                r.get("symbol", ""),
                r.get("quantity", ""),
                r.get("instant", ""),
                r.get("printed_text", _g(r["printed"], 6)),
                _g(r["computed"], 6),
                r.get("unit", ""),
                _g(r.get("deviation_percent"), 2),
                _g(r.get("deviation_digits"), 2),
                f"**{r['verdict']}**" if r["verdict"] == "disagrees" else r["verdict"],
                r.get("note", ""),
            ]
        )
    head = (
        f"{len(run.textbook)} printed values: {counts['agrees']} agree (within half a unit of the last printed "
        f"digit), {counts['rounding']} within rounding (1 %), {counts['disagrees']} disagree.\n\n"
    )
    return head + _table(
        [
            "symbol",
            "quantity",
            "instant",
            "printed",
            "computed",
            "unit",
            "deviation %",
            "last digits",
            "verdict",
            "note",
        ],
        rows,
        "lllrrlrrll",
    )


def _dynamic_section(run: RunResult, images: dict[str, str]) -> str:
    parts = []
    for mode, outcome in run.outcomes.items():
        if mode == "native" or engines.mode(mode).kind != "dynamic" or outcome.result is None:
            continue
        table = convergence_table(outcome)
        trajectory = outcome.trajectory
        parts.append(f"**`{mode}`** — compared: {trajectory.notes if trajectory is not None else outcome.reason}")
        if not table.empty:
            parts.append(
                _table(
                    ["series", "time step [s]", "position error [m]", "observed order", "status"],
                    [
                        [str(r.series), _g(r.timestep, 3), _g(r.position_error, 3), _g(r.order, 3), str(r.status)]
                        for r in table.itertuples()
                    ],
                    "lrrrl",
                )
            )
        if "basis" in outcome.categories:
            parts.append(
                "Verdict (the compared run against the next coarser one of the same settings):\n\n"
                + _table(
                    ["category", "difference", "limit", "result", "basis"],
                    [
                        [
                            str(r.category),
                            _g(r.relative, 3),
                            _g(r.tolerance, 3),
                            "pass" if r.passed else "**FAIL**",
                            str(r.basis),
                        ]
                        for r in outcome.categories.itertuples()
                    ],
                    "lrrll",
                )
            )
    if "convergence" in images:
        parts.insert(0, f"![error against time step]({images['convergence']})")
    return "\n\n".join(parts) if parts else "No dynamic mode ran."


def _solver_section(run: RunResult) -> str:
    native, kin = run.native, run.kinematics
    counts = {Status(code).label: int(n) for code, n in zip(*np.unique(native.status, return_counts=True))}
    good = native.status <= 1
    dof = kin.mobility()
    rng = [kin.input_range(k, run.branch) for k in range(len(run.mechanism.drivers))]
    lines = [
        f"- Degrees of freedom: {dof['rank']} (Grübler count {dof['grubler']}, rank of the constraint "
        f"Jacobian {dof['rank']}); drivers: {', '.join(d.name for d in run.mechanism.drivers)}.",
        f"- Feasible input range: {'; '.join(range_text(kin, r) for r in rng)}; the sweep covers "
        f"{_input_text(run, native.inputs[0, 0])} … {_input_text(run, native.inputs[-1, 0])} in "
        f"{len(native.status)} samples.",
        f"- Assembly branch: `{run.branch}` (of {', '.join(f'`{b}`' for b in kin.branches)}).",
        f"- Sample status: {', '.join(f'{n} {s}' for s, n in counts.items())}.",
    ]
    if good.any():
        lines.append(
            f"- Largest loop-closure residual: {_g(float(native.residual[good].max()), 2)} m; smallest "
            f"inverse condition number of the Jacobian: {_g(float(native.singularity[good].min()), 2)} "
            f"(0 would be a singular configuration: dead centre or limit position)."
        )
    return "\n".join(lines)


def _forces_section(run: RunResult, images: dict[str, str]) -> str:
    if run.no_forces:
        return f"Not computed: {run.no_forces}."
    if run.force_table.empty:
        return "Not computed in this run."
    rows = []
    for r in run.force_table.itertuples():
        if not r.ok:
            rows.append([f"`{r.engine}`", f"**failed**: {r.reason}", "—", "—", "—", "—"])
            continue
        rows.append(
            [
                f"`{r.engine}`",
                "pass" if r.passed else "**FAIL**",
                _g(r.max_rel, 2),
                f"{_g(r.tolerance, 2)} (scale ≥ {_g(r.floor, 3)} {r.unit})",
                f"{r.name} {r.quantity}: {_g(r.max_abs, 3)} {r.unit}",
                str(r.states),
            ]
        )
    e = run.energy
    text = (
        "Reactions (force of a joint's first body on its second, global frame), slider normal forces and "
        "couples, and driver efforts (in the sense that increases the input) over the simulation window, "
        "each source against the native multipliers of M q'' - Phi_q^T lambda = Q at the source's own "
        "states. `newton-euler` is the seed's per-body form M a = D R + Q; pymunk gives magnitudes only "
        "(impulses over a step divided by the step). Differences are relative to the largest native "
        "magnitude, but at least M·max(g, a·L) for forces and that times L for moments (M: the moving "
        "mass).\n\n"
    )
    text += _table(["source", "result", "largest difference (rel.)", "tolerance", "where", "states"], rows, "llrrlr")
    for r in run.force_table.itertuples():
        if getattr(r, "basis", ""):
            text += f"\n\n`{r.engine}`: {r.basis}."
    if e is None:
        text += f"\n\nPower balance of the native solution: not computed ({run.no_energy})."
    else:
        text += (
            f"\n\nPower balance of the native solution (driving power + power of loads = rate of change of "
            f"kinetic + potential energy): largest residual {_g(e['residual'], 2)} W of {_g(e['scale'], 3)} W "
            f"({_g(e['relative'], 2)}, tolerance {_g(e['tolerance'], 2)}); the work done since t = 0 matches the "
            f"energy change within {_g(e['work_error'], 2)} J (trapezoidal rule over {e['samples']} states; "
            f"energy swing {_g(e['energy_swing'], 3)} J)."
        )
    if "forces" in images:
        text += f"\n\n![reactions and driving effort]({images['forces']})"
    return text


def report_markdown(run: RunResult, images: dict[str, str], command: str) -> str:
    """The report of one mechanism; ``images`` maps figure keys to paths relative to the report."""
    mech = run.mechanism
    verdict = (
        "**some modes beyond tolerance**"
        if not run.passed
        else "all modes within tolerance"
        if not run.findings
        else f"all modes within tolerance but the stated findings of {', '.join(f'`{m}`' for m in run.findings)}"
    )
    sections = [
        f"# {mech.name}: {mech.title}",
        f"Source: {mech.source or '—'}. Result: {verdict}.",
        "\n".join(f"> **Warning:** {line}." for line in limit_warnings(run.native, run.branch)),
        mech.notes.strip(),
        f"![the mechanism]({images['drawing']})" + (f"  ![motion]({images['gif']})" if "gif" in images else ""),
        "## Printed answers\n\n" + _textbook_section(run),
        "## Comparison with the native solution\n\n" + _comparison_section(run),
        f"![quantities]({images['quantities']})\n\n![differences]({images['errors']})",
        "## Dynamic modes: error against time step\n\n" + _dynamic_section(run, images),
        "## Joint reactions and driving effort\n\n" + _forces_section(run, images),
        "## Native solver\n\n" + _solver_section(run),
        "## Versions\n\n" + _table(["package", "version"], [[k, v] for k, v in versions().items()]),
        f"Reproduce: `{command}`",
    ]
    return "\n\n".join(s for s in sections if s) + "\n"


def index_markdown(entries: list[dict], command: str) -> str:
    """reports/README.md: one line per mechanism with its worst disagreement."""
    rows = []
    for e in entries:
        rows.append(
            [
                f"[{e['name']}]({e['name']}.md)",
                e["title"],
                ("pass" if e["passed"] else "**FAIL**")
                + (f" (findings: {', '.join(f'`{m}`' for m in e.get('findings', ()))})" if e.get("findings") else ""),
                e["worst"],
                e["textbook"],
            ]
        )
    return (
        "# Reports\n\nOne report per mechanism: every engine mode against the exact native solution, and "
        "the printed answers checked value by value. Last written by `" + command + "`; each report "
        "names the command that reproduces it.\n\n"
        + _table(
            ["mechanism", "title", "result", "largest difference relative to its tolerance", "printed answers"], rows
        )
        + "\n"
    )


def worst_text(run: RunResult) -> str:
    worst = run.worst()
    if worst is None:
        return "—"
    mode, category, relative, tolerance = worst
    return f"`{mode}` {category}: {_g(relative, 2)} (tolerance {_g(tolerance, 2)})"


def textbook_text(run: RunResult) -> str:
    if not run.textbook:
        return "none printed"
    c = verdict_counts(run.textbook)
    return f"{c['agrees']} agree, {c['rounding']} rounding, {c['disagrees']} disagree"
