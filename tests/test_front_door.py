"""The command line and the Python API answer the same inputs alike.

Each case gives the same inputs to ``xcheck solve FILE --at ... --json`` and to
``xcheck.load(FILE).solve(at=...)``: both refuse them with the same line (the
argument named as the user wrote it: ``--at`` there, ``at`` here), or both
solve them to the same numbers with the same warnings.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import pytest
from conftest import MODELS, invoke

import xcheck
from xcheck.errors import XcheckError

SLIDER_CRANK = (MODELS / "slider-crank.toml").read_text(encoding="utf-8")
#: the slider-crank's crank swinging +-30 deg about 0 at 1 Hz: 45 deg is never reached
SWINGING = SLIDER_CRANK.replace(
    'motion = "constant-rate"\nstart = 0\nrate = 100                # rad/s',
    'motion = "harmonic"\ncentre = 0\namplitude = 30\nfrequency = 1',
)
#: the slider-crank's crank standing still: every input is a static position
STANDING = SLIDER_CRANK.replace("rate = 100                # rad/s", "rate = 0")
OPTIONS = {"at": "--at", "rates": "--rate", "accelerations": "--accel"}


def _cli(path: Path, **given: str):
    """(refusal line or None, the JSON's states and warnings) of ``xcheck solve``."""
    args = [arg for name, text in given.items() for arg in (OPTIONS[name], text)]
    done = invoke("solve", str(path), *args, "--json")
    if done.returncode:
        assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
        (line,) = [line for line in done.stderr.splitlines() if line.startswith("xcheck: error: ")]
        return line.removeprefix("xcheck: error: "), None
    return None, json.loads(done.stdout)


def _api(path: Path, **given):
    """(refusal line or None, the Result) of ``xcheck.load(path).solve(**given)``."""
    mech = xcheck.load(path)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = mech.solve(**given)
    except XcheckError as err:
        return str(err), None
    assert [str(w.message) for w in caught] == result.warnings
    return None, result


def _same_verdict(path: Path, cli_text: dict, api_values: dict):
    """Both refuse with the same line, or both solve alike; returns the refusal or None."""
    refused, document = _cli(path, **cli_text)
    api_refused, result = _api(path, **api_values)
    if refused is not None or api_refused is not None:
        assert refused is not None and api_refused is not None, (refused, api_refused)
        for name, option in OPTIONS.items():
            refused = re.sub(rf"{option}\b", name, refused)
        assert refused == api_refused
        return refused
    assert document["warnings"] == result.warnings
    states = document["states"]
    assert len(states) == len(result.solution.status)
    for i, state in enumerate(states):
        for name, body in state["bodies"].items():
            ours = result.solution.body(name)
            for key in ("position", "angle", "velocity", "omega", "acceleration", "alpha"):
                assert body[key] == pytest.approx(ours[key][i].tolist(), rel=0, abs=0), (name, key)
    return None


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mechanism.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_limit_position_is_refused_alike():
    fourbar = MODELS / "fourbar.toml"
    high = xcheck.load(fourbar).kinematics.input_range(0).high
    at = math.degrees(high)
    line = _same_verdict(fourbar, {"at": repr(at)}, {"at": at})
    assert "at crank: expected an input clear of the limit positions" in line


def test_an_input_near_a_limit_position_is_solved_and_warned_about_alike():
    assert _same_verdict(MODELS / "fourbar.toml", {"at": "129.0227"}, {"at": 129.0227}) is None
    _, result = _api(MODELS / "fourbar.toml", at=129.0227)
    assert any("is near a limit or singular position" in line for line in result.warnings)


def test_an_input_outside_the_feasible_range_is_refused_alike():
    line = _same_verdict(MODELS / "fourbar.toml", {"at": "140"}, {"at": 140})
    assert line.endswith(
        "at crank: expected an input within the feasible range (crank: -129.022 … 129.022 deg), found 140 deg"
    )


def test_an_input_the_motion_never_reaches_is_refused_alike(tmp_path):
    path = _write(tmp_path, SWINGING)
    line = _same_verdict(path, {"at": "45"}, {"at": 45})
    assert "at crank: expected a value that the driver's harmonic motion reaches" in line
    # reached: the law's rate there, alike
    assert _same_verdict(path, {"at": "15,-20"}, {"at": [15, -20]}) is None


def test_a_static_position_is_solved_alike(tmp_path):
    path = _write(tmp_path, STANDING)
    assert _same_verdict(path, {"at": "30,200"}, {"at": [30, 200]}) is None
    _, result = _api(path, at=[30, 200])
    assert (result.solution.qd == 0.0).all() and (result.solution.qdd == 0.0).all()


def test_given_rates_are_used_alike():
    fourbar = MODELS / "fourbar.toml"
    assert (
        _same_verdict(
            fourbar,
            {"at": "45,60", "rates": "2", "accelerations": "-1"},
            {"at": [45, 60], "rates": 2, "accelerations": -1},
        )
        is None
    )
    assert _same_verdict(fourbar, {"at": "45,60", "rates": "2,3"}, {"at": [45, 60], "rates": [2, 3]}) is None
    line = _same_verdict(fourbar, {"at": "45,60", "rates": "1,2,3"}, {"at": [45, 60], "rates": [1, 2, 3]})
    assert "rates: expected one state (for every input state) or 2, found 3" in line
    line = _same_verdict(fourbar, {"at": "45", "accelerations": "1"}, {"at": 45, "accelerations": 1})
    assert line.endswith("accelerations: expected it with rates, found accelerations alone")


@pytest.mark.parametrize(
    "text, value",
    [("30:40", [[30, 40]]), ("1e400", math.inf), (",".join(["45"] * 10_001), [45] * 10_001)],
    ids=["two values for one driver", "not finite", "too many states"],
)
def test_a_bad_at_is_refused_by_both(text, value):
    """The command line's text and Python's values are refused, each in one line naming
    ``--at`` or ``at``; where the values are the same numbers, with the same line."""
    refused, _ = _cli(MODELS / "fourbar.toml", at=text)
    api_refused, _ = _api(MODELS / "fourbar.toml", at=value)
    assert refused is not None and api_refused is not None
    assert refused.startswith(str(MODELS / "fourbar.toml") + ": --at")
    assert api_refused.startswith(str(MODELS / "fourbar.toml") + ": at")
    if text.startswith("45,"):
        assert re.sub(r"--at\b", "at", refused) == api_refused


def test_drawing_refuses_what_solving_refuses(tmp_path):
    fourbar = MODELS / "fourbar.toml"
    done = invoke("draw", str(fourbar), "--at", "140", "-o", str(tmp_path / "x.png"))
    assert done.returncode == 2
    with pytest.raises(XcheckError) as err:
        xcheck.load(fourbar).draw(at=140)
    assert done.stderr.strip() == "xcheck: error: " + str(err.value).replace(": at crank", ": --at crank")
    assert not (tmp_path / "x.png").exists()


def test_the_command_line_only_parses_and_prints():
    """cli.py stays a thin layer: at most 700 lines, and no constant of its own
    (limits, tolerances, defaults live below it, where the API reads them too)."""
    import ast

    source = (Path(xcheck.__file__).parent / "cli.py").read_text(encoding="utf-8")
    assert len(source.splitlines()) <= 700
    constants = [
        target.id
        for node in ast.parse(source).body
        if isinstance(node, (ast.Assign, ast.AnnAssign))
        for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
        if isinstance(target, ast.Name) and target.id.isupper()
    ]
    assert constants == []
