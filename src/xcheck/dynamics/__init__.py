"""Inverse dynamics: joint reactions and driving efforts for a prescribed motion.

:func:`inverse_dynamics` (multipliers of M q'' - Phi_q^T lambda = Q) and
:func:`newton_euler` (per-body M a = D R + Q, seed 003) give the native
answers; :func:`energy_balance` checks them against the power balance;
:func:`engine_forces` / :func:`compare_forces` run the engines' own inverse
dynamics and tabulate :func:`force_differences`. The sign conventions are in
:mod:`xcheck.dynamics._forces`.
"""

from ._compare import (
    WINDOW_SAMPLES,
    ForceResult,
    compare_forces,
    determined_states,
    energy_summary,
    engine_forces,
    force_differences,
    force_engines,
    force_floors,
    force_summary,
    window_states,
)
from ._energy import energy_balance, mechanical_energy
from ._forces import (
    DRIVER_QUANTITIES,
    JOINT_QUANTITIES,
    Forces,
    quantity_unit,
    require_constant_loads,
    require_mass_data,
)
from ._inverse import AppliedLoad, applied_loads, body_dynamics, inverse_dynamics, newton_euler

__all__ = [
    "AppliedLoad",
    "applied_loads",
    "DRIVER_QUANTITIES",
    "force_engines",
    "JOINT_QUANTITIES",
    "WINDOW_SAMPLES",
    "ForceResult",
    "Forces",
    "body_dynamics",
    "compare_forces",
    "determined_states",
    "energy_balance",
    "energy_summary",
    "engine_forces",
    "force_differences",
    "force_floors",
    "force_summary",
    "inverse_dynamics",
    "mechanical_energy",
    "newton_euler",
    "quantity_unit",
    "require_constant_loads",
    "require_mass_data",
    "window_states",
]
