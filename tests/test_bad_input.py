"""Bad input: every one gives one line on stderr naming the file, the field,
what was expected and what was found, exit code 2, and no traceback.

Each case is a copy of an example model with one thing broken. It is checked
twice: through the library (``load_mechanism`` then ``Kinematics.assemble``,
asserting the :class:`ModelError`'s fields) and through the installed
``xcheck`` command (asserting the one line on stderr and the exit code).
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import invoke

from xcheck import Kinematics, ModelError, load_mechanism

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
XCHECK = Path(sys.executable).with_name("xcheck")

FOURBAR = (MODELS / "fourbar.toml").read_text(encoding="utf-8")
ARM = (MODELS / "two-body-arm.toml").read_text(encoding="utf-8")
SLIDER = (MODELS / "slider-crank.toml").read_text(encoding="utf-8")
KNOWN = ("fourbar", "slider-crank", "two-body-arm")


def sub(text: str, old: str, new: str) -> str:
    """``text`` with the first ``old`` replaced; fails if the example changed."""
    assert old in text, f"the example no longer contains {old!r}"
    return text.replace(old, new, 1)


def write(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def library_error(path: Path) -> ModelError:
    """The ModelError that loading and assembling ``path``, or taking its
    instants' states (checked when used, not at load), raises."""
    with pytest.raises(ModelError) as info:
        mechanism = load_mechanism(path)
        Kinematics(mechanism).assemble()
        for instant in mechanism.instants:
            instant.states(mechanism)
    err = info.value
    assert err.path == str(path)
    assert str(err) == (
        f"{path}: {err.field}: expected {err.expected}, found {err.found}"
        if err.field
        else f"{path}: expected {err.expected}, found {err.found}"
    )
    return err


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """The command line, in this process (see :func:`conftest.invoke`)."""
    return invoke(*args)


def run_shell(*args: str) -> subprocess.CompletedProcess:
    """The installed ``xcheck`` command in a fresh process: the smoke tests."""
    env = {k: v for k, v in os.environ.items() if k != "XCHECK_MODELS"}
    env["PYTHONIOENCODING"] = "utf-8"
    return subprocess.run(
        [str(XCHECK), *args], capture_output=True, text=True, encoding="utf-8", cwd=ROOT, env=env, timeout=300
    )


def error_line(result: subprocess.CompletedProcess, *needles: str) -> str:
    """The single error line of a failed run; checks exit code 2, no traceback,
    nothing on stdout and that the line holds every needle."""
    assert "Traceback" not in result.stderr + result.stdout
    assert result.returncode == 2, result.stderr
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.startswith("xcheck: error: ")
    for needle in needles:
        assert needle in line, f"{needle!r} not in {line!r}"
    return line


# -- cases of a broken file ------------------------------------------------------
# (id, text, field, parts of `expected`, parts of `found`)


def _one_driver_arm() -> str:
    head, tail = ARM.split('[[drivers]]\nname = "theta2"')
    text = head + "[assembly]" + tail.split("[assembly]")[1]
    text = sub(text, "at = { theta1 = 30, theta2 = 30 }", "at = { theta1 = 30 }")
    return sub(text, "theta1 = 30\ntheta2 = 30\n", "theta1 = 30\n")


def _extra_driver_fourbar() -> str:
    text = FOURBAR.split("[[instants]]")[0]
    return sub(text, "[assembly]", '[[drivers]]\nname = "rocker"\njoint = "D"\nstart = 70\nrate = 0\n\n[assembly]')


CASES = [
    pytest.param(
        sub(FOURBAR, 'type = "revolute"', 'type = "hinge"'),
        "joints[0].type",
        ["'revolute'", "'prismatic'", "'pin-in-slot'"],
        ["'hinge'"],
        id="unknown-joint-type",
    ),
    pytest.param(
        sub(FOURBAR, 'bodies = ["crank", "coupler"]', 'bodies = ["crank", "couplr"]'),
        "joints[1].bodies[1]",
        ["a body", "ground, crank, coupler, rocker"],
        ["'couplr'"],
        id="joint-unknown-body",
    ),
    pytest.param(
        sub(FOURBAR, 'bodies = ["crank", "coupler"]', 'bodies = ["crank", ["coupler"]]'),
        "joints[1].bodies[1]",
        ["a body"],
        ["['coupler']"],
        id="joint-body-not-a-string",
    ),
    pytest.param(
        sub(FOURBAR, 'point = "B"', 'point = "K"'),
        "joints[1].point",
        ["a point of crank (A, B)"],
        ["'K'"],
        id="joint-unknown-point",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", "length = 0"),
        "bodies.rocker.length",
        ["a positive number"],
        ["0"],
        id="zero-length",
    ),
    pytest.param(
        sub(FOURBAR, "length = 450", "length = -450"),
        "bodies.crank.length",
        ["a positive number"],
        ["-450"],
        id="negative-length",
    ),
    pytest.param(
        sub(
            sub(SLIDER, "E = [0, 40] }", "E = [0, 40], E2 = [0, 40] }"),
            'line = "E"\ndirection = 0',
            'line = ["E", "E2"]',
        ),
        "joints[3].line",
        ["two points at different positions"],
        ["E and E2 coincide"],
        id="prismatic-line-coincident-points",
    ),
    pytest.param(
        sub(FOURBAR, 'ends = ["D", "C"]\nlength = 500', "points = { D = [0, 0], C = [0, 0] }"),
        "bodies.rocker.points.D",
        ["apart from", "'C'", "non-zero length"],
        ["C and D coincide"],
        id="zero-length-link-by-points",
    ),
    pytest.param(
        sub(FOURBAR, "D = [600, 0]", "D = [0, 0]"),
        "ground.points.D",
        ["apart from", "'A'", "non-zero length"],
        ["A and D coincide"],
        id="zero-length-ground-link",
    ),
    pytest.param(
        re.sub(r"\[\[drivers\]\].*?\n\n", "", FOURBAR, count=1, flags=re.S),
        "drivers",
        ["[[drivers]]"],
        ["none"],
        id="no-drivers-section",
    ),
    pytest.param(
        _one_driver_arm(),
        "drivers",
        ["2 driver(s)", "degree of freedom", "Grübler count 2"],
        ["1"],
        id="too-few-drivers",
    ),
    pytest.param(
        _extra_driver_fourbar(),
        "drivers",
        ["1 driver(s)", "degree of freedom", "Grübler count 1"],
        ["2"],
        id="too-many-drivers",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", "length = 50"),
        "assembly.at",  # a rocker too short to close the loop: not the sketch's fault
        ["an input at which every loop closes"],
        ["crank = 30 deg", "the loop ground - rocker - coupler - crank - ground cannot close", "rocker D-C 50"],
        id="link-too-short-to-close",
    ),
    pytest.param(
        FOURBAR + "\n[extras]\nsize = 1\n",
        "extras",
        ["one of the keys", "mechanism", "instants"],
        ["unknown key 'extras'"],
        id="unknown-top-level-key",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", "lenght = 500"),
        "bodies.rocker.lenght",
        ["one of the keys", "length"],
        ["unknown key 'lenght'"],
        id="unknown-body-key",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", 'length = "five hundred"'),
        "bodies.rocker.length",
        ["a number or an arithmetic expression"],
        ["'five hundred'"],
        id="non-numeric-string",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", "length = true"),
        "bodies.rocker.length",
        ["a number"],
        ["True"],
        id="boolean-number",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", 'length = "600/sqrt("'),
        "bodies.rocker.length",
        ["a number or an arithmetic expression"],
        ["'600/sqrt('", "was never closed"],
        id="invalid-expression",
    ),
    pytest.param(
        sub(FOURBAR, "length = 500", 'length = "(-1)**0.5"'),
        "bodies.rocker.length",
        ["a number or an arithmetic expression"],
        ["'(-1)**0.5'", "not a real number"],
        id="complex-expression",
    ),
    pytest.param(
        sub(FOURBAR, "points = { K = [0, 0], F = [0, 200] }", "points = { K = [0, 0], F = [0, 200], D = [0, 100] }"),
        "joints",
        ["a revolute joint at 'D' between ground and coupler"],
        ["rename one of the points"],
        id="shared-label-without-revolute",
    ),
    pytest.param(
        sub(FOURBAR, 'joint = "A"', 'joint = ["A"]'),
        "drivers[0].joint",
        ["a joint (A, B, C, D)"],
        ["['A']"],
        id="driver-joint-not-a-string",
    ),
    pytest.param(
        sub(
            FOURBAR, 'ends = ["D", "C"]\nlength = 500', 'sketch = { D = [600, 0], C = [680, 470] }\naxis = [["D"], "C"]'
        ),
        "bodies.rocker.axis",
        ["two labels of the sketch (D, C)"],
        ["[['D'], 'C']"],
        id="axis-label-not-a-string",
    ),
    pytest.param(
        sub(ARM, 'rate = "10/sqrt(2)"', "rate = 1e300"),
        "drivers[1].rate",
        ["stay within 1e+100", "cannot overflow"],
        ["1e+300"],
        id="motion-law-overflows",
    ),
    pytest.param(
        sub(FOURBAR, 'title = "Four-bar linkage with a perpendicular member KF on the coupler"', "title = 5"),
        "mechanism.title",
        ["a non-empty string"],
        ["5"],
        id="title-not-a-string",
    ),
]


@pytest.mark.parametrize(("text", "field", "expected", "found"), CASES)
def test_library_names_field(tmp_path, text, field, expected, found):
    err = library_error(write(tmp_path, text))
    assert err.field == field
    for part in expected:
        assert part in err.expected, f"{part!r} not in {err.expected!r}"
    for part in found:
        assert part in err.found, f"{part!r} not in {err.found!r}"


@pytest.mark.parametrize(("text", "field", "expected", "found"), CASES)
def test_cli_one_line(tmp_path, text, field, expected, found):
    path = write(tmp_path, text)
    line = error_line(run_cli("solve", str(path)), f"{path}: {field}: expected ", *expected, *found)
    assert line.startswith(f"xcheck: error: {path}: {field}: ")


# -- the file as a whole ---------------------------------------------------------


def test_toml_syntax_error_names_line_and_column(tmp_path):
    text = sub(FOURBAR, "length = 450\n", "length = = 450\n")
    line_no = text.splitlines().index("length = = 450") + 1
    path = write(tmp_path, text)
    err = library_error(path)
    assert err.field == f"line {line_no}, column 10"
    assert err.expected == "valid TOML"
    assert err.found == "a syntax error: Invalid value"
    error_line(run_cli("solve", str(path)), f"{path}: line {line_no}, column 10: expected valid TOML", "Invalid value")


def test_toml_syntax_error_at_end_of_document(tmp_path):
    path = write(tmp_path, FOURBAR + "\nnotes = [1, 2")
    err = library_error(path)
    assert err.field == "end of document"
    assert err.expected == "valid TOML"
    assert err.found == "a syntax error: Unclosed array"
    error_line(run_cli("solve", str(path)), f"{path}: end of document: expected valid TOML", "Unclosed array")


def test_missing_file(tmp_path):
    path = tmp_path / "missing.toml"
    err = library_error(path)
    assert err.field == ""
    assert err.expected == "a readable mechanism file"
    assert "No such file" in err.found
    error_line(run_shell("solve", str(path)), str(path), "expected a mechanism file", "no such file")


def test_file_not_utf8(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(FOURBAR.encode("utf-8").replace("Računalna".encode("utf-8"), b"Ra\xe8unalna"))
    err = library_error(path)
    assert err.expected == "a UTF-8 text file"
    assert "not UTF-8" in err.found
    error_line(run_shell("solve", str(path)), str(path), "expected a UTF-8 text file")


# -- inputs outside the feasible range -------------------------------------------

RANGE = re.compile(r"crank: -129\.02\d* … 129\.02\d* deg")


def test_instant_outside_range(tmp_path):
    path = write(tmp_path, sub(FOURBAR, "crank = 120\n", "crank = 150\n"))
    kin = Kinematics(load_mechanism(path))  # the file itself is valid
    rng = kin.input_range("crank")
    assert math.degrees(rng.low) == pytest.approx(-129.02, abs=0.01)
    assert math.degrees(rng.high) == pytest.approx(129.02, abs=0.01)
    assert not rng.contains(math.radians(150))
    line = error_line(
        run_cli("solve", str(path)), f"{path}: instants[2].crank: expected ", "feasible range", "found 150 deg"
    )
    assert RANGE.search(line), line


def test_at_outside_range():
    line = error_line(
        run_cli("solve", "fourbar", "--at", "150", "--models", str(MODELS)),
        "fourbar.toml",
        "--at crank",
        "feasible range",
        "found 150 deg",
    )
    assert RANGE.search(line), line


# -- requests on the command line --------------------------------------------------


def test_unknown_mechanism_lists_known_names():
    line = error_line(run_cli("solve", "nosuch", "--models", str(MODELS)), "'nosuch'", "expected one of")
    for name in KNOWN:
        assert name in line


def test_at_wrong_number_of_values():
    error_line(
        run_cli("solve", "two-body-arm", "--at", "30", "--models", str(MODELS)),
        "two-body-arm.toml: --at: expected 2 value(s) per state separated by ':'",
        "theta1:theta2",
        "found '30'",
    )
    error_line(
        run_cli("solve", "two-body-arm", "--at", "30:30:30", "--models", str(MODELS)),
        "two-body-arm.toml: --at: expected 2 value(s)",
        "found '30:30:30'",
    )


def test_at_not_a_number():
    error_line(
        run_cli("solve", "two-body-arm", "--at", "30:abc", "--models", str(MODELS)),
        "two-body-arm.toml: --at theta2: expected a number or an arithmetic expression",
        "found 'abc'",
    )
    error_line(
        run_cli("solve", "fourbar", "--at", "(-1)**0.5", "--models", str(MODELS)),
        "fourbar.toml: --at crank: expected a number",
        "not a real number",
    )


def test_at_motion_law_overflows(tmp_path):
    """A rate whose products overflow is refused at load, --at or not (it used to
    solve with status ok and every acceleration null)."""
    text = sub(ARM, 'rate = "10/sqrt(2)"', "rate = 1e300").split("[[instants]]")[0]
    path = write(tmp_path, text)
    error_line(
        run_cli("solve", str(path), "--at", "40:30"),
        f"{path}: drivers[1].rate: expected a motion whose speeds",
        "found 1e+300",
    )


def test_coordinates_beyond_the_magnitude_limit_are_refused(tmp_path):
    path = write(tmp_path, FOURBAR.replace("length = 450\n", "length = 1e250\n", 1))
    error_line(run_cli("solve", str(path)), f"{path}: bodies.", "expected coordinates within 1e+100 m")


def test_unknown_branch():
    error_line(
        run_cli("solve", "fourbar", "--branch", "middle", "--models", str(MODELS)),
        "fourbar.toml: assembly.branches: expected a branch named one of upper, lower",
        "found 'middle'",
    )


def test_list_reports_each_bad_file_on_one_line(tmp_path):
    (tmp_path / "fourbar.toml").write_text(FOURBAR, encoding="utf-8")
    bad = write(tmp_path, sub(FOURBAR, "length = 500", "lenght = 500"))
    result = run_cli("list", "--models", str(tmp_path))
    assert "Traceback" not in result.stderr + result.stdout
    assert result.returncode == 2
    assert "fourbar" in result.stdout  # the good file is still listed
    assert result.stderr.splitlines() == [
        f"xcheck: error: {bad}: bodies.rocker.lenght: expected one of the keys points, ends, length, "
        "sketch, axis, mass, com, inertia, found unknown key 'lenght'"
    ]
