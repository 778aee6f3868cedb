"""docs/example_notebook.py: load → sweep → DataFrame → plot → compare, in under ten lines, runs."""

from __future__ import annotations

import os
import subprocess
import sys

from conftest import ROOT

EXAMPLE = ROOT / "docs" / "example_notebook.py"


def test_the_example_is_under_ten_lines_of_code():
    code = [line for line in EXAMPLE.read_text().splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert len(code) < 10, code


def test_the_example_runs_and_writes_its_figures(tmp_path, capsys):
    """In a fresh directory (the bundled mechanisms are found without ./models),
    with the Agg backend."""
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT / "src")}
    env.pop("XCHECK_MODELS", None)
    done = subprocess.run(
        [sys.executable, str(EXAMPLE)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert "formulation-II" in done.stdout and "pass" in done.stdout
    assert "fail" not in done.stdout
    for name in ("fourbar-sweep.png", "fourbar-at-60.png"):
        assert (tmp_path / name).read_bytes().startswith(b"\x89PNG")
