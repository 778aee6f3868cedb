"""The command line: ``xcheck list``, ``solve``, ``run``, ``draw`` and ``export``."""

from __future__ import annotations

import contextlib
import functools
import io
import json
import logging
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

from . import __version__, arguments, cache
from . import engines as registry
from .api import printed_answers, select_modes
from .arguments import MAX_SAMPLES
from .catalog import (
    BENCHMARKS,
    benchmark_names,
    indexed_names,
    installed,
    model_names,
    model_path,
    models_dir,
    reports_dir,
)
from .dynamics import inverse_dynamics
from .errors import InputError, XcheckError
from .fileio import write_atomic
from .kinematics import Kinematics
from .model import Mechanism, load_mechanism
from .motion import drive_warnings
from .output import (
    print_run,
    print_run_totals,
    print_simulation,
    print_solution,
    print_textbook,
    range_text,
    run_json,
    simulation_json,
    solution_json,
    textbook_json,
    wide_console,
)
from .precision import canonical_numbers, drift
from .states import asked_states, drawn_state, instant_states, solve_asked
from .units import evaluate_expression

if TYPE_CHECKING:
    from rich.progress import Progress

__all__ = ["app", "main"]


#: the base of the errors typer raises for a command line it cannot parse (click's
#: ClickException, which typer vendors from 0.2x on)
_USAGE_ERROR: type[Exception] = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


class _OneLineUsageErrors(TyperGroup):
    """The command group, but a command line it cannot parse (an option's value
    of the wrong type, an unknown option or command, a missing argument) is one
    line on stderr, ``xcheck: error: OPTION: expected ..., found ...``, and exit
    code 2, as every other bad input; not a box of usage and help."""

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        forward = {"complete_var": complete_var, "windows_expand_args": windows_expand_args, **extra}
        if not standalone_mode:
            return super().main(args, prog_name, standalone_mode=False, **forward)
        try:
            code = super().main(args, prog_name, standalone_mode=False, **forward)
        except _USAGE_ERROR as err:
            if type(err).__name__ != "NoArgsIsHelpError":  # `xcheck` alone: the help, printed already
                typer.echo(f"xcheck: error: {_usage_line(err)}", err=True)
            sys.exit(getattr(err, "exit_code", 2))
        except typer.Abort:
            typer.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


def _usage_line(err: Exception) -> str:
    """A command line typer could not parse, as what was expected and what was found."""
    message = " ".join(str(err.format_message()).split())  # type: ignore[attr-defined]
    what = message[:1].lower() + message[1:]
    kind = type(err).__name__
    param = getattr(err, "param", None)
    hint = getattr(err, "param_hint", None) or (param.opts[0] if param is not None and param.opts else "")
    hint = " / ".join(hint) if isinstance(hint, (list, tuple)) else str(hint).strip("'\"")
    ctx = getattr(err, "ctx", None)
    if kind == "NoSuchOption":
        known = (
            sorted(o for p in ctx.command.params for o in (*p.opts, *p.secondary_opts) if o[:1] == "-") if ctx else []
        )
        return f"{err.option_name}: expected an option among {', '.join(known)}, found none of that name"  # type: ignore[attr-defined]
    if kind == "MissingParameter":
        return f"{hint or 'an argument'}: expected a value, found none"
    if param is not None:
        names = {"float": "a number", "integer": "a whole number", "int": "a whole number", "boolean": "yes or no"}
        expected = names.get(param.type.name)
        found = re.search(r": '(.*)' is not a valid", message)
        if expected and found:
            return f"{hint}: expected {expected}, found {found[1]!r}"
        return f"{hint}: expected a valid value, found that {what}"
    found = re.search(r"No such command '(.*)'", message)
    if found and ctx is not None and hasattr(ctx.command, "list_commands"):
        return f"expected a command among {', '.join(ctx.command.list_commands(ctx))}, found {found[1]!r}"
    found = re.search(r"Got unexpected extra argument(?:s|\(s\))? \((.*)\)", message)
    if found:
        return f"expected no more arguments, found {found[1]!r}"
    found = re.search(r"Option '(.*)' requires an argument", message)
    if found:
        return f"{found[1]}: expected a value after it, found none"
    return f"expected a command line that `xcheck --help` describes, found that {what}"


app = typer.Typer(
    cls=_OneLineUsageErrors,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Exact kinematics of planar mechanisms, cross-checked against physics engines.",
)

ModelsOption = Annotated[
    Optional[Path],
    typer.Option("--models", help="Directory of mechanism files (default: ./models, or $XCHECK_MODELS)."),
]
ComparisonsOption = Annotated[
    Optional[Path],
    typer.Option(
        "--comparisons",
        help="Directory of printed textbook answers (default: comparisons/ beside "
        "the models directory, or $XCHECK_COMPARISONS).",
    ),
]


def _reports_errors(command):
    """Turn an XcheckError into one line on stderr and exit code 2; say which
    plug-ins could not be loaded, if the command looked for engines."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except XcheckError as err:
            typer.echo(f"xcheck: error: {err}", err=True)
            raise typer.Exit(2) from None
        finally:
            _warn_of_plug_ins()

    return wrapper


def _warn_of_plug_ins() -> None:
    """One line on stderr per plug-in that could not be loaded, where the
    registry was loaded (the command ran without it)."""
    for name, reason in registry.load_problems(load=False).items():
        typer.echo(
            f"xcheck: warning: plug-in {name!r} (entry-point group {registry.ENTRY_POINT_GROUP!r}) could not be "
            f"loaded, and runs nowhere: {reason}",
            err=True,
        )


def _version(value: bool):
    if value:
        typer.echo(f"xcheck {__version__}")
        raise typer.Exit()


class _ToStderr(logging.Handler):
    """What xcheck's loggers say (a cache entry not used, and why), one line each
    on stderr: the stderr of the moment, which a test runner may have replaced."""

    def emit(self, record: logging.LogRecord) -> None:
        typer.echo(self.format(record), err=True)


@app.callback()
def _main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
):
    """Exact kinematics of planar mechanisms, cross-checked against physics engines."""
    said = logging.getLogger("xcheck")
    if not any(isinstance(h, _ToStderr) for h in said.handlers):
        said.addHandler(_ToStderr(logging.WARNING))


@app.command("list")
@_reports_errors
def list_command(
    where: Annotated[
        Optional[Path],
        typer.Argument(
            help="A directory of mechanism files or one .toml file (default: the models directory).", show_default=False
        ),
    ] = None,
    models: ModelsOption = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print JSON (ranges in SI, with the display text) instead of a table.")
    ] = False,
):
    """List the mechanisms: name, title, source, degrees of freedom, input range.

    Examples: xcheck list;  xcheck list my-models/;  xcheck list my-linkage.toml --json
    """
    chosen = where if where is not None else models
    if chosen is not None and chosen.suffix == ".toml":
        if not chosen.is_file():
            raise InputError(f"{chosen}: expected a mechanism file, found no such file")
        paths = [chosen]
    else:
        directory = models_dir(chosen)
        paths = [directory / f"{name}.toml" for name in model_names(directory)]
    benchmarks = [] if chosen is not None and chosen.suffix == ".toml" else benchmark_names(directory)
    rows: list[dict[str, Any]] = []
    failures: list[str] = []
    for path in paths:  # one bad file is reported at the end; the others are listed
        try:
            mech = load_mechanism(path)
            kin = cache.cached_kinematics(mech)  # the branch map of an unchanged file is not computed again
            dof = kin.mobility()
            ranges = [kin.input_range(k) for k in range(len(mech.drivers))]
            warned = drive_warnings(kin)
            cache.store(kin)
        except XcheckError as err:
            failures.append(str(err))
            continue
        rows.append(
            {
                "name": mech.name,
                "title": mech.title,
                "source": mech.source,
                "file": str(path),
                "dof": dof["rank"],
                "ranges": [_range_json(kin, rng) for rng in ranges],
                "warnings": warned,
            }
        )
    if as_json:
        typer.echo(json.dumps(rows, indent=2, ensure_ascii=False, allow_nan=False))
    else:
        table = Table(header_style="bold")
        for header in ("name", "title", "source", "DOF", "input range"):
            table.add_column(header, overflow="fold")
        for row in rows:
            table.add_row(
                row["name"], row["title"], row["source"], str(row["dof"]), "\n".join(r["text"] for r in row["ranges"])
            )
        console = wide_console()
        console.print(table)
        console.print(
            "Engines: "
            + ", ".join(
                escape(
                    f"{e.name} ({', '.join(m.name for m in e.modes)})" + (f": {e.available()}" if e.available() else "")
                )
                for e in registry.engines()
            )
            + ". `xcheck engines` says more.",
            highlight=False,
        )
        if benchmarks:
            console.print(
                f"Free-motion benchmarks (xcheck simulate NAME): {escape(', '.join(benchmarks))}.", highlight=False
            )
        for row in rows:  # a law that asks more than the mechanism can do: said under the table, not as an error
            for line in row["warnings"]:
                console.print(f"[yellow]warning[/yellow]: {escape(line)}", highlight=False)
    for failure in failures:
        typer.echo(f"xcheck: error: {failure}", err=True)
    if failures:
        raise typer.Exit(2)


def _range_json(kin: Kinematics, rng) -> dict:
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


@app.command("engines")
@_reports_errors
def engines_command(
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
):
    """List the engines xcheck judges: their modes, what each can be trusted for, the stated findings.

    One row per mode: its engine and version (or why it cannot run here), its
    kind, what it can be trusted for in one figure, and the quantities where
    its engine is known to be wrong (a stated finding); --json has the
    findings' text and each engine's notes, the documentation a page per engine.
    Engines come from xcheck and from installed packages (entry-point group
    "xcheck.engines"); a plug-in that cannot be loaded is listed with its reason.

    Examples: xcheck engines;  xcheck engines --json
    """
    from .output import engine_version, mode_trust, print_engines

    rows: list[dict[str, Any]] = [
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
    problems = registry.load_problems()
    if as_json:
        typer.echo(json.dumps({"engines": rows, "plugin_errors": problems}, indent=2, ensure_ascii=False))
        return
    print_engines(wide_console(), rows)
    for name, reason in problems.items():
        typer.echo(f"xcheck: error: entry point {name!r} of group {registry.ENTRY_POINT_GROUP!r}: {reason}", err=True)


@app.command("cache")
@_reports_errors
def cache_command(
    clear: Annotated[
        bool, typer.Option("--clear", help="Remove every entry (branch maps, results, figures, JAX compilations).")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of lines.")] = False,
):
    """Show where xcheck keeps what it computed between runs, and how much; --clear empties it.

    The directory is the user's cache directory for xcheck, or $XCHECK_CACHE_DIR
    (`off`: no cache at all); $XCHECK_RESULTS_CACHE=off leaves the results out
    (as `xcheck run --no-cache` does). Every entry is authenticated and made by
    the running code: an edited, foreign or stale one is computed again.

    Examples: xcheck cache;  xcheck cache --clear
    """
    from . import store

    removed = store.clear() if clear else None
    found = store.describe()
    if as_json:
        typer.echo(json.dumps({**found, **({} if removed is None else {"removed": removed})}, indent=2))
        return
    if found["directory"] is None:
        typer.echo(f"the cache is off (${store.CACHE_ENV}=off)")
        return
    if removed is not None:
        typer.echo(f"removed {removed} files")
    typer.echo(f"cache directory: {found['directory']}")
    for kind, counts in found["kinds"].items():
        typer.echo(f"  {kind}: {counts['entries']} files, {counts['bytes'] / 2**20:.1f} MiB")


@app.command("solve")
@_reports_errors
def solve_command(
    name: Annotated[str, typer.Argument(help="Mechanism name (see `xcheck list`) or path to a .toml file.")],
    at: Annotated[
        Optional[str],
        typer.Option(
            "--at",
            metavar="V[,V…]",
            help="Input values in display units (degrees for angles, the model's length unit for slides); "
            "separate states by commas and, for several drivers, their values by colons (30:45). "
            "Rates come from the drivers' motion (angles modulo a turn; a driver that stands still gives "
            "a static position) unless --rate gives them. Default: the instants in the model file.",
        ),
    ] = None,
    rate: Annotated[
        Optional[str],
        typer.Option(
            "--rate",
            metavar="V[:V…]",
            help="With --at: the drivers' rates, one state for every --at state or one per state (angular_rate "
            "of [units] for angles, length unit/s for slides), instead of the motion laws'; 0 gives a static position.",
        ),
    ] = None,
    accel: Annotated[
        Optional[str],
        typer.Option(
            "--accel", metavar="V[:V…]", help="With --rate: the drivers' accelerations (rate unit per s), default 0."
        ),
    ] = None,
    branch: Annotated[
        Optional[str], typer.Option("--branch", help="Assembly branch (default: the model file's first).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON in SI units.")] = False,
    textbook_too: Annotated[
        bool,
        typer.Option(
            "--textbook",
            help="With --at: check the printed answers too (without --at they are always checked: they are "
            "at the file's instants).",
        ),
    ] = False,
    models: ModelsOption = None,
    comparisons: ComparisonsOption = None,
):
    """Solve a mechanism's position, velocity and acceleration at its instants.

    Examples: xcheck solve fourbar;  xcheck solve fourbar --at 45,90 --json;
    xcheck solve two-body-arm --at 30:30;  xcheck solve fourbar --at 60 --rate 1.5 --accel 0
    """
    path = model_path(name, models_dir(models))
    mech = load_mechanism(path)
    if at is None and (rate is not None or accel is not None):
        raise InputError(
            f"{mech.path}: {'--rate' if rate is not None else '--accel'}: expected it with --at "
            "(the instants of the file carry their own rates), found no --at"
        )
    kin = cache.cached_kinematics(mech)
    kin.assemble(branch)
    if at is None:
        asked = instant_states(kin)
    else:
        values, rates, accels = (
            None if text is None else _numbers(text, mech, option)
            for text, option in ((at, "--at"), (rate, "--rate"), (accel, "--accel"))
        )
        asked = asked_states(kin, values, rates, accels, options=("--at", "--rate", "--accel"))
        asked.labels = [f"at {label}" for label in asked.labels]
    try:
        solved = solve_asked(kin, asked, branch)
    finally:
        cache.store(kin)  # the feasible range, refused input or not
    solution, labels = solved.solution, solved.labels
    warned = solved.warnings
    for line in warned:  # before the numbers that explode there
        typer.echo(f"xcheck: warning: {line}", err=True)
    # the printed answers of comparisons/NAME.toml, if any; a bad file is reported
    # after the solution, which still prints
    # reactions and efforts when the file gives mass data; missing data on some
    # bodies is reported after the solution, which still prints
    forces, forces_error = None, None
    if any(b.mass is not None for b in mech.moving_bodies):
        try:
            forces = inverse_dynamics(solution)
        except XcheckError as err:
            forces_error = err
    textbook, textbook_error, document = None, None, ""
    try:  # printed answers are at the book's instants: with --at only on request
        if at is None or textbook_too:
            textbook, document = printed_answers(kin, comparisons)
    except XcheckError as err:
        textbook_error = err
    cache.store(kin)  # the printed answers' branches too
    if as_json:
        output = solution_json(solution, labels, forces)
        output["warnings"] = warned
        if textbook is not None:
            output["textbook"] = textbook_json(textbook)
        typer.echo(json.dumps(output, indent=2, allow_nan=False, ensure_ascii=False))
    else:
        console = wide_console()
        print_solution(console, solution, labels, forces)
        if textbook is not None:
            print_textbook(console, textbook, document)
    if forces_error is not None:
        raise forces_error
    if textbook_error is not None:
        raise textbook_error


@app.command("draw")
@_reports_errors
def draw_command(
    name: Annotated[str, typer.Argument(help="Mechanism name (see `xcheck list`) or path to a .toml file.")],
    at: Annotated[
        Optional[str],
        typer.Option(
            "--at",
            metavar="V[:V…]",
            help="The input in display units (degrees for angles, the model's length unit for slides; "
            "several drivers' values separated by colons). Default: the file's assembly.at.",
        ),
    ] = None,
    output: Annotated[
        Optional[Path], typer.Option("-o", "--output", help="The PNG to write (default: NAME.png here).")
    ] = None,
    branch: Annotated[
        Optional[str], typer.Option("--branch", help="Assembly branch (default: the model file's first).")
    ] = None,
    models: ModelsOption = None,
):
    """Draw the mechanism at an input as a PNG, without running any engine.

    Bodies are drawn as links between their joints, blocks on prismatic joints,
    pins in their slots, the ground hatched, the points labelled and the inputs'
    directions as arrows (from the drivers' motion laws).

    Examples: xcheck draw fourbar;  xcheck draw task-2-1 --at 40 -o task.png
    """
    from .drawing import figure_of

    path = model_path(name, models_dir(models))
    mech = load_mechanism(path)
    kin = cache.cached_kinematics(mech)
    kin.assemble(branch)
    cache.store(kin)
    target = output if output is not None else Path(f"{mech.name}.png")
    if target.suffix.lower() != ".png":
        raise InputError(f"-o {target}: expected a file name ending in .png, found {target.suffix or 'none'}")
    values = None
    if at is not None:
        values = _numbers(at, mech, "--at")
        if len(values) != 1:
            raise InputError(
                f"{mech.path}: --at: expected one state (values of several drivers separated by colons), "
                f"found {arguments.shown(at)}"
            )
    figure = figure_of(drawn_state(kin, values, branch=branch, option="--at"), 0)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    try:
        write_atomic(target, buffer.getvalue())
    except OSError as err:
        raise InputError(f"-o {target}: expected a file that can be written, found {err.strerror or err}") from None
    typer.echo(str(target))


@app.command("run")
@_reports_errors
def run_command(
    name: Annotated[str, typer.Argument(help="Mechanism name, path to a .toml file, or 'all'.")],
    engines: Annotated[
        Optional[str],
        typer.Option(
            "--engines",
            metavar="MODE[,MODE…]",
            help="Modes to run (default: all but those run only on request, such as mjx-dynamic; `xcheck engines` "
            "lists them): native, the engines' modes (e.g. "
            "mujoco-kinematic, pinocchio-dynamic), or groups: an engine's name (formulations, mujoco, "
            "pinocchio, pymunk, mjx, ...), a kind (kinematic, dynamic), or all (every mode).",
        ),
    ] = None,
    samples: Annotated[
        int,
        typer.Option("--samples", help=f"Samples of the sweeps over the feasible input range (3 to {MAX_SAMPLES})."),
    ] = 181,
    branch: Annotated[
        Optional[str], typer.Option("--branch", help="Assembly branch (default: the file's first).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary (SI units) instead of tables.")] = False,
    out: Annotated[
        Optional[Path],
        typer.Option(
            "--out", help="Directory of the Markdown reports (default: reports/ beside the models directory)."
        ),
    ] = None,
    report: Annotated[
        Optional[bool],
        typer.Option(
            "--report/--no-report",
            help="Write the Markdown reports and their figures (default: yes, but not with --json: "
            "a script asking for JSON does not pay for figures unless it adds --report).",
            show_default=False,
        ),
    ] = None,
    quiet: Annotated[
        bool,
        typer.Option(
            "--quiet",
            "-q",
            help="No progress bar and no tables (--json still "
            "prints); the exit code says whether all modes are within "
            "tolerance.",
        ),
    ] = False,
    models: ModelsOption = None,
    comparisons: ComparisonsOption = None,
    gif: Annotated[
        bool,
        typer.Option("--gif/--no-gif", help="With the report: its animated GIF of the motion (the costliest figure)."),
    ] = True,
    jobs: Annotated[
        Optional[int],
        typer.Option(
            "--jobs",
            "-j",
            help="Processes at once (default: one per CPU core): with several mechanisms, one mechanism each; "
            "with one, one mode each. 1: everything one after another in this process. The results and reports "
            "are those of a serial run.",
            show_default=False,
        ),
    ] = None,
    use_cache: Annotated[
        bool,
        typer.Option(
            "--cache/--no-cache",
            help="Take each mode's results from the results cache where this code computed them before, and keep "
            "what is computed (`xcheck cache` shows and clears it). --no-cache computes everything and keeps nothing.",
        ),
    ] = True,
):
    """Compare every solver and engine mode with the exact native solution over the feasible input range.

    Each mechanism gets one verdict: "pass" (every mode within its tolerance),
    "pass with findings" (every failure is an engine's stated finding, see
    `xcheck engines`) or "fail" (the table says which quantity, where, by how
    much). Exit code 0 for pass and pass with findings, 1 when any mechanism
    fails, 2 for bad input. With
    --json only the JSON is written (stdout; every wall-clock time under its
    "timings" key): add --report for the Markdown reports and figures too.

    Examples: xcheck run fourbar;  xcheck run all --json;  xcheck run task-2-1 --engines mujoco,formulations
    """
    started = time.perf_counter()
    arguments.samples(samples, "--samples")
    jobs = arguments.processes(jobs, "--jobs")
    if report is None:  # --json is for scripts: the results, not the figures, unless --report asks for them
        report = not as_json
    if report:  # matplotlib and the figures' code: only when a report is written
        from .report import update_index
    modes = select_modes(engines)
    directory = models_dir(models)
    names = model_names(directory) if name == "all" else [name]
    if out is not None and out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: expected a directory for the reports, found a file")
    options = (
        (f" --engines {engines}" if engines else "")
        + (f" --samples {samples}" if samples != 181 else "")
        + (f" --branch {branch}" if branch else "")
        + _shown_option("--models", models)
        + _shown_option("--comparisons", comparisons)
        + _shown_option("--out", out)
        + ("" if gif else " --no-gif")
    )
    results, entries, failures = [], [], []
    settings = (directory, modes, samples, branch, comparisons, report, out, options, gif, use_cache)
    mode_jobs = jobs if len(names) == 1 else 1  # one mechanism: its modes at once; several: the mechanisms
    jobs = min(jobs, len(names))
    progress = _progress_bar(quiet or as_json)
    with progress:
        task = progress.add_task("", total=len(names) * len(modes))
        if jobs <= 1:
            outcomes = []
            for model in names:

                def step(label: str, mode: str) -> None:
                    progress.update(task, description=f"{label}: {mode}", advance=1)

                outcomes.append(_run_model(model, *settings, step=step, jobs=mode_jobs))
        else:  # one mechanism per worker process; the outcomes kept in the order of the names
            outcomes = _run_models_in_parallel(names, settings, jobs, lambda: progress.update(task, advance=len(modes)))
        for run, entry, problems in outcomes:
            failures += problems
            if entry is not None:
                entries.append(entry)
            if run is not None:
                results.append(run)
    for target in {t for t, _, _ in entries}:
        model_file = next(f for t, f, _ in entries if t == target)
        try:
            update_index(target, [e for t, _, e in entries if t == target], indexed_names(model_file))
        except XcheckError as err:
            failures.append(str(err))
    if as_json:
        documents = [run_json(r) for r in results]
        if name == "all" or documents:
            typer.echo(
                json.dumps(documents if name == "all" else documents[0], indent=2, allow_nan=False, ensure_ascii=False)
            )
    elif not quiet:
        console = wide_console()
        for run in results:
            print_run(console, run)
            if report:
                console.print(f"  report: {reports_dir(Path(run.mechanism.path), out) / (run.mechanism.name + '.md')}")
            console.print()
        if len(names) > 1:
            print_run_totals(console, results, len(names) - len(results), time.perf_counter() - started)
    for failure in failures:
        typer.echo(f"xcheck: error: {failure}", err=True)
    if failures:
        raise typer.Exit(2)
    from .runner import EXIT_CODES

    code = max((EXIT_CODES[r.verdict] for r in results), default=0)
    if code:
        raise typer.Exit(code)


def _run_model(
    model,
    directory,
    modes,
    samples,
    branch,
    comparisons,
    report,
    out,
    options,
    gif=True,
    use_cache=True,
    step=None,
    jobs=1,
):
    """One mechanism of ``xcheck run``: its comparison, its modes in ``jobs``
    processes, and, if ``report``, its report; the caches (branch map,
    results) read and written where ``use_cache``. Returns (the run or None,
    (reports directory, file, index entry) or None, failure lines).
    ``step(label, stage)`` is told of each stage; it is left out in a worker
    process (:func:`_run_models_in_parallel`)."""
    from .runner import run_mechanism

    def tell(label: str, stage: str) -> None:
        if step is not None:
            step(label, stage)

    try:  # one bad file is reported at the end; the others run
        path = model_path(model, directory)
        mechanism = load_mechanism(path)
        kin = cache.cached_kinematics(mechanism) if use_cache else Kinematics(mechanism)
        kin.assemble(branch)
        label = kin.mechanism.name
        if report:  # what is in the report's way is said before the work, not after
            from .report import claim_index, claim_report

            claim_report(reports_dir(path, out), label)
            claim_index(reports_dir(path, out))
        textbook, _ = printed_answers(kin, comparisons)
        run = run_mechanism(
            kin, modes, samples, branch, textbook, progress=lambda mode: tell(label, mode), jobs=jobs, cache=use_cache
        )
        if use_cache:
            cache.store(kin)
    except XcheckError as err:
        if step is not None:
            step(model, "failed")  # the progress bar's share of the file's modes
            for _ in modes[1:]:
                step(model, "failed")
        return None, None, [str(err)]
    tell(label, "report" if report else "done")  # native
    if not report:
        return run, None, []
    from .report import write_report

    target = reports_dir(path, out)
    try:  # a report that cannot be written is reported; the run's results still count
        _, entry = write_report(run, target, f"xcheck run {_shown_model(model)}{options}", gif=gif, jobs=jobs)
        return run, (target, path, entry), []
    except XcheckError as err:
        problem = str(err)
    except OSError as err:
        problem = (
            f"{target}: expected a directory where the report of {label} can be written, found {err.strerror or err}"
        )
    except Exception as err:  # noqa: BLE001 - a bug in a report must not hide the other files
        problem = (
            f"{path}: report: expected a written report, found an internal error "
            f"({type(err).__name__}: {err}); please report it"
        )
    return run, None, [problem]


def _run_models_in_parallel(names, settings, jobs: int, done) -> list:
    """:func:`_run_model` for each name in a pool of ``jobs`` worker processes
    (started afresh: "spawn"), the outcomes in the order of ``names`` whatever
    the order they finish in, so that the output and the reports are those of
    a serial run; ``done()`` after each mechanism. A mechanism whose worker
    died is one failure line and the others still count. Engines registered at
    run time (:func:`xcheck.engines.register`) exist only in this process: run
    them with ``--jobs 1``."""
    from ._parallel import collect, process_pool

    def failed(index: int, reason: str) -> tuple:
        return None, None, [f"{names[index]}: expected its run back from a worker process, found that {reason}"]

    # a mechanism whose every result is in the results cache runs here, while the workers
    # compute the others: its run takes a tenth of a second, a worker's start a second
    here = [i for i, model in enumerate(names) if _all_cached(model, settings)]
    away = [i for i in range(len(names)) if i not in here]
    outcomes = {}
    if len(away) < 2:
        here, away = list(range(len(names))), []
    with contextlib.ExitStack() as stack:
        if away:
            pool = stack.enter_context(process_pool(min(jobs, len(away))))
            futures = {pool.submit(_run_model, names[i], *settings): i for i in away}
        directory, modes, samples, branch, comparisons, report, out, options, gif, use_cache = settings
        for i in here:  # where it is the one mechanism not in the cache: its modes in worker processes
            outcomes[i] = _run_model(
                names[i], directory, modes, samples, branch, comparisons, report, out, options, gif, use_cache,
                jobs=1 if away else jobs,
            )  # fmt: skip
            done()
        if away:
            outcomes.update(collect(futures, failed, lambda _: done()))
    return [outcomes[i] for i in range(len(names))]


def _all_cached(model, settings) -> bool:
    """Whether the results cache holds every mode's results of ``model``
    (:func:`xcheck.result_cache.holds`); False for a file that does not load."""
    from .result_cache import holds

    directory, modes, samples, branch, *_, use_cache = settings
    if not use_cache:
        return False
    try:
        return holds(load_mechanism(model_path(model, directory)), modes, samples, branch)
    except (XcheckError, OSError):
        return False


def _progress_bar(off: bool, label: str = "{task.description}", stdout_terminal: bool = True) -> Progress:
    """A transient progress bar on stderr (``label``, done/total, time): only
    when stderr is a terminal, and stdout too unless ``stdout_terminal`` is
    False; never with --json or --quiet (``off``), so that piped or captured
    output stays clean."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    stderr = Console(stderr=True)
    return Progress(
        SpinnerColumn(),
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=stderr,
        transient=True,
        disable=off or not stderr.is_terminal or (stdout_terminal and not sys.stdout.isatty()),
    )


def _shown_path(path: Path) -> str:
    """A path as a command line would give it: relative to the working
    directory when it lies below it, else as it is."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _shown_model(name: str) -> str:
    """A mechanism argument (a name, 'all' or a path) as a reproducible command line gives it."""
    return _shown_path(Path(name)) if Path(name).suffix == ".toml" or "/" in name else name


def _shown_option(option: str, value: Path | None) -> str:
    return "" if value is None else f" {option} {_shown_path(Path(value))}"


@app.command("simulate")
@_reports_errors
def simulate_command(
    name: Annotated[str, typer.Argument(help="Mechanism name or path to a .toml file with a [free_motion] section.")],
    duration: Annotated[
        Optional[float],
        typer.Option("--duration", help="Simulated time, s (default: the file's [free_motion] duration)."),
    ] = None,
    branch: Annotated[
        Optional[str], typer.Option("--branch", help="Assembly branch (default: the file's first).")
    ] = None,
    engines: Annotated[
        Optional[str],
        typer.Option(
            "--engines",
            metavar="MODE[,MODE…]",
            help="Free-motion modes to run besides the native reference (default: all; `native` alone: none), "
            "or an engine's name.",
        ),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON in SI units.")] = False,
    out: Annotated[
        Optional[Path],
        typer.Option("--out", help="Directory of the Markdown report (default: reports/ beside the models directory)."),
    ] = None,
    report: Annotated[bool, typer.Option("--report/--no-report", help="Write the Markdown report.")] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    models: ModelsOption = None,
    jobs: Annotated[
        Optional[int],
        typer.Option(
            "--jobs",
            "-j",
            help="Free modes run at once, each in its own process (default: one per CPU core; 1: one after "
            "another in this process). The results and the report are those of a serial run.",
            show_default=False,
        ),
    ] = None,
):
    """Release the mechanism to move freely under gravity, springs and loads, and integrate it exactly.

    The native reference: RK4 with accelerations by Gauss's principle and a
    projection onto the constraints after every step, at halving steps until
    two runs agree to the file's tolerance; their difference is the stated
    error. Singular positions passed, the loop closure and the energy balance
    are reported.

    Examples: xcheck simulate iftomm-a02;  xcheck simulate iftomm-a01 --duration 2 --json
    """
    from .report import update_index, write_simulation_report
    from .simulation import simulate_all

    modes = select_modes(engines, kinds=("free",))[1:]  # native always runs
    jobs = arguments.processes(jobs, "--jobs")
    if duration is not None:
        arguments.duration(duration, "--duration")
    path = model_path(name, models_dir(models))
    kin = Kinematics(load_mechanism(path))
    kin.assemble(branch)
    if report:  # what is in the report's way is said before the work, not after
        from .report import claim_index, claim_report

        claim_report(reports_dir(path, out), kin.mechanism.name)
        claim_index(reports_dir(path, out))
    bar = _progress_bar(quiet or as_json)
    with bar:
        # one step for the native reference (its step ladder in the description), one per mode
        task = bar.add_task(f"{kin.mechanism.name}: native", total=1 + len(modes))

        def progress(what: str) -> None:
            if not what.startswith("native:"):  # a mode starts: the stage before it is done
                bar.advance(task)
            bar.update(task, description=f"{kin.mechanism.name}: {what}")

        result = simulate_all(kin, modes, duration, branch, progress=progress, jobs=jobs)
    reference = result.reference
    failure, written = None, None
    if report:
        target = reports_dir(path, out)
        command = (
            f"xcheck simulate {_shown_model(name)}"
            + (f" --duration {duration:g}" if duration else "")
            + (f" --engines {engines}" if engines else "")
            + (f" --branch {branch}" if branch else "")
            + _shown_option("--models", models)
            + _shown_option("--out", out)
        )
        try:  # a report that cannot be written is one line; the results still print
            written, entry = write_simulation_report(result, target, command)
            update_index(target, [entry], indexed_names(path))
        except XcheckError as err:
            failure = str(err)
        except OSError as err:
            failure = f"{target}: expected a directory where the report can be written, found {err.strerror or err}"
    if as_json:
        typer.echo(json.dumps(simulation_json(reference, result), indent=2, allow_nan=False, ensure_ascii=False))
    else:
        print_simulation(wide_console(), reference, result, None if written is None else _shown_path(Path(written)))
    if failure is not None:
        raise InputError(failure)
    if not reference.converged:
        typer.echo(
            f"xcheck: the reference did not reach the tolerance ({reference.tolerance:g} of the size)"
            f": {reference.relative:.3g} at the finest step {reference.motion.step:.3g} s",
            err=True,
        )
        raise typer.Exit(1)


@app.command("export")
@_reports_errors
def export_command(
    names: Annotated[
        Optional[list[str]], typer.Argument(help="Mechanisms to export (default: all in the models directory).")
    ] = None,
    fmt: Annotated[
        str,
        typer.Option(
            "--format",
            help="mjcf (MuJoCo), urdf (Pinocchio/ROS, with its loops file), sdf (Drake, loops included), "
            "exudyn (a script of the system exudyn-free integrates; files with [free_motion]), or all.",
        ),
    ] = "all",
    check: Annotated[
        bool,
        typer.Option(
            "--check",
            help="Write nothing; list each file that is missing or differs from what would be written beyond the "
            "precision of its numbers (12 significant digits), with the first value that moved; exit 1 if any.",
        ),
    ] = False,
    models: ModelsOption = None,
):
    """Write the engine model files (models/mjcf/NAME.xml, models/urdf/NAME.urdf, models/sdf/NAME.sdf,
    models/benchmarks/exudyn/NAME.py) from the mechanism files and the benchmarks.

    Computed numbers are written to 12 significant digits of their scale (a
    length's: the mechanism's size), so every machine writes the same text; a
    file that agrees with what would be written within that precision is left
    as it is. Each file is written whole or not at all (a temporary file
    renamed). A mechanism that cannot be exported is reported in one line on
    stderr (file, field, expected, found) and the others are still exported;
    the exit code is then 2. A format that does not apply to a mechanism (an
    Exudyn script needs [free_motion], Drake's SDF no pin-in-slot) or whose
    engine is not installed is skipped, said so in one line. With --check,
    each file is listed as "missing" or "stale", a stale one with the first
    line or value that moved.

    Examples: xcheck export;  xcheck export fourbar --format mjcf;  xcheck export --check
    """
    directory = models_dir(models)
    writers = registry.exporters()
    formats = list(writers) if fmt == "all" else [fmt]
    for f in formats:
        if f not in writers:
            raise InputError(f"--format: expected one of {', '.join(writers)} or all, found {f!r}")
    outdated, failed = [], 0
    every = [*model_names(directory), *(str(directory / BENCHMARKS / f"{b}.toml") for b in benchmark_names(directory))]
    for name in names or every:
        try:
            path = model_path(name, directory)
            kin = Kinematics(load_mechanism(path))
        except XcheckError as err:
            typer.echo(f"xcheck: error: {' '.join(str(err).split())}", err=True)
            failed += 1
            continue
        for f in formats:
            writer = writers[f]
            subdirectory = writer.export_directory or f
            try:
                if writer.available():
                    raise registry.NotApplicable(writer.available())
                with canonical_numbers() as units:  # the same text on every machine
                    texts = writer.export_files(kin)
            except registry.NotApplicable as err:  # the engine cannot hold it, or is not installed: no file
                typer.echo(f"skipped {f} of {kin.mechanism.name}: {err.reason}")
                continue
            except XcheckError as err:
                typer.echo(f"xcheck: error: {f}: {' '.join(str(err).split())}", err=True)
                failed += 1
                continue
            for file_name, text in texts.items():
                # a bundled file of an installed package exports into ./models, not into the package
                target = (Path("models") if installed(path) else path.parent) / subdirectory / file_name
                current = target.read_text(encoding="utf-8") if target.is_file() else None
                moved = None if current is None else drift(current, text, units)
                if current is not None and moved is None:  # the same, within the precision of its numbers
                    continue
                if check:
                    outdated.append(("missing", target, "") if moved is None else ("stale", target, f": {moved}"))
                    continue
                try:
                    write_atomic(target, text)
                except OSError as err:
                    typer.echo(
                        f"xcheck: error: {target}: expected a file that can be written, found {err.strerror or err}",
                        err=True,
                    )
                    failed += 1
                    continue
                typer.echo(f"wrote {target}")
    for state, target, why in outdated:
        typer.echo(f"{state}: {target}{why}")
    if failed:
        raise typer.Exit(2)
    if outdated:
        raise typer.Exit(1)


def _numbers(text: str, mech: Mechanism, option: str) -> list[list[float]]:
    """An option's text as numbers: states separated by commas, each the drivers'
    values separated by colons, each a number or an arithmetic expression; the
    values as given (display units: :func:`xcheck.states.asked_states` converts
    and checks them)."""
    states = []
    for item in text.split(","):
        parts = item.split(":")
        if len(parts) != len(mech.drivers):
            raise InputError(
                f"{mech.path}: {option}: expected {len(mech.drivers)} value(s) per state separated "
                f"by ':' ({':'.join(d.name for d in mech.drivers)}), found {arguments.shown(item)}"
            )
        state = []
        for driver, part in zip(mech.drivers, parts):
            try:
                state.append(evaluate_expression(part.strip()))
            except ValueError as err:
                raise InputError(
                    f"{mech.path}: {option} {driver.name}: expected a number or an arithmetic "
                    f"expression, found {arguments.shown(part)} ({err})"
                ) from None
        states.append(state)
    return states


@app.command("fuzz")
@_reports_errors
def fuzz_command(
    count: Annotated[int, typer.Option("--count", help="Random mechanisms to generate (1 to 100000).")] = 100,
    seed: Annotated[
        int,
        typer.Option("--seed", help="The campaign's seed (0 to 2**63 - 1): the same seed, the same mechanisms."),
    ] = 0,
    kinds: Annotated[
        str, typer.Option("--kinds", help="Comma-separated kinds: fourbar, slider-crank, scotch-yoke.")
    ] = "fourbar,slider-crank,scotch-yoke",
    engines: Annotated[
        Optional[str],
        typer.Option(
            "--engines",
            help="Comma-separated modes or groups (default: those of `xcheck run` but mjx-dynamic, "
            "whose compilation for every random mechanism would cost four times the rest).",
        ),
    ] = None,
    samples: Annotated[int, typer.Option("--samples", help=f"Samples of the sweeps (3 to {MAX_SAMPLES}).")] = 181,
    scheduler: Annotated[
        Optional[str], typer.Option("--scheduler", help="Address of a Dask scheduler (default: a local process pool).")
    ] = None,
    workers: Annotated[
        Optional[int], typer.Option("--workers", help="Local worker processes (default: the CPU count).")
    ] = None,
    out: Annotated[Path, typer.Option("--out", help="Output folder: cases/, results/ (Parquet), failures.md.")] = Path(
        "fuzz"
    ),
):
    """Run every mode on random mechanisms; one Parquet row per mechanism and mode.

    Rerunning with the same --out skips the cases done; it must ask for the same
    --kinds, --engines and --samples (OUT/campaign.json keeps them). A file in OUT
    that xcheck did not write is never replaced: the campaign stops before it
    starts. Exit code 0 when no mode failed, 1 when any did (see OUT/failures.md:
    each class with a reproducer file), 2 for bad input.

    Examples: xcheck fuzz --count 40 --seed 1;  xcheck fuzz --count 5000 --scheduler tcp://host:8786 --out big
    """
    from . import fuzz as campaign

    arguments.whole_number(count, "--count", 1, campaign.MAX_CASES)
    arguments.seed(seed, "--seed")
    arguments.samples(samples, "--samples")
    workers = arguments.processes(workers, "--workers")
    chosen = campaign.chosen_kinds(kinds, "--kinds")
    modes = campaign.campaign_modes() if engines is None else select_modes(engines)
    arguments.writable_directory(out, "--out", "the campaign")
    progress = _progress_bar(False, label="fuzz", stdout_terminal=False)  # a long campaign: shown even when piped
    with progress:
        task = progress.add_task("", total=None)

        def step(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        rows = campaign.fuzz(out, count, seed, chosen, modes, samples, workers, scheduler, progress=step)
    rows = rows[rows.seed == seed]
    rows = rows[rows["index"] < count]
    command = f"xcheck fuzz --count {count} --seed {seed} --kinds {','.join(chosen)}" + (
        f" --engines {engines}" if engines else ""
    )
    campaign.write_failure_report(out, rows, command)
    table = Table(title=f"xcheck fuzz: {rows.case.nunique()} cases (seed {seed})")
    for column in ("mode", "cases", "passed", "failed", "error", "not applicable"):
        table.add_column(column, justify="left" if column == "mode" else "right")
    counts = campaign.summary(rows)
    for _, r in counts.iterrows():
        table.add_row(
            escape(str(r["mode"])), *(str(r[c]) for c in ("cases", "passed", "failed", "error", "not applicable"))
        )
    console = Console()
    console.print(table)
    console.print(f"Rows: {escape(str(out / 'results'))}; failure classes: {escape(str(out / 'failures.md'))}")
    if int(counts.failed.sum() + counts.error.sum()):
        raise typer.Exit(1)


def _escape_help_markup(application: typer.Typer) -> None:
    """Escape the help texts of every command and parameter for the terminal's
    renderer, which reads square brackets as markup ("of [units]" showed as "of ").

    Typer renders help with rich markup; xcheck's help is plain text, so each
    text is escaped once here rather than at each of its many definitions."""
    import inspect
    from typing import get_type_hints

    from typer.models import ParameterInfo

    done: set[int] = set()  # Annotated options shared by several commands are escaped once
    for info in [application.registered_callback, *application.registered_commands]:
        if info is None or info.callback is None:
            continue
        if info.help is None and info.callback.__doc__:
            info.help = escape(inspect.cleandoc(info.callback.__doc__))
        # typer evaluates the (string) annotations anew each time it builds the
        # command: they are evaluated once here, so that the escaped texts stay
        function = inspect.unwrap(info.callback)
        function.__annotations__ = hints = get_type_hints(function, include_extras=True)
        for hint in hints.values():
            for meta in getattr(hint, "__metadata__", ()):
                if isinstance(meta, ParameterInfo) and meta.help and id(meta) not in done:
                    done.add(id(meta))
                    meta.help = escape(meta.help)


_escape_help_markup(app)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
