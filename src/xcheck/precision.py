"""How xcheck writes the numbers it computes: in the files it generates, and in
the tables it shows.

Generated files (the engines' model files of ``xcheck export``) hold numbers
computed in double precision, whose last bits depend on the CPU and the
libraries. Inside :func:`canonical_numbers`, :func:`number` rounds each of them
at the :data:`DIGITS` th significant digit of the larger of its magnitude and
its scale (a length's scale is the mechanism's size, a vector's its largest
component), so a value within round-off of zero on its scale is written 0 and
any machine writes the same text. Outside that context :func:`number` keeps
every bit: the engines compute from the same writers, losslessly.
:func:`drift` compares a committed file with a fresh one within that precision.

A measured difference at or below its round-off bound carries no information in
its digits: :func:`shown` prints it as "< bound", so that a report reads the
same on every machine.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

__all__ = [
    "DIGITS",
    "number",
    "numbers",
    "resolution",
    "canonical_numbers",
    "Units",
    "Drift",
    "drift",
    "shown",
    "bound_text",
]

#: Significant digits of a generated file's numbers, counted from the larger of
#: a number's magnitude and its scale: 1e-12 relative, four orders above the
#: round-off of double precision (2.2e-16) and of the solvers' last steps.
DIGITS = 12


class Units(dict):
    """The rounding step (the absolute precision) of each number written in
    :func:`canonical_numbers`: |written value| -> the largest step it was rounded with."""


_UNITS: contextvars.ContextVar[Units | None] = contextvars.ContextVar("xcheck_canonical_units", default=None)


@contextlib.contextmanager
def canonical_numbers() -> Iterator[Units]:
    """Round every :func:`number` written within (the text of a generated file);
    yields the :class:`Units` of the numbers written, for :func:`drift`."""
    units = Units()
    token = _UNITS.set(units)
    try:
        yield units
    finally:
        _UNITS.reset(token)


def number(value: float, scale: float = 0.0) -> float:
    """A computed number as a generated file holds it.

    Within :func:`canonical_numbers`: ``value`` rounded at the :data:`DIGITS` th
    significant digit of ``max(|value|, scale)`` (so values below about 1e-12 of
    the scale become 0); outside: ``value`` itself. Negative zero becomes 0;
    a non-finite value is returned as it is.

    Parameters
    ----------
    value : float
    scale : float
        The magnitude of the quantity the value belongs to, in its units: the
        mechanism's size for a length, the largest component for a vector's
        component (:func:`numbers`), 0 for a quantity given on its own (a
        mass, an inertia: rounded relative to itself).
    """
    value = float(value) + 0.0
    units = _UNITS.get()
    if units is None or not math.isfinite(value):
        return value
    step = resolution(value, scale)
    if step == 0.0:
        return 0.0
    rounded = round(value, -round(math.log10(step))) + 0.0  # correctly rounded decimals: the same everywhere
    units[abs(rounded)] = max(units.get(abs(rounded), 0.0), step)
    return rounded


def resolution(value: float, scale: float = 0.0) -> float:
    """The step a canonical number is rounded to (:func:`number`): one unit in
    the :data:`DIGITS` th significant digit of ``max(|value|, scale)`` (0 for 0)."""
    magnitude = max(abs(float(value)), abs(float(scale)) if math.isfinite(scale) else 0.0)
    if magnitude == 0.0 or not math.isfinite(magnitude):
        return 0.0
    return 10.0 ** (math.floor(math.log10(magnitude)) - DIGITS + 1)


def numbers(values: Iterable[float], scale: float = 0.0) -> list[float]:
    """A vector's components (:func:`number`), each on the scale of the largest
    component (or ``scale``, if larger): a component at round-off of the others is 0."""
    values = [float(v) for v in values]
    finite = [abs(v) for v in values if math.isfinite(v)]
    largest = max([abs(float(scale)), *finite])
    return [number(v, largest) for v in values]


@dataclass(frozen=True)
class Drift:
    """Where a committed generated file differs from a fresh one beyond the
    precision: the line (1-based) and its two versions, and for a number the
    committed and fresh values, how far it moved and what the precision allows."""

    line: int
    committed: str
    generated: str
    committed_value: float | None = None
    generated_value: float | None = None
    allowed: float = 0.0

    def __str__(self) -> str:
        if self.committed_value is None or self.generated_value is None:
            return f"line {self.line} differs: {_clip(self.committed)!r} -> {_clip(self.generated)!r}"
        moved = abs(self.generated_value - self.committed_value)
        return (
            f"line {self.line}: {self.committed_value!r} -> {self.generated_value!r} "
            f"(moved by {moved:.3g}; the precision allows {self.allowed:.3g})"
        )


#: a number token; names and versions (task-2-1, 0.3.0) split into numbers the
#: same way in both texts, so only values that moved compare unequal
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)\b")


def drift(committed: str, generated: str, units: Units) -> Drift | None:
    """The first difference between a committed file and the one generated now
    beyond the precision (None if they agree).

    The texts agree where their non-numeric text is equal and every number is
    equal, or is one ``generated`` wrote in :func:`canonical_numbers` (its step in
    ``units``) and the committed one is within one step of it (the last digit
    of a value at a rounding boundary on another machine).
    """
    if committed == generated:
        return None
    old_lines, new_lines = committed.splitlines(), generated.splitlines()
    for index in range(max(len(old_lines), len(new_lines))):
        old = old_lines[index] if index < len(old_lines) else ""
        new = new_lines[index] if index < len(new_lines) else ""
        if old == new:
            continue
        found = _line_drift(index + 1, old, new, units)
        if found is not None:
            return found
    return None


def _line_drift(line: int, old: str, new: str, units: Units) -> Drift | None:
    old_tokens, new_tokens = _tokens(old), _tokens(new)
    if len(old_tokens) != len(new_tokens):
        return Drift(line, old, new)
    for (old_kind, old_text), (new_kind, new_text) in zip(old_tokens, new_tokens):
        if old_text == new_text:
            continue
        if old_kind != "number" or new_kind != "number":
            return Drift(line, old, new)
        was, now = float(old_text), float(new_text)
        step = units.get(abs(now), 0.0)  # a writer may put the sign in the text ("-{limit}")
        # one step, give or take the binary subtraction's own error (an ulp is at most 2.2e-4 of a step)
        if not abs(now - was) <= step * 1.001:
            return Drift(line, old, new, was, now, step)
    return None


def _tokens(text: str) -> list[tuple[str, str]]:
    """The text split into ("number", token) and ("text", run between numbers)."""
    tokens, at = [], 0
    for match in _NUMBER.finditer(text):
        if match.start() > at:
            tokens.append(("text", text[at : match.start()]))
        tokens.append(("number", match.group()))
        at = match.end()
    if at < len(text):
        tokens.append(("text", text[at:]))
    return tokens


def _clip(text: str, width: int = 80) -> str:
    text = text.strip()
    return text if len(text) <= width else text[: width - 3] + "..."


def bound_text(bound: float) -> str:
    """A round-off bound as tables show it: two significant digits, as tolerances are shown."""
    return f"{bound:.2g}"


def shown(value: float | None, round_off: float = 0.0, digits: int = 2) -> str:
    """A measured value as tables show it.

    Returns "—" for none or a non-finite value, ``"< B"`` where ``|value|`` is
    below its round-off bound ``round_off`` (B: :func:`bound_text`; the value's
    digits would be noise that differs from machine to machine), "0" for zero,
    else ``digits`` significant digits.
    """
    if value is None:
        return "—"
    value = float(value)
    if not math.isfinite(value):
        return "—"
    if round_off > 0.0 and math.isfinite(round_off) and abs(value) < round_off:
        return f"< {bound_text(round_off)}"
    if value == 0.0:
        return "0"
    return f"{value:.{digits}g}"
