"""Figures of a comparison run (matplotlib, Agg), in the model's display units."""

from __future__ import annotations

import contextlib
import gc
import io
import math
import re
import textwrap
from collections.abc import Iterator

import matplotlib
import matplotlib.collections
import matplotlib.lines
import matplotlib.text
import matplotlib.transforms

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import ticker  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from PIL import Image  # noqa: E402

from .. import engines  # noqa: E402
from ..drawing import Pose, PoseArtists, draw_pose, guide_extents  # noqa: E402
from ..kinematics import Solution  # noqa: E402
from ..results import native_at  # noqa: E402
from ..runner import CATEGORIES, RunResult, convergence_table  # noqa: E402
from ..tolerances import convergence_round_off  # noqa: E402

__all__ = [
    "drawing",
    "motion_gif",
    "quantities",
    "error_plots",
    "convergence_plot",
    "forces_plot",
    "tracked",
    "old_objects_frozen",
]

_NATIVE_STYLE = dict(color="black", lw=1.6, ls="-")


def _style(mode: str) -> dict:
    """A mode's matplotlib style (its engine's, :class:`xcheck.engines.Mode`)."""
    return dict(_NATIVE_STYLE) if mode == "native" else dict(engines.mode(mode).style)


def _line_style(mode: str) -> dict:
    """For the log-scale error plots: kinematic modes solid, dynamic ones dashed."""
    color = _style(mode).get("color", "tab:gray")
    return {"color": color, "ls": "--" if mode != "native" and engines.mode(mode).kind == "dynamic" else "-"}


def _is_dynamic(mode: str) -> bool:
    return mode != "native" and engines.mode(mode).kind == "dynamic"


@contextlib.contextmanager
def old_objects_frozen() -> Iterator[None]:
    """Leave the objects alive now out of the garbage collector's passes for the
    block (:func:`gc.freeze`): a figure makes and drops thousands of matplotlib
    objects, which start full collections that would otherwise traverse every
    object the process holds (the run, the modules of the engines) each time."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _png(figure, dpi: int = 90, fit: float | None = None) -> bytes:
    """The figure, complete, as PNG bytes: its RGB pixels (it is opaque) compressed
    at zlib level 3, with no metadata but the resolution ``dpi``; the pixels of
    matplotlib's own PNG of it. Its unlabelled minor ticks and its major ticks are
    drawn as a few artists (:func:`_unlabelled_minor_ticks_as_lines`,
    :func:`_major_ticks_as_artists`: the same pixels); with ``fit``, the figure is
    made the size of what it draws plus ``fit`` inches on each side
    (:func:`_fit_to_contents`). The figure is closed."""
    _unlabelled_minor_ticks_as_lines(figure)
    buffer = io.BytesIO()
    canvas = figure.canvas if isinstance(figure.canvas, FigureCanvasAgg) else FigureCanvasAgg(figure)
    figure.set_dpi(dpi)
    if fit is not None:  # measured at the resolution it is drawn at: text does not scale exactly
        _fit_to_contents(figure, fit)
    _major_ticks_as_artists(figure)
    canvas.draw()
    width, height = canvas.get_width_height(physical=True)
    pixels = Image.frombuffer("RGBA", (width, height), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
    pixels.convert("RGB").save(buffer, format="png", dpi=(dpi, dpi), compress_level=3)
    plt.close(figure)
    return buffer.getvalue()


def _margins(figure, left: float, right: float, bottom: float, top: float, wspace: float, hspace: float) -> None:
    """Fixed margins and gaps between panels, in inches (whatever the figure's
    size): the room for the tick labels, axis labels and titles these figures
    carry, without ``tight_layout``'s measuring pass (a quarter of a report's
    time) or a layout engine's at every draw."""
    width, height = figure.get_size_inches()
    grid = figure.axes[0].get_gridspec()
    rows, columns = grid.nrows, grid.ncols
    inner_w = width - left - right
    inner_h = height - bottom - top
    panel_w = (inner_w - wspace * (columns - 1)) / columns
    panel_h = (inner_h - hspace * (rows - 1)) / rows
    figure.subplots_adjust(
        left=left / width,
        right=1 - right / width,
        bottom=bottom / height,
        top=1 - top / height,
        wspace=wspace / panel_w,
        hspace=hspace / panel_h,
    )


def _fit_to_contents(figure, pad: float) -> None:
    """Make the figure the size of what it draws plus ``pad`` inches on each side,
    its panels moved with it (savefig's ``bbox_inches="tight"`` for :func:`_png`):
    room for what stands outside the panels, such as a legend beside them. For a
    figure whose artists outside the panels are the panels' own (titles, labels,
    legends): a figure's own title or legend would not move."""
    box = figure.get_tightbbox(figure.canvas.get_renderer()).padded(pad)  # inches
    width, height = figure.get_size_inches()
    for ax in figure.axes:
        at = ax.get_position()
        ax.set_position(
            [
                (at.x0 * width - box.x0) / box.width,
                (at.y0 * height - box.y0) / box.height,
                at.width * width / box.width,
                at.height * height / box.height,
            ]
        )
    figure.set_size_inches(box.width, box.height)


def _panels(count: int, columns: int, figsize: tuple[float, float]):
    """A figure of ``count`` panels, ``columns`` to a row, filled row by row, and
    its panels (a list): a grid's places past the last panel are left empty, no
    panel made there."""
    figure = plt.figure(figsize=figsize)
    grid = figure.add_gridspec(math.ceil(count / columns), columns)
    return figure, [figure.add_subplot(grid[n // columns, n % columns]) for n in range(count)]


def _log_panel_title(ax, text: str) -> None:
    """A panel's title on axes with a log y scale, at the axes' top: where
    matplotlib would place it, without measuring every tick label of the panel
    at each draw to find that place (a log axis has no offset text, and these
    panels no ticks on top)."""
    ax.set_title(text, fontsize=9, y=1.0)


#: digits and the minus sign as Unicode superscripts
_SUPERSCRIPTS = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


class _PlainLogFormatter(ticker.LogFormatterSciNotation):
    """matplotlib's labels of a log axis (10^k, and c×10^k where it labels the
    minor ticks) in plain text, the exponent in Unicode superscripts, instead of
    mathtext, whose parser a figure would otherwise start and run for each label."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = re.fullmatch(r"\$\\mathdefault\{(.*)\}\$", label)
        if match is None:
            return label
        text = match.group(1).replace(r"\times", "×")
        return re.sub(r"\^\{(-?[0-9]+)\}", lambda power: power.group(1).translate(_SUPERSCRIPTS), text)


def _plain_log_labels(ax) -> None:
    """Label the log axes of ``ax`` with :class:`_PlainLogFormatter` where they carry
    matplotlib's own log labels (other formatters are kept)."""
    for axis in (ax.xaxis, ax.yaxis):
        for formatter, install in (
            (axis.get_major_formatter(), axis.set_major_formatter),
            (axis.get_minor_formatter(), axis.set_minor_formatter),
        ):
            if type(formatter) is ticker.LogFormatterSciNotation:
                install(_PlainLogFormatter(axis.get_transform().base, labelOnlyBase=formatter.labelOnlyBase))


#: the zorders of a panel's tick artists above its x axis's: x major, x minor, y axis, y major, y minor
#: (matplotlib draws the x axis's ticks, then the y axis's, major before minor, and where two grid
#: lines cross the second blends over the first: the artists keep that order)
_TICK_ORDER = {"x major": 0.5e-6, "x minor": 1e-6, "y axis": 2e-6, "y major": 2.5e-6, "y minor": 3e-6}


def _in_view(axis, locations: np.ndarray) -> np.ndarray:
    """Which tick locations lie in the axis's view, by matplotlib's own test (a mask)."""
    scale = axis.get_transform()
    low, high = sorted(scale.transform(axis.get_view_interval()))
    slack = 1e-10 * (high - low)
    at = scale.transform(locations)
    return (at >= low - slack) & (at <= high + slack)


def _tick_lines(ax, axis, template, locations: np.ndarray, zorder: float) -> None:
    """The grid lines and tick marks of ``axis`` at ``locations``, styled as its
    tick ``template``: one collection of grid lines (one path each: where two lie
    closer than their width, each blends) and one line of tick marks."""
    grid, marks = template.gridline, template.tick1line
    if grid.get_visible():
        ends = np.stack([np.zeros(len(locations)), np.ones(len(locations))], axis=1)
        along = np.repeat(locations[:, None], 2, axis=1)
        segments = np.stack((along, ends) if axis is ax.xaxis else (ends, along), axis=2)
        lines = matplotlib.collections.LineCollection(
            list(segments),
            colors=[grid.get_color()],
            alpha=grid.get_alpha(),
            linewidths=grid.get_linewidth(),
            linestyles=grid.get_linestyle(),
            capstyle=grid.get_solid_capstyle(),
            joinstyle=grid.get_solid_joinstyle(),
            transform=grid.get_transform(),
            zorder=zorder,
        )
        lines.set_clip_path(ax.patch)
        ax.add_artist(lines)
    if marks.get_visible():
        zeros = np.zeros(len(locations))
        line = matplotlib.lines.Line2D(*((locations, zeros) if axis is ax.xaxis else (zeros, locations)))
        line.update_from(marks)
        line.set_transform(marks.get_transform())
        line.set_zorder(zorder)
        line.set_clip_on(False)
        ax.add_artist(line)


def _unlabelled_minor_ticks_as_lines(figure) -> None:
    """Draw the unlabelled minor ticks of ``figure``'s panels as two artists per
    axis, one line of tick marks and one collection of grid lines, styled as
    matplotlib's own minor tick, instead of five artists per tick (tick marks,
    grid line and labels, each made and drawn on its own): the same pixels, a
    fraction of the cost on log axes spanning decades. For a static image: call it once the figure is
    complete (limits and panel positions final); the ticks no longer follow a
    change of limits. Minor ticks that carry labels are left as they are."""
    for ax in figure.axes:
        if not ax.get_visible():
            continue
        base = ax.xaxis.get_zorder()
        ax.yaxis.set_zorder(base + _TICK_ORDER["y axis"])
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if isinstance(axis.get_minor_locator(), ticker.NullLocator):
                continue
            locations = axis.get_minorticklocs()
            locations = locations[_in_view(axis, locations)]
            if any(axis.minor.formatter.format_ticks(locations)):
                continue
            template = axis.get_minor_ticks(1)[0]
            axis.set_minor_locator(ticker.NullLocator())
            if len(locations):
                _tick_lines(ax, axis, template, locations, base + _TICK_ORDER[f"{name} minor"])


def _major_ticks_as_artists(figure) -> None:
    """Draw the ticks of ``figure``'s panels (the major ones, and the minor ones
    :func:`_unlabelled_minor_ticks_as_lines` left because they carry labels) as
    one line of tick marks, one collection of grid lines and a text per label
    each, styled and placed as matplotlib's own ticks, and put each axis label
    where matplotlib would (clear of those labels), instead of five artists per
    tick made and drawn one by one: the same pixels. For a static image at its
    final resolution: call it after :func:`_unlabelled_minor_ticks_as_lines`,
    once the figure's dpi is set. An axis whose labels have an offset, or with
    ticks or its label on its other side, is left as it is."""
    renderer = figure.canvas.get_renderer()
    dots = figure.dpi / 72
    for ax in figure.axes:
        if not ax.get_visible():
            continue
        ax.apply_aspect()  # the limits the drawing will have (an equal aspect adjusts them as it draws)
        base = ax.xaxis.get_zorder()
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if isinstance(axis.get_major_locator(), ticker.NullLocator):
                continue
            # per level, as matplotlib draws them (majors, then minors): its ticks' locations, labels and a tick
            levels = [("major", axis.get_majorticklocs(), axis.major.formatter, axis.get_major_ticks(1)[0])]
            if not isinstance(axis.get_minor_locator(), ticker.NullLocator):  # (minors apart from the majors)
                levels.append(("minor", axis.get_minorticklocs(), axis.minor.formatter, axis.get_minor_ticks(1)[0]))
            if axis.get_label_position() != ("bottom" if name == "x" else "left") or any(
                template.tick2line.get_visible() or template.label2.get_visible() for *_, template in levels
            ):
                continue
            drawn = []
            for level, everywhere, formatter, template in levels:
                labels = formatter.format_ticks(everywhere)  # as matplotlib formats them, all at once
                if formatter.get_offset():
                    break
                shown = _in_view(axis, everywhere)
                drawn.append(
                    (level, everywhere[shown], [label for label, kept in zip(labels, shown) if kept], template)
                )
            else:
                boxes = []
                for level, locations, labels, template in drawn:
                    zorder = base + _TICK_ORDER[f"{name} {level}"]
                    if len(locations):
                        _tick_lines(ax, axis, template, locations, zorder)
                    if template.label1.get_visible():
                        for location, label in zip(
                            locations, labels
                        ):  # an empty one too: its box places the axis label
                            at = (location, 0.0) if name == "x" else (0.0, location)
                            text = matplotlib.text.Text(at[0], at[1], label)
                            text.update_from(template.label1)
                            text.set_zorder(zorder)
                            text.set_clip_on(False)
                            ax.add_artist(text)
                            boxes.append(text.get_window_extent(renderer))
                axis.set_major_locator(ticker.NullLocator())
                axis.set_minor_locator(ticker.NullLocator())
                # the axis label clear of the tick labels, as matplotlib places it (Axis._update_label_position)
                x, y = axis.label.get_position()
                if name == "x":
                    bottom = matplotlib.transforms.Bbox.union([*boxes, ax.spines.get("bottom", ax).get_window_extent()])
                    axis.set_label_coords(x, bottom.y0 - axis.labelpad * dots, transform=axis.label.get_transform())
                else:
                    left = matplotlib.transforms.Bbox.union([*boxes, ax.spines.get("left", ax).get_window_extent()])
                    axis.set_label_coords(left.x0 - axis.labelpad * dots, y, transform=axis.label.get_transform())


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


def _draw_pose(
    ax, run: RunResult, i: int, alpha: float, labels: bool, extents=None, replacing: PoseArtists | None = None
) -> PoseArtists:
    """Sample ``i`` of the native sweep (:func:`xcheck.drawing.draw_pose`): the
    ground, labels and the inputs' arrows with the opaque pose only; in place of
    the pose ``replacing``, if given."""
    native = run.native
    arrows = {d.name: float(native.input_rates[i, k]) for k, d in enumerate(run.mechanism.drivers)} if labels else None
    return draw_pose(
        ax,
        Pose.of(native, i),
        extents,
        scale=run.mechanism.units.length_factor,
        alpha=alpha,
        labels=labels,
        arrows=arrows,
        ground=labels,
        replacing=replacing,
    )


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
    chosen = good[np.linspace(0, len(good) - 1, poses).round().astype(int)]
    extents = guide_extents(native)
    middle = len(chosen) // 2
    for n in [*(n for n in range(len(chosen)) if n != middle), middle]:  # the labelled pose on top
        # guides and slots over their whole travel with the labelled pose; the ghosts' around their pins
        ghost = n != middle
        _draw_pose(
            ax, run, chosen[n], alpha=0.2 if ghost else 1.0, labels=not ghost, extents=None if ghost else extents
        )
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
    """An animated GIF of the mechanism over the sweep, 12 frames a second.

    Each frame is matplotlib's drawing of its pose (:func:`_motion_figure`); the
    frames share one palette (:func:`_one_palette`), so that what stands still
    keeps its colours from frame to frame."""
    figure, draw = _motion_figure(run, frames)
    pictures = []
    for n in range(frames):
        draw(n)
        figure.canvas.draw()
        pictures.append(np.array(figure.canvas.buffer_rgba())[..., :3])  # the figure is opaque
    plt.close(figure)
    height, width = pictures[0].shape[:2]
    strip = _one_palette(np.concatenate(pictures))
    images = [strip.crop((0, n * height, width, (n + 1) * height)) for n in range(frames)]
    movie = io.BytesIO()
    images[0].save(movie, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / 12), loop=0)
    return movie.getvalue()


def _one_palette(pixels: np.ndarray) -> Image.Image:
    """RGB pixels (h, w, 3) on a white ground as a paletted image of 256 colours:
    white, exact, as colour 0, and Pillow's median cut of the other pixels into
    the other 255.

    This is Pillow's median cut of every pixel wherever that cut leaves white,
    the ground and nearly all of a frame, in a box of its own (first), as it does
    on every bundled mechanism: the same image, from a cut over the few percent
    of pixels drawn on the ground instead of every pixel of every frame."""
    # white: the three bytes' AND is 255 (a tenth of the time of comparing each and reducing)
    ground = (pixels[..., 0] & pixels[..., 1] & pixels[..., 2]) == 255
    drawn = pixels[~ground]
    indices = np.zeros(ground.shape, dtype=np.uint8)
    palette = [255, 255, 255] + [0] * 765
    if len(drawn):
        cut = Image.fromarray(drawn[None]).quantize(255, method=Image.Quantize.MEDIANCUT)
        indices[~ground] = np.asarray(cut)[0] + 1
        colours = (cut.getpalette() or [])[:765]
        palette[3 : 3 + len(colours)] = colours
    image = Image.fromarray(indices, mode="P")
    image.putpalette(palette)
    return image


def _motion_figure(run: RunResult, frames: int):
    """The GIF's figure (open) and ``draw(n)``, which shows frame n of ``frames``."""
    mech, native = run.mechanism, run.native
    scale = mech.units.length_factor
    good = np.flatnonzero(native.status <= 1)
    every = [label for label in mech.point_owners]
    xy = np.concatenate([native.point(label)["position"][good] / scale for label in every])
    pad = 0.05 * np.ptp(xy, axis=0).max()
    figure, ax = plt.subplots(figsize=(4.5, 3.6), dpi=70)
    extents = guide_extents(native)
    ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
    ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_axis_off()
    shown: list[PoseArtists] = []

    def draw(n):
        # the frame stays (limits, aspect, no axis); the previous pose's artists move to this one
        i = good[int(round(n * (len(good) - 1) / (frames - 1)))]
        shown[:] = [_draw_pose(ax, run, i, 1.0, True, extents, replacing=shown[0] if shown else None)]

    return figure, draw


def _values(source, point: str, body: str) -> dict[str, np.ndarray | None]:
    """Per category, the tracked point's and body's values in a Solution or a
    Trajectory (None where the source does not give the quantity), SI."""
    if isinstance(source, Solution):
        p, b = source.point(point), source.body(body)
    else:
        p, b = source.points.get(point, {}), source.bodies.get(body, {})
    return {
        "position": p["position"][:, 0] if "position" in p else None,
        "velocity": np.linalg.norm(p["velocity"], axis=1) if "velocity" in p else None,
        "acceleration": np.linalg.norm(p["acceleration"], axis=1) if "acceleration" in p else None,
        "angle": np.unwrap(b["angle"]) if "angle" in b else None,
        "omega": b["omega"] if "omega" in b else None,
        "alpha": b["alpha"] if "alpha" in b else None,
    }


def _on_the_sweep(run: RunResult, inputs: np.ndarray) -> np.ndarray:
    """The samples of a kinematic mode's trajectory that lie on the runner's
    sweep: the first input within the native sweep's span (the runner keeps
    1 % of the range clear of a limit; the engines' own sweeps may go nearer)
    and the other inputs at the values the native sweep holds them at."""
    native = run.native.inputs
    low, high = native[:, 0].min(), native[:, 0].max()
    slack = 1e-9 * max(1.0, high - low)
    keep = (inputs[:, 0] >= low - slack) & (inputs[:, 0] <= high + slack)
    if native.shape[1] > 1:
        keep &= np.all(np.abs(inputs[:, 1:] - native[0, 1:]) <= 1e-9 * np.maximum(1.0, np.abs(native[0, 1:])), axis=1)
    return keep


def _blocks(run: RunResult):
    """The panels' blocks of :func:`quantities` and :func:`error_plots`, each
    with one abscissa for every series in it.

    Returns
    -------
    list of (title, axis, series)
        ``axis`` is "input" (the first driver, the runner's sweep) or "time"
        (s); ``series`` lists (mode, x (SI), mask) with mask the samples shown.
        Kinematic modes go on the input, only their samples on the runner's
        sweep; dynamic modes of a one-input mechanism too (over their window),
        of a mechanism with several inputs against time, where every input moves.
    """
    several = len(run.mechanism.drivers) > 1
    sweep, timed = [], []
    for mode, outcome in run.outcomes.items():
        t = outcome.trajectory
        if mode == "native" or t is None:
            continue
        if not _is_dynamic(mode):
            sweep.append((mode, t.inputs[:, 0], _on_the_sweep(run, t.inputs)))
        elif several and t.times is not None:
            timed.append((mode, t.times, np.ones(len(t.times), dtype=bool)))
        else:
            sweep.append((mode, t.inputs[:, 0], np.ones(len(t.inputs), dtype=bool)))
    driver = run.mechanism.drivers[0].name
    held = ", ".join(d.name for d in run.mechanism.drivers[1:])
    blocks = [
        (
            f"the runner's sweep of {driver}" + (f" ({held} held at the assembly)" if several else ""),
            "input",
            sweep,
        )
    ]
    if timed:
        blocks.append(("the dynamic modes' simulated window (every input moves)", "time", timed))
    return blocks


def _abscissa(run: RunResult, axis: str, x: np.ndarray) -> tuple[np.ndarray, str]:
    return _input_axis(run, x) if axis == "input" else (x, "time [s]")


def quantities(run: RunResult) -> bytes:
    """Each quantity of the tracked point and body, all modes overlaid: against
    the first input over the runner's sweep, and (several inputs) the dynamic
    modes against time with the native solution at their states (PNG)."""
    return _png(quantities_figure(run))


def quantities_figure(run: RunResult):
    """The figure of :func:`quantities` (open: the caller closes it)."""
    mech, units = run.mechanism, run.mechanism.units
    point, body = tracked(run)
    scales = {
        "position": (units.length_factor, f"x of {point} [{units.length}]"),
        "velocity": (units.velocity_factor, f"|v| of {point} [{units.velocity}]"),
        "acceleration": (units.acceleration_factor, f"|a| of {point} [{units.acceleration}]"),
        "angle": (units.angle_factor, f"angle of {body} [{units.angle}]"),
        "omega": (units.angular_rate_factor, f"ω of {body} [{units.angular_rate}]"),
        "alpha": (units.angular_acceleration_factor, f"α of {body} [{units.angular_acceleration}]"),
    }
    blocks = _blocks(run)
    figure, grid = plt.subplots(2 * len(blocks), 3, figsize=(13, 1.0 + 7 * len(blocks)), squeeze=False)
    for b, (title, axis, series) in enumerate(blocks):
        axes = grid[2 * b : 2 * b + 2]
        if axis == "input":
            reference_x, reference = run.native.inputs[:, 0], _values(run.native, point, body)
            label = "native"
        else:  # the native solution at the first dynamic mode's own states
            trajectory = run.outcomes[series[0][0]].trajectory
            assert trajectory is not None
            reference_x = series[0][1]
            reference = _values(native_at(run.kinematics, trajectory, run.branch), point, body)
            label = f"native at {series[0][0]}'s states"
        for ax, category in zip(axes.flat, CATEGORIES):
            factor, ylabel = scales[category]
            native_x, xlabel = _abscissa(run, axis, reference_x)
            if reference[category] is not None:
                ax.plot(native_x, reference[category] / factor, label=label, **_style("native"))
            for mode, raw_x, mask in series:
                trajectory = run.outcomes[mode].trajectory
                assert trajectory is not None
                values = _values(trajectory, point, body)[category]
                if values is None or not mask.any():
                    continue
                x, _ = _abscissa(run, axis, raw_x[mask])
                values = values[mask]
                native_angle = reference[category]
                if category == "angle" and native_angle is not None:  # the native angle's turn, per sample
                    there = np.interp(x, native_x, native_angle)
                    values = values - 2 * np.pi * np.round((values - there) / (2 * np.pi))
                order = np.argsort(x, kind="stable")
                ax.plot(x[order], values[order] / factor, label=mode, **_style(mode))
            ax.set_ylabel(ylabel)
            ax.set_xlabel(xlabel)
            ax.grid(alpha=0.3)
        axes[0, 1].set_title(title, fontsize=9)
    return _with_legend_and_title(
        figure,
        grid,
        f"{mech.name}: quantities (native: line; engines: markers and dashes)\n"
        "each engine at the input it realised; the native line at the sweep's inputs with the rates and "
        "accelerations of the drivers' laws",
    )


def _relative_scales(run: RunResult, outcome) -> dict[str, float]:
    """Per category, the scale that makes a difference relative, as the verdict
    does (:func:`xcheck.runner._categorise`): the mechanism's size for
    positions, 1 rad for angles, else the largest magnitude of the quantity
    over all bodies and points (at least its physical floor; NaN where the
    mode's details have none)."""
    details = outcome.details
    largest = {} if details.empty else details.groupby("quantity", sort=False).scale.max().to_dict()
    scales = {category: float(largest.get(category, math.nan)) for category in CATEGORIES}
    scales.update(position=run.kinematics.system.size, angle=1.0)
    return scales


def error_plots(run: RunResult) -> bytes:
    """Each mode's largest difference over all bodies and points, as a fraction
    of its tolerance, against the input (or time), log scale, with one line at 1:
    the tolerance of every mode (PNG)."""
    return _png(error_figure(run))


def _figure_legend(figure, axes, top: float) -> None:
    """One legend for the whole figure, above its panels (never over the data):
    every series of ``axes`` once, by label."""
    seen: dict[str, object] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(label, handle)
    if seen:
        height = figure.get_size_inches()[1]
        figure.legend(
            list(seen.values()),
            list(seen),
            loc="upper center",
            bbox_to_anchor=(0.5, 1 - top / height),
            ncol=min(5, len(seen)),
            fontsize=7,
            frameon=False,
        )


def _with_legend_and_title(figure, grid, title: str):
    """A grid of panels (three to a row) finished: one legend above them, the
    two-line title, the fixed margins; returns the figure."""
    _figure_legend(figure, grid.flat, top=0.62)
    figure.suptitle(title, fontsize=10)
    _margins(figure, left=0.85, right=0.2, bottom=0.55, top=1.45, wspace=1.1, hspace=0.85)
    return figure


def error_figure(run: RunResult):
    """The figure of :func:`error_plots` (open: the caller closes it).

    Each mode is compared with the native solution at the inputs that mode
    realised (a driven engine's own input, as the verdict takes it), so a
    difference here is not the gap between the curves of :func:`quantities`
    where an engine's input lags the law."""
    blocks = _blocks(run)
    shown = {mode for _, _, series in blocks for mode, _, _ in series}
    limits: dict[str, dict[str, float]] = {mode: {} for mode in shown}  # per mode and category: its tolerance
    for mode in shown:
        table = run.outcomes[mode].categories
        for category, tolerance in zip(table.category, table.tolerance):
            limits[mode].setdefault(category, float(tolerance))
    scales = {mode: _relative_scales(run, run.outcomes[mode]) for mode in shown}  # one pass over each table
    figure, grid = plt.subplots(2 * len(blocks), 3, figsize=(13, 1.0 + 7 * len(blocks)), squeeze=False)
    for b, (title, axis, series) in enumerate(blocks):
        axes = grid[2 * b : 2 * b + 2]
        xlabel = _abscissa(run, axis, np.zeros(1))[1]
        for ax, category in zip(axes.flat, CATEGORIES):
            for mode, raw_x, mask in series:
                errors = run.outcomes[mode].errors.get(category)
                limit = limits[mode].get(category)
                if errors is None or not mask.any() or limit is None:
                    continue
                if not (np.isfinite(limit) and limit > 0):
                    continue
                ratio = errors[mask] / scales[mode][category] / limit
                x, _ = _abscissa(run, axis, raw_x[mask])
                order = np.argsort(x, kind="stable")
                floor = np.fmax(ratio[order], 1e-12)  # exact zeros (and below) drawn at the floor
                ax.semilogy(x[order], floor, label=mode, lw=1, **_line_style(mode))
            ax.axhline(1.0, color="red", ls="-", lw=1.0, label="tolerance")
            ax.set_ylabel(f"{category} difference / tolerance")
            ax.set_xlabel(xlabel)
            ax.grid(alpha=0.3, which="both")
            _plain_log_labels(ax)
        _log_panel_title(axes[0, 1], title)
    return _with_legend_and_title(
        figure,
        grid,
        f"{run.mechanism.name}: difference from the native solution as a fraction of each mode's tolerance "
        "(red line: the tolerance)\neach mode against the native solution at the input value, rate and acceleration "
        "it realised (solid: kinematic modes, dashed: dynamic; 1e-12: an exact zero or less)",
    )


#: the orders whose slopes the convergence plots draw for reference
REFERENCE_ORDERS = (1, 2, 4)


def _reference_slopes(ax) -> None:
    """Grey lines of error proportional to h^p for p in :data:`REFERENCE_ORDERS`,
    through the lower left of the data, inside the axes' present limits; a
    series parallel to one converges at that order."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    lines = [line for line in ax.get_lines() if len(line.get_xdata())]
    if not lines:
        return
    xs = np.concatenate([np.asarray(line.get_xdata(), dtype=float) for line in lines])
    ys = np.concatenate([np.asarray(line.get_ydata(), dtype=float) for line in lines])
    h_low, h_high = xs.min(), xs.max()
    if not h_high > h_low:  # one step: no slope to compare with
        return
    at_smallest = ys[(xs == h_low) & np.isfinite(ys) & (ys > 0)]
    anchor = float(at_smallest.min()) if at_smallest.size else y0
    for order, style in zip(REFERENCE_ORDERS, (":", "--", "-.")):
        h = np.geomspace(h_low, h_high, 20)
        e = anchor * (h / h_low) ** order
        ax.loglog(h, e, color="0.55", lw=0.9, ls=style, zorder=0)
        inside = e <= y1
        end = int(np.flatnonzero(inside)[-1]) if inside.any() else 0
        ax.annotate(
            f"h{order}".translate(_SUPERSCRIPTS) if order != 1 else "h",
            (h[end], e[end]),
            xytext=(2, 0),
            textcoords="offset points",
            fontsize=7,
            fontstyle="italic",
            color="0.4",
        )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def _step_ticks(ax) -> None:
    """Time-step ticks that do not overlap: short labels ("2e-04") at 1, 2 and 5
    times the powers of ten over at most two decades, else at the powers alone;
    the other minor ticks unlabelled."""
    low, high = ax.get_xlim()
    subs = (1.0, 2.0, 5.0) if math.log10(high / low) <= 2.0 else (1.0,)
    ax.xaxis.set_major_locator(ticker.LogLocator(base=10.0, subs=subs, numticks=12))
    ax.xaxis.set_major_formatter(ticker.FuncFormatter(lambda value, _: f"{value:.0e}"))
    ax.xaxis.set_minor_locator(ticker.LogLocator(base=10.0, subs=[float(k) for k in range(1, 10)], numticks=12))
    ax.xaxis.set_minor_formatter(ticker.NullFormatter())


def convergence_plot(run: RunResult) -> bytes | None:
    """Each dynamic mode's position error against time step, log-log (PNG); None if none ran."""
    figure = convergence_figure(run)
    return None if figure is None else _png(figure)


def convergence_figure(run: RunResult):
    """The figure of :func:`convergence_plot` (open: the caller closes it), or None.

    One panel per dynamic mode, two to a row; each series' observed order in
    its legend entry, the legend under its panel (never over the data). A panel
    whose errors all lie at the engine's round-off is said to be so, with the
    round-off bound drawn and no order fitted: there the error is solver noise."""
    dynamic = [(m, o) for m, o in run.outcomes.items() if _is_dynamic(m) and o.result is not None]
    tables = [(m, convergence_table(o)) for m, o in dynamic]
    tables = [(m, t) for m, t in tables if not t.empty]
    if not tables:
        return None
    columns = min(2, len(tables))
    rows = math.ceil(len(tables) / columns)
    legend_rows = max(t.series.nunique() for _, t in tables)
    # inches; under a panel: its axis label (down to 0.2 of its height, where the legend starts) and the legend
    panel_w, panel_h = 4.6, 3.1
    under = 0.2 * panel_h + 0.2 * (legend_rows + 1) + 0.1
    # (the figure's height: its title, then per row the panel and what stands under it)
    figure, axes = _panels(
        len(tables), columns, figsize=(1.1 + columns * panel_w + (columns - 1) * 1.0, 0.85 + rows * (panel_h + under))
    )
    round_off = convergence_round_off("position") * run.kinematics.system.size
    for ax, (mode, table) in zip(axes, tables):
        noise = bool((table.position_error.dropna() <= round_off).all())
        for series, part in table.groupby("series", sort=False):
            ok = part[part.position_error > 0]
            orders = part.order.dropna()
            label = str(series)
            verdict = str(part.verdict.iloc[0]) if "verdict" in part else "converging"
            if noise:
                label += ": at round-off, no order"
            elif len(orders):
                order = float(orders.iloc[-1])
                label += f": order {order:.2f}" if verdict == "converging" else f": {verdict} (order {order:.2f})"
            ax.loglog(ok.timestep, ok.position_error, "o-", ms=4, label=label)
        ax.margins(x=0.06, y=0.12)
        ax.autoscale_view()
        if noise:
            ax.axhline(round_off, color="0.3", ls=":", lw=1.2, label=f"round-off bound {round_off:.1e} m")
            ax.set_ylim(top=max(ax.get_ylim()[1], 2.0 * round_off))
            ax.text(
                0.5,
                0.5,
                "round-off: the error is solver noise\n(no order to observe)",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=8,
                color="0.3",
            )
        else:
            _reference_slopes(ax)
        _step_ticks(ax)
        _plain_log_labels(ax)
        _log_panel_title(ax, mode)
        ax.set_xlabel("time step [s]")
        ax.set_ylabel("largest position error [m]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    height = figure.get_size_inches()[1]
    figure.suptitle(  # placed in inches from the top, so that a tall grid's title clears its first panels
        f"{run.mechanism.name}: error against time step (observed order between the two smallest steps;\n"
        "grey: slopes of order 1, 2, 4)",
        fontsize=10,
        y=1 - 0.12 / height,
        va="top",
    )
    _margins(figure, left=1.1, right=0.25, bottom=under, top=0.85, wspace=1.0, hspace=under + 0.35)
    return figure


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
    figure, axes = _panels(len(panels), columns, figsize=(4.4 * columns, 3.2 * rows))
    for ax, (kind, name) in zip(axes, panels):
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
    axes[0].legend(fontsize=7)
    figure.suptitle(f"{run.mechanism.name}: driving effort and joint reactions over the simulation window", fontsize=10)
    _margins(figure, left=0.75, right=0.2, bottom=0.55, top=0.45, wspace=0.85, hspace=0.7)
    return _png(figure)
