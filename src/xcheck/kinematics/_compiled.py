"""The sweep of :meth:`Kinematics.solve`, compiled with numba.

The same equations, the same Newton rounds and the same checks as the NumPy
implementation in :mod:`._solve` and :mod:`._newton` (which stays the readable
reference and is tested against this one sample by sample), but one sample at
a time with O(n^2) scratch instead of whole-batch (N, n, n) arrays: memory
stays flat whatever the number of samples, and the Jacobian at the solution is
factorised once (LU with partial pivoting) for the determinant's sign, the
inverse (condition number, velocities, accelerations).

Newton runs in rounds over all samples, as the batched reference does: a
sample that has stopped improving keeps iterating while any other sample
still improves, so every sample takes the reference's iterations (up to a
step more or less where its residual sits at the round-off floor, since the
two LU factorisations round differently).

Constraint terms (rows in the system's order): point coincidences (2 rows,
metres), projections (1 row, metres), relative angles (1 row, radians); body
index -1 is the ground.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["Packed", "predict_atlas", "newton_rounds", "check_and_finish", "finish"]

KIND_COINCIDENCE = 0
KIND_PROJECTION = 1
KIND_ANGLE = 2

#: Status codes (the values of :class:`._solve.Status`).
_OK, _NEAR_SINGULAR, _SINGULAR, _NOT_CONVERGED, _BRANCH_JUMP = 0, 1, 2, 3, 4


class Packed:
    """A :class:`ConstraintSystem`'s terms as flat arrays (SI units)."""

    def __init__(self, system) -> None:
        from ._system import _Coincidence, _Projection

        m = len(system.terms)
        self.kind = np.empty(m, dtype=np.int64)
        self.a = np.empty(m, dtype=np.int64)
        self.b = np.empty(m, dtype=np.int64)
        self.s1 = np.zeros((m, 2))
        self.s2 = np.zeros((m, 2))
        self.w = np.zeros((m, 2))
        self.offset = np.zeros(m)
        self.driver = np.full(m, -1, dtype=np.int64)
        self.row = np.asarray(system._offsets[:m], dtype=np.int64)
        for t, term in enumerate(system.terms):
            self.a[t], self.b[t] = term.a, term.b
            if term.driver is not None:
                self.driver[t] = term.driver
            if isinstance(term, _Coincidence):
                self.kind[t] = KIND_COINCIDENCE
                self.s1[t], self.s2[t] = term.s_a, term.s_b
            elif isinstance(term, _Projection):
                self.kind[t] = KIND_PROJECTION
                self.s1[t], self.s2[t], self.w[t] = term.s_q, term.s_p, term.w
            else:
                self.kind[t] = KIND_ANGLE
                self.offset[t] = term.offset
        self.n = system.n
        self.size = float(system.size)
        #: residual_metres' factor per row: size for angle rows, 1 otherwise
        self.metres = np.where(system.row_is_angle, system.size, 1.0).astype(float)
        #: scaled_jacobian's factor per entry, (rows, n)
        rows = np.where(system.row_is_angle, 1.0, 1.0 / system.size)
        self.row_scale = rows.astype(float)
        self.coordinate_scale = system.coordinate_scale()
        self.jacobian_scale = np.ascontiguousarray(rows[:, None] / self.coordinate_scale[None, :])

    def terms(self) -> tuple:
        """The term arrays in the kernels' argument order."""
        return (self.kind, self.a, self.b, self.s1, self.s2, self.w, self.offset, self.driver, self.row)


# -- the constraint equations at one sample ---------------------------------------


def _new_pose(n):
    """Scratch for :func:`_pose`: (bodies + 1, 5), the last row the ground's."""
    pose = np.zeros((n // 3 + 1, 5))
    pose[-1, 3] = 1.0
    return pose


_new_pose = njit(cache=True)(_new_pose)


@njit(cache=True)
def _pose(q, pose):
    """x, y, phi, cos phi, sin phi of every body of q into the rows of pose
    (the last row, index -1, stays the ground's: zeros, cos 1)."""
    for body in range(pose.shape[0] - 1):
        phi = q[3 * body + 2]
        pose[body, 0] = q[3 * body]
        pose[body, 1] = q[3 * body + 1]
        pose[body, 2] = phi
        pose[body, 3] = math.cos(phi)
        pose[body, 4] = math.sin(phi)


@njit(cache=True, inline="always")
def _turn(c, s, v0, v1):
    """A(phi) v from cos phi, sin phi (the ground's 1, 0 give v itself)."""
    return c * v0 - s * v1, s * v0 + c * v1


@njit(cache=True)
def _residual(pose, inputs, kind, ta, tb, s1, s2, w, offset, driver, row, out):
    """Phi(q, c) of one sample into out (rows,)."""
    for t in range(len(kind)):
        a, b, r = ta[t], tb[t], row[t]
        xa, ya, pa, ca, sa = pose[a, 0], pose[a, 1], pose[a, 2], pose[a, 3], pose[a, 4]
        xb, yb, pb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 2], pose[b, 3], pose[b, 4]
        if kind[t] == KIND_COINCIDENCE:
            ax, ay = _turn(ca, sa, s1[t, 0], s1[t, 1])
            bx, by = _turn(cb, sb, s2[t, 0], s2[t, 1])
            out[r] = xa + ax - xb - bx
            out[r + 1] = ya + ay - yb - by
        elif kind[t] == KIND_PROJECTION:
            wx, wy = _turn(ca, sa, w[t, 0], w[t, 1])
            qx, qy = _turn(ca, sa, s1[t, 0], s1[t, 1])
            px, py = _turn(cb, sb, s2[t, 0], s2[t, 1])
            value = wx * (xb + px - xa - qx) + wy * (yb + py - ya - qy)
            if driver[t] >= 0:
                value = value - inputs[driver[t]]
            out[r] = value
        else:
            value = pb - pa - offset[t]
            if driver[t] >= 0:
                value = value - inputs[driver[t]]
            out[r] = value


@njit(cache=True)
def _jacobian(pose, kind, ta, tb, s1, s2, w, row, out):
    """Phi_q of one sample into out (rows, n)."""
    out.fill(0.0)
    for t in range(len(kind)):
        a, b, r = ta[t], tb[t], row[t]
        xa, ya, ca, sa = pose[a, 0], pose[a, 1], pose[a, 3], pose[a, 4]
        xb, yb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 3], pose[b, 4]
        if kind[t] == KIND_COINCIDENCE:
            if a >= 0:
                ax, ay = _turn(ca, sa, s1[t, 0], s1[t, 1])
                k = 3 * a
                out[r, k] = 1.0
                out[r + 1, k + 1] = 1.0
                out[r, k + 2] = 1.0 * -ay
                out[r + 1, k + 2] = 1.0 * ax
            if b >= 0:
                bx, by = _turn(cb, sb, s2[t, 0], s2[t, 1])
                k = 3 * b
                out[r, k] = -1.0
                out[r + 1, k + 1] = -1.0
                out[r, k + 2] = -1.0 * -by
                out[r + 1, k + 2] = -1.0 * bx
        elif kind[t] == KIND_PROJECTION:
            wx, wy = _turn(ca, sa, w[t, 0], w[t, 1])
            qx, qy = _turn(ca, sa, s1[t, 0], s1[t, 1])
            px, py = _turn(cb, sb, s2[t, 0], s2[t, 1])
            dx, dy = xb + px - xa - qx, yb + py - ya - qy
            if b >= 0:
                k = 3 * b
                out[r, k], out[r, k + 1] = wx, wy
                out[r, k + 2] = wx * -py + wy * px
            if a >= 0:
                k = 3 * a
                out[r, k], out[r, k + 1] = -wx, -wy
                out[r, k + 2] = (-wy * dx + wx * dy) - (wx * -qy + wy * qx)
        else:
            if b >= 0:
                out[r, 3 * b + 2] = 1.0
            if a >= 0:
                out[r, 3 * a + 2] = -1.0


@njit(cache=True)
def _gamma(pose, qd, cdd, kind, ta, tb, s1, s2, w, driver, row, out):
    """gamma of one sample into out (rows,)."""
    for t in range(len(kind)):
        a, b, r = ta[t], tb[t], row[t]
        xa, ya, ca, sa = pose[a, 0], pose[a, 1], pose[a, 3], pose[a, 4]
        xb, yb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 3], pose[b, 4]
        wa = qd[3 * a + 2] if a >= 0 else 0.0
        wb = qd[3 * b + 2] if b >= 0 else 0.0
        if kind[t] == KIND_COINCIDENCE:
            ax, ay = _turn(ca, sa, s1[t, 0], s1[t, 1])
            bx, by = _turn(cb, sb, s2[t, 0], s2[t, 1])
            out[r] = ax * (wa * wa) - bx * (wb * wb)
            out[r + 1] = ay * (wa * wa) - by * (wb * wb)
        elif kind[t] == KIND_PROJECTION:
            xda = qd[3 * a] if a >= 0 else 0.0
            yda = qd[3 * a + 1] if a >= 0 else 0.0
            xdb = qd[3 * b] if b >= 0 else 0.0
            ydb = qd[3 * b + 1] if b >= 0 else 0.0
            wx, wy = _turn(ca, sa, w[t, 0], w[t, 1])
            qx, qy = _turn(ca, sa, s1[t, 0], s1[t, 1])
            px, py = _turn(cb, sb, s2[t, 0], s2[t, 1])
            dx, dy = xb + px - xa - qx, yb + py - ya - qy
            ddx = xdb + wb * -py - xda - wa * -qy
            ddy = ydb + wb * px - yda - wa * qx
            quadratic = (
                -(wa * wa) * (wx * dx + wy * dy)
                + 2.0 * wa * (-wy * ddx + wx * ddy)
                - (wb * wb) * (wx * px + wy * py)
                + (wa * wa) * (wx * qx + wy * qy)
            )
            value = -quadratic
            if driver[t] >= 0:
                value = value + cdd[driver[t]]
            out[r] = value
        else:
            value = 0.0
            if driver[t] >= 0:
                value = value + cdd[driver[t]]
            out[r] = value


@njit(cache=True)
def _metres(phi, metres):
    """Largest |phi| in metres (angle rows times size); NaN if any row is NaN."""
    largest = -np.inf
    for r in range(len(phi)):
        v = abs(phi[r]) * metres[r]
        if v != v:
            return np.nan
        if v > largest:
            largest = v
    return largest


# -- dense LU with partial pivoting --------------------------------------------------


@njit(cache=True)
def _lu(a, piv):
    """Factorise a (n, n) in place into L U (unit L) with row swaps piv; returns
    the sign of det a (0 if a pivot is exactly zero, NaN if one is NaN)."""
    n = a.shape[0]
    sign = 1.0
    for k in range(n):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            v = abs(a[i, k])
            if v > big:
                big, p = v, i
        piv[k] = p
        if p != k:
            sign = -sign
            for j in range(n):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        pivot = a[k, k]
        if pivot != pivot:
            return np.nan
        if pivot == 0.0:
            return 0.0
        if pivot < 0.0:
            sign = -sign
        for i in range(k + 1, n):
            factor = a[i, k] / pivot
            a[i, k] = factor
            if factor != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= factor * a[k, j]
    return sign


@njit(cache=True)
def _lu_solve(lu, piv, x):
    """Solve in place with the factors of :func:`_lu`: x (n,) becomes a^-1 x
    (column-oriented substitutions, skipping zeros)."""
    n = lu.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            x[k], x[p] = x[p], x[k]
    for m in range(n):
        xm = x[m]
        if xm != 0.0:
            for i in range(m + 1, n):
                x[i] -= lu[i, m] * xm
    for m in range(n - 1, -1, -1):
        xm = x[m] / lu[m, m]
        x[m] = xm
        if xm != 0.0:
            for i in range(m):
                x[i] -= lu[i, m] * xm


@njit(cache=True)
def _inverse(lu, piv, inverse):
    """a^-1 into inverse (n, n) from the factors of :func:`_lu`: all columns at
    once, row operations skipping the factors' zeros (a Jacobian is sparse)."""
    n = lu.shape[0]
    inverse.fill(0.0)
    for r in range(n):
        inverse[r, r] = 1.0
    for k in range(n):
        p = piv[k]
        if p != k:
            for j in range(n):
                inverse[k, j], inverse[p, j] = inverse[p, j], inverse[k, j]
    for m in range(n):
        for i in range(m + 1, n):
            factor = lu[i, m]
            if factor != 0.0:
                for j in range(n):
                    inverse[i, j] -= factor * inverse[m, j]
    for m in range(n - 1, -1, -1):
        for k in range(m + 1, n):
            factor = lu[m, k]
            if factor != 0.0:
                for j in range(n):
                    inverse[m, j] -= factor * inverse[k, j]
        pivot = lu[m, m]
        for j in range(n):
            inverse[m, j] = inverse[m, j] / pivot


# -- the sweep ------------------------------------------------------------------------


@njit(cache=True)
def predict_atlas(inputs, c_atlas, q_atlas, tangents, period, periodic, scale, tolerance, q, guess, base_sign, signs):
    """Predicted configurations of a one-input sweep from its branch atlas.

    Mirrors :meth:`Kinematics._atlas_predictions` and :func:`._solve._predict`:
    the cubic Hermite curve between the two atlas points around each sample,
    the tangent line past the last one, shifted by whole turns of a crank.

    Parameters
    ----------
    inputs : ndarray, shape (N, 1)
    c_atlas : ndarray, shape (M,)
    q_atlas, tangents : ndarray, shape (M, n)
        Atlas configurations and dq/dc there.
    period : ndarray, shape (n,)
        Change of q over one turn (read only when ``periodic``).
    q, guess : ndarray, shape (N, n)
        Written with the prediction for every sample inside the range.
    base_sign : ndarray, shape (N,)
        Written with the determinant's sign at the atlas point before the sample.
    signs : ndarray, shape (M,)

    Returns
    -------
    ndarray of bool, shape (N,): the samples inside the feasible range.
    """
    n_samples, n = q.shape
    m = len(c_atlas)
    inside_range = np.zeros(n_samples, dtype=np.bool_)
    two_pi = 2.0 * math.pi
    for i in range(n_samples):
        x = inputs[i, 0]
        if periodic:
            turns = math.floor((x - c_atlas[0]) / two_pi)
        else:
            turns = 0.0
            if not (x >= c_atlas[0] - tolerance and x <= c_atlas[m - 1] + tolerance):
                continue
        inside_range[i] = True
        reduced = x - two_pi * turns
        anchor = min(max(np.searchsorted(c_atlas, reduced, side="right") - 1, 0), m - 1)
        nxt = min(anchor + 1, m - 1)
        span = c_atlas[nxt] * scale - c_atlas[anchor] * scale
        base_sign[i] = signs[anchor]
        if span > 0.0:
            t = (reduced * scale - c_atlas[anchor] * scale) / span
            step = c_atlas[nxt] - c_atlas[anchor]
            t2, t3 = t**2, math.pow(t, 3.0)
            h00, h10 = 2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + t
            h01, h11 = -2 * t3 + 3 * t2, t3 - t2
            for j in range(n):
                value = (
                    h00 * q_atlas[anchor, j]
                    + h10 * (tangents[anchor, j] * step)
                    + h01 * q_atlas[nxt, j]
                    + h11 * (tangents[nxt, j] * step)
                )
                if periodic:
                    value = value + turns * period[j]
                q[i, j] = guess[i, j] = value
        else:
            for j in range(n):
                value = q_atlas[anchor, j] + tangents[anchor, j] * (reduced - c_atlas[anchor])
                if periodic:
                    value = value + turns * period[j]
                q[i, j] = guess[i, j] = value
    return inside_range


@njit(cache=True)
def assembled(q, residual, attempt, fixed, per_radian, out):
    """Which attempted samples count as assembled, as :func:`._newton.converged_tolerance`
    decides, without its (N, bodies) temporaries: ``out[i]`` (bool) where the residual
    (m) is at most ``max(fixed, per_radian * largest finite |phi|)`` (m)."""
    for i in range(q.shape[0]):
        largest = 0.0
        for j in range(2, q.shape[1], 3):
            v = abs(q[i, j])
            if math.isfinite(v) and v > largest:
                largest = v
        out[i] = attempt[i] and residual[i] <= max(fixed, per_radian * largest)


@njit(cache=True)
def newton_rounds(
    q, inputs, attempt, kind, ta, tb, s1, s2, w, offset, driver, row, metres, stop, max_iter, residual, iterations
):
    """Newton-Raphson on the attempted samples, in place, as :func:`._newton.newton`.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Starting configurations of the attempted samples, overwritten by the solutions.
    inputs : ndarray, shape (N, k)
    attempt : ndarray of bool, shape (N,)
    residual : ndarray, shape (N,)
        Written: the largest constraint violation (m).
    iterations : ndarray of int, shape (N,)
        Written: the iterations per sample.
    """
    n = q.shape[1]
    rows = len(metres)
    phi = np.empty(rows)
    jac = np.empty((rows, n))
    piv = np.empty(n, dtype=np.int64)
    step = np.empty(n)
    trial = np.empty(n)
    pose = _new_pose(n)
    for i in range(len(attempt)):
        iterations[i] = 0
    for round_ in range(max(max_iter, 1)):
        active = False
        improving = False
        for i in range(len(attempt)):
            if not attempt[i]:
                continue
            _pose(q[i], pose)
            if round_ == 0:  # the starting residuals, and the first round's right-hand sides
                _residual(pose, inputs[i], kind, ta, tb, s1, s2, w, offset, driver, row, phi)
                residual[i] = _metres(phi, metres)
                if not residual[i] > stop or max_iter == 0:
                    continue
            elif not residual[i] > stop:
                continue
            else:
                _residual(pose, inputs[i], kind, ta, tb, s1, s2, w, offset, driver, row, phi)
            active = True
            _jacobian(pose, kind, ta, tb, s1, s2, w, row, jac)
            for r in range(n):
                step[r] = phi[r]
            if _lu(jac, piv) == 0.0:  # exactly singular: least squares, as solve_linear
                _jacobian(pose, kind, ta, tb, s1, s2, w, row, jac)
                step[:] = np.linalg.lstsq(jac, phi, rcond=-1.0)[0]
            else:
                _lu_solve(jac, piv, step)
            finite = True
            for j in range(n):
                trial[j] = q[i, j] - step[j]
                if not np.isfinite(trial[j]):
                    finite = False
            _pose(trial, pose)
            _residual(pose, inputs[i], kind, ta, tb, s1, s2, w, offset, driver, row, phi)
            new = _metres(phi, metres)
            finite = finite and np.isfinite(new)
            if finite:
                for j in range(n):
                    q[i, j] = trial[j]
                if new < residual[i]:
                    improving = True
                residual[i] = new
            iterations[i] += 1
        if not active or not improving:
            break


@njit(cache=True)
def correct(q, samples, rhs, kind, ta, tb, s1, s2, w, offset, driver, row):
    """One Newton step with a given right-hand side, in place: q[i] -= Phi_q(q[i])^-1
    rhs[j] for i = samples[j] (the long-double residuals of :func:`._newton.polish`);
    a sample whose Jacobian is exactly singular, or whose step is not finite, is left."""
    n = q.shape[1]
    jac = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    step = np.empty(n)
    pose = _new_pose(n)
    for j in range(len(samples)):
        i = samples[j]
        _pose(q[i], pose)
        _jacobian(pose, kind, ta, tb, s1, s2, w, row, jac)
        sign = _lu(jac, piv)
        if sign == 0.0 or sign != sign:
            continue
        for r in range(n):
            step[r] = rhs[j, r]
        _lu_solve(jac, piv, step)
        finite = True
        for r in range(n):
            if not np.isfinite(step[r]):
                finite = False
        if finite:
            for r in range(n):
                q[i, r] -= step[r]


@njit(cache=True)
def _scaled_jacobian(pose, kind, ta, tb, s1, s2, w, row, jacobian_scale, out):
    _jacobian(pose, kind, ta, tb, s1, s2, w, row, out)
    for r in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[r, j] = out[r, j] * jacobian_scale[r, j]


@njit(cache=True)
def _copy(source, target):
    """target[...] = source for (n, n) arrays, without numba's slicing machinery."""
    for r in range(source.shape[0]):
        for j in range(source.shape[1]):
            target[r, j] = source[r, j]


@njit(cache=True)
def _norm1(a):
    """Largest column sum of |a| (NaN if any entry is NaN), as np.max(np.sum(...))."""
    n = a.shape[0]
    norm = -np.inf
    for j in range(a.shape[1]):
        total = 0.0
        for r in range(n):
            total += abs(a[r, j])
        if total != total:
            return np.nan
        if total > norm:
            norm = total
    return norm


@njit(cache=True)
def _rates(
    i,
    q,
    pose,
    qd,
    qdd,
    rates,
    cdd,
    lu,
    piv,
    sign,
    scaled,
    inverse,
    vector,
    row_scale,
    coordinate_scale,
    kind,
    ta,
    tb,
    s1,
    s2,
    w,
    driver,
    row,
    n_kinematic,
    near,
    singular,
    status,
    singularity,
):
    """Step 4 of the solve for sample i: singularity, qd and qdd through the
    inverse of the scaled Jacobian (``scaled``), whose LU is in lu, piv."""
    n = lu.shape[0]
    norm = _norm1(scaled)
    if sign == 0.0 or sign != sign:  # exactly singular (or NaN): not determined
        singularity[i] = 0.0
        status[i] = _SINGULAR
        qd[i, :] = np.nan
        qdd[i, :] = np.nan
        return
    _inverse(lu, piv, inverse)
    value = 1.0 / (norm * _norm1(inverse))
    value = value if np.isfinite(value) else 0.0
    singularity[i] = value
    # qd = C^-1 S^-1 D_r (-Phi_t), qdd = C^-1 S^-1 D_r gamma
    for r in range(n):
        vector[r] = 0.0 * row_scale[r] if r < n_kinematic else rates[i, r - n_kinematic] * row_scale[r]
    for r in range(n):
        total = 0.0
        for j in range(n):
            total += inverse[r, j] * vector[j]
        qd[i, r] = total / coordinate_scale[r]
    _gamma(pose, qd[i], cdd[i], kind, ta, tb, s1, s2, w, driver, row, vector)
    for r in range(n):
        vector[r] = vector[r] * row_scale[r]
    for r in range(n):
        total = 0.0
        for j in range(n):
            total += inverse[r, j] * vector[j]
        qdd[i, r] = total / coordinate_scale[r]
    if value < near:
        status[i] = _NEAR_SINGULAR
    if value < singular:
        status[i] = _SINGULAR
        qd[i, :] = np.nan
        qdd[i, :] = np.nan


@njit(cache=True)
def check_and_finish(
    q,
    guess,
    qdd,
    rates,
    cdd,
    attempt,
    converged,
    max_correction,
    base_sign,
    jacobian_scale,
    row_scale,
    coordinate_scale,
    kind,
    ta,
    tb,
    s1,
    s2,
    w,
    driver,
    row,
    n_kinematic,
    near,
    singular,
    status,
    singularity,
):
    """Steps 2 and 4 of the solve for the attempted samples after :func:`newton_rounds`.

    A sample is accepted when it converged, moved little from its prediction
    (``guess``, in the velocity array qd until overwritten) and kept the
    determinant's sign of its anchor; its scaled Jacobian is then factorised
    once for the sign, the condition number, qd and qdd. Rejected samples get
    NaN rows and the status branch-jump (converged) or not-converged.
    ``converged`` (N,) bool: the samples :func:`assembled` counts as assembled.
    """
    n = q.shape[1]
    scaled = np.empty((n, n))
    lu = np.empty((n, n))
    inverse = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    vector = np.empty(n)
    pose = _new_pose(n)
    for i in range(len(attempt)):
        if not attempt[i]:
            continue
        correction = -np.inf
        for j in range(n):
            v = abs(q[i, j] - guess[i, j]) * coordinate_scale[j]
            if v != v or v > correction:
                correction = v
                if v != v:
                    break
        _pose(q[i], pose)
        _scaled_jacobian(pose, kind, ta, tb, s1, s2, w, row, jacobian_scale, scaled)
        _copy(scaled, lu)
        sign = _lu(lu, piv)
        on_branch = correction <= max_correction and (sign == base_sign[i] or sign == 0.0)
        if converged[i] and on_branch:
            status[i] = _OK
            _rates(
                i,
                q,
                pose,
                guess,
                qdd,
                rates,
                cdd,
                lu,
                piv,
                sign,
                scaled,
                inverse,
                vector,
                row_scale,
                coordinate_scale,
                kind,
                ta,
                tb,
                s1,
                s2,
                w,
                driver,
                row,
                n_kinematic,
                near,
                singular,
                status,
                singularity,
            )
        else:
            status[i] = _BRANCH_JUMP if converged[i] else _NOT_CONVERGED
            q[i, :] = np.nan
            guess[i, :] = np.nan
            qdd[i, :] = np.nan


@njit(cache=True)
def finish(
    q,
    qd,
    qdd,
    rates,
    cdd,
    idx,
    jacobian_scale,
    row_scale,
    coordinate_scale,
    kind,
    ta,
    tb,
    s1,
    s2,
    w,
    driver,
    row,
    n_kinematic,
    near,
    singular,
    status,
    singularity,
):
    """Step 4 of the solve (singularity, qd, qdd) for assembled samples idx."""
    n = q.shape[1]
    scaled = np.empty((n, n))
    lu = np.empty((n, n))
    inverse = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    vector = np.empty(n)
    pose = _new_pose(n)
    for i in idx:
        _pose(q[i], pose)
        _scaled_jacobian(pose, kind, ta, tb, s1, s2, w, row, jacobian_scale, scaled)
        _copy(scaled, lu)
        sign = _lu(lu, piv)
        _rates(
            i,
            q,
            pose,
            qd,
            qdd,
            rates,
            cdd,
            lu,
            piv,
            sign,
            scaled,
            inverse,
            vector,
            row_scale,
            coordinate_scale,
            kind,
            ta,
            tb,
            s1,
            s2,
            w,
            driver,
            row,
            n_kinematic,
            near,
            singular,
            status,
            singularity,
        )
