"""Mechanism files written outside the project's own catalogue, and what they
exposed: a change point passed by the sweep, a mechanism name in another script."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import DATA, invoke

import xcheck
from xcheck.batch import export_models
from xcheck.kinematics import Status
from xcheck.results import missing_samples

CHANGE_POINT = DATA / "change-point.toml"


def test_a_change_point_is_no_missing_sample():
    """The five-sample sweep of the change-point four-bar hits crank = 180 deg, where
    all links are collinear: the native solver finds it near-singular (its rates
    carry no digits there), the exact formulations singular (no rates at all).
    That agreement is not a sample the formulations left out."""
    with warnings.catch_warnings(record=True):
        at_change = xcheck.load(CHANGE_POINT).solve(at=180)
    assert "near a limit or singular position" in " ".join(at_change.warnings)
    run = xcheck.run(CHANGE_POINT, engines="native,formulations", samples=5)
    assert run.verdict == "pass", run.summary.to_string()
    for mode in ("formulation-I", "formulation-II"):
        assert int(run.outcomes[mode].categories.missing.max()) == 0


def test_missing_samples_count_only_where_the_native_solution_is_determined():
    status = np.array([Status.OK, Status.OK, Status.NEAR_SINGULAR, Status.OK])
    finite = np.array([True, False, False, True])
    assert missing_samples(status, finite) == 1


@pytest.mark.parametrize("name", ["Schubkurbel-ä", "Računalna kinematika"])
def test_a_name_outside_ascii_is_refused_as_written(tmp_path, name):
    """The name names files, so it is kept to ASCII; the message says so and shows
    the name as the user wrote it (not as escapes)."""
    path = tmp_path / "named.toml"
    path.write_text(CHANGE_POINT.read_text().replace('name = "change-point"', f'name = "{name}"'), encoding="utf-8")
    done = invoke("solve", str(path), "--at", "90")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == (
        f"xcheck: error: {path}: mechanism.name: expected a name of ASCII letters, digits, spaces, '-', '_' and "
        "'.', neither starting with '.' or a space nor ending with a space, at most 100 characters (it names "
        f"the report and the exported files), found {name!r}"
    )


def test_export_names_a_file_that_cannot_assemble_once_and_goes_on(tmp_path):
    """A coupler of 10 m cannot close the change-point four-bar's loop (B and C are at most
    2 + 4 + 3 = 9 m apart): its file is one error, not one per format, and the good file
    beside it is still exported."""
    (tmp_path / "good.toml").write_text(CHANGE_POINT.read_text())
    bad = tmp_path / "open.toml"
    text = CHANGE_POINT.read_text().replace('name = "change-point"', 'name = "open"')
    bad.write_text(text.replace("length = 3\n", "length = 10\n", 1))
    done = list(export_models(None, ["mjcf", "urdf"], tmp_path))
    errors = [text for kind, text in done if kind == "error"]
    assert len(errors) == 1 and errors[0].startswith(f"{bad}: assembly.at: expected an input at which every loop"), done
    assert ("wrote", str(tmp_path / "mjcf" / "change-point.xml")) in done
    assert not (tmp_path / "mjcf" / "open.xml").exists() and not (tmp_path / "urdf" / "open.urdf").exists()
