"""A mechanism's branch map kept between runs, so that ``xcheck list``,
``solve`` and ``run`` do not fit its sketch and walk its feasible range again.

What is kept, per branch: the assembled configuration (the sketch fitted and
closed by Newton-Raphson, :meth:`Kinematics.assemble`) and, per driver, the
feasible range with the configurations its continuation walked through (the
branch's atlas, from which sweeps are predicted) and the change of the
configuration over one turn of a crank. These are the exact floats the solver
computed (JSON keeps every float64 digit), so a run from the cache gives the
same results, bit for bit, as one without.

An entry (:mod:`xcheck.store`: authenticated, made by the running code, read
safely) is named by the SHA-256 of the canonical mechanism (its model, not the
file's bytes: a comment or a reordered key changes nothing) and lies in the
``branch-maps`` folder of xcheck's cache directory. What it supplies is also
checked against the mechanism: shapes, branch and driver names, and loops
closed by every configuration. An entry that fails any check is ignored, said
so (the ``xcheck.cache`` logger) and replaced. A cache that cannot be written
is no error: the map is then computed on every call, as without a cache.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

from . import store as _store
from .kinematics import InputRange, Kinematics, converged_tolerance
from .store import CACHE_ENV, cache_dir

__all__ = ["CACHE_ENV", "KIND", "cache_dir", "entry_path", "restore", "store", "cached_kinematics"]

#: the folder of the branch maps in the cache directory
KIND = "branch-maps"
#: the largest entry read or written, bytes (the largest bundled map is about 2 MB)
MAX_BYTES = 64 * 2**20
log = logging.getLogger("xcheck.cache")


def _name(kin: Kinematics) -> str | None:
    """The entry's name: SHA-256 of the canonical mechanism (without the path it
    was read from); None where it cannot be digested."""
    return _store.mechanism_digest("branch map", kin.mechanism)


def entry_path(kin: Kinematics) -> Path | None:
    """Where the entry of a mechanism lies (None when there is no cache)."""
    name = _name(kin)
    return None if name is None else _store.entry_path(KIND, name)


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
    name = _name(kin)
    if name is None:
        return False
    try:
        payload = json.dumps(_payload(kin), allow_nan=False).encode()
    except ValueError:  # values JSON cannot hold
        return False
    if not _store.write(KIND, name, payload, _store.made_by(), "", MAX_BYTES):
        return False
    kin._cached = _known(kin)  # type: ignore[attr-defined]
    return True


def restore(kin: Kinematics) -> bool:
    """Give ``kin`` the branch map of its entry, if there is a sound one.
    Returns whether it did; an entry that is there but unsound is ignored and
    said so (see the module)."""
    name = _name(kin)
    if name is None:
        return False
    found = _store.read(KIND, name, _store.made_by(), MAX_BYTES)
    problem = found.problem
    if found.payload is not None:
        try:
            assembled, ranges, walked, turns = _parse(kin, json.loads(found.payload))
        except (ValueError, KeyError, TypeError, IndexError, AttributeError) as err:
            problem = f"{_store.entry_path(KIND, name)}: does not fit {kin.mechanism.name} ({err})"
        else:
            kin._assembled.update(assembled)
            kin._ranges.update(ranges)
            kin._walked.update(walked)
            kin._turns.update(turns)
            kin._cached = _known(kin)  # type: ignore[attr-defined]
            return True
    if problem and not (found.stale and problem == found.problem):
        log.warning("xcheck: cache: the branch map of %s: %s; computed again", kin.mechanism.name, problem)
    return False


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
