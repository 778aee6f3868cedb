"""What the terminal shows: units in brackets survive rich's markup (issue 16)."""

from __future__ import annotations

from conftest import MODELS, invoke


def test_solve_tables_keep_their_units():
    done = invoke("solve", "fourbar", "--at", "45", "--models", str(MODELS))
    assert done.returncode == 0, done.stderr
    for header in ("x [mm]", "y [mm]", "φ [deg]", "vx [m/s]", "ax [m/s^2]", "α [rad/s^2]", "Fx [N]", "power [W]"):
        assert header in done.stdout, header


def test_printed_answers_are_shown_at_the_books_instants_or_on_request():
    at_45 = invoke("solve", "fourbar", "--at", "45", "--models", str(MODELS))
    assert at_45.returncode == 0 and "Printed answers" not in at_45.stdout
    asked = invoke("solve", "fourbar", "--at", "45", "--textbook", "--models", str(MODELS))
    assert asked.returncode == 0 and "Printed answers" in asked.stdout
    book = invoke("solve", "fourbar", "--models", str(MODELS))
    assert book.returncode == 0 and "Printed answers" in book.stdout
