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

from ._contract import KINDS, Engine, Mode

__all__ = [
    "ENTRY_POINT_GROUP",
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
)

_registered: dict[str, Engine] = {}
#: names of the engines :func:`register` added in this process (absent from a spawned worker)
_at_run_time: set[str] = set()
_loaded = False
#: entry points that could not be loaded: name -> reason (shown by ``xcheck list``)
_problems: dict[str, str] = {}


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
    from importlib import metadata

    for point in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            _add(_instance(point.load()))
        except Exception as error:  # noqa: BLE001 - a broken plug-in is reported, xcheck still runs
            _problems[point.name] = f"{type(error).__name__}: {error}".splitlines()[0]


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
                        with open(os.path.join(item.path, "entry_points.txt"), "rb") as declared:
                            if group in declared.read():
                                return True
                    except OSError:
                        continue  # declares no entry points
    return False


def _add(engine: Engine, replace: bool = False) -> None:
    if not engine.name:
        raise ValueError(f"{type(engine).__name__}: an engine needs a name")
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


def groups(kinds: tuple[str, ...] = KINDS) -> dict[str, tuple[str, ...]]:
    """``--engines`` shortcuts: each engine's name, and each kind, to its modes
    of these kinds (default: all). An engine's group has every mode of it; a
    kind's leaves out the modes run only on request (:attr:`Mode.on_request`)."""
    found = {e.name: tuple(m.name for m in e.modes if m.kind in kinds) for e in engines()}
    found = {name: chosen for name, chosen in found.items() if chosen}
    for kind in kinds:
        found.setdefault(kind, tuple(m.name for m in modes((kind,)) if not m.on_request))
    return found


def exporters() -> dict[str, Engine]:
    """File format -> the engine that writes it."""
    return {e.export_format: e for e in engines() if e.export_format}


def load_problems() -> dict[str, str]:
    """Entry points that could not be loaded: name -> reason."""
    _load()
    return dict(_problems)


def registered_at_run_time(name: str) -> bool:
    """Whether :func:`register` added (or replaced) this engine in this process:
    a worker process started afresh knows only the built-in engines and the
    entry points, so such an engine's modes run in the process that registered it."""
    return name in _at_run_time
