"""Joint reactions and input efforts from a driven pymunk simulation.

The scene is built with every input driven by a constraint
(``build_scene(..., kinematic_inputs=False)``: a ``SimpleMotor`` per angle, a
slide servo per slide), so that every joint and every driver is a pymunk
constraint. After each step a constraint's ``impulse`` is the impulse it
applied during that step; divided by the time step it is the mean force (or
torque) over the step. pymunk reports the impulse's magnitude only
(``cpvlength`` of a pivot's 2-D impulse, the absolute value of a motor's or
gear's), so the reactions and efforts compare as magnitudes:

* revolute (``PivotJoint``): ``|reaction|``;
* prismatic: ``|reaction|`` = ``|normal|`` from the ``GrooveJoint`` (which
  keeps only the impulse normal to the groove) and ``|moment|`` from the
  ``GearJoint`` that locks the rotation (a pure couple, so the moment about
  the sliding point);
* pin-in-slot: ``|reaction|`` = ``|normal|`` from the ``GrooveJoint``;
* drivers: ``|effort|`` from the motor (N m) or the slide servo (N).

A sample at time t averages the impulses of the steps just before and after
t, and its input acceleration is the central difference of the realised
input rate over the same two steps: both centred at t. Errors fall with the
time step (pymunk integrates by semi-implicit Euler).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pymunk as pm

from xcheck.dynamics import Forces
from xcheck.joints import GearPair, LineJoint, Revolute, converter
from xcheck.kinematics import Kinematics
from xcheck.ladder import off_branch

from .scene import build_scene, native_window

__all__ = ["inverse_forces", "SAMPLES", "STEPS_PER_SAMPLE", "ITERATIONS"]

#: Sample times over the simulation window.
SAMPLES = 40
#: Time steps between two samples (time step = window / (SAMPLES * STEPS_PER_SAMPLE)).
STEPS_PER_SAMPLE = 100
#: Solver iterations: a SimpleMotor needs 50+ to hold its rate (engine notes); the
#: groove and pivot chains of two-loop models needed more than 200 (pymunk-dynamic).
ITERATIONS = 500


def _pin_sources(joint, made: list, scene) -> list[tuple]:
    """A pivot joint's impulse: the magnitude of the pin's reaction."""
    return [("|reaction|", made[0], 1.0)]


def _line_sources(joint, made: list, scene) -> list[tuple]:
    """A groove's impulse: the normal force (the whole reaction); a prismatic lock's: the couple."""
    groove = next(c for c in made if isinstance(c, pm.GrooveJoint))
    found: list[tuple] = [("|reaction|", groove, 1.0), ("|normal|", groove, 1.0)]
    if joint.locked_angle is not None:
        found.append(("|moment|", next(c for c in made if isinstance(c, pm.GearJoint)), 1.0))
    return found


def _gear_sources(gear: GearPair, made: list, scene) -> list[tuple]:
    """A gear joint's impulse is a torque on its second body, whose coefficient in the
    gear pair's row is k_j: the tooth force is that torque over |k_j| (and so is the
    reaction, that force as a vector)."""
    second = next(name for name, body in scene.bodies.items() if body is made[0].b)
    k_j = dict(zip(gear.bodies, gear.coefficients()))[second]
    return [("|tooth_force|", made[0], 1.0 / abs(k_j)), ("|reaction|", made[0], 1.0 / abs(k_j))]


#: a joint's constraints' impulses as its reactions, by its type
_SOURCES: dict[type, Callable] = {Revolute: _pin_sources, LineJoint: _line_sources, GearPair: _gear_sources}


def inverse_forces(
    kinematics: Kinematics,
    branch: str | None = None,
    samples: int = SAMPLES,
    steps_per_sample: int = STEPS_PER_SAMPLE,
    iterations: int = ITERATIONS,
    error_bias: float | None = 0.0,
) -> Forces:
    """Simulate the mechanism with every input driven by a constraint and read
    the constraints' impulses (see the module notes).

    Parameters
    ----------
    kinematics : Kinematics
    branch : str, optional
    samples : int
        Sample times after t = 0 over the simulation window.
    steps_per_sample : int
        Time steps between samples.
    iterations : int
        The space's solver iterations.
    error_bias : float or None
        Every joint constraint's ``error_bias`` (0: full correction each step;
        None: pymunk's default).

    Returns
    -------
    xcheck.dynamics.Forces
        Magnitudes (``|reaction|``, ``|normal|``, ``|moment|``, ``|effort|``),
        the states as pymunk realised them, ``times``, and
        ``diagnostics["joint_gap"]`` (m), the largest joint separation.

    Raises
    ------
    ValueError
        If the native solution does not cover the window, or the scene comes
        apart or goes non-finite.
    """
    mech = kinematics.mechanism
    window, native = native_window(kinematics, branch)
    scene = build_scene(kinematics, native, iterations=iterations, error_bias=error_bias, kinematic_inputs=False)
    dt = window.duration / (samples * steps_per_sample)
    sample_steps = steps_per_sample * np.arange(1, samples + 1)
    # a sample's step n: rates at n - 1 and n + 1, impulses of steps n and n + 1
    wanted = {int(n + offset) for n in sample_steps for offset in (-1, 0, 1)}
    k = len(mech.drivers)
    recorded: dict[int, tuple] = {}
    sources = []  # (kind, name, quantity, constraint, force per impulse per second)
    for joint in mech.joints:
        made = scene.constraints[joint.name]
        found = converter(_SOURCES, joint, "pymunk")(joint, made, scene)
        sources += [("joint", joint.name, *source) for source in found]
    for driver in mech.drivers:
        sources.append(("driver", driver.name, "|effort|", scene.constraints[f"driver:{driver.name}"][0], 1.0))
    gap_bound = 0.05 * mech.size
    ground = mech.ground.name
    owners = [(body, label) for label, body in mech.point_owners.items() if body != ground]
    for n in range(1, int(sample_steps[-1]) + 2):
        scene.step((n - 1) * dt, dt)
        if n not in wanted:
            continue
        q, qd = scene.inputs()
        impulses = np.array([c.impulse * per for *_, c, per in sources])
        gap, _ = scene.joint_gaps()
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd)) and np.all(np.isfinite(impulses))):
            raise ValueError(f"the pymunk scene went non-finite at t = {n * dt:.6g} s")
        if gap > gap_bound:
            skew = scene.skewed_grooves()
            raise ValueError(
                f"the pymunk scene came apart at t = {n * dt:.6g} s: joints {gap:.3g} m apart "
                f"(bound {gap_bound:.3g} m)" + (f" ({skew})" if skew else "")
            )
        recorded[n] = (q, qd, impulses, gap, [scene.world_point(body, label) for body, label in owners])
    inputs = np.array([recorded[int(n)][0] for n in sample_steps]).reshape(samples, k)
    rates = np.array([recorded[int(n)][1] for n in sample_steps]).reshape(samples, k)
    accelerations = np.array(
        [(recorded[int(n) + 1][1] - recorded[int(n) - 1][1]) / (2.0 * dt) for n in sample_steps]
    ).reshape(samples, k)
    forces = np.array([(recorded[int(n)][2] + recorded[int(n) + 1][2]) / (2.0 * dt) for n in sample_steps])
    gaps = np.array([recorded[int(n)][3] for n in sample_steps])
    points = {label: np.array([recorded[int(n)][4][i] for n in sample_steps]) for i, (_, label) in enumerate(owners)}
    left = off_branch(kinematics, kinematics.solve(inputs, rates, branch=branch), points, sample_steps * dt)
    if left:  # its forces would be the other branch's, not an error in them
        raise ValueError(f"the pymunk scene {left}")
    joints: dict = {j.name: {} for j in mech.joints}
    drivers: dict = {d.name: {} for d in mech.drivers}
    for column, (kind, name, quantity, *_) in enumerate(sources):
        (joints if kind == "joint" else drivers)[name][quantity] = forces[:, column]
    return Forces(
        "pymunk",
        inputs,
        rates,
        accelerations,
        joints,
        drivers,
        times=sample_steps * dt,
        settings={
            "engine": f"pymunk {pm.version} (Chipmunk {pm.chipmunk_version})",
            "time_step": dt,
            "steps_per_sample": steps_per_sample,
            "iterations": iterations,
            "error_bias": "pymunk default" if error_bias is None else error_bias,
            "drives": ", ".join(f"{mech.drivers[d.driver_index].name}: {d.kind}" for d in scene.drives),
        },
        diagnostics={"joint_gap": gaps},
        notes=(
            "pymunk simulation with every input driven by a constraint (motor or slide servo), "
            f"time step {dt:.4g} s, {iterations} iterations. Forces are constraint impulses / time step, "
            "averaged over the steps either side of each sample; pymunk gives magnitudes only. Input "
            "accelerations: central differences of the realised input rates over the same steps."
        ),
    )
