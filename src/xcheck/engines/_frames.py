"""Reading a mechanism back from the body frames an engine reports: world points,
the loops' gap, a free run's outputs recorded one by one (PyBullet, Drake,
pymunk) and the arrays a driven run fills and hands back (PyBullet, Drake, DART,
OpenSim)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from xcheck.kinematics import rotate
from xcheck.ladder import FreeProblem, Run
from xcheck.model import GROUND
from xcheck.results import Trajectory

__all__ = [
    "FrameRecorder",
    "driven_run",
    "stepped_samples",
    "empty_states",
    "record_moving_states",
    "loop_gap",
    "native_point_state",
    "point_velocity",
    "world_point",
]


def world_point(frames, body: str, point: np.ndarray) -> np.ndarray:
    """A point fixed in ``body`` (its local coordinates (2,), m) in the world, m.

    ``frames`` maps each moving body's name to its origin (2,) and angle (rad),
    as an engine reports them; the ground's points are their own.
    """
    if body == GROUND:
        return point
    origin, phi = frames[body][:2]
    return origin + rotate(phi, point)


def point_velocity(frames, body: str, point: np.ndarray) -> np.ndarray:
    """The velocity (2,), m/s, of a point fixed in ``body`` (local coordinates (2,), m):
    v_origin + omega x (r - origin), ``frames`` mapping each moving body's name to its
    origin, angle, origin velocity and rate as an engine reports them; the ground's
    points stand still."""
    if body == GROUND:
        return np.zeros(2)
    origin, _, velocity, omega = frames[body]
    arm = world_point(frames, body, point) - origin
    return velocity + omega * np.array([-arm[1], arm[0]])


def native_point_state(
    index, q: np.ndarray, qd: np.ndarray, body: str, point: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(position (2,), velocity (2,), angle, rate) of a point fixed in ``body`` (local
    coordinates (2,), m; the body's origin without one) at native body coordinates ``q``
    and rates ``qd`` (x, y, phi per moving body; ``index`` maps a body's name to the
    position of its x); the ground's points stand still."""
    if body == GROUND:
        return (np.zeros(2) if point is None else point), np.zeros(2), 0.0, 0.0
    k = index[body]
    phi, omega = float(q[k + 2]), float(qd[k + 2])
    arm = np.zeros(2) if point is None else rotate(phi, point)
    return q[k : k + 2] + arm, qd[k : k + 2] + omega * np.array([-arm[1], arm[0]]), phi, omega


def loop_gap(frames, cuts) -> float:
    """The widest gap (m) of the joints an engine holds as loop constraints: ``cuts`` is
    (body, point (2,), body, point (2,)) per joint, ``frames`` as :func:`world_point`'s."""
    return max(
        (float(np.hypot(*(world_point(frames, a, pa) - world_point(frames, b, pb)))) for a, pa, b, pb in cuts),
        default=0.0,
    )


class FrameRecorder:
    """A free run's outputs, from the body frames an engine reports at each
    compared output of a :class:`~xcheck.ladder.FreeProblem`.

    Parameters
    ----------
    problem : FreeProblem
    cuts : sequence of (body, point (2,), body, point (2,))
        The joints the engine holds as loop constraints: their gap is the loop drift.
    gap : callable, optional
        The loops' opening (m) from the frames, instead of the cuts' (pymunk's joints).
    """

    def __init__(self, problem: FreeProblem, cuts=(), gap=None) -> None:
        mechanism = problem.kinematics.mechanism
        self.problem = problem
        count = len(problem.index)
        self.bodies = {
            b.name: {"position": np.full((count, 2), np.nan), "angle": np.full(count, np.nan)}
            for b in mechanism.moving_bodies
        }
        self.points = {label: {"position": np.full((count, 2), np.nan)} for label in mechanism.point_owners}
        self.owners = mechanism.point_owners
        self.local = {label: np.asarray(mechanism.body(o).points[label], float) for label, o in self.owners.items()}
        self.gap = gap if gap is not None else (lambda frames: loop_gap(frames, cuts))
        self.gaps = np.full(count, np.nan)
        self.energy = np.full(count, np.nan)
        #: outputs recorded
        self.reached = 0

    def record(self, frames, j: int, energy: float = math.nan) -> str:
        """Store output ``j`` from ``frames`` (body name to origin (2,), angle, ...) and
        the engine's ``energy`` there (J, NaN where unknown); "" or why the run stops
        here (it went non-finite, came apart: :meth:`FreeProblem.came_apart`)."""
        t = float(self.problem.times[j])
        if not all(np.isfinite(f[0]).all() and math.isfinite(f[1]) for f in frames.values()):
            return f"went non-finite at t = {t:.6g} s"
        for name, states in self.bodies.items():
            states["position"][j] = frames[name][0]
            states["angle"][j] = frames[name][1]
        for label, owner in self.owners.items():
            self.points[label]["position"][j] = world_point(frames, owner, self.local[label])
        gap = self.gap(frames)
        self.gaps[j], self.energy[j] = gap, energy
        self.reached = j + 1
        return self.problem.came_apart(t, gap)

    def trajectory(self, source: str, settings: dict, notes: str) -> Trajectory | None:
        """The outputs recorded, as a Trajectory (diagnostics: constraint_violation,
        and energy where every recorded output has one); None if none was."""
        n = self.reached
        if not n:
            return None
        empty = np.zeros((n, 0))
        bodies = {name: {k: v[:n] for k, v in states.items()} for name, states in self.bodies.items()}
        points = {label: {k: v[:n] for k, v in states.items()} for label, states in self.points.items()}
        diagnostics = {"constraint_violation": self.gaps[:n]}
        if np.all(np.isfinite(self.energy[:n])):
            diagnostics["energy"] = self.energy[:n]
        times = self.problem.times[:n]
        return Trajectory(source, empty, empty, empty, bodies, points, times, settings, diagnostics, notes)


def empty_states(mechanism, samples: int, quantities) -> tuple[dict, dict, np.ndarray, np.ndarray, np.ndarray]:
    """The NaN arrays a driven run fills sample by sample (:func:`driven_run` hands them back).

    Parameters
    ----------
    samples : int
        N, the samples of the run.
    quantities : iterable of str
        The body quantities kept: the vectors ``position``, ``velocity`` and
        ``acceleration`` (N, 2), the others (N,).

    Returns
    -------
    bodies : dict of str to dict of str to ndarray
        Per moving body, per quantity.
    points : dict of str to dict of str to ndarray
        Per named point off the ground, the vectors of ``quantities`` (N, 2): m, m/s, m/s^2.
    inputs, rates : ndarray, shape (N, k)
        The drivers' realised values (rad or m) and rates.
    gaps : ndarray, shape (N,)
        The loops' largest opening (m), zeros.
    """
    vectors = ("position", "velocity", "acceleration")
    bodies = {
        body.name: {key: np.full((samples, 2) if key in vectors else samples, np.nan) for key in quantities}
        for body in mechanism.moving_bodies
    }
    ground = mechanism.ground.name
    kept = ("position", "velocity", *(key for key in quantities if key == "acceleration"))
    points = {
        label: {key: np.full((samples, 2), np.nan) for key in kept}
        for label, owner in mechanism.point_owners.items()
        if owner != ground
    }
    inputs = np.full((samples, len(mechanism.drivers)), np.nan)
    return bodies, points, inputs, np.full_like(inputs, np.nan), np.zeros(samples)


def record_moving_states(mechanism, states: dict[str, tuple], arrays: tuple[dict, dict], j: int) -> bool:
    """Sample ``j`` of the body and point arrays of :func:`empty_states` (position, angle,
    velocity, omega) from an engine's ``states``: per moving body its origin (2,) m, angle
    rad, origin velocity (2,) m/s and rate rad/s. False, nothing stored, where one is not finite."""
    if not all(np.isfinite(s[0]).all() and math.isfinite(s[1]) for s in states.values()):
        return False
    bodies, points = arrays
    for name, (origin, phi, velocity, omega) in states.items():
        bodies[name]["position"][j], bodies[name]["angle"][j] = origin, phi
        bodies[name]["velocity"][j], bodies[name]["omega"][j] = velocity, omega
    for label in points:
        owner = mechanism.point_owners[label]
        local = np.asarray(mechanism.body(owner).points[label], dtype=float)
        points[label]["position"][j] = world_point(states, owner, local)
        points[label]["velocity"][j] = point_velocity(states, owner, local)
    return True


def stepped_samples(
    samples: int, per: int, step: Callable[[int], None], record: Callable[[int], str]
) -> tuple[str, int]:
    """Take ``samples * per`` engine steps, ``step(n)`` the n-th (0-based), and after
    every ``per``-th record sample j = (n + 1) // per - 1 (``record(j)``: "" or why the
    run stops there; "went non-finite ..." where the sample's states were not stored).
    Returns (why it stopped or "", the samples stored), as :func:`driven_run` takes them."""
    failure, reached = "", 0
    for n in range(samples * per):
        if failure:
            break
        step(n)
        if not (n + 1) % per:
            j = (n + 1) // per - 1
            failure = record(j)
            reached = j + (0 if failure.startswith("went non-finite") else 1)
    return failure, reached


def driven_run(
    source: str,
    mechanism,
    times: np.ndarray,
    states: tuple[dict, dict, np.ndarray, np.ndarray, np.ndarray],
    reached: int,
    failure: str,
    settings: dict,
    notes: str,
    accelerations: np.ndarray | None = None,
) -> Run:
    """A driven run's first ``reached`` samples (the states filled before it stopped) as
    the :class:`~xcheck.ladder.Run` a driven ladder judges.

    Parameters
    ----------
    times : ndarray, shape (N,)
        The compared sample times, s (:attr:`xcheck.ladder.DrivenProblem.times`).
    states : (bodies, points, inputs, rates, gaps)
        As :func:`empty_states` makes them, filled: the inputs and rates as the engine
        realised them, the loops' gaps (its ``constraint_violation``).
    failure : str
        Why it stopped ("" where it reached the end).
    settings : dict
        The trajectory's settings (integrator, timestep, series, steps_per_sample).
    accelerations : ndarray, shape (N, k), optional
        The inputs' accelerations as the engine realised them (default: the motion laws').
    """
    bodies, points, inputs, rates, gaps = states
    kept = slice(0, reached)
    if accelerations is None:
        accelerations = np.stack([d.law.at_time(times)[2] for d in mechanism.drivers], axis=1)
    trajectory = Trajectory(
        source,
        inputs[kept],
        rates[kept],
        accelerations[kept],
        {name: {key: value[kept] for key, value in quantities.items()} for name, quantities in bodies.items()},
        {label: {key: value[kept] for key, value in quantities.items()} for label, quantities in points.items()},
        times[kept],
        settings,
        diagnostics={"constraint_violation": gaps[kept]},
        notes=notes,
    )
    return Run(trajectory, failure)
