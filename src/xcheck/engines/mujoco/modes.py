"""MuJoCo adapter: the mechanism as an MJCF file, MuJoCo as a kinematic oracle
(mode ``mujoco-kinematic``) and as a simulator (mode ``mujoco-dynamic``).

``export_files`` writes the MJCF file (see :mod:`.mjcf` for its
conventions); both modes compile that text, so they test the file a user gets.
Run ``xcheck export --format mjcf`` to regenerate models/mjcf/.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pandas as pd

from xcheck.engines._driven import left_branch, refined_timesteps
from xcheck.errors import InputError
from xcheck.kinematics import Kinematics, Status
from xcheck.ladder import convergence_study, observed_order
from xcheck.motion import law_states, simulation_window, sweep_span
from xcheck.results import ModeResult, Trajectory, differences

from .dynamic import DEFAULT, TIGHT, Run, simulate
from .free import FREE_SERIES, prepare_free, run_free_once  # noqa: F401 - the mode "mujoco-free"
from .inverse import inverse_forces
from .mjcf import DEFAULT_MASS, carrier_note, joint_coordinates, layout, mass_properties, mjcf_text
from .model import compile_model
from .oracle import Oracle

__all__ = ["export_files", "run_kinematic", "run_dynamic", "relative_error", "inverse_dynamics"]

KINEMATIC_MODE = "mujoco-kinematic"
DYNAMIC_MODE = "mujoco-dynamic"


def export_files(kinematics: Kinematics) -> dict[str, str]:
    """The MJCF file of a mechanism: ``{"NAME.xml": text}``, NAME the mechanism's name.

    Raises
    ------
    ModelError
        If the mechanism cannot be written (its joints have no spanning tree).
    """
    return {f"{kinematics.mechanism.name}.xml": mjcf_text(kinematics)}


def _compile(kinematics: Kinematics, xml: str | None):
    """(model, layout, "") of the mechanism's MJCF text (``xml`` overrides the
    writer's), or (None, None, one-line reason) if it cannot be written or compiled."""
    try:
        return (*compile_model(kinematics, xml), "")
    except ValueError as error:
        return None, None, str(error)


def _sweeps(kinematics: Kinematics, samples: int, branch: str | None, margin: float):
    """Input sweeps, one per driver, the other inputs held at their reference values.

    Each driver sweeps :func:`~xcheck.motion.sweep_span` (one turn of a crank,
    else the feasible range less ``margin`` at each limit, within what its law
    reaches), split at the reference value into a piece going up and one
    going down, so that Newton can walk out from the reference configuration.

    Returns
    -------
    list of (up, down)
        Per driver, two arrays of shape (N_up, k), (N_down, k) (N_down may be 0),
        each ordered away from the reference value.
    """
    ref = kinematics.reference_inputs()
    sweeps = []
    for k in range(len(kinematics.mechanism.drivers)):
        values = np.linspace(*sweep_span(kinematics, k, branch, margin), samples)
        ups, downs = values[values >= ref[k]], values[values < ref[k]][::-1]
        pair = []
        for part in (ups, downs):
            c = np.tile(ref, (part.size, 1))
            c[:, k] = part
            pair.append(c)
        sweeps.append(tuple(pair))
    return sweeps


def run_kinematic(
    kinematics: Kinematics, samples: int = 361, branch: str | None = None, margin: float = 1e-3, xml: str | None = None
) -> ModeResult:
    """MuJoCo as a kinematic oracle over the feasible range of each input.

    Positions by Newton projection on MuJoCo's loop residuals (``efc_pos``)
    and Jacobian (``efc_J``), each sample from the previous one, starting from
    the native assembled configuration at the reference inputs; velocities from
    the constraint Jacobian with the input rates imposed; accelerations with
    the drift term from ``mj_jacDot``. Bodies and points are read from MuJoCo.

    Parameters
    ----------
    kinematics : Kinematics
    samples : int
        Samples per driver's sweep.
    branch : str, optional
        Assembly branch (default: the model file's first).
    margin : float
        Fraction of a bounded input's feasible range kept clear of each limit.
    xml : str, optional
        MJCF text to use instead of the writer's (to test a wrong file).

    Returns
    -------
    ModeResult
        One trajectory: per driver, its sweep in ascending input order; rates
        and accelerations from the drivers' laws at those values.
        ``summary`` is the trajectory's :func:`differences` table.
    """
    mech = kinematics.mechanism
    model, lay, failure = _compile(kinematics, xml)
    if failure:
        return ModeResult(KINEMATIC_MODE, mech.name, False, failure)
    oracle = Oracle(model, mech, lay)
    ref = kinematics.reference_inputs()
    start = joint_coordinates(mech, lay, kinematics.assemble(branch))
    parts = []  # (inputs, projection arrays) in ascending input order per driver
    for up, down in _sweeps(kinematics, samples, branch, margin):
        for c, order in ((down, slice(None, None, -1)), (up, slice(None))):
            if c.size:
                p = oracle.project(start, ref, c)
                if p.stopped is not None:
                    return ModeResult(
                        KINEMATIC_MODE,
                        mech.name,
                        False,
                        f"MuJoCo's continuation left the assembly branch: it {p.reason}",
                    )
                parts.append((c[order], p.qpos[order], p.residual[order], p.converged[order]))
    inputs, q, residual, converged = (np.concatenate(arrays) for arrays in zip(*parts))
    if not converged.all():
        i = int(np.argmin(converged))
        where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(mech.drivers, inputs[i]))
        return ModeResult(
            KINEMATIC_MODE,
            mech.name,
            False,
            f"MuJoCo's Newton projection did not close the loops at {where} (violation {residual[i]:.3g} m)",
        )
    rates, accelerations, reached = law_states(mech, inputs)
    stand_ins = int((~reached).sum())
    qvel = np.array([oracle.velocity(q[i], rates[i]) for i in range(len(q))])
    qacc = np.array([oracle.acceleration(q[i], qvel[i], accelerations[i]) for i in range(len(q))])
    bodies, points = oracle.states(q, qvel, qacc)
    notes = (
        "Positions: Newton projection on MuJoCo's equality rows (efc_pos, efc_J, least squares) from the "
        "previous sample, predicted along MuJoCo's tangent dq/dc, in steps halved while the correction is "
        "large or the determinant of the system changes sign; velocities: efc_J with the input rates "
        "imposed; accelerations: the same with the drift -Jdot qd from mj_jacDot at both sites of each "
        "connect. Bodies from xpos/xmat, mj_jac, mj_jacDot; points from their sites."
    )
    if stand_ins:
        notes += (
            f" At {stand_ins} input value(s) a driver's law never passes (a driver held at a reference "
            "value its law never reaches), its rate and acceleration are 0."
        )
    trajectory = Trajectory(
        source=KINEMATIC_MODE,
        inputs=inputs,
        input_rates=rates,
        input_accelerations=accelerations,
        bodies=bodies,
        points=points,
        settings={
            "samples": samples,
            "margin": margin,
            "branch": branch or kinematics.branches[0],
            "jacobian": "sparse" if mujoco.mj_isSparse(model) else "dense",
        },
        diagnostics={"constraint_violation": residual},
        notes=notes,
    )
    return ModeResult(KINEMATIC_MODE, mech.name, True, "", [trajectory], differences(kinematics, trajectory, branch))


def _simulated_duration(kinematics: Kinematics, branch: str | None, duration: float | None):
    """(duration in s, reason for failing or "") of a dynamic run: the simulation
    window's, or ``duration`` if the drivers' motion stays feasible that long."""
    try:
        window = simulation_window(kinematics, branch)
    except InputError as error:
        return 0.0, str(error)
    if duration is None or duration <= window.duration:
        return (window.duration if duration is None else duration), ""
    if window.reason == "feasible range":
        inputs = window.inputs(kinematics, np.array([window.duration]))[0][0]
        where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(kinematics.mechanism.drivers, inputs))
        return duration, (
            f"the driven motion leaves the feasible range (2% margin) at t = {window.duration:.6g} s "
            f"({where}); {duration:.6g} s were asked for"
        )
    return duration, (
        f"expected a duration up to the simulation window ({window.duration:.6g} s, "
        f"{window.reason}), found {duration:.6g} s"
    )


def _outside_range(kinematics: Kinematics, branch: str | None, run: Run, dofs: np.ndarray) -> str:
    """Why the realised inputs of a run left their feasible ranges, or ""."""
    for k, driver in enumerate(kinematics.mechanism.drivers):
        rng = kinematics.input_range(k, branch)
        values = run.qpos[:, dofs[k]]
        outside = np.flatnonzero([not rng.contains(float(v)) for v in values])
        if outside.size:
            i = int(outside[0])
            return (
                f"the input {driver.name} reached {values[i]:.6g} at t = {run.times[i]:.6g} s, outside its "
                f"feasible range {rng.low} .. {rng.high}"
            )
    return ""


def _summary_row(kinematics, branch, run: Run, trajectory, oracle_trajectory, violation, tracking, status: str) -> dict:
    """One row of the dynamic mode's summary (errors left empty for a failed run,
    the oracle's acceleration error empty where it was not computed)."""
    row = {
        "setting": run.settings["setting"],
        "integrator": run.settings["integrator"],
        "timestep": run.settings["timestep"],
        "steps": run.steps,
        "status": status or "ok",
        "position_error": np.nan,
        "angle_error": np.nan,
        "velocity_error": np.nan,
        "acceleration_error": np.nan,
        "acceleration_error_oracle": np.nan,
        "observed_order": np.nan,
        "constraint_violation": float(np.max(violation)) if violation.size else np.nan,
        "input_tracking": float(np.max(tracking)) if tracking.size else np.nan,
        **run.columns,
    }
    if status:
        return row

    table = differences(kinematics, trajectory, branch)
    row.update(
        position_error=relative_error(table, "position", absolute=True),
        angle_error=relative_error(table, "angle", absolute=True),
        velocity_error=max(relative_error(table, "velocity"), relative_error(table, "omega")),
        acceleration_error=max(relative_error(table, "acceleration"), relative_error(table, "alpha")),
    )
    if oracle_trajectory is not None:
        oracle = differences(kinematics, oracle_trajectory, branch)
        row["acceleration_error_oracle"] = max(relative_error(oracle, "acceleration"), relative_error(oracle, "alpha"))
    return row


def relative_error(table: pd.DataFrame, quantity: str, absolute: bool = False) -> float:
    """The worst error of one quantity over every body or point of a :func:`differences` table.

    Relative errors are taken against the largest magnitude of that quantity in
    the whole mechanism (e.g. the fastest point's speed), not per row: a body
    whose quantity is zero (a frame origin at a fixed pivot) has a round-off
    scale that would make its own ``max_rel`` meaningless.

    Returns
    -------
    float
        ``max(max_abs)`` in SI units if ``absolute``, else ``max(max_abs) /
        max(scale)`` (``max(max_abs)`` itself where every scale is zero);
        0 when the table has no row of that quantity.
    """
    rows = table[table.quantity == quantity]
    if rows.empty:
        return 0.0
    error, scale = float(rows.max_abs.max()), float(rows.scale.max())
    return error if absolute or scale == 0.0 else error / scale


def run_dynamic(
    kinematics: Kinematics,
    branch: str | None = None,
    samples: int = 101,
    default_timesteps=(2e-3, 1e-3, 5e-4),
    tight_timesteps=(1e-3, 5e-4, 2.5e-4, 1.25e-4),
    duration: float | None = None,
    violation_bound: float = 0.05,
    xml: str | None = None,
    simulator=simulate,
    mode: str = DYNAMIC_MODE,
    title: str = "MuJoCo",
    refine: int = 0,
) -> ModeResult:
    """MuJoCo simulating the mechanism with its inputs driven by the file's servos.

    Every run starts from the exact state at t = 0 (native configuration,
    MuJoCo's velocity solve) and integrates over the simulation window
    (:func:`~xcheck.motion.simulation_window`) with the servos' controls
    following the drivers' laws. Sampled states are compared with the native
    solution at the inputs MuJoCo realised (qpos, qvel, qacc of the input joints).

    Parameters
    ----------
    kinematics : Kinematics
    branch : str, optional
    samples : int
        States sampled per run, evenly in time.
    default_timesteps, tight_timesteps : sequence of float
        Time steps (s) run with the :data:`DEFAULT` (MuJoCo's defaults) and
        :data:`TIGHT` settings.
    duration : float, optional
        Simulated time (s); default the simulation window. Longer than a
        window cut short by the feasible range fails.
    violation_bound : float
        A run whose loop violation exceeds this fraction of the mechanism's
        size counts as diverged.
    xml : str, optional
        MJCF text to use instead of the writer's.
    simulator : callable
        What integrates one run: :func:`~xcheck.engines.mujoco.dynamic.simulate`
        (MuJoCo's C library, default) or another implementation of MuJoCo with
        its signature returning a :class:`~xcheck.engines.mujoco.dynamic.Run`
        (MJX: :class:`xcheck.engines.mjx.dynamic.Simulator`); the run's
        ``columns`` join its summary row.
    mode, title : str
        The mode's name (the result's and the trajectories' source) and the
        engine's title (in messages and notes).
    refine : int
        k > 0: only the tight setting at its smallest time step / 2^k
        (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        ``trajectories[0]``: the tight setting at its smallest time step,
        accelerations from qacc (the comparison's); ``trajectories[1]``: the
        same states with the oracle's accelerations; then every other run.
        ``summary``: one row per run: setting, integrator, timestep (s),
        steps, status ("ok" or why it failed), position_error (m, worst
        body origin or point), angle_error (rad), velocity_error and
        acceleration_error (worst, relative to the mechanism's largest value
        of the quantity: :func:`relative_error`), acceleration_error_oracle (the
        compared run only; empty elsewhere), observed_order (of the position
        error against the previous time step of the same setting),
        constraint_violation (m, worst loop), input_tracking (worst
        |input - law|, rad or m). Errors are empty for a failed run.
    """
    mech = kinematics.mechanism
    if refine:
        default_timesteps, tight_timesteps = (), refined_timesteps(min(tight_timesteps), refine)
    model, lay, failure = _compile(kinematics, xml)
    if failure:
        return ModeResult(mode, mech.name, False, failure)
    duration, failure = _simulated_duration(kinematics, branch, duration)
    if failure:
        return ModeResult(mode, mech.name, False, failure)
    oracle = Oracle(model, mech, lay)
    c0, cd0 = (np.array([float(d.law.at_time(0.0)[i]) for d in mech.drivers]) for i in (0, 1))
    native = kinematics.solve(c0[None], cd0[None], branch=branch)
    if native.status[0] > Status.NEAR_SINGULAR:
        return ModeResult(
            mode,
            mech.name,
            False,
            f"the mechanism has no determined state at t = 0 ({Status(native.status[0]).message})",
        )
    start = oracle.project(joint_coordinates(mech, lay, native.q[0]), c0, c0[None])
    qpos0, qvel0 = start.qpos[0], oracle.velocity(start.qpos[0], cd0)
    dofs = oracle.input_dofs

    plan = [(DEFAULT, dt) for dt in default_timesteps] + [(TIGHT, dt) for dt in tight_timesteps]
    if not plan:
        return ModeResult(mode, mech.name, False, "expected at least one time step to run, found none")
    primary = (TIGHT, min(tight_timesteps)) if tight_timesteps else plan[-1]
    rows, primary_failure = [], ""
    trajectories: list[Trajectory] = []
    for setting, dt in plan:
        run = simulator(copy.deepcopy(model), mech, lay, setting, dt, duration, qpos0, qvel0, samples)
        violation = np.array([oracle.violation(q) for q in run.qpos])
        tracking = np.abs(run.qpos[:, dofs] - run.law)
        status = run.failure
        if not status and violation.size and violation.max() > violation_bound * mech.size:
            i = int(np.argmax(violation > violation_bound * mech.size))
            status = (
                f"diverged: loop violation {violation[i]:.3g} m > {violation_bound:g} x size at "
                f"t = {run.times[i]:.6g} s"
            )
        status = status or _outside_range(kinematics, branch, run, dofs)
        is_primary = (setting, dt) == primary
        trajectory: Trajectory | None = None
        oracle_trajectory: Trajectory | None = None
        if not status:
            trajectory, oracle_trajectory = _run_trajectories(
                oracle, run, setting, duration, violation, tracking, with_oracle=is_primary, mode=mode, title=title
            )
            status = left_branch(kinematics, branch, trajectory, title)
            if status:
                trajectory = oracle_trajectory = None
        rows.append(_summary_row(kinematics, branch, run, trajectory, oracle_trajectory, violation, tracking, status))
        if is_primary and status:
            primary_failure = f"{setting.name} {setting.integrator} dt = {dt:g} s: {status}"
        elif is_primary:
            assert trajectory is not None and oracle_trajectory is not None  # no failure, with_oracle
            trajectories[:0] = [trajectory, oracle_trajectory]
        elif trajectory is not None:
            trajectories.append(trajectory)
    summary = pd.DataFrame(rows)
    for name in summary.setting.unique():  # an exact zero error has no order
        group = summary[summary.setting == name]
        errors, steps = group.position_error.to_numpy(), group.timestep.to_numpy()
        summary.loc[group.index[1:], "observed_order"] = [
            observed_order(errors[i - 1], errors[i], steps[i - 1], steps[i]) for i in range(1, len(errors))
        ]
    study = convergence_study(
        summary.setting + " " + summary.integrator, summary.timestep, summary.position_error, summary.status
    )
    if primary_failure:
        return ModeResult(mode, mech.name, False, primary_failure, trajectories, summary, study)
    return ModeResult(mode, mech.name, True, "", trajectories, summary, study)


def _run_trajectories(
    oracle: Oracle,
    run: Run,
    setting,
    duration: float,
    violation: np.ndarray,
    tracking: np.ndarray,
    with_oracle: bool,
    mode: str = DYNAMIC_MODE,
    title: str = "MuJoCo",
) -> tuple[Trajectory, Trajectory | None]:
    """The trajectory of a run (accelerations from qacc) and, if asked, the same
    states with the kinematic oracle's accelerations (else None)."""
    dofs = oracle.input_dofs
    inputs, rates, accelerations = run.qpos[:, dofs], run.qvel[:, dofs], run.qacc[:, dofs]
    series = f"{run.settings['setting']} {run.settings['integrator']}"
    settings = {
        **run.settings,
        "series": series,
        "accelerations": "qacc",
        "duration": duration,
        "samples": len(run.times),
        "drive": "position servo (ctrl = law value) + velocity servo (ctrl = law rate), zero-order hold",
    }
    diagnostics = {"constraint_violation": violation, "input_tracking": tracking}
    drive = (
        f"{setting.name} setting ({setting.integrator}, dt = {run.settings['timestep']:g} s). Inputs driven "
        "by the file's servos, controls = the laws' value and rate at each step's start; the native solver "
        f"is evaluated at the inputs as {title} realised them (input joints' qpos, qvel, qacc). "
    )
    defaults = [name for name, props in mass_properties(oracle.mechanism).items() if props.default]
    if defaults:
        drive += (
            f"Default mass properties (none in the model) for {', '.join(defaults)}: {DEFAULT_MASS:g} kg at "
            "the centroid of the body's points, a slender bar's inertia plus a small disc term. "
        )
    note = carrier_note(oracle.mechanism, layout(oracle.mechanism).topology)
    drive += f"{note} " if note else ""
    bodies, points = oracle.states(run.qpos, run.qvel, run.qacc)
    trajectory = Trajectory(
        mode,
        inputs,
        rates,
        accelerations,
        bodies,
        points,
        run.times,
        settings,
        diagnostics,
        drive + f"Accelerations: qacc from {title}'s forward dynamics at each sampled state (what "
        f"the integrator uses, including {title}'s constraint stabilisation); the comparison "
        "uses these.",
    )
    if not with_oracle:
        return trajectory, None
    qacc = np.array([oracle.acceleration(q, v, a) for q, v, a in zip(run.qpos, run.qvel, accelerations)])
    bodies, points = oracle.states(run.qpos, run.qvel, qacc)
    return trajectory, Trajectory(
        mode,
        inputs,
        rates,
        accelerations,
        bodies,
        points,
        run.times,
        {**settings, "series": f"{series}, oracle accelerations", "accelerations": "oracle at simulated state"},
        diagnostics,
        drive + "Accelerations: the kinematic oracle at the simulated states (J qdd = -Jdot qd with the input "
        "joints' qacc imposed), not qacc; shown beside the comparison, which uses qacc.",
    )


def inverse_dynamics(
    kinematics: Kinematics, branch: str | None = None, samples: int | None = None, solution=None, xml: str | None = None
):
    """Joint reactions and input efforts from MuJoCo at the native states of the
    simulation window (see :mod:`.inverse` for how).

    Parameters
    ----------
    kinematics : Kinematics
    branch : str, optional
    samples : int, optional
        States over the window (default :data:`xcheck.dynamics.WINDOW_SAMPLES`).
    solution : Solution, optional
        Native states to use instead of the window's.
    xml : str, optional
        MJCF text to use instead of the writer's.

    Returns
    -------
    xcheck.dynamics.Forces

    Raises
    ------
    ValueError
        If the MJCF cannot be written or compiled, or a state does not close
        MuJoCo's loops (the reason in one line).
    """
    model, lay, failure = _compile(kinematics, xml)
    if failure:
        raise ValueError(failure)
    return inverse_forces(kinematics, model, lay, branch, samples, solution)
