"""The guide's worked example (docs/getting-started.md): the file it shows is
docs/examples/crank-rocker.toml word for word, and ``xcheck solve FILE --at 30``
prints the coupler point the guide quotes."""

from __future__ import annotations

import re

from conftest import ROOT
from typer.testing import CliRunner

from xcheck.cli import app

EXAMPLE = ROOT / "docs" / "examples" / "crank-rocker.toml"
GUIDE = ROOT / "docs" / "getting-started.md"


def test_the_guide_shows_the_example_file():
    guide = GUIDE.read_text(encoding="utf-8")
    assert f"```toml\n{EXAMPLE.read_text(encoding='utf-8').rstrip()}\n```" in guide


def test_example_solves_as_the_guide_says():
    result = CliRunner().invoke(app, ["solve", str(EXAMPLE), "--at", "30"])
    assert result.exit_code == 0, result.output
    guide = GUIDE.read_text(encoding="utf-8")
    quoted = re.search(r"^P      coupler .*$", guide, re.M)
    assert quoted is not None
    shown = [line for line in result.output.splitlines() if line.startswith("P ")]
    assert [line.split() for line in shown] == [quoted.group(0).split()]
