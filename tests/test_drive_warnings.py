"""A driver whose motion law asks for more than its joint can do is warned about
in ``list``, ``solve`` and ``run`` (and their JSON): a crank driven round that
cannot turn fully, a harmonic swing beyond the feasible range."""

from __future__ import annotations

import json

import pytest
from conftest import DATA, MODELS
from typer.testing import CliRunner

from xcheck.cli import app

FILE = DATA / "crank-cannot-turn.toml"


def _cli(*args: str):
    return CliRunner().invoke(app, list(args), env={"COLUMNS": "300"})  # one warning, one line


def _one_warning(text: str) -> str:
    lines = [line for line in text.splitlines() if "cannot turn fully" in line]
    assert len(lines) == 1, text
    return lines[0]


def test_list_warns_and_its_json_says_so():
    listed = _cli("list", str(FILE))
    assert listed.exit_code == 0 and listed.stderr == "", listed.output
    line = _one_warning(listed.stdout)  # under the table
    assert line.startswith("warning: crank-cannot-turn: crank is driven round at a constant rate of 1200 rpm")
    assert "104.477 deg" in line  # the limit position derived in the file's header
    document = json.loads(_cli("list", str(FILE), "--json").stdout)
    assert document[0]["warnings"] == [line.removeprefix("warning: ")]


def test_solve_and_run_warn_too():
    solved = _cli("solve", str(FILE), "--at", "45", "--json")
    assert solved.exit_code == 0, solved.output
    assert json.loads(solved.stdout)["warnings"] == [_one_warning(solved.stderr).removeprefix("xcheck: warning: ")]
    ran = _cli("run", str(FILE), "--engines", "formulations", "--no-report", "--samples", "21")
    assert ran.exit_code == 0, ran.output
    assert "warning: crank-cannot-turn: crank is driven round" in _one_warning(ran.stdout)
    document = json.loads(_cli("run", str(FILE), "--engines", "native", "--json", "--samples", "11").stdout)
    assert len(document["warnings"]) == 1 and "cannot turn fully" in document["warnings"][0]


@pytest.mark.parametrize("name", ["slider-crank", "two-body-arm", "task-2-2"])
def test_a_law_that_fits_its_joint_is_not_warned_about(name):
    listed = _cli("list", str(MODELS / f"{name}.toml"), "--json")
    assert json.loads(listed.stdout)[0]["warnings"] == []
    assert "warning" not in _cli("list", str(MODELS / f"{name}.toml")).stdout


def test_a_swing_that_turns_at_a_limit_position_is_the_design():
    """The elliptic trammel's slide swings +-0.5 m, exactly to its limit positions."""
    listed = _cli("list", str(DATA / "elliptic-trammel.toml"), "--json")
    assert json.loads(listed.stdout)[0]["warnings"] == []


def test_a_harmonic_swing_beyond_the_range_is_warned_about(tmp_path):
    text = FILE.read_text(encoding="utf-8").replace(
        'motion = "constant-rate"\nstart = 60\nrate = 1200',
        'motion = "harmonic"\ncentre = 60\namplitude = 80\nfrequency = 2',
    )
    swinging = tmp_path / "swinging.toml"
    swinging.write_text(text, encoding="utf-8")
    lines = [line for line in _cli("list", str(swinging)).stdout.splitlines() if "warning" in line]
    assert len(lines) == 1 and "crank swings over -20 deg … 140 deg, beyond its feasible range" in lines[0]
    assert "104.477 deg" in lines[0]
