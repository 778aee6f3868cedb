"""pymunk: the mechanism as a 2-D constraint scene, simulated and compared.

The mode ``pymunk-dynamic`` (its series, :func:`dynamic_series`, and one run,
:func:`run_dynamic_once`) builds the scene (:mod:`.scene`: one pymunk body per
moving link, a constraint per joint, the inputs driven by their motion laws),
steps it over :func:`xcheck.motion.simulation_window` from the native state at
t = 0 and samples the bodies; the ladder of time steps, solver iteration counts
and error corrections and its judgement are :class:`xcheck.ladder.DrivenLadder`'s.
:func:`scene_figure` draws what pymunk simulated.

Every trajectory carries the inputs as pymunk realised them (read from the
bodies), so :func:`xcheck.results.differences` solves the native model at the
very inputs pymunk reached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk as pm  # the library: absolute imports, so not this module (xcheck.engines.pymunk.modes)

from xcheck.fileio import write_atomic
from xcheck.kinematics import Kinematics, Solution
from xcheck.ladder import DrivenProblem, Run, Rung, Series
from xcheck.results import Trajectory

from .figure import render_png, snapshot
from .free import FREE_SERIES, prepare_free, run_free_once  # noqa: F401 - the mode "pymunk-free"
from .inverse import ITERATIONS, SAMPLES, STEPS_PER_SAMPLE, inverse_forces
from .scene import DEFAULT_MASS, Scene, build_scene, native_window

__all__ = [
    "MODE",
    "DEFAULT_MASS",
    "DYNAMIC_SETTINGS",
    "Scene",
    "Setting",
    "build_scene",
    "dynamic_series",
    "prepare_dynamic",
    "run_dynamic_once",
    "scene_figure",
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
        Time steps between two samples (of a series: its coarsest run's); the
        time step is the window's length over ``samples * steps_per_sample``.
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


#: The ladder's series (:func:`dynamic_series`), each a setting at its coarsest steps per
#: sample and its runs: full correction (error_bias 0) at 500 iterations at 50, 100, 200
#: steps per sample, compared; then 50 iterations and pymunk's defaults (10 iterations, default
#: error_bias) at 200. Full correction makes the position error second order in the time
#: step where pymunk's default leaves it first order; it needs enough iterations to converge
#: or the scene goes unstable (task-2-6 and the inverted slider-crank needed more than 200:
#: 500 leaves a margin).
DYNAMIC_SETTINGS = ((Setting(50, 500), 3), (Setting(200, 50), 1), (Setting(200, 10, None), 1))
#: the compared run's setting (the finest of the first series)
COMPARED_SETTING = Setting(200, 500)
INTEGRATOR = "semi-implicit Euler, iterative impulse solver"


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder's series (:data:`DYNAMIC_SETTINGS`), the compared one first."""
    return tuple(
        Series(
            _series(s.correction, s.iterations), INTEGRATOR, s, timestep=problem.interval / s.steps_per_sample, rungs=n
        )
        for s, n in DYNAMIC_SETTINGS
    )


def prepare_dynamic(problem: DrivenProblem) -> tuple[Solution, float]:
    """The native solution over the window (the scene's start, and the extent of its
    grooves) and the speed (m/s) beyond which a run has blown up: 10 times the native
    top speed of a point over the window (or of the size per window).

    Raises
    ------
    ValueError
        If the native solver does not assemble the mechanism all along the window.
    """
    kinematics = problem.kinematics
    _, native = native_window(kinematics, problem.branch)
    speeds = [np.linalg.norm(native.point(label)["velocity"], axis=1) for label in kinematics.mechanism.point_owners]
    top = max(float(np.max(s)) for s in speeds)
    return native, 10.0 * max(top, kinematics.mechanism.size / problem.window.duration)


def run_dynamic_once(prepared: tuple[Solution, float], problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`)."""
    native, speed_bound = prepared
    setting: Setting = rung.series.options
    return _simulate(problem, native, rung.counts[0], setting, 1, speed_bound)


def _simulate(
    problem: DrivenProblem, native: Solution, per: int, setting: Setting, fd_steps: int, speed_bound: float
) -> Run:
    """Step one scene over the window from the start of ``native`` (the native solution
    over it), ``per`` steps between samples, and sample it; accelerations by central
    differences of velocities ``fd_steps`` steps either side."""
    kinematics, window, samples = problem.kinematics, problem.window, problem.samples
    mech = kinematics.mechanism
    dt = window.duration / samples / per  # the ladder's step (DrivenProblem.rung)
    failure = ""
    scene = build_scene(kinematics, native, iterations=setting.iterations, error_bias=setting.error_bias)
    m = min(fd_steps, per)
    sample_steps = per * np.arange(1, samples + 1)
    wanted: dict[int, list] = {}
    for i, k in enumerate(sample_steps):  # slots: the velocities at k - m, k, k + m
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
                failure = f"went non-finite (NaN or infinite state) at t = {n * dt:.6g} s"
            elif problem.came_apart(n * dt, float(gaps[i])):
                failure = problem.came_apart(n * dt, float(gaps[i]))
            elif speed > speed_bound:
                failure = (
                    f"blew up at t = {n * dt:.6g} s: a point moves at {speed:.3g} m/s "
                    f"(bound {speed_bound:.3g} m/s, 10 times the native top speed)"
                )
        if failure:
            break
    if not failure and not all(np.isfinite(x).all() for x in (vel, omg, pvel, qd_in)):
        failure = "went non-finite (NaN or infinite state) after the last sample"
    columns = {"iterations": setting.iterations, "error_bias": setting.correction}
    if failure:
        skew = scene.skewed_grooves()  # a groove pymunk cannot hold: why the scene broke down
        return Run(None, failure + (f" ({skew})" if skew else ""), columns=columns)
    h = m * dt
    times = sample_steps * dt

    def rate(v: np.ndarray) -> np.ndarray:
        """The central difference at the samples of velocities ``v`` (3, samples, ...) in its slots."""
        return (v[2] - v[0]) / (2.0 * h)

    bodies = {
        name: {
            "position": pos[:, j],
            "angle": ang[:, j],
            "velocity": vel[1, :, j],
            "omega": omg[1, :, j],
            "acceleration": rate(vel[:, :, j]),
            "alpha": rate(omg[:, :, j]),
        }
        for j, name in enumerate(moving)
    }
    points = {
        label: {"position": ppos[:, j], "velocity": pvel[1, :, j], "acceleration": rate(pvel[:, :, j])}
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
    trajectory = Trajectory(
        source=MODE,
        inputs=q_in,
        input_rates=qd_in[1],
        input_accelerations=rate(qd_in),
        bodies=bodies,
        points=points,
        times=times,
        settings={
            "engine": f"pymunk {pm.version} (Chipmunk {pm.chipmunk_version})",
            "integrator": INTEGRATOR,
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
        diagnostics={"constraint_violation": gaps, "lock_error": locks},
        notes=(
            f"Accelerations are central differences of pymunk's velocities, {h:.6g} s ({m} time "
            f"step{'s' if m > 1 else ''}) either side of each sample. Inputs are read from the bodies as "
            f"pymunk realised them ({drives}). Mass properties that took defaults (mass {DEFAULT_MASS:g} kg; "
            f"centre of mass on the body's groove line or at its pin in a groove, where that keeps pymunk's "
            f"groove joints exact, else at the mean of its points and groove ends; moment of a slender rod "
            f"over those): {defaulted or 'none'}."
        ),
    )
    return Run(trajectory, "", columns={**columns, "lock_error": float(np.max(locks))})


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
    setting: Setting = COMPARED_SETTING,
    samples: int = 40,
    branch: str | None = None,
) -> None:
    """A picture of the pymunk scene at a few instants, for the report.

    The scene is stepped as in the driven mode with ``setting`` and drawn
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
