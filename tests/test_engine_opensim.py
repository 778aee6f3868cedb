"""OpenSim (Simbody) in free motion (opensim-free) against the native reference and an
independent one (tests/free_problems.py: the Lagrange reduction in extended precision).

Measured with opensim 4.6 on the free four-bar (tests/data/free-fourbar-released.toml,
1 s): Runge-Kutta-Merson at fixed steps of 1, 0.5, 0.25 ms 6.3e-9, 4.0e-10, 2.5e-11 m
(order 3.99, then below the reference's stated error), loops closed to 1.9e-9 ..
7.3e-12 m; explicit Euler 1.4e-2, 7.4e-3, 2.6e-3 m with its loops held at 1.7e-4 m by
the projection (the constraint tolerance); error-controlled Merson at accuracies 1e-5,
6.25e-7, 3.9e-8: 3.8e-6, 8.9e-8, 2.5e-8 m, loops 3.6e-7 .. 2.5e-9 m.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from conftest import DATA, invoke, run_dynamic, run_free

pytest.importorskip("opensim")

import free_problems as fp  # noqa: E402

from xcheck import Kinematics, engines, load_mechanism  # noqa: E402
from xcheck.dynamics._free import simulate  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.opensim import free  # noqa: E402


@pytest.fixture(scope="module")
def ladder(released_fourbar):
    kin, reference = released_fourbar
    return kin, reference, run_free("opensim-free", kin, reference)


def _series(result, name: str):
    return result.summary[result.summary["series"] == name].sort_values("timestep", ascending=False)


def test_the_engine_is_registered_with_its_modes():
    engine = engines.engine("opensim")
    assert [(m.name, m.kind) for m in engine.modes] == [
        ("opensim-kinematic", "kinematic"),
        ("opensim-dynamic", "dynamic"),
        ("opensim-free", "free"),
    ]
    assert engine.available() == "" and engine.install == "pip install xcheck[opensim]"


def test_merson_converges_at_fourth_order_with_its_loops_closed(ladder):
    _, _, result = ladder
    assert result.ok and (result.summary["status"] == "ok").all()
    merson = _series(result, "merson")
    errors = merson["position_error"].to_numpy()
    assert errors[0] <= 2e-8 and math.log2(errors[0] / errors[1]) >= 3.5  # measured 6.3e-9 m, order 3.99
    assert merson["loop_drift"].max() <= 5e-9  # measured 1.9e-9 m at 1 ms
    assert result.study.set_index("series")["verdict"]["merson"].iloc[0] == "converging"


def test_euler_holds_its_loops_by_projection_alone(ladder):
    _, _, result = ladder
    euler = _series(result, "euler")
    errors = euler["position_error"].to_numpy()
    assert all(math.log2(errors[i] / errors[i + 1]) >= 0.5 for i in range(2))  # measured orders 0.93, 1.52
    # the loops open to the constraint tolerance whatever the step (the table's 1.7e-4 m)
    assert np.all((euler["loop_drift"] > 1e-4) & (euler["loop_drift"] < 2e-4))


def test_the_accuracy_ladder_follows_the_accuracy(ladder):
    _, _, result = ladder
    series = _series(result, "accuracy")
    assert np.allclose(series["accuracy"], [free.accuracy(dt) for dt in series["timestep"]])
    errors, gaps = series["position_error"].to_numpy(), series["loop_drift"].to_numpy()
    assert np.all(np.diff(errors) < 0) and errors[-1] <= 1e-7  # measured 3.8e-6, 8.9e-8, 2.5e-8 m
    assert gaps[-1] <= 1e-8  # measured 2.5e-9 m at accuracy 3.9e-8 (the table: 7.8e-10 m at 1e-8)


def test_the_finest_run_meets_the_independent_reference(ladder):
    """The crank angle of the finest Merson run against the Lagrange reduction's, at every
    compared output (the table's reference: 23.2606 deg at 1 s)."""
    _, _, result = ladder
    best = result.trajectories[0]
    exact = fp.reference("free-fourbar-released", best.times)
    assert math.isclose(math.degrees(exact["crank"][-1, 2]), 23.2606, abs_tol=5e-5)
    assert np.max(np.abs(best.bodies["crank"]["angle"] - exact["crank"][:, 2])) <= 1e-9  # measured 2.9e-10 rad


def test_a_prismatic_joint_and_a_spring_follow_the_reference():
    """tests/data/free-slider-crank-spring.toml (a slider on a prismatic joint, a spring to
    the ground, 2 s) at the first two fixed Merson steps: order 4 (measured 4.6e-7, 2.8e-8 m)."""
    kin = Kinematics(load_mechanism(DATA / "free-slider-crank-spring.toml"))
    kin.assemble()
    result = run_free("opensim-free", kin, simulate(kin), series=free.FREE_SERIES[:1], timestep=1e-3, rungs=2)
    errors = result.summary["position_error"].to_numpy()
    assert result.ok and errors[1] <= 1e-6 and math.log2(errors[0] / errors[1]) >= 3.5


def test_what_the_model_cannot_hold_is_not_applicable(released_fourbar):
    kin, reference = released_fourbar
    mech = kin.mechanism
    spring = load_mechanism(DATA / "free-slider-crank-spring.toml").springs[0]
    damped = dataclasses.replace(mech, springs=(dataclasses.replace(spring, damping=1.0, points=("A", "Q")),))
    with pytest.raises(NotApplicable, match="damping"):
        run_free("opensim-free", Kinematics(damped), reference)
    slot = Kinematics(load_mechanism(DATA / "free-mixed.toml"))
    with pytest.raises(NotApplicable, match="load|pin-in-slot"):
        run_free("opensim-free", slot, reference)


@pytest.mark.parametrize("name", ["fourbar", "slider-crank"])
def test_driven_dynamics_converge_at_fourth_order_in_every_quantity(kinematics, name):
    """opensim-dynamic: the drivers prescribed by their laws, Merson at 16, 8, 4 steps a
    sample. Measured: fourbar positions 8.7e-11, 1.4e-9, 2.1e-8 m, accelerations 1.9e-9,
    3.0e-8, 4.6e-7 relative; slider-crank 8.9e-12, 1.4e-10, 2.3e-9 m (ratio 16 per halving)."""
    from xcheck.results import differences

    kin = kinematics(name)
    result = run_dynamic("opensim-dynamic", kin)
    assert result.ok and (result.summary["status"] == "ok").all()
    runs = sorted(result.trajectories, key=lambda t: t.settings["timestep"])  # finest first
    assert len(runs) == 3
    tables = [differences(kin, run) for run in runs]
    for quantity in ("position", "angle", "velocity", "omega", "acceleration", "alpha"):
        errors = [float(table[table["quantity"] == quantity]["max_abs"].max()) for table in tables]
        assert all(math.log2(errors[i + 1] / errors[i]) >= 3.5 for i in range(2)), (quantity, errors)
    assert result.summary["position_error"].min() <= 2e-10
    assert result.summary["input_error"].max() <= 1e-12  # the coordinates on their laws


@pytest.mark.parametrize("name", ["fourbar", "two-body-arm"])
def test_the_assembler_is_a_kinematic_oracle_to_round_off(kinematics, name):
    """opensim-kinematic: OpenSim's assembler with the drivers prescribed, the loops cut as
    PointOnLineConstraints. Measured over 361 samples: fourbar positions 6.2e-16 m, angles
    1.3e-15, rates 1.4e-14, accelerations 4.9e-13 (of ROUND_OFF's 1e-10 and 1e-9)."""
    from xcheck.engines.opensim.kinematic import run_kinematic
    from xcheck.tolerances import ROUND_OFF

    kin = kinematics(name)
    result = run_kinematic(kin, samples=25)
    assert result.ok and len(result.trajectories[0].inputs) == 25
    worst = result.summary.groupby("quantity")["max_abs"].max()
    for quantity in ("position", "angle", "velocity", "omega", "acceleration", "alpha"):
        assert worst[quantity] <= 1e-3 * ROUND_OFF.limit(quantity), (quantity, worst[quantity])
    assert result.trajectories[0].diagnostics["constraint_violation"].max() <= 1e-12


def test_one_driver_is_prescribed_by_time_one_model_for_the_sweep(kinematics, monkeypatch):
    """With one driver, prescribed by time itself, one model serves every input of a sweep
    whose steps need no walk (the four-bar's 181 samples, 1.4 degrees apart): it is never
    prescribed and initialised again (2 ms an input). Its speeds, projected at the driver's
    unit rate and multiplied by the input's rate, are exact to round-off at a rate of
    2.5 rad/s turning the other way (the law's rate, not 1), the bound of the oracle test
    above scaled with the rates and the accelerations (2.5 and 6.25 times). Measured:
    rates 1.9e-14, accelerations 1.05e-12, as with a model prescribed by a quadratic
    and initialised at each input."""
    from xcheck.engines.opensim.kinematic import run_kinematic
    from xcheck.engines.opensim.model import OpenSimModel
    from xcheck.tolerances import ROUND_OFF

    prescribed = []
    prescribe = OpenSimModel.prescribe
    monkeypatch.setattr(OpenSimModel, "prescribe", lambda om, functions: prescribed.append(prescribe(om, functions)))
    kin = kinematics("fourbar")
    law = dataclasses.replace(kin.mechanism.drivers[0].law, rate=-2.5)
    mech = dataclasses.replace(kin.mechanism, drivers=(dataclasses.replace(kin.mechanism.drivers[0], law=law),))
    result = run_kinematic(Kinematics(mech), samples=181)
    assert result.ok and prescribed == []
    assert np.all(result.trajectories[0].input_rates == -2.5)
    worst = result.summary.groupby("quantity")["max_abs"].max()
    for quantity, scale in (("velocity", 2.5), ("omega", 2.5), ("acceleration", 6.25), ("alpha", 6.25)):
        assert worst[quantity] <= 1e-3 * ROUND_OFF.limit(quantity) * scale, (quantity, worst[quantity])


def test_a_heavy_kilometre_four_bar_is_exact_with_the_drivers_pushed_by_their_efforts():
    """The crank-rocker at 1 km (bodies of 3 to 9 t, crank at 2 rad/s). With the crank
    prescribed, Simbody solves its constraint forces with the round-off of its rate (a
    stated finding, with its reproducer): the oracle's accelerations missed by 4.6e-8 of
    the largest and OpenSim's reactions by 4.8e-8. Realised with the crank free, pushed by
    the effort that gives its law's acceleration, they agree to round-off (measured over
    9 samples: accelerations 7e-13 of the largest, as the rates' 3.5e-13 from Simbody's
    speed projection allows; reactions and effort 2.8e-13)."""
    done = invoke(
        "run", str(DATA / "km-fourbar.toml"), "--engines", "native,opensim-kinematic", "--samples", "9", "--json"
    )
    summary = json.loads(done.stdout)
    oracle = summary["engines"]["opensim-kinematic"]
    assert oracle["verdict"] == "pass", oracle
    for quantity, relative in oracle["relative"].items():
        assert relative <= 1e-3 * oracle["tolerance"][quantity], (quantity, relative)
    forces = summary["forces"]["opensim"]
    assert forces["pass"] and forces["relative"] <= 1e-12, forces
    assert summary["verdict"] == "pass" and done.returncode == 0


def test_the_oracle_walks_a_long_step_on_its_branch():
    """Nine samples of the two-input five-bar, 34 degrees apart: from one sample's
    coordinates the assembler landed on the other branch two samples from the end
    (l2 and l3 swapped: 0.25 of the size off); walked in steps of the continuation's
    longest, it stays on the native branch at round-off."""
    from xcheck.engines.opensim.kinematic import run_kinematic
    from xcheck.tolerances import ROUND_OFF

    result = run_kinematic(Kinematics(load_mechanism(DATA / "fivebar.toml")), samples=9)
    assert result.ok
    worst = result.summary.groupby("quantity")["max_abs"].max()
    for quantity in ("position", "angle", "velocity", "acceleration"):
        assert worst[quantity] <= 1e-3 * ROUND_OFF.limit(quantity), (quantity, worst[quantity])


def test_a_crank_stepping_by_the_longest_step_is_not_walked_in_parts(kinematics, monkeypatch):
    """A turn in 180 samples steps by the continuation's longest step itself, each
    step a few ulps either side of it: every sample is one assembly, none split."""
    from xcheck.engines._continuation import MAX_STEP
    from xcheck.engines._contract import with_unit_mass
    from xcheck.engines.opensim import kinematic

    kin = kinematics("slider-crank")
    mech = dataclasses.replace(with_unit_mass(kin.mechanism), springs=(), rotational_springs=(), loads=())
    inputs = kin.reference_inputs()[0] + np.linspace(0.0, 2.0 * math.pi, 181)[:6, None]
    assert np.any(np.diff(inputs[:, 0]) > MAX_STEP)  # past it by round-off: the case in point
    made = []
    assembled = kinematic._assembled
    monkeypatch.setattr(kinematic, "_assembled", lambda *args: made.append(args[4]) or assembled(*args))
    zeros = np.zeros_like(inputs)
    walked = kinematic.assembled_states(
        mech, kin.assemble(), kin.reference_inputs(), (inputs, zeros, zeros), (range(6),)
    )
    assert [j for j, *_ in walked] == list(range(6))
    assert len(made) == 6


def test_the_oracle_says_where_the_assembler_leaves_a_loop_open(kinematics, monkeypatch):
    """With the loops cut as PointConstraints (three rows, one redundant) the assembler
    leaves the four-bar's loop open (measured 0.08 to 0.18 m): the mode fails, saying where."""
    from xcheck.engines.opensim import kinematic, model

    planar = model.build
    monkeypatch.setattr(kinematic, "build", lambda *args, **options: planar(*args, **{**options, "planar_cuts": False}))
    result = kinematic.run_kinematic(kinematics("fourbar"), samples=9)
    assert not result.ok and "OpenSim's assembler left a loop" in result.reason and "crank = " in result.reason


@pytest.mark.parametrize("name", ["fourbar", "fourbar-dynamics", "stephenson-six-bar"])
def test_reactions_and_efforts_are_the_multipliers_to_round_off(kinematics, name):
    """OpenSim's joint reactions (calcReactionOnChildExpressedInGround, the loop cut's
    constraint record) and driver efforts at the window's states. Measured: fourbar at
    most 2.0e-14 N (largest reaction 5.1 N), effort 7.1e-15 N m (1.85); fourbar-dynamics
    2.6e-14 N (18.9 N), 1.9e-15 N m (1.46). The six-bar's cut E joins two bodies that
    hang from the crank, whose frame its record is expressed in (0.09 N off, of 0.12,
    where it was read as the ground's)."""
    from xcheck.dynamics import determined_states, inverse_dynamics

    six_bar = DATA.parents[1] / "docs" / "examples" / "stephenson-six-bar.toml"
    kin = Kinematics(load_mechanism(six_bar)) if name == "stephenson-six-bar" else kinematics(name)
    solution = determined_states(kin, None, 9)
    native = inverse_dynamics(solution)
    forces = engines.engine("opensim").inverse_dynamics(kin, solution=solution)
    assert set(forces.joints) == set(native.joints) and set(forces.drivers) == set(native.drivers)
    for joint, quantities in native.joints.items():
        reaction = quantities["reaction"]
        assert np.abs(forces.joints[joint]["reaction"] - reaction).max() <= 1e-12 * np.abs(reaction).max(), joint
    for driver, quantities in native.drivers.items():
        effort = quantities["effort"]
        assert np.abs(forces.drivers[driver]["effort"] - effort).max() <= 1e-12 * np.abs(effort).max(), driver


def test_reactions_assemble_each_state_once_from_its_native_configuration(kinematics, monkeypatch):
    """The window's states of fourbar-dynamics lie 5 to 6 degrees of crank apart: each is
    assembled once, from its native configuration, not walked to from the state before in
    steps of the continuation's longest (217 assemblies for 73 states)."""
    from xcheck.dynamics import determined_states, inverse_dynamics
    from xcheck.engines._continuation import MAX_STEP
    from xcheck.engines.opensim import kinematic

    kin = kinematics("fourbar-dynamics")
    solution = determined_states(kin, None, 9)
    assert np.min(np.abs(np.diff(solution.inputs[:, 0]))) > MAX_STEP  # every step a long one
    made = []
    assembled = kinematic._assembled
    monkeypatch.setattr(kinematic, "_assembled", lambda *args: made.append(args[4]) or assembled(*args))
    forces = engines.engine("opensim").inverse_dynamics(kin, solution=solution)
    assert len(made) == len(solution.inputs)
    reaction = inverse_dynamics(solution).joints["B"]["reaction"]
    assert np.abs(forces.joints["B"]["reaction"] - reaction).max() <= 1e-12 * np.abs(reaction).max()


def test_reactions_of_a_prismatic_joint_are_not_applicable():
    kin = Kinematics(load_mechanism(DATA / "free-slider-crank-spring.toml"))
    with pytest.raises(NotApplicable, match="prismatic joint: xcheck reads OpenSim's reactions of revolutes only"):
        engines.engine("opensim").inverse_dynamics(kin)


def test_a_gear_pair_is_a_coordinate_coupler():
    """tests/data/planetary-train.toml without its torque, under gravity (the arm a
    pendulum carrying the planet, the sun and the planet coupled to it by their meshes):
    each mesh a CoordinateCouplerConstraint, Merson against the native reference
    (measured 1.9e-12, 7.1e-14 m at 1, 0.5 ms; with the coupler's slope of the wrong
    sign no run starts)."""
    mech = load_mechanism(DATA / "planetary-train.toml")
    kin = Kinematics(dataclasses.replace(mech, loads=(), gravity=(0.0, -9.81)))
    kin.assemble()
    result = run_free("opensim-free", kin, simulate(kin), series=free.FREE_SERIES[:1], timestep=1e-3, rungs=2)
    errors = result.summary["position_error"].to_numpy()
    assert result.ok and (result.summary["status"] == "ok").all()
    assert errors[0] <= 1e-11 and errors[1] < errors[0], errors


def test_driven_gears_are_coordinate_couplers_too():
    """opensim-dynamic on tests/data/geared-fivebar.toml (a five-bar whose two cranks mesh):
    the mesh a CoordinateCouplerConstraint, the crank prescribed (measured 1.1e-8, 6.9e-10,
    4.3e-11 m: order 4.0)."""
    kin = Kinematics(load_mechanism(DATA / "geared-fivebar.toml"))
    kin.assemble()
    result = run_dynamic("opensim-dynamic", kin)
    assert result.ok and (result.summary["status"] == "ok").all()
    errors = result.summary.sort_values("timestep")["position_error"].to_numpy()
    assert errors[0] <= 1e-10 and all(math.log2(errors[i + 1] / errors[i]) >= 3.5 for i in range(2)), errors
