"""OpenSim as a kinematic oracle (mode ``opensim-kinematic``): at each input of the
sweep (:func:`xcheck.runner.sweep_inputs`), the model of :func:`.model.build` with
each driven coordinate prescribed by the quadratic in time that has the input's
value, rate and acceleration at t = 0, assembled by OpenSim's assembler
(``Model.assemble``, from the previous sample's coordinates), its speeds projected
onto the constraints by Simbody (``Manager.initialize``) and its accelerations
realised (``realizeAcceleration``). Positions, velocities and accelerations are
OpenSim's (``findStation{Location,Velocity,Acceleration}InGround``).

The loops are cut as ``PointOnLineConstraint`` s (the planar pin's two rows): with
a ``PointConstraint`` (three rows, the z row redundant) and a coordinate
prescribed, the assembler has more equations than free coordinates and leaves the
loops open (on the bundled four-bar by 0.08 to 0.18 m). The sweep starts at the
native assembly at the reference inputs and walks up, then down, each sample from
its neighbour's coordinates (``updateAssemblyConditions``: without it the
assembler's goals stay the build state's, and it lands on the other branch). The
drivers prescribe the motion, so masses and forces only weigh Simbody's
acceleration solve: a body without mass data gets 1 kg and m size^2 / 12, and
springs and loads are left out.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from xcheck.engines._contract import with_unit_mass
from xcheck.engines._frames import empty_states, loop_gap
from xcheck.kinematics import Kinematics
from xcheck.ladder import one_line
from xcheck.results import ModeResult, Trajectory, differences

from .dynamic import polynomial, record_state
from .model import build, opensim, opensim_tree

__all__ = ["MODE", "run_kinematic"]

MODE = "opensim-kinematic"
#: the body quantities of the oracle (:func:`xcheck.engines._frames.empty_states`)
QUANTITIES = ("position", "angle", "velocity", "omega", "acceleration", "alpha")
#: the widest a loop may stay open after assembly, of the mechanism's size
CLOSED = 1e-9


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
    tree = opensim_tree(mech, q_ref)
    signs = tree.driver_signs(mech)
    massive = dataclasses.replace(with_unit_mass(mech), springs=(), rotational_springs=(), loads=())
    ref = kinematics.reference_inputs()
    inputs, rates, accelerations = sweep_inputs(kinematics, samples, branch)
    n = len(inputs)
    bodies, points, _, _, gaps = empty_states(mech, n, QUANTITIES)
    for states in (*bodies.values(), *points.values()):  # accelerations are vectors too
        states["acceleration"] = np.full((n, 2), np.nan)
    first = int(np.argmin(np.abs(inputs[:, 0] - ref[0])))
    walks = (range(first, n), range(first - 1, -1, -1))
    widest = CLOSED * mech.size
    start_guess: dict[str, float] = {}
    try:
        for walk in walks:
            guess = dict(start_guess)
            for j in walk:
                functions = {
                    name: polynomial(
                        [sign * 0.5 * accelerations[j, k], sign * rates[j, k], sign * (inputs[j, k] - ref[k])]
                    )
                    for k, (name, sign) in enumerate(signs)
                }
                om = build(massive, q_ref, prescribed=functions, planar_cuts=True)
                model, state = om.model, om.state
                for name, value in guess.items():
                    if not om.coordinates[name].isPrescribed(state):
                        om.coordinates[name].setValue(state, value, False)
                state.setTime(0.0)
                model.updateAssemblyConditions(state)
                model.assemble(state)
                manager = om.started_manager("RungeKuttaMerson", fixed_step=1.0)  # its state lives in it
                state = manager.getState()
                model.realizeAcceleration(state)
                frames = om.frames(state)
                gaps[j] = loop_gap(frames, om.tree.cuts)
                if not gaps[j] <= widest:
                    where = ", ".join(f"{d.name} = {v:.6g}" for d, v in zip(mech.drivers, inputs[j]))
                    raise RuntimeError(f"OpenSim's assembler left a loop {gaps[j]:.3g} m open at {where}")
                record_state(om, mech, state, frames, (bodies, points), j)
                guess = {name: c.getValue(state) for name, c in om.coordinates.items()}
                if j == first:
                    start_guess = guess
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
            "t = 0; speeds projected by Simbody (Manager.initialize); accelerations realised. Loops cut as "
            f"PointOnLineConstraints. OpenSim {osim.__version__}."
        ),
    )
    return ModeResult(MODE, mech.name, True, "", [trajectory], differences(kinematics, trajectory, branch))
