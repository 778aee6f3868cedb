"""A driver's feasible range as a user reads it: in the mechanism file's display
units, its ends rounded inwards so that every value shown is feasible."""

from __future__ import annotations

import math

from .kinematics import InputRange, Kinematics


def _inward(value: float, up: bool, digits: int = 6) -> float:
    """``value`` rounded to ``digits`` significant digits towards the inside of a range."""
    if value == 0.0 or not math.isfinite(value):
        return value
    step = 10.0 ** (math.floor(math.log10(abs(value))) - digits + 1)
    return (math.ceil(value / step) if up else math.floor(value / step)) * step


def range_text(kin: Kinematics, rng: InputRange) -> str:
    """A driver's feasible range in display units, e.g. ``crank: -129.022 … 129.022 deg``
    (the ends rounded inwards, so every value shown is feasible)."""
    units = kin.mechanism.units
    driver = next(d for d in kin.mechanism.drivers if d.name == rng.driver)
    if driver.quantity == "angle":
        scale, unit = units.angle_factor, units.angle
    else:
        scale, unit = units.length_factor, units.length
    if rng.full_turn and driver.quantity == "angle":
        return f"{rng.driver}: full turn"
    if rng.full_turn:  # a slide that met no limit position within its search span
        ref = float(kin.reference_inputs()[[d.name for d in kin.mechanism.drivers].index(rng.driver)])
        return f"{rng.driver}: no limit within {(ref - rng.span) / scale:.6g} … {(ref + rng.span) / scale:.6g} {unit}"
    low = "-inf" if rng.low is None else f"{_inward(rng.low / scale, up=True):.6g}"
    high = "+inf" if rng.high is None else f"{_inward(rng.high / scale, up=False):.6g}"
    return f"{rng.driver}: {low} … {high} {unit}"
