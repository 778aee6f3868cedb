"""OpenSim's model of a mechanism, shared by its modes: an ``osim.Model`` whose
bodies are xcheck's body frames, hung from their parents by ``PinJoint`` s
(about z) and ``SliderJoint`` s (along the joint frame's x) placed by
:func:`xcheck.engines._tree.tree_frames`, so that every coordinate's default
value, 0, is the state the model is built at (OpenSim's assembly at
``initSystem()`` starts from the defaults: elsewhere it fails by centimetres).
Each loop cut at a revolute is a ``PointConstraint`` between its two points
(Simbody's ball constraint: its z row is redundant and accepted), each gear pair
a ``CoordinateCouplerConstraint`` of its gears' revolutes' coordinates. Gravity is
the model's; a linear spring without damping is a ``PointToPointSpring``.

Each tree joint is converted by the converter of its type. Not converted
(:class:`~xcheck.engines.NotApplicable`): pin-in-slot joints and loops cut at a
prismatic joint (:func:`~xcheck.engines._tree.tree_frames`), dampers,
rotational springs and loads (not built here).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from xcheck.dynamics._forces import require_mass_data
from xcheck.engines._contract import NotApplicable, positive_inertia
from xcheck.engines._tree import TreeFrames, tree_frames
from xcheck.joints import Prismatic, Revolute, converter
from xcheck.model import GROUND, Mechanism

__all__ = ["OpenSimModel", "build", "opensim", "opensim_tree", "refuse"]

#: each tree joint type's OpenSim joint class (from the module): a turn about the frames' z, a slide along their x
_JOINTS: dict[type, Callable[[Any], Any]] = {
    Revolute: lambda osim: osim.PinJoint,
    Prismatic: lambda osim: osim.SliderJoint,
}
#: characters OpenSim refuses in a component's name (its component paths use them)
_NOT_IN_NAMES = re.compile(r"[\\*+\s/]")


def opensim():
    """The ``opensim`` module (imported when a mode runs), its log off: it writes on stdout,
    where the JSON of ``--json`` goes, and into ``opensim.log`` in the working folder (a
    user's), and what fails raises as well."""
    import opensim as osim

    osim.Logger.removeFileSink()
    osim.Logger.setLevel(osim.Logger.Level_Off)
    return osim


def refuse(mech: Mechanism) -> None:
    """:class:`NotApplicable` with the reason if xcheck's OpenSim model cannot hold the mechanism's forces."""
    if mech.loads:
        raise NotApplicable(f"load {mech.loads[0].name!r}: xcheck's OpenSim model applies gravity and springs only")
    if mech.rotational_springs:
        raise NotApplicable(
            f"rotational spring {mech.rotational_springs[0].name!r}: xcheck's OpenSim model has linear springs only"
        )
    damped = [s for s in mech.springs if s.damping]
    if damped:
        raise NotApplicable(
            f"spring {damped[0].name!r} has damping: OpenSim's PointToPointSpring has none (not built here)"
        )


def opensim_tree(mech: Mechanism, q: np.ndarray) -> TreeFrames:
    """The mechanism's tree as OpenSim's model holds it (:func:`~xcheck.engines._tree.tree_frames`,
    its gear pairs coupled), zeroed at native body coordinates ``q``."""
    return tree_frames(mech, q, "OpenSim", couplings=True)


def component_name(name: str, index: int) -> str:
    """An OpenSim component's name for xcheck's ``name`` (any text), the ``index``-th of its
    kind: OpenSim refuses spaces, slashes, ``*``, ``+`` and backslashes in names (and a
    refused component, once adopted, crashes the process), so these become ``_`` and
    the index keeps names that differ only there apart."""
    safe = _NOT_IN_NAMES.sub("_", name)
    return safe if safe == name else f"{safe}_{index}"


@dataclass
class OpenSimModel:
    """The mechanism in an initialised OpenSim model.

    Attributes
    ----------
    model : opensim.Model
    state : opensim.State
        The state ``initSystem()`` returned: the build state, assembled.
    tree : TreeFrames
        The joints' frames (zeroed at the build state) and the loop cuts.
    bodies : dict of str to opensim.Body
        Moving body -> OpenSim's body (its frame: xcheck's body frame).
    coordinates : dict of str to opensim.Coordinate
        Tree joint name -> its coordinate.
    actuators : dict of str to opensim.CoordinateActuator
        Tree joint name -> the actuator of its coordinate, where :func:`build` was asked for one.
    """

    model: Any
    state: Any
    tree: TreeFrames
    bodies: dict[str, Any]
    coordinates: dict[str, Any]
    actuators: dict[str, Any] = field(default_factory=dict)

    def prescribe(self, functions: dict[str, Any]) -> None:
        """Prescribe the coordinates of ``functions`` (tree joint name -> an OpenSim
        ``Function`` of time) by new functions and initialise the model again:
        :attr:`state` is its new build state. The same model as :func:`build` with
        these functions gives, its bodies, joints and constraints kept."""
        for name, function in functions.items():
            self.coordinates[name].setPrescribedFunction(function)
        self.state = self.model.initSystem()

    def started_manager(
        self, method: str, *, fixed_step: float | None = None, accuracy: float = 0.0, time: float = 0.0
    ):
        """An OpenSim ``Manager`` of this model integrating with ``method`` (the suffix of
        ``IntegratorMethod_``, e.g. "RungeKuttaMerson") at steps of ``fixed_step`` (s) or, without
        one, to ``accuracy``; it records, writes and analyses nothing, and starts from
        :attr:`state` at ``time`` (s)."""
        osim = opensim()
        manager = osim.Manager(self.model)
        manager.setIntegratorMethod(getattr(osim.Manager, f"IntegratorMethod_{method}"))
        if fixed_step is not None:
            manager.setIntegratorFixedStepSize(fixed_step)
        else:
            manager.setIntegratorAccuracy(accuracy)
        manager.setRecordStatesTrajectory(False)
        manager.setWriteToStorage(False)
        manager.setPerformAnalyses(False)
        self.state.setTime(time)
        manager.initialize(self.state)
        return manager

    def frames(self, state) -> dict[str, tuple]:
        """Per moving body: origin (2,) m and angle rad (continuous from the build state), at ``state``
        realised to position."""
        origins = {}
        for name, body in self.bodies.items():
            p = body.getPositionInGround(state)
            origins[name] = np.array([p.get(0), p.get(1)])
        values = {name: c.getValue(state) for name, c in self.coordinates.items()}
        return self.tree.frames(values, origins)


def build(
    mech: Mechanism,
    q: np.ndarray,
    qd: np.ndarray | None = None,
    prescribed: dict[str, Any] | None = None,
    planar_cuts: bool = False,
    actuated: tuple[str, ...] = (),
) -> OpenSimModel:
    """The mechanism as an OpenSim model assembled at native body coordinates ``q``
    (x, y, phi per moving body; m, rad), its coordinates' default speeds the rates of
    ``qd`` (zero without); ``prescribed``: tree joint name -> an OpenSim ``Function`` of
    time that prescribes its coordinate (0 at the build state). With ``planar_cuts``
    each loop cut is a ``PointOnLineConstraint`` (the point on the line along z through
    the other: the two rows of a planar pin, none redundant) instead of a ``PointConstraint``.
    Each tree joint of ``actuated`` gets a ``CoordinateActuator`` of its coordinate (optimal
    force 1: its actuation is the generalized force, N m or N), in :attr:`OpenSimModel.actuators`.

    Raises
    ------
    NotApplicable
        What the model cannot hold (:func:`refuse`, :func:`~xcheck.engines._tree.tree_frames`).
    ModelError
        If a moving body has no mass data.
    """
    osim = opensim()
    require_mass_data(mech)
    refuse(mech)
    tree = opensim_tree(mech, q)
    model = osim.Model()
    model.setName(component_name(mech.name, 0))
    gravity = np.asarray(mech.gravity, dtype=float)
    model.setGravity(osim.Vec3(float(gravity[0]), float(gravity[1]), 0.0))
    size = mech.size

    def vec3(xy, z: float = 0.0):
        return osim.Vec3(float(xy[0]), float(xy[1]), float(z))

    bodies: dict[str, Any] = {}
    for k, body in enumerate(mech.moving_bodies):
        assert body.mass is not None and body.inertia is not None
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        inertia = positive_inertia(float(body.mass), float(body.inertia), size)
        bodies[body.name] = osim.Body(
            component_name(body.name, k),
            float(body.mass),
            vec3(com),
            osim.Inertia(inertia, inertia, inertia, 0.0, 0.0, 0.0),
        )
        model.addBody(bodies[body.name])

    def frame(name: str):
        return model.getGround() if name == GROUND else bodies[name]

    coordinates: dict[str, Any] = {}
    actuators: dict[str, Any] = {}
    rates = tree.rates(mech, q, np.zeros_like(q) if qd is None else qd)
    for k, joint in enumerate(tree.joints):
        built = converter(_JOINTS, mech.joint(joint.name), "OpenSim")(osim)(
            component_name(joint.name, k),
            frame(joint.parent),
            vec3(joint.parent_point),
            osim.Vec3(0.0, 0.0, joint.parent_angle),
            frame(joint.child),
            vec3(joint.child_point),
            osim.Vec3(0.0, 0.0, joint.child_angle),
        )
        model.addJoint(built)
        coordinate = built.upd_coordinates(0)
        coordinate.setDefaultValue(0.0)
        coordinate.setDefaultSpeedValue(float(rates[joint.name]))
        coordinate.setRangeMin(-1e6)  # no joint limits: a coordinate turns freely
        coordinate.setRangeMax(1e6)
        if prescribed and joint.name in prescribed:
            coordinate.set_prescribed(True)
            coordinate.setPrescribedFunction(prescribed[joint.name])
        coordinates[joint.name] = coordinate
        if joint.name in actuated:
            actuator = osim.CoordinateActuator(coordinate.getName())
            actuator.setName(f"{coordinate.getName()}_actuator")
            actuator.setOptimalForce(1.0)
            model.addForce(actuator)
            actuators[joint.name] = actuator
    for k, (body_a, point_a, body_b, point_b) in enumerate(tree.cuts):
        if planar_cuts:
            along_z = osim.Vec3(0.0, 0.0, 1.0)
            constraint = osim.PointOnLineConstraint(frame(body_a), along_z, vec3(point_a), frame(body_b), vec3(point_b))
        else:
            constraint = osim.PointConstraint(frame(body_a), vec3(point_a), frame(body_b), vec3(point_b))
        constraint.setName(f"loop{k}")
        model.addConstraint(constraint)
    for coupling in tree.couplings:  # a gear pair: the dependent coordinate a linear function of the other
        coupler = osim.CoordinateCouplerConstraint()
        coupler.setName(component_name(coupling.name, len(tree.cuts)))
        independent = osim.ArrayStr()
        independent.append(coordinates[coupling.independent].getName())
        coupler.setIndependentCoordinateNames(independent)
        coupler.setDependentCoordinateName(coordinates[coupling.dependent].getName())
        coupler.setFunction(osim.LinearFunction(float(coupling.ratio), 0.0))
        model.addConstraint(coupler)
    owners = mech.point_owners
    for k, spring in enumerate(mech.springs):
        (a, pa), (b, pb) = ((owners[label], mech.body(owners[label]).points[label]) for label in spring.points)
        force = osim.PointToPointSpring(
            frame(a), vec3(pa), frame(b), vec3(pb), float(spring.stiffness), float(spring.rest_length)
        )
        force.setName(component_name(spring.name, k))
        model.addForce(force)
    state = model.initSystem()
    return OpenSimModel(model, state, tree, bodies, coordinates, actuators)
