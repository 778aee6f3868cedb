"""Drawing the pymunk scene (private to :mod:`xcheck.engines.pymunk`).

Everything drawn is read from pymunk's bodies (:func:`snapshot`); matplotlib
is used through its object API and the Agg canvas, with no global state.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from xcheck.joints import LineJoint
from xcheck.model import GROUND, Mechanism

from .scene import Scene

__all__ = ["snapshot", "render_png"]


def snapshot(scene: Scene) -> dict:
    """What the figure draws, read from pymunk's bodies: per body its points
    (global, m), the revolutes' pins, the grooves' ends, the sliders."""
    mech = scene.mechanism
    shot: dict[str, Any] = {
        "bodies": {b.name: {label: scene.world_point(b.name, label) for label in b.points} for b in mech.bodies},
        "pins": [],
        "grooves": [],
        "inputs": scene.inputs()[0],
        "gap": scene.joint_gaps()[0],
    }
    for joint in mech.joints:
        if isinstance(joint, LineJoint):
            body, start, end = scene.grooves[joint.name]
            ends = [scene.bodies[body].local_to_world(tuple(p)) for p in (start, end)]
            shot["grooves"].append(
                (
                    np.array([[p.x, p.y] for p in ends]),
                    joint.locked_angle is not None,
                    scene.world_point(joint.body_b, joint.point),
                    scene.bodies[joint.body_b].angle,
                )
            )
        elif joint.connects:  # a revolute: its pin, at its second body's point
            body, label = joint.anchors()[-1]
            shot["pins"].append((scene.world_point(body, label), GROUND in (joint.body_a, joint.body_b)))
    return shot


def _draw(ax, mech: Mechanism, shot: dict, colours, scale: float) -> None:
    """One panel: a snapshot, coordinates divided by ``scale``."""
    from matplotlib.patches import Polygon, Rectangle
    from matplotlib.transforms import Affine2D
    from scipy.spatial import ConvexHull, QhullError

    block = 0.06 * mech.size / scale
    for ends, prismatic, point, angle in shot["grooves"]:
        ends = ends / scale
        ax.plot(ends[:, 0], ends[:, 1], color="0.55", lw=6, alpha=0.45, solid_capstyle="round", zorder=1)
        ax.plot(ends[:, 0], ends[:, 1], color="0.3", lw=0.8, ls="--", zorder=1)
        if prismatic:  # a block riding the line, turned with its body
            xy = point / scale
            box = Rectangle(
                (xy[0] - block / 2, xy[1] - block / 2), block, block, fill=False, lw=1.2, ec="0.2", zorder=4
            )
            box.set_transform(Affine2D().rotate_around(xy[0], xy[1], angle) + ax.transData)
            ax.add_patch(box)
        else:  # a pin riding the slot
            ax.plot(*(point / scale), marker="o", ms=6, mfc="0.85", mec="black", zorder=5)
    for k, body in enumerate(mech.moving_bodies):
        pts = np.array(list(shot["bodies"][body.name].values())) / scale
        colour = colours[k % len(colours)]
        if len(pts) >= 3:
            try:
                hull = pts[ConvexHull(pts).vertices]
            except QhullError:  # all in a line
                hull = None
            if hull is not None:
                ax.add_patch(Polygon(hull, closed=True, fc=colour, ec=colour, alpha=0.3, lw=2, zorder=2))
        if len(pts) >= 2:
            far = max(
                ((i, j) for i in range(len(pts)) for j in range(len(pts))),
                key=lambda ij: np.linalg.norm(pts[ij[0]] - pts[ij[1]]),
            )
            ax.plot(
                pts[list(far), 0],
                pts[list(far), 1],
                color=colour,
                lw=3,
                alpha=0.8,
                zorder=2,
                solid_capstyle="round",
                label=body.name,
            )
        else:
            ax.plot(pts[:, 0], pts[:, 1], "s", color=colour, ms=8, zorder=3, label=body.name)
        for label, xy in shot["bodies"][body.name].items():
            ax.annotate(label, xy / scale, xytext=(4, 4), textcoords="offset points", fontsize=7, zorder=6)
    for xy, grounded in shot["pins"]:
        xy = xy / scale
        ax.plot(*xy, marker="^" if grounded else "o", ms=9 if grounded else 6, mfc="white", mec="black", zorder=5)
    ground = np.array(list(shot["bodies"][GROUND].values()) or np.zeros((0, 2))) / scale
    if len(ground):
        ax.plot(ground[:, 0], ground[:, 1], "k+", ms=6, zorder=5)
        carried = {label for b in mech.moving_bodies for label in b.points}
        for label, xy in zip(shot["bodies"][GROUND], ground):
            if label not in carried:
                ax.annotate(label, xy, xytext=(4, 4), textcoords="offset points", fontsize=7, zorder=6)
    ax.grid(True, lw=0.3, alpha=0.5)


def render_png(mech: Mechanism, shots: list, title: str) -> bytes:
    """The figure of :func:`xcheck.engines.pymunk.scene_figure` as PNG bytes.

    Parameters
    ----------
    mech : Mechanism
    shots : list of (float, dict)
        Time (s) and :func:`snapshot` of each panel, left to right.
    title : str
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    units = mech.units
    every = (
        np.concatenate(
            [np.array(list(b.values())).reshape(-1, 2) for _, shot in shots for b in shot["bodies"].values()]
            + [g[0] for _, shot in shots for g in shot["grooves"]]
        )
        / units.length_factor
    )
    low, high = every.min(axis=0), every.max(axis=0)
    pad = 0.08 * max(float(np.max(high - low)), mech.size / units.length_factor)
    aspect = (high[1] - low[1] + 2 * pad) / (high[0] - low[0] + 2 * pad)
    fig = Figure(figsize=(4.2 * len(shots), 1.4 + 4.0 * min(max(aspect, 0.4), 1.5)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(shots), squeeze=False)[0]
    colours = [
        "tab:blue",
        "tab:orange",
        "tab:green",
        "tab:red",
        "tab:purple",
        "tab:brown",
        "tab:pink",
        "tab:olive",
        "tab:cyan",
    ]
    for ax, (t, shot) in zip(axes, shots):
        _draw(ax, mech, shot, colours, units.length_factor)
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_aspect("equal", adjustable="box")
        shown = []
        for driver, value in zip(mech.drivers, shot["inputs"]):
            if driver.quantity == "angle":
                shown.append(f"{driver.name} = {value / units.angle_factor:.4g} {units.angle}")
            else:
                shown.append(f"{driver.name} = {value / units.length_factor:.4g} {units.length}")
        ax.set_title(f"t = {t:.4g} s: {', '.join(shown)}\njoint gap {shot['gap']:.2g} m", fontsize=9)
        ax.set_xlabel(f"x ({units.length})")
    axes[0].set_ylabel(f"y ({units.length})")
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()
