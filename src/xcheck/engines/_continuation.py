"""Continuation for the engines' kinematic oracles: an engine's own Newton
solver walked along a sweep of inputs on one assembly branch.

The engine is seeded as a user would seed it: each step starts from the
previous accepted configuration, predicted along the engine's own tangent
dq/dc (its constraint Jacobian with the inputs' rows). A step is accepted only
if the engine's Newton converges, the correction from the prediction is small
(at most :data:`MAX_CORRECTION`, and at most :data:`CORRECTION_RATIO` of the
predicted move: a tangent step's error grows like its square, so halving the
step brings a too-large correction down) and the determinant of the engine's
square system keeps its sign (it changes only through a singular
configuration, or on the other branch). Otherwise the step is halved; below
:data:`MIN_STEP`, or past a budget of the engine's solves from one sample to the
next, the walk stops and says where and why, so that a branch the engine cannot
follow is a stated result, never a silent jump or a walk without end.

Every number here (residuals, Jacobians) comes from the engine; the native
solver only provides the first configuration (at the reference inputs).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = [
    "MAX_STEP",
    "MIN_STEP",
    "MAX_CORRECTION",
    "CORRECTION_RATIO",
    "PERIODIC",
    "Walk",
    "crank_period",
    "follow",
    "square_rows",
    "square_sign",
    "step_refused",
    "tangent",
]

#: Longest step, scaled input units (rad; slides per mechanism size), as the native continuation.
MAX_STEP = math.radians(2.0)
#: Below this step (scaled input units) the walk stops: the branch cannot be followed further.
#: A correction below it (scaled coordinates) is round-off whatever the step.
MIN_STEP = 1e-9
#: Largest correction from the prediction, scaled coordinates (rad; lengths per size), as the native's.
MAX_CORRECTION = 0.1
#: Largest correction as a fraction of the predicted move (scaled, largest component).
CORRECTION_RATIO = 0.5
#: A walk of one turn repeats the configuration when every coordinate changed by whole
#: turns to within this (scaled: rad; lengths per size): round-off of a turn's steps.
PERIODIC = 1e-8


@dataclass
class Walk:
    """An engine's configurations along a sweep, N samples.

    Attributes
    ----------
    qpos : ndarray, shape (N, nv)
        NaN from the first sample not reached.
    residual : ndarray, shape (N,)
        Largest loop violation, m (inf where not reached).
    iterations : ndarray of int, shape (N,)
        Newton iterations of each sample's last step.
    steps : ndarray of int, shape (N,)
        Accepted steps (substeps) from the previous sample.
    converged : ndarray of bool, shape (N,)
    stopped : int or None
        The first sample not reached, None if all were.
    reason : str
        Why the walk stopped ("" if it did not).
    """

    qpos: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    steps: np.ndarray
    converged: np.ndarray
    stopped: int | None = None
    reason: str = ""


def crank_period(mechanism) -> float | None:
    """2 pi where the mechanism's one driver turns a joint (``follow``'s ``period``), else None."""
    drivers = mechanism.drivers
    return 2.0 * math.pi if len(drivers) == 1 and drivers[0].quantity == "angle" else None


def square_rows(matrix: np.ndarray) -> np.ndarray:
    """Indices of nv independent rows of the (rows, nv) system (pivoted QR of its
    transpose): the planar rows, without the structural zeros (a connect's z)."""
    _, _, pivots = scipy.linalg.qr(matrix.T, pivoting=True, mode="economic")
    return np.sort(pivots[: matrix.shape[1]])


def tangent(matrix: np.ndarray, n_loop: int) -> np.ndarray:
    """dq/dc, (nv, k), of a system matrix (n_loop + k, nv): the loop rows' change zero,
    the inputs' rows the identity (least squares)."""
    k = matrix.shape[0] - n_loop
    rhs = np.zeros((matrix.shape[0], k))
    rhs[n_loop:] = np.eye(k)
    return np.linalg.lstsq(matrix, rhs, rcond=None)[0]


def step_refused(
    q: np.ndarray, guess: np.ndarray, q_new: np.ndarray, sign: float, new_sign: float, coordinate_scale: np.ndarray
) -> str:
    """Why a converged step from ``q`` to ``q_new``, predicted at ``guess``, leaves the
    branch ("" where it is accepted): the determinant's sign (``sign``, ``new_sign``:
    of the square system before and after) changed, or the correction from the
    prediction exceeds :data:`MAX_CORRECTION` or :data:`CORRECTION_RATIO` of the
    predicted move (scaled coordinates)."""
    predicted = float(np.max(np.abs((guess - q) * coordinate_scale)))
    correction = float(np.max(np.abs((q_new - guess) * coordinate_scale)))
    if new_sign != sign and sign != 0.0 and new_sign != 0.0:
        return "the determinant of its Jacobian changes sign (a singular configuration or the other branch)"
    if correction > min(MAX_CORRECTION, max(CORRECTION_RATIO * predicted, MIN_STEP)):
        return f"Newton's correction stays large ({correction:.3g} scaled)"
    return ""


def square_sign(matrix: np.ndarray, rows: np.ndarray) -> float:
    """The sign of the determinant of the square system: ``matrix``'s ``rows``."""
    return float(np.linalg.slogdet(matrix[rows])[0])


def follow(
    newton: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, float, int, bool]],
    system_matrix: Callable[[np.ndarray], np.ndarray],
    n_loop: int,
    q0: np.ndarray,
    c0: np.ndarray,
    inputs: np.ndarray,
    input_scale: np.ndarray,
    coordinate_scale: np.ndarray,
    period: float | None = None,
    budget: int | None = None,
) -> Walk:
    """Walk an engine's solver from (q0, c0) through ``inputs`` in order.

    Parameters
    ----------
    newton : callable
        ``newton(guess (nv,), c (k,)) -> (q (nv,), loop violation (m), iterations, converged)``:
        the engine's own Newton projection.
    system_matrix : callable
        ``system_matrix(q) -> (n_loop + k, nv)``: the engine's loop Jacobian over the inputs' rows.
    n_loop : int
        Loop rows of that matrix.
    q0 : ndarray, shape (nv,)
        An assembled configuration at ``c0`` (k,).
    inputs : ndarray, shape (N, k)
        Input values (rad or m) in the order the mechanism moves through them.
    input_scale, coordinate_scale : ndarray, shapes (k,), (nv,)
        Factors making inputs and coordinates dimensionless (1 for angles, 1/size for lengths).
    period : float, optional
        2 pi where the one input is a crank's angle. Where two samples lie more than a
        turn apart (a crank accelerating through hundreds of turns), the walk goes one
        turn, checks that the engine's configuration repeats (every coordinate changed
        by whole turns, :data:`PERIODIC`), and then skips the remaining whole turns by
        that change, the engine's Newton closing the loops where it lands: the cost
        stays at most a turn per sample (fuzz s1-00419: 94 000 steps over 517 turns).
    budget : int, optional
        The most Newton calls from one sample to the next (None: no bound): where the
        engine's solver fails systematically, accepting only ever smaller steps, the
        walk stops there with its reason instead of creeping on.
    """
    n, nv = inputs.shape[0], q0.size
    qpos, residual = np.full((n, nv), np.nan), np.full(n, np.inf)
    iterations, steps = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    converged = np.zeros(n, dtype=bool)
    c = np.array(c0, dtype=float)
    q, loop, _, ok = newton(np.array(q0, dtype=float), c)  # the start, on the engine's own loops
    if not ok:
        return Walk(
            qpos, residual, iterations, steps, converged, 0, f"the start does not close the loops ({loop:.3g} m)"
        )
    matrix = system_matrix(q)
    rows = square_rows(matrix)
    k = matrix.shape[0] - n_loop
    sign = square_sign(matrix, rows)
    step = MAX_STEP
    taken, its, calls = 0, 0, 0

    def walk_to(target: np.ndarray) -> str:
        """Step from (c, q) to ``target``; "" when there, else why the walk stopped."""
        nonlocal q, c, matrix, sign, step, loop, taken, its, calls
        while True:
            distance = float(np.max(np.abs((target - c) * input_scale), initial=0.0))
            if distance == 0.0:
                return ""
            if budget is not None and calls >= budget:
                where = ", ".join(f"{v:.9g}" for v in c)
                return f"stopped at inputs ({where}): {calls} solves from the last sample did not reach the next"
            fraction = min(1.0, step / distance)
            c_next = target if fraction == 1.0 else c + (target - c) * fraction
            guess = q + tangent(matrix, n_loop) @ (c_next - c)
            q_new, violation, iterations_now, ok = newton(guess, c_next)
            calls += 1
            if ok:
                new_matrix = system_matrix(q_new)
                new_sign = square_sign(new_matrix, rows)
                why = step_refused(q, guess, q_new, sign, new_sign, coordinate_scale)
                ok = not why
            else:
                why = f"Newton does not converge (loop violation {violation:.3g} m)"
            if ok:
                q, c, matrix, sign = q_new, c_next, new_matrix, new_sign if new_sign != 0.0 else sign
                loop, its = violation, iterations_now
                taken += 1
                step = min(MAX_STEP, step * 1.5)
            else:
                step *= 0.5
                if step < MIN_STEP:
                    where = ", ".join(f"{v:.9g}" for v in c)
                    return f"stopped at inputs ({where}): {why}"

    turn: np.ndarray | None = None  # the change of q over one turn forward, once measured
    periodic = period is not None and k == 1
    for i, target in enumerate(inputs):
        taken, its, calls = 0, 0, 0
        ahead = float((target - c)[0]) if periodic else 0.0
        why = ""
        if period is not None and abs(ahead) > period:
            direction = math.copysign(1.0, ahead)
            if turn is None:  # walk one turn and see whether the engine's configuration repeats
                before = q.copy()
                why = walk_to(c + direction * period)
                change = (q - before) * direction
                off_turns = (change - period * np.round(change / period)) * coordinate_scale
                turn = change if float(np.max(np.abs(off_turns))) <= PERIODIC else np.zeros(0)
            if not why and turn.size:
                whole = math.floor(abs(float((target - c)[0])) / period)
                if whole:
                    jumped_c = c + direction * whole * period
                    q_new, violation, iterations_now, ok = newton(q + direction * whole * turn, jumped_c)
                    if not ok:
                        why = f"Newton does not close the loops {whole} turns on (loop violation {violation:.3g} m)"
                    else:
                        q, c, loop, its = q_new, jumped_c, violation, iterations_now
                        matrix = system_matrix(q)
        why = why or walk_to(target)
        if why:
            return Walk(qpos, residual, iterations, steps, converged, i, why)
        qpos[i], residual[i], steps[i], converged[i], iterations[i] = q, loop, taken, True, its
    return Walk(qpos, residual, iterations, steps, converged)
