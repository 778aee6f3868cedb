"""Seed 000's printed four-bar table (Primjer 1, "Rješenja") in the shape other
tests use: :func:`printed_table` and :func:`last_digit_units`.

The printed values, their verdicts and the causes now live in
``comparisons/fourbar.toml`` and are pinned in ``tests/test_comparisons.py``;
this module only reads them back in the old shape, so there is one copy of the
knowledge. It holds no tests of its own.
"""

from __future__ import annotations

import functools
from decimal import Decimal

from conftest import MODELS, ROOT

from xcheck import Kinematics, load_mechanism
from xcheck.textbook import DISAGREES, check_printed, load_comparisons
from xcheck.textbook import ROUNDING as _ROUNDING

#: the old keys and the vocabulary's quantities (formulations I, II, III)
_KEYS = {
    "theta1": "interior D C A",
    "theta2": "interior C B D",
    "theta3": "interior B A C",
    "phi2": "vector B C angle",
    "phi3_II": "vector C D angle",
    "x1": "body crank x",
    "y1": "body crank y",
    "x2": "body coupler x",
    "y2": "body coupler y",
    "x3": "body rocker x",
    "y3": "body rocker y",
    "phi3_III": "body rocker angle",
}
_INSTANTS = ["phi = 30 deg", "phi = 60 deg", "phi = 120 deg"]


def last_digit_units(printed: str, computed: float) -> float:
    """|computed - printed| in units of the printed value's last digit
    (decimal comma or point)."""
    text = Decimal(printed.replace(",", "."))
    return abs(computed - float(text)) / 10.0 ** text.as_tuple().exponent


@functools.cache
def printed_table() -> tuple[list[tuple[str, list[str]]], set[tuple[str, int]], set[tuple[str, int]]]:
    """``(printed, rounding, wrong)``: each quantity with its values as printed in 000,
    "Rješenja", at 30, 60 and 120 deg; the (quantity, instant) pairs printed beyond half
    a unit of their last digit but within 1 % (rounding), and those that disagree (wrong:
    x2 at 120 deg, its sign dropped). Computed on first use (the verdicts solve the
    four-bar), not when a test module imports this one."""
    kin = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
    comparisons = load_comparisons(ROOT / "comparisons" / "fourbar.toml", kin.mechanism)
    rows = {
        (r["quantity"], r["instant"]): r for r in check_printed(kin, comparisons) if "table of results" in r["source"]
    }
    printed, rounding, wrong = [], set(), set()
    for key, quantity in _KEYS.items():
        values = []
        for i, instant in enumerate(_INSTANTS):
            row = rows[(quantity, instant)]
            values.append(row["printed_text"].replace(",", "."))
            if row["verdict"] == _ROUNDING:
                rounding.add((key, i))
            elif row["verdict"] == DISAGREES:
                wrong.add((key, i))
        printed.append((key, values))
    return printed, rounding, wrong
