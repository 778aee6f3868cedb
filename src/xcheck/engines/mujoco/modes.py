"""MuJoCo adapter: the mechanism as an MJCF file, MuJoCo as a kinematic oracle
(mode ``mujoco-kinematic``) and as a simulator (mode ``mujoco-dynamic``: its series,
:func:`dynamic_series`, and one run, :func:`run_dynamic_once`, on the ladder of
:class:`xcheck.ladder.DrivenLadder`).

``export_files`` writes the MJCF file (see :mod:`.mjcf` for its
conventions); both modes compile that text, so they test the file a user gets.
Run ``xcheck export --format mjcf`` to regenerate models/mjcf/.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
import pandas as pd

from xcheck.kinematics import Kinematics
from xcheck.ladder import DrivenProblem, Run, Rung, Series
from xcheck.motion import law_states, sweep_span
from xcheck.results import ModeResult, Trajectory, differences

from .dynamic import DEFAULT, TIGHT, Setting, simulate
from .dynamic import Run as DynamicRun
from .free import FREE_SERIES, prepare_free, run_free_once  # noqa: F401 - the mode "mujoco-free"
from .inverse import inverse_forces
from .mjcf import DEFAULT_MASS, Layout, carrier_note, joint_coordinates, layout, mass_properties, mjcf_text
from .model import compile_model
from .oracle import Oracle

__all__ = [
    "export_files",
    "run_kinematic",
    "DYNAMIC_SETTINGS",
    "MujocoDriven",
    "dynamic_series",
    "prepare_dynamic",
    "run_dynamic_once",
    "relative_error",
    "inverse_dynamics",
]

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


#: The driven ladder's series: the tight setting (RK4, stiff loops) from 1 ms, four runs,
#: compared; MuJoCo's defaults (Euler) from 2 ms, three runs.
DYNAMIC_SETTINGS = ((TIGHT, 1e-3, 4), (DEFAULT, 2e-3, 3))


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The driven ladder's series (:data:`DYNAMIC_SETTINGS`), the compared one first."""
    return tuple(
        Series(s.name, s.integrator, s, name=f"{s.name} {s.integrator}", timestep=dt, rungs=n)
        for s, dt, n in DYNAMIC_SETTINGS
    )


@dataclass
class MujocoDriven:
    """What every driven run shares: the compiled model, its layout and oracle, the start
    (qpos0, qvel0), and what steps a run (:func:`.dynamic.simulate`, or another
    implementation of MuJoCo with its signature: MJX's) with the mode and title it runs as."""

    model: mujoco.MjModel
    layout: Layout
    oracle: Oracle
    qpos0: np.ndarray
    qvel0: np.ndarray
    simulator: Callable[..., DynamicRun] = simulate
    mode: str = DYNAMIC_MODE
    title: str = "MuJoCo"


def prepare_dynamic(
    problem: DrivenProblem, xml: str | None = None, simulator=simulate, mode: str = DYNAMIC_MODE, title: str = "MuJoCo"
) -> MujocoDriven:
    """The compiled MJCF (``xml`` instead of the writer's) and the native state at
    t = 0 in MuJoCo's coordinates (the oracle's projection, its velocity solve).

    Raises
    ------
    ValueError
        If the MJCF cannot be written or compiled.
    """
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    model, lay = compile_model(kinematics, xml)
    oracle = Oracle(model, mech, lay)
    c0, cd0, _ = problem.window.inputs(kinematics, np.zeros(1))
    start = oracle.project(joint_coordinates(mech, lay, problem.start.q[0]), c0[0], c0)
    return MujocoDriven(
        model, lay, oracle, start.qpos[0], oracle.velocity(start.qpos[0], cd0[0]), simulator, mode, title
    )


def run_dynamic_once(prepared: MujocoDriven, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): MuJoCo
    (or ``prepared.simulator``) with the file's servos on the laws; its trajectory
    (accelerations: qacc) and, as a view, the same states with the kinematic
    oracle's accelerations (its error the row's ``acceleration_error_oracle``)."""
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    oracle = prepared.oracle
    setting: Setting = rung.series.options
    run = prepared.simulator(
        copy.deepcopy(prepared.model),
        mech,
        prepared.layout,
        setting,
        rung.timestep,
        rung.counts[0],
        problem.samples,
        prepared.qpos0,
        prepared.qvel0,
    )
    violation = np.array([oracle.violation(q) for q in run.qpos])
    failure = run.failure
    apart = next((i for i, v in enumerate(violation) if problem.came_apart(float(run.times[i]), float(v))), None)
    kept = len(run.times)
    if apart is not None:
        failure, kept = problem.came_apart(float(run.times[apart]), float(violation[apart])), apart + 1
    if not kept:
        return Run(None, failure or "no sample reached", columns=dict(run.columns))
    run = DynamicRun(
        run.times[:kept],
        run.qpos[:kept],
        run.qvel[:kept],
        run.qacc[:kept],
        run.law[:kept],
        failure,
        run.settings,
        run.steps,
        run.columns,
    )
    trajectory, view = _run_trajectories(
        oracle, run, setting, problem.window.duration, violation[:kept], prepared.mode, prepared.title
    )
    columns = {"acceleration_error_oracle": math.nan, **run.columns}
    if not failure:
        table = differences(kinematics, view, problem.branch)
        columns["acceleration_error_oracle"] = max(
            relative_error(table, "acceleration"), relative_error(table, "alpha")
        )
    return Run(trajectory, failure, columns=columns, views=[view])


def _run_trajectories(
    oracle: Oracle,
    run: DynamicRun,
    setting,
    duration: float,
    violation: np.ndarray,
    mode: str = DYNAMIC_MODE,
    title: str = "MuJoCo",
) -> tuple[Trajectory, Trajectory]:
    """The trajectory of a run (accelerations from qacc) and the same states with the
    kinematic oracle's accelerations."""
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
    diagnostics = {"constraint_violation": violation}
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
