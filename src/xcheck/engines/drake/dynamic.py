"""Drake in driven dynamics (mode ``drake-dynamic``): the plant of
:func:`.model.build` with a PD-controlled ``JointActuator`` on each driven joint
(always a tree joint: the spanning tree takes the driven joints first), its
desired state (the drivers' motion laws at the end of each step) on the
plant's desired-state input port, stepped by the discrete SAP solver over
:func:`xcheck.motion.simulation_window` from the native state at t = 0, and
compared with the native solution at the inputs Drake realised (its joint
coordinates and rates).

SAP treats the PD controller implicitly (the force -Kp (q - qd) - Kd (v - vd)
at the step's end state), so a stiff gain is stable: :func:`gains` scales it
with the mechanism's inertia and the step (``Kp = STIFFNESS M / dt^2``,
``Kd = Kp dt``). Above ``Kp dt^2 / M`` = 1e4 the gain no longer matters: the
realised inputs are the same to four digits up to 1e10 (SAP bounds the
stiffness it applies by the step; measured, the cause inside Drake not
traced), and the lag left is a truncation of order 2 (far below the loops'
opening on the four-bars; on an open chain, whose positions at the realised
inputs are exact, it is the one error: 2.3e-7 rad at the finest step on
two-body-arm; see :func:`run_dynamic_once`).

The drivers prescribe the motion, so masses only weigh the solver: a body
without mass data gets 1 kg and m size^2 / 12 about its frame origin
(:func:`xcheck.engines.with_unit_mass`). Drake's discrete plant gives
positions and velocities; its accelerations (the velocity change over a step)
are not compared. What the free mode cannot hold (a pin-in-slot, a loop cut
at a prismatic joint, ...) is :class:`~xcheck.engines.NotApplicable` here too.

Measured: see :func:`run_dynamic_once`; the gain sweep: ``benchmarks/drake_pd_gain.py``.
"""

from __future__ import annotations

import numpy as np

from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import driven_run, empty_states, loop_gap, record_moving_states, stepped_samples
from xcheck.kinematics import Kinematics
from xcheck.ladder import DRIVEN_SAMPLES, DrivenProblem, Run, Rung, Series, came_apart
from xcheck.motion import SimulationWindow
from xcheck.topology import spanning_tree

from .model import DrakeModel, apply_loads, build, drake, refuse, set_state

__all__ = [
    "MODE",
    "STIFFNESS",
    "STEPS_PER_SAMPLE",
    "gains",
    "simulate",
    "dynamic_series",
    "prepare_dynamic",
    "run_dynamic_once",
]

MODE = "drake-dynamic"
INTEGRATOR = "discrete SAP, implicit PD"
#: Kp dt^2 / M: the PD gain against the driven joint's inertia and the step
STIFFNESS = 1e6
#: time steps per compared sample of the ladder's coarsest run, and its runs (doubling the steps)
STEPS_PER_SAMPLE = 25
RUNGS = 3

#: the body quantities Drake gives (:func:`xcheck.engines._frames.empty_states`)
ERRORS = ("position", "angle", "velocity", "omega")


def gains(kinematics: Kinematics, dt: float, stiffness: float = STIFFNESS, damping: float = 1.0) -> dict:
    """Per driven joint its PD gains (Kp, Kd): ``Kp = stiffness M / dt^2`` and
    ``Kd = damping Kp dt``, M the mechanism's total mass times size^2 (kg m^2) on a
    revolute, its total mass (kg) on a prismatic joint; SI (N m/rad, N m s/rad or
    N/m, N s/m)."""
    mech = kinematics.mechanism
    mass = sum(float(b.mass or 0.0) for b in mech.moving_bodies)
    out = {}
    for driver in mech.drivers:
        inertia = mass * mech.size**2 if driver.quantity == "angle" else mass
        kp = stiffness * inertia / dt**2
        out[driver.joint] = (kp, damping * kp * dt)
    return out


def _signs(kinematics: Kinematics) -> list[tuple[str, float]]:
    """Per driver: the tree child of its joint and the sign of the joint coordinate
    against the driver's value (-1 where the tree hangs body_a from body_b)."""
    mech = kinematics.mechanism
    tree = {tj.joint.name: tj for tj in spanning_tree(mech).tree}
    out = []
    for driver in mech.drivers:
        tj = tree[driver.joint]
        flipped = tj.joint.tree_axes == ("hinge",) and tj.child != tj.joint.body_b  # a revolute against its order
        out.append((tj.child, -1.0 if flipped else 1.0))
    return out


def _coordinate(model: DrakeModel, child: str) -> tuple[float, float]:
    """A tree joint's coordinate and rate (rad, rad/s or m, m/s)."""
    joint, context = model.joints[child], model.context
    if joint.type_name() == "revolute":
        return float(joint.get_angle(context)), float(joint.get_angular_rate(context))
    return float(joint.get_translation(context)), float(joint.get_translation_rate(context))


def simulate(
    kinematics: Kinematics,
    massive: Kinematics,
    window: SimulationWindow,
    q0: np.ndarray,
    qd0: np.ndarray,
    per: int,
    samples: int = DRIVEN_SAMPLES,
    pd: dict | None = None,
) -> Run:
    """One run of ``samples`` x ``per`` steps over the window from the state (q0, qd0),
    sampled every ``per`` steps (:class:`~xcheck.ladder.Run`, its failure where it went
    non-finite or came apart). ``pd``: the gains per driven joint (:func:`gains` at the
    run's step without it)."""
    mech = kinematics.mechanism
    dt = window.duration / samples / per  # the ladder's step (DrivenProblem.rung)
    pd = gains(massive, dt) if pd is None else pd
    bodies, points, inputs, rates, gaps = empty_states(mech, samples, ERRORS)
    model = build(massive, dt, pd)
    set_state(model, massive, q0, qd0)
    from pydrake.systems.analysis import Simulator

    simulator = Simulator(model.plant, model.context)
    model.context = simulator.get_mutable_context()
    plant = model.plant
    # the desired state: the actuators' joints in actuator order (the drivers' order here)
    by_joint = {mech.drivers[k].joint: k for k in range(len(mech.drivers))}
    order = [by_joint[plant.get_joint_actuator(i).joint().name()] for i in plant.GetJointActuatorIndices()]
    drivers = _signs(kinematics)
    signs = np.array([drivers[k][1] for k in order])
    port = plant.get_desired_state_input_port(plant.GetModelInstanceByName("DefaultModelInstance"))
    plant.get_actuation_input_port().FixValue(model.context, np.zeros(len(order)))
    timed = any(load.law is not None for load in mech.loads)
    apply_loads(model, 0.0)
    times = window.times(samples + 1)[1:]

    def record(j: int) -> str:
        frames = model.frames()
        if not record_moving_states(mech, frames, (bodies, points), j):
            return f"went non-finite at t = {times[j]:.6g} s"
        for k, (child, sign) in enumerate(drivers):
            value, rate = _coordinate(model, child)
            inputs[j, k], rates[j, k] = sign * value, sign * rate
        gaps[j] = loop_gap(frames, model.cuts)
        return came_apart(float(times[j]), gaps[j], mech.size)

    def step(n: int) -> None:
        t_next = (n + 1) * dt
        # Drake's discrete update at t = n dt samples its inputs there and takes the state to
        # (n + 1) dt; SAP's PD acts on that end state, so its target is the law there
        laws = [mech.drivers[k].law.at_time(t_next) for k in order]
        desired = np.concatenate([signs * [float(v[0]) for v in laws], signs * [float(v[1]) for v in laws]])
        port.FixValue(model.context, desired)
        if timed:
            apply_loads(model, n * dt)
        simulator.AdvanceTo((n + 0.5) * dt)

    failure, reached = stepped_samples(samples, per, step, record)
    settings = {"integrator": INTEGRATOR, "timestep": dt, "series": "default", "steps_per_sample": per}
    notes = (
        f"Drake driven dynamics, {INTEGRATOR}, dt = {dt:.4g} s; inputs as Drake realised them "
        "(input accelerations: the motion laws'; Drake's are not compared)."
    )
    states = (bodies, points, inputs, rates, gaps)
    return driven_run(MODE, mech, times, states, reached, failure, settings, notes)


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: the default plant at :data:`STEPS_PER_SAMPLE` steps per sample, doubling."""
    return (Series("default", INTEGRATOR, timestep=problem.interval / STEPS_PER_SAMPLE, rungs=RUNGS),)


def prepare_dynamic(problem: DrivenProblem) -> Kinematics:
    """The mechanism with unit masses where it has none (:func:`xcheck.engines.with_unit_mass`),
    pydrake imported before the first run's clock starts.

    Raises
    ------
    NotApplicable
        What :func:`.model.build` cannot hold (:func:`.model.refuse`).
    """
    mech = problem.kinematics.mechanism
    refuse(mech, spanning_tree(mech))
    drake()
    return Kinematics(with_unit_mass(mech))


def run_dynamic_once(massive: Kinematics, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`).

    Notes
    -----
    Measured with pydrake 1.51.1 (``python benchmarks/drake_pd_gain.py
    models/NAME.toml``, 2 shared cores), at 25, 50, 100 steps per sample, 40
    samples over the window: position error (m, at the inputs Drake realised),
    its orders, the lag behind the law (rad, or m on a slide), the velocity
    error (relative), the loops' largest gap (m); 0.3, 0.6, 1.1 CPU s a run.

    ============ ========================= ========== =================== ================ ================
    model        position error            orders     lag                 velocity         loop gap
    ============ ========================= ========== =================== ================ ================
    fourbar      7.18e-6, 1.82e-6, 4.58e-7 1.98, 1.99 5.2e-9 .. 3.5e-10   3.0e-3 .. 7.3e-4 3.0e-6 .. 1.9e-7
    slider-crank 5.10e-6, 1.27e-6, 3.19e-7 2.00, 2.00 6.9e-9 .. 4.3e-10   3.8e-3 .. 9.4e-4 5.1e-6 .. 3.2e-7
    fourbar-dyn. 8.21e-6, 2.05e-6, 5.12e-7 2.00, 2.00 5.9e-9 .. 3.7e-10   4.4e-3 .. 1.1e-3 6.4e-6 .. 4.0e-7
    task-2-1     5.80e-5, 1.50e-5, 3.79e-6 1.96, 1.98 1.9e-8 .. 1.4e-9    1.2e-2 .. 2.7e-3 2.1e-5 .. 1.4e-6
    task-2-4     3.39e-5, 8.51e-6, 2.13e-6 1.99, 2.00 4.1e-9 .. 2.5e-10   7.9e-3 .. 2.0e-3 2.3e-5 .. 1.4e-6
    task-2-7     1.16e-5, 2.95e-6, 7.46e-7 1.97, 1.98 2.7e-9 .. 1.8e-10 m 7.4e-3 .. 1.8e-3 2.0e-6 .. 1.3e-7
    two-body-arm 0 (open chain: exact)     -          3.6e-6 .. 2.3e-7    2e-16            0
    ============ ========================= ========== =================== ================ ================

    Angles fall at the positions' orders, rates at order 1.00-1.03 (the
    discrete step's velocities). The same runs at ``Kp dt^2 / M`` = 1e4, 1e8
    and 1e10 give these errors and lags to four digits; at 1 the errors are
    the same and the lag is the gain's (fourbar 4.0e-6 .. 2.7e-7 rad, still
    order 2; on two-body-arm it is smaller than the plateau's, 1.9e-7 against
    2.3e-7 rad at the finest step). Critical damping (``Kd = 2 sqrt(Kp M)``, ``--critical``) leaves
    the positions unchanged (fourbar lag 2.7e-9 .. 1.7e-10 rad). The models
    with a pin-in-slot (task-2-2, -3, -5, -6) are not applicable.
    """
    start = problem.start
    per = rung.counts[0]
    return simulate(problem.kinematics, massive, problem.window, start.q[0], start.qd[0], per, problem.samples)
