"""The states a user asks for, by one rule wherever they are asked for.

``xcheck solve`` and ``xcheck draw`` on the command line, ``solve`` and
``draw`` of :class:`xcheck.api.Assembled` in Python: each turns the inputs a
user gives (or a file's ``[[instants]]``) into the drivers' values, rates and
accelerations, refuses what cannot be answered, solves, and says what to
beware of, through the functions here. The command line only parses its
text into numbers and prints; an argument is named as the user wrote it
(``--at`` there, ``at`` in Python), so the same input gets the same verdict
and the same line.

The rules:

* inputs: numbers, finite, of the mechanism's drivers' count per state, from
  1 to :data:`~xcheck.arguments.MAX_STATES` states, in display units of the
  file unless SI is asked for;
* rates: given (one state for all, or one per state; accelerations then
  default to zero) or else the drivers' motion laws where they pass the input
  (:func:`xcheck.motion.law_states`; a law that stands still gives a static
  position); an input its law never reaches is refused;
* a one-input mechanism's input must lie within the feasible range and at
  least :data:`LIMIT_CLEARANCE` from a limit position;
* every state must assemble with determined velocities;
* warned about, not refused: a driver's law that asks more than its joint can
  do (:func:`xcheck.motion.drive_warnings`) and a state near a limit or
  singular position (:func:`limit_warnings`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import arguments
from .errors import InputError, ModelError
from .kinematics import Kinematics, Solution, Status
from .motion import drive_warnings, law_states

__all__ = [
    "LIMIT_CLEARANCE",
    "LIMIT_FRACTION",
    "LIMIT_CONDITIONING",
    "Asked",
    "states_asked",
    "values_of_text",
    "given_inputs",
    "asked_states",
    "instant_states",
    "check_ranges",
    "solve_asked",
    "drawn_state",
    "reactions_of",
    "limit_warnings",
]

#: inputs closer than this to a limit position (rad; slides per mechanism size)
#: are refused: the mechanism is singular there and its rates grow without bound
LIMIT_CLEARANCE = 1e-8
#: an input closer to a limit position than this fraction of its feasible range
#: is warned about: the runner's sweeps keep 1e-2 clear (where rates are finite
#: and every method agrees to round-off); at 1e-3 velocities are already about
#: three and accelerations about thirty times those at 1e-2, growing without bound
LIMIT_FRACTION = 1e-3
#: below this inverse condition number of the scaled constraint Jacobian a state
#: is warned about as near a singular position (any number of inputs). Measured:
#: the runner's sweeps and the files' instants of every bundled mechanism stay
#: above 6.4e-3 (task-2-1); fourbar reaches 1e-3 about 1e-5 of its range from a limit
LIMIT_CONDITIONING = 1e-3


@dataclass
class Asked:
    """States to solve: the drivers' values, rates and accelerations, SI.

    Attributes
    ----------
    inputs, rates, accelerations : ndarray, shape (N, k)
    labels : list of str
        One per state, for tables and messages.
    fields : list of str or None
        Where each state comes from in the file (``instants[2]``) for the
        messages, or None for inputs given as an argument (then ``option``).
    option : str
        The argument the inputs were given as (``--at``, ``at``).
    """

    inputs: np.ndarray
    rates: np.ndarray
    accelerations: np.ndarray
    labels: list[str]
    fields: list[str] | None = None
    option: str = "at"

    def where(self, i: int, driver: str) -> str:
        """The field a message about state ``i``'s input ``driver`` names."""
        return f"{self.fields[i]}.{driver}" if self.fields else f"{self.option} {driver}"


def values_of_text(text: str, mechanism, option: str = "--at") -> list[list[float]]:
    """An option's text as numbers (``xcheck solve --at 30:45,60:50``): states
    separated by commas, each the drivers' values separated by colons, each a
    number or an arithmetic expression (:func:`xcheck.units.evaluate_expression`);
    the values as given, for :func:`asked_states` to convert and check.

    Raises
    ------
    InputError
        Naming the file, the option and the driver.
    """
    from .units import evaluate_expression

    names = [d.name for d in mechanism.drivers]
    states = []
    for item in text.split(","):
        parts = item.split(":")
        if len(parts) != len(names):
            raise InputError(
                f"{mechanism.path}: {option}: expected {len(names)} value(s) per state separated "
                f"by ':' ({':'.join(names)}), found {arguments.shown(item)}"
            )
        state = []
        for name, part in zip(names, parts):
            try:
                state.append(evaluate_expression(part.strip()))
            except ValueError as err:
                raise InputError(
                    f"{mechanism.path}: {option} {name}: expected a number or an arithmetic "
                    f"expression, found {arguments.shown(part)} ({err})"
                ) from None
        states.append(state)
    return states


def given_inputs(kinematics: Kinematics, values, si: bool = False, option: str = "at") -> np.ndarray:
    """Inputs (or rates, or accelerations) given as an argument, checked, in SI.

    Parameters
    ----------
    values : float or array_like
        Shape (N,) for N states of a one-input mechanism, (k,) for one state of
        a k-input one, or (N, k).
    si : bool
        ``values`` in SI (rad, m, per s) rather than the file's display units.
    option : str
        The argument's name in messages: ``at`` (inputs; ``--at`` on the
        command line), else rates (names holding ``rate``) or accelerations.

    Returns
    -------
    ndarray, shape (N, k)

    Raises
    ------
    InputError
        Naming the file and the argument: not numbers, a shape that does not
        fit, more than :data:`~xcheck.arguments.MAX_STATES` states, a value not finite.
    """
    mech = kinematics.mechanism
    where = f"{mech.path}: {option}"
    si = arguments.flag(si, "si")
    try:
        kind = np.asarray(values).dtype.kind
    except (ValueError, TypeError):  # ragged nesting
        kind = "O"
    if kind not in "iuf":  # not bools, strings, complex numbers or objects
        raise InputError(f"{where}: expected numbers, found {arguments.shown(values)}")
    try:
        arr = kinematics.input_array(values)
    except ValueError as err:
        raise InputError(f"{where}: {err}") from None
    if not 1 <= len(arr) <= arguments.MAX_STATES:
        raise InputError(f"{where}: expected from 1 to {arguments.MAX_STATES} states, found {len(arr)}")
    arguments.finite(arr, where, values)
    if si:
        return arr * 1.0
    units = mech.units
    per_second = "rate" in option or "accel" in option
    factors = [
        (units.angular_rate_factor if per_second else units.angle_factor)
        if d.quantity == "angle"
        else units.length_factor
        for d in mech.drivers
    ]
    return arr * np.array(factors)


def asked_states(
    kinematics: Kinematics,
    at,
    rates=None,
    accelerations=None,
    si: bool = False,
    options: tuple[str, str, str] = ("at", "rates", "accelerations"),
) -> Asked:
    """The states of inputs given as arguments (``xcheck solve --at``, ``solve(at=...)``).

    Rates not given come from the drivers' motion laws where they pass the
    inputs; given rates (one state for every input state, or one per state)
    take accelerations too, default zero. ``options`` name the three
    arguments in messages (``("--at", "--rate", "--accel")`` on the command line).

    Raises
    ------
    InputError
        As :func:`given_inputs`; accelerations without rates; an input that
        its driver's law never reaches, or reaches only where it overflows.
    """
    mech = kinematics.mechanism
    at_option, rate_option, accel_option = options
    if accelerations is not None and rates is None:
        raise InputError(f"{mech.path}: {accel_option}: expected it with {rate_option}, found {accel_option} alone")
    inputs = given_inputs(kinematics, at, si, at_option)
    if rates is None:
        qd, qdd, reached = law_states(mech, inputs)
        for k, driver in enumerate(mech.drivers):
            if not reached[:, k].all():
                value = float(inputs[np.argmin(reached[:, k]), k])
                raise InputError(
                    f"{mech.path}: {at_option} {driver.name}: expected a value that the driver's "
                    f"{driver.law.kind} motion reaches with a finite rate (or give {rate_option}), found "
                    f"{mech.units.show_input(driver.quantity, value, digits=12)}"
                )
    else:
        qd = _per_state(given_inputs(kinematics, rates, si, rate_option), inputs, mech.path, rate_option)
        qdd = np.zeros_like(inputs)
        if accelerations is not None:
            qdd = _per_state(given_inputs(kinematics, accelerations, si, accel_option), inputs, mech.path, accel_option)
    labels = [
        ", ".join(f"{d.name} = {mech.units.show_input(d.quantity, v)}" for d, v in zip(mech.drivers, row))
        for row in inputs
    ]
    return Asked(inputs, qd, qdd, labels, option=at_option)


def states_asked(
    kinematics: Kinematics,
    at=None,
    rates=None,
    accelerations=None,
    si: bool = False,
    options: tuple[str, str, str] = ("at", "rates", "accelerations"),
) -> Asked:
    """The states asked for: the inputs ``at`` given (:func:`asked_states`), or
    without them the file's instants (:func:`instant_states`), which carry
    their own rates, so that rates or accelerations without ``at`` are refused.

    Raises
    ------
    InputError, ModelError
        As :func:`asked_states` and :func:`instant_states`; rates or accelerations without inputs.
    """
    if at is not None:
        return asked_states(kinematics, at, rates, accelerations, si, options)
    if rates is not None or accelerations is not None:
        option = options[1] if rates is not None else options[2]
        raise InputError(
            f"{kinematics.mechanism.path}: {option}: expected it with {options[0]} (the instants of the file "
            f"carry their own rates), found no {options[0]}"
        )
    return instant_states(kinematics)


def _per_state(values: np.ndarray, inputs: np.ndarray, path: str, option: str) -> np.ndarray:
    """Rates or accelerations (M, k) for the N input states: one state for all, or one each."""
    if len(values) not in (1, len(inputs)):
        raise InputError(
            f"{path}: {option}: expected one state (for every input state) or {len(inputs)}, found {len(values)}"
        )
    return np.broadcast_to(values, inputs.shape).copy()


def instant_states(kinematics: Kinematics) -> Asked:
    """The states of the file's ``[[instants]]``, with their own rates.

    Raises
    ------
    ModelError
        If the file has none, or an instant's value is one its driver never reaches.
    """
    mech = kinematics.mechanism
    if not mech.instants:
        raise ModelError(mech.path, "instants", "[[instants]] to solve (or give the inputs)", "none")
    states = np.array([inst.states(mech) for inst in mech.instants])  # (N, k, 3)
    fields = [f"instants[{i}]" for i in range(len(mech.instants))]
    labels = [inst.label for inst in mech.instants]
    return Asked(states[:, :, 0], states[:, :, 1], states[:, :, 2], labels, fields)


def check_ranges(kinematics: Kinematics, asked: Asked, branch: str | None = None) -> None:
    """Refuse an input outside the feasible range or within :data:`LIMIT_CLEARANCE`
    of a limit position.

    Only for one-input mechanisms: with several inputs the range of one
    depends on the others, and the solve's own status decides.

    Raises
    ------
    InputError or ModelError
        The latter for a file's instant (naming ``instants[i].DRIVER``).
    """
    from .ranges import range_text  # the display of a range, in the file's units

    mech = kinematics.mechanism
    if len(mech.drivers) != 1:
        return
    driver = mech.drivers[0]
    rng = kinematics.input_range(0, branch)
    clearance = LIMIT_CLEARANCE * (1.0 if driver.quantity == "angle" else kinematics.system.size)
    for i, q in enumerate(asked.inputs[:, 0]):
        if not rng.contains(q):
            expected = f"an input within the feasible range ({range_text(kinematics, rng)})"
        elif any(limit is not None and abs(q - limit) <= clearance for limit in (rng.low, rng.high)):
            expected = (
                f"an input clear of the limit positions ({range_text(kinematics, rng)}): the mechanism is "
                "singular there and its rates are not determined"
            )
        else:
            continue
        found = mech.units.show_input(driver.quantity, float(q), digits=12)
        if asked.fields:
            raise ModelError(mech.path, asked.where(i, driver.name), expected, found)
        raise InputError(f"{mech.path}: {asked.where(i, driver.name)}: expected {expected}, found {found}")


def _check_statuses(solution: Solution, asked: Asked) -> None:
    """Refuse a state that did not assemble with determined velocities."""
    mech = solution.mechanism
    for i, code in enumerate(solution.status):
        status = Status(int(code))
        if status <= Status.NEAR_SINGULAR:
            continue
        inputs = ", ".join(
            f"{d.name} = {mech.units.show_input(d.quantity, solution.inputs[i, k])}" for k, d in enumerate(mech.drivers)
        )
        raise ModelError(
            mech.path,
            asked.fields[i] if asked.fields else asked.option,
            "a state where the mechanism assembles with determined velocities",
            f"{status.label} at {inputs} ({status.message})",
        )


@dataclass
class Solved:
    """The solution of asked states and what to beware of in it."""

    solution: Solution
    labels: list[str]
    warnings: list[str] = field(default_factory=list)


def solve_asked(kinematics: Kinematics, asked: Asked, branch: str | None = None) -> Solved:
    """Solve asked states on a branch, by the rules of this module.

    Returns
    -------
    Solved
        Its ``warnings``: the drivers' laws that ask more than their joints can
        do, then the states near a limit or singular position.

    Raises
    ------
    InputError or ModelError
        An input outside the feasible range or at a limit position
        (:func:`check_ranges`), or a state that does not assemble with
        determined velocities.
    """
    check_ranges(kinematics, asked, branch)
    solution = kinematics.solve(asked.inputs, asked.rates, asked.accelerations, branch=branch)
    _check_statuses(solution, asked)
    lines = [*drive_warnings(kinematics, branch), *limit_warnings(solution, branch), *spring_warnings(solution)]
    return Solved(solution, asked.labels, lines)


def spring_warnings(solution: Solution) -> list[str]:
    """One line per spring whose ends meet at some solved state while it pulls
    (:func:`xcheck.dynamics.directionless_springs`), naming the first such input."""
    from .dynamics import directionless_springs

    mech = solution.mechanism
    lines = []
    for name, where in directionless_springs(solution).items():
        if where.any():
            i = int(np.flatnonzero(where)[0])
            shown = ", ".join(
                f"{d.name} = {mech.units.show_input(d.quantity, float(solution.inputs[i, k]), digits=10)}"
                for k, d in enumerate(mech.drivers)
            )
            lines.append(
                f"{mech.name}: spring {name!r} has its two ends at one point at {shown}: its pull has no "
                "direction there, so the reactions and efforts are not determined"
            )
    return lines


def reactions_of(solution: Solution):
    """The reactions and efforts of solved states where the file gives mass data
    (:func:`xcheck.dynamics.inverse_dynamics`): (forces, None); (None, the
    error) where some bodies lack it or a load has a time law, for the caller to
    report after the kinematics, which still stand; (None, None) where no body
    has mass data."""
    from .dynamics import inverse_dynamics
    from .errors import XcheckError

    if all(b.mass is None for b in solution.mechanism.moving_bodies):
        return None, None
    try:
        return inverse_dynamics(solution), None
    except XcheckError as err:
        return None, err


def drawn_state(
    kinematics: Kinematics, at=None, si: bool = False, branch: str | None = None, option: str = "at"
) -> Solution:
    """The one state a drawing shows (``xcheck draw``, ``draw()``): at given
    inputs, checked as :func:`asked_states` checks them and refused outside the
    feasible range or at a limit position, or at the file's ``assembly.at``.
    The rates (the drawing's arrows) are the motion laws' where they pass the
    input, else zero: a drawing needs no rates.

    Raises
    ------
    InputError
        As :func:`given_inputs` and :func:`check_ranges`; more than one state;
        an input where the mechanism does not assemble.
    """
    mech = kinematics.mechanism
    if at is None:
        inputs = kinematics.reference_inputs()[None]
    else:
        inputs = given_inputs(kinematics, at, si, option)
        if len(inputs) != 1:
            raise InputError(f"{mech.path}: {option}: expected one state to draw, found {len(inputs)}")
        check_ranges(kinematics, Asked(inputs, 0.0 * inputs, 0.0 * inputs, [""], option=option), branch)
    rates, _, _ = law_states(mech, inputs)
    solution = kinematics.solve(inputs, rates, branch=branch)
    if solution.status[0] > Status.SINGULAR:
        shown = ", ".join(f"{d.name} = {mech.units.show_input(d.quantity, v)}" for d, v in zip(mech.drivers, inputs[0]))
        raise InputError(
            f"{mech.path}: {option}: expected an input where the mechanism assembles, found {shown} "
            f"({Status(int(solution.status[0])).message})"
        )
    return solution


def limit_warnings(solution: Solution, branch: str | None = None) -> list[str]:
    """One line per solution that passes near a limit or singular position,
    naming the input value nearest it; empty when none does.

    A sample is near when it is within :data:`LIMIT_FRACTION` of a one-input
    mechanism's feasible range from a limit, when the inverse condition number
    of its constraint Jacobian is below :data:`LIMIT_CONDITIONING`, or when the
    solver flagged it near-singular or singular.
    """
    kin, mech = solution.kinematics, solution.mechanism
    n = len(solution.status)
    closeness = np.full(n, np.inf)  # smaller: nearer
    why = [""] * n
    good = solution.status <= Status.SINGULAR
    for i in np.flatnonzero(good & (solution.singularity < LIMIT_CONDITIONING)):
        closeness[i] = solution.singularity[i] / LIMIT_CONDITIONING
        why[i] = f"conditioning {solution.singularity[i]:.2g}"
    if len(mech.drivers) == 1:
        rng = kin.input_range(0, branch)
        if rng.low is not None and rng.high is not None and rng.high > rng.low:
            width = rng.high - rng.low
            for i in np.flatnonzero(good):
                value = solution.inputs[i, 0]
                limit = min((rng.low, rng.high), key=lambda v: abs(v - value))
                fraction = abs(value - limit) / width
                if fraction < LIMIT_FRACTION and fraction / LIMIT_FRACTION < closeness[i]:
                    closeness[i] = fraction / LIMIT_FRACTION
                    distance = mech.units.show_input(mech.drivers[0].quantity, abs(value - limit), digits=3)
                    shown = mech.units.show_input(mech.drivers[0].quantity, limit, digits=10)
                    why[i] = (
                        f"{distance} from the limit position at {shown}, conditioning {solution.singularity[i]:.2g}"
                    )
    near = np.flatnonzero(np.isfinite(closeness))
    if not near.size:
        return []
    worst = int(near[np.argmin(closeness[near])])
    where = ", ".join(
        f"{d.name} = {mech.units.show_input(d.quantity, float(solution.inputs[worst, k]), digits=10)}"
        for k, d in enumerate(mech.drivers)
    )
    more = f" ({near.size} samples near it)" if near.size > 1 else ""
    return [
        f"{mech.name}: {where} is near a limit or singular position ({why[worst]}){more}: velocities, "
        "accelerations and forces grow without bound there"
    ]
