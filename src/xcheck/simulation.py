"""Free motion across engines: the native reference and every ``free`` mode against it.

:func:`simulate_all` integrates the native reference of a mechanism's
``[free_motion]`` (:func:`xcheck.dynamics.simulate`) and runs each requested
free mode of the registry (:meth:`xcheck.engines.Engine.run_free`) from the
same initial state, each judged by the one ladder rule of :mod:`xcheck.ladder`.
A mode that fails is a result with its reason; the others still run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from . import engines
from .dynamics._free import FreeReference, simulate
from .dynamics._reference import free_duration
from .engines import NotApplicable
from .kinematics import Kinematics
from .ladder import one_line
from .results import ModeResult

__all__ = ["SimulationResult", "free_modes", "simulate_all"]


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


def simulate_all(
    kinematics: Kinematics,
    modes=None,
    duration: float | None = None,
    branch: str | None = None,
    progress=None,
    jobs: int = 1,
    check: bool = False,
    meanwhile: Callable[[SimulationResult], object] | None = None,
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
        Modes run at once, each in a worker process (:mod:`xcheck._parallel`), the costliest
        first (1: one after another in this process), where that could save time
        (:func:`xcheck.runner.worth_workers`: their costs per simulated second
        times the duration); the modes of engines registered at run time run
        here. The results are those of a serial run.
    check : bool
        Check the reference by the second native method (``reference.check``).
    meanwhile : callable, optional
        Called with the result, its reference computed and no mode yet, while the
        worker processes run the modes (before the modes where they run here):
        work of this process that needs the reference alone, such as its figures.
    """
    from .runner import costliest_first, default_modes, left_out, worth_workers

    start = time.perf_counter()
    reference = simulate(kinematics, branch, duration, progress=progress, check=check)
    result = SimulationResult(kinematics, reference, seconds={"native": time.perf_counter() - start})
    chosen = list(default_modes(("free",))[1:] if modes is None else modes)
    result.left_out = left_out(chosen, ("free",))
    missing = {mode: engines.engine_of(mode).available() for mode in chosen}
    runnable = [mode for mode in chosen if not missing[mode]]
    from ._parallel import collect, known_to_workers, process_pool, submit

    away = [m for m in runnable if known_to_workers(m)]
    if not worth_workers(away, jobs, free_duration(kinematics, duration)):
        away = []
    here = [m for m in runnable if m not in away]
    ran: dict = {}
    if away:
        begin = time.perf_counter()

        def failed(mode: str, why: str):  # its time: until the pool said so
            return ModeResult(mode, kinematics.mechanism.name, False, why), time.perf_counter() - begin

        calls = {mode: (_run_free, (mode, kinematics, reference, branch)) for mode in costliest_first(away)}
        with process_pool(min(jobs, len(away))) as pool:
            futures = submit(pool, calls)
            if meanwhile is not None:
                meanwhile(result)
            ran.update(collect(futures, failed, progress, calls, jobs))
    elif meanwhile is not None:
        meanwhile(result)
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
        outcome = ModeResult(mode, kinematics.mechanism.name, False, one_line(err))
    return outcome, time.perf_counter() - begin
