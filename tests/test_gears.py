"""Gear pairs against answers derived without xcheck's solver.

Three files of tests/data, every number chosen:

* planetary-fixed-sun: an arm about a fixed sun (r 60 mm) carries a planet
  (r 30 mm). Willis' formula, (w_p - w_arm) / (w_sun - w_arm) = -r_sun / r_p,
  with the sun fixed: w_p = 3 w_arm, so the planet's frame angle is 3 theta.
  The tooth force from the planet's turning about its centre, the arm's
  torque from the train's power balance (no gravity).
* planetary-fixed-ring: the planet (r 30) inside a fixed ring (r 90):
  (w_p - w_arm) / (w_ring - w_arm) = +r_ring / r_p gives w_p = -2 w_arm.
* geared-fivebar: cranks at A and E geared 40 : 80 (crank 2 at 90 deg - theta / 2),
  couplers of 150 mm meeting at C: C by intersecting two circles, its rate
  and acceleration by solving the two loop equations by hand.

* planetary-train: sun (r 30) and arm about O, planet (r 30) on the arm,
  meshing with the sun and inside a fixed ring (r 90): w_sun = 4 w_arm,
  w_p = -2 w_arm; the sun's mesh couples three moving bodies.

The native solver is exact to round-off: the tolerance below is 32 eps of each
quantity's largest magnitude over the states (measured: at most 6.3 eps).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import DATA, invoke

import xcheck
from xcheck.dynamics import inverse_dynamics, newton_euler
from xcheck.errors import ModelError
from xcheck.model import parse_mechanism

EPS = np.finfo(float).eps
#: round-off bound, relative to each quantity's largest magnitude over the states
ROUND_OFF = 32 * EPS


def e(angle):
    """Unit vectors at angles (N,), (N, 2)."""
    return np.stack([np.cos(angle), np.sin(angle)], axis=1)


def perp(v):
    return np.stack([-v[:, 1], v[:, 0]], axis=1)


def close(ours, theirs, what=""):
    scale = max(float(np.max(np.abs(theirs))), 1e-300)
    error = float(np.max(np.abs(ours - theirs)))
    assert error <= ROUND_OFF * scale, (what, error / scale)


def solved(name, at, rates, accelerations):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return xcheck.load(DATA / f"{name}.toml").solve(at=at, rates=rates, accelerations=accelerations)


# -- planetary trains ------------------------------------------------------------------


def _planet_motion(arm_length, planet_ratio, theta, omega, alpha):
    """The planet's centre P and mark Q (radius 30 mm on its frame's x axis):
    positions, velocities, accelerations, (N, 2) each, for the planet's frame
    turning planet_ratio times as fast as the arm."""
    k = planet_ratio
    p = arm_length * e(theta)
    pd = arm_length * omega[:, None] * perp(e(theta))
    pdd = arm_length * (alpha[:, None] * perp(e(theta)) - (omega**2)[:, None] * e(theta))
    phi, w, a = k * theta, k * omega, k * alpha
    q = p + 0.03 * e(phi)
    qd = pd + 0.03 * w[:, None] * perp(e(phi))
    qdd = pdd + 0.03 * (a[:, None] * perp(e(phi)) - (w**2)[:, None] * e(phi))
    return (p, pd, pdd), (q, qd, qdd)


@pytest.mark.parametrize(
    "name, arm, ratio",
    [("planetary-fixed-sun", 0.09, 1.0 + 60 / 30), ("planetary-fixed-ring", 0.06, 1.0 - 90 / 30)],
)
def test_a_planetary_train_turns_as_willis_says(name, arm, ratio):
    degrees = np.linspace(-400.0, 800.0, 61)  # several turns either way: angles stay continuous
    theta = np.radians(degrees)
    omega = np.linspace(-3.0, 5.0, 61)
    alpha = np.linspace(7.0, -2.0, 61)
    sol = solved(name, degrees, omega, alpha).solution
    assert (sol.status == 0).all()
    planet = sol.body("planet")
    close(planet["angle"], ratio * theta, "angle")
    close(planet["omega"], ratio * omega, "omega")
    close(planet["alpha"], ratio * alpha, "alpha")
    for label, expected in zip("PQ", _planet_motion(arm, ratio, theta, omega, alpha)):
        point = sol.point(label)
        for key, value in zip(("position", "velocity", "acceleration"), expected):
            close(point[key], value, f"{label} {key}")


def test_a_whole_planetary_train_turns_as_willis_says():
    degrees = np.linspace(-200.0, 500.0, 36)
    theta = np.radians(degrees)
    omega, alpha = np.linspace(-1.0, 3.0, 36), np.linspace(2.0, -4.0, 36)
    sol = solved("planetary-train", degrees, omega, alpha).solution
    assert (sol.status == 0).all()
    for body, ratio in (("sun", 4.0), ("planet", -2.0), ("arm", 1.0)):
        state = sol.body(body)
        for key, value in zip(("angle", "omega", "alpha"), (theta, omega, alpha)):
            close(state[key], ratio * value, f"{body} {key}")
    sun = 0.03 * e(4 * theta)  # the sun's mark S, about O
    close(sol.point("S")["position"], sun, "S")
    close(sol.point("S")["velocity"], 0.03 * 4 * omega[:, None] * perp(e(4 * theta)), "S velocity")
    for label, expected in zip("PQ", _planet_motion(0.06, -2.0, theta, omega, alpha)):
        for key, value in zip(("position", "velocity", "acceleration"), expected):
            close(sol.point(label)[key], value, f"{label} {key}")


def test_the_fixed_sun_trains_tooth_force_and_driving_torque():
    degrees = np.linspace(0.0, 720.0, 37)
    theta = np.radians(degrees)
    omega = np.linspace(-2.0, 4.0, 37)
    alpha = np.linspace(3.0, -5.0, 37)
    sol = solved("planetary-fixed-sun", degrees, omega, alpha).solution
    m_arm, l_arm, m_p, r_p, d = 0.4, 0.09, 0.3, 0.03, 0.09
    i_arm, i_p = m_arm * l_arm**2 / 12, m_p * r_p**2 / 2
    brake = -0.5
    # the planet about its centre: I_p (3 alpha) = brake + r_p F
    tooth = (i_p * 3 * alpha - brake) / r_p
    # power: tau w + brake (3 w) = d/dt KE, KE = (I_arm,O + m_p d^2 + 9 I_p) w^2 / 2
    torque = (i_arm + m_arm * (l_arm / 2) ** 2 + m_p * d**2 + 9 * i_p) * alpha - 3 * brake
    # the tooth force at the pitch point, 2/3 of the way from O to P, pushing the planet
    # counter-clockwise about its centre: along (sin theta, -cos theta)
    vector = tooth[:, None] * np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    for forces in (inverse_dynamics(sol), newton_euler(sol)):
        close(forces.joints["mesh"]["tooth_force"], tooth, f"{forces.source} tooth force")
        close(forces.joints["mesh"]["reaction"], vector, f"{forces.source} reaction")
        close(forces.drivers["arm"]["effort"], torque, f"{forces.source} effort")


# -- the geared five-bar -----------------------------------------------------------------


def _fivebar(theta, omega, alpha):
    """B, D, C of the geared five-bar: (position, velocity, acceleration) each (N, 2)."""
    t2, w2, a2 = math.pi / 2 - theta / 2, -omega / 2, -alpha / 2
    b = 0.04 * e(theta)
    bd = 0.04 * omega[:, None] * perp(e(theta))
    bdd = 0.04 * (alpha[:, None] * perp(e(theta)) - (omega**2)[:, None] * e(theta))
    d = np.array([0.12, 0.0]) + 0.06 * e(t2)
    dd = 0.06 * w2[:, None] * perp(e(t2))
    ddd = 0.06 * (a2[:, None] * perp(e(t2)) - (w2**2)[:, None] * e(t2))
    # C: the two circles of 150 mm about B and D meet left of B -> D (the file's branch "up")
    half = (d - b) / 2
    h = np.sqrt(0.15**2 - np.sum(half**2, axis=1))
    c = b + half + h[:, None] * perp(half / np.linalg.norm(half, axis=1)[:, None])
    # (C - B).(C' - B') = 0, (C - D).(C' - D') = 0; then the same differentiated once more
    rows = np.stack([c - b, c - d], axis=1)  # (N, 2, 2)
    rhs = np.stack([np.sum((c - b) * bd, axis=1), np.sum((c - d) * dd, axis=1)], axis=1)
    cd = np.linalg.solve(rows, rhs[..., None])[..., 0]
    rhs = np.stack(
        [
            np.sum((c - b) * bdd, axis=1) - np.sum((cd - bd) ** 2, axis=1),
            np.sum((c - d) * ddd, axis=1) - np.sum((cd - dd) ** 2, axis=1),
        ],
        axis=1,
    )
    cdd = np.linalg.solve(rows, rhs[..., None])[..., 0]
    return {"B": (b, bd, bdd), "D": (d, dd, ddd), "C": (c, cd, cdd)}


def test_the_geared_fivebar_follows_its_closed_form_over_two_turns():
    """Crank 2 turns half a turn per turn of crank 1: the mechanism repeats only
    after two turns, which the solver follows without taking one turn for the next."""
    degrees = np.linspace(-30.0, 720.0, 76)
    theta = np.radians(degrees)
    omega = np.full(76, 1.5)
    alpha = np.linspace(-1.0, 2.0, 76)
    sol = solved("geared-fivebar", degrees, omega, alpha).solution
    assert (sol.status == 0).all()
    close(sol.body("crank2")["angle"], math.pi / 2 - theta / 2, "crank 2")
    for label, expected in _fivebar(theta, omega, alpha).items():
        point = sol.point(label)
        for key, value in zip(("position", "velocity", "acceleration"), expected):
            close(point[key], value, f"{label} {key}")


def test_the_geared_fivebar_sweeps_two_turns_to_one_mechanism():
    kin = xcheck.load(DATA / "geared-fivebar.toml").kinematics
    rng = kin.input_range(0)
    assert rng.full_turn
    assert ("up", 0) not in kin._turns  # one turn of crank 1 does not bring it back


def test_the_geared_fivebar_reactions_agree_both_ways():
    degrees = np.linspace(0.0, 360.0, 19)
    sol = solved("geared-fivebar", degrees, 1.5, 0.5).solution
    lagrange, euler = inverse_dynamics(sol), newton_euler(sol)
    for joint, values in lagrange.joints.items():
        for quantity, value in values.items():
            close(euler.joints[joint][quantity], value, f"{joint} {quantity}")
    close(euler.drivers["crank"]["effort"], lagrange.drivers["crank"]["effort"], "effort")


# -- free motion ---------------------------------------------------------------------------


def test_a_whole_planetary_trains_free_motion_is_its_one_degree_of_freedom():
    """J theta'' = 4 T_sun, J = I_arm,O + 16 I_sun + m_p d^2 + 4 I_p (d = 60 mm)."""
    from xcheck.dynamics._free import simulate

    kin = xcheck.load(DATA / "planetary-train.toml").kinematics
    reference = simulate(kin)
    j = 0.4 * 0.06**2 / 12 + 0.4 * 0.03**2 + 16 * 0.5 * 0.03**2 / 2 + 0.3 * 0.06**2 + 4 * 0.3 * 0.03**2 / 2
    t = reference.motion.times
    theta = 2.0 * t + 4 * 0.002 * t**2 / (2 * j)
    q = reference.motion.q
    arm, sun, planet = (3 * kin.system.body_index[b] + 2 for b in ("arm", "sun", "planet"))
    assert reference.converged
    assert np.max(np.abs(q[:, arm] - theta)) <= reference.estimate.max() / 0.06 + 1e-12
    assert np.max(np.abs(q[:, sun] - 4 * q[:, arm])) <= 1e-12
    assert np.max(np.abs(q[:, planet] + 2 * q[:, arm])) <= 1e-12


def test_a_planetary_trains_free_motion_is_its_one_degree_of_freedom():
    """Released, the train has one degree of freedom: J theta'' = 3 brake with
    J = I_arm,O + m_p d^2 + 9 I_p, so theta = 2 t + 3 brake t^2 / (2 J) (a
    brake of 5 mN m here: theta'' = -3.2 rad/s^2)."""
    text = (DATA / "planetary-fixed-sun.toml").read_text(encoding="utf-8").replace("torque = -0.5", "torque = -0.005")
    text += "\n[free_motion]\nduration = 1\noutput_step = 0.05\nvelocity = { arm = 2 }\ntolerance = 1e-10\n"
    mech = parse_mechanism(text, "planetary-free.toml")
    kin = xcheck.Kinematics(mech)
    from xcheck.dynamics._free import simulate

    reference = simulate(kin)
    motion = reference.motion
    j = 0.4 * 0.09**2 / 12 + 0.4 * 0.045**2 + 0.3 * 0.09**2 + 9 * 0.3 * 0.03**2 / 2
    t = motion.times
    theta = 2.0 * t + 3 * -0.005 * t**2 / (2 * j)
    arm, planet = (3 * kin.system.body_index[b] + 2 for b in ("arm", "planet"))
    assert reference.converged
    bound = reference.estimate.max() / 0.09 + 1e-12  # the stated error, as an angle at the arm's length
    assert np.max(np.abs(motion.q[:, arm] - theta)) <= bound
    assert np.max(np.abs(motion.q[:, planet] - 3 * motion.q[:, arm])) <= 1e-12  # the mesh holds


# -- the file format ---------------------------------------------------------------------


FIVEBAR = (DATA / "geared-fivebar.toml").read_text(encoding="utf-8")
GEAR = '[[joints]]\ntype = "gear"\nname = "gears"\nbodies = ["crank1", "crank2"]\nradii = [40, 80]\nphase = 90\n'


@pytest.mark.parametrize(
    "replacement, field, expected",
    [
        ("radii = [40, 70]", "joints[5].radii", "pitch radii whose sum is the distance of the centres A and E"),
        ("radii = [40, 80]\nteeth = [20, 40]", "joints[5].radii", "either radii"),
        ('teeth = [20, 40]\nmesh = "internal"', "joints[5].radii", None),  # 20 : 40 internal: radii 120, 240
        ('radii = [40, 80]\nmesh = "sideways"', "joints[5].mesh", "one of 'external', 'internal'"),
        ('radii = [40, 80]\ncarrier = "crank1"', "joints[5].carrier", "a body other than the gears"),
        ('radii = [40, 80]\ncarrier = "coupler1"', "joints[5].carrier", "the body gear crank2 turns on"),
        ('radii = [40, 80]\npoint = "A"', "joints[5].point", "the keys of a gear pair"),
        ("radii = [40, -80]", "joints[5].radii[1]", "a positive number"),
    ],
)
def test_a_bad_gear_pair_is_one_line(replacement, field, expected, tmp_path):
    path = tmp_path / "gears.toml"
    path.write_text(FIVEBAR.replace(GEAR, GEAR.replace("radii = [40, 80]\n", replacement + "\n")), encoding="utf-8")
    done = invoke("solve", str(path))
    if expected is None:  # loads; the internal pair's radii (120, 240 mm) are what the centres allow
        return
    assert done.returncode == 2 and "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith(f"xcheck: error: {path}: {field}: expected {expected}"), line


def test_a_gear_pair_cannot_be_driven_nor_take_a_spring(tmp_path):
    with pytest.raises(
        ModelError, match=r"drivers\[0\].joint: expected a joint that can be driven .*found 'gears', a gear joint"
    ):
        parse_mechanism(FIVEBAR.replace('joint = "A"', 'joint = "gears"'))
    spring = '\n[[rotational_springs]]\njoint = "gears"\nstiffness = 1\n'
    with pytest.raises(ModelError, match=r"a gear joint does not turn about a pivot"):
        parse_mechanism(FIVEBAR + spring)
    with pytest.raises(ModelError, match=r"joints\[0\].radii: expected no radii on a revolute joint"):
        parse_mechanism(FIVEBAR.replace('point = "A"\n', 'point = "A"\nradii = [1, 2]\n', 1))
