"""``xcheck draw``: a PNG of a mechanism at an input, without running any engine."""

from __future__ import annotations

import pytest
from conftest import MODEL_NAMES, MODELS, invoke

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_draw_writes_a_png_of_every_bundled_mechanism(name, tmp_path):
    target = tmp_path / f"{name}.png"
    result = invoke("draw", name, "--models", str(MODELS), "-o", str(target))
    assert result.returncode == 0, result.stderr
    assert target.read_bytes().startswith(PNG)
    assert [p.name for p in tmp_path.iterdir()] == [target.name]  # written whole: no temporary file left
    assert result.stdout.strip() == str(target)


def test_draw_at_an_input_in_display_units(tmp_path):
    target = tmp_path / "task.png"
    result = invoke("draw", "task-2-1", "--at", "40", "--models", str(MODELS), "-o", str(target))
    assert result.returncode == 0, result.stderr
    assert target.read_bytes().startswith(PNG)


@pytest.mark.parametrize(
    "at, expected",
    [
        ("200", "--at crank: expected an input within the feasible range"),
        ("abc", "--at crank: expected a number or an arithmetic expression, found 'abc'"),
        ("10,20", "--at: expected one state"),
        ("1e400", "found '1e400' (the value is not finite)"),
    ],
)
def test_draw_refuses_a_bad_input_in_one_line(at, expected, tmp_path):
    result = invoke("draw", "fourbar", "--at", at, "--models", str(MODELS), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and expected in result.stderr
    assert "fourbar.toml" in result.stderr
    assert not (tmp_path / "x.png").exists()


def test_draw_refuses_an_output_that_is_not_a_png(tmp_path):
    result = invoke("draw", "fourbar", "--models", str(MODELS), "-o", str(tmp_path / "x.txt"))
    assert result.returncode == 2 and result.stderr.startswith("xcheck: error: -o ")


def test_draw_takes_every_drivers_value_and_a_branch(tmp_path):
    arm = invoke("draw", "two-body-arm", "--at", "30:45", "--models", str(MODELS), "-o", str(tmp_path / "arm.png"))
    assert arm.returncode == 0, arm.stderr
    lower = invoke("draw", "fourbar", "--branch", "lower", "--models", str(MODELS), "-o", str(tmp_path / "low.png"))
    assert lower.returncode == 0, lower.stderr
    upper = invoke("draw", "fourbar", "--models", str(MODELS), "-o", str(tmp_path / "up.png"))
    assert (tmp_path / "low.png").read_bytes() != (tmp_path / "up.png").read_bytes()
    assert upper.returncode == 0
