"""What keeps the command line quick, tested as behaviour (never timed):
imports only when used, the branch-map cache (hit, miss, corruption, edits,
entries that are no regular file, results unchanged)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS, ROOT

from xcheck import Kinematics, cache, load_mechanism

#: what a command that draws, fits, tabulates or runs an engine pulls in
HEAVY = ("matplotlib", "scipy.optimize", "pandas", "numba", "mujoco", "pinocchio", "pymunk", "exudyn", "pybullet")


def _modules_after(code: str, cache_dir: Path) -> set[str]:
    """The heavy modules loaded by running ``code`` in a fresh interpreter."""
    script = code + "\nimport sys\nprint('LOADED', *(m for m in sys.modules if m in " + repr(HEAVY) + "))"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), cache.CACHE_ENV: str(cache_dir)}
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return set(done.stdout.splitlines()[-1].split()[1:])


def test_import_cli_pulls_no_heavy_library(tmp_path):
    assert _modules_after("import xcheck.cli", tmp_path) == set()


def test_public_api_still_there_lazily(tmp_path):
    code = (
        "import xcheck\n"
        "assert callable(xcheck.load) and callable(xcheck.run) and callable(xcheck.simulate)\n"
        "assert xcheck.select_modes('formulations')[0] == 'native'\n"
        "from xcheck import Kinematics, Mechanism, load_mechanism, InputError\n"
    )
    assert not {"matplotlib", "numba"} & _modules_after(code, tmp_path)


@pytest.mark.slow
def test_solve_from_the_cache_pulls_no_heavy_library(tmp_path, monkeypatch):
    run = (
        "import sys\nfrom xcheck.cli import main\nsys.argv = ['xcheck', 'solve', 'fourbar']\n"
        "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code\n"
    )
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    entry = cache.entry_path(Kinematics(load_mechanism(MODELS / "fourbar.toml")))
    assert entry is not None and not entry.exists()
    first = _modules_after(run, tmp_path)
    assert entry.exists()  # the sketch was fitted and its map kept: nothing was cached before
    assert "scipy.optimize" not in first  # the sketch fitted without SciPy's optimisers
    assert _modules_after(run, tmp_path) == set()  # from the cache: no fit, no figures, no tables


def _mapped(name: str, branches: bool = True) -> Kinematics:
    kin = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
    for branch in kin.branches if branches else kin.branches[:1]:
        for k in range(len(kin.mechanism.drivers)):
            kin.input_range(k, branch)
    return kin


def _same_map(a: Kinematics, b: Kinematics) -> bool:
    return (
        a._assembled.keys() == b._assembled.keys()
        and all(np.array_equal(a._assembled[k], b._assembled[k]) for k in a._assembled)
        and a._ranges == b._ranges
        and a._walked.keys() == b._walked.keys()
        and all(
            [c for c, _ in a._walked[k]] == [c for c, _ in b._walked[k]]
            and np.array_equal(np.array([q for _, q in a._walked[k]]), np.array([q for _, q in b._walked[k]]))
            for k in a._walked
        )
        and a._turns.keys() == b._turns.keys()
        and all(np.array_equal(a._turns[k], b._turns[k]) for k in a._turns)
    )


@pytest.mark.parametrize("name", ["fourbar", "slider-crank", "two-body-arm"])
def test_cache_hit_gives_the_same_map_bit_for_bit(name, tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    computed = _mapped(name)
    assert cache.store(computed)
    assert not cache.store(computed)  # nothing new: not written again
    restored = Kinematics(computed.mechanism)
    assert cache.restore(restored)
    assert _same_map(computed, restored)
    assert restored.solve(np.linspace(0.1, 0.2, 5) if name != "two-body-arm" else [[0.5, 0.5]]).q.tolist() == (
        computed.solve(np.linspace(0.1, 0.2, 5) if name != "two-body-arm" else [[0.5, 0.5]]).q.tolist()
    )


def test_cache_is_keyed_by_the_mechanism_not_the_file_bytes(tmp_path, monkeypatch):
    """A comment or a reordered table leaves the canonical mechanism as it was: the
    entry is found; a changed value is another mechanism: a miss."""
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "c"))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    text = (MODELS / "fourbar.toml").read_text(encoding="utf-8")
    commented = tmp_path / "commented.toml"
    commented.write_text("# a comment before everything\n" + text + "\n# and one after\n", encoding="utf-8")
    restored = Kinematics(load_mechanism(commented))
    assert cache.entry_path(restored) == cache.entry_path(computed)
    assert cache.restore(restored) and _same_map(restored, computed)
    assert "\ncrank = 60\n" in text
    changed = tmp_path / "changed.toml"
    changed.write_text(text.replace("\ncrank = 60\n", "\ncrank = 61\n"), encoding="utf-8")  # assembled elsewhere
    other = Kinematics(load_mechanism(changed))
    assert cache.entry_path(other) != cache.entry_path(computed) and not cache.restore(other)


def test_cache_off(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "c"))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    monkeypatch.setenv(cache.CACHE_ENV, "off")
    assert cache.cache_dir() is None
    assert not cache.store(_mapped("fourbar", branches=False)) and not cache.restore(Kinematics(computed.mechanism))


def test_cache_defaults_to_the_user_cache_dir(monkeypatch):
    import platformdirs

    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    assert cache.cache_dir() == Path(platformdirs.user_cache_dir("xcheck"))


def _corruptions(text: bytes) -> list[bytes]:
    """Entries that must not be used: damaged, or edited with their header kept
    (a checksum anyone can recompute would let the last two through)."""
    header, _, payload = text.partition(b"\n")
    document = json.loads(payload)
    document["assembled"]["upper"], document["assembled"]["lower"] = (
        document["assembled"]["lower"],
        document["assembled"]["upper"],
    )  # the branches swapped: each still closes the loops
    swapped = json.dumps(document).encode()
    head = json.loads(header)
    head["length"] = len(swapped)
    return [
        b"",
        text[: len(text) // 2],  # truncated
        text.replace(b"0.", b"1.", 1),  # a digit changed
        b"not json\n" + payload,
        header + b"\n[1, 2, 3]",
        json.dumps(head).encode() + b"\n" + swapped,  # edited, its length fixed
    ]


def test_corrupt_or_edited_entry_is_ignored_said_and_replaced(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    computed = _mapped("fourbar")
    assert cache.store(computed)
    entry = cache.entry_path(computed)
    assert entry is not None
    good = entry.read_bytes()
    for bad in _corruptions(good):
        entry.write_bytes(bad)
        fresh = Kinematics(computed.mechanism)
        caplog.clear()
        assert not cache.restore(fresh), bad[:60]
        assert not fresh._assembled and not fresh._ranges  # nothing of it taken
        assert [r.getMessage() for r in caplog.records if "branch map of fourbar" in r.getMessage()], bad[:60]
        for branch in fresh.branches:  # computed again, and the entry replaced
            fresh.input_range(0, branch)
        assert _same_map(fresh, computed)
        assert cache.store(fresh)
        assert entry.read_bytes() == good


def test_entry_of_other_code_or_another_key_is_not_used(tmp_path, monkeypatch):
    """An entry made by other code (another version or source) is a miss, replaced
    quietly; one signed with another cache's key (copied from elsewhere) fails its
    authentication."""
    from xcheck import store

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    entry = cache.entry_path(computed)
    name = entry.stem
    made = store.made_by()
    assert store.read(cache.KIND, name, made, cache.MAX_BYTES).hit
    for field in ("xcheck", "source", "numpy"):
        found = store.read(cache.KIND, name, {**made, field: "other"}, cache.MAX_BYTES)
        assert not found.hit and found.stale and field in found.problem
    (tmp_path / store.KEY_NAME).unlink()  # a fresh key: this entry was signed elsewhere
    assert store.write(cache.KIND, "0" * 64, b"x", made, "", 10)  # makes the new key
    found = store.read(cache.KIND, name, made, cache.MAX_BYTES)
    assert not found.hit and not found.stale and "authentication failed" in found.problem
    assert not cache.restore(Kinematics(computed.mechanism))


@pytest.mark.parametrize("kind", ["fifo", "link to /dev/zero", "folder", "too large", "link to an entry"])
def test_an_entry_that_is_no_regular_file_or_too_large_is_not_read(kind, tmp_path, monkeypatch, caplog):
    """A FIFO at the entry's path would block open() forever, /dev/zero would be read
    until memory runs out, a huge file read whole: each is refused at once, said so,
    and the map computed; a link is not followed, even to a sound entry."""
    import os

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    entry = cache.entry_path(computed)
    sound = tmp_path / "sound.entry"
    os.replace(entry, sound)
    if kind == "fifo":
        os.mkfifo(entry)
    elif kind == "link to /dev/zero":
        entry.symlink_to("/dev/zero")
    elif kind == "folder":
        entry.mkdir()
    elif kind == "too large":
        with open(entry, "wb") as huge:
            huge.truncate(cache.MAX_BYTES + 2**20)  # sparse: no disk used
    else:
        entry.symlink_to(sound)
    fresh = Kinematics(computed.mechanism)
    assert not cache.restore(fresh) and not fresh._assembled
    assert any("branch map of fourbar" in r.getMessage() for r in caplog.records)
    fresh.input_range(0)
    assert _same_map(fresh, computed)


def test_unwritable_cache_is_no_error(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv(cache.CACHE_ENV, str(blocker / "cache"))
    assert not cache.store(_mapped("fourbar", branches=False))


@pytest.mark.slow
def test_list_from_the_cache_prints_the_same(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), cache.CACHE_ENV: str(tmp_path)}
    command = [sys.executable, "-m", "xcheck", "list", "--json"]
    first = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    entries = sorted((tmp_path / cache.KIND).glob("*.entry"))
    assert len(entries) == len(list(MODELS.glob("*.toml")))
    second = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    assert second.stdout == first.stdout and second.stderr == ""
    assert sorted((tmp_path / cache.KIND).glob("*.entry")) == entries
