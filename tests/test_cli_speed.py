"""What keeps the command line quick, tested as behaviour (never timed):
imports only when used, the branch-map cache (hit, miss, corruption, results
unchanged)."""

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
def test_solve_from_the_cache_pulls_no_heavy_library(tmp_path):
    run = (
        "import sys\nfrom xcheck.cli import main\nsys.argv = ['xcheck', 'solve', 'fourbar']\n"
        "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code\n"
    )
    first = _modules_after(run, tmp_path)
    assert "scipy.optimize" in first  # the sketch was fitted: nothing cached yet
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


def test_cache_miss_for_another_file_content_and_when_off(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "c"))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    changed = tmp_path / "fourbar.toml"
    changed.write_text((MODELS / "fourbar.toml").read_text(encoding="utf-8") + "\n# a comment\n", encoding="utf-8")
    assert not cache.restore(Kinematics(load_mechanism(changed)))  # other bytes, other key
    assert cache.entry_path(Kinematics(load_mechanism(changed))) != cache.entry_path(computed)
    monkeypatch.setenv(cache.CACHE_ENV, "off")
    assert cache.cache_dir() is None
    assert not cache.store(_mapped("fourbar", branches=False)) and not cache.restore(Kinematics(computed.mechanism))


def test_cache_defaults_to_the_user_cache_dir(monkeypatch):
    import platformdirs

    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    assert cache.cache_dir() == Path(platformdirs.user_cache_dir("xcheck"))


def _corruptions(text: bytes) -> list[bytes]:
    header, _, payload = text.partition(b"\n")
    document = json.loads(payload)
    document["assembled"]["upper"][0] += 1e-3  # a configuration moved: checksum fixed, loops no longer closed
    moved = json.dumps(document).encode()
    import hashlib

    head = json.loads(header)
    head["sha256"] = hashlib.sha256(moved).hexdigest()
    resealed = json.dumps(head).encode() + b"\n" + moved
    return [
        b"",
        text[: len(text) // 2],  # truncated
        text.replace(b"0.", b"1.", 1),  # a digit changed: checksum fails
        b"not json\n" + payload,
        header + b"\n[1, 2, 3]",
        resealed,
    ]


def test_corrupt_entry_is_ignored_and_replaced(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path))
    computed = _mapped("fourbar", branches=False)
    assert cache.store(computed)
    entry = cache.entry_path(computed)
    assert entry is not None
    good = entry.read_bytes()
    for bad in _corruptions(good):
        entry.write_bytes(bad)
        fresh = Kinematics(computed.mechanism)
        assert not cache.restore(fresh), bad[:60]
        assert not fresh._assembled and not fresh._ranges  # nothing of it taken
        fresh.input_range(0)  # computed again, and the entry replaced
        assert _same_map(fresh, computed)
        assert cache.store(fresh)
        assert entry.read_bytes() == good


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
    entries = sorted(tmp_path.glob("*.json"))
    assert len(entries) == len(list(MODELS.glob("*.toml")))
    second = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    assert second.stdout == first.stdout
    assert sorted(tmp_path.glob("*.json")) == entries
