"""Where reactions and efforts are compared, and how: the native states of the
simulation window, the differences of a set of reactions and efforts from the
native ones, and the native power balance. The engines' own reactions are run
and judged in :mod:`xcheck.reactions`; this package, the exact answer, does not
import what it judges.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..kinematics import Kinematics, Solution, Status
from ..motion import law_states, simulation_window
from ..results import missing_samples, relative_to_floored_scale, scale_floors
from ._energy import energy_balance, mechanical_energy
from ._forces import DRIVER_QUANTITIES, JOINT_QUANTITIES, Forces, quantity_unit, require_mass_data
from ._inverse import directionless_springs, inverse_dynamics

if TYPE_CHECKING:
    import pandas as pd  # imported where used: 0.3 s that `xcheck solve` and `list` need not pay

__all__ = [
    "WINDOW_SAMPLES",
    "window_states",
    "determined_states",
    "force_differences",
    "force_floors",
    "energy_summary",
]


#: States sampled over the simulation window by default (every 5 degrees of a turning crank).
WINDOW_SAMPLES = 73


def window_states(kinematics: Kinematics, branch: str | None = None, samples: int = WINDOW_SAMPLES) -> Solution:
    """The native solution at ``samples`` equally spaced times over the drivers'
    simulation window (:func:`~xcheck.motion.simulation_window`): the states at
    which reactions and efforts are compared.

    Raises
    ------
    InputError
        If the motion starts outside the feasible range.
    """
    window = simulation_window(kinematics, branch)
    return kinematics.solve(*window.inputs(kinematics, window.times(samples)), branch=branch)


def determined_states(
    kinematics: Kinematics, branch: str | None = None, samples: int | None = None, solution: Solution | None = None
) -> Solution:
    """``solution``, or :func:`window_states` with ``samples`` states, checked
    to be determined everywhere: the states an engine's inverse dynamics runs at.

    Raises
    ------
    ValueError
        If a state did not assemble or is singular (the first one, in one line).
    """
    if solution is None:
        solution = window_states(kinematics, branch, **({} if samples is None else {"samples": samples}))
    if not solution.success:
        i = int(np.argmax(solution.status > Status.NEAR_SINGULAR))
        raise ValueError(
            f"the native states are not all determined ({Status(int(solution.status[i])).message} at sample {i})"
        )
    return solution


def _magnitude(values: np.ndarray) -> np.ndarray:
    return np.abs(values) if values.ndim == 1 else np.linalg.norm(values, axis=1)


def force_floors(mechanism, floors: dict[str, float]) -> dict[str, float]:
    """The smallest scale of forces and moments, from the mechanism itself.

    With M the total mass of the moving bodies (kg), L the size, a the
    characteristic angular acceleration (``floors``, from
    :func:`~xcheck.results.scale_floors`) and g the gravity: a force's scale
    is at least F = max(M |g|, M a L, the largest applied load force) (N), a
    moment's at least max(F L, the largest applied torque) (N m).

    Returns
    -------
    dict
        ``{"N": F, "N m": F L or more}``, keyed by the unit column of
        :func:`force_differences`.
    """
    mass = sum(b.mass or 0.0 for b in mechanism.moving_bodies)
    size = floors["size"]
    loads = [float(np.hypot(*load.force)) for load in mechanism.loads]
    torques = [abs(load.torque) for load in mechanism.loads]
    force = max([mass * float(np.hypot(*mechanism.gravity)), mass * floors["acceleration"], *loads])
    return {"N": force, "N m": max([force * size, *torques])}


def force_differences(kinematics: Kinematics, forces: Forces, branch: str | None = None) -> pd.DataFrame:
    """Differences between a source's reactions and efforts and the native ones
    at the source's own states.

    The native kinematics are solved at ``forces``' inputs, rates and
    accelerations and the native multiplier form
    (:func:`~xcheck.dynamics.inverse_dynamics`) gives the reference.

    Returns
    -------
    DataFrame
        One row per (kind, name, quantity) the source gives: ``kind`` "joint"
        or "driver"; ``quantity`` as in :class:`Forces` (``"|reaction|"``
        etc. compare magnitudes); ``unit`` "N" or "N m"; ``max_abs``, ``rms``
        (vectors by Euclidean norm of the difference); ``scale``: the largest
        native magnitude over the states, but at least
        :data:`~xcheck.results.SCALE_FLOOR` of the largest scale of the same
        unit in the table (a joint that carries almost nothing is not divided
        by round-off) and at least ``floor``, :func:`force_floors` of the
        source's inputs (a mechanism that carries almost nothing is not
        either); ``max_rel`` = max_abs / scale; ``worst_sample``,
        ``worst_input`` (first driver's value there, SI); ``samples`` (states
        where the native solution succeeded) and ``missing`` (of those, states
        where the source gave no finite value, :func:`~xcheck.results.missing_samples`:
        left out of the figures).
    """
    import pandas as pd

    native = kinematics.solve(forces.inputs, forces.input_rates, forces.input_accelerations, branch=branch)
    reference = inverse_dynamics(native)
    good = native.status <= Status.NEAR_SINGULAR
    mech = kinematics.mechanism
    rows = []
    for kind, source, exact_all, known in (
        ("joint", forces.joints, reference.joints, JOINT_QUANTITIES),
        ("driver", forces.drivers, reference.drivers, DRIVER_QUANTITIES),
    ):
        for name, quantities in source.items():
            for quantity, values in quantities.items():
                base = quantity.strip("|")
                if base not in known or base not in exact_all[name]:
                    raise ValueError(
                        f"expected quantities of {kind} {name!r} among {', '.join(exact_all[name])}, found {quantity!r}"
                    )
                exact = exact_all[name][base]
                values = np.asarray(values, dtype=float)
                if quantity != base:
                    exact = _magnitude(exact)
                delta = values - exact
                error = _magnitude(delta)
                finite = np.isfinite(error) & good
                if not finite.any():
                    continue
                exact_size = _magnitude(exact)
                determined = np.isfinite(exact_size)
                magnitude = exact_size[good & determined]
                worst = int(np.flatnonzero(finite)[np.argmax(error[finite])])
                rows.append(
                    {
                        "kind": kind,
                        "name": name,
                        "quantity": quantity,
                        "unit": quantity_unit(mech, kind, name, base),
                        "max_abs": float(error[worst]),
                        "rms": float(np.sqrt(np.mean(error[finite] ** 2))),
                        "scale": float(np.max(magnitude)),
                        "worst_sample": worst,
                        "worst_input": float(forces.inputs[worst, 0]),
                        "samples": int(good.sum()),
                        # a state whose native force is not determined either is no state the source left out
                        "missing": missing_samples(native.status, finite | ~determined),
                    }
                )
    # the floors follow the drivers' laws at the source's inputs: an engine's realised rates of a driver
    # that stands still are round-off, not zero, and would drop the static fallback of scale_floors
    law_rates, law_accelerations, _ = law_states(mech, forces.inputs)
    floors = force_floors(mech, scale_floors(mech, law_rates, law_accelerations))
    return relative_to_floored_scale(pd.DataFrame(rows), "unit", floors)


def energy_summary(kinematics: Kinematics, branch: str | None = None, samples: int = 721) -> dict:
    """The power balance of the native solution over the simulation window.

    Returns
    -------
    dict
        ``residual`` (W): the largest |drive + loads - dT/dt - dV/dt| over the
        states; ``scale`` (W): the largest of |drive|, |loads|, |dT/dt|,
        |dV/dt| and the largest kinetic energy times the characteristic rate
        (:func:`~xcheck.results.scale_floors`; a train turning at constant
        speed exchanges no power, and its balance is judged against the power
        its motion holds, not against round-off); ``relative`` = residual / scale; ``work_error`` (J): the
        largest difference over the window between the work the drivers and
        loads did since t = 0 (trapezoidal rule) and the change of T + V since
        t = 0 (quadrature error, falling as samples^-2), with ``energy_swing``
        (J), the largest |T + V - (T + V)(0)|; ``samples``.

    Raises
    ------
    ModelError
        If a moving body has no mass data.
    ValueError
        If a state of the window did not assemble or is singular (the first
        one, in one line: :func:`determined_states`), or a spring's pull has no
        direction there (:func:`~xcheck.dynamics.directionless_springs`).
    """
    require_mass_data(kinematics.mechanism)
    window = simulation_window(kinematics, branch)
    times = window.times(samples)
    solved = kinematics.solve(*window.inputs(kinematics, times), branch=branch)
    solution = determined_states(kinematics, branch, solution=solved)
    for name, where in directionless_springs(solution).items():
        if where.any():
            raise ValueError(
                f"spring {name!r} has its two ends at one point at t = {times[int(np.argmax(where))]:.6g} s: "
                "its pull has no direction there"
            )
    balance = energy_balance(solution, inverse_dynamics(solution))
    kinetic, potential = mechanical_energy(solution)
    rate = scale_floors(kinematics.mechanism, solved.input_rates, solved.input_accelerations)["rate"]
    measured = float(balance[["drive", "loads", "kinetic_rate", "potential_rate"]].abs().to_numpy().max())
    scale = max(measured, float(np.max(kinetic, initial=0.0)) * rate)
    residual = float(balance["residual"].abs().max())
    power = (balance["drive"] + balance["loads"]).to_numpy()
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(times))])
    change = kinetic + potential - kinetic[0] - potential[0]
    return {
        "residual": residual,
        "scale": scale,
        "relative": residual / scale if scale > 0 else residual,
        "work_error": float(np.max(np.abs(work - change))),
        "energy_swing": float(np.max(np.abs(change))),
        "samples": samples,
    }
