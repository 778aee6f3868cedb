"""Many mechanisms at a time, below the command line: the work of ``xcheck list``,
``run``, ``simulate`` (with its report) and ``export``, for scripts too.

Each function takes checked arguments (:mod:`xcheck.arguments`), does the work
and returns what a caller prints; a bad file among many is one failure line
and the others go on. The command line only parses its options, calls these
and prints.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import cache
from .catalog import BENCHMARKS, benchmark_names, indexed_names, installed, model_names, model_path, reports_dir
from .errors import NotApplicable, XcheckError
from .fileio import write_atomic
from .kinematics import Kinematics
from .model import load_mechanism
from .motion import drive_warnings

if TYPE_CHECKING:
    from .runner import RunResult
    from .simulation import SimulationResult
    from .textbook import Comparisons

__all__ = [
    "RunSettings",
    "RunBatch",
    "list_models",
    "run_models",
    "run_model",
    "simulate_model",
    "reference_notes",
    "export_models",
    "shown_path",
    "shown_model",
    "replay_options",
]


def shown_path(path: Path) -> str:
    """A path as a command line would give it: relative to the working
    directory when it lies below it, else as it is."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def shown_model(name: str) -> str:
    """A mechanism argument (a name, 'all' or a path) as a reproducible command line gives it."""
    return shown_path(Path(name)) if Path(name).suffix == ".toml" or "/" in name else name


def replay_options(*options: tuple[str, object]) -> str:
    """`` OPTION VALUE`` for each (option, value) a reproducing command line
    repeats: a path as :func:`shown_path`, True as the bare option; a value of
    None or False is left out."""
    parts = []
    for option, value in options:
        if value is None or value is False:
            continue
        shown = shown_path(value) if isinstance(value, Path) else str(value)
        parts.append(f" {option}" if value is True else f" {option} {shown}")
    return "".join(parts)


# -- list -----------------------------------------------------------------------------


def list_models(paths: list[Path]) -> tuple[list[dict[str, Any]], list[str]]:
    """Each mechanism file's name, title, source, file, degrees of freedom, its
    drivers' feasible ranges (:func:`xcheck.output.range_json`) and the warnings
    about its drivers' laws; the branch maps cached. Returns (rows, failure lines)."""
    from .output import range_json

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
                "ranges": [range_json(kin, rng) for rng in ranges],
                "warnings": warned,
            }
        )
    return rows, failures


# -- run ------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSettings:
    """What every mechanism of a batch of runs shares.

    Attributes
    ----------
    directory : Path
        The models directory names are looked up in.
    modes : tuple of str
        :func:`xcheck.api.select_modes`'s.
    samples : int
    branch : str or None
    comparisons : Path or None
        The printed answers' directory (None: beside the models).
    report : bool
        Write each mechanism's report (and the index).
    out : Path or None
        The reports' directory (None: reports/ beside the models).
    options : str
        The options a report's reproducing command line repeats after the name.
    gif : bool
        The report's animated GIF.
    use_cache : bool
        Read and write the branch maps and the results cache.
    """

    directory: Path
    modes: tuple[str, ...]
    samples: int
    branch: str | None = None
    comparisons: Path | None = None
    report: bool = False
    out: Path | None = None
    options: str = ""
    gif: bool = True
    use_cache: bool = True


@dataclass
class RunBatch:
    """The runs of a batch, in the order of the names, and one line per failure
    (a bad file, a report or an index that could not be written)."""

    results: list[RunResult] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """2 where a file failed, else the worst of the runs' verdicts' codes
        (:data:`xcheck.runner.EXIT_CODES`), 0 for none."""
        from .runner import EXIT_CODES

        return 2 if self.failures else max((EXIT_CODES[r.verdict] for r in self.results), default=0)


def run_model(model: str, settings: RunSettings, step=None, jobs: int = 1):
    """One mechanism of a batch: its comparison, its modes in ``jobs``
    processes, and, if the settings say so, its report. Returns (the run or
    None, (reports directory, file, index entry) or None, failure lines).
    ``step(label, stage)`` is told of each stage (left out in a worker process)."""
    from .runner import run_mechanism
    from .textbook import comparisons_of

    s = settings

    def tell(label: str, stage: str) -> None:
        if step is not None:
            step(label, stage)

    try:  # one bad file is reported at the end; the others run
        path = model_path(model, s.directory)
        mechanism = load_mechanism(path)
        kin = cache.cached_kinematics(mechanism) if s.use_cache else Kinematics(mechanism)
        kin.assemble(s.branch)
        label = kin.mechanism.name
        if s.report:  # what is in the report's way is said before the work, not after
            from .report import claim_index, claim_report, leaves_out

            claim_report(reports_dir(path, s.out), label, partial=leaves_out(s.modes))
            claim_index(reports_dir(path, s.out))
        answers = _PrintedAnswers(kin, comparisons_of(kin.mechanism, s.comparisons))  # a bad file stops it here
        run = run_mechanism(
            kin, s.modes, s.samples, s.branch, progress=lambda mode: tell(label, mode), jobs=jobs,
            cache=s.use_cache, meanwhile=answers.meanwhile,
        )  # fmt: skip
        run.textbook = answers.checked()
        if s.use_cache:
            cache.store(kin)
    except XcheckError as err:
        for _ in s.modes:  # the progress bar's share of the file's modes
            tell(model, "failed")
        return None, None, [str(err)]
    tell(label, "report" if s.report else "done")  # native
    if not s.report:
        return run, None, []
    from .report import write_report

    target = reports_dir(path, s.out)
    try:  # a report that cannot be written is reported; the run's results still count
        _, entry = write_report(run, target, f"xcheck run {shown_model(model)}{s.options}", gif=s.gif, jobs=jobs)
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


class _PrintedAnswers:
    """A mechanism's printed answers (``printed``: its comparisons file, read, or None),
    computed by :meth:`meanwhile`, where the run calls it, while the workers run the
    modes, which do not need them, else by :meth:`checked`."""

    def __init__(self, kinematics: Kinematics, printed: Comparisons | None):
        self.kinematics, self.printed = kinematics, printed
        self.answers: list[dict] | XcheckError | None = None

    def meanwhile(self) -> None:
        """Compute the answers (an error in them kept for :meth:`checked`)."""
        from .textbook import check_printed

        try:
            self.answers = [] if self.printed is None else check_printed(self.kinematics, self.printed)
        except XcheckError as err:  # said once the modes are back, which the cache keeps
            self.answers = err

    def checked(self) -> list[dict]:
        """The printed answers checked (:func:`xcheck.textbook.check_printed`).

        Raises
        ------
        XcheckError
            Where an answer's instant cannot be solved."""
        if self.answers is None:
            self.meanwhile()
        if isinstance(self.answers, XcheckError):
            raise self.answers
        assert self.answers is not None  # computed above
        return self.answers


def run_models(
    names: list[str],
    settings: RunSettings,
    jobs: int = 1,
    step: Callable[[str, str], None] | None = None,
    done: Callable[[], None] | None = None,
) -> RunBatch:
    """:func:`run_model` for each name, then the reports' indexes.

    One mechanism runs its modes in ``jobs`` processes; several run one
    mechanism per worker process (:mod:`xcheck._parallel`), the outcomes in the order
    of ``names`` whatever the order they finish in, so that the results and
    the reports are those of a serial run. A mechanism whose worker died is one
    failure line and the others still count. Engines registered at run time
    (:func:`xcheck.engines.register`) exist only in this process: run them with
    ``jobs=1``. ``step(label, stage)`` is told of each stage in a serial run,
    ``done()`` of each mechanism a worker finished.
    """
    if min(jobs, len(names)) <= 1:
        from ._parallel import start_workers, workers_kept
        from .runner import worth_workers

        with workers_kept():  # one mechanism: the workers of its modes draw its report's figures
            if len(names) == 1 and worth_workers(settings.modes, jobs) and _all_cached(names[0], settings) is False:
                # they start while this process loads the mechanism and solves it
                start_workers(min(jobs, sum(mode != "native" for mode in settings.modes)), preload=_figures(settings))
            outcomes = [run_model(name, settings, step, jobs if len(names) == 1 else 1) for name in names]
    else:
        outcomes = _run_in_pool(names, settings, jobs, done or (lambda: None))
    batch = RunBatch()
    entries = []
    for run, entry, problems in outcomes:
        batch.failures += problems
        if entry is not None:
            entries.append(entry)
        if run is not None:
            batch.results.append(run)
    if entries:
        from .report import update_index

        for target in dict.fromkeys(t for t, _, _ in entries):
            model_file = next(f for t, f, _ in entries if t == target)
            try:
                update_index(target, [e for t, _, e in entries if t == target], indexed_names(model_file))
            except XcheckError as err:
                batch.failures.append(str(err))
    return batch


def _run_in_pool(names: list[str], settings: RunSettings, jobs: int, done: Callable[[], None]) -> list:
    """:func:`run_model` for each name: in worker processes, but a mechanism whose
    every result is in the results cache runs here while the workers compute
    the others (its run takes a tenth of a second, a worker's start a second);
    the outcomes in the order of the names."""
    import contextlib

    from ._parallel import collect, process_pool, submit

    def failed(index: int, reason: str) -> tuple:
        return None, None, [f"{names[index]}: expected its run back from a worker process, found that {reason}"]

    here = [i for i, name in enumerate(names) if _all_cached(name, settings)]
    away = [i for i in range(len(names)) if i not in here]
    if len(away) < 2:
        here, away = list(range(len(names))), []
    outcomes = {}
    with contextlib.ExitStack() as stack:
        if away:
            calls = {i: (run_model, (names[i], settings)) for i in away}
            pool = stack.enter_context(process_pool(min(jobs, len(away)), _figures(settings)))
            futures = submit(pool, calls)
        for i in here:  # where it is the one mechanism not in the cache: its modes in worker processes
            outcomes[i] = run_model(names[i], settings, jobs=1 if away else jobs)
            done()
        if away:
            outcomes.update(collect(futures, failed, lambda _: done(), calls, jobs))
    return [outcomes[i] for i in range(len(names))]


#: the module of the reports' figures (with matplotlib: about 0.3 CPU s to import), which the
#: workers that will draw them import ahead (:func:`xcheck._parallel.start_workers`'s ``preload``)
_FIGURES = "xcheck.report._figures"


def _figures(settings: RunSettings) -> tuple[str, ...]:
    """The reports' figures module where a worker process will draw some (with reports),
    else none: what a fork server imports ahead (:func:`xcheck._parallel.process_pool`)."""
    return (_FIGURES,) if settings.report else ()


def _all_cached(model: str, settings: RunSettings) -> bool | None:
    """Whether the results cache holds every mode's results of ``model``
    (:func:`xcheck.result_cache.holds`; False with the cache off); None for a
    file that does not load (its run says why)."""
    from .result_cache import holds

    try:
        mechanism = load_mechanism(model_path(model, settings.directory))
        return settings.use_cache and holds(mechanism, settings.modes, settings.samples, settings.branch)
    except (XcheckError, OSError):
        return None


# -- simulate -------------------------------------------------------------------------


def simulate_model(
    path: Path,
    modes: tuple[str, ...],
    duration: float | None = None,
    branch: str | None = None,
    report: bool = True,
    out: Path | None = None,
    command: str = "",
    progress=None,
    jobs: int = 1,
    check: bool = True,
) -> tuple[SimulationResult, Path | None, str | None]:
    """A mechanism's free motion (:func:`xcheck.simulation.simulate_all`; ``check``: the
    reference checked by the second native method) and, if ``report``, its report (with
    ``command``, the line that reproduces it) and the index. Returns (the result, the
    report's path or None, a line saying why the report could not be written, or None):
    the results stand either way."""
    from . import engines
    from ._parallel import known_to_workers, start_workers, workers_kept
    from .dynamics._reference import free_duration
    from .runner import worth_workers
    from .simulation import simulate_all

    kin = Kinematics(load_mechanism(path))
    seconds = free_duration(kin, duration, "--duration")  # one line before any work where it is off the outputs
    with workers_kept():
        away = [mode for mode in modes if known_to_workers(mode) and not engines.engine_of(mode).available()]
        if worth_workers(away, jobs, seconds):  # they start while this process solves the reference
            start_workers(min(jobs, len(away)), ("xcheck.simulation",))
        kin.assemble(branch)
        target = reports_dir(path, out)
        if report:  # what is in the report's way is said before the work, not after
            from .report import claim_index, claim_report, leaves_out

            claim_report(target, kin.mechanism.name, partial=leaves_out(modes, ("free",)))
            claim_index(target)
        drawn: dict[str, bytes] = {}

        def meanwhile(partial) -> None:  # the reference's figures while the workers run the modes
            if report:
                from .report import reference_figures

                drawn.update(reference_figures(partial))

        result = simulate_all(
            kin, modes, duration, branch, progress=progress, jobs=jobs, check=check, meanwhile=meanwhile
        )
    if not report:
        return result, None, None
    from .report import update_index, write_simulation_report

    try:  # a report that cannot be written is one line; the results still stand
        written, entry = write_simulation_report(result, target, command, drawn)
        update_index(target, [entry], indexed_names(path))
    except XcheckError as err:
        return result, None, str(err)
    except OSError as err:
        return (
            result,
            None,
            f"{target}: expected a directory where the report can be written, found {err.strerror or err}",
        )
    return result, Path(written), None


# -- export ---------------------------------------------------------------------------


def reference_notes(reference) -> tuple[list[str], int]:
    """What a user is told of a free-motion reference beside its results: a
    line each where it did not reach its tolerance, where its check is
    inconclusive and where the two methods disagree; and the exit code, 1
    where it did not converge or they disagree, else 0."""
    notes = []
    if not reference.converged:
        notes.append(
            f"the {reference.method} reference did not reach the tolerance ({reference.tolerance:g} of "
            f"the size): stated {reference.relative:.3g} ({reference.basis.rsplit('; stopped: ', 1)[-1]})"
        )
    checked = reference.check
    disagree = checked is not None and checked.consistent is False
    if checked is not None and checked.consistent is None:
        notes.append(
            f"the {checked.reference.method} check is inconclusive: it or the reference did not reach "
            f"the tolerance, so their agreement ({checked.agreement.max(initial=0.0):.3g} m) judges neither"
        )
    if checked is not None and disagree:
        second = checked.reference
        notes.append(
            f"the {reference.method} reference and its {second.method} check disagree by "
            f"{checked.agreement.max():.3g} m, beyond their stated errors ({reference.estimate.max():.3g} "
            f"and {second.estimate.max():.3g} m)"
        )
    return notes, 1 if not reference.converged or disagree else 0


def export_models(
    names: list[str] | None, formats: list[str], directory: Path, check: bool = False
) -> Iterator[tuple[str, str]]:
    """Write (or, with ``check``, compare) each mechanism's engine files, the
    mechanisms and the benchmarks of ``directory`` where ``names`` is None.

    Yields (kind, text) as it goes: ``("wrote", path)``; ``("skipped", why)`` for
    a format that does not apply or whose engine is not installed;
    ``("missing", path)`` and ``("stale", "path: what moved")`` with ``check``;
    ``("error", line)`` for a mechanism, a format or a file that failed (the
    others go on). A file that agrees with what would be written within the
    precision of its numbers (:mod:`xcheck.precision`) is left as it is.
    """
    from . import engines as registry
    from .precision import canonical_numbers, drift

    writers = registry.exporters()
    every = [*model_names(directory), *(str(directory / BENCHMARKS / f"{b}.toml") for b in benchmark_names(directory))]
    outdated = []
    for name in names or every:
        try:
            path = model_path(name, directory)
            kin = Kinematics(load_mechanism(path))
            kin.assemble()  # a file that does not assemble is one error, not one per format
        except XcheckError as err:
            yield "error", " ".join(str(err).split())
            continue
        for f in formats:
            writer = writers[f]
            try:
                if writer.available():
                    raise NotApplicable(writer.available())
                with canonical_numbers() as units:  # the same text on every machine
                    texts = writer.export_files(kin)
            except NotApplicable as err:  # the engine cannot hold it, or is not installed: no file
                yield "skipped", f"{f} of {kin.mechanism.name}: {err.reason}"
                continue
            except XcheckError as err:
                yield "error", f"{f}: {' '.join(str(err).split())}"
                continue
            for file_name, text in texts.items():
                # a bundled file of an installed package exports into ./models, not into the package
                target = (
                    (Path("models") if installed(path) else path.parent) / (writer.export_directory or f) / file_name
                )
                current = target.read_text(encoding="utf-8") if target.is_file() else None
                moved = None if current is None else drift(current, text, units)
                if current is not None and moved is None:  # the same, within the precision of its numbers
                    continue
                if check:
                    outdated.append(("missing", str(target)) if moved is None else ("stale", f"{target}: {moved}"))
                    continue
                try:
                    write_atomic(target, text)
                except OSError as err:
                    yield "error", f"{target}: expected a file that can be written, found {err.strerror or err}"
                    continue
                yield "wrote", str(target)
    yield from outdated
