"""Writing generated files whole or not at all, one writer at a time per
directory, in folders shared with the user: xcheck replaces or removes only
what it can tell it wrote, and cleans what a killed writer of its own left.

What xcheck can tell it wrote:

- a text file that starts with its mark (:data:`MARK`, a Markdown comment
  :func:`marked` puts first), or a JSON object whose ``"generator"`` is ``"xcheck"``;
- a report's folder ``NAME/`` holding its manifest (:data:`MANIFEST`, the
  report's evidence) and nothing the manifest does not name;
- a temporary of its own: a hidden name with ``.xcheck-`` and a kind in it
  (:func:`temporary_name`), which no user file has; a temporary folder holds
  the mark file :data:`STAGING_MARK`.

Reports of earlier versions (without marks) are recognised by their form:
Markdown ending with the command that reproduces it, an image folder of
nothing but report figures.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import shutil
import stat
from collections.abc import Iterator
from pathlib import Path

from .errors import InputError

try:
    import fcntl
except ImportError:  # not on Windows: writers are not serialised there
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "write_atomic",
    "directory_lock",
    "read_bounded",
    "read_regular",
    "marked",
    "MARK",
    "MANIFEST",
    "STAGING_MARK",
    "PENDING_MARKDOWN",
    "RESERVED_NAMES",
    "reserved_name",
    "temporary_name",
    "written_by_xcheck",
    "report_folder_files",
    "claim",
    "remove_stale_staging",
    "complete_reports",
]

#: The first characters of every Markdown file xcheck writes (:func:`marked`).
MARK = "<!-- Written by xcheck"
#: A report folder's manifest: the report's evidence, which names the folder's files.
MANIFEST = "results.json"
#: The file that marks a staging or retired folder as xcheck's.
STAGING_MARK = ".xcheck-staging"
#: A report's Markdown while it travels in the report's folder (reports/NAME/), renamed to reports/NAME.md last.
PENDING_MARKDOWN = ".report.md"
#: The index's files in a reports folder; no report may take their names.
RESERVED_NAMES = ("README.md", "index.json")
#: The figures of reports written before reports had a manifest.
_OLD_FIGURES = frozenset(
    {
        "drawing.png",
        "quantities.png",
        "differences.png",
        "convergence.png",
        "forces.png",
        "motion.gif",
        "energy.png",
        "errors.png",
        "work-precision.png",
    }
)
#: How much of a file is read to tell whether xcheck wrote it.
_HEAD = 4096
#: The largest manifest or index read back (a report's evidence is some 100 kB).
_LARGEST_JSON = 64 * 2**20

#: A temporary's name: "." + the name it stands for + ".xcheck-" + kind + "-" + 8 characters
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.xcheck-(?P<kind>tmp|staging|retired)-[a-z0-9]{8}")


def temporary_name(name: str, kind: str) -> str:
    """A hidden name for a temporary of ``name``: ``kind`` is "tmp" (a file of
    :func:`write_atomic`), "staging" (a report folder being written) or
    "retired" (a report folder being replaced)."""
    assert kind in ("tmp", "staging", "retired")
    return f".{name}.xcheck-{kind}-{secrets.token_hex(4)}"


def marked(text: str, what: str) -> str:
    """Markdown ``text`` with xcheck's mark first: a comment saying what wrote it
    and that a later run replaces it (not shown where Markdown is rendered)."""
    return f"{MARK}: {what}. A later run replaces this file; edit a copy. -->\n{text}"


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory
    and an atomic rename, so that a reader never sees a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / temporary_name(path.name, "tmp")
    umask = os.umask(0)
    os.umask(umask)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666 & ~umask)
    try:
        if isinstance(data, bytes):
            with os.fdopen(fd, "wb") as binary:
                binary.write(data)
        else:
            with os.fdopen(fd, "w", encoding="utf-8") as text:
                text.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
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


def read_bounded(path: str | Path, bound: int, whole: bool = True) -> tuple[bytes, os.stat_result]:
    """The bytes of the regular file ``path`` (``whole``: all of them, at most
    ``bound``; else its first ``bound`` bytes) and its status, opened without
    following a link and without blocking, so nothing a user put there (a
    FIFO, a device, a giant) can hang or exhaust the reader.

    Raises
    ------
    OSError
        Missing or unreadable; a link, FIFO, device or folder (``EINVAL``);
        with ``whole``, larger than ``bound`` bytes (``EFBIG``).
    """
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise OSError(errno.EINVAL, "not a regular file", str(path))
        if whole and info.st_size > bound:
            raise OSError(errno.EFBIG, f"{info.st_size} bytes, more than {bound}", str(path))
        chunks, left = [], bound + 1 if whole else bound  # one byte more than allowed tells a file that grew
        while left > 0:
            chunk = os.read(fd, min(left, 2**20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
        if len(data) > bound:
            raise OSError(errno.EFBIG, f"more than {bound} bytes", str(path))
        return data, info
    finally:
        os.close(fd)


def read_regular(path: str | Path, limit: int) -> bytes | None:
    """The first ``limit`` bytes of a regular file, or None where ``path`` is
    missing, a link, a FIFO, a device or a folder, or cannot be read
    (:func:`read_bounded`)."""
    try:
        return read_bounded(path, limit, whole=False)[0]
    except OSError:
        return None


def read_json(path: str | Path) -> object | None:
    """A JSON document of a regular file (at most 64 MiB; :func:`read_regular`), or None."""
    data = read_regular(path, _LARGEST_JSON + 1)
    if data is None or len(data) > _LARGEST_JSON:
        return None
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None


def reserved_name(name: str) -> str | None:
    """Why a mechanism name cannot name a report beside the others (None if it
    can): its NAME.md or its folder NAME/ would be the index's files or another
    report's Markdown, on a file system that ignores case too."""
    folded = name.casefold()
    if folded == "readme":
        return "its report README.md would be the index of the reports"
    if folded in (n.casefold() for n in RESERVED_NAMES):
        return f"its report folder would be the index's file {name}"
    if folded.endswith(".md"):
        return f"its report folder {name}/ would be the Markdown of the report of {name[:-3]!r}"
    return None


def written_by_xcheck(path: Path) -> bool:
    """Whether ``path`` is a file or a report folder that xcheck wrote (see the
    module's notes); False for anything else, a link included."""
    if path.is_symlink():
        return False
    if path.is_dir():
        return report_folder_files(path) is not None
    if path.suffix == ".json":
        document = read_json(path)
        if not isinstance(document, dict):
            return False
        # the index of earlier versions had no generator, but its command
        return document.get("generator") == "xcheck" or str(document.get("written_by", "")).startswith("xcheck ")
    head = read_regular(path, _HEAD)
    if head is None:
        return False
    if head.startswith(MARK.encode()):
        return True
    return _old_report(path, head)


def _old_report(path: Path, head: bytes) -> bool:
    """A report or index of a version before the marks: an index starting as
    xcheck's did, a report ending with the command that reproduces it."""
    if head.startswith(b"# Reports\n\nOne report per mechanism"):
        return True
    if not head.startswith(b"# "):
        return False
    try:
        size = path.stat().st_size
        with path.open("rb") as stream:
            stream.seek(max(0, size - _HEAD))
            tail = stream.read(_HEAD)
    except OSError:
        return False
    last = tail.rstrip(b"\n").rsplit(b"\n", 1)[-1]
    return last.startswith(b"Reproduce: `xcheck ") and last.endswith(b"`")


def report_folder_files(folder: Path) -> list[str] | None:
    """The files of a report folder xcheck wrote (its manifest's list), or None
    where ``folder`` is not one: no manifest of xcheck's, or something in it
    the manifest does not name. A folder of an earlier version, without a
    manifest, is one when it holds nothing but report figures."""
    try:
        entries = {entry.name: entry for entry in folder.iterdir()}
    except OSError:
        return None
    if any(entry.is_symlink() or not entry.is_file() for entry in entries.values()):
        return None
    listed = None
    if MANIFEST in entries:
        document = read_json(entries[MANIFEST])
        if isinstance(document, dict) and document.get("generator") == "xcheck":
            files = document.get("files")
            if isinstance(files, list) and all(isinstance(f, str) for f in files):
                listed = {*files, MANIFEST, PENDING_MARKDOWN, STAGING_MARK}
        if listed is None:
            return None
    elif "drawing.png" in entries:  # every report has its drawing
        listed = set(_OLD_FIGURES) | {PENDING_MARKDOWN}
    else:
        return None
    if set(entries) - listed:
        return None
    return sorted(entries)


def claim(directory: Path, names: list[str], what: str) -> None:
    """Check that xcheck may write ``names`` in ``directory``: each is absent,
    or is xcheck's (:func:`written_by_xcheck`).

    Raises
    ------
    InputError
        Naming the first that is not: it is left as it is.
    """
    for name in names:
        path = directory / name
        if not (path.exists() or path.is_symlink()) or written_by_xcheck(path):
            continue
        kind = "folder" if path.is_dir() and not path.is_symlink() else "file"
        raise InputError(
            f"{path}: expected no file there or {what} written by xcheck, found a {kind} xcheck did not write "
            "(it is left as it is: move it, or write the reports elsewhere with --out)"
        )


def complete_reports(directory: str | Path, name: str | None = None) -> list[Path]:
    """Finish the report units in ``directory`` whose Markdown still waits in
    their folder (NAME/.report.md, see :data:`PENDING_MARKDOWN`): rename it to
    NAME.md, the last step of a report write. Only ``name``'s when given, and
    only where the folder, the waiting Markdown and any NAME.md there are
    xcheck's. Call it holding :func:`directory_lock`. Returns the Markdown
    paths written."""
    directory = Path(directory)
    try:
        folders = [directory / name] if name is not None else sorted(directory.iterdir())
    except OSError:
        return []
    done = []
    for folder in folders:
        pending = folder / PENDING_MARKDOWN
        target = directory / f"{folder.name}.md"
        if folder.name.startswith(".") or folder.is_symlink() or not folder.is_dir():
            continue
        head = read_regular(pending, len(MARK))
        if head != MARK.encode() or report_folder_files(folder) is None:
            continue
        if (target.exists() or target.is_symlink()) and not written_by_xcheck(target):
            continue
        os.replace(pending, target)
        done.append(target)
    return done


def remove_stale_staging(directory: str | Path) -> list[Path]:
    """Remove what killed writers of xcheck left in ``directory``: temporary
    files of :func:`write_atomic` and staging or retired report folders
    holding :data:`STAGING_MARK`, each with a name of :func:`temporary_name`.
    Call it holding :func:`directory_lock`, under which no writer is at work;
    anything else, hidden or not, is left alone. Returns the paths removed."""
    removed: list[Path] = []
    try:
        entries = sorted(Path(directory).iterdir())
    except OSError:
        return removed
    for entry in entries:
        match = _TEMPORARY.fullmatch(entry.name)
        if match is None or entry.is_symlink():
            continue
        if match["kind"] == "tmp" and entry.is_file():
            entry.unlink()
        elif match["kind"] != "tmp" and entry.is_dir() and (entry / STAGING_MARK).is_file():
            shutil.rmtree(entry)
        else:
            continue
        removed.append(entry)
    return removed
