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
import time

import numpy as np
import pandas as pd
import pinocchio as pin

from xcheck.engines._driven import refined_steps
from xcheck.errors import NotApplicable
from xcheck.kinematics import Kinematics
from xcheck.ladder import convergence_study, observed_order
from xcheck.motion import simulation_window
from xcheck.results import ModeResult, differences

from .model import PinocchioMechanism, build_model, joint_coordinates, tree_spec
from .oracle import Oracle, one_line, run_trajectory

__all__ = ["run_dynamic", "INTEGRATORS"]

MODE = "pinocchio-dynamic"
#: integrator name -> (scheme, Baumgarte correction on?)
INTEGRATORS = {
    "rk4": ("rk4", False),
    "semi-implicit-euler": ("euler", False),
    "semi-implicit-euler-baumgarte": ("euler", True),
}
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
#: A trajectory whose loops open wider than this fraction of the mechanism's
#: size, or whose state is not finite, is stopped and reported as failed.
LOOP_OPENING_LIMIT = 0.1
#: Errors at or below this times the size are round-off: no order is reported.
ROUND_OFF = 1e-13


def tracking_gains(window: float) -> tuple[float, float]:
    """(kp 1/s^2, kd 1/s) of the inputs' PD correction for a window of ``window`` s."""
    omega = 2.0 * math.pi * TRACKING_CYCLES / window
    return omega * omega, 2.0 * omega


class _Driven:
    """The dynamics q'' = f(t, q, v) of one mechanism with its inputs driven."""

    def __init__(self, pm: PinocchioMechanism, laws, window: float, baumgarte: tuple[float, float] | None):
        self.pm, self.model, self.laws = pm, pm.model, laws
        self.data = pm.model.createData()
        self.cms = [pin.RigidConstraintModel(cm) for cm in pm.constraints]  # copies: gains are per run
        if baumgarte is not None:
            for cm in self.cms:
                cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(*baumgarte))
        self.cds = [cm.createData() for cm in self.cms]
        pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
        self.settings = pin.ProximalSettings(PROXIMAL_ACCURACY, PROXIMAL_MU, PROXIMAL_MAX_ITER)
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
    driven: _Driven, scheme: str, q0, v0, duration: float, steps: int, every: int, size: float, oracle: Oracle
):
    """March ``steps`` steps over ``duration``; record every ``every`` steps.

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
                return rows, f"diverged at t = {(i + 1) * dt:.4g} s (state not finite)"
            opening = float(np.max(np.abs(oracle.loop_residual(q)), initial=0.0))
            if opening > LOOP_OPENING_LIMIT * size:
                return rows, (
                    f"failed at t = {(i + 1) * dt:.4g} s: the loops opened by {opening:.3g} m, "
                    f"more than {LOOP_OPENING_LIMIT:.0%} of the size"
                )
            record(i + 1)
    return rows, None


def _worst(table: pd.DataFrame, quantities, column: str) -> float:
    """Largest ``column`` of a differences table over the given quantities."""
    return float(table[table.quantity.isin(list(quantities))][column].max())


def _order(errors: list[float], dts: list[float], floor: float) -> list[float]:
    """:func:`~xcheck.results.observed_order` of each run against the one before,
    NaN for the first run and where either error is not above ``floor`` (round-off)."""
    return [math.nan] + [
        observed_order(errors[i - 1], errors[i], dts[i - 1], dts[i], floor) for i in range(1, len(errors))
    ]


def _run(kinematics, pm, oracle, integrator, steps, samples, window, q0, v0, baumgarte, branch, defaults):
    """One simulation: (summary row, Trajectory or None if it failed)."""
    scheme, corrected = INTEGRATORS[integrator]
    laws = [d.law for d in pm.mechanism.drivers]
    size = kinematics.system.size
    dt = window.duration / steps
    gains = ((baumgarte / dt) ** 2, 2.0 * baumgarte / dt) if corrected else None
    start = time.perf_counter()
    driven = None
    try:
        driven = _Driven(pm, laws, window.duration, gains)
        rows, failure = _integrate(driven, scheme, q0, v0, window.duration, steps, steps // (samples - 1), size, oracle)
    except Exception as error:  # noqa: BLE001 - one run failing leaves the others
        rows, failure = [], one_line(error)
    run = {
        "integrator": integrator,
        "dt": dt,
        "steps": steps,
        "status": failure or "ok",
        "seconds": time.perf_counter() - start,
    }
    if failure is not None:
        return run, None
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
        "proximal_mu": PROXIMAL_MU,
        "proximal_accuracy": PROXIMAL_ACCURACY,
        "tracking_kp": kp,
        "tracking_kd": kd,
        "gravity": [float(g) for g in pm.model.gravity.linear],
        "default_mass_properties": defaults,
    }
    notes = (
        f"Pinocchio constraintDynamics (CONTACT_3D loop closures, proximal mu {PROXIMAL_MU:g}), "
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
    trajectory = run_trajectory(pm, oracle, rows, MODE, settings, notes)
    assert trajectory.times is not None and driven is not None  # a run that did not fail
    table = differences(kinematics, trajectory, branch)
    law_inputs = np.array([[float(law.at_time(t)[0]) for law in laws] for t in trajectory.times])
    run.update(
        {
            "position_error_m": _worst(table, ["position"], "max_abs"),
            "angle_error_rad": _worst(table, ["angle"], "max_abs"),
            "velocity_rel": _worst(table, ["velocity", "omega"], "max_rel"),
            "acceleration_rel": _worst(table, ["acceleration", "alpha"], "max_rel"),
            "constraint_violation_m": float(np.max(trajectory.diagnostics["constraint_violation"])),
            "input_error": float(np.max(np.abs(trajectory.inputs - law_inputs))),
            "evaluations": driven.evaluations,
            "proximal_iterations_max": driven.proximal_iterations,
        }
    )
    return run, trajectory


def run_dynamic(
    kinematics: Kinematics,
    steps=(200, 400, 800),
    samples: int = 51,
    branch: str | None = None,
    integrators=tuple(INTEGRATORS),
    baumgarte: float = BAUMGARTE,
    refine: int = 0,
) -> ModeResult:
    """Simulate the mechanism with its inputs driven over the simulation window.

    Parameters
    ----------
    kinematics : Kinematics
    steps : sequence of int
        Time steps per window (dt = window / steps); each a multiple of
        ``samples - 1``.
    samples : int
        Recorded states per run, evenly spaced in time.
    branch : str, optional
    integrators : sequence of str
        Keys of :data:`INTEGRATORS`.
    baumgarte : float
        Baumgarte gains per step (see :data:`BAUMGARTE`).
    refine : int
        k > 0: only RK4 (or the first integrator) at the largest step count
        times 2^k (:meth:`xcheck.engines.Engine.run`).

    Returns
    -------
    ModeResult
        Trajectories: RK4 at the finest step first (the one the comparison
        uses; without RK4, the first integrator at its finest step), then the
        other runs. ``summary``: one row per run with the largest position
        error (m), velocity and acceleration errors (``max_rel`` of
        :func:`~xcheck.results.differences`), loop opening (m), input tracking
        error, observed
        orders and run time. Runs that failed (loops opened wide, state not
        finite) have their reason in ``status`` and no trajectory; the mode
        fails only when the comparison run does.
    """
    mech = kinematics.mechanism
    if refine:
        integrators = ("rk4",) if "rk4" in integrators else tuple(integrators)[:1]
        steps = refined_steps(max(int(n) for n in steps), refine)
    try:
        steps = sorted(int(n) for n in steps)
        if samples < 2 or any(n % (samples - 1) for n in steps):
            raise ValueError(f"expected step counts that are multiples of samples - 1 = {samples - 1}, found {steps}")
        unknown = [name for name in integrators if name not in INTEGRATORS]
        if unknown:
            raise ValueError(f"expected integrators among {', '.join(INTEGRATORS)}, found {unknown[0]!r}")
        window = simulation_window(kinematics, branch)
        pm = build_model(tree_spec(mech))
        oracle = Oracle(pm)
        size = kinematics.system.size
        c0 = np.array([[float(d.law.at_time(0.0)[i]) for d in mech.drivers] for i in range(2)])
        native = kinematics.solve(c0[0][None], c0[1][None], branch=branch)
        if not native.status[0] <= 1:
            raise ValueError(f"the mechanism does not assemble at the inputs at t = 0 ({c0[0].tolist()})")
        q0, _, _, converged = oracle.project(joint_coordinates(pm, native.q[0]), c0[0], size)
        if not converged:
            raise ValueError("the native configuration at t = 0 does not close Pinocchio's loops")
        v0 = oracle.rates(q0, c0[1])
    except NotApplicable:
        raise  # what Pinocchio cannot hold: the mode does not apply
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        return ModeResult(MODE, mech.name, False, one_line(error))

    defaults = [b.name for b in pm.spec.bodies if b.default]
    runs = [
        _run(kinematics, pm, oracle, integrator, n, samples, window, q0, v0, baumgarte, branch, defaults)
        for integrator in integrators
        for n in steps
    ]
    summary = pd.DataFrame([run for run, _ in runs])
    for column, order in (
        ("position_error_m", "order_position"),
        ("constraint_violation_m", "order_drift"),
        ("input_error", "order_input"),
    ):
        if column not in summary:
            summary[column] = math.nan
        summary[order] = math.nan
        for integrator in integrators:
            rows = summary.integrator == integrator
            summary.loc[rows, order] = _order(
                list(summary.loc[rows, column]), list(summary.loc[rows, "dt"]), ROUND_OFF * size
            )
    lead = "rk4" if "rk4" in integrators else integrators[0]
    first = next(i for i, (run, _) in enumerate(runs) if run["integrator"] == lead and run["steps"] == steps[-1])
    ordered = [runs[first]] + [r for i, r in enumerate(runs) if i != first]
    if ordered[0][1] is not None:
        ordered[0][1].settings["role"] = "comparison"
        ordered[0][1].notes += " This run is the one the comparison uses (the most accurate setting)."
    trajectories = [t for _, t in ordered if t is not None]
    comparison, _ = runs[first]
    study = convergence_study(summary.integrator, summary.dt, summary.position_error_m, summary.status)
    if comparison["status"] != "ok" or not trajectories:
        return ModeResult(
            MODE,
            mech.name,
            False,
            f"{comparison['integrator']} at {comparison['steps']} steps: {comparison['status']}",
            trajectories,
            summary,
            study,
        )
    return ModeResult(MODE, mech.name, True, "", trajectories, summary, study)
