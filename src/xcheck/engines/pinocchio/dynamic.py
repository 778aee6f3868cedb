"""Constrained dynamics of a mechanism in Pinocchio, its inputs driven by a
computed torque, integrated with RK4 and with semi-implicit Euler.

How the inputs are driven
-------------------------
At every evaluation of the dynamics the input joints get the generalised force
that makes ``constraintDynamics`` return the input acceleration

    u = c''(t) + kd (c'(t) - S v) + kp (c(t) - S q),

the motion law's acceleration plus a PD correction on the tracking error
(S: the rows of the input joints, signed). ``constraintDynamics`` is affine
in the torque, so k + 1 calls give the affine map and one more call at the
torque found gives the accelerations used (and recorded). The PD natural
frequency is ``TRACKING_CYCLES`` cycles per simulation window, critically
damped. Nothing overwrites q or v: the engine integrates its own equations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from xcheck.ladder import DrivenProblem, Run, Rung, Series

from .model import PinocchioMechanism, build_model, joint_coordinates, tree_spec
from .oracle import Oracle, run_trajectory

__all__ = ["Setting", "INTEGRATORS", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]

MODE = "pinocchio-dynamic"
#: PD tracking of the inputs: natural frequency in cycles per window.
TRACKING_CYCLES = 10.0
#: Baumgarte gains Kp = (BAUMGARTE / dt)^2, Kd = 2 BAUMGARTE / dt: a critically
#: damped loop error with a time constant of 1 / BAUMGARTE steps. Measured on
#: fourbar, slider-crank and inverted: 0.05 to 0.7 run, the error falling as the
#: gain grows (fourbar, 800 steps: 1.1e-4 m at 0.05, 1.5e-5 m at 0.7); 1.0
#: makes semi-implicit Euler diverge. 0.5 keeps a margin below that.
BAUMGARTE = 0.5
#: Proximal settings of constraintDynamics: a planar loop's z row is zero, so
#: the Delassus matrix is singular and needs mu > 0. Measured: 3 to 5 proximal
#: iterations (summary column proximal_iterations_max) give J a + drift ~1e-16.
PROXIMAL_MU = 1e-8
PROXIMAL_ACCURACY = 1e-14
PROXIMAL_MAX_ITER = 50


@dataclass(frozen=True)
class Setting:
    """How a run integrates ``constraintDynamics``: ``scheme`` ("rk4" or "euler",
    semi-implicit), with Baumgarte correction (gains Kp = (baumgarte / dt)^2,
    Kd = 2 baumgarte / dt) or without (``baumgarte`` None), at proximal ``mu``."""

    scheme: str
    baumgarte: float | None = None
    mu: float = PROXIMAL_MU

    def gains(self, dt: float) -> tuple[float, float] | None:
        """Baumgarte's (Kp 1/s^2, Kd 1/s) at the step ``dt`` (s), or None without correction."""
        return None if self.baumgarte is None else ((self.baumgarte / dt) ** 2, 2.0 * self.baumgarte / dt)


#: integrator name -> its setting (the driven ladder's series)
INTEGRATORS = {
    "rk4": Setting("rk4"),
    "semi-implicit-euler": Setting("euler"),
    "semi-implicit-euler-baumgarte": Setting("euler", BAUMGARTE),
}


def tracking_gains(window: float) -> tuple[float, float]:
    """(kp 1/s^2, kd 1/s) of the inputs' PD correction for a window of ``window`` s."""
    omega = 2.0 * math.pi * TRACKING_CYCLES / window
    return omega * omega, 2.0 * omega


class _Driven:
    """The dynamics q'' = f(t, q, v) of one mechanism with its inputs driven."""

    def __init__(self, pm: PinocchioMechanism, laws, window: float, baumgarte: tuple[float, float] | None, mu: float):
        self.pm, self.model, self.laws = pm, pm.model, laws
        self.data = pm.model.createData()
        self.cms = [pin.RigidConstraintModel(cm) for cm in pm.constraints]  # copies: gains are per run
        if baumgarte is not None:
            for cm in self.cms:
                cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(*baumgarte))
        self.cds = [cm.createData() for cm in self.cms]
        pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
        self.settings = pin.ProximalSettings(PROXIMAL_ACCURACY, mu, PROXIMAL_MAX_ITER)
        self.selector = pm.input_selector()
        self.kp, self.kd = tracking_gains(window)
        self.evaluations = 0
        self.proximal_iterations = 0

    def law(self, t: float):
        """(c, c', c'') of the inputs at time t, each (k,)."""
        values = [law.at_time(t) for law in self.laws]
        return tuple(np.array([float(v[i]) for v in values]) for i in range(3))

    def _forward(self, q, v, tau):
        a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.cms, self.cds, self.settings)
        self.proximal_iterations = max(self.proximal_iterations, self.settings.iter)
        return a

    def acceleration(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q'' (nv,), input force (k,)) at time t and state (q, v)."""
        self.evaluations += 1
        c, cd, cdd = self.law(t)
        s = self.selector
        wanted = cdd + self.kd * (cd - s @ v) + self.kp * (c - s @ q)
        free = self._forward(q, v, np.zeros(self.model.nv))
        gain = np.column_stack([self._forward(q, v, row) - free for row in s])  # (nv, k)
        try:
            force = np.linalg.solve(s @ gain, wanted - s @ free)
        except np.linalg.LinAlgError as err:
            raise ValueError(
                f"at t = {t:.6g} s the driven joints' accelerations do not respond to their torques "
                "(Pinocchio's constraint dynamics gives an exactly singular response there)"
            ) from err
        return self._forward(q, v, s.T @ force).copy(), force


def _integrate(
    driven: _Driven, scheme: str, q0, v0, duration: float, steps: int, every: int, came_apart, oracle: Oracle
):
    """March ``steps`` steps over ``duration``; record every ``every`` steps
    (``came_apart(t, gap)``: "" or why the run stops where its loops open by ``gap`` m).

    Returns
    -------
    rows : list of (t, q (nq,), v (nv,), a (nv,), force (k,))
    failure : str or None
        Why the run stopped early (state not finite, loops opened), if it did.
    """
    dt = duration / steps
    q, v = q0.copy(), v0.copy()
    rows = []

    def record(i):
        t = i * dt
        a, force = driven.acceleration(t, q, v)
        rows.append((t, q.copy(), v.copy(), a, force))

    record(0)
    for i in range(steps):
        t = i * dt
        if scheme == "rk4":
            k1v, _ = driven.acceleration(t, q, v)
            k1q = v
            k2v, _ = driven.acceleration(t + dt / 2, q + dt / 2 * k1q, v + dt / 2 * k1v)
            k2q = v + dt / 2 * k1v
            k3v, _ = driven.acceleration(t + dt / 2, q + dt / 2 * k2q, v + dt / 2 * k2v)
            k3q = v + dt / 2 * k2v
            k4v, _ = driven.acceleration(t + dt, q + dt * k3q, v + dt * k3v)
            k4q = v + dt * k3v
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        else:  # semi-implicit (symplectic) Euler: velocity first, then position with the new velocity
            a, _ = driven.acceleration(t, q, v)
            v = v + dt * a
            q = q + dt * v
        if (i + 1) % every == 0:
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
                return rows, f"went non-finite at t = {(i + 1) * dt:.6g} s"
            record(i + 1)
            failure = came_apart((i + 1) * dt, float(np.max(np.abs(oracle.loop_residual(q)), initial=0.0)))
            if failure:
                return rows, failure
    return rows, ""


@dataclass
class PinocchioDriven:
    """What every driven run shares: the model, its oracle, the start (q0, v0) and
    the bodies with default mass properties."""

    pm: PinocchioMechanism
    oracle: Oracle
    q0: np.ndarray
    v0: np.ndarray
    defaults: list[str]


#: the ladder's series (keys of :data:`INTEGRATORS`), RK4 compared
SERIES = ("rk4", "semi-implicit-euler", "semi-implicit-euler-baumgarte")
#: the coarsest run's steps over the window, and the runs (doubling the steps)
STEPS, RUNGS = 200, 3


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """The ladder: RK4 (compared), semi-implicit Euler without and with Baumgarte
    correction, each at 200, 400 and 800 steps over the window."""
    timestep = problem.window.duration / STEPS
    return tuple(Series(name, name, INTEGRATORS[name], timestep=timestep, rungs=RUNGS) for name in SERIES)


def prepare_dynamic(problem: DrivenProblem) -> PinocchioDriven:
    """The model and the native state at t = 0 in it.

    Raises
    ------
    ValueError
        If the native configuration at t = 0 does not close Pinocchio's loops.
    """
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    pm = build_model(tree_spec(mech))
    oracle = Oracle(pm)
    inputs, rates, _ = problem.window.inputs(kinematics, np.zeros(1))
    q0, _, _, converged = oracle.project(joint_coordinates(pm, problem.start.q[0]), inputs[0], kinematics.system.size)
    if not converged:
        raise ValueError("the native configuration at t = 0 does not close Pinocchio's loops")
    return PinocchioDriven(pm, oracle, q0, oracle.rates(q0, rates[0]), [b.name for b in pm.spec.bodies if b.default])


def run_dynamic_once(prepared: PinocchioDriven, problem: DrivenProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`)."""
    pm, oracle, defaults = prepared.pm, prepared.oracle, prepared.defaults
    window = problem.window
    integrator = rung.series.setting
    setting: Setting = rung.series.options
    scheme = setting.scheme
    if scheme not in ("rk4", "euler"):
        raise ValueError(f"expected the scheme rk4 or euler, found {scheme!r}")
    laws = [d.law for d in pm.mechanism.drivers]
    per = rung.counts[0]
    steps = per * problem.samples
    dt = rung.timestep
    gains = setting.gains(dt)
    driven = _Driven(pm, laws, window.duration, gains, setting.mu)
    rows, failure = _integrate(
        driven, scheme, prepared.q0, prepared.v0, window.duration, steps, per, problem.came_apart, oracle
    )
    rows = rows[1:]  # t = 0 is not compared
    columns = {"evaluations": driven.evaluations, "proximal_iterations_max": driven.proximal_iterations}
    if not rows:
        return Run(None, failure, columns=columns)
    kp, kd = tracking_gains(window.duration)
    settings = {
        "integrator": integrator,
        "series": integrator,
        "dt": dt,
        "timestep": dt,
        "steps": steps,
        "duration": window.duration,
        "window": window.reason,
        "baumgarte_kp": gains[0] if gains else 0.0,
        "baumgarte_kd": gains[1] if gains else 0.0,
        "proximal_mu": setting.mu,
        "proximal_accuracy": PROXIMAL_ACCURACY,
        "tracking_kp": kp,
        "tracking_kd": kd,
        "gravity": [float(g) for g in pm.model.gravity.linear],
        "default_mass_properties": defaults,
    }
    notes = (
        f"Pinocchio constraintDynamics (CONTACT_3D loop closures, proximal mu {setting.mu:g}), "
        f"{integrator} at dt = {dt:.4g} s over {window.duration:.6g} s ({window.reason}). "
        "Inputs driven by a computed torque on the input joints: the torque that makes the input "
        "acceleration the motion law's plus a critically damped PD correction "
        f"(kp = {kp:.4g} 1/s^2, kd = {kd:.4g} 1/s) on the tracking error. Accelerations are "
        "constraintDynamics' own at each recorded state."
        + (f" Baumgarte correction Kp = {gains[0]:.4g} 1/s^2, Kd = {gains[1]:.4g} 1/s." if gains else "")
        + (
            f" Loops with no undriven revolute are closed through carriers "
            f"({', '.join(c.name for c in pm.spec.carriers)}: a prismatic joint along the cut joint's line, "
            "CONTACT_3D to a pin, CONTACT_6D to a block) whose mass is taken from the bodies they are held "
            "to, so the mass distribution is the model's."
            if pm.spec.carriers
            else ""
        )
        + (
            f" Default mass properties (none in the model) for {', '.join(defaults)}: 1 kg at the "
            "centroid of the body's points, a slender bar's inertia."
            if defaults
            else ""
        )
    )
    return Run(run_trajectory(pm, oracle, rows, MODE, settings, notes), failure, columns=columns)
