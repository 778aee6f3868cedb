"""OpenSim as a kinematic oracle (mode ``opensim-kinematic``): at each input of the
sweep (:func:`xcheck.runner.sweep_inputs`), the model of :func:`.model.build` with
its drivers prescribed, assembled by OpenSim's assembler (``Model.assemble``, from the
previous sample's coordinates) and its speeds projected onto the constraints by
Simbody (``Manager.initialize``). One driver is prescribed by time itself (its value,
from the build state's, is the time; its rate 1), so that one model serves every
input: the assembly is made at the time of the input's value, and the projected speeds,
linear in the driver's rate, are multiplied by the input's rate. Several drivers are
each prescribed by the quadratic in time that has its input's value, rate and
acceleration at t = 0, the model initialised again at each input (OpenSim fixes a
prescribed function when it initialises the system). The accelerations are
realised (``realizeAcceleration``) on a second model whose drivers are free, each
pushed by a ``CoordinateActuator`` with the effort that gives the input's
acceleration: with the drivers prescribed, Simbody solves their constraint forces
with the round-off of their rates (a stated finding: on a crank-rocker of tonnes at
1 km the accelerations missed by 4.6e-8 of the largest). Positions, velocities and
accelerations are OpenSim's (``findStation{Location,Velocity,Acceleration}InGround``).

The loops are cut as ``PointOnLineConstraint`` s (the planar pin's two rows): with
a ``PointConstraint`` (three rows, the z row redundant) and a coordinate
prescribed, the assembler has more equations than free coordinates and leaves the
loops open (on the bundled four-bar by 0.08 to 0.18 m). The sweep starts at the
native assembly at the reference inputs and walks up, then down, each sample
assembled from its neighbour's coordinates (``updateAssemblyConditions``: without
it the assembler's goals stay the build state's, and it lands on the other
branch). Each assembly is judged by the continuation's rule
(:func:`xcheck.engines._continuation.step_refused`, against the tangent of
OpenSim's constraint Jacobian at the neighbour); where it is refused, the
assembler fails, or the inputs move by more than the continuation's longest step
(:data:`~xcheck.engines._continuation.MAX_STEP`: from 34 degrees away a
five-bar's assembler lands on its other branch), the sample is walked to by
xcheck's continuation with OpenSim's assembler as its Newton, at most
:data:`WALK_BUDGET` assemblies, each with the model's default values at its guess
(from a far default pose the assembler can move an assembled state to the other
branch: a stated finding); where the walk stops, the mode fails with its reason.
The drivers prescribe the motion, so masses and forces only weigh Simbody's
acceleration solve: a body without mass data gets 1 kg and m size^2 / 12, and
springs and loads are left out.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from xcheck.engines._continuation import MAX_STEP, follow, square_rows, square_sign, step_refused, tangent
from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import empty_states, loop_gap
from xcheck.kinematics import Kinematics
from xcheck.ladder import one_line
from xcheck.model import Mechanism
from xcheck.results import ModeResult, Trajectory, differences

from .dynamic import polynomial, record_state
from .model import OpenSimModel, build, opensim, opensim_tree

__all__ = ["MODE", "assembled_states", "run_kinematic"]

MODE = "opensim-kinematic"
#: the body quantities of the oracle (:func:`xcheck.engines._frames.empty_states`)
QUANTITIES = ("position", "angle", "velocity", "omega", "acceleration", "alpha")
#: the widest a loop may stay open after assembly, of the mechanism's size
CLOSED = 1e-9
#: a step this much longer than MAX_STEP (a fraction of it) is not walked in parts
_ROUND_OFF = 1e-9
#: the most assemblies the continuation may take from one sample to the next: where the
#: assembler fails systematically, accepting only ever smaller steps, the mode fails there
#: with the reason instead of creeping on
WALK_BUDGET = 100


def assembled_states(
    mech: Mechanism, q_ref: np.ndarray, ref: np.ndarray, states: tuple, walks: tuple, seeds=None
) -> Iterator:
    """OpenSim's states at given inputs, each assembled from its neighbour's coordinates.

    Parameters
    ----------
    mech : Mechanism
        With mass data on every moving body.
    q_ref : ndarray
        Native body coordinates where the model is built (every coordinate 0 there), the
        drivers at ``ref``.
    states : (inputs, rates, accelerations), each ndarray (N, k)
    walks : sequence of sequences of int
        The samples in the order they are assembled: each walk from the first walk's
        first sample's coordinates (the first from the build state's), each sample from
        the one before.
    seeds : callable, optional
        Sample -> the tree joints' coordinates there (name -> rad or m), where they are
        known (the native states of the inverse dynamics): a sample farther than
        :data:`~xcheck.engines._continuation.MAX_STEP` from the last assembly is assembled
        from them instead of walked to.

    Yields
    ------
    (j, OpenSimModel, state, frames, gap)
        The sample, the model whose drivers are pushed by their efforts (:func:`_realised_by_efforts`)
        and its state at the assembly, realised to acceleration (valid until the next),
        :meth:`~.model.OpenSimModel.frames` and the loops' largest opening there (m).

    Raises
    ------
    RuntimeError
        Where the assembler fails, leaves a loop open by more than :data:`CLOSED` of the
        size or leaves the branch, and xcheck's continuation cannot walk there.
    """
    signs = opensim_tree(mech, q_ref).driver_signs(mech)
    inputs, rates, accelerations = states
    scale = np.array([mech.size if d.quantity == "slide" else 1.0 for d in mech.drivers])
    start_guess: dict[str, float] = {}
    start = np.asarray(ref, dtype=float)
    om = None  # one model, its drivers prescribed anew at each assembly
    pushed = None  # one model, its drivers free and pushed by actuators, for the accelerations
    start_tangent: _Linearised | None = None
    for walk in walks:
        guess, last, tangent_at = dict(start_guess), start, start_tangent
        for step, j in enumerate(walk):
            # a step longer than MAX_STEP from the last assembly is walked by the continuation, as is
            # one whose assembly fails or leaves the branch; a crank's sweep of a turn in 180 samples
            # steps by MAX_STEP itself, give or take its round-off. Where the native states seed
            # each sample (the inverse dynamics), it is assembled from them.
            at = (inputs[j], rates[j], accelerations[j])
            parts = math.ceil(float(np.max(np.abs(inputs[j] - last) / scale)) / MAX_STEP - _ROUND_OFF)
            if seeds is not None:
                om, manager = _assembled(mech, q_ref, ref, signs, at, seeds(j) if parts > 1 else guess, om)
            else:
                why = "" if parts <= 1 else "was not tried over a step longer than the continuation's"
                if not why:
                    try:
                        om, manager = _assembled(mech, q_ref, ref, signs, at, guess, om)
                        why = _refused(om, manager.getState(), tangent_at, inputs[j], signs, mech.size)
                    except RuntimeError as error:  # the assembler failed: the continuation may still get there
                        why = f"failed ({one_line(error)})"
                if why:  # walked to by the continuation, then assembled from where it arrived
                    if om is None:
                        om = _assemble(mech, q_ref, ref, signs, (last, 0.0 * last, 0.0 * last), guess)
                    om, guess = _continued(om, mech, q_ref, ref, signs, guess, last, inputs[j], scale, why)
                    om, manager = _assembled(mech, q_ref, ref, signs, at, guess, om, defaults=True)
            assert om is not None  # assembled above
            state = manager.getState()  # the state lives in the manager
            if pushed is None:
                pushed = build(mech, q_ref, planar_cuts=True, actuated=tuple(name for name, _ in signs))
            pushed_state = _realised_by_efforts(
                pushed, om, state, signs, accelerations[j], _speed_scale(signs, rates[j])
            )
            frames = pushed.frames(pushed_state)
            gap = loop_gap(frames, pushed.tree.cuts)
            if not gap <= CLOSED * mech.size:
                where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(mech.drivers, inputs[j]))
                raise RuntimeError(f"OpenSim's assembler left a loop {gap:.3g} m open at {where}")
            if seeds is None:
                tangent_at = _linearised(om, state, signs, inputs[j], mech.size)
            yield j, pushed, pushed_state, frames, gap
            guess, last = {name: c.getValue(state) for name, c in om.coordinates.items()}, inputs[j]
            if walk is walks[0] and step == 0:
                start_guess, start, start_tangent = guess, last, tangent_at


def _assembled(
    mech: Mechanism,
    q_ref: np.ndarray,
    ref: np.ndarray,
    signs,
    at: tuple,
    guess: dict,
    om: OpenSimModel | None = None,
    defaults: bool = False,
) -> tuple[OpenSimModel, Any]:
    """:func:`_assemble`, its speeds projected: (model, the started manager that holds its state)."""
    om = _assemble(mech, q_ref, ref, signs, at, guess, om, defaults)
    return om, om.started_manager("RungeKuttaMerson", fixed_step=1.0, time=_clock(signs, at[0], ref))


def _assemble(
    mech: Mechanism,
    q_ref: np.ndarray,
    ref: np.ndarray,
    signs,
    at: tuple,
    guess: dict,
    om: OpenSimModel | None = None,
    defaults: bool = False,
) -> OpenSimModel:
    """The model of :func:`.model.build` with the drivers prescribed at ``at``
    (values, rates, accelerations at t = 0, each ndarray (k,)), its state assembled from
    the free coordinates' values ``guess`` (name -> value). ``om``: a model of an earlier
    call, prescribed anew (:meth:`.model.OpenSimModel.prescribe`) instead of built;
    ``defaults``: its coordinates' default values set to ``guess`` first (from an
    assembled state, OpenSim's assembler can land on another branch where the default
    pose is far: a stated finding)."""
    values, rates, accelerations = at
    if len(signs) == 1:  # one driver: prescribed by time itself, its value the time (_clock), its rate 1
        functions = {signs[0][0]: opensim().LinearFunction(1.0, 0.0)}
    else:  # value, rate and acceleration at t = 0, from the build state's value
        functions = {
            name: polynomial([sign * accelerations[k] / 2, sign * rates[k], sign * (values[k] - ref[k])])
            for k, (name, sign) in enumerate(signs)
        }
    built = om is None
    if om is None:
        om = build(mech, q_ref, prescribed=functions, planar_cuts=True)
    if defaults:
        for name, value in guess.items():
            om.coordinates[name].setDefaultValue(value)
    if defaults or (not built and len(signs) > 1):
        om.prescribe(functions)
    model, state = om.model, om.state
    for name, value in guess.items():
        if not om.coordinates[name].isPrescribed(state):
            om.coordinates[name].setValue(state, value, False)
    state.setTime(_clock(signs, values, ref))
    if len(signs) == 1:  # the assembly starts from the driver's value (a quadratic about t = 0 has it there
        # once the system is initialised; time itself has it at t = 0)
        om.coordinates[signs[0][0]].setValue(state, _clock(signs, values, ref), False)
    model.updateAssemblyConditions(state)
    model.assemble(state)
    return om


def _clock(signs, values: np.ndarray, ref: np.ndarray) -> float:
    """The time at which :func:`_assemble`'s model prescribes the drivers at ``values``
    (ndarray (k,); ``ref``: the build state's): with one driver, prescribed by time
    itself, its value from the build state's; with several, each by its own
    quadratic about t = 0."""
    return signs[0][1] * (float(values[0]) - float(ref[0])) if len(signs) == 1 else 0.0


def _speed_scale(signs, rates: np.ndarray) -> float:
    """What the speeds of :func:`_assemble`'s state, projected by Simbody with its
    drivers' rates, are multiplied by to be those at ``rates`` (ndarray (k,)): with one
    driver, prescribed at rate 1 (:func:`_clock`), its rate (the velocity constraints are
    linear in the speeds); with several, prescribed at ``rates``, 1."""
    return signs[0][1] * float(rates[0]) if len(signs) == 1 else 1.0


@dataclasses.dataclass(frozen=True)
class _Linearised:
    """An assembled state's coordinates and constraint Jacobian, for the next step's
    prediction and branch test (:mod:`xcheck.engines._continuation`).

    Attributes
    ----------
    q : ndarray (nv,)
        The tree joints' coordinates, in :attr:`.model.OpenSimModel.coordinates`' order.
    c : ndarray (k,)
        The inputs there.
    matrix : ndarray (loop rows + k, nv)
        OpenSim's position-constraint Jacobian (Simbody's ``calcPq``) over the inputs' rows.
    n_loop : int
    rows : ndarray of int
        The rows of the square system.
    scale : ndarray (nv,)
        Each coordinate's scale: 1 for an angle, 1 / size for a length.
    """

    q: np.ndarray
    c: np.ndarray
    matrix: np.ndarray
    n_loop: int
    rows: np.ndarray
    scale: np.ndarray


def _coordinates(om: OpenSimModel, state) -> np.ndarray:
    """The tree joints' coordinates at ``state`` (rad or m), in ``om.coordinates``' order."""
    return np.array([c.getValue(state) for c in om.coordinates.values()])


def _system_matrix(om: OpenSimModel, state, signs) -> np.ndarray:
    """OpenSim's loop constraints' position Jacobian at ``state`` (Simbody's ``calcPq``,
    its columns in ``om.coordinates``' order) over one row per input (its coordinate's
    change per the input's, the drivers' ``signs``). ``calcPq`` also has a row per
    prescribed coordinate, first (OpenSim prescribes by a constraint): the input rows replace them."""
    osim = opensim()
    om.model.realizePosition(state)
    pq = osim.Matrix()
    om.model.getMatterSubsystem().calcPq(state, pq)
    names = list(om.coordinates)
    columns = [c.getBodyIndex() - 1 for c in om.coordinates.values()]  # one q per body (revolute, slider)
    rows = np.array([[pq.get(i, j) for j in columns] for i in range(pq.nrow())]).reshape(pq.nrow(), len(names))
    inputs = np.zeros((len(signs), len(names)))
    for k, (name, sign) in enumerate(signs):
        inputs[k, names.index(name)] = sign
    # the prescribed coordinates' rows come first (joints are added before constraints), each a unit
    # row to round-off (1 + 2 ulp seen); a loop's row can be one too (a crank at a whole turn), so
    # they are found by place
    prescribed = np.abs(rows[: len(signs)])
    if not all(any(np.allclose(row, np.abs(unit), rtol=0.0, atol=1e-9) for row in prescribed) for unit in inputs):
        raise RuntimeError("expected calcPq's first rows to be the prescribed coordinates'")
    return np.vstack([rows[len(signs) :], inputs])


def _linearised(om: OpenSimModel, state, signs, c: np.ndarray, size: float) -> _Linearised:
    """The state's :class:`_Linearised` at inputs ``c`` (``size``: the mechanism's, m)."""
    matrix = _system_matrix(om, state, signs)
    n_loop = matrix.shape[0] - len(signs)
    q = _coordinates(om, state)
    return _Linearised(q, np.array(c, dtype=float), matrix, n_loop, square_rows(matrix), _scale(om, size))


def _scale(om: OpenSimModel, size: float) -> np.ndarray:
    """Each coordinate's scale, in ``om.coordinates``' order: 1 for an angle, 1 / ``size`` for a length."""
    rotational = opensim().Coordinate.Rotational
    return np.array([1.0 if c.getMotionType() == rotational else 1.0 / size for c in om.coordinates.values()])


def _gap(om: OpenSimModel, state) -> float:
    """The loops' largest opening at ``state`` (m)."""
    om.model.realizePosition(state)
    return loop_gap(om.frames(state), om.tree.cuts)


def _refused(om: OpenSimModel, state, last: _Linearised | None, c: np.ndarray, signs, size: float) -> str:
    """Why the assembly at ``state`` (inputs ``c``) is not one the continuation would
    accept from ``last`` ("" where it is; ``size``: the mechanism's, m): a loop left open
    wider than :data:`CLOSED` of the size, or by
    :func:`~xcheck.engines._continuation.step_refused` with ``last``'s tangent as the
    prediction (not where there is no ``last``: the walk's start)."""
    gap = _gap(om, state)
    if not gap <= CLOSED * size:
        return f"left a loop {gap:.3g} m open"
    if last is None:
        return ""
    guess = last.q + tangent(last.matrix, last.n_loop) @ (c - last.c)
    sign, new_sign = square_sign(last.matrix, last.rows), square_sign(_system_matrix(om, state, signs), last.rows)
    why = step_refused(last.q, guess, _coordinates(om, state), sign, new_sign, last.scale)
    return f"left the branch ({why})" if why else ""


def _continued(om, mech, q_ref, ref, signs, guess: dict, last: np.ndarray, target: np.ndarray, scale, why: str):
    """(model, coordinates name -> value) at inputs ``target``, walked from ``guess`` at
    inputs ``last`` by xcheck's continuation (:func:`~xcheck.engines._continuation.follow`)
    with OpenSim's assembler as its Newton and OpenSim's constraint Jacobian, at most
    :data:`WALK_BUDGET` assemblies; ``scale``: each input's (1 for an angle, the size for a slide).

    Raises
    ------
    RuntimeError
        Where the walk stops: what the assembler did at ``target`` (``why``) and why the walk stopped.
    """
    names = list(om.coordinates)

    def newton(q: np.ndarray, c: np.ndarray):
        nonlocal om
        try:
            om = _assemble(mech, q_ref, ref, signs, (c, 0.0 * c, 0.0 * c), dict(zip(names, q)), om, defaults=True)
        except RuntimeError:  # the assembler failed: a step the continuation halves
            return q, math.inf, 0, False
        gap = _gap(om, om.state)
        return _coordinates(om, om.state), gap, 0, bool(gap <= CLOSED * mech.size)

    def system_matrix(q: np.ndarray) -> np.ndarray:  # at the assembly newton has just made, q
        return _system_matrix(om, om.state, signs)

    n_loop = _system_matrix(om, om.state, signs).shape[0] - len(signs)
    q0 = np.array([guess.get(name, 0.0) for name in names])
    c0, targets = np.asarray(last, dtype=float), np.asarray(target, dtype=float)[None, :]
    coordinates = _scale(om, mech.size)
    walk = follow(newton, system_matrix, n_loop, q0, c0, targets, 1.0 / scale, coordinates, budget=WALK_BUDGET)
    if walk.stopped is not None:
        where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(mech.drivers, target))
        raise RuntimeError(f"OpenSim's assembler {why} at {where}; xcheck's continuation {walk.reason}")
    return om, dict(zip(names, walk.qpos[0]))


def _realised_by_efforts(
    pushed: OpenSimModel, assembled: OpenSimModel, state, signs, accelerations, speed_scale: float = 1.0
) -> object:
    """``pushed``'s state (its drivers free, an actuator on each) at the coordinates and
    speeds of ``assembled``'s ``state``, realised to acceleration with the actuators'
    efforts solved so that the driven coordinates accelerate as ``accelerations``
    (ndarray (k,), the drivers' sense; ``signs``: the drivers' (joint name, sign)).

    The accelerations are linear in the efforts: realised with none and with each
    effort at its coordinate's mass-matrix entry (a response of the size of the
    accelerations), the efforts are solved, then corrected once from the realised
    accelerations. Not with the drivers prescribed: Simbody solves a prescribed
    motion's constraint forces with the round-off of its rate (a finding).
    """
    osim = opensim()
    model, pushed_state = pushed.model, pushed.state
    for name, coordinate in assembled.coordinates.items():
        pushed.coordinates[name].setValue(pushed_state, coordinate.getValue(state), False)
        pushed.coordinates[name].setSpeedValue(pushed_state, coordinate.getSpeedValue(state) * speed_scale)
    driven = [pushed.coordinates[name] for name, _ in signs]
    target = np.array([sign * float(a) for (_, sign), a in zip(signs, accelerations)])

    def realised(efforts: np.ndarray) -> np.ndarray:
        for (name, _), effort in zip(signs, efforts):
            pushed.actuators[name].overrideActuation(pushed_state, True)
            pushed.actuators[name].setOverrideActuation(pushed_state, float(effort))
        model.realizeAcceleration(pushed_state)
        return np.array([c.getAccelerationValue(pushed_state) for c in driven])

    model.realizePosition(pushed_state)
    mass = osim.Matrix()
    model.getMatterSubsystem().calcM(pushed_state, mass)
    units = np.array([mass.get(i, i) for i in (c.getBodyIndex() - 1 for c in driven)])  # one mobility per body
    free = realised(np.zeros(len(driven)))
    response = np.column_stack(
        [(realised(np.where(np.arange(len(driven)) == k, unit, 0.0)) - free) / unit for k, unit in enumerate(units)]
    )
    efforts = np.linalg.solve(response, target - free)
    efforts += np.linalg.solve(response, target - realised(efforts))
    realised(efforts)
    return pushed_state


def run_kinematic(kinematics: Kinematics, samples: int = 361, branch: str | None = None) -> ModeResult:
    """OpenSim's assembler, speed projection and acceleration over the sweep.

    Parameters
    ----------
    kinematics : Kinematics
    samples : int
        Samples of the sweep of the first driver (:func:`xcheck.runner.sweep_inputs`).
    branch : str, optional
        Assembly branch (default: the model file's first).

    Returns
    -------
    ModeResult
        One trajectory over the sweep; ``summary`` is its
        :func:`~xcheck.results.differences` table. ``ok`` is False, with the
        reason, where the assembler fails or leaves a loop open.

    Raises
    ------
    NotApplicable
        What the OpenSim model cannot hold (:func:`.model.opensim_tree`).
    """
    from xcheck.runner import sweep_inputs

    osim = opensim()
    mech = kinematics.mechanism
    q_ref = kinematics.assemble(branch)
    ref = kinematics.reference_inputs()
    inputs, rates, accelerations = sweep_inputs(kinematics, samples, branch)
    n = len(inputs)
    bodies, points, _, _, gaps = empty_states(mech, n, QUANTITIES)
    first = int(np.argmin(np.abs(inputs[:, 0] - ref[0])))
    massive = dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=())
    try:
        for j, om, state, frames, gap in assembled_states(
            massive, q_ref, ref, (inputs, rates, accelerations), (range(first, n), range(first - 1, -1, -1))
        ):
            gaps[j] = gap
            record_state(om, mech, state, frames, (bodies, points), j)
    except RuntimeError as error:  # OpenSim's exceptions are RuntimeErrors: the mode failed, as data
        return ModeResult(MODE, mech.name, False, one_line(error))
    trajectory = Trajectory(
        source=MODE,
        inputs=inputs,
        input_rates=rates,
        input_accelerations=accelerations,
        bodies=bodies,
        points=points,
        settings={"samples": samples, "branch": branch or kinematics.branches[0], "cuts": "PointOnLineConstraint"},
        diagnostics={"constraint_violation": gaps},
        notes=(
            "OpenSim's assembler (Model.assemble, from the neighbouring sample's coordinates) with "
            + (
                "the driven coordinate prescribed by time itself, at the time of the input's value; speeds projected "
                "by Simbody (Manager.initialize) at its unit rate and multiplied by the input's rate"
                if len(mech.drivers) == 1
                else "the driven coordinates prescribed by quadratics in time with the inputs' values, rates and "
                "accelerations at t = 0; speeds projected by Simbody (Manager.initialize)"
            )
            + "; accelerations realised with the drivers free, each pushed by the effort that gives its input's "
            f"acceleration. Loops cut as PointOnLineConstraints. OpenSim {osim.__version__}."
        ),
    )
    return ModeResult(MODE, mech.name, True, "", [trajectory], differences(kinematics, trajectory, branch))
