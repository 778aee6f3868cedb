"""The bad-input corpus (issue 18): every file of tests/data/bad/ gives exit
code 2, one line on stderr naming the file and the field, nothing on stdout
and no traceback.

Each file's first line (after a byte-order mark, if the file has one) says
what is wrong, which field the error must name (`` Must name: `FIELD`. ``; an
empty field for errors about the file as a whole, which name no field) and,
for the free-motion cases, `` Command: simulate.`` (default ``solve``).
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from conftest import DATA, invoke

#: characters of an error line besides the file's path: the longest clear
#: message of the corpus (a hostile name's, which lists the safe alphabet and
#: echoes 60 characters of the name) is under 300
MAX_MESSAGE = 400
BAD = sorted((DATA / "bad").glob("*.toml"))
HEADER = re.compile(r"# Bad: .+\. Must name: `(?P<field>[^`]*)`\.(?: Command: (?P<command>solve|simulate)\.)?")


def header(path: Path) -> tuple[str, str]:
    """The field the error must name and the command to run, from the file's first line."""
    first = path.read_bytes().split(b"\n", 1)[0].decode("utf-8", errors="replace").lstrip("\ufeff")
    match = HEADER.fullmatch(first)
    assert match, f"{path.name}: first line {first!r} does not say what the error must name"
    return match["field"], match["command"] or "solve"


def test_corpus_has_at_least_60_files():
    assert len(BAD) >= 60


@pytest.mark.parametrize("path", BAD, ids=[p.stem for p in BAD])
def test_bad_file_gives_one_line_and_exit_2(path):
    field, command = header(path)
    started = time.monotonic()
    done = invoke(command, str(path))
    seconds = time.monotonic() - started
    assert "Traceback" not in done.stderr + done.stdout, done.stderr[-3000:]
    assert done.returncode == 2, done.stderr[-3000:]
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr[-3000:]
    prefix = f"xcheck: error: {path}: " + (f"{field}: " if field else "") + "expected "
    assert lines[0].startswith(prefix), f"{lines[0][:500]!r} does not start with {prefix!r}"
    # values found are echoed shortened, so that the line stays readable
    # whatever the file holds (a 200000-character expression, a 1e302 count)
    assert len(lines[0]) - len(str(path)) <= MAX_MESSAGE, f"{len(lines[0])} characters: {lines[0][:300]!r}"
    assert seconds < 10, f"{seconds:.1f} s for one bad file"


HOSTILE = [p for p in BAD if p.stem.startswith("name-")]


@pytest.mark.parametrize("command", ["run", "export"])
@pytest.mark.parametrize("path", HOSTILE, ids=[p.stem for p in HOSTILE])
def test_hostile_name_writes_nothing(tmp_path, path, command):
    """A file whose [mechanism] name is hostile (path separators, '..', control
    characters), run or exported from a models folder deep in a temporary
    directory, is refused in one line and writes nothing anywhere there."""
    models = tmp_path / "a" / "b" / "models"
    models.mkdir(parents=True)
    source = models / "hostile.toml"
    source.write_bytes(path.read_bytes())
    args = (
        ["--engines", "formulations", "--samples", "3", "--out", str(tmp_path / "a" / "b" / "reports")]
        if command == "run"
        else []
    )
    done = invoke(command, "hostile", *args, "--models", str(models))
    assert "Traceback" not in done.stderr + done.stdout, done.stderr[-3000:]
    assert done.returncode == 2, done.stderr[-3000:]
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"xcheck: error: {source}: mechanism.name: expected "), lines
    assert not any(c in lines[0] for c in "\x00\x07\x1b\r"), "control characters reach the terminal"
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p != source and p.is_file())
    assert written == []
