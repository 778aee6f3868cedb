"""The results cache (xcheck.result_cache): the same results with and without it, an
entry that is corrupt, edited, signed elsewhere or made by other code is
computed again (and, but for the last, said so), keyed by the canonical
mechanism, and shown, cleared and turned off as documented."""

from __future__ import annotations

import json
import pickle

import pytest
from conftest import MODELS, invoke, results_cache_on

from xcheck import result_cache, store

#: few samples, the bundled models
ARGS = ("--samples", "21", "--models", str(MODELS))


@pytest.fixture
def cache_on(tmp_path, monkeypatch):
    """The results cache on, in a folder of this test's own (through ``monkeypatch``,
    so that a test's own ``monkeypatch`` of the same variables is undone first)."""
    monkeypatch.setenv(store.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(result_cache.RESULTS_ENV)
    return tmp_path / "cache"


def _run(*args: str) -> tuple[dict, str]:
    done = invoke("run", "fourbar", "--json", *ARGS, *args)
    assert done.returncode in (0, 1) and "Traceback" not in done.stderr, done.stderr
    return json.loads(done.stdout), done.stderr


def _without_timings_and_cache(document: dict) -> dict:
    return {k: v for k, v in document.items() if k not in ("timings", "cache")}


@pytest.mark.slow
def test_the_same_results_and_report_with_and_without_the_cache(cache_on, tmp_path):
    """Twice with the cache (the second run takes every mode, the reactions and the
    report's figures from it: none is drawn again) and once with --no-cache: the JSON
    is the same but for timings and the cache's fields, and so are the reports'
    figures, byte for byte, and their Markdown; the terminal and the report's
    evidence say what came from the cache, and when it was computed."""
    out = {name: tmp_path / name for name in ("first", "second", "none")}
    first, _ = _run("--report", "--out", str(out["first"]), "--no-gif")
    figures = {p: p.stat().st_mtime_ns for p in (cache_on / result_cache.FIGURES).glob("*.entry")}
    assert len(figures) == 5  # drawing, quantities, differences, convergence, forces: kept for the next run
    second, _ = _run("--report", "--out", str(out["second"]), "--no-gif")
    assert {p: p.stat().st_mtime_ns for p in (cache_on / result_cache.FIGURES).glob("*.entry")} == figures
    fresh, _ = _run("--report", "--out", str(out["none"]), "--no-gif", "--no-cache")
    modes = set(first["engines"]) - {"native"} | set(first["not_applicable"])
    assert first["cache"]["from_cache"] == {} and fresh["cache"] == {"from_cache": {}, "recomputed": {}}
    assert set(second["cache"]["from_cache"]) == modes | {"forces"}
    assert _without_timings_and_cache(second) == _without_timings_and_cache(first) == _without_timings_and_cache(fresh)
    for image in sorted(p.relative_to(out["first"]) for p in out["first"].rglob("*.png")):
        assert (out["second"] / image).read_bytes() == (out["none"] / image).read_bytes(), image
    # the report reads the same whichever way its results came; its evidence says when each was computed
    report = (out["second"] / "fourbar.md").read_text(encoding="utf-8")
    assert report.replace(str(out["second"]), "OUT") == (out["none"] / "fourbar.md").read_text(
        encoding="utf-8"
    ).replace(str(out["none"]), "OUT").replace(" --no-cache", "")
    evidence = json.loads((out["second"] / "fourbar" / "results.json").read_text(encoding="utf-8"))
    assert (
        evidence["modes"]["mujoco-kinematic"]["produced"]["computed"]
        == second["cache"]["from_cache"]["mujoco-kinematic"]
    )
    assert (
        "computed"
        not in json.loads((out["none"] / "fourbar" / "results.json").read_text(encoding="utf-8"))["modes"][
            "mujoco-kinematic"
        ]["produced"]
    )
    table = invoke("run", "fourbar", *ARGS, "--no-report")
    assert "from the results cache:" in table.stdout and "--no-cache computes them again" in table.stdout


def _entry(cache: object, mode: str) -> tuple:
    """The path of a mode's entry (found by the mode's name inside the payload) and its parts."""
    for path in sorted((cache / result_cache.KIND).glob("*.entry")):
        header, _, payload = path.read_bytes().partition(b"\n")
        value = pickle.loads(payload)
        if getattr(value, "mode", None) == mode:
            return path, json.loads(header), value
    raise AssertionError(f"no entry of {mode}")


def _signed(header: dict, payload: bytes, key: bytes) -> bytes:
    import hashlib
    import hmac

    header = {k: v for k, v in header.items() if k != "mac"}
    header["length"] = len(payload)
    signed = json.dumps(header, sort_keys=True, separators=(",", ":")).encode()
    header["mac"] = hmac.new(key, signed + b"\n" + payload, hashlib.sha256).hexdigest()
    return json.dumps(header, sort_keys=True).encode() + b"\n" + payload


def _edited(header: dict, value) -> bytes:
    """The entry with its error multiplied by ten and its header kept (length fixed)."""
    value.categories["max_abs"] = value.categories["max_abs"] * 10
    payload = pickle.dumps(value)
    head = dict(header, length=len(payload))
    return json.dumps(head, sort_keys=True).encode() + b"\n" + payload


@pytest.mark.parametrize("damage", ["truncated", "garbage", "numbers edited", "signed elsewhere", "other version"])
def test_a_damaged_or_foreign_entry_is_computed_again_and_said_so(cache_on, damage):
    """Each damaged entry gives the results computed afresh, not its own, names the
    entry and why on stderr (an entry of another version quietly: an upgrade is no
    fault), and is replaced: the next run takes it from the cache again."""
    engines = ("--engines", "mujoco-kinematic,formulation-II")
    reference, _ = _run(*engines)
    path, header, value = _entry(cache_on, "mujoco-kinematic")
    good = path.read_bytes()
    key = (cache_on / store.KEY_NAME).read_bytes()
    payload = good.partition(b"\n")[2]
    if damage == "truncated":
        bad = good[: len(good) // 2]
    elif damage == "garbage":
        bad = b"\x00garbage\n" + payload
    elif damage == "numbers edited":
        bad = _edited(header, value)
    elif damage == "signed elsewhere":
        bad = _signed(header, payload, b"k" * store.KEY_BYTES)
    else:
        made = dict(header["made_by"], xcheck="0.0.1")
        bad = _signed(dict(header, made_by=made), payload, key)
    path.write_bytes(bad)
    again, stderr = _run(*engines)
    assert "mujoco-kinematic" not in again["cache"]["from_cache"] and "formulation-II" in again["cache"]["from_cache"]
    assert "mujoco-kinematic" in again["cache"]["recomputed"]
    assert _without_timings_and_cache(again) == _without_timings_and_cache(reference)
    said = [line for line in stderr.splitlines() if "mujoco-kinematic of fourbar" in line]
    if damage == "other version":
        assert said == [] and "xcheck" in again["cache"]["recomputed"]["mujoco-kinematic"]
    else:
        assert len(said) == 1 and str(path) in said[0] and said[0].endswith("computed again"), stderr
    assert path.read_bytes() != bad
    third, _ = _run(*engines)
    assert "mujoco-kinematic" in third["cache"]["from_cache"]


def test_keyed_by_the_mechanism_not_the_file_bytes(cache_on, tmp_path):
    """A comment changes nothing: the results come from the cache; another value of
    the mechanism, other samples or another branch are other results."""
    folder = tmp_path / "models"
    folder.mkdir()
    path = folder / "fourbar.toml"
    text = (MODELS / "fourbar.toml").read_text(encoding="utf-8")
    path.write_text(text, encoding="utf-8")

    def run(*args: str) -> set:
        done = invoke("run", str(path), "--json", "--engines", "formulation-II", "--samples", "11", *args)
        assert done.returncode == 0, done.stderr
        return set(json.loads(done.stdout)["cache"]["from_cache"])

    assert run() == set()
    path.write_text("# a comment\n" + text, encoding="utf-8")
    assert run() == {"formulation-II", "forces"}
    assert run("--samples", "13") == {"forces"}  # the reactions are computed over the motion, not the sweep
    assert run("--branch", "lower") == set()
    path.write_text(text.replace("\ncrank = 60\n", "\ncrank = 61\n"), encoding="utf-8")
    assert run() == set()


def test_no_cache_reads_and_writes_nothing_and_clear_empties_it(cache_on):
    _run("--engines", "formulations", "--no-cache")
    assert not (cache_on / result_cache.KIND).exists()
    _run("--engines", "formulations")
    shown = json.loads(invoke("cache", "--json").stdout)
    assert shown["directory"] == str(cache_on) and shown["kinds"]["results"]["entries"] == 3  # two modes, the reactions
    cleared = invoke("cache", "--clear")
    assert cleared.returncode == 0 and "removed" in cleared.stdout
    assert not list((cache_on).rglob("*.entry")) and not (cache_on / store.KEY_NAME).exists()
    second, _ = _run("--engines", "formulations")
    assert second["cache"]["from_cache"] == {}


def test_results_cache_off_by_environment(cache_on, monkeypatch):
    monkeypatch.setenv(result_cache.RESULTS_ENV, "off")
    _run("--engines", "formulations")
    assert not (cache_on / result_cache.KIND).exists()


def test_a_plug_in_engines_results_are_keyed_by_its_source(cache_on, tmp_path, monkeypatch):
    """An engine from another package: its results are kept, and computed again once
    its source changes (xcheck's own digest does not cover it)."""
    import sys

    from xcheck import Kinematics, engines, load_mechanism
    from xcheck.runner import run_mechanism

    source = (
        "from conftest import shifted_sweep\n"
        "from xcheck import engines\n"
        "from xcheck.tolerances import Tolerance\n"
        "class Toy(engines.Engine):\n"
        "    name = 'cachetoy'\n"
        "    modes = (engines.Mode('cachetoy-kinematic', 'kinematic', Tolerance(1e-6, 1, 1, 1, 'toy')),)\n"
        "    def run(self, mode, kinematics, *, native, samples, branch=None):\n"
        "        return shifted_sweep(mode, kinematics, native, SHIFT)\n"
        "SHIFT = 1e-7\n"
    )
    (tmp_path / "cachetoy.py").write_text(source, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    import cachetoy

    engines.register(cachetoy.Toy())
    try:
        kin = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
        modes = ("native", "cachetoy-kinematic")
        assert not run_mechanism(kin, modes, 11).provenance["cachetoy-kinematic"].from_cache
        assert run_mechanism(kin, modes, 11).provenance["cachetoy-kinematic"].from_cache
        (tmp_path / "cachetoy.py").write_text(source.replace("SHIFT = 1e-7", "SHIFT = 2e-7"), encoding="utf-8")
        assert not run_mechanism(kin, modes, 11).provenance["cachetoy-kinematic"].from_cache
    finally:
        engines.unregister("cachetoy")
        sys.modules.pop("cachetoy", None)


def test_an_unusable_cache_directory_is_no_error(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv(store.CACHE_ENV, str(blocker / "cache"))
    with results_cache_on():
        first, _ = _run("--engines", "formulations")
    assert first["cache"] == {"from_cache": {}, "recomputed": {}}


def test_run_all_takes_what_the_cache_holds_here_and_computes_the_rest(cache_on, tmp_path):
    """`run all --jobs 2`: a mechanism whose results are all in the cache runs in this
    process, the others in workers; the JSON is that of the first run, in its order,
    and a changed file is the only one computed again."""
    import shutil

    folder = tmp_path / "models"
    folder.mkdir()
    for name in ("fourbar", "slider-crank", "two-body-arm"):
        shutil.copy(MODELS / f"{name}.toml", folder)
    args = ("run", "all", "--models", str(folder), "--engines", "formulations,mujoco-kinematic", "--samples", "11")

    def run() -> list:
        done = invoke(*args, "--json", "--jobs", "2")
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout)

    first = run()
    second = run()
    assert [_without_timings_and_cache(d) for d in second] == [_without_timings_and_cache(d) for d in first]
    assert all(set(d["cache"]["from_cache"]) >= {"formulation-II", "mujoco-kinematic"} for d in second)
    for name, old, new in (
        ("fourbar", "rate = 1.0 ", "rate = 1.5 "),
        ("slider-crank", "rate = 100 ", "rate = 120 "),
        ("two-body-arm", "\n[mechanism]", "# a comment changes nothing\n[mechanism]"),
    ):
        text = (folder / f"{name}.toml").read_text(encoding="utf-8")
        assert old in text
        (folder / f"{name}.toml").write_text(text.replace(old, new, 1), encoding="utf-8")
    third = run()  # two mechanisms to compute in workers, one from the cache here
    assert [d["mechanism"] for d in third] == [d["mechanism"] for d in first]
    cached = {d["mechanism"] for d in third if "mujoco-kinematic" in d["cache"]["from_cache"]}
    assert cached == {"two-body-arm"}
    assert _without_timings_and_cache(third[2]) == _without_timings_and_cache(first[2])
    assert third[0]["scale_floors"]["omega"] == 1.5 * first[0]["scale_floors"]["omega"]  # computed at the new rate
