"""The progress bar: on a terminal only, never with --json or with stdout piped.

Slow: each case runs ``xcheck run fourbar`` (kinematic modes) under a
pseudo-terminal, 5 to 15 s on a shared machine.
"""

from __future__ import annotations

import os
import pty
import subprocess
import sys

import pytest
from conftest import ROOT

pytestmark = pytest.mark.slow

BAR = "━"  # rich's bar glyph
COMMAND = ["run", "fourbar", "--engines", "kinematic", "--samples", "37", "--no-report"]


def _under_terminal(*args: str, pipe_stdout: bool = False) -> tuple[int, str, str]:
    """(exit code, what the terminal showed, stdout if piped) of ``xcheck ARGS``
    with stderr (and stdout unless ``pipe_stdout``) on a pseudo-terminal."""
    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "120"}
    process = subprocess.Popen(
        [sys.executable, "-m", "xcheck", *args],
        stdout=subprocess.PIPE if pipe_stdout else slave,
        stderr=slave,
        env=env,
        cwd=ROOT,
    )
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # the terminal closed
            break
        if not data:
            break
        chunks.append(data)
    piped = process.stdout.read().decode() if process.stdout else ""
    process.wait(timeout=600)
    os.close(master)
    return process.returncode, b"".join(chunks).decode(errors="replace"), piped


def test_progress_bar_on_a_terminal():
    code, shown, _ = _under_terminal(*COMMAND)
    assert code == 0 and BAR in shown and "fourbar: " in shown


def test_no_progress_bar_with_json():
    code, shown, _ = _under_terminal(*COMMAND, "--json")
    assert code == 0 and BAR not in shown and shown.lstrip().startswith("{")


def test_no_progress_bar_when_stdout_is_piped():
    code, shown, piped = _under_terminal(*COMMAND, pipe_stdout=True)
    assert code == 0 and BAR not in shown and BAR not in piped and "fourbar" in piped
