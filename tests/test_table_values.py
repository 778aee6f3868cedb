"""Solution tables: a value at round-off is not printed with its noise digits, and
angular accelerations are in an angle unit per s², never rpm/s."""

from __future__ import annotations

import re

import pytest
from conftest import DATA, MODELS
from typer.testing import CliRunner

from xcheck.cli import app


def _solve(*args: str) -> str:
    result = CliRunner().invoke(app, ["solve", *args], env={"COLUMNS": "250"})
    assert result.exit_code == 0, result.output
    return result.stdout


def _row(text: str, name: str) -> list[str]:
    return next(line.split() for line in text.splitlines() if line.startswith(f"{name} "))


@pytest.mark.parametrize(
    "args",
    [
        ["fourbar", "--at", "30"],
        ["fourbar-dynamics"],  # x of B at crank = 90 deg printed 6.12323e-15 mm
        ["slider-crank"],  # vy of B on the slide line printed -8.88178e-16 m/s
        ["task-2-5"],  # x of link4 printed -6.65678e-34 m
        [str(DATA / "scotch-yoke.toml"), "--at", "30"],  # a reaction printed 4.2423e-17 N
    ],
)
def test_noise_is_not_printed_as_a_value(args):
    """No cell of a table shows the digits of round-off (a number of order 1e-9 or
    less, in tables of millimetres, metres per second and newtons whose values are
    of order one): such a value is "0" where exact, else "< bound"."""
    text = _solve(*args, "--models", str(MODELS)) if not args[0].endswith(".toml") else _solve(*args)
    rows = [line for line in text.splitlines() if not line.startswith(" ")]  # not the residual line
    cells = [cell.strip() for line in rows for cell in re.split(r"\s{2,}", line)]
    for cell in cells:
        tiny = re.fullmatch(r"-?\d(?:\.\d+)?e-(\d+)", cell)
        assert tiny is None or int(tiny.group(1)) < 9, f"a value of order 1e-{tiny.group(1)}:\n{text}"


def test_ground_points_and_a_constant_rate_show_zero():
    text = _solve("fourbar", "--at", "30", "--models", str(MODELS))
    assert _row(text, "A")[2:] == ["0"] * 8
    crank = _row(text, "crank")
    assert crank[-1] == "0" or crank[-2] == "<"  # alpha: zero, or "< bound"


def test_angular_accelerations_of_an_rpm_file_are_per_second_squared():
    text = _solve(str(DATA / "rocker-driven.toml"), "--at", "1.8")
    assert "rpm/s" not in text
    assert "α [rad/s^2]" in text and "ω [rpm]" in text
    assert "rocker = 1.8 rad, 20 rpm, 0 rad/s^2" in text
