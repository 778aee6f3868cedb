"""OpenSim (Simbody inside): the mechanism as an ``osim.Model`` of pin and slider
joints whose loops are closed by point constraints (:mod:`.model`), integrated
in free motion by Simbody's integrators with projection onto the constraints
(:mod:`.free`)."""

from __future__ import annotations

from xcheck.engines._contract import Engine, Mode
from xcheck.tolerances import FREE_MOTION

__all__ = ["OpenSim"]


class OpenSim(Engine):
    """OpenSim (Simbody): free motion with error-controlled or fixed-step integration and
    projection onto the constraints."""

    name = "opensim"
    title = "OpenSim"
    requires = ("opensim",)
    implementation = "xcheck.engines.opensim.modes"
    distributions = ("opensim",)
    install = "pip install xcheck[opensim]"
    modes = (Mode("opensim-free", "free", FREE_MOTION, style=dict(color="tab:olive", lw=1, ls="-")),)
    color = "tab:olive"
    notes = (
        "Revolute and prismatic joints: an OpenSim Model of PinJoint and SliderJoint (xcheck's body frames as "
        "OpenSim's bodies, every coordinate 0 at the start) with each loop cut at a revolute closed by a "
        "PointConstraint (Simbody's ball constraint; its z row is redundant and accepted); gravity and linear "
        "springs without damping (PointToPointSpring). Integrated by Simbody through OpenSim's Manager, which "
        "projects the state onto the constraints after each step: Runge-Kutta-Merson and explicit Euler at "
        "fixed steps, and Runge-Kutta-Merson with its error control (accuracy 1e-5 at a 1 ms step, divided "
        "by 16 at each halving). Not converted (not applicable): pin-in-slot joints, loops cut at a prismatic "
        "joint, dampers, rotational springs and loads."
    )
