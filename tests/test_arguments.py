"""Every entry checks its arguments by one rule (xcheck.arguments): a bad value
gets one line naming the argument, what was expected and what was found, as an
InputError (a ValueError) from Python and exit code 2 from the command line,
before any work is done."""

from __future__ import annotations

import doctest
import math
import os
import warnings

import numpy as np
import pytest
from conftest import MODELS, invoke

import xcheck
from xcheck import arguments
from xcheck.errors import InputError

FOURBAR = str(MODELS / "fourbar.toml")


def test_docstring_examples_run():
    failed, attempted = doctest.testmod(arguments)
    assert attempted >= 2 and failed == 0


@pytest.mark.parametrize("value", [3, 181, np.int64(500), 100_000, 21.0, np.float32(7.0)])
def test_a_whole_number_in_range_is_taken(value):
    assert arguments.samples(value) == int(value) and type(arguments.samples(value)) is int


@pytest.mark.parametrize(
    "value, found",
    [
        (2, "2"),
        (-5, "-5"),
        (100_001, "100001"),
        (10**9, "1000000000"),
        (10**30, str(10**30)),
        (math.nan, "nan"),
        (math.inf, "inf"),
        (2.5, "2.5"),
        (True, "True"),
        ("21", "'21'"),
        (None, "None"),
        (np.float64(math.nan), "nan"),
    ],
)
def test_a_bad_number_of_samples_is_one_line(value, found):
    with pytest.raises(InputError) as caught:
        arguments.samples(value)
    assert str(caught.value) == f"samples: expected a whole number from 3 to 100000, found {found}"


def test_a_long_value_is_cut_in_the_message():
    with pytest.raises(InputError) as caught:
        arguments.samples("x" * 500)
    assert len(str(caught.value)) < 160 and str(caught.value).endswith("…")


@pytest.mark.parametrize("seed", [-1, 2**63, 10**30, 1.5])
def test_a_seed_outside_64_bits_is_refused(seed):
    with pytest.raises(InputError, match=r"^seed: expected a whole number from 0 to 9223372036854775807"):
        arguments.seed(seed)


def test_processes_default_to_the_cpu_count(monkeypatch):
    import os

    monkeypatch.delenv(arguments.JOBS_ENV, raising=False)
    assert arguments.processes(None) == (os.cpu_count() or 1)
    with pytest.raises(InputError, match="^--workers: expected a whole number from 1 to 256, found 0$"):
        arguments.processes(0, "--workers")


def test_xcheck_jobs_sets_the_default_processes_and_a_bad_one_is_one_line(monkeypatch):
    """$XCHECK_JOBS is the default where a value is not given (a container's share of
    the cores); a given value wins; a bad one is refused, naming the variable, before
    any work (the command line: exit 2, one line)."""
    monkeypatch.setenv("XCHECK_JOBS", " 3 ")
    assert arguments.processes(None) == 3 and arguments.processes(2, "--jobs") == 2
    monkeypatch.setenv("XCHECK_JOBS", "")
    assert arguments.processes(None) == (os.cpu_count() or 1)
    for bad, found in (("0", "0"), ("300", "300"), ("two", "'two'"), ("1.5", "'1.5'")):
        monkeypatch.setenv("XCHECK_JOBS", bad)
        with pytest.raises(InputError, match=rf"^\$XCHECK_JOBS: expected a whole number from 1 to 256, found {found}$"):
            arguments.processes(None, "--jobs")
    done = invoke("run", "fourbar", "--engines", "formulations", "--json")
    assert done.returncode == 2 and done.stdout == ""
    line = "xcheck: error: $XCHECK_JOBS: expected a whole number from 1 to 256, found '1.5'"
    assert done.stderr.strip().splitlines() == [line]


def test_a_directory_that_cannot_be_written_is_refused(tmp_path):
    (tmp_path / "file").write_text("mine", encoding="utf-8")
    with pytest.raises(InputError, match="found a file$"):
        arguments.writable_directory(tmp_path / "file", "--out", "the campaign")
    with pytest.raises(InputError, match="found that it cannot be made"):
        arguments.writable_directory(tmp_path / "file" / "below", "--out", "the campaign")
    assert arguments.writable_directory(tmp_path / "new" / "deep", "--out", "x").is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "new"]  # the probe left nothing


# ----------------------------------------------------------------------------- the API


@pytest.fixture(scope="module")
def fourbar():
    return xcheck.load(FOURBAR)


def _one_line(call, *needles):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(InputError) as caught:
            call()
    text = str(caught.value)
    assert "\n" not in text and all(n in text for n in needles), text
    return text


@pytest.mark.parametrize(
    "call, needles",
    [
        (lambda m: m.solve(at=np.inf), ("fourbar.toml: at: expected finite values, found inf",)),
        (lambda m: m.solve(at=[30, np.nan]), ("at: expected finite values",)),
        (lambda m: m.solve(at="thirty"), ("at: expected numbers, found 'thirty'",)),
        (lambda m: m.solve(at={"crank": 30}), ("at: expected numbers",)),
        (lambda m: m.solve(at=[]), ("at: expected from 1 to 10000 states, found 0",)),
        (lambda m: m.solve(at=np.zeros(100_001)), ("found 100001",)),
        (lambda m: m.solve(at=[[30, 40]]), ("at: expected inputs of shape (N, 1), found (1, 2)",)),
        (lambda m: m.solve(at=30, rates=np.nan), ("rates: expected finite values, found nan",)),
        (lambda m: m.solve(at=30, rates=1, accelerations=-np.inf), ("accelerations: expected finite values",)),
        (lambda m: m.draw(at=np.nan), ("at: expected finite values, found nan",)),
        (lambda m: m.draw(at=[30, 40]), ("at: expected one state to draw, found 2",)),
        (lambda m: m.sweep(samples=-5), ("samples: expected a whole number from 2 to 100000, found -5",)),
        (lambda m: m.sweep(samples=math.nan), ("samples:", "found nan")),
        (lambda m: m.animate(frames=10**9), ("frames: expected a whole number from 2 to 100000",)),
        (lambda m: m.animate(frames=5, interval=-1), ("interval: expected a finite number above 0 ms, found -1",)),
        (lambda m: m.sweep(samples=5).draw(5), ("i: expected a whole number from 0 to 4, found 5",)),
        (lambda m: m.sweep(samples=5).plot(point="Z"), ("point: expected one of A, D, B, C", "found 'Z'")),
        (lambda m: m.sweep(samples=5).plot(body=["crank"]), ("body: expected one of crank, coupler, rocker",)),
    ],
)
def test_assembled_mechanism_checks_its_arguments(fourbar, call, needles):
    _one_line(lambda: call(fourbar), *needles)


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"samples": 10**9}, "samples: expected a whole number from 3 to 100000, found 1000000000"),
        ({"samples": -5}, "samples: expected a whole number from 3 to 100000, found -5"),
        ({"samples": math.nan}, "found nan"),
        ({"engines": 5}, "engines: expected a comma-separated string or a sequence of mode or group names, found 5"),
        ({"engines": ["native", None]}, "engines: expected"),
    ],
)
def test_run_checks_its_arguments_before_any_work(kwargs, needle):
    _one_line(lambda: xcheck.run(FOURBAR, **{"engines": "native", **kwargs}), needle)


def test_run_checks_its_processes():
    from xcheck import api

    _one_line(
        lambda: api.run(FOURBAR, engines="native", jobs=0), "jobs: expected a whole number from 1 to 256, found 0"
    )


def test_a_huge_but_finite_input_is_refused_as_on_the_command_line(fourbar):
    """1e300 degrees is a number, outside the crank's feasible range: refused in
    one line naming the range, as ``xcheck solve fourbar --at 1e300 --rate 1`` does."""
    with pytest.raises(
        InputError, match=r"fourbar.toml: at crank: expected an input within the feasible range \(crank"
    ):
        fourbar.solve(at=1e300, rates=1.0)


# ----------------------------------------------------------------------------- the same rule on the command line


@pytest.mark.parametrize(
    "args, line",
    [
        (
            ["run", FOURBAR, "--samples", "-5"],
            "xcheck: error: --samples: expected a whole number from 3 to 100000, found -5",
        ),
        (["run", FOURBAR, "--jobs", "0"], "xcheck: error: --jobs: expected a whole number from 1 to 256, found 0"),
        (["fuzz", "--samples", "2"], "xcheck: error: --samples: expected a whole number from 3 to 100000, found 2"),
        (["fuzz", "--workers", "999"], "xcheck: error: --workers: expected a whole number from 1 to 256, found 999"),
    ],
)
def test_the_command_line_applies_the_same_rule(tmp_path, args, line):
    result = invoke(*args, "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and result.stderr.splitlines() == [line]
    assert not (tmp_path / "out").exists()  # refused before anything was written


@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda m: m.solve(at=True), "at: expected numbers, found True"),
        (lambda m: m.solve(at="30"), "at: expected numbers, found '30'"),
        (lambda m: m.solve(at=[30, [40]]), "at: expected numbers"),
        (lambda m: m.solve(at=1 + 2j), "at: expected numbers, found (1+2j)"),
        (lambda m: m.solve(at=0.5, si=1), "si: expected True or False, found 1"),
        (lambda m: m.draw(at=0.5, si="yes"), "si: expected True or False, found 'yes'"),
        (lambda m: m.animate(frames=3, interval=True), "interval: expected a finite number above 0 ms, found True"),
        (lambda m: m.animate(frames=3, interval=math.inf), "interval: expected a finite number above 0 ms, found inf"),
        (lambda m: m.sweep(samples=3).plot(point=0), "point: expected one of A, D, B, C, K, F, found 0"),
        (lambda m: m.sweep(samples=3).plot(body=""), "body: expected one of crank, coupler, rocker, found ''"),
    ],
)
def test_values_of_the_wrong_type_are_named(fourbar, call, needle):
    _one_line(lambda: call(fourbar), needle)


@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda: xcheck.load(5), "name: expected a path (str or os.PathLike), found 5"),
        (lambda: xcheck.load(""), "name: expected a path (str or os.PathLike), found ''"),
        (lambda: xcheck.load("fourbar", models=3.5), "models: expected a path (str or os.PathLike), found 3.5"),
        (lambda: xcheck.load(FOURBAR, branch=["upper"]), "branch: expected a string, found ['upper']"),
        (lambda: xcheck.load_mechanism(None), "path: expected a path (str or os.PathLike), found None"),
        (lambda: xcheck.select_modes("native", kinds="free"), "kinds: expected a tuple of kinds among"),
        (lambda: xcheck.printed_answers(xcheck.load(FOURBAR).kinematics, 0), "comparisons: expected a path"),
        (lambda: xcheck.api.run(FOURBAR, engines="native", samples=5, progress=3), "progress: expected a function"),
        (lambda: xcheck.api.run(FOURBAR, engines="native", samples=5, branch=np.zeros(2)), "branch: expected a string"),
    ],
)
def test_entries_name_an_argument_of_the_wrong_type(call, needle):
    _one_line(call, needle)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_named_as_a_mechanism_file_does_not_hang(tmp_path):
    """`xcheck list DIR` with a FIFO named x.toml there hung in open(); nothing writes
    to it, so it reads as an empty file, one line among the others' rows."""
    (tmp_path / "fourbar.toml").write_bytes((MODELS / "fourbar.toml").read_bytes())
    os.mkfifo(tmp_path / "x.toml")
    result = invoke("list", str(tmp_path))
    assert result.returncode == 2 and "fourbar" in result.stdout
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"xcheck: error: {tmp_path / 'x.toml'}: ")


@pytest.mark.parametrize(
    "value, found", [(0, "0"), (-1, "-1"), (math.nan, "nan"), ("2", "'2'"), (True, "True"), (2e6, "2000000.0")]
)
def test_a_duration_is_checked_alike_from_python_and_the_command_line(value, found):
    with pytest.raises(InputError) as caught:
        xcheck.simulate("iftomm-a01", duration=value)
    assert str(caught.value) == f"duration: expected a time above 0 s and at most 1e6 s, found {found}"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        result = invoke("simulate", "iftomm-a01", "--duration", str(value), "--no-report")
        assert result.returncode == 2
        assert result.stderr.startswith("xcheck: error: --duration: expected a time above 0 s and at most 1e6 s, found")


@pytest.mark.parametrize(
    "args, line",
    [
        (["simulate", "iftomm-a01", "--duration", "soon"], "--duration: expected a number, found 'soon'"),
        (["run", FOURBAR, "--samples", "many"], "--samples: expected a whole number, found 'many'"),
        (["run", FOURBAR, "--jobs", "1.5"], "--jobs: expected a whole number, found '1.5'"),
        (["fuzz", "--seed", "x"], "--seed: expected a whole number, found 'x'"),
        (["solve"], "name: expected a value, found none"),
        (["solve", FOURBAR, "--at"], "--at: expected a value after it, found none"),
        (["solve", FOURBAR, "extra"], "expected no more arguments, found 'extra'"),
        (["frobnicate"], "expected a command among list, engines"),
        (["run", FOURBAR, "--sample", "5"], "--sample: expected an option among --branch"),
    ],
)
def test_a_command_line_that_cannot_be_parsed_is_one_line(args, line):
    """Typer's box of usage and help (five lines) was the one bad input that was
    not one line; now it says what was expected and found, exit code 2."""
    result = invoke(*args)
    assert result.returncode == 2 and result.stdout == ""
    (error,) = result.stderr.splitlines()
    assert error.startswith(f"xcheck: error: {line}"), error


def test_help_and_no_arguments_are_as_they_were():
    assert invoke("--help").returncode == 0 and "Usage" in invoke("--help").stdout
    assert invoke("run", "--help").returncode == 0
    bare = invoke()
    assert bare.returncode == 2 and "Usage" in bare.stdout and "error" not in bare.stderr
