"""Constraint equations in Cartesian body coordinates (seed 000, formulation III).

Each moving body ``i`` has the coordinates ``q[3i:3i+3] = (x, y, phi)`` of its
frame. Joints and drivers give ``Phi(q, c) = 0`` with ``c`` the drivers' input
values. Everything is vectorised over a leading sample axis of length N:
``q`` has shape (N, n), ``c`` shape (N, k).

The equations follow Haug's (and the seed's) notation: ``A(phi)`` rotates a
body-frame vector into the global frame, ``R`` rotates by +90 degrees, so
``dA/dphi s = R A s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model import GROUND, Mechanism, PinInSlot, Prismatic, Revolute

__all__ = ["ConstraintSystem"]


def rotate(phi, s) -> np.ndarray:
    """A(phi) s: a body vector s (2,) turned by phi (rad, a scalar or shape (N,));
    returns shape (2,) or (N, 2)."""
    return _rotate_cs(np.cos(phi), np.sin(phi), s)


def _rotate_cs(c: np.ndarray, sn: np.ndarray, s: np.ndarray) -> np.ndarray:
    # long double stays long double (polishing), anything else is double
    wide = any(np.asarray(v).dtype == np.longdouble for v in (c, sn, s))
    out = np.empty(np.shape(c) + (2,), dtype=np.longdouble if wide else float)
    out[..., 0] = c * s[0] - sn * s[1]
    out[..., 1] = sn * s[0] + c * s[1]
    return out


def _perp(v: np.ndarray) -> np.ndarray:
    """R v: rotate vectors of shape (..., 2) by +90 degrees."""
    out = np.empty_like(v)
    out[..., 0] = -v[..., 1]
    out[..., 1] = v[..., 0]
    return out


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


class _Poses:
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
class _Coincidence:
    """Point s_a of body a coincides with point s_b of body b (2 rows, metres)."""

    a: int
    s_a: np.ndarray
    b: int
    s_b: np.ndarray
    driver: None = None
    rows: int = 2
    is_angle: bool = False

    def residual(self, poses, c):
        return (
            poses.frame(self.a)[0]
            + poses.rotate(self.a, self.s_a)
            - poses.frame(self.b)[0]
            - poses.rotate(self.b, self.s_b)
        )

    def jacobian(self, poses, out):
        for index, s, sign in ((self.a, self.s_a, 1.0), (self.b, self.s_b, -1.0)):
            if index < 0:
                continue
            k = 3 * index
            out[:, 0, k] = sign
            out[:, 1, k + 1] = sign
            out[:, :, k + 2] = sign * _perp(poses.rotate(index, s))

    def gamma(self, poses, cdd):
        return (
            poses.rotate(self.a, self.s_a) * (poses.rates(self.a)[1] ** 2)[:, None]
            - poses.rotate(self.b, self.s_b) * (poses.rates(self.b)[1] ** 2)[:, None]
        )


@dataclass(frozen=True)
class _Projection:
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
    rows: int = 1
    is_angle: bool = False

    def _parts(self, poses):
        w = poses.rotate(self.a, self.w)
        as_q, as_p = poses.rotate(self.a, self.s_q), poses.rotate(self.b, self.s_p)
        d = poses.frame(self.b)[0] + as_p - poses.frame(self.a)[0] - as_q
        return w, as_q, as_p, d

    def residual(self, poses, c):
        w, _, _, d = self._parts(poses)
        value = _dot(w, d)
        if self.driver is not None:
            value = value - c[:, self.driver]
        return value[:, None]

    def jacobian(self, poses, out):
        w, as_q, as_p, d = self._parts(poses)
        if self.b >= 0:
            k = 3 * self.b
            out[:, 0, k : k + 2] = w
            out[:, 0, k + 2] = _dot(w, _perp(as_p))
        if self.a >= 0:
            k = 3 * self.a
            out[:, 0, k : k + 2] = -w
            out[:, 0, k + 2] = _dot(_perp(w), d) - _dot(w, _perp(as_q))

    def gamma(self, poses, cdd):
        w, as_q, as_p, d = self._parts(poses)
        rd_a, phid_a = poses.rates(self.a)
        rd_b, phid_b = poses.rates(self.b)
        dd = rd_b + phid_b[:, None] * _perp(as_p) - rd_a - phid_a[:, None] * _perp(as_q)
        quadratic = (
            -(phid_a**2) * _dot(w, d)
            + 2.0 * phid_a * _dot(_perp(w), dd)
            - phid_b**2 * _dot(w, as_p)
            + phid_a**2 * _dot(w, as_q)
        )
        value = -quadratic
        if self.driver is not None:
            value = value + cdd[:, self.driver]
        return value[:, None]


@dataclass(frozen=True)
class _RelativeAngle:
    """phi_b - phi_a = offset + c (1 row, radians)."""

    a: int
    b: int
    offset: float = 0.0
    driver: int | None = None
    rows: int = 1
    is_angle: bool = True

    def residual(self, poses, c):
        value = poses.frame(self.b)[1] - poses.frame(self.a)[1] - self.offset
        if self.driver is not None:
            value = value - c[:, self.driver]
        return value[:, None]

    def jacobian(self, poses, out):
        if self.b >= 0:
            out[:, 0, 3 * self.b + 2] = 1.0
        if self.a >= 0:
            out[:, 0, 3 * self.a + 2] = -1.0

    def gamma(self, poses, cdd):
        value = np.zeros(poses.n_samples)
        if self.driver is not None:
            value = value + cdd[:, self.driver]
        return value[:, None]


class ConstraintSystem:
    """Phi(q, c), its Jacobian Phi_q and the acceleration right-hand side gamma.

    Rows are the joints' constraints in file order, then one row per driver.

    Parameters
    ----------
    mechanism : Mechanism

    Attributes
    ----------
    n : int
        Number of coordinates, 3 per moving body.
    n_kinematic : int
        Number of joint constraint rows (drivers excluded).
    n_drivers : int
    size : float
        The mechanism's characteristic length (m), used to scale tolerances.
    """

    def __init__(self, mechanism: Mechanism):
        self.mechanism = mechanism
        self.body_names = [b.name for b in mechanism.moving_bodies]
        self.body_index = {name: i for i, name in enumerate(self.body_names)}
        self.body_index[GROUND] = -1
        self.n = 3 * len(self.body_names)
        self.size = mechanism.size
        joint_terms = [t for joint in mechanism.joints for t in self._joint_terms(joint)]
        driver_terms = [self._driver_term(d, k) for k, d in enumerate(mechanism.drivers)]
        self.terms = joint_terms + driver_terms
        self.n_kinematic = sum(t.rows for t in joint_terms)
        self.n_drivers = len(driver_terms)
        self.n_rows = self.n_kinematic + self.n_drivers
        self.row_is_angle = np.concatenate([[t.is_angle] * t.rows for t in self.terms])
        self._offsets = np.cumsum([0] + [t.rows for t in self.terms])

    # -- building ---------------------------------------------------------
    def _local(self, body: str, label: str) -> tuple[int, np.ndarray]:
        return self.body_index[body], self.mechanism.body(body).points[label]

    def _joint_terms(self, joint) -> list:
        if isinstance(joint, Revolute):
            a, s_a = self._local(joint.body_a, joint.point_a)
            b, s_b = self._local(joint.body_b, joint.point_b)
            return [_Coincidence(a, s_a, b, s_b)]
        a, s_q = self._local(joint.body_a, joint.line_point)
        b, s_p = self._local(joint.body_b, joint.point)
        normal = np.array([-joint.direction[1], joint.direction[0]])
        terms: list[_Projection | _RelativeAngle] = [_Projection(a, s_q, normal, b, s_p)]
        if isinstance(joint, Prismatic):
            terms.append(_RelativeAngle(a, b, joint.angle))
        return terms

    def _driver_term(self, driver, k: int):
        joint = self.mechanism.joint(driver.joint)
        a, b = self.body_index[joint.body_a], self.body_index[joint.body_b]
        if isinstance(joint, Revolute):
            return _RelativeAngle(a, b, 0.0, driver=k)
        assert isinstance(joint, (Prismatic, PinInSlot))
        _, s_q = self._local(joint.body_a, joint.line_point)
        _, s_p = self._local(joint.body_b, joint.point)
        return _Projection(a, s_q, joint.direction, b, s_p, driver=k)

    # -- evaluation -------------------------------------------------------
    def residual(self, q: np.ndarray, c: np.ndarray, kinematic_only: bool = False) -> np.ndarray:
        """Phi(q, c), shape (N, rows); metres for point rows, radians for angle rows."""
        terms = self.terms[: len(self.terms) - self.n_drivers] if kinematic_only else self.terms
        poses = _Poses(q)
        return np.concatenate([t.residual(poses, c) for t in terms], axis=1)

    def jacobian(self, q: np.ndarray, kinematic_only: bool = False) -> np.ndarray:
        """Phi_q, shape (N, rows, n)."""
        rows = self.n_kinematic if kinematic_only else self.n_rows
        out = np.zeros((q.shape[0], rows, self.n))
        poses = _Poses(q)
        for t, start in zip(self.terms, self._offsets):
            if start >= rows:
                break
            t.jacobian(poses, out[:, start : start + t.rows])
        return out

    def gamma(self, q: np.ndarray, qd: np.ndarray, cdd: np.ndarray) -> np.ndarray:
        """gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt, shape (N, rows)."""
        poses = _Poses(q, qd)
        return np.concatenate([t.gamma(poses, cdd) for t in self.terms], axis=1)

    def velocity_rhs(self, cd: np.ndarray) -> np.ndarray:
        """-Phi_t: zero for joints, the input rates for driver rows; shape (N, rows)."""
        rhs = np.zeros((cd.shape[0], self.n_rows))
        rhs[:, self.n_kinematic :] = cd
        return rhs

    def input_values(self, q: np.ndarray) -> np.ndarray:
        """The drivers' current inputs (joint angles, slides) at q, shape (N, k)."""
        zero = np.zeros((q.shape[0], self.n_drivers))
        return -self.residual(q, zero)[:, self.n_kinematic :]

    def unwind_angles(self, q: np.ndarray, c: np.ndarray) -> np.ndarray:
        """q with body angles moved by whole turns so that every angle row holds.

        The angle rows (relative angles of prismatic joints, revolute drivers)
        are linear in the body angles, so a sketch fitted with ``atan2`` may
        satisfy them only modulo 2 pi: a crank drawn at 200 deg comes out at
        -160 deg. Walking the angle rows outwards from the ground (they form a
        forest: redundant rows are refused) fixes each body's turn count once.

        Parameters
        ----------
        q : ndarray, shape (n,)
        c : ndarray, shape (k,)
            The drivers' inputs (rad or m).

        Returns
        -------
        ndarray, shape (n,)
        """
        q = np.array(q, dtype=float)
        edges = [(t, start) for t, start in zip(self.terms, self._offsets) if isinstance(t, _RelativeAngle)]
        placed = {-1}
        while edges:
            progress = False
            for t, start in list(edges):
                if t.a not in placed and t.b not in placed:
                    continue
                r = float(self.residual(q[None], c[None])[0, start])
                turns = round(r / (2.0 * math.pi))
                if turns:
                    if t.b not in placed:
                        q[3 * t.b + 2] -= 2.0 * math.pi * turns
                    else:
                        q[3 * t.a + 2] += 2.0 * math.pi * turns
                placed.update((t.a, t.b))
                edges.remove((t, start))
                progress = True
            if not progress:  # a group of bodies not tied to the ground by angle rows
                placed.add(edges[0][0].b)
        return q

    # -- scaling ----------------------------------------------------------
    def residual_metres(self, phi: np.ndarray) -> np.ndarray:
        """Largest constraint violation per sample in metres (angles times size); (N,)."""
        scale = np.where(self.row_is_angle[: phi.shape[1]], self.size, 1.0)
        return np.max(np.abs(phi) * scale, axis=1)

    def coordinate_scale(self) -> np.ndarray:
        """Per-coordinate scale making q dimensionless: 1/size for x, y; 1 for phi; (n,)."""
        scale = np.ones(self.n)
        scale[0::3] = scale[1::3] = 1.0 / self.size
        return scale

    def scaled_jacobian(self, jac: np.ndarray) -> np.ndarray:
        """Dimensionless Phi_q (rows in size units, columns per size), same shape."""
        rows = np.where(self.row_is_angle[: jac.shape[1]], 1.0, 1.0 / self.size)
        return jac * (rows[:, None] / self.coordinate_scale()[None, :])

    def input_scale(self) -> np.ndarray:
        """Per-driver scale making inputs dimensionless (1 for angles, 1/size for slides); (k,)."""
        return np.array([1.0 if d.quantity == "angle" else 1.0 / self.size for d in self.mechanism.drivers])
