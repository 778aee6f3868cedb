"""The constraint equations of every kind of row, written once.

Every joint type turns into a few constraint terms of three kinds; this module
holds their residuals, Jacobian entries and acceleration right-hand sides
(gamma = -(Phi_q qd)_q qd). The functions use only arithmetic, so the same
definition serves the NumPy path (arrays of samples or of joints, any float
type) and both compiled paths (numba compiles them for scalars and inlines
them into the kernels of ``kinematics._compiled`` and ``dynamics._free_compiled``).

Arguments are the global-frame quantities of a term's bodies: frame origins
``(x, y)``, angles ``p``, rates ``(xd, yd)`` and ``w`` (angular), and body
vectors already turned into the global frame by :func:`turn`. Body ``a`` is the
first body of a term, ``b`` the second, ``c`` a third (angle terms only); the
ground has zeros.

Kinds
-----
coincidence (2 rows, m)
    r_a + A_a s_a - r_b - A_b s_b = 0: a point of a on a point of b.
projection (1 row, m)
    w . (r_P - r_Q) = input: the offset of point P (body b) from point Q
    (body a) along a unit vector w fixed in body a.
angles (1 row, rad or m)
    k_a phi_a + k_b phi_b + k_c phi_c = offset + input: a linear relation of
    up to three bodies' angles (a locked or driven relative angle; a gear
    pair's arcs on its pitch circles).
"""

from __future__ import annotations

__all__ = [
    "turn",
    "coincidence_residual",
    "coincidence_jacobian",
    "coincidence_gamma",
    "projection_offset",
    "projection_residual",
    "projection_jacobian",
    "projection_gamma",
    "angles_residual",
]


def turn(c, s, x, y):
    """A(phi) (x, y) from c = cos phi, s = sin phi: a body vector in the global frame."""
    return c * x - s * y, s * x + c * y


def coincidence_residual(xa, ya, ax, ay, xb, yb, bx, by):
    """The two rows r_a + A_a s_a - r_b - A_b s_b (m), with (ax, ay) = A_a s_a, (bx, by) = A_b s_b."""
    return xa + ax - xb - bx, ya + ay - yb - by


def coincidence_jacobian(ax, ay, bx, by):
    """The angle entries of Phi_q: (row x, row y) by phi_a, then by phi_b.

    The position entries are the identity for body a and minus it for body b.
    """
    return -ay, ax, by, -bx


def coincidence_gamma(ax, ay, wa, bx, by, wb):
    """gamma of the two rows (m/s^2): the centripetal terms of both points."""
    return ax * (wa * wa) - bx * (wb * wb), ay * (wa * wa) - by * (wb * wb)


def projection_offset(xa, ya, qx, qy, xb, yb, px, py):
    """d = r_P - r_Q (m), with (qx, qy) = A_a s_Q and (px, py) = A_b s_P."""
    return xb + px - xa - qx, yb + py - ya - qy


def projection_residual(wx, wy, dx, dy):
    """w . d (m), with (wx, wy) = A_a w and d from :func:`projection_offset`; the
    caller subtracts a driver's input."""
    return wx * dx + wy * dy


def projection_jacobian(wx, wy, qx, qy, px, py, dx, dy):
    """The angle entries of Phi_q: (by phi_b, by phi_a).

    The position entries are (wx, wy) for body b and (-wx, -wy) for body a.
    """
    return wx * -py + wy * px, (-wy * dx + wx * dy) - (wx * -qy + wy * qx)


def projection_gamma(wx, wy, qx, qy, px, py, dx, dy, xda, yda, wa, xdb, ydb, wb):
    """gamma of the row (m/s^2); the caller adds a driver's input acceleration."""
    ddx = xdb + wb * -py - xda - wa * -qy
    ddy = ydb + wb * px - yda - wa * qx
    quadratic = (
        -(wa * wa) * (wx * dx + wy * dy)
        + 2.0 * wa * (-wy * ddx + wx * ddy)
        - (wb * wb) * (wx * px + wy * py)
        + (wa * wa) * (wx * qx + wy * qy)
    )
    return -quadratic


def angles_residual(pa, pb, pc, ka, kb, kc, offset):
    """k_a phi_a + k_b phi_b + k_c phi_c - offset; the caller subtracts a driver's
    input. Its Jacobian entries are the coefficients, its gamma zero."""
    return ka * pa + kb * pb + kc * pc - offset
