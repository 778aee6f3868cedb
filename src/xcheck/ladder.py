"""One convergence study for every engine: the time-step ladder, run and judged
by one rule whichever engine produced the runs.

A dynamic or free mode is judged by how its error falls as its time step falls.
The ladder's policy lives here, once: which runs make a ladder (the engine's
:class:`Series`, each at halving time steps), which outputs are compared, when
a run has left the reference's branch or only its phase, which errors count
for the order and which are round-off, the observed order (one name,
``order``, computed once), the energy and loop-closure columns, whether a
ladder converges, and which of an engine's stated :class:`Finding` s apply. An
engine supplies only what only it knows: its series, what every run shares
(its model, built once: ``prepare``) and one run at a given series and step
(``run_once``), returning a :class:`Run`: a trajectory, or a stated failure.

:func:`run_rungs` is the one place that runs a ladder's rungs (independent
calls); :func:`free_study` makes a free mode's :class:`~xcheck.results.ModeResult`
from them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import NotApplicable, XcheckError
from .results import ModeResult, Trajectory

if TYPE_CHECKING:
    import pandas as pd

    from .dynamics._free import FreeReference
    from .kinematics import Kinematics
    from .model import Mechanism

__all__ = [
    "APART",
    "COMPARED",
    "FREE_ROUND_OFF",
    "FREE_STEPS",
    "LADDER_COLUMNS",
    "ORDER_MARGIN",
    "STUDY_COLUMNS",
    "Finding",
    "FreeProblem",
    "Run",
    "Rung",
    "Series",
    "applicable_findings",
    "conservative",
    "convergence_study",
    "empty_study",
    "free_errors",
    "free_study",
    "ladder_verdicts",
    "left_branch",
    "observed_order",
    "one_line",
    "out_of_phase",
    "path_distance",
    "run_rungs",
]

#: A fraction of the mechanism's size: a run whose loops open wider has come apart
#: (the engine stops it); one farther than this from every configuration the
#: reference passes through has left the reference's branch; one on the branch
#: whose points are farther than this from the reference's at the same time is
#: out of phase (a large phase error, measured to the end like any other).
APART = 0.1
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
#: Accepted observed orders: at least the expected one less ORDER_MARGIN. An
#: error C h^p (1 + e h) shows the order p - log2(1 + e h) + ... between h and
#: h / 2; a margin of 0.5 is halfway to the next lower integer order, so a
#: lower-order defect (p - 1) fails and the next term may still be a good part
#: of the leading one. A higher order means the error falls at least as fast.
#: A ladder without an expected order converges when every halving shows at
#: least 1 - ORDER_MARGIN, the lowest order an integrator has, so accepted.
ORDER_MARGIN = 0.5
#: the columns of a convergence study
STUDY_COLUMNS = ("series", "timestep", "position_error", "status", "order", "verdict")
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
class Finding:
    """A stated, measured defect of an engine: the quantities it spoils and
    where it holds. A mode failing only in findings that apply is the
    engine's known result (its verdict "finding"), and every ladder row the
    finding applies to carries its title.

    Attributes
    ----------
    title : str
        One line, e.g. "MJX's connect rows lack J-dot qd".
    text : str
        The defect as measured, with its figures and where they come from.
    quantities : tuple of str
        The quantities it spoils (:data:`xcheck.results.BODY_QUANTITIES` names:
        position, angle, velocity, omega, acceleration, alpha).
    kinds : tuple of str
        The kinds of mode it applies to (``kinematic``, ``dynamic``, ``free``).
    closed_loops : bool
        Whether it holds only on a mechanism with closed loops (a joint that the
        spanning tree cuts): an engine's loop constraint plays no part in an
        open chain.
    reproducer : str
        The script that shows the defect to the engine's maintainers, relative to
        the repository (``reproducers/NAME.py``: it imports only that engine and
        numpy, prints the measured numbers beside the expected ones, and exits 0
        while the defect shows); the tests run it where the engine is installed.
        A finding that flags no mode's rows (``kinds`` empty: xcheck's model
        works around the defect, or it shows as the runs' failure) is stated
        for its reproducer.
    series : tuple of str
        The ladder series (:attr:`Series.key`) it holds for, where it is one of
        an engine's solvers (Newton's Featherstone); empty: every series, and
        a driven mode.
    """

    title: str
    text: str
    quantities: tuple[str, ...]
    kinds: tuple[str, ...] = ("kinematic", "dynamic", "free")
    closed_loops: bool = False
    reproducer: str = ""
    series: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """The finding as JSON: title, text, quantities, kinds, closed_loops, reproducer, series."""
        return {
            "title": self.title,
            "text": self.text,
            "quantities": list(self.quantities),
            "kinds": list(self.kinds),
            "closed_loops": self.closed_loops,
            "reproducer": self.reproducer,
            "series": list(self.series),
        }


def applicable_findings(
    findings: Sequence[Finding], kind: str, quantity: str, mechanism: Mechanism, series: str | None = None
) -> list[Finding]:
    """The findings that hold for ``quantity`` of a ``kind`` mode on ``mechanism`` (for a
    ladder's row, of its ``series``): the one rule by which a finding flags a row and
    excuses a failing category. A finding of some series only holds for a row of one of them."""
    if not findings:
        return []
    loops = None
    out = []
    for finding in findings:
        if kind not in finding.kinds or quantity not in finding.quantities:
            continue
        if finding.series and series not in finding.series:
            continue
        if finding.closed_loops:
            if loops is None:
                from .topology import spanning_tree

                loops = bool(spanning_tree(mechanism).cuts)
            if not loops:
                continue
        out.append(finding)
    return out


@dataclass(frozen=True)
class Series:
    """One series of a ladder: what an engine varies apart from the time step.

    Attributes
    ----------
    setting : str
        The setting's short name ("default", "stiff", "best").
    integrator : str
        The integrator and solver as the row shows them.
    options : object
        The engine's own description of the setting (what its one run reads).
    name : str
        What makes the runs of one ladder (default: ``setting``); unique in a ladder.
    scale : float
        Its steps are the ladder's times this (Drake's ``best``: a quarter).
    """

    setting: str
    integrator: str
    options: Any = None
    name: str = ""
    scale: float = 1.0

    @property
    def key(self) -> str:
        """The series' name: ``name``, or ``setting`` without one."""
        return self.name or self.setting


@dataclass(frozen=True)
class Rung:
    """One run of a ladder: a series at a time step.

    Attributes
    ----------
    series : Series
    timestep : float
        s.
    counts : tuple of int
        Free motion: the steps between consecutive compared outputs (one fewer
        than the outputs); empty where ``misfit``.
    misfit : str
        Why the step cannot be run ("" where it can): it does not divide the output step.
    """

    series: Series
    timestep: float
    counts: tuple[int, ...] = ()
    misfit: str = ""


@dataclass
class Run:
    """One run as an engine returns it.

    Attributes
    ----------
    trajectory : Trajectory or None
        The states at the compared outputs the run reached (free motion: the
        first of :attr:`FreeProblem.times`, positions and angles, angles
        continuous from the start's), with ``diagnostics``
        ``constraint_violation`` (m, the loops' opening as the engine holds
        them, per sample) and, where the engine knows it, ``energy`` (J, kinetic
        and potential energy less the constant loads' potential, per sample).
        None where no output was reached.
    failure : str
        Why the run stopped before the end ("" where it ran through): it went
        non-finite, came apart, its solver gave up.
    cpu_seconds : float
        The run's CPU time, s (NaN: the ladder's clock around the call).
    columns : dict
        The engine's own columns of the row (compile time, solver figures).
    """

    trajectory: Trajectory | None
    failure: str = ""
    cpu_seconds: float = math.nan
    columns: dict = field(default_factory=dict)


def one_line(error: BaseException) -> str:
    """An exception as one line: its message, after its type's name unless it is
    an error xcheck states for a user (XcheckError, ValueError)."""
    text = " ".join(str(error).split())
    if isinstance(error, (XcheckError, ValueError, NotApplicable)) and text:
        return text
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def run_rungs(call: Callable[[Rung], Run], rungs: Sequence[Rung]) -> list[Run]:
    """Every rung's run, in order: ``call(rung)`` for each rung that fits, each
    an independent call (the one place a ladder's runs are made). A rung that
    does not fit, or whose call raises, is a failed :class:`Run` with the reason;
    a run without its own CPU time gets the call's."""
    runs = []
    for rung in rungs:
        if rung.misfit:
            runs.append(Run(None, rung.misfit))
            continue
        begin = time.process_time()
        try:
            run = call(rung)
        except NotApplicable:
            raise
        except Exception as error:  # noqa: BLE001 - a run that fails is a row with its reason
            run = Run(None, one_line(error))
        if not math.isfinite(run.cpu_seconds):
            run.cpu_seconds = time.process_time() - begin
        runs.append(run)
    return runs


# --- the convergence study ---------------------------------------------------------------------------------------


def observed_order(
    coarse_error: float, fine_error: float, coarse_step: float, fine_step: float, floor: float = 0.0
) -> float:
    """The observed order of convergence between two runs,
    log(e_coarse / e_fine) / log(h_coarse / h_fine).

    Parameters
    ----------
    coarse_error, fine_error : float
        The errors of the runs at the time steps ``coarse_step`` and
        ``fine_step`` (any consistent units).
    floor : float
        Errors at or below this are round-off: no order.

    Returns
    -------
    float
        NaN where either error is not finite or not above ``floor``, or the
        steps are equal or not positive.
    """
    values = (coarse_error, fine_error, coarse_step, fine_step)
    if not all(math.isfinite(float(v)) for v in values):
        return math.nan
    if coarse_error <= floor or fine_error <= floor or coarse_error <= 0.0 or fine_error <= 0.0:
        return math.nan
    if coarse_step <= 0.0 or fine_step <= 0.0 or coarse_step == fine_step:
        return math.nan
    return math.log(coarse_error / fine_error) / math.log(coarse_step / fine_step)


def empty_study() -> pd.DataFrame:
    """A convergence study without runs."""
    import pandas as pd

    return pd.DataFrame(columns=list(STUDY_COLUMNS))


def convergence_study(series, timestep, position_error, status, floor: float = 0.0) -> pd.DataFrame:
    """A ladder's error against time step, in one shape for every engine.

    Parameters
    ----------
    series : sequence of str
        What makes runs of one ladder (integrator and settings), per run.
    timestep : sequence of float
        Time step of each run, s.
    position_error : sequence of float
        Largest position error of each run, m.
    status : sequence of str
        "ok" or why the run does not count, one line: its error is not used.
    floor : float
        Errors at or below this (m) are round-off: no order.

    Returns
    -------
    DataFrame
        The columns of :data:`STUDY_COLUMNS`, sorted by series then falling
        time step; ``order`` is :func:`observed_order` between a run and the
        previous (coarser) run of its series that counts, NaN for the first and
        for a run that does not count; ``verdict`` is its series' (the same on
        each of its rows): "converging" where every halving that counts shows an
        order of at least 1 - :data:`ORDER_MARGIN` or falls to the floor,
        "within round-off" where every error that counts is at or below it,
        "not converging" where the error does not fall with the step, "cannot
        tell" where fewer than two runs count (:func:`ladder_verdicts` says it
        in words).
    """
    import pandas as pd

    table = pd.DataFrame(
        {
            "series": [str(v) for v in series],
            "timestep": np.asarray(timestep, dtype=float),
            "position_error": np.asarray(position_error, dtype=float),
            "status": [str(v) for v in status],
        }
    )
    table = table.sort_values(["series", "timestep"], ascending=[True, False], kind="stable").reset_index(drop=True)
    names, steps = list(table["series"]), table["timestep"].to_numpy()
    errors, counts = table["position_error"].to_numpy(), (table["status"] == "ok").to_numpy()
    counts = counts & np.isfinite(errors)
    orders = [math.nan] * len(table)
    falls: dict[str, list[bool]] = {}  # series -> whether each halving that counts falls fast enough
    last: dict[str, int] = {}  # series -> its previous run that counts
    for i, name in enumerate(names):
        if not counts[i]:
            continue
        if name in last:
            j = last[name]
            orders[i] = observed_order(errors[j], errors[i], steps[j], steps[i], floor)
            order = observed_order(errors[j], errors[i], steps[j], steps[i])
            falls.setdefault(name, []).append(errors[i] <= floor or order >= 1.0 - ORDER_MARGIN)
        last[name] = i
    table["order"] = orders
    verdicts = {}
    for name in dict.fromkeys(names):
        counted = errors[[n == name and c for n, c in zip(names, counts)]]
        if len(counted) < 2:
            verdicts[name] = "cannot tell"
        elif np.all(counted <= floor):
            verdicts[name] = "within round-off"
        else:
            verdicts[name] = "converging" if all(falls.get(name, [])) else "not converging"
    table["verdict"] = [verdicts[name] for name in names]
    return table


def ladder_verdicts(study: pd.DataFrame) -> dict[str, str]:
    """Each series' verdict of a :func:`convergence_study` in words, with the
    figures behind it: "converging (orders 1.00, 1.00)", "not converging
    (0.0531, 0.0531, 0.0531 m as the step halves)", "within round-off (...)",
    "cannot tell: 1 of 3 runs went through"."""
    out = {}
    for name, part in study.groupby("series", sort=False):
        verdict = str(part["verdict"].iloc[0]) if "verdict" in part else ""
        counted = part[(part.status == "ok") & np.isfinite(part.position_error.to_numpy(dtype=float))]
        shown = ", ".join(f"{e:.3g}" for e in counted.position_error)
        orders = [f"{o:.2f}" for o in counted.order if math.isfinite(o)]
        if verdict == "converging":
            out[str(name)] = f"converging (orders {', '.join(orders)})" if orders else "converging to round-off"
        elif verdict == "not converging":
            out[str(name)] = f"not converging ({shown} m as the step halves)"
        elif verdict == "within round-off":
            out[str(name)] = f"within round-off ({shown} m)"
        else:
            out[str(name)] = f"cannot tell: {len(counted)} of {len(part)} runs went through"
    return out


# --- free motion -------------------------------------------------------------------------------------------------


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

    def steps(self, steps: Sequence[float] = FREE_STEPS) -> tuple[float, ...]:
        """A ladder's time steps (s, coarsest first) for this reference: as given
        where the coarsest is at most the output step, else all scaled down by the
        same factor so that the coarsest is a tenth of it (a 0.03 s squeeze with
        outputs every 0.1 ms gets 10, 5, 2.5 us instead of 1, 0.5, 0.25 ms)."""
        output = self.output_step
        factor = 1.0 if float(steps[0]) <= output else output / (10.0 * float(steps[0]))
        return tuple(float(s) * factor for s in steps)

    def rung(self, series: Series, timestep: float) -> Rung:
        """The rung of ``series`` at ``timestep`` (s): its steps between compared
        outputs, or why the step does not fit (it must divide the output step)."""
        output = self.output_step
        per_output = max(1, int(round(output / timestep)))
        if abs(per_output * timestep - output) > 1e-9 * output:
            return Rung(series, timestep, misfit=f"the step does not divide the output step ({output:g} s)")
        return Rung(series, timestep, tuple(int(n) * per_output for n in np.diff(self.index)))

    def came_apart(self, t: float, gap: float) -> str:
        """ "" or the failure of a run whose loops are ``gap`` (m) open at ``t`` (s):
        the check every engine makes at each compared output."""
        if not math.isfinite(gap):
            return f"went non-finite at t = {t:.6g} s"
        if gap > self.apart:
            return f"came apart at t = {t:.6g} s (loops {gap:.3g} m open)"
        return ""


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


def _point_gaps(trajectory: Trajectory, native, index: np.ndarray) -> np.ndarray:
    """The largest distance (m) of a named point from the reference's at each sample (N,)."""
    position = np.zeros(len(index))
    for label, states in trajectory.points.items():
        if "position" in states:
            gap = np.asarray(states["position"]) - native.point(label)["position"][index]
            position = np.maximum(position, np.hypot(gap[:, 0], gap[:, 1]))
    return position


def path_distance(reference: FreeReference, trajectory: Trajectory) -> np.ndarray:
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


def left_branch(reference: FreeReference, trajectory: Trajectory, limit: float) -> str:
    """ "" if every sample of ``trajectory`` lies within ``limit`` (m) of the reference's
    path (:func:`path_distance`: a run out of phase on the branch stays near it), else
    the status of a run that left the branch: when, and how far it was then."""
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


def out_of_phase(reference: FreeReference, trajectory: Trajectory, limit: float) -> str:
    """ "" if every named point stays within ``limit`` (m) of the reference's at the
    same time, else when the run fell out of phase (for a run on the branch:
    :func:`left_branch` found it near the reference's path throughout)."""
    times = np.asarray(trajectory.times)
    index = np.searchsorted(reference.motion.times, times - TIME_MATCH)
    gaps = _point_gaps(trajectory, reference.motion.solution(), index)
    off = np.flatnonzero(gaps > limit)
    if not off.size:
        return ""
    return f"out of phase from t ≈ {float(times[int(off[0])]):.4g} s"


def conservative(mechanism: Mechanism) -> bool:
    """Whether energy less the constant loads' potential is conserved: no damper and
    no load with a time law."""
    dampers = any(s.damping for s in mechanism.springs) or any(s.damping for s in mechanism.rotational_springs)
    return not dampers and all(load.law is None for load in mechanism.loads)


def _free_row(problem: FreeProblem, rung: Rung, run: Run, titles: str) -> tuple[dict, Trajectory | None]:
    """A free run judged: (its row, its trajectory where it counts, else None)."""
    mech = problem.kinematics.mechanism
    series = rung.series
    row: dict = {
        "setting": series.setting,
        "series": series.key,
        "integrator": series.integrator,
        "timestep": rung.timestep,
        "steps": int(sum(rung.counts)),
        "status": run.failure or "ok",
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
        "finding": titles,
    }
    trajectory = run.trajectory
    if trajectory is None or trajectory.times is None or not len(trajectory.times):
        if row["status"] == "ok":
            row["status"] = "no output reached"
        row.update(run.columns)
        return row, None
    if len(trajectory.times) < len(problem.index) and row["status"] == "ok":
        row["status"] = f"stopped at t = {float(trajectory.times[-1]):.6g} s"
    simulated = float(trajectory.times[-1] - trajectory.times[0])
    row["simulated"] = simulated
    if simulated > 0.0:
        row["cpu_per_simulated_second"] = run.cpu_seconds / simulated
    errors = free_errors(problem.reference, trajectory)
    row.update({key: errors[key] for key in ("position_error", "final_error", "angle_error")})
    diagnostics = trajectory.diagnostics
    if "constraint_violation" in diagnostics and len(diagnostics["constraint_violation"]):
        row["loop_drift"] = float(np.max(diagnostics["constraint_violation"]))
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
    steps: Sequence[float] = FREE_STEPS,
) -> ModeResult:
    """A free mode's ladder against the native reference: every series at the
    ladder's steps (``steps``, fitted to the reference's outputs by
    :meth:`FreeProblem.steps` and scaled by the series' ``scale``), each run
    made by ``run_once(prepared, problem, rung)`` and judged by one rule.

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
    steps : sequence of float
        The ladder's time steps, s, coarsest first (default :data:`FREE_STEPS`).

    Returns
    -------
    ModeResult
        ``summary``: one row per run with every column of :data:`LADDER_COLUMNS`
        and series, steps, angle_error (rad), simulated (s reached),
        cpu_seconds, then the engine's own columns; status is "ok" or why the
        run does not count (it stopped: its errors are those of the outputs it
        reached; it left the reference's branch: measured to the end); phase
        says when a run on the branch fell out of phase; ``study``:
        :func:`convergence_study` of the runs that count, the reference's
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
    rungs = [problem.rung(s, step * s.scale) for s in series for step in problem.steps(steps)]
    runs = run_rungs(lambda rung: run_once(prepared, problem, rung), rungs)
    titles = {
        key: "; ".join(f.title for f in applicable_findings(findings, "free", "position", mech, key))
        for key in dict.fromkeys(rung.series.key for rung in rungs)
    }
    judged = [_free_row(problem, rung, run, titles[rung.series.key]) for rung, run in zip(rungs, runs)]
    return ladder_result(mode, mech.name, judged, free_floor(problem))


def free_floor(problem: FreeProblem) -> float:
    """The round-off floor of a free ladder's errors, m: the reference's stated
    error (an engine's error within it is not measured), at least
    :data:`FREE_ROUND_OFF` of the size."""
    return max(float(np.max(problem.reference.estimate)), FREE_ROUND_OFF * problem.kinematics.mechanism.size)


def ladder_result(mode: str, mechanism: str, judged: list[tuple[dict, Trajectory | None]], floor: float) -> ModeResult:
    """A ladder's ModeResult from its judged runs (row, trajectory where it counts):
    the summary with each row's ``order`` from the study, the study, and the
    counting runs' trajectories, the most accurate first."""
    import pandas as pd

    summary = pd.DataFrame([row for row, _ in judged])
    study = convergence_study(
        summary["series"], summary["timestep"], summary["position_error"], summary["status"], floor
    )
    order = study.set_index(["series", "timestep"])["order"]
    summary["order"] = [float(order.get((r.series, r.timestep), math.nan)) for r in summary.itertuples()]
    counted = sorted((row["position_error"], i) for i, (row, t) in enumerate(judged) if t is not None)
    trajectories = [judged[i][1] for _, i in counted]
    if not trajectories:
        first = judged[0][0]
        reason = f"no run went through ({first['series']} dt = {first['timestep']:.4g} s: {first['status']})"
        return ModeResult(mode, mechanism, False, reason, [], summary, study)
    return ModeResult(mode, mechanism, True, "", trajectories, summary, study)
