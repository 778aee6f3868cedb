"""The printed answers of seed 000 (four-bar, Primjer 1; two-body arm,
Primjer 2-3), reproduced from the printed data.

A printed value "agrees" when it is the computed value rounded to the printed
digits (within half a unit of the last digit); "rounding" when it is off by at
most one unit of the last digit. Each verdict is pinned here; the one printed
value the seed gets wrong is pinned as wrong, with the cause.
"""

from __future__ import annotations

import numpy as np
import pytest


def last_digit_units(printed: str, computed: float) -> float:
    """|computed - printed| in units of the printed value's last digit."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return abs(computed - float(printed)) / 10.0 ** (-decimals)


def _angle(v):
    return np.degrees(np.arctan2(v[:, 1], v[:, 0]))


def _interior(at, first, second):
    """Angle at ``at`` from the ray to ``first`` counter-clockwise to the ray to ``second``, deg."""
    return (_angle(second - at) - _angle(first - at)) % 360.0


@pytest.fixture(scope="module")
def fourbar(kinematics):
    kin = kinematics("fourbar")
    solution = kin.solve(np.radians([30.0, 60.0, 120.0]))
    assert solution.success
    p = {label: solution.point(label)["position"] * 1e3 for label in "ABCD"}
    body = {name: solution.body(name) for name in ("crank", "coupler", "rocker")}
    return {
        # formulation I: interior angles at D, C, B (seed's eq. 2-4)
        "theta1": _interior(p["D"], p["C"], p["A"]),
        "theta2": _interior(p["C"], p["B"], p["D"]),
        "theta3": _interior(p["B"], p["A"], p["C"]),
        # formulation II: link angles, rocker vector from C to D
        "phi2": np.degrees(body["coupler"]["angle"]),
        "phi3_II": _angle(p["D"] - p["C"]) % 360.0,
        # formulation III: body centres (mid-links) and the rocker angle D->C
        "x1": body["crank"]["position"][:, 0] * 1e3, "y1": body["crank"]["position"][:, 1] * 1e3,
        "x2": body["coupler"]["position"][:, 0] * 1e3, "y2": body["coupler"]["position"][:, 1] * 1e3,
        "x3": body["rocker"]["position"][:, 0] * 1e3, "y3": body["rocker"]["position"][:, 1] * 1e3,
        "phi3_III": np.degrees(body["rocker"]["angle"]),
    }


# (quantity, [printed at 30, 60, 120 deg]) as printed in 000, "Rješenja"
PRINTED_FOURBAR = [
    ("theta1", ["109.4", "97.15", "40.60"]),
    ("theta2", ["37.37", "69.17", "147.61"]),
    ("theta3", ["183.23", "133.68", "51.79"]),
    ("phi2", ["33.23", "13.68", "-8.22"]),
    ("phi3_II", ["250.59", "262.85", "319.40"]),
    ("x1", ["194.856", "112.500", "-112.50"]),
    ("y1", ["112.500", "194.856", "194.856"]),
    ("x2", ["577.921", "443.620", "2.30906"]),
    ("y2", ["348.297", "442.911", "357.559"]),
    ("x3", ["683.065", "631.120", "410.191"]),
    ("y3", ["235.797", "248.056", "162.704"]),
    ("phi3_III", ["70.59", "82.85", "139.40"]),
]
# printed values off by more than half a unit of their last digit but at most one:
ROUNDING = {("theta2", 0), ("theta3", 2)}  # 37.3649 printed 37.37; 51.7845 printed 51.79
# printed values that are wrong:
WRONG = {("x2", 2)}  # the sign is dropped: the seed's own Mathematica output reads x2 -> -2.30906


@pytest.mark.parametrize("quantity,printed", PRINTED_FOURBAR)
def test_fourbar_printed_table(fourbar, quantity, printed):
    for i, text in enumerate(printed):
        units = last_digit_units(text, fourbar[quantity][i])
        if (quantity, i) in WRONG:
            assert units > 100.0, f"{quantity} at sample {i} is no longer wrong"
        elif (quantity, i) in ROUNDING:
            assert 0.5 < units <= 1.0, f"{quantity}[{i}] = {fourbar[quantity][i]} vs printed {text}"
        else:
            assert units <= 0.5, f"{quantity}[{i}] = {fourbar[quantity][i]} vs printed {text}"


def test_fourbar_sign_slip_is_only_a_sign(fourbar):
    """x2 at 120 deg: the printed magnitude is right, the sign is not."""
    assert last_digit_units("-2.30906", fourbar["x2"][2]) <= 0.5


def test_two_body_arm_point_p(kinematics):
    """000 Primjer 2 and 3: r_P in mm, v_P in m/s, a_P in m/s^2, as printed
    by the seed's Mathematica run."""
    kin = kinematics("two-body-arm")
    instant = kin.mechanism.instants[0]
    state = np.array([instant.inputs[d.name] for d in kin.mechanism.drivers])
    solution = kin.solve(state[None, :, 0], state[None, :, 1], state[None, :, 2])
    p = solution.point("P")
    for computed, printed in [
        (p["position"][0, 0] * 1e3, "323.205"), (p["position"][0, 1] * 1e3, "659.808"),
        (p["velocity"][0, 0], "-9.49585"), (p["velocity"][0, 1], "2.45559"),
        (p["acceleration"][0, 0], "-79.8672"), (p["acceleration"][0, 1], "-132.799"),
    ]:
        assert last_digit_units(printed, computed) <= 0.5, (computed, printed)


def test_two_body_arm_closed_form(kinematics):
    """r_P = (150 + 100 sqrt 3, 400 + 150 sqrt 3) mm exactly (the seed's own algebra)."""
    kin = kinematics("two-body-arm")
    solution = kin.solve(np.radians([[30.0, 30.0]]))
    exact = np.array([150 + 100 * np.sqrt(3), 400 + 150 * np.sqrt(3)]) * 1e-3
    np.testing.assert_allclose(solution.point("P")["position"][0], exact, rtol=0, atol=1e-15)
