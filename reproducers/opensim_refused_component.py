"""OpenSim: a component that ``Model.addForce`` refuses stays in the model, and the process crashes at exit.

A pendulum (one body on a ``PinJoint``) and a ``PointToPointSpring`` named
"spring 1": OpenSim refuses the space in the name, and ``addForce`` raises.
A refusal should leave the model as it was (it assembles, and the process ends
normally). Measured with opensim 4.6: ``addForce`` raises, but the spring stays
in the model (``initSystem`` raises on it again), and the process dies with a
segmentation fault when it ends; the same model with the spring named
"spring_1" assembles and the process ends normally.

Run: ``python opensim_refused_component.py``. Runs each variant in a child
process and prints the measured outcome beside the expected one; exits 0 while
the defect shows, 1 once it no longer does.
"""

import subprocess
import sys

import opensim as osim


def run(name: str) -> None:
    """Build the pendulum with a spring named ``name``; print what addForce and initSystem did."""
    osim.Logger.setLevel(osim.Logger.Level_Off)
    model = osim.Model()
    body = osim.Body("rod", 1.0, osim.Vec3(0.05, 0.0, 0.0), osim.Inertia(1e-3, 1e-3, 1e-3, 0.0, 0.0, 0.0))
    model.addBody(body)
    pin = osim.PinJoint("O", model.getGround(), osim.Vec3(0), osim.Vec3(0), body, osim.Vec3(0), osim.Vec3(0))
    model.addJoint(pin)
    spring = osim.PointToPointSpring(model.getGround(), osim.Vec3(0.6, 0.0, 0.0), body, osim.Vec3(0.1, 0, 0), 1e3, 0.25)
    spring.setName(name)
    outcome = []
    try:
        model.addForce(spring)
        outcome.append("addForce took it")
    except RuntimeError:
        outcome.append("addForce refused it")
    try:
        model.initSystem()
        outcome.append("the model assembled")
    except RuntimeError:
        outcome.append("initSystem refused the spring again (it stayed in the model)")
    print(", ".join(outcome), flush=True)


VARIANTS = {"spring_1": "addForce took it, the model assembled", "spring 1": "addForce refused it, the model assembled"}

if __name__ == "__main__":
    if len(sys.argv) > 1:
        run(sys.argv[1])
        sys.exit(0)
    from importlib.metadata import version

    print(f"opensim {version('opensim')}: a PointToPointSpring whose name OpenSim refuses, each in a child process")
    died = {}
    for name, expected in VARIANTS.items():
        child = subprocess.run([sys.executable, __file__, name], capture_output=True, text=True, timeout=120)
        died[name] = child.returncode != 0
        measured = child.stdout.strip() + (f"; the process died (exit status {child.returncode})" if died[name] else "")
        print(f"  named {name!r}: expected: {expected}, the process ends normally")
        print(f"  {' ' * (len(name) + 8)}measured: {measured}")
    shown = died["spring 1"] and not died["spring_1"]
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
