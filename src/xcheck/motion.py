"""The time window over which a mechanism's drivers can be simulated.

A dynamic simulation drives the inputs by their motion laws; a crank that turns
round is simulated for one turn, an input that rocks between limit positions
only while every input stays inside its feasible range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .kinematics import Kinematics

__all__ = ["SimulationWindow", "drive_warnings", "law_states", "reached_span", "simulation_window", "sweep_span"]


@dataclass(frozen=True)
class SimulationWindow:
    """Times 0 <= t <= ``duration`` (s) over which the drivers' motion is feasible.

    ``reason`` says what ended the window: "one turn", "one period",
    "feasible range" or "time cap".
    """

    duration: float
    reason: str

    def times(self, count: int) -> np.ndarray:
        """``count`` equally spaced sample times from 0 to the end, shape (count,)."""
        return np.linspace(0.0, self.duration, count)

    def inputs(self, kinematics: Kinematics, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The drivers' (q, qd, qdd) at ``times``, each of shape (len(times), k), SI."""
        laws = [d.law.at_time(times) for d in kinematics.mechanism.drivers]
        q, qd, qdd = (np.stack([np.broadcast_to(law[i], times.shape) for law in laws], axis=1) for i in range(3))
        return q, qd, qdd


def simulation_window(
    kinematics: Kinematics, branch: str | None = None, margin: float = 0.02, time_cap: float = 10.0
) -> SimulationWindow:
    """How long the drivers' motion laws can run from t = 0.

    Parameters
    ----------
    margin : float
        Fraction of a bounded input's feasible range kept clear of each limit
        position (near a limit the mechanism is near-singular).
    time_cap : float
        Longest window, s.

    Raises
    ------
    InputError
        If the motion leaves the feasible range at once.
    """
    mech = kinematics.mechanism
    ends = [(time_cap, "time cap")]
    for k, driver in enumerate(mech.drivers):
        law = driver.law
        if law.kind == "harmonic" and law.frequency > 0.0:
            ends.append((1.0 / law.frequency, "one period"))
        elif driver.quantity == "angle":
            turn = law.time_at(law.start + math.copysign(2.0 * math.pi, law.rate or law.acceleration or 1.0))
            if turn is not None and turn > 0.0:
                ends.append((turn, "one turn"))
    duration, reason = min(ends)
    times = np.linspace(0.0, duration, 20001)
    q = SimulationWindow(duration, reason).inputs(kinematics, times)[0]
    inside = np.ones(times.shape, dtype=bool)
    for k, driver in enumerate(mech.drivers):
        rng = kinematics.input_range(k, branch)
        ok = np.ones(times.shape, dtype=bool)
        low = high = None
        if rng.low is not None and rng.high is not None:
            pad = margin * (rng.high - rng.low)
            low, high = rng.low + pad, rng.high - pad
        elif rng.low is not None:
            low = rng.low + (margin * abs(rng.low) if rng.low else margin)
        elif rng.high is not None:
            high = rng.high - (margin * abs(rng.high) if rng.high else margin)
        if low is not None:
            ok &= q[:, k] >= low
        if high is not None:
            ok &= q[:, k] <= high
        if not ok[0]:
            show = mech.units.show_input
            limits = " … ".join("" if v is None else show(driver.quantity, v) for v in (low, high))
            raise InputError(
                f"{mech.path}: drivers[{k}]: expected a motion that starts inside the feasible range "
                f"less {margin:.0%} of it at each limit position ({limits}), "
                f"found {driver.name} starting at {show(driver.quantity, float(q[0, k]))}"
            )
        inside &= ok
    if not inside.all():
        duration, reason = float(times[np.argmin(inside) - 1]), "feasible range"
    return SimulationWindow(duration, reason)


def law_states(mechanism, inputs: np.ndarray):
    """The drivers' rates and accelerations where their motion laws pass ``inputs``.

    One rule for every sweep and for ``xcheck solve --at``: the law's state at
    the time nearest t = 0 at which it passes the value (angles modulo a
    turn); a law that stands still gives zeros (a static position).

    Parameters
    ----------
    inputs : ndarray, shape (N, k)
        The drivers' values, SI.

    Returns
    -------
    rates, accelerations : ndarray, shape (N, k)
        Zero where the law never passes the value.
    reached : ndarray of bool, shape (N, k)
    """
    rates, accelerations = np.zeros_like(inputs), np.zeros_like(inputs)
    reached = np.zeros(inputs.shape, dtype=bool)
    for k, driver in enumerate(mechanism.drivers):
        for i, value in enumerate(inputs[:, k]):
            state = driver.law.state_at(float(value))
            if state is not None and all(math.isfinite(v) for v in state):
                rates[i, k], accelerations[i, k], reached[i, k] = state[1], state[2], True
    return rates, accelerations, reached


def reached_span(
    driver, low: float, high: float, around: float | None = None, count: int = 4001
) -> tuple[float, float] | None:
    """The stretch of ``[low, high]`` (SI) that the driver's motion law reaches
    without a gap, to (high - low) / (count - 1) refined by bisection at its
    ends; None if it reaches no value there.

    Of several stretches (a harmonic angle reaches an arc, which a window of a
    full turn may cut in two) the one holding ``around`` is taken, else the
    longest. A harmonic slide in a wider feasible range covers only
    centre +- amplitude; a law that stands still reaches every value.
    """
    values = np.linspace(low, high, count)
    hit = np.array([driver.law.state_at(float(v)) is not None for v in values])
    if not hit.any():
        return None
    edges = np.flatnonzero(np.diff(np.concatenate([[0], hit.astype(int), [0]])))
    runs = list(zip(edges[::2], edges[1::2] - 1))  # (first, last) index of each stretch
    if around is not None:
        near = int(np.argmin(np.abs(values - around)))
        holding = [r for r in runs if r[0] <= near <= r[1]]
    first, last = holding[0] if around is not None and holding else max(runs, key=lambda r: r[1] - r[0])
    lo = values[first] if first == 0 else _edge(driver, values[first - 1], values[first])
    hi = values[last] if last == count - 1 else _edge(driver, values[last + 1], values[last])
    law = driver.law
    if law.kind == "harmonic" and not law.turns:  # time_at admits 1e-12 of overshoot at a turning point
        lo, hi = max(lo, law.centre - abs(law.amplitude)), min(hi, law.centre + abs(law.amplitude))
    return float(lo), float(hi)


def _edge(driver, outside: float, inside: float) -> float:
    """The last value the law reaches between ``inside`` (reached) and ``outside``, by bisection."""
    for _ in range(60):
        middle = 0.5 * (outside + inside)
        if driver.law.state_at(middle) is None:
            outside = middle
        else:
            inside = middle
    return inside


def sweep_span(kinematics: Kinematics, k: int, branch: str | None = None, margin: float = 1e-2) -> tuple[float, float]:
    """The values (SI) over which driver ``k`` is swept, the others held at their
    reference values: one turn up from the reference for a crank that turns
    round, else the feasible range less ``margin`` of its width at each limit
    position (an unbounded side: the range's search span); either narrowed to
    the stretch about the reference that the driver's law reaches
    (:func:`reached_span`), so that every sample's rates are the law's.

    Raises
    ------
    InputError
        If the law reaches no value of the range.
    """
    mech = kinematics.mechanism
    driver, ref = mech.drivers[k], float(kinematics.reference_inputs()[k])
    rng = kinematics.input_range(k, branch)
    turns = rng.full_turn and driver.quantity == "angle"
    if turns:
        low, high = ref, ref + 2.0 * math.pi
    else:
        low = rng.low if rng.low is not None else ref - rng.span
        high = rng.high if rng.high is not None else ref + rng.span
        pad = margin * (high - low)
        low, high = low + pad, high - pad
    span = reached_span(driver, low, high, around=ref)
    if turns and span is not None and span[1] - span[0] < 2.0 * math.pi * (1.0 - 1e-9):
        # a law that does not turn round (a harmonic crank angle): its arc about the reference
        span = reached_span(driver, ref - 2.0 * math.pi, ref + 2.0 * math.pi, around=ref)
    if span is None:
        shown = " … ".join(mech.units.show_input(driver.quantity, v) for v in (low, high))
        raise InputError(
            f"{mech.path}: drivers[{k}]: expected a motion that reaches the feasible range "
            f"({shown}), found one that never does"
        )
    return span


def drive_warnings(kinematics: Kinematics, branch: str | None = None) -> list[str]:
    """One line per driver whose motion law asks for more than its joint can do:
    an angle driven round (at a constant rate or acceleration) where it cannot
    turn fully, or a harmonic law swinging beyond the feasible range. Empty
    when every law fits. Each line names the driver, its law and its range.

    xcheck still sweeps and simulates only the feasible range (the part of it
    the law reaches), so its results stand; what the file says would move the
    mechanism into a limit position, where a real one locks or breaks.
    """
    from .ranges import range_text  # the display of a range, in the file's units

    mech = kinematics.mechanism
    lines = []
    for k, driver in enumerate(mech.drivers):
        law = driver.law
        if law.static:
            continue
        rng = kinematics.input_range(k, branch)
        if rng.full_turn:
            continue
        if law.kind != "harmonic" and driver.quantity == "angle":
            if law.kind == "constant-rate":
                how = f"at a constant rate of {law.rate / mech.units.angular_rate_factor:.6g} {mech.units.angular_rate}"
            else:
                how = "at a constant acceleration"
            lines.append(
                f"{mech.name}: {driver.name} is driven round {how}, but it cannot turn fully "
                f"({range_text(kinematics, rng)}): the mechanism reaches a limit position there; "
                "only the feasible range is swept"
            )
        elif law.kind == "harmonic":
            low, high = law.centre - abs(law.amplitude), law.centre + abs(law.amplitude)
            # a swing that turns at a limit position (an elliptic trammel's slide) is the design, not too far
            slack = 1e-9 * (high - low)
            if (rng.low is not None and low < rng.low - slack) or (rng.high is not None and high > rng.high + slack):
                lines.append(
                    f"{mech.name}: {driver.name} swings over "
                    f"{mech.units.show_input(driver.quantity, low)} … {mech.units.show_input(driver.quantity, high)}, "
                    f"beyond its feasible range ({range_text(kinematics, rng)}): the mechanism reaches a limit "
                    "position there; only the feasible range is swept"
                )
    return lines
