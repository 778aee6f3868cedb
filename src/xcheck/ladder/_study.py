"""The convergence study: a ladder's error against its time step, the observed
order (one name, computed once) and each series' verdict."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..results import ModeResult, Trajectory
from ._core import ORDER_MARGIN

if TYPE_CHECKING:
    import pandas as pd

#: the columns of a convergence study
STUDY_COLUMNS = ("series", "timestep", "position_error", "status", "order", "verdict")


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


def ladder_result(
    mode: str,
    mechanism: str,
    judged: list[tuple[dict, Trajectory | None]],
    floor: float,
    compared: int | None = None,
    views: list | None = None,
) -> ModeResult:
    """A ladder's ModeResult from its judged runs (row, trajectory where it counts):
    the summary with each row's ``order`` from the study, the study (``floor``:
    its round-off, m), and the counting runs' trajectories.

    Without ``compared`` the most accurate run comes first; ``ok`` where any run
    counts. With ``compared`` (an index of ``judged``) that run comes first, then
    its ``views`` (the same states seen otherwise), then the others in order;
    ``ok`` where it counts.
    """
    import pandas as pd

    summary = pd.DataFrame([row for row, _ in judged])
    study = convergence_study(
        summary["series"], summary["timestep"], summary["position_error"], summary["status"], floor
    )
    order = study.set_index(["series", "timestep"])["order"]
    summary["order"] = [float(order.get((r.series, r.timestep), math.nan)) for r in summary.itertuples()]
    if compared is None:
        counted = sorted((row["position_error"], i) for i, (row, t) in enumerate(judged) if t is not None)
        trajectories = [judged[i][1] for _, i in counted]
        if not trajectories:
            head = judged[0][0]
            reason = f"no run went through ({head['series']} dt = {head['timestep']:.4g} s: {head['status']})"
            failed = {"series": head["series"], "timestep": head["timestep"]}
            return ModeResult(mode, mechanism, False, reason, [], summary, study, failed)
        return ModeResult(mode, mechanism, True, "", trajectories, summary, study)
    row, compared_run = judged[compared]
    others = [t for i, (_, t) in enumerate(judged) if i != compared and t is not None]
    if compared_run is None:
        reason = f"{row['series']} dt = {row['timestep']:.4g} s: {row['status']}"
        failed = {"series": row["series"], "timestep": row["timestep"]}
        return ModeResult(mode, mechanism, False, reason, others, summary, study, failed)
    return ModeResult(mode, mechanism, True, "", [compared_run, *(views or []), *others], summary, study)
