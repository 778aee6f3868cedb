"""States of a mechanism from any source, and their differences from the
native solution, as pandas tables.

Every engine mode returns :class:`Trajectory` objects; :func:`differences`
solves the native general solver at the trajectory's own inputs (value, rate
and acceleration of each driver, as the engine realised them) and tabulates the
largest and RMS difference per body and point quantity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .kinematics import Kinematics, Solution, Status

if TYPE_CHECKING:
    import pandas as pd  # imported where used: 0.3 s that `xcheck solve` and `list` need not pay

__all__ = [
    "BODY_QUANTITIES",
    "POINT_QUANTITIES",
    "Trajectory",
    "ModeResult",
    "differences",
    "native_at",
    "relative_to_floored_scale",
    "sample_errors",
    "scale_floors",
    "trajectory_from_solution",
    "STANDARD_GRAVITY",
]

#: per body: key -> shape suffix; angles are compared modulo 2 pi
BODY_QUANTITIES = {"position": 2, "angle": 0, "velocity": 2, "omega": 0, "acceleration": 2, "alpha": 0}
#: per point
POINT_QUANTITIES = {"position": 2, "velocity": 2, "acceleration": 2}
#: smallest scale of a quantity, as a fraction of the largest of its kind (see differences)
SCALE_FLOOR = 1e-3
#: m/s^2: sets the time scale sqrt(L / g) of a mechanism whose inputs do not move
STANDARD_GRAVITY = 9.80665


def scale_floors(mechanism, input_rates, input_accelerations) -> dict[str, float]:
    """The smallest scale of each quantity, from the mechanism itself.

    With L the mechanism's size (m), each input i has an angular rate w_i =
    its largest |rate| over the samples (revolute) or |rate| / L (sliding), an
    angular acceleration a_i = max(w_i^2, its largest |acceleration|, or
    |acceleration| / L) and a reach r_i: the largest distance from a revolute
    input's joint to a point of the moving bodies it joins (the crank's
    length), L for a sliding one. The characteristic angular rate is w =
    max w_i, the angular acceleration a = max a_i, the velocity max w_i r_i
    and the acceleration max a_i r_i, so that a small crank driving long
    links (1000:1) is judged at its tip's speed, not at w L. When every rate
    is zero, w = sqrt(a_in), or where every acceleration is zero too (a static
    mechanism) w = sqrt(g / L) (g: the mechanism's gravity, else
    :data:`STANDARD_GRAVITY`), the rate of a pendulum of the mechanism's
    size, with reach L.

    Parameters
    ----------
    mechanism : Mechanism
    input_rates, input_accelerations : array_like, shape (N, k)
        The drivers' rates (rad/s or m/s) and accelerations (rad/s^2 or m/s^2).

    Returns
    -------
    dict of str to float
        ``size`` L (m), ``rate`` w (rad/s), ``angular_acceleration`` a
        (rad/s^2), and per quantity of :data:`BODY_QUANTITIES`: position L,
        angle 1 rad, omega w, alpha a, velocity (m/s) and acceleration (m/s^2)
        as above.
    """
    size = mechanism.size
    per = np.array([1.0 if d.quantity == "angle" else 1.0 / size for d in mechanism.drivers])
    reach = np.array([driver_reach(mechanism, d) for d in mechanism.drivers])
    rates = np.abs(np.asarray(input_rates, dtype=float).reshape(-1, len(per))) * per
    accelerations = np.abs(np.asarray(input_accelerations, dtype=float).reshape(-1, len(per))) * per
    w_each = np.nanmax(rates, axis=0, initial=0.0)
    a_each = np.maximum(w_each**2, np.nanmax(accelerations, axis=0, initial=0.0))
    w = float(np.max(w_each, initial=0.0))
    if w == 0.0:  # inputs at rest: accelerating from rest, or static
        a_in = float(np.max(a_each, initial=0.0))
        g = float(np.hypot(*mechanism.gravity)) or STANDARD_GRAVITY
        w = math.sqrt(a_in) if a_in > 0.0 else math.sqrt(g / size)
        a = max(w * w, a_in)
        velocity, acceleration = w * size, a * size
    else:
        a = float(np.max(a_each))
        velocity, acceleration = float(np.max(w_each * reach)), float(np.max(a_each * reach))
    return {
        "size": size,
        "rate": w,
        "angular_acceleration": a,
        "position": size,
        "angle": 1.0,
        "omega": w,
        "alpha": a,
        "velocity": velocity,
        "acceleration": acceleration,
    }


def driver_reach(mechanism, driver) -> float:
    """The length (m) over which a driver's rate becomes a speed.

    A revolute input's reach is the largest distance from its joint to a point
    of the moving bodies it joins (its crank's length); a sliding input's, and
    a revolute one whose bodies have no point off the joint, the mechanism's
    size (a sliding rate is divided by the size in :func:`scale_floors`).
    """
    joint = mechanism.joint(driver.joint)
    if driver.quantity != "angle" or not hasattr(joint, "point_a"):
        return mechanism.size
    reach = 0.0
    for body_name, label in ((joint.body_a, joint.point_a), (joint.body_b, joint.point_b)):
        body = mechanism.body(body_name)
        if body is mechanism.ground:
            continue
        points = np.array(list(body.points.values())) - body.points[label]
        reach = max(reach, float(np.max(np.hypot(points[:, 0], points[:, 1]), initial=0.0)))
    return reach if reach > 0.0 else mechanism.size


@dataclass
class Trajectory:
    """States of a mechanism from one source, SI units, N samples.

    Attributes
    ----------
    source : str
        The mode that produced it, e.g. ``"mujoco-kinematic"``.
    inputs, input_rates, input_accelerations : ndarray, shape (N, k)
        The drivers' values, rates and accelerations as the source realised them.
    bodies : dict of str to dict of str to ndarray
        Per moving body, the keys of :data:`BODY_QUANTITIES`: position (N, 2),
        angle (N,), velocity (N, 2), omega (N,), acceleration (N, 2), alpha (N,).
        A quantity the source cannot give is left out.
    points : dict of str to dict of str to ndarray
        Per named point, the keys of :data:`POINT_QUANTITIES`, each (N, 2).
    times : ndarray, shape (N,), optional
        Simulation time of each sample (dynamic modes).
    settings : dict
        What produced it: integrator, time step, constraint settings, ...; a
        dynamic mode's has ``"timestep"`` (s) and ``"series"`` (str, the same
        for the runs of one convergence ladder).
    diagnostics : dict of str to ndarray
        Per-sample extras, e.g. ``"constraint_violation"`` (N,) in m.
    notes : str
        How accelerations (or anything else) were obtained, for the report.
    """

    source: str
    inputs: np.ndarray
    input_rates: np.ndarray
    input_accelerations: np.ndarray
    bodies: dict
    points: dict
    times: np.ndarray | None = None
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    notes: str = ""


@dataclass
class ModeResult:
    """The outcome of one engine mode on one mechanism.

    ``ok`` is False when the mode could not run or failed (``reason`` says why,
    in one line); ``trajectories`` holds one entry per setting (time step,
    integrator, ...), the first being the one the comparison uses.
    ``summary`` is an optional table of the engine's own (e.g. every run's
    errors and diagnostics); a dynamic mode's ``study`` is its error against
    time step (:func:`xcheck.ladder.convergence_study`), the same for every engine.
    Where a ladder's compared run failed, ``failed_run`` holds its ``series`` and
    ``timestep`` (s), by which an engine's stated findings may explain the failure.
    """

    mode: str
    mechanism: str
    ok: bool
    reason: str = ""
    trajectories: list = field(default_factory=list)
    summary: pd.DataFrame | None = None
    study: pd.DataFrame | None = None
    failed_run: dict = field(default_factory=dict)


def trajectory_from_solution(solution: Solution, source: str = "native") -> Trajectory:
    """The native solution as a :class:`Trajectory` (for uniform handling)."""
    mech = solution.mechanism
    return Trajectory(
        source=source,
        inputs=solution.inputs,
        input_rates=solution.input_rates,
        input_accelerations=solution.input_accelerations,
        bodies={b.name: solution.body(b.name) for b in mech.moving_bodies},
        points={label: solution.point(label) for label in mech.point_owners},
        diagnostics={"residual": solution.residual},
    )


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def native_at(kinematics: Kinematics, trajectory: Trajectory, branch: str | None = None) -> Solution:
    """The native solution at a trajectory's own inputs, rates and accelerations."""
    return kinematics.solve(trajectory.inputs, trajectory.input_rates, trajectory.input_accelerations, branch=branch)


def _errors(trajectory: Trajectory, native: Solution):
    """(kind, name, quantity, error (N,), native magnitude (N,)) for every quantity the trajectory has."""
    sources = [
        ("body", name, q, native.body(name))
        for name in trajectory.bodies
        for q in BODY_QUANTITIES
        if q in trajectory.bodies[name]
    ]
    sources += [
        ("point", label, q, native.point(label))
        for label in trajectory.points
        for q in POINT_QUANTITIES
        if q in trajectory.points[label]
    ]
    for kind, name, quantity, reference in sources:
        values = (trajectory.bodies if kind == "body" else trajectory.points)[name][quantity]
        exact = reference[quantity]
        delta = values - exact
        if quantity == "angle":
            delta = _wrap(delta)
        error = np.abs(delta) if delta.ndim == 1 else np.linalg.norm(delta, axis=1)
        magnitude = np.abs(exact) if exact.ndim == 1 else np.linalg.norm(exact, axis=1)
        yield kind, name, quantity, error, magnitude


def sample_errors(trajectory: Trajectory, native: Solution) -> dict[str, np.ndarray]:
    """Per quantity, the largest error over all bodies and points at each sample.

    Returns
    -------
    dict of str to ndarray, shape (N,)
        SI units; NaN where the native solver did not succeed.
    """
    good = native.status <= 1
    worst: dict[str, np.ndarray] = {}
    for _, _, quantity, error, _ in _errors(trajectory, native):
        worst[quantity] = np.fmax(worst.get(quantity, np.full(error.shape, -np.inf)), error)
    return {q: np.where(good, e, np.nan) for q, e in worst.items()}


def differences(
    kinematics: Kinematics,
    trajectory: Trajectory,
    branch: str | None = None,
    native: Solution | None = None,
    floors: dict[str, float] | None = None,
) -> pd.DataFrame:
    """Differences between a trajectory and the native solution at its inputs.

    Returns
    -------
    DataFrame
        One row per (kind, name, quantity) the trajectory has: ``kind`` is
        "body" or "point"; columns ``max_abs`` and ``rms`` (SI units of the
        quantity; vectors by Euclidean norm), ``scale`` (largest magnitude of
        the native quantity over the samples, but at least
        :data:`SCALE_FLOOR` of the largest among all bodies' and points' of the
        same quantity, so that a quantity that is zero, such as the velocity
        of a frame on a ground pivot, is not divided by round-off, and at
        least the quantity's physical floor ``floors`` (default
        :func:`scale_floors` of the trajectory's inputs), so that a quantity
        that is zero everywhere, such as the angular acceleration of a bar
        turning uniformly, is not either), ``floor`` (that physical floor),
        ``max_rel`` (max_abs / scale),
        ``worst_sample`` (index) and ``worst_input`` (the first driver's value
        there, SI). Samples where the native solver did not succeed are left
        out (``samples`` counts the others); ``missing`` counts those of them
        where the trajectory has no finite value (:func:`missing_samples`). Pass
        ``native`` (from :func:`native_at`) when it is already solved.
    """
    import pandas as pd

    if native is None:
        native = native_at(kinematics, trajectory, branch)
    if floors is None:
        floors = scale_floors(kinematics.mechanism, trajectory.input_rates, trajectory.input_accelerations)
    good = native.status <= 1
    rows = []
    for kind, name, quantity, error, magnitude in _errors(trajectory, native):
        determined = good & np.isfinite(error)
        if not determined.any():
            continue
        where = np.flatnonzero(determined)
        worst = where[int(np.argmax(error[where]))]
        rows.append(
            {
                "kind": kind,
                "name": name,
                "quantity": quantity,
                "max_abs": float(error[worst]),
                "rms": float(np.sqrt(np.mean(error[where] ** 2))),
                "scale": float(np.max(magnitude[where])),
                "worst_sample": int(worst),
                "worst_input": float(trajectory.inputs[worst, 0]),
                "samples": int(good.sum()),
                "missing": missing_samples(native.status, determined),
            }
        )
    return relative_to_floored_scale(pd.DataFrame(rows), "quantity", floors)


def missing_samples(status: np.ndarray, finite: np.ndarray) -> int:
    """How many samples a source leaves without a value where the native solution
    has one: native ``status`` OK (N,) and ``finite`` (N,) false. A sample the
    native solver finds near-singular is not counted: its rates there carry few
    or no digits (a change point's carry none), and a source that finds the state
    singular says the same."""
    return int(np.count_nonzero((status == Status.OK) & ~finite))


def undetermined_text(missing: int) -> str:
    """The words for ``missing`` samples (:func:`missing_samples`)."""
    return f"no value at {missing} sample{'s' if missing != 1 else ''} where the native solution has one"


def relative_to_floored_scale(
    table: pd.DataFrame, kind_column: str, floors: dict[str, float] | None = None
) -> pd.DataFrame:
    """Floor each row's ``scale`` at :data:`SCALE_FLOOR` of the largest scale of
    its kind (rows with equal ``kind_column``) and at the physical floor
    ``floors[kind]`` (SI, 0 where not given; stated in a ``floor`` column),
    and add ``max_rel`` = max_abs / scale after ``scale``; the table is
    changed in place and returned."""
    if not table.empty:
        largest = table.groupby(kind_column)["scale"].transform("max")
        floor = table[kind_column].map(lambda kind: (floors or {}).get(kind, 0.0)).astype(float)
        table["scale"] = np.maximum(np.maximum(table["scale"], SCALE_FLOOR * largest), floor)
        table.insert(list(table.columns).index("scale") + 1, "floor", floor)
        with np.errstate(divide="ignore", invalid="ignore"):
            table.insert(
                list(table.columns).index("floor") + 1,
                "max_rel",
                np.where(table["scale"] > 0, table["max_abs"] / table["scale"], table["max_abs"]),
            )
    return table
