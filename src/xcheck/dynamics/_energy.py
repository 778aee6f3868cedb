"""The power balance of a prescribed motion: what the drivers put in goes into
kinetic and potential energy, less what the applied loads put in.

    sum_k effort_k c'_k + P_loads = dT/dt + dV/dt

with T = sum (m |v_G|^2 + I_G omega^2) / 2, V = -sum m g . r_G and P_loads
= sum F . v_P + torque omega over the applied loads and the springs' and
dampers' pulls (:func:`~xcheck.dynamics._inverse.applied_loads`). Ideal joints do no work, so the balance holds
exactly for the exact reactions and efforts: its residual measures how well
the efforts were computed (and, integrated over time, how consistent the
kinematic solution's velocities and accelerations are).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..kinematics import Solution
from ._forces import Forces
from ._inverse import _perp, _rot, applied_loads, body_dynamics

if TYPE_CHECKING:
    import pandas as pd  # imported where used: 0.3 s that `xcheck solve` and `list` need not pay

__all__ = ["energy_balance", "mechanical_energy"]


def mechanical_energy(solution: Solution) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy of the moving bodies, each (N,) J.

    The potential energy is that of gravity, zero at the global origin.
    """
    mech = solution.mechanism
    kinetic = np.zeros(solution.q.shape[0])
    potential = np.zeros(solution.q.shape[0])
    for b in body_dynamics(solution).values():
        kinetic += 0.5 * (b["mass"] * np.sum(b["velocity"] ** 2, axis=1) + b["inertia"] * b["omega"] ** 2)
        potential -= b["mass"] * (b["com"] @ mech.gravity)
    return kinetic, potential


def energy_balance(solution: Solution, forces: Forces) -> pd.DataFrame:
    """The power balance per state.

    Parameters
    ----------
    solution : Solution
        The motion (N states).
    forces : Forces
        Efforts at the same states (e.g. :func:`inverse_dynamics` of ``solution``).

    Returns
    -------
    DataFrame
        One row per state: ``drive`` (sum of effort x input rate), ``loads``
        (power of the applied forces and torques), ``kinetic_rate`` (dT/dt),
        ``potential_rate`` (dV/dt), all W, and ``residual`` = drive + loads -
        kinetic_rate - potential_rate, W.
    """
    import pandas as pd

    mech = solution.mechanism
    n = solution.q.shape[0]
    drive = np.zeros(n)
    for k, driver in enumerate(mech.drivers):
        drive += forces.drivers[driver.name]["effort"] * solution.input_rates[:, k]
    loads = np.zeros(n)
    kinetic_rate = np.zeros(n)
    potential_rate = np.zeros(n)
    for b in body_dynamics(solution).values():
        kinetic_rate += (
            b["mass"] * np.sum(b["velocity"] * b["acceleration"], axis=1) + b["inertia"] * b["omega"] * b["alpha"]
        )
        potential_rate -= b["mass"] * (b["velocity"] @ mech.gravity)
    for load in applied_loads(solution):
        state = solution.body(load.body)
        arm = _rot(state["angle"], load.point)
        v = state["velocity"] + state["omega"][:, None] * _perp(arm)
        loads += np.einsum("ij,ij->i", v, load.force) + load.torque * state["omega"]
    return pd.DataFrame(
        {
            "drive": drive,
            "loads": loads,
            "kinetic_rate": kinetic_rate,
            "potential_rate": potential_rate,
            "residual": drive + loads - kinetic_rate - potential_rate,
        }
    )
