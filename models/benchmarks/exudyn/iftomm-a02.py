"""Exudyn model of iftomm-a02 (iftomm-a02.toml), written by `xcheck export --format exudyn`
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

mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [0.0, 0.5, 1.57079632679], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.5, 0.0, -1.0], 'name': 'crank1', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [1.0, 0.5, 1.57079632679], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.5, 0.0, -1.0], 'name': 'crank2', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [2.0, 0.5, 1.57079632679], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.5, 0.0, -1.0], 'name': 'crank3', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [0.5, 1.0, 0.0], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [1.0, 0.0, 0.0], 'name': 'coupler1', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [1.5, 1.0, 0.0], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [1.0, 0.0, 0.0], 'name': 'coupler2', 'Vshow': False})
mbs.AddObject({'objectType': 'Ground', 'referencePosition': [0.0, 0.0, 0.0], 'referenceRotation': [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], 'referenceHT': [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], 'name': 'object0', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 0.0833333333333, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 0, 'name': 'object1', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 0.0833333333333, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 1, 'name': 'object2', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 0.0833333333333, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 2, 'name': 'object3', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 0.0833333333333, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 3, 'name': 'object4', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 1.0, 'inertia': 0.0833333333333, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 4, 'name': 'object5', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [0, 1], 'activeConnector': True, 'name': 'object6', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [2, 3], 'activeConnector': True, 'name': 'object7', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [4, 5], 'activeConnector': True, 'name': 'object8', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [6, 7], 'activeConnector': True, 'name': 'object9', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [8, 9], 'activeConnector': True, 'name': 'object10', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [10, 11], 'activeConnector': True, 'name': 'object11', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [12, 13], 'activeConnector': True, 'name': 'object12', 'Vshow': False})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker0', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [-0.5, 0.0, 0.0], 'name': 'marker1', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [1.0, 0.0, 0.0], 'name': 'marker2', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [-0.5, 0.0, 0.0], 'name': 'marker3', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [2.0, 0.0, 0.0], 'name': 'marker4', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [-0.5, 0.0, 0.0], 'name': 'marker5', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker6', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 4, 'localPosition': [-0.5, 0.0, 0.0], 'name': 'marker7', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 4, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker8', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker9', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker10', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 5, 'localPosition': [-0.5, 0.0, 0.0], 'name': 'marker11', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 5, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker12', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [0.5, 0.0, 0.0], 'name': 'marker13', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker14', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker15', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker16', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 4, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker17', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 5, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker18', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 14, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load0', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 15, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load1', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 16, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load2', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 17, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load3', 'Vshow': True})
mbs.AddLoad({'loadType': 'ForceVector', 'markerNumber': 18, 'loadVector': [0.0, -9.81, 0.0], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load4', 'Vshow': True})


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
    for name in ['coupler1', 'coupler2', 'crank1', 'crank2', 'crank3']:
        node = mbs.GetNodeNumber(name)
        start = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates, exu.ConfigurationType.Reference)
        displaced = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates)
        print(name, *(f'{r + d:.12g}' for r, d in zip(start, displaced)))
