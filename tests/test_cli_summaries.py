"""What the commands print at a glance: ``engines`` as a table that fits a screen,
``simulate``'s summary with units and its report's path, ``run all``'s totals line."""

from __future__ import annotations

import re
import shutil

from conftest import MODELS
from typer.testing import CliRunner

from xcheck import engines
from xcheck.cli import app
from xcheck.output import mode_trust

WIDE = {"COLUMNS": "160"}


def test_engines_is_a_table_of_one_line_per_mode_that_fits_a_screen():
    result = CliRunner().invoke(app, ["engines"], env=WIDE)
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert len(lines) <= 40, len(lines)
    assert lines[0].split() == ["engine", "version", "mode", "kind", "trusted", "for", "stated", "findings"]
    for mode in engines.modes(engines.KINDS):
        row = next(line for line in lines if f" {mode.name} " in f" {line} ")
        assert mode_trust(mode) in row and mode.kind in row
    mjx = next(line for line in lines if " mjx-dynamic " in line)
    assert "acceleration, angular acceleration" in mjx  # its stated findings, by quantity


def test_simulate_prints_a_summary_with_units_and_where_the_report_is(tmp_path):
    out = tmp_path / "reports"
    result = CliRunner().invoke(
        app,
        ["simulate", "iftomm-a01", "--duration", "0.2", "--engines", "mujoco-free", "--out", str(out), "--jobs", "1"],
        env=WIDE,
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert len(lines) <= 12, result.output
    assert re.match(
        r"iftomm-a01 — free motion for 0.2 s: native reference \(DOP853\) converged, error <= \S+ m", lines[0]
    )
    header = next(line for line in lines if line.startswith("mode "))
    for unit in ("error [m]", "loop drift [m]", "energy drift [J]", "CPU [s per s]"):
        assert unit in header
    assert any(line.startswith("mujoco-free ") for line in lines)
    assert lines[-1] == f"report: {out / 'iftomm-a01.md'}" and (out / "iftomm-a01.md").is_file()
    quiet = CliRunner().invoke(
        app, ["simulate", "iftomm-a01", "--duration", "0.2", "--engines", "native", "--no-report"]
    )
    assert quiet.output.splitlines()[-1] == "report: not written (--no-report)"


def test_run_all_ends_with_its_totals(tmp_path):
    for name in ("fourbar", "slider-crank"):
        shutil.copy(MODELS / f"{name}.toml", tmp_path)
    (tmp_path / "broken.toml").write_text('[mechanism]\nname = "broken"\n', encoding="utf-8")
    result = CliRunner().invoke(
        app, ["run", "all", "--models", str(tmp_path), "--engines", "formulations", "--no-report", "--jobs", "1"]
    )
    assert result.exit_code == 2  # the broken file
    totals = [line for line in result.stdout.splitlines() if line.strip()][-1]
    assert re.fullmatch(
        r"3 mechanisms \(2 pass, 1 not run: bad input\); modes: 6 of 6 passed, 0 stated findings, 0 failed; \d+ s",
        totals,
    ), totals


def test_a_mode_whose_convergence_cannot_be_observed_shows_no_tolerance_not_nan(tmp_path):
    """Pinocchio's driven run through the dead centre of tests/data/near-dead-centre.toml
    goes through at its finest step only, so no order, hence no tolerance, can be
    observed (the JSON's tolerance is null): the table and the report show none, the
    failure line says why, instead of printing NaN as if it were a number, and the
    report is written (it had failed on the missing tolerances)."""
    result = CliRunner().invoke(
        app,
        ["run", "tests/data/near-dead-centre.toml", "--engines", "native,pinocchio-dynamic", "--out", str(tmp_path)],
        env=WIDE,
    )
    assert result.exit_code == 1, result.output
    assert not re.search(r"\bnan\b", result.output, re.IGNORECASE)
    row = next(line for line in result.output.splitlines() if line.startswith("pinocchio-dynamic "))
    assert row.split()[1] == "FAIL" and all(cell.endswith("/—") for cell in row.split()[2:])
    assert "position 6.28e-03 with no tolerance (no coarser run of the same settings ran through" in result.output
    report = (tmp_path / "near-dead-centre.md").read_text(encoding="utf-8")
    row = next(line for line in report.splitlines() if line.startswith("| `pinocchio-dynamic` | **FAIL**"))
    assert row.count("/ — ✗") == 6 and not re.search(r"\bnan\b", report, re.IGNORECASE)
