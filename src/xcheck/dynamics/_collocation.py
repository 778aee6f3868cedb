"""Free motion by Gauss-Legendre collocation: the check of the DOP853 reference.

The same equations as :mod:`._adaptive` (the index-1 form in body coordinates,
accelerations by Gauss's principle, positions and velocities projected onto the
constraints after every step, by the same compiled kernels), discretised in time
independently of it: fixed steps of the implicit Runge-Kutta method of
:data:`STAGES` stages at the Gauss-Legendre points, the collocation method of
order 2 :data:`STAGES` (Hairer, Norsett and Wanner, *Solving Ordinary
Differential Equations I*, 2nd ed., Springer 1993, II.7), its stages' slopes
found by fixed-point iteration until they no longer change (the motions it checks
are not stiff at the steps it takes; a step whose iteration does not settle stops
the run). The outputs fall on the ends of steps.

A singular position is where Gauss's accelerations are ill-conditioned: near it
they move by a state's distance from the constraints over the Jacobian's smallest
singular value. The steps of an output's stretch are therefore arranged so that a
singular position found ahead (along the state's second-order Taylor path, as
DOP853 finds it) lies in the middle of the step that crosses it, the point of a
step farthest from its stages (0.17 of the step from the nearest), and the stages
of that step, and of every step that starts near a singular position (its measure
below ``SINGULAR_THRESHOLD``), are projected onto the constraints before their
accelerations are evaluated (a vector field that agrees with the equations on the
constraints: the method's order is unchanged). A collocation stage is off the
constraints only by the method's stage error, of order :data:`STAGES` + 1 in the
step, where an extrapolation method's substeps are off by their own second-order
error, whose projection near a singular position is ill-conditioned (see
docs/free-motion.md).
"""

from __future__ import annotations

import math
import time
from functools import lru_cache

import numpy as np
from numba import njit

from .._numba import run_compiled
from ._adaptive import _crossing_ahead, _rates
from ._free import PROJECTION_ITERATIONS, SINGULAR_THRESHOLD, HalvingSteps
from ._free_compiled import NO, _energy_of, _internal, _project

__all__ = ["STAGES", "CollocationLadder", "collocation_reference", "simulate_collocation", "tableau"]

#: the stages of the collocation (order 2 x STAGES); an even count, so that no stage lies
#: in the middle of a step, where a singular crossing is put
STAGES = 4
#: the most fixed-point iterations of a step's stages
ITERATIONS = 40
#: the change of a stage from one iteration to the next (a position's, of the size, and a
#: velocity's times the step) at which its iteration has settled; where it stops falling
#: above :data:`UNSETTLED`, or has not settled after :data:`ITERATIONS`, the step did not
#: converge. Near a singular position the accelerations' own round-off stops the changes
#: falling sooner (measured: at up to 3e-11 on IFToMM A02, 5e-10 on iftomm-a02-n40, whose
#: forty windows lose rank together), a noise that shows in the differences of the ladder.
SETTLED = 1e-15
UNSETTLED = 1e-6

# status codes of the compiled integration
OK, NON_FINITE, OVER_BUDGET, UNCONVERGED = 0, 1, 2, 3
_MESSAGES = {
    NON_FINITE: "the state went non-finite",
    OVER_BUDGET: "its work budget was spent",
    UNCONVERGED: "the collocation's fixed-point iteration did not converge",
}


@lru_cache(maxsize=None)
def tableau(stages: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Butcher tableau (A (s, s), c (s,), b (s,)) of the Gauss-Legendre collocation of
    ``stages`` stages: c the roots of the shifted Legendre polynomial, A and b the integrals of
    the Lagrange polynomials at c (HNW I, II.7)."""
    from numpy.polynomial import legendre, polynomial

    c = (legendre.legroots([0.0] * stages + [1.0]) + 1.0) / 2.0
    a, b = np.empty((stages, stages)), np.empty(stages)
    for j in range(stages):
        others = np.delete(c, j)
        integral = polynomial.polyint(polynomial.polyfromroots(others) / np.prod(c[j] - others))
        b[j] = polynomial.polyval(1.0, integral)
        a[:, j] = polynomial.polyval(c, integral)
    return a, np.ascontiguousarray(c), b


def work_per_step(iterations: float = 8.0) -> float:
    """Evaluations of the accelerations in one step: :data:`STAGES` per fixed-point iteration
    (about eight), one at its end and its projection's solves."""
    return STAGES * iterations + 1.0 + 1.0 + PROJECTION_ITERATIONS


def simulate_collocation(kinematics, start, duration: float, output_step: float, step: float, budget: float):
    """One run from ``start`` (:class:`._free.FreeState`) over ``duration`` (s) at steps of at
    most ``step`` (s; shortened to divide ``output_step``), outputs every ``output_step`` (s), within
    ``budget`` evaluations of the accelerations, as a :class:`._free.FreeMotion` (``failure`` where
    it stopped early, its outputs those reached)."""
    from ._free import FreeMotion, _Dynamics
    from ._free_compiled import Packed

    begin = time.process_time()
    per_output = max(1, math.ceil(output_step / step - 1e-9))
    h = output_step / per_output
    outputs = int(round(duration / output_step))
    packed = Packed(_Dynamics(kinematics))
    q, qd, qdd, residual, energy, work, passes, counts, status, reached = run_compiled(
        _integrate,
        packed.arrays(),
        packed.structure(),
        np.ascontiguousarray(start.q, dtype=float),
        np.ascontiguousarray(start.qd, dtype=float),
        h,
        int(per_output),
        int(outputs),
        float(output_step),
        float(budget),
        *tableau(STAGES),
    )
    failure = "" if status == OK else f"{_MESSAGES[int(status)]} after t = {(reached - 1) * output_step:.6g} s"
    return FreeMotion(
        kinematics,
        np.arange(reached) * output_step,
        q[:reached],
        qd[:reached],
        qdd[:reached],
        residual[:reached],
        energy[:reached],
        work[:reached],
        [float(t) for t in passes],
        h,
        time.process_time() - begin,
        method="Gauss",
        failure=failure,
        statistics={"steps": int(counts[1]), "evaluations": float(counts[0]), "crossings": int(counts[2])},
    )


class CollocationLadder(HalvingSteps):
    """Gauss-Legendre collocation (:func:`simulate_collocation`) at halving steps
    (:class:`._free.HalvingSteps`); its error falls 2^(2 x :data:`STAGES`) times a halving
    (its order)."""

    name = "Gauss"
    nominal: float | None = 2.0 ** (2 * STAGES)

    def run(self, setting: float, evaluations: float, start=None):
        start = self.start if start is None else start
        return simulate_collocation(self.kinematics, start, self.duration, self.output_step, setting, evaluations)

    def work(self, setting: float, previous) -> float:
        """Evaluations: twice the last run's (twice the steps), or before any,
        :func:`work_per_step` for each step."""
        if previous is not None and "evaluations" in previous.statistics:
            return 2.0 * float(previous.statistics["evaluations"])
        per_output = max(1, math.ceil(self.output_step / setting - 1e-9))
        return work_per_step() * per_output * round(self.duration / self.output_step)

    def describe(self) -> str:
        return (
            f"Gauss-Legendre collocation ({STAGES} stages, order {2 * STAGES}, the stages by fixed-point "
            "iteration) at a fixed step on the index-1 equations, positions and velocities projected onto the "
            f"constraints after every step; steps halved from {self.first:.4g} s, at most {self.halvings + 1} runs"
        )


def collocation_reference(kinematics, start, duration: float, output_step: float, tolerance: float, progress=None):
    """The collocation's ladder (judged by :func:`._reference.run_ladder`) over ``duration`` (s)
    with outputs every ``output_step`` (s): steps halved from the output step, at most half the
    motion's shortest time scale (:func:`._reference.time_scale`) and a hundredth of the duration,
    at most seven runs."""
    from ._reference import run_ladder, time_scale

    first = min(output_step, 0.5 * time_scale(kinematics, start)[0], duration / 100.0)
    method = CollocationLadder(kinematics, start, duration, output_step, first, 6)
    return run_ladder(kinematics, method, tolerance, progress=progress)


# -- the compiled parts -----------------------------------------------------------


@_internal
def _step(model, structure, scratch, buffers, measure, y, t, h, A, c, b, project, start, K, stage, f, counts):
    """One collocation step of ``h`` (s) from (t, y), ``start`` dy/dt there: the stages' slopes
    ``K`` by fixed-point iteration (from ``start``), the new state into ``stage``. Whether the
    iteration settled (see :data:`SETTLED`); its evaluations are added to ``counts[0]``."""
    s, n = len(c), (len(y) - 1) // 2
    d = model[21]
    for i in range(s):
        K[i] = start
    last = math.inf
    settled = False
    for _ in range(ITERATIONS):
        change = 0.0
        for i in range(s):
            stage[:] = y
            for j in range(s):
                stage += (h * A[i, j]) * K[j]
            _rates(model, structure, scratch, buffers, measure, stage, t + c[i] * h, f, project)
            for k in range(n):  # a position's change, and a velocity's over the step, of the size
                change = max(change, abs(h * (f[k] - K[i, k])) * d[k], abs(h * h * (f[n + k] - K[i, n + k])) * d[k])
            K[i] = f
        counts[0] += s
        if change <= SETTLED:
            settled = True
            break
        if not change < last:  # no longer falling: round-off, or diverging
            settled = change <= UNSETTLED
            break
        last = change
    stage[:] = y
    for i in range(s):
        stage += (h * b[i]) * K[i]
    return settled


@_internal
def _split(length, at):
    """Where to split a stretch of ``length`` (s) so that a singular position ``at`` (s) into it
    lies in the middle of the step that crosses it, that step as long as may be: (the split,
    s, ``length`` for none; whether the crossing step is the first)."""
    if at <= 0.5 * length:
        return min(2.0 * at, length), True
    return max(length - 2.0 * (length - at), 0.0), False


@njit(cache=True)
def _integrate(model, structure, q0, qd0, h, per_output, outputs, output_step, budget, A, c, b):
    n, rows = len(q0), len(model[20])
    dim = 2 * n + 1
    buffers = (np.zeros((n, n)), np.zeros((rows, n)), np.empty(rows), np.empty(rows), np.empty(n))
    side = rows if structure[5][0] > 0 else 0
    scratch = (np.zeros((side, side)), np.empty((side, side)))
    q_out, qd_out, qdd_out = np.empty((outputs + 1, n)), np.empty((outputs + 1, n)), np.empty((outputs + 1, n))
    residual, energy, work = np.zeros(outputs + 1), np.empty(outputs + 1), np.zeros(outputs + 1)
    counts = np.zeros(3)  # evaluations, steps, planned crossings
    found, count = np.empty(16), 0
    y, start, f, stage = np.zeros(dim), np.empty(dim), np.empty(dim), np.empty(dim)
    K = np.empty((len(c), dim))
    dense = np.zeros((1, dim))  # (_crossing_ahead follows the Taylor path, not a dense output)
    edges = np.empty(per_output + 2)

    q, qd, _, measure = _project(model, structure, scratch, buffers, q0.copy(), qd0.copy())
    y[:n], y[n : 2 * n] = q, qd
    q_out[0], qd_out[0] = q, qd
    qdd = _rates(model, structure, scratch, buffers, measure, y, 0.0, start, NO)
    qdd_out[0], energy[0] = qdd, _energy_of(model, q, qd)
    counts[0] += 2 + PROJECTION_ITERATIONS
    for i in range(1, outputs + 1):
        begin = (i - 1) * output_step
        # the steps of this output's stretch: h each, but where a singular position lies ahead, the
        # step across it and its nearer neighbour within the stretch split anew (:func:`_split`)
        for j in range(per_output + 1):
            edges[j] = j * h
        steps, crossing = per_output, -1
        ahead, measures = _crossing_ahead(model, structure, scratch, buffers, q, qd, qdd, output_step, dense, y)
        counts[0] += 3 * measures
        if ahead < output_step:
            counts[2] += 1
            if count == len(found):
                found = np.concatenate((found, np.empty(len(found))))
            found[count] = begin + ahead
            count += 1
            j = min(int(ahead / h), per_output - 1)
            low, high = j, j + 1
            if ahead - j * h < 0.5 * h and j > 0:
                low = j - 1
            elif ahead - j * h >= 0.5 * h and j < per_output - 1:
                high = j + 2
            split, first = _split((high - low) * h, ahead - low * h)
            if split <= 0.0 or split >= (high - low) * h:  # one step across it
                for k in range(high, per_output + 1):
                    edges[k - (high - low - 1)] = k * h
                steps, crossing = per_output - (high - low - 1), low
            else:
                for k in range(high, per_output + 1):
                    edges[k - (high - low - 2)] = k * h
                edges[low + 1] = low * h + split
                steps, crossing = per_output - (high - low - 2), low if first else low + 1
        drift = 0.0
        for j in range(steps):
            if counts[0] >= budget:
                return q_out, qd_out, qdd_out, residual, energy, work, found[:count], counts, OVER_BUDGET, i
            t = begin + edges[j]
            step = (i * output_step if j == steps - 1 else begin + edges[j + 1]) - t
            near = j == crossing or measure < SINGULAR_THRESHOLD
            settled = _step(model, structure, scratch, buffers, measure, y, t, step, A, c, b, near, start, K,
                            stage, f, counts)  # fmt: skip
            if not settled:
                return q_out, qd_out, qdd_out, residual, energy, work, found[:count], counts, UNCONVERGED, i
            q, qd, before, measure = _project(
                model, structure, scratch, buffers, stage[:n].copy(), stage[n : 2 * n].copy()
            )
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
                return q_out, qd_out, qdd_out, residual, energy, work, found[:count], counts, NON_FINITE, i
            y[:n], y[n : 2 * n], y[2 * n] = q, qd, stage[2 * n]
            drift = max(drift, before)
            qdd = _rates(model, structure, scratch, buffers, measure, y, t + step, start, NO)
            counts[0] += 2 + PROJECTION_ITERATIONS
            counts[1] += 1
        q_out[i], qd_out[i], qdd_out[i] = q, qd, qdd
        residual[i], energy[i], work[i] = drift, _energy_of(model, q, qd), y[2 * n]
    return q_out, qd_out, qdd_out, residual, energy, work, found[:count], counts, OK, outputs + 1
