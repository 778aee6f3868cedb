"""The registry of engines: the built-in ones, those other packages declare
under the entry-point group ``xcheck.engines``, and those registered at run
time (:func:`register`).

Everything that lists modes -- the runner, ``--engines``, the JSON and the
report -- asks here, so an engine added in one place appears everywhere.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path

from ._contract import KINDS, Engine, Mode

__all__ = [
    "ENTRY_POINT_GROUP",
    "ALL",
    "register",
    "unregister",
    "engines",
    "engine",
    "modes",
    "mode",
    "engine_of",
    "groups",
    "exporters",
    "load_problems",
    "registered_at_run_time",
    "skip_entry_points",
    "TIMEOUT_ENV",
]

#: the entry-point group through which an installed package adds engines:
#: ``[project.entry-points."xcheck.engines"] myengine = "mypackage.xcheck_engine:MyEngine"``
ENTRY_POINT_GROUP = "xcheck.engines"
#: the engines xcheck ships, in the order tables show them ("module:class")
_BUILT_IN = (
    "xcheck.formulations.engine:Formulations",
    "xcheck.engines.mujoco:MuJoCo",
    "xcheck.engines.pinocchio:Pinocchio",
    "xcheck.engines.pymunk:Pymunk",
    "xcheck.engines.exudyn:Exudyn",
    "xcheck.engines.pybullet:PyBullet",
    "xcheck.engines.drake:Drake",
    "xcheck.engines.mjx:MJX",
    "xcheck.engines.opensim:OpenSim",
    "xcheck.engines.dart:Dart",
    "xcheck.engines.newton:Newton",
)

_registered: dict[str, Engine] = {}
#: names of the engines :func:`register` added in this process (absent from a spawned worker)
_at_run_time: set[str] = set()
_loaded = False
#: entry points that could not be loaded: name -> reason (shown by ``xcheck list`` and ``engines``)
_problems: dict[str, str] = {}
#: entry points not to load, with the reason (:func:`skip_entry_points`)
_skipped: dict[str, str] = {}


def _instance(target: object) -> Engine:
    engine = target() if isinstance(target, type) else target
    if not isinstance(engine, Engine):
        raise TypeError(f"expected an xcheck.engines.Engine, found {type(engine).__name__}")
    return engine


def _load() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for spec in _BUILT_IN:
        module, _, name = spec.partition(":")
        _add(_instance(getattr(importlib.import_module(module), name)))
    if not _may_declare_plug_ins():
        return
    for point in _declared_entry_points():
        if point.name in _skipped:
            _problems[point.name] = _skipped[point.name]
            continue
        try:
            _add(_load_plug_in(point, _plug_in_timeout()))
        except Exception as error:  # noqa: BLE001 - a broken plug-in is reported, xcheck still runs
            _problems[point.name] = _reason(error)


class _NotLoaded(Exception):
    """A plug-in that could not be loaded; the message says why."""


def _declared_entry_points() -> list:
    """The entry points of :data:`ENTRY_POINT_GROUP` of every installed
    distribution (the first of each name on the path, as
    :func:`importlib.metadata.entry_points` takes them).

    A distribution whose metadata cannot be read (a malformed
    ``entry_points.txt``, bytes that are not text) is left out: it is listed
    in :func:`load_problems` if its file names the group, and skipped silently
    otherwise, as the other packages' business.
    """
    from importlib import metadata

    found: list = []
    seen: set[str] = set()
    for distribution in metadata.distributions():
        key = getattr(distribution, "_normalized_name", None)  # how metadata tells two copies apart
        if key is not None:
            if key in seen:
                continue
            seen.add(key)
        folder = getattr(distribution, "_path", None)  # a folder on the path (not a zip file)
        if isinstance(folder, Path):
            try:
                if _entry_points_file(folder) is None:
                    continue  # declares no entry points
            except OSError as error:
                _problems[str(folder)] = f"its entry_points.txt cannot be read ({error.strerror or error})"
                continue
        try:
            found.extend(distribution.entry_points.select(group=ENTRY_POINT_GROUP))
        except Exception as error:  # noqa: BLE001 - another package's broken metadata must not stop xcheck
            try:
                declared = ENTRY_POINT_GROUP in (distribution.read_text("entry_points.txt") or "")
            except Exception:  # noqa: BLE001 - not even text: it cannot declare the group readably
                declared = False
            if declared:
                where = getattr(distribution, "_path", None) or key or "a distribution"
                _problems[f"{where}"] = f"its entry_points.txt cannot be read ({_reason(error)})"
    return found


def _load_plug_in(point, timeout: float) -> Engine:
    """The engine an entry point names, imported and made in a thread of its own.

    Whatever the import does is confined to that thread: an exception of any
    kind, ``sys.exit()`` and a ``KeyboardInterrupt`` it raises itself become
    :class:`_NotLoaded` with the reason, and so does an import still running
    after ``timeout`` seconds (it is interrupted where it runs Python code, and
    left to finish alone where it sleeps in a call). A real Ctrl-C reaches this
    (the main) thread while it waits and stops xcheck as anywhere else.
    """
    import threading

    loaded: list[Engine] = []
    failed: list[BaseException] = []

    def load() -> None:
        try:
            loaded.append(_instance(point.load()))
        except BaseException as error:  # noqa: BLE001 - SystemExit and the plug-in's own KeyboardInterrupt too
            failed.append(error)

    worker = threading.Thread(target=load, name=f"xcheck plug-in {point.name}", daemon=True)
    worker.start()
    # joined in short slices: the kernel may hand a Ctrl-C to the plug-in's thread,
    # and the main thread, blocked in one long join, would not raise it until the timeout
    deadline = time.monotonic() + timeout
    while worker.is_alive() and time.monotonic() < deadline:
        worker.join(min(0.05, max(0.0, deadline - time.monotonic())))
    if worker.is_alive():
        _interrupt(worker)
        raise _NotLoaded(f"its import did not finish within {timeout:g} s (${TIMEOUT_ENV} sets the limit)")
    if failed:
        raise _NotLoaded(_reason(failed[0]))
    return loaded[0]


def _interrupt(thread) -> None:
    """Raise :class:`_NotLoaded` in ``thread`` at its next Python instruction (CPython)."""
    import ctypes

    if thread.ident is not None:
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident), ctypes.py_object(_NotLoaded))


def _reason(error: BaseException, limit: int = 200) -> str:
    """Why a plug-in could not be loaded, in one line."""
    if isinstance(error, _NotLoaded):
        return str(error)
    if isinstance(error, SystemExit):
        return f"its import called sys.exit({error.code!r})"
    try:
        message = str(error)
    except Exception:  # noqa: BLE001 - an exception whose message itself fails
        message = ""
    line = f"{type(error).__name__}: {' '.join(message.split())}" if message.strip() else type(error).__name__
    return line if len(line) <= limit else line[: limit - 1] + "…"


#: the environment variable that sets how long a plug-in's import may take (seconds)
TIMEOUT_ENV = "XCHECK_PLUGIN_TIMEOUT"
#: how long a plug-in's import may take where $XCHECK_PLUGIN_TIMEOUT does not say (seconds)
PLUG_IN_TIMEOUT = 30.0


def _plug_in_timeout() -> float:
    """$XCHECK_PLUGIN_TIMEOUT where it is a number of seconds above 0, else :data:`PLUG_IN_TIMEOUT`."""
    try:
        value = float(os.environ.get(TIMEOUT_ENV, ""))
    except ValueError:
        return PLUG_IN_TIMEOUT
    return value if 0.0 < value < 1e6 else PLUG_IN_TIMEOUT


def skip_entry_points(reasons: dict[str, str]) -> None:
    """Leave these entry points unloaded in this process, each listed with its
    reason (a worker process is told which ones its parent could not load, so
    that it does not wait for a hanging import again)."""
    _skipped.update(reasons)


def _may_declare_plug_ins() -> bool:
    """False only where no installed distribution can declare an entry point
    of ``ENTRY_POINT_GROUP``.

    Importing :mod:`importlib.metadata` and scanning every distribution takes
    40 ms, a tenth of ``xcheck list``. Distributions on the path are folders
    named ``*.dist-info`` or ``*.egg-info`` with an ``entry_points.txt``;
    reading those for the group's name takes 2 ms. Where the path holds
    anything else metadata could look in (a zip file, an egg, a finder of its
    own on ``sys.meta_path``), the answer is True and metadata decides.
    """
    from importlib.machinery import PathFinder

    if any(finder is not PathFinder and hasattr(finder, "find_distributions") for finder in sys.meta_path):
        return True
    group = ENTRY_POINT_GROUP.encode()
    for entry in sys.path:
        folder = entry or "."
        if os.path.isfile(folder) or folder.lower().endswith(".egg"):
            return True  # a zip file, or an egg whose metadata lies in EGG-INFO
        try:
            listing = os.scandir(folder)
        except OSError:
            continue  # no such folder: nothing to find there
        with listing:
            for item in listing:
                if item.name.endswith((".dist-info", ".egg-info")) and item.is_dir():
                    try:
                        declared = _entry_points_file(Path(item.path))
                    except OSError:
                        return True  # a FIFO, a device, a giant: the full scan names it
                    if declared is not None and group in declared:
                        return True
    return False


#: the largest entry_points.txt read, bytes (a package's own holds a few hundred)
_MAX_ENTRY_POINTS_BYTES = 1 << 20


def _entry_points_file(folder: Path) -> bytes | None:
    """The ``entry_points.txt`` of a distribution's folder; None where there is none.

    Raises
    ------
    OSError
        Where it is no regular file (a FIFO would block for ever, a device never
        end) or larger than :data:`_MAX_ENTRY_POINTS_BYTES`.
    """
    from ..fileio import read_bounded

    try:
        return read_bounded(folder / "entry_points.txt", _MAX_ENTRY_POINTS_BYTES)[0]
    except FileNotFoundError:
        return None


def _add(engine: Engine, replace: bool = False) -> None:
    if not engine.name:
        raise ValueError(f"{type(engine).__name__}: an engine needs a name")
    if engine.name in (ALL, "native"):
        raise ValueError(f"{type(engine).__name__}: {engine.name!r} is a reserved name (an --engines selection)")
    if engine.name in _registered and not replace:
        raise ValueError(f"an engine named {engine.name!r} is already registered")
    taken = {m.name: e.name for e in _registered.values() if e.name != engine.name for m in e.modes}
    for m in engine.modes:
        if m.kind not in KINDS:
            raise ValueError(
                f"{engine.name}: mode {m.name!r}: expected a kind among {', '.join(KINDS)}, found {m.kind!r}"
            )
        if m.name in taken or m.name == "native":
            raise ValueError(f"{engine.name}: mode {m.name!r} is already provided by {taken.get(m.name, 'xcheck')}")
    _registered[engine.name] = engine


def register(engine: Engine | type[Engine], replace: bool = False) -> Engine:
    """Add an engine (an instance or a class) to the registry; returns the instance.

    Raises
    ------
    ValueError
        If its name or one of its modes' names is taken (unless ``replace``).
    """
    _load()
    instance = _instance(engine)
    _add(instance, replace)
    _at_run_time.add(instance.name)
    return instance


def unregister(name: str) -> None:
    """Remove an engine (no error if absent)."""
    _load()
    _registered.pop(name, None)
    _at_run_time.discard(name)


def engines() -> tuple[Engine, ...]:
    """Every registered engine, built-in first."""
    _load()
    return tuple(_registered.values())


def engine(name: str) -> Engine:
    """An engine by name; ValueError listing the names if unknown."""
    _load()
    if name not in _registered:
        raise ValueError(f"expected an engine among {', '.join(_registered)}, found {name!r}")
    return _registered[name]


def modes(kinds: tuple[str, ...] = KINDS) -> tuple[Mode, ...]:
    """Every mode of these kinds (default: all) of every engine, in the order of
    :data:`KINDS` (kinematic, dynamic, free), each in engine order."""
    every = [m for e in engines() for m in e.modes if m.kind in kinds]
    return tuple(sorted(every, key=lambda m: KINDS.index(m.kind)))


def mode(name: str) -> Mode:
    """A mode by name; ValueError listing the names if unknown."""
    found = {m.name: m for m in modes()}
    if name not in found:
        raise ValueError(f"expected an engine mode among {', '.join(found)}, found {name!r}")
    return found[name]


def engine_of(mode_name: str) -> Engine:
    """The engine that provides a mode."""
    for e in engines():
        if any(m.name == mode_name for m in e.modes):
            return e
    raise ValueError(f"expected an engine mode among {', '.join(m.name for m in modes())}, found {mode_name!r}")


#: the ``--engines`` group of every mode, those run only on request included
ALL = "all"


def groups(kinds: tuple[str, ...] = KINDS) -> dict[str, tuple[str, ...]]:
    """``--engines`` shortcuts: each engine's name, each kind, and :data:`ALL`
    to their modes of these kinds (default: all kinds). An engine's group and
    ``all`` have every mode; a kind's leaves out the modes run only on request
    (:attr:`Mode.on_request`)."""
    found = {e.name: tuple(m.name for m in e.modes if m.kind in kinds) for e in engines()}
    found = {name: chosen for name, chosen in found.items() if chosen and name != ALL}
    for kind in kinds:
        found.setdefault(kind, tuple(m.name for m in modes((kind,)) if not m.on_request))
    found[ALL] = tuple(m.name for m in modes(kinds))
    return found


def exporters() -> dict[str, Engine]:
    """File format -> the engine that writes it."""
    return {e.export_format: e for e in engines() if e.export_format}


def load_problems(load: bool = True) -> dict[str, str]:
    """Entry points that could not be loaded: name -> reason (the entry point's
    name, or the path of a distribution whose metadata cannot be read), by
    name; with ``load`` False, only if the registry has been loaded already."""
    if load:
        _load()
    return dict(sorted(_problems.items()))


def registered_at_run_time(name: str) -> bool:
    """Whether :func:`register` added (or replaced) this engine in this process:
    a worker process started afresh knows only the built-in engines and the
    entry points, so such an engine's modes run in the process that registered it."""
    return name in _at_run_time
