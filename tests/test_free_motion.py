"""The native free-motion reference against answers derived independently:
the simple pendulum's closed form in Jacobi's elliptic functions (IFToMM A01)
and the double four-bar reduced to its one degree of freedom on the
parallelogram branch (IFToMM A02), through its singular positions."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest
from conftest import DATA, MODELS, invoke
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

from xcheck import Kinematics, load_mechanism
from xcheck.dynamics._free import FreeState, free_reference, release_state, simulate_free

G = 9.81


def _start(name: str, angle: float, rate: float) -> tuple[Kinematics, FreeState]:
    """The mechanism of tests/data/NAME.toml at its driver's ``angle`` (rad)
    turning at ``rate`` (rad/s); the rest of the velocity follows from the constraints."""
    kin = Kinematics(load_mechanism(DATA / f"{name}.toml"))
    kin.assemble()
    sol = kin.solve(np.array([[angle]]), np.array([[rate]]), np.array([[0.0]]))
    return kin, FreeState(sol.q[0], sol.qd[0])


def pendulum_exact(times: np.ndarray) -> np.ndarray:
    """P1 of the pendulum released at rest from (-1, 0): theta from the downward
    vertical, sin(theta / 2) = k sn(K - w0 t | k^2), k = sin(45 deg); (N, 2) m."""
    k = math.sin(math.pi / 4)
    sn, _, _, _ = ellipj(ellipk(k * k) - math.sqrt(G) * times, k * k)
    theta = 2.0 * np.arcsin(k * sn)
    return np.stack([-np.sin(theta), -np.cos(theta)], axis=1)


def double_fourbar_exact(times: np.ndarray) -> np.ndarray:
    """B0 of the double four-bar on its parallelogram branch: every crank at
    theta, the couplers translating; T = 3/2 theta'^2 (three cranks m L^2 / 3
    about their pivots, two couplers at the tips' speed), V = 3.5 g sin(theta),
    so theta'' = -(3.5 / 3) g cos(theta); theta(0) = 90 deg, theta'(0) = -1
    rad/s (B0 moves at +1 m/s along x). (N, 2) m, from DOP853 at rtol 1e-13."""
    ode = solve_ivp(
        lambda t, y: [y[1], -3.5 / 3.0 * G * math.cos(y[0])],
        (0.0, float(times[-1])),
        [math.pi / 2, -1.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
        t_eval=times,
    )
    return np.stack([np.cos(ode.y[0]), np.sin(ode.y[0])], axis=1)


def test_pendulum_converges_at_order_four_to_the_closed_form():
    kin, start = _start("pendulum", math.pi, 0.0)
    errors = []
    for step in (0.005, 0.0025):
        motion = simulate_free(kin, start, 1.0, 0.01, step)
        found = motion.solution().point("P1")["position"]
        errors.append(float(np.abs(found - pendulum_exact(motion.times)).max()))
        assert motion.residual.max() <= 1e-9  # the loop drifts O(h^5) a step before each projection
    order = math.log2(errors[0] / errors[1])
    assert 3.5 <= order <= 4.5, errors


@pytest.mark.slow
def test_pendulum_reference_states_an_honest_error():
    kin, start = _start("pendulum", math.pi, 0.0)
    reference = free_reference(kin, start, 3.0, 0.01, tolerance=1e-9)
    assert reference.converged
    found = reference.motion.solution().point("P1")["position"]
    true_error = np.abs(found - pendulum_exact(reference.motion.times)).max(axis=1)
    assert true_error.max() <= 1e-9 * kin.system.size
    assert np.all(true_error <= reference.estimate + 1e-15)  # the estimate bounds the true error
    # no loads: the energy is kept to the integrator's accuracy (measured 6.4e-11 J at the finest
    # step, 1.25 ms, of a swing of m g L = 9.81 J: 6.6e-12; the bound leaves the estimate's factor 15)
    assert np.abs(reference.motion.energy_error).max() <= 1e-10 * G


@pytest.mark.slow
def test_double_fourbar_passes_its_singular_positions_on_the_branch():
    """Through two all-horizontal passes in 1.5 s, to 1e-9 of the size, the
    passes found where the reduced solution has its cranks horizontal."""
    kin, start = _start("double-fourbar", math.pi / 2, -1.0)
    reference = free_reference(kin, start, 1.5, 0.01, tolerance=1e-9)
    assert reference.converged
    motion = reference.motion
    exact = double_fourbar_exact(motion.times)
    true_error = np.abs(motion.solution().point("B0")["position"] - exact).max(axis=1)
    assert true_error.max() <= 1e-9 * kin.system.size
    assert np.all(true_error <= reference.estimate + 1e-15)
    # the horizontal positions of the reduced solution: sin(theta) changes sign
    crossings = motion.times[1:][np.sign(exact[1:, 1]) != np.sign(exact[:-1, 1])]
    assert len(crossings) == len(motion.singular_passes) == 2
    assert np.allclose(motion.singular_passes, crossings, atol=0.01 + motion.step)


@functools.cache
def _double_fourbar_reduction():
    """theta'' = -(3.5 / 3) g cos(theta) from 90 degrees at -1 rad/s: (theta, theta') as a
    function of time, by mpmath's Taylor method in 20 digits."""
    import mpmath as mp

    with mp.workdps(20):
        rate = mp.mpf(3.5) / 3 * mp.mpf("9.81")
        return mp.odefun(lambda _, y: [y[1], -rate * mp.cos(y[0])], 0, [mp.pi / 2, mp.mpf(-1)])


def _double_fourbar_state(t: float) -> tuple[np.ndarray, np.ndarray]:
    """The body coordinates and rates of models/benchmarks/iftomm-a02.toml at ``t`` (s) on its
    parallelogram branch (three cranks, then two couplers), from :func:`_double_fourbar_reduction`."""
    import mpmath as mp

    with mp.workdps(20):
        theta, w = _double_fourbar_reduction()(mp.mpf(t))
        c, s, w = float(mp.cos(theta)), float(mp.sin(theta)), float(w)
    q = [[i + c / 2, s / 2, float(theta)] for i in range(3)] + [[i + 0.5 + c, s, 0.0] for i in range(2)]
    qd = [[-s * w / 2, c * w / 2, w]] * 3 + [[-s * w, c * w, 0.0]] * 2
    return np.ravel(q), np.ravel(qd)


@pytest.mark.parametrize("tolerance", [1e-14, 1e-15])
def test_dop853_crosses_a_singular_position_at_round_off(tolerance):
    """A02 from its exact state 0.2 s before the pass at 0.714 s to 0.2 s after it, DOP853
    at a local tolerance of 1e-14 and 1e-15: the velocity error at the end stays within 1e-13
    m/s. Measured: 2.7e-14 and 2.8e-14 m/s (7e-15 over a stretch without a pass); with the
    crossing step's stages unprojected, whose accelerations move by a stage's distance from
    the constraints over the Jacobian's smallest singular value, 1.7e-13 and 5.5e-13."""
    from xcheck.dynamics._adaptive import integrate_adaptive
    from xcheck.dynamics._free import _Dynamics
    from xcheck.dynamics._free_compiled import Packed

    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a02.toml"))
    assert [b.name for b in kin.mechanism.moving_bodies] == ["crank1", "crank2", "crank3", "coupler1", "coupler2"]
    q0, qd0 = _double_fourbar_state(0.5)  # (20 digits: the state 1e-20 off, measured against 30)
    q1, qd1 = _double_fourbar_state(0.9)
    run = integrate_adaptive(Packed(_Dynamics(kin)), q0, qd0, 40, 0.01, tolerance, 10**6)
    assert not run.failure and run.crossings == 1 and len(run.passes) == 1
    off = np.abs(run.qd[-1] - qd1)
    off[2::3] *= kin.system.size
    assert off.max() <= 1e-13


# -- the file format and `xcheck simulate` ----------------------------------------


def test_spring_and_damper_follow_the_damped_oscillator():
    """tests/data/spring-block.toml: m u'' + c u' + k u = 0 from u0 = 0.05 m at rest
    (closed form in its header); the damper's work keeps the energy balance."""
    done = invoke("simulate", str(DATA / "spring-block.toml"), "--json", "--no-report", "--engines", "native")
    assert done.returncode == 0, done.stderr
    native = json.loads(done.stdout)["native"]
    t, w0, zeta = 2.0, 10.0, 0.1
    wd = w0 * math.sqrt(1.0 - zeta**2)
    exact = 0.1 + 0.05 * math.exp(-zeta * w0 * t) * (math.cos(wd * t) + zeta * w0 / wd * math.sin(wd * t))
    found = native["final"]["points"]["B"]["position"][0]
    estimate = native["error_estimate"]
    assert estimate["converged"] and estimate["relative"] <= 1e-10
    assert abs(found - exact) <= estimate["final"]
    # E - E0 - W: measured 3.3e-12 J of 0.25 J stored in the spring at release
    assert native["energy_balance"]["largest"] <= 1e-10


def test_rotational_spring_and_damper_follow_the_damped_oscillator():
    """tests/data/torsion-pendulum.toml: I u'' + c u' + k u = 0 for the twist u
    from u0 = pi/6 at rest (closed form in its header). Measured: 4.6e-13 rad
    from the closed form at 2 s, within the stated 9.4e-13; the energy balance
    (spring energy, damper work) 2.3e-13 J of 0.27 J. MuJoCo's and Pinocchio's
    RK4 (the spring's torque applied through their force callbacks) 1.6e-11 m at
    the rim at 1 ms; pymunk's DampedRotarySpring: tests/test_free_pymunk.py."""
    done = invoke(
        "simulate",
        str(DATA / "torsion-pendulum.toml"),
        "--json",
        "--no-report",
        "--engines",
        "native,mujoco-free,pinocchio-free",
    )
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    native = doc["native"]
    t, w0, zeta, u0 = 2.0, 10.0, 0.1, math.pi / 6
    wd = w0 * math.sqrt(1.0 - zeta**2)
    exact = math.radians(-20) + u0 * math.exp(-zeta * w0 * t) * (math.cos(wd * t) + zeta * w0 / wd * math.sin(wd * t))
    found = native["final"]["bodies"]["disc"]["angle"]
    estimate = native["error_estimate"]
    assert estimate["converged"] and estimate["final"] <= 1e-11
    assert abs(found - exact) <= estimate["final"]
    assert native["energy_balance"]["largest"] <= 1e-11
    # MuJoCo and Pinocchio at RK4 integrate the same one-degree-of-freedom ODE: 1.6e-11 m at 1 ms
    for mode in ("mujoco-free", "pinocchio-free"):
        rows = [r for r in doc["engines"][mode]["ladder"] if r["integrator"] in ("RK4", "rk4")]
        assert rows and all(r["position_error"] <= 3e-11 for r in rows)


def test_torque_across_a_joint_shifts_the_oscillation(tmp_path):
    """The torsion pendulum with a constant torque of 0.5 N m across its pin
    ([[loads]] joint = "O"): the twist oscillates about u_eq = T / k = 0.25 rad,
    u = u_eq + (u0 - u_eq) exp(-zeta w0 t) (cos(wd t) + zeta w0 / wd sin(wd t));
    the energy balance counts the torque's work."""
    path = tmp_path / "driven-disc.toml"
    text = (DATA / "torsion-pendulum.toml").read_text(encoding="utf-8")
    path.write_text(text + '\n[[loads]]\njoint = "O"\ntorque = 0.5\n', encoding="utf-8")
    done = invoke("simulate", str(path), "--json", "--no-report", "--engines", "native")
    assert done.returncode == 0, done.stderr
    native = json.loads(done.stdout)["native"]
    t, w0, zeta, u0, u_eq = 2.0, 10.0, 0.1, math.pi / 6, 0.25
    wd = w0 * math.sqrt(1.0 - zeta**2)
    exact = (
        math.radians(-20)
        + u_eq
        + (u0 - u_eq) * math.exp(-zeta * w0 * t) * (math.cos(wd * t) + zeta * w0 / wd * math.sin(wd * t))
    )
    found = native["final"]["bodies"]["disc"]["angle"]
    assert abs(found - exact) <= native["error_estimate"]["final"] <= 1e-11
    assert native["energy_balance"]["largest"] <= 1e-11


@pytest.mark.parametrize(
    "extra,field,found",
    [
        ('joint = "O"\ntorque = 1\nforce = [1, 0]\n', "loads[0].force", "'force' as well"),
        ('joint = "Q"\ntorque = 1\n', "loads[0].joint", "'Q'"),
        ('joint = "O"\n', "loads[0].torque", "none"),
    ],
)
def test_bad_joint_torque_is_one_line(tmp_path, extra, field, found):
    path = tmp_path / "bad.toml"
    text = (DATA / "torsion-pendulum.toml").read_text(encoding="utf-8")
    path.write_text(text + "\n[[loads]]\n" + extra, encoding="utf-8")
    done = invoke("simulate", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {field}: expected " in lines[0] and found in lines[0], lines


def test_harmonic_force_drives_the_oscillator():
    """tests/data/shaken-block.toml: m u'' + c u' + k u = F0 sin(W t), closed form in
    its header. Measured: the reference 1.2e-12 m from it at 2 s (stated 1.9e-11 m);
    MuJoCo's and Pinocchio's RK4, which evaluate the law at their stage times, 1.9e-11 m
    at 1 ms (order 4 down to the reference's own error); pymunk 4.5e-4 .. 1.1e-4 m
    (first order)."""
    done = invoke(
        "simulate",
        str(DATA / "shaken-block.toml"),
        "--json",
        "--no-report",
        "--engines",
        "native,mujoco-free,pinocchio-free",
    )
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    native = doc["native"]
    m, k, c, f0, w = 2.0, 200.0, 4.0, 3.0, 2.0 * math.pi * 1.2
    w0, zeta = math.sqrt(k / m), c / (2.0 * math.sqrt(k * m))
    wd = w0 * math.sqrt(1.0 - zeta**2)
    x, d = f0 / math.hypot(k - m * w * w, c * w), math.atan2(c * w, k - m * w * w)
    a = 0.05 + x * math.sin(d)
    b = (zeta * w0 * a - x * w * math.cos(d)) / wd
    t = 2.0
    exact = 0.1 + x * math.sin(w * t - d) + math.exp(-zeta * w0 * t) * (a * math.cos(wd * t) + b * math.sin(wd * t))
    found = native["final"]["points"]["B"]["position"][0]
    assert abs(found - exact) <= native["error_estimate"]["final"] <= 1e-10
    assert native["energy_balance"]["largest"] <= 1e-10  # the force's work counted at every stage
    for mode in ("mujoco-free", "pinocchio-free"):
        rows = [r for r in doc["engines"][mode]["ladder"] if r["integrator"] in ("RK4", "rk4")]
        assert rows and all(r["position_error"] <= 4e-11 for r in rows), mode


def test_time_law_loads_are_free_motion_only(tmp_path):
    """A driven motion's states carry no time: solve refuses the reactions with one
    line (after the kinematics), run reports them not computed and goes on."""
    path = DATA / "shaken-block.toml"
    done = invoke("solve", str(path), "--at", "0.15")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "loads: expected constant loads for the inverse dynamics of a driven motion" in done.stderr
    assert "'shaker' with a harmonic law (1.2 Hz)" in done.stderr
    done = invoke("run", str(path), "--json", "--out", str(tmp_path), "--engines", "native")
    assert done.returncode == 0, done.stderr
    assert "time laws act in free motion" in json.loads(done.stdout)["forces_not_computed"]


@pytest.mark.parametrize(
    "law,field,found",
    [
        ('{ kind = "chirp" }', "loads[0].law.kind", "'chirp'"),
        ('{ kind = "ramp", duration = 0 }', "loads[0].law.duration", "0"),
        ('{ kind = "harmonic", frequency = -1 }', "loads[0].law.frequency", "-1"),
        ('{ kind = "ramp", duration = 1, frequency = 2 }', "loads[0].law.frequency", "'frequency'"),
    ],
)
def test_bad_load_law_is_one_line(tmp_path, law, field, found):
    path = tmp_path / "bad.toml"
    text = (DATA / "shaken-block.toml").read_text(encoding="utf-8")
    old = 'law = { kind = "harmonic", frequency = 1.2 }'
    assert old in text
    path.write_text(text.replace(old, f"law = {law}"), encoding="utf-8")
    done = invoke("simulate", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {field}: expected " in lines[0] and found in lines[0], lines


def test_engines_converge_on_every_joint_and_force_kind():
    """tests/data/free-mixed.toml over 0.2 s (a slot, a prismatic joint on a moving
    body, springs to the ground and between bodies, a rotational spring-damper, forces,
    torques, gravity): Pinocchio's RK4 and MuJoCo's stiff RK4 converge on the native
    reference, which no engine shares code with. Measured (2026-11-25): Pinocchio RK4
    1.21e-5, 7.44e-7, 4.63e-8 m at dt = 1, 0.5, 0.25 ms (order 4); MuJoCo stiff RK4
    1.42e-5, 4.78e-6, 9.62e-7 m; the bounds are twice the finest."""
    done = invoke(
        "simulate", str(DATA / "free-mixed.toml"), "--duration", "0.2", "--json", "--no-report",
        "--engines", "native,mujoco-free,pinocchio-free",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    engines = json.loads(done.stdout)["engines"]

    def finest(mode: str, setting: str, integrator: str) -> list[float]:
        rows = [r for r in engines[mode]["ladder"] if r["setting"] == setting and r["integrator"] == integrator]
        assert all(r["status"] == "ok" for r in rows)
        return [r["position_error"] for r in sorted(rows, key=lambda r: r["timestep"])]

    pinocchio = finest("pinocchio-free", "rk4", "rk4")
    assert pinocchio[0] <= 1e-7 and pinocchio[1] / pinocchio[0] >= 12.0  # order 4: 16
    assert finest("mujoco-free", "stiff", "RK4")[0] <= 2e-6


@pytest.mark.parametrize(
    "change,field,found",
    [
        (('joint = "O"\nstiffness = 2', 'joint = "P"\nstiffness = 2'), "rotational_springs[0].joint", "'P'"),
        (("stiffness = 2", "stiffness = -2"), "rotational_springs[0].stiffness", "-2"),
        (("damping = 0.04", "damping = -1"), "rotational_springs[0].damping", "-1"),
        (("rest_angle = -20", 'rest_angle = "x"'), "rotational_springs[0].rest_angle", "'x'"),
    ],
)
def test_bad_rotational_spring_is_one_line(tmp_path, change, field, found):
    path = tmp_path / "bad.toml"
    text = (DATA / "torsion-pendulum.toml").read_text(encoding="utf-8")
    assert change[0] in text
    path.write_text(text.replace(change[0], change[1]), encoding="utf-8")
    done = invoke("simulate", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {field}: expected " in lines[0] and found in lines[0], lines


def test_rotational_spring_on_a_prismatic_joint_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    text = (DATA / "spring-block.toml").read_text(encoding="utf-8")
    path.write_text(text + '\n[[rotational_springs]]\njoint = "guide"\nstiffness = 1\n', encoding="utf-8")
    done = invoke("simulate", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "rotational_springs[0].joint: expected a revolute or pin-in-slot joint (none)" in done.stderr
    assert "a prismatic joint does not turn" in done.stderr


def test_simulate_json_states_the_pendulum_and_its_error():
    done = invoke(
        "simulate",
        "iftomm-a01",
        "--duration",
        "1",
        "--json",
        "--no-report",
        "--engines",
        "native",
        "--models",
        str(MODELS),
    )
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    final = doc["native"]["final"]
    assert final["t"] == pytest.approx(1.0, abs=1e-12)
    exact = pendulum_exact(np.array([1.0]))[0]
    error = float(np.abs(np.array(final["points"]["P1"]["position"]) - exact).max())
    assert error <= doc["native"]["error_estimate"]["final"] <= 1e-9
    assert doc["native"]["singular_passes"] == []


@pytest.mark.parametrize(
    "change,field,found",
    [
        (("duration = 2", "duration = 0"), "free_motion.duration", "0"),
        (("stiffness = 200", "stiffness = -1"), "springs[0].stiffness", "-1"),
        (('points = ["O", "B"]', 'points = ["O", "Q"]'), "springs[0].points", "'Q'"),
        (("output_step = 0.01", "output_step = 0.3"), "free_motion.output_step", "0.3"),
        (
            ("tolerance = 1e-10", 'point_velocity = { point = "B", value = [0, 1] }'),
            "free_motion.point_velocity",
            "violate by 1 m/s",
        ),
    ],
)
def test_bad_free_motion_input_is_one_line(tmp_path, change, field, found):
    path = tmp_path / "bad.toml"
    text = (DATA / "spring-block.toml").read_text(encoding="utf-8")
    assert change[0] in text
    path.write_text(text.replace(change[0], change[1]), encoding="utf-8")
    done = invoke("simulate", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {field}: expected " in lines[0] and found in lines[0], lines


def test_simulate_needs_a_free_motion_section():
    done = invoke("simulate", "fourbar", "--models", str(MODELS))
    assert done.returncode == 2 and "free_motion: expected a [free_motion] section" in done.stderr


def test_simulate_writes_a_report_and_the_index_keeps_it(tmp_path):
    done = invoke(
        "simulate", "iftomm-a01", "--duration", "0.5", "--engines", "native,mujoco-free",
        "--out", str(tmp_path), "-q", "--models", str(MODELS),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = (tmp_path / "iftomm-a01.md").read_text(encoding="utf-8")
    for heading in ("## The native reference", "## Engines in free motion", "## Versions"):
        assert heading in report
    assert report.rstrip().endswith("`") and "Reproduce: `xcheck simulate iftomm-a01 --duration 0.5" in report
    for image in ("drawing.png", "energy.png"):
        assert (tmp_path / "iftomm-a01" / image).read_bytes().startswith(b"\x89PNG")
    # a later `xcheck run` into the same folder keeps the benchmark's line in the index
    ran = invoke(
        "run",
        "fourbar",
        "--engines",
        "formulations",
        "--samples",
        "11",
        "--out",
        str(tmp_path),
        "-q",
        "--models",
        str(MODELS),
    )
    assert ran.returncode == 0, ran.stderr
    index = (tmp_path / "README.md").read_text(encoding="utf-8")
    assert "[iftomm-a01](iftomm-a01.md)" in index and "[fourbar](fourbar.md)" in index


#: the IVP test set's reference state of Andrews' squeezer at t = 0.03 s (problem
#: andrews; the angles of models/benchmarks/iftomm-a03.toml's header), rad
ANDREWS = {
    "beta": 15.8107711962990,
    "theta": -15.7563710598430,
    "gamma": 0.0408222401307310,
    "phi": -0.534730116322695,
    "delta": 0.524409965880530,
    "Omega": 0.534730116322695,
    "epsilon": 1.04808074104226,
}


def _andrews_angles(kin: Kinematics, q: np.ndarray) -> dict[str, float]:
    """The IVP test set's angles of Andrews' squeezer from body coordinates q (n,), rad."""
    angle = {name: q[3 * i + 2] for name, i in kin.system.body_index.items() if i >= 0}
    return {
        "beta": angle["crank"],
        "theta": angle["rod"] - angle["crank"],
        "gamma": angle["body3"],
        "phi": angle["body4"] - angle["body5"],
        "delta": angle["body5"],
        "Omega": angle["body6"] - angle["body7"],
        "epsilon": angle["body7"],
    }


@pytest.mark.slow
def test_andrews_squeezer_reaches_the_published_state():
    """IFToMM A03 (seven bodies, a spring and a motor torque, the crank through 2.5
    turns in 0.03 s) at h = 10 us against the published state. Measured: 1.3e-9 rad
    at h = 10 us and 1.4e-9 at 5 us (the two runs differ by 1.3e-10: the rest is
    the published value's own precision), 3e-11 at 20 us."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a03.toml"))
    kin.assemble()
    motion = simulate_free(kin, release_state(kin), 0.03, 1e-4, 1e-5)
    found = _andrews_angles(kin, motion.q[-1])
    assert max(abs(found[k] - ANDREWS[k]) for k in ANDREWS) <= 5e-9, found
    assert motion.residual.max() <= 1e-12  # m, the loops before each projection
    assert abs(motion.energy_error).max() <= 1e-8 * abs(motion.energy).max()  # motor work and the spring


def test_andrews_squeezer_both_native_methods_reach_the_published_state():
    """A03 at the file's tolerance: DOP853 and its check (Gauss-Legendre collocation)
    converge, agree within their stated errors, and each reaches the published state to its
    precision. Measured: they agree to 4.6e-12 m (6.2e-11 of the size; stated 2.3e-11 and
    5.2e-13 m), and both are 1.36e-9 and 1.43e-9 rad from the published state (at a
    tolerance of 1e-11 of the size too: the rest is the published value's own precision)."""
    from xcheck.dynamics._free import simulate

    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a03.toml"))
    kin.assemble()
    reference = simulate(kin, check=True)
    assert reference.check is not None and reference.check.consistent
    for run in (reference, reference.check.reference):
        assert run.converged, run.method
        found = _andrews_angles(kin, run.motion.q[-1])
        assert max(abs(found[k] - ANDREWS[k]) for k in ANDREWS) <= 5e-9, run.method


@pytest.mark.slow
def test_double_fourbar_of_forty_windows_follows_its_reduction():
    """models/benchmarks/iftomm-a02-n40.toml (81 bars, 243 coordinates, 242 rows: the
    banded path) through its first all-horizontal pass, where all forty windows
    lose rank together: every crank at the reduced theta'' = -((41/2 + 40) /
    (41/3 + 40)) g cos(theta). Measured (2026-11-25) over 1 s from a 2.5 ms
    step: converged at 1.25 ms, stated 1.9e-8 m (angles times the 40 m size),
    true 1.3e-9 (crank angles times the size) and 3.2e-11 m (B0); energy
    balance 2.8e-8 J of about 600 J; the bounds leave a factor of about 4."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks/iftomm-a02-n40.toml"))
    assert (len(kin.mechanism.moving_bodies), kin.system.n) == (81, 243)
    reference = free_reference(kin, release_state(kin), 1.0, 0.01, tolerance=1e-9, first_step=2.5e-3)
    assert reference.converged
    motion, size = reference.motion, kin.system.size
    k = (41 / 2 + 40) / (41 / 3 + 40)
    ode = solve_ivp(
        lambda t, y: [y[1], -k * G * math.cos(y[0])],
        (0.0, 1.0),
        [math.pi / 2, -1.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
        t_eval=motion.times,
    )
    theta = ode.y[0]
    cranks = [3 * i + 2 for i, b in enumerate(kin.mechanism.moving_bodies) if b.name.startswith("crank")]
    assert len(cranks) == 41
    angle_error = np.abs(motion.q[:, cranks] - theta[:, None]).max(axis=1) * size
    exact = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    point_error = np.abs(motion.solution().point("B0")["position"] - exact).max(axis=1)
    assert np.all(angle_error <= reference.estimate + 1e-15)  # the estimate bounds the true error
    assert angle_error.max() <= 5e-9 and point_error.max() <= 1e-10
    assert np.abs(motion.energy_error).max() <= 1e-7
    crossings = motion.times[1:][np.sign(exact[1:, 1]) != np.sign(exact[:-1, 1])]
    assert len(crossings) == len(motion.singular_passes) == 1
    assert np.allclose(motion.singular_passes, crossings, atol=0.01 + motion.step)


def test_reference_adds_the_round_off_measured_from_moved_starts(monkeypatch):
    """The kept run is repeated from starts moved by a few ulps in opposite patterns
    (projected onto the constraints); twice their largest difference so far from the kept
    run is added to the stated error at every output, and where that lifts it above the
    tolerance the ladder is not converged."""
    import types

    import xcheck.dynamics._free as free
    from xcheck.dynamics._reference import ROUND_OFF_FACTOR, ROUND_OFF_RUNS

    kin = Kinematics(load_mechanism(MODELS / "benchmarks/iftomm-a02.toml"))
    start = release_state(kin)
    errors = {0.0025: 1e-6, 0.00125: 1e-7, 0.000625: 1e-8, 0.0003125: 1e-9}  # m, made up
    amplify = {"by": 0.0}
    starts = []

    def fake(kinematics, moved, duration, output_step, step, compiled=True):
        starts.append(moved.q.copy())
        q = np.zeros((3, kinematics.system.n))
        q[:, 0] = errors[round(step, 9)] + np.array([0.0, 1.0, 0.5]) * amplify["by"] * (moved.q - start.q).max()
        return types.SimpleNamespace(q=q, step=step, seconds=0.0, times=np.arange(3) * 0.5, statistics={}, failure="")

    monkeypatch.setattr(free, "simulate_free", fake)
    tolerance = 5e-7 / kin.system.size
    exact = free.free_reference(kin, start, 1.0, 0.01, tolerance=tolerance, first_step=0.0025)
    assert exact.converged and [entry["difference"] for entry in exact.ladder[-ROUND_OFF_RUNS:]] == [0.0, 0.0]
    moved = starts[-ROUND_OFF_RUNS:]
    assert ROUND_OFF_RUNS == 2 and 0.0 < np.abs(moved[0] - moved[1]).max() < 1e-13 * kin.system.size
    assert np.dot(moved[0] - start.q, moved[1] - start.q) < 0.0  # opposite: apart along the one free direction
    amplify["by"] = 1e9
    rounded = free.free_reference(kin, start, 1.0, 0.01, tolerance=tolerance, first_step=0.0025)
    spreads = [entry["difference"] for entry in rounded.ladder[-ROUND_OFF_RUNS:]]
    assert all(e["status"].startswith("round-off") for e in rounded.ladder[-ROUND_OFF_RUNS:])
    assert spreads[0] != spreads[1] and 1e-7 < max(spreads) < 1e-5  # a few ulps of each start, amplified
    added = ROUND_OFF_FACTOR * max(spreads)
    np.testing.assert_allclose(rounded.estimate - exact.estimate, [0.0, added, added], rtol=1e-12, atol=1e-20)
    assert not rounded.converged
    assert "the round-off measured lifts the stated error above the tolerance" in rounded.basis
    assert f"2 x their largest difference from the kept run, up to {added:.3g} m, added to the stated error" in (
        rounded.basis
    )


def test_reference_ladder_stops_where_the_difference_grows_twice(monkeypatch):
    """A difference that grows once (a coarse run off its asymptote) does not end the ladder;
    one that grows twice in a row (round-off, not truncation, rules there) does: not
    converged, the run with the least stated error kept, then run again from starts moved
    by a few ulps (its round-off: none here, the made-up runs ignore their start)."""
    import types

    import xcheck.dynamics._free as free

    errors = {0.0025: 1e-6, 0.00125: 1e-7, 0.000625: 5e-6, 0.0003125: 5e-5, 0.00015625: 0.0}  # m, made up
    kin = Kinematics(load_mechanism(MODELS / "benchmarks/iftomm-a02.toml"))
    start = release_state(kin)

    def fake(kinematics, start, duration, output_step, step, compiled=True):
        q = np.zeros((3, kinematics.system.n))
        q[:, 0] = errors[round(step, 9)]
        return types.SimpleNamespace(q=q, step=step, seconds=0.0, times=np.arange(3) * 0.5, statistics={}, failure="")

    monkeypatch.setattr(free, "simulate_free", fake)
    reference = free.free_reference(kin, start, 1.0, 0.01, tolerance=1e-12, first_step=0.0025)
    assert not reference.converged
    assert "grew twice" in reference.basis
    assert reference.motion.step == 0.00125
    assert reference.estimate.max() == pytest.approx(9e-7)
    assert [entry["step"] for entry in reference.ladder] == [0.0025, 0.00125, 0.000625, 0.0003125, 0.00125, 0.00125]
    assert reference.ladder[-1]["status"].startswith("round-off") and reference.ladder[-1]["difference"] == 0.0
    assert "round-off, measured by 2 more runs at 0.00125" in reference.basis
