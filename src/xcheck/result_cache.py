"""The results cache: each mode's outcome on a mechanism kept between runs, as
build tools keep what they built, so that a repeated ``xcheck run``, or ``run
all`` after one file changed, computes only what changed.

An entry (:mod:`xcheck.store`: authenticated, read safely, lying in the
``results`` folder of xcheck's cache directory) is named by the SHA-256 of
everything that determines a mode's outcome: the canonical mechanism (its
model, with the path it was read from, which messages name: not the file's
bytes, so a comment changes nothing), the mode, the samples and the branch.
What computed it must be what runs now (:func:`xcheck.store.made_by`:
xcheck's version and a digest of its source, the numerical libraries, and the
engine's packages; for an engine from another package, a digest of that
package's source too), else it is recomputed. Only outcomes that ran through
(or a mode that does not apply) are kept: a failure may be the machine's.

The cache is read and written by :func:`xcheck.runner.run_mechanism` unless
told not to (``--no-cache``), or where ``$XCHECK_RESULTS_CACHE`` is ``off``
(or ``$XCHECK_CACHE_DIR``, every cache). Each outcome says whether it came
from the cache and when it was computed (:class:`Provenance`); an entry that
was there but could not be used is said so (the ``xcheck.cache`` logger) and
replaced.
"""

from __future__ import annotations

import datetime
import logging
import os
import pickle
import sys
from dataclasses import dataclass
from pathlib import Path

from . import store

__all__ = [
    "RESULTS_ENV",
    "KIND",
    "FIGURES",
    "Provenance",
    "enabled",
    "lookup",
    "keep",
    "summary",
    "provenance_json",
    "run_identity",
    "holds",
    "cached_figure",
    "keep_figure",
]

#: the environment variable that turns the results cache off (``off``) while other caches stay on
RESULTS_ENV = "XCHECK_RESULTS_CACHE"
#: the folder of the results in the cache directory
KIND = "results"
#: the largest entry read or written, bytes (a dynamic mode's ladder on the bundled mechanisms: under 4 MB)
MAX_BYTES = 256 * 2**20
#: the folder of the reports' figures in the cache directory
FIGURES = "figures"
#: the largest figure read or written, bytes (the bundled mechanisms' largest: about 0.5 MB)
MAX_FIGURE_BYTES = 64 * 2**20
log = logging.getLogger("xcheck.cache")


@dataclass(frozen=True)
class Provenance:
    """Where a mode's outcome came from.

    Attributes
    ----------
    from_cache : bool
        Read from the results cache rather than computed in this run.
    computed_at : str
        When it was computed (UTC, ISO 8601 to the second); "" where it was
        computed in this run and not kept.
    recomputed : str
        Why an entry that was there was not used ("" where none was, or it was).
    identity : str
        The entry's authentication code ("" where none was written or read):
        equal identities, equal outcomes.
    """

    from_cache: bool = False
    computed_at: str = ""
    recomputed: str = ""
    identity: str = ""


def enabled() -> bool:
    """Whether the results cache is on: a cache directory, and ``$XCHECK_RESULTS_CACHE`` not ``off``."""
    return os.environ.get(RESULTS_ENV, "").strip().lower() != "off" and store.cache_dir() is not None


def _engine_code(engine) -> dict[str, str] | None:
    """What of an engine's code keys its results beyond xcheck's own: its
    packages' versions, and for an engine outside xcheck the digest of its
    module's package; None where that code cannot be read (an engine defined
    in a notebook or at the prompt: never cached)."""
    made = {f"{engine.name} {name}": store.version(name) for name in engine.distributions}
    module = type(engine).__module__
    if module == "xcheck" or module.startswith("xcheck."):
        return made
    top = sys.modules.get(module.partition(".")[0])
    origin = getattr(top, "__file__", None)
    if not origin:
        return None
    path = Path(origin)
    files = sorted(path.parent.rglob("*.py")) if path.name == "__init__.py" else [path]
    try:
        made[f"{engine.name} source"] = store.digest(
            *((f.relative_to(path.parent).as_posix(), f.read_bytes()) for f in files)
        )
    except OSError:
        return None
    return made


def _entry(kinematics, parts: tuple, engines_used) -> tuple[str, dict[str, str]] | None:
    """The entry's name (SHA-256 of the mechanism and ``parts``) and what must
    have made it; None where the mechanism cannot be digested or an engine's
    code cannot be read."""
    try:
        name = store.digest("outcome", kinematics.mechanism, *parts)
    except TypeError:
        return None
    made = store.made_by()
    for engine in engines_used:
        extra = _engine_code(engine)
        if extra is None:
            return None
        made.update(extra)
    return name, made


def lookup(kinematics, label: str, parts: tuple, engines_used=()):
    """What the cache holds for ``parts`` (a mode's name, samples and branch;
    or what else the runner keeps) on this mechanism: ``(value, provenance)``,
    the value None on a miss. ``engines_used``: the engines whose code made it;
    ``label`` names it in messages."""
    entry = _entry(kinematics, parts, engines_used)
    if entry is None:
        return None, Provenance()
    name, made = entry
    found = store.read(KIND, name, made, MAX_BYTES)
    problem = found.problem
    if found.payload is not None:
        from ._parallel import picklable_mechanisms

        picklable_mechanisms()
        try:
            value = pickle.loads(found.payload)  # authenticated: written by this user's xcheck, this code
        except Exception as err:  # noqa: BLE001 - an entry that does not load is a miss, said so
            problem = f"{store.entry_path(KIND, name)}: could not be read back ({type(err).__name__})"
        else:
            return value, Provenance(True, str(found.meta.get("computed_at", "")), "", found.meta["mac"])
    if problem and not (found.stale and problem == found.problem):
        log.warning("xcheck: cache: %s of %s: %s; computed again", label, kinematics.mechanism.name, problem)
    return None, Provenance(recomputed=problem)


def holds(mechanism, modes, samples: int, branch: str | None) -> bool:
    """Whether the cache has an entry for every mode of ``modes`` (but "native",
    and those whose engine is not installed) on ``mechanism``: a quick look at
    the folder (nothing read), for where a run should go (a worker process
    pays its start for nothing when every result is already there)."""
    from . import engines

    if not enabled():
        return False
    branches = list(mechanism.assembly.branches)
    chosen = branch if branch is not None else (branches[0] if branches else None)
    try:
        for mode in modes:
            if mode == "native" or engines.engine_of(mode).available():
                continue
            name = store.digest("outcome", mechanism, mode, int(samples), chosen)
            path = store.entry_path(KIND, name)
            if path is None or not path.is_file():
                return False
    except TypeError:
        return False
    return True


def keep(kinematics, parts: tuple, engines_used, value, recomputed: str = "") -> Provenance:
    """Write ``value`` for ``parts`` (as :func:`lookup`) to the cache; returns
    its provenance (with the entry's identity where it was written)."""
    entry = _entry(kinematics, parts, engines_used)
    if entry is None:
        return Provenance(recomputed=recomputed)
    name, made = entry
    from ._parallel import picklable_mechanisms

    picklable_mechanisms()
    try:
        payload = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - a value that does not pickle is simply not kept
        return Provenance(recomputed=recomputed)
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    identity = store.write(KIND, name, payload, made, now, MAX_BYTES)
    return Provenance(False, now if identity else "", recomputed, identity)


def summary(provenance: dict[str, Provenance]) -> str:
    """One line naming the results taken from the cache and when they were
    computed ("" where none was): what the terminal says (a report's evidence
    keeps each time; its text is the same either way)."""
    times: dict[str, list[str]] = {}
    for name, where in provenance.items():
        if where.from_cache:
            times.setdefault(where.computed_at.replace("T", " ").replace("Z", " UTC"), []).append(name)
    if not times:
        return ""
    parts = [f"{', '.join(names)} (computed {when or 'at an unknown time'})" for when, names in sorted(times.items())]
    return "from the results cache: " + "; ".join(parts) + "; --no-cache computes them again"


def provenance_json(provenance: dict[str, Provenance]) -> dict:
    """The JSON of a run's provenance: ``from_cache`` (name to when it was
    computed, UTC) and ``recomputed`` (name to why the entry there was not used)."""
    return {
        "from_cache": {name: p.computed_at for name, p in provenance.items() if p.from_cache},
        "recomputed": {name: p.recomputed for name, p in provenance.items() if p.recomputed},
    }


def run_identity(run) -> str | None:
    """A digest of everything a run's report figures are drawn from, where
    every result of the run has an identity in the results cache (read from
    it, or kept in it by this run); None otherwise (nothing then is cached of
    its figures). Equal identities, equal figures."""
    parts = []
    for mode in run.outcomes:
        if mode != "native":
            where = run.provenance.get(mode)
            if where is None or not where.identity:
                return None
            parts.append((mode, where.identity))
    if run.native_forces is not None:
        where = run.provenance.get("forces")
        if where is None or not where.identity:
            return None
        parts.append(("forces", where.identity))
    try:
        return store.digest(
            "run",
            run.kinematics.mechanism,
            int(run.native.inputs.shape[0]),
            run.branch,
            parts,
            dict(run.not_applicable),
            run.no_forces,
            run.no_energy,
            run.textbook,
        )
    except TypeError:
        return None


def _figure_maker() -> dict[str, str]:
    return {**store.made_by("matplotlib", "pillow")}


def cached_figure(identity: str, function: str) -> tuple[bool, bytes | None]:
    """``(found, bytes)`` of a report figure (the name of its function in
    :mod:`xcheck.report._figures`) of the run ``identity``; bytes None where
    the run has nothing to show there. An entry that cannot be used is said so."""
    name = store.digest("figure", identity, function)
    found = store.read(FIGURES, name, _figure_maker(), MAX_FIGURE_BYTES)
    if found.payload is not None:
        return True, found.payload[1:] if found.payload[:1] == b"+" else None
    if found.problem and not found.stale:
        log.warning("xcheck: cache: the figure %s: %s; drawn again", function, found.problem)
    return False, None


def keep_figure(identity: str, function: str, data: bytes | None) -> None:
    """Keep a report figure of the run ``identity`` (see :func:`cached_figure`)."""
    payload = b"-" if data is None else b"+" + data
    store.write(FIGURES, store.digest("figure", identity, function), payload, _figure_maker(), "", MAX_FIGURE_BYTES)
