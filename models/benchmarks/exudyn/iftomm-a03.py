"""Exudyn model of iftomm-a03 (iftomm-a03.toml), written by `xcheck export --format exudyn`
(xcheck 0.3.0); regenerate it rather than edit it.

The system xcheck's mode exudyn-free integrates: 2-D rigid bodies with their nodes at the
centres of mass, at the release state of [free_motion]; joints as index-3 constraints;
gravity as a force at each centre of mass; springs, torques and loads as in the file.
Run it to integrate 0.03 s at a step of 1e-05 s with Exudyn's gen-alpha rho 0.9, index 3
(xcheck's `default` setting) and print each body's final node coordinates (x, y of the
centre of mass in m, angle in rad).
"""

import math  # noqa: F401 - used by the load laws, when there are some

import exudyn as exu

SC = exu.SystemContainer()
mbs = SC.AddSystem()

mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [0.0009182486, -5.674075e-05, -0.06171389001], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'crank', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.00449143336, 0.00027753626, -0.06171389001], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'rod', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.01874218667, 0.02048510679, 0.45527981916], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'body3', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.03022293983, 0.01207118236, 0.71003336971], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'body4', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.05323682816, 0.01663184797, 0.48736497954], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'body5', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.02854326854, -0.01072225471, 1.00787905438], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'body6', 'Vshow': False})
mbs.AddNode({'nodeType': 'RigidBody2D', 'referenceCoordinates': [-0.0592624028, -0.01060069833, 1.23054744455], 'initialCoordinates': [0.0, 0.0, 0.0], 'initialVelocities': [0.0, 0.0, 0.0], 'name': 'body7', 'Vshow': False})
mbs.AddObject({'objectType': 'Ground', 'referencePosition': [0.0, 0.0, 0.0], 'referenceRotation': [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], 'referenceHT': [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], 'name': 'object0', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.04325, 'inertia': 2.194e-06, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 0, 'name': 'object1', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.00365, 'inertia': 4.41e-07, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 1, 'name': 'object2', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.02373, 'inertia': 5.255e-06, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 2, 'name': 'object3', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.00706, 'inertia': 5.667e-07, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 3, 'name': 'object4', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.0705, 'inertia': 1.169e-05, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 4, 'name': 'object5', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.00706, 'inertia': 5.667e-07, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 5, 'name': 'object6', 'Vshow': False})
mbs.AddObject({'objectType': 'RigidBody2D', 'mass': 0.05498, 'inertia': 1.912e-05, 'centerOfMass': [0.0, 0.0], 'nodeNumber': 6, 'name': 'object7', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [0, 1], 'activeConnector': True, 'name': 'object8', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [2, 3], 'activeConnector': True, 'name': 'object9', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [4, 5], 'activeConnector': True, 'name': 'object10', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [6, 7], 'activeConnector': True, 'name': 'object11', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [8, 9], 'activeConnector': True, 'name': 'object12', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [10, 11], 'activeConnector': True, 'name': 'object13', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [12, 13], 'activeConnector': True, 'name': 'object14', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [14, 15], 'activeConnector': True, 'name': 'object15', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [16, 17], 'activeConnector': True, 'name': 'object16', 'Vshow': False})
mbs.AddObject({'objectType': 'JointRevolute2D', 'markerNumbers': [18, 19], 'activeConnector': True, 'name': 'object17', 'Vshow': False})
mbs.AddObject({'objectType': 'ConnectorSpringDamper', 'markerNumbers': [21, 22], 'referenceLength': 0.07785, 'stiffness': 4530.0, 'damping': 0.0, 'force': 0.0, 'velocityOffset': 0.0, 'activeConnector': True, 'springForceUserFunction': 0, 'name': 'object18', 'Vshow': False})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [0.0, 0.0, 0.0], 'name': 'marker0', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [-0.00092, 0.0, 0.0], 'name': 'marker1', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 1, 'localPosition': [0.00608, 0.0, 0.0], 'name': 'marker2', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [0.0115, 0.0, 0.0], 'name': 'marker3', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [-0.0165, 0.0, 0.0], 'name': 'marker4', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [-0.01043, -0.01626, 0.0], 'name': 'marker5', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [-0.03635, 0.03273, 0.0], 'name': 'marker6', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [-0.01043, 0.01874, 0.0], 'name': 'marker7', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [-0.06934, -0.00227, 0.0], 'name': 'marker8', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 5, 'localPosition': [-0.02308, -0.00916, 0.0], 'name': 'marker9', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 5, 'localPosition': [0.01692, -0.00916, 0.0], 'name': 'marker10', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 4, 'localPosition': [0.0, 0.00579, 0.0], 'name': 'marker11', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [-0.0165, 0.0, 0.0], 'name': 'marker12', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 4, 'localPosition': [0.0, -0.01421, 0.0], 'name': 'marker13', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [-0.06934, -0.00227, 0.0], 'name': 'marker14', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 7, 'localPosition': [0.00449, 0.01228, 0.0], 'name': 'marker15', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 7, 'localPosition': [0.00449, -0.02772, 0.0], 'name': 'marker16', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 6, 'localPosition': [-0.00579, 0.0, 0.0], 'name': 'marker17', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 2, 'localPosition': [-0.0165, 0.0, 0.0], 'name': 'marker18', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 6, 'localPosition': [0.01421, 0.0, 0.0], 'name': 'marker19', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyRigid', 'bodyNumber': 1, 'localPosition': [-0.00092, 0.0, 0.0], 'localHT': [[1.0, 0.0, 0.0, -0.00092], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], 'name': 'marker20', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 3, 'localPosition': [0.00957, 0.00074, 0.0], 'name': 'marker21', 'Vshow': True})
mbs.AddMarker({'markerType': 'BodyPosition', 'bodyNumber': 0, 'localPosition': [0.014, 0.072, 0.0], 'name': 'marker22', 'Vshow': True})
mbs.AddLoad({'loadType': 'TorqueVector', 'markerNumber': 20, 'loadVector': [0.0, 0.0, 0.033], 'bodyFixed': False, 'loadVectorUserFunction': 0, 'name': 'load0', 'Vshow': True})


if __name__ == "__main__":
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = 3000
    settings.timeIntegration.endTime = 0.03
    settings.timeIntegration.verboseMode = 0
    settings.timeIntegration.adaptiveStep = False
    settings.timeIntegration.generalizedAlpha.spectralRadius = 0.9
    settings.solution.file.write = False
    mbs.SolveDynamic(settings)
    for name in ['body3', 'body4', 'body5', 'body6', 'body7', 'crank', 'rod']:
        node = mbs.GetNodeNumber(name)
        start = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates, exu.ConfigurationType.Reference)
        displaced = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates)
        print(name, *(f'{r + d:.12g}' for r, d in zip(start, displaced)))
