"""Free motion by DOP853 with error control: the second native method.

The same equations as :mod:`._free`'s RK4 (the index-1 form in body coordinates,
accelerations by Gauss's principle, positions and velocities projected onto the
constraints after every step, by the same compiled kernels), discretised in time
independently of it: DOP853, Dormand and Prince's explicit Runge-Kutta pair of
order 8 (with estimates of orders 5 and 3) whose steps follow the motion under
a local error tolerance, and whose dense output of order 7 gives the outputs
(Hairer, Norsett and Wanner, *Solving Ordinary Differential Equations I*, 2nd
ed., Springer 1993, II.5, II.6 and II.10; the coefficients are scipy's). Each
output is projected as a step's end is.

The local error is measured in the dimensionless units of the error estimate:
positions against ``tolerance`` x size (angles against ``tolerance`` rad),
velocities against ``tolerance`` x the largest speed of the moment (so a body
that should not turn, whose rate is round-off, does not set the step).

A singular position is where Gauss's accelerations are ill-conditioned: a stage
that lands close to it returns an acceleration whose error grows as the inverse
cube of the distance (measured on the IFToMM double four-bar: 1e-9 at 0.01 rad,
1e-6 at 0.001 rad), so an error control that halves its step there only lands
closer. So a crossing is planned: where the singularity measure, followed along
the state's second-order Taylor path, falls below the threshold within the next
step and a half, the steps are cut so that it lies :data:`CROSSING_AT` of the way
through a step of the length the control proposes, the point of a step farthest
from every stage of DOP853 and of its dense output (0.13 of the step away). That
step is accepted at an error norm up to :data:`CROSSING_ALLOWANCE`, since a
shorter one would only be worse; its error, like every other, shows in the
differences of the reference's ladder. Its stages are projected onto the
constraints before their accelerations are evaluated: a stage is off them by
its own truncation error, and near a singular position the accelerations move
by that error over the Jacobian's smallest singular value (measured on A02 at
1e-3 s from a pass: a state 1e-13 m off moves them by 2.3e-10 m/s^2), where on
the constraints they are accurate to round-off.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.integrate._ivp import dop853_coefficients as _dop853

from .._numba import run_compiled
from ._free import (
    BANDED_LEAST_SQUARES_BELOW,
    LEAST_SQUARES_BELOW,
    PROJECTION_CUTOFF,
    PROJECTION_ITERATIONS,
    SINGULAR_THRESHOLD,
)
from ._free_compiled import (
    NO,
    YES,
    _acceleration,
    _banded_measure,
    _energy_of,
    _internal,
    _jacobian_of,
    _mass_of,
    _power_of,
    _project,
    _solve,
)

__all__ = ["AdaptiveRun", "integrate_adaptive", "simulate_adaptive", "CROSSING_AT", "CROSSING_ALLOWANCE"]

#: where in a step a planned singular crossing lies: the fraction of the step farthest
#: from every node of DOP853 and of its dense output (0.133 of the step away)
CROSSING_AT = 0.4667
#: the error norm up to which a step planned across a singular position is accepted: its
#: error estimate there measures the ill-conditioned accelerations of the stages nearest the
#: singular position more than the step's truncation error (measured on iftomm-a02-n40 at the
#: local tolerance 1e-14: norms of 1.5e6 and, once shortened, 1.4e7, the shorter steps' rejected
#: in turn until the run stalled; accepted, the run's true error is 2.5e-10 of the size)
CROSSING_ALLOWANCE = 1e9
#: golden-section steps locating a singular pass within its step (0.618^30: 5e-7 of it)
PASS_SEARCH = 30
#: the work of a singularity measure (and of a projection's solve, which measures too), in
#: evaluations of the accelerations (measured: 2.3 on iftomm-a02-n40's banded path, 1.5 on A02)
MEASURE_COST = 3.0

# status codes of the compiled integration
OK, NON_FINITE, OVER_BUDGET, STEP_UNDERFLOW = 0, 1, 2, 3
_MESSAGES = {
    NON_FINITE: "the state went non-finite",
    OVER_BUDGET: "its work budget was spent",
    STEP_UNDERFLOW: "the step fell below 1e-12 of the duration",
}

_TABLEAU = tuple(np.ascontiguousarray(a) for a in (_dop853.A, _dop853.B, _dop853.C, _dop853.E3, _dop853.E5, _dop853.D))
_STAGES = _dop853.N_STAGES  # 12; K's row 12 is f at the step's end; rows 13-15 the dense output's stages
_EXTENDED = _dop853.N_STAGES_EXTENDED
_POWER = _dop853.INTERPOLATOR_POWER


@dataclass
class AdaptiveRun:
    """The raw outputs of :func:`integrate_adaptive` (SI units).

    Attributes
    ----------
    q, qd, qdd : ndarray, shape (N, n)
    residual : ndarray, shape (N,)
        The largest loop-closure violation before the projection of the output, m.
    energy, work : ndarray, shape (N,)
        T + V (J) and the work of the loads and dampers since t = 0 (J).
    passes : list of float
        Times of singular passes, s.
    accepted, rejected, evaluations, crossings : int
        Steps accepted and rejected, accelerations evaluated, steps planned across
        a singular position.
    cost : int
        The run's work in evaluations of the accelerations (see :func:`integrate_adaptive`).
    failure : str
        "" or why the run stopped, with the time; N is then the outputs reached.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    residual: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    passes: list[float]
    accepted: int
    rejected: int
    evaluations: int
    crossings: int
    cost: int
    failure: str


def integrate_adaptive(
    packed,
    q0: np.ndarray,
    qd0: np.ndarray,
    outputs: int,
    output_step: float,
    tolerance: float,
    budget: int,
    trace: np.ndarray | None = None,
) -> AdaptiveRun:
    """Integrate from (q0, qd0) (projected first) to ``outputs`` x ``output_step`` (s) at the
    local ``tolerance`` (dimensionless) within a work of ``budget`` evaluations of the
    accelerations, in which every solve counts at its cost: a plain evaluation 1, a
    projection a solve for each of its Newton iterations and one for the velocities, a
    singularity measure 3, and a solve through a dense least-squares fallback (near a
    singular position) :func:`_least_squares_cost` (all measured: see docs/benchmarks.md).

    ``packed`` is :class:`._free_compiled.Packed`. ``trace`` (K, 4), if given, gets each
    attempted step's start (s), length (s), error norm and the singularity measure there.
    """
    trace = np.zeros((0, 4)) if trace is None else trace
    result = run_compiled(
        _integrate,
        packed.arrays(),
        packed.structure(),
        np.ascontiguousarray(q0, dtype=float),
        np.ascontiguousarray(qd0, dtype=float),
        int(outputs),
        float(output_step),
        float(tolerance),
        int(budget),
        _TABLEAU,
        trace,
    )
    q, qd, qdd, residual, energy, work, passes, counts, status, reached, when = result
    failure = "" if status == OK else f"{_MESSAGES[int(status)]} at t = {when:.6g} s"
    return AdaptiveRun(
        q[:reached],
        qd[:reached],
        qdd[:reached],
        residual[:reached],
        energy[:reached],
        work[:reached],
        [float(t) for t in passes],
        int(counts[0]),
        int(counts[1]),
        int(counts[2]),
        int(counts[3]),
        int(counts[4]),
        failure,
    )


def simulate_adaptive(kinematics, start, duration: float, output_step: float, tolerance: float, budget: int):
    """One run of this method from ``start`` (:class:`._free.FreeState`) over ``duration`` (s),
    outputs every ``output_step`` (s), at the local ``tolerance``, as a :class:`._free.FreeMotion`
    (``step`` the mean step; ``failure`` where it stopped early, its outputs those reached)."""
    from ._free import FreeMotion, _Dynamics
    from ._free_compiled import Packed

    begin = time.process_time()
    dyn = _Dynamics(kinematics)
    outputs = int(round(duration / output_step))
    run = integrate_adaptive(Packed(dyn), start.q, start.qd, outputs, output_step, tolerance, budget)
    return FreeMotion(
        kinematics,
        np.arange(len(run.q)) * output_step,
        run.q,
        run.qd,
        run.qdd,
        run.residual,
        run.energy,
        run.work,
        run.passes,
        duration / max(run.accepted, 1),
        time.process_time() - begin,
        method="DOP853",
        failure=run.failure,
        statistics={
            "tolerance": tolerance,
            "steps": run.accepted,
            "rejected": run.rejected,
            "evaluations": run.evaluations,
            "crossings": run.crossings,
            "cost": run.cost,
        },
    )


# -- the compiled parts -----------------------------------------------------------


@_internal
def _stage(A, s, h, y, K, out):
    """The state at stage ``s`` of the step: y + h sum_j A[s, j] K[j], into ``out``."""
    out[:] = y
    for j in range(s):
        if A[s, j] != 0.0:
            out += (h * A[s, j]) * K[j]


@_internal
def _rates(model, structure, scratch, buffers, measure, y, t, out, project):
    """dy/dt of y = (q, qd, work) at time t (s) into ``out``; q'' returned. With ``project``,
    of y's (q, qd) projected onto the constraints first (a stage near a singular position)."""
    n = (len(y) - 1) // 2
    q, qd = y[:n], y[n : 2 * n]
    if project:
        q, qd, _, _ = _project(model, structure, scratch, buffers, q.copy(), qd.copy())
    qdd = _acceleration(model, structure, scratch, buffers, measure, q, qd, t)
    out[:n] = qd
    out[n : 2 * n] = qdd
    out[2 * n] = _power_of(model, q, qd, t)
    return qdd


@_internal
def _error_norm(K, h, E3, E5, y0, y1, d, tolerance, floor):
    """DOP853's error norm of the step (scipy's), positions against ``tolerance`` (scaled by
    ``d``), velocities against ``tolerance`` x the largest scaled speed (at least ``floor``)."""
    n = len(d)
    speed = floor
    for i in range(n):
        speed = max(speed, abs(y0[n + i]) * d[i], abs(y1[n + i]) * d[i])
    err5, err3 = 0.0, 0.0
    for i in range(2 * n):
        e5, e3 = 0.0, 0.0
        for s in range(len(E5)):
            e5 += K[s, i] * E5[s]
            e3 += K[s, i] * E3[s]
        scale = tolerance / d[i] if i < n else tolerance * speed / d[i - n]
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * 2 * n)


@_internal
def _dense(A, C, D, model, structure, scratch, buffers, measure, t, h, y, y_new, K, F, project):
    """The dense output's coefficients of the step (its three extra stages first) into ``F``."""
    stage = np.empty(len(y))
    for s in range(_STAGES + 1, _EXTENDED):
        _stage(A, s, h, y, K, stage)
        _rates(model, structure, scratch, buffers, measure, stage, t + C[s] * h, K[s], project)
    delta = y_new - y
    F[0] = delta
    F[1] = h * K[0] - delta
    F[2] = 2.0 * delta - h * (K[_STAGES] + K[0])
    for r in range(_POWER - 3):
        F[3 + r] = 0.0
        for s in range(_EXTENDED):
            F[3 + r] += (h * D[r, s]) * K[s]


@_internal
def _dense_at(F, y_old, x):
    """The dense output at x in [0, 1] of the step (scipy's Dop853DenseOutput)."""
    y = np.zeros(len(y_old))
    for i in range(len(F)):
        y += F[len(F) - 1 - i]
        if i % 2 == 0:
            y *= x
        else:
            y *= 1.0 - x
    return y + y_old


@_internal
def _measure(model, structure, scratch, buffers, q):
    """The singularity measure of the constraint Jacobian at q (``_Dynamics.project``'s; on the
    banded path without its least-squares fallback, a dense SVD, where the factor fails)."""
    m_buf, j_buf = buffers[0], buffers[1]
    _mass_of(model, q, m_buf)
    _jacobian_of(model, q, j_buf)
    if structure[5][0] > 0:
        return _banded_measure(m_buf, j_buf, model[20], model[21], model[22], structure, scratch)
    return _solve(
        m_buf, j_buf, np.zeros(len(q)), np.zeros(j_buf.shape[0]), YES, PROJECTION_CUTOFF, 0.0, model[20],
        model[21], model[22], structure, scratch,
    )[1]  # fmt: skip


@_internal
def _measure_at(model, structure, scratch, buffers, along_dense, x, q, qd, qdd, F, y):
    """The measure at ``x`` along the Taylor path q + x qd + x^2 qdd / 2 (x in s), or
    along the step's dense output F from y (``along_dense``, x in [0, 1])."""
    if along_dense:
        point = _dense_at(F, y, x)[: len(q)]
    else:
        point = q + x * qd + (0.5 * x * x) * qdd
    return _measure(model, structure, scratch, buffers, point)


@_internal
def _least(model, structure, scratch, buffers, along_dense, high, q, qd, qdd, F, y):
    """(x, measure) of the least measure on [0, high] along the path of :func:`_measure_at`,
    by golden-section search (the measure is unimodal there: a V at a crossing)."""
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    low = 0.0
    a, b = low + (1.0 - ratio) * (high - low), low + ratio * (high - low)
    fa = _measure_at(model, structure, scratch, buffers, along_dense, a, q, qd, qdd, F, y)
    fb = _measure_at(model, structure, scratch, buffers, along_dense, b, q, qd, qdd, F, y)
    for _ in range(PASS_SEARCH):
        if fa <= fb:
            high, b, fb = b, a, fa
            a = low + (1.0 - ratio) * (high - low)
            fa = _measure_at(model, structure, scratch, buffers, along_dense, a, q, qd, qdd, F, y)
        else:
            low, a, fa = a, b, fb
            b = low + ratio * (high - low)
            fb = _measure_at(model, structure, scratch, buffers, along_dense, b, q, qd, qdd, F, y)
    return (a, fa) if fa <= fb else (b, fb)


@_internal
def _crossing_ahead(model, structure, scratch, buffers, q, qd, qdd, reach, F, y):
    """Where, within ``reach`` (s), the state's second-order Taylor path passes closest to a
    singular position: (the time ahead (s), or inf where the measure does not fall there or
    stays above the threshold; the measures taken)."""
    sigma = _measure(model, structure, scratch, buffers, q)
    small = 1e-4 * reach
    slope = (_measure_at(model, structure, scratch, buffers, NO, small, q, qd, qdd, F, y) - sigma) / small
    if not (slope < 0.0 and sigma < -2.0 * slope * reach):  # rising, or out of reach at its present rate
        return math.inf, 2
    where, least = _least(model, structure, scratch, buffers, NO, reach, q, qd, qdd, F, y)
    if least >= SINGULAR_THRESHOLD or where >= 0.999 * reach:
        return math.inf, 4 + PASS_SEARCH
    return where, 4 + PASS_SEARCH


@_internal
def _least_squares_cost(rows, n):
    """The work of a solve through the dense least-squares fallback (an SVD of the rows x rows
    J M^-1 J^T), in evaluations of the accelerations: 3 + rows^3 / (200 (30 + n)) (measured:
    2.9 on A02, 14 rows of 15 coordinates; 243 on iftomm-a02-n40, 242 rows of 243)."""
    return 3.0 + rows**3 / (200.0 * (30.0 + n))


@_internal
def _solve_cost(measure, below, heavy):
    """The work of a solve after a measure of ``measure``: 1 (a plain solve), or ``heavy``
    (the least-squares fallback) at or below ``below`` (NaN too)."""
    return 1.0 if measure > below else heavy


@_internal
def _stage_cost(measure, below, heavy, projected, projection):
    """The work of a stage's evaluation (:func:`_solve_cost`), and of its projection where
    ``projected`` (``projection`` solves, each measuring)."""
    solve = _solve_cost(measure, below, heavy)
    return solve + projection * max(MEASURE_COST, solve) if projected else solve


@_internal
def _plan(h, ahead):
    """The next step, ``h`` as the error control proposes it, cut where a singular position
    lies ``ahead`` (s): so that it lies CROSSING_AT of the way through a step of about ``h``
    (a shorter step first where it lies beyond that). (step, whether it crosses)."""
    if not ahead < (1.0 + CROSSING_AT) * h:
        return h, False
    if ahead <= 1.02 * CROSSING_AT * h:  # (a step 2 % longer rather than a sliver first)
        return ahead / CROSSING_AT, True
    return ahead - CROSSING_AT * h, False


@njit(cache=True)
def _integrate(model, structure, q0, qd0, outputs, output_step, tolerance, budget, tableau, trace):
    A, B, C, E3, E5, D = tableau
    n, rows = len(q0), len(model[20])
    d = model[21]
    dim = 2 * n + 1
    duration = outputs * output_step
    floor = 1.0 / duration  # the smallest speed (1/s) the velocities' error is measured against
    buffers = (np.zeros((n, n)), np.zeros((rows, n)), np.empty(rows), np.empty(rows), np.empty(n))
    side = rows if structure[5][0] > 0 else 0
    scratch = (np.zeros((side, side)), np.empty((side, side)))
    q_out, qd_out, qdd_out = np.empty((outputs + 1, n)), np.empty((outputs + 1, n)), np.empty((outputs + 1, n))
    residual, energy, work = np.zeros(outputs + 1), np.empty(outputs + 1), np.zeros(outputs + 1)
    counts = np.zeros(5)  # accepted, rejected, evaluations, planned crossings, work (see integrate_adaptive)
    heavy = _least_squares_cost(rows, n)
    below = BANDED_LEAST_SQUARES_BELOW if structure[5][0] > 0 else LEAST_SQUARES_BELOW
    projection = 1 + PROJECTION_ITERATIONS  # the most solves a projection takes
    found, passes = np.empty(16), 0
    K = np.zeros((_EXTENDED, dim))
    F = np.zeros((_POWER, dim))
    y, y_new, stage = np.zeros(dim), np.empty(dim), np.empty(dim)

    q, qd, _, measure = _project(model, structure, scratch, buffers, q0.copy(), qd0.copy())
    y[:n], y[n : 2 * n] = q, qd
    qdd = _rates(model, structure, scratch, buffers, measure, y, 0.0, K[0], NO)
    counts[2] += 1
    counts[4] += projection * max(MEASURE_COST, _solve_cost(measure, below, heavy)) + _solve_cost(measure, below, heavy)
    if not np.all(np.isfinite(K[0])):
        return q_out, qd_out, qdd_out, residual, energy, work, found[:0], counts, NON_FINITE, 0, 0.0
    q_out[0], qd_out[0], qdd_out[0], energy[0] = q, qd, qdd, _energy_of(model, q, qd)
    written = 1

    # the first step: scipy's select_initial_step, in the error's units
    speed = floor
    for i in range(n):
        speed = max(speed, abs(qd[i]) * d[i])
    d0, d1 = 0.0, 0.0
    for i in range(n):
        d0 += (y[i] * d[i] / tolerance) ** 2 + (y[n + i] * d[i] / (tolerance * speed)) ** 2
        d1 += (K[0, i] * d[i] / tolerance) ** 2 + (K[0, n + i] * d[i] / (tolerance * speed)) ** 2
    d0, d1 = math.sqrt(d0 / (2 * n)), math.sqrt(d1 / (2 * n))
    h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h = min(h, duration)
    stage[:] = y + h * K[0]
    _rates(model, structure, scratch, buffers, measure, stage, h, K[1], NO)
    counts[2] += 1
    counts[4] += _solve_cost(measure, below, heavy)
    d2 = 0.0
    for i in range(n):
        d2 += ((K[1, i] - K[0, i]) * d[i] / tolerance) ** 2
        d2 += ((K[1, n + i] - K[0, n + i]) * d[i] / (tolerance * speed)) ** 2
    d2 = math.sqrt(d2 / (2 * n)) / h
    if not math.isfinite(d2):
        h = min(h, 1e-3 * duration)
    else:
        h1 = max(1e-6, h * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        h = min(100.0 * h, h1, duration)
    # the next planned crossing of a singular position (s; inf: none), and the steps tried across it
    planned, measures = _crossing_ahead(model, structure, scratch, buffers, q, qd, qdd, 1.5 * h, F, y)
    counts[4] += measures * MEASURE_COST
    proposed = h  # the error control's step, before a plan cut it
    h, crossing = _plan(h, planned)
    worst = 0.0  # the largest error norm of a step accepted across a singular position

    t = 0.0
    rejected_last = False
    while t < duration:
        if counts[4] >= budget:
            return q_out, qd_out, qdd_out, residual, energy, work, found[:passes], counts, OVER_BUDGET, written, t
        if h < 1e-12 * duration:
            return q_out, qd_out, qdd_out, residual, energy, work, found[:passes], counts, STEP_UNDERFLOW, written, t
        last = t + h >= duration * (1.0 - 1e-14)
        if last:
            h = duration - t
        for s in range(1, _STAGES):
            _stage(A, s, h, y, K, stage)
            _rates(model, structure, scratch, buffers, measure, stage, t + C[s] * h, K[s], crossing)
        y_new[:] = y
        for j in range(_STAGES):
            y_new += (h * B[j]) * K[j]
        _rates(model, structure, scratch, buffers, measure, y_new, t + h, K[_STAGES], crossing)
        counts[2] += _STAGES
        counts[4] += _STAGES * _stage_cost(measure, below, heavy, crossing, projection)
        error = _error_norm(K, h, E3, E5, y, y_new, d, tolerance, floor)
        attempt = int(counts[0] + counts[1])
        if attempt < len(trace):
            trace[attempt, 0], trace[attempt, 1], trace[attempt, 2], trace[attempt, 3] = t, h, error, measure
        # a shorter step across a singular position would only land its stages closer to it
        if not error <= (CROSSING_ALLOWANCE if crossing else 1.0):  # NaN too
            counts[1] += 1
            proposed = h * (max(0.2, 0.9 * error ** (-1.0 / 8.0)) if math.isfinite(error) else 0.25)
            h, crossing = _plan(proposed, planned - t)
            rejected_last = True
            continue
        counts[0] += 1
        if crossing:
            counts[3] += 1
            worst = max(worst, error)
        t_new = duration if last else t + h
        # the outputs in (t, t_new], from the dense output, each projected; a crossing's least measure
        if crossing or (written <= outputs and written * output_step < t_new - 1e-12 * duration):
            _dense(A, C, D, model, structure, scratch, buffers, measure, t, h, y, y_new, K, F, crossing)
            counts[2] += 3
            counts[4] += 3 * _stage_cost(measure, below, heavy, crossing, projection)
        while written <= outputs and written * output_step <= t_new + 1e-12 * duration:
            target = written * output_step
            if written == outputs or abs(target - t_new) <= 1e-12 * duration:
                state = y_new.copy()
            else:
                state = _dense_at(F, y, (target - t) / h)
            qo, qdo, before, _ = _project(model, structure, scratch, buffers, state[:n].copy(), state[n : 2 * n].copy())
            q_out[written], qd_out[written] = qo, qdo
            qdd_out[written] = _acceleration(model, structure, scratch, buffers, measure, qo, qdo, target)
            residual[written], energy[written], work[written] = before, _energy_of(model, qo, qdo), state[2 * n]
            counts[2] += 1
            counts[4] += projection * max(MEASURE_COST, _solve_cost(measure, below, heavy))
            counts[4] += _solve_cost(measure, below, heavy)
            written += 1
        if crossing:
            where, least = _least(model, structure, scratch, buffers, YES, 1.0, q, qd, qdd, F, y)
            counts[4] += (2 + PASS_SEARCH) * MEASURE_COST
            if least < SINGULAR_THRESHOLD:
                if passes == len(found):
                    found = np.concatenate((found, np.empty(len(found))))
                found[passes] = t + where * h
                passes += 1
        # accept: the end, projected, starts the next step
        q, qd, _, measure = _project(model, structure, scratch, buffers, y_new[:n].copy(), y_new[n : 2 * n].copy())
        counts[4] += projection * max(MEASURE_COST, _solve_cost(measure, below, heavy))
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
            return q_out, qd_out, qdd_out, residual, energy, work, found[:passes], counts, NON_FINITE, written, t
        t = t_new
        y[:n], y[n : 2 * n], y[2 * n] = q, qd, y_new[2 * n]
        qdd = _rates(model, structure, scratch, buffers, measure, y, t, K[0], NO)
        counts[2] += 1
        counts[4] += _solve_cost(measure, below, heavy)
        # the next step: the error control's, or where a plan cut this one (to land a crossing
        # well inside a step), the one it proposed before
        factor = 10.0 if error == 0.0 else min(10.0, 0.9 * error ** (-1.0 / 8.0))
        if rejected_last:
            factor = min(1.0, factor)
        rejected_last = False
        proposed = proposed if h < proposed * (1.0 - 1e-12) or crossing else h * factor
        if crossing or planned <= t:
            planned = math.inf
        if planned == math.inf:
            ahead, measures = _crossing_ahead(model, structure, scratch, buffers, q, qd, qdd, 1.5 * proposed, F, y)
            planned = t + ahead
            counts[4] += measures * MEASURE_COST
        h, crossing = _plan(proposed, planned - t)
    return q_out, qd_out, qdd_out, residual, energy, work, found[:passes], counts, OK, written, t
