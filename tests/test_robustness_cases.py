"""Mechanism files written outside the project's own catalogue, and what they
exposed: a change point passed by the sweep, a mechanism name in another script."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

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
    That agreement is not a sample the formulations left out, and the run warns of the
    singular position it passes."""
    with warnings.catch_warnings(record=True):
        at_change = xcheck.load(CHANGE_POINT).solve(at=180)
    assert "near a limit or singular position" in " ".join(at_change.warnings)
    run = xcheck.run(CHANGE_POINT, engines="native,formulations", samples=5)
    assert run.verdict == "pass", run.summary.to_string()
    # the terminal says so, as the report does (they print the run's warnings)
    assert any("crank = 180 deg is near a limit or singular position" in line for line in run.warnings), run.warnings
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


def _solved(name: str) -> list[dict]:
    done = invoke("solve", str(DATA / f"{name}.toml"), "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)["states"]


def _close(found, expected, scale: float) -> None:
    assert np.max(np.abs(np.asarray(found, float) - np.asarray(expected, float))) <= 1e-13 * scale, (found, expected)


# The answers below were derived apart from xcheck with sympy (20 digits), as each file's
# comments say: closed-form positions differentiated in time, and a torque by the power balance.


def test_offset_slider_crank_in_mm_and_rpm_with_a_load():
    """Slider positions, velocities and accelerations (SI, from a file in mm, deg and rpm), and
    the crank torque against gravity and a 100 N load."""
    states = _solved("offset-slider-crank")
    expected = {
        0: ([0.21758552076855569, -0.02], [-0.45465555997979385, 0], [-7.6306734555495242, 0], -3.1704696739790871),
        1: ([0.13299202255930347, -0.02], [0.22440794730173312, 0], [5.4385790126276255, 0], 1.6443513502898258),
    }
    for i, (position, velocity, acceleration, effort) in expected.items():
        point = states[i]["points"]["B"]
        _close(point["position"], position, 0.2)
        _close(point["velocity"], velocity, 0.5)
        _close(point["acceleration"], acceleration, 8.0)
        _close([states[i]["drivers"]["crank"]["effort"]], [effort], 3.0)


def test_crank_shaper_with_a_slot_on_a_moving_rocker():
    """The ram and the rocker of a quick-return shaper (cm, deg/s in the file) at crank = 135 deg."""
    state = _solved("crank-shaper")[1]
    ram = state["points"]["C"]
    _close(ram["position"], [0.13740485840189022, 0.28], 0.3)
    _close(ram["velocity"], [-0.40287400308132980, 0], 0.5)
    _close(ram["acceleration"], [0.52291342705030732, 0], 1.0)
    rocker = state["bodies"]["rocker"]
    _close(
        [rocker["angle"], rocker["omega"], rocker["alpha"]],
        [1.7592758375655018, 0.68849009648158766, -0.82568606124459108],
        2.0,
    )


def test_fivebar_with_two_inputs_and_explicit_rates():
    """C of a five-bar driven by both cranks, the second's rate and acceleration given in the instant."""
    point = _solved("fivebar-two-inputs")[1]["points"]["C"]
    _close(point["position"], [0.13373817821122408, 0.29764875617791083], 0.3)
    _close(point["velocity"], [-0.12993834391093967, -0.039538537965162415], 0.2)
    _close(point["acceleration"], [-0.056410953697900143, -0.15164409235147829], 0.2)


def test_a_damped_sprung_pendulum_released_level_follows_its_own_equation():
    """The native free motion against the pendulum's one equation (the file's comments),
    integrated by scipy to 1e-13: within the error xcheck states, at every output."""
    from scipy.integrate import solve_ivp

    mass, gravity, arm, inertia, stiffness, damping = 1.2, 9.81, 0.25, 0.025, 3.0, 0.05

    def swing(_, y):
        angle, rate = y
        torque = -mass * gravity * arm * np.cos(angle) - stiffness * (angle + np.pi / 2) - damping * rate
        return [rate, torque / (inertia + mass * arm**2)]

    motion = xcheck.simulate(DATA / "pendulum-spring-damper.toml")
    assert motion.attrs["converged"]
    times = motion.time_s.to_numpy()
    exact = solve_ivp(swing, (0, 2), [0.0, 0.0], method="DOP853", t_eval=times, rtol=1e-13, atol=1e-15).y[0]
    tip_error = 0.5 * np.abs(motion.angle_rad.to_numpy() - exact)  # the tip P, 0.5 m out
    assert np.all(tip_error <= motion.error_bound_m.to_numpy() + 1e-14), np.max(tip_error)
    assert abs(motion.angle_rad.iloc[-1] - exact[-1]) < 1e-11  # (measured 3.1e-13 rad)


@pytest.mark.parametrize("degrees", [1e308, 1e200])
def test_an_input_a_double_cannot_place_is_never_assembled(degrees):
    """At 1e308 deg the crank's angle is a double with nothing left below 1e290 rad: the
    shaper's loops could not be closed there, and were reported closed ("ok") 15 cm open.
    Such a state is refused; 1e17 deg, whose double is still placed exactly, assembles."""
    shaper = xcheck.load(DATA / "crank-shaper.toml")
    with pytest.raises(ValueError, match="expected a state where the mechanism assembles"):
        shaper.solve(at=degrees)
    state = shaper.solve(at=1e17).to_frame()
    assert np.isfinite(state.x_m).all()


def test_a_sweep_whose_samples_a_double_cannot_tell_apart_is_refused(tmp_path):
    """From 1e100 deg a turn adds nothing a double can hold: every sample of the sweep was
    the same state, and the run passed on it."""
    text = (DATA / "crank-shaper.toml").read_text()
    path = tmp_path / "wound.toml"
    path.write_text(
        text.replace("start = 0\n", "start = 1e100\n").replace("at = { crank = 0 }", "at = { crank = 1e100 }")
    )
    done = invoke("run", str(path), "--engines", "native", "--samples", "5", "--no-report", "--no-cache")
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == (
        f"xcheck: error: {path}: assembly.at.crank: expected an input a double holds finely enough to sweep "
        "5 distinct samples around it, found 1e+100 deg, where they coincide"
    )


def _spring_through_the_slider(tmp_path) -> Path:
    """The offset slider-crank with a spring of rest length 50 mm from the ground point S on
    the slider's line, which the slider's pin B passes at crank = 90 deg exactly: there
    B_x = 50 cos 90 + sqrt(180^2 - (50 + 20)^2) = sqrt(27500) mm."""
    text = (DATA / "offset-slider-crank.toml").read_text()
    text = text.replace(
        "points = { O = [0, 0], L = [0, -20] }", 'points = { O = [0, 0], L = [0, -20], S = ["sqrt(27500)", -20] }'
    )
    path = tmp_path / "spring.toml"
    path.write_text(text + '\n[[springs]]\npoints = ["S", "B"]\nstiffness = 2000\nrest_length = 50\n')
    return path


def test_a_spring_whose_ends_meet_has_no_direction_there(tmp_path):
    """Where the ends of a spring with a rest length meet, its 100 N pull has no direction: the
    round-off of B's position chose one (the crank torque was a number, its sign noise). The
    reactions and efforts there are undetermined, said in a warning, and the power balance over
    the motion is not computed, with the reason, instead of being printed as NaN."""
    path = _spring_through_the_slider(tmp_path)
    done = invoke("solve", str(path), "--at", "90,100", "--json")
    assert done.returncode == 0, done.stderr
    states = json.loads(done.stdout)["states"]
    assert states[0]["drivers"]["crank"]["effort"] is None and states[0]["joints"]["O"]["reaction"] is None
    assert np.isfinite(states[1]["drivers"]["crank"]["effort"])
    assert "spring 'spring 1' has its two ends at one point at crank = 90 deg" in done.stderr
    run = xcheck.run(path, engines="native", samples=7)
    assert run.energy is None and "spring 'spring 1' has its two ends at one point" in run.no_energy
