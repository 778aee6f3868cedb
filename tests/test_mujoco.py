"""The MuJoCo adapter: the MJCF files, MuJoCo as a kinematic oracle and as a
simulator, each compared with the native solver.

Measured figures quoted below come from this file's own runs (MuJoCo 4.0.0);
``python -m pytest tests/test_mujoco.py`` reproduces them.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from conftest import DATA, MODEL_NAMES, MODELS

from xcheck import Kinematics, ModelError, engines
from xcheck.engines.mujoco import modes
from xcheck.engines.mujoco.dynamic import DEFAULT, TIGHT, simulate
from xcheck.engines.mujoco.modes import export_files, inverse_dynamics, relative_error, run_kinematic
from xcheck.errors import XcheckError
from xcheck.ladder import DrivenLadder, DrivenProblem, Series
from xcheck.model import parse_mechanism
from xcheck.precision import canonical_numbers, drift
from xcheck.results import differences
from xcheck.topology import spanning_tree

INVERTED = (DATA / "inverted.toml").read_text()
SLIDER_DRIVEN = (DATA / "slider-driven.toml").read_text()

# The inverted slider-crank and the slide-driven slider-crank cover pin-in-slot and
# prismatic joints on moving bodies and a slide input; REVERSED covers what no model
# has: revolutes listed child first (the hinge axis flips), a prismatic joint whose
# line is on the moving body (the ground point slides) with a locked angle of -20 deg.
REVERSED = (DATA / "reversed.toml").read_text()

# A loop closed by sliding joints only: a table sliding on the ground, a wedge
# sliding up the table, the wedge's pin in an inclined slot of the ground.
ALL_SLIDING = """
[mechanism]
name = "wedges"
[units]
length = "m"
[ground]
points = { O = [0, 0] }
[bodies.table]
points = { T = [0, 0] }
[bodies.wedge]
points = { W = [0, 0] }
[[joints]]
name = "table slide"
type = "prismatic"
bodies = ["ground", "table"]
line = "O"
direction = 0
point = "T"
[[joints]]
name = "wedge slide"
type = "prismatic"
bodies = ["table", "wedge"]
line = "T"
direction = 90
point = "W"
[[joints]]
name = "incline"
type = "pin-in-slot"
bodies = ["ground", "wedge"]
line = "O"
direction = 45
point = "W"
[[drivers]]
name = "push"
joint = "table slide"
motion = "constant-rate"
start = 0.1
rate = 0.5
[assembly]
at = { push = 0.1 }
[assembly.branches.only]
W = [0.1, 0.1]
"""


STRINGS = {"inverted": INVERTED, "slider-driven": SLIDER_DRIVEN, "reversed": REVERSED}
CASES = [*MODEL_NAMES, *STRINGS]

# Tight setting's time steps in these tests (the mode's default plan has more).
TEST_TIGHT_STEPS = (5e-4, 2.5e-4)


def run_dynamic(kin, tight=(1e-3, 4), default=(2e-3, 3), xml=None, duration=None):
    """mujoco-dynamic's ladder: the tight setting from ``tight[0]`` s over ``tight[1]``
    runs (compared; None: not run), MuJoCo's defaults likewise, on ``xml`` where given."""
    series = [
        Series(
            setting.name, setting.integrator, setting, name=f"{setting.name} {setting.integrator}", timestep=h, rungs=n
        )
        for setting, plan in ((TIGHT, tight), (DEFAULT, default))
        if plan is not None
        for h, n in (plan,)
    ]
    engine = engines.engine("mujoco")
    ladder = DrivenLadder(
        "mujoco-dynamic",
        kin,
        None,
        lambda problem: series,
        modes.run_dynamic_once,
        lambda problem: modes.prepare_dynamic(problem, xml),
        engine.findings,
        duration,
    )
    return ladder.run()


@pytest.fixture(scope="module")
def case(kinematics):
    """(Kinematics, MJCF text) of a case, each exported once for the module."""
    cache = {}

    def get(name: str):
        if name not in cache:
            kin = Kinematics(parse_mechanism(STRINGS[name], name)) if name in STRINGS else kinematics(name)
            (text,) = export_files(kin).values()
            cache[name] = (kin, text)
        return cache[name]

    return get


def _speed(kin: Kinematics, table) -> float:
    """The mechanism's speed W (1/s) over a :func:`differences` table's samples: the
    largest native angular velocity, or point speed per size, whichever is larger."""
    omega = table[table.quantity == "omega"].scale.max()
    speed = table[(table.kind == "point") & (table.quantity == "velocity")].scale.max()
    return float(max(omega, speed / kin.system.size))


# -- the files ------------------------------------------------------------------


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_committed_mjcf_is_current_and_opens(case, name):
    """models/mjcf/NAME.xml is what the writer writes now, MuJoCo opens it, and its
    bodies and sites carry the model's names."""
    kin, _ = case(name)
    with canonical_numbers() as units:  # as `xcheck export` writes it
        ((file_name, text),) = export_files(kin).items()
    path = MODELS / "mjcf" / file_name
    regenerate = "regenerate with: xcheck export --format mjcf"
    assert path.exists(), f"{path} is missing; {regenerate}"
    moved = drift(path.read_text(encoding="utf-8"), text, units)  # within the precision of its numbers
    assert moved is None, f"{path} is stale ({moved}); {regenerate}"
    model = mujoco.MjModel.from_xml_path(str(path))
    mech = kin.mechanism
    assert {model.body(i).name for i in range(1, model.nbody)} == {b.name for b in mech.moving_bodies}
    assert {model.site(i).name for i in range(model.nsite)} == {
        f"{b.name}.{label}" for b in mech.bodies for label in b.points
    }
    assert model.neq == len(spanning_tree(mech).cuts)
    assert model.opt.gravity.tolist() == [*mech.gravity.tolist(), 0.0]  # the model's, zero when none


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_points_are_written_without_loss(case, name):
    """Every point's coordinates read back from the file as the same doubles."""
    kin, text = case(name)
    sites = {s.get("name"): s.get("pos") for s in ET.fromstring(text).iter("site")}
    for body in kin.mechanism.bodies:
        for label, xy in body.points.items():
            x, y, _ = (float(v) for v in sites[f"{body.name}.{label}"].split())
            assert (x, y) == (float(xy[0]), float(xy[1]))


# -- kinematic oracle -----------------------------------------------------------


@pytest.mark.parametrize("name", CASES)
def test_kinematic_mode_agrees_at_round_off(case, name):
    """MuJoCo's own kinematics over each input's feasible range (margin 1e-3 of the
    range at limit positions) agree with the native solver at round-off, for every
    body and named point. Rates are relative to the mechanism's largest value of
    the quantity (:func:`relative_error`). Measured worst over the cases: position
    1.2e-14 of the size and angle 4.9e-14 rad (inverted), velocity 1.9e-13 and
    acceleration 5.6e-13 (slider-driven, next to its dead centres); the bounds are
    the project's round-off targets."""
    kin, text = case(name)
    result = run_kinematic(kin, xml=text)
    assert result.ok, result.reason
    table, trajectory = result.summary, result.trajectories[0]
    mech = kin.mechanism
    assert set(table[table.kind == "body"].name) == {b.name for b in mech.moving_bodies}
    assert set(table[table.kind == "point"].name) == set(mech.point_owners)
    assert (table.samples == len(trajectory.inputs)).all()  # the native solver solved every sample
    assert relative_error(table, "position", absolute=True) <= 1e-10 * kin.system.size
    assert relative_error(table, "angle", absolute=True) <= 1e-10
    for quantity in ("velocity", "omega", "acceleration", "alpha"):
        assert relative_error(table, quantity) <= 1e-9, quantity
    assert np.max(trajectory.diagnostics["constraint_violation"]) <= 1e-12 * kin.system.size


def test_a_link_one_millimetre_too_long_is_caught(case):
    """An MJCF whose crank is 1 mm longer than the model's: the kinematic mode
    still runs (MuJoCo closes the loop), and the differences name the point B at
    the crank's end with an error of exactly that millimetre."""
    kin, text = case("fourbar")
    root = ET.fromstring(text)
    site = next(s for s in root.iter("site") if s.get("name") == "crank.B")
    coupler = next(b for b in root.iter("body") if b.get("name") == "coupler")
    for element in (site, coupler):
        x, y, z = (float(v) for v in element.get("pos").split())
        element.set("pos", f"{x + 1e-3!r} {y!r} {z!r}")
    result = run_kinematic(kin, xml=ET.tostring(root, encoding="unicode"))
    assert result.ok, result.reason
    table = result.summary
    wrong = table[table.max_abs > 1e-10 * kin.system.size]
    named = set(zip(wrong.kind, wrong.name, wrong.quantity))
    assert ("point", "B", "position") in named
    assert {("body", "coupler", "position"), ("body", "rocker", "angle")} <= named
    b = table[(table.kind == "point") & (table.name == "B") & (table.quantity == "position")].iloc[0]
    assert b.max_abs == pytest.approx(1e-3, rel=1e-9)


# -- simulation -----------------------------------------------------------------


@pytest.mark.parametrize("name", CASES)
def test_dynamic_mode_agrees_and_converges_at_second_order(case, name):
    """The simulation with the tight setting (RK4, solref 2 dt, solimp 0.9999)
    against the native solution at the inputs MuJoCo realised.

    Errors scale with the mechanism's speed W (largest angular velocity, or point
    speed per size) times the time step: position ~ size (W dt)^2, velocity ~
    W dt. Measured at dt = 2.5e-4 s over the loop cases: position / (size (W
    dt)^2) from 8e-4 (task-2-5) to 0.063 (task-2-7), angle / (W dt)^2 up to
    0.081 (task-2-7), velocity / (W dt) up to 0.024 (task-2-2), the oracle's
    accelerations at the simulated states / (W dt) up to 0.061 (inverted).
    Bounds: about three times the worst, for models of the same kind. Observed
    order of the position error from 5e-4 to 2.5e-4 s: 1.93 to 2.11. qacc-based
    accelerations do not fall with the step (MuJoCo's constraint stabilisation is
    in qacc): 1e-3 to 4.1e-3 (task-2-1) of the largest acceleration.
    """
    kin, text = case(name)
    result = run_dynamic(kin, tight=(TEST_TIGHT_STEPS[0], 2), default=(2e-3, 1), xml=text)
    assert result.ok, result.reason
    summary, compared = result.summary, result.trajectories[0]
    dt = compared.settings["timestep"]  # 2.5e-4 s, shortened to divide the sample interval
    assert compared.settings["setting"] == "tight" and 1.25e-4 < dt <= 2.5e-4
    assert compared.settings["accelerations"] == "qacc"
    assert result.trajectories[1].settings["accelerations"] == "oracle at simulated state"
    assert (summary.status == "ok").all(), summary.status.tolist()
    table = differences(kin, compared)
    mech = kin.mechanism
    assert set(table[table.kind == "body"].name) == {b.name for b in mech.moving_bodies}
    assert set(table[table.kind == "point"].name) == set(mech.point_owners)
    row = summary[(summary.setting == "tight") & (summary.timestep == dt)].iloc[0]  # the compared run
    assert row.position_error == relative_error(table, "position", absolute=True)
    size = kin.system.size
    if not spanning_tree(mech).cuts:
        # an open chain has no loop to drift: round-off (measured 1.1e-15 of the size)
        assert row.position_error <= 1e-13 * size
        assert row.velocity_error <= 1e-12 and row.acceleration_error <= 1e-12
        return
    w_dt = _speed(kin, table) * dt
    assert row.position_error <= 0.2 * size * w_dt**2
    assert row.angle_error <= 0.25 * w_dt**2
    assert row.velocity_error <= 0.08 * w_dt
    assert row.acceleration_error_oracle <= 0.2 * w_dt
    assert row.acceleration_error <= 0.015
    assert 1.7 <= row.order <= 2.3


def test_dynamic_default_plan_reports_the_error_trend(case):
    """The mode's own plan on the four-bar, from the file as written: three time
    steps with MuJoCo's defaults, four with the tight setting. Measured: tight
    position errors 1.4e-8, 3.2e-9, 7.9e-10, 2.0e-10 m (orders 2.11, 2.03, 2.01);
    the defaults' error does not fall with the time step (2.4e-5, 6.0e-5,
    7.8e-5 m: solref's 0.02 s time constant, not the step, sets it)."""
    kin, _ = case("fourbar")
    result = engines.engine("mujoco").dynamic_ladder("mujoco-dynamic", kin).run()
    assert result.ok, result.reason
    summary = result.summary
    assert list(summary.setting) == ["tight"] * 4 + ["default"] * 3
    assert list(summary.integrator) == ["RK4"] * 4 + ["Euler"] * 3
    assert 1.2e-4 <= result.trajectories[0].settings["timestep"] <= 1.25e-4
    tight, default = summary[summary.setting == "tight"], summary[summary.setting == "default"]
    assert np.all((tight.order.iloc[1:] > 1.8) & (tight.order.iloc[1:] < 2.2))
    assert np.all(default.order.iloc[1:] < 0.5)
    assert set(result.study[result.study.series == "default Euler"].verdict) == {"not converging"}
    assert default.position_error.min() > 1e4 * tight.position_error.min()
    assert len(result.trajectories) == 2 + 6  # compared run twice (qacc, oracle), then every other run


# -- bad input ------------------------------------------------------------------


# -- loops with no undriven revolute (issue 12, item 3) -----------------------------
# The Scotch yoke of tests/data: its loop closes only through the driven crank
# revolute, the guide (prismatic) and the slot (pin-in-slot), so it is cut at the
# slot; listing the slot before the guide makes the guide the cut (a weld).
# Closed form (r = 0.1 m, theta the crank angle, w its rate, m_yoke = 2 kg):
# yoke x = r cos(theta), x' = -r w sin(theta), x'' = -r w^2 cos(theta);
# crank torque = m_yoke r^2 w^2 sin(theta) cos(theta).
YOKE_TEXT = (DATA / "scotch-yoke.toml").read_text()


def _yoke_with_prismatic_cut() -> str:
    guide = YOKE_TEXT.index('[[joints]]\nname = "guide"')
    slot = YOKE_TEXT.index('[[joints]]\nname = "slot"')
    drivers = YOKE_TEXT.index("[[drivers]]")
    return YOKE_TEXT[:guide] + YOKE_TEXT[slot:drivers] + YOKE_TEXT[guide:slot] + YOKE_TEXT[drivers:]


YOKES = {"slot": YOKE_TEXT, "guide": _yoke_with_prismatic_cut()}
YOKE_R, YOKE_MASS = 0.1, 2.0


def _yoke(cut: str) -> Kinematics:
    return Kinematics(parse_mechanism(YOKES[cut], DATA / "scotch-yoke.toml"))


@pytest.mark.parametrize("cut", YOKES)
def test_scotch_yoke_is_cut_at_its_sliding_joint_and_matches_the_closed_form(cut):
    """The loop is cut at the pin-in-slot (connect to a carrier) or at the
    prismatic joint (weld to a carrier), and MuJoCo's kinematics over a whole
    crank turn equal the closed form. Measured: 1.3e-16 m, 1.6e-15 m/s,
    1.6e-15 m/s^2 (round-off); bound 1e-14 of r, r w, r w^2."""
    kin = _yoke(cut)
    assert [j.name for j in spanning_tree(kin.mechanism).cuts] == [cut]
    root = ET.fromstring(export_files(kin)["scotch-yoke.xml"])
    (equality,) = root.find("equality")
    assert (equality.tag, equality.get("site1")) == ("connect" if cut == "slot" else "weld", f"{cut}.carrier")
    result = run_kinematic(kin, samples=73)
    assert result.ok, result.reason
    t = result.trajectories[0]
    theta, w = t.inputs[:, 0], t.input_rates[:, 0]
    assert np.ptp(theta) == pytest.approx(2 * np.pi) and np.all(t.input_accelerations == 0.0)
    yoke = t.bodies["yoke"]
    r = YOKE_R
    assert np.max(np.abs(yoke["position"][:, 0] - r * np.cos(theta))) < 1e-14 * r
    assert np.max(np.abs(yoke["position"][:, 1])) < 1e-14 * r
    assert np.max(np.abs(yoke["velocity"][:, 0] + r * w * np.sin(theta))) < 1e-14 * r * 2.0
    assert np.max(np.abs(yoke["acceleration"][:, 0] + r * w**2 * np.cos(theta))) < 1e-14 * r * 4.0
    p = t.points["P"]["position"]
    assert np.max(np.abs(p - r * np.column_stack([np.cos(theta), np.sin(theta)]))) < 1e-14 * r


@pytest.mark.parametrize("cut", YOKES)
def test_scotch_yoke_driving_torque_is_the_closed_form(cut):
    """MuJoCo's inverse dynamics (carriers massless, the model's masses): the
    crank torque m r^2 w^2 sin cos and the slot's normal force m r w^2 cos
    (the yoke's inertia force, carried by the slot). Measured 1.2e-16 N m of
    0.04 N m; bound 1e-13 of the largest value."""
    kin = _yoke(cut)
    forces = inverse_dynamics(kin)
    theta, w = forces.inputs[:, 0], forces.input_rates[:, 0]
    torque = YOKE_MASS * YOKE_R**2 * w**2 * np.sin(theta) * np.cos(theta)
    assert np.max(np.abs(forces.drivers["crank"]["effort"] - torque)) < 1e-13 * np.max(np.abs(torque))
    push = YOKE_MASS * YOKE_R * w**2 * np.cos(theta)  # minus the yoke's m x'', passed on to the pin
    slot = forces.joints["slot"]["reaction"]  # yoke on crank
    assert np.max(np.abs(slot[:, 0] - push)) < 1e-13 * np.max(np.abs(push))
    assert np.max(np.abs(slot[:, 1])) < 1e-13 * np.max(np.abs(push))


def test_carriers_keep_the_models_mass_distribution():
    """The pin's body plus its carrier (a point mass at the pin) have the
    crank's mass, centre of mass and inertia (0.5 kg at O, 0.5 0.1^2 / 12)."""
    model = mujoco.MjModel.from_xml_string(export_files(_yoke("slot"))["scotch-yoke.xml"])
    crank, carrier = model.body("crank"), model.body("slot.carrier")
    data = mujoco.MjData(model)
    data.qpos[:] = [0.3, 0.1 * np.cos(0.3), 0.1 * np.sin(0.3)]  # O, guide, carrier: the loop closed at 0.3 rad
    mujoco.mj_kinematics(model, data)
    masses = [model.body_mass[b.id] for b in (crank, carrier)]
    coms = [data.xipos[b.id][:2] for b in (crank, carrier)]
    assert sum(masses) == pytest.approx(0.5, rel=1e-15)
    com = sum(m * c for m, c in zip(masses, coms)) / sum(masses)
    np.testing.assert_allclose(com, [0.0, 0.0], atol=1e-16)
    inertia = model.body_inertia[crank.id][2] + sum(m * (c @ c) for m, c in zip(masses, coms))
    assert inertia == pytest.approx(0.5 * 0.1**2 / 12, rel=1e-13)


def test_scotch_yoke_simulates_within_the_dynamic_tolerance():
    """mujoco-dynamic on the yoke cut at its slot: runs, and the tight RK4
    runs converge at second order. Measured (5e-4, 2.5e-4 s): 1.9e-9, 4.6e-10 m
    (orders 2.02)."""
    kin = _yoke("slot")
    result = run_dynamic(kin, tight=(TEST_TIGHT_STEPS[0], 2), default=None)
    assert result.ok, result.reason
    assert "carrier" in result.trajectories[0].notes
    errors = result.summary.position_error.to_numpy()
    assert errors[-1] < 1e-8 * kin.mechanism.size
    assert 1.8 < result.summary.order.iloc[-1] < 2.2


def test_a_loop_of_sliding_joints_only_runs():
    """The wedges: one loop of two prismatic joints and a pin-in-slot in an
    inclined slot of the ground (the carrier hangs from the ground). Closed form:
    W = (s, s) with s the pushed slide, W' = (0.5, 0.5) m/s, W'' = 0."""
    kin = Kinematics(parse_mechanism(ALL_SLIDING, "wedges"))
    assert export_files(kin)
    result = run_kinematic(kin, samples=21)
    assert result.ok, result.reason
    t = result.trajectories[0]
    s = t.inputs[:, 0]
    w = t.points["W"]
    np.testing.assert_allclose(w["position"], np.column_stack([s, s]), rtol=0, atol=1e-15 * np.max(np.abs(s)))
    np.testing.assert_allclose(w["velocity"], 0.5, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w["acceleration"], 0.0, rtol=0, atol=1e-15)
    assert run_dynamic(kin, tight=(5e-4, 1), default=None).ok


def test_a_loop_of_driven_joints_only_fails_both_modes_in_one_line():
    """Drive the wedge's slide too: the loop then has one undriven joint left, the
    incline, and runs; drive all three and nothing is left to cut."""
    text = (
        ALL_SLIDING
        + """
[[drivers]]
name = "lift"
joint = "wedge slide"
motion = "constant-rate"
start = 0.1
rate = 0.5
[[drivers]]
name = "slope"
joint = "incline"
motion = "constant-rate"
start = 0.1414213562373095
rate = 0.7071067811865476
"""
    )
    text = text.replace("at = { push = 0.1 }", "at = { push = 0.1, lift = 0.1, slope = 0.1414213562373095 }")
    try:
        kin = Kinematics(parse_mechanism(text, "wedges"))
    except XcheckError:
        pytest.skip("the native model refuses a loop of driven joints itself")
    kinematic, dynamic = run_kinematic(kin), run_dynamic(kin)
    assert not kinematic.ok and "\n" not in kinematic.reason and "driven joints only" in kinematic.reason
    # the driven ladder sets its problem up first: the native solver refuses the over-driven start
    assert not dynamic.ok and "\n" not in dynamic.reason
    assert "expected 1 driver(s), one per degree of freedom" in dynamic.reason, dynamic.reason
    with pytest.raises(ModelError, match="driven joints only"):
        export_files(kin)


def test_a_diverging_simulation_fails_with_its_reason(case, tmp_path, monkeypatch):
    """RK4 at 50 ms: the 250 rad/s servo is far past RK4's stability limit. MuJoCo's
    warning becomes the run's failure (and no MUJOCO_LOG.TXT is written); in the
    mode's ladder (the step shortened to divide the 41 ms sample interval) the loops
    are 1.1 m open at the first sample (measured), before MuJoCo warns: the run came apart."""
    kin, text = case("fourbar")
    monkeypatch.chdir(tmp_path)
    handler = mujoco.get_mju_user_warning()
    prepared = modes.prepare_dynamic(DrivenProblem.of(kin), text)
    run = simulate(
        copy.deepcopy(prepared.model),
        kin.mechanism,
        prepared.layout,
        TIGHT,
        0.05,
        40,
        1,
        prepared.qpos0,
        prepared.qvel0,
    )
    assert run.failure.startswith("diverged") and "unstable" in run.failure and "\n" not in run.failure
    assert len(run.times) == 0
    result = run_dynamic(kin, tight=(0.05, 1), default=None, xml=text)
    assert not result.ok and "\n" not in result.reason
    assert result.reason.startswith("tight RK4 dt = 0.04095 s: came apart at t = 0.04095"), result.reason
    row = result.summary.iloc[0]
    assert row.status.startswith("came apart") and np.isnan(row.order)
    assert result.trajectories == []
    assert mujoco.get_mju_user_warning() == handler
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_a_motion_leaving_the_feasible_range_fails(case):
    """The four-bar's crank rocks between limit positions at +-129 deg: driving it
    for 5 s at 1 rad/s from 30 deg would cross one; starting at 140 deg, past it."""
    kin, text = case("fourbar")
    result = run_dynamic(kin, duration=5.0, xml=text)
    assert not result.ok
    assert "feasible range" in result.reason
    outside = (MODELS / "fourbar.toml").read_text().replace("start = 30\n", "start = 140\n")
    assert "start = 140" in outside
    result = run_dynamic(Kinematics(parse_mechanism(outside, "fourbar-outside")))
    assert not result.ok
    assert "feasible range" in result.reason and "\n" not in result.reason


# -- xcheck export (issue 12, item 6) ----------------------------------------------


def _export(*args):
    from typer.testing import CliRunner

    from xcheck.cli import app

    return CliRunner().invoke(app, ["export", *args])


@pytest.fixture
def models_with_a_bad_file(tmp_path):
    """A models directory: a malformed file sorting first, the four-bar and the Scotch yoke."""
    models = tmp_path / "models"
    models.mkdir()
    (models / "aaa-broken.toml").write_text('[mechanism]\nname = "broken"\n')
    (models / "fourbar.toml").write_text((MODELS / "fourbar.toml").read_text())
    (models / "scotch-yoke.toml").write_text(YOKE_TEXT)
    return models


def test_export_reports_a_bad_file_and_writes_the_rest(models_with_a_bad_file):
    """One line for the malformed file (file, field, expected, found), every other
    file written, exit 2 at the end."""
    models = models_with_a_bad_file
    result = _export("--format", "mjcf", "--models", str(models))
    assert result.exit_code == 2
    (line,) = result.stderr.splitlines()
    assert "aaa-broken.toml: bodies: expected" in line and "found" in line
    for name in ("fourbar", "scotch-yoke"):
        text = (models / "mjcf" / f"{name}.xml").read_text()
        with canonical_numbers():  # as xcheck export writes them
            expected = export_files(
                Kinematics(parse_mechanism((models / f"{name}.toml").read_text(), models / f"{name}.toml"))
            ).popitem()[1]
        assert text == expected


def test_export_check_lists_missing_and_stale_files(models_with_a_bad_file):
    """--check writes nothing and names each file: "missing" where there is none,
    "stale" where it differs; exit 1 (2 with a bad file)."""
    models = models_with_a_bad_file
    (models / "aaa-broken.toml").unlink()
    (models / "mjcf").mkdir()
    (models / "mjcf" / "fourbar.xml").write_text("<mujoco/>\n")
    result = _export("--check", "--format", "mjcf", "--models", str(models))
    assert result.exit_code == 1
    stale, missing = result.stdout.splitlines()
    assert (
        stale
        == f"stale: {models / 'mjcf' / 'fourbar.xml'}: line 1 differs: '<mujoco/>' -> '<mujoco model=\"fourbar\">'"
    )
    assert missing == f"missing: {models / 'mjcf' / 'scotch-yoke.xml'}"
    assert not (models / "mjcf" / "scotch-yoke.xml").exists()
    assert _export("--format", "mjcf", "--models", str(models)).exit_code == 0
    assert _export("--check", "--format", "mjcf", "--models", str(models)).exit_code == 0
    # a value that moved: named with its line, its two values and how far it moved
    path = models / "mjcf" / "fourbar.xml"
    text = path.read_text()
    path.write_text(text.replace('<site name="ground.D" pos="0.6 0 0" />', '<site name="ground.D" pos="0.61 0 0" />'))
    result = _export("--check", "--format", "mjcf", "--models", str(models))
    assert result.exit_code == 1
    line = next(n for n, row in enumerate(text.splitlines(), 1) if 'name="ground.D"' in row)
    assert result.stdout.splitlines() == [
        f"stale: {path}: line {line}: 0.61 -> 0.6 (moved by 0.01; the precision allows 1e-12)"
    ]
    # and one a step apart in its last digit, as another CPU may write it, is current
    path.write_text(text.replace('pos="0.194855715851 0.1125 0"', 'pos="0.194855715852 0.1125 0"'))
    assert text != path.read_text()
    assert _export("--check", "--format", "mjcf", "--models", str(models)).exit_code == 0


def test_export_reports_a_file_that_cannot_be_written_and_goes_on(models_with_a_bad_file):
    """A plain file where the urdf/ directory should be: the URDF files cannot be
    written (one line each), the MJCF files are, exit 2; nothing half-written."""
    models = models_with_a_bad_file
    (models / "aaa-broken.toml").unlink()
    (models / "urdf").write_text("not a directory\n")
    result = _export("--models", str(models))
    assert result.exit_code == 2
    errors = result.stderr.splitlines()
    assert len(errors) == 4 and all("expected a file that can be written" in e for e in errors)
    assert sorted(p.name for p in (models / "mjcf").iterdir()) == ["fourbar.xml", "scotch-yoke.xml"]
