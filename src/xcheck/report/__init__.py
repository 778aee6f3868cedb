"""Markdown reports of comparison runs: reports/NAME.md with its images in
reports/NAME/, and reports/README.md indexing them.

A report appears whole or not at all: its images are written into a fresh
directory beside the old one, which replaces the old directory by renames; the
Markdown file is written through a temporary file and a rename. Writers of one
directory take turns (a file lock), and each first removes what a killed
writer left there.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

from ..fileio import directory_lock, remove_stale_staging, write_atomic
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


def write_report(run: RunResult, directory: str | Path, command: str, gif: bool = True) -> Path:
    """Write reports/NAME.md and reports/NAME/*.png|gif for one run; returns the Markdown path.

    One writer at a time per directory (:func:`xcheck.fileio.directory_lock`),
    which first removes the staging that killed runs left there.
    """
    with directory_lock(directory):
        remove_stale_staging(directory)
        return _write_report(run, Path(directory), command, gif)


def _write_report(run: RunResult, directory: Path, command: str, gif: bool) -> Path:
    name = run.mechanism.name

    def render(staging: Path) -> str:
        images = {"drawing": "drawing.png", "quantities": "quantities.png", "errors": "differences.png"}
        (staging / "drawing.png").write_bytes(_figures.drawing(run))
        (staging / "quantities.png").write_bytes(_figures.quantities(run))
        (staging / "differences.png").write_bytes(_figures.error_plots(run))
        convergence = _figures.convergence_plot(run)
        if convergence is not None:
            (staging / "convergence.png").write_bytes(convergence)
            images["convergence"] = "convergence.png"
        forces = _figures.forces_plot(run)
        if forces is not None:
            (staging / "forces.png").write_bytes(forces)
            images["forces"] = "forces.png"
        if gif:
            (staging / "motion.gif").write_bytes(_figures.motion_gif(run))
            images["gif"] = "motion.gif"
        return report_markdown(run, {k: f"{name}/{v}" for k, v in images.items()}, command)

    return _replace_report(directory, name, render)


def _replace_report(directory: Path, name: str, render) -> Path:
    """Write reports/NAME/ (the images ``render(staging)`` puts in a staging
    folder, swapped in whole; it must write drawing.png, the mark of a report
    folder) and then reports/NAME.md (the text ``render`` returns, atomically)."""
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
    markdown = directory / f"{name}.md"
    write_atomic(markdown, text)
    return markdown


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
        remove_stale_staging(directory)
        return _replace_report(Path(directory), name, render)


def index_entry(run: RunResult) -> dict:
    """The line of reports/README.md for one run."""
    return {
        "name": run.mechanism.name,
        "title": run.mechanism.title,
        "passed": run.passed,
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
        known = {e["name"]: e for e in read_index(directory)}
        known.update({e["name"]: e for e in entries})
        fresh = {e["name"] for e in entries}
        return write_index([e for n, e in known.items() if n in keep or n in fresh], directory, command)
