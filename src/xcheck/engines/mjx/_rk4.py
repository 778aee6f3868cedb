"""MJX's RK4 step with one forward pass in its graph.

``mjx.step`` with ``mjINT_RK4`` calls ``mjx.forward`` once and then runs the
three further stages in a ``jax.lax.scan`` unrolled three times: four copies
of the forward pass in the compiled graph, and a fifth where the driven mode
also samples ``qacc``. XLA's compile time grows with the copies (measured on
models/fourbar.toml, driven rollout: 7.0 CPU s tracing and 27.5 s compiling).
:func:`step` is the same tableau as ``mujoco.mjx._src.forward.rungekutta4``
(the stages' states, times and warm start alike), written as one
``jax.lax.scan`` over the four stages, not unrolled, whose body is the one
``mjx.forward``; the first stage's ``qacc`` (the forward pass at the step's
start) is returned as well, so sampling needs no pass of its own (3.2 s
tracing, 11.1 s compiling, and the run 2.4 times faster).

Positions advance as ``qpos + dt qvel``, which is MJX's integration for hinge
and slide joints; :func:`applies` says whether a model has only those and no
actuator activations.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .free import load_mjx

__all__ = ["applies", "step"]

#: The stages' weights on the previous stage's rates (the Butcher tableau's
#: sub-diagonal, 0 for the first stage) and the solution's weights.
_A = np.array([0.0, 0.5, 0.5, 1.0])
_B = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0


def applies(model: mujoco.MjModel) -> bool:
    """Whether :func:`step` integrates ``model``: hinge and slide joints only, no activations."""
    linear = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    return model.na == 0 and all(int(t) in linear for t in model.jnt_type)


def step(m, d):
    """One RK4 step of MJX's dynamics.

    Parameters
    ----------
    m : mjx.Model
    d : mjx.Data
        The state at the step's start (qpos, qvel, time, ctrl, qacc_warmstart).

    Returns
    -------
    mjx.Data, array of shape (nv,)
        The state one ``m.opt.timestep`` later, as ``mjx.step`` returns it (the
        last stage's forward quantities, ``qacc_warmstart`` its ``qacc``), and
        ``qacc`` at the step's start (rad/s^2 or m/s^2).
    """
    jax, jnp, mjx = load_mjx()
    qpos0, qvel0, time0 = d.qpos, d.qvel, d.time
    dt = m.opt.timestep

    def stage(carry, weights):
        rate, acceleration, rate_sum, acceleration_sum, d = carry
        a, b = weights[0], weights[1]
        d = d.replace(qpos=qpos0 + dt * (a * rate), qvel=qvel0 + dt * (a * acceleration), time=time0 + a * dt)
        d = mjx.forward(m, d)
        return (d.qvel, d.qacc, rate_sum + b * d.qvel, acceleration_sum + b * d.qacc, d), d.qacc

    zero = jnp.zeros_like(qvel0)
    weights = jnp.stack([jnp.asarray(_A), jnp.asarray(_B)], axis=1)
    (_, _, rate_sum, acceleration_sum, d), accelerations = jax.lax.scan(stage, (zero, zero, zero, zero, d), weights)
    d = d.replace(
        qpos=qpos0 + dt * rate_sum, qvel=qvel0 + dt * acceleration_sum, time=time0 + dt, qacc_warmstart=d.qacc
    )
    return d, accelerations[0]
