"""The engine contract's conformance suite: :func:`check_engine` runs an engine
(built in or a plug-in) through what :mod:`xcheck.engines` promises, on small
bundled mechanisms, and names every promise it breaks.

Call it from an engine's own tests::

    from xcheck.testing import check_engine

    def test_my_engine_keeps_the_contract():
        check_engine(MyEngine())

What it checks, each a promise of the contract (``engines/_contract.py``, the
ladder's :class:`~xcheck.ladder.Run`, CONTRIBUTING's engine part):

- the declaration: a name that is not reserved, modes with a kind among
  :data:`~xcheck.engines.KINDS` and unique names, a reason for each mode run
  only on request, a positive cost, a force tolerance beside a force order;
- availability: :meth:`~xcheck.engines.Engine.available` is one line, never an
  exception, and says "not installed" where a required package is missing (then
  no mode runs: each is skipped with that reason);
- stated findings: a one-line title, a text, quantities and kinds xcheck knows,
  and a reproducer ``reproducers/ENGINE_what.py``;
- each mode runs, or raises :class:`~xcheck.engines.NotApplicable` with a reason,
  or fails as data (``ok`` False with a one-line reason), never another
  exception: a kinematic mode on the bundled four-bar (a few samples), a dynamic
  mode's ladder on it (its first series, two rungs, a short window, then
  refined once as the runner does), a free mode's ladder on the bundled simple
  pendulum (IFToMM A01, 0.05 s; its first series, two rungs);
- every trajectory and run: the stated shapes (N samples of each quantity,
  bodies and points of the mechanism), positions in metres (within ten sizes of
  the mechanism's reach), finite numbers or a stated failure, a run stopped
  where its loops come apart, the compared output times, and each run's settings
  naming its time step and series;
- where declared, :meth:`~xcheck.engines.Engine.export_files` (file names to
  text) and :meth:`~xcheck.engines.Engine.inverse_dynamics` (a
  :class:`~xcheck.dynamics.Forces`, with ``refine=1`` where a force order is stated).

It judges the contract, not accuracy: errors and orders are the runner's
verdict. The contract promises no determinism, so none is checked.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from .engines import KINDS, Engine, NotApplicable
from .engines._contract import _installed
from .ladder import APART, FAILURE, FORCE_QUANTITIES, REACTIONS, Run
from .results import BODY_QUANTITIES, POINT_QUANTITIES, ModeResult, Trajectory

if TYPE_CHECKING:
    from .dynamics._free import FreeReference
    from .kinematics import Kinematics

__all__ = ["ContractBroken", "EngineCheck", "check_engine"]

#: samples of a kinematic mode's sweep
SAMPLES = 5
#: simulated time of a dynamic mode's ladder, s (at most the drivers' window)
DRIVEN_DURATION = 0.05
#: simulated time of a free mode's ladder, s (five output steps of the pendulum)
FREE_DURATION = 0.05
#: runs of each checked series
RUNGS = 2
#: positions farther than this many sizes beyond the mechanism's reach are not in metres
REACH_SIZES = 10.0
#: output times must match the compared ones to this (s)
TIME_MATCH = 1e-9


class ContractBroken(AssertionError):
    """An engine breaks promises of the contract; the message has one line per broken promise."""


@dataclass
class EngineCheck:
    """What :func:`check_engine` found.

    Attributes
    ----------
    engine : str
    broken : list of str
        One line per broken promise: ``ENGINE: MODE: PROMISE: what was found``.
    skipped : dict of str to str
        Modes not run, with the reason (not installed, not applicable).
    ran : list of str
        Modes that ran to a result (ok or a stated failure).
    """

    engine: str
    broken: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)
    ran: list[str] = field(default_factory=list)

    def breaks(self, where: str, promise: str, found: str) -> None:
        """Record a broken promise of the engine (``where``: a mode, or "engine"),
        once: the first thing found that breaks it."""
        head = f"{self.engine}: {where}: {promise}: "
        if not any(line.startswith(head) for line in self.broken):
            self.broken.append(head + found)


def check_engine(
    engine: Engine | type[Engine], modes: Sequence[str] | None = None, *, raises: bool = True
) -> EngineCheck:
    """Run an engine through the promises of the engine contract.

    Parameters
    ----------
    engine : Engine or Engine subclass
    modes : sequence of str, optional
        The modes to run (default: every declared mode); the declaration is
        checked whole either way.
    raises : bool
        Raise :class:`ContractBroken` where a promise is broken (else only
        return what was found).

    Returns
    -------
    EngineCheck
        The broken promises (none where it passes), the modes skipped with why
        (the engine is not available here; :class:`~xcheck.engines.NotApplicable`)
        and the modes that ran.

    Raises
    ------
    ContractBroken
        With ``raises``: one line per broken promise, each naming the engine,
        the mode (or "engine") and the promise.
    """
    instance = engine() if isinstance(engine, type) else engine
    check = EngineCheck(getattr(instance, "name", "") or type(instance).__name__)
    if not isinstance(instance, Engine):
        check.breaks("engine", "is an xcheck.engines.Engine", f"found {type(instance).__name__}")
    else:
        _check_declaration(instance, check)
        reason = _check_availability(instance, check)
        declared = {m.name: m.kind for m in instance.modes}
        chosen = list(declared) if modes is None else list(modes)
        for name in chosen:
            if name not in declared:
                raise ValueError(f"expected a mode of {check.engine} ({', '.join(declared)}), found {name!r}")
            if reason:
                check.skipped[name] = reason
            else:
                _check_mode(instance, name, declared[name], check)
        if not reason:
            _check_files(instance, check)
    if raises and check.broken:
        raise ContractBroken(
            f"{check.engine} breaks {len(check.broken)} promise(s) of the engine contract:\n" + "\n".join(check.broken)
        )
    return check


# -- the declaration ---------------------------------------------------------------------------


def _one_line(text: object) -> bool:
    return isinstance(text, str) and bool(text.strip()) and "\n" not in text


def _check_declaration(engine: Engine, check: EngineCheck) -> None:
    from .engines._registry import ALL
    from .ladder import Finding

    if not engine.name or engine.name in (ALL, "native"):
        check.breaks("engine", "declares a name of its own", f"found {engine.name!r}")
    if not engine.modes:
        check.breaks("engine", "declares its modes", "found none")
    names = [m.name for m in engine.modes]
    for name in sorted({n for n in names if names.count(n) > 1}):
        check.breaks(name, "names each mode once", f"declared {names.count(name)} times")
    for mode in engine.modes:
        if mode.kind not in KINDS:
            check.breaks(mode.name, "declares a kind among " + ", ".join(KINDS), f"found {mode.kind!r}")
        if mode.on_request and not _one_line(mode.on_request_reason):
            check.breaks(mode.name, "says in one line why it runs only on request", "found no reason")
        if not (isinstance(mode.cost, (int, float)) and math.isfinite(mode.cost) and mode.cost > 0):
            check.breaks(mode.name, "states a positive cost (CPU s)", f"found {mode.cost!r}")
    if engine.force_order is not None and engine.force_tolerance is None:
        check.breaks("engine", "states a force tolerance beside its force order", "found force_tolerance None")
    for finding in engine.findings:
        where = f"finding {getattr(finding, 'title', finding)!r}"
        if not isinstance(finding, Finding):
            check.breaks("engine", "states findings as xcheck.engines.Finding", f"found {type(finding).__name__}")
            continue
        problems = []
        if not _one_line(finding.title):
            problems.append("a one-line title")
        if not str(finding.text).strip():
            problems.append("the measured defect in its text")
        known = (*BODY_QUANTITIES, *FORCE_QUANTITIES, FAILURE)
        if not finding.quantities or set(finding.quantities) - set(known):
            problems.append(f"quantities among {', '.join(known)} (found {list(finding.quantities)})")
        if set(finding.kinds) - {*KINDS, REACTIONS}:
            problems.append(f"kinds among {', '.join((*KINDS, REACTIONS))} (found {list(finding.kinds)})")
        if REACTIONS in finding.kinds and engine.force_tolerance is None:
            problems.append("reactions only where the engine gives them (found kinds with reactions)")
        name = finding.reproducer.rpartition("/")[2]
        if not (finding.reproducer.startswith("reproducers/") and name.startswith(f"{engine.name}_")):
            problems.append(f"a reproducer reproducers/{engine.name}_WHAT.py (found {finding.reproducer!r})")
        elif not name.endswith(".py"):
            problems.append(f"a reproducer script ending in .py (found {finding.reproducer!r})")
        for problem in problems:
            check.breaks("engine", f"states its {where} with {problem.split(' (')[0]}", problem)


def _check_availability(engine: Engine, check: EngineCheck) -> str:
    """Check :meth:`Engine.available`; its reason ("" where the engine can run here)."""
    try:
        reason = engine.available()
    except Exception as error:  # noqa: BLE001 - the broken promise is the finding
        check.breaks("engine", "says whether it can run, never raising", _error(error))
        return _error(error)
    if not isinstance(reason, str) or (reason and not _one_line(reason)):
        check.breaks("engine", "says in one line why it cannot run", f"found {reason!r}")
        return str(reason) or "unavailable"
    missing = [name for name in engine.requires if not _installed(name)]
    if missing and "not installed" not in reason:
        check.breaks(
            "engine",
            "says a missing package is not installed",
            f"{', '.join(missing)} missing, available() says {reason!r}",
        )
        return reason or f"not installed: {', '.join(missing)}"
    return reason


def _error(error: BaseException) -> str:
    from .ladder import one_line

    return one_line(error)


# -- the bundled mechanisms --------------------------------------------------------------------


@lru_cache(maxsize=None)
def _kinematics(name: str) -> Kinematics:
    from .catalog import _BUNDLED
    from .kinematics import Kinematics
    from .model import load_mechanism

    path = _BUNDLED / f"{name}.toml"
    if not path.exists():
        path = _BUNDLED / "benchmarks" / f"{name}.toml"
    return Kinematics(load_mechanism(path))


@lru_cache(maxsize=None)
def _reference() -> FreeReference:
    from .dynamics._free import simulate

    return simulate(_kinematics("iftomm-a01"), duration=FREE_DURATION)


def _reach(kinematics: Kinematics, positions: Sequence[np.ndarray]) -> float:
    """The farthest a position in metres can be: the mechanism's reach plus ten sizes."""
    mech = kinematics.mechanism
    farthest = max((float(np.max(np.abs(p))) for p in positions if np.size(p)), default=0.0)
    return farthest + REACH_SIZES * mech.size


# -- the modes ---------------------------------------------------------------------------------


def _check_mode(engine: Engine, mode: str, kind: str, check: EngineCheck) -> None:
    _kinematics("fourbar")  # the mechanisms are xcheck's, made before the engine is asked anything
    if kind == "free":
        _reference()
    try:
        if kind == "kinematic":
            _check_kinematic(engine, mode, check)
        elif kind == "dynamic":
            _check_dynamic(engine, mode, check)
        elif kind == "free":
            _check_free(engine, mode, check)
        else:
            return
    except NotApplicable as error:
        if not _one_line(getattr(error, "reason", "")):
            check.breaks(mode, "says in one line why it does not apply (NotApplicable)", f"found {str(error)!r}")
        check.skipped[mode] = f"not applicable: {error}"
        return
    except Exception as error:  # noqa: BLE001 - the broken promise is the finding
        if not any(line.startswith(f"{check.engine}: {mode}: ") for line in check.broken):
            # else the runs' broken promises made the ladder fail: they are the finding
            check.breaks(mode, "fails as data (ok False with its reason) or raises NotApplicable", _error(error))
        return
    check.ran.append(mode)


def _check_result(mode: str, result: object, check: EngineCheck) -> ModeResult | None:
    """The mode's result where it is one that ran; None (its broken promise recorded, or a stated failure)."""
    if not isinstance(result, ModeResult):
        check.breaks(mode, "returns an xcheck.results.ModeResult", f"found {type(result).__name__}")
        return None
    if result.mode != mode:
        check.breaks(mode, "returns the result of the mode asked for", f"found the mode {result.mode!r}")
    if not result.ok:
        if not _one_line(result.reason):
            check.breaks(mode, "states a failure's reason in one line", f"found {result.reason!r}")
        return None
    if not result.trajectories or not all(isinstance(t, Trajectory) for t in result.trajectories):
        check.breaks(mode, "gives its trajectories (xcheck.results.Trajectory), the compared one first", "found none")
        return None
    return result


def _check_kinematic(engine: Engine, mode: str, check: EngineCheck) -> None:
    _check_sweep(engine, mode, _kinematics("fourbar"), check)


def _check_sweep(engine: Engine, mode: str, kinematics: Kinematics, check: EngineCheck) -> ModeResult | None:
    """A mode run through :meth:`Engine.run` on a sweep of :data:`SAMPLES`: its result
    and trajectories checked; the result where it ran."""
    from .runner import sweep_inputs

    native = kinematics.solve(*sweep_inputs(kinematics, SAMPLES))
    result = _check_result(mode, engine.run(mode, kinematics, native=native, samples=SAMPLES), check)
    if result is not None:
        reach = _reach(kinematics, [s["position"] for s in _parts(native, kinematics)])
        for trajectory in result.trajectories:
            _check_trajectory(mode, trajectory, kinematics, reach, check, driven=True)
    return result


def _parts(solution, kinematics: Kinematics) -> list[dict]:
    mech = kinematics.mechanism
    return [solution.body(b.name) for b in mech.moving_bodies] + [solution.point(p) for p in mech.point_owners]


class _Recorder:
    """An engine's one run, each call kept with its rung and problem for the checks."""

    def __init__(self, run_once: Callable[..., Run]):
        self.run_once = run_once
        self.calls: list[tuple[Any, Any, Run]] = []

    def __call__(self, mode: str, prepared: Any, problem: Any, rung: Any) -> Run:
        run = self.run_once(mode, prepared, problem, rung)
        self.calls.append((problem, rung, run))
        return run


def _probe(engine: Engine, method: str) -> tuple[Engine, _Recorder]:
    """A copy of ``engine`` whose ``method`` (its one run) is recorded."""
    probe = copy.copy(engine)
    recorder = _Recorder(getattr(engine, method))
    setattr(probe, method, recorder)
    return probe, recorder


def _check_dynamic(engine: Engine, mode: str, check: EngineCheck) -> None:
    from .ladder import DrivenProblem

    kinematics = _kinematics("fourbar")
    probe, recorder = _probe(engine, "run_dynamic_once")
    problem = DrivenProblem.of(kinematics, None, DRIVEN_DURATION)
    try:
        series = list(engine.dynamic_series(mode, problem))[:1]
    except NotImplementedError:  # it runs its own ladder in run(), as the runner allows
        series = []
    if not series:
        result = _check_sweep(engine, mode, kinematics, check)
        if result is not None:
            _check_ladder_result(mode, result, kinematics, check)
        return
    ladder = probe.dynamic_ladder(
        mode, kinematics, series=[dataclasses.replace(series[0], rungs=RUNGS)], duration=DRIVEN_DURATION
    )

    def run() -> list:
        first = ladder.run()
        # refined once, as the runner asks where an observed order falls short
        return [first, ladder.refine(1)] if isinstance(first, ModeResult) and first.ok else [first]

    _check_ladder(mode, run, recorder, kinematics, check, driven=True)


def _check_free(engine: Engine, mode: str, check: EngineCheck) -> None:
    kinematics, reference = _kinematics("iftomm-a01"), _reference()
    probe, recorder = _probe(engine, "run_free_once")
    try:
        series: list | None = list(engine.free_series(mode, kinematics))[:1]
    except NotImplementedError:  # it runs its own ladder in run_free()
        series = None
    if series is not None:
        series = [dataclasses.replace(s, rungs=RUNGS) for s in series]
    _check_ladder(
        mode, lambda: [probe.run_free(mode, kinematics, reference, series=series)], recorder, kinematics, check, False
    )


def _check_ladder(
    mode: str, run: Callable[[], list], recorder: _Recorder, kinematics: Kinematics, check: EngineCheck, driven: bool
) -> None:
    """Run a ladder (``run``: its results), then check its runs and, where they keep
    their promises, its results (else a broken run's consequences would be lines too)."""
    before = len(check.broken)
    try:
        results = run()
    finally:
        _check_runs(mode, recorder, kinematics, check, driven)
    if len(check.broken) > before:
        return
    for found in results:
        result = _check_result(mode, found, check)
        if result is not None:
            _check_ladder_result(mode, result, kinematics, check)


def _check_ladder_result(mode: str, result: ModeResult, kinematics: Kinematics, check: EngineCheck) -> None:
    from .ladder import STUDY_COLUMNS

    if result.study is None or set(STUDY_COLUMNS) - set(result.study.columns):
        check.breaks(mode, "gives its convergence study (xcheck.ladder.convergence_study)", "found none")
    for trajectory in result.trajectories:
        settings = trajectory.settings
        step, series = settings.get("timestep"), settings.get("series")
        if not (isinstance(step, (int, float)) and step > 0 and isinstance(series, str) and series):
            check.breaks(
                mode,
                "states each trajectory's settings: timestep (s) and series",
                f"found timestep {step!r}, series {series!r}",
            )


def _check_runs(mode: str, recorder: _Recorder, kinematics: Kinematics, check: EngineCheck, driven: bool) -> None:
    """Each recorded run against what :class:`xcheck.ladder.Run` promises."""
    reference = None if driven else _reference()
    for problem, rung, run in recorder.calls:
        at, run_name = mode, f"the run {rung.series.key} at dt = {rung.timestep:.4g} s"
        if not isinstance(run, Run):
            check.breaks(at, "returns an xcheck.ladder.Run", f"{run_name}: found {type(run).__name__}")
            continue
        if run.failure and not _one_line(run.failure):
            check.breaks(at, "states a run's failure in one line", f"{run_name}: found {run.failure!r}")
        trajectory, expected = run.trajectory, np.asarray(problem.times)
        if trajectory is None:
            if not run.failure:
                check.breaks(at, "states why a run reached no output", f"{run_name}: no trajectory and no failure")
            continue
        times = trajectory.times
        if times is None or np.ndim(times) != 1 or len(times) > len(expected):
            check.breaks(at, "samples at the compared times (problem.times)", f"{run_name}: found times {times!r:.80}")
            continue
        if not np.allclose(np.asarray(times, dtype=float), expected[: len(times)], rtol=0.0, atol=TIME_MATCH):
            check.breaks(
                at, "samples at the compared times (problem.times)", f"{run_name}: found {np.asarray(times)[:3]} ..."
            )
        if len(times) < len(expected) and not run.failure:
            check.breaks(
                at,
                "states why a run stopped before the end",
                f"{run_name}: {len(times)} of {len(expected)} outputs and no failure",
            )
        settings = trajectory.settings
        if settings.get("series") != rung.series.key or not np.isclose(
            float(settings.get("timestep", math.nan)), rung.timestep, rtol=1e-12, atol=0.0
        ):
            check.breaks(
                at,
                "states its run's settings (Rung.settings: timestep and series)",
                f"{run_name}: found timestep {settings.get('timestep')!r}, series {settings.get('series')!r}",
            )
        if reference is not None:
            positions = [reference.motion.solution().point(p)["position"] for p in kinematics.mechanism.point_owners]
        else:
            positions = [s["position"] for s in _parts(problem.start, kinematics)]
        _check_trajectory(at, trajectory, kinematics, _reach(kinematics, positions), check, driven)
        gaps = trajectory.diagnostics.get("constraint_violation")
        if gaps is not None and np.shape(gaps) == (len(times),) and not run.failure:
            apart = np.flatnonzero(np.asarray(gaps, dtype=float) > APART * kinematics.mechanism.size)
            if apart.size:
                check.breaks(
                    at,
                    "stops a run where its loops come apart (problem.came_apart)",
                    f"{run_name}: loops {float(gaps[apart[0]]):.3g} m open at t = {float(times[apart[0]]):.6g} s "
                    "and no failure",
                )


def _check_trajectory(
    where: str, trajectory: object, kinematics: Kinematics, reach: float, check: EngineCheck, driven: bool
) -> None:
    """A trajectory's shapes, names, units and numbers."""
    if not isinstance(trajectory, Trajectory):
        check.breaks(where, "gives trajectories (xcheck.results.Trajectory)", f"found {type(trajectory).__name__}")
        return
    mech = kinematics.mechanism
    bodies, points = {b.name for b in mech.moving_bodies}, set(mech.point_owners)
    inputs = np.asarray(trajectory.inputs)
    counts = [
        np.shape(v)[0]
        for part in (*trajectory.bodies.values(), *trajectory.points.values())
        for v in part.values()
        if np.ndim(v)
    ]
    if trajectory.times is not None:
        counts.append(len(trajectory.times))
    if driven or inputs.size:
        counts.append(inputs.shape[0] if inputs.ndim == 2 else -1)
    n = counts[0] if counts else 0
    shape = "the stated shapes (N samples of every quantity: (N, 2) vectors, (N,) angles, (N, k) inputs)"
    if not counts or len(set(counts)) > 1:
        check.breaks(where, f"gives trajectories of {shape}", f"found sample counts {sorted(set(counts))}")
        return
    drivers = len(mech.drivers)
    for name in ("inputs", "input_rates", "input_accelerations"):
        values = np.asarray(getattr(trajectory, name))
        if (driven or values.size) and values.shape != (n, drivers):
            check.breaks(where, f"gives trajectories of {shape}", f"{name} {values.shape}, expected {(n, drivers)}")
    unknown = sorted(set(trajectory.bodies) - bodies) + sorted(set(trajectory.points) - points)
    if unknown:
        check.breaks(where, "names only the mechanism's bodies and points", f"found {', '.join(unknown)}")
    if not driven and not any("position" in trajectory.points.get(p, {}) for p in points):
        check.breaks(where, "gives the named points' positions in free motion", "found none")
    for kind, parts, quantities in (
        ("body", trajectory.bodies, BODY_QUANTITIES),
        ("point", trajectory.points, POINT_QUANTITIES),
    ):
        for name, states in parts.items():
            for quantity, values in states.items():
                if quantity not in quantities:
                    check.breaks(where, "gives only the quantities xcheck knows", f"{kind} {name}: {quantity!r}")
                    continue
                expected = (n, 2) if quantities[quantity] == 2 else (n,)
                array = np.asarray(values)
                if array.shape != expected:
                    check.breaks(
                        where,
                        f"gives trajectories of {shape}",
                        f"{kind} {name} {quantity} {array.shape}, expected {expected}",
                    )
                    continue
                if not np.all(np.isfinite(array)):
                    check.breaks(
                        where, "gives finite numbers or a stated failure", f"{kind} {name} {quantity} not finite"
                    )
                elif quantity == "position" and float(np.max(np.abs(array))) > reach:
                    check.breaks(
                        where,
                        "gives positions in metres (SI inside)",
                        f"{kind} {name} at {float(np.max(np.abs(array))):.4g} m, the mechanism reaches {reach:.4g} m",
                    )


# -- files and forces --------------------------------------------------------------------------


def _check_files(engine: Engine, check: EngineCheck) -> None:
    kinematics = _kinematics("fourbar")
    if engine.export_format:
        try:
            files = engine.export_files(kinematics)
        except NotApplicable:
            files = {}
        except Exception as error:  # noqa: BLE001 - the broken promise is the finding
            check.breaks("engine", "exports its model files or raises NotApplicable", _error(error))
            files = {}
        if not isinstance(files, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in files.items()):
            check.breaks("engine", "exports its model files as {file name: text}", f"found {type(files).__name__}")
    if engine.force_tolerance is not None:
        from .dynamics import Forces

        options: list[dict] = [{}] + ([{"refine": 1}] if engine.force_order is not None else [])
        for option in options:
            try:
                forces = engine.inverse_dynamics(kinematics, **option)
            except NotApplicable:
                continue
            except Exception as error:  # noqa: BLE001 - the broken promise is the finding
                check.breaks("engine", f"gives reactions and efforts (inverse_dynamics{_shown(option)})", _error(error))
                continue
            if not isinstance(forces, Forces):
                check.breaks(
                    "engine",
                    f"gives reactions and efforts (inverse_dynamics{_shown(option)}) as xcheck.dynamics.Forces",
                    f"found {type(forces).__name__}",
                )


def _shown(option: dict) -> str:
    return "(" + ", ".join(f"{k}={v!r}" for k, v in option.items()) + ")" if option else ""
