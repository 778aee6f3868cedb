"""Drawings of a mechanism in one position: bodies as links between their
joints, blocks on sliders and swivels, pins in their slots, hatched ground,
labelled points and the inputs' arrows.

Matplotlib is used through :class:`matplotlib.figure.Figure` only (no pyplot,
no backend is chosen), so that the figures work in scripts, notebooks and the
reports alike.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import patches
from matplotlib.figure import Figure

from .errors import InputError
from .fileio import write_atomic
from .joints import GearPair, LineJoint
from .kinematics import Solution, rotate
from .model import Mechanism, PinInSlot, Prismatic, Revolute

__all__ = ["Pose", "PoseArtists", "draw_pose", "figure_of", "guide_extents", "check_png_name", "save_png"]

#: body colours (matplotlib's tab10, ground black)
COLORS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)


@dataclass
class Pose:
    """One position of a mechanism: each body's frame (origin (2,) m, angle rad).

    Build it with :meth:`of` from a :class:`~xcheck.kinematics.Solution`.
    """

    mechanism: Mechanism
    frames: dict[str, tuple[np.ndarray, float]]

    @classmethod
    def of(cls, solution: Solution, i: int) -> "Pose":
        """Sample ``i`` of a solution."""
        frames = {solution.mechanism.ground.name: (np.zeros(2), 0.0)}
        for body in solution.mechanism.moving_bodies:
            state = solution.body(body.name)
            frames[body.name] = (state["position"][i], float(state["angle"][i]))
        return cls(solution.mechanism, frames)

    def point(self, body: str, label: str) -> np.ndarray:
        """World position of a body's named point, (2,) m."""
        r, phi = self.frames[body]
        return r + rotate(np.array([phi]), self.mechanism.body(body).points[label])[0]

    def direction(self, body: str, local: np.ndarray) -> np.ndarray:
        """A direction fixed in a body, in world axes, (2,)."""
        return rotate(np.array([self.frames[body][1]]), local)[0]


def _line_joints(mech: Mechanism):
    return [j for j in mech.joints if isinstance(j, (Prismatic, PinInSlot))]


def guide_extents(solution: Solution) -> dict[str, tuple[float, float]]:
    """Per line joint, the range of its slide (m along the line from its line
    point) over every determined sample of a solution: how long to draw the
    guides and slots so that they hold the blocks and pins at every pose."""
    good = solution.status <= 1
    extents = {}
    for joint in _line_joints(solution.mechanism):
        if not good.any():
            break
        phi = solution.body(joint.body_a)["angle"][good]
        d = rotate(phi, joint.direction)
        gap = (
            solution.point(joint.point, joint.body_b)["position"][good]
            - solution.point(joint.line_point, joint.body_a)["position"][good]
        )
        slides = np.einsum("ij,ij->i", d, gap)
        extents[joint.name] = (float(slides.min()), float(slides.max()))
    return extents


def _joint_labels(mech: Mechanism) -> dict[str, list[str]]:
    """Per body, the labels of its points that joints use (in joint order)."""
    used: dict[str, list[str]] = {b.name: [] for b in (mech.ground, *mech.moving_bodies)}
    for joint in mech.joints:
        pairs = list(joint.anchors())  # a line's point places it: the body's link runs to it too
        pairs += [(joint.body_a, joint.line_point)] if isinstance(joint, LineJoint) else []
        for body, label in pairs:
            if label not in used[body]:
                used[body].append(label)
    return used


def _nearest_points(points: np.ndarray, segments: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """For each of ``points`` (k, 2), the nearest point of each segment, (k, n, 2)."""
    a = np.array([segment[0] for segment in segments], dtype=float).reshape(-1, 2)
    ab = np.array([segment[1] for segment in segments], dtype=float).reshape(-1, 2) - a
    length2 = ab[:, 0] * ab[:, 0] + ab[:, 1] * ab[:, 1]
    gap = np.asarray(points, dtype=float)[:, None, :] - a
    along = gap[..., 0] * ab[:, 0] + gap[..., 1] * ab[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(length2 > 0.0, np.clip(along / np.where(length2 > 0.0, length2, 1.0), 0.0, 1.0), 0.0)
    return a + t[..., None] * ab


def _nearest_on_segments(p: np.ndarray, segments: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The point of a set of segments nearest p, (2,)."""
    assert segments
    q = _nearest_points(np.asarray(p)[None, :], segments)[0]
    return q[int(np.argmin(np.hypot(*(p - q).T)))]  # the first of equals


def _hull_order(points: np.ndarray) -> np.ndarray:
    """Indices of points in counter-clockwise order around their centre."""
    centre = points.mean(axis=0)
    return np.argsort(np.arctan2(points[:, 1] - centre[1], points[:, 0] - centre[0]))


def _convex_hull(points: np.ndarray, tolerance: float) -> np.ndarray:
    """The corners of the points' convex hull, counter-clockwise (Andrew's
    monotone chain); a point within ``tolerance`` (area units) of an edge is no corner."""
    ordered = sorted(map(tuple, points))

    def half(sequence):
        chain: list = []
        for q in sequence:
            while len(chain) >= 2:
                (ax_, ay), (bx, by) = chain[-2], chain[-1]
                if (bx - ax_) * (q[1] - ay) - (by - ay) * (q[0] - ax_) > tolerance:
                    break
                chain.pop()
            chain.append(q)
        return chain[:-1]

    return np.array(half(ordered) + half(ordered[::-1]))


def _on_a_named_point(q: np.ndarray, named: list[np.ndarray], size: float) -> bool:
    """Whether ``q`` is one of a body's named points (to 1e-9 of the size)."""
    return any(float(np.hypot(*(q - p))) <= 1e-9 * size for p in named)


def _plate(points: np.ndarray, size: float) -> np.ndarray | None:
    """The corners of a body's plate: its points' convex hull where three or
    more of them are not in one line (an area above 1e-4 of the size squared),
    else None (a bar)."""
    if len(points) < 3:
        return None
    ring = _convex_hull(points, 1e-9 * size * size)
    if len(ring) < 3:
        return None
    x, y = ring[:, 0], ring[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    return ring if area > 1e-4 * size * size else None


#: the directions a label may take from its point, in order of preference when as clear
_LABEL_DIRECTIONS = np.array([[math.cos(a), math.sin(a)] for a in np.radians([45, 135, 315, 225, 90, 0, 270, 180])])


def _clear_label(
    drawn: "PoseArtists", text: str, p: np.ndarray, segments, taken: list[np.ndarray], gap: float, style: dict
) -> None:
    """Write ``text`` beside point ``p`` (drawing units) on the side farthest
    from the drawn links (``segments``) and the labels already placed
    (``taken``, which this one joins), ``gap`` away from the point."""
    spots = p + 1.6 * gap * _LABEL_DIRECTIONS  # where each direction's label would stand, (8, 2)
    clearance = np.full(len(spots), math.inf)
    if len(segments):
        gaps = spots[:, None, :] - _nearest_points(spots, segments)
        clearance = np.fmin(clearance, np.hypot(gaps[..., 0], gaps[..., 1]).min(axis=1))
    if taken:
        gaps = spots[:, None, :] - np.array(taken)
        clearance = np.fmin(clearance, np.hypot(gaps[..., 0], gaps[..., 1]).min(axis=1))
    clearest = int(np.argmax(clearance))  # the first of equals
    best = _LABEL_DIRECTIONS[clearest]
    taken.append(spots[clearest])
    drawn.label(
        text,
        p,
        p + gap * best,
        "left" if best[0] > 0.3 else "right" if best[0] < -0.3 else "center",
        "bottom" if best[1] > 0.3 else "top" if best[1] < -0.3 else "center",
        **style,
    )


def _add_patch(ax, patch: patches.Patch) -> None:
    """Add a patch to the axes; where its view is fixed (autoscaling off both
    ways, as on the frames of an animation), without growing its data limits,
    which nothing then reads and which cost a third of drawing a pose."""
    if _view_fixed(ax):
        ax.add_artist(patch)
    else:
        ax.add_patch(patch)


def _view_fixed(ax) -> bool:
    """Whether the axes' limits are fixed (autoscaling off both ways)."""
    return not (ax.get_autoscalex_on() or ax.get_autoscaley_on())


def _arc(centre, diameter: float, theta1: float, theta2: float, **style) -> patches.Arc:
    """A circular arc from ``theta1`` to ``theta2`` (degrees)."""
    return patches.Arc(centre, diameter, diameter, theta1=theta1, theta2=theta2, **style)


def _move_arc(arc: patches.Arc, centre, diameter: float, theta1: float, theta2: float) -> None:
    """Move an arc of :func:`_arc` to new geometry."""
    arc.set_center(centre)
    arc.set_width(diameter)
    arc.set_height(diameter)
    arc.theta1, arc.theta2 = theta1, theta2  # read when it is drawn
    arc.stale = True


#: per kind of patch a pose draws, how one is moved to new geometry (the arguments that made it, but its style)
_MOVES: dict[object, Callable[..., object]] = {
    patches.Polygon: lambda polygon, corners: polygon.set_xy(corners),
    patches.Circle: lambda circle, centre, radius: (circle.set_center(centre), circle.set_radius(radius)),
    _arc: _move_arc,
    patches.FancyArrowPatch: lambda arrow, a, b: arrow.set_positions(a, b),
}


class PoseArtists:
    """The artists :func:`draw_pose` drew for one pose on an axes, in the order drawn.

    Given back to :func:`draw_pose` as ``replacing``, they give way to the next
    pose: on axes whose view is fixed (autoscaling off, as on the frames of an
    animation), each artist that the next pose draws again at the same place in
    the order, of the same kind and style, is moved to its new geometry instead
    of made anew (the same picture: the same artists in the same order); the
    others are removed. Elsewhere all are removed and the next pose made anew.
    """

    def __init__(self, ax, replacing: "PoseArtists | None" = None):
        self.ax = ax
        self._drawn: list[tuple[tuple, object]] = []
        self._old: list[tuple[tuple, object]] = []
        if replacing is not None:
            self._old = replacing._drawn
            if replacing.ax is not ax or not _view_fixed(ax):
                self._drop(0)

    @property
    def artists(self) -> list:
        """The artists drawn, in the order drawn."""
        return [artist for _, artist in self._drawn]

    def _drop(self, start: int) -> None:
        """Remove the old artists from ``start`` in the order on."""
        for _, artist in self._old[start:]:
            artist.remove()  # type: ignore[attr-defined]
        del self._old[start:]

    def _reused(self, key: tuple):
        """The old artist at this place in the order, if it has this kind and style, else None
        (and the old artists from here on removed, so that new ones keep the order)."""
        at = len(self._drawn)
        if at < len(self._old) and self._old[at][0] == key:
            return self._old[at][1]
        self._drop(at)
        return None

    def _add(self, key: tuple, artist) -> None:
        self._drawn.append((key, artist))

    def line(self, x, y, *fmt: str, **style) -> None:
        """A line through the points ``x``, ``y`` (sequences), as ``ax.plot`` draws it."""
        key = ("line", fmt, tuple(sorted(style.items())))
        line = self._reused(key)
        if line is None:
            (line,) = self.ax.plot(x, y, *fmt, **style)
        else:
            line.set_data(x, y)
        self._add(key, line)

    def label(self, text: str, point: np.ndarray, at: np.ndarray, ha: str, va: str, **style) -> None:
        """A point's label written at ``at`` (data), aligned ``ha``, ``va``."""
        key = ("label", text, tuple(sorted(style.items())))
        annotation = self._reused(key)
        if annotation is None:
            annotation = self.ax.annotate(text, point, xytext=at, textcoords="data", ha=ha, va=va, **style)
        else:
            annotation.xy = point
            annotation.set_position(at)
            annotation.set_horizontalalignment(ha)
            annotation.set_verticalalignment(va)
        self._add(key, annotation)

    def patch(self, kind, *geometry, **style) -> None:
        """A patch ``kind(*geometry, **style)``, ``kind`` one of :data:`_MOVES`."""
        key = (kind, tuple(sorted(style.items())))
        patch = self._reused(key)
        if patch is None:
            patch = kind(*geometry, **style)
            _add_patch(self.ax, patch)
        else:
            _MOVES[kind](patch, *geometry)
        self._add(key, patch)

    def finish(self) -> "PoseArtists":
        """Remove the old artists the pose did not reuse; returns itself."""
        self._drop(len(self._drawn))
        return self


def _hatched_strip(
    drawn: PoseArtists, start: np.ndarray, end: np.ndarray, side: np.ndarray, depth: float, z: float
) -> None:
    """Ground hatching: a line from start to end with a hatched strip of
    ``depth`` on the side ``side`` (unit vector)."""
    drawn.line([start[0], end[0]], [start[1], end[1]], color="black", lw=1.2, zorder=z)
    corners = np.array([start, end, end + depth * side, start + depth * side])
    drawn.patch(patches.Polygon, corners, closed=True, fill=False, hatch="////", lw=0, color="0.35", zorder=z)


def _block(
    drawn: PoseArtists,
    centre: np.ndarray,
    along: np.ndarray,
    length: float,
    height: float,
    color: str,
    z: float,
    alpha: float = 1.0,
) -> None:
    """A slide block centred at ``centre``, its long side along ``along``."""
    u = along / np.hypot(*along)
    n = np.array([-u[1], u[0]])
    corners = np.array(
        [centre + sx * 0.5 * length * u + sy * 0.5 * height * n for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    )
    drawn.patch(
        patches.Polygon, corners, closed=True, facecolor=color, edgecolor="black", alpha=0.85 * alpha, lw=1, zorder=z
    )


def draw_pose(
    ax,
    pose: Pose,
    extents: dict[str, tuple[float, float]] | None = None,
    scale: float = 1.0,
    alpha: float = 1.0,
    labels: bool = True,
    arrows: dict[str, float] | None = None,
    ground: bool = True,
    replacing: PoseArtists | None = None,
) -> PoseArtists:
    """Draw one position of the mechanism on a matplotlib axes.

    Parameters
    ----------
    ax : matplotlib Axes
    pose : Pose
    extents : dict, optional
        Per line joint, the slide range to draw its guide or slot over
        (:func:`guide_extents`); default: around the present position.
    scale : float
        Metres per drawing unit (the model's length unit: ``units.length_factor``).
    alpha : float
        Opacity of the bodies (ghost poses < 1).
    labels : bool
        Write the points' labels.
    arrows : dict of str to float, optional
        Per driver's name, the sign of its rate: an arrow shows the input
        (a curved one around a driven pin, a straight one along a slide).
    ground : bool
        Draw the ground's pivots, guides and hatching.
    replacing : PoseArtists, optional
        The artists of a pose drawn before on these axes, which this one
        replaces (reusing them where the view is fixed: :class:`PoseArtists`).

    Returns
    -------
    PoseArtists
        The artists drawn.
    """
    artists = PoseArtists(ax, replacing)
    mech = pose.mechanism
    gname = mech.ground.name
    every = [pose.point(b.name, lbl) for b in (mech.ground, *mech.moving_bodies) for lbl in b.points]
    span = np.ptp(np.array(every), axis=0).max() if len(every) > 1 else 1.0
    size = max(span, 1e-12)  # metres
    pin_r = 0.012 * size / scale
    block_l, block_h = 0.09 * size, 0.05 * size
    used = _joint_labels(mech)
    extents = extents or {}
    colors = {b.name: COLORS[n % len(COLORS)] for n, b in enumerate(mech.moving_bodies)}
    colors[gname] = "black"

    def w(xy):  # metres to drawing units
        return np.asarray(xy) / scale

    # guides and slots: the line of a line joint, drawn on its body_a (slots on
    # one line, like two pins in one guide, are one slot)
    segments: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {b.name: [] for b in mech.moving_bodies}
    stubs: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {b.name: [] for b in mech.moving_bodies}
    lines: dict[tuple, list] = {}
    for joint in _line_joints(mech):
        origin = pose.point(joint.body_a, joint.line_point)
        d = pose.direction(joint.body_a, joint.direction)
        now = float(d @ (pose.point(joint.body_b, joint.point) - origin))
        low, high = extents.get(joint.name, (now, now))
        key = (joint.body_a, joint.line_point, *np.round(joint.direction, 12), type(joint).__name__)
        if key in lines:
            entry = lines[key]
            entry[3], entry[4] = min(entry[3], low, now), max(entry[4], high, now)
        else:
            lines[key] = [joint, origin, d, min(low, now, 0.0), max(high, now, 0.0)]
    for joint, origin, d, low, high in lines.values():
        start, end = origin + (low - 0.5 * block_l) * d, origin + (high + 0.5 * block_l) * d
        if joint.body_a == gname:
            if ground:
                normal = np.array([-d[1], d[0]])
                offset = 0.5 * block_h * normal
                _hatched_strip(artists, w(start - offset), w(end - offset), -normal, 0.35 * block_h / scale, 1)
        elif isinstance(joint, PinInSlot):
            normal = np.array([-d[1], d[0]])
            for side in (-1, 1):
                a, b = w(start + side * 1.6 * pin_r * scale * normal), w(end + side * 1.6 * pin_r * scale * normal)
                artists.line([a[0], b[0]], [a[1], b[1]], color=colors[joint.body_a], lw=1.4, alpha=alpha, zorder=2)
            for cap, turn in ((start, 1.0), (end, -1.0)):
                angle = math.degrees(math.atan2(d[1], d[0])) + 90.0 * turn
                artists.patch(
                    _arc,
                    w(cap),
                    3.2 * pin_r,
                    angle,
                    angle + 180.0,
                    ec=colors[joint.body_a],
                    lw=1.4,
                    alpha=alpha,
                    zorder=2,
                )
            stubs[joint.body_a].append((start, end))
        else:  # a rod fixed in body_a along which body_b's block slides
            segments[joint.body_a].append((start, end))

    # bodies: links between their joints, plates for three or more, other points on stubs
    for body in mech.moving_bodies:
        color = colors[body.name]
        nodes = [pose.point(body.name, lbl) for lbl in used[body.name]]
        named = [pose.point(body.name, lbl) for lbl in body.points]
        bars = [(nodes[0], nodes[1])] if len(nodes) == 2 else []
        # a point off the bar whose foot on it is no named point (a Jansen foot's G off D-F) makes the body a
        # rigid plate; one whose foot is a named point (the four-bar's F above K on B-C) is a member from there
        loose = [
            p
            for lbl, p in zip(body.points, named)
            if bars and lbl not in used[body.name] and not _on_a_named_point(_nearest_on_segments(p, bars), named, size)
        ]
        corners = _plate(np.array(nodes + loose), size) if loose else None
        if corners is not None:
            ring = corners
            artists.patch(patches.Polygon, w(ring), closed=True, facecolor=color, alpha=0.15 * alpha, lw=0, zorder=2)
            segments[body.name] += [(ring[k], ring[(k + 1) % len(ring)]) for k in range(len(ring))]
        elif len(nodes) == 2:
            segments[body.name].append((nodes[0], nodes[1]))
        elif len(nodes) >= 3:
            ring = np.array(nodes)[_hull_order(np.array(nodes))]
            artists.patch(patches.Polygon, w(ring), closed=True, facecolor=color, alpha=0.15 * alpha, lw=0, zorder=2)
            segments[body.name] += [(ring[k], ring[(k + 1) % len(ring)]) for k in range(len(ring))]
        for label in body.points:
            if label in used[body.name]:
                continue
            p = pose.point(body.name, label)
            if segments[body.name] or stubs[body.name]:
                q = _nearest_on_segments(p, segments[body.name] + stubs[body.name])
                if np.hypot(*(p - q)) > 1e-9 * size:
                    segments[body.name].append((q, p))
            elif nodes:
                segments[body.name].append((nodes[0], p))
        for a, b in segments[body.name]:
            a, b = w(a), w(b)
            artists.line([a[0], b[0]], [a[1], b[1]], color=color, lw=3.0, alpha=alpha, zorder=3, solid_capstyle="round")
    # gears: each gear's pitch circle about its centre, with a radius along its
    # frame's x axis that shows it turning
    for joint in mech.joints:
        if isinstance(joint, GearPair):
            for gear, at, radius in (
                (joint.body_a, joint.centre_a, joint.radius_a),
                (joint.body_b, joint.centre_b, joint.radius_b),
            ):
                c, tick = pose.point(gear, at), pose.direction(gear, np.array([1.0, 0.0]))
                style = dict(color=colors[gear], alpha=alpha, zorder=2.5)
                artists.patch(patches.Circle, w(c), radius / scale, fill=False, ls="-.", lw=1.3, **style)
                end = w(c + radius * tick)
                artists.line([w(c)[0], end[0]], [w(c)[1], end[1]], lw=1.0, **style)
                segments.setdefault(gear, []).append((c, c + radius * tick))
    # blocks: on every prismatic joint, the block of body_b along the line
    for joint in mech.joints:
        if isinstance(joint, Prismatic):
            centre = pose.point(joint.body_b, joint.point)
            d = pose.direction(joint.body_a, joint.direction)
            owner = joint.body_b if joint.body_b != gname else joint.body_a
            _block(artists, w(centre), d, block_l / scale, block_h / scale, colors[owner], 4, alpha)
    # ground pivots: a triangle over hatching
    symbols: list[tuple[np.ndarray, np.ndarray]] = []  # their edges, which labels keep clear of too
    if ground:
        for joint in mech.joints:
            if isinstance(joint, Revolute) and gname in (joint.body_a, joint.body_b):
                label = joint.point_a if joint.body_a == gname else joint.point_b
                p = w(pose.point(gname, label))
                h = 3.2 * pin_r
                tri = np.array([p, p + [-0.8 * h, -1.4 * h], p + [0.8 * h, -1.4 * h]])
                artists.patch(patches.Polygon, tri, closed=True, facecolor="white", edgecolor="black", lw=1, zorder=1)
                symbols += [(tri[k], tri[(k + 1) % 3]) for k in range(3)] + [
                    (p + [-1.3 * h, -2.0 * h], p + [1.3 * h, -2.0 * h])
                ]
                _hatched_strip(
                    artists, p + [-1.3 * h, -1.4 * h], p + [1.3 * h, -1.4 * h], np.array([0.0, -1.0]), 0.6 * h, 1
                )
    # pins: revolute and pin-in-slot joints
    for joint in mech.joints:
        if isinstance(joint, Revolute):
            p = w(pose.point(joint.body_a, joint.point_a))
        elif isinstance(joint, PinInSlot):
            p = w(pose.point(joint.body_b, joint.point))
        else:
            continue
        artists.patch(patches.Circle, p, pin_r, facecolor="white", edgecolor="black", lw=1.2, alpha=alpha, zorder=5)
    # points and their labels, each on the side of its point clearest of the links and the other labels
    drawn = [(w(a), w(b)) for body in mech.moving_bodies for a, b in segments[body.name] + stubs[body.name]]
    drawn += symbols
    taken: list[np.ndarray] = []
    shown: set[str] = set()
    for body in (mech.ground, *mech.moving_bodies):
        for label in body.points:
            if label in shown:
                continue
            shown.add(label)
            p = w(pose.point(body.name, label))
            if label not in used[body.name]:
                artists.line([p[0]], [p[1]], "o", color="black", ms=3, alpha=alpha, zorder=6)
            if labels:
                _clear_label(artists, label, p, drawn, taken, 3.0 * pin_r, dict(fontsize=9, zorder=7))
    # the inputs
    for driver in mech.drivers if arrows is not None else ():
        sign = 1.0 if (arrows or {}).get(driver.name, 1.0) >= 0.0 else -1.0
        joint = mech.joint(driver.joint)
        if isinstance(joint, Revolute):
            centre = w(pose.point(joint.body_a, joint.point_a))
            radius = 0.09 * size / scale
            start_angle = pose.frames[joint.body_b][1] - sign * 0.9
            a = centre + radius * np.array([math.cos(start_angle), math.sin(start_angle)])
            b = centre + radius * np.array([math.cos(start_angle + sign * 1.8), math.sin(start_angle + sign * 1.8)])
            artists.patch(
                patches.FancyArrowPatch,
                a,
                b,
                connectionstyle=f"arc3,rad={0.45 * sign}",
                arrowstyle="-|>",
                mutation_scale=12,
                color="crimson",
                lw=1.5,
                zorder=8,
            )
            _clear_label(
                artists, driver.name, b, drawn, taken, 3.0 * pin_r, dict(color="crimson", fontsize=8, zorder=8)
            )
        else:
            assert isinstance(joint, LineJoint)
            p = pose.point(joint.body_b, joint.point)
            d = pose.direction(joint.body_a, joint.direction) * sign
            n = np.array([-d[1], d[0]])
            a = w(p + 0.9 * block_h * n - 0.5 * block_l * d)
            b = w(p + 0.9 * block_h * n + 0.9 * block_l * d)
            artists.patch(
                patches.FancyArrowPatch, a, b, arrowstyle="-|>", mutation_scale=12, color="crimson", lw=1.5, zorder=8
            )
            _clear_label(
                artists, driver.name, b, drawn, taken, 3.0 * pin_r, dict(color="crimson", fontsize=8, zorder=8)
            )
    return artists.finish()


def figure_of(solution: Solution, i: int = 0, title: str | None = None, extents=None) -> Figure:
    """A figure of sample ``i`` of a solution, in the model's length unit, with
    the inputs' arrows (direction of the rates at that sample)."""
    mech = solution.mechanism
    units = mech.units
    figure = Figure(figsize=(6.4, 5.2))
    ax = figure.add_subplot()
    pose = Pose.of(solution, i)
    rates = {d.name: float(solution.input_rates[i, k]) for k, d in enumerate(mech.drivers)}
    draw_pose(ax, pose, extents, scale=units.length_factor, arrows=rates)
    if title is None:
        title = f"{mech.name}: " + ", ".join(
            f"{d.name} = {units.show_input(d.quantity, float(solution.inputs[i, k]))}"
            for k, d in enumerate(mech.drivers)
        )
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.margins(0.08)
    ax.set_xlabel(f"x [{units.length}]")
    ax.set_ylabel(f"y [{units.length}]")
    ax.grid(alpha=0.25)
    figure.tight_layout()
    return figure


def check_png_name(target: Path, option: str = "output") -> None:
    """Refuse a drawing's file name that does not end in .png, in one line naming ``option``."""
    if Path(target).suffix.lower() != ".png":
        found = Path(target).suffix or "none"
        raise InputError(f"{option} {target}: expected a file name ending in .png, found {found}")


def save_png(figure: Figure, target: Path, option: str = "output") -> None:
    """Write a figure as a PNG (100 dpi), whole or not at all.

    Raises
    ------
    InputError
        If the name does not end in .png or the file cannot be written (naming ``option``).
    """
    check_png_name(target, option)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    try:
        write_atomic(Path(target), buffer.getvalue())
    except OSError as err:
        why = err.strerror or err
        raise InputError(f"{option} {target}: expected a file that can be written, found {why}") from None
