"""xcheck's cache directory: entries that are hints, never the truth.

The branch maps (:mod:`xcheck.cache`), the modes' results
(:mod:`xcheck.result_cache`) and the report's figures are kept here between runs,
each entry a file named by the SHA-256 of what it answers (a mechanism, a
mode, its settings). The directory is ``platformdirs.user_cache_dir("xcheck")``,
or ``$XCHECK_CACHE_DIR`` (``off`` turns every cache off); ``xcheck cache``
shows and clears it.

An entry is authenticated, not just checksummed: a line of JSON (the layout,
the entry's kind and name, what computed it, when, the payload's length and an
HMAC-SHA256 of all of it under a secret key), then the payload. The key is 32
random bytes in ``key`` beside the entries, made on first use with mode 0600,
so an entry edited or brought from elsewhere (whose HMAC a checksum anyone can
recompute would not catch) fails, as does a truncated or corrupt one. What
computed an entry (xcheck's version and a digest of its source, the versions
of the libraries and engines it used) is part of what is authenticated and
must equal the running one, so an entry of other code is never served.

An entry is opened without following a link, refused unless it is a regular
file (a FIFO or a device would block or never end), and read with a size
bound (:func:`xcheck.fileio.read_bounded`). Every entry that cannot be used is a miss with its reason
(:class:`Lookup`); the caller recomputes, says so and writes a fresh entry.
An entry is written whole or not at all (:func:`xcheck.fileio.write_atomic`);
a cache that cannot be written is no error.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import hmac
import json
import os
import platform
import re
import secrets
import shutil
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .fileio import read_bounded, write_atomic

__all__ = [
    "CACHE_ENV",
    "FORMAT",
    "KEY_NAME",
    "Lookup",
    "cache_dir",
    "clear",
    "describe",
    "digest",
    "mechanism_digest",
    "entry_path",
    "read",
    "made_by",
    "source_digest",
    "write",
]

#: the environment variable that puts the cache elsewhere (a directory), or turns it off (``off``)
CACHE_ENV = "XCHECK_CACHE_DIR"
#: the layout of an entry (its first line); another value is a miss
FORMAT = 2
#: the secret key's file in the cache directory
KEY_NAME = "key"
#: bytes of the key
KEY_BYTES = 32
#: the longest first line of an entry (its header), bytes
HEADER_BYTES = 64 * 1024
#: what is not an entry in the cache directory, but is kept there: the key, and JAX's compilations
_NOT_ENTRIES = (KEY_NAME, "jax")

_source_digest: str | None = None


def cache_dir() -> Path | None:
    """The cache directory: ``$XCHECK_CACHE_DIR``, else the user's cache
    directory for xcheck; None when ``$XCHECK_CACHE_DIR`` is ``off``."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen:
        return None if chosen.strip().lower() == "off" else Path(chosen)
    import platformdirs

    return Path(platformdirs.user_cache_dir("xcheck"))


def source_digest() -> str:
    """SHA-256 of xcheck's own code: every ``.py`` file of the package, by its
    path inside it, so that a change to any of them (a checkout, an editable
    install, a patched copy) is never served what earlier code computed."""
    global _source_digest
    if _source_digest is None:
        root = Path(__file__).resolve().parent
        digest = hashlib.sha256(__version__.encode())
        for path in sorted(root.rglob("*.py")):
            relative = path.relative_to(root).as_posix()
            if relative.startswith("_data/"):
                continue  # the bundled mechanisms: inputs, keyed by their content
            digest.update(b"\0" + relative.encode() + b"\0")
            digest.update(path.read_bytes())
        _source_digest = digest.hexdigest()
    return _source_digest


def made_by(*distributions: str) -> dict[str, str]:
    """What computes an entry: xcheck's version and source digest, Python, the
    machine, the numerical libraries (NumPy, SciPy, pandas, Numba), and the
    versions of ``distributions`` (an engine's packages; "not installed" where
    one is not)."""
    found = {
        "xcheck": __version__,
        "source": source_digest(),
        "python": platform.python_version(),
        "machine": f"{sys.platform} {platform.machine()}",
    }
    for name in ("numpy", "scipy", "pandas", "numba", *distributions):
        found[name] = version(name)
    return found


_installed: dict[str, str] | None = None


def version(distribution: str) -> str:
    """The installed version of a distribution, "not installed" where there is
    none. Read from the names of the ``*.dist-info`` folders on the path (1 ms;
    :mod:`importlib.metadata` costs 30 ms to import, a tenth of ``xcheck
    solve``), else from :mod:`importlib.metadata` (an egg, a zip)."""
    global _installed
    if _installed is None:
        _installed = {}
        for entry in reversed(sys.path):  # the first on the path wins, as the import system's
            with contextlib.suppress(OSError), os.scandir(entry or ".") as listing:
                for item in listing:
                    if item.name.endswith(".dist-info"):
                        name, _, rest = item.name[: -len(".dist-info")].partition("-")
                        _installed[_normal(name)] = rest
    found = _installed.get(_normal(distribution))
    if found:
        return found
    from importlib import metadata

    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return "not installed"


def _normal(name: str) -> str:
    """A distribution's name as its dist-info folder and PEP 503 compare it."""
    return re.sub(r"[-_.]+", "_", name).lower()


def mechanism_digest(kind: str, mechanism: Any, *values: Any) -> str | None:
    """:func:`digest` of ``kind``, the canonical mechanism (its model, not the path it
    was read from: the same model read from another file is the same) and ``values``;
    None where they cannot be digested."""
    try:
        return digest(kind, dataclasses.replace(mechanism, path=""), *values)
    except TypeError:
        return None


def digest(*values: Any) -> str:
    """SHA-256 of ``values`` by content: dataclasses field by field (with their
    class), mappings in their order, sequences, NumPy arrays (dtype, shape,
    bytes), floats to every bit, strings, bytes, numbers, None.

    Raises
    ------
    TypeError
        For a value of another type (then nothing is cached).
    """
    hashed = hashlib.sha256()

    def add(value: Any) -> None:
        if isinstance(value, bytes):
            hashed.update(f"bytes:{len(value)};".encode() + value)
        elif value is None or isinstance(value, bool | int | str):
            hashed.update(f"{type(value).__name__}:{value!r};".encode())
        elif isinstance(value, float):
            hashed.update(f"float:{value.hex()};".encode())
        elif isinstance(value, np.ndarray | np.generic):
            array = np.ascontiguousarray(value)
            hashed.update(f"array:{array.dtype.str}:{array.shape};".encode())
            hashed.update(array.tobytes())
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            hashed.update(f"{type(value).__module__}.{type(value).__qualname__}(".encode())
            for item in dataclasses.fields(value):
                hashed.update(f"{item.name}=".encode())
                add(getattr(value, item.name))
            hashed.update(b")")
        elif isinstance(value, Mapping):
            hashed.update(b"{")
            for k, v in value.items():
                add(k)
                add(v)
            hashed.update(b"}")
        elif isinstance(value, tuple | list):
            hashed.update(b"[")
            for v in value:
                add(v)
            hashed.update(b"]")
        else:
            raise TypeError(f"no digest for a {type(value).__name__}")

    for value in values:
        add(value)
    return hashed.hexdigest()


def entry_path(kind: str, name: str) -> Path | None:
    """Where the entry ``name`` (a hex digest) of ``kind`` lies; None without a cache."""
    directory = cache_dir()
    return None if directory is None else directory / kind / f"{name}.entry"


@dataclass(frozen=True)
class Lookup:
    """What a read found.

    Attributes
    ----------
    payload : bytes or None
        The entry's payload, authenticated and made by the running code; None on a miss.
    meta : dict
        The entry's header (``made_by``, ``computed_at``, ``mac``, ...) when found.
    problem : str
        Why an entry that was there could not be used (one line, "" for a plain
        miss or a hit): the caller recomputes, and says so unless ``stale``.
    stale : bool
        The entry is sound but was made by other code or versions (an upgrade,
        an edited checkout): an expected miss, replaced without a word.
    """

    payload: bytes | None
    meta: dict
    problem: str = ""
    stale: bool = False

    @property
    def hit(self) -> bool:
        return self.payload is not None


def _key(directory: Path, create: bool) -> bytes | None:
    """The secret key of ``directory``, made (mode 0600) where there is none and
    ``create``; None where there is none, or it is not a private regular file of
    this user's holding exactly :data:`KEY_BYTES` bytes (then nothing is trusted)."""
    path = directory / KEY_NAME
    try:
        return _read_key(path)
    except FileNotFoundError:
        if not create:
            return None
    except OSError:
        return None
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd, fresh = tempfile.mkstemp(prefix=".key.", dir=directory)  # mode 0600
        try:
            os.write(fd, secrets.token_bytes(KEY_BYTES))
            os.fsync(fd)
        finally:
            os.close(fd)
        try:
            os.link(fresh, path)  # fails where another process made one first: theirs is the key
        except FileExistsError:
            pass
        finally:
            os.unlink(fresh)
        return _read_key(path)
    except OSError:
        return None


def _read_key(path: Path) -> bytes | None:
    data, info = read_bounded(path, KEY_BYTES)
    private = info.st_mode & 0o077 == 0 and (not hasattr(os, "getuid") or info.st_uid == os.getuid())
    return data if private and len(data) == KEY_BYTES else None


def _mac(key: bytes, header: dict, payload: bytes) -> str:
    signed = json.dumps(header, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()
    return hmac.new(key, signed + b"\n" + payload, hashlib.sha256).hexdigest()


def write(kind: str, name: str, payload: bytes, made: dict[str, str], computed_at: str, bound: int) -> str:
    """Write an entry whole (or nothing). Returns its MAC (the entry's identity),
    "" where there is no cache, the payload is larger than ``bound`` or the
    cache cannot be written."""
    path = entry_path(kind, name)
    if path is None or len(payload) > bound:
        return ""
    key = _key(path.parent.parent, create=True)
    if key is None:
        return ""
    header: dict[str, Any] = {
        "format": FORMAT,
        "kind": kind,
        "name": name,
        "made_by": made,
        "computed_at": computed_at,
        "length": len(payload),
    }
    header["mac"] = _mac(key, header, payload)
    try:
        write_atomic(path, json.dumps(header, sort_keys=True).encode() + b"\n" + payload)
    except (OSError, ValueError):
        return ""
    return header["mac"]


def read(kind: str, name: str, made: dict[str, str], bound: int) -> Lookup:
    """The entry ``name`` of ``kind`` if it is authentic and made by ``made``
    (see the module); else a miss, with the reason where an entry was there."""
    path = entry_path(kind, name)
    if path is None:
        return Lookup(None, {})
    try:
        data, _ = read_bounded(path, bound + HEADER_BYTES)
    except (FileNotFoundError, NotADirectoryError):  # no entry, or no cache directory there
        return Lookup(None, {})
    except OSError as err:
        return Lookup(None, {}, f"{path}: {err.strerror or err}: not read")
    first, newline, payload = data.partition(b"\n")
    try:
        header = json.loads(first) if newline and len(first) <= HEADER_BYTES else None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            return Lookup(None, {}, f"{path}: not an entry of this xcheck's layout")
        mac = str(header.pop("mac"))
        if header.get("kind") != kind or header.get("name") != name or header.get("length") != len(payload):
            return Lookup(None, {}, f"{path}: truncated, or not the entry of what it is named for")
        key = _key(path.parent.parent, create=False)
        if key is None or not hmac.compare_digest(mac, _mac(key, header, payload)):
            return Lookup(None, {}, f"{path}: its authentication failed (edited, or written elsewhere)")
    except (ValueError, KeyError, TypeError):
        return Lookup(None, {}, f"{path}: corrupt")
    header["mac"] = mac
    if header.get("made_by") != made:
        theirs: dict = header["made_by"] if isinstance(header.get("made_by"), dict) else {}
        changed = sorted(k for k in set(made) | set(theirs) if made.get(k) != theirs.get(k))
        return Lookup(None, header, f"{path}: computed by other code or versions ({', '.join(changed)})", True)
    return Lookup(payload, header)


def describe() -> dict[str, Any]:
    """The cache directory (None where off), and per kind its entries and bytes."""
    directory = cache_dir()
    found: dict[str, Any] = {"directory": None if directory is None else str(directory), "kinds": {}}
    if directory is None or not directory.is_dir():
        return found
    for folder in sorted(directory.iterdir()):
        if folder.name in _NOT_ENTRIES or not folder.is_dir() or folder.is_symlink():
            continue
        entries = [p for p in folder.glob("*.entry") if p.is_file() and not p.is_symlink()]
        found["kinds"][folder.name] = {"entries": len(entries), "bytes": sum(p.stat().st_size for p in entries)}
    jax = directory / "jax"
    if jax.is_dir() and not jax.is_symlink():
        files = [p for p in jax.rglob("*") if p.is_file()]
        found["kinds"]["jax"] = {"entries": len(files), "bytes": sum(p.stat().st_size for p in files)}
    return found


def clear() -> int:
    """Remove every entry, JAX's compilations and the key (a fresh one is made
    on next use); returns the files removed. Only what xcheck keeps there is
    removed: ``*.entry`` files in its kinds' folders, ``jax/``, the key."""
    directory = cache_dir()
    if directory is None or not directory.is_dir():
        return 0
    removed = 0
    for folder in directory.iterdir():
        if folder.is_symlink() or not folder.is_dir():
            continue
        if folder.name == "jax":
            removed += sum(1 for p in folder.rglob("*") if p.is_file())
            shutil.rmtree(folder, ignore_errors=True)
            continue
        for entry in folder.glob("*.entry"):
            with contextlib.suppress(OSError):
                entry.unlink()
                removed += 1
        with contextlib.suppress(OSError):
            folder.rmdir()  # where nothing else is left in it
    with contextlib.suppress(FileNotFoundError):
        (directory / KEY_NAME).unlink()
        removed += 1
    return removed
