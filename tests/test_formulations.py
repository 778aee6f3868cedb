"""Formulations I and II (seed 000's generalized and relative coordinates, seed
004's complex-number method) against the general solver, which is exact to
round-off: every mechanism in models/ and a few variants that reach every
code path (every joint type and driver kind, tilted ground, L-shaped crank,
reversed joints, both branches, all three loop cases, a non-dyadic linkage).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DATA, MODEL_NAMES
from printed_fourbar import last_digit_units, printed_table

from xcheck import Kinematics, Status
from xcheck.engines import NotApplicable
from xcheck.formulations import (
    FORMULATIONS,
    applicability,
    formulation,
    plan_loops,
    run_formulation,
)
from xcheck.model import parse_mechanism
from xcheck.results import differences

INVERTED = (DATA / "inverted.toml").read_text()
SLIDER_DRIVEN = (DATA / "slider-driven.toml").read_text()

# A Grashof crank-rocker with a tilted ground line, an L-shaped crank (its frame
# not along A->B), the driven joint written (crank, ground) so the input is
# -phi_crank, and the rocker's frame from C to D; two branches, full turns.
TILTED_FOURBAR = """
[mechanism]
name = "tilted-fourbar"
[units]
length = "m"
[ground]
points = { A = [0.1, 0.2], D = [0.55, -0.05] }
[bodies.crank]
points = { A = [0.02, -0.03], B = [0.06, 0.07], G = [0, 0] }
[bodies.coupler]
ends = ["B", "C"]
length = 0.35
points = { F = [0.05, 0.08] }
[bodies.rocker]
ends = ["C", "D"]
length = 0.3
[[joints]]
type = "revolute"
bodies = ["crank", "ground"]
point = "A"
[[joints]]
type = "revolute"
bodies = ["crank", "coupler"]
point = "B"
[[joints]]
type = "revolute"
bodies = ["rocker", "coupler"]
point = "C"
[[joints]]
type = "revolute"
bodies = ["rocker", "ground"]
point = "D"
[[drivers]]
name = "crank"
joint = "A"
rate = 2
[assembly]
at = { crank = 0 }
[assembly.branches.open]
C = [0.4, 0.3]
[assembly.branches.crossed]
C = [0.35, -0.3]
"""

# A slider-crank without a slider: the rod's pin B runs in a ground slot at 30
# degrees, offset from the crank pivot; both branches.
SLOT_CRANK = """
[mechanism]
name = "slot-crank"
[units]
length = "m"
[ground]
points = { O = [0, 0], L = [0.05, -0.08] }
[bodies.crank]
points = { O = [0, 0], A = [0.1, 0.02] }
[bodies.rod]
points = { A = [0, 0], B = [0.3, 0.05], M = [0.1, -0.04] }
[[joints]]
type = "revolute"
bodies = ["ground", "crank"]
point = "O"
[[joints]]
type = "revolute"
bodies = ["crank", "rod"]
point = "A"
[[joints]]
type = "pin-in-slot"
bodies = ["ground", "rod"]
line = "L"
direction = 30
point = "B"
[[drivers]]
name = "crank"
joint = "O"
rate = 3
[assembly]
at = { crank = 0 }
[assembly.branches.ahead]
B = [0.35, 0.1]
[assembly.branches.behind]
B = [-0.2, -0.2]
"""

# A slider-crank whose guide line is carried by the block (the prismatic joint
# written (slider, ground), a ground point sliding on it), locked at 25 degrees,
# the rod's pin B away from the guide's line.
BLOCK_LINE = """
[mechanism]
name = "block-line"
[units]
length = "m"
[ground]
points = { O = [0, 0], P = [0.2, -0.05] }
[bodies.crank]
ends = ["O", "A"]
length = 0.1
[bodies.rod]
ends = ["A", "B"]
length = 0.32
[bodies.slider]
points = { B = [0.01, 0.02], Q = [-0.05, 0.03] }
[[joints]]
type = "revolute"
bodies = ["ground", "crank"]
point = "O"
[[joints]]
type = "revolute"
bodies = ["crank", "rod"]
point = "A"
[[joints]]
type = "revolute"
bodies = ["slider", "rod"]
point = "B"
[[joints]]
name = "guide"
type = "prismatic"
bodies = ["slider", "ground"]
line = "Q"
direction = 10
point = "P"
angle = 25
[[drivers]]
name = "crank"
joint = "O"
rate = 3
[assembly]
at = { crank = 0 }
[assembly.branches.ahead]
B = [0.4, 0.0]
"""

# Scotch yoke: the crank pin slides in a slot of a yoke that slides on the
# ground; the loop's two unknowns are both lengths.
SCOTCH_YOKE = """
[mechanism]
name = "scotch-yoke"
[units]
length = "m"
[ground]
points = { O = [0, 0] }
[bodies.crank]
points = { O = [0, 0], A = [0.1, 0] }
[bodies.yoke]
points = { Y = [0, 0], K = [0.3, 0.02] }
[[joints]]
type = "revolute"
bodies = ["ground", "crank"]
point = "O"
[[joints]]
name = "guide"
type = "prismatic"
bodies = ["ground", "yoke"]
line = "O"
direction = 0
point = "Y"
[[joints]]
name = "slot"
type = "pin-in-slot"
bodies = ["yoke", "crank"]
line = "K"
direction = 80
point = "A"
[[drivers]]
name = "crank"
joint = "O"
start = 30
rate = 3
[assembly]
at = { crank = 30 }
[assembly.branches.only]
Y = [-0.2, 0]
"""

# A class-III Assur group (a ternary link held by three binary links, one on the
# crank): one degree of freedom, but every loop has three unknown angles.
ASSUR_III = """
[mechanism]
name = "assur-iii"
[units]
length = "m"
[ground]
points = { O = [0, 0], G2 = [1.1, 0.1], G3 = [0.6, -0.1] }
[bodies.crank]
sketch = { O = [0, 0], A = [0.1, 0.17] }
[bodies.link1]
sketch = { A = [0.1, 0.17], T1 = [0.5, 0.6] }
[bodies.link2]
sketch = { G2 = [1.1, 0.1], T2 = [0.9, 0.55] }
[bodies.link3]
sketch = { G3 = [0.6, -0.1], T3 = [0.7, 0.3] }
[bodies.triad]
sketch = { T1 = [0.5, 0.6], T2 = [0.9, 0.55], T3 = [0.7, 0.3] }
[[joints]]
type = "revolute"
bodies = ["ground", "crank"]
point = "O"
[[joints]]
type = "revolute"
bodies = ["crank", "link1"]
point = "A"
[[joints]]
type = "revolute"
bodies = ["link1", "triad"]
point = "T1"
[[joints]]
type = "revolute"
bodies = ["ground", "link2"]
point = "G2"
[[joints]]
type = "revolute"
bodies = ["link2", "triad"]
point = "T2"
[[joints]]
type = "revolute"
bodies = ["ground", "link3"]
point = "G3"
[[joints]]
type = "revolute"
bodies = ["link3", "triad"]
point = "T3"
[[drivers]]
name = "crank"
joint = "O"
rate = 1
[assembly]
at = { crank = 0 }
[assembly.branches.drawn]
T1 = [0.5, 0.6]
"""


def _fourbar_driven_at_b() -> str:
    """The seed four-bar driven at its crank-coupler joint B (input phi_coupler -
    phi_crank): the crank and coupler angles form one unknown."""
    from conftest import MODELS

    text = (MODELS / "fourbar.toml").read_text().split("[[instants]]")[0]
    assert 'joint = "A"' in text and "at = { crank = 30 }" in text
    return text.replace('joint = "A"', 'joint = "B"').replace("at = { crank = 30 }", "at = { crank = 3.2 }")


VARIANTS = {
    "inverted": INVERTED,
    "slider-driven": SLIDER_DRIVEN,
    "tilted-fourbar": TILTED_FOURBAR,
    "slot-crank": SLOT_CRANK,
    "block-line": BLOCK_LINE,
    "scotch-yoke": SCOTCH_YOKE,
    "fourbar-driven-at-b": _fourbar_driven_at_b(),
    "assur-iii": ASSUR_III,
}
NAMES = MODEL_NAMES + list(VARIANTS)

# For each mechanism (models/ and variants): per formulation, None if it
# applies, else a phrase its not-applicable reason must contain. A model added
# to models/ must be classified here: a silent "not applicable" is a regression.
EXPECTED = {
    "fourbar": {"formulation-I": None, "formulation-II": None},
    "fourbar-dynamics": {"formulation-I": None, "formulation-II": None},
    "slider-crank": {"formulation-I": None, "formulation-II": None},
    "two-body-arm": {"formulation-I": "2 inputs", "formulation-II": None},
    "task-2-1": {"formulation-I": "5 moving bodies with 1 prismatic, 6 revolute", "formulation-II": None},
    "task-2-2": {"formulation-I": "the input is the slide", "formulation-II": None},
    "task-2-3": {
        "formulation-I": "4 moving bodies with 1 pin-in-slot, 1 prismatic, 4 revolute",
        "formulation-II": None,
    },
    "task-2-4": {"formulation-I": "5 moving bodies with 2 prismatic, 5 revolute", "formulation-II": None},
    "task-2-5": {
        "formulation-I": "4 moving bodies with 1 pin-in-slot, 1 prismatic, 4 revolute",
        "formulation-II": None,
    },
    "task-2-6": {
        "formulation-I": "4 moving bodies with 1 pin-in-slot, 1 prismatic, 4 revolute",
        "formulation-II": None,
    },
    "task-2-7": {"formulation-I": "the input is the slide", "formulation-II": None},
    "inverted": {"formulation-I": "4 moving bodies", "formulation-II": None},
    "slider-driven": {"formulation-I": "the input is the slide", "formulation-II": None},
    "tilted-fourbar": {"formulation-I": None, "formulation-II": None},
    "slot-crank": {"formulation-I": None, "formulation-II": None},
    "block-line": {"formulation-I": None, "formulation-II": None},
    "scotch-yoke": {"formulation-I": "2 moving bodies with 1 pin-in-slot, 1 prismatic", "formulation-II": None},
    "fourbar-driven-at-b": {"formulation-I": "not at a ground pivot", "formulation-II": None},
    "assur-iii": {"formulation-I": "5 moving bodies with 7 revolute", "formulation-II": "not dyadic"},
}

# The seeds' loops, in their order, by the kind of their two unknowns
# (004: "=> phi3, phi4", "=> r5, phi5", ...; 000 formulation II: phi2, phi3).
SEED_LOOPS = {
    "fourbar": ["two angles"],
    "fourbar-dynamics": ["two angles"],  # 003: z1, z2
    "task-2-1": ["two angles", "length and angle"],
    "task-2-2": ["length and angle", "length and angle"],
    "task-2-3": ["length and angle", "length and angle"],
    "task-2-4": ["length and angle", "length and angle"],
    "task-2-5": ["length and angle", "length and angle"],
    "task-2-6": ["length and angle", "length and angle"],
    "task-2-7": ["length and angle", "length and angle"],
}

# Measured by `.venv/bin/python tests/test_formulations.py` (the table per
# mechanism, branch and formulation): the largest relative difference over all
# of them is 1.8e-13 (inverted, formulation II, arm alpha, 3 % of the range from
# a limit position, where the loop's 2 x 2 matrix has inverse condition 0.02);
# elsewhere 5e-16 to 5e-14. Both solvers are exact to round-off; near a limit
# position the round-off of large terms that cancel (accelerations grow as
# d^-3/2) sets the gap (6e-12 at 0.1 % of the range), so sweeps keep 2 % of the
# range away from the limits.
AGREEMENT = 1e-12
MARGIN = 0.02
SAMPLES = 200


@pytest.fixture(scope="module")
def kin(kinematics):
    cache = {}

    def get(name: str) -> Kinematics:
        if name in VARIANTS:
            if name not in cache:
                cache[name] = Kinematics(parse_mechanism(VARIANTS[name], name))
            return cache[name]
        return kinematics(name)

    return get


def _sweeps(kin: Kinematics, branch: str):
    """One sweep per driver over its feasible range (MARGIN of the range from a
    limit position; a full turn for a crank), the others at the reference
    inputs; rates and accelerations nonzero and varying (rad/s, rad/s^2 or
    size/s, size/s^2)."""
    ref = kin.reference_inputs()
    u = np.linspace(0.0, 1.0, SAMPLES)
    unit = np.array([1.0 if d.quantity == "angle" else kin.system.size for d in kin.mechanism.drivers])
    for k, driver in enumerate(kin.mechanism.drivers):
        rng = kin.input_range(k, branch)
        half = math.pi if driver.quantity == "angle" else 0.5 * rng.span
        low = rng.low + MARGIN * (rng.high - rng.low) if rng.low is not None else ref[k] - half
        high = rng.high - MARGIN * (rng.high - rng.low) if rng.high is not None else ref[k] + half
        if (rng.low is None) != (rng.high is None):  # one limit only: keep clear of it by MARGIN * half
            low = rng.low + MARGIN * half if rng.low is not None else low
            high = rng.high - MARGIN * half if rng.high is not None else high
        c = np.tile(ref, (SAMPLES, 1))
        c[:, k] = low + (high - low) * u
        yield c, (0.8 + 0.5 * np.cos(3 * u))[:, None] * unit, (-1.0 + 0.5 * np.sin(5 * u))[:, None] * unit


def _expected(name: str) -> dict:
    if name not in EXPECTED:
        pytest.fail(
            f"mechanism {name!r} is not classified: add it to EXPECTED in tests/test_formulations.py "
            "(which formulations apply, and why the others do not)"
        )
    return EXPECTED[name]


@pytest.mark.parametrize("method", list(FORMULATIONS))
@pytest.mark.parametrize("name", NAMES)
def test_agrees_with_general_solver_or_says_why_not(kin, name, method):
    """Where a formulation applies, it reproduces the general solver over its
    feasible sweeps on every branch (positions, angles, velocities,
    accelerations of every body and named point) to AGREEMENT relative, and
    every sample assembles; where it does not, it says so with the reason."""
    k = kin(name)
    reason = _expected(name)[method]
    said = applicability(k)[method]
    if reason is not None:
        assert said is not None and reason in said, said
        with pytest.raises(NotApplicable, match=reason):
            FORMULATIONS[method](k, k.reference_inputs()[None, :])
        return
    assert said is None
    for branch in k.branches:
        for table in _compare(k, method, branch):
            worst = table.loc[table["relative"].idxmax()]
            assert worst["relative"] < AGREEMENT, (branch, worst.to_dict())


def _compare(k: Kinematics, method: str, branch: str):
    """The difference tables of a formulation's sweeps against the general
    solver, after the checks every trajectory must pass."""
    mech = k.mechanism
    for c, cd, cdd in _sweeps(k, branch):
        trajectory = FORMULATIONS[method](k, c, cd, cdd, branch=branch)
        assert trajectory.source == method
        assert set(trajectory.bodies) == {b.name for b in mech.moving_bodies}
        assert set(trajectory.points) == set(mech.point_owners)
        assert np.all(trajectory.diagnostics["status"] <= Status.NEAR_SINGULAR)
        # measured: at most 2.2e-15 of the size (2.6e-15 at 0.1 % of the range from a limit)
        assert np.max(trajectory.diagnostics["residual"]) < 1e-13 * mech.size
        table = differences(k, trajectory, branch=branch)
        assert (table["samples"] == SAMPLES).all()  # the general solver assembled every sample too
        yield _with_relative(table)


def _with_relative(table):
    """``table`` with a column ``relative``: max_abs over the quantity's own
    scale, except for a quantity that is zero up to round-off (the velocity of
    a frame origin on a ground pivot, whose scale is ~1e-17 and whose max_rel
    is then ~1): that one is measured on the largest value of the same
    quantity anywhere in the mechanism."""
    largest = table.groupby("quantity")["scale"].transform("max")
    zero = table["scale"] <= 1e-9 * largest
    return table.assign(relative=table["max_abs"] / table["scale"].where(~zero, largest))


def test_formulation_i_thetas_against_the_printed_table(kinematics):
    """Seed 000's formulation I table: theta1, theta2, theta3 at phi = 30, 60,
    120 deg, with the verdicts of tests/printed_fourbar.py (agrees, or
    off by rounding where the general solver found so)."""
    trajectory = FORMULATIONS["formulation-I"](kinematics("fourbar"), np.radians([30.0, 60.0, 120.0]))
    table, rounding, wrong = printed_table()
    rows = [(q, printed) for q, printed in table if q.startswith("theta")]
    assert [q for q, _ in rows] == ["theta1", "theta2", "theta3"]
    for quantity, printed in rows:
        computed = np.degrees(trajectory.diagnostics[quantity])
        for i, text in enumerate(printed):
            units = last_digit_units(text, computed[i])
            assert (quantity, i) not in wrong
            if (quantity, i) in rounding:
                assert 0.5 < units <= 1.0, (quantity, i, computed[i], text)
            else:
                assert units <= 0.5, (quantity, i, computed[i], text)


@pytest.mark.parametrize("branch", ["upper", "lower"])
def test_formulation_i_thetas_are_the_interior_angles(kinematics, branch):
    """theta1 at D (D->C to D->A), theta2 at C (C->B to C->D), theta3 at B
    (B->A to B->C), counter-clockwise, from the general solver's points, over
    the feasible range, re-entrant quadrilaterals (theta3 > 180 deg) included."""
    kin = kinematics("fourbar")
    rng = kin.input_range("crank", branch)
    c = np.linspace(rng.low + 1e-3, rng.high - 1e-3, 500)
    trajectory = FORMULATIONS["formulation-I"](kin, c, branch=branch)
    solution = kin.solve(c, branch=branch)
    p = {label: solution.point(label)["position"] for label in "ABCD"}

    def interior(at, first, second):
        u, v = p[first] - p[at], p[second] - p[at]
        return (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(u[:, 1], u[:, 0])) % (2 * np.pi)

    for quantity, (at, first, second) in {"theta1": "DCA", "theta2": "CBD", "theta3": "BAC"}.items():
        gap = np.angle(np.exp(1j * (trajectory.diagnostics[quantity] - interior(at, first, second))))
        assert np.max(np.abs(gap)) < 1e-12  # measured at most 8.9e-15 rad
    # part of the range is re-entrant at B on both branches (the printed 30 deg state is)
    assert np.any(trajectory.diagnostics["theta3"] > np.pi)


@pytest.mark.parametrize("name", [n for n in SEED_LOOPS if n in MODEL_NAMES])
def test_loops_derived_from_the_model_are_the_seeds(kinematics, name):
    """The loops formulation II derives, in solving order, have the unknowns of
    the seeds' loops (two angles; a length and an angle)."""
    plan = plan_loops(kinematics(name).mechanism)
    assert [loop.case for loop in plan.loops] == SEED_LOOPS[name], plan.describe()


def test_loop_cases_of_the_variants(kin):
    """Each closed-form case is exercised: two lengths (Scotch yoke), an
    unknown angle shared by two bodies (four-bar driven at B), none (open chain)."""
    assert [loop.case for loop in plan_loops(kin("scotch-yoke").mechanism).loops] == ["two lengths"]
    plan = plan_loops(kin("fourbar-driven-at-b").mechanism)
    assert [loop.case for loop in plan.loops] == ["two angles"]
    assert plan.root["coupler"] == plan.root["crank"] != plan.root["ground"]
    assert plan_loops(kin("two-body-arm").mechanism).loops == []


def test_non_dyadic_mechanism_is_solved_by_the_general_solver_only(kin):
    """The class-III Assur group assembles and moves in the general solver;
    formulation II refuses it, naming the reason."""
    k = kin("assur-iii")
    rng = k.input_range(0)
    solution = k.solve(np.linspace(rng.low + 0.05, rng.high - 0.05, 50), np.ones(50), np.ones(50))
    assert solution.success
    with pytest.raises(NotApplicable, match="not dyadic: every remaining loop has 3 or more unknowns"):
        FORMULATIONS["formulation-II"](k, [0.0])
    result = run_formulation("formulation-II", k, [0.0])
    assert not result.ok and result.reason.startswith("not applicable: not dyadic")


@pytest.mark.parametrize("method", list(FORMULATIONS))
def test_beyond_the_limit_position_nothing_is_reported(kinematics, method):
    """Past the four-bar's limit position no formulation assembles (as the
    general solver): the status says so and positions are NaN, never numbers."""
    kin = kinematics("fourbar")
    high = kin.input_range("crank").high
    c = np.array([high - 0.1, high + 1e-3, math.radians(170.0)])
    trajectory = FORMULATIONS[method](kin, c, np.ones(3), np.ones(3))
    status = trajectory.diagnostics["status"]
    assert list(status) == [Status.OK, Status.NOT_CONVERGED, Status.NOT_CONVERGED]
    assert list(kin.solve(c).status[1:]) == [Status.NOT_CONVERGED] * 2
    for body in trajectory.bodies.values():
        assert np.all(np.isfinite(body["position"][0])) and np.all(np.isnan(body["position"][1:]))
    assert np.all(np.isnan(trajectory.diagnostics["residual"][1:]))


def test_registry_and_mode_result(kinematics):
    kin = kinematics("two-body-arm")
    with pytest.raises(ValueError, match="formulation-I, formulation-II"):
        formulation("formulation-III")
    refused = run_formulation("formulation-I", kin, kin.reference_inputs()[None, :])
    assert not refused.ok and refused.reason == "not applicable: 2 inputs; formulation I has one generalized coordinate"
    done = run_formulation("formulation-II", kin, kin.reference_inputs()[None, :])
    assert done.ok and done.trajectories[0].source == "formulation-II"
    with pytest.raises(ValueError, match=r"expected inputs of shape \(N, 2\)"):
        FORMULATIONS["formulation-II"](kin, np.zeros((3, 3)))


if __name__ == "__main__":
    # The measured agreement: largest relative difference per mechanism, branch and formulation.
    from conftest import MODELS

    from xcheck import load_mechanism

    print(f"{'mechanism':22s} {'branch':9s} {'formulation':15s} {'relative':>9s}  worst quantity")
    for name in NAMES:
        k = (
            Kinematics(parse_mechanism(VARIANTS[name], name))
            if name in VARIANTS
            else Kinematics(load_mechanism(MODELS / f"{name}.toml"))
        )
        for method in FORMULATIONS:
            why = applicability(k)[method]
            if why is not None:
                print(f"{name:22s} {'':9s} {method:15s} {'n/a':>9s}  {why}")
                continue
            for branch in k.branches:
                tables = list(_compare(k, method, branch))
                worst = max((t.loc[t["relative"].idxmax()] for t in tables), key=lambda row: row["relative"])
                print(
                    f"{name:22s} {branch:9s} {method:15s} {worst['relative']:9.2e}  {worst['name']} {worst['quantity']}"
                )
