"""Mechanism files written the way a user writes them (issue 12): body angles
beyond +-180 deg, inputs given with their rates, static positions, motion laws
that reach a value modulo a turn, a directory with one bad file, and what a
user of their own file reads. Every expected value is a closed form derived
here, not xcheck's output."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS, run_dynamic
from typer.testing import CliRunner

from xcheck import Kinematics, load_mechanism
from xcheck.cli import app
from xcheck.model import parse_mechanism
from xcheck.runner import all_modes, sweep_inputs
from xcheck.units import evaluate_expression

DATA = Path(__file__).parent / "data"
FOURBAR_200 = DATA / "fourbar-200.toml"
YOKE = DATA / "scotch-yoke.toml"
TRAMMEL = DATA / "elliptic-trammel.toml"


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _json(*args) -> dict:
    result = _cli(*args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


# -- closed forms ----------------------------------------------------------
def _fourbar_200(theta: float, omega: float = 0.0):
    """Crank 0.1, coupler 0.4, rocker 0.3 m, ground A = 0, D = (0.35, 0):
    B, C (left of B -> D) and the coupler's and rocker's angular velocities."""
    b = 0.1 * np.array([math.cos(theta), math.sin(theta)])
    d = np.array([0.35, 0.0])
    bd = d - b
    dist = float(np.linalg.norm(bd))
    along = (0.4**2 - 0.3**2 + dist**2) / (2.0 * dist)
    height = math.sqrt(0.4**2 - along**2)
    unit = bd / dist
    c = b + along * unit + height * np.array([-unit[1], unit[0]])
    theta3 = math.atan2(*(c - b)[::-1])
    theta4 = math.atan2(*(c - d)[::-1])
    # velocity loop r2 w2 e2' + r3 w3 e3' = r4 w4 e4' solved by Cramer's rule
    w3 = omega * 0.1 * math.sin(theta4 - theta) / (0.4 * math.sin(theta3 - theta4))
    w4 = omega * 0.1 * math.sin(theta3 - theta) / (0.3 * math.sin(theta3 - theta4))
    return b, c, w3, w4


# -- 1. body angles are continuous -------------------------------------------
@pytest.mark.parametrize("degrees", [200.0, 300.0, 200.0 + 720.0, -160.0, 10.0, 200.0 - 1080.0])
def test_crank_assembled_at_200_deg_solves_at_any_angle(degrees):
    state = _json("solve", FOURBAR_200, "--at", repr(degrees))["states"][0]
    theta = math.radians(degrees)
    b, c, w3, w4 = _fourbar_200(theta, 1.5)
    assert state["status"] == "ok"
    assert state["bodies"]["crank"]["angle"] == pytest.approx(theta, abs=1e-12)  # continuous, never wrapped
    assert np.allclose(state["points"]["B"]["position"], b, atol=1e-13)
    assert np.allclose(state["points"]["C"]["position"], c, atol=1e-13)
    assert state["bodies"]["coupler"]["omega"] == pytest.approx(w3, abs=1e-12)
    assert state["bodies"]["rocker"]["omega"] == pytest.approx(w4, abs=1e-12)


def test_crank_assembled_at_200_deg_turns_fully():
    kin = Kinematics(load_mechanism(FOURBAR_200))
    assert kin.input_range("crank").full_turn
    assert kin.assemble()[2] == pytest.approx(math.radians(200.0), abs=1e-12)  # the crank's phi


@pytest.mark.parametrize("theta_deg", [150.0, 250.0, 150.0 + 360.0])
def test_a_prismatic_angle_offset_beyond_180_deg(theta_deg):
    kin = Kinematics(load_mechanism(DATA / "arm-block.toml"))
    theta, s = math.radians(theta_deg), 0.3
    solution = kin.solve(np.array([[theta, s]]), np.array([[1.0, 0.1]]), np.zeros((1, 2)))
    assert solution.success
    block = solution.body("block")
    e, n = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
    assert block["angle"][0] == pytest.approx(theta + math.radians(120.0), abs=1e-12)
    assert np.allclose(block["position"][0], s * e, atol=1e-14)
    assert np.allclose(block["velocity"][0], 0.1 * e + s * 1.0 * n, atol=1e-13)  # s' e + s theta' n
    assert block["omega"][0] == pytest.approx(1.0, abs=1e-13)


# -- 5. --at with rates; static positions; laws modulo a turn -------------------
def test_at_with_explicit_rate_and_acceleration():
    state = _json("solve", FOURBAR_200, "--at", "250", "--rate", "2", "--accel", "0.5")["states"][0]
    _, _, w3, w4 = _fourbar_200(math.radians(250.0), 2.0)
    assert state["bodies"]["crank"]["omega"] == 2.0 and state["bodies"]["crank"]["alpha"] == 0.5
    assert state["bodies"]["coupler"]["omega"] == pytest.approx(w3, abs=1e-12)
    assert state["bodies"]["rocker"]["omega"] == pytest.approx(w4, abs=1e-12)


def test_rate_needs_at_and_accel_needs_rate():
    assert "expected it with --at" in _cli("solve", FOURBAR_200, "--rate", "1").stderr
    result = _cli("solve", FOURBAR_200, "--at", "250", "--accel", "1")
    assert result.exit_code == 2 and "expected it with --rate" in result.stderr


def _static_yoke(tmp_path, force: float) -> Path:
    """The Scotch yoke with its crank standing still and a force along the guide on the yoke."""
    text = YOKE.read_text().replace("rate = 2.0             # rad/s", "rate = 0").split("[[instants]]")[0]
    path = tmp_path / "static-yoke.toml"
    path.write_text(text + f'\n[[loads]]\nbody = "yoke"\npoint = "Y"\nforce = [{force}, 0]\n')
    return path


def test_a_driver_that_stands_still_gives_statics(tmp_path):
    """Virtual work: tau d(theta) + F dx = 0 with x = r cos(theta), so tau = F r sin(theta)."""
    path = _static_yoke(tmp_path, 10.0)
    for degrees in (60.0, 200.0, 60.0 + 720.0):
        state = _json("solve", path, "--at", repr(degrees))["states"][0]
        assert state["bodies"]["crank"]["omega"] == 0.0 and state["bodies"]["yoke"]["velocity"] == [0.0, 0.0]
        assert state["drivers"]["crank"]["effort"] == pytest.approx(
            10.0 * 0.1 * math.sin(math.radians(degrees)), abs=1e-12
        )


def test_a_static_mechanism_runs_its_kinematic_modes(tmp_path):
    text = (MODELS / "fourbar.toml").read_text().replace("rate = 1.0            # rad/s (chosen)", "rate = 0")
    path = tmp_path / "still.toml"
    path.write_text(text.replace('name = "fourbar"', 'name = "still"').split("[[instants]]")[0])
    result = _cli("run", path, "--engines", "formulations,dynamic,mjx", "--samples", "11", "--no-report", "--json")
    document = json.loads(result.stdout)
    assert result.exit_code == 0, result.output
    assert set(document["not_applicable"]) == {
        "mujoco-dynamic",
        "pinocchio-dynamic",
        "pymunk-dynamic",
        "exudyn-dynamic",
        "pybullet-dynamic",
        "drake-dynamic",
        "mjx-dynamic",
        "dart-dynamic",
        "opensim-dynamic",
    }


def test_constant_acceleration_crank_reaches_any_angle_modulo_a_turn(tmp_path):
    """From rest at 200 deg with alpha = 1 rad/s^2: 0 deg (= 360) is reached after
    160 deg, where omega = sqrt(2 alpha * 160 deg)."""
    text = FOURBAR_200.read_text().replace(
        'motion = "constant-rate"\nstart = 200\nrate = 1.5             # rad/s',
        'motion = "constant-acceleration"\nstart = 200\nacceleration = 1.0',
    )
    path = tmp_path / "accelerating.toml"
    path.write_text(text)
    for degrees in ("0", "360", "-360"):
        state = _json("solve", path, "--at", degrees)["states"][0]
        assert state["bodies"]["crank"]["omega"] == pytest.approx(math.sqrt(2.0 * math.radians(160.0)), rel=1e-14)
        assert state["bodies"]["crank"]["alpha"] == 1.0
        assert state["bodies"]["crank"]["angle"] == pytest.approx(math.radians(float(degrees)), abs=1e-14)


def test_harmonic_law_takes_the_time_nearest_zero():
    """x_A = 0.5 sin(pi t / 2) passes 0.25 m at t = 1/3 s: x_A' = 0.5 (pi/2) cos(pi/6)."""
    state = _json("solve", TRAMMEL, "--at", "0.25")["states"][0]
    w = math.pi / 2.0
    assert state["bodies"]["slider_a"]["velocity"][0] == pytest.approx(0.5 * w * math.cos(math.pi / 6.0), rel=1e-14)
    assert state["bodies"]["bar"]["omega"] == pytest.approx(w, rel=1e-13)  # phi = 90 deg + w t
    assert state["bodies"]["bar"]["angle"] == pytest.approx(math.pi / 2.0 + w / 3.0, rel=1e-14)


def test_an_unreachable_instant_does_not_block_at(tmp_path):
    path = tmp_path / "trammel.toml"
    path.write_text(TRAMMEL.read_text() + '\n[[instants]]\nlabel = "beyond"\nx_A = 0.7\n')
    assert _cli("solve", path, "--at", "0.25").exit_code == 0
    result = _cli("solve", path)
    assert result.exit_code == 2 and "instants[1].x_A" in result.stderr and "0.7" in result.stderr


SLIDER_HARMONIC = (
    (MODELS / "slider-crank.toml")
    .read_text()
    .replace(
        'name = "crank"\njoint = "O"\nmotion = "constant-rate"\nstart = 0\nrate = 100                # rad/s',
        'name = "slide"\njoint = "slide"\nmotion = "harmonic"\ncentre = 340\namplitude = 80\nfrequency = 5',
    )
    .replace("at = { crank = 0 }", "at = { slide = 400 }")
    .split("[[instants]]")[0]
)


def test_one_rule_for_harmonic_inputs_in_solve_and_run(tmp_path):
    """The slide's law reaches 340 +- 80 mm only; the feasible range is wider.
    run sweeps only what the law reaches, with the law's own rates; solve refuses
    a value beyond it unless --rate gives the rates."""
    path = tmp_path / "slider.toml"
    path.write_text(SLIDER_HARMONIC)
    kin = Kinematics(load_mechanism(path))
    rng = kin.input_range(0)
    assert rng.low < 0.26 or rng.high > 0.42  # the case needs a range wider than the law
    inputs, rates, _ = sweep_inputs(kin, 21)
    assert inputs[:, 0].min() >= 0.26 - 1e-12 and inputs[:, 0].max() <= 0.42 + 1e-12
    w = 2.0 * math.pi * 5.0
    expected = 0.08 * w * np.sqrt(np.clip(1.0 - ((inputs[:, 0] - 0.34) / 0.08) ** 2, 0.0, None))
    assert np.allclose(np.abs(rates[:, 0]), expected, atol=1e-9)
    beyond = 1e3 * (rng.high - 1e-3) if rng.high > 0.42 else 1e3 * (rng.low + 1e-3)
    refused = _cli("solve", path, "--at", repr(beyond))
    assert refused.exit_code == 2 and "--rate" in refused.stderr
    assert _cli("solve", path, "--at", repr(beyond), "--rate", "0").exit_code == 0


# -- 6. one bad file does not stop a directory -------------------------------
def test_run_all_reports_a_bad_file_and_runs_the_rest(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "aaa-bad.toml").write_text("[mechanism]\nname = 'bad'\n[[joints]]\ntype = 'welded'\n")
    (folder / "fourbar-200.toml").write_text(FOURBAR_200.read_text())
    result = _cli(
        "run",
        "all",
        "--models",
        folder,
        "--engines",
        "formulations",
        "--samples",
        "11",
        "--out",
        tmp_path / "out",
        "-q",
    )
    assert result.exit_code == 2
    assert "aaa-bad.toml" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert (tmp_path / "out" / "fourbar-200.md").is_file()


def test_list_reports_a_bad_file_and_lists_the_rest(tmp_path):
    (tmp_path / "bad.toml").write_text("not toml [")
    (tmp_path / "fourbar-200.toml").write_text(FOURBAR_200.read_text())
    result = _cli("list", tmp_path, "--json")
    assert result.exit_code == 2 and "bad.toml" in result.stderr
    assert [row["name"] for row in json.loads(result.stdout)] == ["fourbar-200"]


# -- 7. what a user of their own file reads ----------------------------------
def test_list_gives_ranges_in_si_and_takes_a_file_or_a_folder(tmp_path):
    """The trammel's end A reaches +-L = +-0.5 m, where the bar lies along the guide.
    The folder holds three files (every file of tests/data costs seconds of range
    finding; a folder with a bad file among good ones is the test below's)."""
    rows = _json("list", TRAMMEL)
    assert [r["name"] for r in rows] == ["elliptic-trammel"]
    x_range = rows[0]["ranges"][0]
    assert x_range["unit"] == "m" and not x_range["full_turn"]
    assert x_range["low"] == pytest.approx(-0.5, abs=1e-8) and x_range["high"] == pytest.approx(0.5, abs=1e-8)
    assert x_range["text"].startswith("x_A: ")
    assert _json("list", "--models", FOURBAR_200)[0]["ranges"][0]["full_turn"] is True
    for path in (FOURBAR_200, YOKE, TRAMMEL):
        (tmp_path / path.name).write_bytes(path.read_bytes())
    assert [r["name"] for r in _json("list", tmp_path)] == ["elliptic-trammel", "fourbar-200", "scotch-yoke"]


def test_a_users_report_and_index_say_what_was_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fourbar-200.toml").write_text(FOURBAR_200.read_text())
    result = _cli("run", "fourbar-200.toml", "--engines", "formulations", "--samples", "11", "--out", "rep", "-q")
    assert result.exit_code == 0, result.output
    report = (tmp_path / "rep" / "fourbar-200.md").read_text()
    assert "No printed answers were given" in report and "comparisons/fourbar-200.toml" in report
    reproduce = next(line for line in report.splitlines() if line.startswith("Reproduce:"))
    assert reproduce == ("Reproduce: `xcheck run fourbar-200.toml --engines formulations --samples 11 --out rep`")
    index = (tmp_path / "rep" / "README.md").read_text()
    assert "xcheck run all" not in index and "`xcheck run fourbar-200.toml" in index


@pytest.mark.parametrize(
    "text,expected",
    [
        ("degrees(asin(0.5))", 30.0),
        ("acos(-1)", math.pi),
        ("4 * atan(1)", math.pi),
        ("degrees(atan(1 / sqrt(3)))", 30.0),
    ],
)
def test_inverse_trigonometry_in_expressions(text, expected):
    assert evaluate_expression(text) == pytest.approx(expected, rel=1e-15)


def test_inverse_trigonometry_out_of_its_domain_is_one_clear_line(tmp_path):
    path = tmp_path / "fourbar-200.toml"
    path.write_text(FOURBAR_200.read_text().replace("start = 200", 'start = "degrees(asin(2))"'))
    result = _cli("solve", path)
    assert result.exit_code == 2 and "drivers[0].start" in result.stderr and "Traceback" not in result.output


def test_mujoco_dynamic_says_it_used_default_masses():
    result = run_dynamic("mujoco-dynamic", Kinematics(load_mechanism(FOURBAR_200)), duration=0.05)
    assert result.ok, result.reason
    assert "Default mass properties (none in the model) for crank, coupler, rocker" in result.trajectories[0].notes


def test_a_harmonic_crank_angle_sweeps_its_arc_across_the_start_of_a_turn():
    """A crank of the turning four-bar rocked by 190 +- 40 deg: the sweep covers
    150 ... 230 deg, rates from the law (0 at the turning points, 40 deg * 2 pi at 190)."""
    text = FOURBAR_200.read_text().replace(
        'motion = "constant-rate"\nstart = 200\nrate = 1.5             # rad/s',
        'motion = "harmonic"\ncentre = 190\namplitude = 40\nfrequency = 1',
    )
    kin = Kinematics(parse_mechanism(text.replace("at = { crank = 200 }", "at = { crank = 190 }")))
    inputs, rates, _ = sweep_inputs(kin, 11)
    assert np.allclose(np.degrees(inputs[:, 0]), np.linspace(150.0, 230.0, 11), atol=1e-7)
    amplitude, w = math.radians(40.0), 2.0 * math.pi
    expected = amplitude * w * np.sqrt(np.clip(1.0 - ((inputs[:, 0] - math.radians(190.0)) / amplitude) ** 2, 0, None))
    assert np.allclose(np.abs(rates[:, 0]), expected, atol=1e-6)


def test_json_says_angles_are_continuous():
    document = _json("solve", FOURBAR_200, "--at", "920")
    assert document["units"]["angle"] == "rad" and document["angles"].startswith("continuous")
    assert document["states"][0]["bodies"]["crank"]["angle"] == pytest.approx(math.radians(920.0), abs=1e-12)


def test_wedge_closed_form():
    """Plunger at y = 50 - s/2 mm on the face of slope 1/2; rates -s'/2, -s''/2; nothing turns."""
    state = _json("solve", DATA / "wedge.toml", "--at", "30")["states"][0]
    s, s_dot, s_ddot = 0.030, math.sqrt(0.020**2 + 2.0 * 0.005 * 0.030), 0.005  # s' = sqrt(v0^2 + 2 a s)
    plunger = state["bodies"]["plunger"]
    assert plunger["position"] == pytest.approx([0.100, 0.050 - s / 2.0], abs=1e-15)
    assert plunger["velocity"] == pytest.approx([0.0, -s_dot / 2.0], abs=1e-15)
    assert plunger["acceleration"] == pytest.approx([0.0, -s_ddot / 2.0], abs=1e-15)
    assert plunger["omega"] == 0.0 and state["bodies"]["wedge"]["alpha"] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scotch-yoke", "elliptic-trammel", "fourbar-200", "wedge", "rocker-driven"])
def test_every_mode_runs_within_tolerance_on_the_issue_mechanisms(name, tmp_path):
    """The bar of issue 12: the user-written mechanisms through `xcheck run FILE`,
    every mode (those run only on request too) within its tolerance (exit 0),
    none failing or refused."""
    result = _cli("run", DATA / f"{name}.toml", "--out", tmp_path, "--json", "--samples", "61", "--engines", "all")
    document = json.loads(result.stdout)
    failed = {m: e for m, e in document["engines"].items() if not (e.get("pass") or e.get("finding"))}
    assert result.exit_code == 0 and not failed, failed
    assert {m for m, e in document["engines"].items() if e.get("finding")} <= {"mjx-dynamic"}
    assert set(document["engines"]) | set(document["not_applicable"]) == set(all_modes())
    # Exudyn's driven mode drives joint angles only (the trammel's and the wedge's inputs are slides)
    slides = name in ("elliptic-trammel", "wedge")
    # PyBullet's, Drake's, DART's, OpenSim's and Newton's models hold no pin-in-slot (the yoke's and
    # the wedge's slots); Newton (not in xcheck[all]) prescribes only a body hung from the ground
    slots = 'type = "pin-in-slot"' in (DATA / f"{name}.toml").read_text(encoding="utf-8")
    no_slots = {"pybullet-dynamic", "drake-dynamic", "dart-dynamic", "opensim-dynamic", "opensim-kinematic"}
    not_applicable = document["not_applicable"]
    assert set(not_applicable) - {"newton-dynamic"} <= (
        {"formulation-I"} | ({"exudyn-dynamic"} if slides else set()) | (no_slots if slots else set())
    )
    for mode in no_slots & set(not_applicable):
        assert "pin-in-slot" in not_applicable[mode]
    if "newton-dynamic" in not_applicable:
        reason = not_applicable["newton-dynamic"]
        assert any(why in reason for why in ("not installed", "pin-in-slot", "joins two moving bodies")), reason


def test_a_report_that_cannot_be_written_is_one_line_and_the_rest_run(tmp_path):
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the reports directory should be")
    folder = tmp_path / "two"
    folder.mkdir()
    for name in ("fourbar-200", "wedge"):
        (folder / f"{name}.toml").write_text((DATA / f"{name}.toml").read_text())
    result = _cli(
        "run",
        "all",
        "--models",
        folder,
        "--engines",
        "formulations",
        "--samples",
        "11",
        "--out",
        blocked / "reports",
        "--json",
        "--report",
    )
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 2, result.output
    assert all("expected a directory where the report of" in line for line in lines)
    assert [run["mechanism"] for run in json.loads(result.stdout)] == ["fourbar-200", "wedge"]  # both ran
    assert "Traceback" not in result.output


def test_exact_methods_near_a_change_point_are_judged_by_the_conditioning():
    """A parallelogram swept to 1 % of its change points (kappa up to 323): the
    formulations lose digits as eps kappa^2 in accelerations (3.4e-11), and
    their bound says so: max(1e-12, 10 eps kappa^2), kappa measured on the sweep."""
    result = _cli("run", DATA / "para.toml", "--engines", "kinematic", "--no-report", "--json")
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    kin = Kinematics(load_mechanism(DATA / "para.toml"))
    native = kin.solve(*sweep_inputs(kin, 181))
    kappa = 1.0 / native.singularity.min()
    assert 250.0 < kappa < 400.0
    alpha = document["engines"]["formulation-I"]
    assert alpha["tolerance"]["alpha"] == pytest.approx(10.0 * np.finfo(float).eps * kappa**2, rel=1e-9)
    assert alpha["tolerance"]["angle"] == 1e-12  # 10 eps kappa = 7e-13 does not bind
    assert alpha["relative"]["alpha"] > 1e-12  # the loss is real: the fixed round-off bound would fail it


def test_rocker_driven_range_closed_form():
    """The rocker's limits where crank (0.1) and coupler (|BC| = sqrt(0.13)) line up."""
    r4_sq, ad = 0.05**2 + 0.3**2, 0.35
    coupler = math.sqrt(0.2**2 + 0.3**2)
    limits = sorted(
        math.acos((ac**2 - ad**2 - r4_sq) / (2.0 * ad * math.sqrt(r4_sq))) for ac in (coupler + 0.1, coupler - 0.1)
    )
    rng = _json("list", DATA / "rocker-driven.toml")[0]["ranges"][0]
    assert rng["low"] == pytest.approx(limits[0], abs=1e-9) and rng["high"] == pytest.approx(limits[1], abs=1e-9)


def test_an_unbounded_slide_is_not_a_full_turn():
    """The wedge's push meets no limit (the face is a line): not "full turn", which is for cranks."""
    rng = _json("list", DATA / "wedge.toml")[0]["ranges"][0]
    assert rng["low"] is None and rng["high"] is None and rng["full_turn"] is False
    assert "no limit within" in rng["text"] and "mm" in rng["text"]


@pytest.mark.parametrize(
    "args,field,found",
    [
        (("--at", "30", "--rate", "abc"), "--rate crank", "'abc'"),
        (("--at", "30", "--rate", "1:2"), "--rate", "'1:2'"),
        (("--at", "30,40", "--rate", "1,2,3"), "--rate", "found 3"),
        (("--at", "30", "--rate", "1e400"), "--rate crank", "not finite"),
        (("--at", "30", "--rate", "1", "--accel", "1:2"), "--accel", "'1:2'"),
    ],
)
def test_bad_rates_are_one_line(args, field, found):
    result = _cli("solve", FOURBAR_200, *args)
    line = result.stderr.strip()
    assert result.exit_code == 2 and len(line.splitlines()) == 1
    assert line.startswith(f"xcheck: error: {FOURBAR_200}: {field}: expected ") and found in line


@pytest.mark.parametrize("name", ["./../../victim", "../../x", "a/b", ".hidden", "bell\x07", "x" * 101, " lead"])
def test_a_mechanism_name_must_be_a_plain_file_name(tmp_path, name):
    """The name names reports/NAME.md and models/mjcf/NAME.xml: it may not climb out of them."""
    path = tmp_path / "models" / "evil.toml"
    path.parent.mkdir()
    path.write_text(FOURBAR_200.read_text().replace('name = "fourbar-200"', f"name = {json.dumps(name)}", 1))
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "keep.txt").write_text("mine")
    result = _cli("run", path, "--engines", "formulations", "--samples", "11")
    assert result.exit_code == 2 and "mechanism.name: expected a name of ASCII letters" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "\x07" not in result.stderr
    assert (victim / "keep.txt").read_text() == "mine"
    assert _cli("export", "--models", path.parent).exit_code == 2
    assert not (tmp_path / "mjcf").exists() and not (path.parent / "mjcf").exists()


def test_a_folder_xcheck_did_not_write_is_never_replaced(tmp_path):
    (tmp_path / "fourbar-200.toml").write_text(FOURBAR_200.read_text())
    mine = tmp_path / "reports" / "fourbar-200"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("mine")
    result = _cli("run", tmp_path / "fourbar-200.toml", "--engines", "formulations", "--samples", "11", "-q")
    assert result.exit_code == 2 and "a folder xcheck did not write" in result.stderr
    assert (mine / "notes.txt").read_text() == "mine"


def test_a_byte_order_mark_is_not_content(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + FOURBAR_200.read_bytes())
    assert _cli("solve", path, "--at", "200").exit_code == 0


def test_toml_nested_too_deeply_is_one_line(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 100000 + "]" * 100000 + "\n")
    result = _cli("solve", path)
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "nested too deeply" in result.stderr


def test_no_engines_is_refused():
    result = _cli("run", FOURBAR_200, "--engines", "", "--no-report")
    assert result.exit_code == 2 and "--engines: expected at least one mode" in result.stderr


def test_a_motion_through_a_singular_state_leaves_the_power_balance_out(tmp_path):
    """The double four-bar driven a whole turn passes its change points, where the native
    velocities are not determined: the power balance is not computed and says why
    (it used to end `xcheck run all` with a traceback); the other files still run."""
    folder = tmp_path / "models"
    folder.mkdir()
    for name in ("double-fourbar", "fourbar-loaded"):
        (folder / f"{name}.toml").write_text((DATA / f"{name}.toml").read_text())
    result = _cli("run", "all", "--models", folder, "--engines", "formulations", "--samples", "21", "--json")
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    documents = {d["mechanism"]: d for d in json.loads(result.stdout)}
    assert set(documents) == {"double-fourbar", "fourbar-loaded"}
    double = documents["double-fourbar"]
    assert double["energy"] is None and "not all determined" in double["energy_not_computed"]
    assert double["engines"]["native"]["pass"] is False  # its sweep meets the undetermined samples too
    assert (
        documents["fourbar-loaded"]["energy"]["passed"] and documents["fourbar-loaded"]["energy_not_computed"] is None
    )
