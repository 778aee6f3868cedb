"""The physical floor of the comparison's scales (issue 12, item 2): a quantity
that is zero everywhere is compared against a scale from the mechanism's size
and its inputs' rates, not against round-off."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from xcheck import Kinematics, load_mechanism
from xcheck.dynamics import force_floors
from xcheck.results import STANDARD_GRAVITY, scale_floors
from xcheck.runner import run_mechanism

DATA = ROOT / "tests" / "data"


@pytest.fixture(scope="module")
def trammel():
    return Kinematics(load_mechanism(DATA / "elliptic-trammel.toml"))


def test_floor_of_a_sliding_input(trammel):
    # bar AB of 0.5 m is the largest extent: L = 0.5 m; a slide rate of 0.785 m/s is w = 0.785 / 0.5
    floors = scale_floors(trammel.mechanism, [[0.3], [-0.785]], [[0.1], [1.0]])
    w = 0.785 / 0.5
    a = max(w * w, 1.0 / 0.5)  # 2.4649 > 2.0
    assert floors["size"] == pytest.approx(0.5, rel=1e-15)
    assert floors["omega"] == pytest.approx(1.57, rel=1e-14)
    assert floors["alpha"] == pytest.approx(a, rel=1e-14)
    assert floors["velocity"] == pytest.approx(0.785, rel=1e-14)
    assert floors["acceleration"] == pytest.approx(0.5 * 2.4649, rel=1e-14)
    # an input acceleration beyond w^2 sets alpha's floor: 3 m/s^2 / 0.5 m = 6 rad/s^2
    assert scale_floors(trammel.mechanism, [[0.785]], [[3.0]])["alpha"] == pytest.approx(6.0, rel=1e-14)


def test_floor_of_a_revolute_input():
    fourbar = load_mechanism(DATA / "fourbar-200.toml")  # coupler 400 mm is the largest extent
    floors = scale_floors(fourbar, [[1.5], [-0.5]], [[0.0], [-3.0]])
    assert floors["size"] == pytest.approx(0.4, rel=1e-15)
    assert floors["omega"] == pytest.approx(1.5, rel=1e-15)
    assert floors["alpha"] == pytest.approx(3.0, rel=1e-15)  # |-3| > 1.5^2 = 2.25
    # speeds at the crank's tip, 100 mm from its pivot, not at the coupler's 400 mm
    assert floors["velocity"] == pytest.approx(0.15, rel=1e-14)  # 1.5 rad/s x 0.1 m
    assert floors["acceleration"] == pytest.approx(0.3, rel=1e-14)


def test_floor_of_a_short_crank_driving_long_links():
    """A crank of 500 m driving a rod of 500 km (1000:1): the speed floor is the
    crank tip's, 1000 times below the rate times the size, which let a velocity
    1000 times too wrong pass as round-off (issue 18)."""
    slider = load_mechanism(DATA / "ratio-1000.toml")
    floors = scale_floors(slider, [[2.0]], [[0.5]])
    assert floors["size"] == pytest.approx(5e5, rel=1e-12)
    assert floors["velocity"] == pytest.approx(2.0 * 500.0, rel=1e-12)
    assert floors["acceleration"] == pytest.approx(4.0 * 500.0, rel=1e-12)


def test_floor_of_a_static_mechanism(trammel):
    floors = scale_floors(trammel.mechanism, np.zeros((3, 1)), np.zeros((3, 1)))
    w = math.sqrt(STANDARD_GRAVITY / 0.5)  # a pendulum of the bar's length
    assert floors["omega"] == pytest.approx(w, rel=1e-14)
    assert floors["alpha"] == pytest.approx(STANDARD_GRAVITY / 0.5, rel=1e-14)
    assert floors["acceleration"] == pytest.approx(STANDARD_GRAVITY, rel=1e-14)
    # starting from rest with an acceleration: w = sqrt(a)
    assert scale_floors(trammel.mechanism, [[0.0]], [[2.0]])["omega"] == pytest.approx(2.0, rel=1e-14)


def test_force_floor_of_the_scotch_yoke():
    yoke = load_mechanism(DATA / "scotch-yoke.toml")
    # crank 0.5 kg + yoke 2 kg, no gravity, crank r = 0.1 m at 2 rad/s: F = 2.5 kg x 2^2 x 0.1 m
    floors = force_floors(yoke, scale_floors(yoke, [[2.0]], [[0.0]]))
    assert floors["N"] == pytest.approx(1.0, rel=1e-14)
    assert floors["N m"] == pytest.approx(0.1, rel=1e-14)


def test_trammel_alpha_identically_zero_passes(trammel):
    """The bar turns uniformly and the sliders do not turn: alpha is 0 everywhere;
    every exact method and both kinematic oracles must reproduce it to round-off."""
    run = run_mechanism(trammel, modes=("formulation-II", "mujoco-kinematic", "pinocchio-kinematic"), samples=61)
    assert set(run.outcomes) == {"native", "formulation-II", "mujoco-kinematic", "pinocchio-kinematic"}
    for mode, outcome in run.outcomes.items():
        assert outcome.ok, (mode, outcome.reason)
        if mode == "native":
            continue
        alpha = outcome.categories.set_index("category").loc["alpha"]
        assert alpha.passed and alpha.relative <= alpha.tolerance, (mode, alpha.relative)
        assert alpha.floor == pytest.approx((math.pi / 2) ** 2, rel=1e-12)  # w = 0.5 m x (pi/2) / 0.5 m
        assert outcome.passed, (mode, outcome.categories)
