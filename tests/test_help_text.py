"""Help text as a terminal shows it: every word of the source survives the
renderer, square brackets included ("of [units]" once showed as "of ")."""

from __future__ import annotations

import re

import pytest
import typer.main
from typer.testing import CliRunner

from xcheck.cli import app

COMMANDS = sorted(typer.main.get_command(app).commands)  # type: ignore[attr-defined]


def _rendered(*args: str) -> str:
    result = CliRunner().invoke(app, [*args, "--help"], env={"COLUMNS": "200", "TERMINAL_WIDTH": "200"})
    assert result.exit_code == 0, result.output
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", result.output).split())


def test_the_examples_of_the_report_show_their_brackets():
    assert "angular_rate of [units] for angles" in _rendered("solve")
    assert "an Exudyn script needs [free_motion], Drake's SDF no pin-in-slot" in _rendered("export")


@pytest.mark.parametrize("name", COMMANDS)
def test_every_bracketed_word_of_a_help_text_is_shown(name):
    command = typer.main.get_command(app).commands[name]  # type: ignore[attr-defined]
    texts = [command.help or ""] + [getattr(p, "help", None) or "" for p in command.params]
    shown = _rendered(name)
    for text in texts:
        for word in re.findall(r"\[[^\[\]]+\]", text.replace("\\[", "[")):
            assert word in shown, (name, word)
