"""Newton in driven dynamics (mode ``newton-dynamic``): the model of
:func:`.model.build` with the body each driver turns or slides made one of
Newton's kinematic bodies (``is_kinematic``: a user-prescribed body that does not
respond to forces, Newton's only exact way to prescribe a motion), stepped by
each of Newton's solvers that takes a loop joint over
:func:`xcheck.motion.simulation_window` from the native state at t = 0, and
compared with the native solution at the inputs Newton realised (its kinematic
joints' coordinates and rates, read back from the bodies' poses by
``newton.eval_ik``).

Before every step the driven joints' coordinates and rates are set to the laws'
at the step's end and the kinematic bodies placed there (``newton.eval_fk`` on
them alone); the solver moves the other bodies to the step's end around them.
Newton allows only a body hung from the ground to be kinematic, so a driver
between two moving bodies is not applicable. The drivers prescribe the motion,
so masses and forces only weigh the solver: a body without mass data gets 1 kg
and m size^2 / 12 (:func:`xcheck.engines.with_unit_mass`), and springs and
loads, which the Newton model does not hold, are left out (they change the
drivers' efforts, not the motion). Newton's accelerations are not compared.

The series, each at Newton's defaults on the CPU (warp, float32), are those of
:mod:`.free`: ``mujoco`` (compared), ``xpbd``, ``semi-implicit`` and
``featherstone`` (it ignores loop joints, a finding: its runs come apart).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.engines._frames import (
    driven_run,
    empty_states,
    loop_gap,
    record_moving_states,
    stepped_samples,
    world_point,
)
from xcheck.engines._tree import tree_frames
from xcheck.kinematics import Kinematics
from xcheck.ladder import DrivenProblem, Run, Rung, Series
from xcheck.model import GROUND, Mechanism

from .model import NewtonModel, build, newton, solver

__all__ = ["MODE", "STEPS_PER_SAMPLE", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]

MODE = "newton-dynamic"
#: time steps per compared sample of each series' coarsest run, and its runs (doubling the steps)
STEPS_PER_SAMPLE = 25
RUNGS = 3
#: the body quantities Newton's runs give (:func:`xcheck.engines._frames.empty_states`)
QUANTITIES = ("position", "angle", "velocity", "omega")
#: Newton's solvers in this mode (:func:`.model.solver`), the compared one first
SOLVERS = (
    ("xpbd", "SolverXPBD, kinematic drivers, float32"),
    ("mujoco", "SolverMuJoCo (MuJoCo C), kinematic drivers, float32"),
    ("semi-implicit", "SolverSemiImplicit, kinematic drivers, float32"),
    ("featherstone", "SolverFeatherstone, kinematic drivers, float32"),
)


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: each solver of :data:`SOLVERS` at :data:`STEPS_PER_SAMPLE` steps per
    sample, doubling over :data:`RUNGS` runs."""
    dt = problem.interval / STEPS_PER_SAMPLE
    return tuple(Series(key, integrator, key, timestep=dt, rungs=RUNGS) for key, integrator in SOLVERS)


def driven_bodies(mech: Mechanism, q: np.ndarray) -> frozenset[str]:
    """The bodies the drivers move, to be Newton's kinematic bodies: each driven tree
    joint's child.

    Raises
    ------
    NotApplicable
        Where a driven joint joins two moving bodies: Newton prescribes a motion only
        through kinematic bodies, and only a body hung from the ground can be one.
    """
    tree = tree_frames(mech, q, "Newton")
    frames = {joint.name: joint for joint in tree.joints}
    bodies = set()
    for driver in mech.drivers:
        joint = frames[driver.joint]
        if joint.parent != GROUND:
            raise NotApplicable(
                f"the driver of joint {driver.joint!r} joins two moving bodies: Newton prescribes a motion only "
                "through kinematic bodies, and only a body hung from the ground can be one"
            )
        bodies.add(joint.child)
    return frozenset(bodies)


def prepare_dynamic(problem: DrivenProblem) -> Kinematics:
    """The mechanism with unit masses where it has none and without springs and loads
    (the drivers prescribe the motion), Newton imported before the first run's clock starts.

    Raises
    ------
    NotApplicable
        What :func:`driven_bodies` and :func:`.model.build` cannot hold.
    """
    mech = problem.kinematics.mechanism
    driven_bodies(mech, problem.start.q[0])
    newton()
    return Kinematics(dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=()))


def _states(built: NewtonModel, mech: Mechanism, state, previous: dict | None) -> dict[str, tuple]:
    """Per moving body: origin (2,) m, angle rad (continuous from ``previous``), origin
    velocity (2,) m/s, rate rad/s. Newton's body twist is the centre of mass's
    velocity and the rate: the origin's is v_com - omega x (R com)."""
    frames = built.frames(state, previous)
    twists = state.body_qd.numpy()
    out = {}
    for name, link in built.links.items():
        origin, phi = frames[name]
        com = mech.body(name).com
        arm = np.zeros(2) if com is None else world_point(frames, name, np.asarray(com, dtype=float)) - origin
        omega = float(twists[link][5])
        velocity = np.asarray(twists[link][:2], dtype=float) - omega * np.array([-arm[1], arm[0]])
        out[name] = (origin, phi, velocity, omega)
    return out


def run_dynamic_once(massive: Kinematics, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): before every
    step the kinematic bodies set to the laws at the step's end, then the solver's step."""
    module, wp = newton()
    mech = problem.kinematics.mechanism
    dt, per, samples, times = rung.timestep, rung.counts[0], problem.samples, problem.times
    q0, qd0 = problem.start.q[0], problem.start.qd[0]
    built = build(massive.mechanism, q0, qd0, driven_bodies(mech, q0))
    model = built.model
    drivers = built.tree.driver_signs(mech)
    joints = [built.joints[name] for name, _ in drivers]
    q_index = model.joint_q_start.numpy()[joints]
    qd_index = model.joint_qd_start.numpy()[joints]
    start = np.array([float(d.law.at_time(0.0)[0]) for d in mech.drivers])
    signs = np.array([sign for _, sign in drivers])
    state, next_state, control = model.state(), model.state(), model.control()
    state.joint_q.zero_()
    state.joint_qd.assign(built.rates)
    module.eval_fk(model, state.joint_q, state.joint_qd, state)
    stepper = solver(rung.series.options, model)
    read_q = wp.zeros(model.joint_coord_count, dtype=wp.float32, device="cpu")
    read_qd = wp.zeros(model.joint_dof_count, dtype=wp.float32, device="cpu")
    bodies, points, inputs, rates, gaps = empty_states(mech, samples, QUANTITIES)
    previous: dict | None = None

    def record(j: int) -> str:
        nonlocal previous
        states = _states(built, mech, state, previous)
        if not record_moving_states(mech, states, (bodies, points), j):
            return f"went non-finite at t = {times[j]:.6g} s"
        previous = {name: s[:2] for name, s in states.items()}
        module.eval_ik(model, state, read_q, read_qd)
        inputs[j] = start + signs * read_q.numpy()[q_index]
        rates[j] = signs * read_qd.numpy()[qd_index]
        gaps[j] = loop_gap(states, built.tree.cuts)
        return problem.came_apart(float(times[j]), float(gaps[j]))

    def step(n: int) -> None:
        nonlocal state, next_state
        laws = [d.law.at_time((n + 1) * dt) for d in mech.drivers]
        q, qd = state.joint_q.numpy(), state.joint_qd.numpy()
        q[q_index] = signs * (np.array([float(law[0]) for law in laws]) - start)
        qd[qd_index] = signs * np.array([float(law[1]) for law in laws])
        state.joint_q.assign(q)
        state.joint_qd.assign(qd)
        module.eval_fk(model, state.joint_q, state.joint_qd, state, body_flag_filter=module.BodyFlags.KINEMATIC)
        state.clear_forces()
        stepper.step(state, next_state, control, None, dt)
        state, next_state = next_state, state

    failure, reached = stepped_samples(samples, per, step, record)
    integrator = rung.series.integrator
    settings = {"integrator": integrator, "timestep": dt, "series": rung.series.key, "steps_per_sample": per}
    notes = (
        f"Newton driven dynamics, {integrator}, dt = {dt:.4g} s; inputs as Newton realised them "
        "(input accelerations: the motion laws'; Newton's are not compared)."
    )
    return driven_run(MODE, mech, times, (bodies, points, inputs, rates, gaps), reached, failure, settings, notes)
