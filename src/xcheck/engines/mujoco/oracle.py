"""MuJoCo's own kinematics of a compiled mechanism: loop-closure residuals and
Jacobians (equality rows of the constraint arrays), drift terms (``mj_jacDot``),
and the states of bodies and named points read back from ``mjData``.

Everything here uses MuJoCo's functions on MuJoCo's model; only the input
values and the starting configuration come from outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from xcheck.model import Mechanism

from .._continuation import crank_period, follow
from .mjcf import Layout

__all__ = ["STOP_TOLERANCE", "CONVERGED_TOLERANCE", "Oracle", "Projection"]

#: Newton stops once the loop violation is below this fraction of the mechanism's size.
STOP_TOLERANCE = 1e-15
#: A sample counts as assembled when its violation is below this fraction.
CONVERGED_TOLERANCE = 1e-10


@dataclass
class Projection:
    """Configurations found by Newton projection, N samples.

    Attributes
    ----------
    qpos : ndarray, shape (N, nq)
    residual : ndarray, shape (N,)
        Largest loop violation, m.
    iterations : ndarray of int, shape (N,)
    converged : ndarray of bool, shape (N,)
    steps : ndarray of int, shape (N,)
        Accepted continuation steps from the previous sample.
    stopped : int or None
        The first sample the walk did not reach (None: all reached).
    reason : str
        Why it stopped.
    """

    qpos: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    steps: np.ndarray | None = None
    stopped: int | None = None
    reason: str = ""


class Oracle:
    """Kinematics of one MuJoCo model of a mechanism.

    Parameters
    ----------
    model : mujoco.MjModel
        Compiled from the MJCF writer's output (hinge and slide joints only,
        so ``nq == nv`` and ``qpos`` and ``qvel`` share indices).
    mechanism : Mechanism
    layout : Layout
        The writer's layout (driver joints, site names).
    """

    def __init__(self, model: mujoco.MjModel, mechanism: Mechanism, layout: Layout):
        if model.nq != model.nv:
            raise ValueError(
                f"expected a model of hinge and slide joints (nq == nv), found nq = {model.nq}, nv = {model.nv}"
            )
        self.model, self.data = model, mujoco.MjData(model)
        self.mechanism, self.size = mechanism, mechanism.size
        self.nv = model.nv
        self.input_dofs = np.array([model.joint(name).dofadr[0] for name in layout.driver_joints])
        self.selector = np.zeros((len(self.input_dofs), self.nv))
        self.selector[np.arange(len(self.input_dofs)), self.input_dofs] = 1.0
        # input rows in metres: angles times the mechanism's size
        self.input_scale = np.array(
            [
                self.size if model.jnt_type[model.dof_jntid[j]] == mujoco.mjtJoint.mjJNT_HINGE else 1.0
                for j in self.input_dofs
            ]
        )
        self.bodies = [(b.name, model.body(b.name).id) for b in mechanism.moving_bodies]
        owners = mechanism.point_owners
        self.points = [(label, model.site(f"{owners[label]}.{label}").id) for label in owners]
        # (object 1, object 2, type) per equality: a connect gives 3 rows (its sites' points), a weld 6
        # (translation, then rotation), a joint equality (a gear pair) 1 (its joints' coordinates)
        self.equalities = [(model.eq_obj1id[i], model.eq_obj2id[i], model.eq_type[i]) for i in range(model.neq)]
        self._jacp, self._jacr = np.zeros((3, self.nv)), np.zeros((3, self.nv))
        # coordinates made dimensionless: hinges in rad, slides per mechanism size
        self.coordinate_scale = np.array(
            [
                1.0 if model.jnt_type[model.dof_jntid[j]] == mujoco.mjtJoint.mjJNT_HINGE else 1.0 / self.size
                for j in range(self.nv)
            ]
        )

    # -- loop closure -------------------------------------------------------
    def constraints(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Equality residual and Jacobian at ``qpos`` (``mj_fwdPosition``).

        Returns
        -------
        residual : ndarray, shape (r,)
            ``efc_pos`` of the equality rows, m (3 per connect; z is zero).
        jacobian : ndarray, shape (r, nv)
            ``efc_J`` of those rows, dense.
        """
        m, d = self.model, self.data
        d.qpos[:] = qpos
        mujoco.mj_fwdPosition(m, d)
        rows = np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        if mujoco.mj_isSparse(m):
            dense = np.zeros((d.nefc, self.nv))
            mujoco.mju_sparse2dense(dense, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
        else:
            dense = d.efc_J[: d.nefc * self.nv].reshape(d.nefc, self.nv)
        # a joint equality's row is in radians: in metres, as the native residual's, times the size
        scale = np.where(m.eq_type[d.efc_id[rows]] == mujoco.mjtEq.mjEQ_JOINT, self.size, 1.0)
        return d.efc_pos[rows] * scale, dense[rows] * scale[:, None]

    def _system(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The loop rows stacked over the input rows: residual (r,) and matrix (r + k, nv)."""
        residual, jacobian = self.constraints(qpos)
        return residual, np.vstack([jacobian, self.selector])

    def _lstsq(self, matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Least squares of the loop rows over the input rows (a planar loop's z rows are
        zero, so the stack is not square), equilibrated first: rows per size (angle
        inputs' as they are), slide columns per size. Unscaled, the hinge columns carry
        lengths and the slide ones not, and the solution's round-off grew with that
        spread instead of the mechanism's conditioning."""
        rows = np.ones(matrix.shape[0]) / self.size
        rows[matrix.shape[0] - len(self.input_dofs) :] = self.coordinate_scale[self.input_dofs]
        columns = 1.0 / self.coordinate_scale
        scaled = np.linalg.lstsq(rows[:, None] * matrix * columns, (rows * rhs.T).T, rcond=None)[0]
        return (columns * scaled.T).T

    def violation(self, qpos: np.ndarray) -> float:
        """Largest loop violation at ``qpos``, m."""
        residual, _ = self.constraints(qpos)
        return float(np.max(np.abs(residual), initial=0.0))

    def newton(self, q: np.ndarray, c: np.ndarray, max_iter: int = 30) -> tuple[np.ndarray, float, int, bool]:
        """Newton steps on [efc_pos; q_in - c] = 0 from ``q`` (nv,) at inputs ``c`` (k,).

        Returns
        -------
        q : ndarray, shape (nv,)
            The best iterate (stops when no longer improving: the round-off floor).
        violation : float
            Its largest loop violation, m.
        iterations : int
        converged : bool
            Loops and inputs within ``CONVERGED_TOLERANCE`` of the size.
        """
        stop, ok = STOP_TOLERANCE * self.size, CONVERGED_TOLERANCE * self.size
        best_q, best, best_loop, iterations = np.array(q, dtype=float), np.inf, np.inf, 0
        for it in range(max_iter + 1):
            loop, matrix = self._system(q)
            rows = np.concatenate([loop, q[self.input_dofs] - c])
            loop_value = float(np.max(np.abs(loop), initial=0.0))
            value = max(loop_value, float(np.max(np.abs(rows[loop.size :]) * self.input_scale)))
            if not value < best:  # no longer improving: round-off floor (or divergence)
                break
            best_q, best, best_loop = q, value, loop_value
            if value <= stop or it == max_iter:
                break
            q = q - self._lstsq(matrix, rows)
            iterations = it + 1
        return best_q, best_loop, iterations, best <= ok

    def system_matrix(self, qpos: np.ndarray) -> np.ndarray:
        """MuJoCo's loop Jacobian over the inputs' rows at ``qpos``: shape (r + k, nv)."""
        return self._system(qpos)[1]

    def project(self, start: np.ndarray, start_inputs: np.ndarray, inputs: np.ndarray) -> Projection:
        """MuJoCo's Newton walked along a sweep, each sample from the previous one
        (:func:`xcheck.engines._continuation.follow`).

        Parameters
        ----------
        start : ndarray, shape (nq,)
            An assembled configuration at ``start_inputs`` (k,), next to ``inputs[0]``;
            projected onto MuJoCo's loops first.
        inputs : ndarray, shape (N, k)
            Input values (rad or m) in the order the mechanism moves through them.

        Notes
        -----
        Each step is predicted from the previous accepted one along the tangent
        dq/dc (MuJoCo's constraint Jacobian with the inputs' rows), corrected by
        Newton steps, and halved while the correction is large or the
        determinant of the square system changes sign. ``stopped`` and
        ``reason`` say where the branch could not be followed.
        """
        start = np.asarray(start, dtype=float)
        walk = follow(
            self.newton,
            self.system_matrix,
            self.constraints(start)[0].size,
            start,
            np.asarray(start_inputs, dtype=float),
            np.asarray(inputs, dtype=float),
            self.coordinate_scale[self.input_dofs],
            self.coordinate_scale,
            crank_period(self.mechanism),
        )
        return Projection(
            walk.qpos, walk.residual, walk.iterations, walk.converged, walk.steps, walk.stopped, walk.reason
        )

    def tangent(self, qpos: np.ndarray) -> np.ndarray:
        """dq/dc at ``qpos``: shape (nv, k)."""
        _, matrix = self._system(qpos)
        rhs = np.vstack(
            [
                np.zeros((matrix.shape[0] - self.selector.shape[0], self.selector.shape[0])),
                np.eye(self.selector.shape[0]),
            ]
        )
        return self._lstsq(matrix, rhs)

    def velocity(self, qpos: np.ndarray, rates: np.ndarray) -> np.ndarray:
        """Joint velocities with the inputs' rates imposed: J qd = 0, qd_in = rates; (nv,)."""
        loop, matrix = self._system(qpos)
        return self._lstsq(matrix, np.concatenate([np.zeros(loop.size), rates]))

    def drift(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """J-dot qd of the loop rows (m/s^2), from ``mj_jacDot`` at both sites of each connect or weld; (r,).

        A weld's rotation rows have no drift in a plane: their Jacobian is
        constant (rotations about z only) and their residual, the vector part
        of the relative quaternion, has a zero second-order term where it is
        zero; a joint equality (a gear pair's, linear) has none either.
        """
        m, d = self.model, self.data
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_comVel(m, d)
        out = []
        for obj1, obj2, kind in self.equalities:
            if kind == mujoco.mjtEq.mjEQ_JOINT:  # linear in the joints' coordinates: no drift
                out.append(np.zeros(1))
                continue
            out.append(self._point_drift(obj1, qvel) - self._point_drift(obj2, qvel))
            if kind == mujoco.mjtEq.mjEQ_WELD:
                out.append(np.zeros(3))
        return np.concatenate(out) if out else np.zeros(0)

    def _point_drift(self, site: int, qvel: np.ndarray) -> np.ndarray:
        mujoco.mj_jacDot(
            self.model, self.data, self._jacp, None, self.data.site_xpos[site], self.model.site_bodyid[site]
        )
        return self._jacp @ qvel

    def acceleration(self, qpos: np.ndarray, qvel: np.ndarray, accelerations: np.ndarray) -> np.ndarray:
        """Joint accelerations: J qdd = -J-dot qd, qdd_in = accelerations; (nv,)."""
        _, matrix = self._system(qpos)
        return self._lstsq(matrix, np.concatenate([-self.drift(qpos, qvel), accelerations]))

    # -- states -------------------------------------------------------------
    def states(self, qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray) -> tuple[dict, dict]:
        """Bodies' and named points' states over N samples, read from MuJoCo.

        Parameters
        ----------
        qpos, qvel, qacc : ndarray, shape (N, nv)

        Returns
        -------
        bodies : dict
            Per moving body: position (N, 2), angle (N,), velocity, omega,
            acceleration, alpha (body frame origin; ``xpos``, ``xmat``,
            ``mj_jac`` and ``mj_jacDot``).
        points : dict
            Per point label (its first owner's site): position, velocity,
            acceleration, each (N, 2).
        """
        m, d = self.model, self.data
        n = qpos.shape[0]
        bodies: dict[str, dict[str, np.ndarray]] = {
            name: {
                "position": np.empty((n, 2)),
                "angle": np.empty(n),
                "velocity": np.empty((n, 2)),
                "omega": np.empty(n),
                "acceleration": np.empty((n, 2)),
                "alpha": np.empty(n),
            }
            for name, _ in self.bodies
        }
        points: dict[str, dict[str, np.ndarray]] = {
            label: {"position": np.empty((n, 2)), "velocity": np.empty((n, 2)), "acceleration": np.empty((n, 2))}
            for label, _ in self.points
        }
        jacp, jacr, dotp, dotr = (np.zeros((3, self.nv)) for _ in range(4))
        for i in range(n):
            d.qpos[:], d.qvel[:] = qpos[i], qvel[i]
            mujoco.mj_fwdPosition(m, d)
            mujoco.mj_comVel(m, d)
            for name, body in self.bodies:
                point = d.xpos[body]
                mujoco.mj_jac(m, d, jacp, jacr, point, body)
                mujoco.mj_jacDot(m, d, dotp, dotr, point, body)
                out = bodies[name]
                out["position"][i] = point[:2]
                out["angle"][i] = np.arctan2(d.xmat[body, 3], d.xmat[body, 0])
                out["velocity"][i] = jacp[:2] @ qvel[i]
                out["omega"][i] = jacr[2] @ qvel[i]
                out["acceleration"][i] = jacp[:2] @ qacc[i] + dotp[:2] @ qvel[i]
                out["alpha"][i] = jacr[2] @ qacc[i] + dotr[2] @ qvel[i]
            for label, site in self.points:
                point, body = d.site_xpos[site], m.site_bodyid[site]
                mujoco.mj_jac(m, d, jacp, None, point, body)
                mujoco.mj_jacDot(m, d, dotp, None, point, body)
                out = points[label]
                out["position"][i] = point[:2]
                out["velocity"][i] = jacp[:2] @ qvel[i]
                out["acceleration"][i] = jacp[:2] @ qacc[i] + dotp[:2] @ qvel[i]
        return bodies, points
