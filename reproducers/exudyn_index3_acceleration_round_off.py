"""Exudyn: index-3 generalized-alpha accelerations grow as the time step falls.

A wheel (0.3 kg, 1.35e-4 kg m^2) turns about a fixed centre: its node's x and y
held by ``CoordinateConstraint``s, its angle driven by an
``ObjectConnectorCoordinate`` whose offset user function is
phi(t) = 2 t + 1.5 t^2 rad (and its derivative 2 + 3 t). Its angular
acceleration is exactly 3 rad/s^2 at every instant, whatever the load; a brake
torque of -0.5 N m acts on it. Integrated by the implicit generalized-alpha
solver (index-3 constraints, spectral radius 0.9, Newton tolerance 1e-10,
fixed steps, 0.5 s) the node's angle holds the law to the last bit, yet its
``Coordinates_tt`` over the second half of the run miss 3 rad/s^2 by an error
that grows as the step falls, about the step squared to the power -1: Newton
solves for the accelerations, and the angle's round-off, eps |phi| (one unit
in its last place), reaches them over beta h^2, summed over past steps by the
method's damping of a constrained coordinate (a double root -rho_inf), some
500 times that unit at rho_inf 0.9.

What a step h should give: at most the round-off of an angle exact to its
last place differentiated twice over the step, eps |phi| / h^2 (the noise
floor of positions exact to round-off), and a smaller error as h falls.
Measured with Exudyn 1.13.6: 8.2e-7, 2.7e-6, 1.5e-5, 7.1e-5 rad/s^2 at
h = 4e-4, 2e-4, 1e-4, 5e-5 s (360 to 580 times eps |phi| / h^2), unchanged by
Newton's tolerance (1e-8 or 1e-13: the driven angle is linear in the node
coordinate, Newton converges in one step), 15 times larger when the angle
coordinate starts at 16 rad instead of 0 (its round-off), 10 and 75 times
smaller at rho_inf 0.6 and 0 (still 6.7 times the bound at 0).

Run: ``python exudyn_index3_acceleration_round_off.py``. Prints the measured
errors beside the expected bound; exits 0 while the defect shows (the error at
the finest step over 100 times the bound and growing as the step falls), 1 once
it no longer does.
"""

import sys

import exudyn as exu
import exudyn.itemInterface as ei
import numpy as np

STEPS = (4e-4, 2e-4, 1e-4, 5e-5)
ALPHA = 3.0  # rad/s^2, exact


def run(h: float, start: float = 0.0, rho: float = 0.9, tolerance: float = 1e-10, end: float = 0.5):
    """(the largest |alpha - 3| over the second half of the run, rad/s^2; the largest |phi| there, rad)."""
    container = exu.SystemContainer()
    mbs = container.AddSystem()
    fixed = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=mbs.AddNode(ei.NodePointGround()), coordinate=0))
    node = mbs.AddNode(
        ei.NodeRigidBody2D(
            referenceCoordinates=[0.0, 0.0, 0.0],
            initialCoordinates=[0.0, 0.0, start],
            initialVelocities=[0.0, 0.0, 2.0],
        )
    )
    mbs.AddObject(ei.ObjectRigidBody2D(nodeNumber=node, mass=0.3, inertia=1.35e-4))
    x, y, phi = (mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=node, coordinate=k)) for k in range(3))
    mbs.AddObject(ei.CoordinateConstraint(markerNumbers=[fixed, x]))
    mbs.AddObject(ei.CoordinateConstraint(markerNumbers=[fixed, y]))
    mbs.AddObject(
        ei.ObjectConnectorCoordinate(
            markerNumbers=[fixed, phi],
            offsetUserFunction=lambda mbs, t, item, value: start + 2.0 * t + 0.5 * ALPHA * t * t,
            offsetUserFunction_t=lambda mbs, t, item, value: 2.0 + ALPHA * t,
        )
    )
    mbs.AddLoad(
        ei.LoadTorqueVector(markerNumber=mbs.AddMarker(ei.MarkerNodeRigid(nodeNumber=node)), loadVector=[0, 0, -0.5])
    )
    kinds = (exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_tt)
    sensors = [mbs.AddSensor(ei.SensorNode(nodeNumber=node, storeInternal=True, outputVariableType=k)) for k in kinds]
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = int(round(end / h))
    settings.timeIntegration.endTime = end
    settings.timeIntegration.verboseMode = 0
    settings.timeIntegration.adaptiveStep = False
    settings.timeIntegration.generalizedAlpha.spectralRadius = rho
    settings.timeIntegration.newton.relativeTolerance = tolerance
    settings.timeIntegration.newton.absoluteTolerance = tolerance
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = h
    settings.linearSolver.solverType = exu.LinearSolverType.EigenDense
    exu.config.printToConsole = False
    mbs.SolveDynamic(settings)
    angles, accelerations = (mbs.GetSensorStoredData(s) for s in sensors)
    late = angles[:, 0] >= 0.5 * end
    return float(np.max(np.abs(accelerations[late, 3] - ALPHA))), float(np.max(np.abs(angles[late, 3])))


def main() -> int:
    eps = float(np.finfo(float).eps)
    print(f"Exudyn {exu.config.Version()}: driven wheel, phi = 2 t + 1.5 t^2, alpha exactly {ALPHA} rad/s^2")
    print("gen-alpha rho_inf 0.9, index 3, Newton tolerance 1e-10, second half of 0.5 s")
    errors, bounds = [], []
    for h in STEPS:
        error, extent = run(h)
        bound = eps * extent / h**2
        errors.append(error)
        bounds.append(bound)
        print(f"h = {h:g} s: measured |alpha - 3| {error:.3g} rad/s^2, expected at most eps |phi| / h^2 = {bound:.3g}")
    for tolerance in (1e-8, 1e-13):
        print(f"h = 1e-4 s, Newton tolerance {tolerance:g}: measured {run(1e-4, tolerance=tolerance)[0]:.3g} rad/s^2")
    error, extent = run(1e-4, start=16.0)
    print(f"h = 1e-4 s, angle from 16 rad: measured {error:.3g} rad/s^2, expected at most {eps * extent / 1e-8:.3g}")
    for rho in (0.6, 0.0):
        print(f"h = 1e-4 s, rho_inf {rho:g}: measured {run(1e-4, rho=rho)[0]:.3g} rad/s^2")
    shown = errors[-1] > 100.0 * bounds[-1] and errors[-1] > 4.0 * errors[0]
    print("defect shown" if shown else "defect not shown: the accelerations stay within round-off")
    return 0 if shown else 1


if __name__ == "__main__":
    sys.exit(main())
