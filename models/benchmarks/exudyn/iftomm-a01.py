"""Exudyn model of iftomm-a01 (iftomm-a01.toml), written by `xcheck export --format exudyn`
(xcheck 0.3.0); regenerate it rather than edit it.

The system xcheck's mode exudyn-free integrates: 2-D rigid bodies with their nodes at the
centres of mass, at the release state of [free_motion]; joints as index-3 constraints;
gravity as a force at each centre of mass; springs, torques and loads as in the file.
Run it to integrate 10 s at a step of 0.001 s with Exudyn's gen-alpha rho 0.9, index 3
(xcheck's `default` setting) and print each body's final node coordinates (x, y of the
centre of mass in m, angle in rad).
"""

import math  # noqa: F401 - used by the load laws, when there are some

import exudyn as exu

SC = exu.SystemContainer()
mbs = SC.AddSystem()

mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-1.0, 0.0, 3.14159265359], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'link', 'Vshow': False})
mbs.AddObject({'objectType': 'Ground', 'referencePosition': [0.0, 0.0, 0.0], 'referenceRotation': [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], 'referenceHT': [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], 'name': 'object0', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 1e-12, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 0, 'name': 'object1', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [0, 1], 'activeConnector': True, 'name': 'object2', 'Vshow': False})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker0', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [-1.0, 0.0, 0.0], 'name': 'marker1', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker2', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 2, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load0', 'Vshow': True})


if __name__ == "__main__":
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = 10000
    settings.timeIntegration.endTime = 10.0
    settings.timeIntegration.verboseMode = 0
    settings.timeIntegration.adaptiveStep = False
    settings.timeIntegration.generalizedAlpha.spectralRadius = 0.9
    settings.solution.file.write = False
    mbs.SolveDynamic(settings)
    for name in ['link']:
        node = mbs.GetNodeNumber(name)
        start = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates, exu.ConfigurationType.Reference)
        displaced = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates)
        print(name, *(f'{r + d:.12g}' for r, d in zip(start, displaced)))
