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
accelerations from the integrator. A slide driver (the slide of a prismatic
joint or pin-in-slot, nonlinear in the node coordinates) has no coordinate
constraint here: :class:`~xcheck.engines.NotApplicable`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from xcheck.engines._contract import NotApplicable, with_unit_mass
from xcheck.engines._driven import driven_result, ladder
from xcheck.kinematics import Kinematics, Status, rotate
from xcheck.ladder import Series
from xcheck.model import GROUND, Mechanism
from xcheck.motion import simulation_window
from xcheck.results import ModeResult, Trajectory

from .model import Setting, build_system, solver_settings

__all__ = ["MODE", "SETTINGS", "STEPS_PER_SAMPLE", "run_dynamic"]

MODE = "exudyn-dynamic"
#: the compared series (Newton to 1e-10: positions exact to it) and Exudyn's defaults
SETTINGS = tuple(
    Series(name, setting.integrator, setting)
    for name, setting in (("best", Setting(0.9, newton_tolerance=1e-10)), ("default", Setting(0.9)))
)
#: time steps per sample of the ladder, finest first
STEPS_PER_SAMPLE = (100, 50, 25)
#: samples compared per run
SAMPLES = 40

_ERRORS = {"position": "abs", "angle": "abs", "velocity": "rel", "omega": "rel", "acceleration": "rel", "alpha": "rel"}


def _perp(v: np.ndarray) -> np.ndarray:
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _simulate(kinematics: Kinematics, mech: Mechanism, window, q0, qd0, series: Series, per: int):
    """One run: (row, Trajectory or None)."""
    import exudyn as exu
    import exudyn.itemInterface as ei

    duration = window.duration
    dt = duration / (SAMPLES * per)
    setting: Setting = series.options
    row = {"setting": series.setting, "integrator": series.integrator, "timestep": dt, "status": "ok"}
    begin = time.process_time()
    model = build_system(mech, q0, qd0)
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
        if not solve(
            mbs, solver_settings(setting, dt, duration, duration / SAMPLES), showHints=False, showCausingItems=False
        ):
            row["status"] = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
    except Exception:  # noqa: BLE001 - a solver that gives up is a row
        row["status"] = f"Newton failed at t = {mbs.systemData.GetTime():.6g} s"
    finally:
        config.printToConsole = printing
    row["cpu_seconds"] = time.process_time() - begin
    if row["status"] != "ok":
        return row, None
    times = window.times(SAMPLES + 1)[1:]
    data = {name: [mbs.GetSensorStoredData(s) for s in found] for name, found in sensors.items()}
    stored = next(iter(data.values()))[0][:, 0]
    rows = [int(np.argmin(np.abs(stored - t))) for t in times]
    if np.max(np.abs(stored[rows] - times)) > 1e-9 * duration:
        row["status"] = "Exudyn's samples are not at the window's sample times"
        return row, None
    state = {name: [d[rows, 1:4] for d in found] for name, found in data.items()}
    for name in state:
        state[name][0] = state[name][0] + model.reference[name][None, :]
    if not all(np.isfinite(x).all() for found in state.values() for x in found):
        row["status"] = "went non-finite"
        return row, None
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
        diagnostics={"input_error": inputs - window.inputs(kinematics, times)[0]},
        notes=f"Exudyn driven dynamics, {setting.integrator}, dt = {dt:.4g} s; inputs as Exudyn realised them.",
    )
    return row, trajectory


def run_dynamic(kinematics: Kinematics, branch: str | None = None, refine: int = 0) -> ModeResult:
    """Simulate the driven mechanism in Exudyn at :data:`SETTINGS` x
    :data:`STEPS_PER_SAMPLE` and compare each run with the native solution;
    ``refine`` k > 0 runs only the first setting at 2^k times its finest step
    count (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        ``trajectories``: the runs that went through, the finest of the first
        setting first; ``summary``: per run setting, timestep (s), status,
        cpu_seconds and the largest errors (position m, angle rad; velocity,
        omega, acceleration, alpha relative to the native magnitude);
        ``study``: :func:`~xcheck.results.convergence_study` of the position error.

    Raises
    ------
    NotApplicable
        A slide driver, or a driver on a joint that is not a revolute.
    """
    mech = kinematics.mechanism
    for driver in mech.drivers:
        if driver.quantity != "angle":  # a revolute's
            raise NotApplicable(
                f"driver {driver.name}: a slide has no coordinate constraint in Exudyn (only joint angles are driven)"
            )
    try:
        window = simulation_window(kinematics, branch)
        q, qd, qdd = window.inputs(kinematics, np.zeros(1))
        start = kinematics.solve(q, qd, qdd, branch=branch)
        if start.status[0] > Status.NEAR_SINGULAR:
            raise ValueError("the native solver does not assemble the mechanism at t = 0")
        massive = with_unit_mass(mech)
        runs = [
            _simulate(kinematics, massive, window, start.q[0], start.qd[0], setting, per)
            for setting, per in ladder(SETTINGS, STEPS_PER_SAMPLE, refine)
        ]
    except NotApplicable:
        raise
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        return ModeResult(MODE, mech.name, False, f"{MODE}: {type(error).__name__}: {error}".splitlines()[0])
    return driven_result(MODE, kinematics, runs, _ERRORS, branch)
