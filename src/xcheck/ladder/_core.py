"""What every ladder shares: an engine's series and one run, the rungs and how
they are run, the findings that apply."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import NotApplicable, XcheckError
from ..results import Trajectory

if TYPE_CHECKING:
    from ..model import Mechanism

#: A fraction of the mechanism's size: a run whose loops open wider has come apart
#: (the engine stops it); one farther than this from every configuration the
#: reference passes through has left the reference's branch; one on the branch
#: whose points are farther than this from the reference's at the same time is
#: out of phase (a large phase error, measured to the end like any other).
APART = 0.1
#: Accepted observed orders: at least the expected one less ORDER_MARGIN. An
#: error C h^p (1 + e h) shows the order p - log2(1 + e h) + ... between h and
#: h / 2; a margin of 0.5 is halfway to the next lower integer order, so a
#: lower-order defect (p - 1) fails and the next term may still be a good part
#: of the leading one. A higher order means the error falls at least as fast.
#: A ladder without an expected order converges when every halving shows at
#: least 1 - ORDER_MARGIN, the lowest order an integrator has, so accepted.
ORDER_MARGIN = 0.5


#: The kind of a force source (an engine's joint reactions and driving efforts), beside
#: the modes' kinds: a finding with it in its ``kinds`` holds for the engine's reactions.
REACTIONS = "reactions"
#: The quantities of a force source a finding can spoil
#: (:data:`xcheck.dynamics.JOINT_QUANTITIES` and :data:`~xcheck.dynamics.DRIVER_QUANTITIES`).
FORCE_QUANTITIES = ("reaction", "normal", "moment", "tooth_force", "effort")
#: The quantity of a finding whose defect makes a run fail as a whole (come apart,
#: turn non-finite) rather than miss: a mode or force source that fails where it
#: holds has the engine's known result, and its failure line names it.
FAILURE = "failure"


@dataclass(frozen=True)
class Finding:
    """A stated, measured defect of an engine: the quantities it spoils and
    where it holds. A mode or force source failing only in findings that apply
    is the engine's known result (its verdict "finding"), and every ladder row
    the finding applies to carries its title.

    Attributes
    ----------
    title : str
        One line, e.g. "MJX's connect rows lack J-dot qd".
    text : str
        The defect as measured, with its figures and where they come from.
    quantities : tuple of str
        The quantities it spoils: :data:`xcheck.results.BODY_QUANTITIES` names
        (position, angle, velocity, omega, acceleration, alpha), a force
        source's (:data:`FORCE_QUANTITIES`), or :data:`FAILURE`: the runs fail.
    kinds : tuple of str
        What it applies to: the kinds of mode (``kinematic``, ``dynamic``,
        ``free``) and :data:`REACTIONS`, the engine's force source.
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
        works around the defect) is stated for its reproducer.
    series : tuple of str
        The ladder series (:attr:`Series.key`) it holds for, where it is one of
        an engine's solvers (Newton's Featherstone); empty: every series.
    steps_below : float or None
        It holds only for runs at a time step below this, s (where the defect was
        measured); None: at any step.
    mechanisms : callable or None
        It holds only on a mechanism for which this returns True (what in a
        mechanism the defect needs, as only its engine knows); None: on any.
    mechanisms_text : str
        What ``mechanisms`` asks, in words (e.g. "a driven body that is a point mass").
    """

    title: str
    text: str
    quantities: tuple[str, ...]
    kinds: tuple[str, ...] = ("kinematic", "dynamic", "free")
    closed_loops: bool = False
    reproducer: str = ""
    series: tuple[str, ...] = ()
    steps_below: float | None = None
    mechanisms: Callable[[Mechanism], bool] | None = None
    mechanisms_text: str = ""

    def as_dict(self) -> dict:
        """The finding as JSON: title, text, quantities, kinds, closed_loops, reproducer, series,
        steps_below (s, or None) and mechanisms (``mechanisms_text``, or None)."""
        return {
            "title": self.title,
            "text": self.text,
            "quantities": list(self.quantities),
            "kinds": list(self.kinds),
            "closed_loops": self.closed_loops,
            "reproducer": self.reproducer,
            "series": list(self.series),
            "steps_below": self.steps_below,
            "mechanisms": self.mechanisms_text or None,
        }

    @property
    def scope(self) -> str:
        """Where it holds, in words: its kinds, quantities and conditions; "flags no
        mode's rows" where ``kinds`` is empty."""
        if not self.kinds:
            return "flags no mode's rows"
        kinds = [f"{k} modes" if k != REACTIONS else "reactions" for k in self.kinds]
        parts = [", ".join(kinds), ", ".join("the runs fail" if q == FAILURE else q for q in self.quantities)]
        parts += ["closed loops only"] if self.closed_loops else []
        parts += [f"series {', '.join(self.series)}"] if self.series else []
        parts += [f"time steps below {self.steps_below:g} s"] if self.steps_below is not None else []
        parts += [self.mechanisms_text] if self.mechanisms_text else []
        return "; ".join(parts)


def applicable_findings(
    findings: Sequence[Finding],
    kind: str,
    quantity: str,
    mechanism: Mechanism,
    series: str | None = None,
    timestep: float | None = None,
) -> list[Finding]:
    """The findings that hold for ``quantity`` (or :data:`FAILURE`) of a ``kind`` mode
    or force source (:data:`REACTIONS`) on ``mechanism``, for a run of ``series`` at
    ``timestep`` (s): the one rule by which a finding flags a row and excuses a
    failing category, force source or run. A finding of some series only holds for
    a run of one of them, one below a time step only for a run with a smaller one."""
    if not findings:
        return []
    loops = None
    out = []
    for finding in findings:
        if kind not in finding.kinds or quantity not in finding.quantities:
            continue
        if finding.series and series not in finding.series:
            continue
        if finding.steps_below is not None and not (timestep is not None and timestep < finding.steps_below):
            continue
        if finding.closed_loops:
            if loops is None:
                from ..topology import spanning_tree

                loops = bool(spanning_tree(mechanism).cuts)
            if not loops:
                continue
        if finding.mechanisms is not None and not finding.mechanisms(mechanism):
            continue
        out.append(finding)
    return out


def finding_titles(
    findings: Sequence[Finding],
    kind: str,
    quantities: Sequence[str],
    mechanism: Mechanism,
    series: str,
    timestep: float | None = None,
) -> str:
    """The titles (joined by "; ") of the findings that hold for any of ``quantities``
    on a ``kind`` ladder's row of ``series`` at ``timestep`` (s) on ``mechanism``: its
    ``finding`` column."""
    found = [f for q in quantities for f in applicable_findings(findings, kind, q, mechanism, series, timestep)]
    return "; ".join(dict.fromkeys(f.title for f in found))


def run_titles(
    findings: Sequence[Finding], kind: str, quantities: Sequence[str], mechanism: Mechanism, rung: Rung, counts: bool
) -> str:
    """The ``finding`` column of a ``kind`` ladder's row for the run at ``rung``: the
    titles of the findings that hold for its ``quantities`` at its series and step, and
    for :data:`FAILURE` where the run does not count (it failed)."""
    judged = (*quantities, *(() if counts else (FAILURE,)))
    return finding_titles(findings, kind, judged, mechanism, rung.series.key, rung.timestep)


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
    timestep : float or None
        Its coarsest time step, s (None: the ladder's: :data:`FREE_STEPS`'s first
        in free motion); the ladder fits it to the outputs it compares.
    rungs : int
        Its runs, the step halving from one to the next.
    """

    setting: str
    integrator: str
    options: Any = None
    name: str = ""
    timestep: float | None = None
    rungs: int = 3

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
        The steps between consecutive compared outputs (one fewer than the
        outputs); empty where ``misfit``.
    misfit : str
        Why the step cannot be run ("" where it can): it does not divide the output step.
    """

    series: Series
    timestep: float
    counts: tuple[int, ...] = ()
    misfit: str = ""

    @property
    def settings(self) -> dict:
        """What every run's trajectory states of its settings: setting, integrator,
        timestep (s) and series (:attr:`Series.key`, what makes the runs of one ladder)."""
        series = self.series
        return {
            "setting": series.setting,
            "integrator": series.integrator,
            "timestep": self.timestep,
            "series": series.key,
        }


@dataclass
class Run:
    """One run as an engine returns it.

    Attributes
    ----------
    trajectory : Trajectory or None
        The states at the compared outputs the run reached (the first of the
        problem's ``times``; angles continuous from the start's; free motion:
        positions and angles; driven: the inputs, rates and accelerations as
        the engine realised them and what it gives of each body's and point's
        quantities), with ``diagnostics`` ``constraint_violation`` (m, the
        loops' opening as the engine holds them, per sample) and, in free
        motion where the engine knows it, ``energy`` (J, kinetic and potential
        energy less the constant loads' potential, per sample). None where no
        output was reached.
    failure : str
        Why the run stopped before the end ("" where it ran through): it went
        non-finite, came apart, its solver gave up.
    cpu_seconds : float
        The run's CPU time, s (NaN: the ladder's clock around the call).
    columns : dict
        The engine's own columns of the row (compile time, solver figures).
    views : list of Trajectory
        The same states seen otherwise (MuJoCo's accelerations from its
        kinematic oracle), shown after the run where it is the compared one.
    """

    trajectory: Trajectory | None
    failure: str = ""
    cpu_seconds: float = math.nan
    columns: dict = field(default_factory=dict)
    views: list = field(default_factory=list)


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


def ladder_row(rung: Rung, run: Run, measured: dict) -> dict:
    """A run's row before it is judged, the same for every ladder: what names the run
    (setting, series, integrator, timestep in s, steps), its status (the run's
    failure, else "ok"), the ``measured`` columns as given (NaN until judged) and
    its ``finding`` column, empty until judged (:func:`run_titles`)."""
    series = rung.series
    return {
        "setting": series.setting,
        "series": series.key,
        "integrator": series.integrator,
        "timestep": rung.timestep,
        "steps": int(sum(rung.counts)),
        "status": run.failure or "ok",
        **measured,
        "finding": "",
    }


def reached(row: dict, run: Run, expected: int, nothing: str) -> np.ndarray | None:
    """The times (s) of the samples ``run`` reached, to be judged; None where it reached
    none (its ``row``'s status then says ``nothing``, where the run stated no failure,
    and takes the run's own columns). A run that stopped short of the ``expected``
    samples without a stated failure has the time it stopped as its status."""
    trajectory = run.trajectory
    if trajectory is None or trajectory.times is None or not len(trajectory.times):
        if row["status"] == "ok":
            row["status"] = nothing
        row.update(run.columns)
        return None
    times = np.asarray(trajectory.times, dtype=float)
    if len(times) < expected and row["status"] == "ok":
        row["status"] = f"stopped at t = {times[-1]:.6g} s"
    return times


def loop_drift(trajectory: Trajectory) -> float:
    """The widest the loops opened over a run (its ``constraint_violation``
    diagnostic), in the mechanism's length unit; NaN where the engine gives none."""
    gaps = trajectory.diagnostics.get("constraint_violation")
    return float(np.max(gaps)) if gaps is not None and len(gaps) else math.nan


def conservative(mechanism: Mechanism) -> bool:
    """Whether energy less the constant loads' potential is conserved: no damper and
    no load with a time law."""
    dampers = any(s.damping for s in mechanism.springs) or any(s.damping for s in mechanism.rotational_springs)
    return not dampers and all(load.law is None for load in mechanism.loads)


def came_apart(t: float, gap: float, size: float) -> str:
    """ "" or the failure of a run whose loops are ``gap`` (m) open at ``t`` (s) on a
    mechanism of ``size`` (m): non-finite, or wider than :data:`APART` of the size.
    The check every engine makes at each compared output, free or driven."""
    if not math.isfinite(gap):
        return f"went non-finite at t = {t:.6g} s"
    if gap > APART * size:
        return f"came apart at t = {t:.6g} s (loops {gap:.3g} m open)"
    return ""
