"""What the drawings show (issue 16): blocks on prismatic joints, pins inside
their slots, bodies as links between their joints, hatched ground, labelled
points and the inputs' arrows."""

from __future__ import annotations

import numpy as np
from conftest import MODELS
from matplotlib import patches

import xcheck
from xcheck.drawing import COLORS, Pose
from xcheck.states import given_inputs


def _drawn(name: str, at=None):
    mech = xcheck.load(name, models=MODELS)
    figure = mech.draw(at=at)
    ax = figure.axes[0]
    c = mech.kinematics.reference_inputs()[None] if at is None else given_inputs(mech.kinematics, at)
    solved = Pose.of(mech.kinematics.solve(c, branch=mech.branch), 0)
    scale = mech.mechanism.units.length_factor  # drawings are in the file's length unit

    def point(body: str, label: str) -> np.ndarray:
        return solved.point(body, label) / scale

    color = {b.name: COLORS[n % len(COLORS)] for n, b in enumerate(mech.mechanism.moving_bodies)}
    return mech, ax, point, color


def _segments(ax, color: str, width: float):
    return [
        np.column_stack(line.get_data()).astype(float)
        for line in ax.get_lines()
        if line.get_color() == color and line.get_linewidth() == width
    ]


def test_a_block_sits_on_the_swivel_of_task_2_1():
    mech, ax, point, color = _drawn("task-2-1", at=40)
    e = point("block", "E")
    blocks = [
        p
        for p in ax.patches
        if isinstance(p, patches.Polygon)
        and p.get_facecolor()[:3] == patches.Polygon([[0, 0]], facecolor=color["block"]).get_facecolor()[:3]
    ]
    assert blocks, "no block drawn"
    corners = blocks[0].get_xy()[:4]
    assert np.allclose(corners.mean(axis=0), e, atol=1e-12)
    # its long side along link 5, which slides through it
    along = corners[1] - corners[0]
    axis = point("link5", "M") - point("link5", "B")
    assert abs(along[0] * axis[1] - along[1] * axis[0]) <= 1e-9 * np.hypot(*along) * np.hypot(*axis)


def test_the_pins_of_task_2_2_sit_inside_their_slot():
    mech, ax, point, color = _drawn("task-2-2", at=0.5)
    sides = _segments(ax, color["lever"], 1.4)
    assert len(sides) == 2  # one slot for both pins (two joints on one line)
    for label, body in (("B", "slider"), ("E", "link6")):
        pin = point(body, label)
        signs = []
        for side in sides:
            a, b = side
            cross = (b[0] - a[0]) * (pin[1] - a[1]) - (b[1] - a[1]) * (pin[0] - a[0])
            signs.append(np.sign(cross))
            t = np.dot(pin - a, b - a) / np.dot(b - a, b - a)
            assert 0.0 < t < 1.0, f"pin {label} past the end of its slot"
        assert signs[0] == -signs[1], f"pin {label} outside its slot"
        circles = [p for p in ax.patches if isinstance(p, patches.Circle) and np.allclose(p.center, pin, atol=1e-12)]
        assert circles, f"no pin drawn at {label}"


def test_bodies_are_links_between_their_joints_not_hulls():
    mech, ax, point, color = _drawn("fourbar", at=60)
    drawn = {frozenset(tuple(np.round(p, 9)) for p in segment) for segment in _segments(ax, color["coupler"], 3.0)}
    b, c = point("coupler", "B"), point("coupler", "C")
    k, f = point("coupler", "K"), point("coupler", "F")

    def edge(p, q):
        return frozenset({tuple(np.round(p, 9)), tuple(np.round(q, 9))})

    assert edge(b, c) in drawn
    assert edge(k, f) in drawn  # F on its stub from K (its foot on BC), not a hull's corner
    assert edge(b, f) not in drawn and edge(c, f) not in drawn


def test_ground_is_hatched_points_labelled_and_the_input_has_an_arrow():
    mech, ax, point, color = _drawn("slider-crank", at=30)
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) >= 2  # the pivot O and the slider's guide
    texts = {t.get_text() for t in ax.texts}
    assert set(mech.mechanism.point_owners) <= texts
    arrows = [p for p in ax.patches if isinstance(p, patches.FancyArrowPatch)]
    assert len(arrows) == 1 and "crank" in texts


def test_a_label_takes_the_side_clearest_of_the_links_and_the_labels_placed():
    from matplotlib.figure import Figure

    from xcheck.drawing import PoseArtists, _clear_label

    ax = Figure().add_subplot()
    drawn = PoseArtists(ax)
    taken: list = []
    _clear_label(drawn, "A", np.zeros(2), [], taken, 1.0, {})  # nothing near: the first side, up and right
    _clear_label(drawn, "B", np.zeros(2), [], taken, 1.0, {})  # A's place taken: the side farthest from it
    link = [(np.array([-10.0, 50.0]), np.array([10.0, 50.0]))]  # through C, level: above it (before below)
    _clear_label(drawn, "C", np.array([0.0, 50.0]), link, taken, 1.0, {})
    sides = {t.get_text(): (t.get_ha(), t.get_va()) for t in ax.texts}
    assert sides == {"A": ("left", "bottom"), "B": ("right", "top"), "C": ("center", "bottom")}
    assert np.allclose(ax.texts[0].xyann, [np.sqrt(0.5), np.sqrt(0.5)])
    assert len(taken) == 3


def _pixels(figure) -> np.ndarray:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return np.array(canvas.buffer_rgba())


def test_a_pose_drawn_in_place_of_another_is_the_picture_of_a_fresh_drawing():
    """On axes whose view is fixed, the next pose moves the artists of the one
    it replaces (a slot's arcs, pins, blocks, labels) and gives the pixels of
    that pose drawn anew; where an artist's style changes (the input's arrow
    turns the other way) the rest are made anew in the same order; on axes that
    autoscale, every old artist goes."""
    from matplotlib.figure import Figure

    from xcheck.drawing import draw_pose, guide_extents

    mech = xcheck.load("task-2-2", models=MODELS)
    solution = mech.solve(at=[0.2, 0.6, 1.0]).solution  # the slider's height, m
    extents = guide_extents(solution)
    driver = mech.mechanism.drivers[0].name

    def axes():
        ax = Figure(figsize=(3, 3), dpi=50).add_subplot()
        ax.set_xlim(-0.2, 1.2)
        ax.set_ylim(-0.2, 1.4)
        return ax

    moved = axes()
    first = draw_pose(moved, Pose.of(solution, 0), extents, arrows={driver: 1.0})
    before = moved.get_children()  # held: no id is reused while they live
    second = draw_pose(moved, Pose.of(solution, 1), extents, arrows={driver: 1.0}, replacing=first)
    assert set(map(id, moved.get_children())) == set(map(id, before))  # every artist moved, none made
    fresh = axes()
    draw_pose(fresh, Pose.of(solution, 1), extents, arrows={driver: 1.0})
    assert np.array_equal(_pixels(moved.figure), _pixels(fresh.figure))

    draw_pose(moved, Pose.of(solution, 2), extents, arrows={driver: -1.0}, replacing=second)
    fresh = axes()
    draw_pose(fresh, Pose.of(solution, 2), extents, arrows={driver: -1.0})
    assert np.array_equal(_pixels(moved.figure), _pixels(fresh.figure))
    assert len(moved.get_children()) == len(fresh.get_children())

    growing = Figure().add_subplot()
    first = draw_pose(growing, Pose.of(solution, 0), extents)
    old = first.artists  # held: no id is reused while they live
    draw_pose(growing, Pose.of(solution, 1), extents, replacing=first)
    assert old and not set(map(id, growing.get_children())) & set(map(id, old))
