"""Pinocchio's own kinematics of a closed-loop mechanism: loop residuals and
Jacobians from the constraint models, drift from frame classical accelerations,
and the states of the body and point frames.

Every function here works on one sample; the caller loops. ``q``, ``v``, ``a``
are Pinocchio joint coordinates and their rates (nq = nv, m or rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from xcheck.results import Trajectory

from .._continuation import Walk, crank_period, follow
from .model import PinocchioMechanism

__all__ = ["Oracle", "NEWTON_TOLERANCE", "CONVERGED_TOLERANCE", "frame_states", "one_line", "run_trajectory"]

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
#: Newton stops when every loop and driver residual is below this times the
#: mechanism's size (m; rad for angle inputs): round-off is ~1e-16.
NEWTON_TOLERANCE = 1e-14
#: A projection counts as converged below this times the size (as MuJoCo's and the native solver's);
#: Newton goes on towards NEWTON_TOLERANCE while it improves.
CONVERGED_TOLERANCE = 1e-10
_MAX_ITERATIONS = 30


@dataclass
class Oracle:
    """Newton projection, velocity and acceleration of a mechanism in Pinocchio.

    The rows of the full system are the loop closures (3 per CONTACT_3D cut,
    the z row identically zero; 6 per CONTACT_6D, rows z, rotation x and y
    zero) followed by one row per driver, ``sign * q[index] = c``.
    Systems are solved in the least-squares sense (``lstsq``), which is exact
    for a consistent system of full column rank.

    Parameters
    ----------
    pm : PinocchioMechanism
        The description; this object holds its own ``data`` workspace.
    """

    pm: PinocchioMechanism
    data: pin.Data = field(init=False)
    cds: list = field(init=False)

    def __post_init__(self):
        self._model = self.pm.model
        self.data = self._model.createData()
        self.cds = self.pm.constraint_datas()
        self.selector = self.pm.input_selector()
        self.rows = self.pm.constraint_rows()
        self.n_loop = sum(n for _, n in self.rows)
        self._size = float(self.pm.mechanism.size)

    def solve(self, jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Least squares of [J_loop; S] x = rhs ((rows,) or (rows, m)), equilibrated first:
        rows per size (angle inputs' as they are), slide columns per size. Unscaled, the
        revolute columns carry lengths and the prismatic ones not, and the round-off
        grew with that spread: reactions 3.7e-12 to 1.1e-11 of their scale on a Scotch
        yoke of 81 m to 81 km (xcheck fuzz s1-00052), 1e-15 equilibrated."""
        size = self._size
        columns = 1.0 / self.coordinate_scale(size)
        rows = np.ones(jac.shape[0]) / size
        rows[self.n_loop :] = np.abs(self.selector) @ self.coordinate_scale(size)
        scaled = np.linalg.lstsq(rows[:, None] * jac * columns, (rows * np.asarray(rhs).T).T, rcond=None)[0]
        return (columns * scaled.T).T

    # -- loop closure ------------------------------------------------------
    def loop_residual(self, q: np.ndarray) -> np.ndarray:
        """Anchor 1 minus anchor 2 of each cut, world axes, shape (loop rows,), m; a
        CONTACT_6D's rotation rows: the rotation vector from anchor 2 to anchor 1 (rad)."""
        model, data = self._model, self.data
        pin.forwardKinematics(model, data, q)
        out = np.empty(self.n_loop)
        for (start, n), cm, cd in zip(self.rows, self.pm.constraints, self.cds):
            cm.calc(model, data, cd)
            out[start : start + 3] = cd.oMc1.translation - cd.oMc2.translation
            if n == 6:
                out[start + 3 : start + 6] = pin.log3(cd.oMc1.rotation @ cd.oMc2.rotation.T)
        return out

    def loop_jacobian(self, q: np.ndarray) -> np.ndarray:
        """d(loop_residual)/dq from ``getConstraintsJacobian``, shape (loop rows, nv).

        Call after :meth:`loop_residual` at the same q.
        """
        if not self.n_loop:
            return np.zeros((0, self._model.nv))
        pin.computeJointJacobians(self._model, self.data, q)
        return pin.getConstraintsJacobian(self._model, self.data, self.pm.constraints, self.cds)

    def system(self, q: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(residual (loop rows + k,), Jacobian (loop rows + k, nv)) of loops and drivers."""
        residual = np.concatenate([self.loop_residual(q), self.selector @ q - c])
        return residual, np.vstack([self.loop_jacobian(q), self.selector])

    def project(self, q: np.ndarray, c: np.ndarray, size: float):
        """Newton-Raphson onto the loops at inputs ``c`` (k,) from ``q``.

        Iterates until every loop and driver residual is below
        ``NEWTON_TOLERANCE`` of the size (driver rows of angles times the size),
        or, below ``CONVERGED_TOLERANCE`` of it, until a step no longer
        improves: the round-off floor, which grows with the coordinates'
        magnitudes (a rod of 426 km at a crank angle of 136 rad, many turns
        on: 6e-9 m = 1.4e-14 of the size, eps x 136 x 426 km).

        Returns
        -------
        q : ndarray, shape (nq,)
        residual : float
            Largest loop residual, m.
        iterations : int
        converged : bool
        """
        q = np.array(q, dtype=float)
        metres = np.concatenate([np.ones(self.n_loop), np.abs(self.selector) @ (size * self.coordinate_scale(size))])
        best_q, best, best_loop, best_iteration = q, np.inf, np.inf, 0
        for iteration in range(_MAX_ITERATIONS + 1):
            residual, jac = self.system(q, c)
            worst = float(np.max(np.abs(residual) * metres, initial=0.0))
            loop = float(np.max(np.abs(residual[: self.n_loop]), initial=0.0))
            if not np.isfinite(worst) or (not worst < best and best <= CONVERGED_TOLERANCE * size):
                break  # no longer improving at the round-off floor (or diverged)
            if worst < best:
                best_q, best, best_loop, best_iteration = q, worst, loop, iteration
            if worst <= NEWTON_TOLERANCE * size or iteration == _MAX_ITERATIONS:
                break
            q = q - self.solve(jac, residual)
        return best_q, best_loop, best_iteration, best <= CONVERGED_TOLERANCE * size

    def system_matrix(self, q: np.ndarray) -> np.ndarray:
        """[J_loop; S] at q: shape (loop rows + k, nv)."""
        self.loop_residual(q)
        return np.vstack([self.loop_jacobian(q), self.selector])

    def coordinate_scale(self, size: float) -> np.ndarray:
        """Per velocity coordinate (nv,): 1 for an angle, 1/size for a slide (makes them dimensionless)."""
        scale = np.ones(self._model.nv)
        for joint in self._model.joints[1:]:
            if "Prismatic" in joint.shortname():
                scale[joint.idx_v : joint.idx_v + joint.nv] = 1.0 / size
        return scale

    def follow(self, q: np.ndarray, c: np.ndarray, inputs: np.ndarray, size: float) -> Walk:
        """Pinocchio's Newton walked from (q (nq,), c (k,)) through ``inputs`` (N, k) in
        order, each step predicted along Pinocchio's tangent and halved while the
        correction is large or the determinant changes sign
        (:func:`xcheck.engines._continuation.follow`)."""
        scale = self.coordinate_scale(size)
        selected = np.abs(self.selector) @ scale  # each input's coordinate's scale, (k,)
        return follow(
            lambda guess, target: self.project(guess, target, size),
            self.system_matrix,
            self.n_loop,
            np.asarray(q, dtype=float),
            np.asarray(c, dtype=float),
            np.asarray(inputs, dtype=float),
            selected,
            scale,
            crank_period(self.pm.mechanism),
        )

    def rates(self, q: np.ndarray, right: np.ndarray) -> np.ndarray:
        """Solve [J_loop; S] x = [0; right] for x (nv,) or (nv, m) at q.

        With ``right`` the input rates this is the velocity; with the identity
        (k, k) the tangent dq/dc.
        """
        self.loop_residual(q)
        jac = np.vstack([self.loop_jacobian(q), self.selector])
        rhs = np.zeros((jac.shape[0],) + np.shape(right)[1:])
        rhs[self.n_loop :] = right
        return self.solve(jac, rhs)

    def drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Loop acceleration at zero joint acceleration, shape (loop rows,), m/s^2:
        classical acceleration of anchor 1 minus anchor 2 (world axes); a
        CONTACT_6D's rotation rows: angular acceleration 1 minus 2 (rad/s^2)."""
        model, data = self._model, self.data
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        out = np.empty(self.n_loop)
        for (start, n), cm in zip(self.rows, self.pm.constraints):
            a1 = pin.getFrameClassicalAcceleration(model, data, cm.joint1_id, cm.joint1_placement, LWA)
            a2 = pin.getFrameClassicalAcceleration(model, data, cm.joint2_id, cm.joint2_placement, LWA)
            out[start : start + 3] = a1.linear - a2.linear
            if n == 6:
                out[start + 3 : start + 6] = a1.angular - a2.angular
        return out

    def acceleration(self, q: np.ndarray, v: np.ndarray, input_accelerations: np.ndarray) -> np.ndarray:
        """Joint accelerations (nv,) with J a = -drift and S a = input accelerations."""
        drift = self.drift(q, v)
        self.loop_residual(q)
        jac = np.vstack([self.loop_jacobian(q), self.selector])
        rhs = np.concatenate([-drift, input_accelerations])
        return self.solve(jac, rhs)


def frame_states(pm: PinocchioMechanism, data: pin.Data, q, v, a) -> tuple[dict, dict]:
    """Positions, velocities and classical accelerations of every body frame
    and named point at one state (q, v, a), world axes.

    Returns
    -------
    bodies : dict of str to dict
        Per moving body: position (2,), angle (float), velocity (2,), omega,
        acceleration (2,), alpha (SI).
    points : dict of str to dict
        Per ``"<body>.<label>"``: position, velocity, acceleration, each (2,).
    """
    model = pm.model
    pin.forwardKinematics(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    bodies, points = {}, {}
    for name, fid in pm.body_frames.items():
        placement = data.oMf[fid]
        vel = pin.getFrameVelocity(model, data, fid, LWA)
        acc = pin.getFrameClassicalAcceleration(model, data, fid, LWA)
        bodies[name] = {
            "position": placement.translation[:2].copy(),
            "angle": float(np.arctan2(placement.rotation[1, 0], placement.rotation[0, 0])),
            "velocity": vel.linear[:2].copy(),
            "omega": float(vel.angular[2]),
            "acceleration": acc.linear[:2].copy(),
            "alpha": float(acc.angular[2]),
        }
    for name, fid in pm.point_frames.items():
        vel = pin.getFrameVelocity(model, data, fid, LWA)
        acc = pin.getFrameClassicalAcceleration(model, data, fid, LWA)
        points[name] = {
            "position": data.oMf[fid].translation[:2].copy(),
            "velocity": vel.linear[:2].copy(),
            "acceleration": acc.linear[:2].copy(),
        }
    return bodies, points


def one_line(error: BaseException) -> str:
    """An exception as the one-line reason of a failed mode."""
    return " ".join(str(error).split()) or type(error).__name__


def run_trajectory(pm, oracle: Oracle, rows, source: str, settings: dict, notes: str) -> Trajectory:
    """A run's recorded states as a Trajectory: ``rows`` are (t, q, v, a, force) per
    sample; diagnostics constraint_violation (m) and velocity_violation (m/s) of the
    loops, and input_force."""
    mech = pm.mechanism
    m = len(rows)
    times = np.array([r[0] for r in rows])
    q, v, a, force = (np.array([r[i] for r in rows]) for i in (1, 2, 3, 4))
    s = oracle.selector
    bodies: dict[str, dict[str, np.ndarray]] = {b.name: {} for b in mech.moving_bodies}
    points: dict[str, dict[str, np.ndarray]] = {label: {} for label in mech.point_owners}
    states = [frame_states(pm, oracle.data, q[i], v[i], a[i]) for i in range(m)]
    for name in bodies:
        for quantity in ("position", "angle", "velocity", "omega", "acceleration", "alpha"):
            bodies[name][quantity] = np.array([st[0][name][quantity] for st in states])
    for label, owner in mech.point_owners.items():
        for quantity in ("position", "velocity", "acceleration"):
            points[label][quantity] = np.array([st[1][f"{owner}.{label}"][quantity] for st in states])
    loop = np.array([np.max(np.abs(oracle.loop_residual(qi)), initial=0.0) for qi in q])
    velocity_loop = []
    for qi, vi in zip(q, v):
        oracle.loop_residual(qi)
        velocity_loop.append(float(np.max(np.abs(oracle.loop_jacobian(qi) @ vi), initial=0.0)))
    return Trajectory(
        source=source,
        inputs=q @ s.T,
        input_rates=v @ s.T,
        input_accelerations=a @ s.T,
        bodies=bodies,
        points=points,
        times=times,
        settings=settings,
        diagnostics={"constraint_violation": loop, "velocity_violation": np.array(velocity_loop), "input_force": force},
        notes=notes,
    )
