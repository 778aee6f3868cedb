"""MJX in driven dynamics (mode ``mjx-dynamic``): the MuJoCo
engine's MJCF file with its position and velocity servos, stepped on MJX's JAX
back end in float64 by MuJoCo's own driven run
(:func:`xcheck.engines.mujoco.modes.run_dynamic_once`) with :class:`Simulator` in
place of MuJoCo's C loop, and compared with MuJoCo (C) at the same settings.

One setting: MuJoCo's tight one (:data:`xcheck.engines.mujoco.dynamic.TIGHT`:
RK4, stiff loops, solref 2 dt, solimp 0.9999, tolerance 1e-12) with the Newton
solver, over its step ladder; MuJoCo's default setting is not run (it is
MuJoCo's own, Euler: a second compilation). The rollout (:func:`rollout`) is
one ``jax.jit`` compilation per mechanism: the time step, solref, solimp and
tolerance are data, and so are the controls (the drivers' laws at each step's
start, zero-order hold, as MuJoCo's C loop feeds them), indexed per step from
an array padded to the ladder's longest run; a ``jax.lax.scan`` over the
samples runs each sample's steps in a ``jax.lax.fori_loop`` whose bounds are
data. Each step is :func:`xcheck.engines.mjx._rk4.step`: MJX's RK4 with one
forward pass in the graph instead of five (``mjx.step``'s four and one for
sampling ``qacc``; tracing and
compilation 16 to 20 CPU s per mechanism instead of 36 to 47, runs 2.4 times
faster). Accelerations are MJX's own ``qacc`` (the first stage's forward pass
at each sampled state with that step's controls), as MuJoCo's driven mode
samples its own.
(MuJoCo's (C) ``qacc`` at MJX's states would count the loops' J-dot qd twice:
MJX's constraint lacks the term and its stabilisation holds the loops open by
what makes up for it, so C's stabilisation adds it again; measured on the
four-bar at 1 and 0.5 ms: 0.087 and 0.20 relative acceleration error.)

Measured: see :data:`xcheck.engines.mjx.MJX`'s notes and the mode's tolerance.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import mujoco
import numpy as np

from xcheck.engines.mujoco import modes as mujoco_modes
from xcheck.engines.mujoco.dynamic import Run, Setting, simulate
from xcheck.engines.mujoco.mjcf import Layout
from xcheck.errors import NotApplicable
from xcheck.ladder import DrivenProblem, Rung, Series
from xcheck.ladder import Run as LadderRun
from xcheck.model import Mechanism
from xcheck.results import differences

from . import _rk4
from .free import MAX_VALUE, _difference, load_mjx, mjx_model

__all__ = ["DYNAMIC_MODE", "SOLVER", "Simulator", "rollout", "dynamic_series", "prepare_dynamic", "run_dynamic_once"]

DYNAMIC_MODE = "mjx-dynamic"
#: MJX's solver (MuJoCo's default; MJX has Newton and CG, not PGS).
SOLVER = "Newton"


def rollout(m, parameters: dict, qpos0, qvel0, ctrl, bounds):
    """MJX's driven motion from (qpos0, qvel0) at t = 0: the states at the sample steps,
    stepped by :func:`xcheck.engines.mjx._rk4.step` (MJX's RK4 with one forward
    pass in the graph).

    Parameters
    ----------
    m : mjx.Model
    parameters : dict of arrays
        ``timestep`` (s), ``tolerance``, ``solref`` (2,), ``solimp`` (5,)
        (every equality alike): data, not constants of the compilation.
    qpos0, qvel0 : array, shape (nq,), (nv,)
    ctrl : array, shape (L, nu)
        The controls of step k (0-based) in row k (zero-order hold); rows past
        the run's last step are padding, never read.
    bounds : int array, shape (S,)
        The step index of each sample, ascending, ``bounds[0] == 0``; a repeated
        index is a sample of no further step.

    Returns
    -------
    qpos, qvel, qacc : arrays, shape (S, nq), (S, nv), (S, nv)
        The states at ``bounds`` (rad or m, per s, per s^2); ``qacc`` from
        the forward pass at the state with that step's controls, including
        MJX's constraint stabilisation, as MuJoCo's driven mode samples its own.
    """
    jax, jnp, mjx = load_mjx()
    m = m.replace(
        opt=m.opt.replace(timestep=parameters["timestep"], tolerance=parameters["tolerance"]),
        eq_solref=jnp.broadcast_to(parameters["solref"], m.eq_solref.shape),
        eq_solimp=jnp.broadcast_to(parameters["solimp"], m.eq_solimp.shape),
    )
    d = mjx.make_data(m).replace(qpos=qpos0, qvel=qvel0, ctrl=ctrl[0])
    types = jax.eval_shape(lambda d: _rk4.step(m, d)[0], d)  # the step's own dtypes (see free.rollout)
    d = jax.tree_util.tree_map(lambda x, t: x.astype(t.dtype), d, types)

    def sample(d, interval):
        start, end = interval[0], interval[1]

        def one_step(k, carry):
            d, qacc = carry
            after, first = _rk4.step(m, d.replace(ctrl=ctrl[k]))
            kept = jax.tree_util.tree_map(lambda new, old: jnp.where(k < end, new, old), after, d)
            return kept, jnp.where(k == start, first, qacc)

        # a sample of no further step (the last) takes one step for its qacc, and keeps its state
        after, qacc = jax.lax.fori_loop(start, jnp.maximum(end, start + 1), one_step, (d, jnp.zeros_like(d.qacc)))
        return after, (d.qpos, d.qvel, qacc)

    intervals = jnp.stack([bounds, jnp.concatenate([bounds[1:], bounds[-1:]])], axis=1)
    _, states = jax.lax.scan(sample, d, intervals)
    return states


class Simulator:
    """MJX in place of :func:`xcheck.engines.mujoco.dynamic.simulate` (same call, same
    :class:`~xcheck.engines.mujoco.dynamic.Run`), compiling :func:`rollout` once for
    the runs of a ladder (and once more for a refinement's longer run).

    Parameters
    ----------
    steps : int
        The ladder's longest run, steps: the controls are padded to it, so every
        run of the ladder has the same shapes.

    Attributes
    ----------
    compile_seconds : float
        CPU s of the last compilation (NaN before the first run).
    """

    def __init__(self, steps: int) -> None:
        self.steps = steps
        self.compile_seconds = math.nan
        #: the compiled rollouts by the controls' length
        self._compiled: dict[int, tuple[Any, Any]] = {}

    def __call__(
        self,
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
        """One run, as :func:`xcheck.engines.mujoco.dynamic.simulate`; ``Run.columns``:
        compile_seconds (shared by the ladder), cpu_seconds (the run alone) and
        cpu_per_simulated_second. A non-finite state, or one beyond 1e10, is a
        failure (MJX does not warn as MuJoCo's C library does).

        Raises
        ------
        NotApplicable
            What of the file or the setting MJX does not implement
            (``mjx.put_model``'s NotImplementedError), or a joint that
            :func:`xcheck.engines.mjx._rk4.step` does not integrate.
        """
        jax, _, _ = load_mjx()
        settings = setting.apply(model, timestep)
        settings["solver"] = SOLVER
        steps = per * samples
        length = max(self.steps, steps) + 1  # the controls padded: one compilation serves a ladder's runs
        bounds = (per * np.arange(samples + 1)).astype(np.int64)
        step_times = np.arange(steps + 1) * timestep
        laws = [d.law.at_time(step_times) for d in mechanism.drivers]
        ctrl = np.zeros((length, model.nu))
        for driver, law in zip(mechanism.drivers, laws):
            ctrl[: steps + 1, model.actuator(f"{driver.name}.position").id] = law[0]
            ctrl[: steps + 1, model.actuator(f"{driver.name}.velocity").id] = law[1]
        parameters = {
            "timestep": np.float64(timestep),
            "tolerance": np.float64(model.opt.tolerance),
            "solref": np.asarray(model.eq_solref[0] if model.neq else [0.02, 1.0], dtype=float),
            "solimp": np.asarray(model.eq_solimp[0] if model.neq else [0.9, 0.95, 0.001, 0.5, 2.0], dtype=float),
        }
        arguments = (parameters, np.asarray(qpos0, float), np.asarray(qvel0, float), ctrl, bounds)
        if length not in self._compiled:
            if not _rk4.applies(model):
                raise NotApplicable(
                    "xcheck steps MJX by RK4 with one forward pass, for hinge and slide joints without "
                    "actuator activations; this model has others"
                )
            try:
                m = mjx_model(model, setting.integrator, SOLVER)
            except NotImplementedError as error:
                raise NotApplicable(f"MJX does not implement {error}") from error
            begin = time.process_time()
            self._compiled[length] = (m, jax.jit(rollout).lower(m, *arguments).compile())
            self.compile_seconds = time.process_time() - begin
        m, compiled = self._compiled[length]
        begin = time.process_time()
        qpos, qvel, qacc = (np.asarray(a)[1:] for a in jax.block_until_ready(compiled(m, *arguments)))
        cpu = time.process_time() - begin
        sample_steps = bounds[1:]  # t = 0 is not compared
        bad = ~(np.all(np.isfinite(qpos), axis=1) & np.all(np.isfinite(qvel), axis=1))
        bad |= np.any(np.abs(qpos) > MAX_VALUE, axis=1) | np.any(np.abs(qvel) > MAX_VALUE, axis=1)
        s = int(np.argmax(bad)) if bad.any() else samples
        failure = f"went non-finite, or beyond 1e10, at t = {step_times[sample_steps[s]]:.6g} s" if bad.any() else ""
        law = np.stack([law[0][sample_steps] for law in laws], axis=1)
        duration = steps * timestep
        columns = {
            "compile_seconds": self.compile_seconds,
            "cpu_seconds": cpu,
            "cpu_per_simulated_second": cpu / max(duration, 1e-300),
        }
        return Run(
            step_times[sample_steps][:s], qpos[:s], qvel[:s], qacc[:s], law[:s], failure, settings, steps, columns
        )


def dynamic_series(problem: DrivenProblem) -> tuple[Series, ...]:
    """MuJoCo's tight series alone (RK4, stiff loops; its default setting is MuJoCo's
    own, Euler: a second compilation), with MJX's solver."""
    return (mujoco_modes.dynamic_series(problem)[0],)


@dataclass
class MjxDriven:
    """What every MJX driven run shares: the MuJoCo engine's prepared model with MJX
    as its simulator, and, where it runs beside it, MuJoCo (C)'s."""

    mjx: mujoco_modes.MujocoDriven
    mujoco: mujoco_modes.MujocoDriven | None


def prepare_dynamic(problem: DrivenProblem, compare: bool = True) -> MjxDriven:
    """The MuJoCo engine's driven model (:func:`xcheck.engines.mujoco.modes.prepare_dynamic`)
    stepped by a :class:`Simulator`; with ``compare``, MuJoCo (C)'s beside it: the
    columns ``mujoco_position_error`` (m), ``mujoco_cpu_per_simulated_second`` (s) and
    ``mujoco_difference`` (m, the largest distance between a named point of the two
    runs at the same sample)."""
    load_mjx()
    longest = max(problem.rung(s, s.rungs - 1).counts[0] * problem.samples for s in dynamic_series(problem))
    mjx = mujoco_modes.prepare_dynamic(problem, simulator=Simulator(longest), mode=DYNAMIC_MODE, title="MJX")
    return MjxDriven(mjx, replace(mjx, simulator=_timed, mode="mujoco-dynamic", title="MuJoCo") if compare else None)


def run_dynamic_once(prepared: MjxDriven, problem: DrivenProblem, rung: Rung) -> LadderRun:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_dynamic_once`): MuJoCo's
    driven run on MJX, and MuJoCo (C)'s at the same rung where it runs beside it."""
    run = mujoco_modes.run_dynamic_once(prepared.mjx, problem, rung)
    run.columns["solver"] = SOLVER
    if prepared.mujoco is None:
        return run
    theirs = mujoco_modes.run_dynamic_once(prepared.mujoco, problem, rung)
    run.columns["mujoco_position_error"] = math.nan
    run.columns["mujoco_cpu_per_simulated_second"] = theirs.columns.get("cpu_per_simulated_second", math.nan)
    run.columns["mujoco_difference"] = math.nan
    if theirs.trajectory is not None and not theirs.failure:
        table = differences(problem.kinematics, theirs.trajectory, problem.branch)
        run.columns["mujoco_position_error"] = mujoco_modes.relative_error(table, "position", absolute=True)
        if run.trajectory is not None and not run.failure:
            run.columns["mujoco_difference"] = _difference(run.trajectory, theirs.trajectory)
    return run


def _timed(model: mujoco.MjModel, *args) -> Run:
    """MuJoCo's (C) :func:`~xcheck.engines.mujoco.dynamic.simulate`, with its CPU s per
    simulated second as the column ``cpu_per_simulated_second``."""
    begin = time.process_time()
    run = simulate(model, *args)
    duration = float(args[3]) * float(args[4]) * float(args[5])  # timestep x per x samples
    run.columns["cpu_per_simulated_second"] = (time.process_time() - begin) / max(duration, 1e-300)
    return run
