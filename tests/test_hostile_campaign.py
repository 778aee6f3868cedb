"""A campaign of hostile and careless inputs, drawn from a seed as ``xcheck fuzz``
draws mechanisms: bad arguments to every entry of the Python API and hostile text
for the command line's options, campaign and reports folders holding a user's
files, folders of mechanism files that are not all files, installed plug-ins that
exit, interrupt or hang, addresses where no Dask scheduler answers, poisoned
caches, and free-motion files within the format's limits but beyond reason.

Scenario ``i`` of a surface is drawn from ``numpy.random.default_rng([SEED,
surface, i])`` alone, and its id says what it holds: a failure is its own
reproducer. Every scenario must end cleanly -- a result, or exit code 2 with one
line saying what was expected and what was found (``InputError`` from Python) --
in bounded time, and leave every file of the user's as it was. The oracle also
knows which scenarios must run and which must be refused, so that refusing
everything cannot pass.
"""

from __future__ import annotations

import contextlib
import faulthandler
import json
import math
import os
import re
import shutil
import stat
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import MODELS, ROOT, install_plug_in, invoke
from test_fuzz_folder import _stranger
from test_plug_ins import _GOOD

import xcheck
from xcheck import api, fuzz
from xcheck.engines import _registry
from xcheck.errors import XcheckError

#: the campaign's seed
SEED = 32
#: the longest a scenario may take, s (a hang fails the test run instead of blocking it)
WATCHDOG = 120.0
#: the longest an error line may be
MAX_LINE = 500


@contextlib.contextmanager
def _bounded(seconds: float = WATCHDOG):
    """Fail loudly (tracebacks of every thread, then exit) if the block hangs."""
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def _rng(surface: int, index: int) -> np.random.Generator:
    return np.random.default_rng([SEED, surface, index])


def _pick(rng: np.random.Generator, items):
    return items[int(rng.integers(len(items)))]


# ----------------------------------------------------------------------------- what a user keeps


@dataclass
class Keepsakes:
    """The user's things in a scratch folder: each path and what it was."""

    root: Path
    items: dict[str, tuple] = field(default_factory=dict)

    def snapshot(self, path: Path) -> tuple:
        info = os.lstat(path)
        if stat.S_ISLNK(info.st_mode):
            return ("link", os.readlink(path))
        if stat.S_ISDIR(info.st_mode):
            return ("folder",)
        if stat.S_ISREG(info.st_mode):
            return ("file", path.read_bytes(), stat.S_IMODE(info.st_mode))
        return ("other", stat.S_IFMT(info.st_mode))

    def keep(self, path: Path) -> None:
        self.items[str(path)] = self.snapshot(path)

    def changed(self) -> list[str]:
        """The user's paths that are gone or differ."""
        lost = []
        for name, before in self.items.items():
            try:
                now = self.snapshot(Path(name))
            except FileNotFoundError:
                now = ("gone",)
            if now != before:
                lost.append(f"{name}: {before[0]} -> {now[0]}")
        return lost


#: a line as Python prints an exception that nothing caught
_UNCAUGHT = re.compile(r"^(Traceback \(most recent call last\)|[\w.]*(Error|Exception|Interrupt|Exit)\b)", re.M)


def _clean(result, allowed: tuple[int, ...], must: int | None = None, errors: int = 1) -> list[str]:
    """What is wrong with a command's outcome: an exit code outside ``allowed``
    (or other than ``must``), a traceback, or an exit 2 that is not ``errors``
    error lines, each saying what was expected and what was found."""
    problems = []
    if _UNCAUGHT.search(result.stdout + result.stderr):
        problems.append(f"a traceback: {result.stderr[-600:]!r}")
    if result.returncode not in allowed or (must is not None and result.returncode != must):
        problems.append(f"exit code {result.returncode} (expected {must if must is not None else allowed})")
    if result.returncode == 2:
        lines = [line for line in result.stderr.splitlines() if not line.startswith("xcheck: warning:")]
        if len(lines) != errors or not all(line.startswith("xcheck: error: ") for line in lines):
            problems.append(f"not {errors} error line(s): {result.stderr[-600:]!r}")
        for line in lines:
            if "expected" not in line or "found" not in line or len(line) > MAX_LINE:
                problems.append(f"an error line that does not say what was expected and found: {line[:600]!r}")
    return problems


# ----------------------------------------------------------------------------- surface 1: the Python API

#: values no argument should take silently to a wrong answer
HOSTILE = [
    math.nan,
    math.inf,
    -math.inf,
    -1,
    0,
    -0.0,
    10**30,
    -(10**30),
    1e308,
    2.5,
    True,
    None,
    "",
    "abc",
    "30",
    "nan",
    "\x00",
    [],
    [[]],
    [math.nan],
    [1, [2]],
    {},
    {"crank": 30},
    object(),
    1 + 2j,
    b"x",
    ...,
    np.zeros((2, 2, 2)),
    np.zeros(0),
    np.array([np.nan]),
    np.float64(np.nan),
    np.int64(-3),
    np.bool_(True),
    Path("/nonexistent/xcheck.toml"),
]

_FOURBAR = str(MODELS / "fourbar.toml")
_TWO_INPUTS = str(MODELS / "two-body-arm.toml")


@pytest.fixture(scope="module")
def loaded():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fourbar, arm = xcheck.load(_FOURBAR), xcheck.load(_TWO_INPUTS)
        return {"fourbar": fourbar, "arm": arm, "sweep": fourbar.sweep(samples=5)}


#: each entry of the API and one argument of it: (label, call(loaded, value)), other arguments good
#: and small (a valid value drawn here must be cheap to run)
ENTRIES: list[tuple[str, Callable]] = [
    ("Assembled.solve(at=)", lambda m, v: m["fourbar"].solve(at=v)),
    ("Assembled.solve(rates=)", lambda m, v: m["fourbar"].solve(at=30, rates=v)),
    ("Assembled.solve(accelerations=)", lambda m, v: m["fourbar"].solve(at=30, rates=1, accelerations=v)),
    ("Assembled.solve(si=)", lambda m, v: m["fourbar"].solve(at=0.5, si=v)),
    ("Assembled.solve(at=) of two inputs", lambda m, v: m["arm"].solve(at=v)),
    ("Assembled.sweep(samples=)", lambda m, v: m["fourbar"].sweep(samples=v)),
    ("Assembled.draw(at=)", lambda m, v: m["fourbar"].draw(at=v)),
    ("Assembled.draw(si=)", lambda m, v: m["fourbar"].draw(at=0.5, si=v)),
    ("Assembled.animate(frames=)", lambda m, v: m["fourbar"].animate(frames=v)),
    ("Assembled.animate(interval=)", lambda m, v: m["fourbar"].animate(frames=3, interval=v)),
    ("Result.draw(i)", lambda m, v: m["sweep"].draw(v)),
    ("Result.plot(point=)", lambda m, v: m["sweep"].plot(point=v)),
    ("Result.plot(body=)", lambda m, v: m["sweep"].plot(body=v)),
    ("load(name)", lambda m, v: xcheck.load(v)),
    ("load(models=)", lambda m, v: xcheck.load("fourbar", models=v)),
    ("load(branch=)", lambda m, v: xcheck.load(_FOURBAR, branch=v)),
    ("load_mechanism(path)", lambda m, v: xcheck.load_mechanism(v)),
    ("select_modes(chosen)", lambda m, v: xcheck.select_modes(v)),
    ("select_modes(kinds=)", lambda m, v: xcheck.select_modes("native", kinds=v)),
    ("printed_answers(comparisons=)", lambda m, v: xcheck.printed_answers(m["fourbar"].kinematics, v)),
    ("run(samples=)", lambda m, v: api.run(_FOURBAR, engines="native", samples=v)),
    ("run(engines=)", lambda m, v: api.run(_FOURBAR, engines=v, samples=5)),
    ("run(branch=)", lambda m, v: api.run(_FOURBAR, engines="native", samples=5, branch=v)),
    ("run(jobs=)", lambda m, v: api.run(_FOURBAR, engines="native", samples=5, jobs=v)),
    ("run(comparisons=)", lambda m, v: api.run(_FOURBAR, engines="native", samples=5, comparisons=v)),
    ("run(progress=)", lambda m, v: api.run(_FOURBAR, engines="native", samples=5, progress=v)),
    ("simulate(duration=)", lambda m, v: xcheck.simulate("iftomm-a01", duration=v)),
    ("simulate(branch=)", lambda m, v: xcheck.simulate("iftomm-a01", duration=0.05, branch=v)),
    ("fuzz(count=)", lambda m, v: fuzz.fuzz(m["out"], count=v, modes="formulations", workers=1, samples=5)),
    ("fuzz(seed=)", lambda m, v: fuzz.fuzz(m["out"], count=1, seed=v, modes="formulations", workers=1, samples=5)),
    ("fuzz(kinds=)", lambda m, v: fuzz.fuzz(m["out"], count=1, kinds=v, modes="formulations", workers=1, samples=5)),
    ("fuzz(modes=)", lambda m, v: fuzz.fuzz(m["out"], count=1, modes=v, workers=1, samples=5)),
    ("fuzz(workers=)", lambda m, v: fuzz.fuzz(m["out"], count=1, modes="formulations", workers=v, samples=5)),
    ("fuzz(batch=)", lambda m, v: fuzz.fuzz(m["out"], count=1, modes="formulations", workers=1, batch=v, samples=5)),
    ("fuzz(out)", lambda m, v: fuzz.fuzz(v, count=1, modes="formulations", workers=1, samples=5)),
]

#: values that would be valid but too costly for a campaign, per entry (a valid draw of these is skipped)
_COSTLY = {
    "Assembled.sweep(samples=)": lambda v: 200 < v <= 100_000,
    "Assembled.animate(frames=)": lambda v: 20 < v <= 100_000,
    "run(samples=)": lambda v: 200 < v <= 100_000,
    "run(jobs=)": lambda v: 1 < v <= 256,
    "fuzz(count=)": lambda v: 1 < v <= 100_000,
    "fuzz(workers=)": lambda v: 1 < v <= 256,
    "fuzz(out)": lambda v: isinstance(v, (str, os.PathLike)) and bool(os.fspath(v)),  # a folder of the machine's
    "run(engines=)": lambda v: v is None,  # every engine: minutes
    "simulate(duration=)": lambda v: v is None or 0.05 < v <= 1e6,  # the file's 10 s, or more
    "fuzz(modes=)": lambda v: v is None,
}


def _costly(label: str, value) -> bool:
    rule = _COSTLY.get(label)
    if rule is None or isinstance(value, (bool, np.bool_)):  # a bool is no count or time
        return False
    try:
        return bool(rule(value))
    except (TypeError, ValueError):
        return False  # not a number: no cost


API_DRAWS = 4 * len(ENTRIES)


@pytest.mark.filterwarnings("ignore:Animation was deleted without rendering")  # animate()'s answer, unused
@pytest.mark.parametrize("index", range(API_DRAWS))
def test_an_api_entry_given_a_hostile_value_answers_or_says_why(index, loaded, tmp_path, monkeypatch):
    """One entry, one argument, a value from :data:`HOSTILE`: a result, or an
    :class:`~xcheck.XcheckError` (an ``InputError`` is a ``ValueError``) in one
    line; never another exception, never a hang."""
    rng = _rng(1, index)
    label, call = ENTRIES[index % len(ENTRIES)]  # each entry in turn, a value drawn
    value = _pick(rng, HOSTILE)
    if _costly(label, value):
        pytest.skip(f"{label} {value!r}: valid and costly")
    monkeypatch.chdir(tmp_path)
    context = {**loaded, "out": tmp_path / "campaign"}
    with _bounded(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            call(context, value)
        except XcheckError as err:
            message = str(err)
            assert message and "\n" not in message and len(message) <= MAX_LINE, f"{label} {value!r}: {message!r}"
        except BaseException as err:  # noqa: BLE001 - the finding
            pytest.fail(f"{label} {value!r}: {type(err).__name__}: {err}"[:MAX_LINE])


# ----------------------------------------------------------------------------- surface 2: a campaign's folder

#: things a user may keep in the folder given to ``fuzz --out``: name -> whether
#: the campaign must refuse to start beside it (it would have to replace it)
USER_THINGS = {
    "README.md": False,
    "index.json": False,
    "notes.md": False,
    ".notes.md.20251126": False,
    ".draft.md.backup_1": False,
    ".photos.2025abcd/": False,
    "results-of-mine.parquet": False,
    "failures.md": True,
    "failures.md (a folder)": True,
    "failures.md (a FIFO)": True,
    "failures.md (a link)": True,
    "campaign.json": True,
    "cases/ a case file": True,
    "results/ a stray part": True,
    "results/ a part of other columns": True,
    "results/ without campaign.json": True,
    "cases (a file)": True,
    "results (a file)": True,
}

#: option values and whether they must be refused
OPTIONS = [
    ((), False),
    (("--seed", "7"), False),
    (("--seed", "-1"), True),
    (("--seed", "123456789012345678901234567890"), True),
    (("--samples", "2"), True),
    (("--count", "0"), True),
    (("--workers", "0"), True),
    (("--kinds", "fourbar,hexapod"), True),
    (("--engines", "nosuch"), True),
]


def _make(out: Path, thing: str, keep: Keepsakes) -> None:
    """Put the user's ``thing`` into ``out`` and note it."""
    outside = out.parent / "outside.md"
    if thing.endswith("/"):
        (out / thing).mkdir()
        (out / thing / "photo.jpg").write_bytes(b"\xff\xd8 a photo")
        keep.keep(out / thing / "photo.jpg")
    elif thing == "failures.md (a folder)":
        (out / "failures.md").mkdir()
        (out / "failures.md" / "keep.txt").write_text("mine", encoding="utf-8")
        keep.keep(out / "failures.md" / "keep.txt")
    elif thing == "failures.md (a FIFO)":
        os.mkfifo(out / "failures.md")
        keep.keep(out / "failures.md")
    elif thing == "failures.md (a link)":
        outside.write_text(fuzz._REPORT_MARK + "\nmine, though it looks like xcheck's\n", encoding="utf-8")
        (out / "failures.md").symlink_to(outside)
        keep.keep(outside)
        keep.keep(out / "failures.md")
    elif thing in ("cases (a file)", "results (a file)"):
        (out / thing.split(" ")[0]).write_text("the user's file\n", encoding="utf-8")
        keep.keep(out / thing.split(" ")[0])
    elif thing == "cases/ a case file":
        (out / "cases").mkdir(exist_ok=True)
        for seed in (0, 7):
            path = out / "cases" / f"{fuzz.generate(seed, 0).name}.toml"
            path.write_text("# my own mechanism\n", encoding="utf-8")
            keep.keep(path)
    elif thing.startswith("results/"):
        (out / "results").mkdir(exist_ok=True)
        path = out / "results" / "part-000000-mine.parquet"
        if thing == "results/ a stray part":
            path.write_bytes(b"PAR1 not really")
        elif thing == "results/ a part of other columns":
            pd.DataFrame({"mine": [1.0]}).to_parquet(path)
        else:
            pd.DataFrame({c: [] for c in fuzz.COLUMNS}).to_parquet(path)
        keep.keep(path)
    else:
        (out / thing).write_text(f"the user's {thing}\n", encoding="utf-8")
        keep.keep(out / thing)


FOLDER_DRAWS = 14


def _folder_draw(index: int) -> tuple[list[str], tuple[str, ...], bool]:
    """Scenario ``index``: the user's things in the folder, the options, and
    whether the campaign must refuse. About half the scenarios must run."""
    rng = _rng(2, index)
    harmless = [t for t, conflict in USER_THINGS.items() if not conflict and rng.uniform() < 0.4]
    conflicts = [t for t, conflict in USER_THINGS.items() if conflict and (hasattr(os, "mkfifo") or "FIFO" not in t)]
    things = harmless + ([_pick(rng, conflicts)] if rng.uniform() < 0.35 else [])
    options, bad_option = _pick(rng, OPTIONS) if rng.uniform() < 0.35 else OPTIONS[int(rng.integers(2))]
    return things, options, bad_option or any(USER_THINGS[t] for t in things)


def test_the_folder_scenarios_hold_runs_and_refusals():
    outcomes = [_folder_draw(i)[2] for i in range(FOLDER_DRAWS)]
    assert 4 <= sum(outcomes) <= FOLDER_DRAWS - 4


@pytest.mark.parametrize("index", range(FOLDER_DRAWS))
def test_a_campaign_beside_a_users_files_runs_or_refuses_and_keeps_them(index, tmp_path):
    things, options, refuse = _folder_draw(index)
    out = tmp_path / "proj"
    out.mkdir()
    keep = Keepsakes(out)
    for thing in things:
        _make(out, thing, keep)
    args = ("fuzz", "--count", "1", "--engines", "formulations", "--workers", "1", "--samples", "21", *options)
    with _bounded():
        result = invoke(*args, "--out", str(out))
    problems = _clean(result, (0, 1, 2), 2 if refuse else None)
    if not refuse and result.returncode == 2:
        problems.append("refused a folder it could use")
    problems += [f"changed the user's {c}" for c in keep.changed()]
    assert not problems, f"{things} {options}: {problems}"


# ----------------------------------------------------------------------------- surface 6: a reports folder

#: what a user may keep in the folder given to ``run --out`` or ``simulate --out``
#: (NAME: the mechanism's name): thing -> whether xcheck must refuse to write there
REPORT_THINGS = {
    "notes.md": False,
    "notes/.report.md": False,
    ".notes.md.20251126": False,
    ".draft.md.backup_1": False,
    ".photos.2025abcd/holiday.jpg": False,
    ".NAME.xcheck-staging-0123abcd/mine.txt": False,
    "other/NAME/drawing.png": False,
    "README.md": True,
    "index.json": True,
    "NAME.md": True,
    "NAME/drawing.png + thesis.tex": True,
    "README.md (a link)": True,
    "NAME.md (a FIFO)": True,
}

#: the commands that write reports: (arguments before --out, the mechanism's name)
_RUN = ("run", str(ROOT / "tests" / "data" / "fourbar-200.toml"), "--engines", "native", "--samples", "11")
REPORTERS = [
    ((*_RUN, "--no-gif", "-q"), "fourbar-200"),
    (("simulate", "iftomm-a01", "--duration", "0.05", "--engines", "native", "-q"), "iftomm-a01"),
]  # fmt: skip

#: names a mechanism may not take (the index's, or a report's Markdown)
RESERVED = ["README", "readme", "README.md", "index.json", "Index.JSON", "notes.md"]


def _report_draw(index: int) -> tuple[list[str], int, str | None, bool]:
    """Scenario ``index``: the user's things, the command, a reserved name for the
    mechanism (or None), and whether xcheck must refuse."""
    rng = _rng(6, index)
    harmless = [t for t, conflict in REPORT_THINGS.items() if not conflict and rng.uniform() < 0.5]
    conflicts = [t for t, conflict in REPORT_THINGS.items() if conflict and (hasattr(os, "mkfifo") or "FIFO" not in t)]
    things = harmless + ([_pick(rng, conflicts)] if rng.uniform() < 0.35 else [])
    command = int(rng.integers(len(REPORTERS)))
    reserved = _pick(rng, RESERVED) if command == 0 and rng.uniform() < 0.2 else None
    return things, command, reserved, reserved is not None or any(REPORT_THINGS[t] for t in things)


REPORT_DRAWS = 8


def test_the_report_scenarios_hold_runs_and_refusals():
    outcomes = [_report_draw(i)[3] for i in range(REPORT_DRAWS)]
    assert 2 <= sum(outcomes) <= REPORT_DRAWS - 2


@pytest.mark.parametrize("index", range(REPORT_DRAWS))
def test_reports_beside_a_users_files_are_written_or_refused_and_keep_them(index, tmp_path):
    things, command, reserved, refuse = _report_draw(index)
    args, name = REPORTERS[command]
    if reserved is not None:
        renamed = tmp_path / "named.toml"
        renamed.write_text(
            Path(args[1]).read_text(encoding="utf-8").replace(f'name = "{name}"', f'name = "{reserved}"')
        )
        args = (args[0], str(renamed), *args[2:])
    out = tmp_path / "proj"
    out.mkdir()
    keep = Keepsakes(out)
    for thing in things:
        thing = thing.replace("NAME", name)
        if thing.endswith(" + thesis.tex"):
            folder = out / thing.split("/")[0]
            folder.mkdir()
            for part in ("drawing.png", "thesis.tex"):
                (folder / part).write_text(f"the user's {part}\n", encoding="utf-8")
                keep.keep(folder / part)
        elif thing.endswith(" (a link)"):
            outside = tmp_path / "elsewhere.md"
            outside.write_text("mine\n", encoding="utf-8")
            (out / thing.split(" ")[0]).symlink_to(outside)
            keep.keep(outside)
            keep.keep(out / thing.split(" ")[0])
        elif thing.endswith(" (a FIFO)"):
            os.mkfifo(out / thing.split(" ")[0])
            keep.keep(out / thing.split(" ")[0])
        else:
            path = out / thing
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(f"the user's {thing}\n", encoding="utf-8")
            keep.keep(path)
    with _bounded():
        result = invoke(*args, "--out", str(out))
    problems = _clean(result, (0, 1, 2), 2 if refuse else None)
    if not refuse and result.returncode == 2:
        problems.append("refused a folder it could use")
    if not refuse and not (out / f"{name}.md").is_file():
        problems.append("wrote no report")
    problems += [f"changed the user's {c}" for c in keep.changed()]
    assert not problems, f"{things} {args[0]} {reserved}: {problems}"


# ----------------------------------------------------------------------------- surface 7: the caches

#: the commands whose answers a cache entry feeds (the branch maps; the modes' results for run)
CACHED_COMMANDS = [
    ("solve", _FOURBAR, "--at", "60", "--branch", "upper", "--json"),
    ("solve", _FOURBAR, "--at", "100", "--branch", "lower", "--json"),
    ("list", _FOURBAR, "--json"),
    ("run", _FOURBAR, "--engines", "native,formulations", "--samples", "21", "--no-report", "--json"),
]

#: what may be done to a cache directory between two commands
POISONS = [
    "branches swapped",
    "range narrowed",
    "a digit changed",
    "truncated",
    "garbage",
    "empty",
    "a FIFO",
    "a link to /dev/zero",
    "a folder",
    "a sparse giant",
    "a link to a sound entry",
    "key deleted",
    "another key",
    "key readable by all",
    "key a FIFO",
    "key a link to a file of the user's",
    "the cache a file",
]

#: keys of the JSON that differ between two runs of the same question (wall times, where an answer came from)
_VOLATILE = ("timing", "seconds", "cache", "computed", "provenance")


def _differences(a, b, path: str = "") -> list[str]:
    """Where two JSON answers differ: other keys, other text, or numbers apart by
    more than 1e-9 of their size (a branch map restored from the cache gives the
    same numbers as one computed, identical where measured; another branch or
    range differs in the first digits)."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = {k for k in set(a) | set(b) if not any(v in k for v in _VOLATILE)}
        return [d for k in sorted(keys) for d in _differences(a.get(k), b.get(k), f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{path}[{i}]")]
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        return [] if abs(a - b) <= 1e-9 * max(abs(a), abs(b), 1e-300) else [f"{path}: {a!r} != {b!r}"]
    return [] if a == b else [f"{path}: {str(a)[:60]!r} != {str(b)[:60]!r}"]


@pytest.fixture(scope="module")
def uncached():
    """Each command's JSON answer with every cache off: the truth to compare with."""
    from xcheck.result_cache import RESULTS_ENV
    from xcheck.store import CACHE_ENV

    answers = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(CACHE_ENV, "off")
        patch.delenv(RESULTS_ENV, raising=False)
        for command in CACHED_COMMANDS:
            result = invoke(*command)
            assert result.returncode == 0, result.stderr
            answers[command] = json.loads(result.stdout)
    return answers


def _poison(cache: Path, poison: str, keep: Keepsakes) -> None:
    """Do ``poison`` to every entry of the cache directory ``cache`` (or to its key)."""
    from xcheck.store import KEY_NAME

    key = cache / KEY_NAME
    entries = [e for e in sorted(cache.glob("*/*.entry")) if e.is_file() and not e.is_symlink()]  # not poisoned yet
    if poison == "key deleted":
        key.unlink()
    elif poison == "another key":
        key.write_bytes(os.urandom(len(key.read_bytes())))
    elif poison == "key readable by all":
        key.chmod(0o644)
    elif poison == "key a FIFO":
        key.unlink()
        os.mkfifo(key)
    elif poison == "key a link to a file of the user's":
        mine = cache.parent / "my-secret.txt"
        mine.write_text("the user's own secret\n", encoding="utf-8")
        keep.keep(mine)
        key.unlink()
        key.symlink_to(mine)
    elif poison == "the cache a file":
        shutil.rmtree(cache)
        cache.write_text("the user's file where the cache was\n", encoding="utf-8")
        keep.keep(cache)
    for entry in entries if poison not in ("key deleted", "another key", "the cache a file") else []:
        text = entry.read_bytes()
        header, _, payload = text.partition(b"\n")
        if poison in ("branches swapped", "range narrowed") and entry.parent.name == "branch-maps":
            document = json.loads(payload)
            if poison == "branches swapped" and {"upper", "lower"} <= set(document["assembled"]):
                assembled = document["assembled"]
                assembled["upper"], assembled["lower"] = assembled["lower"], assembled["upper"]
            for item in document["ranges"] if poison == "range narrowed" else []:
                if item["low"] is not None and item["high"] is not None:
                    item["low"], item["high"] = math.radians(-60), math.radians(60)
            edited = json.dumps(document).encode()
            head = json.loads(header)
            head["length"] = len(edited)  # a checksum anyone can recompute would now pass
            entry.write_bytes(json.dumps(head).encode() + b"\n" + edited)
        elif poison == "a digit changed":
            entry.write_bytes(text.replace(b"0.", b"1.", 1))
        elif poison == "truncated":
            entry.write_bytes(text[: len(text) // 2])
        elif poison == "garbage":
            entry.write_bytes(os.urandom(len(text)))
        elif poison == "empty":
            entry.write_bytes(b"")
        elif poison in ("a FIFO", "a link to /dev/zero", "a folder", "a sparse giant", "a link to a sound entry"):
            entry.unlink()
            if poison == "a FIFO":
                os.mkfifo(entry)
            elif poison == "a link to /dev/zero":
                entry.symlink_to("/dev/zero")
            elif poison == "a folder":
                entry.mkdir()
            elif poison == "a sparse giant":
                with open(entry, "wb") as giant:
                    giant.truncate(2**30)  # 1 GB, no disk used
            else:
                sound = entry.with_suffix(".sound")
                sound.write_bytes(text)
                entry.symlink_to(sound)


CACHE_DRAWS = len(POISONS)


def _cache_draw(index: int) -> tuple[tuple, list[str], tuple]:
    """Scenario ``index``: the command that fills the cache, the poison (each in
    turn: two would hide each other, as a cache made a file hides an edited
    entry), and the command asked again (``run``, the costliest, in a quarter of them)."""
    rng = _rng(7, index)
    cheap = CACHED_COMMANDS[:3]
    first = CACHED_COMMANDS[3] if index % 4 == 0 else _pick(rng, cheap)
    then = CACHED_COMMANDS[3] if index % 4 == 1 else _pick(rng, cheap)
    return first, [POISONS[index % len(POISONS)]], then


@pytest.mark.skipif(not (hasattr(os, "mkfifo") and Path("/dev/zero").exists()), reason="FIFOs and /dev/zero")
@pytest.mark.parametrize("index", range(CACHE_DRAWS))
def test_a_poisoned_cache_never_changes_an_answer(index, tmp_path, monkeypatch, uncached):
    """A command's answer fills the cache, the cache is poisoned, and the
    command (or another) asked again answers exactly as with no cache at all:
    in bounded time, exit 0, nothing of the user's touched."""
    from xcheck.result_cache import RESULTS_ENV
    from xcheck.store import CACHE_ENV

    first, poisons, then = _cache_draw(index)
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    monkeypatch.delenv(RESULTS_ENV, raising=False)  # the modes' results cached too
    keep = Keepsakes(tmp_path)
    other = CACHED_COMMANDS[0] if first == CACHED_COMMANDS[1] else CACHED_COMMANDS[1]
    with _bounded():
        filled = invoke(*first)  # and the other branch: both in the map, for swapping
        filled_too = invoke(*other)
        for poison in poisons:
            if cache.is_dir():
                _poison(cache, poison, keep)
        result = invoke(*then)
    problems = _clean(filled, (0,), 0) + _clean(filled_too, (0,), 0) + _clean(result, (0,), 0)
    if result.returncode == 0:
        problems += _differences(uncached[then], json.loads(result.stdout))[:5]
    problems += [f"changed the user's {c}" for c in keep.changed()]
    assert not problems, f"{first[0]} then {poisons} then {then[0]} {then[2:4]}: {problems}"


# ----------------------------------------------------------------------------- surface 8: the command line's options

#: text a user may type for any option
HOSTILE_TEXT = [
    "nan", "inf", "-inf", "-1", "0", "1e309", "1e-320", "", " ", "abc", "1/0", "2**1000", "9" * 400, "((1)",
    "30,", ",", ":", "30:40", "0x10", "-", "é", "30\n40", "upper", "lower", "native,,", "NATIVE", "/", "/dev/null",
    "/sys/xcheck.png", "x.txt", "a/b/c.png", "out.png",
]  # fmt: skip

#: a command with one option to fill ("{}"; "OUT" is a scratch folder), and whether a value would be costly
OPTION_COMMANDS: list[tuple[tuple[str, ...], Callable[[str], bool]]] = [
    (("solve", _FOURBAR, "--at", "{}"), lambda v: False),
    (("solve", _FOURBAR, "--at", "30", "--rate", "{}"), lambda v: False),
    (("solve", _FOURBAR, "--at", "30", "--rate", "1", "--accel", "{}"), lambda v: False),
    (("solve", _FOURBAR, "--branch", "{}"), lambda v: False),
    (("solve", _TWO_INPUTS, "--at", "{}"), lambda v: False),
    (("draw", _FOURBAR, "--at", "{}", "-o", "OUT/x.png"), lambda v: False),
    (("draw", _FOURBAR, "-o", "{}"), lambda v: False),
    (("run", _FOURBAR, "--engines", "{}", "--samples", "11", "--no-report"), lambda v: _engines_beyond_native(v)),
    (("run", _FOURBAR, "--branch", "{}", "--engines", "native", "--samples", "11", "--no-report"), lambda v: False),
    (("run", _FOURBAR, "--samples", "{}", "--engines", "native", "--no-report"), lambda v: _many_samples(v)),
    (("simulate", "iftomm-a01", "--duration", "{}", "--engines", "native", "--no-report"), lambda v: _a_time(v)),
    (("list", "{}"), lambda v: v in ("/", "/dev/null")),  # the root folder: every file in it
]  # fmt: skip


def _engines_beyond_native(text: str) -> bool:
    """Whether ``text`` would select modes besides the native solver (each costs seconds)."""
    try:
        return xcheck.select_modes(text) != ("native",)
    except XcheckError:
        return False


def _many_samples(text: str) -> bool:
    """Whether ``text`` would be a valid count of samples above a quick one."""
    return text.strip().isdigit() and 200 < int(text) <= 100_000


def _a_time(text: str) -> bool:
    """Whether ``text`` would be a valid simulated time longer than a quick one."""
    try:
        value = float(text)
    except ValueError:
        return False
    return 0.05 < value <= 1e6


OPTION_DRAWS = 3 * len(OPTION_COMMANDS)


@pytest.mark.parametrize("index", range(OPTION_DRAWS))
def test_an_option_given_hostile_text_answers_or_says_why(index, tmp_path, monkeypatch):
    rng = _rng(8, index)
    template, costly = OPTION_COMMANDS[index % len(OPTION_COMMANDS)]
    value = _pick(rng, HOSTILE_TEXT)
    if costly(value):
        pytest.skip(f"{template[0]} {value!r}: valid and costly")
    monkeypatch.chdir(tmp_path)
    args = [value if part == "{}" else part.replace("OUT", str(tmp_path)) for part in template]
    with _bounded():
        result = invoke(*args)
    problems = _clean(result, (0, 1, 2))
    assert not problems, f"{args}: {problems}"


# ----------------------------------------------------------------------------- surface 9: free-motion files

_SPRING = ROOT / "tests" / "data" / "free-slider-crank-spring.toml"

#: changes to the slider-crank with a spring: (what, old text, new text), each a file within every
#: limit of the format that a careless or hostile user may write
FREE_CHANGES = [
    ("a stiff spring", "stiffness = 1000", "stiffness = 1e7"),
    ("a stiffer spring", "stiffness = 1000", "stiffness = 1e9"),
    ("an absurd spring", "stiffness = 1000", "stiffness = 1e300"),
    ("a heavy damper", "rest_length = 0.25", "rest_length = 0.25\ndamping = 1e8"),
    ("a fast crank", "velocity = { crank = 32 }", "velocity = { crank = 1e150 }"),
    ("a long run", "duration = 2\n", "duration = 1e9\n"),
    ("fine outputs", "output_step = 0.01", "output_step = 1e-6"),
    ("a fine run", "duration = 2\noutput_step = 0.01", "duration = 1\noutput_step = 1e-6"),
    ("a feather", "mass = 1.2", "mass = 1e-300"),
    ("a mountain", "mass = 1.2", "mass = 1e300"),
    ("a crushing gravity", "gravity = [0, -9.81]", "gravity = [0, -1e300]"),
    ("a tight tolerance", "tolerance = 1e-9", "tolerance = 1e-13"),
]

#: --duration values given with the unchanged file: a whole number of output steps or not, tiny, huge
FREE_DURATIONS = ["0.014", "0.015", "0.02", "1e-300", "1e6"]


def _free_draw(index: int) -> tuple[str, str, str, str | None]:
    """Scenario ``index``: each change at the file's own duration, then the
    unchanged file at each ``--duration``: (what, old text, new text, duration)."""
    if index < len(FREE_CHANGES):
        return (*FREE_CHANGES[index], None)
    return ("the file as it is", "", "", FREE_DURATIONS[index - len(FREE_CHANGES)])


FREE_DRAWS = len(FREE_CHANGES) + len(FREE_DURATIONS)
#: the free scenarios' work budget (evaluations x (30 + coordinates)): a tenth of the reference's
#: own, so that each stays within seconds; the same rule refuses up front or stops at it
FREE_BUDGET = 1e7


@pytest.mark.parametrize("index", range(FREE_DRAWS))
def test_a_hostile_free_motion_file_is_simulated_or_refused_in_bounded_time(index, tmp_path, monkeypatch):
    """The native reference of a free motion: a result with finite numbers (converged or
    not, exit 0 or 1), or one line and exit 2 -- in bounded time, never a traceback."""
    from xcheck.dynamics import _reference

    monkeypatch.setattr(_reference, "WORK_BUDGET", FREE_BUDGET)
    what, old, new, duration = _free_draw(index)
    text = _SPRING.read_text(encoding="utf-8")
    assert old in text, what
    path = tmp_path / "free.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    args = ["simulate", str(path), "--engines", "native", "--json", "--no-report"]
    args += ["--duration", duration] if duration is not None else []
    started = time.monotonic()
    with _bounded():
        result = invoke(*args)
    seconds = time.monotonic() - started
    problems = _clean(result, (0, 1, 2))
    if result.returncode in (0, 1):
        try:
            document = json.loads(result.stdout)
        except ValueError as err:
            problems.append(f"not JSON: {err}")
        else:  # a run to another time than the one asked for is a wrong answer
            if duration is not None and not math.isclose(document["duration"], float(duration), rel_tol=1e-12):
                problems.append(f"asked for {duration} s, simulated {document['duration']} s")
    if seconds > 60:
        problems.append(f"took {seconds:.0f} s")
    assert not problems, f"{what}, --duration {duration}: {problems}"


# ----------------------------------------------------------------------------- surface 3: folders of mechanism files

#: entries of a models folder that are not mechanism files, each its own error line
NOT_FILES = ["a FIFO", "a folder", "a link loop", "a link to nothing", "empty", "binary", "too large", "/dev/zero"]


def _not_a_file(folder: Path, kind: str, name: str) -> bool:
    """Put an entry ``name``.toml of ``kind`` into ``folder``; False where this machine cannot."""
    path = folder / f"{name}.toml"
    if kind == "a FIFO":
        if not hasattr(os, "mkfifo"):
            return False
        os.mkfifo(path)
    elif kind == "a folder":
        path.mkdir()
    elif kind == "a link loop":
        path.symlink_to(path)
    elif kind == "a link to nothing":
        path.symlink_to(folder / "nowhere" / "x.toml")
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 8)
    elif kind == "too large":
        with open(path, "wb") as big:
            big.truncate(50_000_000)  # sparse: no disk written
    elif kind == "/dev/zero":
        if not Path("/dev/zero").exists():
            return False
        path.symlink_to("/dev/zero")
    return True


MODEL_FOLDER_DRAWS = 6


@pytest.mark.parametrize("index", range(MODEL_FOLDER_DRAWS))
def test_list_over_a_folder_of_things_that_are_not_mechanism_files(index, tmp_path):
    """``xcheck list DIR`` lists the good files and gives one line for each entry
    it could not read, whatever it is, without hanging."""
    rng = _rng(3, index)
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "fourbar.toml").write_bytes((MODELS / "fourbar.toml").read_bytes())
    kinds = [k for k in NOT_FILES if rng.uniform() < 0.5] or [_pick(rng, NOT_FILES)]
    made = [f"bad{i}" for i, kind in enumerate(kinds) if _not_a_file(folder, kind, f"bad{i}")]
    with _bounded():
        result = invoke("list", str(folder))
    problems = _clean(result, (0, 2), 2 if made else 0, errors=len(made))
    lines = result.stderr.splitlines()
    if sorted(line.split(f"{folder}/", 1)[-1].split(".toml")[0] for line in lines) != sorted(made):
        problems.append(f"not one line per bad entry: {lines}")
    if "fourbar" not in result.stdout:
        problems.append("the good file was not listed")
    assert not problems, f"{kinds}: {problems}"


# ----------------------------------------------------------------------------- surface 4: plug-ins

#: plug-ins that must not load: name -> (module source, entry_points.txt line or None for the usual)
BROKEN_PLUG_INS = {
    "exit0": ("import sys\nsys.exit(0)\n", None),
    "exit3": ("raise SystemExit(3)\n", None),
    "interrupt": ("raise KeyboardInterrupt\n", None),
    "error": ("raise RuntimeError('no licence')\n", None),
    "syntax": ("def (:\n", None),
    "missing": ("import xcheck_no_such_module_at_all\n", None),
    "notengine": ("X = 42\n", None),
    "sleeps": ("import time\ntime.sleep(600)\n", None),
    "loops": ("while True:\n    pass\n", None),
    "takenname": (
        "from xcheck import engines\nclass X(engines.Engine):\n    name = 'mujoco'\n",
        None,
    ),
    "takenmode": (
        "from xcheck import engines\nfrom xcheck.tolerances import Tolerance\n"
        "class X(engines.Engine):\n    name = 'takenmode'\n"
        "    modes = (engines.Mode('native', 'kinematic', Tolerance(1, 1, 1, 1, 'any')),)\n",
        None,
    ),
    "badvalue": ("", "badvalue = xcheck_plug_badvalue:X:Y:Z"),
    "malformed": ("", "this line has no equals sign"),
    "fifo": ("", None),  # its entry_points.txt a FIFO (made below)
}

COMMANDS = [
    ("engines", "--json"),
    ("list", _FOURBAR),
    ("run", _FOURBAR, "--engines", "native,formulations", "--no-report", "--samples", "21"),
]

PLUG_IN_DRAWS = 4


@pytest.mark.parametrize("index", range(PLUG_IN_DRAWS))
def test_a_site_of_broken_plug_ins_never_stops_a_command(index, tmp_path):
    rng = _rng(4, index)
    site = tmp_path / "site"
    site.mkdir()
    install_plug_in(site, "xcheck_plug_good", _GOOD, "[xcheck.engines]\nplugged = xcheck_plug_good:Plugged\n")
    chosen = [name for name in BROKEN_PLUG_INS if rng.uniform() < 0.4]
    expected = set()
    for name in chosen:
        source, line = BROKEN_PLUG_INS[name]
        module = f"xcheck_plug_{name}"
        install_plug_in(site, module, source, f"[xcheck.engines]\n{line or f'{name} = {module}:X'}\n")
        if name == "fifo":
            (site / f"{module}-1.0.dist-info" / "entry_points.txt").unlink()
            os.mkfifo(site / f"{module}-1.0.dist-info" / "entry_points.txt")
        expected.add(str(site / f"{module}-1.0.dist-info") if name in ("malformed", "fifo") else name)
    command = COMMANDS[index % len(COMMANDS)]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), str(ROOT / "src")]),
        _registry.TIMEOUT_ENV: "0.5",  # each hanging plug-in costs the run this wait
    }
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "xcheck", *command], env=env, capture_output=True, text=True, timeout=WATCHDOG
    )
    problems = _clean(result, (0,), 0)
    if time.monotonic() - started > 60:
        problems.append(f"took {time.monotonic() - started:.0f} s")
    warned = {line.split("'")[1] for line in result.stderr.splitlines() if line.startswith("xcheck: warning: plug-in ")}
    if warned != expected:
        problems.append(f"warned of {sorted(warned)}, expected {sorted(expected)}")
    if command[0] != "run" and "plugged" not in result.stdout:
        problems.append("the good plug-in is not listed")
    assert not problems, f"{chosen} {command[0]}: {problems}"


# ----------------------------------------------------------------------------- surface 5: a scheduler that is not one

STRANGERS = ["silent", "http", "garbage", "closes", "closed port"]


@pytest.mark.parametrize("index", range(2))
def test_a_stranger_at_the_scheduler_address_is_one_line(index, tmp_path, monkeypatch):
    rng = _rng(5, index)
    kind = _pick(rng, STRANGERS)
    # a silent server waits out one and a half times the limit; a closed port needs
    # Dask's own give-up at the limit to come before that
    monkeypatch.setattr(fuzz, "SCHEDULER_TIMEOUT", 0.5 if kind == "silent" else 1.0)
    answers = {"silent": None, "http": b"HTTP/1.1 400 Bad\r\n\r\n", "garbage": bytes(rng.integers(0, 256, 512))}
    answers["closes"] = b""
    server = contextlib.nullcontext("tcp://127.0.0.1:9") if kind == "closed port" else _stranger(answers[kind])
    with server as address, _bounded():
        result = invoke("fuzz", "--count", "1", "--engines", "formulations", "--scheduler", address,
                        "--out", str(tmp_path / "campaign"))  # fmt: skip
    problems = _clean(result, (2,), 2)
    assert not problems, f"{kind}: {problems}"


# ----------------------------------------------------------------------------- the oracle can fail


def test_the_oracle_sees_a_changed_file_and_an_unclean_exit(tmp_path):
    """The checks above are not vacuous: a user file rewritten, a second error
    line, a traceback and a refusal of a usable folder are each reported."""
    (tmp_path / "README.md").write_text("mine", encoding="utf-8")
    keep = Keepsakes(tmp_path)
    keep.keep(tmp_path / "README.md")
    (tmp_path / "README.md").write_text("# Reports", encoding="utf-8")
    assert keep.changed() == [f"{tmp_path / 'README.md'}: file -> file"]
    done = subprocess.CompletedProcess
    assert _clean(done([], 2, "", "xcheck: error: a: expected b, found c\nxcheck: error: d\n"), (2,))
    assert _clean(done([], 1, "", 'Traceback (most recent call last):\n  File "x"\nValueError: x\n'), (0, 1))
    assert _clean(done([], 2, "", "xcheck: error: a: expected b, found c\n"), (0, 1, 2), 0)
    assert not _clean(done([], 2, "", "xcheck: error: a: expected b, found c\n"), (0, 1, 2), 2)
