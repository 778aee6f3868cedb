"""Cases a review found: inputs at limit positions, a bifurcation, two inputs,
harmonic turning points, a user's own files (a driver that does not move:
test_user_files)."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest
from conftest import MODELS
from typer.testing import CliRunner

from xcheck import Kinematics, Status, load_mechanism
from xcheck.cli import app

DATA = Path(__file__).parent / "data"


def _cli(*args):
    return CliRunner().invoke(app, list(args))


def test_an_input_at_a_limit_position_is_refused():
    """The range's own end is refused (rates unbounded there); just inside it solves."""
    kin = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
    high = math.degrees(kin.input_range("crank").high)
    result = _cli("solve", str(MODELS / "fourbar.toml"), "--at", repr(high))
    assert result.exit_code == 2 and "clear of the limit positions" in result.stderr
    assert _cli("solve", str(MODELS / "fourbar.toml"), "--at", "129.022").exit_code == 0


def test_the_printed_range_is_feasible():
    """The displayed ends are rounded inwards: the value shown is accepted."""
    result = _cli("list", "--json", "--models", str(MODELS))
    fourbar = next(r for r in json.loads(result.stdout) if r["name"] == "fourbar")
    high = fourbar["ranges"][0]["text"].split("…")[1].split()[0]
    assert _cli("solve", str(MODELS / "fourbar.toml"), "--at", high).exit_code == 0


def test_a_parallelogram_stops_at_its_change_points():
    """At 0 and 180 deg the parallelogram's two branches cross (det Phi_q = 0):
    continuation stops there instead of carrying on along the crossed branch."""
    kin = Kinematics(load_mechanism(DATA / "para.toml"))
    rng = kin.input_range("crank", "parallel")
    assert rng.low == pytest.approx(0.0, abs=1e-6) and rng.high == pytest.approx(math.pi, abs=1e-6)
    solution = kin.solve([math.radians(10), math.radians(90), math.radians(170)], branch="parallel")
    rocker = solution.body("rocker")["angle"]
    crank = solution.body("crank")["angle"]
    assert (solution.status == Status.OK).all()
    assert abs(rocker - crank).max() < 1e-12  # parallel: the rocker turns with the crank
    assert _cli("solve", str(DATA / "para.toml"), "--at", "-90", "--branch", "parallel").exit_code == 2


def test_two_inputs_are_judged_by_the_solve_not_by_one_range_at_a_time():
    """(170, 79.9) deg assembles although 170 is outside the left input's range
    with the right one held at its assembly value."""
    kin = Kinematics(load_mechanism(DATA / "fivebar.toml"))
    assert not kin.input_range("left").contains(math.radians(170))
    result = _cli("solve", str(DATA / "fivebar.toml"), "--at", "170:79.9", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["states"][0]["status"] == "ok"


def test_harmonic_turning_points_are_reached_with_zero_rate():
    law = load_mechanism(DATA / "fivebar.toml").drivers[1].law
    for value in (law.centre - law.amplitude, law.centre + law.amplitude):
        q, qd, qdd = law.state_at(value)
        assert q == value and qd == 0.0 and qdd != 0.0


def test_a_users_own_file_uses_its_own_folder(tmp_path):
    """A copy of the four-bar with another rocker length, in a folder of its own:
    the repository's printed answers are not applied to it, and reports and
    exported files go beside it."""
    own = tmp_path / "fourbar.toml"
    own.write_text((MODELS / "fourbar.toml").read_text().replace("length = 500", "length = 520"))
    solved = _cli("solve", str(own), "--json")
    assert solved.exit_code == 0 and "textbook" not in json.loads(solved.stdout)
    assert _cli("run", str(own), "--engines", "formulations", "--samples", "11", "-q").exit_code == 0
    assert (tmp_path / "reports" / "fourbar.md").is_file()
    assert _cli("export", str(own), "--format", "mjcf").exit_code == 0
    assert (tmp_path / "mjcf" / "fourbar.xml").is_file()
    assert _cli("run", str(own), "--out", str(own), "--no-report").exit_code == 2


def test_a_users_own_comparisons_folder_is_used(tmp_path):
    """The same file with the repository's comparisons copied beside its models/ folder."""
    (tmp_path / "models").mkdir()
    shutil.copy(MODELS / "fourbar.toml", tmp_path / "models" / "fourbar.toml")
    shutil.copytree(MODELS.parent / "comparisons", tmp_path / "comparisons")
    solved = _cli("solve", str(tmp_path / "models" / "fourbar.toml"), "--json")
    assert len(json.loads(solved.stdout)["textbook"]) == 96
