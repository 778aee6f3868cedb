"""What the driven-dynamics modes of engines without an oracle of their own
(Exudyn, PyBullet) share: their runs of a step ladder judged against the native
solution at the inputs each engine realised, as one :class:`~xcheck.compare.ModeResult`."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from xcheck.compare import ModeResult, Trajectory, convergence_study, differences
from xcheck.kinematics import Kinematics

__all__ = ["driven_result"]


def driven_result(
    mode: str,
    kinematics: Kinematics,
    runs: list[tuple[dict, Trajectory | None]],
    errors: dict[str, str],
    branch: str | None = None,
) -> ModeResult:
    """The mode's result from its runs, the compared one first.

    Parameters
    ----------
    runs : list of (dict, Trajectory or None)
        Per run its summary row (setting, timestep s, status, cpu_seconds, ...) and
        its trajectory (None where the run failed).
    errors : dict of str to str
        The compared quantities, each ``"abs"`` (m or rad) or ``"rel"`` (relative
        to the native magnitude): the row gains ``QUANTITY_error``, the largest over
        bodies and points; ``input_error`` (SI) and ``loop_gap`` (m) come from the
        trajectory's diagnostics ``input_error`` and ``constraint_violation``.

    Returns
    -------
    ModeResult
        ``ok`` where the first run went through; ``study``: the position error's
        :func:`~xcheck.compare.convergence_study` (errors at 1e-13 of the size
        have no order: the drivers fix the positions exactly there).
    """
    mech = kinematics.mechanism
    rows = []
    for row, trajectory in runs:
        if trajectory is not None:
            table = differences(kinematics, trajectory, branch)
            for quantity, kind in errors.items():
                part = table[table["quantity"] == quantity]
                if part.empty:
                    continue
                worst = float(part["max_abs"].max())
                scale = float(part["scale"].max())
                row[f"{quantity}_error"] = worst / scale if kind == "rel" and scale > 0.0 else worst
            diagnostics = trajectory.diagnostics
            row["input_error"] = float(np.max(np.abs(diagnostics["input_error"])))
            if "constraint_violation" in diagnostics:
                row["loop_gap"] = float(np.max(diagnostics["constraint_violation"]))
        rows.append(row)
    summary = pd.DataFrame(rows)
    position = summary["position_error"] if "position_error" in summary else [math.nan] * len(summary)
    floor = 1e-13 * mech.size
    study = convergence_study(summary["setting"], summary["timestep"], position, summary["status"], floor)
    trajectories = [t for _, t in runs if t is not None]
    if runs[0][1] is None:
        return ModeResult(mode, mech.name, False, f"{mode}: {runs[0][0]['status']}", trajectories, summary, study)
    return ModeResult(mode, mech.name, True, "", trajectories, summary, study)
