"""The sweep of :meth:`Kinematics.solve`, compiled with numba.

The same equations, the same Newton rounds and the same checks as the NumPy
implementation in :mod:`._solve` and :mod:`._newton` (which stays the readable
reference and is tested against this one sample by sample), but one sample at
a time with O(n^2) scratch instead of whole-batch (N, n, n) arrays: memory
stays flat whatever the number of samples, and the Jacobian at the solution is
factorised once (LU with partial pivoting) for the determinant's sign, the
inverse (condition number, velocities, accelerations). From ``BANDED_FROM``
coordinates the Jacobian is stored and factorised as a band matrix
(:meth:`Packed._layout`, :mod:`._banded`): O(n) scratch and work per sample on
a chain, with the condition number estimated rather than computed exactly.

Newton runs in rounds over all samples, as the batched reference does: a
sample that has stopped improving keeps iterating while any other sample
still improves, so every sample takes the reference's iterations (up to a
step more or less where its residual sits at the round-off floor, since the
two LU factorisations round differently).

Constraint terms (rows in the system's order) are the system's terms as flat
arrays (:meth:`Packed.terms`), their equations those of :mod:`xcheck.joints._equations`,
compiled and inlined here; body index -1 is the ground.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, objmode

from ..joints import _equations as eq
from ..joints._terms import COINCIDENCE, GEOMETRY, PROJECTION
from ._banded import band_lu, band_norm1, band_solve, inverse_norm1_estimate

__all__ = ["Packed", "predict_atlas", "newton_rounds", "check_and_finish", "finish"]

_inline = njit(cache=True, inline="always")
_turn = _inline(eq.turn)
_coincidence_residual = _inline(eq.coincidence_residual)
_coincidence_jacobian = _inline(eq.coincidence_jacobian)
_coincidence_gamma = _inline(eq.coincidence_gamma)
_projection_offset = _inline(eq.projection_offset)
_projection_residual = _inline(eq.projection_residual)
_projection_jacobian = _inline(eq.projection_jacobian)
_projection_gamma = _inline(eq.projection_gamma)
_angles_residual = _inline(eq.angles_residual)

#: from this many coordinates, Phi_q is factorised as a band matrix
#: (:meth:`Packed._layout`, :mod:`._banded`), and the singularity measure is
#: Higham's estimate of 1 / the 1-norm condition number instead of the exact value
BANDED_FROM = 30
#: ... unless the band (2 kl + ku + 1 entries a row) is wider than this share of n:
#: a body joined to many others, whose band storage and LU would cost more than dense
BAND_WIDTH_LIMIT = 0.5

#: Status codes (the values of :class:`._solve.Status`).
_OK, _NEAR_SINGULAR, _SINGULAR, _NOT_CONVERGED, _BRANCH_JUMP = 0, 1, 2, 3, 4


class Packed:
    """A :class:`ConstraintSystem`'s terms as flat arrays (SI units)."""

    def __init__(self, system) -> None:
        m = len(system.terms)
        self.kind = np.empty(m, dtype=np.int64)
        self.bodies = np.full((m, 3), -1, dtype=np.int64)
        self.geometry = np.zeros((m, GEOMETRY))
        self.offset = np.zeros(m)
        self.driver = np.full(m, -1, dtype=np.int64)
        self.row = np.asarray(system._offsets[:m], dtype=np.int64)
        for t, term in enumerate(system.terms):
            self.kind[t], self.bodies[t], self.geometry[t], self.offset[t] = term.packed()
            if term.driver is not None:
                self.driver[t] = term.driver
        self.n = system.n
        self.size = float(system.size)
        #: residual_metres' factor per row: size for angle rows, 1 otherwise
        self.metres = np.where(system.row_is_angle, system.size, 1.0).astype(float)
        #: scaled_jacobian's factor per entry, (rows, n)
        rows = np.where(system.row_is_angle, 1.0, 1.0 / system.size)
        self.row_scale = rows.astype(float)
        self.coordinate_scale = system.coordinate_scale()
        self.jacobian_scale = np.ascontiguousarray(rows[:, None] / self.coordinate_scale[None, :])
        self._layout(system)

    def terms(self) -> tuple:
        """The term arrays in the kernels' argument order."""
        return (self.kind, self.bodies, self.geometry, self.offset, self.driver, self.row)

    def structure(self) -> tuple:
        """Where the kernels keep Phi_q: ``layout`` (4, n), None where dense, and ``band`` (3,);
        see :meth:`_layout`."""
        return (self.layout, self.band)

    def _layout(self, system) -> None:
        """How the kernels store Phi_q (square systems only).

        Dense below ``BANDED_FROM`` coordinates: row r, column k at [r, k]. From
        there, banded (:mod:`._banded`): the bodies in reverse Cuthill-McKee order
        of the graph the joints make of them, each term's rows placed by its
        first body in that order; row r, column k at [i, col_pos[k] - i + kl] with
        i = row_pos[r] (:func:`_set`). ``layout`` rows: row_pos, col_pos, and the inverse
        permutations row_of, col_of. ``band``: (kl, ku, the sign of the two
        permutations, which det Phi_q's sign is corrected by). Dense
        also where the band would be wider than n / 2 (a body joined to many).
        """
        n, rows = self.n, len(self.metres)
        self.layout: np.ndarray | None = None
        self.band = np.array([n - 1, n - 1, 1], dtype=np.int64)
        if n < BANDED_FROM or rows != n:
            return
        from scipy.sparse import csgraph, csr_matrix

        bodies = n // 3
        pairs = [(a, b) for row in self.bodies for a in row for b in row if a >= 0 and b >= 0 and a != b]
        first = np.array([a for a, b in pairs] + list(range(bodies)), dtype=np.int64)
        second = np.array([b for a, b in pairs] + list(range(bodies)), dtype=np.int64)
        graph = csr_matrix((np.ones(len(first)), (first, second)), shape=(bodies, bodies))
        body_pos = np.empty(bodies, dtype=np.int64)
        body_pos[csgraph.reverse_cuthill_mckee(graph, symmetric_mode=True)] = np.arange(bodies)
        col_pos = (3 * body_pos[:, None] + np.arange(3)).ravel()

        def placed(t: int) -> tuple[int, int]:
            at = sorted(body_pos[body] for body in self.bodies[t] if body >= 0)
            return at[0], at[-1]

        counts = np.diff(np.append(self.row, rows))
        row_of = np.concatenate([self.row[t] + np.arange(counts[t]) for t in sorted(range(len(self.kind)), key=placed)])
        row_pos = np.empty(n, dtype=np.int64)
        row_pos[row_of] = np.arange(n)
        col_of = np.empty(n, dtype=np.int64)
        col_of[col_pos] = np.arange(n)
        # each row of a term may touch the three coordinates of either of its bodies
        offsets = [
            col_pos[3 * body + c] - row_pos[self.row[t] + j]
            for t in range(len(self.kind))
            for body in self.bodies[t]
            if body >= 0
            for j in range(counts[t])
            for c in range(3)
        ]
        kl, ku = int(max(0, -min(offsets))), int(max(0, max(offsets)))
        if 2 * kl + ku + 1 > BAND_WIDTH_LIMIT * n:
            return
        sign = _permutation_sign(row_of) * _permutation_sign(col_of)
        self.layout = np.stack([row_pos, col_pos, row_of, col_of]).astype(np.int64)
        self.band = np.array([kl, ku, sign], dtype=np.int64)


def _permutation_sign(order: np.ndarray) -> int:
    """+1 or -1: the parity of a permutation (its number of even-length cycles)."""
    seen = np.zeros(len(order), dtype=bool)
    sign = 1
    for start in range(len(order)):
        length, at = 0, start
        while not seen[at]:
            seen[at] = True
            at = order[at]
            length += 1
        if length % 2 == 0 and length > 0:
            sign = -sign
    return sign


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


@njit(cache=True)
def _residual(pose, inputs, kind, bodies, geometry, offset, driver, row, out):
    """Phi(q, c) of one sample into out (rows,)."""
    g = geometry
    for t in range(len(kind)):
        a, b, r = bodies[t, 0], bodies[t, 1], row[t]
        xa, ya, pa, ca, sa = pose[a, 0], pose[a, 1], pose[a, 2], pose[a, 3], pose[a, 4]
        xb, yb, pb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 2], pose[b, 3], pose[b, 4]
        if kind[t] == COINCIDENCE:
            ax, ay = _turn(ca, sa, g[t, 0], g[t, 1])
            bx, by = _turn(cb, sb, g[t, 2], g[t, 3])
            out[r], out[r + 1] = _coincidence_residual(xa, ya, ax, ay, xb, yb, bx, by)
            continue
        if kind[t] == PROJECTION:
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            value = _projection_residual(wx, wy, dx, dy)
        else:
            pc = pose[bodies[t, 2], 2]
            value = _angles_residual(pa, pb, pc, g[t, 6], g[t, 7], g[t, 8], offset[t])
        if driver[t] >= 0:
            value = value - inputs[driver[t]]
        out[r] = value


@njit(cache=True)
def _set(out, layout, kl, r, k, value):
    """Phi_q[r, k] = value, in dense (``layout`` None) or banded storage
    (:meth:`Packed._layout`). numba compiles the two apart (it prunes the
    branch on None), so the dense kernels carry no banded code."""
    if layout is None:
        out[r, k] = value
    else:
        i = layout[0, r]
        out[i, layout[1, k] - i + kl] = value


@njit(cache=True)
def _jacobian(pose, kind, bodies, geometry, row, layout, band, out):
    """Phi_q of one sample into out: (rows, n) where ``layout`` is None, else
    banded (n, 2 kl + ku + 1) as :meth:`Packed._layout` says."""
    out.fill(0.0)
    kl = band[0]
    g = geometry
    for t in range(len(kind)):
        a, b, r = bodies[t, 0], bodies[t, 1], row[t]
        xa, ya, ca, sa = pose[a, 0], pose[a, 1], pose[a, 3], pose[a, 4]
        xb, yb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 3], pose[b, 4]
        if kind[t] == COINCIDENCE:
            ax, ay = _turn(ca, sa, g[t, 0], g[t, 1])
            bx, by = _turn(cb, sb, g[t, 2], g[t, 3])
            a0, a1, b0, b1 = _coincidence_jacobian(ax, ay, bx, by)
            if a >= 0:
                k = 3 * a
                _set(out, layout, kl, r, k, 1.0)
                _set(out, layout, kl, r + 1, k + 1, 1.0)
                _set(out, layout, kl, r, k + 2, a0)
                _set(out, layout, kl, r + 1, k + 2, a1)
            if b >= 0:
                k = 3 * b
                _set(out, layout, kl, r, k, -1.0)
                _set(out, layout, kl, r + 1, k + 1, -1.0)
                _set(out, layout, kl, r, k + 2, b0)
                _set(out, layout, kl, r + 1, k + 2, b1)
        elif kind[t] == PROJECTION:
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            phi_b, phi_a = _projection_jacobian(wx, wy, qx, qy, px, py, dx, dy)
            if b >= 0:
                k = 3 * b
                _set(out, layout, kl, r, k, wx)
                _set(out, layout, kl, r, k + 1, wy)
                _set(out, layout, kl, r, k + 2, phi_b)
            if a >= 0:
                k = 3 * a
                _set(out, layout, kl, r, k, -wx)
                _set(out, layout, kl, r, k + 1, -wy)
                _set(out, layout, kl, r, k + 2, phi_a)
        else:
            for slot in range(3):
                body = bodies[t, slot]
                if body >= 0 and g[t, 6 + slot] != 0.0:
                    _set(out, layout, kl, r, 3 * body + 2, g[t, 6 + slot])


@njit(cache=True)
def _gamma(pose, qd, cdd, kind, bodies, geometry, driver, row, out):
    """gamma of one sample into out (rows,)."""
    g = geometry
    for t in range(len(kind)):
        a, b, r = bodies[t, 0], bodies[t, 1], row[t]
        xa, ya, ca, sa = pose[a, 0], pose[a, 1], pose[a, 3], pose[a, 4]
        xb, yb, cb, sb = pose[b, 0], pose[b, 1], pose[b, 3], pose[b, 4]
        wa = qd[3 * a + 2] if a >= 0 else 0.0
        wb = qd[3 * b + 2] if b >= 0 else 0.0
        if kind[t] == COINCIDENCE:
            ax, ay = _turn(ca, sa, g[t, 0], g[t, 1])
            bx, by = _turn(cb, sb, g[t, 2], g[t, 3])
            out[r], out[r + 1] = _coincidence_gamma(ax, ay, wa, bx, by, wb)
            continue
        value = 0.0
        if kind[t] == PROJECTION:
            xda = qd[3 * a] if a >= 0 else 0.0
            yda = qd[3 * a + 1] if a >= 0 else 0.0
            xdb = qd[3 * b] if b >= 0 else 0.0
            ydb = qd[3 * b + 1] if b >= 0 else 0.0
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            value = _projection_gamma(wx, wy, qx, qy, px, py, dx, dy, xda, yda, wa, xdb, ydb, wb)
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


# -- dense or banded, as the Packed layout says -----------------------------------------


@njit(cache=True)
def _matrix(rows, n, layout, band):
    """Scratch for Phi_q: (rows, n) dense (``layout`` None), or (n, 2 kl + ku + 1) banded."""
    if layout is not None:
        return np.empty((n, 2 * band[0] + band[1] + 1))
    return np.empty((rows, n))


@njit(cache=True)
def _factorise(matrix, piv, layout, band):
    """LU of Phi_q in place; returns the sign of det Phi_q in the system's order
    (0 if exactly singular, NaN if NaN), as :func:`_lu`."""
    if layout is not None:
        return band_lu(matrix, band[0], band[1], piv) * band[2]
    return _lu(matrix, piv)


@njit(cache=True)
def _solve(lu, piv, layout, band, x, work):
    """x (n,), rows in the system's order, becomes Phi_q^-1 x (coordinates in the
    system's order), from :func:`_factorise`'s factors; ``work`` (n,) is scratch."""
    if layout is not None:
        n = len(x)
        for r in range(n):
            work[layout[0, r]] = x[r]
        band_solve(lu, band[0], band[1], piv, work)
        for j in range(n):
            x[layout[3, j]] = work[j]
    else:
        _lu_solve(lu, piv, x)


@njit(cache=True)
def _least_squares_step(pose, kind, bodies, geometry, row, phi, n, step):
    """step = lstsq(Phi_q, phi) at an exactly singular Jacobian, from a dense Phi_q."""
    dense = np.empty((len(phi), n))
    _jacobian(pose, kind, bodies, geometry, row, None, np.zeros(4, dtype=np.int64), dense)
    # NumPy's lstsq, called back in Python: the same LAPACK driver (gelsd) and the
    # same bits as numba's own, whose compilation was most of this module's cold start
    with objmode(solution="float64[:]"):
        solution = np.linalg.lstsq(dense, phi, rcond=-1.0)[0]
    for r in range(n):
        step[r] = solution[r]


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
    q,
    inputs,
    attempt,
    kind,
    bodies,
    geometry,
    offset,
    driver,
    row,
    layout,
    band,
    metres,
    stop,
    max_iter,
    residual,
    iterations,
):
    """Newton-Raphson on the attempted samples, in place, as :func:`._newton.newton`.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Starting configurations of the attempted samples, overwritten by the solutions.
    inputs : ndarray, shape (N, k)
    attempt : ndarray of bool, shape (N,)
    layout, band : ndarray of int
        :meth:`Packed.structure`: dense or banded Phi_q.
    residual : ndarray, shape (N,)
        Written: the largest constraint violation (m).
    iterations : ndarray of int, shape (N,)
        Written: the iterations per sample.
    """
    n = q.shape[1]
    rows = len(metres)
    phi = np.empty(rows)
    jac = _matrix(rows, n, layout, band)
    piv = np.empty(n, dtype=np.int64)
    step = np.empty(n)
    trial = np.empty(n)
    work = np.empty(n)
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
                _residual(pose, inputs[i], kind, bodies, geometry, offset, driver, row, phi)
                residual[i] = _metres(phi, metres)
                if not residual[i] > stop or max_iter == 0:
                    continue
            elif not residual[i] > stop:
                continue
            else:
                _residual(pose, inputs[i], kind, bodies, geometry, offset, driver, row, phi)
            active = True
            _jacobian(pose, kind, bodies, geometry, row, layout, band, jac)
            for r in range(n):
                step[r] = phi[r]
            if _factorise(jac, piv, layout, band) == 0.0:  # exactly singular: least squares, as solve_linear
                _least_squares_step(pose, kind, bodies, geometry, row, phi, n, step)
            else:
                _solve(jac, piv, layout, band, step, work)
            finite = True
            for j in range(n):
                trial[j] = q[i, j] - step[j]
                if not np.isfinite(trial[j]):
                    finite = False
            _pose(trial, pose)
            _residual(pose, inputs[i], kind, bodies, geometry, offset, driver, row, phi)
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
def correct(q, samples, rhs, kind, bodies, geometry, offset, driver, row, layout, band):
    """One Newton step with a given right-hand side, in place: q[i] -= Phi_q(q[i])^-1
    rhs[j] for i = samples[j] (the long-double residuals of :func:`._newton.polish`);
    a sample whose Jacobian is exactly singular, or whose step is not finite, is left."""
    n = q.shape[1]
    jac = _matrix(n, n, layout, band)
    piv = np.empty(n, dtype=np.int64)
    step = np.empty(n)
    work = np.empty(n)
    pose = _new_pose(n)
    for j in range(len(samples)):
        i = samples[j]
        _pose(q[i], pose)
        _jacobian(pose, kind, bodies, geometry, row, layout, band, jac)
        sign = _factorise(jac, piv, layout, band)
        if sign == 0.0 or sign != sign:
            continue
        for r in range(n):
            step[r] = rhs[j, r]
        _solve(jac, piv, layout, band, step, work)
        finite = True
        for r in range(n):
            if not np.isfinite(step[r]):
                finite = False
        if finite:
            for r in range(n):
                q[i, r] -= step[r]


@njit(cache=True)
def _scaled_jacobian(pose, kind, bodies, geometry, row, layout, band, jacobian_scale, out):
    """The dimensionless Phi_q (entries times ``jacobian_scale`` (rows, n)) into out."""
    _jacobian(pose, kind, bodies, geometry, row, layout, band, out)
    if layout is not None:
        n, kl = out.shape[0], band[0]
        for i in range(n):
            for jj in range(out.shape[1]):
                j = jj + i - kl
                if 0 <= j < n:
                    out[i, jj] = out[i, jj] * jacobian_scale[layout[2, i], layout[3, j]]
        return
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
def _times_inverse(inverse, lu, piv, layout, band, vector, work, coordinate_scale, out):
    """out (n,) = C^-1 (scaled Phi_q)^-1 vector: by the explicit inverse where
    dense, by the banded factors where banded (``vector`` is overwritten there);
    ``work`` (n,) is scratch."""
    n = len(vector)
    if layout is not None:
        _solve(lu, piv, layout, band, vector, work)
        for r in range(n):
            out[r] = vector[r] / coordinate_scale[r]
        return
    for r in range(n):
        total = 0.0
        for j in range(n):
            total += inverse[r, j] * vector[j]
        out[r] = total / coordinate_scale[r]


@njit(cache=True)
def _rates(
    i,
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
    scratch,
    layout,
    band,
    row_scale,
    coordinate_scale,
    kind,
    bodies,
    geometry,
    driver,
    row,
    n_kinematic,
    near,
    singular,
    status,
    singularity,
):
    """Step 4 of the solve for sample i: singularity, qd and qdd through the
    inverse of the scaled Jacobian (``scaled``), whose LU is in lu, piv (dense:
    the explicit inverse, into ``inverse``, and the exact condition number;
    banded: solves, and the estimate). ``scratch`` (3, n).

    (Arguments are few on purpose: with four more, LLVM stopped inlining this
    into the sample loop, and the dense sweep lost 30 % of this step.)"""
    n = lu.shape[0]
    vector, work, signs = scratch[0], scratch[1], scratch[2]
    norm = _norm1(scaled) if layout is None else band_norm1(scaled, band[0], work)
    if sign == 0.0 or sign != sign:  # exactly singular (or NaN): not determined
        singularity[i] = 0.0
        status[i] = _SINGULAR
        qd[i, :] = np.nan
        qdd[i, :] = np.nan
        return
    if layout is not None:  # the inverse is dense: its norm is estimated
        inverse_norm = inverse_norm1_estimate(lu, band[0], band[1], piv, work, signs)
    else:
        _inverse(lu, piv, inverse)
        inverse_norm = _norm1(inverse)
    value = 1.0 / (norm * inverse_norm)
    value = value if np.isfinite(value) else 0.0
    singularity[i] = value
    # qd = C^-1 S^-1 D_r (-Phi_t), qdd = C^-1 S^-1 D_r gamma
    for r in range(n):
        vector[r] = 0.0 * row_scale[r] if r < n_kinematic else rates[i, r - n_kinematic] * row_scale[r]
    _times_inverse(inverse, lu, piv, layout, band, vector, work, coordinate_scale, qd[i])
    _gamma(pose, qd[i], cdd[i], kind, bodies, geometry, driver, row, vector)
    for r in range(n):
        vector[r] = vector[r] * row_scale[r]
    _times_inverse(inverse, lu, piv, layout, band, vector, work, coordinate_scale, qdd[i])
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
    bodies,
    geometry,
    driver,
    row,
    layout,
    band,
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
    scaled = _matrix(n, n, layout, band)
    lu = _matrix(n, n, layout, band)
    inverse = np.empty((n, n)) if layout is None else np.empty((1, 1))
    piv = np.empty(n, dtype=np.int64)
    scratch = np.empty((3, n))
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
        _scaled_jacobian(pose, kind, bodies, geometry, row, layout, band, jacobian_scale, scaled)
        _copy(scaled, lu)
        sign = _factorise(lu, piv, layout, band)
        on_branch = correction <= max_correction and (sign == base_sign[i] or sign == 0.0)
        if converged[i] and on_branch:
            status[i] = _OK
            _rates(
                i,
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
                scratch,
                layout,
                band,
                row_scale,
                coordinate_scale,
                kind,
                bodies,
                geometry,
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
    bodies,
    geometry,
    driver,
    row,
    layout,
    band,
    n_kinematic,
    near,
    singular,
    status,
    singularity,
):
    """Step 4 of the solve (singularity, qd, qdd) for assembled samples idx."""
    n = q.shape[1]
    scaled = _matrix(n, n, layout, band)
    lu = _matrix(n, n, layout, band)
    inverse = np.empty((n, n)) if layout is None else np.empty((1, 1))
    piv = np.empty(n, dtype=np.int64)
    scratch = np.empty((3, n))
    pose = _new_pose(n)
    for i in idx:
        _pose(q[i], pose)
        _scaled_jacobian(pose, kind, bodies, geometry, row, layout, band, jacobian_scale, scaled)
        _copy(scaled, lu)
        sign = _factorise(lu, piv, layout, band)
        _rates(
            i,
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
            scratch,
            layout,
            band,
            row_scale,
            coordinate_scale,
            kind,
            bodies,
            geometry,
            driver,
            row,
            n_kinematic,
            near,
            singular,
            status,
            singularity,
        )
