"""Constraint terms: the rows a joint or a driver adds, evaluated over N samples.

A term holds its bodies' indices (-1: the ground) and its geometry in body
frames; :mod:`._equations` holds its equations. Everything is vectorised over
a leading sample axis: ``q`` has shape (N, n), ``c`` (the drivers' inputs)
shape (N, k). The compiled kernels read the same terms through :meth:`packed`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _equations as eq

__all__ = [
    "COINCIDENCE",
    "PROJECTION",
    "ANGLES",
    "GEOMETRY",
    "Poses",
    "Term",
    "Coincidence",
    "Projection",
    "Angles",
    "relative_angle",
    "rotate",
]

#: term kinds, as the compiled kernels know them
COINCIDENCE, PROJECTION, ANGLES = 0, 1, 2
#: a term's geometry in :meth:`Term.packed`: nine numbers, the first body's
#: point (0:2), the second body's point (2:4), a direction (4:6), three angle
#: coefficients (6:9); a kind uses its own
GEOMETRY = 9


def rotate(phi, s) -> np.ndarray:
    """A(phi) s: a body vector s (2,) turned by phi (rad, a scalar or shape (N,));
    returns shape (2,) or (N, 2)."""
    return _rotate_cs(np.cos(phi), np.sin(phi), s)


def _rotate_cs(c: np.ndarray, sn: np.ndarray, s: np.ndarray) -> np.ndarray:
    # long double stays long double (polishing), anything else is double
    wide = any(np.asarray(v).dtype == np.longdouble for v in (c, sn, s))
    out = np.empty(np.shape(c) + (2,), dtype=np.longdouble if wide else float)
    out[..., 0], out[..., 1] = eq.turn(c, sn, s[0], s[1])
    return out


class Poses:
    """Body frames' positions, angles (with cosines and sines computed once)
    and rates across N samples; index -1 is the ground."""

    def __init__(self, q: np.ndarray, qd: np.ndarray | None = None):
        n_samples, n = q.shape
        q3 = q.reshape(n_samples, n // 3, 3)
        self.n_samples = n_samples
        self.r, self.phi = q3[..., :2], q3[..., 2]
        self.cos, self.sin = np.cos(self.phi), np.sin(self.phi)
        if qd is not None:
            qd3 = qd.reshape(n_samples, n // 3, 3)
            self.rd, self.phid = qd3[..., :2], qd3[..., 2]

    def frame(self, index: int):
        """(r (N, 2), phi (N,)) of one body."""
        if index < 0:
            return np.zeros((self.n_samples, 2)), np.zeros(self.n_samples)
        return self.r[:, index], self.phi[:, index]

    def rates(self, index: int):
        """(r_dot (N, 2), phi_dot (N,)) of one body."""
        if index < 0:
            return np.zeros((self.n_samples, 2)), np.zeros(self.n_samples)
        return self.rd[:, index], self.phid[:, index]

    def rotate(self, index: int, s: np.ndarray) -> np.ndarray:
        """A(phi) s of one body, shape (N, 2)."""
        if index < 0:
            return np.broadcast_to(s, (self.n_samples, 2))
        return _rotate_cs(self.cos[:, index], self.sin[:, index], s)


@dataclass(frozen=True)
class Term:
    """What every term has: its rows, whether they are angles (rad) or lengths
    (m), and the driver whose input it prescribes (None for a joint's term)."""

    rows = 1
    is_angle = False

    @property
    def bodies(self) -> tuple[int, ...]:
        """The bodies whose coordinates the term's rows involve (-1: the ground)."""
        raise NotImplementedError

    def packed(self) -> tuple[int, tuple[int, int, int], np.ndarray, float]:
        """(kind, three body indices (-1: none or the ground), geometry (GEOMETRY,), offset)."""
        raise NotImplementedError

    def residual(self, poses: Poses, c: np.ndarray) -> np.ndarray:
        """Its rows of Phi(q, c), (N, rows)."""
        raise NotImplementedError

    def jacobian(self, poses: Poses, out: np.ndarray) -> None:
        """Its rows of Phi_q into ``out`` (N, rows, n), zero where not written."""
        raise NotImplementedError

    def gamma(self, poses: Poses, cdd: np.ndarray) -> np.ndarray:
        """Its rows of gamma, (N, rows), with the drivers' input accelerations ``cdd`` (N, k)."""
        raise NotImplementedError


def _geometry(*parts: tuple[int, object]) -> np.ndarray:
    out = np.zeros(GEOMETRY)
    for start, values in parts:
        values = np.asarray(values, dtype=float).ravel()
        out[start : start + len(values)] = values
    return out


@dataclass(frozen=True)
class Coincidence(Term):
    """Point s_a of body a coincides with point s_b of body b (2 rows, metres)."""

    a: int
    s_a: np.ndarray
    b: int
    s_b: np.ndarray
    driver: None = None
    rows = 2

    @property
    def bodies(self) -> tuple[int, ...]:
        return (self.a, self.b)

    def packed(self):
        return COINCIDENCE, (self.a, self.b, -1), _geometry((0, self.s_a), (2, self.s_b)), 0.0

    def residual(self, poses, c):
        (xa, ya), (xb, yb) = poses.frame(self.a)[0].T, poses.frame(self.b)[0].T
        (ax, ay), (bx, by) = poses.rotate(self.a, self.s_a).T, poses.rotate(self.b, self.s_b).T
        return np.stack(eq.coincidence_residual(xa, ya, ax, ay, xb, yb, bx, by), axis=1)

    def jacobian(self, poses, out):
        (ax, ay), (bx, by) = poses.rotate(self.a, self.s_a).T, poses.rotate(self.b, self.s_b).T
        a0, a1, b0, b1 = eq.coincidence_jacobian(ax, ay, bx, by)
        for index, sign, angle in ((self.a, 1.0, (a0, a1)), (self.b, -1.0, (b0, b1))):
            if index < 0:
                continue
            k = 3 * index
            out[:, 0, k] = sign
            out[:, 1, k + 1] = sign
            out[:, 0, k + 2], out[:, 1, k + 2] = angle

    def gamma(self, poses, cdd):
        (ax, ay), (bx, by) = poses.rotate(self.a, self.s_a).T, poses.rotate(self.b, self.s_b).T
        wa, wb = poses.rates(self.a)[1], poses.rates(self.b)[1]
        return np.stack(eq.coincidence_gamma(ax, ay, wa, bx, by, wb), axis=1)


@dataclass(frozen=True)
class Projection(Term):
    """w . (r_P - r_Q) = c: the offset of point P (body b) from point Q (body a)
    along a unit vector w fixed in body a (1 row, metres).

    With w the normal of a line, c = 0: P stays on the line. With w its
    direction and c a driver's input: the slide displacement is prescribed.
    """

    a: int
    s_q: np.ndarray
    w: np.ndarray
    b: int
    s_p: np.ndarray
    driver: int | None = None

    @property
    def bodies(self) -> tuple[int, ...]:
        return (self.a, self.b)

    def packed(self):
        geometry = _geometry((0, self.s_q), (2, self.s_p), (4, self.w))
        return PROJECTION, (self.a, self.b, -1), geometry, 0.0

    def _parts(self, poses):
        (wx, wy), (qx, qy) = poses.rotate(self.a, self.w).T, poses.rotate(self.a, self.s_q).T
        px, py = poses.rotate(self.b, self.s_p).T
        (xa, ya), (xb, yb) = poses.frame(self.a)[0].T, poses.frame(self.b)[0].T
        return (wx, wy, qx, qy, px, py, *eq.projection_offset(xa, ya, qx, qy, xb, yb, px, py))

    def residual(self, poses, c):
        wx, wy, *_, dx, dy = self._parts(poses)
        value = eq.projection_residual(wx, wy, dx, dy)
        if self.driver is not None:
            value = value - c[:, self.driver]
        return value[:, None]

    def jacobian(self, poses, out):
        parts = self._parts(poses)
        phi_b, phi_a = eq.projection_jacobian(*parts)
        wx, wy = parts[0], parts[1]
        if self.b >= 0:
            k = 3 * self.b
            out[:, 0, k], out[:, 0, k + 1], out[:, 0, k + 2] = wx, wy, phi_b
        if self.a >= 0:
            k = 3 * self.a
            out[:, 0, k], out[:, 0, k + 1], out[:, 0, k + 2] = -wx, -wy, phi_a

    def gamma(self, poses, cdd):
        (rd_a, wa), (rd_b, wb) = poses.rates(self.a), poses.rates(self.b)
        (xda, yda), (xdb, ydb) = rd_a.T, rd_b.T
        wx, wy, qx, qy, px, py, dx, dy = self._parts(poses)
        value = eq.projection_gamma(wx, wy, qx, qy, px, py, dx, dy, xda, yda, wa, xdb, ydb, wb)
        if self.driver is not None:
            value = value + cdd[:, self.driver]
        return value[:, None]


@dataclass(frozen=True)
class Angles(Term):
    """k_a phi_a + k_b phi_b + k_c phi_c = offset + c (1 row): radians for a
    relative angle (coefficients -1, 1, 0), metres for a gear pair's arcs.

    ``c`` is -1 (the ground, coefficient 0) where only two bodies take part.
    """

    a: int
    b: int
    c: int = -1
    coefficients: tuple[float, float, float] = (-1.0, 1.0, 0.0)
    offset: float = 0.0
    driver: int | None = None
    is_angle: bool = True

    @property
    def bodies(self) -> tuple[int, ...]:
        return (self.a, self.b, self.c)

    def packed(self):
        return ANGLES, (self.a, self.b, self.c), _geometry((6, self.coefficients)), float(self.offset)

    def residual(self, poses, c):
        ka, kb, kc = self.coefficients
        pa, pb, pc = (poses.frame(index)[1] for index in self.bodies)
        value = eq.angles_residual(pa, pb, pc, ka, kb, kc, self.offset)
        if self.driver is not None:
            value = value - c[:, self.driver]
        return value[:, None]

    def jacobian(self, poses, out):
        for index, k in zip(self.bodies, self.coefficients):
            if index >= 0 and k != 0.0:
                out[:, 0, 3 * index + 2] = k

    def gamma(self, poses, cdd):
        value = np.zeros(poses.n_samples)
        if self.driver is not None:
            value = value + cdd[:, self.driver]
        return value[:, None]


def relative_angle(a: int, b: int, offset: float = 0.0, driver: int | None = None) -> Angles:
    """phi_b - phi_a = offset + c (1 row, radians)."""
    return Angles(a, b, -1, (-1.0, 1.0, 0.0), offset, driver)
