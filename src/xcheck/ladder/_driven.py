"""Driven dynamics: an engine's ladder with the inputs driven by their motion
laws over the simulation window, each run compared with the native solution at
the inputs the engine realised."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import NotApplicable
from ..results import BODY_QUANTITIES, ModeResult, Trajectory
from ._core import (
    APART,
    Finding,
    Run,
    Rung,
    Series,
    came_apart,
    ladder_row,
    loop_drift,
    one_line,
    reached,
    run_rungs,
    run_titles,
)
from ._study import ladder_result

if TYPE_CHECKING:
    from ..kinematics import Kinematics, Solution
    from ..motion import SimulationWindow

__all__ = ["DRIVEN_SAMPLES", "DYNAMIC_COLUMNS", "DrivenProblem", "DrivenLadder", "driven_floor", "off_branch"]

#: States compared per driven run: the ends of this many equal intervals over the simulation
#: window. Not t = 0: every run starts there from the native state (its positions and rates
#: are the start, not the engine's), and accelerations there say how the engine starts:
#: pymunk's velocities differenced over its first steps miss the native acceleration by 0.7
#: of its largest magnitude at every step size (the four-bar's coupler, 50 to 800 steps a
#: sample), where at the first interval's end they fall at order 1 (1.0e-3 to 6.6e-5).
DRIVEN_SAMPLES = 40
#: the columns of a driven mode's ladder, in the order tables show them (every engine's rows have them all)
DYNAMIC_COLUMNS = (
    "setting",
    "integrator",
    "timestep",
    "status",
    "position_error",
    "angle_error",
    "velocity_error",
    "acceleration_error",
    "order",
    "loop_drift",
    "input_error",
    "cpu_seconds",
    "finding",
)
#: the compared quantities of a driven row: column -> (quantities, "abs" in SI or "rel" to the native scale)
_ERRORS = {
    "position_error": (("position",), "abs"),
    "angle_error": (("angle",), "abs"),
    "velocity_error": (("velocity", "omega"), "rel"),
    "acceleration_error": (("acceleration", "alpha"), "rel"),
}


@dataclass(frozen=True)
class DrivenProblem:
    """What every run of a driven ladder shares: the mechanism, its simulation
    window, the native state at t = 0 and the compared sample times.

    Attributes
    ----------
    kinematics : Kinematics
    branch : str or None
    window : SimulationWindow
        The drivers' window (:func:`xcheck.motion.simulation_window`), or a
        shorter one asked for.
    start : Solution
        The native state at t = 0 (one sample): every run starts there.
    samples : int
        Compared states: the ends of this many equal intervals, ``times``.
    """

    kinematics: Kinematics
    branch: str | None
    window: SimulationWindow
    start: Solution
    samples: int = DRIVEN_SAMPLES

    @classmethod
    def of(cls, kinematics: Kinematics, branch: str | None = None, duration: float | None = None) -> DrivenProblem:
        """The problem of a mechanism: its window (``duration`` s of it, where
        given) and its native state at t = 0.

        Raises
        ------
        ValueError
            If the motion cannot start (no window, no determined state at t = 0)
            or ``duration`` is longer than the window.
        """
        from ..kinematics import Status
        from ..motion import SimulationWindow, simulation_window

        window = simulation_window(kinematics, branch)
        if duration is not None:
            if not 0.0 < duration <= window.duration * (1.0 + 1e-12):
                raise ValueError(
                    f"expected a duration within the simulation window ({window.duration:.6g} s, "
                    f"{window.reason}), found {duration:g} s"
                )
            window = SimulationWindow(float(duration), window.reason)
        start = kinematics.solve(*window.inputs(kinematics, np.zeros(1)), branch=branch)
        if start.status[0] > Status.NEAR_SINGULAR:
            raise ValueError(f"the mechanism has no determined state at t = 0 ({Status(start.status[0]).message})")
        return cls(kinematics, branch, window, start)

    @property
    def times(self) -> np.ndarray:
        """The compared sample times, s (samples,): after t = 0 to the window's end."""
        return self.window.times(self.samples + 1)[1:]

    @property
    def interval(self) -> float:
        """The time between compared samples, s."""
        return self.window.duration / self.samples

    def rung(self, series: Series, k: int) -> Rung:
        """Rung ``k`` of ``series``: its ``timestep`` fitted to the sample interval
        (the largest step not above it that divides the interval) and halved k times."""
        coarsest = self.interval if series.timestep is None else series.timestep
        per = max(1, math.ceil(self.interval / coarsest - 1e-9)) * 2**k
        return Rung(series, self.interval / per, (per,) * self.samples)

    def came_apart(self, t: float, gap: float) -> str:
        """ "" or the failure of a run whose loops are ``gap`` (m) open at ``t`` (s)
        (:func:`~xcheck.ladder.came_apart`)."""
        return came_apart(t, gap, self.kinematics.mechanism.size)


def driven_floor(kinematics: Kinematics) -> float:
    """The round-off floor of a driven ladder's position errors, m: an engine's
    kinematic round-off bound (:func:`xcheck.tolerances.convergence_round_off`)
    times the size; the native positions at the realised inputs are exact."""
    from ..tolerances import convergence_round_off

    return convergence_round_off("position") * kinematics.mechanism.size


def _driven_row(problem: DrivenProblem, rung: Rung, run: Run) -> tuple[dict, Trajectory | None]:
    """A driven run judged: (its row, its trajectory where it counts, else None); its
    ``finding`` column is left empty."""
    from ..kinematics import Status
    from ..results import differences, native_at

    kinematics, branch = problem.kinematics, problem.branch
    measured = {
        **{column: math.nan for column in _ERRORS},
        "order": math.nan,
        "loop_drift": math.nan,
        "input_error": math.nan,
        "simulated": 0.0,
        "cpu_seconds": run.cpu_seconds,
    }
    row = ladder_row(rung, run, measured)
    times = reached(row, run, len(problem.times), "no sample reached")
    trajectory = run.trajectory
    if times is None or trajectory is None:
        return row, None
    row["simulated"] = float(times[-1])
    native = native_at(kinematics, trajectory, branch)
    good = native.status <= Status.NEAR_SINGULAR
    if row["status"] == "ok" and not good.all():
        i = int(np.argmin(good))
        row["status"] = f"the mechanism does not assemble at the inputs realised at t = {times[i]:.6g} s"
    if row["status"] == "ok":
        points = {label: states["position"] for label, states in trajectory.points.items() if "position" in states}
        row["status"] = off_branch(kinematics, native, points, times) or "ok"
    table = differences(kinematics, trajectory, branch, native=native)
    for column, (quantities, kind) in _ERRORS.items():
        errors = [_worst(table, quantity, kind) for quantity in quantities]
        if any(math.isfinite(e) for e in errors):
            row[column] = max(e for e in errors if math.isfinite(e))
    row["loop_drift"] = loop_drift(trajectory)
    if trajectory.inputs.size:
        law = problem.window.inputs(kinematics, times)[0]
        row["input_error"] = float(np.max(np.abs(np.asarray(trajectory.inputs) - law)))
    row.update(run.columns)
    return row, trajectory if row["status"] == "ok" else None


def _worst(table, quantity: str, kind: str) -> float:
    """The worst error of one quantity over every body and point of a differences table
    (NaN where it has none): SI where ``kind`` is "abs", else against the quantity's
    largest magnitude anywhere in the mechanism (floored; as the runner's categories)."""
    if table.empty:
        return math.nan
    rows = table[table.quantity == quantity]
    if rows.empty:
        return math.nan
    error, scale = float(rows.max_abs.max()), float(rows.scale.max())
    return error if kind == "abs" or scale == 0.0 else error / scale


def off_branch(kinematics: Kinematics, native, points: dict, times) -> str:
    """ "" or when a driven motion left the assembly branch: a named point farther
    than :data:`APART` of the size from the native configuration ``native`` at the
    inputs the engine realised (samples where the native solver did not determine
    a state are passed over). An engine's soft or lagging loops can carry a
    mechanism across a near dead centre onto the other branch (fuzz s1-00018:
    MuJoCo, PyBullet, Drake), a stated result of the engine rather than a
    disagreement in a quantity.

    Parameters
    ----------
    native : Solution
        The native solution at the realised inputs (N samples).
    points : dict of str to ndarray, shape (N, 2)
        Positions (m) of named points as the engine has them.
    times : ndarray, shape (N,)
        The samples' times, s.
    """
    from ..kinematics import Status

    good = native.status <= Status.NEAR_SINGULAR
    gaps = np.zeros(len(good))
    for label, positions in points.items():
        gaps = np.maximum(gaps, np.hypot(*(np.asarray(positions) - native.point(label)["position"]).T))
    off = np.flatnonzero(good & (gaps > APART * kinematics.mechanism.size))
    if not off.size:
        return ""
    i = int(off[0])
    return (
        f"left the assembly branch at t = {float(times[i]):.6g} s: a point {gaps[i]:.3g} m from the native "
        "configuration at the inputs realised"
    )


class DrivenLadder:
    """A driven mode's ladder: every series at its halving steps over the
    simulation window, the first series' finest run the compared one, each run
    made by ``run_once(prepared, problem, rung)`` and judged by one rule; and the
    compared series refined, a rung at a time, for the runner to tell a ladder not
    yet in its asymptotic range from a lower order.

    Parameters
    ----------
    mode : str
    kinematics : Kinematics
    branch : str or None
    series : callable
        The engine's series for a :class:`DrivenProblem` (each with its coarsest
        ``timestep`` and ``rungs``), the compared one first.
    run_once : callable
        One run (:class:`~xcheck.ladder.Run`) of the engine: its trajectory at the
        problem's ``times`` (the inputs, rates and accelerations as realised).
    prepare : callable, optional
        What every run shares, built once; raises
        :class:`~xcheck.errors.NotApplicable` for what the engine cannot hold,
        any other exception for a mode that fails as a whole.
    findings : sequence of Finding
        The engine's stated findings: a row carries the titles of those that
        apply to a driven mode's quantities on this mechanism.
    duration : float, optional
        Simulated time, s (default: the simulation window).
    """

    def __init__(
        self,
        mode: str,
        kinematics: Kinematics,
        branch: str | None,
        series: Callable[[DrivenProblem], Sequence[Series]],
        run_once: Callable[[Any, DrivenProblem, Rung], Run],
        prepare: Callable[[DrivenProblem], Any] | None = None,
        findings: Sequence[Finding] = (),
        duration: float | None = None,
    ):
        self.mode, self.kinematics, self.branch = mode, kinematics, branch
        self._series, self._run_once, self._prepare = series, run_once, prepare
        self.findings, self.duration = tuple(findings), duration
        self._ready: tuple[DrivenProblem, Any, tuple[Series, ...]] | None = None
        #: every run so far: (its row, its trajectory where it counts, its views)
        self.judged: list[tuple[dict, Trajectory | None, list]] = []

    def _start(self) -> tuple[DrivenProblem, Any, tuple[Series, ...]]:
        """The problem, what the runs share and the series, made once (raises as ``prepare``)."""
        if self._ready is None:
            problem = DrivenProblem.of(self.kinematics, self.branch, self.duration)
            prepared = self._prepare(problem) if self._prepare is not None else None
            self._ready = (problem, prepared, tuple(self._series(problem)))
        return self._ready

    def _runs(self, rungs: list[Rung]) -> None:
        """Run and judge ``rungs``, adding them to :attr:`judged`."""
        problem, prepared, _ = self._start()
        mech = self.kinematics.mechanism
        for rung, run in zip(rungs, run_rungs(lambda rung: self._run_once(prepared, problem, rung), rungs)):
            row, trajectory = _driven_row(problem, rung, run)
            row["finding"] = run_titles(
                self.findings, "dynamic", tuple(BODY_QUANTITIES), mech, rung, trajectory is not None
            )
            self.judged.append((row, trajectory, run.views))

    def _result(self, compared: int) -> ModeResult:
        row, _, views = self.judged[compared]
        judged = [(r, t) for r, t, _ in self.judged]
        return ladder_result(
            self.mode, self.kinematics.mechanism.name, judged, driven_floor(self.kinematics), compared, views
        )

    def run(self) -> ModeResult:
        """The whole ladder: its :class:`~xcheck.results.ModeResult` (``summary``: a row
        per run with the columns of :data:`DYNAMIC_COLUMNS` and series, steps,
        simulated (s reached), then the engine's own columns; ``study``; the
        compared run's trajectory first, then its views, then the other runs that
        count). ``ok`` False, with the reason, where the compared run does not count
        or the mode cannot start.

        Raises
        ------
        NotApplicable
            From ``prepare``.
        """
        try:
            problem, _, series = self._start()
        except NotApplicable:
            raise
        except Exception as error:  # noqa: BLE001 - a mode that cannot start is a result with its reason
            return ModeResult(self.mode, self.kinematics.mechanism.name, False, one_line(error))
        if not series:
            return ModeResult(self.mode, self.kinematics.mechanism.name, False, "expected a series to run, found none")
        first = len(self.judged)
        rungs = [problem.rung(s, k) for s in series for k in range(s.rungs)]
        self._runs(rungs)
        return self._result(first + series[0].rungs - 1)

    def refine(self, k: int) -> ModeResult:
        """The ladder with one more run: the compared series at its finest step
        halved ``k`` times (k >= 1), now the compared run, judged with the others."""
        if k < 1:
            raise ValueError(f"expected a refinement of at least 1, found {k}")
        problem, _, series = self._start()
        self._runs([problem.rung(series[0], series[0].rungs - 1 + k)])
        return self._result(len(self.judged) - 1)
