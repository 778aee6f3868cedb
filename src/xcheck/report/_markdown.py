"""The Markdown report of a comparison run and the index of all reports."""

from __future__ import annotations

import math
import re
from decimal import Decimal
from pathlib import Path

import numpy as np

from .. import engines
from ..kinematics import Status
from ..precision import shown
from ..ranges import range_text
from ..runner import (
    CATEGORIES,
    RunResult,
    condition_number,
    convergence_table,
    left_out_text,
    run_verdict,
    tolerance,
    versions,
)
from ..tolerances import conditioned_round_off
from ._evidence import Evidence

__all__ = [
    "mode_parts",
    "source_parts",
    "passed",
    "report_markdown",
    "index_markdown",
    "verdict_counts",
    "worst_text",
    "textbook_text",
]

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


def _round_off(row) -> float:
    """A categories row's round-off bound (0 where the table has none)."""
    bound = getattr(row, "round_off", 0.0)
    return float(bound) if bound is not None and math.isfinite(bound) else 0.0


def _category_round_off(outcome, category: str) -> float:
    """A mode's round-off bound of one category (0 if it has none)."""
    table = outcome.categories
    if table.empty or "category" not in table:
        return 0.0
    return max((_round_off(r) for r in table.itertuples() if r.category == category), default=0.0)


def _table(headers: list[str], rows: list[list[str]], align: str | None = None) -> str:
    align = align or "l" * len(headers)
    marks = {"l": "---", "r": "---:", "c": ":---:"}
    lines = ["| " + " | ".join(headers) + " |", "| " + " | ".join(marks[a] for a in align) + " |"]
    lines += ["| " + " | ".join(str(c).replace("|", "\\|").replace("\n", " ") for c in row) + " |" for row in rows]
    return "\n".join(lines)


def verdict_counts(textbook: list[dict]) -> dict[str, int]:
    return {v: sum(r["verdict"] == v for r in textbook) for v in ("agrees", "rounding", "disagrees")}


def _mode_row(run: RunResult, outcome) -> list[str]:
    """A mode's cells of the comparison table, after its name."""
    if not outcome.ok:
        result = "finding, failed" if outcome.finding else "**failed**"
        return [f"{result}: {outcome.reason}"] + ["—"] * len(CATEGORIES) + [""]
    cells = []
    table = outcome.categories.set_index("category") if not outcome.categories.empty else None
    for c in CATEGORIES:
        if table is None or c not in table.index:
            cells.append("—")
            continue
        row = table.loc[c]
        mark = "" if row.passed else " ✗"
        cells.append(f"{shown(row.relative, _round_off(row))} / {_g(row.tolerance, 2)}{mark}")
    worst = ""
    if table is not None:
        largest = _worst(outcome)  # a category with no tolerance (its order not observed) counts as the worst
        if largest is not None:
            c = largest["category"]
            x = float(table.at[c, "worst_input"])
            worst = f"{c}: {table.at[c, 'worst']!s} at {run.mechanism.drivers[0].name} = {_input_text(run, x)}"
        else:
            worst = "round-off everywhere"
    result = {"pass": "pass", "finding": "finding", "fail": "**FAIL**"}[outcome.verdict]
    if outcome.reason:
        result += f" ({outcome.reason})"
    return [result] + cells + [worst]


def _worst(outcome) -> dict | None:
    """A mode's largest difference relative to its tolerance, over the
    differences above their round-off bound (below it, which is largest is
    noise): category, relative, tolerance; None if none."""
    best = None
    for row in outcome.categories.itertuples():
        if row.relative < _round_off(row):
            continue
        ratio = row.relative / row.tolerance if row.tolerance > 0 else math.inf
        if best is None or ratio > best[0]:
            best = (ratio, {"category": str(row.category), "relative": float(row.relative), "tolerance": row.tolerance})
    return None if best is None else best[1]


def mode_parts(run: RunResult, made: dict) -> dict[str, dict]:
    """What the report shows of each mode of the run (JSON: table rows as lists
    of cells, text), with its verdict and ``made``, where it comes from
    (:func:`._evidence.produced`; :func:`_made`)."""
    parts = {}
    for mode, outcome in run.outcomes.items():
        t = tolerance(mode)
        parts[mode] = {
            "row": _mode_row(run, outcome),
            "tolerance": [_g(t.position, 2), _g(t.angle, 2), _g(t.velocity, 2), _g(t.acceleration, 2), t.basis],
            "finding": outcome.finding,
            "dynamic": _dynamic_block(run, mode, outcome),
            "verdict": outcome.verdict,
            "ran": bool(outcome.ok and not outcome.categories.empty),
            "worst": _worst(outcome) if outcome.ok and not outcome.finding else None,
            "produced": _made(run, mode, made),
        }
    for mode, reason in run.not_applicable.items():
        parts[mode] = {"not_applicable": reason, "produced": _made(run, mode, made)}
    return parts


def _made(run: RunResult, key: str, made: dict) -> dict:
    """Where a mode's (or, for "forces", the reactions') part comes from:
    ``made``, and for an outcome the results cache gave, when it was computed
    (``computed``; the report's text is the same either way)."""
    cached = run.provenance.get(key)
    if cached is None or not cached.from_cache:
        return made
    return {**made, "computed": cached.computed_at}


def _provenance(evidence: Evidence) -> tuple[dict[str, str], str]:
    """For the parts kept from earlier runs: a mark per part (" [1]") and the
    notes that say where each mark's parts come from ("" when none is kept)."""
    marks: dict[str, str] = {}
    notes: dict[tuple, int] = {}
    kept = [(k, p) for k, p in (*evidence.modes.items(), *evidence.sources.items()) if k in evidence.carried]
    kept += [(f, evidence.figures[f]) for f in sorted(evidence.kept)]
    for key, part in kept:
        made = part["produced"]
        origin = (made["command"], made["xcheck"], made["date"])
        number = notes.setdefault(origin, len(notes) + 1)
        marks[key] = f" [{number}]"
    text = "\n".join(
        f"[{n}] Kept from an earlier run, not rerun by this one: `{command}` (xcheck {version}, {date})."
        for (command, version, date), n in notes.items()
    )
    return marks, text


def _comparison_section(run: RunResult, evidence: Evidence, marks: dict[str, str]) -> str:
    headers = ["mode", "result"] + [f"{c} ({_CATEGORY_UNIT[c]})" for c in CATEGORIES] + ["worst at"]
    ran = {m: p for m, p in evidence.modes.items() if "not_applicable" not in p}
    rows = [[f"`{mode}`{marks.get(mode, '')}", *part["row"]] for mode, part in ran.items()]
    text = _table(headers, rows, "ll" + "r" * len(CATEGORIES) + "l")
    for mode, part in ran.items():
        if part["finding"]:
            fails = "fails (✗)" if part.get("ran") else "failed"
            text += f"\n\n`{mode}` {fails} only where its engine is known to be wrong: {part['finding']}."
    text += (
        "\n\nEach cell: the largest difference from the native solution / the tolerance; < b: below b, "
        "the round-off that the states' conditioning allows (10 eps kappa for positions and angles, 10 eps kappa^2 "
        "for rates; 100 for an engine's kinematics), whose digits differ from machine to machine. Positions are "
        "relative to the mechanism's size, angles in rad, rates relative to the largest magnitude of that "
        "quantity over all bodies and points, but at least its scale floor (below). `native` is checked "
        "against its own equations (loop closure, velocity and acceleration equations). A dynamic mode's "
        "tolerance is the largest error its own convergence at the expected order allows (the verdict's "
        "basis is under the dynamic modes). ✗ marks a difference beyond its tolerance."
    )
    absent = {m: p["not_applicable"] for m, p in evidence.modes.items() if "not_applicable" in p}
    if absent:
        text += (
            "\n\nNot applicable here: " + "; ".join(f"`{m}`{marks.get(m, '')}: {r}" for m, r in absent.items()) + "."
        )
    if run.left_out:
        text += "\n\n" + left_out_markdown(run.left_out)
    text += "\n\nTolerances and their basis:\n\n" + _table(
        ["mode", "position", "angle", "velocity", "acceleration", "basis"],
        [[f"`{m}`{marks.get(m, '')}", *p["tolerance"]] for m, p in ran.items()],
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
    relative = _exact_round_off(run)
    rows = []
    for r in run.textbook:
        # the computed value's round-off in each column's units: percent, and units of the last printed digit
        last_digit = _last_digit(r.get("printed_text", ""))
        in_digits = relative * abs(r["computed"]) / last_digit if last_digit else 0.0
        rows.append(
            [
                r.get("symbol", ""),
                r.get("quantity", ""),
                r.get("instant", ""),
                r.get("printed_text", _g(r["printed"], 6)),
                _g(r["computed"], 6),
                r.get("unit", ""),
                shown(r.get("deviation_percent"), 100.0 * relative),
                shown(r.get("deviation_digits"), in_digits),
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


def _last_digit(printed: str) -> float:
    """The unit of a printed value's last digit ("112,500": 0.001); 0 if it is not a number."""
    try:
        exponent = Decimal(printed.replace(",", ".")).as_tuple().exponent
    except ArithmeticError:
        return 0.0
    return 10.0**exponent if isinstance(exponent, int) else 0.0


def _exact_round_off(run: RunResult) -> float:
    """The relative round-off of the native solution's values: 10 eps kappa^2
    (accelerations', the largest), kappa over the sweep."""
    return conditioned_round_off("acceleration", condition_number(run.native))


def _dynamic_block(run: RunResult, mode: str, outcome) -> str:
    """A dynamic mode's part of the dynamic section: what was compared, its
    error against time step, its verdict ("" for another mode)."""
    if mode == "native" or engines.mode(mode).kind != "dynamic" or outcome.result is None:
        return ""
    table = convergence_table(outcome)
    trajectory = outcome.trajectory
    parts = [f"**`{mode}`** — compared: {trajectory.notes if trajectory is not None else outcome.reason}"]
    if not table.empty:
        # the position error's round-off in m: the position category's (relative to the size)
        floor = _category_round_off(outcome, "position") * run.kinematics.system.size
        parts.append(
            _table(
                ["series", "time step [s]", "position error [m]", "observed order", "status"],
                [
                    [str(r["series"]), _g(r["timestep"], 3), shown(r["position_error"], floor, 3), _g(r["order"], 3)]
                    + [str(r["status"])]
                    for r in table.to_dict("records")
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
                        shown(r.relative, _round_off(r), 3),
                        _g(r.tolerance, 3),
                        "pass" if r.passed else "**FAIL**",
                        str(r.basis),
                    ]
                    for r in outcome.categories.itertuples()
                ],
                "lrrll",
            )
        )
    return "\n\n".join(parts)


def _dynamic_section(evidence: Evidence, images: dict[str, str], marks: dict[str, str]) -> str:
    parts = []
    for mode, part in evidence.modes.items():
        block = part.get("dynamic", "")
        if block:
            head = f"**`{mode}`**"
            parts.append(block.replace(head, head + marks.get(mode, ""), 1) if block.startswith(head) else block)
    if "convergence" in images:
        parts.insert(0, _image("error against time step", images["convergence"], marks.get("convergence.png", "")))
    return "\n\n".join(parts) if parts else "No dynamic mode ran."


def _image(caption: str, path: str, mark: str = "") -> str:
    """A figure's Markdown; a figure kept from an earlier run says so (its mark)."""
    return f"![{caption}]({path})" + (f"\n\n(Figure{mark}: kept from an earlier run.)" if mark else "")


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
        closure = _category_round_off(run.outcomes["native"], "position") if "native" in run.outcomes else 0.0
        lines.append(
            f"- Largest loop-closure residual: "
            f"{shown(float(native.residual[good].max()), closure * kin.system.size)} m; smallest "
            f"inverse condition number of the Jacobian: {_g(float(native.singularity[good].min()), 2)} "
            f"(0 would be a singular configuration: dead centre or limit position)."
        )
    return "\n".join(lines)


def source_parts(run: RunResult, made: dict) -> dict[str, dict]:
    """What the report shows of each force source of the run (JSON), with
    whether it passed and ``made``, where it comes from."""
    parts = {}
    made = _made(run, "forces", made)
    for r in run.force_table.to_dict("records"):
        finding = str(r.get("finding", "") or "")
        # where its engine's stated findings explain its failure, the part says so (and only then)
        explained = {"verdict": "finding", "finding": finding} if finding else {}
        if not r["ok"]:  # failed, or the engine cannot hold the mechanism (no verdict either way)
            outcome = "not applicable" if not r["applies"] else "finding, failed" if finding else "**failed**"
            parts[str(r["engine"])] = {
                "row": [f"{outcome}: {r['reason']}", "—", "—", "—", "—"],
                "basis": "",
                "passed": not r["applies"],
                "produced": made,
                **explained,
            }
            continue
        bound, relative, unit = float(r.get("round_off", 0.0)), float(r["max_rel"]), r["unit"]
        if relative < bound:  # where the largest noise lies says nothing
            scale = r["max_abs"] / relative if relative > 0 else 0.0
            where = f"everywhere {shown(r['max_abs'], bound * scale, 3)} {unit}" if scale else "everywhere 0"
        else:
            where = f"{r['name']} {r['quantity']}: {_g(r['max_abs'], 3)} {unit}"
        parts[str(r["engine"])] = {
            "row": [
                "pass" if r["passed"] else "finding" if finding else "**FAIL**",
                shown(relative, bound),
                f"{_g(r['tolerance'], 2)} (scale ≥ {_g(r['floor'], 3)} {unit})",
                where,
                str(r["states"]),
            ],
            "basis": str(r.get("basis", "") or ""),
            "passed": bool(r["passed"]),
            "produced": made,
            **explained,
        }
    return parts


def _forces_section(run: RunResult, evidence: Evidence, images: dict[str, str], marks: dict[str, str]) -> str:
    if run.no_forces:
        return f"Not computed: {run.no_forces}."
    if not evidence.sources:
        return "Not computed in this run."
    rows = [[f"`{source}`{marks.get(source, '')}", *part["row"]] for source, part in evidence.sources.items()]
    e = run.energy
    text = (
        "Reactions (force of a joint's first body on its second, global frame), slider normal forces and "
        "couples, and driver efforts (in the sense that increases the input) over the simulation window, "
        "each source against the native multipliers of M q'' - Phi_q^T lambda = Q at the source's own "
        "states. `newton-euler` is the seed's per-body form M a = D R + Q; pymunk gives magnitudes only "
        "(impulses over a step divided by the step). Differences are relative to the largest native "
        "magnitude, but at least M·max(g, a·L) for forces and that times L for moments (M: the moving "
        "mass); < b: below b, the round-off that the states' conditioning allows.\n\n"
    )
    text += _table(["source", "result", "largest difference (rel.)", "tolerance", "where", "states"], rows, "llrrlr")
    for source, part in evidence.sources.items():
        if part.get("finding"):
            text += f"\n\n`{source}` fails only where its engine is known to be wrong: {part['finding']}."
        if part["basis"]:
            text += f"\n\n`{source}`: {part['basis']}."
    if e is None:
        text += f"\n\nPower balance of the native solution: not computed ({run.no_energy})."
    else:
        bound = e.get("round_off", 0.0)
        text += (
            f"\n\nPower balance of the native solution (driving power + power of loads = rate of change of "
            f"kinetic + potential energy): largest residual {shown(e['residual'], bound * e['scale'])} W of "
            f"{_g(e['scale'], 3)} W ({shown(e['relative'], bound)}, tolerance {_g(e['tolerance'], 2)}); the work "
            f"done since t = 0 matches the energy change within {_g(e['work_error'], 2)} J (trapezoidal rule "
            f"over {e['samples']} states; energy swing {_g(e['energy_swing'], 3)} J)."
        )
    if "forces" in images:
        text += "\n\n" + _image("reactions and driving effort", images["forces"], marks.get("forces.png", ""))
    return text


def report_verdict(run: RunResult, evidence: Evidence) -> str:
    """The verdict of the report (:func:`xcheck.runner.run_verdict`) over its
    evidence: the run's parts and those kept from earlier runs."""
    sources = [p.get("verdict", "pass" if p["passed"] else "fail") for p in evidence.sources.values()]
    return run_verdict(
        [*(p.get("verdict", "pass") for p in evidence.modes.values()), *(v for v in sources if v != "not applicable")],
        run.energy is None or bool(run.energy["passed"]),
    )


def passed(run: RunResult, evidence: Evidence) -> bool:
    """The report's verdict is not "fail" (:func:`report_verdict`)."""
    return report_verdict(run, evidence) != "fail"


def finding_names(evidence: Evidence) -> list[str]:
    """The modes, and the force sources (``ENGINE-forces``), that fail only in their
    engines' stated findings, as :attr:`xcheck.runner.RunResult.findings` names them."""
    modes = [mode for mode, part in evidence.modes.items() if part.get("finding")]
    return modes + [f"{source}-forces" for source, part in evidence.sources.items() if part.get("finding")]


def report_markdown(run: RunResult, evidence: Evidence, images: dict[str, str], command: str) -> str:
    """The report of one mechanism: ``run``'s native solution and the parts of
    ``evidence`` (the run's, and those kept from earlier runs, marked);
    ``images`` maps figure keys to paths relative to the report."""
    mech = run.mechanism
    marks, provenance = _provenance(evidence)
    findings = finding_names(evidence)
    verdict = {
        "pass": "**pass** (every mode within its tolerance)",
        "pass with findings": "**pass with findings** (every mode within its tolerance but the stated findings of "
        f"{', '.join(f'`{m}`' for m in findings)})",
        "fail": "**fail** (some modes beyond their tolerance)",
    }[report_verdict(run, evidence)]
    sections = [
        f"# {mech.name}: {mech.title}",
        f"Source: {mech.source or '—'}. Result: {verdict}.",
        provenance,
        "\n\n".join(f"> **Warning:** {line}." for line in run.warnings),
        mech.notes.strip(),
        f"![the mechanism]({images['drawing']})" + (f"  ![motion]({images['gif']})" if "gif" in images else ""),
        "## Printed answers\n\n" + _textbook_section(run),
        "## Comparison with the native solution\n\n" + _comparison_section(run, evidence, marks),
        _image("quantities", images["quantities"], marks.get("quantities.png", ""))
        + "\n\n"
        + _image("differences", images["errors"], marks.get("differences.png", "")),
        "## Dynamic modes: error against time step\n\n" + _dynamic_section(evidence, images, marks),
        "## Joint reactions and driving effort\n\n" + _forces_section(run, evidence, images, marks),
        "## Native solver\n\n" + _solver_section(run),
        "## Versions\n\n" + _table(["package", "version"], [[k, v] for k, v in versions().items()]),
        f"Reproduce: `{command}`",
    ]
    return "\n\n".join(s for s in sections if s) + "\n"


def left_out_markdown(left: dict[str, str]) -> str:
    """The run's line on the modes it left out (:func:`xcheck.runner.left_out_text`) as a sentence."""
    line = re.sub(r"(--engines \S+?)([,)]| or)", r"`\1`\2", left_out_text(left))
    return line[0].upper() + line[1:] + "."


def index_markdown(entries: list[dict]) -> str:
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
                f"`{e['command']}`" if e.get("command") else "—",
            ]
        )
    return (
        "# Reports\n\nOne report per mechanism: every engine mode against the exact native solution, and "
        "the printed answers checked value by value.\n\n"
        + _table(
            [
                "mechanism",
                "title",
                "result",
                "largest difference relative to its tolerance",
                "printed answers",
                "reproduce",
            ],
            rows,
        )
        + "\n"
    )


def worst_text(evidence: Evidence) -> str:
    """The index's cell of a report: its mode with the largest difference
    relative to its tolerance, over the modes that do not fail only in their
    stated findings and the differences above their round-off bound."""
    best = None
    for mode, part in evidence.modes.items():
        worst = part.get("worst")
        if worst is None:
            continue
        ratio = worst["relative"] / worst["tolerance"] if worst["tolerance"] > 0 else math.inf
        if best is None or ratio > best[0]:
            best = (ratio, mode, worst)
    if best is None:
        measured = any(p.get("ran") and not p.get("finding") for p in evidence.modes.values())
        return "all within round-off" if measured else "—"
    _, mode, worst = best
    return f"`{mode}` {worst['category']}: {_g(worst['relative'], 2)} (tolerance {_g(worst['tolerance'], 2)})"


def textbook_text(run: RunResult) -> str:
    if not run.textbook:
        return "none printed"
    c = verdict_counts(run.textbook)
    return f"{c['agrees']} agree, {c['rounding']} rounding, {c['disagrees']} disagree"
