"""How xcheck writes numbers: canonical numbers in generated files, the
comparison of a committed file with a fresh one within their precision, and
differences at round-off shown as such."""

from __future__ import annotations

import math

import numpy as np
import pytest

from xcheck.precision import bound_text, canonical_numbers, drift, number, numbers, shown


def test_numbers_are_exact_outside_the_canonical_context():
    """The engines compute from the same writers: there nothing is rounded."""
    value = 0.40610378112568946
    assert number(value, 1.0) == value
    assert numbers([1.0, 1.2246467991473532e-16]) == [1.0, 1.2246467991473532e-16]
    assert math.copysign(1.0, number(-0.0)) == 1.0  # never a negative zero


def test_canonical_numbers_round_at_the_twelfth_digit_of_their_scale():
    with canonical_numbers() as units:
        assert number(0.40610378112568946) == 0.406103781126
        assert number(0.4061037811256895) == 0.406103781126  # one unit in the last place apart: the same
        assert number(1.0000000000000258) == 1.0
        assert number(-1.0, 1.0) == -1.0
        # a value at round-off of its scale is 0: sin(pi) of a unit length
        assert number(1.2246467991473532e-16, 1.0) == 0.0
        assert number(3.2820035428884744e-22, 1.0) == 0.0
        # a small quantity given on its own keeps its twelve digits (an inertia of 1e-12 kg m^2)
        assert number(1.234567890123456e-12) == 1.23456789012e-12
        # on the scale of a 0.6 m mechanism, a length is written to 1e-12 m
        assert number(1.234567890123456e-5, 0.6) == 1.2345679e-5
        assert math.copysign(1.0, number(-1e-20, 1.0)) == 1.0
        assert math.isnan(number(math.nan)) and number(math.inf) == math.inf
    assert units[0.406103781126] == pytest.approx(1e-12)
    assert units[1.2345679e-5] == pytest.approx(1e-12)  # the scale's step, not the value's


def test_a_vector_is_written_on_the_scale_of_its_largest_component():
    with canonical_numbers():
        assert numbers([-1.0, 3.2820035428884744e-22, 3.141592653589793]) == [-1.0, 0.0, 3.14159265359]
        assert numbers([0.5000000000000129, -3.06161699786901e-17, -1.0000000000000258]) == [0.5, 0.0, -1.0]
        # a vector of round-off on a given scale (a point at the origin of a 2 m mechanism)
        assert numbers([1e-17, -2e-17, 0.0], 2.0) == [0.0, 0.0, 0.0]


def test_canonical_numbers_are_the_same_for_inputs_a_few_ulps_apart():
    """What two CPUs computing the same value may give: a few units in the last
    place apart. Over 10 000 values of all magnitudes, the written numbers agree
    but where a value lies within those ulps of a rounding boundary, and then
    they differ by one step, which :func:`drift` accepts."""
    rng = np.random.default_rng(31)
    values = rng.uniform(-1.0, 1.0, 10_000) * 10.0 ** rng.integers(-8, 8, 10_000)
    differ = 0
    for value in values:
        nudged = value
        for _ in range(int(rng.integers(1, 5))):
            nudged = np.nextafter(nudged, math.inf if rng.random() < 0.5 else -math.inf)
        with canonical_numbers() as units:
            a, b = number(value), number(float(nudged))
        differ += a != b
        if a != b:
            assert drift(repr(a), repr(b), units) is None
    assert differ <= 10  # about 1e-4 of the values: 0 to 2 of 10 000 over seeds 0-9


def test_drift_accepts_the_last_digit_and_names_what_moved():
    with canonical_numbers() as units:
        text = f'<body pos="{number(0.4061037811256895)} {number(1e-17, 1.0)}"/>'
    assert text == '<body pos="0.406103781126 0.0"/>'
    assert drift(text, text, units) is None
    # the committed file from a machine whose value lay at a rounding boundary: one step apart
    assert drift('<body pos="0.406103781125 0.0"/>', text, units) is None
    # an old lossless file within the precision
    assert drift('<body pos="0.40610378112568946 1.2246467991473532e-16"/>', text, units) is None
    # a value that moved
    moved = drift('<body pos="0.41 0.0"/>', text, units)
    assert moved is not None and moved.line == 1
    assert moved.committed_value == 0.41 and moved.generated_value == 0.406103781126
    assert "moved by 0.0039" in str(moved) and "line 1" in str(moved)
    # the text around the numbers must be the same
    assert drift('<body pos="0.406103781126 0.0" axisangle="0 0 1 1e-17"/>', text, units) is not None
    # a number that was not computed (no step recorded) must be equal
    assert drift("version 0.3.0\n", "version 0.3.1\n", units) is not None
    # a line added or removed
    assert drift(text + "\n<x/>\n", text + "\n", units) is not None


def test_drift_takes_a_sign_written_as_text():
    """A writer may write the sign itself: ``lower="-{limit}"``."""
    with canonical_numbers() as units:
        text = f'lower="-{number(3.5000000000000004)}"'
    assert drift('lower="-3.5000000000000004"', text, units) is None


@pytest.mark.parametrize(
    ("bound", "text"), [(6.46e-14, "6.5e-14"), (2e-12, "2e-12"), (1.94e-12, "1.9e-12"), (1e-5, "1e-05"), (3.2, "3.2")]
)
def test_a_bound_is_shown_as_a_tolerance_is(bound, text):
    assert bound_text(bound) == text


def test_values_below_their_round_off_bound_are_shown_as_such():
    assert shown(9.3e-16, 6.46e-14) == "< 6.5e-14"
    assert shown(8.8e-16, 6.46e-14) == "< 6.5e-14"  # the same on another machine
    assert shown(-2.5e-14, 1e-12) == "< 1e-12"
    assert shown(3.4e-11, 1.9e-12) == "3.4e-11"
    assert shown(0.0021) == "0.0021" and shown(0.0) == "0"
    assert shown(None) == "—" and shown(math.nan, 1e-12) == "—" and shown(math.inf) == "—"
    assert shown(1.234567, digits=4) == "1.235"
