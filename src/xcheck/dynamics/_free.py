"""Free motion: the native reference for a mechanism moving under gravity and loads.

The constrained equations of motion in body coordinates,

    M(q) q'' + Phi_q^T lambda = Q(q, q'),   Phi(q) = 0,

are integrated by the classical fixed-step RK4 on the index-1 form, the
accelerations from Gauss's principle (the M-weighted least-squares solution of
Phi_q q'' = gamma, which stays defined where Phi_q loses rank at a singular
configuration), and after every step the positions and then the velocities
are projected back onto the constraints along M^-1 Phi_q^T (the M-weighted
smallest correction), so the loops stay closed to round-off and the motion
stays on the branch it came from through singular positions. (An adaptive
DOP853 on the same index-1 form leaves the physical branch or stalls at the
singular passes of the IFToMM double four-bar, even at rtol 1e-12.)

:func:`free_reference` runs a ladder of halving steps until two consecutive
runs agree to the requested accuracy; the difference between them is the
stated error estimate (for RK4 about 15 times the finer run's true error).

Drivers play no part: their rows are left out (the mechanism moves freely).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import null_space, solve_triangular

from ..joints import _equations as eq
from ..joints._terms import Coincidence, Poses
from ..kinematics import Kinematics, Solution, Status, rotate

__all__ = [
    "FreeState",
    "FreeMotion",
    "FreeReference",
    "mass_matrix",
    "simulate_free",
    "free_reference",
    "consistent_state",
    "release_state",
    "simulate",
]

#: smallest singular value of the dimensionless constraint Jacobian below which
#: a local minimum (over the steps) counts as passing a singular configuration
SINGULAR_THRESHOLD = 1e-2
#: relative rank cut-off of the least-squares solves (of J M^-1 J^T, dimensionless)
RANK_CUTOFF = 1e-12
#: relative rank cut-off of the projections' least-squares solves
PROJECTION_CUTOFF = 1e-12
#: below this singularity measure the accelerations' multipliers come from
#: least squares (rank-revealing) rather than a plain solve
LEAST_SQUARES_BELOW = 1e-3
#: the smallest error estimate, relative to the size: float64 round-off of the state a step
#: from the start (measured: DOP853's runs at local tolerances 1e-11 to 1e-14 up to 2.2e-14 of
#: the size off at their first outputs, the double pendulum of tests/free_problems.py)
ROUND_OFF = 1e-13
#: at most this many Newton iterations of the position projection after each step,
#: stopping once the loops close to PROJECTION_TOLERANCE x size
PROJECTION_ITERATIONS = 3
PROJECTION_TOLERANCE = 1e-15
#: from this many constraint rows, where every body has mass and inertia (M
#: positive definite, block-diagonal), the solves go through J M^-1 J^T itself,
#: banded along the chain, rather than through the augmented M + J^T J, whose
#: inverse is dense (:meth:`_Dynamics._constrained_banded`)
BANDED_FROM = 40
#: inverse and power iterations estimating the extreme eigenvalues of J M^-1 J^T
#: there; measured on iftomm-a02-n40 along its branch (crank angles 1e-5 to
#: pi/2): the smallest to 1e-10 relative (its neighbour is four times larger, or
#: round-off below 1e-12), the largest up to 11 % low (its neighbours crowd), the
#: measure within 3.5 % of eigvalsh's; 30 iterations gain only a factor 2 there
EIGEN_ITERATIONS = 8
#: on that path, the multipliers come from least squares (a dense SVD) below this
#: singularity measure only: above it the ratio of the extreme eigenvalues of
#: J M^-1 J^T exceeds 5e-11 (the measure squared over 1 + the largest eigenvalue,
#: about 1.75 on the IFToMM chains), the cut-off (RANK_CUTOFF, 1e-12) drops
#: nothing and least squares equals the banded Cholesky solve to round-off (whose
#: error, eps over the measure, is the SVD's as well); an SVD of 242 rows costs
#: more than a hundred banded steps
BANDED_LEAST_SQUARES_BELOW = 1e-5


@dataclass(frozen=True)
class FreeState:
    """A state of the free mechanism: body coordinates and their rates (n,), SI."""

    q: np.ndarray
    qd: np.ndarray


@dataclass
class FreeMotion:
    """One integration of the free mechanism.

    Attributes
    ----------
    times : ndarray, shape (N,)
        Output times, s.
    q, qd, qdd : ndarray, shape (N, n)
        Body coordinates (x, y, phi per moving body; angles continuous), rates
        and accelerations at the output times.
    residual : ndarray, shape (N,)
        Largest loop-closure violation before the projection of the step that
        ends there, m (0 at t = 0): what one step drifts.
    energy : ndarray, shape (N,)
        Kinetic plus gravitational potential energy, J.
    work : ndarray, shape (N,)
        Work done by the applied loads since t = 0, J (integrated with the motion).
    singular_passes : list of float
        Times (s) at which the motion passed a singular configuration (a local
        minimum of the smallest singular value of the dimensionless
        constraint Jacobian below :data:`SINGULAR_THRESHOLD`).
    step : float
        The time step, s (an adaptive method's: the duration over its steps).
    seconds : float
        CPU time of the integration, s.
    method : str
        "RK4" (:func:`simulate_free`), "DOP853" (:mod:`._adaptive`) or "Gauss"
        (:mod:`._collocation`).
    failure : str
        "" or why the run stopped early (its outputs are then those reached).
    statistics : dict
        An adaptive run's counts: steps, rejected, evaluations, crossings, and its work
        (cost) in evaluations, its projections, singularity measures and least-squares
        solves counted at their cost.
    """

    kinematics: Kinematics
    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    residual: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    singular_passes: list[float]
    step: float
    seconds: float
    method: str = "RK4"
    failure: str = ""
    statistics: dict = field(default_factory=dict)

    def solution(self) -> Solution:
        """The motion as a :class:`~xcheck.kinematics.Solution` (points, bodies,
        reactions through :func:`xcheck.dynamics.inverse_dynamics`)."""
        system = self.kinematics.system
        n = len(self.times)
        inputs = system.input_values(self.q)
        k = inputs.shape[1]
        jac = system.jacobian(self.q)
        rates = np.einsum("nij,nj->ni", jac, self.qd)[:, system.n_kinematic :]
        gamma = system.gamma(self.q, self.qd, np.zeros((n, k)))[:, system.n_kinematic :]
        accelerations = np.einsum("nij,nj->ni", jac, self.qdd)[:, system.n_kinematic :] - gamma
        return Solution(
            self.kinematics,
            self.kinematics._branch_name(None),
            inputs,
            rates,
            accelerations,
            self.q,
            self.qd,
            self.qdd,
            np.full(n, int(Status.OK)),
            self.residual,
            np.ones(n),
            np.zeros(n, dtype=int),
        )

    @property
    def energy_error(self) -> np.ndarray:
        """E(t) - E(0) - W(t): the energy balance's residual at each output, J (N,)."""
        return self.energy - self.energy[0] - self.work


@dataclass
class FreeReference:
    """A native reference: the run a ladder keeps and its stated error (see
    :mod:`._reference` for the rule).

    Attributes
    ----------
    motion : FreeMotion
        The run kept: the one that met the tolerance, or where the ladder stopped
        short of it, the finer run of the last pair whose difference fell.
    estimate : ndarray, shape (N,)
        The stated error at each output: a bound on the largest error so far of a
        body position (m) or angle (rad, times the mechanism's size), at least
        1e-14 of the size.
    relative : float
        max(estimate) / size.
    converged : bool
        relative <= ``tolerance``, the requested accuracy (relative to the size).
    ladder : list of dict
        Per run: setting (a fixed-step method's step, s; DOP853's local tolerance), steps,
        seconds (CPU), difference from the previous run that went through (m),
        status ("ok" or why it failed), and, from the second run on, error (its
        stated error, m) and rule (how it was obtained); a fixed-step method's also step (s).
    method : str
        "DOP853", "RK4" or "Gauss".
    basis : str
        The ladder and how it stopped, in words.
    check : FreeCheck or None
        The other native method against this one, where it ran.
    """

    motion: FreeMotion
    estimate: np.ndarray
    relative: float
    converged: bool
    ladder: list[dict] = field(default_factory=list)
    tolerance: float = math.nan
    method: str = "RK4"
    basis: str = ""
    check: FreeCheck | None = None


@dataclass
class FreeCheck:
    """The second native method's reference against the first.

    Attributes
    ----------
    reference : FreeReference
        The second method's own ladder and run.
    times : ndarray, shape (K,)
        The outputs compared (s): the second run's, each an output of the first.
    agreement : ndarray, shape (K,)
        The largest difference so far between the two runs' body positions (m) and
        angles (rad x size).
    relative : float
        max(agreement) / size.
    consistent : bool or None
        Whether the largest agreement is within the sum of the two largest stated errors
        (where not, one of them is wrong: a finding); None where either did not meet its
        tolerance (inconclusive).
    """

    reference: FreeReference
    times: np.ndarray
    agreement: np.ndarray
    relative: float
    consistent: bool | None


def mass_matrix(kinematics: Kinematics, q: np.ndarray) -> np.ndarray:
    """M(q) in body coordinates (frame origin x, y and angle per body), (n, n).

    A body of mass m, inertia I about its centre of mass G at s (body frame)
    has, with a = A(phi) s, the block [[m, 0, -m a_y], [0, m, m a_x], [-m a_y,
    m a_x, I + m |s|^2]] (:func:`_mass_blocks`).
    """
    return _block_diagonal(_mass_blocks(_Bodies(kinematics), q))


def _block_diagonal(blocks: np.ndarray) -> np.ndarray:
    """The (3B, 3B) matrix with the (B, 3, 3) blocks on its diagonal."""
    first = 3 * np.arange(len(blocks))[:, None, None]
    out = np.zeros((3 * len(blocks), 3 * len(blocks)))
    out[first + np.arange(3)[None, :, None], first + np.arange(3)[None, None, :]] = blocks
    return out


class _Bodies:
    """Mass data of the moving bodies as arrays (B bodies)."""

    def __init__(self, kinematics: Kinematics):
        bodies = kinematics.mechanism.moving_bodies
        self.mass = np.array([float(b.mass or 0.0) for b in bodies])
        self.inertia = np.array([float(b.inertia or 0.0) for b in bodies])
        self.com = np.array([np.zeros(2) if b.com is None else np.asarray(b.com, dtype=float) for b in bodies])
        self.com = self.com.reshape(len(bodies), 2)

    def arms(self, q: np.ndarray) -> np.ndarray:
        """A(phi) s of every body's centre of mass, (B, 2)."""
        c, sn = np.cos(q[2::3]), np.sin(q[2::3])
        return np.stack([c * self.com[:, 0] - sn * self.com[:, 1], sn * self.com[:, 0] + c * self.com[:, 1]], axis=1)


def _mass_blocks(bodies: _Bodies, q: np.ndarray) -> np.ndarray:
    """Each body's 3 x 3 block of M(q), (B, 3, 3)."""
    a = bodies.arms(q)
    m = bodies.mass
    blocks = np.zeros((len(m), 3, 3))
    blocks[:, 0, 0] = blocks[:, 1, 1] = m
    blocks[:, 0, 2] = blocks[:, 2, 0] = -m * a[:, 1]
    blocks[:, 1, 2] = blocks[:, 2, 1] = m * a[:, 0]
    blocks[:, 2, 2] = bodies.inertia + m * np.einsum("ij,ij->i", bodies.com, bodies.com)
    return blocks


class _Joints:
    """The joints' constraints at one state, vectorised over the revolute
    joints (point coincidences); other terms through their own equations.
    Rows: the coincidences (2 each), then the other terms."""

    def __init__(self, system):
        terms = system.terms[: len(system.terms) - system.n_drivers]
        coincidences = [t for t in terms if isinstance(t, Coincidence)]
        self.others = [t for t in terms if not isinstance(t, Coincidence)]
        self.n, ground = system.n, system.n // 3  # the ground is a padded body of zero coordinates
        self.a = np.array([ground if t.a < 0 else t.a for t in coincidences], dtype=int)
        self.b = np.array([ground if t.b < 0 else t.b for t in coincidences], dtype=int)
        self.s_a = np.array([t.s_a for t in coincidences], dtype=float).reshape(-1, 2)
        self.s_b = np.array([t.s_b for t in coincidences], dtype=float).reshape(-1, 2)
        count = len(coincidences)
        self.x_rows, self.y_rows = 2 * np.arange(count), 2 * np.arange(count) + 1
        self.rows = 2 * count + sum(t.rows for t in self.others)
        self.row_is_angle = np.array(
            [False] * (2 * count) + [t.is_angle for t in self.others for _ in range(t.rows)], dtype=bool
        )
        self._last_key: bytes = b""
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0), np.zeros(0))

    def _turned(self, q: np.ndarray):
        """(q padded with the ground's zeros, A(phi_a) s_a (T, 2), A(phi_b) s_b (T, 2)); the last
        state's are kept, since the Jacobian, gamma and the residual are asked at one state in turn."""
        key = q.tobytes()
        if key == self._last_key:
            return self._last
        padded = np.concatenate([q, np.zeros(3)])
        c, sn = np.cos(padded[2::3]), np.sin(padded[2::3])
        turned = [padded]
        for index, s in ((self.a, self.s_a), (self.b, self.s_b)):
            arm = np.empty((len(index), 2))
            arm[:, 0], arm[:, 1] = eq.turn(c[index], sn[index], s[:, 0], s[:, 1])
            turned.append(arm)
        self._last_key, self._last = key, (turned[0], turned[1], turned[2])
        return self._last

    def residual(self, q: np.ndarray) -> np.ndarray:
        padded, ra, rb = self._turned(q)
        r = padded.reshape(-1, 3)[:, :2]
        ends = (*r[self.a].T, *ra.T, *r[self.b].T, *rb.T)
        values = [np.stack(eq.coincidence_residual(*ends), axis=1).ravel()]
        if self.others:
            poses, zero = Poses(q[None]), np.zeros((1, 0))
            values += [t.residual(poses, zero)[0] for t in self.others]
        return np.concatenate(values)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        _, ra, rb = self._turned(q)
        out = np.zeros((self.rows, self.n + 3))
        a0, a1, b0, b1 = eq.coincidence_jacobian(ra[:, 0], ra[:, 1], rb[:, 0], rb[:, 1])
        for index, sign, angle in ((self.a, 1.0, (a0, a1)), (self.b, -1.0, (b0, b1))):
            out[self.x_rows, 3 * index] = sign
            out[self.y_rows, 3 * index + 1] = sign
            out[self.x_rows, 3 * index + 2] = angle[0]
            out[self.y_rows, 3 * index + 2] = angle[1]
        out = out[:, : self.n]
        if self.others:
            poses, start = Poses(q[None]), 2 * len(self.a)
            for t in self.others:
                block = np.zeros((1, t.rows, self.n))
                t.jacobian(poses, block)
                out[start : start + t.rows] = block[0]
                start += t.rows
        return out

    def gamma(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        _, ra, rb = self._turned(q)
        w = np.concatenate([qd, np.zeros(3)])[2::3]
        gamma = eq.coincidence_gamma(ra[:, 0], ra[:, 1], w[self.a], rb[:, 0], rb[:, 1], w[self.b])
        values = [np.stack(gamma, axis=1).ravel()]
        if self.others:
            poses, zero = Poses(q[None], qd[None]), np.zeros((1, 0))
            values += [t.gamma(poses, zero)[0] for t in self.others]
        return np.concatenate(values)


def start_vector(rows: int) -> np.ndarray:
    """The fixed start of the eigenvalue iterations, (rows,): 1 + sin(1.3 i + 0.4) / 2,
    never orthogonal to an extreme eigenvector in practice."""
    return 1.0 + 0.5 * np.sin(1.3 * np.arange(rows) + 0.4)


def augmented_measure(smallest: float, largest: float) -> float:
    """The singularity measure, sqrt(smallest / largest eigenvalue) of the augmented
    J (M + J^T J)^-1 J^T = S (1 + S)^-1, from the smallest and largest eigenvalue of S =
    J M^-1 J^T (dimensionless)."""
    if not largest > 0.0:
        return 0.0
    smallest = max(smallest, 0.0)
    return math.sqrt((smallest / (1.0 + smallest)) / (largest / (1.0 + largest)))


def _iterated_measure(schur: np.ndarray, lower: np.ndarray, start: np.ndarray) -> float:
    """:func:`augmented_measure` from the Rayleigh quotients of :data:`EIGEN_ITERATIONS`
    inverse (through the Cholesky factor ``lower``) and power iterations on ``schur`` (m, m)."""
    v = start / np.linalg.norm(start)
    for _ in range(EIGEN_ITERATIONS):
        v = solve_triangular(lower, solve_triangular(lower, v, lower=True), lower=True, trans="T")
        v /= np.linalg.norm(v)
    w = start / np.linalg.norm(start)
    for _ in range(EIGEN_ITERATIONS):
        w = schur @ w
        w /= np.linalg.norm(w)
    return augmented_measure(float(v @ schur @ v), float(w @ schur @ w))


class _Dynamics:
    """The equations of the free mechanism at one state (no sample axis)."""

    def __init__(self, kinematics: Kinematics):
        from ._forces import require_mass_data

        mech = kinematics.mechanism
        require_mass_data(mech)
        self.kinematics, self.system = kinematics, kinematics.system
        self.joints = _Joints(self.system)
        self.bodies = _Bodies(kinematics)
        self.index = {b.name: i for i, b in enumerate(mech.moving_bodies)}
        self.loads = [
            (
                3 * self.index[load.body],
                np.asarray(load.point, dtype=float),
                np.asarray(load.force, dtype=float),
                float(load.torque),
                load.law,
            )
            for load in mech.loads
            if load.body in self.index
        ]
        self.gravity = np.asarray(mech.gravity, dtype=float)
        owners = mech.point_owners
        self.springs = [
            (
                self._anchor(owners[s.points[0]], s.points[0]),
                self._anchor(owners[s.points[1]], s.points[1]),
                s.stiffness,
                s.rest_length,
                s.damping,
            )
            for s in mech.springs
        ]
        self.rotational = [
            (self._offset(s.body_a), self._offset(s.body_b), s.stiffness, s.rest_angle, s.damping)
            for s in mech.rotational_springs
        ]
        size = self.system.size
        self.size = size
        self.scale_rows = np.where(self.joints.row_is_angle, 1.0, 1.0 / size)
        self.scale_coordinates = self.system.coordinate_scale()
        self.mass_scale = max(float(self.bodies.mass.sum()), 1e-300)
        self.measure = 0.0  # the singularity measure of the last projection (0: not yet known)
        d, r = self.scale_coordinates, self.scale_rows  # scaled units of _constrained, precomputed
        self.jac_factor = r[:, None] / d[None, :]
        self.mass_factor = 1.0 / (d[:, None] * d[None, :] * self.mass_scale)
        self.load_factor = 1.0 / (d * self.mass_scale)
        positive = bool(np.all(self.bodies.mass > 0.0) and np.all(self.bodies.inertia > 0.0))
        rows = [(a, b) for a, b in zip(self.joints.a, self.joints.b)] + [t.bodies for t in self.joints.others]
        moving = [[k for k in row if k >= 0] for row in rows]
        distinct = all(len(set(k)) == len(k) for k in moving)  # a row on two slots of one body would count it twice
        self.banded = positive and distinct and self.joints.rows >= BANDED_FROM
        self.start = start_vector(self.joints.rows)

    def _offset(self, body: str) -> int | None:
        """The body's coordinate offset, None for the ground."""
        return 3 * self.index[body] if body in self.index else None

    def _twists(self, q: np.ndarray, qd: np.ndarray):
        """Per rotational spring: (its bodies' offsets, the angle phi_b - phi_a - rest (rad)
        and its rate, stiffness, damping)."""
        for a, b, stiffness, rest, damping in self.rotational:
            angle = (0.0 if b is None else q[b + 2]) - (0.0 if a is None else q[a + 2]) - rest
            rate = (0.0 if b is None else qd[b + 2]) - (0.0 if a is None else qd[a + 2])
            yield a, b, angle, rate, stiffness, damping

    def _anchor(self, body: str, label: str) -> tuple[int | None, np.ndarray]:
        """(coordinate offset of the body or None for the ground, the point in its frame or global)."""
        point = np.asarray(self.kinematics.mechanism.body(body).points[label], dtype=float)
        return (3 * self.index[body] if body in self.index else None), point

    @staticmethod
    def _point(anchor, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, arm A(phi) s) of an anchored point, m and m/s."""
        k, s = anchor
        if k is None:
            return s, np.zeros(2), np.zeros(2)
        arm = rotate(q[k + 2], s)
        return q[k : k + 2] + arm, qd[k : k + 2] + qd[k + 2] * np.array([-arm[1], arm[0]]), arm

    def _spring_states(self, q: np.ndarray, qd: np.ndarray):
        """Per spring: (length l, rate dl/dt, unit vector from the first end to the second, the
        ends' anchors and arms), m, m/s."""
        for first, second, stiffness, rest, damping in self.springs:
            p, vp, arm_p = self._point(first, q, qd)
            r, vr, arm_r = self._point(second, q, qd)
            d = r - p
            length = float(np.hypot(d[0], d[1]))
            unit = d / length if length > 0.0 else np.zeros(2)
            yield length, float(unit @ (vr - vp)), unit, (first, arm_p), (second, arm_r), stiffness, rest, damping

    def residual_metres(self, q: np.ndarray) -> float:
        return float(
            np.max(np.abs(self.joints.residual(q)) * np.where(self.joints.row_is_angle, self.size, 1.0), initial=0.0)
        )

    def _mass(self, q: np.ndarray) -> np.ndarray:
        """M(q), (n, n)."""
        return _block_diagonal(_mass_blocks(self.bodies, q))

    def _loads_at(self, t: float):
        """Per load: (coordinate offset, point (body frame), force (N), torque (N m)) at time t (s)."""
        for k, p, f, torque, law in self.loads:
            if law is None:
                yield k, p, f, torque
            else:
                s = float(law.factor(t))
                yield k, p, s * f, s * torque

    def forces(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Q at time t (s): gravity, the applied loads, the springs and dampers (linear and
        rotational) and the velocity terms of M's offset centres of mass (n,)."""
        a = self.bodies.arms(q)
        m, w = self.bodies.mass, qd[2::3]
        out = np.zeros(self.system.n)
        weight = m[:, None] * self.gravity[None, :]
        out[0::3] = weight[:, 0] + m * w * w * a[:, 0]
        out[1::3] = weight[:, 1] + m * w * w * a[:, 1]
        out[2::3] = a[:, 0] * weight[:, 1] - a[:, 1] * weight[:, 0]
        for k, p, f, torque in self._loads_at(t):
            arm = self._point((k, p), q, qd)[2]
            out[k : k + 2] += f
            out[k + 2] += arm[0] * f[1] - arm[1] * f[0] + torque
        for length, rate, unit, (first, arm_p), (second, arm_r), stiffness, rest, damping in self._spring_states(q, qd):
            tension = stiffness * (length - rest) + damping * rate
            for (k, _), arm, force in ((first, arm_p, tension * unit), (second, arm_r, -tension * unit)):
                if k is not None:
                    out[k : k + 2] += force
                    out[k + 2] += arm[0] * force[1] - arm[1] * force[0]
        for a, b, angle, rate, stiffness, damping in self._twists(q, qd):
            torque = -stiffness * angle - damping * rate  # on body b; body a gets its opposite
            if b is not None:
                out[b + 2] += torque
            if a is not None:
                out[a + 2] -= torque
        return out

    def power(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> float:
        """Power of the applied loads at time t (s) and of the dampers, linear and
        rotational (gravity and springs are in the potential energy), W."""
        total = 0.0
        for k, p, f, torque in self._loads_at(t):
            velocity = self._point((k, p), q, qd)[1]
            total += float(f @ velocity) + torque * qd[k + 2]
        for _, rate, *_, damping in self._spring_states(q, qd):
            total -= damping * rate * rate
        for *_, rate, _, damping in self._twists(q, qd):
            total -= damping * rate * rate
        return total

    def energy(self, q: np.ndarray, qd: np.ndarray) -> float:
        """T + V, J (V of gravity, zero at the origin, and of the linear and rotational springs)."""
        blocks = _mass_blocks(self.bodies, q)
        rates = qd.reshape(-1, 3)
        kinetic = 0.5 * float(np.einsum("bi,bij,bj->", rates, blocks, rates))
        centres = q.reshape(-1, 3)[:, :2] + self.bodies.arms(q)
        springs = sum(
            0.5 * stiffness * (length - rest) ** 2
            for length, _, _, _, _, stiffness, rest, _ in self._spring_states(q, np.zeros_like(q))
        )
        springs += sum(0.5 * stiffness * angle**2 for _, _, angle, _, stiffness, _ in self._twists(q, qd))
        return kinetic - float(self.bodies.mass @ (centres @ self.gravity)) + springs

    def _constrained(
        self,
        mass: np.ndarray,
        jac: np.ndarray,
        load: np.ndarray,
        gap: np.ndarray,
        measure: bool = False,
        cutoff: float = RANK_CUTOFF,
    ) -> tuple[np.ndarray, float]:
        """The x minimising (1/2) x^T M x - load^T x subject to J x = gap, and
        the singularity measure of J there.

        In scaled units (coordinates per size, rows per size, masses per the
        total), M is augmented by J^T J, which leaves the solution unchanged
        on the constraints and makes it positive definite where M alone is
        singular off them (a point mass); the multipliers then solve
        (J Mbar^-1 J^T) nu = gap - J Mbar^-1 load in the least-squares sense,
        which stays defined where J loses rank at a singular configuration.
        The measure (computed when ``measure``, else NaN) is sqrt(smallest /
        largest singular value) of J Mbar^-1 J^T, of the order of J's own;
        while the last one measured exceeds :data:`LEAST_SQUARES_BELOW` the
        multipliers come from a plain solve. Shapes (n,), n coordinates.
        """
        if self.banded:
            return self._constrained_banded(mass, jac, load, gap, measure, cutoff)
        d = self.scale_coordinates
        scaled_jac = jac * self.jac_factor
        augmented = mass * self.mass_factor + scaled_jac.T @ scaled_jac
        scaled_gap = self.scale_rows * gap
        rhs_columns = np.empty((len(d), 1 + scaled_jac.shape[0]))
        rhs_columns[:, 0] = load * self.load_factor + scaled_jac.T @ scaled_gap
        rhs_columns[:, 1:] = scaled_jac.T
        solved = np.linalg.solve(augmented, rhs_columns)
        free, mj = solved[:, 0], solved[:, 1:]
        schur, rhs = scaled_jac @ mj, scaled_gap - scaled_jac @ free
        if not measure and self.measure > LEAST_SQUARES_BELOW:
            try:  # away from singular configurations a plain solve does (and is 5 times faster)
                return (free + mj @ np.linalg.solve(schur, rhs)) / d, math.nan
            except np.linalg.LinAlgError:
                pass
        multipliers, _, _, singular = np.linalg.lstsq(schur, rhs, rcond=cutoff)
        return (free + mj @ multipliers) / d, math.sqrt(float(singular[-1] / singular[0]))

    def _constrained_banded(
        self, mass: np.ndarray, jac: np.ndarray, load: np.ndarray, gap: np.ndarray, measure: bool, cutoff: float
    ) -> tuple[np.ndarray, float]:
        """:meth:`_constrained` where M is positive definite and the rows many
        (:data:`BANDED_FROM`): x = M^-1 (load + J^T nu) with (J M^-1 J^T) nu =
        gap - J M^-1 load, in the same scaled units. M is block-diagonal, so
        J M^-1 J^T is banded along the chain (the compiled kernel factors it
        as such), where the augmented form's is dense. Its eigenvalues s are
        the augmented form's s / (1 + s), so the measure is the same quantity,
        here from the Rayleigh quotients of :data:`EIGEN_ITERATIONS` inverse
        and power iterations from :func:`start_vector` (eigvalsh would cost
        more than the rest of the step); where the Cholesky factor does not
        exist, or below :data:`BANDED_LEAST_SQUARES_BELOW`, from the least-squares
        solve's singular values."""
        d = self.scale_coordinates
        scaled_jac = jac * self.jac_factor
        scaled_mass = mass * self.mass_factor
        free = np.linalg.solve(scaled_mass, load * self.load_factor)
        mj = np.linalg.solve(scaled_mass, scaled_jac.T)
        schur, rhs = scaled_jac @ mj, self.scale_rows * gap - scaled_jac @ free
        try:
            lower: np.ndarray | None = np.linalg.cholesky(schur)
        except np.linalg.LinAlgError:
            lower = None
        singularity, plain = math.nan, self.measure > BANDED_LEAST_SQUARES_BELOW
        if measure:
            singularity = 0.0 if lower is None else _iterated_measure(schur, lower, self.start)
            plain = singularity > BANDED_LEAST_SQUARES_BELOW
        if plain and lower is not None:
            multipliers = solve_triangular(lower, solve_triangular(lower, rhs, lower=True), lower=True, trans="T")
        else:
            multipliers, _, _, singular = np.linalg.lstsq(schur, rhs, rcond=cutoff)
            if measure:
                singularity = augmented_measure(float(singular[-1]), float(singular[0]))
        return (free + mj @ multipliers) / d, singularity

    def acceleration(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> np.ndarray:
        """q'' at time t (s) by Gauss's principle: M q'' - Q as small as the constraints
        J q'' = gamma allow (M-weighted)."""
        load = self.forces(q, qd, t)
        return self._constrained(self._mass(q), self.joints.jacobian(q), load, self.joints.gamma(q, qd))[0]

    def project(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
        """(q, qd) moved onto Phi = 0 and Phi_q qd = 0 by the M-weighted
        smallest corrections; the largest violation before (m) and the
        singularity measure at the new state."""
        before = self.residual_metres(q)
        gap, tolerance = before, PROJECTION_TOLERANCE * self.size
        zero = np.zeros(self.system.n)
        for _ in range(PROJECTION_ITERATIONS):
            if gap <= tolerance:
                break
            q = (
                q
                + self._constrained(
                    self._mass(q),
                    self.joints.jacobian(q),
                    zero,
                    -self.joints.residual(q),
                    measure=True,
                    cutoff=PROJECTION_CUTOFF,
                )[0]
            )
            gap = self.residual_metres(q)
        jac = self.joints.jacobian(q)
        correction, singular = self._constrained(
            self._mass(q), jac, zero, -(jac @ qd), measure=True, cutoff=PROJECTION_CUTOFF
        )
        self.measure = singular
        return q, qd + correction, before, singular


def simulate_free(
    kinematics: Kinematics,
    start: FreeState,
    duration: float,
    output_step: float,
    step: float,
    compiled: bool = True,
) -> FreeMotion:
    """Integrate the free mechanism from ``start`` over ``duration`` (s).

    Parameters
    ----------
    start : FreeState
        Consistent initial state (on the constraints; see :func:`consistent_state`).
    output_step : float
        Spacing of the outputs, s; a whole number of steps (``step`` is
        shortened to divide it).
    step : float
        The largest time step, s.
    compiled : bool
        Run the numba-compiled integrator (:mod:`._free_compiled`, the same
        steps 30 to 100 times faster) rather than this module's NumPy one.
    """
    begin = time.process_time()
    dyn = _Dynamics(kinematics)
    per_output = max(1, math.ceil(output_step / step - 1e-9))
    h = output_step / per_output
    outputs = int(round(duration / output_step))
    n = kinematics.system.n
    times = np.arange(outputs + 1) * output_step
    q_out, qd_out, qdd_out = (np.empty((outputs + 1, n)) for _ in range(3))
    residual, energy, work = np.zeros(outputs + 1), np.empty(outputs + 1), np.zeros(outputs + 1)
    q, qd = np.asarray(start.q, dtype=float).copy(), np.asarray(start.qd, dtype=float).copy()
    arrays = (q_out, qd_out, qdd_out, residual, energy, work)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        return _stopped(kinematics, times, arrays, [], h, begin, 0)
    if compiled:
        return _simulate_compiled(dyn, start, outputs, output_step, per_output, h, begin)
    w = 0.0
    passes: list[float] = []
    sigma = [dyn.project(q, qd)[3]] * 2

    def derivative(q, qd, t):
        return qd, dyn.acceleration(q, qd, t), dyn.power(q, qd, t)

    q_out[0], qd_out[0], qdd_out[0], energy[0] = q, qd, dyn.acceleration(q, qd, 0.0), dyn.energy(q, qd)
    for i in range(1, outputs + 1):
        drift = 0.0
        for j in range(per_output):
            t = times[i - 1] + j * h
            k1 = derivative(q, qd, t)
            k2 = derivative(q + 0.5 * h * k1[0], qd + 0.5 * h * k1[1], t + 0.5 * h)
            k3 = derivative(q + 0.5 * h * k2[0], qd + 0.5 * h * k2[1], t + 0.5 * h)
            k4 = derivative(q + h * k3[0], qd + h * k3[1], t + h)
            q = q + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
            qd = qd + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
            w += h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
                break  # (the least-squares solves refuse non-finite input)
            q, qd, before, value = dyn.project(q, qd)
            drift = max(drift, before)
            if sigma[1] < SINGULAR_THRESHOLD and sigma[1] <= sigma[0] and sigma[1] < value:
                passes.append(float(times[i - 1] + j * h))  # the previous step was the closest
            sigma = [sigma[1], value]
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
            return _stopped(kinematics, times, arrays, passes, h, begin, i)
        q_out[i], qd_out[i], qdd_out[i] = q, qd, dyn.acceleration(q, qd, times[i])
        residual[i], energy[i], work[i] = drift, dyn.energy(q, qd), w
    return FreeMotion(
        kinematics, times, q_out, qd_out, qdd_out, residual, energy, work, passes, h, time.process_time() - begin
    )


def _stopped(kinematics, times, arrays, passes, h, begin, failed) -> FreeMotion:
    """A run that went non-finite before output ``failed``: its outputs before it, and why."""
    q, qd, qdd, residual, energy, work = (a[:failed] for a in arrays)
    return FreeMotion(
        kinematics,
        times[:failed],
        q,
        qd,
        qdd,
        residual,
        energy,
        work,
        [t for t in passes if t < times[failed]],
        h,
        time.process_time() - begin,
        failure=f"the state went non-finite at t = {times[failed]:.6g} s",
    )


def _simulate_compiled(
    dyn: _Dynamics, start: FreeState, outputs: int, output_step: float, per_output: int, h: float, begin: float
) -> FreeMotion:
    """:func:`simulate_free` through the compiled integrator."""
    from .._numba import run_compiled
    from ._free_compiled import Packed, integrate

    q0 = np.ascontiguousarray(start.q, dtype=float)
    qd0 = np.ascontiguousarray(start.qd, dtype=float)
    packed = Packed(dyn)
    q, qd, qdd, residual, energy, work, passes, failed = run_compiled(
        integrate, packed.arrays(), packed.structure(), q0, qd0, h, per_output, outputs, output_step
    )
    times = np.arange(outputs + 1) * output_step
    if failed >= 0:
        passed = [float(t) for t in passes]
        return _stopped(dyn.kinematics, times, (q, qd, qdd, residual, energy, work), passed, h, begin, failed)
    return FreeMotion(
        dyn.kinematics,
        times,
        q,
        qd,
        qdd,
        residual,
        energy,
        work,
        [float(t) for t in passes],
        h,
        time.process_time() - begin,
    )


def consistent_state(kinematics: Kinematics, q: np.ndarray, qd: np.ndarray) -> FreeState:
    """(q, qd) projected onto the constraints (the M-weighted smallest change)."""
    dyn = _Dynamics(kinematics)
    q, qd, _, _ = dyn.project(np.asarray(q, dtype=float), np.asarray(qd, dtype=float))
    return FreeState(q, qd)


class HalvingSteps:
    """The settings of a fixed-step method's ladder: steps halved from ``first_step`` (s), at
    most ``max_halvings`` + 1 runs (of :class:`StepLadder` and
    :class:`._collocation.CollocationLadder`)."""

    fixed_step = True

    def __init__(self, kinematics, start, duration, output_step, first_step, max_halvings):
        self.kinematics, self.start, self.duration, self.output_step = kinematics, start, duration, output_step
        self.first, self.halvings = first_step, max(int(max_halvings), 1)

    def settings(self) -> list[float]:
        return [self.first / 2.0**k for k in range(self.halvings + 1)]

    def cost(self) -> str:
        return f"steps of {self.first:.3g} s over {self.duration:g} s"


class StepLadder(HalvingSteps):
    """RK4 (:func:`simulate_free`) at halving steps (:class:`HalvingSteps`); its error falls
    16 times a halving (order 4)."""

    name = "RK4"
    nominal: float | None = 16.0

    def __init__(self, kinematics, start, duration, output_step, first_step, max_halvings, compiled=True):
        super().__init__(kinematics, start, duration, output_step, first_step, max_halvings)
        self.compiled = compiled

    def run(self, setting: float, evaluations: float, start: FreeState | None = None) -> FreeMotion:
        start = self.start if start is None else start
        return simulate_free(self.kinematics, start, self.duration, self.output_step, setting, self.compiled)

    def work(self, setting: float, previous: FreeMotion | None) -> float:
        """Evaluations: four accelerations and a projection a step."""
        per_output = max(1, math.ceil(self.output_step / setting - 1e-9))
        return 5.0 * per_output * round(self.duration / self.output_step)

    def describe(self) -> str:
        return (
            f"RK4 at a fixed step on the index-1 equations (accelerations by Gauss's principle), positions and "
            f"velocities projected onto the constraints after every step; steps halved from {self.first:.4g} s, "
            f"at most {self.halvings + 1} runs"
        )


class ToleranceLadder:
    """DOP853 (:mod:`._adaptive`) at local tolerances divided by ten from ``first`` down to
    :data:`FINEST_TOLERANCE`."""

    name = "DOP853"
    nominal: float | None = None
    fixed_step = False

    def __init__(self, kinematics, start, duration, output_step, first, time_scale, source=""):
        self.kinematics, self.start, self.duration, self.output_step = kinematics, start, duration, output_step
        self.first, self.scale, self.source = first, time_scale, source

    def settings(self) -> list[float]:
        count = max(1, int(math.floor(math.log10(self.first / FINEST_TOLERANCE) + 1e-9)) + 1)
        return [self.first / 10.0**k for k in range(count)]

    def run(self, setting: float, evaluations: float, start: FreeState | None = None) -> FreeMotion:
        from ._adaptive import simulate_adaptive

        budget = int(min(evaluations, 2**62))
        start = self.start if start is None else start
        return simulate_adaptive(self.kinematics, start, self.duration, self.output_step, setting, budget)

    def work(self, setting: float, previous: FreeMotion | None) -> float:
        """Work in evaluations (as :func:`._adaptive.integrate_adaptive` counts it): the last
        run's 1.4 times (measured: 1.3 to 1.4 times a tenth of the tolerance), or before any,
        from the shortest time scale: DOP853's steps stay below about 3.3 of it (its stability
        on the negative real axis), each 13 evaluations, a projection and a look ahead for a
        singular position (31 in all); an output costs an evaluation and a projection (13)."""
        if previous is not None and "cost" in previous.statistics:
            return 1.4 * float(previous.statistics["cost"])
        steps = self.duration / (3.3 * self.scale) if self.scale > 0.0 else 0.0
        return 31.0 * steps + 13.0 * round(self.duration / self.output_step)

    def describe(self) -> str:
        return (
            "DOP853 (Dormand and Prince's Runge-Kutta pair of order 8 with error control and its dense "
            "output) on the index-1 equations, positions and velocities projected onto the constraints "
            f"after every step; local tolerances divided by ten from {self.first:.3g}, at most down to "
            f"{FINEST_TOLERANCE:g}"
        )

    def cost(self) -> str:
        by = f", set by {self.source}" if self.source else ""
        return (
            f"steps of at most 3.3 x the motion's shortest time scale, {self.scale:.3g} s{by}, over "
            f"{self.duration:g} s, and {round(self.duration / self.output_step)} outputs"
        )


#: the finest local tolerance of a DOP853 ladder (below it float64's round-off of the state
#: rules: on IFToMM A02 the ladders at 1e-11 of its size from 40 starts moved 4 ulps keep runs
#: 7.4e-13 to 1.7e-11 m off; the round-off the ladder measures bounds that at every output)
FINEST_TOLERANCE = 1e-15


def free_reference(
    kinematics: Kinematics,
    start: FreeState,
    duration: float,
    output_step: float,
    tolerance: float = 1e-9,
    first_step: float | None = None,
    max_halvings: int = 6,
    progress=None,
) -> FreeReference:
    """The RK4 reference: runs at halving steps judged by :func:`._reference.run_ladder`.

    Parameters
    ----------
    first_step : float, optional
        The coarsest step, s (default: output_step / 4, at most duration / 1000, and at
        most half the motion's shortest time scale, :func:`._reference.time_scale`).
    max_halvings : int
        The ladder has at most this many runs after the first.
    progress : callable, optional
        Called with a line before each run.
    """
    from ._reference import run_ladder, time_scale

    if first_step is None:
        first_step = min(output_step / 4.0, duration / 1000.0, 0.5 * time_scale(kinematics, start)[0])
    method = StepLadder(kinematics, start, duration, output_step, first_step, max_halvings)
    return run_ladder(kinematics, method, tolerance, progress=progress)


def adaptive_reference(
    kinematics: Kinematics,
    start: FreeState,
    duration: float,
    output_step: float,
    tolerance: float = 1e-9,
    progress=None,
) -> FreeReference:
    """The DOP853 reference: runs at local tolerances from a tenth of ``tolerance`` (at most
    1e-6, at least 1e-13) down, judged by :func:`._reference.run_ladder`."""
    from ._reference import run_ladder, time_scale

    first = min(max(0.1 * tolerance, 100.0 * FINEST_TOLERANCE), 1e-6)  # three runs at least
    method = ToleranceLadder(kinematics, start, duration, output_step, first, *time_scale(kinematics, start))
    return run_ladder(kinematics, method, tolerance, progress=progress)


def release_state(kinematics: Kinematics, branch: str | None = None) -> FreeState:
    """The state at which ``[free_motion]`` releases the mechanism: assembled at
    its drivers' values ``at``, the velocity from the drivers' rates
    ``velocity`` (others 0) or from one point's ``point_velocity`` through the
    velocity constraints.

    Raises
    ------
    ModelError
        If the file has no [free_motion], the mechanism does not assemble
        there, or the point velocity violates the constraints.
    """
    from ..errors import ModelError

    mech, system = kinematics.mechanism, kinematics.system
    spec = mech.free_motion
    if spec is None:
        raise ModelError(mech.path, "free_motion", "a [free_motion] section (duration, velocity, ...)", "none")
    inputs = np.array([[spec.at[d.name] for d in mech.drivers]])
    rates = np.array([[spec.rates.get(d.name, 0.0) for d in mech.drivers]])
    solution = kinematics.solve(inputs, rates, np.zeros_like(rates), branch=branch)
    if solution.status[0] > Status.NEAR_SINGULAR:
        raise ModelError(
            mech.path,
            "free_motion.at",
            "a position where the mechanism assembles with a determined velocity",
            Status(int(solution.status[0])).message,
        )
    q, qd = solution.q[0], solution.qd[0]
    if spec.point is not None and spec.point_velocity is not None:
        body = mech.point_owners[spec.point]
        if body not in system.body_index or system.body_index[body] < 0:
            raise ModelError(
                mech.path,
                "free_motion.point_velocity.point",
                "a point on a moving body",
                f"{spec.point!r} on the ground",
            )
        k = 3 * system.body_index[body]
        arm = rotate(q[k + 2], np.asarray(mech.body(body).points[spec.point], dtype=float))
        rows = np.zeros((2, system.n))
        rows[0, k], rows[1, k + 1] = 1.0, 1.0
        rows[:, k + 2] = [-arm[1], arm[0]]
        # the velocities the joints allow, qd = N a, and the a whose point velocity comes closest
        scaled = system.scaled_jacobian(system.jacobian(q[None], kinematic_only=True))[0]
        free = null_space(scaled) * system.coordinate_scale()[:, None] ** -1.0
        amounts, *_ = np.linalg.lstsq(rows @ free, spec.point_velocity, rcond=None)
        qd = free @ amounts
        miss = float(np.hypot(*(rows @ qd - spec.point_velocity)))
        if miss > 1e-9 * max(float(np.hypot(*spec.point_velocity)), 1e-300):
            raise ModelError(
                mech.path,
                "free_motion.point_velocity",
                "a velocity the joints allow at the release position",
                f"one they violate by {miss:.3g} m/s",
            )
    return consistent_state(kinematics, q, qd)


def simulate(
    kinematics: Kinematics,
    branch: str | None = None,
    duration: float | None = None,
    progress=None,
    check: bool = False,
    tolerance: float | None = None,
) -> FreeReference:
    """The native reference of the mechanism's ``[free_motion]`` (over ``duration``, s, a
    whole number of output steps, instead of the file's; to ``tolerance`` x the size instead
    of the file's): DOP853's ladder from :func:`release_state`; with ``check``, the ladder of
    Gauss-Legendre collocation (:mod:`._collocation`) too, compared with it (``reference.check``).

    Raises
    ------
    InputError
        A duration that is not a whole number of output steps, too many outputs, a
        motion no run can follow within the work budget.
    """
    from ._reference import compare_runs, free_duration

    spec = kinematics.mechanism.free_motion
    length = free_duration(kinematics, duration)
    assert spec is not None
    start = release_state(kinematics, branch)
    output = min(spec.output_step, length)
    tolerance = spec.tolerance if tolerance is None else tolerance
    reference = adaptive_reference(kinematics, start, length, output, tolerance, progress=progress)
    if check:  # Gauss-Legendre collocation at the reference's outputs
        from ._collocation import collocation_reference

        reference.check = compare_runs(
            kinematics, reference, collocation_reference(kinematics, start, length, output, tolerance, progress)
        )
    return reference
