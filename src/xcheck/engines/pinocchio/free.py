"""Free motion in Pinocchio (mode ``pinocchio-free``): the mechanism released,
integrated with ``constraintDynamics``; the ladder and its judgement are
:func:`xcheck.ladder.free_study`'s.

The tree and its loop closures are :mod:`.model`'s (CONTACT_3D/6D
``RigidConstraintModel`` s). No driver acts (tau = 0 on every joint): the
drivers only placed the mechanism. Gravity is the model's (``model.gravity``);
the file's constant loads and its springs enter as generalised forces
J^T f through the Jacobians of the body and point frames. The start is the
reference's initial native state, mapped to Pinocchio's q (Newton
projection onto the loops at the native inputs) and v (the constraint
Jacobian with the native input rates).

The series: RK4 without and with Baumgarte correction and semi-implicit Euler
with it, the integrator code of :mod:`.dynamic`'s driven mode.

Measured on the IFToMM double four-bar (A02) over 10 s (singular passes at
0.71, 1.23, 2.66, 3.17 s, ...), default ladder 9.9 s CPU: RK4 without
Baumgarte stops with NaN at the 3rd or 4th singular pass (dt 1e-3: NaN at
3.174 s, 9.4e-6 m until then; 2.5e-4: NaN at 2.658 s), its loops drifting
(6.6e-7 m at 1e-3); with Baumgarte it runs through, 1.7e-9 m at every step
(the reference's own error), loops closed to 2e-13 m; semi-implicit Euler
with Baumgarte 2.9e-5, 7.3e-6, 1.8e-6 m (order 2.0). With mu 1e-8 RK4
without Baumgarte also stops (NaN at 3.174 s at dt 1e-3, leaves the branch
at 4.2 s at 5e-4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from xcheck.kinematics import Kinematics
from xcheck.ladder import FreeProblem, Run, Rung, Series, conservative

from .dynamic import BAUMGARTE, PROXIMAL_ACCURACY, PROXIMAL_MAX_ITER, Setting
from .model import PinocchioMechanism, build_model, joint_coordinates, point_frame, tree_spec
from .oracle import LWA, Oracle, run_trajectory

__all__ = ["FREE_SERIES", "FREE_MU", "prepare_free", "run_free_once"]

MODE = "pinocchio-free"
#: Proximal mu of constraintDynamics in free motion (a planar loop's z row is
#: zero: the Delassus matrix is singular and needs mu > 0): 1e-12, the engine
#: notes' setting; see the module's notes for mu 1e-8 on the IFToMM double four-bar.
FREE_MU = 1e-12


FREE_SERIES = (
    Series("rk4", "rk4", Setting("rk4", mu=FREE_MU)),
    Series("rk4-baumgarte", "rk4", Setting("rk4", BAUMGARTE, FREE_MU)),
    Series("semi-implicit-euler-baumgarte", "euler", Setting("euler", BAUMGARTE, FREE_MU)),
)


def _jacobian(model, data, fid: int) -> np.ndarray:
    """A frame's Jacobian, LOCAL_WORLD_ALIGNED, shape (6, nv) (Pinocchio returns (6,) when nv = 1)."""
    return np.reshape(pin.getFrameJacobian(model, data, fid, LWA), (6, model.nv))


class _Free:
    """q'' = f(q, v) of the released mechanism: constraintDynamics with the applied forces."""

    def __init__(self, pm: PinocchioMechanism, mu: float, baumgarte: tuple[float, float] | None, q0_native: np.ndarray):
        self.pm, self.model = pm, pm.model
        self.data = pm.model.createData()
        self.cms = [pin.RigidConstraintModel(cm) for cm in pm.constraints]  # copies: gains are per run
        if baumgarte is not None:
            for cm in self.cms:
                cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(*baumgarte))
        self.cds = [cm.createData() for cm in self.cms]
        pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
        self.settings = pin.ProximalSettings(PROXIMAL_ACCURACY, mu, PROXIMAL_MAX_ITER)
        self.work_data = pm.model.createData()
        mech = pm.mechanism
        self.loads = [
            (
                pm.body_frames[load.body],
                np.asarray(load.point, float),
                np.asarray(load.force, float),
                load.torque,
                load.law,
            )
            for load in mech.loads
            if load.body in pm.body_frames
        ]
        owners = mech.point_owners
        self.springs = [
            (
                pm.point_frames[point_frame(owners[s.points[0]], s.points[0])],
                pm.point_frames[point_frame(owners[s.points[1]], s.points[1])],
                s.stiffness,
                s.rest_length,
                s.damping,
            )
            for s in mech.springs
        ]
        index = {b.name: i for i, b in enumerate(mech.moving_bodies)}
        self.twists = [
            (pm.body_frames.get(t.body_a), pm.body_frames.get(t.body_b), t.stiffness, t.rest_angle, t.damping)
            for t in mech.rotational_springs
        ]
        # each rotational spring's angle phi_b - phi_a, continuous from the native initial state
        start = {name: float(q0_native[3 * i + 2]) for name, i in index.items()}  # the ground's is 0
        self._twist = [start.get(t.body_b, 0.0) - start.get(t.body_a, 0.0) for t in mech.rotational_springs]
        self._twist_energy = list(self._twist)
        self._angles: dict[int, float] = {}
        self.evaluations = 0
        self.proximal_iterations = 0
        # no load nor spring: one zero force serves every evaluation (Pinocchio does not write to it)
        self._unforced = None if self.loads or self.springs or self.twists else np.zeros(self.model.nv)

    def applied(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Generalised force of the loads at time t (s) and of the springs (nv,), N or N m."""
        tau = np.zeros(self.model.nv)
        if not self.loads and not self.springs and not self.twists:
            return tau
        model, data = self.model, self.work_data
        pin.forwardKinematics(model, data, q, v)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for fid, point, force, torque, law in self.loads:
            if law is not None:
                factor = float(law.factor(t))
                force, torque = factor * force, factor * torque
            jac = _jacobian(model, data, fid)
            arm = data.oMf[fid].rotation[:2, :2] @ point
            moment = arm[0] * force[1] - arm[1] * force[0] + torque
            tau += jac[:2].T @ force + jac[5] * moment
        for first, second, stiffness, rest, damping in self.springs:
            d = data.oMf[second].translation[:2] - data.oMf[first].translation[:2]
            length = float(np.hypot(d[0], d[1]))
            unit = d / length if length > 0.0 else np.zeros(2)
            rel = (
                pin.getFrameVelocity(model, data, second, LWA).linear[:2]
                - pin.getFrameVelocity(model, data, first, LWA).linear[:2]
            )
            tension = stiffness * (length - rest) + damping * float(unit @ rel)
            for fid, force in ((first, tension * unit), (second, -tension * unit)):
                tau += _jacobian(model, data, fid)[:2].T @ force
        for k, (first, second, stiffness, rest, damping) in enumerate(self.twists):
            twist = self._turned(k, self._twist, first, second)
            rate = sum(
                sign * pin.getFrameVelocity(model, data, fid, LWA).angular[2]
                for fid, sign in ((second, 1.0), (first, -1.0))
                if fid is not None
            )
            torque = -stiffness * (twist - rest) - damping * rate  # on the second body
            for fid, sign in ((second, 1.0), (first, -1.0)):
                if fid is not None:
                    tau += _jacobian(model, data, fid)[5] * sign * torque
        return tau

    def _turned(self, k: int, last: list[float], first, second) -> float:
        """Rotational spring k's angle phi_b - phi_a from the frames (``work_data``'s placements),
        to the nearest turn from ``last[k]``, which it updates."""
        data = self.work_data
        twist = 0.0
        for fid, sign in ((second, 1.0), (first, -1.0)):
            if fid is not None:
                rotation = data.oMf[fid].rotation
                twist += sign * math.atan2(rotation[1, 0], rotation[0, 0])
        twist += 2.0 * math.pi * round((last[k] - twist) / (2.0 * math.pi))
        last[k] = twist
        return twist

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic + gravitational + spring energy (linear and rotational) minus the constant loads' potential, J
        (a constant force f at a point r has potential -f . r, a couple T on angle phi -T phi;
        the angle is kept continuous from one call to the next: call it in time order)."""
        model, data = self.model, self.work_data
        total = pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(model, data, q)
        pin.updateFramePlacements(model, data)
        for i, (fid, point, force, torque, _) in enumerate(self.loads):
            placement = data.oMf[fid]
            r = placement.translation[:2] + placement.rotation[:2, :2] @ point
            phi = math.atan2(placement.rotation[1, 0], placement.rotation[0, 0])
            if i in self._angles:  # continuous from the previous call (a turn below pi between calls)
                phi += 2.0 * math.pi * round((self._angles[i] - phi) / (2.0 * math.pi))
            self._angles[i] = phi
            total -= float(force @ r) + torque * phi
        for first, second, stiffness, rest, _ in self.springs:
            length = float(np.linalg.norm(data.oMf[second].translation - data.oMf[first].translation))
            total += 0.5 * stiffness * (length - rest) ** 2
        for k, (first, second, stiffness, rest, _) in enumerate(self.twists):
            total += 0.5 * stiffness * (self._turned(k, self._twist_energy, first, second) - rest) ** 2
        return float(total)

    def _constraint_dynamics(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """q'' (nv,) at (q, v) and time t (s): Pinocchio's own array, overwritten by the next call."""
        self.evaluations += 1
        tau = self.applied(q, v, t) if self._unforced is None else self._unforced
        a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.cms, self.cds, self.settings)
        self.proximal_iterations = max(self.proximal_iterations, self.settings.iter)
        return a

    def acceleration(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> np.ndarray:
        """q'' (nv,) at (q, v) and time t (s)."""
        return self._constraint_dynamics(q, v, t).copy()

    def derivative(self, state: np.ndarray, t: float) -> np.ndarray:
        """(v, q'') (2 nv,) of the state (q, v) (2 nv,) at time t (s): what an explicit
        Runge-Kutta method steps (q and v one array: half the array operations)."""
        n = self.model.nv
        out = np.empty(2 * n)
        out[:n] = state[n:]
        out[n:] = self._constraint_dynamics(state[:n], state[n:], t)
        return out


def _start(kinematics: Kinematics, pm: PinocchioMechanism, oracle: Oracle, problem: FreeProblem):
    """Pinocchio's (q0, v0) of the reference's initial native state.

    q0: :func:`.model.joint_coordinates` of the native body coordinates,
    projected onto the loops at its own input values; v0: the joint rates
    whose body-frame velocities (x', y', phi' of every moving body, LOCAL_WORLD_ALIGNED
    frame Jacobians) are the native ones, in the least-squares sense (exact
    when the native state closes the loops).

    Raises
    ------
    ValueError
        If the native state does not close Pinocchio's loops.
    """
    size = kinematics.system.size
    q_native, qd_native = problem.start
    guess = joint_coordinates(pm, q_native)
    q0, residual, _, converged = oracle.project(guess, oracle.selector @ guess, size)
    if not converged:
        raise ValueError(f"the reference's initial state does not close Pinocchio's loops (residual {residual:.3g} m)")
    model, data = pm.model, oracle.data
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)
    names = [b.name for b in pm.mechanism.moving_bodies]
    rows = np.vstack([_jacobian(model, data, pm.body_frames[name])[[0, 1, 5]] for name in names])
    v0 = np.linalg.lstsq(rows, qd_native, rcond=None)[0]
    miss = float(np.max(np.abs(rows @ v0 - qd_native), initial=0.0))
    if miss > 1e-9 * max(float(np.max(np.abs(qd_native), initial=0.0)), 1.0):
        raise ValueError(f"the reference's initial velocity is not one of Pinocchio's tree (off by {miss:.3g})")
    return q0, v0


@dataclass
class PinocchioFree:
    """What every free run shares: the model, its oracle and the start (q0, v0)."""

    pm: PinocchioMechanism
    oracle: Oracle
    q0: np.ndarray
    v0: np.ndarray


def prepare_free(problem: FreeProblem) -> PinocchioFree:
    """The model (:func:`.model.build_model`) and the reference's initial state in it.

    Raises
    ------
    ValueError
        If the native state does not close Pinocchio's loops.
    """
    kinematics = problem.kinematics
    pm = build_model(tree_spec(kinematics.mechanism))
    oracle = Oracle(pm)
    q0, v0 = _start(kinematics, pm, oracle, problem)
    return PinocchioFree(pm, oracle, q0, v0)


def _integrate(free: _Free, scheme: str, prepared: PinocchioFree, problem: FreeProblem, rung: Rung):
    """March ``rung.counts`` steps of ``rung.timestep`` s between the compared outputs.

    Returns
    -------
    rows : list of (t, q, v, a, force (0,))
        At the outputs reached.
    failure : str
    energy : list of float
        Energy at the outputs reached, J.
    """
    dt = rung.timestep
    half, sixth = dt / 2, dt / 6
    n = prepared.q0.size
    q, v = prepared.q0.copy(), prepared.v0.copy()
    state = np.concatenate((q, v))  # RK4's (q, v)
    rows, energy = [], []

    def record(t):
        rows.append((t, q.copy(), v.copy(), free.acceleration(q, v, t), np.zeros(0)))
        energy.append(free.energy(q, v))

    record(0.0)
    step = 0
    for count in rung.counts:
        for _ in range(count):
            now = step * dt
            if scheme == "rk4":  # on (q, v) as one array: each operation that of q and of v
                k1 = free.derivative(state, now)
                k2 = free.derivative(state + half * k1, now + half)
                k3 = free.derivative(state + half * k2, now + half)
                k4 = free.derivative(state + dt * k3, now + dt)
                state = state + sixth * (k1 + 2 * k2 + 2 * k3 + k4)
                finite = np.isfinite(state).all()
            else:  # semi-implicit Euler: velocity first, then position with the new velocity
                v = v + dt * free.acceleration(q, v, now)
                q = q + dt * v
                finite = np.isfinite(q).all() and np.isfinite(v).all()
            step += 1
            if not finite:
                return rows, f"went non-finite at t = {step * dt:.6g} s", energy
        t = step * dt
        if scheme == "rk4":
            q, v = state[:n].copy(), state[n:].copy()
        record(t)
        failure = problem.came_apart(t, float(np.max(np.abs(prepared.oracle.loop_residual(q)), initial=0.0)))
        if failure:
            return rows, failure, energy
    return rows, "", energy


def run_free_once(prepared: PinocchioFree, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`)."""
    setting: Setting = rung.series.options
    scheme, mu = setting.scheme, setting.mu
    dt = rung.timestep
    mech = problem.kinematics.mechanism
    gains = setting.gains(dt)
    free = _Free(prepared.pm, mu, gains, problem.start[0])
    rows, failure, energy = _integrate(free, scheme, prepared, problem, rung)
    columns = {
        "proximal_mu": mu,
        "baumgarte_kp": gains[0] if gains else 0.0,
        "baumgarte_kd": gains[1] if gains else 0.0,
        "evaluations": free.evaluations,
        "proximal_iterations_max": free.proximal_iterations,
    }
    settings = {
        "setting": rung.series.setting,
        "series": rung.series.key,
        "integrator": scheme,
        "timestep": dt,
        "proximal_mu": mu,
        "proximal_accuracy": PROXIMAL_ACCURACY,
        "baumgarte_kp": columns["baumgarte_kp"],
        "baumgarte_kd": columns["baumgarte_kd"],
        "gravity": [float(g) for g in prepared.pm.model.gravity.linear],
    }
    notes = (
        f"Pinocchio constraintDynamics (loop closures CONTACT_3D/6D, proximal mu {mu:g}), free motion "
        f"(tau = 0: no driver), {rung.series.setting} at dt = {dt:.4g} s, from the reference's initial state."
        + (f" Baumgarte Kp = {gains[0]:.4g} 1/s^2, Kd = {gains[1]:.4g} 1/s." if gains else "")
    )
    out = run_trajectory(prepared.pm, prepared.oracle, rows, MODE, settings, notes)
    start = problem.start[0]
    for i, body in enumerate(mech.moving_bodies):  # continuous, and the reference's at t = 0
        angle = np.unwrap(np.asarray(out.bodies[body.name]["angle"], dtype=float))
        out.bodies[body.name]["angle"] = angle + 2.0 * math.pi * round((start[3 * i + 2] - angle[0]) / (2.0 * math.pi))
    if conservative(mech):  # E less the constant loads' potential
        out.diagnostics["energy"] = np.array(energy)
    return Run(out, failure, columns=columns)
