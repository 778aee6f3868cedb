"""pymunk: the mechanism as a 2-D constraint scene, simulated and compared.

The mode ``pymunk-dynamic`` (:func:`run_dynamic`) builds the scene
(:mod:`.scene`: one pymunk body per moving link, a constraint per
joint, the inputs driven by their motion laws), steps it over
:func:`xcheck.motion.simulation_window` from the native state at t = 0,
samples the bodies, and compares them with the native solution for several
time steps, solver iteration counts and error corrections: the error trend,
with how far the joints came apart. :func:`scene_figure` draws what pymunk
simulated.

Every trajectory carries the inputs as pymunk realised them (read from the
bodies), so :func:`xcheck.results.differences` solves the native model at the
very inputs pymunk reached.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
import pymunk as pm  # the library: absolute imports, so not this module (xcheck.engines.pymunk.modes)

from xcheck.engines._driven import refined_steps
from xcheck.errors import NotApplicable
from xcheck.fileio import write_atomic
from xcheck.kinematics import Kinematics, Solution
from xcheck.ladder import convergence_study, observed_order
from xcheck.motion import SimulationWindow
from xcheck.results import ModeResult, Trajectory, differences

from .figure import render_png, snapshot
from .free import FREE_SERIES, prepare_free, run_free_once  # noqa: F401 - the mode "pymunk-free"
from .inverse import ITERATIONS, SAMPLES, STEPS_PER_SAMPLE, inverse_forces
from .scene import DEFAULT_MASS, Scene, build_scene, native_window

__all__ = [
    "MODE",
    "DEFAULT_MASS",
    "DEFAULT_SETTINGS",
    "Scene",
    "Setting",
    "build_scene",
    "run_dynamic",
    "scene_figure",
    "trajectory_errors",
    "inverse_dynamics",
]

#: The mode this module provides.
MODE = "pymunk-dynamic"


@dataclass(frozen=True)
class Setting:
    """One simulation of the scene.

    Attributes
    ----------
    steps_per_sample : int
        Time steps between two samples; the time step is the window's length
        over ``samples * steps_per_sample``.
    iterations : int
        The space's solver iterations per step.
    error_bias : float or None
        Every joint constraint's ``error_bias`` (fraction of a joint's error
        left after one second): 0 corrects the whole error in one step; None
        keeps pymunk's default (0.9 left per 1/60 s).
    """

    steps_per_sample: int
    iterations: int
    error_bias: float | None = 0.0

    @property
    def correction(self) -> str:
        return "pymunk default" if self.error_bias is None else f"error_bias {self.error_bias:g}"


#: The settings :func:`run_dynamic` runs by default, the comparison's first:
#: three time steps at 500 iterations with full correction (error_bias 0),
#: then the finest step with 50 iterations and with pymunk's defaults (10
#: iterations, default error_bias). Full correction makes the position error
#: second order in the time step where pymunk's default leaves it first order;
#: it needs enough iterations to converge or the scene goes unstable (task-2-6
#: and the inverted slider-crank needed more than 200: 500 leaves a margin).
DEFAULT_SETTINGS = (
    Setting(200, 500),
    Setting(100, 500),
    Setting(50, 500),
    Setting(200, 50),
    Setting(200, 10, None),
)


@dataclass
class _Run:
    """The outcome of one simulation."""

    setting: Setting
    dt: float
    trajectory: Trajectory | None = None
    failure: str = ""
    run_time: float = 0.0


def _simulate(
    kinematics: Kinematics,
    native: Solution,
    window: SimulationWindow,
    samples: int,
    setting: Setting,
    fd_steps: int,
    gap_bound: float,
    speed_bound: float,
) -> _Run:
    """Step one scene over the window and sample it (see :func:`run_dynamic`)."""
    mech = kinematics.mechanism
    per = setting.steps_per_sample
    dt = window.duration / (samples * per)
    run = _Run(setting, dt)
    start = time.perf_counter()
    scene = build_scene(kinematics, native, iterations=setting.iterations, error_bias=setting.error_bias)
    m = min(fd_steps, per)
    sample_steps = per * np.arange(1, samples + 1)
    wanted: dict[int, list] = {}
    for i, k in enumerate(sample_steps):
        for offset, slot in ((-m, 0), (0, 1), (m, 2)):
            wanted.setdefault(int(k + offset), []).append((i, slot))
    moving = [b.name for b in mech.moving_bodies]
    owners = mech.point_owners
    labels = list(owners)
    nb, npt, k_in = len(moving), len(labels), len(mech.drivers)
    pos, ang = np.full((samples, nb, 2), np.nan), np.full((samples, nb), np.nan)
    vel, omg = np.full((3, samples, nb, 2), np.nan), np.full((3, samples, nb), np.nan)
    ppos, pvel = np.full((samples, npt, 2), np.nan), np.full((3, samples, npt, 2), np.nan)
    q_in, qd_in = np.full((samples, k_in), np.nan), np.full((3, samples, k_in), np.nan)
    gaps, locks = np.full(samples, np.nan), np.full(samples, np.nan)
    pm_bodies = [scene.bodies[name] for name in moving]
    for n in range(1, int(sample_steps[-1] + m) + 1):
        scene.step((n - 1) * dt, dt)
        if n not in wanted:
            continue
        q_now, qd_now = scene.inputs()
        body_v = [(v.x, v.y) for v in (b.velocity_at_local_point((0.0, 0.0)) for b in pm_bodies)]
        body_w = [b.angular_velocity for b in pm_bodies]
        point_v = [scene.point_velocity(owners[label], label) for label in labels]
        for i, slot in wanted[n]:
            vel[slot, i], omg[slot, i], pvel[slot, i], qd_in[slot, i] = body_v, body_w, point_v, qd_now
            if slot != 1:
                continue
            pos[i] = [(b.position.x, b.position.y) for b in pm_bodies]
            ang[i] = [b.angle for b in pm_bodies]
            ppos[i] = [scene.world_point(owners[label], label) for label in labels]
            q_in[i] = q_now
            gaps[i], locks[i] = scene.joint_gaps()
            speed = float(np.max(np.linalg.norm(pvel[1, i], axis=1), initial=0.0))
            finite = all(np.isfinite(x).all() for x in (pos[i], ang[i], vel[1, i], omg[1, i], pvel[1, i]))
            if not (finite and math.isfinite(gaps[i])):
                run.failure = f"went non-finite (NaN or infinite state) at t = {n * dt:.6g} s"
            elif gaps[i] > gap_bound:
                skew = scene.skewed_grooves()
                run.failure = (
                    f"came apart at t = {n * dt:.6g} s: joints {gaps[i]:.3g} m apart "
                    f"(bound {gap_bound:.3g} m)" + (f" ({skew})" if skew else "")
                )
            elif speed > speed_bound:
                run.failure = (
                    f"blew up at t = {n * dt:.6g} s: a point moves at {speed:.3g} m/s "
                    f"(bound {speed_bound:.3g} m/s, 10 times the native top speed)"
                )
        if run.failure:
            break
    run.run_time = time.perf_counter() - start
    if not run.failure and not all(np.isfinite(x).all() for x in (vel, omg, pvel, qd_in)):
        run.failure = "went non-finite (NaN or infinite state) after the last sample"
    if run.failure:
        return run
    h = m * dt
    times = sample_steps * dt
    bodies = {
        name: {
            "position": pos[:, j],
            "angle": ang[:, j],
            "velocity": vel[1, :, j],
            "omega": omg[1, :, j],
            "acceleration": (vel[2, :, j] - vel[0, :, j]) / (2.0 * h),
            "alpha": (omg[2, :, j] - omg[0, :, j]) / (2.0 * h),
        }
        for j, name in enumerate(moving)
    }
    points = {
        label: {
            "position": ppos[:, j],
            "velocity": pvel[1, :, j],
            "acceleration": (pvel[2, :, j] - pvel[0, :, j]) / (2.0 * h),
        }
        for j, label in enumerate(labels)
    }
    drives = ", ".join(f"{mech.drivers[d.driver_index].name}: {d.kind}" for d in scene.drives)
    skew = scene.skewed_grooves()
    # a skewed groove holds the pin's velocity along a skewed direction: the pin leaves its
    # groove by O(dt) over the window, so positions converge at order 1 there (measured 1.00 on
    # xcheck fuzz s1-00012, a Scotch yoke whose crank's centre of mass is mid-crank; 2.00 with
    # exact grooves, tests/data/scotch-yoke.toml)
    orders = {"position": 1.0, "angle": 1.0} if skew else {}
    defaulted = "; ".join(f"{name}: {', '.join(props)}" for name, props in scene.defaults.items() if props)
    run.trajectory = Trajectory(
        source=MODE,
        inputs=q_in,
        input_rates=qd_in[1],
        input_accelerations=(qd_in[2] - qd_in[0]) / (2.0 * h),
        bodies=bodies,
        points=points,
        times=times,
        settings={
            "engine": f"pymunk {pm.version} (Chipmunk {pm.chipmunk_version})",
            "integrator": "semi-implicit Euler, iterative impulse solver",
            "time_step": dt,
            "timestep": dt,
            "series": _series(setting.correction, setting.iterations),
            "iterations": setting.iterations,
            "steps_per_sample": per,
            "error_bias": setting.correction,
            "drives": drives,
            "difference_step": h,
            **({"orders": orders, "orders_reason": skew} if orders else {}),
        },
        diagnostics={"joint_gap": gaps, "lock_error": locks, "input_error": q_in - window.inputs(kinematics, times)[0]},
        notes=(
            f"Accelerations are central differences of pymunk's velocities, {h:.6g} s ({m} time "
            f"step{'s' if m > 1 else ''}) either side of each sample. Inputs are read from the bodies as "
            f"pymunk realised them ({drives}). Mass properties that took defaults (mass {DEFAULT_MASS:g} kg; "
            f"centre of mass on the body's groove line or at its pin in a groove, where that keeps pymunk's "
            f"groove joints exact, else at the mean of its points and groove ends; moment of a slender rod "
            f"over those): {defaulted or 'none'}."
        ),
    )
    return run


#: Column of :func:`trajectory_errors` -> (rows' quantity, kind of error).
_ERROR_COLUMNS = {
    "position_error": ("position", "abs"),
    "angle_error": ("angle", "abs"),
    "velocity_error": ("velocity", "rel"),
    "omega_error": ("omega", "rel"),
    "acceleration_error": ("acceleration", "rel"),
    "alpha_error": ("alpha", "rel"),
}


def trajectory_errors(kinematics: Kinematics, trajectory: Trajectory, branch: str | None = None) -> dict[str, float]:
    """The largest differences of a trajectory from the native solution (on
    ``branch``, by default the model's first), from :func:`xcheck.results.differences`.

    Returns
    -------
    dict
        ``position_error`` (m) and ``angle_error`` (rad): largest absolute
        difference over bodies and points; ``velocity_error``, ``omega_error``,
        ``acceleration_error``, ``alpha_error``: largest absolute difference
        over the largest native magnitude of that quantity in the mechanism
        (dimensionless); ``joint_gap`` (m) and ``lock_error`` (rad): largest
        over the samples. A quantity no row has is left out.
    """
    table = differences(kinematics, trajectory, branch)
    out = {}
    for column, (quantity, kind) in _ERROR_COLUMNS.items():
        rows = table[table["quantity"] == quantity]
        if rows.empty:
            continue
        worst = float(rows["max_abs"].max())
        if kind == "rel":
            scale = float(rows["scale"].max())
            worst = worst / scale if scale > 0.0 else worst
        out[column] = worst
    out["joint_gap"] = float(np.max(trajectory.diagnostics["joint_gap"]))
    out["lock_error"] = float(np.max(trajectory.diagnostics["lock_error"]))
    return out


def _summary(kinematics: Kinematics, runs: list[_Run], branch: str | None) -> pd.DataFrame:
    """One row per setting; the observed order of the position error between
    a setting and the next coarser one of the same iterations and correction."""
    mech = kinematics.mechanism
    rows: list[dict] = []
    for run in runs:
        row = {
            "setting": len(rows),
            "error_bias": run.setting.correction,
            "iterations": run.setting.iterations,
            "time_step": run.dt,
            "status": run.failure or "ok",
        }
        if run.trajectory is not None:
            row.update(trajectory_errors(kinematics, run.trajectory, branch))
            drift = np.max(np.abs(run.trajectory.diagnostics["input_error"]), axis=0)
            row.update({f"input_error:{d.name}": float(e) for d, e in zip(mech.drivers, drift)})
        row["run_time"] = run.run_time
        rows.append(row)
    table = pd.DataFrame(rows)
    table["order"] = np.nan
    if "position_error" in table:
        for _, group in table.groupby(["error_bias", "iterations"]):
            group = group[group["status"] == "ok"].sort_values("time_step")
            for (i, fine), (_, coarse) in zip(group.iterrows(), list(group.iterrows())[1:]):
                table.loc[i, "order"] = observed_order(
                    coarse["position_error"], fine["position_error"], coarse["time_step"], fine["time_step"]
                )
    return table


def run_dynamic(
    kinematics: Kinematics,
    *,
    settings=DEFAULT_SETTINGS,
    samples: int = 40,
    fd_steps: int = 1,
    gap_bound: float | None = None,
    branch: str | None = None,
    refine: int = 0,
) -> ModeResult:
    """Simulate the mechanism in pymunk and compare it with the native solution.

    The drivers follow their motion laws over
    :func:`xcheck.motion.simulation_window`, from the native state at t = 0.
    Each setting is one simulation, sampled at ``samples`` equally spaced
    times after t = 0.

    Parameters
    ----------
    kinematics : Kinematics
    settings : sequence of Setting
        The first is the one the comparison uses (by default the finest time
        step with 500 iterations and full error correction); the others give
        the error's trend with time step, iterations and pymunk's default
        correction.
    samples : int
        Sample times per simulation.
    fd_steps : int
        Time steps either side of a sample for the central differences of
        velocity that give accelerations.
    gap_bound : float, optional
        A simulation whose joints come further apart than this (m) has
        failed; default 5 % of the mechanism's size. One whose points move
        faster than 10 times the native top speed has failed too.
    branch : str, optional
        Assembly branch.
    refine : int
        k > 0: only the first setting at 2^k times its steps per
        sample (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        ``trajectories``: one per setting that ran through; ``summary``: one row
        per setting (see :func:`trajectory_errors` for the error columns, plus
        ``input_error:<driver>``, the largest difference of the realised input
        from its motion law in rad or m, ``order``, the observed order of the
        position error in the time step against the next coarser setting of the
        same iterations and correction, and ``run_time`` in s; a failed run's
        error figures and a row without a coarser partner's order are NaN, the
        ``status`` says why). ``ok`` is
        False, with the reason in one line, when the first setting fails or the
        scene cannot be built; nothing is raised.
    """
    mech = kinematics.mechanism
    settings = tuple(settings)
    if refine and settings:
        first = settings[0]
        settings = tuple(replace(first, steps_per_sample=n) for n in refined_steps(first.steps_per_sample, refine))
    try:
        if not settings:
            raise ValueError("expected at least one setting, found none")
        window, native = native_window(kinematics, branch)
        bound = 0.05 * mech.size if gap_bound is None else float(gap_bound)
        speeds = [np.linalg.norm(native.point(label)["velocity"], axis=1) for label in mech.point_owners]
        top = max(float(np.max(s)) for s in speeds)
        speed_bound = 10.0 * max(top, mech.size / window.duration)
        runs = [_simulate(kinematics, native, window, samples, s, fd_steps, bound, speed_bound) for s in settings]
        summary = _summary(kinematics, runs, branch)
    except NotApplicable:
        raise  # what pymunk cannot hold: the mode does not apply
    except Exception as err:  # the other modes still run: report, never raise
        reason = " ".join(str(err).split())
        if not isinstance(err, ValueError) or not reason:
            reason = f"{type(err).__name__}: {reason}"
        return ModeResult(MODE, mech.name, False, f"{MODE}: {reason}")
    errors = summary["position_error"] if "position_error" in summary else [math.nan] * len(summary)
    study = convergence_study(
        [_series(r.setting.correction, r.setting.iterations) for r in runs], summary.time_step, errors, summary.status
    )
    first = runs[0]
    if first.trajectory is None:
        return ModeResult(
            MODE,
            mech.name,
            False,
            f"{MODE}: the scene {first.failure} (time step {first.dt:.3g} s, {first.setting.iterations} iterations)",
            [],
            summary,
            study,
        )
    return ModeResult(
        MODE, mech.name, True, "", [r.trajectory for r in runs if r.trajectory is not None], summary, study
    )


def _series(correction: str, iterations: int) -> str:
    """The convergence series of a setting: its error correction and iterations."""
    return f"{correction}, {iterations} iterations"


def inverse_dynamics(
    kinematics: Kinematics,
    branch: str | None = None,
    samples: int = SAMPLES,
    steps_per_sample: int = STEPS_PER_SAMPLE,
    iterations: int = ITERATIONS,
    error_bias: float | None = 0.0,
    refine: int = 0,
):
    """Magnitudes of the joint reactions and input efforts in a driven pymunk
    simulation: constraint impulses over the time step (see
    :mod:`.inverse`); ``refine`` k > 0 takes 2^k times ``steps_per_sample``
    (:attr:`xcheck.engines.Engine.force_order`).

    Parameters
    ----------
    kinematics : Kinematics
    branch : str, optional
    samples : int
        Sample times over the simulation window.
    steps_per_sample : int
        Time steps between samples.
    iterations : int
    error_bias : float or None

    Returns
    -------
    xcheck.dynamics.Forces

    Raises
    ------
    ValueError
        If the scene cannot be built, comes apart or goes non-finite.
    """
    return inverse_forces(kinematics, branch, samples, steps_per_sample * 2**refine, iterations, error_bias)


def scene_figure(
    kinematics: Kinematics,
    path,
    *,
    times=None,
    count: int = 4,
    setting: Setting = DEFAULT_SETTINGS[0],
    samples: int = 40,
    branch: str | None = None,
) -> None:
    """A picture of the pymunk scene at a few instants, for the report.

    The scene is stepped as in :func:`run_dynamic` with ``setting`` and drawn
    from pymunk's own body positions: each body as the hull of its points
    (a bar between its two ends, a square for a one-point slider), pins as
    circles (triangles on the ground), grooves as grey bands, prismatic
    blocks as squares turned with their body. Coordinates and inputs are in
    the mechanism's display units. The PNG is written whole or not at all.

    Parameters
    ----------
    kinematics : Kinematics
    path : str or Path
        The PNG to write.
    times : sequence of float, optional
        Instants (s) inside the simulation window; default ``count`` of them
        equally spaced from 0 to its end.
    setting : Setting
        Time step (through ``samples``), iterations and correction.

    Raises
    ------
    ValueError
        If the window cannot be simulated or a time lies outside it.
    """
    mech = kinematics.mechanism
    window, native = native_window(kinematics, branch)
    times = window.times(count) if times is None else np.asarray(times, dtype=float)
    if times.size == 0 or np.any(times < 0.0) or np.any(times > window.duration):
        raise ValueError(
            f"expected times within the simulation window 0 .. {window.duration:.6g} s, "
            f"found {np.round(times, 6).tolist()}"
        )
    dt = window.duration / (samples * setting.steps_per_sample)
    scene = build_scene(kinematics, native, iterations=setting.iterations, error_bias=setting.error_bias)
    shots, n = [], 0
    for t in np.sort(times):
        while n < round(t / dt):
            scene.step(n * dt, dt)
            n += 1
        shots.append((n * dt, snapshot(scene)))
    drives = ", ".join(f"{mech.drivers[d.driver_index].name}: {d.kind}" for d in scene.drives)
    title = (
        f"{mech.title or mech.name}: the pymunk scene ({drives}; time step {dt:.3g} s, "
        f"{setting.iterations} iterations, {setting.correction})"
    )
    write_atomic(path, render_png(mech, shots, title))
