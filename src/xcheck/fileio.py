"""Writing generated files whole or not at all, one writer at a time per
directory, and cleaning what a killed writer left behind."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # not on Windows: writers are not serialised there
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "write_atomic",
    "directory_lock",
    "remove_stale_staging",
    "complete_reports",
    "REPORT_IMAGES",
    "PENDING_MARKDOWN",
]

#: The files of a report's image folder (reports/NAME/).
REPORT_IMAGES = frozenset(
    {"drawing.png", "quantities.png", "differences.png", "convergence.png", "forces.png", "motion.gif"}
)

#: A report's Markdown while it travels in the report's image folder (reports/NAME/), renamed to reports/NAME.md last
PENDING_MARKDOWN = ".report.md"

#: A hidden temporary name as ``tempfile`` makes it: "." + name + "." + 8 characters
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}")


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory
    and an atomic rename, so that a reader never sees a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; a written file is an ordinary one
    try:
        if isinstance(data, bytes):
            with os.fdopen(fd, "wb") as binary:
                binary.write(data)
        else:
            with os.fdopen(fd, "w", encoding="utf-8") as text:
                text.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def directory_lock(directory: str | Path) -> Iterator[None]:
    """Hold an exclusive lock (``fcntl.flock``) on ``directory`` itself while
    writing into it: concurrent runs writing the same reports take turns. The
    lock leaves no file behind and is released when the process ends, killed
    or not."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    if fcntl is None:
        yield
        return
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def complete_reports(directory: str | Path, name: str | None = None) -> list[Path]:
    """Finish the report units in ``directory`` whose Markdown still waits in
    their image folder (NAME/.report.md, see :data:`PENDING_MARKDOWN`): rename
    it to NAME.md, the last step of a report write. Only ``name``'s when given.
    Call it holding :func:`directory_lock`. Returns the Markdown paths written."""
    directory = Path(directory)
    folders = [directory / name] if name is not None else sorted(directory.iterdir())
    done = []
    for folder in folders:
        pending = folder / PENDING_MARKDOWN
        if folder.name.startswith(".") or folder.is_symlink() or not pending.is_file() or pending.is_symlink():
            continue
        os.replace(pending, directory / f"{folder.name}.md")
        done.append(directory / f"{folder.name}.md")
    return done


def remove_stale_staging(directory: str | Path) -> list[Path]:
    """Remove what killed writers left in ``directory``: hidden staging folders
    of reports (``.NAME.XXXXXXXX`` holding report images, ``.NAME.old.XXXXXXXX``
    holding one such folder) and hidden temporary Markdown files of
    :func:`write_atomic` (``.FILE.md.XXXXXXXX``). Call it holding
    :func:`directory_lock`, under which no writer is at work; anything else,
    hidden or not, is left alone. Returns the paths removed."""
    removed = []
    for entry in sorted(Path(directory).iterdir()):
        match = _TEMPORARY.fullmatch(entry.name)
        if match is None or entry.is_symlink():
            continue
        name = match["name"]
        if entry.is_file() and name.endswith(".md"):
            entry.unlink()
        elif entry.is_dir() and (_holds_images(entry) or (name.endswith(".old") and _holds_report(entry, name[:-4]))):
            shutil.rmtree(entry)
        else:
            continue
        removed.append(entry)
    return removed


def _holds_images(folder: Path) -> bool:
    """Whether ``folder`` holds nothing but report images and maybe the report's Markdown (as staging does)."""
    return all(
        (c.name in REPORT_IMAGES or c.name == PENDING_MARKDOWN) and c.is_file() and not c.is_symlink()
        for c in folder.iterdir()
    )


def _holds_report(folder: Path, name: str) -> bool:
    """Whether ``folder`` holds nothing but a report's image folder ``name`` (a retired report)."""
    return all(c.name == name and c.is_dir() and not c.is_symlink() and _holds_images(c) for c in folder.iterdir())
