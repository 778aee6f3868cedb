"""MuJoCo's model of a mechanism, shared by its modes: the MJCF writer's text
(:func:`.mjcf.mjcf_text`) compiled by MuJoCo, and the same model released in
free motion (its servos off)."""

from __future__ import annotations

import mujoco
import numpy as np

from xcheck.errors import XcheckError
from xcheck.kinematics import Kinematics, rotate
from xcheck.model import GROUND, Mechanism

from .mjcf import Layout, layout, mjcf_text

__all__ = ["compile_model", "free_model", "joint_velocities"]


def compile_model(kinematics: Kinematics, xml: str | None = None) -> tuple[mujoco.MjModel, Layout]:
    """The compiled MJCF of the mechanism (``xml`` instead of the writer's text) and its layout.

    Raises
    ------
    ValueError
        If the writer cannot express the mechanism or MuJoCo rejects the file
        (the reason in one line).
    """
    mech = kinematics.mechanism
    try:
        lay = layout(mech)
        text = mjcf_text(kinematics) if xml is None else xml
    except XcheckError as error:
        raise ValueError(f"MJCF writer: {' '.join(str(error).split())}") from error
    try:
        return mujoco.MjModel.from_xml_string(text), lay
    except ValueError as error:  # MuJoCo's compiler
        raise ValueError(f"MuJoCo rejects the MJCF: {error}".splitlines()[0]) from error


def free_model(kinematics: Kinematics) -> tuple[mujoco.MjModel, Layout]:
    """The compiled MJCF of the mechanism for free motion: springs as tendons (the
    writer's), actuation off (gains and biases zeroed), energy on.

    Raises
    ------
    ValueError
        :func:`compile_model`'s.
    """
    model, lay = compile_model(kinematics)
    model.actuator_gainprm[:] = 0.0
    model.actuator_biasprm[:] = 0.0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    return model, lay


def joint_velocities(mechanism: Mechanism, lay: Layout, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """MuJoCo ``qvel`` of body coordinates and rates: the time derivative of
    :func:`.mjcf.joint_coordinates`.

    Parameters
    ----------
    q, qd : ndarray, shape (3 m,)
        x, y (m), phi (rad) of each moving body and their rates (m/s, rad/s).

    Returns
    -------
    ndarray, shape (nv,)
        Hinges: ``omega_b - omega_a`` (rad/s); slides: the rate of the slide displacement (m/s).
    """
    frames = {GROUND: (np.zeros(2), 0.0, np.zeros(2), 0.0)}
    for i, body in enumerate(mechanism.moving_bodies):
        frames[body.name] = (
            np.asarray(q[3 * i : 3 * i + 2], dtype=float),
            float(q[3 * i + 2]),
            np.asarray(qd[3 * i : 3 * i + 2], dtype=float),
            float(qd[3 * i + 2]),
        )

    def state(body: str, label: str | None):
        r, phi, v, w = frames[body]
        if label is None:
            return r, v, phi, w
        arm = rotate(phi, mechanism.body(body).points[label])
        return r + arm, v + w * np.array([-arm[1], arm[0]]), phi, w

    qvel = []
    for mj in lay.joints:
        joint = mj.joint
        if mj.kind == "hinge":
            qvel.append(frames[joint.body_b][3] - frames[joint.body_a][3])
        else:  # a slide: its joint's (or, a carrier's, its cut's) slide displacement
            qvel.append(joint.coordinate(state)[1])
    return np.array(qvel)
