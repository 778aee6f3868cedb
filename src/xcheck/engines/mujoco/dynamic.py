"""MuJoCo simulating a mechanism: settings, the driven run, and what is sampled.

The input joints are driven by the file's servos (a position and a velocity
actuator per driver) whose controls follow the drivers' motion laws; MuJoCo
integrates everything else, loop closures included. Nothing overwrites the
state during a run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from xcheck.model import Mechanism

from .mjcf import MUJOCO_SOLIMP, MUJOCO_SOLREF, MUJOCO_TOLERANCE, Layout

__all__ = ["Setting", "DEFAULT", "TIGHT", "Run", "simulate"]


@dataclass(frozen=True)
class Setting:
    """Solver settings of a run.

    Attributes
    ----------
    name : str
    integrator : str
        MuJoCo integrator name (``"Euler"``, ``"RK4"``, ...).
    stiff : bool
        False: MuJoCo's defaults (solref 0.02 s, solimp 0.9 0.95, solver
        tolerance 1e-8), set explicitly: the written file carries the tight
        ones. True: solref time constant 2 dt (the
        smallest MuJoCo accepts, ``refsafe``; with refsafe disabled, dt and
        dt/2 measured 5 and 70 times worse on the four-bar), damping ratio 1,
        solimp 0.9999 (the largest impedance), and solver tolerance 1e-12.
    """

    name: str
    integrator: str
    stiff: bool

    def apply(self, model: mujoco.MjModel, timestep: float) -> dict:
        """Set the timestep and these settings on ``model``; returns them as a dict."""
        model.opt.timestep = timestep
        model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{self.integrator.upper()}")
        if self.stiff:
            model.eq_solref[:] = (2.0 * timestep, 1.0)
            model.eq_solimp[:] = (0.9999, 0.9999, 0.001, 0.5, 2.0)
            model.opt.tolerance = 1e-12
        else:
            model.eq_solref[:] = MUJOCO_SOLREF
            model.eq_solimp[:] = MUJOCO_SOLIMP
            model.opt.tolerance = MUJOCO_TOLERANCE
        return {
            "setting": self.name,
            "integrator": self.integrator,
            "timestep": timestep,
            "solref": [float(v) for v in model.eq_solref[0]] if model.neq else [],
            "solimp": [float(v) for v in model.eq_solimp[0]] if model.neq else [],
            "solver_tolerance": float(model.opt.tolerance),
        }


#: What a user starts from with no settings of their own: MuJoCo's defaults.
DEFAULT = Setting("default", "Euler", False)
#: Stiff loop closures and a fourth-order integrator.
TIGHT = Setting("tight", "RK4", True)


@dataclass
class Run:
    """Sampled states of one simulation.

    Attributes
    ----------
    times : ndarray, shape (N,)
    qpos, qvel, qacc : ndarray, shape (N, nv)
        ``qacc`` from ``mj_forward`` at each sampled state with that step's
        controls: the acceleration the integrator starts the step from.
    law : ndarray, shape (N, k)
        The drivers' law values at the sample times (what the servos aim at).
    failure : str
        Empty, or why the run stopped: a non-finite state, or a MuJoCo warning
        (an unstable simulation, after which MuJoCo resets the state).
    settings : dict
    steps : int
    columns : dict
        Further columns of the run's summary row (e.g. MJX's compile and run CPU
        seconds); none for MuJoCo's.
    """

    times: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc: np.ndarray
    law: np.ndarray
    failure: str = ""
    settings: dict = field(default_factory=dict)
    steps: int = 0
    columns: dict = field(default_factory=dict)


def simulate(
    model: mujoco.MjModel,
    mechanism: Mechanism,
    layout: Layout,
    setting: Setting,
    timestep: float,
    per: int,
    samples: int,
    qpos0: np.ndarray,
    qvel0: np.ndarray,
) -> Run:
    """Integrate from (qpos0, qvel0) at t = 0 for ``samples`` x ``per`` steps of
    ``timestep`` s, sampling the state every ``per`` steps (not at t = 0).

    Each step, the controls are the drivers' law values and rates at the
    step's start time (zero-order hold): position servo ctrl = q(t), velocity
    servo ctrl = qd(t). With RK4 the held controls make the servo lag by about
    rate x dt / 2; the comparison is made at the inputs as realised, so the lag
    shows only in the tracking error.
    """
    settings = setting.apply(model, timestep)
    data = mujoco.MjData(model)
    steps = per * samples
    sample_steps = per * np.arange(1, samples + 1)
    k = len(mechanism.drivers)
    position_ids = [model.actuator(f"{d.name}.position").id for d in mechanism.drivers]
    velocity_ids = [model.actuator(f"{d.name}.velocity").id for d in mechanism.drivers]
    step_times = np.arange(steps + 1) * timestep
    laws = [d.law.at_time(step_times) for d in mechanism.drivers]
    ctrl = np.zeros((steps + 1, model.nu))
    for j in range(k):
        ctrl[:, position_ids[j]] = laws[j][0]
        ctrl[:, velocity_ids[j]] = laws[j][1]

    data.qpos[:], data.qvel[:] = qpos0, qvel0
    qpos, qvel, qacc = (np.full((samples, model.nv), np.nan) for _ in range(3))
    failure, s = "", 0
    warnings: list[str] = []
    previous = mujoco.get_mju_user_warning()
    # MuJoCo's warnings (an unstable simulation) become the run's failure, not a MUJOCO_LOG.TXT
    mujoco.set_mju_user_warning(warnings.append)
    try:
        for step in range(steps + 1):
            data.ctrl[:] = ctrl[step]
            if s < samples and step == sample_steps[s]:
                mujoco.mj_forward(model, data)
                qpos[s], qvel[s], qacc[s] = data.qpos, data.qvel, data.qacc
                if not (np.all(np.isfinite(qpos[s])) and np.all(np.isfinite(qvel[s]))):
                    failure = f"went non-finite at t = {step_times[step]:.6g} s"
                    break
                s += 1
                if step == steps:
                    break
            mujoco.mj_step(model, data)
            if warnings:
                failure = f"diverged at t = {step_times[step]:.6g} s: {warnings[0].strip()}"
                break
    finally:
        mujoco.set_mju_user_warning(previous)
    law = np.stack([law[0][sample_steps] for law in laws], axis=1)
    return Run(step_times[sample_steps][:s], qpos[:s], qvel[:s], qacc[:s], law[:s], failure, settings, steps)
