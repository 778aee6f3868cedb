"""A run of some modes (``--engines``) updates their parts of a report and keeps
the others': their rows, sections and figures, marked with the run that
produced them; a later run of every mode replaces the marks with its own parts."""

from __future__ import annotations

import hashlib
import json
import shutil

from conftest import MODELS, ROOT
from typer.testing import CliRunner

from xcheck.cli import app
from xcheck.fileio import MANIFEST
from xcheck.report import _evidence

FOURBAR = ("run", "fourbar", "--models", MODELS, "--samples", "31", "--no-gif", "-q")


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_run_of_some_modes_keeps_the_others_rows_and_figures(tmp_path):
    out = tmp_path / "reports"
    both = _cli(*FOURBAR, "--engines", "formulations,mujoco-kinematic", "--out", out)
    assert both.exit_code == 0, both.output
    first = (out / "fourbar.md").read_text(encoding="utf-8")
    differences = _digest(out / "fourbar" / "differences.png")
    assert "[1]" not in first

    some = _cli(*FOURBAR, "--engines", "formulations", "--out", out)
    assert some.exit_code == 0, some.output
    report = (out / "fourbar.md").read_text(encoding="utf-8")
    rows = [line for line in report.splitlines() if line.startswith("| `mujoco-kinematic`")]
    assert len(rows) == 2 and all(row.startswith("| `mujoco-kinematic` [1] |") for row in rows)  # comparison, tolerance
    kept = [line for line in first.splitlines() if line.startswith("| `mujoco-kinematic` |")]
    assert [row.replace(" [1]", "") for row in rows] == kept  # the very rows of the earlier run
    assert "| `mujoco` [1] | pass |" in report  # its reactions, from the earlier run too
    assert "| `newton-euler` | pass |" in report and "| `formulation-I` | pass |" in report  # rerun: unmarked
    provenance = next(line for line in report.splitlines() if line.startswith("[1] "))
    assert "`xcheck run fourbar --engines formulations,mujoco-kinematic" in provenance and "xcheck 0." in provenance
    # the differences of every mode: the earlier figure, kept and marked, not one without MuJoCo
    assert _digest(out / "fourbar" / "differences.png") == differences
    assert "(Figure [1]: kept from an earlier run.)" in report
    evidence = json.loads((out / "fourbar" / MANIFEST).read_text(encoding="utf-8"))
    made = {mode: part["produced"]["command"] for mode, part in evidence["modes"].items()}
    assert made["mujoco-kinematic"].startswith("xcheck run fourbar --engines formulations,mujoco-kinematic ")
    assert made["formulation-I"].startswith("xcheck run fourbar --engines formulations ")
    assert sorted(evidence["files"]) == sorted(p.name for p in (out / "fourbar").iterdir() if p.name != MANIFEST)

    # every mode of the report again: its own parts, no marks, the first report's text
    again = _cli(*FOURBAR, "--engines", "formulations,mujoco-kinematic", "--out", out)
    assert again.exit_code == 0, again.output
    assert (out / "fourbar.md").read_text(encoding="utf-8") == first


def test_the_index_line_of_a_partial_run_counts_the_kept_modes(tmp_path):
    """The index says what the report says: a kept mode's result counts."""
    out = tmp_path / "reports"
    assert _cli(*FOURBAR, "--engines", "formulations,mujoco-kinematic", "--out", out).exit_code == 0
    evidence = out / "fourbar" / MANIFEST
    document = json.loads(evidence.read_text(encoding="utf-8"))
    document["modes"]["mujoco-kinematic"]["verdict"] = "fail"  # as if MuJoCo had failed then
    document["modes"]["mujoco-kinematic"]["row"][0] = "**FAIL**"
    evidence.write_text(json.dumps(document), encoding="utf-8")
    assert _cli(*FOURBAR, "--engines", "formulations", "--out", out).exit_code == 0  # this run's modes pass
    assert "Result: **fail** (some modes beyond their tolerance)" in (out / "fourbar.md").read_text(encoding="utf-8")
    entry = json.loads((out / "index.json").read_text(encoding="utf-8"))["entries"][0]
    assert entry["name"] == "fourbar" and entry["passed"] is False
    # a kept figure the user removed is drawn afresh (of the modes run), not left out
    (out / "fourbar" / "differences.png").unlink()
    assert _cli(*FOURBAR, "--engines", "formulations", "--out", out).exit_code == 0
    assert (out / "fourbar" / "differences.png").is_file()
    assert "![differences](fourbar/differences.png)\n\n## Dynamic modes" in (out / "fourbar.md").read_text()


def test_a_report_of_an_earlier_version_is_not_merged_into_but_kept(tmp_path):
    """A report without evidence cannot keep the other modes' parts: a run of
    some modes says so in one line and leaves it whole."""
    out = tmp_path / "reports"
    (out / "fourbar").mkdir(parents=True)
    (out / "fourbar.md").write_text("# fourbar: Four-bar\n\nReproduce: `xcheck run fourbar`\n", encoding="utf-8")
    (out / "fourbar" / "drawing.png").write_bytes(b"\x89PNG an earlier drawing")
    before = {p: _digest(p) for p in out.rglob("*") if p.is_file()}
    result = _cli(*FOURBAR, "--engines", "formulations", "--out", out)
    line = result.stderr.strip()
    assert result.exit_code == 2 and len(line.splitlines()) == 1, result.output
    assert "without it" in line and "without --engines" in line and str(out / "fourbar") in line
    assert {p: _digest(p) for p in out.rglob("*") if p.is_file()} == before


def test_simulating_the_reference_alone_keeps_the_engines_of_the_committed_report(tmp_path):
    """``xcheck simulate iftomm-a01 --engines native`` on the committed report:
    the reference is new, the seven engines' sections and figures are the
    committed ones, marked."""
    out = tmp_path / "reports"
    shutil.copytree(ROOT / "reports" / "iftomm-a01", out / "iftomm-a01")
    shutil.copyfile(ROOT / "reports" / "iftomm-a01.md", out / "iftomm-a01.md")
    committed = json.loads((out / "iftomm-a01" / MANIFEST).read_text(encoding="utf-8"))
    engines = [mode for mode, part in committed["modes"].items() if "section" in part]
    assert len(engines) >= 2
    kept = {name: _digest(out / "iftomm-a01" / name) for name in ("errors.png", "work-precision.png")}
    done = _cli("simulate", "iftomm-a01", "--engines", "native", "--out", out, "--models", MODELS, "-q")
    assert done.exit_code == 0, done.output
    report = (out / "iftomm-a01.md").read_text(encoding="utf-8")
    for mode in engines:
        assert f"**`{mode}`** [1]" in report, mode
    assert report.count("(Figure [1]: kept from an earlier run.)") == 2
    assert {name: _digest(out / "iftomm-a01" / name) for name in kept} == kept
    assert "Reproduce: `xcheck simulate iftomm-a01 --engines native" in report
    entry = json.loads((out / "index.json").read_text(encoding="utf-8"))["entries"][0]
    assert all(mode in entry["worst"] for mode in engines)


def test_a_rerun_on_another_day_leaves_the_evidence_as_it_was(tmp_path, monkeypatch):
    """The parts a rerun of the same command reproduces keep their provenance, so
    a committed report's evidence reads the same after ``make run`` on any day; a
    part that shows something else is stamped anew."""
    out = tmp_path / "reports"
    assert _cli(*FOURBAR, "--engines", "formulations", "--out", out).exit_code == 0
    evidence = out / "fourbar" / MANIFEST
    first = {path: path.read_bytes() for path in (evidence, out / "fourbar.md")}
    monkeypatch.setattr(_evidence, "_today", lambda: "2099-12-31")
    assert _cli(*FOURBAR, "--engines", "formulations", "--out", out).exit_code == 0
    assert {path: path.read_bytes() for path in first} == first

    document = json.loads(evidence.read_text(encoding="utf-8"))
    document["modes"]["formulation-I"]["row"][1] = "0.5 / 1e-12"  # as if that run had shown another difference
    evidence.write_text(json.dumps(document), encoding="utf-8")
    assert _cli(*FOURBAR, "--engines", "formulations", "--out", out).exit_code == 0
    dates = {mode: part["produced"]["date"] for mode, part in json.loads(evidence.read_bytes())["modes"].items()}
    assert dates["formulation-I"] == "2099-12-31" and dates["formulation-II"] != "2099-12-31"


def test_a_partial_runs_rows_keep_the_whole_runs_order():
    """A source or mode the run did not rerun stays where the whole run put it,
    not after those it reran (a partial run of the kinematic modes reran OpenSim's
    reactions but not pymunk's, which come before them)."""
    made = _evidence.produced("xcheck run fourbar")
    parts = {name: {"row": [name], "produced": made} for name in ("newton-euler", "mujoco", "pymunk", "opensim")}
    previous = _evidence.Evidence("run", "fourbar", modes=dict(parts), sources=dict(parts))
    fresh_parts = {name: parts[name] for name in ("newton-euler", "opensim")}
    fresh = _evidence.Evidence("run", "fourbar", modes=dict(fresh_parts), sources=dict(fresh_parts))
    merged = _evidence.merge(fresh, previous)
    assert list(merged.sources) == list(merged.modes) == ["newton-euler", "mujoco", "pymunk", "opensim"]
    assert merged.carried == {"mujoco", "pymunk"}
    alone = _evidence.merge(_evidence.Evidence("run", "fourbar", sources={"pymunk": parts["pymunk"]}), previous)
    assert list(alone.sources) == ["newton-euler", "mujoco", "pymunk", "opensim"]
