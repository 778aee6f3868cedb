"""Markdown reports of comparison runs: reports/NAME.md with its images in
reports/NAME/, and reports/README.md indexing them.

A report is written as one unit: its images and its Markdown are written
into a fresh staging directory beside the old one; nothing is replaced until
all are written. Then the staging directory replaces the old image directory
and the Markdown, carried in it, is renamed into place last (two renames). A
run killed between those renames leaves the new Markdown waiting in the new
image directory; the next writer, taking the directory's file lock, first
completes such a unit (:func:`xcheck.fileio.complete_reports`) and removes what
killed writers left.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

from ..fileio import PENDING_MARKDOWN, complete_reports, directory_lock, remove_stale_staging, write_atomic
from ..runner import RunResult
from . import _figures
from ._markdown import index_markdown, report_markdown, textbook_text, worst_text

__all__ = [
    "write_report",
    "write_simulation_report",
    "write_index",
    "read_index",
    "update_index",
    "index_entry",
    "simulation_entry",
    "INDEX_DATA",
]


def write_report(run: RunResult, directory: str | Path, command: str, gif: bool = True, jobs: int = 1) -> Path:
    """Write reports/NAME.md and reports/NAME/*.png|gif for one run; returns the Markdown path.

    One writer at a time per directory (:func:`xcheck.fileio.directory_lock`),
    which first removes the staging that killed runs left there. With ``jobs``
    > 1, one worker process draws part of the figures (the same bytes), unless
    an engine registered at run time took part (a worker does not know it).
    """
    with directory_lock(directory):
        complete_reports(directory)
        remove_stale_staging(directory)
        return _write_report(run, Path(directory), command, gif, jobs)


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
#: the figures a worker draws when there is one, while this process draws the others:
#: on fourbar the GIF 1.2 s, quantities 0.6 and drawing 0.3 after the worker's start
#: (about 1.2 s: xcheck, pandas, matplotlib), against convergence 1.6, differences
#: 1.3 and forces 0.4 here
_WORKER_SHARE = ("motion_gif", "quantities", "drawing")


def _figure(function: str, run: RunResult) -> bytes | None:
    """One figure's bytes (how a worker process draws it)."""
    return getattr(_figures, function)(run)


def _known_here_only(run: RunResult) -> bool:
    """Whether a mode of the run belongs to an engine registered at run time, whose
    styles and tolerances a spawned worker does not know (it draws nothing then)."""
    from .._parallel import known_to_workers

    return any(m != "native" and not known_to_workers(m) for m in (*run.outcomes, *run.not_applicable))


def _write_report(run: RunResult, directory: Path, command: str, gif: bool, jobs: int = 1) -> Path:
    name = run.mechanism.name
    wanted = [(file, function, key) for file, function, key in _IMAGES if gif or function != "motion_gif"]

    def render(staging: Path) -> str:
        drawn: dict[str, bytes | None] = {}
        if jobs > 1 and not _known_here_only(run):
            from .._parallel import process_pool

            with process_pool(1) as pool:
                away = {f: pool.submit(_figure, f, run) for _, f, _ in wanted if f in _WORKER_SHARE}
                drawn.update({f: _figure(f, run) for _, f, _ in wanted if f not in away})
                drawn.update({f: future.result() for f, future in away.items()})
        else:
            drawn.update({f: _figure(f, run) for _, f, _ in wanted})
        images = {}
        for file, function, key in wanted:
            data = drawn[function]
            if data is not None:
                (staging / file).write_bytes(data)
                images[key] = f"{name}/{file}"
        return report_markdown(run, images, command)

    return _replace_report(directory, name, render)


def _replace_report(directory: Path, name: str, render) -> Path:
    """Write reports/NAME/ and reports/NAME.md as one unit: the images
    ``render(staging)`` puts in a staging folder (it must write drawing.png, the
    mark of a report folder) and the Markdown it returns, written beside them;
    then the folder is swapped in and the Markdown renamed out of it, last."""
    directory.mkdir(parents=True, exist_ok=True)
    if Path(name).name != name or name in (".", ".."):  # the loader allows plain file names only
        raise ValueError(f"a mechanism name that is a plain file name, found {name!r}")
    existing = directory / name
    if existing.exists() and not (existing.is_dir() and (existing / "drawing.png").is_file()):
        raise FileExistsError(
            f"{existing} exists and is not a report's image folder: xcheck replaces only folders it wrote"
        )
    staging = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=directory))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(staging, 0o777 & ~umask)
    try:
        text = render(staging)
        (staging / PENDING_MARKDOWN).write_text(text, encoding="utf-8")
        target = directory / name
        retired = None
        if target.exists():
            retired = Path(tempfile.mkdtemp(prefix=f".{name}.old.", dir=directory))
            os.replace(target, retired / name)
        os.replace(staging, target)
        if retired is not None:
            shutil.rmtree(retired, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    complete_reports(directory, name)
    return directory / f"{name}.md"


def write_simulation_report(result, directory: str | Path, command: str) -> Path:
    """Write reports/NAME.md and reports/NAME/*.png for a free-motion run
    (:class:`xcheck.simulation.SimulationResult`); returns the Markdown path."""
    from . import _simulation

    name = result.kinematics.mechanism.name

    def render(staging: Path) -> str:
        images = {}
        for key, data in _simulation.figures(result).items():
            (staging / f"{key}.png").write_bytes(data)
            images[key] = f"{name}/{key}.png"
        return _simulation.markdown(result, images, command)

    with directory_lock(directory):
        complete_reports(directory)
        remove_stale_staging(directory)
        return _replace_report(Path(directory), name, render)


def index_entry(run: RunResult) -> dict:
    """The line of reports/README.md for one run."""
    return {
        "name": run.mechanism.name,
        "title": run.mechanism.title,
        "passed": run.passed,
        "findings": list(run.findings),
        "worst": worst_text(run),
        "textbook": textbook_text(run),
    }


#: the index's data beside its Markdown: the entries README.md is built from
INDEX_DATA = "index.json"


def simulation_entry(result) -> dict:
    """The line of reports/README.md for a free-motion run."""
    reference = result.reference
    ran = ", ".join(result.outcomes) or "native only"
    return {
        "name": result.kinematics.mechanism.name,
        "title": result.kinematics.mechanism.title,
        "passed": bool(reference.converged),
        "worst": f"free motion: reference error {reference.relative:.2g} of the size ({ran})",
        "textbook": "—",
    }


def write_index(entries: list[dict], directory: str | Path, command: str) -> Path:
    """Write reports/README.md and its data (:data:`INDEX_DATA`) from index entries."""
    directory = Path(directory)
    ordered = sorted(entries, key=lambda e: e["name"])
    write_atomic(
        directory / INDEX_DATA,
        json.dumps({"written_by": command, "entries": ordered}, indent=1, ensure_ascii=False) + "\n",
    )
    path = directory / "README.md"
    write_atomic(path, index_markdown(ordered, command))
    return path


def read_index(directory: str | Path) -> list[dict]:
    """The entries of a reports directory's index (from :data:`INDEX_DATA`; none
    where it is missing or not xcheck's)."""
    path = Path(directory) / INDEX_DATA
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return [e for e in data["entries"] if isinstance(e, dict) and isinstance(e.get("name"), str)]
    except (OSError, ValueError, KeyError, TypeError):
        return []


def update_index(directory: str | Path, entries: list[dict], keep: set[str], command: str) -> Path:
    """Add these entries to a reports directory's index, keeping the entries
    already there whose mechanisms are in ``keep`` (the folder's models);
    ``command`` is the run that wrote it last. The read and the write are one
    step under the directory's lock, so concurrent runs keep each other's lines."""
    with directory_lock(directory):
        complete_reports(directory)
        known = {e["name"]: e for e in read_index(directory)}
        known.update({e["name"]: e for e in entries})
        fresh = {e["name"] for e in entries}
        return write_index([e for n, e in known.items() if n in keep or n in fresh], directory, command)
