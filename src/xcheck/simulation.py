"""Free motion across engines: the native reference and every ``free`` mode against it.

:func:`simulate_all` integrates the native reference of a mechanism's
``[free_motion]`` (:func:`xcheck.dynamics.simulate`) and runs each requested
free mode of the registry (:meth:`xcheck.engines.Engine.run_free`) from the
same initial state; :func:`free_errors` measures an engine's trajectory
against the reference. A mode that fails is a result with its reason; the
others still run.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import engines
from .dynamics._free import FreeReference, simulate
from .engines import NotApplicable
from .kinematics import Kinematics, rotate
from .model import GROUND
from .results import ModeResult, Trajectory

__all__ = [
    "SimulationResult",
    "free_modes",
    "free_errors",
    "free_row",
    "outputs_per_step",
    "empty_path",
    "FrameRecorder",
    "world_point",
    "loop_gap",
    "finish_free_run",
    "LADDER_COLUMNS",
    "ladder_steps",
    "left_branch",
    "path_distance",
    "simulate_all",
]

#: the columns of a free mode's ladder that tables show, in order
LADDER_COLUMNS = (
    "setting",
    "integrator",
    "timestep",
    "status",
    "position_error",
    "final_error",
    "order",
    "loop_drift",
    "energy_drift",
    "cpu_per_simulated_second",
)
#: output times of an engine's trajectory must match the reference's to this (s)
TIME_MATCH = 1e-9


@dataclass
class SimulationResult:
    """The native reference and each free mode's result.

    Attributes
    ----------
    reference : FreeReference
    outcomes : dict of str to ModeResult
        Per free mode that ran (``ok`` False with the reason when it failed).
    not_applicable : dict of str to str
        Modes that do not apply or whose engine is not installed, with the reason.
    seconds : dict of str to float
        Wall time of the reference ("native") and of each mode, s.
    left_out : dict of str to str
        The modes run only on request that a run of every default mode left
        out, with why (:func:`xcheck.runner.left_out`).
    """

    kinematics: Kinematics
    reference: FreeReference
    outcomes: dict[str, ModeResult] = field(default_factory=dict)
    not_applicable: dict[str, str] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    left_out: dict[str, str] = field(default_factory=dict)


def free_modes() -> tuple[str, ...]:
    """The registry's free-motion modes."""
    return tuple(m.name for m in engines.modes(("free",)))


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
    position = np.zeros(len(times))
    for label, states in trajectory.points.items():
        if "position" in states:
            gap = np.asarray(states["position"]) - native.point(label)["position"][index]
            position = np.maximum(position, np.hypot(gap[:, 0], gap[:, 1]))
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


def path_distance(reference, trajectory: Trajectory) -> np.ndarray:
    """How far each sample is from the reference's path, m (N,): the least, over
    every reference output, of the largest named-point distance.

    A run out of phase with the reference but on its branch stays near its path
    (within the points' travel between outputs); one that left the branch does not.
    """
    native = reference.motion.solution()
    labels = list(trajectory.points)
    path = np.stack([native.point(label)["position"] for label in labels], axis=1)  # (M, P, 2)
    states = np.stack([trajectory.points[label]["position"] for label in labels], axis=1)  # (N, P, 2)
    out = np.empty(len(states))
    for i, state in enumerate(states):
        gap = path - state[None]
        out[i] = float(np.min(np.max(np.hypot(gap[..., 0], gap[..., 1]), axis=1)))
    return out


def left_branch(reference, trajectory: Trajectory, limit: float) -> str:
    """ "" if every sample of ``trajectory`` lies within ``limit`` (m) of the reference's
    path (:func:`path_distance`: a run out of phase on the branch stays near it), else
    the status line of a run that left the branch: when, and how far it was then."""
    away = path_distance(reference, trajectory)
    off = np.flatnonzero(away > limit)
    if not off.size:
        return ""
    first = int(off[0])
    times = trajectory.times if trajectory.times is not None else np.arange(len(away), dtype=float)
    return (
        f"left the branch at t ≈ {float(times[first]):.4g} s: {away[first]:.3g} m from every configuration "
        "the reference passes through"
    )


def free_row(setting: str, integrator: str, timestep: float) -> dict:
    """A ladder row before its run: the columns of
    :meth:`xcheck.engines.Engine.run_free`'s summary, figures NaN, status "ok"."""
    return {
        "setting": setting,
        "integrator": integrator,
        "timestep": timestep,
        "steps": 0,
        "status": "ok",
        "cpu_seconds": math.nan,
        "cpu_per_simulated_second": math.nan,
        "position_error": math.nan,
        "final_error": math.nan,
        "loop_drift": math.nan,
        "energy_drift": math.nan,
    }


def outputs_per_step(reference: FreeReference, timestep: float) -> tuple[int, str]:
    """(steps per reference output, "") or (0, why not): a fixed-step engine samples
    the reference's output times only if its step divides the output step."""
    times = reference.motion.times
    output = float(times[1] - times[0]) if len(times) > 1 else float(times[-1])
    per_output = max(1, int(round(output / timestep)))
    if abs(per_output * timestep - output) > 1e-9 * output:
        return 0, f"the step does not divide the output step ({output:g} s)"
    return per_output, ""


def empty_path(mechanism, count: int) -> tuple[dict, dict]:
    """NaN-filled ``(bodies, points)`` of :class:`~xcheck.results.Trajectory` for
    ``count`` samples: each moving body's position (count, 2) and angle (count,),
    each named point's position (count, 2)."""
    bodies = {
        b.name: {"position": np.full((count, 2), np.nan), "angle": np.full(count, np.nan)}
        for b in mechanism.moving_bodies
    }
    points = {label: {"position": np.full((count, 2), np.nan)} for label in mechanism.point_owners}
    return bodies, points


def world_point(frames, body: str, point: np.ndarray) -> np.ndarray:
    """A point fixed in ``body`` (its local coordinates (2,), m) in the world, m.

    ``frames`` maps each moving body's name to its origin (2,) and angle (rad),
    as an engine reports them; the ground's points are their own.
    """
    if body == GROUND:
        return point
    origin, phi = frames[body][:2]
    return origin + rotate(phi, point)


def loop_gap(frames, cuts) -> float:
    """The widest gap (m) of the joints an engine holds as loop constraints: ``cuts`` is
    (body, point (2,), body, point (2,)) per joint, ``frames`` as :func:`world_point`'s."""
    return max(
        (float(np.hypot(*(world_point(frames, a, pa) - world_point(frames, b, pb)))) for a, pa, b, pb in cuts),
        default=0.0,
    )


class FrameRecorder:
    """A free run's outputs, from the body frames an engine reports at each.

    Parameters
    ----------
    mechanism : Mechanism
    count : int
        Outputs to record.
    cuts : sequence of (body, point (2,), body, point (2,))
        The joints the engine holds as loop constraints: their gap is the loop drift.
    apart : float
        Gap (m) beyond which the run counts as come apart.
    """

    def __init__(self, mechanism, count: int, cuts, apart: float) -> None:
        self.bodies, self.points = empty_path(mechanism, count)
        self.owners = mechanism.point_owners
        self.local = {label: np.asarray(mechanism.body(o).points[label], float) for label, o in self.owners.items()}
        self.cuts, self.apart = cuts, apart
        #: largest loop gap recorded so far, m
        self.drift = 0.0

    @property
    def path(self) -> tuple[dict, dict]:
        """``(bodies, points)`` as :func:`empty_path` makes them, NaN where not recorded."""
        return self.bodies, self.points

    def record(self, frames, j: int, t: float) -> str:
        """Store output ``j`` (at ``t``, s) from ``frames`` (body name to origin (2,), angle);
        "" or why the run stops here (went non-finite, came apart)."""
        if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
            return f"went non-finite at t = {t:.6g} s"
        for name, states in self.bodies.items():
            states["position"][j] = frames[name][0]
            states["angle"][j] = frames[name][1]
        for label, owner in self.owners.items():
            self.points[label]["position"][j] = world_point(frames, owner, self.local[label])
        gap = loop_gap(frames, self.cuts)
        self.drift = max(self.drift, gap)
        if gap > self.apart:
            return f"came apart at t = {t:.6g} s (loops {gap:.3g} m open)"
        return ""


def finish_free_run(
    mode: str,
    reference: FreeReference,
    index,
    path: tuple[dict, dict],
    settings: dict,
    notes: str,
    row: dict,
    limit: float,
) -> tuple[dict, Trajectory]:
    """A run that went through, compared: its Trajectory at the reference's outputs
    ``index``, and the row with position_error, final_error (m) and, where it strayed
    farther than ``limit`` (m) from the reference's path, the status saying so."""
    empty = np.zeros((len(index), 0))
    bodies, points = path
    trajectory = Trajectory(
        mode, empty, empty, empty, bodies, points, reference.motion.times[index], settings, notes=notes
    )
    errors = free_errors(reference, trajectory)
    row.update(position_error=errors["position_error"], final_error=errors["final_error"])
    row["status"] = left_branch(reference, trajectory, limit) or row["status"]
    return row, trajectory


def ladder_steps(reference: FreeReference, steps) -> tuple[float, ...]:
    """An engine's time steps (s, coarsest first) for this reference: as given
    where the coarsest is at most the output step, else all scaled down by the
    same factor so that the coarsest is a tenth of it (a 0.03 s squeeze with
    outputs every 0.1 ms gets 10, 5, 2.5 us instead of 1, 0.5, 0.25 ms)."""
    times = reference.motion.times
    output = float(times[1] - times[0]) if len(times) > 1 else float(times[-1])
    factor = 1.0 if float(steps[0]) <= output else output / (10.0 * float(steps[0]))
    return tuple(float(s) * factor for s in steps)


#: the native reference's wall time (s) from which the free modes go to worker processes
PARALLEL_REFERENCE = 1.0


def simulate_all(
    kinematics: Kinematics,
    modes=None,
    duration: float | None = None,
    branch: str | None = None,
    progress=None,
    jobs: int = 1,
) -> SimulationResult:
    """The native reference of the mechanism's free motion and each free mode against it.

    Parameters
    ----------
    modes : sequence of str, optional
        Free modes to run (default: every one but those run only on request,
        :attr:`xcheck.engines.Mode.on_request`); none gives the reference alone.
    duration : float, optional
        Simulated time, s (default: the file's).
    progress : callable, optional
        Called with a line saying what runs now (with ``jobs`` > 1: each mode as it finishes).
    jobs : int
        Modes run at once, each in a worker process started afresh (1: one after
        another in this process), where the reference took at least
        :data:`PARALLEL_REFERENCE`; the modes of engines registered at run time
        run here. The results are those of a serial run.
    """
    start = time.perf_counter()
    reference = simulate(
        kinematics,
        branch,
        duration,
        progress=None if progress is None else (lambda h: progress(f"native: RK4 at {h:.4g} s")),
    )
    result = SimulationResult(kinematics, reference, seconds={"native": time.perf_counter() - start})
    from .runner import default_modes, left_out

    chosen = list(default_modes(("free",))[1:] if modes is None else modes)
    result.left_out = left_out(chosen, ("free",))
    missing = {mode: engines.engine_of(mode).available() for mode in chosen}
    runnable = [mode for mode in chosen if not missing[mode]]
    from ._parallel import collect, known_to_workers, process_pool

    # a short or simple motion (its reference under PARALLEL_REFERENCE s) has short ladders too:
    # a worker's start (about 1 s of CPU) would cost more than it saves
    alone = jobs <= 1 or result.seconds["native"] < PARALLEL_REFERENCE
    away = [] if alone else [m for m in runnable if known_to_workers(m)]
    if len(away) < 2:  # one mode gains nothing from a worker
        away = []
    here = [m for m in runnable if m not in away]
    ran: dict = {}
    if away:
        begin = time.perf_counter()

        def failed(mode: str, why: str):  # its time: until the pool said so
            return ModeResult(mode, kinematics.mechanism.name, False, why), time.perf_counter() - begin

        with process_pool(min(jobs, len(away))) as pool:
            futures = {pool.submit(_run_free, mode, kinematics, reference, branch): mode for mode in away}
            ran.update(collect(futures, failed, progress))
    for mode in here:
        if progress is not None:
            progress(mode)
        ran[mode] = _run_free(mode, kinematics, reference, branch)
    for mode in chosen:  # in the order asked for, however the modes ran
        if missing[mode]:
            result.not_applicable[mode] = missing[mode]
            continue
        outcome, result.seconds[mode] = ran[mode]
        if isinstance(outcome, NotApplicable):
            result.not_applicable[mode] = outcome.reason
        else:
            result.outcomes[mode] = outcome
    return result


def _run_free(mode: str, kinematics: Kinematics, reference: FreeReference, branch: str | None):
    """One free mode against the reference: (its ModeResult, or its NotApplicable
    returned rather than raised, and its wall time, s); never raises."""
    begin = time.perf_counter()
    outcome: ModeResult | NotApplicable
    try:
        outcome = engines.engine_of(mode).run_free(mode, kinematics, reference, branch=branch)
    except NotApplicable as err:
        outcome = err
    except Exception as err:  # noqa: BLE001 - an engine's failure is its mode's result
        outcome = ModeResult(mode, kinematics.mechanism.name, False, f"{type(err).__name__}: {err}".splitlines()[0])
    return outcome, time.perf_counter() - begin
