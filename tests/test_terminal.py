"""What the terminal shows: units in brackets survive rich's markup (issue 16)."""

from __future__ import annotations

from conftest import MODELS, invoke


def test_solve_tables_keep_their_units():
    done = invoke("solve", "fourbar", "--at", "45", "--models", str(MODELS))
    assert done.returncode == 0, done.stderr
    for header in ("x [mm]", "y [mm]", "φ [deg]", "vx [m/s]", "ax [m/s^2]", "α [rad/s^2]", "Fx [N]", "power [W]"):
        assert header in done.stdout, header
