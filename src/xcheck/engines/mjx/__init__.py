"""MJX: MuJoCo's second implementation (MuJoCo XLA, in JAX), run on the same MJCF
file as :mod:`xcheck.engines.mujoco`, in free motion (:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["MJX"]


class MJX(Engine):
    """MJX (MuJoCo XLA, JAX on CPU in float64): free motion."""

    name = "mjx"
    title = "MJX"
    requires = ("mujoco.mjx", "jax")
    implementation = "xcheck.engines.mjx.free"
    distributions = ("mujoco-mjx", "jax")
    install = "pip install xcheck[mjx]"
    modes = (Mode("mjx-free", "free", FREE_MOTION, style=dict(color="tab:cyan", lw=1, ls="-.")),)
    color = "tab:cyan"
    notes = (
        "The MuJoCo engine's MJCF file (revolute, prismatic and pin-in-slot joints, loops closed by connect "
        "or weld equalities, springs as spatial tendons) put on MJX's JAX back end (mjx.put_model, float64), "
        "stepped by one jit-compiled jax.lax.scan. Constant torques, and constant forces at a body's centre "
        "of mass, through xfrc_applied. Not converted (not applicable): loads with a time law or a force "
        "off the centre of mass, and rotational springs (MuJoCo's free mode applies them in the passive-force "
        "callback mjcb_passive, which MJX does not call). MJX refuses MuJoCo's implicit integrator, the PGS "
        "solver and the energy flag (energy is MuJoCo's, at MJX's states). Free motion only: no driven mode."
    )
