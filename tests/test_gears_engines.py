"""Gear pairs in the engines, through `xcheck run`: each engine that offers a
coupling (MuJoCo's joint equality, pymunk's GearJoint, PyBullet's gear
constraint, Drake's coupler constraint, Exudyn's coordinate constraint) holds
the files of tests/data within its tolerance, judged by the runner's one rule, or
fails only in its stated finding; Pinocchio has none and says why.

The files' answers are derived without xcheck's solver in tests/test_gears.py;
here the native solution is the reference every mode is compared with.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from conftest import DATA, invoke


def run(name: str, engines: str) -> dict:
    """``xcheck run`` of a test file with a few samples, its JSON summary."""
    done = invoke("run", str(DATA / f"{name}.toml"), "--engines", engines, "--samples", "9", "--json")
    assert "Traceback" not in done.stderr, done.stderr
    return json.loads(done.stdout)


def test_an_arm_carrying_a_planet_round_a_fixed_sun_in_mujoco_pybullet_and_drake():
    pytest.importorskip("mujoco")
    pytest.importorskip("pybullet")
    pytest.importorskip("pydrake")
    summary = run("planetary-fixed-sun", "native,mujoco,pybullet-dynamic,drake-dynamic,pinocchio-kinematic")
    verdicts = {mode: result["verdict"] for mode, result in summary["engines"].items()}
    assert verdicts == dict.fromkeys(
        ("native", "mujoco-kinematic", "mujoco-dynamic", "pybullet-dynamic", "drake-dynamic"), "pass"
    )
    assert "couple no joint coordinates" in summary["not_applicable"]["pinocchio-kinematic"]
    assert summary["verdict"] == "pass"


def test_a_planet_inside_a_fixed_ring_in_pymunk_and_exudyn():
    """pymunk's GearJoint couples the two bodies' absolute angles, Exudyn's
    coordinate constraint two nodes' angles: each holds the internal mesh. The
    train turns at constant speed with no load: no power flows, and its power
    balance is judged against the power its motion holds (it failed against
    its round-off, 1.0 of 8.7e-19 W)."""
    pytest.importorskip("pymunk")
    pytest.importorskip("exudyn")
    summary = run("planetary-fixed-ring", "native,pymunk-dynamic,exudyn-dynamic")
    verdicts = {mode: result["verdict"] for mode, result in summary["engines"].items()}
    assert verdicts == dict.fromkeys(("native", "pymunk-dynamic", "exudyn-dynamic"), "pass")
    assert summary["energy"]["passed"] and summary["energy"]["scale"] > 1e-3, summary["energy"]
    assert summary["verdict"] == "pass"


def test_pymunk_on_the_fixed_sun_train_within_the_round_off_of_its_angles():
    """The planet turns through up to 19 rad: pymunk's full error correction puts
    its angle's round-off into its angular velocity over the time step, and the
    central difference of those into its acceleration over the step squared
    (measured exactly a unit in the last place of the angle over 2 dt^2). Its
    angular acceleration is judged above that floor, eps x 19 / (rate x dt)^2,
    not the fixed 1e-9 (it failed there, its error growing as dt fell)."""
    pytest.importorskip("pymunk")
    summary = run("planetary-fixed-sun", "native,pymunk-dynamic")
    pymunk = summary["engines"]["pymunk-dynamic"]
    assert pymunk["verdict"] == "pass", pymunk
    alpha = pymunk["convergence"]["alpha"]
    floor = float(np.finfo(float).eps) * 6 * np.pi / (summary["scale_floors"]["rate"] * alpha["step"]) ** 2
    stated = float(re.search(r"noise floor of ([0-9.e+-]+)\)", alpha["basis"]).group(1))
    assert stated == pytest.approx(floor, rel=5e-3) and 1e-9 < stated < 1e-7, alpha["basis"]  # shown to 3 digits
    assert pymunk["relative"]["alpha"] <= pymunk["tolerance"]["alpha"]


def test_exudyn_on_the_fixed_sun_train_fails_only_in_its_stated_finding():
    """Exudyn's driven train holds positions, angles and rates; its accelerations
    are its coordinates' round-off over the step squared, summed by the
    generalized-alpha method (its stated finding, with its reproducer): the
    planet's, geared 3 to 1 to the arm, is not tied bit for bit to the arm's,
    and both angles are quadratic in time, so no truncation error hides it.
    Its error grows as the step halves (observed order below 0), far above
    the runner's noise floor, unchanged by Newton's tolerance (1e-8 .. 1e-13)."""
    pytest.importorskip("exudyn")
    from xcheck.engines.exudyn import Exudyn

    summary = run("planetary-fixed-sun", "native,exudyn-dynamic")
    exudyn = summary["engines"]["exudyn-dynamic"]
    assert exudyn["verdict"] == "finding" and summary["verdict"] == "pass with findings", exudyn
    relative, tolerance, convergence = exudyn["relative"], exudyn["tolerance"], exudyn["convergence"]
    for held in ("position", "angle", "velocity", "omega"):
        assert relative[held] <= tolerance[held], (held, relative[held], tolerance[held])
    (finding,) = Exudyn.findings
    for spoiled in finding.quantities:
        assert relative[spoiled] > 10 * tolerance[spoiled], (spoiled, relative[spoiled], tolerance[spoiled])
        assert convergence[spoiled]["observed_order"] < 0, convergence[spoiled]["basis"]
    assert exudyn["finding"] == finding.text


def test_a_geared_fivebar_in_pybullet():
    """A gear pair on a closed loop: PyBullet's gear constraint with its slip
    corrected at every step (without, positions converged at order 1 and failed)."""
    pytest.importorskip("pybullet")
    summary = run("geared-fivebar", "native,pybullet-dynamic")
    assert {mode: result["verdict"] for mode, result in summary["engines"].items()} == {
        "native": "pass",
        "pybullet-dynamic": "pass",
    }
    assert summary["verdict"] == "pass"
