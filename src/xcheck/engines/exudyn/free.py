"""Exudyn in free motion (mode ``exudyn-free``): the system of
:func:`.model.build_system` released at the native reference's initial state
and integrated by Exudyn's implicit generalized-alpha solver at fixed steps;
the ladder and its judgement are :func:`xcheck.ladder.free_study`'s.

The series: Exudyn's defaults (``default``: generalized-alpha, spectral radius
0.9, index-3 constraints, modified Newton to 1e-8 relative), no numerical
damping (``undamped``: spectral radius 1, what a user picks to keep energy),
index-2 (velocity-level) constraints with Newmark's trapezoidal rule
(``index-2``, Exudyn's TrapezoidalIndex2), at its best (``best``: the defaults
with Newton to 1e-10, which closes the loops to round-off) and Newton to 1e-12
(``newton-1e-12``). Exudyn's step reduction after a failed Newton step is off:
it would write the samples off the reference's output times, and the row's
step is then the step. Exudyn's explicit integrators (RK44, DOPRI5) refuse
these joints ("explicit integrator detected object ... which contains
constraints that cannot be solved").

Measured with Exudyn 1.13.6 (``xcheck simulate NAME --engines
native,exudyn-free``, 2 shared cores), largest error over the outputs at dt =
1, 0.5, 0.25 ms (A03: 10, 5, 2.5 us):

- A01 pendulum, 10 s: defaults 1.22e-4, 3.06e-5, 7.68e-6 m (order 2.00), loops
  2e-13 m; index 2 7.2e-5 .. 4.5e-6 m, loops drifting 2.2e-6 .. 1.4e-7 m;
  undamped (rho 1) grows unstable, Newton fails at 5.4 .. 5.6 s.
- A02 double four-bar, 10 s, ten singular passes: defaults and best stay on the
  branch, 1.94e-4, 4.8e-5, 1.2e-5 m (order 2.0), loops 1e-12 (best: 6e-15) m,
  0.04 .. 0.18 s CPU per simulated second; index 2 fails at the 3rd or 4th pass
  (2.66 / 3.17 s); Newton to 1e-12 at the first (0.714 s); undamped gains
  energy (2.4 .. 150 J) and fails at 6.5 .. 7.0 s.
- A03 Andrews' squeezer, 0.03 s: best 6.05e-7, 1.51e-7, 3.79e-8 m (order 2.00),
  6 .. 25 s CPU per simulated second; the defaults' 1.08e-8 m at 2.5 us (orders
  2.3, 3.5) is Newton's 1e-8 tolerance mixing with the truncation error, not a
  higher order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from xcheck.kinematics import rotate
from xcheck.ladder import FreeProblem, Run, Rung, Series, conservative
from xcheck.model import GROUND
from xcheck.results import Trajectory

from .model import Setting, build_system, energy, joint_gaps, matched, refuse, solver_settings

__all__ = ["FREE_SERIES", "prepare_free", "run_free_once"]

MODE = "exudyn-free"
FREE_SERIES = tuple(
    Series(name, setting.integrator, setting)
    for name, setting in (
        ("default", Setting(0.9)),
        ("undamped", Setting(1.0)),
        ("index-2", Setting(0.9, index2=True)),
        ("best", Setting(0.9, newton_tolerance=1e-10)),
        ("newton-1e-12", Setting(0.9, newton_tolerance=1e-12)),
    )
)


def prepare_free(problem: FreeProblem) -> None:
    """Refuse what Exudyn cannot hold (:func:`.model.refuse`) before any run."""
    refuse(problem.kinematics.mechanism)


def run_free_once(_, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`): Exudyn
    integrates to the end in one call, recording every reference output."""
    import exudyn as exu
    import exudyn.itemInterface as ei

    mech = problem.kinematics.mechanism
    setting: Setting = rung.series.options
    dt = rung.timestep
    wanted = problem.times
    duration = float(wanted[-1])
    model = build_system(mech, *problem.start)
    mbs = model.mbs
    sensors = {
        name: tuple(
            mbs.AddSensor(ei.SensorNode(nodeNumber=node, storeInternal=True, outputVariableType=kind))
            for kind in (exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_t)
        )
        for name, node in model.nodes.items()
    }
    mbs.Assemble()
    failure = ""
    config: Any = exu.config
    printing, config.printToConsole = config.printToConsole, False  # its banner on failure: the row says it
    try:
        solve: Any = exu.SolveDynamic  # its stubs lack showHints
        every = problem.output_step
        done = solve(mbs, solver_settings(setting, dt, duration, every), showHints=False, showCausingItems=False)
        if not done:
            failure = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
    except Exception as error:  # noqa: BLE001 - a solver that gives up is a row
        said = f"{error}".splitlines()[0] if f"{error}" else type(error).__name__
        failure = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
        failure += "" if said == "SolveDynamic terminated" else f" ({said})"
    finally:
        config.printToConsole = printing
    stored = {name: (mbs.GetSensorStoredData(a), mbs.GetSensorStoredData(b)) for name, (a, b) in sensors.items()}
    keep = matched(next(iter(stored.values()))[0], wanted, 1e-9 * max(duration, 1.0))
    reached = len(keep)
    # the state at each sample: centre of mass (x, y, phi) and its rates, then the frame origins and points
    coords = {n: model.reference[n][None, :] + stored[n][0][keep, 1:4] for n in model.nodes}
    rates = {n: stored[n][1][keep, 1:4] for n in model.nodes}
    finite = np.ones(reached, dtype=bool)
    for n in model.nodes:
        finite &= np.isfinite(coords[n]).all(axis=1) & np.isfinite(rates[n]).all(axis=1)
    if not finite.all():
        reached = int(np.argmin(finite))
        failure = failure or f"went non-finite at t = {wanted[reached]:.6g} s"
    if not reached:
        return Run(None, failure)
    coords = {n: v[:reached] for n, v in coords.items()}
    rates = {n: v[:reached] for n, v in rates.items()}
    angles = {n: c[:, 2] for n, c in coords.items()}
    bodies, points = {}, {}
    for body in mech.moving_bodies:
        c, w = coords[body.name], rates[body.name]
        arm = np.stack([rotate(phi, model.com[body.name]) for phi in c[:, 2]])
        normal = np.stack([-arm[:, 1], arm[:, 0]], axis=1)
        origin, origin_velocity = c[:, :2] - arm, w[:, :2] - w[:, 2:3] * normal
        bodies[body.name] = {"position": origin, "angle": c[:, 2], "velocity": origin_velocity, "omega": w[:, 2]}
        for label, xy in body.points.items():
            reach = np.stack([rotate(phi, np.asarray(xy, dtype=float)) for phi in c[:, 2]])
            points[(body.name, label)] = origin + reach
        for load in mech.loads:
            if load.body == body.name:
                points[("load", load.name)] = origin + np.stack([rotate(phi, load.point) for phi in c[:, 2]])
    for label, xy in mech.ground.points.items():
        points[(GROUND, label)] = np.broadcast_to(np.asarray(xy, dtype=float), (reached, 2))
    gaps = joint_gaps(mech, points, angles)
    apart = [problem.came_apart(float(t), float(g)) for t, g in zip(wanted, gaps)]
    stop = next((i for i, why in enumerate(apart) if why), None)
    if stop is not None and not failure:
        failure, reached = apart[stop], stop + 1
    keep_to = slice(0, reached)
    named = {
        label: {"position": np.array(points[(owner, label)])[keep_to]} for label, owner in mech.point_owners.items()
    }
    bodies = {name: {k: v[keep_to] for k, v in states.items()} for name, states in bodies.items()}
    diagnostics = {"constraint_violation": gaps[keep_to]}
    if conservative(mech):  # E less the constant loads' potential
        diagnostics["energy"] = energy(mech, model, coords, rates, angles, points)[keep_to]
    empty = np.zeros((reached, 0))
    settings = {
        "setting": rung.series.setting,
        "series": rung.series.key,
        "integrator": rung.series.integrator,
        "timestep": dt,
        "spectral_radius": setting.spectral_radius,
        "index2": setting.index2,
        "newton_tolerance": setting.newton_tolerance,
    }
    notes = f"Exudyn free motion, {rung.series.integrator}, dt = {dt:g} s, from the reference's initial state."
    return Run(
        Trajectory(MODE, empty, empty, empty, bodies, named, wanted[:reached], settings, diagnostics, notes), failure
    )
