"""How a free-motion reference is run and judged: its ladder of runs, the error it
states, the second method's check, the bounds on its work, and its duration.

One rule (:func:`run_ladder`) serves both native methods: runs at ever finer
settings (RK4: the step halved; DOP853: the local tolerance divided by ten),
each compared with the last one that went through. The stated error of a run is
the largest difference so far from that previous run, at every output (the
previous run's own error, which the finer one is taken not to exceed). Where the
method's error has a nominal rate (RK4's falls 16 times a halving) and, at an
output, the last two differences fell at least that fast, it is instead
:data:`SAFETY` times the difference over (rate - 1) there, the error left after a
geometric series at that rate (Roache's grid convergence index, with his factor
of safety for three or more runs). DOP853's global error has no such rate under
its local error control (measured from one tolerance to the next a tenth of it:
4 to 17 times smaller), so its runs state the difference. The ladder stops at the requested tolerance;
where a difference grows, the finer runs only add round-off, and the finer run
of the pair before is kept, not converged; it also stops where the next run
would overrun the work budget. A run that fails (goes non-finite, or cannot
follow the motion) is the ladder's entry with its reason, and the ladder goes on
from the next setting. The kept run's round-off is then measured and added to its
stated error: :data:`ROUND_OFF_RUNS` more runs at its setting from starts moved a few
ulps, :data:`ROUND_OFF_FACTOR` x their largest difference from it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
from threadpoolctl import threadpool_limits

from .. import arguments
from ..errors import InputError
from ..kinematics import Kinematics
from ._free import ROUND_OFF, FreeCheck, FreeMotion, FreeReference, FreeState

__all__ = [
    "SAFETY",
    "WORK_BUDGET",
    "MAX_OUTPUT_VALUES",
    "run_ladder",
    "stated_error",
    "difference",
    "compare_runs",
    "time_scale",
    "free_duration",
    "LadderMethod",
]

#: Roache's factor of safety on an error extrapolated from an observed rate (three or more runs)
SAFETY = 1.25
#: the work one method's ladder may do, in evaluations of the accelerations times
#: :func:`work_units`: RK4 counts five evaluations a step (16 to 31 s of CPU); DOP853 counts its
#: projections, singularity measures and least-squares solves at their cost in evaluations
#: (7 to 10 s of CPU, near singular positions too)
WORK_BUDGET = 1e8
#: how far the round-off runs start from the ladder's start: this many units in the last place
ROUND_OFF_ULPS = 4.0
#: how many runs measure the round-off of the kept run, from starts moved in opposite patterns of signs
ROUND_OFF_RUNS = 2
#: the round-off stated: this many times the largest difference of those runs from the kept one.
#: Float64's round-off enters at every step and grows as the motion's own sensitivity carries
#: it (on IFToMM A02 an energy error becomes a phase error that grows with time), so runs whose
#: roundings differ scatter about the true motion as independent samples: the kept run's own
#: round-off is one more sample, which two samples' spread bounds only with this margin
#: (measured on A02 from 40 starts moved 4 ulps, its ladder at 1e-11 of the size: twice the
#: spread of two runs bounds the true error at every output from all 40, at most 0.71 of the
#: stated error; the spread of one run, unscaled, from 35, up to 1.6 times below it from 5)
ROUND_OFF_FACTOR = 2.0
#: the most values an output array may hold (outputs times coordinates: 160 MB each)
MAX_OUTPUT_VALUES = 2e7


class LadderMethod(Protocol):
    """What a ladder needs of a method: its name, the rate its error nominally falls by from
    one setting to the next (None: none), whether a setting is a fixed step (s; the ladder's
    rows then also give the step a run took), its start, its settings (coarsest first), a run
    at a setting within a number of evaluations (from its start, or another), the
    evaluations a setting would cost (given the last run that went through, or None), a
    line describing the ladder and a few words on what sets its first runs' cost."""

    name: str
    nominal: float | None
    fixed_step: bool
    start: FreeState

    def settings(self) -> Sequence[float]: ...

    def run(self, setting: float, evaluations: float, start: FreeState | None = None) -> FreeMotion: ...

    def work(self, setting: float, previous: FreeMotion | None) -> float: ...

    def describe(self) -> str: ...

    def cost(self) -> str: ...


def difference(kinematics: Kinematics, fine: FreeMotion, coarse: FreeMotion) -> np.ndarray:
    """Per output, the largest |fine - coarse| so far over body positions (m) and angles
    (rad x size), at least the round-off floor: the running maximum, because the two runs'
    difference may pass through zero where the error does not. Both runs must share their
    output times (N,)."""
    return np.maximum(spread_of(kinematics, fine, coarse), ROUND_OFF * kinematics.system.size)


def stated_error(gap: np.ndarray, previous: np.ndarray | None, nominal: float | None) -> tuple[np.ndarray, str]:
    """The stated error of a run (m, (N,)) from ``gap``, its running difference from the run
    before, ``previous``, the difference before that (None with one), and the method's
    ``nominal`` rate (None: none); with how it was obtained. Where the last two differences
    fell at least ``nominal`` times: :data:`SAFETY` x the difference / (``nominal`` - 1); where
    they fell less than 1 + :data:`SAFETY` times, the runs are not converging there:
    :data:`SAFETY` x the larger of the two; elsewhere the difference."""
    if previous is None:
        return gap.copy(), "the difference"
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = previous / gap
    fast = rate >= nominal if nominal is not None else np.zeros(len(gap), dtype=bool)
    slow = ~(rate >= 1.0 + SAFETY)  # NaN too
    estimate = gap.copy()
    if nominal is not None:
        estimate[fast] = SAFETY * gap[fast] / (nominal - 1.0)
    estimate[slow] = SAFETY * np.maximum(gap[slow], previous[slow])
    rules = []
    if fast.any():
        rules.append(f"{SAFETY:g} x the difference / ({nominal:g} - 1) where it fell {nominal:g} times or faster")
    if slow.any():
        rules.append(
            f"{SAFETY:g} x the larger of the last two differences where they fell less than {1 + SAFETY:g} times"
        )
    if not rules:
        return estimate, "the difference"
    if (fast | slow).all():
        return estimate, "; ".join(rules)
    return estimate, "; ".join(rules) + " (else the difference)"


def run_ladder(
    kinematics: Kinematics,
    method: LadderMethod,
    tolerance: float,
    budget: float | None = None,
    progress: Callable[[str], None] | None = None,
) -> FreeReference:
    """Run ``method``'s ladder until its stated error is within ``tolerance`` x the mechanism's
    size (see the module's docstring), within ``budget`` (:func:`work_units`; default
    :data:`WORK_BUDGET`).

    Raises
    ------
    InputError
        If no run went through (each rung's reason in the message), or the first two runs,
        the fewest that state an error, would already overrun the budget.
    """
    budget = WORK_BUDGET if budget is None else budget
    size = kinematics.system.size
    settings = list(method.settings())
    units = work_units(kinematics)
    first = sum(method.work(setting, None) for setting in settings[:2]) * units
    if first > budget:
        raise InputError(
            f"{kinematics.mechanism.path}: free_motion: expected a motion the {method.name} reference can follow "
            f"within its work budget ({budget:.3g} evaluations x (30 + coordinates)), found one its first two "
            f"runs would need {first:.3g} for ({method.cost()})"
        )
    ladder: list[dict] = []
    spent = 0.0
    last: FreeMotion | None = None  # the last run that went through
    gaps: list[np.ndarray] = []  # the differences so far
    best: tuple[FreeMotion, np.ndarray, float, float] | None = None  # the run with the least stated error so far
    converged, stop, grew = False, "", 0
    for setting in settings:
        cost = method.work(setting, last) * units
        if spent + cost > budget:
            stop = f"the next run would overrun the work budget ({budget:.3g}; {spent:.3g} spent)"
            break
        if progress is not None:
            progress(f"native: {method.name} at {setting:.4g}")
        # one BLAS thread: the solves are small (at most a few hundred rows), and threads that
        # wait for each other on a busy machine cost many times the work the budget counts
        # (iftomm-a02-n40's SVDs near a singular position: 32 ms of CPU with two threads, 6 with one)
        with threadpool_limits(limits=1, user_api="blas"):
            motion = method.run(setting, (budget - spent) / units)
        spent += float(motion.statistics.get("cost", motion.statistics.get("evaluations", cost / units))) * units
        entry = _ladder_entry(method, setting, motion, motion.failure or "ok")
        steps = entry["steps"]
        ladder.append(entry)
        if motion.failure:
            continue
        if last is None:
            last = motion
            continue
        gap = difference(kinematics, motion, last)
        entry["difference"] = float(gap.max())
        estimate, rule = stated_error(gap, gaps[-1] if gaps else None, method.nominal)
        estimate = np.maximum(estimate, round_off(kinematics, motion, steps))
        entry["error"], entry["rule"] = float(estimate.max()), rule
        relative = float(estimate.max()) / size
        # a difference that grows: a coarse run off its asymptote, or, twice in a row, finer
        # runs that only add round-off (or leave the motion's accuracy behind, as at a singular pass)
        grew = grew + 1 if gaps and gap.max() > gaps[-1].max() else 0
        gaps.append(gap)
        last = motion
        if best is None or relative <= best[2]:
            best = motion, estimate, relative, setting
        if relative <= tolerance:
            converged = True
            break
        if grew >= 2:
            stop = "the difference grew twice in a row as the setting was refined: round-off rules there"
            break
    else:
        stop = f"the finest setting ({settings[-1]:.4g}) was reached"
        if ladder and ladder[-1]["status"] != "ok":
            stop += f", where the run stopped: {ladder[-1]['status']}"
    if best is None:
        reasons = _reasons(ladder) or stop
        if last is None:
            raise InputError(
                f"{kinematics.mechanism.path}: free_motion: expected a motion the {method.name} reference can "
                f"follow, found none of its runs went through ({reasons})"
            )
        best = last, np.full(len(last.times), math.inf), math.inf, math.nan  # one run went through: error unknown
    motion, estimate, relative, kept = best
    stopped = f"stopped at the tolerance, {tolerance:g} of the size" if converged else f"stopped: {stop}"
    if math.isfinite(relative):
        estimate, measured = _with_round_off(kinematics, method, motion, kept, estimate, ladder, progress)
        relative = float(estimate.max()) / size
        if converged and relative > tolerance:
            converged = False
            stopped = (
                f"stopped: the round-off measured lifts the stated error above the tolerance, {tolerance:g} of the size"
            )
        stopped += f"; {measured}"
    basis = f"{method.describe()}; {stopped}"
    return FreeReference(motion, estimate, relative, converged, ladder, tolerance, method.name, basis)


def _with_round_off(
    kinematics: Kinematics,
    method: LadderMethod,
    kept: FreeMotion,
    setting: float,
    estimate: np.ndarray,
    ladder: list[dict],
    progress: Callable[[str], None] | None,
) -> tuple[np.ndarray, str]:
    """The stated error ``estimate`` (m, (N,)) of the ``kept`` run (at ``setting``) plus its
    round-off: :data:`ROUND_OFF_RUNS` more runs at its setting, from :func:`perturbed_start`
    in patterns 0, 1, ..., and :data:`ROUND_OFF_FACTOR` x their largest
    running difference from the kept run, added at every output; with the words that say so.
    The runs are the ladder's last entries. A run that fails leaves the round-off unmeasured:
    the error is then unknown (inf)."""
    evaluations = 2.0 * float(kept.statistics.get("cost", kept.statistics.get("evaluations", 0.0))) + 1e6
    runs = "a second run" if ROUND_OFF_RUNS == 1 else f"{ROUND_OFF_RUNS} more runs"
    moved_by = f"from starts moved {ROUND_OFF_ULPS:g} ulps in opposite patterns of signs"
    how = f"round-off, measured by {runs} at {setting:.4g} {moved_by}"
    spread = np.zeros(len(kept.times))
    for pattern in range(ROUND_OFF_RUNS):
        if progress is not None:
            progress(f"native: {method.name} at {setting:.4g} from a start moved {ROUND_OFF_ULPS:g} ulps (round-off)")
        with threadpool_limits(limits=1, user_api="blas"):
            moved = method.run(setting, evaluations, perturbed_start(kinematics, method.start, pattern))
        entry = _ladder_entry(
            method, setting, moved, moved.failure or f"round-off: from a start moved {ROUND_OFF_ULPS:g} ulps"
        )
        ladder.append(entry)
        if moved.failure or len(moved.times) != len(kept.times):
            failed = f"{how}: a run failed ({moved.failure or 'its outputs differ'}), so the error is unknown"
            return np.full(len(kept.times), math.inf), failed
        apart = spread_of(kinematics, moved, kept)
        spread = np.maximum(spread, apart)
        entry["difference"] = float(apart.max())
    total = estimate + ROUND_OFF_FACTOR * spread
    entry["error"], entry["rule"] = float(total.max()), how
    return total, (
        f"{how} (projected onto the constraints): {ROUND_OFF_FACTOR:g} x their largest difference from the kept "
        f"run, up to {ROUND_OFF_FACTOR * spread.max():.3g} m, added to the stated error"
    )


def _ladder_entry(method: LadderMethod, setting: float, motion: FreeMotion, status: str) -> dict:
    """The ladder's row of a run of ``method`` at ``setting``: its steps, CPU seconds and
    ``status`` (its ``difference`` NaN until one is measured; a fixed-step method's also its step,
    s, the setting shortened to divide the output step)."""
    steps = (
        int(motion.statistics.get("steps", round(float(motion.times[-1]) / motion.step))) if len(motion.times) else 0
    )
    entry = {"setting": setting, "steps": steps, "seconds": motion.seconds, "difference": math.nan, "status": status}
    if method.fixed_step:
        entry["step"] = motion.step
    return entry


def perturbed_start(kinematics: Kinematics, start: FreeState, pattern: int = 0) -> FreeState:
    """``start`` moved by :data:`ROUND_OFF_ULPS` units in the last place of each coordinate
    and rate (of the size, 1 rad, or the largest rate of its kind where that is larger), in
    the fixed pattern of signs numbered ``pattern`` (an odd one the opposite of the even one
    before it, so that two runs start apart even where the constraints leave one direction
    free), then projected onto the constraints."""
    from ._free import consistent_state

    q, qd = np.asarray(start.q, dtype=float), np.asarray(start.qd, dtype=float)
    signs = np.where(np.random.default_rng(12345 + pattern // 2).random(2 * len(q)) < 0.5, -1.0, 1.0)
    signs *= -1.0 if pattern % 2 else 1.0
    angle = np.zeros(len(q), dtype=bool)
    angle[2::3] = True
    floor_q = np.where(angle, 1.0, kinematics.system.size)
    floor_qd = np.where(angle, np.abs(qd[angle]).max(initial=0.0), np.abs(qd[~angle]).max(initial=0.0))
    step = ROUND_OFF_ULPS * np.finfo(float).eps
    moved_q = q + step * np.maximum(np.abs(q), floor_q) * signs[: len(q)]
    moved_qd = qd + step * np.maximum(np.abs(qd), floor_qd) * signs[len(q) :]
    return consistent_state(kinematics, moved_q, moved_qd)


def spread_of(kinematics: Kinematics, one: FreeMotion, other: FreeMotion) -> np.ndarray:
    """Per output, the largest |one - other| so far over body positions (m) and angles
    (rad x size), (N,): the running maximum."""
    delta = np.abs(one.q - other.q)
    delta[:, 2::3] *= kinematics.system.size
    return np.maximum.accumulate(delta.max(axis=1))


def round_off(kinematics: Kinematics, motion: FreeMotion, steps: int) -> np.ndarray:
    """The least error a run of ``steps`` steps may state at each output (m, (N,)): the
    round-off of its state, :data:`ROUND_OFF` x the size at the start, and float64's epsilon x
    the size more for every step taken by then (the worst case, a rounding a step that adds up;
    the steps spread evenly over the run)."""
    taken = steps * motion.times / motion.times[-1] if len(motion.times) > 1 else np.zeros(len(motion.times))
    return kinematics.system.size * (ROUND_OFF + np.finfo(float).eps * taken)


def _reasons(ladder: list[dict]) -> str:
    """Why the ladder's runs failed, each reason once with the settings it ended."""
    settings: dict[str, list[str]] = {}
    for entry in ladder:
        settings.setdefault(entry["status"], []).append(f"{entry['setting']:.3g}")
    return "; ".join(f"{', '.join(at)}: {why}" for why, at in settings.items())


def work_units(kinematics: Kinematics) -> float:
    """The work of one evaluation of the accelerations, in the budget's units: 30 + the
    coordinates (measured: about 0.16 to 0.31 us a unit, from 9 to 243 coordinates)."""
    return 30.0 + kinematics.system.n


def compare_runs(kinematics: Kinematics, reference: FreeReference, check: FreeReference) -> FreeCheck:
    """The check's motion against the reference's at the check's output times (each an output
    of the reference): their running largest difference (m, as :func:`difference`), and whether
    its largest stays within the sum of their largest stated errors (None where either did not
    meet its tolerance: then their stated errors bound nothing)."""
    ref, other = reference.motion, check.motion
    spacing = float(ref.times[1] - ref.times[0]) if len(ref.times) > 1 else 1.0
    index = np.rint(other.times / spacing).astype(int)
    index = index[index < len(ref.times)]
    count = len(index)
    size = kinematics.system.size
    delta = np.abs(ref.q[index] - other.q[:count])
    delta[:, 2::3] *= size
    agreement = np.maximum.accumulate(delta.max(axis=1)) if count else np.zeros(0)
    bound = float(reference.estimate.max()) + float(check.estimate.max())
    consistent: bool | None = None  # inconclusive where either did not meet its tolerance
    if reference.converged and check.converged:
        consistent = bool(count == len(other.times) and float(agreement.max(initial=0.0)) <= bound)
    return FreeCheck(check, other.times[:count], agreement, float(agreement.max(initial=0.0)) / size, consistent)


def time_scale(kinematics: Kinematics, start: FreeState) -> tuple[float, str]:
    """The shortest time scale of the motion at its release (s) and what sets it: the fastest
    rate of the system linearised about the release state on its constraints (stiffness of
    springs and gravity: sqrt of the largest eigenvalue of M^-1 K in the joints' free
    directions; dampers: the largest of M^-1 C), or of the release motion itself."""
    from scipy.linalg import eigvals, null_space

    from ._free import _Dynamics

    dyn = _Dynamics(kinematics)
    q, qd = np.asarray(start.q, dtype=float), np.asarray(start.qd, dtype=float)
    scale = dyn.scale_coordinates
    free = null_space(dyn.joints.jacobian(q) / scale[None, :]) / scale[:, None]  # (n, f), SI
    rates = {"the release velocity": float(np.max(np.abs(qd * scale), initial=0.0))}
    if free.shape[1]:
        base = dyn.forces(q, qd)
        stiffness, damping = np.zeros((len(q), free.shape[1])), np.zeros((len(q), free.shape[1]))
        for j in range(free.shape[1]):
            h = 1e-7 / max(float(np.abs(free[:, j] * scale).max()), 1e-300)
            stiffness[:, j] = -(dyn.forces(q + h * free[:, j], qd) - base) / h
            damping[:, j] = -(dyn.forces(q, qd + h * free[:, j]) - base) / h
        mass = free.T @ dyn._mass(q) @ free
        with np.errstate(all="ignore"):
            spring = eigvals(free.T @ stiffness, mass)
            dashpot = eigvals(free.T @ damping, mass)
        spring = spring[np.isfinite(spring)]
        dashpot = dashpot[np.isfinite(dashpot)]
        rates["the springs and gravity"] = math.sqrt(float(np.max(np.abs(spring), initial=0.0)))
        rates["the dampers"] = float(np.max(np.abs(dashpot), initial=0.0))
    what = max(rates, key=lambda k: rates[k])
    fastest = rates[what]
    return (math.inf if not fastest > 0.0 else 1.0 / fastest), what


def free_duration(kinematics: Kinematics, duration: float | None, argument: str = "duration") -> float:
    """The duration of a free motion (s): the file's, or ``duration``, which must be a whole
    number of the file's output steps, above 0 and at most 1e6 s, and keep the outputs within
    :data:`MAX_OUTPUT_VALUES` (outputs x coordinates). ``argument`` names it in messages.

    Raises
    ------
    InputError
        One line naming what was expected and what was found.
    """
    spec = kinematics.mechanism.free_motion
    if spec is None:
        raise InputError(
            f"{kinematics.mechanism.path}: free_motion: expected a [free_motion] section to simulate, found none"
        )
    if duration is None:
        length = spec.duration
    else:
        duration = arguments.duration(duration, argument)
        steps = duration / spec.output_step
        if abs(steps - round(steps)) > 1e-9 * max(steps, 1.0) or round(steps) < 1:
            below = max(math.floor(steps), 1) * spec.output_step
            above = max(math.ceil(steps), 1) * spec.output_step
            nearest = f"{below:g} s" if below == above else f"{below:g} s or {above:g} s"
            raise InputError(
                f"{argument}: expected a whole number of output steps ({spec.output_step:g} s), "
                f"e.g. {nearest}, found {duration:g} s"
            )
        length = round(steps) * spec.output_step
    outputs = round(length / spec.output_step) + 1
    values = outputs * kinematics.system.n
    if values > MAX_OUTPUT_VALUES:
        raise InputError(
            f"{kinematics.mechanism.path}: free_motion: expected at most {MAX_OUTPUT_VALUES:.3g} output values "
            f"(outputs x {kinematics.system.n} coordinates), found {outputs} outputs over {length:g} s "
            f"({values:.3g}); a longer output_step or a shorter duration"
        )
    return float(length)
