"""Figures of a comparison run (matplotlib, Agg), in the model's display units."""

from __future__ import annotations

import io
import math
import tempfile
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import animation  # noqa: E402
from scipy.spatial import ConvexHull, QhullError  # noqa: E402

from .. import engines  # noqa: E402
from ..model import PinInSlot, Prismatic  # noqa: E402
from ..runner import CATEGORIES, RunResult, convergence_table  # noqa: E402

__all__ = ["drawing", "motion_gif", "quantities", "error_plots", "convergence_plot", "forces_plot", "tracked"]

_NATIVE_STYLE = dict(color="black", lw=1.6, ls="-")
#: an observed order below this is shown as "not converging" (the error does not fall with the step)
NOT_CONVERGING = 0.5


def _style(mode: str) -> dict:
    """A mode's matplotlib style (its engine's, :class:`xcheck.engines.Mode`)."""
    return dict(_NATIVE_STYLE) if mode == "native" else dict(engines.mode(mode).style)


def _line_style(mode: str) -> dict:
    """For the log-scale error plots: kinematic modes solid, dynamic ones dashed."""
    color = _style(mode).get("color", "tab:gray")
    return {"color": color, "ls": "--" if mode != "native" and engines.mode(mode).kind == "dynamic" else "-"}


def _is_dynamic(mode: str) -> bool:
    return mode != "native" and engines.mode(mode).kind == "dynamic"


def _png(figure, dpi: int = 90, **options) -> bytes:
    """The figure as PNG bytes (``options`` go to ``savefig``); the figure is closed."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, **options)
    plt.close(figure)
    return buffer.getvalue()


def _input_axis(run: RunResult, values: np.ndarray) -> tuple[np.ndarray, str]:
    """The first driver's values in display units, and the axis label."""
    mech = run.mechanism
    driver, units = mech.drivers[0], mech.units
    if driver.quantity == "angle":
        return values / units.angle_factor, f"{driver.name} [{units.angle}]"
    return values / units.length_factor, f"{driver.name} [{units.length}]"


def tracked(run: RunResult) -> tuple[str, str]:
    """The point and body whose quantities the plots show: the fastest moving
    named point and the body with the largest range of angular velocity that is
    not driven directly (the output link)."""
    mech, native = run.mechanism, run.native
    ground = set(mech.ground.points)
    speeds = {
        label: np.nanmax(np.linalg.norm(native.point(label)["velocity"], axis=1))
        for label in mech.point_owners
        if label not in ground
    }
    point = max(speeds, key=lambda label: speeds[label])
    driven = set()
    for d in mech.drivers:
        joint = mech.joint(d.joint)
        driven.add(joint.body_b)
    spans = {b.name: np.ptp(native.body(b.name)["omega"]) for b in mech.moving_bodies}
    candidates = {k: v for k, v in spans.items() if k not in driven} or spans
    return point, max(candidates, key=lambda name: candidates[name])


def _body_outline(points: np.ndarray):
    """Vertices of a body's outline (convex hull, or the segment through collinear points)."""
    if len(points) >= 3:
        try:
            hull = ConvexHull(points)
            return points[np.append(hull.vertices, hull.vertices[0])]
        except QhullError:
            pass
    if len(points) >= 2:
        direction = points[-1] - points[0]
        order = np.argsort(points @ direction)
        return points[[order[0], order[-1]]]
    return points


def _draw_pose(ax, run: RunResult, i: int, alpha: float, labels: bool) -> None:
    mech, native, scale = run.mechanism, run.native, run.mechanism.units.length_factor
    colors = plt.cm.tab10(np.linspace(0, 1, 10))
    for n, body in enumerate(mech.moving_bodies):
        pts = np.array([native.point(label, body.name)["position"][i] for label in body.points]) / scale
        outline = _body_outline(pts)
        ax.plot(outline[:, 0], outline[:, 1], "-", color=colors[n % 10], lw=2.5, alpha=alpha, solid_capstyle="round")
        if len(outline) > 3:
            ax.fill(outline[:, 0], outline[:, 1], color=colors[n % 10], alpha=0.12 * alpha)
    for label in mech.point_owners:
        xy = native.point(label)["position"][i] / scale
        on_ground = label in mech.ground.points
        ax.plot(*xy, "^" if on_ground else "o", color="black", ms=7 if on_ground else 4, alpha=alpha)
        if labels:
            ax.annotate(label, xy, xytext=(4, 4), textcoords="offset points", fontsize=9)


def drawing(run: RunResult, poses: int = 5) -> bytes:
    """The mechanism at a few inputs of the sweep, its named points and their paths (PNG)."""
    mech, native = run.mechanism, run.native
    scale, unit = mech.units.length_factor, mech.units.length
    good = np.flatnonzero(native.status <= 1)
    figure, ax = plt.subplots(figsize=(7, 5.5))
    for label in mech.point_owners:
        if label in mech.ground.points:
            continue
        path = native.point(label)["position"][good] / scale
        ax.plot(path[:, 0], path[:, 1], lw=0.8, color="tab:gray", alpha=0.7)
    for joint in mech.joints:
        if isinstance(joint, (Prismatic, PinInSlot)) and joint.body_a == "ground":
            slide = native.point(joint.point, joint.body_b)["position"][good] / scale
            ax.plot(slide[:, 0], slide[:, 1], "--", color="black", lw=0.8)
    chosen = good[np.linspace(0, len(good) - 1, poses).round().astype(int)]
    for n, i in enumerate(chosen):
        _draw_pose(ax, run, i, alpha=0.25 + 0.75 * (n == len(chosen) // 2), labels=n == len(chosen) // 2)
    values, label = _input_axis(run, native.inputs[chosen, 0])
    title = (
        f"{mech.name}: {label.split(' [')[0]} = "
        + ", ".join(f"{v:.4g}" for v in values)
        + f" {label.split('[')[1].rstrip(']')} (labels at the middle pose; grey: paths)"
    )
    ax.set_title(textwrap.fill(title, 80), fontsize=9)  # 80 characters of 9 pt fit the 7 in figure
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.grid(alpha=0.3)
    figure.tight_layout()
    return _png(figure)


def motion_gif(run: RunResult, frames: int = 24) -> bytes:
    """An animated GIF of the mechanism over the sweep."""
    mech, native = run.mechanism, run.native
    scale = mech.units.length_factor
    good = np.flatnonzero(native.status <= 1)
    every = [label for label in mech.point_owners]
    xy = np.concatenate([native.point(label)["position"][good] / scale for label in every])
    pad = 0.05 * np.ptp(xy, axis=0).max()
    figure, ax = plt.subplots(figsize=(4.5, 3.6), dpi=70)

    def draw(n):
        ax.clear()
        ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
        ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
        ax.set_aspect("equal")
        ax.set_axis_off()
        _draw_pose(ax, run, good[int(round(n * (len(good) - 1) / (frames - 1)))], alpha=1.0, labels=True)

    movie = animation.FuncAnimation(figure, draw, frames=frames)
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(tmp) / "motion.gif"
        movie.save(target, writer=animation.PillowWriter(fps=12))
        plt.close(figure)
        return target.read_bytes()


def _series(run: RunResult, mode: str, point: str, body: str):
    """Per category: (inputs (N,), values (N,)) of the tracked point and body in a mode."""
    if mode == "native":
        sol = run.native
        p, b, inputs = sol.point(point), sol.body(body), sol.inputs[:, 0]
    else:
        t = run.outcomes[mode].trajectory
        assert t is not None  # only modes that produced a trajectory are plotted
        p, b, inputs = t.points.get(point, {}), t.bodies.get(body, {}), t.inputs[:, 0]
    return {
        "position": (inputs, p["position"][:, 0]) if "position" in p else None,
        "velocity": (inputs, np.linalg.norm(p["velocity"], axis=1)) if "velocity" in p else None,
        "acceleration": (inputs, np.linalg.norm(p["acceleration"], axis=1)) if "acceleration" in p else None,
        "angle": (inputs, np.unwrap(b["angle"])) if "angle" in b else None,
        "omega": (inputs, b["omega"]) if "omega" in b else None,
        "alpha": (inputs, b["alpha"]) if "alpha" in b else None,
    }


def quantities(run: RunResult) -> bytes:
    """Each quantity of the tracked point and body against the input, all modes overlaid (PNG)."""
    mech, units = run.mechanism, run.mechanism.units
    point, body = tracked(run)
    scales = {
        "position": (units.length_factor, f"x of {point} [{units.length}]"),
        "velocity": (units.velocity_factor, f"|v| of {point} [{units.velocity}]"),
        "acceleration": (units.acceleration_factor, f"|a| of {point} [{units.acceleration}]"),
        "angle": (units.angle_factor, f"angle of {body} [{units.angle}]"),
        "omega": (units.angular_rate_factor, f"ω of {body} [{units.angular_rate}]"),
        "alpha": (units.angular_rate_factor, f"α of {body} [{units.angular_acceleration}]"),
    }
    figure, axes = plt.subplots(2, 3, figsize=(13, 7))
    modes = ["native"] + [m for m, o in run.outcomes.items() if m != "native" and o.trajectory is not None]
    for ax, category in zip(axes.flat, CATEGORIES):
        factor, ylabel = scales[category]
        reference = _series(run, "native", point, body)[category]
        for mode in modes:
            data = _series(run, mode, point, body)[category]
            if data is None:
                continue
            x, _ = _input_axis(run, data[0])
            values = data[1]
            if category == "angle":  # same turn as the native angle at the first sample
                native_there = np.interp(data[0][0], reference[0], reference[1])
                values = values - 2 * np.pi * np.round((values[0] - native_there) / (2 * np.pi))
            order = np.argsort(x, kind="stable") if mode != "native" else slice(None)
            ax.plot(x[order], values[order] / factor, label=mode, **_style(mode))
        ax.set_ylabel(ylabel)
        ax.set_xlabel(_input_axis(run, np.zeros(1))[1])
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=7, loc="best")
    figure.suptitle(
        f"{mech.name}: quantities against the input (native: line; engines: markers and dashes)", fontsize=10
    )
    figure.tight_layout()
    return _png(figure)


def error_plots(run: RunResult) -> bytes:
    """Each mode's largest error over all bodies and points against the input, log scale (PNG)."""
    figure, axes = plt.subplots(2, 3, figsize=(13, 7))
    units = {
        "position": "m",
        "velocity": "m/s",
        "acceleration": "m/s²",
        "angle": "rad",
        "omega": "rad/s",
        "alpha": "rad/s²",
    }
    for ax, category in zip(axes.flat, CATEGORIES):
        for mode, outcome in run.outcomes.items():
            errors = outcome.errors.get(category)
            if errors is None or outcome.trajectory is None:
                continue
            x, _ = _input_axis(run, outcome.trajectory.inputs[:, 0])
            order = np.argsort(x, kind="stable")
            floor = np.where(errors[order] > 0, errors[order], 1e-18)  # exact zeros drawn at the floor
            ax.semilogy(x[order], floor, label=mode, lw=1, **_line_style(mode))
        ax.set_ylabel(f"largest {category} error [{units[category]}]")
        ax.set_xlabel(_input_axis(run, np.zeros(1))[1])
        ax.grid(alpha=0.3, which="both")
    axes.flat[0].legend(fontsize=7, loc="best")
    figure.suptitle(
        f"{run.mechanism.name}: difference from the native solution (largest over all bodies "
        "and points; 1e-18 marks an exact zero)",
        fontsize=10,
    )
    figure.tight_layout()
    return _png(figure)


def convergence_plot(run: RunResult) -> bytes | None:
    """Each dynamic mode's position error against time step, log-log (PNG); None if none ran."""
    dynamic = [(m, o) for m, o in run.outcomes.items() if _is_dynamic(m) and o.result is not None]
    tables = [(m, convergence_table(o)) for m, o in dynamic]
    tables = [(m, t) for m, t in tables if not t.empty]
    if not tables:
        return None
    figure, axes = plt.subplots(1, len(tables), figsize=(4.6 * len(tables), 4), squeeze=False)
    for ax, (mode, table) in zip(axes[0], tables):
        for series, part in table.groupby("series", sort=False):
            if len(part) < 1:
                continue
            ok = part[part.position_error > 0]
            (line,) = ax.loglog(ok.timestep, ok.position_error, "o-", ms=4, label=series)
            orders = part.order.dropna()
            if len(orders):
                order = float(orders.iloc[-1])
                ax.annotate(
                    f"order {order:.2f}" if order >= NOT_CONVERGING else f"not converging (order {order:.2f})",
                    (ok.timestep.iloc[-1], ok.position_error.iloc[-1]),
                    xytext=(4, -10),
                    textcoords="offset points",
                    fontsize=7,
                    color=line.get_color(),
                )
        ax.set_title(mode, fontsize=9)
        ax.set_xlabel("time step [s]")
        ax.set_ylabel("largest position error [m]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    figure.suptitle(
        f"{run.mechanism.name}: error against time step (observed order between the two smallest steps)", fontsize=10
    )
    figure.tight_layout()
    return _png(figure)


def forces_plot(run: RunResult) -> bytes | None:
    """Driving efforts and joint reaction magnitudes against the input, native
    lines with every engine's values overlaid (PNG); None without forces."""
    native = run.native_forces
    if native is None:
        return None
    sources = [(r.engine, r.forces) for r in run.forces if r.ok and r.forces is not None and r.engine != "newton-euler"]
    panels = [("driver", name) for name in native.drivers] + [("joint", name) for name in native.joints]
    columns = min(3, len(panels))
    rows = math.ceil(len(panels) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.4 * columns, 3.2 * rows), squeeze=False)
    for ax, (kind, name) in zip(axes.flat, panels):
        key = "effort" if kind == "driver" else "reaction"
        table = native.drivers if kind == "driver" else native.joints
        x, xlabel = _input_axis(run, native.inputs[:, 0])
        values = table[name][key]
        magnitude = values if values.ndim == 1 else np.linalg.norm(values, axis=1)
        if kind == "joint":
            magnitude = np.abs(magnitude)
        ax.plot(x, magnitude, color="black", lw=1.6, label="native")
        if kind == "driver" and any(f"|{key}|" in (f.drivers.get(name) or {}) for _, f in sources):
            ax.plot(x, np.abs(magnitude), color="black", lw=0.8, ls=":", label="|native|")
        for engine, forces in sources:
            source = forces.drivers if kind == "driver" else forces.joints
            data = source.get(name, {})
            series = data.get(key, data.get(f"|{key}|"))
            if series is None:
                continue
            series = np.asarray(series)
            series = series if series.ndim == 1 else np.linalg.norm(series, axis=1)
            if kind == "joint" or f"|{key}|" in data:
                series = np.abs(series)
            ex, _ = _input_axis(run, forces.inputs[:, 0])
            described = engines.engine(engine)
            ax.plot(ex, series, color=described.color, label=engine, **dict(described.force_style))
        driver = next((d for d in run.mechanism.drivers if d.name == name), None)
        unit = "N m" if driver is not None and driver.quantity == "angle" else "N"
        label = f"effort of {name} [{unit}]" if kind == "driver" else f"|reaction| at {name} [N]"
        ax.set_ylabel(label)
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    figure.suptitle(f"{run.mechanism.name}: driving effort and joint reactions over the simulation window", fontsize=10)
    figure.tight_layout()
    return _png(figure)
