"""The engine contract: an engine registered from this module alone appears in
``xcheck run``, ``--engines``, ``engines``, ``list``, the JSON and the report,
judged like the built-in ones; an engine that raises fails with its reason
while the others run; one whose package is missing says so.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import DATA, MODELS, shifted_sweep
from typer.testing import CliRunner

from xcheck import engines
from xcheck.cli import app
from xcheck.ladder import Run, Series
from xcheck.results import trajectory_from_solution
from xcheck.tolerances import Tolerance

#: the toy's known error: every position moved by this fraction of the mechanism's size along x
SHIFT = 3e-7


class Shifted(engines.Engine):
    """The native sweep with every body and point position moved by SHIFT x size along x."""

    name = "toy"
    title = "a toy engine"
    modes = (
        engines.Mode(
            "toy-kinematic",
            "kinematic",
            Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "the toy: positions within 1e-6 of the size"),
        ),
    )

    def run(self, mode, kinematics, *, native, samples, branch=None):
        return shifted_sweep(mode, kinematics, native, SHIFT)


class Exploding(engines.Engine):
    name = "boom"
    modes = (engines.Mode("boom-kinematic", "kinematic", Tolerance(1, 1, 1, 1, "anything")),)

    def run(self, mode, kinematics, *, native, samples, branch=None):
        raise RuntimeError("the toy engine exploded")


class Missing(engines.Engine):
    name = "absent"
    requires = ("no_such_package_xcheck_test",)
    install = "pip install absent"
    modes = (engines.Mode("absent-dynamic", "dynamic", Tolerance(1, 1, 1, 1, "anything")),)


@pytest.fixture
def toys():
    registered = [engines.register(engine) for engine in (Shifted, Exploding, Missing)]
    yield registered
    for engine in registered:
        engines.unregister(engine.name)


def _cli(*args):
    return CliRunner().invoke(app, [*args, "--models", str(MODELS)])


def test_toy_engines_are_judged_and_reported(toys, tmp_path):
    result = _cli(
        "run",
        "fourbar",
        "--engines",
        "toy,boom,absent,formulation-II",
        "--json",
        "--report",
        "--samples",
        "21",
        "--out",
        str(tmp_path),
    )
    assert result.exit_code == 1, result.output  # boom failed
    doc = json.loads(result.stdout)
    toy = doc["engines"]["toy-kinematic"]
    assert toy["pass"] is True
    # the known error: SHIFT of the size, to round-off
    assert toy["relative"]["position"] == pytest.approx(SHIFT, rel=1e-6)
    assert toy["relative"]["velocity"] <= 1e-12
    boom = doc["engines"]["boom-kinematic"]
    assert boom["pass"] is False and "RuntimeError: the toy engine exploded" in boom["reason"]
    assert doc["engines"]["formulation-II"]["pass"] is True  # the others still ran
    assert "not installed: no_such_package_xcheck_test (pip install absent)" in doc["not_applicable"]["absent-dynamic"]
    report = (tmp_path / "fourbar.md").read_text(encoding="utf-8")
    assert "`toy-kinematic`" in report and "the toy: positions within 1e-6 of the size" in report
    assert "the toy engine exploded" in report


def test_toy_engines_are_listed_and_selectable(toys):
    listed = CliRunner().invoke(app, ["engines", "--json"])
    assert listed.exit_code == 0, listed.output
    by_name = {e["name"]: e for e in json.loads(listed.stdout)["engines"]}
    assert by_name["toy"]["modes"] == [
        {
            "name": "toy-kinematic",
            "kind": "kinematic",
            "trusted_for": "exact to 1e-6 of the size",
            "on_request": False,
            "findings": [],
        }
    ]
    assert by_name["absent"]["available"] is False
    assert "toy (toy-kinematic)" in " ".join(_cli("list").stdout.split())  # however the line wraps
    kinematic = _cli("run", "fourbar", "--engines", "kinematic", "--json", "--no-report", "--samples", "11")
    assert "toy-kinematic" in json.loads(kinematic.stdout)["engines"]


def test_an_unknown_group_names_the_toys(toys):
    result = _cli("run", "fourbar", "--engines", "nosuch")
    assert result.exit_code == 2 and "toy-kinematic" in result.stderr and "boom" in result.stderr


def test_a_taken_name_is_refused(toys):
    class Clash(engines.Engine):
        name = "clash"
        modes = (engines.Mode("toy-kinematic", "kinematic", Tolerance(1, 1, 1, 1, "")),)

    with pytest.raises(ValueError, match="already provided by toy"):
        engines.register(Clash)
    with pytest.raises(ValueError, match="already registered"):
        engines.register(Shifted)


class Known(Shifted):
    """The toy's shifted positions judged at a bound below the shift: a failure in
    position that its engine states as a finding."""

    name = "known"
    modes = (
        engines.Mode(
            "known-kinematic",
            "kinematic",
            Tolerance(1e-8, 1e-12, 1e-12, 1e-12, "positions within 1e-8 of the size"),
        ),
    )
    findings = (
        engines.Finding(
            "the toy moves its positions", "the toy moves every position by 3e-7 of the size", ("position",)
        ),
    )


class Unknown(Shifted):
    """The same failure, its engine stating a finding elsewhere (in velocity): a plain failure."""

    name = "unknown"
    modes = (
        engines.Mode(
            "unknown-kinematic",
            "kinematic",
            Tolerance(1e-8, 1e-12, 1e-12, 1e-12, "positions within 1e-8 of the size"),
        ),
    )
    findings = (engines.Finding("a velocity defect", "a finding the toy does not show", ("velocity",)),)


class Costly(Shifted):
    name = "costly"
    modes = (
        engines.Mode(
            "costly-kinematic", "kinematic", Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "as the toy"), on_request=True
        ),
    )


@pytest.fixture
def findings():
    registered = [engines.register(engine) for engine in (Known, Unknown, Costly)]
    yield registered
    for engine in registered:
        engines.unregister(engine.name)


def test_a_stated_finding_fails_the_mode_but_not_the_run(findings, tmp_path):
    """A mode failing only in its engine's stated findings: the mode does not pass, its
    error and bound are shown with the finding, and the run exits 0; a failure in a
    category the engine did not state is a failure of the run."""
    args = ("run", "fourbar", "--json", "--samples", "21", "--out", str(tmp_path))
    known = _cli(*args, "--engines", "known-kinematic,formulation-II", "--report")
    assert known.exit_code == 0, known.output
    doc = json.loads(known.stdout)
    entry = doc["engines"]["known-kinematic"]
    assert entry["pass"] is False and entry["finding"] == "the toy moves every position by 3e-7 of the size"
    assert entry["relative"]["position"] == pytest.approx(SHIFT, rel=1e-6) and doc["verdict"] == "pass with findings"
    assert entry["verdict"] == "finding"
    assert doc["engines"]["formulation-II"]["finding"] is None
    report = (tmp_path / "fourbar.md").read_text(encoding="utf-8")
    assert "Result: **pass with findings** (every mode within its tolerance but the stated findings of " in report
    assert "stated findings of `known-kinematic`)" in report
    assert "`known-kinematic` fails (✗) only where its engine is known to be wrong: the toy moves" in report
    table = _cli("run", "fourbar", "--engines", "known-kinematic", "--samples", "21", "--no-report")
    assert table.exit_code == 0 and "finding" in table.stdout
    assert "known-kinematic: the engine's stated finding: the toy moves every position" in " ".join(
        table.stdout.split()
    )
    unknown = _cli(*args, "--engines", "unknown-kinematic", "--no-report")
    assert unknown.exit_code == 1, unknown.output
    doc = json.loads(unknown.stdout)
    entry = doc["engines"]["unknown-kinematic"]
    assert entry["pass"] is False and entry["finding"] is None
    assert entry["verdict"] == "fail" and doc["verdict"] == "fail"


def test_a_mode_on_request_runs_only_when_named(findings):
    """A mode marked on_request is out of the default selection and of its kind's
    group, and runs when its name or its engine's is given."""
    import xcheck

    assert "costly-kinematic" not in xcheck.select_modes(None) and "known-kinematic" in xcheck.select_modes(None)
    assert "costly-kinematic" not in xcheck.select_modes("kinematic")
    assert xcheck.select_modes("costly") == ("native", "costly-kinematic")
    assert "costly-kinematic" not in engines.groups()["kinematic"] and "costly-kinematic" in engines.groups()["costly"]
    listed = CliRunner().invoke(app, ["engines", "--json"])
    modes = {m["name"]: m for e in json.loads(listed.stdout)["engines"] for m in e["modes"]}
    assert modes["costly-kinematic"]["on_request"] and not modes["known-kinematic"]["on_request"]
    assert modes["known-kinematic"]["findings"] == ["position"]  # the quantities its findings spoil
    known = next(e for e in json.loads(listed.stdout)["engines"] if e["name"] == "known")
    assert known["findings"] == [
        {
            "title": "the toy moves its positions",
            "text": "the toy moves every position by 3e-7 of the size",
            "quantities": ["position"],
            "kinds": ["kinematic", "dynamic", "free"],
            "closed_loops": False,
            "reproducer": "",
            "series": [],
            "steps_below": None,
            "mechanisms": None,
        }
    ]


class FreeToy(engines.Engine):
    """A free mode whose one run returns the native reference's own motion at the
    compared outputs, every point moved by SHIFT x size: the ladder is the core's."""

    name = "freetoy"
    modes = (engines.Mode("freetoy-free", "free", Tolerance(1, 1, 1, 1, "benchmark: no verdict")),)

    def free_series(self, mode, kinematics):
        return (Series("toy", "copy"),)

    def run_free_once(self, mode, prepared, problem, rung):
        index = problem.index
        trajectory = trajectory_from_solution(problem.reference.motion.solution(), source=mode)
        trajectory.times = problem.times
        shift = np.array([SHIFT * problem.kinematics.system.size, 0.0])
        for states in trajectory.points.values():
            states["position"] = states["position"][index] + shift
        for states in trajectory.bodies.values():
            for key in list(states):
                states[key] = states[key][index]
        trajectory.diagnostics = {"constraint_violation": np.zeros(len(index))}
        return Run(trajectory)


def test_a_free_mode_from_a_test_module_runs_in_simulate():
    engines.register(FreeToy)
    try:
        done = _cli(
            "simulate",
            str(DATA / "spring-block.toml"),
            "--duration",
            "0.2",
            "--engines",
            "freetoy",
            "--json",
            "--no-report",
        )
        run = _cli("run", "fourbar", "--engines", "freetoy")  # a free mode is not a mode of `run`
    finally:
        engines.unregister("freetoy")
    assert done.exit_code == 0, done.output
    ladder = json.loads(done.stdout)["engines"]["freetoy-free"]["ladder"]
    assert ladder[0]["position_error"] == pytest.approx(SHIFT * 1.0, rel=1e-9)  # spring-block's size is 1 m
    assert run.exit_code == 2 and "found 'freetoy'" in run.stderr


class Weighty(Shifted):
    """The toy declared costly enough that a run with --jobs sends the modes to workers."""

    name = "weighty"
    modes = (
        engines.Mode("weighty-kinematic", "kinematic", Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "as the toy"), cost=5.0),
        engines.Mode("weighty-other", "kinematic", Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "as the toy"), cost=5.0),
    )


def test_an_engine_registered_at_run_time_runs_here_beside_the_worker_processes():
    """A spawned worker knows only the built-in and entry-point engines: with
    jobs > 1 the modes of an engine registered in this process run in it, the
    others in workers, and the run lists them in the order asked for."""
    from xcheck import api
    from xcheck.runner import PARALLEL_SAVING

    engines.register(Weighty)
    try:
        assert engines.registered_at_run_time("weighty") and not engines.registered_at_run_time("mujoco")
        assert 5.0 + 0.04 > PARALLEL_SAVING  # the summed cost less the costliest: worth workers
        told = []
        run = api.run(
            "fourbar",
            "weighty-kinematic,formulation-II,weighty-other",
            samples=21,
            models=MODELS,
            jobs=2,
            progress=told.append,
        )
    finally:
        engines.unregister("weighty")
    assert not engines.registered_at_run_time("weighty")
    assert list(run.outcomes) == ["native", "weighty-kinematic", "formulation-II", "weighty-other"]
    assert sorted(told) == ["forces", "formulation-II", "weighty-kinematic", "weighty-other"]
    for mode in ("weighty-kinematic", "weighty-other"):
        position = run.outcomes[mode].categories.set_index("category").relative["position"]
        assert run.outcomes[mode].passed and position == pytest.approx(SHIFT, rel=1e-6)
    assert run.outcomes["formulation-II"].passed and run.outcomes["formulation-II"].result is not None


def test_an_engines_availability_imports_nothing():
    """`available()` finds a dotted requirement (MJX's ``mujoco.mjx``) without importing
    its parent (MuJoCo: 0.25 s of every `xcheck list`), and names a missing submodule."""
    import subprocess
    import sys

    probe = (
        "import sys; from xcheck import engines; "
        "[e.available() for e in engines.engines()]; "
        "print(sorted(m for m in ('mujoco', 'jax', 'pinocchio', 'pymunk') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"

    class Partly(engines.Engine):
        name = "partly"
        requires = ("json.decoder", "json.no_such_submodule_xcheck", "no_such_package_xcheck.sub")

    assert Partly().available() == "not installed: json.no_such_submodule_xcheck, no_such_package_xcheck.sub"


_PLUG_IN = """
from xcheck import engines
from xcheck.tolerances import Tolerance


class Plugged(engines.Engine):
    name = "plugged"
    modes = (engines.Mode("plugged-kinematic", "kinematic", Tolerance(1, 1, 1, 1, "anything")),)
"""


def _install_plug_in(site, entry_points: str) -> None:
    from conftest import install_plug_in

    install_plug_in(site, "xcheck_plug_test", _PLUG_IN, entry_points)


def _engines_with(path: str):
    """(the engines' names, the plug-in errors) of ``xcheck engines --json`` with
    ``path`` first on a fresh interpreter's path."""
    import os
    import subprocess
    import sys

    from conftest import ROOT

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([path, str(ROOT / "src")])}
    done = subprocess.run(
        [sys.executable, "-m", "xcheck", "engines", "--json"], env=env, capture_output=True, text=True, check=True
    )
    doc = json.loads(done.stdout)
    return {e["name"] for e in doc["engines"]}, doc["plugin_errors"]


def test_an_installed_plug_in_is_listed_and_a_broken_one_reported(tmp_path):
    """The entry-point group end to end, through the quick check of the
    installed distributions that spares ``importlib.metadata`` where none
    declares the group."""
    _install_plug_in(
        tmp_path, "[xcheck.engines]\nplugged = xcheck_plug_test:Plugged\nbroken = xcheck_plug_no_such_module:Gone\n"
    )
    names, problems = _engines_with(str(tmp_path))
    assert "plugged" in names and "mujoco" in names
    assert list(problems) == ["broken"] and "ModuleNotFoundError" in problems["broken"]


def test_a_plug_in_inside_a_zip_file_on_the_path_is_found(tmp_path):
    """A zip file on the path is one place the quick check cannot read: it
    leaves the answer to ``importlib.metadata``."""
    import shutil

    site = tmp_path / "site"
    site.mkdir()
    _install_plug_in(site, "[xcheck.engines]\nplugged = xcheck_plug_test:Plugged\n")
    archive = shutil.make_archive(str(tmp_path / "plug"), "zip", site)
    names, problems = _engines_with(archive)
    assert "plugged" in names and problems == {}


def test_a_plug_in_in_an_egg_on_the_path_is_found(tmp_path):
    """An egg keeps its entry points in ``EGG-INFO``, which the quick check does
    not read: an egg on the path leaves the answer to ``importlib.metadata``."""
    egg = tmp_path / "xcheck_plug_test-1.0.egg"
    (egg / "EGG-INFO").mkdir(parents=True)
    (egg / "xcheck_plug_test.py").write_text(_PLUG_IN, encoding="utf-8")
    (egg / "EGG-INFO" / "PKG-INFO").write_text(
        "Metadata-Version: 2.1\nName: xcheck-plug-test\nVersion: 1.0\n", encoding="utf-8"
    )
    (egg / "EGG-INFO" / "entry_points.txt").write_text(
        "[xcheck.engines]\nplugged = xcheck_plug_test:Plugged\n", encoding="utf-8"
    )
    names, problems = _engines_with(str(egg))
    assert "plugged" in names and problems == {}


def test_no_plug_in_declared_skips_the_metadata_scan(tmp_path):
    """A distribution with other entry points only: nothing is listed, and the
    registry never imports ``importlib.metadata`` (40 ms of ``xcheck list``)."""
    import os
    import subprocess
    import sys

    from conftest import ROOT

    _install_plug_in(tmp_path, "[console_scripts]\nplug = xcheck_plug_test:main\n")
    names, problems = _engines_with(str(tmp_path))
    assert "plugged" not in names and problems == {}
    probe = (
        "import sys, xcheck.cli; from xcheck import engines; engines.engines(); "
        "print('importlib.metadata' in sys.modules)"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT / "src")])}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
