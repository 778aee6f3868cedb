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

import numpy as np

from ..joints._terms import Angles, Poses, rotate
from ..model import GROUND, Mechanism

__all__ = ["ConstraintSystem", "rotate"]


def _perp(v: np.ndarray) -> np.ndarray:
    """R v: rotate vectors of shape (..., 2) by +90 degrees."""
    out = np.empty_like(v)
    out[..., 0] = -v[..., 1]
    out[..., 1] = v[..., 0]
    return out


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
        joint_terms = [t for joint in mechanism.joints for t in joint.terms(self._local)]
        driver_terms = [mechanism.joint(d.joint).driver_term(self._local, k) for k, d in enumerate(mechanism.drivers)]
        self.terms = joint_terms + driver_terms
        self.n_kinematic = sum(t.rows for t in joint_terms)
        self.n_drivers = len(driver_terms)
        self.n_rows = self.n_kinematic + self.n_drivers
        self.row_is_angle = np.concatenate([[t.is_angle] * t.rows for t in self.terms])
        self._offsets = np.cumsum([0] + [t.rows for t in self.terms])

    # -- building ---------------------------------------------------------
    def _local(self, body: str, label: str | None) -> tuple[int, np.ndarray]:
        """(body's index, -1 the ground; the labelled point in its frame, or its origin), m."""
        return self.body_index[body], np.zeros(2) if label is None else self.mechanism.body(body).points[label]

    # -- evaluation -------------------------------------------------------
    def residual(self, q: np.ndarray, c: np.ndarray, kinematic_only: bool = False) -> np.ndarray:
        """Phi(q, c), shape (N, rows); metres for point rows, radians for angle rows."""
        terms = self.terms[: len(self.terms) - self.n_drivers] if kinematic_only else self.terms
        poses = Poses(q)
        return np.concatenate([t.residual(poses, c) for t in terms], axis=1)

    def jacobian(self, q: np.ndarray, kinematic_only: bool = False) -> np.ndarray:
        """Phi_q, shape (N, rows, n)."""
        rows = self.n_kinematic if kinematic_only else self.n_rows
        out = np.zeros((q.shape[0], rows, self.n))
        poses = Poses(q)
        for t, start in zip(self.terms, self._offsets):
            if start >= rows:
                break
            t.jacobian(poses, out[:, start : start + t.rows])
        return out

    def gamma(self, q: np.ndarray, qd: np.ndarray, cdd: np.ndarray) -> np.ndarray:
        """gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt, shape (N, rows)."""
        poses = Poses(q, qd)
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

        The angle rows (relative angles of prismatic joints, revolute drivers,
        gear pairs) are linear in the body angles, so a sketch fitted with
        ``atan2`` may satisfy them only modulo whole turns: a crank drawn at
        200 deg comes out at -160 deg. Walking the angle rows outwards from the
        ground fixes each body's turn count once, by the first row that leaves
        it the only body not yet placed.

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
        edges = [(t, start) for t, start in zip(self.terms, self._offsets) if isinstance(t, Angles)]
        placed = {-1}
        while edges:
            progress = False
            for t, start in list(edges):
                turning = [(index, k) for index, k in zip(t.bodies, t.coefficients) if k != 0.0]
                loose = [(index, k) for index, k in turning if index not in placed]
                if len(loose) > 1:
                    continue
                if loose:
                    index, k = loose[0]
                    r = float(self.residual(q[None], c[None])[0, start])
                    q[3 * index + 2] -= 2.0 * math.pi * round(r / (2.0 * math.pi * k))
                placed.update(index for index, _ in turning)
                edges.remove((t, start))
                progress = True
            if not progress:  # a group of bodies not tied to the ground by angle rows
                placed.add(next(index for index in edges[0][0].bodies if index not in placed))
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
