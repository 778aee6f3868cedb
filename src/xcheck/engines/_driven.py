"""What the driven-dynamics modes of engines without an oracle of their own
(Exudyn, PyBullet) share: their runs of a step ladder judged against the native
solution at the inputs each engine realised, as one :class:`~xcheck.results.ModeResult`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import pandas as pd

from xcheck import engines
from xcheck.kinematics import Kinematics, Solution, Status
from xcheck.ladder import convergence_study
from xcheck.results import ModeResult, Trajectory, differences, native_at

__all__ = [
    "LEFT_BRANCH",
    "branch_gap_status",
    "driven_result",
    "driven_start",
    "driven_trajectory",
    "empty_states",
    "ladder",
    "left_branch",
    "refined_steps",
    "refined_timesteps",
]

#: a driven ladder's setting type (PyBullet's, Exudyn's)
S = TypeVar("S")

#: A driven run with a named point farther than this fraction of the mechanism's size from
#: the native configuration at the inputs the engine realised has left the assembly branch.
LEFT_BRANCH = 0.1


def refined_steps(finest: int, refine: int) -> tuple[int]:
    """The steps per sample of a refinement (``refine`` k > 0, see
    :meth:`xcheck.engines.Engine.run`): one run at ``finest`` 2^k."""
    if refine < 1:
        raise ValueError(f"expected a refinement of at least 1, found {refine}")
    return (finest * 2**refine,)


def refined_timesteps(smallest: float, refine: int) -> tuple[float]:
    """The time step (s) of a refinement: one run at ``smallest`` / 2^k."""
    (factor,) = refined_steps(1, refine)
    return (smallest / factor,)


def ladder(settings: Sequence[S], steps_per_sample: Sequence[int], refine: int = 0) -> list[tuple[S, int]]:
    """(setting, steps per sample) of each run of a driven ladder, the compared one
    first (PyBullet's, Exudyn's): every step count of the first setting and the
    finest (the first) of the others; with ``refine`` k > 0 the first setting's
    refinement alone (:func:`refined_steps`)."""
    if refine:
        return [(settings[0], per) for per in refined_steps(steps_per_sample[0], refine)]
    return [(settings[0], per) for per in steps_per_sample] + [(s, steps_per_sample[0]) for s in settings[1:]]


def empty_states(mechanism, samples: int, quantities) -> tuple[dict, dict, np.ndarray, np.ndarray, np.ndarray]:
    """The NaN arrays a driven run fills sample by sample (PyBullet's, Drake's).

    Parameters
    ----------
    samples : int
        N, the samples of the run.
    quantities : iterable of str
        The body quantities kept: ``position`` and ``velocity`` (N, 2), the others (N,).

    Returns
    -------
    bodies : dict of str to dict of str to ndarray
        Per moving body, per quantity.
    points : dict of str to dict of str to ndarray
        Per named point off the ground, ``position`` and ``velocity`` (N, 2), m and m/s.
    inputs, rates : ndarray, shape (N, k)
        The drivers' realised values (rad or m) and rates.
    gaps : ndarray, shape (N,)
        The loops' largest opening (m), zeros.
    """
    bodies = {
        body.name: {
            key: np.full((samples, 2) if key in ("position", "velocity") else samples, np.nan) for key in quantities
        }
        for body in mechanism.moving_bodies
    }
    ground = mechanism.ground.name
    points = {
        label: {"position": np.full((samples, 2), np.nan), "velocity": np.full((samples, 2), np.nan)}
        for label, owner in mechanism.point_owners.items()
        if owner != ground
    }
    inputs = np.full((samples, len(mechanism.drivers)), np.nan)
    return bodies, points, inputs, np.full_like(inputs, np.nan), np.zeros(samples)


def left_branch(kinematics: Kinematics, branch: str | None, trajectory: Trajectory, engine: str) -> str:
    """ "" if every named point of a driven run stays within :data:`LEFT_BRANCH` of the
    size of the native configuration at the inputs the engine realised, else when and
    how far it left. An engine's soft or lagging loops can carry a mechanism across a
    near dead centre onto the other branch (fuzz s1-00018: MuJoCo, PyBullet, Drake), a
    stated result of the engine rather than a disagreement in a quantity.

    Parameters
    ----------
    trajectory : Trajectory
        The run's states (``times`` in s, or None: the sample index is reported).
    engine : str
        The engine's title, for the message ("MuJoCo").
    """
    points = {label: states["position"] for label, states in trajectory.points.items()}
    native = native_at(kinematics, trajectory, branch)
    return branch_gap_status(kinematics, native, points, trajectory.times, engine)


def branch_gap_status(
    kinematics: Kinematics, native: Solution, points: dict[str, np.ndarray], times: np.ndarray | None, engine: str
) -> str:
    """:func:`left_branch` for states given as named points' positions.

    Parameters
    ----------
    native : Solution
        The native solution at the engine's realised inputs (N samples).
    points : dict of str to ndarray, shape (N, 2)
        Positions (m) of named points as the engine has them.
    times : ndarray, shape (N,), or None
        The samples' times (s).
    """
    good = native.status <= Status.NEAR_SINGULAR
    gaps = np.zeros(len(native.status))
    for label, positions in points.items():
        gaps = np.maximum(gaps, np.hypot(*(positions - native.point(label)["position"]).T))
    off = np.flatnonzero(good & (gaps > LEFT_BRANCH * kinematics.mechanism.size))
    if not off.size:
        return ""
    i = int(off[0])
    when = f"t = {float(times[i]):.6g} s" if times is not None else f"sample {i}"
    return (
        f"left the assembly branch at {when}: a point {gaps[i]:.3g} m from the native configuration "
        f"at the inputs {engine} realised"
    )


def driven_result(
    mode: str,
    kinematics: Kinematics,
    runs: list[tuple[dict, Trajectory | None]],
    errors: dict[str, str],
    branch: str | None = None,
) -> ModeResult:
    """The mode's result from its runs, the compared one first.

    Parameters
    ----------
    runs : list of (dict, Trajectory or None)
        Per run its summary row (setting, timestep s, status, cpu_seconds, ...) and
        its trajectory (None where the run failed).
    errors : dict of str to str
        The compared quantities, each ``"abs"`` (m or rad) or ``"rel"`` (relative
        to the native magnitude): the row gains ``QUANTITY_error``, the largest over
        bodies and points; ``input_error`` (SI) and ``loop_gap`` (m) come from the
        trajectory's diagnostics ``input_error`` and ``constraint_violation``.

    Returns
    -------
    ModeResult
        ``ok`` where the first run went through; ``study``: the position error's
        :func:`~xcheck.results.convergence_study` (errors at 1e-13 of the size
        have no order: the drivers fix the positions exactly there).
    """
    mech = kinematics.mechanism
    title = engines.engine_of(mode).title
    kept: list[tuple[dict, Trajectory | None]] = []
    for row, trajectory in runs:
        status = "" if trajectory is None else left_branch(kinematics, branch, trajectory, title)
        if status:  # a run on the other branch is the engine's result, not a quantity's error
            row["status"] = status
            trajectory = None
        kept.append((row, trajectory))
    runs = kept
    rows = []
    for row, trajectory in runs:
        if trajectory is not None:
            table = differences(kinematics, trajectory, branch)
            for quantity, kind in errors.items():
                part = table[table["quantity"] == quantity]
                if part.empty:
                    continue
                worst = float(part["max_abs"].max())
                scale = float(part["scale"].max())
                row[f"{quantity}_error"] = worst / scale if kind == "rel" and scale > 0.0 else worst
            diagnostics = trajectory.diagnostics
            row["input_error"] = float(np.max(np.abs(diagnostics["input_error"])))
            if "constraint_violation" in diagnostics:
                row["loop_gap"] = float(np.max(diagnostics["constraint_violation"]))
        rows.append(row)
    summary = pd.DataFrame(rows)
    position = summary["position_error"] if "position_error" in summary else [math.nan] * len(summary)
    floor = 1e-13 * mech.size
    study = convergence_study(summary["setting"], summary["timestep"], position, summary["status"], floor)
    trajectories = [t for _, t in runs if t is not None]
    if runs[0][1] is None:
        first = runs[0][0]
        reason = f"{first['setting']} dt = {first['timestep']:.4g} s: {first['status']}"
        return ModeResult(mode, mech.name, False, reason, trajectories, summary, study)
    return ModeResult(mode, mech.name, True, "", trajectories, summary, study)


def driven_start(kinematics: Kinematics, branch: str | None = None):
    """The simulation window and the native state at t = 0 a driven run starts from:
    (window, q (n,), qd (n,)), native body coordinates and rates.

    Raises
    ------
    ValueError
        If the native solver does not assemble the mechanism at t = 0.
    """
    from xcheck.motion import simulation_window

    window = simulation_window(kinematics, branch)
    q, qd, qdd = window.inputs(kinematics, np.zeros(1))
    start = kinematics.solve(q, qd, qdd, branch=branch)
    if start.status[0] > Status.NEAR_SINGULAR:
        raise ValueError("the native solver does not assemble the mechanism at t = 0")
    return window, start.q[0], start.qd[0]


def driven_trajectory(
    mode: str,
    kinematics: Kinematics,
    window,
    states: tuple[dict, dict, np.ndarray, np.ndarray, np.ndarray],
    accelerations: np.ndarray | None,
    settings: dict,
    notes: str,
) -> Trajectory:
    """A driven run's samples as a Trajectory at the window's sample times after t = 0.

    Parameters
    ----------
    states : (bodies, points, inputs, rates, gaps)
        As :func:`empty_states` makes them, filled: the inputs and rates as the engine realised them.
    accelerations : ndarray, shape (N, k), or None
        The inputs' accelerations as the engine realised them (None: the motion laws').
    settings : dict
        The trajectory's settings (integrator, timestep, series, ...).
    """
    bodies, points, inputs, rates, gaps = states
    times = window.times(len(inputs) + 1)[1:]
    if accelerations is None:
        accelerations = np.stack([d.law.at_time(times)[2] for d in kinematics.mechanism.drivers], axis=1)
    law_q, law_qd, _ = window.inputs(kinematics, times)
    diagnostics = {"input_error": inputs - law_q, "input_rate_error": rates - law_qd, "constraint_violation": gaps}
    return Trajectory(mode, inputs, rates, accelerations, bodies, points, times, settings, diagnostics, notes)
