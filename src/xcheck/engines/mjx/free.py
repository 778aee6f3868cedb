"""MJX in free motion (mode ``mjx-free``): the MuJoCo engine's free-motion MJCF
(:func:`xcheck.engines.mujoco.free.free_model`: servos off, springs as spatial
tendons) on MJX's JAX back end in float64, compared with the native reference
and with MuJoCo's C implementation at the same settings.

The rollout is one ``jax.jit``-compiled function (:func:`rollout`): a
``jax.lax.scan`` over the compared samples whose body steps ``mjx.step`` a
number of times given as data (``jax.lax.fori_loop``). The time step, the
equality solref and solimp and the solver tolerance are data too, so one
compilation per integrator and solver (static in MJX) serves every step and
softness of the ladder. The ladder is MuJoCo's free mode's (default softness
and stiff loops, :class:`xcheck.engines.mujoco.dynamic.Setting`) with each
integrator MJX has (Euler, implicitfast, RK4; MuJoCo's ``implicit`` is not
implemented in MJX) and each of its solvers (Newton, CG; not PGS).

Batched: ``batched=True`` runs the rows of one integrator and solver (every
softness and step) as one ``jax.vmap`` of the same rollout; the loop over
steps runs as long as the finest step needs, the coarser rows masked. That is
MJX's point on a GPU; on this CPU (2 shared cores) a batch costs more than the
same rows in sequence (measured below), so the default is batched on an
accelerator and sequential on the CPU. No GPU was measured
(benchmarks/bench_mjx.py measures one).

MJX computes no energy (``mjENBL_ENERGY`` is refused) and calls no
passive-force callback, so: constant torques, and constant forces at a body's
centre of mass, are applied through ``xfrc_applied`` (exact); a load with a
time law or a force elsewhere, and a rotational spring, is not applicable.
Energy, loop drift and the sampled accelerations are MuJoCo's (C) at MJX's
sampled states, with the same loads. Compile time is reported apart from run
time (``compile_seconds``, CPU s of the executable a row ran, shared by the
rows of one integrator and solver; ``cpu_seconds`` is the run alone). JAX's own
persistent cache keeps compilations between runs, in ``jax/`` of xcheck's cache
directory unless ``JAX_COMPILATION_CACHE_DIR`` names another (:func:`load_mjx`;
measured: the A01 test of tests/test_engine_mjx.py, 11.3 CPU s, then 6.2 s).

Measured (2026-11-25, 2 shared cores, mujoco 4.0.0, mujoco-mjx 3.17.0, jax 0.10.2 on
the CPU; ``ALL_SETTINGS`` on A02, Newton and CG Euler and Newton
implicitfast and RK4 on A01 and A03, dt = 1, 0.5, 0.25
ms). The pendulum (A01, 10 s): Euler 2.2e-3 .. 5.5e-4 m (order 1.00), RK4 at the
reference's own error (2e-11 m), MuJoCo (C) within 3e-15 m. The double four-bar
(A02, 10 s, ten singular passes): every run stays on the branch; default softness
1.9 m out of phase (loops open by 8e-4 m), no convergence, and 2.0 m from MuJoCo
(C); stiff loops converge at order 0.85 (Euler and implicitfast alike: 2.7e-4,
1.5e-4, 8.2e-5 m) and 0.7 (RK4: 1.8e-4, 1.1e-4, 6.8e-5 m), loops closed to 3e-8 ..
3e-9 m, against MuJoCo (C)'s 1.1e-3, 3.3e-4, 1.4e-4 m (Euler): the two differ by
8.8e-4, 1.8e-4, 5.8e-5 m. Andrews' squeezer (A03, 0.03 s, a constant torque and a
spring tendon): default softness leaves the branch at 10.6 ms (as MuJoCo (C) does);
stiff Euler 3.4e-4, 1.7e-4, 8.5e-5 m at 10, 5, 2.5 us (order 1.0, MuJoCo (C) within
4.8e-7 m), stiff RK4 6.9e-6, 1.9e-6, 4.9e-7 m (order 1.9, loops open by 4.5e-6 ..
2.8e-7 m) where MuJoCo (C)'s RK4 reaches 8.6e-9 .. 4.6e-10 m (loops 4.6e-9 ..
2.9e-10 m). The difference is one term: MuJoCo 4.0's reference acceleration of a
connect row carries -J-dot qd, MJX 3.17's does not (tests/test_engine_mjx.py), so
MJX's stabilisation holds the loops open by about J-dot qd (2 dt)^2, which is large
at the squeezer's 1100 rad/s. CG gives Newton's errors to 3 digits at 1.1 to 2.3
times its CPU. CPU per simulated second at 1 ms (A02): Euler 0.05 s, RK4 0.32 s
(MuJoCo (C): Euler 0.008 to 0.011 s); compilation 14 CPU s (Euler, implicitfast) to
25 CPU s (RK4) per integrator and solver. The batched ladder (A02, stiff and default
Newton Euler, six rows) cost 10.3 CPU s against 8.0 s in sequence; a batch of copies
at one step pays (benchmarks/bench_mjx.py, A02 stiff Newton Euler at 1 ms, wall):
6.2e3 steps/s alone, 3.0e4 for 16, 2.6e4 for 64.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
import time
from dataclasses import dataclass, replace
from functools import partial

import mujoco
import numpy as np
import pandas as pd

from xcheck.engines import NotApplicable
from xcheck.engines.mujoco import dynamic as mujoco_dynamic
from xcheck.engines.mujoco import free as mujoco_free
from xcheck.engines.mujoco.mjcf import joint_coordinates, mass_properties
from xcheck.engines.mujoco.oracle import Oracle
from xcheck.errors import XcheckError
from xcheck.kinematics import Kinematics
from xcheck.model import Mechanism
from xcheck.results import ModeResult, Trajectory, convergence_study
from xcheck.simulation import free_errors, ladder_steps, left_branch
from xcheck.store import cache_dir

__all__ = [
    "FREE_MODE",
    "ALL_SETTINGS",
    "SETTINGS",
    "TIMESTEPS",
    "Setting",
    "load_mjx",
    "mjx_model",
    "rollout",
    "run_free",
]

FREE_MODE = "mjx-free"
#: The ladder's time steps, s (MuJoCo's free mode's).
TIMESTEPS = mujoco_free.TIMESTEPS
#: A state component beyond this (MuJoCo's mjMAXVAL, where C MuJoCo warns) is a blow-up.
MAX_VALUE = 1e10


@dataclass(frozen=True)
class Setting:
    """One series of the ladder.

    Attributes
    ----------
    softness : str
        ``"default"`` (MuJoCo's constraint softness) or ``"stiff"`` (solref 2 dt,
        solimp 0.9999, tolerance 1e-12): :class:`xcheck.engines.mujoco.dynamic.Setting`.
    integrator : str
        ``"Euler"``, ``"implicitfast"`` or ``"RK4"`` (MuJoCo's names).
    solver : str
        ``"Newton"`` or ``"CG"``.
    """

    softness: str
    integrator: str
    solver: str

    @property
    def name(self) -> str:
        """The summary's ``setting``: softness and solver, e.g. ``"stiff Newton"``."""
        return f"{self.softness} {self.solver}"

    def mujoco(self) -> mujoco_dynamic.Setting:
        """The MuJoCo engine's setting of the same softness and integrator."""
        return mujoco_dynamic.Setting(self.name, self.integrator, self.softness == "stiff")


#: Every softness, integrator and solver (six compilations; about 15 min on A02's 10 s on 2 shared cores).
ALL_SETTINGS = tuple(
    Setting(softness, integrator, solver)
    for softness in ("default", "stiff")
    for solver in ("Newton", "CG")
    for integrator in ("Euler", "implicitfast", "RK4")
)
#: The default ladder (two compilations, 20 to 40 CPU s): Newton with Euler and RK4. Measured
#: on A01, A02 and A03 (ALL_SETTINGS on A02): implicitfast gave Euler's errors to 4 digits (no velocity-dependent
#: force but dampers) and CG Newton's to 3 digits at 1.1 to 2.3 times its CPU time.
SETTINGS = tuple(s for s in ALL_SETTINGS if s.solver == "Newton" and s.integrator != "implicitfast")


def load_mjx():
    """``(jax, jax.numpy, mujoco.mjx)`` with float64 on and the persistent
    compilation cache set (:func:`_persistent_cache`), imported quietly.

    ``mujoco.mjx`` tries its Warp back end at import and, without the ``warp``
    package, prints "Failed to import warp: ..." twice to stdout (``print``, not
    a logger); the import runs with stdout redirected to a buffer that is
    dropped. ``jax_enable_x64`` is set before any array is made (JAX's default
    is float32).
    """
    import jax

    jax.config.update("jax_enable_x64", True)
    _persistent_cache(jax)
    with contextlib.redirect_stdout(io.StringIO()):
        from mujoco import mjx
    import jax.numpy as jnp

    return jax, jnp, mjx


#: The largest the persistent compilation cache grows, bytes (JAX evicts the
#: least recently used entries beyond it); an entry is about 1 to 4 MB here.
CACHE_BYTES = 2**30


def _persistent_cache(jax) -> None:
    """Keep JAX's compilations between runs: its persistent cache in ``jax/`` of
    xcheck's cache directory (:func:`xcheck.store.cache_dir`), unless
    ``$JAX_COMPILATION_CACHE_DIR`` already names one or xcheck's cache is off.
    Set before JAX's first compilation, which fixes the cache for the process."""
    if jax.config.jax_compilation_cache_dir:
        return
    directory = cache_dir()
    if directory is None:
        return
    jax.config.update("jax_compilation_cache_dir", str(directory / "jax"))
    jax.config.update("jax_compilation_cache_max_size", CACHE_BYTES)


def mjx_model(model: mujoco.MjModel, integrator: str, solver: str):
    """An ``mjx.Model`` (JAX back end) of a copy of ``model`` with this integrator
    and solver (static in MJX) and the energy flag off (MJX refuses it).

    Raises
    ------
    NotImplementedError
        What MJX refuses (e.g. ``mjINT_IMPLICIT``, ``mjSOL_PGS``).
    """
    _, _, mjx = load_mjx()
    model = copy.deepcopy(model)
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    model.opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{solver.upper()}")
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    return mjx.put_model(model, impl="jax")


def rollout(m, parameters: dict, qpos0, qvel0, xfrc, samples: int):
    """MJX's motion from (qpos0, qvel0): the states after each of ``samples - 1``
    intervals of ``parameters["every"]`` steps.

    Parameters
    ----------
    m : mjx.Model
    parameters : dict of arrays
        ``timestep`` (s), ``tolerance``, ``solref`` (2,), ``solimp`` (5,) (every
        equality alike), ``every`` (int, steps per sample): data, not constants
        of the compilation.
    qpos0, qvel0 : array, shape (nq,), (nv,)
    xfrc : array, shape (nbody, 6)
        Constant applied forces and torques at the bodies' centres of mass (N, N m).
    samples : int
        Static: the scan's length is ``samples - 1``.

    Returns
    -------
    qpos, qvel : arrays, shape (samples - 1, nq), (samples - 1, nv)
    """
    jax, jnp, mjx = load_mjx()
    m = m.replace(
        opt=m.opt.replace(timestep=parameters["timestep"], tolerance=parameters["tolerance"]),
        eq_solref=jnp.broadcast_to(parameters["solref"], m.eq_solref.shape),
        eq_solimp=jnp.broadcast_to(parameters["solimp"], m.eq_solimp.shape),
    )
    d = mjx.make_data(m).replace(qpos=qpos0, qvel=qvel0, xfrc_applied=xfrc)
    # with float64 on, make_data gives int32 tendon wrap indices (ten_wrapadr, ten_wrapnum, wrap_obj)
    # that mjx.step returns as int64, which a loop carry refuses: start from step's own dtypes
    types = jax.eval_shape(partial(mjx.step, m), d)
    d = jax.tree_util.tree_map(lambda x, t: x.astype(t.dtype), d, types)

    def sample(d, _):
        d = jax.lax.fori_loop(0, parameters["every"], lambda _, d: mjx.step(m, d), d)
        return d, (d.qpos, d.qvel)

    _, states = jax.lax.scan(sample, d, None, length=samples - 1)
    return states


def _parameters(model: mujoco.MjModel, setting: Setting, timestep: float, every: int) -> tuple[dict, dict]:
    """(rollout parameters, the settings dict of the row) of one run: MuJoCo's
    :meth:`~xcheck.engines.mujoco.dynamic.Setting.apply` on a copy of ``model``."""
    model = copy.deepcopy(model)
    settings = setting.mujoco().apply(model, timestep)
    settings["solver"] = setting.solver
    solref = model.eq_solref[0] if model.neq else np.array([0.02, 1.0])
    solimp = model.eq_solimp[0] if model.neq else np.array([0.9, 0.95, 0.001, 0.5, 2.0])
    parameters = {
        "timestep": np.float64(timestep),
        "tolerance": np.float64(model.opt.tolerance),
        "solref": np.asarray(solref, dtype=float),
        "solimp": np.asarray(solimp, dtype=float),
        "every": np.int64(every),
    }
    return parameters, settings


def applied_forces(mechanism: Mechanism, model: mujoco.MjModel) -> np.ndarray:
    """The mechanism's loads as MuJoCo's ``xfrc_applied`` (nbody, 6): force and
    torque at each body's centre of mass, global frame (N, N m).

    Raises
    ------
    NotApplicable
        A rotational spring, a load with a time law, or a force off the body's
        centre of mass (their torque turns with the body, which xfrc_applied
        held over a step cannot follow; MuJoCo's free mode applies them in
        ``mjcb_passive``, which MJX does not call).
    """
    if mechanism.rotational_springs:
        names = ", ".join(repr(s.name) for s in mechanism.rotational_springs)
        raise NotApplicable(f"rotational spring {names}: MJX has no passive-force callback to apply it")
    xfrc = np.zeros((model.nbody, 6))
    centres = mass_properties(mechanism)
    for load in mechanism.loads:
        if load.law is not None:
            raise NotApplicable(f"load {load.name!r} has a time law: MJX has no passive-force callback to apply it")
        force = np.asarray(load.force, dtype=float)
        off = float(np.hypot(*(np.asarray(load.point, dtype=float) - centres[load.body].com)))
        if np.any(force != 0.0) and off > 1e-12 * mechanism.size:
            raise NotApplicable(
                f"load {load.name!r}: a force {off:.3g} m off the centre of mass of {load.body!r} "
                "(MJX has no passive-force callback; xfrc_applied acts at the centre of mass)"
            )
        xfrc[model.body(load.body).id] += [force[0], force[1], 0.0, 0.0, 0.0, float(load.torque)]
    return xfrc


def _mujoco_states(model: mujoco.MjModel, settings: Setting, timestep: float, xfrc, qpos, qvel):
    """MuJoCo's (C) qacc (N, nv) and energy (N,) at MJX's states, same settings and loads."""
    model = copy.deepcopy(model)
    settings.mujoco().apply(model, timestep)
    model.opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{settings.solver.upper()}")
    data = mujoco.MjData(model)
    data.xfrc_applied[:] = xfrc
    qacc, energy = np.empty_like(qvel), np.empty(len(qpos))
    for i, (q, v) in enumerate(zip(qpos, qvel)):
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        qacc[i], energy[i] = data.qacc, data.energy[0] + data.energy[1]
    return qacc, energy


def _empty_row(setting: Setting, timestep: float, steps: int) -> dict:
    return {
        "setting": setting.name,
        "integrator": setting.integrator,
        "timestep": timestep,
        "steps": steps,
        "status": "ok",
        "compile_seconds": math.nan,
        "cpu_seconds": math.nan,
        "cpu_per_simulated_second": math.nan,
        "position_error": math.nan,
        "final_error": math.nan,
        "angle_error": math.nan,
        "loop_drift": math.nan,
        "energy_drift": math.nan,
        "mujoco_position_error": math.nan,
        "mujoco_loop_drift": math.nan,
        "mujoco_cpu_per_simulated_second": math.nan,
        "mujoco_difference": math.nan,
    }


@dataclass
class _Run:
    setting: Setting
    timestep: float
    every: int
    parameters: dict
    settings: dict
    row: dict
    qpos: np.ndarray | None = None
    qvel: np.ndarray | None = None


def _execute(runs: list[_Run], m, qpos0, qvel0, xfrc, samples: int, batched: bool) -> float:
    """Compile the rollout once and run ``runs`` (of one integrator and solver),
    sequentially or as one vmap batch; fills their states and CPU times, returns
    the compile CPU time (s)."""
    jax, _, _ = load_mjx()
    stack = {key: np.stack([run.parameters[key] for run in runs]) for key in runs[0].parameters}
    begin = time.process_time()
    if batched:
        function = jax.vmap(partial(rollout, samples=samples), in_axes=(None, 0, None, None, None))
        compiled = jax.jit(function).lower(m, stack, qpos0, qvel0, xfrc).compile()
    else:
        function = partial(rollout, samples=samples)
        compiled = jax.jit(function).lower(m, runs[0].parameters, qpos0, qvel0, xfrc).compile()
    compile_seconds = time.process_time() - begin
    if batched:
        begin = time.process_time()
        qpos, qvel = jax.block_until_ready(compiled(m, stack, qpos0, qvel0, xfrc))
        share = (time.process_time() - begin) / len(runs)  # the batch's CPU time, shared out
        for i, run in enumerate(runs):
            run.qpos, run.qvel = np.asarray(qpos[i]), np.asarray(qvel[i])
            run.row["cpu_seconds"] = share
    else:
        for run in runs:
            begin = time.process_time()
            qpos, qvel = jax.block_until_ready(compiled(m, run.parameters, qpos0, qvel0, xfrc))
            run.row["cpu_seconds"] = time.process_time() - begin
            run.qpos, run.qvel = np.asarray(qpos), np.asarray(qvel)
    return compile_seconds


def _finish(kinematics, model, lay, oracle, reference, run: _Run, index, xfrc, qpos0, qvel0, compare: bool):
    """Judge one run: (summary row, Trajectory or None)."""
    mech = kinematics.mechanism
    row = run.row
    times = reference.motion.times[index]
    assert run.qpos is not None and run.qvel is not None
    qpos = np.concatenate([qpos0[None], run.qpos])
    qvel = np.concatenate([qvel0[None], run.qvel])
    bad = ~(np.all(np.isfinite(qpos), axis=1) & np.all(np.isfinite(qvel), axis=1))
    bad |= np.any(np.abs(qvel) > MAX_VALUE, axis=1) | np.any(np.abs(qpos) > MAX_VALUE, axis=1)
    s = int(np.argmax(bad)) if bad.any() else len(times)
    failure = f"NaN or beyond 1e10 by t = {times[s]:.4g} s" if s < len(times) else ""
    duration = float(times[-1] - times[0])
    row["cpu_per_simulated_second"] = row["cpu_seconds"] / max(duration, 1e-300)
    if compare:
        mj_model = copy.deepcopy(model)
        mj_model.opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{run.setting.solver.upper()}")
        mj_row, mj_trajectory = mujoco_free._run(
            kinematics, mj_model, lay, oracle, reference, run.setting.mujoco(), run.timestep, qpos0, qvel0
        )
        for key in ("position_error", "loop_drift", "cpu_per_simulated_second"):
            row[f"mujoco_{key}"] = mj_row[key]
    if s < 2:
        row["status"] = failure or "no step went through"
        return row, None
    good = slice(0, s)
    qacc, energy = _mujoco_states(model, run.setting, run.timestep, xfrc, qpos[good], qvel[good])
    trajectory = mujoco_free._trajectory(
        kinematics, oracle, reference, run.settings, qpos[good], qvel[good], qacc, times[good]
    )
    trajectory = replace(
        trajectory,
        source=FREE_MODE,
        notes=f"MJX free motion, {trajectory.settings['series']}, dt = {run.timestep:g} s: the MuJoCo engine's "
        "MJCF (servos off) on MJX's JAX back end in float64, from the reference's initial state; accelerations "
        "are MuJoCo's (C) qacc at MJX's states.",
    )
    drift = np.array([oracle.violation(q) for q in qpos[good]])
    trajectory.diagnostics = {"constraint_violation": drift, "energy": energy}
    row["loop_drift"] = float(drift.max())
    if not (mech.loads or any(spring.damping for spring in mech.springs)):  # E conserved
        row["energy_drift"] = float(np.max(np.abs(energy - energy[0])))
    if compare and mj_trajectory is not None and not failure:
        row["mujoco_difference"] = _difference(trajectory, mj_trajectory)
    if failure:
        row["status"] = failure
        return row, None
    errors = free_errors(reference, trajectory)
    row.update(
        position_error=errors["position_error"], final_error=errors["final_error"], angle_error=errors["angle_error"]
    )
    left = left_branch(reference, trajectory, mujoco_free.LEFT_BRANCH * mech.size)
    if left:
        row["status"] = left
        return row, None
    return row, trajectory


def _difference(a: Trajectory, b: Trajectory) -> float:
    """The largest distance between the same named point in two trajectories at the same samples, m."""
    worst = 0.0
    for label, states in a.points.items():
        gap = np.asarray(states["position"]) - np.asarray(b.points[label]["position"])
        worst = max(worst, float(np.max(np.hypot(gap[:, 0], gap[:, 1]))))
    return worst


def run_free(
    kinematics: Kinematics,
    reference,
    branch: str | None = None,
    timesteps=TIMESTEPS,
    settings=SETTINGS,
    batched: bool | None = None,
    compare: bool = True,
) -> ModeResult:
    """MJX's free motion of the mechanism against the native reference.

    Parameters
    ----------
    kinematics : Kinematics
    reference : FreeReference
        The native reference; its initial state is MJX's, its output times
        (every k-th, about 200) are compared.
    branch : str, optional
        Unused: the reference's initial state fixes the branch.
    timesteps : sequence of float
        The ladder's time steps, s.
    settings : sequence of Setting
        The ladder's series (:data:`SETTINGS`).
    batched : bool, optional
        Run the rows of each integrator and solver as one ``jax.vmap`` batch
        (default: on an accelerator, not on the CPU).
    compare : bool
        Also run MuJoCo (C) at each setting (its free mode's run): its
        ``mujoco_position_error``, ``mujoco_loop_drift`` (m),
        ``mujoco_cpu_per_simulated_second`` and ``mujoco_difference`` (m, the
        largest point distance between the two trajectories).

    Returns
    -------
    ModeResult
        See :meth:`xcheck.engines.Engine.run_free`; ``summary`` also has
        compile_seconds, angle_error (rad), observed_order, and the
        MuJoCo columns.

    Raises
    ------
    NotApplicable
        A load or spring MJX cannot apply (:func:`applied_forces`).
    """
    mech = kinematics.mechanism
    jax, _, _ = load_mjx()
    try:
        model, lay = mujoco_free.free_model(kinematics)
    except XcheckError as error:
        return ModeResult(FREE_MODE, mech.name, False, f"MJCF writer: {' '.join(str(error).split())}")
    except ValueError as error:
        return ModeResult(FREE_MODE, mech.name, False, f"MuJoCo rejects the MJCF: {error}".splitlines()[0])
    xfrc = applied_forces(mech, model)
    if batched is None:
        batched = jax.default_backend() != "cpu"
    oracle = Oracle(model, mech, lay)
    q0, qd0 = reference.motion.q[0], reference.motion.qd[0]
    qpos0 = joint_coordinates(mech, lay, q0)
    qvel0 = mujoco_free.joint_velocities(mech, lay, q0, qd0)
    residual, jacobian = oracle.constraints(qpos0)
    closure = float(np.max(np.abs(residual), initial=0.0))
    rate = float(np.max(np.abs(jacobian @ qvel0), initial=0.0))
    if closure > 1e-9 * mech.size or rate > 1e-9 * max(float(np.max(np.abs(qd0))), 1.0) * mech.size:
        return ModeResult(
            FREE_MODE,
            mech.name,
            False,
            f"the initial state does not close MuJoCo's loops (position {closure:.3g} m, velocity {rate:.3g} m/s)",
        )
    groups: dict[tuple[str, str], list[_Run]] = {}
    order: list[_Run] = []
    index = np.arange(1)
    for setting in settings:
        for dt in ladder_steps(reference, timesteps):
            index, every, misfit = mujoco_free._sampling(reference, float(dt))
            run = _Run(setting, float(dt), every, {}, {}, _empty_row(setting, float(dt), every * (len(index) - 1)))
            order.append(run)
            if misfit:
                run.row["status"] = misfit
                continue
            run.parameters, run.settings = _parameters(model, setting, float(dt), every)
            groups.setdefault((setting.integrator, setting.solver), []).append(run)
    rows, trajectories = {}, []
    for (integrator, solver), runs in groups.items():
        try:
            m = mjx_model(model, integrator, solver)
        except NotImplementedError as error:
            for run in runs:
                run.row["status"] = f"MJX does not implement {error}"
            continue
        compile_seconds = _execute(runs, m, qpos0, qvel0, xfrc, len(index), batched)
        for run in runs:
            run.row["compile_seconds"] = compile_seconds
            row, trajectory = _finish(
                kinematics, model, lay, oracle, reference, run, index, xfrc, qpos0, qvel0, compare
            )
            rows[id(run)] = row
            if trajectory is not None:
                trajectories.append((row["position_error"], trajectory))
    summary = pd.DataFrame([rows.get(id(run), run.row) for run in order])
    floor = float(np.max(reference.estimate))  # errors within the reference's own are not measured: no order
    study = convergence_study(
        summary.setting + " " + summary.integrator,
        summary.timestep,
        summary.position_error,
        summary.status,
        floor=floor,
    )
    observed = study.set_index(["series", "timestep"])["order"]
    summary["observed_order"] = [
        float(observed.get((f"{r.setting} {r.integrator}", r.timestep), math.nan)) for r in summary.itertuples()
    ]
    trajectories.sort(key=lambda pair: pair[0])
    if not trajectories:
        first = summary.iloc[0]
        return ModeResult(
            FREE_MODE,
            mech.name,
            False,
            f"no run went through ({first.setting} {first.integrator} dt = {first.timestep:g} s: {first.status})",
            [],
            summary,
            study,
        )
    return ModeResult(FREE_MODE, mech.name, True, "", [t for _, t in trajectories], summary, study)
