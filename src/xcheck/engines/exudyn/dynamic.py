"""Exudyn in driven dynamics (mode ``exudyn-dynamic``): the mechanism of
:func:`.free.build_system` with each driver an ``ObjectConnectorCoordinate``
on the two bodies' angle coordinates (phi_b - phi_a = the motion law, through
Exudyn's offset user function), integrated by generalized-alpha over
:func:`xcheck.motion.simulation_window` from the native state at t = 0, and
compared with the native solution at the inputs Exudyn realised.

The drivers prescribe the motion (the mechanism has as many degrees of freedom
as drivers), so masses only weigh the Newton iterations: a body without mass
data gets 1 kg and m size^2 / 12 about its frame origin. Positions come from
Exudyn's index-3 constraints (exact to Newton's tolerance), velocities and
accelerations from the integrator (the accelerations carry the coordinates'
round-off over the step squared: the engine's stated finding). A slide driver (the slide of a prismatic
joint or pin-in-slot, nonlinear in the node coordinates) has no coordinate
constraint here: :class:`~xcheck.engines.NotApplicable`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.kinematics import rotate
from xcheck.ladder import DrivenProblem, Run, Rung, Series
from xcheck.model import GROUND, Mechanism
from xcheck.results import Trajectory, scale_floors

from .model import Setting, build_system, joint_gaps, matched, newton_floor, solver_settings

__all__ = ["MODE", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]

MODE = "exudyn-dynamic"


def _perp(v: np.ndarray) -> np.ndarray:
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: Newton to 1e-10 (positions exact to it) at 25, 50 and 100 steps per
    sample, compared; Exudyn's defaults at the finest."""
    interval = problem.interval
    return tuple(
        Series(name, setting.integrator, setting, timestep=interval / per, rungs=rungs)
        for name, setting, per, rungs in (
            ("best", Setting(0.9, newton_tolerance=1e-10), 25, 3),
            ("default", Setting(0.9), 100, 1),
        )
    )


def prepare_dynamic(problem: DrivenProblem) -> Mechanism:
    """The mechanism with unit masses where it has none.

    Raises
    ------
    NotApplicable
        A slide driver, or a driver on a joint that is not a revolute.
    """
    mech = problem.kinematics.mechanism
    for driver in mech.drivers:
        if driver.quantity != "angle":  # a revolute's
            raise NotApplicable(
                f"driver {driver.name}: a slide has no coordinate constraint in Exudyn (only joint angles are driven)"
            )
    return with_unit_mass(mech)


def run_dynamic_once(mech: Mechanism, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`)."""
    import exudyn as exu
    import exudyn.itemInterface as ei

    window, series = problem.window, rung.series
    duration, dt, per = window.duration, rung.timestep, rung.counts[0]
    setting: Setting = series.options
    failure = ""
    floors = scale_floors(mech, *problem.window.inputs(problem.kinematics, problem.times)[1:])
    model = build_system(mech, problem.start.q[0], problem.start.qd[0])
    mbs = model.mbs
    ground = mbs.AddNode(ei.NodePointGround(visualization=ei.VNodePointGround(show=False)))
    fixed = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    pairs = []
    for driver in mech.drivers:
        joint = mech.joint(driver.joint)
        a, b = joint.body_a, joint.body_b
        markers = [
            fixed
            if body == GROUND
            else mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=model.nodes[body], coordinate=2))
            for body in (a, b)
        ]
        start = (model.reference[b][2] if b != GROUND else 0.0) - (model.reference[a][2] if a != GROUND else 0.0)
        law = driver.law

        def offset(mbs, t, item, value, law=law, start=start):
            return float(law.at_time(t)[0]) - start

        def offset_t(mbs, t, item, value, law=law):
            return float(law.at_time(t)[1])

        mbs.AddObject(
            ei.ObjectConnectorCoordinate(
                markerNumbers=markers,
                offsetUserFunction=offset,
                offsetUserFunction_t=offset_t,
                visualization=ei.VObjectConnectorCoordinate(show=False),
            )
        )
        pairs.append((a, b))
    kinds = (
        exu.OutputVariableType.Coordinates,
        exu.OutputVariableType.Coordinates_t,
        exu.OutputVariableType.Coordinates_tt,
    )
    sensors = {
        name: [mbs.AddSensor(ei.SensorNode(nodeNumber=node, storeInternal=True, outputVariableType=k)) for k in kinds]
        for name, node in model.nodes.items()
    }
    mbs.Assemble()
    config: Any = exu.config
    printing, config.printToConsole = config.printToConsole, False
    try:
        solve: Any = exu.SolveDynamic  # its stubs lack showHints
        every = problem.interval
        settings = solver_settings(setting, dt, duration, every, newton_floor(mech, floors))
        if not solve(mbs, settings, showHints=False, showCausingItems=False):
            failure = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
    except Exception:  # noqa: BLE001 - a solver that gives up is a row
        failure = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
    finally:
        config.printToConsole = printing
    data = {name: [mbs.GetSensorStoredData(s) for s in found] for name, found in sensors.items()}
    rows = matched(next(iter(data.values()))[0], problem.times, 1e-9 * max(duration, 1.0))
    state = {name: [d[rows, 1:4] for d in found] for name, found in data.items()}
    for name in state:
        state[name][0] = state[name][0] + model.reference[name][None, :]
    finite = np.ones(len(rows), dtype=bool)
    for found in state.values():
        for x in found:
            finite &= np.isfinite(x).all(axis=1)
    if not finite.all():
        failure = failure or f"went non-finite at t = {problem.times[int(np.argmin(finite))]:.6g} s"
        state = {name: [x[: int(np.argmin(finite))] for x in found] for name, found in state.items()}
    times = problem.times[: len(next(iter(state.values()))[0])]
    if not len(times):
        return Run(None, failure or "no sample reached")
    bodies, points = {}, {}
    for body in mech.moving_bodies:
        (c, v, a) = state[body.name]
        phi, w, alpha = c[:, 2], v[:, 2], a[:, 2]
        arm = np.stack([rotate(p, model.com[body.name]) for p in phi])
        origin = c[:, :2] - arm
        velocity = v[:, :2] - w[:, None] * _perp(arm)
        acceleration = a[:, :2] - alpha[:, None] * _perp(arm) + (w * w)[:, None] * arm
        bodies[body.name] = {
            "position": origin,
            "angle": phi,
            "velocity": velocity,
            "omega": w,
            "acceleration": acceleration,
            "alpha": alpha,
        }
        for label, xy in body.points.items():
            reach = np.stack([rotate(p, np.asarray(xy, dtype=float)) for p in phi])
            points[(body.name, label)] = {
                "position": origin + reach,
                "velocity": velocity + w[:, None] * _perp(reach),
                "acceleration": acceleration + alpha[:, None] * _perp(reach) - (w * w)[:, None] * reach,
            }
    named = {label: points[(owner, label)] for label, owner in mech.point_owners.items() if owner != GROUND}
    gaps = joint_gaps(
        mech,
        {key: value["position"] for key, value in points.items()},
        {name: states["angle"] for name, states in bodies.items()},
    )

    def relative(a: str, b: str, k: int, key: str) -> np.ndarray:
        value = bodies[b][key] if b != GROUND else np.zeros(len(times))
        return value - (bodies[a][key] if a != GROUND else 0.0)

    inputs = np.stack([relative(a, b, 0, "angle") for a, b in pairs], axis=1)
    rates = np.stack([relative(a, b, 0, "omega") for a, b in pairs], axis=1)
    accelerations = np.stack([relative(a, b, 0, "alpha") for a, b in pairs], axis=1)
    trajectory = Trajectory(
        MODE,
        inputs,
        rates,
        accelerations,
        bodies,
        named,
        times,
        {
            "integrator": setting.integrator,
            "timestep": dt,
            "series": series.key,
            "steps_per_sample": per,
            "newton_tolerance": setting.newton_tolerance,
        },
        diagnostics={"constraint_violation": gaps},
        notes=f"Exudyn driven dynamics, {setting.integrator}, dt = {dt:.4g} s; inputs as Exudyn realised them.",
    )
    return Run(trajectory, failure)
