"""What an inverse-dynamics computation returns, and the sign conventions.

Sign conventions (every source follows them)
--------------------------------------------
* A joint's **reaction** is the force that the joint's first body (``body_a``)
  exerts on its second (``body_b``), global frame, N; ``body_b`` exerts the
  opposite force on ``body_a``. For a revolute it acts at the pin; for a
  prismatic or pin-in-slot joint at the sliding point (a point of
  ``body_b``), and it is the force normal to the line only: a driven slide's
  push along the line is the driver's effort, not part of the reaction.
* The **normal** force of a prismatic or pin-in-slot joint is the reaction's
  component along the line's left normal ``n = R u`` (``u`` the line's unit
  direction in ``body_a``'s frame turned into the global frame), N: reaction
  = normal * n.
* The **moment** of a prismatic joint is the couple (N m, counter-clockwise)
  that ``body_a`` exerts on ``body_b`` besides the normal force at the sliding
  point: the moment about the sliding point of everything the joint transmits.
* The **tooth force** of a gear pair (N) is the tangential force at the pitch
  point that ``body_a`` exerts on ``body_b``, positive where it turns
  ``body_b`` counter-clockwise relative to the carrier; its ``reaction`` is
  that force as a vector. The coupling acts as torques on the gears and the
  carrier (``joints.GearPair``): the gears' revolutes carry no share of it.
* A driver's **effort** is the torque (N m, revolute) or force (N, along the
  line, slide) that ``body_a`` of the driven joint exerts on ``body_b`` in the
  sense that increases the driven quantity; ``body_a`` gets the opposite.
  The driver's power is effort times the input rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..model import Mechanism

__all__ = [
    "JOINT_QUANTITIES",
    "DRIVER_QUANTITIES",
    "Forces",
    "require_constant_loads",
    "require_mass_data",
    "quantity_unit",
]

#: per joint: quantity -> shape suffix (2: a vector in the global frame); a joint
#: type's ``quantities`` say which it carries
JOINT_QUANTITIES = {"reaction": 2, "normal": 0, "moment": 0, "tooth_force": 0}
#: per driver
DRIVER_QUANTITIES = {"effort": 0}


def quantity_unit(mechanism: Mechanism, kind: str, name: str, quantity: str) -> str:
    """SI unit of a joint's or driver's quantity: "N" or "N m"."""
    base = quantity.strip("|")
    if kind == "driver":
        driver = next(d for d in mechanism.drivers if d.name == name)
        return "N m" if driver.quantity == "angle" else "N"
    return "N m" if base == "moment" else "N"


@dataclass
class Forces:
    """Joint reactions and driver efforts over N states, SI units.

    Attributes
    ----------
    source : str
        What computed them: ``"native"``, ``"native-newton-euler"``,
        ``"mujoco"``, ``"pinocchio"``, ``"pymunk"``.
    inputs, input_rates, input_accelerations : ndarray, shape (N, k)
        The states' driver values, rates and accelerations (rad or m, per s,
        per s^2) as the source had them: the native solver at these inputs is
        the reference.
    joints : dict of str to dict of str to ndarray
        Per joint name: ``"reaction"`` (N, 2) N; ``"normal"`` (N,) N for
        prismatic and pin-in-slot joints; ``"moment"`` (N,) N m for prismatic
        joints (see the module's sign conventions). A source that only knows
        magnitudes gives ``"|reaction|"``, ``"|normal|"``, ``"|moment|"``
        (N,) instead; a quantity it cannot give is left out.
    drivers : dict of str to dict of str to ndarray
        Per driver name: ``"effort"`` (N,) N m or N (or ``"|effort|"``).
    times : ndarray, shape (N,), optional
        Simulation times (simulated sources).
    settings : dict
    diagnostics : dict of str to ndarray
        Per-state extras, e.g. ``"residual"`` of the equations solved.
    notes : str
        How the forces were obtained.
    """

    source: str
    inputs: np.ndarray
    input_rates: np.ndarray
    input_accelerations: np.ndarray
    joints: dict
    drivers: dict
    times: np.ndarray | None = None
    settings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    notes: str = ""


def require_mass_data(mechanism: Mechanism) -> None:
    """Raise :class:`ModelError` (one line) unless every moving body has a mass and
    an inertia.

    The field is the first body without them; the message names them all.
    """
    missing = mechanism.without_mass
    if missing:
        some = "it" if len(missing) == 1 else "them"
        raise ModelError(
            mechanism.path,
            f"bodies.{missing[0]}",
            "mass and inertia on every moving body for dynamics",
            f"none on {', '.join(missing)} (add mass = kg, inertia = kg m^2 and com to {some})",
        )


def require_constant_loads(mechanism: Mechanism) -> None:
    """Raise :class:`ModelError` (one line) if a load has a time law: the states of a
    driven motion (solve, run) carry no time, so only free motion applies time laws."""
    for load in mechanism.loads:
        if load.law is not None:
            raise ModelError(
                mechanism.path,
                "loads",
                "constant loads for the inverse dynamics of a driven motion (time laws act in free motion)",
                f"{load.name!r} with a {load.law.describe()}",
            )
