"""What ``xcheck solve`` shows: JSON in SI units, tables in display units."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rich.cells import cell_len
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from .kinematics import InputRange, Kinematics, Solution, Status
from .precision import shown
from .ranges import range_text

__all__ = [
    "mode_trust",
    "engine_version",
    "engine_rows",
    "print_list",
    "print_fuzz",
    "range_json",
    "print_engines",
    "print_run_totals",
    "solution_json",
    "print_solution",
    "wide_console",
    "textbook_json",
    "print_textbook",
    "run_json",
    "print_run",
]


def engine_version(engine) -> str:
    """The installed version of an engine's first distribution ("xcheck X" for
    one that needs none), or "" where it is not installed."""
    from importlib import metadata

    from . import __version__

    if not engine.distributions:
        return f"xcheck {__version__}"
    try:
        return metadata.version(engine.distributions[0])
    except metadata.PackageNotFoundError:
        return ""


#: the quantity categories a finding may name, as ``xcheck engines`` shows them
_CATEGORY_WORDS = {"omega": "angular velocity", "alpha": "angular acceleration", "failure": "runs fail"}


def print_engines(console: Console, rows: list[dict]) -> None:
    """``xcheck engines``: one line per mode (rows as its JSON has them)."""
    table = Table(box=None, pad_edge=False, header_style="bold")
    for header in ("engine", "version", "mode", "kind", "trusted for", "stated findings"):
        table.add_column(header, no_wrap=header != "stated findings")
    for row in rows:
        # the reason (with its install command) goes under the table: in the column it squeezed the others out
        version = row["version"] if row["available"] else "[red]not installed[/red]"
        for k, mode in enumerate(row["modes"]):
            findings = ", ".join(_CATEGORY_WORDS.get(c, c) for c in mode["findings"]) or "—"
            held = [f for f in row.get("findings", ()) if mode["kind"] in f["kinds"]]
            steps = [f["steps_below"] for f in held if f.get("steps_below") is not None]
            where = ["closed loops"] if held and all(f["closed_loops"] for f in held) else []
            where += [f"steps < {max(steps):g} s"] if held and len(steps) == len(held) else []
            findings += f" ({'; '.join(where)})" if where else ""
            kind = mode["kind"] + (" (on request)" if mode["on_request"] else "")
            table.add_row(
                escape(row["name"]) if k == 0 else "",
                version if k == 0 else "",
                escape(mode["name"]),
                kind,
                escape(mode["trusted_for"]),
                f"[yellow]{escape(findings)}[/yellow]" if mode["findings"] else findings,
            )
    print_table(console, table)
    for row in rows:
        if not row["available"]:
            console.print(f"{escape(row['name'])}: [red]{escape(row['reason'])}[/red]", highlight=False)
    console.print(
        "trusted for: a kinematic mode's largest position error per mechanism size; a dynamic mode's expected "
        "order of convergence as the time step halves. How each engine is modelled, its settings and the "
        "evidence of its findings: the documentation's engine pages; --json has the findings' text.",
        highlight=False,
    )


def mode_trust(mode) -> str:
    """What a mode (:class:`xcheck.engines.Mode`) can be trusted for, in one figure:
    a kinematic mode's position bound, a dynamic mode's expected order of
    convergence in positions (or its fixed position bound), "benchmark" for free motion."""
    tolerance = mode.tolerance
    if mode.kind == "kinematic":
        return f"exact to {_short(tolerance.position)} of the size"
    if mode.kind == "dynamic":
        order = mode.orders.get("position")
        if order is not None:
            return f"converges at order {order:g}"
        rates = mode.orders.get("velocity")
        return f"positions to {_short(tolerance.position)}" + (f", rates at order {rates:g}" if rates else "")
    return "benchmark (no verdict)"


def _short(value: float) -> str:
    """A bound in one significant digit, 1e-6 rather than 1e-06."""
    return f"{value:.0e}".replace("e-0", "e-").replace("e+0", "e")


def _number(value) -> float | None:
    """A finite float, or None (never NaN) for undetermined values."""
    value = float(value) + 0.0  # no negative zero
    return value if math.isfinite(value) else None


def _pair(values) -> list[float | None] | None:
    pair = [_number(v) for v in values]
    return None if any(v is None for v in pair) else pair


def solution_json(solution: Solution, labels: list[str] | None = None, forces=None) -> dict:
    """The JSON document of ``xcheck solve --json`` (SI units).

    Parameters
    ----------
    solution : Solution
    labels : list of str, optional
        A label per sample (the model file's instant labels).
    forces : xcheck.dynamics.Forces, optional
        Reactions and efforts at the same states: adds ``"joints"``
        (``{JOINT: {"reaction": [Fx, Fy], "normal": N, "moment": M}}``, N and
        N m) and ``"drivers"`` (``{DRIVER: {"effort": E}}``, N m or N) per state.
    """
    mech = solution.mechanism
    bodies = {b.name: solution.body(b.name) for b in mech.moving_bodies}
    points = {label: solution.point(label) for label in mech.point_owners}
    states = []
    for i in range(solution.q.shape[0]):
        status = Status(int(solution.status[i]))
        state = {
            "inputs": {
                d.name: {
                    "q": _number(solution.inputs[i, k]),
                    "qd": _number(solution.input_rates[i, k]),
                    "qdd": _number(solution.input_accelerations[i, k]),
                }
                for k, d in enumerate(mech.drivers)
            },
            "status": status.label,
            "message": status.message,
            "residual": _number(solution.residual[i]),
            "singularity": _number(solution.singularity[i]),
            "bodies": {
                name: {
                    "position": _pair(s["position"][i]),
                    "angle": _number(s["angle"][i]),
                    "velocity": _pair(s["velocity"][i]),
                    "omega": _number(s["omega"][i]),
                    "acceleration": _pair(s["acceleration"][i]),
                    "alpha": _number(s["alpha"][i]),
                }
                for name, s in bodies.items()
            },
            "points": {
                label: {key: _pair(p[key][i]) for key in ("position", "velocity", "acceleration")}
                for label, p in points.items()
            },
        }
        if forces is not None:
            state["joints"] = {
                name: {q: (_pair(v[i]) if v.ndim == 2 else _number(v[i])) for q, v in values.items()}
                for name, values in forces.joints.items()
            }
            state["drivers"] = {
                name: {q: _number(v[i]) for q, v in values.items()} for name, values in forces.drivers.items()
            }
        if labels is not None:
            state = {"label": labels[i], **state}
        states.append(state)
    units = {"length": "m", "angle": "rad", "time": "s"}
    if forces is not None:
        units.update(force="N", torque="N m")
    return {
        "mechanism": mech.name,
        "branch": solution.branch,
        "units": units,
        "angles": "continuous: never wrapped (a crank two turns on is 4 pi further)",
        "states": states,
    }


def range_json(kin: Kinematics, rng: InputRange) -> dict:
    """A driver's feasible range for JSON: SI bounds (rad or m; null where a
    crank turns round or a slide met no limit within its search span) and the
    display text."""
    driver = next(d for d in kin.mechanism.drivers if d.name == rng.driver)
    return {
        "driver": rng.driver,
        "quantity": driver.quantity,
        "unit": "rad" if driver.quantity == "angle" else "m",
        "low": rng.low,
        "high": rng.high,
        "full_turn": rng.full_turn and driver.quantity == "angle",
        "text": range_text(kin, rng),
    }


def _fmt(value: float, digits: int = 6) -> str:
    if not math.isfinite(value):
        return "—"
    if value == 0.0:
        return "0"
    return f"{value + 0.0:.{digits}g}"


def wide_console(**kwargs) -> Console:
    """A console at least 140 columns wide, so that tables are never cut short
    when the output goes to a file or pipe (rich assumes 80 there)."""
    console = Console(**kwargs)
    if console.width < 140:
        console = Console(width=140, **kwargs)
    return console


def print_table(console: Console, table: Table) -> None:
    """Print ``table`` as ``console.print(table)`` would, faster where it can.

    rich lays out every cell of a table as a renderable of its own, about 80 µs
    a cell: 0.4 s for ``xcheck solve fourbar``'s tables. A table of the plain kind
    this module builds (no box, no edge padding, text cells, no column widths of
    its own) that fits the console, or fits it once its one wrapping column is
    narrowed, is instead written as one styled :class:`rich.text.Text` per line,
    with the same characters and styles. Any other table goes to rich.
    """
    lines = _plain_table_lines(console, table)
    if lines is None:
        console.print(table)
        return
    console.print(Text("\n").join(lines), soft_wrap=True)


def _plain_table_lines(console: Console, table: Table) -> list[Text] | None:
    """The lines of ``table`` as rich would render them, or None where this
    table is not of the plain kind :func:`print_table` can lay out itself."""
    columns = table.columns
    if (
        not columns
        or table.box is not None
        or table.pad_edge
        or tuple(table.padding) != (0, 1, 0, 1)
        or table.collapse_padding
        or not table.show_header
        or table.show_footer
        or table.title
        or table.caption
        or table.expand
        or table.width is not None
        or table.min_width is not None
        or table.row_styles
        or table.style not in ("", "none")
        or table.highlight
        or any(row.style or row.end_section for row in table.rows)
    ):
        return None
    header_style = console.get_style(table.header_style or "")
    grid: list[list[Text]] = []  # [column][row], the header first
    for column in columns:
        if (
            column.width is not None
            or column.min_width is not None
            or column.max_width is not None
            or column.ratio is not None
            or column.style
            or column.header_style
            or column.highlight
            or column.vertical != "top"
            or column.justify not in ("left", "right", "default")
        ):
            return None
        header, cells = column.header, list(column.cells)
        if not isinstance(header, str) or "\n" in header or not all(isinstance(cell, str) for cell in cells):
            return None
        grid.append(
            [console.render_str(header, style=header_style, highlight=False)]
            + [console.render_str(str(cell), highlight=False) for cell in cells]
        )
    last = len(columns) - 1
    pads = [(0 if i == 0 else 1, 0 if i == last else 1) for i in range(len(columns))]
    widths = [max(max(map(cell_len, text.plain.split("\n"))) for text in cells) for cells in grid]
    widths = [max(w + left + right, 1) - left - right for w, (left, right) in zip(widths, pads)]
    excess = sum(widths) + sum(left + right for left, right in pads) - console.width
    if excess > 0:
        # rich narrows the widest wrapping column first; done here for one such column
        wrapping = [i for i, column in enumerate(columns) if not column.no_wrap]
        if len(wrapping) != 1 or widths[wrapping[0]] <= excess:
            return None
        widths[wrapping[0]] -= excess
    lines = []
    for row in range(len(grid[0])):
        style = header_style if row == 0 else None
        wrapped = [
            _cell_lines(console, texts[row], width, column) for column, texts, width in zip(columns, grid, widths)
        ]
        height = max(len(cell) for cell in wrapped)
        for line_no in range(height):
            line = Text()
            for column, cell, width, (left, right) in zip(columns, wrapped, widths, pads):
                at = line_no - (height - len(cell) if row == 0 else 0)  # rich puts headers at the bottom
                text = cell[at] if 0 <= at < len(cell) else Text()
                gap = width - cell_len(text.plain)
                if column.justify == "right":
                    line.append(" " * (left + gap), style)
                    line.append_text(text)
                    line.append(" " * right, style)
                else:
                    line.append(" " * left, style)
                    line.append_text(text)
                    line.append(" " * (gap + right), style)
            lines.append(line)
    return lines


def _cell_lines(console: Console, text: Text, width: int, column) -> list[Text]:
    """The lines of one cell as rich wraps and justifies them in ``width``
    cells; a line that fits comes back as it is, to be padded to the width."""
    plain = text.plain
    if "\n" not in plain and plain == plain.rstrip() and cell_len(plain) <= width:
        return [text]  # what wrap gives a line that fits, but for the padding added later
    return list(text.wrap(console, width, justify=column.justify, overflow=column.overflow, no_wrap=column.no_wrap))


def print_solution(console: Console, solution: Solution, labels: list[str] | None = None, forces=None) -> None:
    """Tables of bodies and points per state, in the model's display units, and
    of joint reactions and driver efforts (N, N m) when ``forces`` is given."""
    mech = solution.mechanism
    u = mech.units
    L, A, W = u.length_factor, u.angle_factor, u.angular_rate_factor
    V, AC, AL = u.velocity_factor, u.acceleration_factor, u.angular_acceleration_factor
    alpha_unit = u.angular_acceleration
    for i in range(solution.q.shape[0]):
        status = Status(int(solution.status[i]))
        inputs = []
        for k, d in enumerate(mech.drivers):
            if d.quantity == "angle":
                inputs.append(
                    f"{d.name} = {_fmt(solution.inputs[i, k] / A)} {u.angle}, "
                    f"{_fmt(solution.input_rates[i, k] / W)} {u.angular_rate}, "
                    f"{_fmt(solution.input_accelerations[i, k] / AL)} {alpha_unit}"
                )
            else:
                inputs.append(
                    f"{d.name} = {_fmt(solution.inputs[i, k] / L)} {u.length}, "
                    f"{_fmt(solution.input_rates[i, k] / L)} {u.length}/s, "
                    f"{_fmt(solution.input_accelerations[i, k] / L)} {u.length}/s^2"
                )
        title = f"[bold]{mech.name}[/bold]" + (f" — {labels[i]}" if labels else "")
        console.print(title)
        console.print("  " + "; ".join(inputs))
        style = "green" if status == Status.OK else "yellow" if status == Status.NEAR_SINGULAR else "red"
        console.print(
            f"  status [{style}]{status.label}[/{style}] ({status.message}); "
            f"loop-closure residual {solution.residual[i] / L:.2g} {u.length}; "
            f"conditioning {solution.singularity[i]:.2g}; branch {solution.branch}"
        )

        bodies = Table(box=None, pad_edge=False, header_style="bold")
        for header in (
            "body",
            f"x [{u.length}]",
            f"y [{u.length}]",
            f"φ [{u.angle}]",
            f"vx [{u.velocity}]",
            f"vy [{u.velocity}]",
            f"ω [{u.angular_rate}]",
            f"ax [{u.acceleration}]",
            f"ay [{u.acceleration}]",
            f"α [{alpha_unit}]",
        ):
            bodies.add_column(escape(header), justify="right" if header != "body" else "left", no_wrap=True)
        bound = _state_round_off(solution, i)
        for b in mech.moving_bodies:
            s = solution.body(b.name)
            bodies.add_row(
                b.name,
                _at_round_off(s["position"][i, 0] / L, bound["position"] / L),
                _at_round_off(s["position"][i, 1] / L, bound["position"] / L),
                _at_round_off(s["angle"][i] / A, bound["angle"] / A),
                _at_round_off(s["velocity"][i, 0] / V, bound["velocity"] / V),
                _at_round_off(s["velocity"][i, 1] / V, bound["velocity"] / V),
                _at_round_off(s["omega"][i] / W, bound["omega"] / W),
                _at_round_off(s["acceleration"][i, 0] / AC, bound["acceleration"] / AC),
                _at_round_off(s["acceleration"][i, 1] / AC, bound["acceleration"] / AC),
                _at_round_off(s["alpha"][i] / AL, bound["alpha"] / AL),
            )
        print_table(console, bodies)

        points = Table(box=None, pad_edge=False, header_style="bold")
        for header in (
            "point",
            "body",
            f"x [{u.length}]",
            f"y [{u.length}]",
            f"vx [{u.velocity}]",
            f"vy [{u.velocity}]",
            f"|v| [{u.velocity}]",
            f"ax [{u.acceleration}]",
            f"ay [{u.acceleration}]",
            f"|a| [{u.acceleration}]",
        ):
            points.add_column(escape(header), justify="left" if header in ("point", "body") else "right", no_wrap=True)
        for label, owner in mech.point_owners.items():
            p = solution.point(label)
            v, a = p["velocity"][i], p["acceleration"][i]
            points.add_row(
                label,
                owner,
                _at_round_off(p["position"][i, 0] / L, bound["position"] / L),
                _at_round_off(p["position"][i, 1] / L, bound["position"] / L),
                _at_round_off(v[0] / V, bound["velocity"] / V),
                _at_round_off(v[1] / V, bound["velocity"] / V),
                _at_round_off(float(np.hypot(*v)) / V, bound["velocity"] / V),
                _at_round_off(a[0] / AC, bound["acceleration"] / AC),
                _at_round_off(a[1] / AC, bound["acceleration"] / AC),
                _at_round_off(float(np.hypot(*a)) / AC, bound["acceleration"] / AC),
            )
        print_table(console, points)
        if forces is not None:
            _print_forces(console, solution, forces, i)
        console.print()


def _at_round_off(value: float, bound: float) -> str:
    """A value of a solution table (:func:`xcheck.precision.shown`, six digits):
    "< bound" at round-off, but "0" where it is exactly zero (a ground point)."""
    return "0" if value == 0.0 else shown(value, bound, 6)


def _kappa(solution: Solution, i: int) -> float:
    """The condition number of state ``i``'s scaled constraint Jacobian (inf where singular)."""
    measure = float(solution.singularity[i])
    return 1.0 / measure if measure > 0.0 and math.isfinite(measure) else math.inf


def _state_round_off(solution: Solution, i: int) -> dict[str, float]:
    """Per quantity category, the round-off of state ``i``'s values (SI): what
    the state's conditioning allows (:func:`xcheck.tolerances.conditioned_round_off`,
    kappa the inverse of the state's singularity measure) times the category's
    scale at that state (the mechanism's size for positions; the largest speed,
    angular rate times size, acceleration over its points and bodies for rates).
    A value below it is noise: tables show it as "< bound", never its digits."""
    from .tolerances import conditioned_round_off

    mech, size = solution.mechanism, solution.kinematics.system.size
    kappa = _kappa(solution, i)
    parts = [solution.point(label) for label in mech.point_owners] + [solution.body(b.name) for b in mech.moving_bodies]
    speed = max((float(np.hypot(*p["velocity"][i])) for p in parts), default=0.0)
    accel = max((float(np.hypot(*p["acceleration"][i])) for p in parts), default=0.0)
    bodies = [solution.body(b.name) for b in mech.moving_bodies]
    speed = max([speed] + [abs(float(b["omega"][i])) * size for b in bodies])
    accel = max([accel] + [abs(float(b["alpha"][i])) * size for b in bodies])
    scale = {
        "position": size,
        "angle": 1.0,
        "velocity": speed,
        "omega": speed / size,
        "acceleration": accel,
        "alpha": accel / size,
    }
    return {c: conditioned_round_off(c, kappa) * s for c, s in scale.items()}


def _print_forces(console: Console, solution: Solution, forces, i: int) -> None:
    """Reactions (first body on second) and efforts at state i, SI units."""
    mech = solution.mechanism
    reactions = Table(box=None, pad_edge=False, header_style="bold")
    geared = any("tooth_force" in forces.joints[j.name] for j in mech.joints)
    headers = ("joint", "type", "force of → on", "Fx [N]", "Fy [N]", "|F| [N]", "normal [N]", "moment [N·m]")
    for header in headers + (("tooth [N]",) if geared else ()):
        reactions.add_column(
            escape(header), justify="left" if header in ("joint", "type", "force of → on") else "right", no_wrap=True
        )
    # round-off: what the state's conditioning allows an acceleration, on the largest force's scale
    largest = max(
        [float(np.hypot(*forces.joints[j.name]["reaction"][i])) for j in mech.joints]
        + [
            abs(float(forces.joints[j.name][k][i]))
            for j in mech.joints
            for k in ("normal",)
            if k in forces.joints[j.name]
        ]
        + [0.0]
    )
    from .tolerances import conditioned_round_off

    force_bound = conditioned_round_off("acceleration", _kappa(solution, i)) * largest
    size = solution.kinematics.system.size
    for joint in mech.joints:
        values = forces.joints[joint.name]
        f = values["reaction"][i]
        reactions.add_row(
            joint.name,
            joint.kind,
            f"{joint.body_a} → {joint.body_b}",
            _at_round_off(f[0], force_bound),
            _at_round_off(f[1], force_bound),
            _at_round_off(float(np.hypot(*f)), force_bound),
            _at_round_off(values["normal"][i], force_bound) if "normal" in values else "",
            _at_round_off(values["moment"][i], force_bound * size) if "moment" in values else "",
            *(
                (_at_round_off(values["tooth_force"][i], force_bound) if "tooth_force" in values else "",)
                if geared
                else ()
            ),
        )
    print_table(console, reactions)
    efforts = Table(box=None, pad_edge=False, header_style="bold")
    for header in ("driver", "joint", "effort", "unit", "power [W]"):
        efforts.add_column(
            escape(header), justify="left" if header in ("driver", "joint", "unit") else "right", no_wrap=True
        )
    for k, driver in enumerate(mech.drivers):
        effort = forces.drivers[driver.name]["effort"][i]
        efforts.add_row(
            driver.name,
            driver.joint,
            _fmt(effort),
            "N·m" if driver.quantity == "angle" else "N",
            _fmt(effort * solution.input_rates[i, k]),
        )
    print_table(console, efforts)


def textbook_json(results: list[dict]) -> list[dict]:
    """The ``"textbook"`` list of ``xcheck solve --json``: one object per printed
    value (see :func:`xcheck.textbook.check_printed`); ``printed`` and
    ``computed`` are in the entry's ``unit``, not SI; ``deviation_percent`` is
    null when the exact value is 0."""
    rows = []
    for r in results:
        row = dict(r)
        for key in ("printed", "computed", "deviation_percent", "deviation_digits"):
            row[key] = None if r[key] is None else _number(r[key])
        rows.append(row)
    return rows


_VERDICT_STYLE = {"agrees": "green", "rounding": "yellow", "disagrees": "red"}


def print_textbook(console: Console, results: list[dict], document: str = "") -> None:
    """The table of printed values against the exact ones, with the verdicts."""
    counts = {v: sum(r["verdict"] == v for r in results) for v in _VERDICT_STYLE}
    console.print(
        f"[bold]Printed answers[/bold]{' — ' + document if document else ''}: {len(results)} values; "
        + ", ".join(f"[{_VERDICT_STYLE[v]}]{n} {v}[/{_VERDICT_STYLE[v]}]" for v, n in counts.items())
    )
    several_instants = len({r["instant"] for r in results}) > 1
    several_branches = len({r["branch"] for r in results}) > 1
    table = Table(box=None, pad_edge=False, header_style="bold")
    headers = ["symbol", "quantity"] + ["instant"] * several_instants + ["branch"] * several_branches
    headers += ["printed", "computed", "unit", "deviation %", "last digits", "verdict", "note"]
    for header in headers:
        numeric = header in ("printed", "computed", "deviation %", "last digits")
        table.add_column(
            escape(header), justify="right" if numeric else "left", no_wrap=header != "note", overflow="fold"
        )
    for r in results:
        digits = max(6, sum(c.isdigit() for c in r["printed_text"].lstrip("-0,.")) + 2)
        percent = "—" if r["deviation_percent"] is None else f"{r['deviation_percent']:+.3g}"
        style = _VERDICT_STYLE[r["verdict"]]
        cells = [r["symbol"], r["quantity"]] + [r["instant"]] * several_instants + [r["branch"]] * several_branches
        cells += [
            r["printed_text"],
            _fmt(r["computed"], digits),
            r["unit"],
            percent,
            f"{r['deviation_digits']:+.3g}",
            f"[{style}]{r['verdict']}[/{style}]",
            r["note"],
        ]
        table.add_row(*cells)
    print_table(console, table)
    console.print()


def run_json(run) -> dict:
    """The JSON summary of ``xcheck run --json`` for one mechanism (SI units).

    Per mode: the largest absolute difference per category (m, m/s, m/s^2,
    rad, rad/s, rad/s^2), the same relative (see :class:`xcheck.runner.ModeOutcome`),
    the tolerances, the round-off bound of each relative difference (below it,
    its digits are noise that differs from machine to machine; the reports show
    "< bound" there: :func:`xcheck.precision.shown`), the physical floor of each
    category's scale (SI; ``scale_floors``: the run's,
    :func:`xcheck.results.scale_floors`), pass and reason; a
    dynamic mode adds ``convergence`` per category: the basis of its verdict
    (expected and observed order, the coarser run's error and time step (s),
    the time step compared, the error the expected order predicts there and
    the measured one; see :func:`xcheck.runner._convergence_verdict`).
    Every wall-clock time is under the one key ``timings`` (``seconds``: the
    whole run; ``engines``: per mode), so that two runs' JSON without it are
    identical; ``cache`` says which results came from the results cache, and
    when they were computed (:func:`xcheck.result_cache.provenance_json`): the JSON
    without these two keys is the same with or without the cache.
    """
    from .result_cache import provenance_json
    from .runner import CATEGORIES

    engines = {}
    for mode, outcome in run.outcomes.items():
        entry: dict[str, Any] = {c: None for c in CATEGORIES}
        entry["relative"] = {c: None for c in CATEGORIES}
        entry["tolerance"] = {c: None for c in CATEGORIES}
        entry["round_off"] = {c: None for c in CATEGORIES}
        entry["scale_floor"] = {c: None for c in CATEGORIES}
        for row in outcome.categories.itertuples():
            entry[row.category] = _number(row.max_abs)
            entry["relative"][row.category] = _number(row.relative)
            entry["tolerance"][row.category] = _number(row.tolerance)
            entry["round_off"][row.category] = _number(getattr(row, "round_off", math.nan))
            entry["scale_floor"][row.category] = _number(getattr(row, "floor", math.nan))
            if hasattr(row, "basis"):  # a dynamic mode judged by its convergence
                entry.setdefault("convergence", {})[row.category] = {
                    "basis": row.basis,
                    "expected_order": _number(row.expected_order),
                    "observed_order": _number(row.observed_order),
                    "coarse_error": _number(row.coarse_error),
                    "coarse_step": _number(row.coarse_step),
                    "step": _number(row.step),
                    "estimate": _number(row.estimate),
                    "measured": _number(row.relative),
                }
        entry.update(
            {
                "verdict": outcome.verdict,
                "pass": outcome.passed,
                "reason": outcome.reason or None,
                "finding": outcome.finding or None,
            }
        )
        engines[mode] = entry
    forces = {}
    for row in run.force_table.itertuples():
        forces[row.engine] = {
            "max_abs": _number(row.max_abs),
            "unit": row.unit or None,
            "relative": _number(row.max_rel),
            "tolerance": _number(row.tolerance),
            "round_off": _number(getattr(row, "round_off", math.nan)),
            "scale_floor": _number(getattr(row, "floor", math.nan)),
            "worst": f"{row.name} {row.quantity}".strip() or None,
            "states": int(row.states),
            "pass": bool(row.passed) if row.applies else None,
            "verdict": row.verdict,
            "reason": row.reason or None,
            "finding": row.finding or None,
        }
    energy = (
        None if run.energy is None else {k: (_number(v) if isinstance(v, float) else v) for k, v in run.energy.items()}
    )
    return {
        "mechanism": run.mechanism.name,
        "samples": int(run.native.inputs.shape[0]),
        "branch": run.branch,
        "verdict": run.verdict,
        "warnings": run.warnings,
        "scale_floors": {k: _number(v) for k, v in run.floors.items()} or None,
        "engines": engines,
        "not_applicable": run.not_applicable,
        "left_out": run.left_out,
        "forces": forces,
        "energy": energy,
        "forces_not_computed": run.no_forces or None,
        "energy_not_computed": run.no_energy or None,
        "textbook": textbook_json(run.textbook),
        "cache": provenance_json(run.provenance),
        "timings": {
            "seconds": round(run.seconds, 3),
            "engines": {mode: round(outcome.seconds, 3) for mode, outcome in run.outcomes.items()},
        },
    }


def print_run(console: Console, run) -> None:
    """The comparison table of one mechanism: per mode and category, the
    largest difference and its tolerance; the worst place of a failing mode."""
    from .result_cache import summary
    from .runner import CATEGORIES, left_out_text

    mech = run.mechanism
    status = {
        "pass": "[green]pass[/green]: every mode within its tolerance",
        "pass with findings": "[yellow]pass with findings[/yellow]: every mode within its tolerance but the "
        "engines' stated findings",
        "fail": "[red]fail[/red]: some modes beyond their tolerance",
    }[run.verdict]
    console.print(f"[bold]{mech.name}[/bold] — {mech.title}: {status} ({run.seconds:.1f} s)")
    for line in run.warnings:
        console.print(f"  [yellow]warning[/yellow]: {escape(line)}", highlight=False)
    table = Table(box=None, pad_edge=False, header_style="bold")
    table.add_column("mode", no_wrap=True)
    table.add_column("result", no_wrap=True)
    for c in CATEGORIES:
        table.add_column(c, justify="right", no_wrap=True)
    failures = []
    driver = mech.drivers[0]
    scale, unit = (
        (mech.units.angle_factor, mech.units.angle)
        if driver.quantity == "angle"
        else (mech.units.length_factor, mech.units.length)
    )
    for mode, outcome in run.outcomes.items():
        if not outcome.ok:
            style = "yellow" if outcome.finding else "red"
            table.add_row(mode, f"[{style}]{outcome.verdict}[/{style}]", *["—"] * len(CATEGORIES))
            failures.append(f"[{style}]{mode}: {escape(outcome.reason)}[/{style}]")
            if outcome.finding:
                failures.append(f"[yellow]{mode}: the engine's stated finding: {escape(outcome.finding)}[/yellow]")
            continue
        cells = []
        rows = {r.category: r for r in outcome.categories.itertuples()}
        for c in CATEGORIES:
            r = rows.get(c)
            if r is None:
                cells.append("—")
                continue
            style = "green" if r.passed else "yellow" if outcome.finding else "red"
            judged = math.isfinite(r.tolerance)  # none where the mode's convergence could not be observed
            cells.append(f"[{style}]{r.relative:.1e}[/{style}]/" + (f"{r.tolerance:.2g}" if judged else "—"))
            if not r.passed:
                if not judged:
                    against = f"with no tolerance ({escape(str(r.basis))})"
                elif r.relative <= r.tolerance:  # failed for the samples it left without a value
                    against = f"within {r.tolerance:.2g}"
                else:
                    against = f"> {r.tolerance:.2g}"
                failures.append(
                    f"[{style}]{mode}: {c} {r.relative:.2e} {against} at {r.worst}, "
                    f"{driver.name} = {r.worst_input / scale:.4g} {unit}[/{style}]"
                )
        if outcome.finding:
            failures.append(f"[yellow]{mode}: the engine's stated finding: {escape(outcome.finding)}[/yellow]")
        shown = {"pass": "[green]pass[/green]", "finding": "[yellow]finding[/yellow]", "fail": "[red]FAIL[/red]"}
        table.add_row(mode, shown[outcome.verdict], *cells)
    print_table(console, table)
    console.print(
        "  largest difference from the native solution / tolerance: position per mechanism size, "
        "angle in rad, rates per the quantity's largest magnitude (floored); a dynamic mode's tolerance "
        "is the largest error its own convergence at the expected order allows (basis: report, JSON)"
    )
    for failure in failures:
        console.print(f"  {failure}")
    if run.not_applicable:
        console.print("  not applicable: " + "; ".join(f"{m} ({r})" for m, r in run.not_applicable.items()))
    if run.left_out:
        console.print(f"  {escape(left_out_text(run.left_out))}")
    if not run.force_table.empty:
        parts = []
        for row in run.force_table.itertuples():
            if not row.applies:
                parts.append(f"{row.engine} not applicable ({row.reason})")
                continue
            if not row.ok:
                failed = "[yellow]finding[/yellow] (failed: " if row.finding else "[red]failed[/red] ("
                parts.append(f"{row.engine} {failed}{row.reason})")
                continue
            style = "green" if row.passed else "yellow" if row.finding else "red"
            parts.append(f"{row.engine} [{style}]{row.max_rel:.1e}[/{style}]/{row.tolerance:g}")
        console.print("  joint reactions and driving effort vs native: " + ", ".join(parts))
        for row in run.force_table.itertuples():
            if row.finding:
                console.print(
                    f"  [yellow]{row.engine} reactions: the engine's stated finding: {escape(row.finding)}[/yellow]"
                )
        e = run.energy
        if e is None:
            console.print(f"  power balance: not computed ({escape(run.no_energy)})")
        else:
            style = "green" if e["passed"] else "red"
            console.print(
                f"  power balance (drive + loads = d(T+V)/dt): [{style}]{e['relative']:.1e}[/{style}] "
                f"of {e['scale']:.3g} W"
            )
    elif run.no_forces and (
        mech.loads or mech.springs or mech.rotational_springs or len(mech.without_mass) < len(mech.moving_bodies)
    ):  # a file that asks for dynamics hears why there are no reactions; a kinematics-only one does not
        console.print(f"  joint reactions and driving effort: not computed ({escape(run.no_forces)})")
    cached = summary(run.provenance)
    if cached:
        console.print(f"  {cached}")
    if run.textbook:
        counts = {v: sum(r["verdict"] == v for r in run.textbook) for v in ("agrees", "rounding", "disagrees")}
        console.print(
            f"  printed answers: {len(run.textbook)} values — {counts['agrees']} agree, "
            f"{counts['rounding']} rounding, {counts['disagrees']} disagree (table: xcheck solve "
            f"{mech.name}, or the report)"
        )


def simulation_json(reference, result=None) -> dict:
    """The JSON document of ``xcheck simulate --json`` (SI units): the native
    reference's final state, its method, stated error and its basis, the second
    method's check, the singular positions passed, the loop closure and energy
    balance, and the ladder; with ``result``
    (:class:`xcheck.simulation.SimulationResult`) each free mode's ladder
    under ``engines`` and the modes that did not run under ``not_applicable``."""
    motion = reference.motion
    mech = motion.kinematics.mechanism
    solution = motion.solution()
    last = len(motion.times) - 1
    final = {
        "t": _number(motion.times[last]),
        "points": {
            label: {
                "position": _pair(solution.point(label)["position"][last]),
                "velocity": _pair(solution.point(label)["velocity"][last]),
            }
            for label in mech.point_owners
        },
        "bodies": {
            b.name: {
                "position": _pair(solution.body(b.name)["position"][last]),
                "angle": _number(solution.body(b.name)["angle"][last]),
                "omega": _number(solution.body(b.name)["omega"][last]),
            }
            for b in mech.moving_bodies
        },
    }
    return {
        "mechanism": mech.name,
        "duration": _number(motion.times[-1]),
        "output_step": _number(motion.times[1] - motion.times[0]) if len(motion.times) > 1 else None,
        "native": {
            "final": final,
            "method": reference.method,
            "error_estimate": {
                "largest": _number(reference.estimate.max()),
                "relative": _number(reference.relative),
                "final": _number(reference.estimate[-1]),
                "converged": reference.converged,
                "tolerance": _number(reference.tolerance),
                "basis": reference.basis,
                "rule": FREE_ERROR_RULE,
            },
            "check": _free_check_json(reference),
            "step": _number(motion.step),
            "singular_passes": [_number(t) for t in motion.singular_passes],
            "loop_closure": _number(motion.residual.max()),
            "energy_balance": {
                "largest": _number(abs(motion.energy_error).max()),
                "energy_start": _number(motion.energy[0]),
                "note": "E(t) - E(0) - W(t): kinetic + potential energy against the work of loads and dampers",
            },
            "ladder": [_ladder_entry(entry) for entry in reference.ladder],
            "cpu_seconds": _number(sum(entry["seconds"] for entry in reference.ladder)),
        },
        "engines": {}
        if result is None
        else {mode: _free_mode_json(outcome) for mode, outcome in result.outcomes.items()},
        "not_applicable": {} if result is None else dict(result.not_applicable),
        "left_out": {} if result is None else dict(result.left_out),
    }


#: how a native reference's stated error is obtained, for the JSON (see dynamics._reference)
FREE_ERROR_RULE = (
    "per output, the largest difference so far of a body position (m) or angle (rad times the size) between "
    "the run kept and the one before it in the ladder (the previous run's error, which the finer one does not "
    "exceed); for the check (Gauss-Legendre collocation, order 8), where the last two differences fell 256 "
    "times a halving or faster, 1.25 times the difference over 255 there instead (Roache's grid convergence "
    "index); where they fell less than 2.25 times "
    "(the runs not converging there), 1.25 times the larger of the two; at least the run's round-off (1e-13 of "
    "the size and float64's epsilon of it a step taken); plus the kept run's round-off: twice the largest "
    "difference so far from it of two more runs at its setting from starts moved 4 units in the last place; "
    "the ladder stops at the tolerance "
    "(converged), or, not converged, keeping the run with the least stated error: where the difference grew "
    "twice in a row (round-off), at its finest setting or at its work budget; a run that fails is the ladder's "
    "entry with its reason"
)


def _ladder_entry(entry: dict) -> dict:
    """A ladder row, numbers as JSON numbers, status and rule as text."""
    return {k: (v if isinstance(v, str) else _number(v)) for k, v in entry.items()}


def _free_check_json(reference) -> dict | None:
    """The second native method against the reference: its own ladder and their agreement."""
    check = reference.check
    if check is None:
        return None
    other = check.reference
    return {
        "method": other.method,
        "agreement": _number(check.agreement.max(initial=0.0)),
        "agreement_relative": _number(check.relative),
        "compared_outputs": len(check.times),
        "consistent": check.consistent,
        "note": "the largest difference of a body position (m) or angle (rad times the size) between the two "
        "methods' runs at the compared outputs; consistent: within the sum of their stated errors (null: "
        "inconclusive, where either did not reach its tolerance)",
        "error_estimate": {
            "largest": _number(other.estimate.max()),
            "relative": _number(other.relative),
            "converged": other.converged,
            "basis": other.basis,
        },
        "ladder": [_ladder_entry(entry) for entry in other.ladder],
        "cpu_seconds": _number(sum(entry["seconds"] for entry in other.ladder)),
    }


def _free_mode_json(outcome) -> dict:
    """A free mode's result: ok, reason, its ladder (one row per run, SI) and each
    series' verdict (:func:`xcheck.ladder.ladder_verdicts`)."""
    from .ladder import ladder_verdicts

    def cell(value):
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        if isinstance(value, (int, float, np.integer, np.floating)):
            return _number(value)
        return None if value is None or value == "" else str(value)

    rows = [] if outcome.summary is None else outcome.summary.to_dict("records")
    study = outcome.study
    return {
        "ok": outcome.ok,
        "reason": outcome.reason or None,
        "ladder": [{str(k): cell(v) for k, v in row.items()} for row in rows],
        "convergence": {} if study is None or study.empty else ladder_verdicts(study),
    }


def print_simulation(console, reference, result=None, report: str | None = None) -> None:
    """``xcheck simulate``'s summary: what backs the native reference, one line
    per free mode (its best run against the reference, SI units in the headers),
    and where the report is (``report``). The final state and every run of each
    ladder are in the report and the JSON."""
    doc = simulation_json(reference, result)
    native = doc["native"]
    estimate = native["error_estimate"]
    state = "converged" if estimate["converged"] else "[red]NOT converged[/red]"
    console.print(
        f"[bold]{escape(doc['mechanism'])}[/bold] — free motion for {doc['duration']:g} s: native reference "
        f"({native['method']}) {state}, error <= {_e(estimate['largest'])} m ({_e(estimate['relative'])} of the "
        f"size) at a mean step of {_e(native['step'])} s",
        highlight=False,
    )
    passes = native["singular_passes"]
    console.print(
        f"  loops closed to {_e(native['loop_closure'])} m before each projection; energy balance "
        f"{_e(native['energy_balance']['largest'])} J; singular positions passed: "
        + (f"{len(passes)} (first at {passes[0]:.4g} s)" if passes else "none")
        + f"; CPU {native['cpu_seconds']:.3g} s over {len(native['ladder'])} runs",
        highlight=False,
    )
    check = native["check"]
    if check is not None:
        verdict = {
            True: "within their stated errors",
            False: "[red]beyond their stated errors[/red]",
            None: "inconclusive (one of them is not converged)",
        }[check["consistent"]]
        console.print(
            f"  checked by {check['method']} (error <= {_e(check['error_estimate']['largest'])} m, CPU "
            f"{check['cpu_seconds']:.3g} s): the two agree to {_e(check['agreement'])} m, {verdict}",
            highlight=False,
        )
    if doc["engines"]:
        table = Table(box=None, pad_edge=False, header_style="bold")
        headers = (
            "mode",
            "runs",
            "best run",
            "error [m]",
            "order",
            "convergence",
            "loop drift [m]",
            "energy drift [J]",
            "CPU [s per s]",
            "breakdowns",
        )
        for header in headers:
            table.add_column(
                escape(header), justify="left" if header in ("mode", "best run", "breakdowns") else "right"
            )
        for mode, entry in doc["engines"].items():
            ladder = entry["ladder"]
            ran = [row for row in ladder if row.get("status") == "ok" and row.get("position_error") is not None]
            broken = len(ladder) - len(ran)
            if not entry["ok"] or not ran:
                why = entry["reason"] or "no run reached the end"
                table.add_row(escape(mode), str(len(ladder)), f"[red]failed[/red]: {escape(why)}", *[""] * 7)
                continue
            best = min(ran, key=lambda row: row["position_error"])
            table.add_row(
                escape(mode),
                str(len(ladder)),
                escape(f"{best.get('setting', '')} {best.get('integrator', '')} {_e(best.get('timestep'))} s".strip()),
                _e(best["position_error"]),
                "—" if best.get("order") is None else f"{best['order']:.2g}",
                escape(entry["convergence"].get(best.get("series", ""), "").split(" (")[0]) or "—",
                _e(best.get("loop_drift")),
                _e(best.get("energy_drift")),
                _e(best.get("cpu_per_simulated_second")),
                f"{broken} of {len(ladder)}" if broken else "none",
            )
        print_table(console, table)
        console.print(
            "  best run: the setting and step of the smallest largest point error against the reference; order: "
            "observed as the step halves; convergence: its series' (not converging: the error does not fall with "
            "the step); breakdowns: runs that blew up, came apart or left the branch",
            highlight=False,
        )
    for mode, reason in doc["not_applicable"].items():
        console.print(f"  {escape(mode)}: not run ({escape(reason)})", highlight=False)
    if doc["left_out"]:
        from .runner import left_out_text

        console.print(f"  {escape(left_out_text(doc['left_out']))}", highlight=False)
    console.print(f"report: {escape(report)}" if report else "report: not written (--no-report)", highlight=False)


def print_run_totals(console: Console, runs: list, failed_files: int, seconds: float) -> None:
    """The last line of ``xcheck run`` over several mechanisms: their verdicts,
    the modes passed, the stated findings, the modes failed, and the wall time."""
    verdicts = [run.verdict for run in runs]
    outcomes = [outcome for run in runs for outcome in run.outcomes.values()]
    passed = sum(outcome.passed for outcome in outcomes)
    findings = sum(bool(outcome.finding) for outcome in outcomes)
    failed = len(outcomes) - passed - findings
    counts = ", ".join(f"{verdicts.count(v)} {v}" for v in ("pass", "pass with findings", "fail") if verdicts.count(v))
    style = "red" if failed or failed_files or "fail" in verdicts else "green"
    console.print(
        f"[{style}]{len(runs) + failed_files} mechanisms[/{style}]"
        + (f" ({counts}" + (f", {failed_files} not run: bad input" if failed_files else "") + ")")
        + f"; modes: {passed} of {len(outcomes)} passed, {findings} stated findings, {failed} failed; {seconds:.0f} s",
        highlight=False,
    )


def _e(value) -> str:
    """A measured value in three significant digits ("—" where there is none)."""
    return "—" if value is None else f"{value:.3g}"


def _cell(value) -> str:
    if value is None:
        return "—"
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _g(value) -> str:
    return "—" if value is None else f"{value:.10g}"


def print_list(console: Console, rows: list[dict], benchmarks: list[str]) -> None:
    """``xcheck list``'s table (:func:`xcheck.batch.list_models`'s rows), the
    engines and their modes, the free-motion benchmarks, then the warnings
    about the drivers' laws (said under the table, not as errors)."""
    from . import engines as registry

    table = Table(header_style="bold")
    for header in ("name", "title", "source", "DOF", "input range"):
        table.add_column(header, overflow="fold")
    for row in rows:
        table.add_row(
            row["name"], row["title"], row["source"], str(row["dof"]), "\n".join(r["text"] for r in row["ranges"])
        )
    console.print(table)
    console.print(
        "Engines: "
        + ", ".join(
            escape(f"{e.name} ({', '.join(m.name for m in e.modes)})" + (f": {e.available()}" if e.available() else ""))
            for e in registry.engines()
        )
        + ". `xcheck engines` says more.",
        highlight=False,
    )
    if benchmarks:
        console.print(
            f"Free-motion benchmarks (xcheck simulate NAME): {escape(', '.join(benchmarks))}.", highlight=False
        )
    for row in rows:
        for line in row["warnings"]:
            console.print(f"[yellow]warning[/yellow]: {escape(line)}", highlight=False)


def engine_rows() -> list[dict]:
    """One row per registered engine for ``xcheck engines`` (its JSON and
    :func:`print_engines`): name, title, version, whether it is available and
    why not, its modes (kind, what each is trusted for, on request, the
    quantities of its stated findings), the findings, whether it gives forces,
    its export format, its notes."""
    from . import engines as registry

    return [
        {
            "name": e.name,
            "title": e.title,
            "version": engine_version(e),
            "available": not e.available(),
            "reason": e.available() or None,
            "modes": [
                {
                    "name": m.name,
                    "kind": m.kind,
                    "trusted_for": mode_trust(m),
                    "on_request": m.on_request,
                    "findings": list(dict.fromkeys(q for f in e.findings if m.kind in f.kinds for q in f.quantities)),
                }
                for m in e.modes
            ],
            "findings": [f.as_dict() for f in e.findings],
            "forces": e.force_tolerance is not None,
            "export_format": e.export_format,
            "notes": e.notes,
        }
        for e in registry.engines()
    ]


def print_fuzz(console: Console, counts, title: str, out) -> None:
    """A fuzz campaign's summary (:func:`xcheck.fuzz.summary`: per mode its cases,
    passed, failed, errors, not applicable) and where its rows and failure classes are."""
    table = Table(title=title)
    columns = ("cases", "passed", "failed", "error", "not applicable")
    table.add_column("mode", justify="left")
    for column in columns:
        table.add_column(column, justify="right")
    for _, r in counts.iterrows():
        table.add_row(escape(str(r["mode"])), *(str(r[c]) for c in columns))
    console.print(table)
    console.print(f"Rows: {escape(str(out / 'results'))}; failure classes: {escape(str(out / 'failures.md'))}")
