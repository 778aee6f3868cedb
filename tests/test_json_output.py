"""`--json` of `xcheck run` (issue 18): every wall-clock time is under one key,
"timings", so that two runs of the same mechanism give identical JSON once that
key is removed."""

from __future__ import annotations

import json

from conftest import MODELS
from typer.testing import CliRunner

from xcheck.cli import app


def _run_json(*args: str) -> dict:
    result = CliRunner().invoke(app, ["run", *args, "--json", "--no-report", "--quiet", "--models", str(MODELS)])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _times(value, path=""):
    """The paths of every key that names a time of the run (seconds, wall time)."""
    if isinstance(value, dict):
        for key, item in value.items():
            if any(word in key.lower() for word in ("second", "wall", "elapsed", "duration")):
                yield f"{path}.{key}"
            yield from _times(item, f"{path}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _times(item, f"{path}[{i}]")


def test_timings_are_under_one_key_and_runs_diff_clean():
    first = _run_json("fourbar", "--engines", "formulations", "--samples", "31")
    second = _run_json("fourbar", "--engines", "formulations", "--samples", "31")
    for document in (first, second):
        timings = document.pop("timings")
        assert set(timings) == {"seconds", "engines"}
        assert timings["seconds"] >= 0
        assert set(timings["engines"]) == set(document["engines"])
        assert all(t >= 0 for t in timings["engines"].values())
        assert list(_times(document)) == []  # no time left among the results
    assert first == second


def test_json_writes_no_report_unless_asked(tmp_path):
    """A script asking for JSON does not pay for figures: `run --json` writes
    only the JSON; `--json --report` writes the report as a plain run does."""
    common = ["run", "fourbar", "--engines", "formulations", "--samples", "11", "--quiet", "--models", str(MODELS)]
    bare = CliRunner().invoke(app, [*common, "--json", "--out", str(tmp_path / "bare")])
    assert bare.exit_code == 0, bare.output
    assert json.loads(bare.stdout)["mechanism"] == "fourbar"
    assert not (tmp_path / "bare").exists()
    asked = CliRunner().invoke(app, [*common, "--json", "--report", "--out", str(tmp_path / "asked")])
    assert asked.exit_code == 0, asked.output
    assert json.loads(asked.stdout)["mechanism"] == "fourbar"
    assert (tmp_path / "asked" / "fourbar.md").is_file() and (tmp_path / "asked" / "fourbar" / "drawing.png").is_file()
