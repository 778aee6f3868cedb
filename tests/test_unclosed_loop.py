"""An input at which a loop cannot close names the loop, how far it stays open and
the lengths around it, instead of blaming the branch sketch."""

from __future__ import annotations

import math

import pytest
from conftest import DATA, ROOT

import xcheck

FOURBAR = DATA / "crank-cannot-turn.toml"  # ground A-D 60, crank 40, coupler 30, rocker 50 mm


def _message(path) -> str:
    with pytest.raises(xcheck.ModelError) as caught:
        xcheck.load(path)
    return str(caught.value)


def test_a_crank_position_the_four_bar_cannot_reach(tmp_path):
    """At crank = 180 deg, B is 40 + 60 = 100 mm from D, but coupler and rocker
    reach 30 + 50 = 80 mm: the loop stays 20 mm open."""
    text = FOURBAR.read_text(encoding="utf-8").replace("at = { crank = 60 }", "at = { crank = 180 }")
    path = tmp_path / "unreachable.toml"
    path.write_text(text.replace("C = [47, 48]", "C = [-20, 25]"), encoding="utf-8")
    message = _message(path)
    assert message.startswith(f"{path}: assembly.at: expected an input at which every loop closes, found crank = 180")
    assert "the loop ground - rocker - coupler - crank - ground cannot close" in message
    assert "its joints stay 20 mm apart in all at best" in message
    assert "(mm): ground A-D 60, rocker D-C 50, coupler C-B 30, crank B-A 40" in message
    assert "sketch" not in message


def test_a_link_too_short_for_the_assembly_input(tmp_path):
    """models/fourbar.toml with a rocker of 50 mm instead of 500: at crank = 30 deg
    B = 450 (cos 30, sin 30) lies |BD| from D = (600, 0), and coupler (450) and
    rocker (50) close only where |BD| >= 400."""
    text = (ROOT / "models" / "fourbar.toml").read_text(encoding="utf-8")
    path = tmp_path / "short-rocker.toml"
    path.write_text(text.replace("length = 500", "length = 50"), encoding="utf-8")
    bd = math.dist((450 * math.cos(math.radians(30)), 450 * math.sin(math.radians(30))), (600, 0))
    message = _message(path)
    assert f"its joints stay {400 - bd:.3g} mm apart in all at best" in message  # 92 mm
    assert "rocker D-C 50" in message


def test_the_open_loop_of_a_six_bar_is_the_one_named(tmp_path):
    """A dyad u-w of 20 + 20 mm hung from the crank-rocker's coupler point P to a
    ground point E 300 mm away cannot reach it: the loop through the dyad is named,
    not the four-bar's, which closes."""
    text = (ROOT / "docs" / "examples" / "crank-rocker.toml").read_text(encoding="utf-8")
    text = text.replace("points = { A = [0, 0], D = [80, 0] }", "points = { A = [0, 0], D = [80, 0], E = [300, 0] }")
    dyad = '[bodies.u]\nends = ["P", "G"]\nlength = 20\n\n[bodies.w]\nends = ["E", "G"]\nlength = 20\n\n' + "".join(
        f'[[joints]]\ntype = "revolute"\nbodies = ["{a}", "{b}"]\npoint = "{p}"\n\n'
        for a, b, p in (("coupler", "u", "P"), ("u", "w", "G"), ("ground", "w", "E"))
    )
    text = text.replace("[[drivers]]", dyad + "[[drivers]]").replace("C = [100, 60]", "C = [100, 60]\nG = [150, 50]")
    path = tmp_path / "sixbar.toml"
    path.write_text(text, encoding="utf-8")
    message = _message(path)
    assert "assembly.at: expected an input at which every loop closes, found crank = 0 deg" in message
    loop = message.split("where the loop ")[1].split(" cannot close")[0].split(" - ")
    assert {"u", "w", "coupler", "ground"} <= set(loop) and "rocker" not in loop
    assert "u P-G 20, w G-E 20" in message
