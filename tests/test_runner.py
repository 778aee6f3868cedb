"""`xcheck run`: the runner on every mechanism, the JSON summary, exit codes,
a perturbed engine model caught and named, and reports written whole."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from conftest import MODEL_NAMES, MODELS, WHOLE_RUN_SAMPLES, results_cache_on
from typer.testing import CliRunner

from xcheck import engines
from xcheck.cli import app
from xcheck.engines.mujoco import model as mujoco_model
from xcheck.runner import CATEGORIES, all_modes, tolerance

ALL_MODES = all_modes()
#: what runs with no selection: every mode but those run only on request (MJX's driven mode)
DEFAULT_MODES = tuple(m for m in ALL_MODES if m == "native" or not engines.mode(m).on_request)


def _cli(*args, **env):
    return CliRunner().invoke(app, [*args, "--models", str(MODELS)], env=env or None)


def test_every_mode_has_a_tolerance_and_one_engine():
    assert all(tolerance(m).basis for m in ALL_MODES)
    names = [m.name for e in engines.engines() for m in e.modes if m.kind != "free"]  # free: xcheck simulate
    assert len(names) == len(set(names)) and set(names) == set(ALL_MODES) - {"native"}
    assert {"formulations", "mujoco", "pinocchio", "pymunk"} <= {e.name for e in engines.engines()}


@pytest.mark.slow
@pytest.mark.parametrize("name", MODEL_NAMES)
def test_every_mode_within_tolerance(whole_run, name):
    """The whole comparison on every mechanism: every mode that applies runs
    (those run only on request too), and all are within their tolerances (the
    figures behind the dynamic tolerances are in each engine's modes, xcheck.engines)."""
    run = whole_run(MODELS / f"{name}.toml")
    failed = {
        m: (o.reason, o.categories.to_dict("records")) for m, o in run.outcomes.items() if not (o.passed or o.finding)
    }
    assert not failed and run.passed
    assert set(run.findings) <= {"mjx-dynamic"}  # MJX's accelerations, where the loops' J-dot qd is not zero
    ran = set(run.outcomes) | set(run.not_applicable)
    assert ran == set(ALL_MODES) and run.left_out == {}
    # formulation II applies to every model here; Exudyn's driven mode drives angles only;
    # PyBullet's, Drake's, DART's, OpenSim's and Newton's models hold no pin-in-slot; Newton
    # (not in xcheck[all]) prescribes only a body hung from the ground
    mech = run.kinematics.mechanism
    slides = any(d.quantity == "slide" for d in mech.drivers)
    slots = any(type(j).__name__ == "PinInSlot" for j in mech.joints)
    no_slots = ("pybullet-dynamic", "drake-dynamic", "dart-dynamic", "opensim-dynamic", "opensim-kinematic")
    assert set(run.not_applicable) - {"newton-dynamic"} <= (
        {"formulation-I"} | ({"exudyn-dynamic"} if slides else set()) | (set(no_slots) if slots else set())
    )
    if "exudyn-dynamic" in run.not_applicable:
        assert "slide" in run.not_applicable["exudyn-dynamic"]
    for mode in no_slots:
        if mode in run.not_applicable:
            assert "pin-in-slot" in run.not_applicable[mode]
    if "newton-dynamic" in run.not_applicable:
        reason = run.not_applicable["newton-dynamic"]
        assert any(why in reason for why in ("not installed", "pin-in-slot", "joins two moving bodies")), reason
    for outcome in run.outcomes.values():
        expected = {"position", "velocity", "acceleration"} if outcome.mode == "native" else set(CATEGORIES)
        if outcome.mode in ("pybullet-dynamic", "drake-dynamic", "dart-dynamic", "newton-dynamic"):  # not compared
            expected -= {"acceleration", "alpha"}
        assert set(outcome.categories.category) == expected


@pytest.mark.slow
def test_json_summary_shape(whole_run):
    """The JSON of every mode of the four-bar (the comparison of
    test_every_mode_within_tolerance, read from the run's results cache). A whole
    comparison, MJX's compilation included: with the slow tests it costs only the
    JSON's reading (the comparison is theirs), without them the whole comparison."""
    whole_run(MODELS / "fourbar.toml")
    with results_cache_on():
        result = _cli(
            "run", "fourbar", "--json", "--no-report", "--samples", str(WHOLE_RUN_SAMPLES), "--engines", "all"
        )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["mechanism"] == "fourbar" and doc["samples"] == WHOLE_RUN_SAMPLES and "pass" not in doc
    # MJX's stated finding (its qacc lacks the loops' J-dot qd) shows at an exact state, the
    # start; the driven ladder compares the samples after it, where MJX's loops, held open,
    # make up for it (measured 2.5e-3 of the largest acceleration at 0.125 ms, the bound 1.5e-2):
    # every mode passes (its rows still name the finding: test_engine_mjx)
    assert doc["verdict"] == "pass"
    assert set(doc["engines"]) | set(doc["not_applicable"]) == set(ALL_MODES) and doc["left_out"] == {}
    assert "mjx-dynamic" in doc["engines"] and set(doc["not_applicable"]) <= {"newton-dynamic"}  # Newton: not installed
    assert set(doc["cache"]["from_cache"]) >= set(doc["engines"]) - {"native"} and doc["cache"]["recomputed"] == {}
    for mode, entry in doc["engines"].items():
        assert entry["pass"] and entry["reason"] is None and entry["verdict"] == "pass" and entry["finding"] is None
        for category in ("position", "velocity", "acceleration"):
            # PyBullet gives no accelerations; Drake's, DART's and Newton's (where installed) are not compared
            if (
                mode in ("pybullet-dynamic", "drake-dynamic", "dart-dynamic", "newton-dynamic")
                and category == "acceleration"
            ):
                assert entry[category] is None
                continue
            assert isinstance(entry[category], float) and entry[category] >= 0.0
            assert entry["relative"][category] <= entry["tolerance"][category]
    textbook = doc["textbook"]
    assert len(textbook) == 96
    assert {"quantity", "printed", "computed", "deviation_percent", "verdict", "note"} <= set(textbook[0])
    assert sum(t["verdict"] == "disagrees" for t in textbook) == 1


def test_run_all_json_is_a_list():
    result = _cli("run", "all", "--json", "--no-report", "--samples", "11", "--engines", "formulations")
    assert result.exit_code == 0, result.output
    docs = json.loads(result.stdout)
    assert [d["mechanism"] for d in docs] == MODEL_NAMES
    assert all(
        set(d["engines"]) | set(d["not_applicable"]) == {"native", "formulation-I", "formulation-II"} for d in docs
    )


@pytest.mark.parametrize(
    "args,message",
    [
        (["run", "nosuch"], "unknown mechanism 'nosuch'"),
        (["run", "fourbar", "--engines", "bullet"], "--engines: expected modes or groups"),
    ],
)
def test_bad_input_exits_2(args, message):
    result = _cli(*args)
    assert result.exit_code == 2
    assert message in result.stderr and "Traceback" not in result.output


def test_perturbed_engine_model_is_caught_and_named(monkeypatch):
    """MuJoCo given a crank 1 mm longer than the model's: the run exits 1, the
    table marks mujoco-kinematic as failing, names the place, and the other
    modes still pass."""
    text = mujoco_model.mjcf_text

    def longer_crank(kinematics):
        root = ET.fromstring(text(kinematics))
        site = next(s for s in root.iter("site") if s.get("name") == "crank.B")
        coupler = next(b for b in root.iter("body") if b.get("name") == "coupler")
        for element in (site, coupler):
            x, y, z = (float(v) for v in element.get("pos").split())
            element.set("pos", f"{x + 1e-3!r} {y!r} {z!r}")
        return ET.tostring(root, encoding="unicode")

    monkeypatch.setattr(mujoco_model, "mjcf_text", longer_crank)  # the text the builder compiles
    result = _cli(
        "run", "fourbar", "--engines", "mujoco-kinematic,pinocchio-kinematic", "--no-report", "--samples", "31"
    )
    assert result.exit_code == 1, result.output
    lines = result.stdout.splitlines()
    row = next(line for line in lines if line.startswith("mujoco-kinematic"))
    assert "FAIL" in row
    assert next(line for line in lines if line.startswith("pinocchio-kinematic")).split()[1] == "pass"
    failure = next(line for line in lines if line.strip().startswith("mujoco-kinematic: position"))
    assert "point" in failure or "body" in failure


def test_a_failing_mode_is_reported_and_others_run(monkeypatch):
    def broken(self, mode, kinematics, *args, **options):
        raise RuntimeError("engine crashed")

    # a dynamic mode is its ladder: the engine crashes making it (in this process only: --jobs 1)
    monkeypatch.setattr(type(engines.engine("pymunk")), "dynamic_ladder", broken)
    result = _cli(
        "run", "slider-crank", "--engines", "pymunk,formulations", "--no-report", "--samples", "21", "--jobs", "1"
    )
    assert result.exit_code == 1
    assert "pymunk-dynamic: RuntimeError: engine crashed" in result.stdout
    assert next(line for line in result.stdout.splitlines() if line.startswith("formulation-I ")).split()[1] == "pass"


@pytest.mark.slow
def test_reports_are_written_whole(tmp_path):
    result = _cli("run", "two-body-arm", "--out", str(tmp_path), "--samples", "21", "--quiet")
    assert result.exit_code == 0, result.output
    assert result.stdout == ""
    report = (tmp_path / "two-body-arm.md").read_text()
    for heading in (
        "## Printed answers",
        "## Comparison with the native solution",
        "## Dynamic modes: error against time step",
        "## Native solver",
        "## Versions",
    ):
        assert heading in report
    for image in ("drawing.png", "quantities.png", "differences.png", "convergence.png", "motion.gif"):
        assert (tmp_path / "two-body-arm" / image).stat().st_size > 1000
        assert f"two-body-arm/{image}" in report
    models = Path(MODELS).resolve()
    shown = models.relative_to(Path.cwd().resolve()) if models.is_relative_to(Path.cwd().resolve()) else models
    assert f"Reproduce: `xcheck run two-body-arm --samples 21 --models {shown} --out {tmp_path}`" in report
    index = (tmp_path / "README.md").read_text()
    assert "[two-body-arm](two-body-arm.md)" in index
    # rerunning replaces the report; no staging directories are left behind
    assert (
        _cli(
            "run", "two-body-arm", "--out", str(tmp_path), "--samples", "21", "-q", "--engines", "formulations"
        ).exit_code
        == 0
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["README.md", "index.json", "two-body-arm", "two-body-arm.md"]


def test_forces_and_energy_in_the_json_summary():
    """A mechanism with mass data carries the reactions' comparison and the power
    balance; one without says why there are none."""
    result = _cli("run", "fourbar-dynamics", "--json", "--no-report", "--samples", "21", "--engines", "kinematic")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert set(doc["forces"]) == {"newton-euler", "mujoco", "pinocchio", "opensim"}
    for source, entry in doc["forces"].items():
        # 1e-12, or the round-off at the states' conditioning times the length ratio
        # (runner.force_tolerance on fourbar-dynamics: 10 eps kappa^2 ratio = 3.1e-12 for
        # Newton-Euler at the native states, 100 eps kappa^2 ratio = 3.1e-11 for an engine)
        bound = 5e-12 if source == "newton-euler" else 5e-11
        assert entry["pass"] is True and entry["relative"] <= entry["tolerance"] <= bound
    assert doc["energy"]["passed"] is True and doc["energy"]["relative"] <= 1e-12
    result = _cli("run", "task-2-3", "--json", "--no-report", "--samples", "21", "--engines", "formulations")
    doc = json.loads(result.stdout)
    assert doc["forces"] == {} and "expected mass and inertia" in doc["forces_not_computed"]


def test_work_meanwhile_is_done_once_after_the_reactions(monkeypatch):
    """``run_mechanism``'s ``meanwhile`` (a report's imports, done while workers run the
    modes): called once, after the reactions, in a run of this process too."""
    from xcheck import load, runner

    events = []
    add_forces = runner._add_forces

    def recorded(*args, **kwargs):
        add_forces(*args, **kwargs)
        events.append("reactions")

    monkeypatch.setattr(runner, "_add_forces", recorded)
    kinematics = load(MODELS / "slider-crank.toml").kinematics
    run = runner.run_mechanism(
        kinematics, ("native", "formulation-I"), 11, meanwhile=lambda: events.append("meanwhile")
    )
    assert events == ["reactions", "meanwhile"] and run.outcomes["formulation-I"].ok


def test_no_work_meanwhile_where_every_mode_comes_from_the_cache(monkeypatch, tmp_path):
    """With every mode's outcome in the results cache nothing is computed, so there is
    no wait for ``meanwhile`` to fill (a warm run's report would import matplotlib for
    nothing)."""
    from xcheck import load, runner
    from xcheck.store import CACHE_ENV

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    kinematics = load(MODELS / "slider-crank.toml").kinematics
    calls = []
    with results_cache_on():
        for _ in range(2):
            run = runner.run_mechanism(kinematics, ("native", "formulation-I"), 11, meanwhile=lambda: calls.append(1))
            assert run.outcomes["formulation-I"].ok
    assert calls == [1] and run.provenance["formulation-I"].from_cache
