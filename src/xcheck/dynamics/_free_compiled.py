"""The free-motion integrator of :mod:`._free`, compiled with numba.

The same equations, the same steps and the same order of operations as the
NumPy implementation in :mod:`._free` (which stays the readable reference
and is tested against this one output by output): RK4 on the index-1 form,
the accelerations by Gauss's principle, an M-weighted projection of the
positions and velocities after every step. The model is packed into flat
arrays by :class:`Packed`; :func:`integrate` runs one whole integration in
compiled code (a plain-Python step costs about 1.3 ms on the double
four-bar, most of it interpreter overhead around 3 x 3 and 15 x 15 algebra).

Constraint terms (rows in this order): point coincidences (2 rows each,
metres), then in the system's order the other terms (projections, 1 row,
metres; angle rows, 1 row, radians or metres), their equations those of
:mod:`xcheck.joints._equations`. Body index -1 is the ground.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..joints import _equations as eq
from ..joints._terms import ANGLES, GEOMETRY
from ._free import (
    BANDED_LEAST_SQUARES_BELOW,
    EIGEN_ITERATIONS,
    LEAST_SQUARES_BELOW,
    PROJECTION_CUTOFF,
    PROJECTION_ITERATIONS,
    PROJECTION_TOLERANCE,
    RANK_CUTOFF,
    SINGULAR_THRESHOLD,
)

__all__ = ["Packed", "integrate"]

#: bodies a constraint row may involve (a gear pair's two gears and their carrier)
SLOTS = 3

#: the equations' functions are inlined where they are called (numba IR): compiled as
#: functions of their own, each would be compiled and linked once more for every caller
_inline = njit(cache=True, inline="always")
#: a function called only from compiled code: no wrapper for calls from Python (the only
#: entry points, :func:`integrate` and ``_adaptive._integrate``, keep theirs), which saves
#: compiling one per function (numba's type stubs do not list these options)
_internal = njit(cache=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)  # type: ignore[call-overload]
#: flags for the compiled functions' boolean arguments: numba types a literal ``True`` or
#: ``False`` as a type of its own and compiles the function it is passed to (with all it
#: calls) once for each, where a NumPy bool is one type for both
YES, NO = np.bool_(True), np.bool_(False)
_turn = _inline(eq.turn)
_coincidence_residual = _inline(eq.coincidence_residual)
_coincidence_jacobian = _inline(eq.coincidence_jacobian)
_coincidence_gamma = _inline(eq.coincidence_gamma)
_projection_offset = _inline(eq.projection_offset)
_projection_residual = _inline(eq.projection_residual)
_projection_jacobian = _inline(eq.projection_jacobian)
_projection_gamma = _inline(eq.projection_gamma)
_angles_residual = _inline(eq.angles_residual)


class Packed:
    """The free mechanism as the arrays :func:`integrate` reads (SI units).

    Built from a ``_Dynamics`` of :mod:`._free` (so both read the same model).
    """

    def __init__(self, dyn) -> None:
        joints, bodies = dyn.joints, dyn.bodies
        ground = joints.n // 3
        self.mass, self.inertia, self.com = bodies.mass, bodies.inertia, np.ascontiguousarray(bodies.com)
        self.c_a = np.where(joints.a == ground, -1, joints.a).astype(np.int64)
        self.c_b = np.where(joints.b == ground, -1, joints.b).astype(np.int64)
        self.c_sa, self.c_sb = np.ascontiguousarray(joints.s_a), np.ascontiguousarray(joints.s_b)
        packed = [t.packed() for t in joints.others]  # projections and angle rows, in the system's order
        self.o_kind = np.array([kind for kind, *_ in packed], dtype=np.int64)
        self.o_bodies = np.array([bodies for _, bodies, *_ in packed], dtype=np.int64).reshape(-1, 3)
        self.o_geometry = np.array([geometry for *_, geometry, _ in packed], dtype=float).reshape(-1, GEOMETRY)
        self.o_offset = np.array([offset for *_, offset in packed], dtype=float)
        self.gravity = np.asarray(dyn.gravity, dtype=float)
        self.l_body = np.array([k // 3 for k, *_ in dyn.loads], dtype=np.int64)
        self.l_point = np.array([p for _, p, *_ in dyn.loads], dtype=float).reshape(-1, 2)
        self.l_force = np.array([f for _, _, f, *_ in dyn.loads], dtype=float).reshape(-1, 2)
        self.l_torque = np.array([t for _, _, _, t, _ in dyn.loads], dtype=float)
        # per load: the time law's code (0: constant) and parameters (LoadLaw.parameters)
        self.l_law = np.array(
            [(0.0, 0.0, 0.0, 0.0) if law is None else law.parameters() for *_, law in dyn.loads], dtype=float
        ).reshape(-1, 4)
        ends = [(first, second) for first, second, *_ in dyn.springs]
        self.s_body = np.array([[-1 if k is None else k // 3 for k, _ in pair] for pair in ends], dtype=np.int64)
        self.s_body = self.s_body.reshape(-1, 2)
        self.s_point = np.array([[p for _, p in pair] for pair in ends], dtype=float).reshape(-1, 2, 2)
        self.s_law = np.array([[k, rest, c] for _, _, k, rest, c in dyn.springs], dtype=float).reshape(-1, 3)
        twists = [(a, b) for a, b, *_ in dyn.rotational]
        self.r_body = np.array([[-1 if k is None else k // 3 for k in pair] for pair in twists], dtype=np.int64)
        self.r_body = self.r_body.reshape(-1, 2)
        self.r_law = np.array([[k, rest, c] for _, _, k, rest, c in dyn.rotational], dtype=float).reshape(-1, 3)
        self.row_is_angle = joints.row_is_angle.astype(np.bool_)
        self.scale_rows = np.asarray(dyn.scale_rows, dtype=float)
        self.scale_coordinates = np.asarray(dyn.scale_coordinates, dtype=float)
        self.mass_scale = float(dyn.mass_scale)
        self.size = float(dyn.size)
        self._band(dyn)

    def _band(self, dyn) -> None:
        """The structure of J M^-1 J^T for :func:`_constrained_banded` (used where
        ``dyn.banded``): each row's bodies (m, SLOTS; -1 the ground or none), per body the rows on it
        (CSR: ``body_ptr`` (B + 1,), ``body_row`` and ``body_slot``, which of the row's
        two bodies it is), the rows' positions in a reverse Cuthill-McKee order (m,)
        and the half-bandwidth there, and the iterations' start in that order (m,)."""
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        slots = [(a, b, -1) for a, b in zip(self.c_a, self.c_b) for _ in range(2)]
        slots += [tuple(row) for row in self.o_bodies]
        rows, bodies = len(slots), len(self.mass)
        self.row_body = np.array(slots, dtype=np.int64).reshape(rows, SLOTS)
        on = [
            [(r, slot) for r in range(rows) for slot in range(SLOTS) if self.row_body[r, slot] == k]
            for k in range(bodies)
        ]
        self.body_ptr = np.cumsum([0] + [len(e) for e in on]).astype(np.int64)
        self.body_row = np.array([r for e in on for r, _ in e], dtype=np.int64)
        self.body_slot = np.array([slot for e in on for _, slot in e], dtype=np.int64)
        coupled = [(r, c) for e in on for r, _ in e for c, _ in e]
        first = np.array([r for r, _ in coupled], dtype=np.int64)
        second = np.array([c for _, c in coupled], dtype=np.int64)
        pattern = csr_matrix((np.ones(len(first)), (first, second)), shape=(rows, rows))
        order = reverse_cuthill_mckee(pattern, symmetric_mode=True) if rows else np.zeros(0, dtype=np.int64)
        self.position = np.empty(rows, dtype=np.int64)
        self.position[order] = np.arange(rows)
        width = int(np.abs(self.position[first] - self.position[second]).max(initial=0))
        self.band = np.array([1 if dyn.banded else 0, width], dtype=np.int64)
        self.start = np.empty(rows)
        self.start[self.position] = dyn.start
        # each row's columns, ascending: the three coordinates of each of its bodies
        self.row_columns = np.full((rows, 3 * SLOTS), -1, dtype=np.int64)
        self.row_width = np.zeros(rows, dtype=np.int64)
        for r in range(rows):
            columns = sorted({3 * k + i for k in self.row_body[r] if k >= 0 for i in range(3)})
            self.row_columns[r, : len(columns)] = columns
            self.row_width[r] = len(columns)

    def structure(self) -> tuple:
        """The band structure in :func:`integrate`'s ``structure`` order, then each
        row's columns (m, 3 SLOTS; -1 past ``row_width``) for :func:`_constrained`."""
        return (
            self.row_body,
            self.body_ptr,
            self.body_row,
            self.body_slot,
            self.position,
            self.band,
            self.start,
            self.row_columns,
            self.row_width,
        )

    def arrays(self) -> tuple:
        """The arrays in :func:`integrate`'s argument order."""
        return (
            self.mass,
            self.inertia,
            self.com,
            self.c_a,
            self.c_sa,
            self.c_b,
            self.c_sb,
            self.o_kind,
            self.o_bodies,
            self.o_geometry,
            self.o_offset,
            self.gravity,
            self.l_body,
            self.l_point,
            self.l_force,
            self.l_torque,
            self.s_body,
            self.s_point,
            self.s_law,
            self.row_is_angle,
            self.scale_rows,
            self.scale_coordinates,
            self.mass_scale,
            self.size,
            self.r_body,
            self.r_law,
            self.l_law,
        )


# -- the pieces, at one state -------------------------------------------------


@_internal
def _frame(q, body):
    """(x, y, cos phi, sin phi) of a body (the ground: 0, 0, 1, 0)."""
    if body < 0:
        return 0.0, 0.0, 1.0, 0.0
    phi = q[3 * body + 2]
    return q[3 * body], q[3 * body + 1], math.cos(phi), math.sin(phi)


@_internal
def _angle(q, body):
    """phi of a body (the ground: 0)."""
    return q[3 * body + 2] if body >= 0 else 0.0


@_internal
def _rate(qd, body):
    """(xd, yd, omega) of a body (the ground: zeros)."""
    if body < 0:
        return 0.0, 0.0, 0.0
    return qd[3 * body], qd[3 * body + 1], qd[3 * body + 2]


@_internal
def _residual(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, out):
    row = 0
    for t in range(len(c_a)):
        xa, ya, ca, sa = _frame(q, c_a[t])
        xb, yb, cb, sb = _frame(q, c_b[t])
        ax, ay = _turn(ca, sa, c_sa[t, 0], c_sa[t, 1])
        bx, by = _turn(cb, sb, c_sb[t, 0], c_sb[t, 1])
        out[row], out[row + 1] = _coincidence_residual(xa, ya, ax, ay, xb, yb, bx, by)
        row += 2
    g = o_geometry
    for t in range(len(o_kind)):
        a, b, c = o_bodies[t, 0], o_bodies[t, 1], o_bodies[t, 2]
        if o_kind[t] == ANGLES:
            pa, pb, pc = _angle(q, a), _angle(q, b), _angle(q, c)
            out[row] = _angles_residual(pa, pb, pc, g[t, 6], g[t, 7], g[t, 8], o_offset[t])
        else:
            xa, ya, ca, sa = _frame(q, a)
            xb, yb, cb, sb = _frame(q, b)
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            out[row] = _projection_residual(wx, wy, dx, dy)
        row += 1


@_internal
def _jacobian(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, out):
    """Phi_q into ``out`` (m, n): only its structural entries, the same at every
    call, are written; the rest of ``out`` must be zero (:func:`integrate`'s buffer
    is; zeroing it per call cost more than the banded solve on 81 bars)."""
    row = 0
    for t in range(len(c_a)):
        a, b = c_a[t], c_b[t]
        _, _, ca, sa = _frame(q, a)
        _, _, cb, sb = _frame(q, b)
        ax, ay = _turn(ca, sa, c_sa[t, 0], c_sa[t, 1])
        bx, by = _turn(cb, sb, c_sb[t, 0], c_sb[t, 1])
        a0, a1, b0, b1 = _coincidence_jacobian(ax, ay, bx, by)
        if a >= 0:
            k = 3 * a
            out[row, k], out[row + 1, k + 1] = 1.0, 1.0
            out[row, k + 2], out[row + 1, k + 2] = a0, a1
        if b >= 0:
            k = 3 * b
            out[row, k], out[row + 1, k + 1] = -1.0, -1.0
            out[row, k + 2], out[row + 1, k + 2] = b0, b1
        row += 2
    g = o_geometry
    for t in range(len(o_kind)):
        a, b = o_bodies[t, 0], o_bodies[t, 1]
        if o_kind[t] == ANGLES:
            for slot in range(SLOTS):
                body = o_bodies[t, slot]
                if body >= 0 and g[t, 6 + slot] != 0.0:
                    out[row, 3 * body + 2] = g[t, 6 + slot]
        else:
            xa, ya, ca, sa = _frame(q, a)
            xb, yb, cb, sb = _frame(q, b)
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            phi_b, phi_a = _projection_jacobian(wx, wy, qx, qy, px, py, dx, dy)
            if b >= 0:
                k = 3 * b
                out[row, k], out[row, k + 1], out[row, k + 2] = wx, wy, phi_b
            if a >= 0:
                k = 3 * a
                out[row, k], out[row, k + 1], out[row, k + 2] = -wx, -wy, phi_a
        row += 1


@_internal
def _gamma(q, qd, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, out):
    row = 0
    for t in range(len(c_a)):
        _, _, ca, sa = _frame(q, c_a[t])
        _, _, cb, sb = _frame(q, c_b[t])
        wa, wb = _rate(qd, c_a[t])[2], _rate(qd, c_b[t])[2]
        ax, ay = _turn(ca, sa, c_sa[t, 0], c_sa[t, 1])
        bx, by = _turn(cb, sb, c_sb[t, 0], c_sb[t, 1])
        out[row], out[row + 1] = _coincidence_gamma(ax, ay, wa, bx, by, wb)
        row += 2
    g = o_geometry
    for t in range(len(o_kind)):
        if o_kind[t] == ANGLES:
            out[row] = 0.0
        else:
            a, b = o_bodies[t, 0], o_bodies[t, 1]
            xa, ya, ca, sa = _frame(q, a)
            xb, yb, cb, sb = _frame(q, b)
            xda, yda, wa = _rate(qd, a)
            xdb, ydb, wb = _rate(qd, b)
            wx, wy = _turn(ca, sa, g[t, 4], g[t, 5])
            qx, qy = _turn(ca, sa, g[t, 0], g[t, 1])
            px, py = _turn(cb, sb, g[t, 2], g[t, 3])
            dx, dy = _projection_offset(xa, ya, qx, qy, xb, yb, px, py)
            out[row] = _projection_gamma(wx, wy, qx, qy, px, py, dx, dy, xda, yda, wa, xdb, ydb, wb)
        row += 1


@_internal
def _mass(q, mass, inertia, com, out):
    """M(q) into ``out`` (n, n): only its 3 x 3 diagonal blocks are written; the
    rest of ``out`` must be zero (:func:`integrate`'s buffer is)."""
    for i in range(len(mass)):
        k = 3 * i
        c, s = math.cos(q[k + 2]), math.sin(q[k + 2])
        ax, ay = c * com[i, 0] - s * com[i, 1], s * com[i, 0] + c * com[i, 1]
        m = mass[i]
        out[k, k] = out[k + 1, k + 1] = m
        out[k, k + 1] = out[k + 1, k] = 0.0
        out[k, k + 2] = out[k + 2, k] = -m * ay
        out[k + 1, k + 2] = out[k + 2, k + 1] = m * ax
        out[k + 2, k + 2] = inertia[i] + m * (com[i, 0] * com[i, 0] + com[i, 1] * com[i, 1])


@_internal
def _point(q, qd, body, s0, s1):
    """(x, y, vx, vy, arm x, arm y) of a point fixed in a body (or the ground)."""
    x, y, c, s = _frame(q, body)
    xd, yd, w = _rate(qd, body)
    ax, ay = c * s0 - s * s1, s * s0 + c * s1
    if body < 0:
        return s0, s1, 0.0, 0.0, 0.0, 0.0
    return x + ax, y + ay, xd - w * ay, yd + w * ax, ax, ay


@_internal
def _spring(q, qd, s_body, s_point, i):
    """(length, rate, unit x, unit y, first end's arm x, y, second end's arm x, y)."""
    px, py, vpx, vpy, apx, apy = _point(q, qd, s_body[i, 0], s_point[i, 0, 0], s_point[i, 0, 1])
    rx, ry, vrx, vry, arx, ary = _point(q, qd, s_body[i, 1], s_point[i, 1, 0], s_point[i, 1, 1])
    dx, dy = rx - px, ry - py
    length = math.hypot(dx, dy)
    ux, uy = (dx / length, dy / length) if length > 0.0 else (0.0, 0.0)
    return length, ux * (vrx - vpx) + uy * (vry - vpy), ux, uy, apx, apy, arx, ary


@_internal
def _twist(q, qd, r_body, r_law, i):
    """(phi_b - phi_a - rest, its rate) of rotational spring i, rad and rad/s."""
    a, b = r_body[i, 0], r_body[i, 1]
    angle = (q[3 * b + 2] if b >= 0 else 0.0) - (q[3 * a + 2] if a >= 0 else 0.0) - r_law[i, 1]
    rate = (qd[3 * b + 2] if b >= 0 else 0.0) - (qd[3 * a + 2] if a >= 0 else 0.0)
    return angle, rate


@_internal
def _law_factor(l_law, j, t):
    """Load j's time-law factor at t (s): 1 (constant), offset + sin(2 pi f t + phase)
    (harmonic) or min(t / duration, 1) (ramp); see ``model.LoadLaw``."""
    code = l_law[j, 0]
    if code == 1.0:
        return l_law[j, 3] + math.sin(2.0 * math.pi * l_law[j, 1] * t + l_law[j, 2])
    if code == 2.0:
        return min(t / l_law[j, 1], 1.0)
    return 1.0


@_internal
def _forces(
    q, qd, t, mass, com, gravity, l_body, l_point, l_force, l_torque, l_law, s_body, s_point, s_law, r_body, r_law, out
):
    out[:] = 0.0
    for i in range(len(mass)):
        k = 3 * i
        c, s = math.cos(q[k + 2]), math.sin(q[k + 2])
        ax, ay = c * com[i, 0] - s * com[i, 1], s * com[i, 0] + c * com[i, 1]
        m, w = mass[i], qd[k + 2]
        gx, gy = m * gravity[0], m * gravity[1]
        out[k] = gx + m * w * w * ax
        out[k + 1] = gy + m * w * w * ay
        out[k + 2] = ax * gy - ay * gx
    for j in range(len(l_body)):
        k = 3 * l_body[j]
        c, s = math.cos(q[k + 2]), math.sin(q[k + 2])
        ax, ay = c * l_point[j, 0] - s * l_point[j, 1], s * l_point[j, 0] + c * l_point[j, 1]
        factor = _law_factor(l_law, j, t)
        fx, fy = factor * l_force[j, 0], factor * l_force[j, 1]
        out[k] += fx
        out[k + 1] += fy
        out[k + 2] += ax * fy - ay * fx + factor * l_torque[j]
    for j in range(len(s_body)):
        length, rate, ux, uy, apx, apy, arx, ary = _spring(q, qd, s_body, s_point, j)
        tension = s_law[j, 0] * (length - s_law[j, 1]) + s_law[j, 2] * rate
        for body, ax, ay, sign in ((s_body[j, 0], apx, apy, 1.0), (s_body[j, 1], arx, ary, -1.0)):
            if body >= 0:
                k = 3 * body
                fx, fy = sign * tension * ux, sign * tension * uy
                out[k] += fx
                out[k + 1] += fy
                out[k + 2] += ax * fy - ay * fx
    for j in range(len(r_body)):
        angle, rate = _twist(q, qd, r_body, r_law, j)
        torque = -r_law[j, 0] * angle - r_law[j, 2] * rate  # on body b; body a gets its opposite
        if r_body[j, 1] >= 0:
            out[3 * r_body[j, 1] + 2] += torque
        if r_body[j, 0] >= 0:
            out[3 * r_body[j, 0] + 2] -= torque


@_internal
def _power(q, qd, t, l_body, l_point, l_force, l_torque, l_law, s_body, s_point, s_law, r_body, r_law):
    total = 0.0
    for j in range(len(l_body)):
        _, _, vx, vy, _, _ = _point(q, qd, l_body[j], l_point[j, 0], l_point[j, 1])
        factor = _law_factor(l_law, j, t)
        total += factor * (l_force[j, 0] * vx + l_force[j, 1] * vy + l_torque[j] * qd[3 * l_body[j] + 2])
    for j in range(len(s_body)):
        rate = _spring(q, qd, s_body, s_point, j)[1]
        total -= s_law[j, 2] * rate * rate
    for j in range(len(r_body)):
        rate = _twist(q, qd, r_body, r_law, j)[1]
        total -= r_law[j, 2] * rate * rate
    return total


@_internal
def _energy(q, qd, mass, inertia, com, gravity, s_body, s_point, s_law, r_body, r_law):
    kinetic, potential = 0.0, 0.0
    for i in range(len(mass)):
        k = 3 * i
        c, s = math.cos(q[k + 2]), math.sin(q[k + 2])
        ax, ay = c * com[i, 0] - s * com[i, 1], s * com[i, 0] + c * com[i, 1]
        m = mass[i]
        xd, yd, w = qd[k], qd[k + 1], qd[k + 2]
        rotational = inertia[i] + m * (com[i, 0] * com[i, 0] + com[i, 1] * com[i, 1])
        kinetic += 0.5 * (m * (xd * xd + yd * yd) + 2.0 * w * (-m * ay * xd + m * ax * yd) + rotational * w * w)
        potential -= m * ((q[k] + ax) * gravity[0] + (q[k + 1] + ay) * gravity[1])
    still = np.zeros_like(qd)
    for j in range(len(s_body)):
        length = _spring(q, still, s_body, s_point, j)[0]
        potential += 0.5 * s_law[j, 0] * (length - s_law[j, 1]) ** 2
    for j in range(len(r_body)):
        potential += 0.5 * r_law[j, 0] * _twist(q, qd, r_body, r_law, j)[0] ** 2
    return kinetic + potential


@_internal
def _cholesky(matrix, lower):
    """Write the lower Cholesky factor of the symmetric ``matrix`` (n, n) into
    ``lower``; False where it is not positive definite."""
    n = len(matrix)
    for j in range(n):
        total = matrix[j, j]
        for k in range(j):
            total -= lower[j, k] * lower[j, k]
        if not total > 0.0:
            return False
        lower[j, j] = math.sqrt(total)
        for i in range(j + 1, n):
            total = matrix[i, j]
            for k in range(j):
                total -= lower[i, k] * lower[j, k]
            lower[i, j] = total / lower[j, j]
        for i in range(j):
            lower[i, j] = 0.0
    return True


@_internal
def _cholesky_solve(lower, x):
    """Overwrite the columns of ``x`` (n, k) with the solutions of L L^T X = x."""
    n, k = x.shape
    for c in range(k):
        for i in range(n):
            total = x[i, c]
            for j in range(i):
                total -= lower[i, j] * x[j, c]
            x[i, c] = total / lower[i, i]
        for i in range(n - 1, -1, -1):
            total = x[i, c]
            for j in range(i + 1, n):
                total -= lower[j, i] * x[j, c]
            x[i, c] = total / lower[i, i]


@_internal
def _least_squares(matrix, rhs, cutoff):
    """(the minimum-norm least-squares solution of matrix x = rhs, singular values
    at most ``cutoff`` x the largest dropped, as LAPACK's gelsd; the singular values)."""
    u, singular, vt = np.linalg.svd(matrix)
    m = len(singular)
    projected = np.zeros(m)
    for i in range(m):
        if singular[i] > cutoff * singular[0]:
            total = 0.0
            for r in range(m):
                total += u[r, i] * rhs[r]
            projected[i] = total / singular[i]
    x = np.zeros(m)
    for j in range(m):
        total = 0.0
        for i in range(m):
            total += vt[i, j] * projected[i]
        x[j] = total
    return x, singular


@_internal
def _constrained(
    mass, jac, load, gap, measure, cutoff, last_measure, scale_rows, d, mass_scale, row_columns, row_width
):
    """As ``_Dynamics._constrained``: (x, singularity measure or NaN). The
    symmetric positive definite solves by Cholesky (plain loops, which at these
    sizes beat LAPACK's call overhead), the measure from the eigenvalues of
    J Mbar^-1 J^T, the least-squares solve by SVD only below
    :data:`LEAST_SQUARES_BELOW` (above it, it drops nothing and equals the plain solve).

    J enters only through each row's columns (``row_columns``, ascending: at most
    nine, where a dense loop visits all n), added in the order the dense sums
    take, so the results are those of the dense loops but for the sign of an
    exact zero."""
    m, n = jac.shape
    sj = np.empty((m, 3 * SLOTS))  # the scaled J on each row's columns
    for r in range(m):
        for e in range(row_width[r]):
            j = row_columns[r, e]
            sj[r, e] = jac[r, j] * scale_rows[r] / d[j]
    scaled_gap = scale_rows * gap
    augmented = np.empty((n, n))
    columns = np.zeros((n, 1 + m))  # the right-hand side (load, then J^T), then the solution
    for i in range(n):
        for j in range(n):
            augmented[i, j] = mass[i, j] / (d[i] * d[j] * mass_scale)
        columns[i, 0] = load[i] / (d[i] * mass_scale)
    for r in range(m):  # row by row, so each entry's sum runs over r in order, as the dense loops'
        for e in range(row_width[r]):
            i = row_columns[r, e]
            for f in range(row_width[r]):
                augmented[i, row_columns[r, f]] += sj[r, e] * sj[r, f]
            columns[i, 0] += sj[r, e] * scaled_gap[r]
            columns[i, 1 + r] = sj[r, e]
    lower = np.empty((n, n))
    if not _cholesky(augmented, lower):  # non-finite q, or a direction with no mass and no constraint
        return np.full(n, np.nan), math.nan
    _cholesky_solve(lower, columns)
    schur = np.empty((m, m))
    rhs = np.empty(m)
    for r in range(m):
        for c in range(m):
            total = 0.0
            for e in range(row_width[r]):
                total += sj[r, e] * columns[row_columns[r, e], 1 + c]
            schur[r, c] = total
        total = scaled_gap[r]
        for e in range(row_width[r]):
            total -= sj[r, e] * columns[row_columns[r, e], 0]
        rhs[r] = total
    singularity = math.nan
    plain = last_measure > LEAST_SQUARES_BELOW
    if measure:  # sqrt(smallest / largest eigenvalue) of the symmetric positive semi-definite schur
        values = np.linalg.eigvalsh(0.5 * (schur + schur.T))
        singularity = math.sqrt(max(values[0], 0.0) / values[-1]) if values[-1] > 0.0 else 0.0
        plain = singularity > LEAST_SQUARES_BELOW
    multipliers = np.empty(m)
    lower = np.empty((m, m))
    if plain and _cholesky(schur, lower):  # away from singular configurations a plain solve does
        column = rhs.reshape(m, 1)
        _cholesky_solve(lower, column)
        multipliers[:] = column[:, 0]
    else:
        multipliers, singular = _least_squares(schur, rhs, cutoff)
        if measure:
            singularity = math.sqrt(singular[-1] / singular[0])
    x = np.empty(n)
    for j in range(n):
        total = columns[j, 0]
        for r in range(m):
            total += columns[j, 1 + r] * multipliers[r]
        x[j] = total / d[j]
    return x, singularity


@_internal
def _augmented_measure(smallest, largest):
    """As ``_free.augmented_measure``."""
    if not largest > 0.0:
        return 0.0
    smallest = max(smallest, 0.0)
    return math.sqrt((smallest / (1.0 + smallest)) / (largest / (1.0 + largest)))


@_internal
def _band_cholesky(matrix, lower, band):
    """The lower Cholesky factor of the symmetric ``matrix`` (m, m) of half-bandwidth
    ``band`` into ``lower`` (only its band is written); False where it is not positive definite."""
    m = len(matrix)
    for j in range(m):
        low = max(0, j - band)
        total = matrix[j, j]
        for k in range(low, j):
            total -= lower[j, k] * lower[j, k]
        if not total > 0.0:
            return False
        pivot = math.sqrt(total)
        lower[j, j] = pivot
        for i in range(j + 1, min(m, j + band + 1)):
            total = matrix[i, j]
            for k in range(max(low, i - band), j):
                total -= lower[i, k] * lower[j, k]
            lower[i, j] = total / pivot
    return True


@_internal
def _band_solve(lower, band, x):
    """Overwrite ``x`` (m,) with the solution of L L^T y = x, L banded."""
    m = len(x)
    for i in range(m):
        total = x[i]
        for j in range(max(0, i - band), i):
            total -= lower[i, j] * x[j]
        x[i] = total / lower[i, i]
    for i in range(m - 1, -1, -1):
        total = x[i]
        for j in range(i + 1, min(m, i + band + 1)):
            total -= lower[j, i] * x[j]
        x[i] = total / lower[i, i]


@_internal
def _band_times(matrix, band, x):
    """matrix @ x for a banded (m, m) matrix."""
    m = len(x)
    out = np.zeros(m)
    for i in range(m):
        for j in range(max(0, i - band), min(m, i + band + 1)):
            out[i] += matrix[i, j] * x[j]
    return out


@_internal
def _band_measure(schur, lower, band, start):
    """As ``_free._iterated_measure``, on the banded ``schur`` and its factor."""
    v = start / math.sqrt(np.dot(start, start))
    for _ in range(EIGEN_ITERATIONS):
        _band_solve(lower, band, v)
        v /= math.sqrt(np.dot(v, v))
    w = start / math.sqrt(np.dot(start, start))
    for _ in range(EIGEN_ITERATIONS):
        w = _band_times(schur, band, w)
        w /= math.sqrt(np.dot(w, w))
    return _augmented_measure(np.dot(v, _band_times(schur, band, v)), np.dot(w, _band_times(schur, band, w)))


@_internal
def _banded_schur(mass, jac, load, gap, scale_rows, d, mass_scale, structure, work):
    """J M^-1 J^T (scaled) assembled in the rows' banded order into ``work[0]``, for
    :func:`_constrained_banded`: (M^-1 load (n,), M^-1 applied to each row's scaled J on
    its bodies (m, SLOTS, 3), the multipliers' right-hand side in banded order (m,))."""
    row_body, body_ptr, body_row, body_slot, position, band_info, start, _, _ = structure
    schur = work[0]
    band = band_info[1]
    m, n = jac.shape
    bodies = n // 3
    inverse = np.empty((bodies, 3, 3))
    free = np.empty(n)
    block = np.empty((3, 3))
    for k in range(bodies):
        o = 3 * k
        for i in range(3):
            for j in range(3):
                block[i, j] = mass[o + i, o + j] / (d[o + i] * d[o + j] * mass_scale)
        c00 = block[1, 1] * block[2, 2] - block[1, 2] * block[2, 1]
        c01 = block[1, 2] * block[2, 0] - block[1, 0] * block[2, 2]
        c02 = block[1, 0] * block[2, 1] - block[1, 1] * block[2, 0]
        det = block[0, 0] * c00 + block[0, 1] * c01 + block[0, 2] * c02
        inverse[k, 0, 0], inverse[k, 1, 0], inverse[k, 2, 0] = c00 / det, c01 / det, c02 / det
        inverse[k, 0, 1] = (block[0, 2] * block[2, 1] - block[0, 1] * block[2, 2]) / det
        inverse[k, 1, 1] = (block[0, 0] * block[2, 2] - block[0, 2] * block[2, 0]) / det
        inverse[k, 2, 1] = (block[0, 1] * block[2, 0] - block[0, 0] * block[2, 1]) / det
        inverse[k, 0, 2] = (block[0, 1] * block[1, 2] - block[0, 2] * block[1, 1]) / det
        inverse[k, 1, 2] = (block[0, 2] * block[1, 0] - block[0, 0] * block[1, 2]) / det
        inverse[k, 2, 2] = (block[0, 0] * block[1, 1] - block[0, 1] * block[1, 0]) / det
        for i in range(3):
            total = 0.0
            for j in range(3):
                total += inverse[k, i, j] * load[o + j] / (d[o + j] * mass_scale)
            free[o + i] = total
    rows = np.zeros((m, SLOTS, 3))  # scaled J on each row's bodies
    solved = np.zeros((m, SLOTS, 3))  # M^-1 applied to them
    rhs = np.empty(m)
    for r in range(m):
        total = scale_rows[r] * gap[r]
        for slot in range(SLOTS):
            k = row_body[r, slot]
            if k < 0:
                continue
            for i in range(3):
                rows[r, slot, i] = jac[r, 3 * k + i] * scale_rows[r] / d[3 * k + i]
            for i in range(3):
                solved[r, slot, i] = (
                    inverse[k, i, 0] * rows[r, slot, 0]
                    + inverse[k, i, 1] * rows[r, slot, 1]
                    + inverse[k, i, 2] * rows[r, slot, 2]
                )
                total -= rows[r, slot, i] * free[3 * k + i]
        rhs[position[r]] = total
    for i in range(m):  # outside its band schur stays zero (integrate's buffer starts so)
        for j in range(max(0, i - band), min(m, i + band + 1)):
            schur[i, j] = 0.0
    for k in range(bodies):
        for e in range(body_ptr[k], body_ptr[k + 1]):
            r, sr = body_row[e], body_slot[e]
            for f in range(body_ptr[k], body_ptr[k + 1]):
                c, sc = body_row[f], body_slot[f]
                schur[position[r], position[c]] += (
                    rows[r, sr, 0] * solved[c, sc, 0]
                    + rows[r, sr, 1] * solved[c, sc, 1]
                    + rows[r, sr, 2] * solved[c, sc, 2]
                )
    return free, solved, rhs


@_internal
def _constrained_banded(
    mass, jac, load, gap, measure, cutoff, last_measure, scale_rows, d, mass_scale, structure, work
):
    """As ``_Dynamics._constrained_banded``: (x, singularity measure or NaN). M^-1 by
    3 x 3 blocks, J by its (at most three) bodies per row, J M^-1 J^T assembled body
    by body in the rows' banded order and factored as banded; the least-squares
    solve (dense SVD) only where that factor does not exist or below
    :data:`BANDED_LEAST_SQUARES_BELOW`."""
    row_body, body_ptr, body_row, body_slot, position, band_info, start, _, _ = structure
    schur, lower = work
    band = band_info[1]
    m, n = jac.shape
    bodies = n // 3
    free, solved, rhs = _banded_schur(mass, jac, load, gap, scale_rows, d, mass_scale, structure, work)
    factored = _band_cholesky(schur, lower, band)
    singularity = math.nan
    plain = last_measure > BANDED_LEAST_SQUARES_BELOW
    if measure:
        singularity = _band_measure(schur, lower, band, start) if factored else 0.0
        plain = singularity > BANDED_LEAST_SQUARES_BELOW
    if plain and factored:
        multipliers = rhs.copy()
        _band_solve(lower, band, multipliers)
    else:
        multipliers, singular = _least_squares(schur, rhs, cutoff)
        if measure:
            singularity = _augmented_measure(singular[-1], singular[0])
    x = np.empty(n)
    for k in range(bodies):
        for i in range(3):
            total = free[3 * k + i]
            for e in range(body_ptr[k], body_ptr[k + 1]):
                r, slot = body_row[e], body_slot[e]
                total += solved[r, slot, i] * multipliers[position[r]]
            x[3 * k + i] = total / d[3 * k + i]
    return x, singularity


@_internal
def _banded_measure(mass, jac, scale_rows, d, mass_scale, structure, work):
    """The singularity measure of :func:`_constrained_banded` alone (0 where J M^-1 J^T has no
    Cholesky factor), never through its least-squares fallback."""
    _banded_schur(mass, jac, np.zeros(jac.shape[1]), np.zeros(jac.shape[0]), scale_rows, d, mass_scale, structure, work)
    schur, lower = work
    band = structure[5][1]
    if not _band_cholesky(schur, lower, band):
        return 0.0
    return _band_measure(schur, lower, band, structure[6])


@_internal
def _solve(mass, jac, load, gap, measure, cutoff, last_measure, scale_rows, d, mass_scale, structure, work):
    """``_constrained_banded`` where the structure says banded, else ``_constrained``."""
    if structure[5][0] > 0:
        return _constrained_banded(
            mass, jac, load, gap, measure, cutoff, last_measure, scale_rows, d, mass_scale, structure, work
        )
    return _constrained(
        mass, jac, load, gap, measure, cutoff, last_measure, scale_rows, d, mass_scale, structure[7], structure[8]
    )


@_internal
def _times(matrix, vector):
    """matrix @ vector, (m, n) by (n,)."""
    out = np.zeros(matrix.shape[0])
    for i in range(matrix.shape[0]):
        for j in range(matrix.shape[1]):
            out[i] += matrix[i, j] * vector[j]
    return out


@_internal
def _rows_times(jac, vector, structure):
    """jac @ vector, (m, n) by (n,); on the banded path through each row's (at most three) bodies."""
    if structure[5][0] == 0:
        return _times(jac, vector)
    row_body = structure[0]
    out = np.zeros(jac.shape[0])
    for r in range(jac.shape[0]):
        for slot in range(SLOTS):
            k = row_body[r, slot]
            if k >= 0:
                for i in range(3 * k, 3 * k + 3):
                    out[r] += jac[r, i] * vector[i]
    return out


@_internal
def _acceleration(model, structure, work, buffers, last_measure, q, qd, t):
    """q'' by Gauss's principle (``_Dynamics.acceleration``)."""
    (mass, inertia, com, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, gravity,
     l_body, l_point, l_force, l_torque, s_body, s_point, s_law, _, scale_rows, d, mass_scale, _,
     r_body, r_law, l_law) = model  # fmt: skip
    m_buf, j_buf, _, g_buf, f_buf = buffers
    _mass(q, mass, inertia, com, m_buf)
    _jacobian(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, j_buf)
    _forces(
        q, qd, t, mass, com, gravity, l_body, l_point, l_force, l_torque, l_law, s_body, s_point, s_law, r_body, r_law,
        f_buf,
    )  # fmt: skip
    _gamma(q, qd, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, g_buf)
    return _solve(
        m_buf, j_buf, f_buf, g_buf, NO, RANK_CUTOFF, last_measure, scale_rows, d, mass_scale, structure, work
    )[0]


@_internal
def _residual_metres(model, buffers, q):
    """The largest loop-closure violation, m (angles times the size)."""
    (_, _, _, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, _,
     _, _, _, _, _, _, _, row_is_angle, _, _, _, size, _, _, _) = model  # fmt: skip
    r_buf = buffers[2]
    _residual(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, r_buf)
    largest = 0.0
    for i in range(len(r_buf)):
        largest = max(largest, abs(r_buf[i]) * (size if row_is_angle[i] else 1.0))
    return largest


@_internal
def _project(model, structure, work, buffers, q, qd):
    """(q, qd) moved onto the constraints (``_Dynamics.project``): (q, qd, violation before, measure)."""
    (mass, inertia, com, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, _,
     _, _, _, _, _, _, _, _, scale_rows, d, mass_scale, size, _, _, _) = model  # fmt: skip
    m_buf, j_buf, r_buf, _, _ = buffers
    zero = np.zeros(len(q))
    before = _residual_metres(model, buffers, q)
    gap, tolerance = before, PROJECTION_TOLERANCE * size
    for _ in range(PROJECTION_ITERATIONS):
        if gap <= tolerance:
            break
        _mass(q, mass, inertia, com, m_buf)
        _jacobian(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, j_buf)
        _residual(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, o_offset, r_buf)
        step = _solve(
            m_buf, j_buf, zero, -r_buf, YES, PROJECTION_CUTOFF, 0.0, scale_rows, d, mass_scale, structure, work
        )[0]
        q = q + step
        gap = _residual_metres(model, buffers, q)
    _mass(q, mass, inertia, com, m_buf)
    _jacobian(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, j_buf)
    correction, singular = _solve(
        m_buf,
        j_buf,
        zero,
        -_rows_times(j_buf, qd, structure),
        YES,
        PROJECTION_CUTOFF,
        0.0,
        scale_rows,
        d,
        mass_scale,
        structure,
        work,
    )
    return q, qd + correction, before, singular


@_internal
def _jacobian_of(model, q, out):
    """Phi_q at q into ``out`` (m, n; its non-structural entries must be zero)."""
    (_, _, _, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, _, _,
     _, _, _, _, _, _, _, _, _, _, _, _, _, _, _) = model  # fmt: skip
    _jacobian(q, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, out)


@_internal
def _gamma_of(model, q, qd, out):
    """gamma = Phi_q q'' at (q, qd) into ``out`` (m,)."""
    (_, _, _, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, _, _,
     _, _, _, _, _, _, _, _, _, _, _, _, _, _, _) = model  # fmt: skip
    _gamma(q, qd, c_a, c_sa, c_b, c_sb, o_kind, o_bodies, o_geometry, out)


@_internal
def _mass_of(model, q, out):
    """M(q) into ``out`` (n, n; only its 3 x 3 diagonal blocks are written)."""
    _mass(q, model[0], model[1], model[2], out)


@_internal
def _forces_of(model, q, qd, t, out):
    """Q at time t (s) into ``out`` (n,): gravity, loads, springs, dampers and M's velocity terms."""
    (mass, _, com, _, _, _, _, _, _, _, _, gravity,
     l_body, l_point, l_force, l_torque, s_body, s_point, s_law, _, _, _, _, _,
     r_body, r_law, l_law) = model  # fmt: skip
    _forces(
        q, qd, t, mass, com, gravity, l_body, l_point, l_force, l_torque, l_law, s_body, s_point, s_law, r_body, r_law,
        out,
    )  # fmt: skip


@_internal
def _energy_of(model, q, qd):
    """T + V, J."""
    (mass, inertia, com, _, _, _, _, _, _, _, _, gravity,
     _, _, _, _, s_body, s_point, s_law, _, _, _, _, _, r_body, r_law, _) = model  # fmt: skip
    return _energy(q, qd, mass, inertia, com, gravity, s_body, s_point, s_law, r_body, r_law)


@_internal
def _power_of(model, q, qd, t):
    """Power of the loads at t (s) and of the dampers, W."""
    (_, _, _, _, _, _, _, _, _, _, _, _,
     l_body, l_point, l_force, l_torque, s_body, s_point, s_law,
     _, _, _, _, _, r_body, r_law, l_law) = model  # fmt: skip
    return _power(q, qd, t, l_body, l_point, l_force, l_torque, l_law, s_body, s_point, s_law, r_body, r_law)


@njit(cache=True)
def integrate(model, structure, q0, qd0, h, per_output, outputs, output_step):
    """One integration (see ``_free.simulate_free``).

    Parameters
    ----------
    model : tuple
        :meth:`Packed.arrays`.
    structure : tuple
        :meth:`Packed.structure`.
    q0, qd0 : (n,)
        The consistent initial state.
    h : float
        The step, s; ``per_output`` steps per output, ``outputs`` outputs
        ``output_step`` (s) apart.

    Returns
    -------
    q_out, qd_out, qdd_out : (outputs + 1, n); residual, energy, work : (outputs + 1,);
    passes : (P,) times of singular passes, s; failed : the output index at
    which the state went non-finite, or -1.
    """
    n, rows = len(q0), len(model[20])
    buffers = (np.zeros((n, n)), np.zeros((rows, n)), np.empty(rows), np.empty(rows), np.empty(n))
    q_out, qd_out, qdd_out = np.empty((outputs + 1, n)), np.empty((outputs + 1, n)), np.empty((outputs + 1, n))
    residual, energy, work = np.zeros(outputs + 1), np.empty(outputs + 1), np.zeros(outputs + 1)
    side = rows if structure[5][0] > 0 else 0
    scratch = (np.zeros((side, side)), np.empty((side, side)))  # J M^-1 J^T and its factor, banded path
    found, count = np.empty(16), 0
    q, qd = q0.copy(), qd0.copy()
    w = 0.0
    q, qd, _, measure = _project(model, structure, scratch, buffers, q, qd)
    sigma0 = sigma1 = measure
    q, qd = q0.copy(), qd0.copy()  # as the NumPy integrator: the start is used as given
    q_out[0], qd_out[0] = q, qd
    qdd_out[0] = _acceleration(model, structure, scratch, buffers, measure, q, qd, 0.0)
    energy[0] = _energy_of(model, q, qd)
    for i in range(1, outputs + 1):
        drift = 0.0
        for j in range(per_output):
            t = (i - 1) * output_step + j * h
            a1, p1 = _acceleration(model, structure, scratch, buffers, measure, q, qd, t), _power_of(model, q, qd, t)
            q2, qd2 = q + 0.5 * h * qd, qd + 0.5 * h * a1
            half = t + 0.5 * h
            a2, p2 = (
                _acceleration(model, structure, scratch, buffers, measure, q2, qd2, half),
                _power_of(model, q2, qd2, half),
            )
            q3, qd3 = q + 0.5 * h * qd2, qd + 0.5 * h * a2
            a3, p3 = (
                _acceleration(model, structure, scratch, buffers, measure, q3, qd3, half),
                _power_of(model, q3, qd3, half),
            )
            q4, qd4 = q + h * qd3, qd + h * a3
            a4, p4 = (
                _acceleration(model, structure, scratch, buffers, measure, q4, qd4, t + h),
                _power_of(model, q4, qd4, t + h),
            )
            q = q + h / 6.0 * (qd + 2.0 * qd2 + 2.0 * qd3 + qd4)
            qd = qd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            w += h / 6.0 * (p1 + 2.0 * p2 + 2.0 * p3 + p4)
            q, qd, before, measure = _project(model, structure, scratch, buffers, q, qd)
            drift = max(drift, before)
            if sigma1 < SINGULAR_THRESHOLD and sigma1 <= sigma0 and sigma1 < measure:
                if count == len(found):
                    found = np.concatenate((found, np.empty(len(found))))
                found[count] = t  # the previous step was the closest
                count += 1
            sigma0, sigma1 = sigma1, measure
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
            return q_out, qd_out, qdd_out, residual, energy, work, found[:count], i
        q_out[i], qd_out[i] = q, qd
        qdd_out[i] = _acceleration(model, structure, scratch, buffers, measure, q, qd, i * output_step)
        residual[i], energy[i], work[i] = drift, _energy_of(model, q, qd), w
    return q_out, qd_out, qdd_out, residual, energy, work, found[:count], -1
