"""`output.print_table` writes exactly what rich's own table rendering writes.

The fast path lays out plain tables itself (rich took 0.4 s for the tables of
`xcheck solve fourbar`); these tests hold it to rich's bytes, with and without
colour, on the tables xcheck prints and on random ones, and check that a table
it cannot lay out goes to rich.
"""

from __future__ import annotations

import io
import random

import pytest
from rich.console import Console
from rich.style import Style
from rich.table import Table

from xcheck import output
from xcheck.cli import app
from xcheck.output import _plain_table_lines, print_table


def _printed(table: Table, width: int, terminal: bool, fast: bool) -> tuple[str, list[tuple[str, Style]]]:
    """What a console of this width writes for ``table``, and its characters'
    styles as merged segments (the same styled text may come in differently
    split ANSI runs)."""
    console = Console(
        file=io.StringIO(),
        width=width,
        force_terminal=terminal,
        color_system="truecolor" if terminal else None,
        record=True,
    )
    if fast:
        print_table(console, table)
    else:
        console.print(table)
    runs: list[tuple[str, Style]] = []
    for segment in console._record_buffer:
        style = segment.style or Style.null()
        if runs and runs[-1][1] == style:
            runs[-1] = (runs[-1][0] + segment.text, style)
        elif segment.text:
            runs.append((segment.text, style))
    return console.file.getvalue(), runs


def _same_as_rich(table: Table, width: int = 140) -> bool:
    """True if the fast path took the table. Asserts that it writes rich's bytes
    without colour, and the same characters in the same styles with colour."""
    by_rich, by_xcheck = _printed(table, width, False, False), _printed(table, width, False, True)
    assert by_xcheck[0] == by_rich[0]
    by_rich, by_xcheck = _printed(table, width, True, False), _printed(table, width, True, True)
    assert by_xcheck[1] == by_rich[1]
    assert any(style for _, style in by_rich[1])  # colour was on
    return _plain_table_lines(Console(width=width), table) is not None


def _random_table(rng: random.Random) -> Table:
    words = ["a", "bc", "φ [deg]", "→", "—", "[green]agrees[/green]", "1.25e-09", "x" * 12, "[bold]b[/bold]"]
    table = Table(box=None, pad_edge=False, header_style="bold")
    columns = rng.randint(1, 7)
    wrapping = rng.randrange(columns) if rng.random() < 0.7 else None
    for i in range(columns):
        table.add_column(
            rng.choice(words + [""]),
            justify=rng.choice(["left", "right", "default"]),
            no_wrap=i != wrapping,
            overflow=rng.choice(["fold", "ellipsis", "crop"]),
        )
    for _ in range(rng.randint(0, 6)):
        cells = []
        for i in range(columns):
            count = rng.randint(0, 12 if i == wrapping else 2)
            cells.append(" ".join(rng.choice(words) for _ in range(count)))
        table.add_row(*cells)
    return table


def test_random_plain_tables_are_rich_s_bytes():
    rng = random.Random(17)
    taken = 0
    for _ in range(400):
        taken += _same_as_rich(_random_table(rng), width=rng.choice([20, 40, 60, 140]))
    # most must take the fast path, or this proves nothing (282 of the 400 with this seed)
    assert taken > 250


def test_a_table_with_a_box_a_title_or_too_narrow_goes_to_rich():
    boxed = Table(header_style="bold")
    boxed.add_column("name")
    boxed.add_row("fourbar")
    assert not _same_as_rich(boxed)
    titled = Table(box=None, pad_edge=False, title="t")
    titled.add_column("name")
    titled.add_row("fourbar")
    assert not _same_as_rich(titled)
    unwrappable = Table(box=None, pad_edge=False)
    for _ in range(3):
        unwrappable.add_column("c", no_wrap=True)
    unwrappable.add_row("x" * 30, "y" * 30, "z" * 30)
    assert not _same_as_rich(unwrappable, width=60)
    assert _same_as_rich(unwrappable, width=140)


@pytest.mark.parametrize("name", ["fourbar", "slider-crank", "task-2-3", "fourbar-dynamics"])
def test_the_tables_of_solve_are_rich_s_bytes(name, monkeypatch):
    from typer.testing import CliRunner

    tables = []
    monkeypatch.setattr(output, "print_table", lambda console, table: tables.append(table))
    result = CliRunner().invoke(app, ["solve", name])
    assert result.exit_code == 0, result.output
    assert len(tables) >= 4
    # the textbook table of fourbar wraps its notes: the narrowing is exercised too
    assert all(_same_as_rich(table) for table in tables)
