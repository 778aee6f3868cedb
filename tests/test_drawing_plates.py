"""Drawings: a body of three or more points not in one line is a plate (a
Jansen foot D-F-G, whose G is no joint, was two bars with a side missing), and
labels stand clear of the links."""

from __future__ import annotations

import numpy as np
from conftest import MODELS
from matplotlib import patches

import xcheck
from xcheck.drawing import _nearest_on_segments


def _figure(name: str, at: float):
    return xcheck.load(name, models=MODELS).draw(at=at)


def test_a_body_with_a_point_off_its_bar_is_a_plate(tmp_path):
    """A Jansen-like foot: a link with joints at D and F and its foot G off the
    line D-F, attached nowhere else: drawn as the plate D, F, G. (The four-bar's
    coupler, whose F hangs from the named point K on B-C, stays a bar with a
    member K-F: tests/test_drawing.py.)"""
    text = (MODELS.parent / "docs" / "examples" / "crank-rocker.toml").read_text(encoding="utf-8")
    text = text.replace("length = 70\n", "length = 70\npoints = { G = [10, -30] }\n")  # the rocker's foot
    path = tmp_path / "foot.toml"
    path.write_text(text, encoding="utf-8")
    mech = xcheck.load(path)
    figure = mech.draw()
    solved = mech.solve(at=0).to_frame()
    where = {row.name: (row.x_m * 1000, row.y_m * 1000) for row in solved[solved.kind == "point"].itertuples()}
    plates = [p for p in figure.axes[0].patches if isinstance(p, patches.Polygon) and p.get_fill() and p.get_alpha()]
    corners = [sorted(map(tuple, np.round(p.get_xy()[:-1], 6))) for p in plates]
    assert sorted(tuple(np.round(where[label], 6)) for label in ("D", "C", "G")) in corners


def test_labels_stand_clear_of_the_links():
    """Every point's label is placed off the links: the text's anchor is farther
    from every drawn bar than from its own point's pin."""
    figure = _figure("task-2-1", 40)
    ax = figure.axes[0]
    bars = [
        (np.array([line.get_xdata()[0], line.get_ydata()[0]]), np.array([line.get_xdata()[1], line.get_ydata()[1]]))
        for line in ax.get_lines()
        if line.get_linewidth() == 3.0 and len(line.get_xdata()) == 2
    ]
    assert bars
    for text in ax.texts:
        anchor = np.asarray(text.xyann, dtype=float)
        point = np.asarray(text.xy, dtype=float)
        gap = float(np.hypot(*(anchor - point)))
        clear = float(np.hypot(*(anchor - _nearest_on_segments(anchor, bars))))
        assert clear >= 0.5 * gap, (text.get_text(), clear, gap)
