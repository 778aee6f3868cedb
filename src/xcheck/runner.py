"""The comparison runner: every solver and engine mode on one mechanism.

:func:`run_mechanism` sweeps the mechanism's feasible input range with the
native general solver, runs each requested mode (the seeds' other
formulations, MuJoCo, Pinocchio and pymunk, kinematic and dynamic), and
tabulates per mode and quantity category the largest and RMS difference from
the native solution against a tolerance. A mode that fails is reported with its
reason; the others still run.
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np
import pandas as pd

from . import __version__, engines
from .arguments import DEFAULT_SAMPLES
from .dynamics import (
    Forces,
    energy_summary,
    inverse_dynamics,
    require_constant_loads,
    require_mass_data,
    window_states,
)
from .engines import NotApplicable
from .errors import InputError, XcheckError
from .kinematics import Kinematics, Solution
from .ladder import (
    FAILURE,
    ORDER_MARGIN,
    REACTIONS,
    applicable_findings,
    empty_study,
    observed_order,
    one_line,
)
from .motion import drive_warnings, law_states, simulation_window, sweep_span
from .reactions import ForceResult, compare_forces, engine_forces, force_summary
from .results import (
    ModeResult,
    Trajectory,
    differences,
    native_at,
    sample_errors,
    scale_floors,
    undetermined_text,
)
from .states import limit_warnings
from .tolerances import (
    CONDITIONING_FACTOR,
    ENGINE_CONDITIONING_FACTOR,
    Tolerance,
    conditioned_round_off,
    convergence_round_off,
    length_ratio,
    power_round_off,
)

__all__ = [
    "is_static",
    "all_modes",
    "default_modes",
    "left_out",
    "left_out_text",
    "tolerance",
    "CATEGORIES",
    "NATIVE_TOLERANCE",
    "ModeOutcome",
    "RunResult",
    "VERDICTS",
    "run_verdict",
    "EXIT_CODES",
    "SUMMARY_COLUMNS",
    "run_mechanism",
    "sweep_inputs",
    "versions",
    "convergence_table",
    "force_tolerance",
    "force_round_off",
    "condition_number",
    "energy_tolerance",
    "ORDER_MARGIN",
    "convergence_limit",
    "NEWTON_EULER_TOLERANCE",
    "ENERGY_TOLERANCE",
]


def all_modes() -> tuple[str, ...]:
    """Every mode, in the order tables show them: native, then the registry's
    (:func:`xcheck.engines.modes`: kinematic modes, then dynamic ones; free
    motion runs in ``xcheck simulate``)."""
    return ("native", *(m.name for m in engines.modes(engines.DRIVEN_KINDS)))


def default_modes(kinds: tuple[str, ...] = engines.DRIVEN_KINDS) -> tuple[str, ...]:
    """The modes a run takes when none are named: "native" and every mode of
    ``kinds`` but those run only on request (:attr:`xcheck.engines.Mode.on_request`),
    in the order of :func:`all_modes`."""
    return ("native", *(m.name for m in engines.modes(kinds) if not m.on_request))


def left_out(modes, kinds: tuple[str, ...] = engines.DRIVEN_KINDS) -> dict[str, str]:
    """The modes of ``kinds`` run only on request (:attr:`xcheck.engines.Mode.on_request`)
    that a selection of every default mode leaves out, each with its reason;
    empty for a narrower selection (``--engines mujoco`` leaves nothing out)."""
    if not set(default_modes(kinds)) - {"native"} <= set(modes):
        return {}
    return {
        m.name: m.on_request_reason or "run on request"
        for m in engines.modes(kinds)
        if m.on_request and m.name not in modes
    }


def left_out_text(left: dict[str, str]) -> str:
    """The one line that says which modes a run left out and why ("" where none)."""
    if not left:
        return ""
    asked = ", ".join(dict.fromkeys(f"--engines {engines.engine_of(mode).name}" for mode in left))
    return f"left out, run only on request ({asked} or --engines all): " + "; ".join(
        f"{mode} ({why})" for mode, why in left.items()
    )


#: quantity categories of the tables; body positions count with point positions
CATEGORIES = ("position", "velocity", "acceleration", "angle", "omega", "alpha")


#: the general solver against its own equations
NATIVE_TOLERANCE = Tolerance(
    1e-12,
    1e-12,
    1e-12,
    1e-12,
    "the solver's own equations: loop closure and the velocity and acceleration equations satisfied to round-off",
)


def tolerance(mode: str) -> Tolerance:
    """What a mode must meet (:data:`NATIVE_TOLERANCE` or its engine's)."""
    return NATIVE_TOLERANCE if mode == "native" else engines.mode(mode).tolerance


#: How many times a dynamic mode whose observed order falls short is run again
#: with its finest step halved once more (:meth:`xcheck.ladder.DrivenLadder.refine`):
#: near a singular configuration a ladder's finest pair may not yet be in the
#: asymptotic range (fuzz cases s1-00022, s1-00093: an order of 0.3 where 1 is
#: expected), and only a finer pair tells that from a lower order.
REFINEMENTS = 2

#: a run's modes go to worker processes only where that could save more than this
#: (s): the summed :attr:`~xcheck.engines.Mode.cost` less the costliest, against
#: the workers' start (Python, NumPy, pandas and xcheck: about 0.4 s of CPU, once for
#: the fork server of the command's workers, each where they are spawned) and the
#: engines each of them imports again
PARALLEL_SAVING = 2.0
#: the power balance of the native solution: drive + loads = d(T + V)/dt, relative
ENERGY_TOLERANCE = 1e-12
#: the seed's per-body Newton-Euler form against the native multipliers: round-off (measured at most 1.7e-13)
NEWTON_EULER_TOLERANCE = 1e-12


@dataclass
class ModeOutcome:
    """One mode's comparison with the native solution.

    Attributes
    ----------
    mode : str
    ok : bool
        False when the mode could not run or failed; ``reason`` says why.
    reason : str
    passed : bool
        ok, and every category within its tolerance.
    categories : DataFrame
        One row per category: max_abs (SI), rms, relative (position per
        mechanism size, angle in rad, others per the largest magnitude of
        that quantity over all bodies and points, but at least ``floor``, its
        physical floor from :func:`xcheck.results.scale_floors`), tolerance,
        round_off (the bound below which the difference is round-off:
        :func:`xcheck.tolerances.conditioned_round_off`), passed, worst (the
        body or point), worst_input (first driver, SI);
        a dynamic mode's also the basis of its verdict (expected_order,
        observed_order, coarse_error, coarse_step, step, estimate, basis:
        see :func:`_convergence_verdict`), its tolerance the limit found there,
        and, where its orders fell short and it was run again with finer
        steps (:data:`REFINEMENTS`), refinements (how many times) or
        refinement_failure (why a finer run failed).
    details : DataFrame
        :func:`xcheck.results.differences` of the compared trajectory.
    result : ModeResult or None
        The engine's own result: every trajectory and its summary table.
    trajectory : Trajectory or None
        The compared trajectory.
    errors : dict of str to ndarray
        Per quantity, the largest error over all bodies and points at each
        sample of the trajectory (SI), for plots.
    seconds : float
        Wall time of the mode.
    findings : dict of str to tuple of Finding
        Per category, the engine's stated findings that hold for it on this
        mechanism (:func:`xcheck.ladder.applicable_findings`); for a mode that
        failed, under :data:`~xcheck.ladder.FAILURE`, those that hold for its
        failed run.
    """

    mode: str
    ok: bool
    reason: str = ""
    passed: bool = False
    categories: pd.DataFrame = field(default_factory=pd.DataFrame)
    details: pd.DataFrame = field(default_factory=pd.DataFrame)
    result: ModeResult | None = None
    trajectory: Trajectory | None = None
    errors: dict = field(default_factory=dict)
    seconds: float = 0.0
    findings: dict = field(default_factory=dict)

    @property
    def finding(self) -> str:
        """The engine's stated defects (:attr:`xcheck.engines.Engine.findings`) where
        every category the mode fails has one that holds (:attr:`findings`), or
        where it failed, one holds for its failed run; "" where it passed, or fails
        in a way no finding explains."""
        if self.mode == "native" or (self.ok and (self.passed or self.categories.empty)):
            return ""
        failing = (
            pd.Series([FAILURE]) if not self.ok else self.categories.category[~self.categories.passed.astype(bool)]
        )
        return explained(failing, self.findings)

    @property
    def verdict(self) -> str:
        """ "pass", "finding" (it fails, or did not run through, only in its
        engine's stated findings), "fail" (beyond a tolerance elsewhere) or
        "failed" (it did not run through)."""
        if not self.ok:
            return "finding" if self.finding else "failed"
        return "pass" if self.passed else "finding" if self.finding else "fail"


def explained(failing, findings: dict) -> str:
    """The texts (joined by "; ") of the stated findings that explain every one of
    ``failing`` (quantity names) by ``findings`` (quantity name to the findings that
    hold for it); "" where any is unexplained, or none fails."""
    failing = list(failing)
    if not failing or not all(findings.get(quantity) for quantity in failing):
        return ""
    return "; ".join(dict.fromkeys(f.text for quantity in failing for f in findings[quantity]))


def run_verdict(verdicts, others_pass: bool) -> str:
    """The one rule of a run's verdict (:data:`VERDICTS`), from the verdicts of its
    modes and force sources (:attr:`ModeOutcome.verdict`, :func:`force_verdict`;
    sources that do not apply left out) and whether its power balance is within
    its tolerance: "fail" where a mode or source fails or failed or the balance
    does not pass, else "pass with findings" where one fails only in its engine's
    stated findings, else "pass"."""
    verdicts = list(verdicts)
    if not others_pass or any(v not in ("pass", "finding") for v in verdicts):
        return "fail"
    return "pass with findings" if "finding" in verdicts else "pass"


#: the verdicts of a run, best first (:attr:`RunResult.verdict`)
VERDICTS = ("pass", "pass with findings", "fail")
#: the exit code of ``xcheck run`` per verdict; 2 is bad input
EXIT_CODES = {"pass": 0, "pass with findings": 0, "fail": 1}
#: the columns of :attr:`RunResult.summary`
SUMMARY_COLUMNS = ("engine", "mode", "kind", "verdict", "category", "error", "tolerance", "reason")


@dataclass
class RunResult:
    """Everything ``xcheck run`` found for one mechanism.

    ``provenance`` maps each mode that the results cache answered or kept to its
    :class:`xcheck.result_cache.Provenance` (from the cache or computed, when, and
    why an entry there was not used); empty where the cache was not used.
    ``left_out`` maps the modes run only on request that a run of every
    default mode did not run to why they wait to be asked for
    (:func:`left_out`).
    """

    kinematics: Kinematics
    branch: str
    native: Solution
    outcomes: dict[str, ModeOutcome]
    not_applicable: dict[str, str]
    textbook: list[dict]
    seconds: float
    forces: list[ForceResult] = field(default_factory=list)
    force_table: pd.DataFrame = field(default_factory=pd.DataFrame)
    native_forces: Forces | None = None
    energy: dict | None = None
    no_forces: str = ""
    no_energy: str = ""
    floors: dict = field(default_factory=dict)
    #: what the file asks that the mechanism cannot do (:func:`xcheck.motion.drive_warnings`), then
    #: where the sweep passes near a limit or singular position (:func:`xcheck.states.limit_warnings`)
    warnings: list[str] = field(default_factory=list)
    provenance: dict = field(default_factory=dict)
    left_out: dict = field(default_factory=dict)

    @property
    def mechanism(self):
        return self.kinematics.mechanism

    @property
    def passed(self) -> bool:
        """Every mode within its tolerance, or failing only where its engine's
        stated findings say (:attr:`ModeOutcome.finding`), and the reactions
        and the power balance within theirs: the :attr:`verdict` is not "fail"."""
        return self.verdict != "fail"

    @property
    def findings(self) -> dict[str, str]:
        """Mode name (a force source: ``ENGINE-forces``) to its stated finding, for the
        modes and force sources that fail only there."""
        modes = {mode: o.finding for mode, o in self.outcomes.items() if o.finding}
        forces = self.force_table
        sources = {} if "finding" not in forces else dict(zip(forces.engine, forces.finding))
        return modes | {f"{source}-forces": finding for source, finding in sources.items() if finding}

    @property
    def verdict(self) -> str:
        """The run's one verdict (:data:`VERDICTS`): "pass" when every mode,
        the reactions and the power balance are within their tolerances, "pass
        with findings" when every failure is an engine's stated finding
        (:attr:`findings`), else "fail". The exit code of ``xcheck run`` follows
        it (:data:`EXIT_CODES`)."""
        forces = [v for v in self.force_table.get("verdict", []) if v != "not applicable"]
        energy_pass = self.energy is None or bool(self.energy["passed"])
        return run_verdict([*(o.verdict for o in self.outcomes.values()), *forces], energy_pass)

    @property
    def summary(self) -> pd.DataFrame:
        """One row per mode (:data:`SUMMARY_COLUMNS`): engine, mode, kind
        (native, kinematic, dynamic), verdict ("pass"; "finding": it fails
        only where its engine is known to be wrong; "fail"; "failed": it did
        not run through; "not applicable"), the category whose relative error
        is largest against its tolerance, that error and tolerance (relative:
        see :class:`ModeOutcome`), and the reason of a mode that failed or does
        not apply, or its finding."""
        rows = []
        for mode, outcome in self.outcomes.items():
            worst: tuple[float, str, float, float] | None = None  # (ratio, category, relative, tolerance)
            for category, relative, limit in zip(
                outcome.categories.get("category", []),
                outcome.categories.get("relative", []),
                outcome.categories.get("tolerance", []),
            ):
                relative, limit = float(relative), float(limit)
                ratio = relative / limit if limit > 0 else math.inf
                if worst is None or not ratio <= worst[0]:
                    worst = (ratio, str(category), relative, limit)
            rows.append(
                {
                    "engine": "xcheck" if mode == "native" else engines.engine_of(mode).name,
                    "mode": mode,
                    "kind": "native" if mode == "native" else engines.mode(mode).kind,
                    "verdict": outcome.verdict,
                    "category": worst[1] if worst else None,
                    "error": worst[2] if worst else math.nan,
                    "tolerance": worst[3] if worst else math.nan,
                    "reason": outcome.reason or outcome.finding or None,
                }
            )
        for mode, reason in self.not_applicable.items():
            rows.append(
                {
                    "engine": engines.engine_of(mode).name,
                    "mode": mode,
                    "kind": engines.mode(mode).kind,
                    "verdict": "not applicable",
                    "category": None,
                    "error": math.nan,
                    "tolerance": math.nan,
                    "reason": reason,
                }
            )
        return pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))

    def __repr__(self) -> str:
        return f"<RunResult {self.mechanism.name}: {self.verdict}, {len(self.outcomes)} modes run>"

    def _repr_html_(self) -> str:
        """The summary as an HTML table under a line with the verdict (a notebook shows this)."""
        from html import escape

        head = f"<p><b>{escape(self.mechanism.name)}</b>: {escape(self.verdict)} ({self.seconds:.1f} s)</p>"
        return head + self.summary.to_html(index=False, na_rep="", float_format=lambda v: f"{v:.3g}")

    def worst(self) -> tuple[str, str, float, float] | None:
        """(mode, category, relative error, tolerance) of the largest error
        relative to its tolerance, over the modes that ran, but those failing
        only in their stated findings (:attr:`findings`); None if none."""
        best = None
        for outcome in self.outcomes.values():
            if outcome.finding:
                continue
            for _, row in outcome.categories.iterrows():
                ratio = row.relative / row.tolerance if row.tolerance > 0 else math.inf
                if best is None or ratio > best[0]:
                    best = (ratio, (outcome.mode, row.category, float(row.relative), float(row.tolerance)))
        return None if best is None else best[1]


def is_static(mechanism) -> bool:
    """True when no driver moves: every state of the sweep is a static position
    (rates and accelerations zero), so there is no motion to integrate."""
    return all(d.law.static for d in mechanism.drivers)


def sweep_inputs(kinematics: Kinematics, samples: int, branch: str | None = None, margin: float = 1e-2):
    """The native sweep: the first driver over its feasible range (one turn for a
    crank, ``margin`` of the range clear of each limit position), other drivers
    at their assembly values; rates and accelerations from the motion laws
    (:func:`xcheck.motion.law_states`, the rule of ``xcheck solve --at``), the
    sweep narrowed to the values the first driver's law reaches.

    Near a limit position every method loses digits in proportion to the
    condition number of the equations (the exact formulations differ from the
    general solver by 6e-12 at 0.1 % of the range, 1.6e-13 at 1 %), so the
    comparison at round-off keeps 1 % clear; the feasible range itself is
    reported to 1e-10.

    Returns
    -------
    inputs, rates, accelerations : ndarray, shape (samples, k)
    """
    mech = kinematics.mechanism
    ref = kinematics.reference_inputs()
    span = sweep_span(kinematics, 0, branch, margin)
    inputs = np.tile(ref, (samples, 1))
    inputs[:, 0] = np.linspace(*span, samples)
    if samples > 1 and not np.all(np.diff(inputs[:, 0]) > 0.0):  # a double too coarse there: samples coincide
        driver = mech.drivers[0]
        raise InputError(
            f"{mech.path}: assembly.at.{driver.name}: expected an input a double holds finely enough to sweep "
            f"{samples} distinct samples around it, found "
            f"{mech.units.show_input(driver.quantity, float(inputs[0, 0]))}, where they coincide"
        )
    rates, accelerations, reached = law_states(mech, inputs)
    for k, driver in enumerate(mech.drivers):
        if not reached[:, k].all():
            shown = mech.units.show_input(driver.quantity, float(inputs[np.argmin(reached[:, k]), k]))
            raise InputError(
                f"{mech.path}: assembly.at.{driver.name}: expected a value that the driver's "
                f"{driver.law.kind} motion reaches (the sweep takes the rates from the laws), "
                f"found {shown}, which it never does"
            )
    return inputs, rates, accelerations


def _categorise(
    kinematics: Kinematics, details: pd.DataFrame, tolerance: Tolerance, condition: float = 1.0
) -> pd.DataFrame:
    """Per category: the worst row of a differences table against the tolerance;
    ``floor`` is the physical floor of the category's scale (the table's)."""
    size = kinematics.system.size
    rows = []
    for category in CATEGORIES:
        part = details[details.quantity == category]
        if part.empty:
            continue
        if category == "position":
            relative = part.max_abs / size
        elif category == "angle":
            relative = part.max_abs
        else:  # against the largest magnitude of the quantity anywhere in the mechanism, floored
            relative = part.max_abs / float(part.scale.max())
        worst = int(np.argmax(relative.to_numpy()))
        row = part.iloc[worst]
        limit = tolerance.limit(category, condition)
        missing = int(part.missing.max()) if "missing" in part else 0
        rows.append(
            {
                "category": category,
                "max_abs": float(part.max_abs.max()),
                "rms": float(np.sqrt(np.mean(part.rms.to_numpy() ** 2))),
                "relative": float(relative.iloc[worst]),
                "tolerance": limit,
                "round_off": conditioned_round_off(category, condition, tolerance.conditioning_factor),
                "floor": float(part["floor"].max()) if "floor" in part else math.nan,
                "passed": bool(relative.iloc[worst] <= limit) and missing == 0,
                "missing": missing,
                "worst": f"{row['kind']} {row['name']}" + (f" ({undetermined_text(missing)})" if missing else ""),
                "worst_input": float(row.worst_input),
            }
        )
    return pd.DataFrame(rows)


def convergence_limit(
    coarse_error: float, coarse_step: float, fine_step: float, order: float, round_off: float
) -> float:
    """The largest error at ``fine_step`` that still shows convergence at an
    order of at least ``order`` - :data:`ORDER_MARGIN` from ``coarse_error`` at
    ``coarse_step``, plus ``round_off`` (:func:`convergence_round_off`): the
    error is the truncation, which falls with the step, on top of the
    engine's noise floor, which does not (Pinocchio's accelerations on a
    crank-rocker driven near its limit: 1.63e-8 then 1.61e-9 as the step
    halves, truncation C h^4 over a floor of 6e-10). NaN when the coarse
    error is not finite."""
    if not math.isfinite(coarse_error):
        return math.nan
    return round_off + coarse_error * (fine_step / coarse_step) ** (order - ORDER_MARGIN)


def _step_and_series(trajectory: Trajectory) -> tuple[float, str]:
    """The time step (s) and the series (what makes runs of one ladder) of a
    dynamic mode's trajectory, from its settings (the engine contract)."""
    settings = trajectory.settings
    return float(settings.get("timestep", math.nan)), str(settings.get("series", ""))


def _coordinate_extent(trajectory: Trajectory, size: float) -> float:
    """The largest coordinate of a trajectory: its bodies' angles (rad) and its
    bodies' and points' positions (of the ``size``, m), in absolute value; 0 where
    it has none."""
    parts = [np.abs(np.asarray(b["angle"], float)).ravel() for b in trajectory.bodies.values() if "angle" in b]
    parts += [
        np.abs(np.asarray(x["position"], float)).ravel() / size
        for x in (*trajectory.bodies.values(), *trajectory.points.values())
        if "position" in x
    ]
    return float(np.nanmax(np.concatenate(parts), initial=0.0)) if parts else 0.0


def _convergence_verdict(
    kinematics: Kinematics,
    mode: str,
    result: ModeResult,
    categories: pd.DataFrame,
    tolerance: Tolerance,
    floors: dict,
    branch: str | None,
) -> pd.DataFrame:
    """Judge a dynamic mode's categories by its convergence to the exact answer.

    The compared run (time step h_f) and the next coarser run of the same
    series (h_c, same integrator and settings) give per category the errors
    e_f and e_c (relative as in :func:`_categorise`) and the observed order
    :func:`~xcheck.results.observed_order`. A category with an expected order
    p (the mode's ``orders``, :class:`xcheck.engines.Mode`, or the compared trajectory's
    ``settings["orders"]`` where the run states an engine limitation) passes when e_f <= :func:`convergence_limit`
    (e_c, h_c, h_f, p), i.e. the observed order is at least p -
    :data:`ORDER_MARGIN`, or e_f is at round-off; ``tolerance`` becomes that
    limit. Added columns: expected_order, observed_order, coarse_error,
    coarse_step, step (s), estimate (e_c (h_f / h_c)^p, the error the expected
    order predicts for the compared run), basis (one line).
    """
    compared = result.trajectories[0]
    # a run may declare lower orders for a stated engine limitation (its settings' "orders")
    expected = {**engines.mode(mode).orders, **compared.settings.get("orders", {})}
    step, series = _step_and_series(compared)
    coarser = [t for t in result.trajectories[1:] if _step_and_series(t)[1] == series and _step_and_series(t)[0] > step]
    coarse = min(coarser, key=lambda t: _step_and_series(t)[0]) if coarser else None
    coarse_errors, coarse_step = {}, math.nan
    if coarse is not None:
        coarse_step = _step_and_series(coarse)[0]
        table = _categorise(kinematics, differences(kinematics, coarse, branch=branch, floors=floors), tolerance)
        coarse_errors = dict(zip(table.category, table.relative))
    extent = _coordinate_extent(compared, floors["size"])
    categories = categories.copy()
    for column in ("expected_order", "observed_order", "coarse_error", "coarse_step", "step", "estimate"):
        categories[column] = math.nan
    categories["basis"] = ""
    for i, row in categories.iterrows():
        order = expected.get(row.category)
        if order is None:
            categories.loc[i, "basis"] = f"fixed bound {row.tolerance:g} (the quantity does not converge)"
            continue
        fine = float(row.relative)
        coarse_error = float(coarse_errors.get(row.category, math.nan))
        round_off = convergence_round_off(row.category, step, extent, floors["rate"])
        limit = convergence_limit(coarse_error, coarse_step, step, order, round_off)
        estimate = coarse_error * (step / coarse_step) ** order if math.isfinite(coarse_error) else math.nan
        observed = observed_order(coarse_error, fine, coarse_step, step)
        by_order = coarse is not None and math.isfinite(coarse_error) and fine <= limit
        ladder = (
            f"from {coarse_error:.3g} at dt = {coarse_step:.4g} s to {fine:.3g} at dt = {step:.4g} s; "
            f"the expected order predicts {estimate:.3g}"
        )
        if by_order or (coarse is not None and fine > round_off):
            basis = (
                f"observed order {observed:.3g} (expected {order:g}; accepted: the error falls at least at "
                f"order {order - ORDER_MARGIN:g} above a noise floor of {round_off:.3g}) " + ladder
            )
        elif fine <= round_off:
            basis = f"within the engine's round-off bound ({fine:.2g} <= {round_off:g}), where no order shows" + (
                f" (observed {observed:.3g} " + ladder + ")" if coarse is not None else ""
            )
            limit = round_off if math.isnan(limit) else limit
        else:
            basis = "no coarser run of the same settings ran through: the order cannot be observed"
        if row.category in compared.settings.get("orders", {}):
            basis += f"; the run expects order {order:g} here: {compared.settings.get('orders_reason', '')}"
        categories.loc[
            i, ["expected_order", "observed_order", "coarse_error", "coarse_step", "step", "estimate", "tolerance"]
        ] = [order, observed, coarse_error, coarse_step, step, estimate, limit]
        categories.loc[i, "passed"] = bool(fine <= limit) and int(row.missing) == 0
        categories.loc[i, "basis"] = basis
    categories["passed"] = categories["passed"].astype(bool)
    return categories


def _native_self_check(
    kinematics: Kinematics, native: Solution, tolerance: Tolerance, floors: dict[str, float]
) -> ModeOutcome:
    """The general solver against its own equations: Phi = 0, Phi_q qd = -Phi_t, Phi_q qdd = gamma;
    rates relative to the largest |qd| or |qdd| in m/s or m/s^2 (angles' times the size), floored by
    ``floors`` (:func:`scale_floors`). (It was the size times the largest |qd|, m^2/s where a length's
    rate is the largest: 1000 times too lax at 1 km, so a wrong rate 1e-10 of the speed passed.)"""
    system = kinematics.system
    good = native.status <= 1
    if not good.any():
        return ModeOutcome("native", False, "no sample of the sweep assembled")
    q, qd, qdd = native.q[good], native.qd[good], native.qdd[good]
    jac = system.jacobian(q)
    velocity_gap = np.einsum("nij,nj->ni", jac, qd) - system.velocity_rhs(native.input_rates[good])
    acceleration_gap = np.einsum("nij,nj->ni", jac, qdd) - system.gamma(q, qd, native.input_accelerations[good])
    inputs = native.inputs[good, 0]
    # the largest rate of any coordinate in m/s (m/s^2): lengths as they are, angles times the size
    metres = system.size * system.coordinate_scale()
    rows = []
    for category, gap, scale in (
        ("position", native.residual[good], system.size),
        ("velocity", system.residual_metres(velocity_gap), max(floors["velocity"], np.max(np.abs(qd * metres)))),
        (
            "acceleration",
            system.residual_metres(acceleration_gap),
            max(floors["acceleration"], np.max(np.abs(qdd * metres))),
        ),
    ):
        worst = int(np.argmax(gap))
        relative = float(gap[worst] / scale)
        rows.append(
            {
                "category": category,
                "max_abs": float(gap[worst]),
                "rms": float(np.sqrt(np.mean(gap**2))),
                "relative": relative,
                "tolerance": tolerance.limit(category),
                # residuals of the equations are backward errors: round-off the conditioning does not amplify
                "round_off": conditioned_round_off(category, 1.0),
                "floor": floors.get(category, math.nan),
                "passed": relative <= tolerance.limit(category),
                "worst": "constraint equations",
                "worst_input": float(inputs[worst]),
            }
        )
    table = pd.DataFrame(rows)
    failed = int((~good).sum())
    reason = f"{failed} of {len(good)} samples did not assemble" if failed else ""
    return ModeOutcome("native", True, reason, bool(table.passed.all()) and not failed, table)


def condition_number(solution: Solution) -> float:
    """The largest condition number of the scaled constraint Jacobian over a
    solution's determined samples (1 if none)."""
    good = (solution.status <= 1) & (solution.singularity > 0)
    return float(1.0 / solution.singularity[good].min()) if good.any() else 1.0


def _run_mode(
    kinematics: Kinematics, mode: str, native: Solution, samples: int, branch: str | None, floors: dict[str, float]
):
    """Run one non-native mode; never raises (a failure is an outcome). ``floors``:
    the physical floors of the scales (:func:`scale_floors` of the native sweep)."""
    start = time.perf_counter()
    engine, kind = engines.engine_of(mode), engines.mode(mode).kind
    ladder = None
    try:
        if kind == "dynamic":
            try:
                ladder = engine.dynamic_ladder(mode, kinematics, branch)
            except NotImplementedError:  # a plug-in that runs its own ladder in run()
                ladder = None
        if ladder is not None:
            result = ladder.run()
        else:
            result = engine.run(mode, kinematics, native=native, samples=samples, branch=branch)
    except NotApplicable:
        raise
    except Exception as err:  # an engine's failure is this mode's outcome, not the run's
        findings = {FAILURE: tuple(applicable_findings(engine.findings, kind, FAILURE, kinematics.mechanism))}
        return ModeOutcome(mode, False, one_line(err), seconds=time.perf_counter() - start, findings=findings)
    if not result.ok or not result.trajectories:
        failed = result.failed_run
        findings = {
            FAILURE: tuple(
                applicable_findings(
                    engine.findings, kind, FAILURE, kinematics.mechanism, failed.get("series"), failed.get("timestep")
                )
            )
        }
        why = result.reason or "no trajectory"
        return ModeOutcome(mode, False, why, result=result, seconds=time.perf_counter() - start, findings=findings)
    trajectory, reference, details, categories = _judge(kinematics, mode, result, floors, branch)
    short = _order_short(categories)
    orders = [_observed_orders(categories, short)]
    for refine in range(1, REFINEMENTS + 1):
        if not _order_short(categories):
            break
        if ladder is None:
            note = "; not refined: the engine runs its own ladder (it has no run_dynamic_once)"
            categories = _with_basis(categories, note, short)
            break
        try:
            finer = ladder.refine(refine)
        except Exception as err:  # noqa: BLE001 - the ladder's verdict stands, with why it was not refined
            finer = ModeResult(mode, kinematics.mechanism.name, False, one_line(err))
        if not finer.ok or not finer.trajectories:
            why = finer.reason or "no trajectory"
            categories = _with_basis(categories, f"; its finest step halved {_times(refine)} failed: {why}", short)
            categories["refinement_failure"] = why
            break
        result = finer
        trajectory, reference, details, categories = _judge(kinematics, mode, result, floors, branch)
        orders.append(_observed_orders(categories, short))
        categories = _with_basis(categories, _refinement_note(refine, orders), short)
        categories["refinements"] = refine
    passed = bool(not categories.empty and categories.passed.all())
    judged = (kinematics.mechanism, trajectory.settings.get("series"), trajectory.settings.get("timestep"))
    findings = {c: tuple(applicable_findings(engine.findings, kind, c, *judged)) for c in categories.category}
    return ModeOutcome(
        mode,
        True,
        "",
        passed,
        categories,
        details,
        result,
        trajectory,
        sample_errors(trajectory, reference),
        time.perf_counter() - start,
        findings,
    )


def _judge(kinematics: Kinematics, mode: str, result: ModeResult, floors: dict[str, float], branch: str | None):
    """A mode's result against the native solution: (compared trajectory, the
    native states at its inputs, differences, categories with their verdicts)."""
    tolerance = engines.mode(mode).tolerance
    trajectory = result.trajectories[0]
    reference = native_at(kinematics, trajectory, branch)
    details = differences(kinematics, trajectory, branch=branch, native=reference, floors=floors)
    categories = _categorise(kinematics, details, tolerance, condition_number(reference))
    if engines.mode(mode).kind == "dynamic" and not categories.empty:
        categories = _convergence_verdict(kinematics, mode, result, categories, tolerance, floors, branch)
    return trajectory, reference, details, categories


def _order_short(categories: pd.DataFrame) -> list[str]:
    """The categories of a dynamic mode that failed by an observed order short
    of the expected one, when every other failing one failed its fixed bound
    (a quantity its engine states does not converge) and no sample is missing:
    what a finer ladder may settle; else []."""
    if categories.empty or "basis" not in categories:
        return []
    failing = categories[~categories.passed.astype(bool)]
    by_order = failing.basis.str.startswith("observed order")
    if not by_order.any() or not (by_order | failing.basis.str.startswith("fixed bound")).all():
        return []
    return [] if int(failing.missing.sum()) else list(failing.category[by_order])


def _observed_orders(categories: pd.DataFrame, names: list[str]) -> str:
    """The observed orders of the ``names`` categories, one line."""
    if "observed_order" not in categories:
        return ""
    rows = categories[categories.category.isin(names)]
    return ", ".join(f"{name} {order:.3g}" for name, order in zip(rows.category, rows.observed_order.astype(float)))


def _refinement_note(refine: int, orders: list[str]) -> str:
    """What the refined ladders showed, for a category's basis."""
    return (
        f"; judged on the ladder's finest step halved {_times(refine)}, as its own orders fell short "
        f"(observed orders, coarsest pair first: {'; '.join(orders)})"
    )


def _times(count: int) -> str:
    """ "once", "twice", "3 times"."""
    return {1: "once", 2: "twice"}.get(count, f"{count} times")


def _with_basis(categories: pd.DataFrame, note: str, names: list[str]) -> pd.DataFrame:
    """``categories`` with ``note`` appended to the basis of the ``names`` categories."""
    categories = categories.copy()
    judged = categories.category.isin(names)
    categories.loc[judged, "basis"] = categories.loc[judged, "basis"] + note
    return categories


def run_mechanism(
    kinematics: Kinematics,
    modes=None,
    samples: int = DEFAULT_SAMPLES,
    branch: str | None = None,
    textbook: list[dict] | None = None,
    progress=None,
    jobs: int = 1,
    cache: bool = True,
    meanwhile: Callable[[], object] | None = None,
) -> RunResult:
    """Run the native solver and the requested modes on one mechanism.

    Parameters
    ----------
    modes : sequence of str
        Names from :func:`all_modes` (default: all but those run only on
        request, :attr:`xcheck.engines.Mode.on_request`); "native" always runs.
    samples : int
        Samples of the native sweep and of the kinematic modes' sweeps.
    textbook : list of dict, optional
        The printed-answer checks to carry into the result.
    progress : callable, optional
        Called with each mode's name before it runs (with ``jobs`` > 1: as it
        finishes), and with "forces" before the reactions.
    jobs : int
        Modes run at once, each in a worker process (1: one after another in
        this process), where that could save time (:data:`PARALLEL_SAVING`).
        The results are those of a serial run.
    cache : bool
        Take each mode's outcome from the results cache where it holds one
        made by this code, and keep what was computed there
        (:mod:`xcheck.result_cache`; also off where ``$XCHECK_RESULTS_CACHE`` or
        ``$XCHECK_CACHE_DIR`` is ``off``). The outcomes are the same either way.
    meanwhile : callable, optional
        Called once where a mode is computed (not every one taken from the results
        cache): after the reactions in a serial run; where worker processes run the
        modes (and the reactions of their engines), after this process's share of the
        reactions, while it waits for them. Work of this process that needs none of the
        modes' results, such as a report's imports.
    """
    from . import result_cache

    start = time.perf_counter()
    static = is_static(kinematics.mechanism)
    branch_name = kinematics._branch_name(branch)
    inputs, rates, accelerations = sweep_inputs(kinematics, samples, branch)
    simulation_window(kinematics, branch)  # one rule for every file: a motion that starts outside is refused here
    native = kinematics.solve(inputs, rates, accelerations, branch=branch)
    floors = scale_floors(kinematics.mechanism, rates, accelerations)
    outcomes = {"native": _native_self_check(kinematics, native, NATIVE_TOLERANCE, floors)}
    if modes is None:
        modes = default_modes()
    modes = tuple(m for m in modes if m != "native")
    reasons = {}  # mode to why it does not run here
    for mode in modes:
        if mode not in all_modes():
            raise ValueError(f"expected modes among {', '.join(all_modes())}, found {mode!r}")
        missing = engines.engine_of(mode).available()
        if missing:
            reasons[mode] = missing
        elif static and engines.mode(mode).kind == "dynamic":
            reasons[mode] = (
                "the drivers stand still (every state is a static position): there is no motion to integrate"
            )
    run = RunResult(kinematics, branch_name, native, outcomes, {}, textbook or [], 0.0, floors=floors)
    run.warnings = [*drive_warnings(kinematics, branch), *limit_warnings(native, branch)]
    run.left_out = left_out(("native", *modes))
    cached = {}
    cache = cache and result_cache.enabled()
    for mode in modes if cache else ():
        if mode not in reasons:
            parts, used = (mode, samples, branch_name), (engines.engine_of(mode),)
            cached_outcome, run.provenance[mode] = result_cache.lookup(kinematics, mode, parts, used)
            if cached_outcome is not None:
                cached[mode] = cached_outcome
    runnable = [mode for mode in modes if mode not in reasons and mode not in cached]
    arguments = (kinematics, native, samples, branch, floors)
    if worth_workers(runnable, jobs):
        for mode in modes:
            if progress is not None and mode not in runnable:
                progress(mode)
        ran = _run_modes_in_parallel(run, runnable, modes, arguments, jobs, progress, cache, meanwhile)
    else:
        ran = {}
        for mode in modes:
            if progress is not None:
                progress(mode)
            if mode in runnable:
                ran[mode] = _run_or_not_applicable(mode, *arguments)
        _add_forces(run, modes, branch, progress, cache)
        if meanwhile is not None and runnable:  # with every mode cached there is no wait to fill
            meanwhile()
    for mode in runnable if cache else ():  # what ran through, or does not apply: a failure may be the machine's
        if isinstance(ran[mode], NotApplicable) or ran[mode].ok:
            parts, used = (mode, samples, branch_name), (engines.engine_of(mode),)
            recomputed = run.provenance[mode].recomputed
            run.provenance[mode] = result_cache.keep(kinematics, parts, used, ran[mode], recomputed)
    ran.update(cached)
    for mode in modes:  # in the order asked for, however the modes ran
        if mode in reasons or isinstance(ran[mode], NotApplicable):
            run.not_applicable[mode] = reasons.get(mode) or ran[mode].reason
        else:
            outcomes[mode] = ran[mode]
    run.seconds = time.perf_counter() - start
    return run


def worth_workers(modes, jobs: int, scale: float = 1.0) -> bool:
    """Whether running ``modes`` in ``jobs`` worker processes could save time: two or more
    of them, whose summed :attr:`~xcheck.engines.Mode.cost` times ``scale`` (a free mode's
    cost is per simulated second: ``scale`` the duration, s) less the costliest exceeds
    :data:`PARALLEL_SAVING`."""
    known = {mode.name: mode.cost for mode in engines.modes()}
    costs = [known[mode] * scale for mode in modes if mode in known]
    return jobs > 1 and len(costs) > 1 and sum(costs) - max(costs) > PARALLEL_SAVING


def costliest_first(modes) -> list[str]:
    """``modes`` by falling :attr:`~xcheck.engines.Mode.cost` (the order of equal ones kept):
    the order a pool starts them in, so that the longest does not start last."""
    return sorted(modes, key=lambda mode: -engines.mode(mode).cost)


def _run_or_not_applicable(mode: str, kinematics: Kinematics, native: Solution, samples, branch, floors):
    """:func:`_run_mode`, or the mode's :class:`NotApplicable` returned rather
    than raised (how a worker process hands it back)."""
    try:
        return _run_mode(kinematics, mode, native, samples, branch, floors)
    except NotApplicable as err:
        return err


def _run_modes_in_parallel(
    run: RunResult,
    runnable: list[str],
    modes: tuple[str, ...],
    arguments: tuple,
    jobs: int,
    progress,
    cache: bool,
    meanwhile: Callable[[], object] | None = None,
) -> dict:
    """Each of the ``runnable`` modes in a pool of ``jobs`` worker processes, the
    costliest first (:attr:`xcheck.engines.Mode.cost`), each engine's reactions
    computed after its costliest mode there, by the worker that has loaded the engine
    (:func:`_run_with_forces`); meanwhile this process computes the native reactions,
    the power balance and the reactions of the engines none of whose modes a worker
    runs, then runs the modes of engines registered at run time, which a worker does not
    know (:func:`xcheck._parallel.known_to_workers`), then ``meanwhile``, and at last
    judges the reactions (:func:`_add_forces`). Returns mode name to its
    :class:`ModeOutcome` or :class:`NotApplicable`. A worker that dies (an engine's
    crash) is that mode's failure, with the reason, and its reactions' too."""
    from ._parallel import collect, known_to_workers, process_pool, submit

    branch = arguments[3]  # (kinematics, native, samples, branch, floors)
    here = [mode for mode in runnable if not known_to_workers(mode)]
    away = costliest_first(mode for mode in runnable if mode not in here)
    sources = _forces_wanted(run, modes, progress, cache)
    with_forces = {}  # mode to the force source computed after it
    for source in sources[1:]:  # newton-euler, the first, is this process's
        mode = next((m for m in away if engines.engine_of(m).name == source), None)
        if mode is not None:
            with_forces[mode] = source
    calls = {
        mode: (_run_with_forces, (mode, with_forces[mode], *arguments))
        if mode in with_forces
        else (_run_or_not_applicable, (mode, *arguments))
        for mode in away
    }
    with process_pool(max(1, min(jobs, len(away)))) as pool:
        futures = submit(pool, calls)
        forces = _NativeForces(run, branch) if sources else None
        computed = {s: engine_forces(run.kinematics, s, branch) for s in sources if s not in with_forces.values()}
        ran = {}
        for mode in here:
            if progress is not None:
                progress(mode)
            ran[mode] = _run_or_not_applicable(mode, *arguments)
        if meanwhile is not None:
            meanwhile()
        ran.update(collect(futures, lambda mode, why: ModeOutcome(mode, False, why), progress, calls, jobs))
    for mode, source in with_forces.items():
        if isinstance(ran[mode], tuple):
            ran[mode], computed[source] = ran[mode]
        else:  # its worker died: the mode failed, and the reactions after it were not computed
            computed[source] = ForceResult(source, run.mechanism.name, False, ran[mode].reason)
    if forces is not None:
        forces.judge([computed[s] for s in sources], cache)
    return ran


def _run_with_forces(mode: str, source: str, kinematics: Kinematics, native: Solution, samples, branch, floors):
    """(:func:`_run_or_not_applicable` of ``mode``, then the reactions of the force
    source ``source`` (:func:`~xcheck.reactions.engine_forces`)): in the worker that has
    loaded the mode's engine, the reactions of that engine."""
    outcome = _run_or_not_applicable(mode, kinematics, native, samples, branch, floors)
    return outcome, engine_forces(kinematics, source, branch)


#: what :func:`_add_forces` sets on a run (and the results cache keeps)
_FORCE_FIELDS = ("native_forces", "forces", "force_table", "energy", "no_energy")


def _add_forces(run: RunResult, modes, branch: str | None, progress, cache: bool = False) -> None:
    """Reactions and efforts of every source against the native multipliers,
    and the native power balance, when every moving body has mass data; from
    the results cache where ``cache`` and it holds them."""
    sources = _forces_wanted(run, modes, progress, cache)
    if sources:
        forces = _NativeForces(run, branch)
        forces.judge(compare_forces(run.kinematics, sources, branch), cache)


def _forces_wanted(run: RunResult, modes, progress, cache: bool) -> list[str]:
    """The force sources whose reactions are to be computed: "newton-euler", then each
    engine with reactions that runs one of ``modes``; none where a moving body lacks
    mass data or a load varies (``run.no_forces`` says why), or where ``cache`` and the
    results cache holds them (set on ``run``). ``progress("forces")`` before."""
    from . import result_cache

    kinematics = run.kinematics
    try:
        require_mass_data(kinematics.mechanism)
        require_constant_loads(kinematics.mechanism)
    except XcheckError as err:
        run.no_forces = str(err)
        return []
    sources = ["newton-euler"] + [
        e.name
        for e in engines.engines()
        if e.force_tolerance is not None and not e.available() and any(m.name in modes for m in e.modes)
    ]
    if progress is not None:
        progress("forces")
    if cache:
        kept, run.provenance["forces"] = result_cache.lookup(kinematics, "forces", *_forces_key(run, sources))
        if kept is not None:
            for name in _FORCE_FIELDS:
                setattr(run, name, kept[name])
            return []
    return sources


def _forces_key(run: RunResult, sources: list[str]) -> tuple[tuple, tuple]:
    """The results cache's (parts, engines used) of a run's reactions from ``sources``."""
    return ("forces and energy", tuple(sources), run.branch), tuple(engines.engine(s) for s in sources[1:])


class _NativeForces:
    """A run's native reactions and power balance, computed when made; :meth:`judge`
    then sets the sources' reactions against them on the run (:func:`_add_forces`)."""

    def __init__(self, run: RunResult, branch: str | None):
        kinematics = run.kinematics
        self.run, self.branch = run, branch
        states = window_states(kinematics, branch)
        run.native_forces = inverse_dynamics(states)
        self.condition = condition_number(states)
        self.ratio = length_ratio(kinematics.mechanism)
        try:
            energy = energy_summary(kinematics, branch)
        except ValueError as err:  # the motion passes an undetermined state: a balance there means nothing
            run.no_energy = f"over the simulation window, {err}"
            return
        energy["tolerance"] = energy_tolerance(self.condition, self.ratio)
        energy["round_off"] = power_round_off(self.condition, self.ratio)
        energy["passed"] = bool(energy["relative"] <= energy["tolerance"])
        run.energy = energy

    def judge(self, results: list[ForceResult], cache: bool) -> None:
        """Tabulate and judge each source's reactions (``results``, one per source, the
        native per-body form first), refining a source beyond its bound
        (:func:`_refine_forces`), and keep them in the results cache where ``cache`` and
        each ran through or does not apply."""
        from . import result_cache

        run, branch, condition, ratio = self.run, self.branch, self.condition, self.ratio
        sources = [r.engine for r in results]
        run.forces = results
        round_off = {source: force_round_off(source, condition, ratio) for source in sources}
        table = force_summary(run.forces, round_off)
        table["tolerance"] = [force_tolerance(source, condition, ratio) for source in table.engine]
        table["round_off"] = [round_off[source] for source in table.engine]
        table["passed"] = table.ok & (table.max_rel <= table.tolerance)
        table["basis"], table["refinements"], table["refinement_failure"] = "", 0, ""
        for i in table.index[table.ok & ~table.passed]:
            _refine_forces(run, table, i, branch)
        table["finding"] = [_force_finding(run, row) for row in table.itertuples()]
        table["verdict"] = [force_verdict(row) for row in table.itertuples()]
        run.force_table = table
        if cache and all(r.ok or not r.applies for r in run.forces):
            kept = {name: getattr(run, name) for name in _FORCE_FIELDS}
            recomputed = run.provenance["forces"].recomputed
            run.provenance["forces"] = result_cache.keep(run.kinematics, *_forces_key(run, sources), kept, recomputed)


def _force_finding(run: RunResult, row) -> str:
    """The texts of the stated findings of a force source's engine that explain its
    failure (:func:`explained`): every quantity beyond its tolerance, or the source's
    failure to run through (:data:`~xcheck.ladder.FAILURE`), by the findings that hold
    for it (:func:`~xcheck.ladder.applicable_findings`, kind :data:`~xcheck.ladder.REACTIONS`);
    "" where it passed, does not apply, or fails in a way no finding explains."""
    if row.engine == "newton-euler" or not row.applies or (row.ok and row.passed):
        return ""
    if row.ok:
        table = next(r.table for r in run.forces if r.engine == row.engine)
        assert table is not None  # a source that ran through has its table
        beyond = table[table.max_rel.to_numpy(dtype=float) > float(row.tolerance)]
        failing = list(dict.fromkeys(str(q).strip("|") for q in beyond.quantity))
    else:
        failing = [FAILURE]
    findings, mech = engines.engine(row.engine).findings, run.mechanism
    return explained(failing, {q: tuple(applicable_findings(findings, REACTIONS, q, mech)) for q in failing})


def force_verdict(row) -> str:
    """A force source's verdict, as a mode's (:attr:`ModeOutcome.verdict`): "pass",
    "finding" (it fails, or did not run through, only in its engine's stated findings),
    "fail", "failed" (it did not run through) or "not applicable"; ``row``: one of
    :attr:`RunResult.force_table`."""
    if not row.applies:
        return "not applicable"
    if row.ok and row.passed:
        return "pass"
    return "finding" if row.finding else "fail" if row.ok else "failed"


def _refine_forces(run: RunResult, table: pd.DataFrame, row: int, branch: str | None) -> None:
    """Judge a force source beyond its bound whose reactions converge with a time
    step (:attr:`~xcheck.engines.Engine.force_order` p) by their convergence, as a
    dynamic mode's: halve its step up to :data:`REFINEMENTS` times, and pass it
    where its error falls at least at order p - :data:`ORDER_MARGIN`, and at most
    at p + 1, between the last two steps (pymunk's impulses on a Scotch yoke: 0.25, 0.12, 0.08 relative
    at 100, 200, 400 steps a sample, fuzz case s1-00168). ``table`` (a
    :func:`~xcheck.reactions.force_summary` with tolerance, passed, basis) and
    ``run.forces`` take the finest run; ``basis`` says what was seen, and, where
    a finer run failed, why."""
    source = str(table.at[row, "engine"])
    order = None if source == "newton-euler" else engines.engine(source).force_order
    if order is None:
        return
    position = table.index.get_loc(row)
    bound = float(table.tolerance.to_numpy(dtype=float)[position])
    errors, seen = [float(table.max_rel.to_numpy(dtype=float)[position])], []
    for refine in range(1, REFINEMENTS + 1):
        finer = engine_forces(run.kinematics, source, branch, refine=refine)
        if not finer.ok:
            table.at[row, "basis"] = (
                f"beyond its bound {bound:g} at its step ({', '.join(f'{e:.3g}' for e in errors)} as it was "
                f"halved); halved {_times(refine)} it failed: {finer.reason}"
            )
            table.at[row, "refinement_failure"] = finer.reason
            return
        summary = force_summary([finer], {source: float(table.round_off.to_numpy(dtype=float)[position])}).iloc[0]
        errors.append(float(summary.max_rel))
        limit = errors[-2] * 0.5 ** (order - ORDER_MARGIN)
        observed = observed_order(errors[-2], errors[-1], 2.0, 1.0)
        seen.append(f"{observed:.3g}")
        for column in ("max_rel", "name", "quantity", "max_abs", "unit", "floor", "states", "seconds"):
            table.at[row, column] = summary[column]
        run.forces = [finer if r.engine == source else r for r in run.forces]
        # a fall far faster than the order (40.9 then 0.336 relative, s1-00275) says the coarser
        # run was not converging yet: only a further halving can show the order
        settled = observed <= order + 1.0 or errors[-1] <= bound
        accepted = max(bound, limit) if settled else bound
        table.at[row, "tolerance"] = accepted
        table.at[row, "passed"] = errors[-1] <= accepted
        table.at[row, "refinements"] = refine
        table.at[row, "basis"] = (
            f"beyond its bound {bound:g} at its step; the error with the step halved {_times(refine)}: "
            f"{', '.join(f'{e:.3g}' for e in errors)} (observed orders "
            f"{', '.join(seen)}; expected {order:g}, accepted at least {order - ORDER_MARGIN:g})"
        )
        if table.at[row, "passed"]:
            return


def convergence_table(outcome: ModeOutcome) -> pd.DataFrame:
    """A dynamic mode's error against time step, the same for every engine: its
    result's ``study`` (:func:`xcheck.ladder.convergence_study`; columns
    series, timestep (s), position_error (m), status, order, verdict), empty if none."""
    study = None if outcome.result is None else outcome.result.study
    return empty_study() if study is None else study


def energy_tolerance(condition: float = 1.0, ratio: float = 1.0) -> float:
    """The bound on the native power balance (relative to its largest term):
    :data:`ENERGY_TOLERANCE`, but at least the round-off at the states'
    conditioning and the mechanism's length ratio
    (:func:`~xcheck.tolerances.power_round_off`: 10 eps kappa^2 size/shortest;
    1.6e-12 measured at a rod 1000 times its crank, 3.3e-11 at 10 000)."""
    return max(ENERGY_TOLERANCE, power_round_off(condition, ratio))


def force_tolerance(source: str, condition: float = 1.0, ratio: float = 1.0) -> float:
    """The bound on a force source's reactions and efforts relative to the native
    ones: the source's own, but at least the round-off of accelerations at the
    states' conditioning ``condition`` and the mechanism's length ratio
    ``ratio`` (10 eps kappa^2 ratio for Newton-Euler at the native states, 100
    for an engine's own double-precision computation:
    :data:`~xcheck.tolerances.ENGINE_CONDITIONING_FACTOR`, :func:`~xcheck.tolerances.power_round_off`),
    since the reactions come from the accelerations and a body ``ratio`` times
    longer than the crank carries its angular acceleration's round-off (eps
    kappa^2 of the crank's) into forces with its length, while the force scale
    follows the crank's tip (:func:`~xcheck.results.scale_floors`). Measured on a
    rod 1000 times its crank (tests/data/ratio-1000.toml): the ground pin's
    reaction from Newton-Euler, MuJoCo and Pinocchio 3.0e-12 to 3.4e-12 off the
    native multipliers, 15 eps ratio. Measured (xcheck fuzz, seed 1): on a slider-crank
    near its dead centre (kappa = 163) MuJoCo's reactions 5.1e-11 (8.6 eps
    kappa^2), Pinocchio's 1.5e-12 (3.7e-11 before its solves were
    equilibrated); on a near-parallelogram (kappa = 4326) Pinocchio's 1.3e-14
    (3.2e-12 unequilibrated). Over the models with mass data kappa is 2 to 156
    (task-2-1): Newton-Euler's bound stays 1e-12 up to kappa = 21 and is 5.4e-11
    at task-2-1, an engine's 1e-12 up to kappa = 6.7 and 5.4e-10 at task-2-1."""
    bound = NEWTON_EULER_TOLERANCE if source == "newton-euler" else engines.engine(source).force_tolerance
    return math.nan if bound is None else max(bound, force_round_off(source, condition, ratio))


def force_round_off(source: str, condition: float = 1.0, ratio: float = 1.0) -> float:
    """The round-off of a force source's reactions and efforts relative to the
    native ones (:func:`~xcheck.tolerances.power_round_off`): 10 eps kappa^2
    ratio for Newton-Euler at the native states, 100 for an engine's own
    double-precision computation (MuJoCo 14 eps kappa^2 ratio at s1-00158)."""
    factor = CONDITIONING_FACTOR if source == "newton-euler" else ENGINE_CONDITIONING_FACTOR
    return power_round_off(condition, ratio, factor)


def versions() -> dict[str, str]:
    """Versions of xcheck, Python and every engine and library that shapes results."""
    found = {"xcheck": __version__, "python": platform.python_version()}
    packages = [package for e in engines.engines() for package in e.distributions]
    for package in (*packages, "numpy", "scipy", "pandas", "matplotlib"):
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = "not installed"
    return found
