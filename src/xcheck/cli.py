"""The command line: it parses each command's options, calls the functions below
it (:mod:`xcheck.states`, :mod:`xcheck.batch`, :mod:`xcheck.api`) and prints."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console

from . import arguments, cache
from . import engines as registry
from ._command_line import (
    OneLineUsageErrors,
    escape_help_markup,
    print_version,
    progress_bar,
    reports_errors,
    route_loggers,
)
from .api import printed_answers, select_modes
from .arguments import DEFAULT_SAMPLES, MAX_SAMPLES
from .batch import (
    RunSettings,
    export_models,
    list_models,
    reference_notes,
    replay_options,
    run_models,
    shown_model,
    shown_path,
    simulate_model,
)
from .catalog import benchmark_names, model_names, model_path, models_dir, reports_dir
from .errors import InputError, XcheckError
from .model import load_mechanism
from .output import (
    print_fuzz,
    print_list,
    print_run,
    print_run_totals,
    print_simulation,
    print_solution,
    print_textbook,
    run_json,
    simulation_json,
    solution_json,
    textbook_json,
    wide_console,
)
from .states import drawn_state, reactions_of, solve_asked, states_asked, values_of_text

__all__ = ["app", "main"]


app = typer.Typer(
    cls=OneLineUsageErrors,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Exact kinematics of planar mechanisms, cross-checked against physics engines.",
)

ModelsOption = Annotated[
    Optional[Path],
    typer.Option("--models", help="Directory of mechanism files (default: ./models, or $XCHECK_MODELS)."),
]
BranchOption = Annotated[Optional[str], typer.Option("--branch", help="Assembly branch (default: the file's first).")]
ComparisonsOption = Annotated[
    Optional[Path],
    typer.Option(
        "--comparisons",
        help="Directory of printed textbook answers (default: comparisons/ beside "
        "the models directory, or $XCHECK_COMPARISONS).",
    ),
]


def _echo_json(document) -> None:
    """A command's JSON on stdout: indented, UTF-8, no NaN (an unanswered value is null)."""
    typer.echo(json.dumps(document, indent=2, allow_nan=False, ensure_ascii=False))


@app.callback()
def _main(
    version: Annotated[
        bool, typer.Option("--version", callback=print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
):
    """Exact kinematics of planar mechanisms, cross-checked against physics engines."""
    route_loggers()


@app.command("list")
@reports_errors
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
    rows, failures = list_models(paths)
    if as_json:
        _echo_json(rows)
    else:
        print_list(wide_console(), rows, benchmarks)
    for failure in failures:
        typer.echo(f"xcheck: error: {failure}", err=True)
    if failures:
        raise typer.Exit(2)


@app.command("engines")
@reports_errors
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
    from .output import engine_rows, print_engines

    rows = engine_rows()
    problems = registry.load_problems()
    if as_json:
        _echo_json({"engines": rows, "plugin_errors": problems})
        return
    print_engines(wide_console(), rows)
    for name, reason in problems.items():
        typer.echo(f"xcheck: error: entry point {name!r} of group {registry.ENTRY_POINT_GROUP!r}: {reason}", err=True)


@app.command("cache")
@reports_errors
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
        _echo_json({**found, **({} if removed is None else {"removed": removed})})
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
@reports_errors
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
    branch: BranchOption = None,
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
    options = ("--at", "--rate", "--accel")
    given = (None if text is None else values_of_text(text, mech, o) for text, o in zip((at, rate, accel), options))
    values, rates, accels = given
    kin = cache.cached_kinematics(mech)
    kin.assemble(branch)
    asked = states_asked(kin, values, rates, accels, options=options)
    if at is not None:
        asked.labels = [f"at {label}" for label in asked.labels]
    try:
        solved = solve_asked(kin, asked, branch)
    finally:
        cache.store(kin)  # the feasible range, refused input or not
    solution, labels = solved.solution, solved.labels
    warned = solved.warnings
    for line in warned:  # before the numbers that explode there
        typer.echo(f"xcheck: warning: {line}", err=True)
    # reactions where the file gives mass data, and printed answers: a fault in
    # either is reported after the solution, which still prints
    forces, forces_error = reactions_of(solution)
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
        _echo_json(output)
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
@reports_errors
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
    branch: BranchOption = None,
    models: ModelsOption = None,
):
    """Draw the mechanism at an input as a PNG, without running any engine.

    Bodies are drawn as links between their joints, blocks on prismatic joints,
    pins in their slots, the ground hatched, the points labelled and the inputs'
    directions as arrows (from the drivers' motion laws).

    Examples: xcheck draw fourbar;  xcheck draw task-2-1 --at 40 -o task.png
    """
    from .drawing import check_png_name, figure_of, save_png

    path = model_path(name, models_dir(models))
    mech = load_mechanism(path)
    kin = cache.cached_kinematics(mech)
    kin.assemble(branch)
    cache.store(kin)
    target = output if output is not None else Path(f"{mech.name}.png")
    check_png_name(target, "-o")
    values = None if at is None else values_of_text(at, mech, "--at")
    save_png(figure_of(drawn_state(kin, values, branch=branch, option="--at"), 0), target, "-o")
    typer.echo(str(target))


@app.command("run")
@reports_errors
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
    ] = DEFAULT_SAMPLES,
    branch: BranchOption = None,
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
            help="Processes at once (default: $XCHECK_JOBS, or one per CPU core): with several mechanisms, "
            "one mechanism each; with one, one mode each. 1: everything one after another in this process. "
            "The results and reports are those of a serial run.",
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
    modes = select_modes(engines)
    directory = models_dir(models)
    names = model_names(directory) if name == "all" else [name]
    if out is not None and out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: expected a directory for the reports, found a file")
    options = replay_options(
        ("--engines", engines), ("--samples", None if samples == DEFAULT_SAMPLES else samples), ("--branch", branch),
        ("--models", models), ("--comparisons", comparisons), ("--out", out), ("--no-gif", not gif),
    )  # fmt: skip
    settings = RunSettings(directory, modes, samples, branch, comparisons, report, out, options, gif, use_cache)
    progress = progress_bar(quiet or as_json)
    with progress:
        task = progress.add_task("", total=len(names) * len(modes))
        batch = run_models(
            names,
            settings,
            jobs,
            step=lambda label, mode: progress.update(task, description=f"{label}: {mode}", advance=1),
            done=lambda: progress.update(task, advance=len(modes)),
        )
    results, failures = batch.results, batch.failures
    if as_json:
        documents = [run_json(r) for r in results]
        if name == "all" or documents:
            _echo_json(documents if name == "all" else documents[0])
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
    if batch.exit_code:
        raise typer.Exit(batch.exit_code)


@app.command("simulate")
@reports_errors
def simulate_command(
    name: Annotated[str, typer.Argument(help="Mechanism name or path to a .toml file with a [free_motion] section.")],
    duration: Annotated[
        Optional[float],
        typer.Option("--duration", help="Simulated time, s (default: the file's [free_motion] duration)."),
    ] = None,
    branch: BranchOption = None,
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
    check: Annotated[
        bool,
        typer.Option(
            "--check/--no-check",
            help="Check the reference by the second native method (Gauss-Legendre collocation of order 8 at "
            "halving steps) and report how closely the two agree.",
        ),
    ] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    models: ModelsOption = None,
    jobs: Annotated[
        Optional[int],
        typer.Option(
            "--jobs",
            "-j",
            help="Free modes run at once, each in its own process (default: $XCHECK_JOBS, or one per CPU "
            "core; 1: one after another in this process). The results and the report are those of a serial run.",
            show_default=False,
        ),
    ] = None,
):
    """Release the mechanism to move freely under gravity, springs and loads, and integrate it exactly.

    The native reference: DOP853 (order 8, error control, dense output) with
    accelerations by Gauss's principle and a projection onto the constraints
    after every step, at local tolerances a tenth of the last until two runs
    agree to the file's tolerance; their difference plus the measured round-off
    is the stated error, checked by Gauss-Legendre collocation (order 8, halving
    steps). Singular passes, loop closure and the energy balance are reported.

    Exit codes: 0 when the reference met its tolerance (and, checked, the two
    methods agree within their stated errors); 1 when it did not, or they
    disagree (the report and the JSON are still written); 2 for bad input, a
    --duration that is not a whole number of output steps, or a motion no run can
    follow within the work budget.

    Examples: xcheck simulate iftomm-a02;  xcheck simulate iftomm-a01 --duration 2 --json
    """
    modes = select_modes(engines, kinds=("free",))[1:]  # native always runs
    jobs = arguments.processes(jobs, "--jobs")
    if duration is not None:
        arguments.duration(duration, "--duration")
    path = model_path(name, models_dir(models))
    command = f"xcheck simulate {shown_model(name)}" + replay_options(
        ("--duration", f"{duration:g}" if duration else None), ("--engines", engines), ("--branch", branch),
        ("--models", models), ("--out", out), ("--no-check", not check),
    )  # fmt: skip
    bar = progress_bar(quiet or as_json)
    with bar:
        # one step for the native reference (its step ladder in the description), one per mode
        task = bar.add_task(f"{path.stem}: native", total=1 + len(modes))

        def progress(what: str) -> None:
            if not what.startswith("native:"):  # a mode starts: the stage before it is done
                bar.advance(task)
            bar.update(task, description=f"{path.stem}: {what}")

        result, written, failure = simulate_model(
            path, modes, duration, branch, report, out, command, progress=progress, jobs=jobs, check=check
        )
    reference = result.reference
    if as_json:
        _echo_json(simulation_json(reference, result))
    else:
        print_simulation(wide_console(), reference, result, None if written is None else shown_path(Path(written)))
    if failure is not None:
        raise InputError(failure)
    notes, code = reference_notes(reference)
    for note in notes:
        typer.echo(f"xcheck: {note}", err=True)
    if code:
        raise typer.Exit(code)


@app.command("export")
@reports_errors
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
    failed = outdated = False
    for kind, text in export_models(names, formats, directory, check):
        if kind == "error":
            typer.echo(f"xcheck: error: {text}", err=True)
        else:
            typer.echo(f"{kind}{':' if kind in ('missing', 'stale') else ''} {text}")
        failed = failed or kind == "error"
        outdated = outdated or kind in ("missing", "stale")
    if failed:
        raise typer.Exit(2)
    if outdated:
        raise typer.Exit(1)


@app.command("fuzz")
@reports_errors
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
    samples: Annotated[
        int, typer.Option("--samples", help=f"Samples of the sweeps (3 to {MAX_SAMPLES}).")
    ] = DEFAULT_SAMPLES,
    scheduler: Annotated[
        Optional[str], typer.Option("--scheduler", help="Address of a Dask scheduler (default: a local process pool).")
    ] = None,
    workers: Annotated[
        Optional[int], typer.Option("--workers", help="Local worker processes (default: $XCHECK_JOBS, or one per CPU).")
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
    progress = progress_bar(False, label="fuzz", stdout_terminal=False)  # a long campaign: shown even when piped
    with progress:
        task = progress.add_task("", total=None)

        def step(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        rows = campaign.fuzz(out, count, seed, chosen, modes, samples, workers, scheduler, progress=step)
    rows = rows[(rows.seed == seed) & (rows["index"] < count)]
    command = f"xcheck fuzz --count {count} --seed {seed} --kinds {','.join(chosen)}" + (
        f" --engines {engines}" if engines else ""
    )
    campaign.write_failure_report(out, rows, command)
    counts = campaign.summary(rows)
    print_fuzz(Console(), counts, f"xcheck fuzz: {rows.case.nunique()} cases (seed {seed})", out)
    if int(counts.failed.sum() + counts.error.sum()):
        raise typer.Exit(1)


escape_help_markup(app)


def main() -> None:
    """Console-script entry point (:func:`xcheck._parallel.run_as_command`)."""
    from ._parallel import run_as_command

    run_as_command(app)


if __name__ == "__main__":  # pragma: no cover
    main()
