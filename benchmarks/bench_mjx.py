"""Benchmark of MJX's batched free motion (xcheck's ``mjx-free`` rollout):
simulation steps per second for batch sizes 1, 16, 256 and 4096 of one
mechanism started at different speeds, as one ``jax.vmap`` of the same
jit-compiled rollout (:func:`xcheck.engines.mjx.free.rollout`).

This is what MJX is for on a GPU; xcheck's own measurements were made on a
CPU only (no GPU was available). Run on a machine with a GPU and a CUDA build
of jax (``pip install -U "jax[cuda12]"``):

    PYTHONPATH=src python benchmarks/bench_mjx.py                 # iftomm-a02, stiff Newton Euler, 1 ms
    PYTHONPATH=src python benchmarks/bench_mjx.py --sizes 1,16 --duration 0.2 --integrator RK4

Each batch element is the mechanism's free motion from the reference's
initial configuration with its initial velocities scaled by a factor from 0.5
to 1.5, element 0 at 1 (a scaled velocity still closes the loops: the constraint is linear in
the velocities). Compile time and run time are printed apart; the run is
timed on the second call (wall time, ``jax.block_until_ready``), and element
0 of each batch is checked against the batch of one (largest qpos difference).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from xcheck import Kinematics, load_mechanism
from xcheck.catalog import model_path, models_dir
from xcheck.dynamics._free import simulate
from xcheck.engines.mjx import free
from xcheck.engines.mujoco.mjcf import joint_coordinates
from xcheck.engines.mujoco.model import free_model, joint_velocities


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default="iftomm-a02")
    parser.add_argument("--sizes", default="1,16,256,4096", help="batch sizes, comma separated")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated time, s")
    parser.add_argument("--timestep", type=float, default=1e-3, help="s")
    parser.add_argument("--every", type=int, default=10, help="steps between samples")
    parser.add_argument("--integrator", default="Euler", choices=("Euler", "implicitfast", "RK4"))
    parser.add_argument("--solver", default="Newton", choices=("Newton", "CG"))
    parser.add_argument("--softness", default="stiff", choices=("default", "stiff"))
    args = parser.parse_args()

    jax, jnp, _ = free.load_mjx()
    kin = Kinematics(load_mechanism(model_path(args.model, models_dir())))
    kin.assemble()
    reference = simulate(kin, duration=args.timestep * args.every)  # only its initial state is used
    mech = kin.mechanism
    model, lay = free_model(kin)
    q0, qd0 = reference.motion.q[0], reference.motion.qd[0]
    qpos0, qvel0 = joint_coordinates(mech, lay, q0), joint_velocities(mech, lay, q0, qd0)
    xfrc = free.applied_forces(mech, model)
    setting = free.Setting(args.softness, args.integrator, args.solver)
    samples = max(2, round(args.duration / (args.timestep * args.every)) + 1)
    parameters, _ = free._parameters(model, setting, args.timestep, np.full(samples - 1, args.every))
    m = free.mjx_model(model, args.integrator, args.solver)
    steps = (samples - 1) * args.every
    print(f"{args.model}: {setting.series.key}, dt = {args.timestep:g} s, {steps} steps per element")
    print(f"jax {jax.__version__}, backend {jax.default_backend()}, devices {jax.devices()}")
    batch_rollout = jax.vmap(free.rollout, in_axes=(None, None, 0, 0, None))
    first = None
    for size in (int(s) for s in args.sizes.split(",")):
        factors = np.concatenate([[1.0], np.linspace(0.5, 1.5, size - 1)])  # element 0 at the reference's speed
        qpos = jnp.asarray(np.tile(qpos0, (size, 1)))
        qvel = jnp.asarray(factors[:, None] * qvel0[None, :])
        begin = time.perf_counter()
        compiled = jax.jit(batch_rollout).lower(m, parameters, qpos, qvel, xfrc).compile()
        compile_seconds = time.perf_counter() - begin
        jax.block_until_ready(compiled(m, parameters, qpos, qvel, xfrc))  # warm
        begin = time.perf_counter()
        out = jax.block_until_ready(compiled(m, parameters, qpos, qvel, xfrc))
        wall = time.perf_counter() - begin
        final = np.asarray(out[0][:, -1])
        if first is None:
            first = final[0]
        agree = float(np.max(np.abs(final[0] - first)))
        print(
            f"batch {size:5d}: compile {compile_seconds:7.2f} s, run {wall:8.3f} s, "
            f"{size * steps / wall:12.4g} steps/s, {size * args.duration / wall:10.4g} simulated s per s, "
            f"element at factor 1 vs batch of one: {agree:.2g} rad or m"
        )


if __name__ == "__main__":
    main()
