"""A mechanism's branch map kept between runs, so that ``xcheck list``,
``solve`` and ``run`` do not fit its sketch and walk its feasible range again.

What is kept, per branch: the assembled configuration (the sketch fitted and
closed by Newton-Raphson, :meth:`Kinematics.assemble`) and, per driver, the
feasible range with the configurations its continuation walked through (the
branch's atlas, from which sweeps are predicted) and the change of the
configuration over one turn of a crank. These are the exact floats the solver
computed (JSON keeps every float64 digit), so a run from the cache gives the
same results, bit for bit, as one without.

An entry is a file named by the SHA-256 of the mechanism file's bytes,
xcheck's version, NumPy's version and the source of the code that computes
the map (so a changed solver never reads an old map). It lies in
``platformdirs.user_cache_dir("xcheck")``, or in ``$XCHECK_CACHE_DIR``
(``off`` turns the cache off): a line of JSON (the layout's number, the key,
the SHA-256 of what follows), then the map as JSON. An entry is written whole or not at all
(:func:`xcheck.fileio.write_atomic`) and is never trusted: one that cannot be
read, whose checksum or key does not match, whose shapes do not fit the
mechanism, or whose configurations do not close the mechanism's loops is
ignored (and replaced). A cache that cannot be written is no error: the map is
then computed on every call, as without a cache.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .fileio import write_atomic
from .kinematics import InputRange, Kinematics, converged_tolerance

__all__ = ["CACHE_ENV", "cache_dir", "entry_path", "restore", "store", "cached_kinematics"]

#: the environment variable that puts the cache elsewhere (a directory), or turns it off (``off``)
CACHE_ENV = "XCHECK_CACHE_DIR"
#: the layout of an entry; another value is a miss
FORMAT = 1
#: the modules whose code computes what is cached: their source is part of the key
_CODE = (
    "kinematics/_solve.py",
    "kinematics/_newton.py",
    "kinematics/_system.py",
    "model/_load.py",
    "model/_mechanism.py",
    "units.py",
)
_code_digest: str | None = None


def cache_dir() -> Path | None:
    """The directory of the entries: ``$XCHECK_CACHE_DIR``, else the user's
    cache directory for xcheck; None when ``$XCHECK_CACHE_DIR`` is ``off``."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen:
        return None if chosen.strip().lower() == "off" else Path(chosen)
    import platformdirs

    return Path(platformdirs.user_cache_dir("xcheck"))


def _code() -> str:
    """SHA-256 of the source of the modules that compute the map."""
    global _code_digest
    if _code_digest is None:
        digest = hashlib.sha256()
        here = Path(__file__).resolve().parent
        for name in _CODE:
            try:
                digest.update((here / name).read_bytes())
            except OSError:  # installed without sources: the version alone keys the code
                digest.update(name.encode())
        _code_digest = digest.hexdigest()
    return _code_digest


def _key(kin: Kinematics) -> str | None:
    """The entry's key: SHA-256 of the file's bytes and of what computes the
    map; None for a mechanism that was not read from a file."""
    try:
        data = Path(kin.mechanism.path).read_bytes()
    except (OSError, ValueError):
        return None
    digest = hashlib.sha256(data)
    digest.update(f"\0xcheck {__version__}\0numpy {np.__version__}\0{_code()}".encode())
    return digest.hexdigest()


def entry_path(kin: Kinematics) -> Path | None:
    """Where the entry of a mechanism lies (None when there is no cache or no file)."""
    directory = cache_dir()
    key = _key(kin)
    return None if directory is None or key is None else directory / f"{key}.json"


def _payload(kin: Kinematics) -> dict[str, Any]:
    """What a Kinematics knows of its branches, as JSON values."""
    ranges = []
    for (branch, k), rng in sorted(kin._ranges.items()):
        walked = kin._walked[(branch, k)]
        turn = kin._turns.get((branch, k))
        ranges.append(
            {
                "branch": branch,
                "driver": k,
                "name": rng.driver,
                "low": rng.low,
                "high": rng.high,
                "span": rng.span,
                "walked_inputs": [c for c, _ in walked],
                "walked_q": [q.tolist() for _, q in walked],
                "turn": None if turn is None else turn.tolist(),
            }
        )
    return {"assembled": {b: q.tolist() for b, q in sorted(kin._assembled.items())}, "ranges": ranges}


def _known(kin: Kinematics) -> tuple[frozenset, frozenset]:
    """Which branches and ranges ``kin`` has computed (or restored)."""
    return frozenset(kin._assembled), frozenset(kin._ranges)


def store(kin: Kinematics) -> bool:
    """Write what ``kin`` has computed of its branches to its entry, if it
    knows more than the entry holds. Returns whether an entry was written;
    a cache that cannot be written is silently passed over."""
    if not kin._assembled or getattr(kin, "_cached", None) == _known(kin):
        return False  # nothing computed, or nothing new since the entry was read or written
    path = entry_path(kin)
    if path is None:
        return False
    try:
        payload = json.dumps(_payload(kin), allow_nan=False).encode()
        header = {"format": FORMAT, "key": path.stem, "sha256": hashlib.sha256(payload).hexdigest()}
        write_atomic(path, json.dumps(header).encode() + b"\n" + payload)
    except (OSError, ValueError):  # no cache directory to write in, or values JSON cannot hold
        return False
    kin._cached = _known(kin)  # type: ignore[attr-defined]
    return True


def restore(kin: Kinematics) -> bool:
    """Give ``kin`` the branch map of its entry, if there is a sound one.
    Returns whether it did; an unsound entry is ignored (see the module)."""
    path = entry_path(kin)
    if path is None:
        return False
    try:
        first, _, payload = path.read_bytes().partition(b"\n")
        header = json.loads(first)
        if header["format"] != FORMAT or header["key"] != path.stem:
            return False
        if header["sha256"] != hashlib.sha256(payload).hexdigest():
            return False  # truncated or altered
        assembled, ranges, walked, turns = _parse(kin, json.loads(payload))
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError):
        return False  # missing, unreadable, truncated or of another shape: a miss
    kin._assembled.update(assembled)
    kin._ranges.update(ranges)
    kin._walked.update(walked)
    kin._turns.update(turns)
    kin._cached = _known(kin)  # type: ignore[attr-defined]
    return True


def _parse(kin: Kinematics, payload: dict[str, Any]):
    """The entry's values as the solver keeps them, checked against the
    mechanism (shapes, branch and driver names, loops closed); ValueError if
    anything does not fit."""
    system, mech = kin.system, kin.mechanism
    n = system.n
    c_ref = kin.reference_inputs()
    branches = set(kin.branches)

    def configurations(values) -> np.ndarray:
        q = np.array(values, dtype=float)
        if q.ndim != 2 or q.shape[1] != n or not np.all(np.isfinite(q)):
            raise ValueError("configurations of another shape")
        return q

    def closed(q: np.ndarray, c: np.ndarray) -> None:
        gap = system.residual_metres(system.residual(q, c))
        if not np.all(gap <= converged_tolerance(system, q)):
            raise ValueError("configurations that do not close the loops")

    assembled = {}
    for branch, values in payload["assembled"].items():
        if branch not in branches:
            raise ValueError(f"unknown branch {branch!r}")
        q = configurations([values])
        closed(q, c_ref[None])
        assembled[branch] = q[0]
    ranges, walked, turns = {}, {}, {}
    for item in payload["ranges"]:
        branch, k = item["branch"], item["driver"]
        if branch not in assembled or not isinstance(k, int) or not 0 <= k < len(mech.drivers):
            raise ValueError("a range of an unknown branch or driver")
        if item["name"] != mech.drivers[k].name:
            raise ValueError("a range of another driver")
        low, high, span = item["low"], item["high"], float(item["span"])
        for bound in (low, high):
            if bound is not None and not (isinstance(bound, float | int) and np.isfinite(bound)):
                raise ValueError("a bound that is not a number")
        inputs = np.array(item["walked_inputs"], dtype=float)
        q = configurations(item["walked_q"])
        if inputs.shape != (q.shape[0],) or not np.all(np.isfinite(inputs)):
            raise ValueError("walked inputs of another shape")
        c = np.repeat(c_ref[None], len(inputs), axis=0)
        c[:, k] = inputs
        closed(q, c)
        ranges[(branch, k)] = InputRange(mech.drivers[k].name, low, high, span)
        walked[(branch, k)] = [(float(x), row) for x, row in zip(inputs, q)]
        if item["turn"] is not None:
            turns[(branch, k)] = configurations([item["turn"]])[0]
    return assembled, ranges, walked, turns


def cached_kinematics(mech) -> Kinematics:
    """A :class:`Kinematics` for ``mech`` with its branch map from the cache when there is one."""
    kin = Kinematics(mech)
    restore(kin)
    return kin
