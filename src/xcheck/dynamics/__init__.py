"""Inverse dynamics: joint reactions and driving efforts for a prescribed motion.

:func:`inverse_dynamics` (multipliers of M q'' - Phi_q^T lambda = Q) and
:func:`newton_euler` (per-body M a = D R + Q, seed 003) give the native
answers; :func:`energy_balance` checks them against the power balance;
:func:`force_differences` tabulates another set of reactions against them
(the engines' own are run by :mod:`xcheck.reactions`: the exact answer does not
import the engines it judges). The sign conventions are in
:mod:`xcheck.dynamics._forces`.
"""

from ._compare import (
    WINDOW_SAMPLES,
    determined_states,
    energy_summary,
    force_differences,
    force_floors,
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
from ._inverse import (
    AppliedLoad,
    applied_loads,
    body_dynamics,
    directionless_springs,
    inverse_dynamics,
    newton_euler,
)

__all__ = [
    "directionless_springs",
    "AppliedLoad",
    "applied_loads",
    "DRIVER_QUANTITIES",
    "JOINT_QUANTITIES",
    "WINDOW_SAMPLES",
    "Forces",
    "body_dynamics",
    "determined_states",
    "energy_balance",
    "energy_summary",
    "force_differences",
    "force_floors",
    "inverse_dynamics",
    "mechanical_energy",
    "newton_euler",
    "quantity_unit",
    "require_constant_loads",
    "require_mass_data",
    "window_states",
]
