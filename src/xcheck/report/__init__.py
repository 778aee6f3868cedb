"""Markdown reports of comparison runs: reports/NAME.md with its figures and
its evidence in reports/NAME/, and reports/README.md indexing them.

The reports folder is shared with the user: xcheck writes and replaces only
files it can tell it wrote (:mod:`xcheck.fileio`: its mark in the Markdown, the
folder's manifest, the index's generator), and stops with one line naming
anything else in its way. A mechanism named as the index (README, index.json)
or another report (NAME.md) is refused when it is loaded.

A report is written as one unit: its figures, its evidence
(:mod:`._evidence`) and its Markdown are written into a fresh staging folder
beside the old one; nothing is replaced until all are written. Then the
staging folder replaces the old one and the Markdown, carried in it, is
renamed into place last (two renames). A run killed between those renames
leaves the new Markdown waiting in the new folder; the next writer, taking
the directory's file lock, first completes such a unit
(:func:`xcheck.fileio.complete_reports`) and removes what killed writers left.

A run of some modes (``--engines``) updates their parts of the report and
keeps the other modes' parts, marked with the run that produced them, and
any figure that shows them (:func:`._evidence.merge`).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..engines import DRIVEN_KINDS
from ..errors import InputError
from ..fileio import (
    MANIFEST,
    PENDING_MARKDOWN,
    RESERVED_NAMES,
    STAGING_MARK,
    claim,
    complete_reports,
    directory_lock,
    marked,
    read_json,
    remove_stale_staging,
    temporary_name,
    write_atomic,
)
from ..runner import RunResult
from ._evidence import Evidence, merge, produced, read_evidence
from ._markdown import (
    finding_names,
    index_markdown,
    mode_parts,
    passed,
    report_markdown,
    source_parts,
    textbook_text,
    worst_text,
)

__all__ = [
    "write_report",
    "write_simulation_report",
    "reference_figures",
    "claim_report",
    "claim_index",
    "leaves_out",
    "write_index",
    "read_index",
    "update_index",
    "INDEX_DATA",
]


def leaves_out(modes: Iterable[str], kinds: tuple[str, ...] = DRIVEN_KINDS) -> bool:
    """Whether a run of ``modes`` (of ``kinds``) leaves out modes a run without
    ``--engines`` runs: its report keeps theirs from an earlier one."""
    from ..api import select_modes

    return not set(select_modes(kinds=kinds)) - {"native"} <= set(modes)


@contextlib.contextmanager
def _writing(directory: Path, name: str, partial: bool) -> Iterator[None]:
    """Hold the directory's lock, with what killed writers left completed or
    removed, and the report's files claimed (:func:`claim_report`)."""
    with directory_lock(directory):
        complete_reports(directory)
        remove_stale_staging(directory)
        claim_report(directory, name, partial)
        yield


def claim_report(directory: str | Path, name: str, partial: bool = False) -> None:
    """Check that the report of mechanism ``name`` may be written in
    ``directory``: NAME.md and NAME/ are absent or xcheck's
    (:func:`xcheck.fileio.claim`), and, for a run of some modes only
    (``partial``), an earlier report there has the evidence that keeps the
    other modes' parts (a report of an earlier version has none).

    Raises
    ------
    InputError
        Naming what is in the way (left as it is).
    """
    if Path(name).name != name or name in (".", ".."):  # the loader allows plain file names only
        raise ValueError(f"a mechanism name that is a plain file name, found {name!r}")
    directory = Path(directory)
    claim(directory, [f"{name}.md", name], "a report")
    folder = directory / name
    if partial and folder.is_dir() and not (folder / MANIFEST).is_file():
        raise InputError(
            f"{folder}: expected a report with its evidence ({MANIFEST}) to keep the modes this run leaves out, "
            "found a report of an earlier version of xcheck without it (it is left as it is: run every mode "
            "once, without --engines, remove it, or write elsewhere with --out)"
        )


def write_report(
    run: RunResult, directory: str | Path, command: str, gif: bool = True, jobs: int = 1
) -> tuple[Path, dict]:
    """Write reports/NAME.md and reports/NAME/ (figures and evidence) for one run.

    One writer at a time per directory (:func:`xcheck.fileio.directory_lock`),
    which first removes the staging that killed runs left there. The modes of
    an earlier report that the run did not run are kept, with the figures that
    show them (see the module's notes). With ``jobs`` > 1, one worker process
    draws part of the figures (the same bytes), unless an engine registered at
    run time took part (a worker does not know it).

    Returns
    -------
    path : Path
        The report's Markdown.
    entry : dict
        Its line of the index (:func:`update_index`).

    Raises
    ------
    InputError
        Where NAME.md or NAME/ is something xcheck did not write (nothing is written).
    """
    directory = Path(directory)
    with _writing(directory, run.mechanism.name, leaves_out([*run.outcomes, *run.not_applicable])):
        return _write_report(run, directory, command, gif, jobs)


#: the report's images: file name, the figure function of :mod:`._figures` (bytes,
#: or None where the run has nothing to show), its key for the Markdown
_IMAGES = (
    ("drawing.png", "drawing", "drawing"),
    ("quantities.png", "quantities", "quantities"),
    ("differences.png", "error_plots", "errors"),
    ("convergence.png", "convergence_plot", "convergence"),
    ("forces.png", "forces_plot", "forces"),
    ("motion.gif", "motion_gif", "gif"),
)
#: the figures two workers draw, a share each, where the run has workers (this process draws
#: none, and need not import matplotlib): the shares about equal (each figure's cost:
#: benchmarks/bench_report_figures.py)
_WORKER_SHARES = (("convergence_plot", "quantities", "drawing"), ("error_plots", "motion_gif", "forces_plot"))


def _figure(function: str, run: RunResult, identity: str | None = None) -> bytes | None:
    """One figure's bytes, drawn (how a worker process draws it), and kept in the
    figure cache where the run has an ``identity`` (:func:`xcheck.result_cache.run_identity`)."""
    from . import _figures

    with _figures.old_objects_frozen():
        data = getattr(_figures, function)(run)
    if identity is not None:
        from ..result_cache import keep_figure

        keep_figure(identity, function, data)
    return data


def _drawn(functions: list[str], run: RunResult, identity: str | None) -> dict[str, bytes | None]:
    """:func:`_figure` of each of ``functions``, by function (how a worker draws its share)."""
    return {function: _figure(function, run, identity) for function in functions}


def _known_here_only(run: RunResult) -> bool:
    """Whether a mode of the run belongs to an engine registered at run time, whose
    styles and tolerances a spawned worker does not know (it draws nothing then)."""
    from .._parallel import known_to_workers

    return any(m != "native" and not known_to_workers(m) for m in (*run.outcomes, *run.not_applicable))


def _figure_modes(run: RunResult, function: str) -> list[str]:
    """The modes (and force sources) a figure of the run shows."""
    from .. import engines

    modes = [m for m in run.outcomes if m != "native"]
    if function in ("quantities", "error_plots"):
        return modes
    if function == "convergence_plot":
        return [m for m in modes if engines.mode(m).kind == "dynamic"]
    if function == "forces_plot":
        return [str(source) for source in run.force_table.get("engine", [])]
    return []


def _write_report(run: RunResult, directory: Path, command: str, gif: bool, jobs: int = 1) -> tuple[Path, dict]:
    name = run.mechanism.name
    wanted = [(file, function, key) for file, function, key in _IMAGES if gif or function != "motion_gif"]
    made = produced(command)
    fresh = Evidence(
        "run",
        name,
        mode_parts(run, made),
        source_parts(run, made),
        {file: {"modes": _figure_modes(run, function), "produced": made} for file, function, _ in wanted},
    )
    evidence = _merged(fresh, directory / name)
    drawing = [(file, function, key) for file, function, key in wanted if file not in evidence.kept]

    def render(staging: Path) -> str:
        drawn = _cached_figures(run, [f for _, f, _ in drawing])  # a run whose results all came from the cache
        identity = drawn.pop("", None)
        missing = [(file, f, key) for file, f, key in drawing if f not in drawn]
        if jobs > 1 and not _known_here_only(run) and missing:
            from .._parallel import process_pool

            with process_pool(2) as pool:
                shares = [[f for _, f, _ in missing if f in share] for share in _WORKER_SHARES]
                for there in [pool.submit(_drawn, share, run, identity) for share in shares if share]:
                    drawn.update(there.result())
        else:
            drawn.update({f: _figure(f, run, identity) for _, f, _ in missing})
        images = _keep_figures(directory / name, staging, evidence, {key: file for file, _, key in wanted})
        for file, function, key in drawing:
            data = drawn[function]
            if data is None:
                evidence.figures.pop(file, None)
                continue
            (staging / file).write_bytes(data)
            images[key] = f"{name}/{file}"
        return report_markdown(run, evidence, images, command)

    path = _replace_report(directory, name, evidence, render)
    entry = {
        "name": name,
        "title": run.mechanism.title,
        "passed": passed(run, evidence),
        "findings": finding_names(evidence),
        "worst": worst_text(evidence),
        "textbook": textbook_text(run),
        "command": command,
    }
    return path, entry


def _cached_figures(run: RunResult, functions: list[str]) -> dict:
    """The figures (by function) of a run that the figure cache holds, where every
    result of the run has an identity in the results cache; the identity under
    the key "" (absent where it has none: nothing is then kept)."""
    from ..result_cache import cached_figure, run_identity

    identity = run_identity(run) if run.provenance else None
    if identity is None:
        return {}
    found: dict = {"": identity}
    for function in functions:
        hit, data = cached_figure(identity, function)
        if hit:
            found[function] = data
    return found


def _merged(fresh: Evidence, folder: Path) -> Evidence:
    """``fresh`` merged with the evidence of the report in ``folder``
    (:func:`._evidence.merge`); a figure to keep whose file is gone is drawn afresh."""
    evidence = merge(fresh, read_evidence(folder, fresh.kind, fresh.mechanism))
    for file in sorted(evidence.kept):
        if not (folder / file).is_file() or (folder / file).is_symlink():
            evidence.kept.discard(file)
            evidence.figures[file] = fresh.figures[file]
    return evidence


def _keep_figures(old: Path, staging: Path, evidence: Evidence, keys: dict[str, str]) -> dict[str, str]:
    """Copy the figures ``evidence`` keeps from the old report folder into the
    staging folder; returns their Markdown keys -> paths."""
    images = {}
    for key, file in keys.items():
        if file in evidence.kept:
            shutil.copyfile(old / file, staging / file)
            images[key] = f"{old.name}/{file}"
    return images


def _replace_report(directory: Path, name: str, evidence: Evidence, render) -> Path:
    """Write reports/NAME/ and reports/NAME.md as one unit: the figures
    ``render(staging)`` puts in a staging folder, the evidence as the folder's
    manifest, and the Markdown it returns, written beside them; then the folder
    is swapped in and the Markdown renamed out of it, last. Call it holding
    the directory's lock, NAME.md and NAME/ claimed (:func:`claim_report`)."""
    staging = directory / temporary_name(name, "staging")
    umask = os.umask(0)
    os.umask(umask)
    staging.mkdir(0o777 & ~umask)
    (staging / STAGING_MARK).touch()
    try:
        text = render(staging)
        files = sorted(p.name for p in staging.iterdir() if p.name != STAGING_MARK)
        document = evidence.document(files)
        (staging / MANIFEST).write_text(json.dumps(document, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        (staging / PENDING_MARKDOWN).write_text(marked(text, f"the report of {name}"), encoding="utf-8")
        target = directory / name
        retired = None
        if target.exists():
            retired = directory / temporary_name(name, "retired")
            retired.mkdir()
            (retired / STAGING_MARK).touch()
            os.replace(target, retired / name)
        os.replace(staging, target)
        (target / STAGING_MARK).unlink()
        if retired is not None:
            shutil.rmtree(retired, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    complete_reports(directory, name)
    return directory / f"{name}.md"


def write_simulation_report(
    result, directory: str | Path, command: str, drawn: dict[str, bytes] | None = None
) -> tuple[Path, dict]:
    """Write reports/NAME.md and reports/NAME/ (figures and evidence) for a
    free-motion run (:class:`xcheck.simulation.SimulationResult`), keeping the
    parts of the free modes it did not run as :func:`write_report` does;
    ``drawn``: figures already drawn, by key (:func:`reference_figures`).
    Returns the Markdown's path and its line of the index."""
    from . import _simulation

    name = result.kinematics.mechanism.name
    directory = Path(directory)
    made = produced(command)
    fresh = Evidence(
        "simulate",
        name,
        _simulation.mode_parts(result, made),
        figures={f"{key}.png": {"modes": m, "produced": made} for key, m in _simulation.figure_modes(result).items()},
    )

    made_figures = dict(drawn or {})
    with _writing(directory, name, leaves_out([*result.outcomes, *result.not_applicable], ("free",))):
        evidence = _merged(fresh, directory / name)

        def render(staging: Path) -> str:
            keys = {key: f"{key}.png" for key in _simulation.figure_modes(result)}
            images = _keep_figures(directory / name, staging, evidence, keys)
            missing = [key for key, file in keys.items() if file not in evidence.kept and key not in made_figures]
            made_figures.update(_simulation.figures(result, missing))
            for key, file in keys.items():
                if file in evidence.kept:
                    continue
                if key not in made_figures:
                    evidence.figures.pop(file, None)
                    continue
                (staging / file).write_bytes(made_figures[key])
                images[key] = f"{name}/{file}"
            return _simulation.markdown(result, evidence, images, command)

        path = _replace_report(directory, name, evidence, render)
    reference = result.reference
    engines = ", ".join(m for m, p in evidence.modes.items() if "section" in p) or "native only"
    entry = {
        "name": name,
        "title": result.kinematics.mechanism.title,
        "passed": bool(reference.converged),
        "worst": f"free motion: reference error {reference.relative:.2g} of the size ({engines})",
        "textbook": "—",
        "command": command,
    }
    return path, entry


def reference_figures(result) -> dict[str, bytes]:
    """The figures of a free-motion report that show the native reference alone, by key:
    drawn from a :class:`xcheck.simulation.SimulationResult` whose modes need not have
    run yet (for :func:`write_simulation_report`'s ``drawn``)."""
    from . import _simulation

    return _simulation.figures(result, _simulation.REFERENCE_FIGURES)


#: the index's data beside its Markdown: the entries README.md is built from
INDEX_DATA = "index.json"


def write_index(entries: list[dict], directory: str | Path) -> Path:
    """Write reports/README.md and its data (:data:`INDEX_DATA`) from index
    entries. Call it holding the directory's lock, the index's files claimed."""
    directory = Path(directory)
    ordered = sorted(entries, key=lambda e: e["name"])
    write_atomic(
        directory / INDEX_DATA,
        json.dumps({"generator": "xcheck", "entries": ordered}, indent=1, ensure_ascii=False) + "\n",
    )
    path = directory / "README.md"
    write_atomic(path, marked(index_markdown(ordered), "the index of the reports"))
    return path


def read_index(directory: str | Path) -> list[dict]:
    """The entries of a reports directory's index (from :data:`INDEX_DATA`; none
    where it is missing or not xcheck's)."""
    document = read_json(Path(directory) / INDEX_DATA)
    if not isinstance(document, dict) or not isinstance(document.get("entries"), list):
        return []
    return [e for e in document["entries"] if isinstance(e, dict) and isinstance(e.get("name"), str)]


def claim_index(directory: str | Path) -> None:
    """Check that the index may be written in ``directory`` (its files absent
    or xcheck's; :func:`xcheck.fileio.claim`), raising InputError otherwise."""
    claim(Path(directory), list(RESERVED_NAMES), "the index of the reports")


def update_index(directory: str | Path, entries: list[dict], keep: set[str]) -> Path:
    """Add these entries to a reports directory's index, keeping the entries
    already there whose mechanisms are in ``keep`` (the folder's models). The
    read and the write are one step under the directory's lock, so concurrent
    runs keep each other's lines.

    Raises
    ------
    InputError
        Where README.md or index.json there is a file xcheck did not write.
    """
    with directory_lock(directory):
        complete_reports(directory)
        claim_index(directory)
        known = {e["name"]: e for e in read_index(directory)}
        known.update({e["name"]: e for e in entries})
        fresh = {e["name"] for e in entries}
        return write_index([e for n, e in known.items() if n in keep or n in fresh], directory)
