"""MJX in free motion (mode ``mjx-free``): the MuJoCo engine's free-motion MJCF
(:func:`xcheck.engines.mujoco.free.free_model`: servos off, springs as spatial
tendons) on MJX's JAX back end in float64, compared with the native reference
and with MuJoCo's C implementation at the same settings.

The rollout is one ``jax.jit``-compiled function (:func:`rollout`): a
``jax.lax.scan`` over the compared outputs whose body steps ``mjx.step`` the
run's number of steps to the next output, given as data
(``jax.lax.fori_loop``). The time step, the equality solref and solimp and the
solver tolerance are data too, so one compilation per integrator and solver
(static in MJX) serves every step and softness of the ladder. The ladder and
its judgement are :func:`xcheck.ladder.free_study`'s; the series are MuJoCo's
free mode's (default softness and stiff loops,
:class:`xcheck.engines.mujoco.dynamic.Setting`) with each integrator MJX has
(Euler, implicitfast, RK4; MuJoCo's ``implicit`` is not implemented in MJX)
and each of its solvers (Newton, CG; not PGS). Each run is one call of the
compiled rollout; a ``jax.vmap`` batch of copies, MJX's point on a GPU, is
what benchmarks/bench_mjx.py measures.

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
the CPU; ``ALL_SERIES`` on A02, Newton and CG Euler and Newton
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
25 CPU s (RK4) per integrator and solver. A batch of copies at one step pays
(benchmarks/bench_mjx.py, A02 stiff Newton Euler at 1 ms, wall): 6.2e3 steps/s
alone, 3.0e4 for 16, 2.6e4 for 64.
"""

from __future__ import annotations

import contextlib
import copy
import io
import time
from dataclasses import dataclass, field, replace
from functools import partial

import mujoco
import numpy as np

from xcheck.engines.mujoco import dynamic as mujoco_dynamic
from xcheck.engines.mujoco import free as mujoco_free
from xcheck.engines.mujoco.mjcf import mass_properties
from xcheck.errors import NotApplicable
from xcheck.ladder import FreeProblem, Run, Rung, Series, free_errors
from xcheck.model import Mechanism
from xcheck.results import Trajectory
from xcheck.store import cache_dir

__all__ = [
    "FREE_MODE",
    "ALL_SERIES",
    "FREE_SERIES",
    "MjxFree",
    "Setting",
    "applied_forces",
    "load_mjx",
    "mjx_model",
    "prepare_free",
    "rollout",
    "run_free_once",
]

FREE_MODE = "mjx-free"
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
    def series(self) -> Series:
        """Its series of the ladder: the setting "softness solver" (e.g. "stiff
        Newton") with the integrator, named "stiff Newton Euler"."""
        setting = f"{self.softness} {self.solver}"
        return Series(setting, self.integrator, self, name=f"{setting} {self.integrator}")

    def mujoco(self) -> mujoco_dynamic.Setting:
        """The MuJoCo engine's setting of the same softness and integrator."""
        return mujoco_dynamic.Setting(f"{self.softness} {self.solver}", self.integrator, self.softness == "stiff")


#: Every softness, integrator and solver (six compilations; about 15 min on A02's 10 s on 2 shared cores).
ALL_SERIES = tuple(
    Setting(softness, integrator, solver).series
    for softness in ("default", "stiff")
    for solver in ("Newton", "CG")
    for integrator in ("Euler", "implicitfast", "RK4")
)
#: The default ladder (two compilations, 20 to 40 CPU s): Newton with Euler and RK4. Measured
#: on A01, A02 and A03 (ALL_SERIES on A02): implicitfast gave Euler's errors to 4 digits (no velocity-dependent
#: force but dampers) and CG Newton's to 3 digits at 1.1 to 2.3 times its CPU time.
FREE_SERIES = tuple(s for s in ALL_SERIES if s.options.solver == "Newton" and s.integrator != "implicitfast")


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


def rollout(m, parameters: dict, qpos0, qvel0, xfrc):
    """MJX's motion from (qpos0, qvel0): the states after each interval of
    ``parameters["counts"]`` steps.

    Parameters
    ----------
    m : mjx.Model
    parameters : dict of arrays
        ``timestep`` (s), ``tolerance``, ``solref`` (2,), ``solimp`` (5,) (every
        equality alike), ``counts`` (int, shape (K,): the steps of each interval):
        data, not constants of the compilation (but K, the scan's length).
    qpos0, qvel0 : array, shape (nq,), (nv,)
    xfrc : array, shape (nbody, 6)
        Constant applied forces and torques at the bodies' centres of mass (N, N m).

    Returns
    -------
    qpos, qvel : arrays, shape (K, nq), (K, nv)
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

    def sample(d, count):
        d = jax.lax.fori_loop(0, count, lambda _, d: mjx.step(m, d), d)
        return d, (d.qpos, d.qvel)

    _, states = jax.lax.scan(sample, d, parameters["counts"])
    return states


def _parameters(model: mujoco.MjModel, setting: Setting, timestep: float, counts) -> tuple[dict, dict]:
    """(rollout parameters, the trajectory's settings) of one run: MuJoCo's
    :meth:`~xcheck.engines.mujoco.dynamic.Setting.apply` on a copy of ``model``,
    ``counts`` the steps of each interval between outputs."""
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
        "counts": np.asarray(counts, dtype=np.int64),
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


@dataclass
class MjxFree:
    """What every MJX free run shares: MuJoCo's free model and start, the constant
    applied forces, whether MuJoCo (C) runs beside it, and the compiled rollouts
    by (integrator, solver, outputs), each with its compile CPU time (s)."""

    mujoco: mujoco_free.FreeModel
    xfrc: np.ndarray
    compare: bool = True
    compiled: dict = field(default_factory=dict)

    def executable(self, setting: Setting, parameters: dict):
        """(mjx.Model, the compiled rollout, its compile CPU seconds) for the
        setting's integrator and solver, compiled on first use.

        Raises
        ------
        NotImplementedError
            What MJX refuses (e.g. ``mjINT_IMPLICIT``, ``mjSOL_PGS``).
        """
        jax, _, _ = load_mjx()
        key = (setting.integrator, setting.solver, len(parameters["counts"]))
        if key not in self.compiled:
            m = mjx_model(self.mujoco.model, setting.integrator, setting.solver)
            arguments = (m, parameters, self.mujoco.qpos0, self.mujoco.qvel0, self.xfrc)
            begin = time.process_time()
            compiled = jax.jit(rollout).lower(*arguments).compile()
            self.compiled[key] = (m, compiled, time.process_time() - begin)
        return self.compiled[key]


def prepare_free(problem: FreeProblem, compare: bool = True) -> MjxFree:
    """MuJoCo's free model and start (:func:`xcheck.engines.mujoco.free.prepare_free`)
    and the loads as ``xfrc_applied``; ``compare``: also run MuJoCo (C) at each rung
    (the row's ``mujoco_position_error``, ``mujoco_loop_drift`` (m),
    ``mujoco_cpu_per_simulated_second`` and ``mujoco_difference``: the largest
    point distance between the two complete runs, m).

    Raises
    ------
    NotApplicable
        A load or spring MJX cannot apply (:func:`applied_forces`).
    ValueError
        :func:`xcheck.engines.mujoco.free.prepare_free`'s.
    """
    load_mjx()
    prepared = mujoco_free.prepare_free(problem)
    return MjxFree(prepared, applied_forces(problem.kinematics.mechanism, prepared.model), compare)


def run_free_once(prepared: MjxFree, problem: FreeProblem, rung: Rung) -> Run:
    """One run of the ladder (:meth:`xcheck.engines.Engine.run_free_once`): the
    compiled rollout, then MuJoCo's (C) accelerations and energy at MJX's states
    and, where ``prepared.compare``, MuJoCo (C) at the same setting."""
    jax, _, _ = load_mjx()
    kinematics = problem.kinematics
    mech = kinematics.mechanism
    setting: Setting = rung.series.options
    model, oracle = prepared.mujoco.model, prepared.mujoco.oracle
    qpos0, qvel0 = prepared.mujoco.qpos0, prepared.mujoco.qvel0
    parameters, settings = _parameters(model, setting, rung.timestep, rung.counts)
    try:
        m, compiled, compile_seconds = prepared.executable(setting, parameters)
    except NotImplementedError as error:
        return Run(None, f"MJX does not implement {error}")
    columns = {"compile_seconds": compile_seconds}
    begin = time.process_time()
    qpos, qvel = jax.block_until_ready(compiled(m, parameters, qpos0, qvel0, prepared.xfrc))
    cpu = time.process_time() - begin
    times = problem.times
    qpos = np.concatenate([qpos0[None], np.asarray(qpos)])
    qvel = np.concatenate([qvel0[None], np.asarray(qvel)])
    bad = ~(np.all(np.isfinite(qpos), axis=1) & np.all(np.isfinite(qvel), axis=1))
    bad |= np.any(np.abs(qvel) > MAX_VALUE, axis=1) | np.any(np.abs(qpos) > MAX_VALUE, axis=1)
    s = int(np.argmax(bad)) if bad.any() else len(times)
    failure = f"NaN or beyond 1e10 by t = {times[s]:.4g} s" if s < len(times) else ""
    gaps = np.array([oracle.violation(q) for q in qpos[:s]])
    apart = next((i for i in range(s) if problem.came_apart(float(times[i]), float(gaps[i]))), None)
    if apart is not None:
        failure, s = problem.came_apart(float(times[apart]), float(gaps[apart])), apart + 1
    trajectory = None
    if s:
        good = slice(0, s)
        qacc, energy = _mujoco_states(model, setting, rung.timestep, prepared.xfrc, qpos[good], qvel[good])
        trajectory = mujoco_free.states(kinematics, oracle, problem, qpos[good], qvel[good], qacc)
        trajectory = replace(
            trajectory,
            source=FREE_MODE,
            settings={**settings, "series": rung.series.key, "samples": s},
            diagnostics={"constraint_violation": gaps[good]},
            notes=f"MJX free motion, {rung.series.key}, dt = {rung.timestep:g} s: the MuJoCo engine's MJCF (servos "
            "off) on MJX's JAX back end in float64, from the reference's initial state; accelerations are MuJoCo's "
            "(C) qacc at MJX's states.",
        )
        if not mech.loads:  # MuJoCo's energy holds no load's potential (MJX takes no rotational spring)
            trajectory.diagnostics["energy"] = energy
    if prepared.compare:
        columns.update(_beside_mujoco(prepared, problem, rung, None if failure else trajectory))
    return Run(trajectory, failure, cpu, columns)


def _beside_mujoco(prepared: MjxFree, problem: FreeProblem, rung: Rung, trajectory: Trajectory | None) -> dict:
    """MuJoCo (C) at the same rung and solver: its position error and loop drift (m),
    CPU per simulated second, and its largest point distance from MJX's complete run (m)."""
    model = copy.deepcopy(prepared.mujoco.model)
    model.opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{rung.series.options.solver.upper()}")
    mj_rung = replace(rung, series=replace(rung.series, options=rung.series.options.mujoco()))
    mj = mujoco_free.run_free_once(prepared.mujoco, problem, mj_rung, model)
    keys = ("mujoco_position_error", "mujoco_loop_drift", "mujoco_cpu_per_simulated_second", "mujoco_difference")
    out = dict.fromkeys(keys, float("nan"))
    if mj.trajectory is None or mj.trajectory.times is None:
        return out
    times = mj.trajectory.times
    out["mujoco_loop_drift"] = float(np.max(mj.trajectory.diagnostics["constraint_violation"]))
    if len(times) > 1:
        out["mujoco_cpu_per_simulated_second"] = mj.cpu_seconds / float(times[-1] - times[0])
    if not mj.failure:
        out["mujoco_position_error"] = free_errors(problem.reference, mj.trajectory)["position_error"]
        if trajectory is not None:
            out["mujoco_difference"] = _difference(trajectory, mj.trajectory)
    return out


def _difference(a: Trajectory, b: Trajectory) -> float:
    """The largest distance between the same named point in two trajectories at the same samples, m."""
    worst = 0.0
    for label, states in a.points.items():
        gap = np.asarray(states["position"]) - np.asarray(b.points[label]["position"])
        worst = max(worst, float(np.max(np.hypot(gap[:, 0], gap[:, 1]))))
    return worst
