"""Pinocchio adapter: every mechanism as a kinematic tree with loop constraints.

Modes
-----
``pinocchio-kinematic`` (:func:`run_kinematic`)
    Pinocchio as a kinematic oracle: Newton projection onto the loops from the
    previous sample, velocities from the constraint Jacobian with the inputs'
    rates imposed, accelerations from the drift (frame classical accelerations
    at zero joint acceleration). Exact to round-off when the model is right.
``pinocchio-dynamic`` (the series and one run of :mod:`.dynamic`)
    ``constraintDynamics`` with the inputs driven by a computed torque, integrated
    with RK4 and with semi-implicit Euler (with and without Baumgarte
    correction) at several time steps.
``pinocchio-free`` (the series and one run of :mod:`.free`)
    Free motion (no driver) with ``constraintDynamics`` from the native
    reference's initial state, at each integrator of the ladder.

Model files
-----------
:func:`export_files` writes the tree as URDF and the loop closures as JSON
(``models/urdf/NAME.urdf`` and ``NAME.loops.json``).

The model is built from the canonical mechanism in :mod:`.model`; see
there for the frame conventions.
"""

from __future__ import annotations

import numpy as np

from xcheck.errors import NotApplicable
from xcheck.kinematics import Kinematics
from xcheck.motion import law_states, sweep_span
from xcheck.results import ModeResult, Trajectory, differences

from .dynamic import dynamic_series, prepare_dynamic, run_dynamic_once  # noqa: F401 - "pinocchio-dynamic"
from .free import FREE_SERIES, prepare_free, run_free_once  # noqa: F401 - the mode "pinocchio-free"
from .inverse import inverse_forces
from .model import PinocchioMechanism, build_model, joint_coordinates, point_frame, tree_spec
from .oracle import NEWTON_TOLERANCE, Oracle, frame_states, one_line
from .urdf import export_texts

__all__ = [
    "run_kinematic",
    "dynamic_series",
    "prepare_dynamic",
    "run_dynamic_once",
    "FREE_SERIES",
    "prepare_free",
    "run_free_once",
    "export_files",
    "build",
    "sweep_inputs",
    "inverse_dynamics",
]

KINEMATIC = "pinocchio-kinematic"
#: Fraction of a bounded input's feasible range kept clear of each limit
#: position (there the mechanism is singular), as in the simulation window.
RANGE_MARGIN = 0.02


def build(kinematics: Kinematics) -> PinocchioMechanism:
    """The Pinocchio model of a mechanism, built through the API.

    Raises
    ------
    ModelError
        If the mechanism's joints have no spanning tree.
    """
    return build_model(tree_spec(kinematics.mechanism))


# -- kinematic oracle --------------------------------------------------------
class _NotConverged(RuntimeError):
    """A sample the continuation could not reach on the branch (the mode's reason)."""


def sweep_inputs(kinematics: Kinematics, samples: int, branch: str | None = None):
    """The inputs of the kinematic sweep: each driver in turn over its feasible
    range, the others held at their reference values.

    Each driver sweeps :func:`~xcheck.motion.sweep_span` with
    :data:`RANGE_MARGIN` (one turn of a crank, else the feasible range less
    the margin at each end, within the values its law reaches: a harmonic
    slide covers only centre +- amplitude). Rates and accelerations are the
    laws' (:func:`~xcheck.motion.law_states`, the rule of ``xcheck solve
    --at``); where a law never passes a value (a driver held at a reference
    value its law never reaches) they are zero, and the notes say so.

    Returns
    -------
    inputs, rates, accelerations : ndarray, shape (samples * k, k), SI
    starts : list of int
        Per driver, the index of the sample of its sweep nearest the
        reference inputs (where the projection starts).
    notes : list of str
    """
    mech = kinematics.mechanism
    ref = kinematics.reference_inputs()
    blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    starts, notes = [], []
    for i, driver in enumerate(mech.drivers):
        low, high = sweep_span(kinematics, i, branch, RANGE_MARGIN)
        values = np.linspace(low, high, samples)
        notes.append(
            f"{driver.name} from {low:.6g} to {high:.6g} (motion.sweep_span: one turn of a crank, else "
            f"the feasible range less {RANGE_MARGIN:.0%} at each limit, within what the law reaches)"
        )
        inputs = np.tile(ref, (samples, 1))
        inputs[:, i] = values
        rates, accelerations, reached = law_states(mech, inputs)
        for j, d in enumerate(mech.drivers):
            if not reached[:, j].all():
                notes.append(
                    f"{d.name}: its motion law does not pass some of the values used: rate and acceleration 0 there"
                )
        starts.append(len(blocks) * samples + int(np.argmin(np.abs(values - ref[i]))))
        blocks.append((inputs, rates, accelerations))
    stacked = tuple(np.concatenate([b[j] for b in blocks]) for j in range(3))
    return (*stacked, starts, notes)


def _empty_states(pm: PinocchioMechanism, n: int) -> tuple[dict, dict]:
    mech = pm.mechanism
    bodies = {
        b.name: {
            "position": np.full((n, 2), np.nan),
            "angle": np.full(n, np.nan),
            "velocity": np.full((n, 2), np.nan),
            "omega": np.full(n, np.nan),
            "acceleration": np.full((n, 2), np.nan),
            "alpha": np.full(n, np.nan),
        }
        for b in mech.moving_bodies
    }
    points = {
        label: {q: np.full((n, 2), np.nan) for q in ("position", "velocity", "acceleration")}
        for label in mech.point_owners
    }
    return bodies, points


def _store(pm: PinocchioMechanism, bodies: dict, points: dict, i: int, state: tuple[dict, dict]) -> None:
    body_state, point_state = state
    for name, values in body_state.items():
        for quantity, value in values.items():
            bodies[name][quantity][i] = value
    for label, owner in pm.mechanism.point_owners.items():
        for quantity, value in point_state[point_frame(owner, label)].items():
            points[label][quantity][i] = value


def run_kinematic(kinematics: Kinematics, samples: int = 361, branch: str | None = None) -> ModeResult:
    """Positions, velocities and accelerations from Pinocchio's own kinematics.

    Parameters
    ----------
    kinematics : Kinematics
    samples : int
        Samples per driver's sweep (see :func:`sweep_inputs`).
    branch : str, optional
        Assembly branch (default: the model's first).

    Returns
    -------
    ModeResult
        One trajectory; ``summary`` is its :func:`~xcheck.results.differences`
        table. ``ok`` is False, with the reason, when the model cannot be
        built or a sample does not converge.
    """
    name = kinematics.mechanism.name
    try:
        pm = build(kinematics)
        oracle = Oracle(pm)
        size = kinematics.system.size
        inputs, rates, accelerations, starts, sweep_notes = sweep_inputs(kinematics, samples, branch)
        n = inputs.shape[0]
        bodies, points = _empty_states(pm, n)
        residual = np.full(n, np.nan)
        iterations = np.zeros(n, dtype=int)
        c_ref = kinematics.reference_inputs()
        q_ref = joint_coordinates(pm, kinematics.assemble(branch))
        q_ref, _, _, ok = oracle.project(q_ref, c_ref, size)
        if not ok:
            return ModeResult(
                KINEMATIC,
                name,
                False,
                "the native assembled configuration does not close Pinocchio's loops (model conversion error)",
            )
        per_driver = n // len(starts)

        def walk(order: np.ndarray, q_prev: np.ndarray, c_prev: np.ndarray) -> np.ndarray:
            """Follow the branch from (q_prev, c_prev) through the samples ``order``; their first solution."""
            path = oracle.follow(q_prev, c_prev, inputs[order], size)
            if path.stopped is not None:
                raise _NotConverged(f"Pinocchio's continuation left the assembly branch: it {path.reason}")
            for j, i in enumerate(order):
                q, residual[i], iterations[i] = path.qpos[j], path.residual[j], path.iterations[j]
                v = oracle.rates(q, rates[i])
                a = oracle.acceleration(q, v, accelerations[i])
                _store(pm, bodies, points, i, frame_states(pm, oracle.data, q, v, a))
            return path.qpos[0]

        for d, start in enumerate(starts):
            q_start = walk(np.arange(start, (d + 1) * per_driver), q_ref, c_ref)
            if start > d * per_driver:
                walk(np.arange(start - 1, d * per_driver - 1, -1), q_start, inputs[start])
        trajectory = Trajectory(
            source=KINEMATIC,
            inputs=inputs,
            input_rates=rates,
            input_accelerations=accelerations,
            bodies=bodies,
            points=points,
            settings={
                "samples_per_driver": samples,
                "branch": kinematics._branch_name(branch),
                "newton_tolerance_m": NEWTON_TOLERANCE * size,
                "loops": len(pm.constraints),
                "nq": pm.model.nq,
            },
            diagnostics={"loop_residual": residual, "iterations": iterations},
            notes="Pinocchio forward kinematics; Newton projection onto the loops (getConstraintsJacobian of "
            "CONTACT_3D constraints, least squares) from the previous sample with a tangent prediction, in "
            "steps halved while the correction is large or the determinant of the system changes sign; "
            "velocities from the constraint Jacobian with the input rates imposed; accelerations with the "
            "drift from frame classical accelerations at zero joint acceleration. Sweep: " + "; ".join(sweep_notes),
        )
        summary = differences(kinematics, trajectory, branch)
        return ModeResult(KINEMATIC, name, True, "", [trajectory], summary)
    except NotApplicable:
        raise  # what Pinocchio cannot hold: the mode does not apply
    except Exception as error:  # noqa: BLE001 - a failed mode is data, reported in one line
        return ModeResult(KINEMATIC, name, False, one_line(error))


def export_files(kinematics: Kinematics) -> dict[str, str]:
    """The tree as URDF and the loop closures as JSON: {``NAME.urdf``: text,
    ``NAME.loops.json``: text} (see :mod:`.urdf` for the layout)."""
    spec = tree_spec(kinematics.mechanism)
    pm = build(kinematics)
    q = joint_coordinates(pm, kinematics.assemble())
    assembly = {}
    for js in spec.joints:
        j = pm.model.getJointId(js.name)
        assembly[js.name] = float(q[pm.model.idx_qs[j]])
    return export_texts(spec, assembly)


def inverse_dynamics(kinematics: Kinematics, branch: str | None = None, samples: int | None = None, solution=None):
    """Joint reactions and input efforts from Pinocchio (RNEA with the loop-cut
    forces, see :mod:`.inverse`) at the native states of the
    simulation window.

    Parameters
    ----------
    kinematics : Kinematics
    branch : str, optional
    samples : int, optional
        States over the window (default :data:`xcheck.dynamics.WINDOW_SAMPLES`).
    solution : Solution, optional
        Native states to use instead of the window's.

    Returns
    -------
    xcheck.dynamics.Forces

    Raises
    ------
    ModelError, ValueError
        If the model cannot be built or a state does not close Pinocchio's loops.
    """
    return inverse_forces(kinematics, branch, samples, solution)
