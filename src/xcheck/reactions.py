"""The engines' reactions and driving efforts against the native ones.

Each engine of the registry with a ``force_tolerance`` provides
:meth:`~xcheck.engines.Engine.inverse_dynamics` (kinematics, branch=None,
**options) -> Forces; :func:`engine_forces` runs one at the native states of
the simulation window (:func:`xcheck.dynamics.window_states`) and tabulates
:func:`xcheck.dynamics.force_differences`, never raising: a failure is a
:class:`ForceResult` with ``ok`` False and a one-line ``reason``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import engines
from .dynamics import Forces, force_differences, newton_euler, require_mass_data, window_states
from .errors import NotApplicable
from .kinematics import Kinematics
from .ladder import one_line

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["ForceResult", "compare_forces", "engine_forces", "force_engines", "force_summary"]


def force_engines() -> tuple[str, ...]:
    """The registered engines that give reactions and efforts."""
    return tuple(e.name for e in engines.engines() if e.force_tolerance is not None)


@dataclass
class ForceResult:
    """One source's reactions and efforts on one mechanism.

    Attributes
    ----------
    engine : str
        One of :func:`force_engines`, or ``"newton-euler"`` (the native per-body form).
    mechanism : str
    ok : bool
    reason : str
        Why it failed, one line (empty when ok).
    forces : Forces or None
    table : DataFrame or None
        :func:`force_differences` of ``forces``.
    seconds : float
        Run time.
    applies : bool
        False where the engine cannot hold the mechanism (``reason`` says
        why): not a failure.
    """

    engine: str
    mechanism: str
    ok: bool
    reason: str = ""
    forces: Forces | None = None
    table: pd.DataFrame | None = None
    seconds: float = 0.0
    applies: bool = True


def engine_forces(kinematics: Kinematics, engine: str, branch: str | None = None, **options) -> ForceResult:
    """Run one engine's inverse dynamics and compare it with the native one.

    Parameters
    ----------
    kinematics : Kinematics
    engine : str
        One of :func:`force_engines`, or ``"newton-euler"``.
    branch : str, optional
    **options
        Passed to the engine's function.

    Returns
    -------
    ForceResult
        Never raises: a mechanism without mass data, an engine that cannot
        load it, or any failure gives ``ok`` False and the reason in one line.
    """
    mech = kinematics.mechanism
    start = time.perf_counter()
    try:
        require_mass_data(mech)
        if engine == "newton-euler":
            forces = newton_euler(window_states(kinematics, branch, **options))
        elif engine in force_engines():
            forces = engines.engine(engine).inverse_dynamics(kinematics, branch=branch, **options)
        else:
            raise ValueError(f"expected an engine ({', '.join(['newton-euler', *force_engines()])}), found {engine!r}")
        table = force_differences(kinematics, forces, branch)
    except NotApplicable as error:
        return ForceResult(
            engine, mech.name, False, one_line(error), seconds=time.perf_counter() - start, applies=False
        )
    except Exception as error:  # noqa: BLE001 - a failed engine is data: reported, the others still run
        return ForceResult(engine, mech.name, False, one_line(error), seconds=time.perf_counter() - start)
    return ForceResult(engine, mech.name, True, "", forces, table, time.perf_counter() - start)


def compare_forces(
    kinematics: Kinematics, engines=None, branch: str | None = None, options: dict | None = None
) -> list[ForceResult]:
    """:func:`engine_forces` for each engine (default: newton-euler and every
    :func:`force_engines`; ``options``: engine -> keyword arguments)."""
    engines = ("newton-euler", *force_engines()) if engines is None else engines
    options = options or {}
    return [engine_forces(kinematics, engine, branch, **options.get(engine, {})) for engine in engines]


def force_summary(results: list[ForceResult], round_off: Mapping[str, float] | None = None) -> pd.DataFrame:
    """One row per result of :func:`compare_forces`: ``engine``, ``ok``,
    ``reason``, the worst ``max_rel`` with its ``name`` and ``quantity`` (NaN
    and empty for a failed engine), ``max_abs`` there (SI, ``unit``), the
    physical ``floor`` of that unit's scale (:func:`force_floors`),
    ``states``, ``seconds`` and ``applies``. Where every quantity of a source
    lies below its ``round_off`` (engine -> relative bound), which is worst is
    noise: the row is then its largest quantity (the largest ``scale``), so that
    it reads the same on any machine."""
    import pandas as pd

    rows = []
    for r in results:
        row = {
            "engine": r.engine,
            "ok": r.ok,
            "reason": r.reason,
            "max_rel": np.nan,
            "name": "",
            "quantity": "",
            "max_abs": np.nan,
            "unit": "",
            "floor": np.nan,
            "states": 0,
            "seconds": r.seconds,
            "applies": r.applies,
        }
        if r.ok and r.table is not None and not r.table.empty:
            relative = r.table["max_rel"].to_numpy()
            at = int(np.nanargmax(relative))
            if round_off is not None and relative[at] < round_off.get(r.engine, 0.0):
                at = int(np.argmax(r.table["scale"].to_numpy()))
            worst = r.table.iloc[at]
            row.update(
                max_rel=float(worst["max_rel"]),
                name=worst["name"],
                quantity=worst["quantity"],
                max_abs=float(worst["max_abs"]),
                unit=worst["unit"],
                floor=float(worst["floor"]),
                states=int(worst["samples"]),
            )
        rows.append(row)
    return pd.DataFrame(rows)
