"""OpenSim as a kinematic oracle (mode ``opensim-kinematic``): at each input of the
sweep (:func:`xcheck.runner.sweep_inputs`), the model of :func:`.model.build` with
each driven coordinate prescribed by the quadratic in time that has the input's
value, rate and acceleration at t = 0, assembled by OpenSim's assembler
(``Model.assemble``, from the previous sample's coordinates) and its speeds projected
onto the constraints by Simbody (``Manager.initialize``). The accelerations are
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
native assembly at the reference inputs and walks up, then down, each sample from
its neighbour's coordinates (``updateAssemblyConditions``: without it the
assembler's goals stay the build state's, and it lands on the other branch),
through intermediate assemblies where the inputs move by more than the
continuation's longest step (:data:`xcheck.engines._continuation.MAX_STEP`):
from 34 degrees away a five-bar's assembler lands on its other branch. The
drivers prescribe the motion, so masses and forces only weigh Simbody's
acceleration solve: a body without mass data gets 1 kg and m size^2 / 12, and
springs and loads are left out.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

from xcheck.engines._continuation import MAX_STEP
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
        Where the assembler fails, or leaves a loop open by more than :data:`CLOSED` of the size.
    """
    signs = opensim_tree(mech, q_ref).driver_signs(mech)
    inputs, rates, accelerations = states
    scale = np.array([mech.size if d.quantity == "slide" else 1.0 for d in mech.drivers])
    start_guess: dict[str, float] = {}
    start = np.asarray(ref, dtype=float)
    om = None  # one model, its drivers prescribed anew at each assembly
    pushed = None  # one model, its drivers free and pushed by actuators, for the accelerations
    for walk in walks:
        guess, last = dict(start_guess), start
        for step, j in enumerate(walk):
            # a longer step than MAX_STEP from the last assembly: walked in steps, each from the one before;
            # a crank's sweep of a turn in 180 samples steps by MAX_STEP itself, give or take its round-off
            parts = math.ceil(float(np.max(np.abs(inputs[j] - last) / scale)) / MAX_STEP - _ROUND_OFF)
            if seeds is not None and parts > 1:
                guess, parts = seeds(j), 1
            for fraction in np.arange(1, parts) / parts:
                between = last + fraction * (inputs[j] - last)
                om, manager = _assembled(mech, q_ref, ref, signs, (between, 0 * between, 0 * between), guess, om)
                guess = {name: c.getValue(manager.getState()) for name, c in om.coordinates.items()}
            om, manager = _assembled(mech, q_ref, ref, signs, (inputs[j], rates[j], accelerations[j]), guess, om)
            state = manager.getState()  # the state lives in the manager
            if pushed is None:
                pushed = build(mech, q_ref, planar_cuts=True, actuated=tuple(name for name, _ in signs))
            pushed_state = _realised_by_efforts(pushed, om, state, signs, accelerations[j])
            frames = pushed.frames(pushed_state)
            gap = loop_gap(frames, pushed.tree.cuts)
            if not gap <= CLOSED * mech.size:
                where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(mech.drivers, inputs[j]))
                raise RuntimeError(f"OpenSim's assembler left a loop {gap:.3g} m open at {where}")
            yield j, pushed, pushed_state, frames, gap
            guess, last = {name: c.getValue(state) for name, c in om.coordinates.items()}, inputs[j]
            if walk is walks[0] and step == 0:
                start_guess, start = guess, last


def _assembled(mech: Mechanism, q_ref: np.ndarray, ref: np.ndarray, signs, at: tuple, guess: dict, om=None):
    """The model of :func:`.model.build` with the drivers prescribed at ``at``
    (values, rates, accelerations at t = 0, each ndarray (k,)), assembled from the
    free coordinates' values ``guess`` (name -> value), speeds projected; returns
    (model, the started manager that holds its state). ``om``: a model of an earlier
    call, prescribed anew (:meth:`.model.OpenSimModel.prescribe`) instead of built."""
    values, rates, accelerations = at
    functions = {  # value, rate and acceleration at t = 0, from the build state's value
        name: polynomial([sign * accelerations[k] / 2, sign * rates[k], sign * (values[k] - ref[k])])
        for k, (name, sign) in enumerate(signs)
    }
    if om is None:
        om = build(mech, q_ref, prescribed=functions, planar_cuts=True)
    else:
        om.prescribe(functions)
    model, state = om.model, om.state
    for name, value in guess.items():
        if not om.coordinates[name].isPrescribed(state):
            om.coordinates[name].setValue(state, value, False)
    state.setTime(0.0)
    model.updateAssemblyConditions(state)
    model.assemble(state)
    return om, om.started_manager("RungeKuttaMerson", fixed_step=1.0)


def _realised_by_efforts(pushed: OpenSimModel, assembled: OpenSimModel, state, signs, accelerations) -> object:
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
        pushed.coordinates[name].setSpeedValue(pushed_state, coordinate.getSpeedValue(state))
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
            "OpenSim's assembler (Model.assemble, from the neighbouring sample's coordinates) with the driven "
            "coordinates prescribed by quadratics in time with the inputs' values, rates and accelerations at "
            "t = 0; speeds projected by Simbody (Manager.initialize); accelerations realised with the drivers "
            "free, each pushed by the effort that gives its input's acceleration. Loops cut as "
            f"PointOnLineConstraints. OpenSim {osim.__version__}."
        ),
    )
    return ModeResult(MODE, mech.name, True, "", [trajectory], differences(kinematics, trajectory, branch))
