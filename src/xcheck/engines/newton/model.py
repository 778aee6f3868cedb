"""Newton's model of a mechanism: a ``newton.ModelBuilder`` (y up) whose links are
xcheck's body frames, hung from their parents (or the world) by revolute joints
(about z) and prismatic joints (along the joint frame's x) placed by
:func:`xcheck.engines._tree.tree_frames`, every coordinate 0 at the state the
model is built at, the tree's joints one articulation; each loop cut at a
revolute is a revolute joint left out of the articulation (Newton's loop
joint), its frames turned so that its coordinate too is 0 there. Newton's MuJoCo
backend computes a loop joint's anchors at q = 0 (a finding): zeroed at the
start, they are right. Gravity is the model's; the model is finalised on the CPU
(warp's float32).

Each tree joint is converted by the converter of its type. Not converted
(:class:`~xcheck.engines.NotApplicable`): pin-in-slot joints, loops cut at a
prismatic joint and gear pairs (:func:`~xcheck.engines._tree.tree_frames`),
springs, dampers and loads (not built here).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from xcheck.dynamics._forces import require_mass_data
from xcheck.engines._contract import positive_inertia
from xcheck.engines._tree import TreeFrames, gravity_only, tree_frames
from xcheck.joints import Prismatic, Revolute, converter
from xcheck.model import GROUND, Mechanism

__all__ = ["NewtonModel", "build", "newton", "solver"]

#: Newton's floor on a moment of inertia (kg m^2), below any :func:`positive_inertia` gives a
#: point mass of a mechanism of millimetres or more; Newton's own (1e-10) would replace
#: a point mass's 1e-12 m size^2 by about 1e-6 kg m^2 (with a warning)
POINT_MASS_FLOOR = 1e-30


def newton():
    """The ``newton`` and ``warp`` modules (imported when a mode runs), warp's messages below
    errors off: it prints its start and each kernel's compilation on stdout, where the JSON
    of ``xcheck simulate --json`` goes."""
    import warp

    warp.config.log_level = warp.LOG_ERROR
    import newton as module

    return module, warp


@dataclass
class NewtonModel:
    """The mechanism as a finalised Newton model.

    Attributes
    ----------
    model : newton.Model
    tree : TreeFrames
    links : dict of str to int
        Moving body -> its link index.
    joints : dict of str to int
        Tree joint -> its Newton joint index.
    start : dict of str to float
        Moving body -> its angle at the build state, rad.
    rates : ndarray
        ``joint_qd`` at the start (float32), the loop joints' rates included.
    """

    model: Any
    tree: TreeFrames
    links: dict[str, int]
    joints: dict[str, int]
    start: dict[str, float]
    rates: np.ndarray

    def frames(self, state, previous: dict[str, tuple] | None = None) -> dict[str, tuple]:
        """Per moving body: origin (2,) m and angle rad at ``state``, the angle continuous
        from ``previous`` (these frames at an earlier state; the build state's without).

        Newton's maximal-coordinate solvers (XPBD, semi-implicit) leave ``joint_q`` as it
        was: the links' own poses are read, each angle taken within half a turn of its
        previous value (outputs are far closer than half a turn of any link).
        """
        poses = state.body_q.numpy()
        out = {}
        for name, link in self.links.items():
            pose = poses[link]
            before = self.start[name] if previous is None else previous[name][1]
            raw = 2.0 * math.atan2(float(pose[5]), float(pose[6]))
            turned = before + math.remainder(raw - before, 2.0 * math.pi)
            out[name] = (np.asarray(pose[:2], dtype=float), turned)
        return out


#: each tree joint type's converter: the model builder -> (its method adding the joint, the joint's axis in its frames)
_JOINTS: dict[type, Callable] = {
    Revolute: lambda builder: (builder.add_joint_revolute, (0.0, 0.0, 1.0)),
    Prismatic: lambda builder: (builder.add_joint_prismatic, (1.0, 0.0, 0.0)),
}


def _depth_first(tree: TreeFrames) -> list:
    """The tree's joints in depth-first order (each subtree whole before the next): the
    order Newton's MuJoCo backend needs to convert the articulation faithfully."""
    children: dict[str, list] = {}
    for frames in tree.joints:
        children.setdefault(frames.parent, []).append(frames)
    out: list = []

    def visit(body: str) -> None:
        for frames in children.get(body, []):
            out.append(frames)
            visit(frames.child)

    visit(GROUND)
    return out


def build(mech: Mechanism, q: np.ndarray, qd: np.ndarray, kinematic: frozenset[str] = frozenset()) -> NewtonModel:
    """The mechanism as a Newton model at native body coordinates ``q`` and rates ``qd``
    (x, y, phi per moving body; m, rad, m/s, rad/s), all joint coordinates 0 there,
    the bodies named in ``kinematic`` Newton's kinematic bodies (their motion set by
    the caller; Newton allows only bodies hung from the ground).

    Raises
    ------
    NotApplicable
        What the model cannot hold (:func:`~xcheck.engines._tree.gravity_only`,
        :func:`~xcheck.engines._tree.tree_frames`).
    ModelError
        If a moving body has no mass data.
    """
    module, wp = newton()
    require_mass_data(mech)
    gravity_only(mech, "Newton")
    tree = tree_frames(mech, q, "Newton")
    gravity = np.asarray(mech.gravity, dtype=float)
    builder = module.ModelBuilder(up_axis=module.Axis.Y, gravity=(float(gravity[0]), float(gravity[1]), 0.0))
    # a point mass's least inertia (positive_inertia) kept as it is: Newton would raise it to about 1e-6 kg m^2
    builder.inertia_absolute_tolerance = POINT_MASS_FLOOR
    size = mech.size
    links: dict[str, int] = {}
    for body in mech.moving_bodies:
        assert body.mass is not None and body.inertia is not None
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        inertia = positive_inertia(float(body.mass), float(body.inertia), size)
        links[body.name] = builder.add_link(
            mass=float(body.mass),
            com=wp.vec3(float(com[0]), float(com[1]), 0.0),
            inertia=wp.mat33(inertia, 0.0, 0.0, 0.0, inertia, 0.0, 0.0, 0.0, inertia),
            is_kinematic=body.name in kinematic,
            label=body.name,
        )

    def link(name: str) -> int:
        return -1 if name == GROUND else links[name]

    def xform(point, angle: float):
        turn = wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), float(angle))
        return wp.transform(wp.vec3(float(point[0]), float(point[1]), 0.0), turn)

    joints = []
    for frames in _depth_first(tree):
        add, axis = converter(_JOINTS, mech.joint(frames.name), "Newton")(builder)
        joints.append(
            add(
                link(frames.parent),
                link(frames.child),
                parent_xform=xform(frames.parent_point, frames.parent_angle),
                child_xform=xform(frames.child_point, frames.child_angle),
                axis=axis,
                label=frames.name,
            )
        )
    builder.add_articulation(joints)
    index = {b.name: 3 * i for i, b in enumerate(mech.moving_bodies)}

    def angle(name: str) -> float:
        return 0.0 if name == GROUND else float(q[index[name] + 2])

    def rate(name: str) -> float:
        return 0.0 if name == GROUND else float(qd[index[name] + 2])

    loop_rates = []
    for body_a, point_a, body_b, point_b in tree.cuts:
        builder.add_joint_revolute(
            link(body_a),
            link(body_b),
            parent_xform=xform(point_a, angle(body_b) - angle(body_a)),
            child_xform=xform(point_b, 0.0),
            axis=(0.0, 0.0, 1.0),
        )
        loop_rates.append(rate(body_b) - rate(body_a))
    model = builder.finalize(device="cpu")
    tree_rates = tree.rates(mech, q, qd)
    rates = np.zeros(model.joint_dof_count, dtype=np.float32)
    dof_starts = model.joint_qd_start.numpy()
    for frames, j in zip(_depth_first(tree), joints):
        rates[dof_starts[j]] = tree_rates[frames.name]
    for k, value in enumerate(loop_rates):
        rates[dof_starts[len(joints) + k]] = value
    start = {name: angle(name) for name in links}
    indices = {frames.name: j for frames, j in zip(_depth_first(tree), joints)}
    return NewtonModel(model, tree, links, indices, start, rates)


def solver(name: str, model):
    """Newton's solver of a series on ``model``."""
    module, _ = newton()
    solvers = module.solvers
    if name == "mujoco":
        with warnings.catch_warnings():  # mujoco-warp runs on xcheck's MuJoCo, newer than Newton's pin
            warnings.filterwarnings("ignore", message="MuJoCo dependency version mismatch")
            return solvers.SolverMuJoCo(model, use_mujoco_cpu=True, disable_contacts=True)
    if name == "xpbd":
        return solvers.SolverXPBD(model)
    if name == "featherstone":
        return solvers.SolverFeatherstone(model)
    if name == "semi-implicit":
        return solvers.SolverSemiImplicit(model)
    raise ValueError(f"expected a Newton solver (mujoco, xpbd, featherstone, semi-implicit), found {name!r}")
