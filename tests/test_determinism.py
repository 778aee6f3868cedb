"""Two runs of the same command give the same results (issue 18): the JSON
without its timings, the reports byte for byte once the --out directory each
names is replaced, and the images byte for byte."""

from __future__ import annotations

import json

import pytest
from conftest import MODELS, invoke


def _run(out) -> dict:
    done = invoke(
        "run",
        "fourbar",
        "--engines",
        "formulations,mujoco-kinematic",
        "--samples",
        "31",
        "--out",
        str(out),
        "--json",
        "--report",
        "--models",
        str(MODELS),
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode in (0, 1), done.stderr
    document = json.loads(done.stdout)
    assert "timings" in document
    del document["timings"]
    return document


@pytest.mark.slow
def test_two_runs_give_identical_json_reports_and_images(tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    assert _run(first) == _run(second)
    files = sorted(p.relative_to(first) for p in first.rglob("*") if p.is_file())
    assert sorted(p.relative_to(second) for p in second.rglob("*") if p.is_file()) == files
    assert {str(p) for p in files} >= {"fourbar.md", "README.md", "fourbar/drawing.png", "fourbar/quantities.png"}
    for relative in files:
        a, b = (first / relative).read_bytes(), (second / relative).read_bytes()
        if relative.suffix in (".md", ".json"):  # the reports and the index name the run's --out
            a = a.replace(str(first).encode(), b"OUT")
            b = b.replace(str(second).encode(), b"OUT")
        assert a == b, f"{relative} differs between the two runs"
