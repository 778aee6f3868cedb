"""Free motion: an engine's ladder against the native reference, the mechanism
released from the reference's initial state."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import NotApplicable
from ..results import ModeResult, Trajectory
from ._core import (
    APART,
    Finding,
    Run,
    Rung,
    Series,
    came_apart,
    conservative,
    ladder_row,
    loop_drift,
    one_line,
    reached,
    run_rungs,
    run_titles,
)
from ._study import ladder_result

if TYPE_CHECKING:
    from ..dynamics._free import FreeReference
    from ..kinematics import Kinematics

#: About this many reference outputs are compared: every k-th, and the last.
COMPARED = 200
#: A free ladder's time steps, s, coarsest first (halving), as long as the
#: coarsest is at most the reference's output step (see :func:`FreeProblem.steps`).
FREE_STEPS = (1e-3, 5e-4, 2.5e-4)
#: Free positions closer than this fraction of the size to the reference's are round-off
#: (no order): an engine's model of a point mass (:data:`xcheck.engines.POINT_MASS_INERTIA`:
#: 1e-12 m size^2) and float64 over 1e3 to 1e5 steps differ by about 1e-12 of the size
#: (measured: MuJoCo's and MJX's RK4 on the IFToMM pendulum, a point mass, 1.06e-12 to
#: 1.66e-12 m of its 1 m at 1, 0.5 and 0.25 ms over 0.5 s, not falling; the reference's
#: stated error there 3.9e-14 m).
FREE_ROUND_OFF = 1e-11
#: the columns of a free mode's ladder, in the order tables show them (every engine's rows have them all)
LADDER_COLUMNS = (
    "setting",
    "integrator",
    "timestep",
    "status",
    "phase",
    "position_error",
    "final_error",
    "order",
    "loop_drift",
    "energy_drift",
    "cpu_per_simulated_second",
    "finding",
)
#: output times of an engine's trajectory must match the reference's to this (s)
TIME_MATCH = 1e-9


@dataclass(frozen=True)
class FreeProblem:
    """What every run of a free ladder shares: the mechanism, the native
    reference, and the compared outputs.

    Attributes
    ----------
    kinematics : Kinematics
    reference : FreeReference
    index : ndarray of int, shape (N,)
        The compared reference outputs: every k-th (about :data:`COMPARED`)
        from the first, and the last.
    """

    kinematics: Kinematics
    reference: FreeReference
    index: np.ndarray

    @classmethod
    def of(cls, kinematics: Kinematics, reference: FreeReference) -> FreeProblem:
        """The problem of a reference, its compared outputs chosen."""
        outputs = len(reference.motion.times)
        every = max(1, math.ceil((outputs - 1) / COMPARED))
        index = np.arange(0, outputs, every)
        if index[-1] != outputs - 1:
            index = np.append(index, outputs - 1)
        return cls(kinematics, reference, index)

    @property
    def times(self) -> np.ndarray:
        """The compared output times, s (N,)."""
        return self.reference.motion.times[self.index]

    @property
    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """The initial state: body coordinates q (x, y, phi per moving body; m, rad) and rates qd."""
        return self.reference.motion.q[0], self.reference.motion.qd[0]

    @property
    def apart(self) -> float:
        """The loops' opening (m) beyond which a run has come apart: :data:`APART` x size."""
        return APART * self.kinematics.mechanism.size

    @property
    def output_step(self) -> float:
        """The reference's output step, s."""
        times = self.reference.motion.times
        return float(times[1] - times[0]) if len(times) > 1 else float(times[-1])

    def steps(self, series: Series) -> tuple[float, ...]:
        """A series' time steps (s, coarsest first): its ``timestep`` (default
        :data:`FREE_STEPS`'s first) halved ``rungs - 1`` times, where the ladder's
        coarsest step is at most the output step; else every series' steps scaled
        down by the same factor, so that the ladder's coarsest is a tenth of it (a
        0.03 s squeeze with outputs every 0.1 ms gets 10, 5, 2.5 us instead of 1,
        0.5, 0.25 ms)."""
        output = self.output_step
        factor = 1.0 if FREE_STEPS[0] <= output else output / (10.0 * FREE_STEPS[0])
        coarsest = FREE_STEPS[0] if series.timestep is None else series.timestep
        return tuple(coarsest * factor / 2**k for k in range(series.rungs))

    def rung(self, series: Series, timestep: float) -> Rung:
        """The rung of ``series`` at ``timestep`` (s): its steps between compared
        outputs, or why the step does not fit (it must divide the output step)."""
        output = self.output_step
        per_output = max(1, int(round(output / timestep)))
        if abs(per_output * timestep - output) > 1e-9 * output:
            return Rung(series, timestep, misfit=f"the step does not divide the output step ({output:g} s)")
        return Rung(series, timestep, tuple(int(n) * per_output for n in np.diff(self.index)))

    def came_apart(self, t: float, gap: float) -> str:
        """ "" or the failure of a run whose loops are ``gap`` (m) open at ``t`` (s)
        (:func:`~xcheck.ladder.came_apart`)."""
        return came_apart(t, gap, self.kinematics.system.size)  # the mechanism's, computed once


def free_errors(reference: FreeReference, trajectory: Trajectory) -> dict[str, float]:
    """An engine's free motion against the native reference.

    ``trajectory.times`` must be output times of the reference (to
    :data:`TIME_MATCH`). Returns position_error (the largest distance of a
    named point from the reference's over the compared outputs, m),
    final_error (at the last compared output, m), angle_error (the largest
    body angle difference, rad), compared (the number of outputs) and
    worst_time (s, where the position error is largest).

    Raises
    ------
    ValueError
        If a time is not an output time of the reference.
    """
    motion = reference.motion
    times = np.asarray(trajectory.times, dtype=float)
    index = np.searchsorted(motion.times, times - TIME_MATCH)
    index = np.clip(index, 0, len(motion.times) - 1)
    if not np.all(np.abs(motion.times[index] - times) <= TIME_MATCH):
        raise ValueError("expected the engine's samples at the reference's output times")
    native = motion.solution()
    position = _point_gaps(trajectory, native, index)
    angle = np.zeros(len(times))
    for name, states in trajectory.bodies.items():
        if "angle" in states:
            angle = np.maximum(angle, np.abs(np.asarray(states["angle"]) - native.body(name)["angle"][index]))
    worst = int(np.argmax(position))
    return {
        "position_error": float(position[worst]),
        "final_error": float(position[-1]),
        "angle_error": float(np.max(angle)),
        "compared": float(len(times)),
        "worst_time": float(times[worst]),
    }


def point_gaps(trajectory: Trajectory, native, times: np.ndarray) -> np.ndarray:
    """The largest distance (m) of a named point of ``trajectory`` from the reference's at
    each of its samples (N,): ``native`` the reference's :class:`~xcheck.kinematics.Solution`
    at its output ``times`` (s), which the samples' times match (to :data:`TIME_MATCH`)."""
    index = np.searchsorted(times, np.asarray(trajectory.times, dtype=float) - TIME_MATCH)
    return _point_gaps(trajectory, native, index)


def _point_gaps(trajectory: Trajectory, native, index: np.ndarray) -> np.ndarray:
    """The largest distance (m) of a named point from the reference's at each sample (N,)."""
    position = np.zeros(len(index))
    for label, states in trajectory.points.items():
        if "position" in states:
            gap = np.asarray(states["position"]) - native.point(label)["position"][index]
            position = np.maximum(position, np.hypot(gap[:, 0], gap[:, 1]))
    return position


def path_distance(reference: FreeReference, trajectory: Trajectory, samples=None) -> np.ndarray:
    """How far each sample (or each of ``samples``, indices) is from the reference's
    path, m (N,): the least, over every reference output, of the largest named-point
    distance.

    A run out of phase with the reference but on its branch stays near its path
    (within the points' travel between outputs); one that left the branch does not.
    """
    native = reference.motion.solution()
    labels = list(trajectory.points)
    path = np.stack([native.point(label)["position"] for label in labels], axis=1)  # (M, P, 2)
    states = np.stack([trajectory.points[label]["position"] for label in labels], axis=1)  # (N, P, 2)
    if samples is not None:
        states = states[samples]
    out = np.empty(len(states))
    for i, state in enumerate(states):
        gap = path - state[None]
        out[i] = float(np.min(np.max(np.hypot(gap[..., 0], gap[..., 1]), axis=1)))
    return out


def left_branch(reference: FreeReference, trajectory: Trajectory, limit: float) -> str:
    """ "" if every sample of ``trajectory`` lies within ``limit`` (m) of the reference's
    path (:func:`path_distance`: a run out of phase on the branch stays near it), else
    the status of a run that left the branch: when, and how far it was then.

    Only the samples farther than ``limit`` from the reference at their own time are
    measured against the whole path: that distance bounds the path's from above."""
    candidates = None
    if trajectory.times is not None:
        gaps = point_gaps(trajectory, reference.motion.solution(), reference.motion.times)
        candidates = np.flatnonzero(gaps > limit)
        if not candidates.size:
            return ""
    away = path_distance(reference, trajectory, candidates)
    off = np.flatnonzero(away > limit)
    if not off.size:
        return ""
    first = int(off[0] if candidates is None else candidates[off[0]])
    times = trajectory.times if trajectory.times is not None else np.arange(first + 1, dtype=float)
    return (
        f"left the branch at t ≈ {float(times[first]):.4g} s: {float(away[off[0]]):.3g} m from every "
        "configuration the reference passes through"
    )


def out_of_phase(reference: FreeReference, trajectory: Trajectory, limit: float) -> str:
    """ "" if every named point stays within ``limit`` (m) of the reference's at the
    same time, else when the run fell out of phase (for a run on the branch:
    :func:`left_branch` found it near the reference's path throughout)."""
    gaps = point_gaps(trajectory, reference.motion.solution(), reference.motion.times)
    off = np.flatnonzero(gaps > limit)
    if not off.size:
        return ""
    return f"out of phase from t ≈ {float(np.asarray(trajectory.times)[int(off[0])]):.4g} s"


def _free_row(problem: FreeProblem, rung: Rung, run: Run) -> tuple[dict, Trajectory | None]:
    """A free run judged: (its row, its trajectory where it counts, else None); its
    ``finding`` column is left empty."""
    mech = problem.kinematics.mechanism
    measured = {
        "phase": "",
        "position_error": math.nan,
        "final_error": math.nan,
        "angle_error": math.nan,
        "order": math.nan,
        "loop_drift": math.nan,
        "energy_drift": math.nan,
        "simulated": 0.0,
        "cpu_seconds": run.cpu_seconds,
        "cpu_per_simulated_second": math.nan,
    }
    row = ladder_row(rung, run, measured)
    times = reached(row, run, len(problem.index), "no output reached")
    trajectory = run.trajectory
    if times is None or trajectory is None:
        return row, None
    simulated = float(times[-1] - times[0])
    row["simulated"] = simulated
    if simulated > 0.0:
        row["cpu_per_simulated_second"] = run.cpu_seconds / simulated
    errors = free_errors(problem.reference, trajectory)
    row.update({key: errors[key] for key in ("position_error", "final_error", "angle_error")})
    row["loop_drift"] = loop_drift(trajectory)
    diagnostics = trajectory.diagnostics
    if diagnostics.get("energy") is not None and conservative(mech):
        energy = np.asarray(diagnostics["energy"], dtype=float)
        row["energy_drift"] = float(np.max(np.abs(energy - energy[0])))
    if row["status"] == "ok":
        row["status"] = left_branch(problem.reference, trajectory, problem.apart) or "ok"
    if row["status"] == "ok":
        row["phase"] = out_of_phase(problem.reference, trajectory, problem.apart)
    row.update(run.columns)
    return row, trajectory if row["status"] == "ok" else None


def free_study(
    mode: str,
    kinematics: Kinematics,
    reference: FreeReference,
    series: Sequence[Series],
    run_once: Callable[[Any, FreeProblem, Rung], Run],
    prepare: Callable[[FreeProblem], Any] | None = None,
    findings: Sequence[Finding] = (),
) -> ModeResult:
    """A free mode's ladder against the native reference: every series at its
    halving steps (:meth:`FreeProblem.steps`), each run made by
    ``run_once(prepared, problem, rung)`` and judged by one rule.

    Parameters
    ----------
    series : sequence of Series
        The engine's series.
    run_once : callable
        One run (:class:`Run`) of the engine.
    prepare : callable, optional
        What every run shares, built once from the :class:`FreeProblem` (the
        engine's model); it raises :class:`~xcheck.errors.NotApplicable` for
        what the engine cannot represent, any other exception for a mode that
        fails as a whole (its message the reason).
    findings : sequence of Finding
        The engine's stated findings: a row carries the titles of those that
        apply to free positions on this mechanism.

    Returns
    -------
    ModeResult
        ``summary``: one row per run with every column of :data:`LADDER_COLUMNS`
        and series, steps, angle_error (rad), simulated (s reached),
        cpu_seconds, then the engine's own columns; status is "ok" or why the
        run does not count (it stopped: its errors are those of the outputs it
        reached; it left the reference's branch: measured to the end); phase
        says when a run on the branch fell out of phase; ``study``:
        :func:`~xcheck.ladder.convergence_study` of the runs that count, the reference's
        stated error as the round-off floor; ``trajectories``: the runs that
        count, the most accurate first. ``ok`` False where no run counts.

    Raises
    ------
    NotApplicable
        From ``prepare``.
    """
    mech = kinematics.mechanism
    problem = FreeProblem.of(kinematics, reference)
    try:
        prepared = prepare(problem) if prepare is not None else None
    except NotApplicable:
        raise
    except Exception as error:  # noqa: BLE001 - a mode that cannot start is a result with its reason
        return ModeResult(mode, mech.name, False, one_line(error))
    rungs = [problem.rung(s, step) for s in series for step in problem.steps(s)]
    runs = run_rungs(lambda rung: run_once(prepared, problem, rung), rungs)
    judged = []
    for rung, run in zip(rungs, runs):
        row, trajectory = _free_row(problem, rung, run)
        row["finding"] = run_titles(findings, "free", ("position",), mech, rung, trajectory is not None)
        judged.append((row, trajectory))
    return ladder_result(mode, mech.name, judged, free_floor(problem))


def free_floor(problem: FreeProblem) -> float:
    """The round-off floor of a free ladder's errors, m: the reference's stated
    error (an engine's error within it is not measured), at least
    :data:`FREE_ROUND_OFF` of the size."""
    return max(float(np.max(problem.reference.estimate)), FREE_ROUND_OFF * problem.kinematics.mechanism.size)
