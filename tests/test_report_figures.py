"""The run report's figures (issue 16): one sweep and one abscissa per block,
relative differences against each mode's tolerance, convergence slopes and
ticks that do not overlap."""

from __future__ import annotations

import io
import itertools
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import MODELS  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import NullLocator  # noqa: E402

from xcheck import api  # noqa: E402
from xcheck.report import _figures  # noqa: E402


def test_kinematic_samples_off_the_runners_sweep_are_left_out():
    native = np.column_stack([np.linspace(0.1, 1.0, 5), np.full(5, 0.5)])
    run = SimpleNamespace(native=SimpleNamespace(inputs=native))
    engine = np.array(
        [
            [0.1, 0.5],  # on the sweep
            [1.0, 0.5],  # its end
            [1.0 + 1e-3, 0.5],  # past the runner's margin: the engine's own sweep goes nearer the limit
            [0.5, 0.2],  # the second driver's sweep
        ]
    )
    assert _figures._on_the_sweep(run, engine).tolist() == [True, True, False, False]


def test_reference_slopes_are_orders_one_two_and_four():
    figure = Figure()
    ax = figure.add_subplot()
    ax.loglog([1e-4, 1e-3], [1e-9, 1e-6], "o-")
    limits = ax.get_xlim(), ax.get_ylim()
    _figures._reference_slopes(ax)
    slopes = sorted(
        round(float(np.polyfit(np.log(line.get_xdata()), np.log(line.get_ydata()), 1)[0]), 9)
        for line in ax.get_lines()
        if line.get_color() == "0.55"
    )
    assert slopes == [1.0, 2.0, 4.0]
    assert (ax.get_xlim(), ax.get_ylim()) == limits  # the data's view is kept


@pytest.mark.parametrize("span", [(1.5e-4, 2.1e-3), (2e-3, 8e-3), (1e-6, 1e-2)])
def test_time_step_tick_labels_do_not_overlap(span):
    figure = Figure(figsize=(4.6, 4))
    ax = figure.add_subplot()
    ax.loglog(span, [1e-9, 1e-6], "o-")
    _figures._step_ticks(ax)
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = [
        label.get_window_extent(renderer)
        for label in ax.get_xticklabels(which="both")
        if label.get_visible() and label.get_text() and ax.get_xlim()[0] <= label.get_position()[0] <= ax.get_xlim()[1]
    ]
    assert len(boxes) >= 2  # labelled, even on less than a decade
    assert not any(a.overlaps(b) for a, b in itertools.combinations(boxes, 2))


@pytest.mark.parametrize(
    "y, minor_labelled",
    [((3e-10, 4e-4), False), ((2e-7, 3e-5), False), ((2e-6, 5e-6), True)],  # decades; under one: labels
)
def test_minor_ticks_drawn_as_two_lines_give_matplotlibs_pixels(y, minor_labelled):
    """The report's unlabelled minor ticks, drawn as one line of tick marks and
    one of grid lines per axis, are the pixels of matplotlib's own ticks (grid
    on both, log x with the time-step ticks of the convergence figure)."""

    def figure() -> Figure:
        made = Figure(figsize=(3.2, 2.6))
        ax = made.add_subplot()
        ax.loglog([1.5e-4, 2.1e-3], y, "o-")
        ax.grid(alpha=0.3, which="both")
        _figures._step_ticks(ax)
        return made

    def pixels(made: Figure) -> bytes:
        canvas = FigureCanvasAgg(made)
        canvas.draw()
        return bytes(canvas.buffer_rgba())

    theirs, ours = figure(), figure()
    _figures._unlabelled_minor_ticks_as_lines(ours)
    (ax,) = ours.axes
    replaced = {axis: isinstance(axis.get_minor_locator(), NullLocator) for axis in (ax.xaxis, ax.yaxis)}
    assert replaced == {ax.xaxis: True, ax.yaxis: not minor_labelled}
    assert len(ax.lines) == 1 + sum(replaced.values()) == 1 + len(ax.collections)  # data; marks, grid per axis
    assert pixels(ours) == pixels(theirs)


@pytest.mark.parametrize(
    "x, y, scale, replaced",
    [
        ((-130.0, 125.0), (0.1, 800.0), "linear", True),  # the quantities figure's panels
        ((-130.0, 125.0), (-18.0, 6.5), "linear", True),  # negative labels
        ((-130.0, 125.0), (1e-12, 1.0), "log", True),  # the differences figure's, minor ticks unlabelled
        ((-130.0, 125.0), (2e-6, 7e-6), "log", True),  # labelled minor ticks: drawn as artists too
        ((-130.0, 125.0), (1e5, 1e5 + 1e-3), "linear", False),  # labels with an offset: left as they are
        ((-0.2, 0.32), (-0.2, 0.3), "equal", True),  # the drawing: its limits set by the aspect as it draws
    ],
)
def test_major_ticks_drawn_as_artists_give_matplotlibs_pixels(x, y, scale, replaced):
    """A report's major ticks, drawn as one line of tick marks, one of grid lines
    and a text per label, with the axis labels placed clear of them as matplotlib
    places them, are the pixels of matplotlib's own ticks."""

    def figure() -> Figure:
        made = Figure(figsize=(3.2, 2.6), dpi=90)
        FigureCanvasAgg(made)
        ax = made.add_subplot()
        ax.plot(x, y, "o-")
        if scale == "equal":
            ax.set_aspect("equal", adjustable="datalim")
        else:
            ax.set_yscale(scale)
        ax.set_xlabel("crank [deg]")
        ax.set_ylabel("x of C [mm]")
        ax.set_title("the runner's sweep", fontsize=9)
        ax.grid(alpha=0.3, which="both")
        return made

    def pixels(made: Figure) -> bytes:
        made.canvas.draw()
        return bytes(made.canvas.buffer_rgba())

    theirs, ours = figure(), figure()
    _figures._unlabelled_minor_ticks_as_lines(ours)
    _figures._major_ticks_as_artists(ours)
    (ax,) = ours.axes
    assert isinstance(ax.xaxis.get_major_locator(), NullLocator)
    assert isinstance(ax.yaxis.get_major_locator(), NullLocator) == replaced
    if scale == "log":  # its minor ticks too, labelled or not
        assert isinstance(ax.yaxis.get_minor_locator(), NullLocator) == replaced
    assert pixels(ours) == pixels(theirs)


@pytest.fixture(scope="module")
def two_input_run():
    return api.run("two-body-arm", engines="formulations,mujoco", samples=21, models=MODELS)


def test_two_inputs_the_sweep_against_the_input_and_the_dynamic_modes_against_time(two_input_run):
    run = two_input_run
    figure = _figures.quantities_figure(run)
    axes = np.array(figure.axes).reshape(4, 3)
    assert {ax.get_xlabel() for ax in axes[:2].flat} == {"theta1 [deg]"}
    assert {ax.get_xlabel() for ax in axes[2:].flat} == {"time [s]"}
    low, high = np.degrees(run.native.inputs[:, 0].min()), np.degrees(run.native.inputs[:, 0].max())
    for ax in axes[:2].flat:
        labels = {line.get_label() for line in ax.get_lines()}
        assert "mujoco-dynamic" not in labels
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata())
            assert x.min() >= low - 1e-9 and x.max() <= high + 1e-9, line.get_label()
            assert np.ptp(x) > 0.9 * (high - low), line.get_label()  # no stack of samples at one input
    assert {line.get_label() for line in axes[2, 0].get_lines()} == {
        "native at mujoco-dynamic's states",
        "mujoco-dynamic",
    }


def test_differences_are_fractions_of_each_modes_tolerance_with_one_tolerance_line(two_input_run):
    """Each mode's difference, relative as the verdict takes it, divided by its
    own tolerance: one line at 1 is every mode's tolerance (ten dotted lines in
    engine colours could not be told apart)."""
    run = two_input_run
    figure = _figures.error_figure(run)
    position = figure.axes[0]
    outcome = run.outcomes["mujoco-kinematic"]
    (line,) = [line for line in position.get_lines() if line.get_label() == "mujoco-kinematic"]
    keep = _figures._on_the_sweep(run, outcome.trajectory.inputs)
    tolerance = float(outcome.categories.set_index("category").tolerance["position"])
    expected = np.fmax(outcome.errors["position"][keep] / run.kinematics.system.size / tolerance, 1e-12)
    x = np.degrees(outcome.trajectory.inputs[keep, 0])
    assert np.array_equal(np.asarray(line.get_ydata()), expected[np.argsort(x, kind="stable")])
    for ax in figure.axes:
        (tolerance_line,) = [line for line in ax.get_lines() if line.get_label() == "tolerance"]
        assert list(tolerance_line.get_ydata()) == [1.0, 1.0]
        assert not [line for line in ax.get_lines() if line.get_linestyle() == ":"]  # no per-mode dotted bounds
    assert position.get_yscale() == "log"
    assert position.get_legend() is None and len(figure.legends) == 1  # the legend outside the panels


def _boxes_apart(figure) -> None:
    """Every panel with its tick labels, axis labels and title lies inside the
    figure and clear of the other panels (fixed margins instead of tight_layout
    must not hide or overlap anything a reader relies on)."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    page = figure.bbox
    boxes = [ax.get_tightbbox(renderer) for ax in figure.axes if ax.get_visible()]
    for box in boxes:
        assert box.x0 >= page.x0 - 1 and box.y0 >= page.y0 - 1 and box.x1 <= page.x1 + 1 and box.y1 <= page.y1 + 1
    for a, b in itertools.combinations(boxes, 2):
        overlap_x = min(a.x1, b.x1) - max(a.x0, b.x0)
        overlap_y = min(a.y1, b.y1) - max(a.y0, b.y0)
        assert overlap_x <= 1 or overlap_y <= 1, (a, b)
    title = figure._suptitle.get_window_extent(renderer)
    assert all(title.y0 >= box.y1 - 1 for box in boxes)


def test_panels_and_their_labels_fit_without_tight_layout(two_input_run):
    _boxes_apart(_figures.quantities_figure(two_input_run))
    _boxes_apart(_figures.error_figure(two_input_run))
    convergence = _figures.convergence_figure(two_input_run)
    assert convergence is not None
    _boxes_apart(convergence)


@pytest.mark.parametrize("name", ["slider-crank", "two-body-arm"])
def test_the_gif_is_matplotlibs_drawing_of_each_frame_in_one_palette(name):
    """Each frame of the GIF is matplotlib's drawing of its pose, its colours
    reduced to one palette for the whole animation (Pillow's median cut of all
    the frames' pixels; at most 256 colours in all
    frames together: a palette per frame gives thousands), white kept white, and
    the few pixels of anti-aliased edges moved to a near colour (1.2 % of a frame
    at most, measured on three mechanisms; 0.9 % with a median cut per frame)."""
    from PIL import Image, ImageSequence

    run = api.run(name, engines="formulation-II", samples=61, models=MODELS)  # 24 distinct poses of 61
    data = _figures.motion_gif(run)
    figure, draw = _figures._motion_figure(run, 24)
    drawn = []
    for n in range(24):
        draw(n)
        figure.canvas.draw()
        drawn.append(np.array(figure.canvas.buffer_rgba())[..., :3])
    matplotlib.pyplot.close(figure)
    with Image.open(io.BytesIO(data)) as movie:
        frames = [np.asarray(frame.convert("RGB")) for frame in ImageSequence.Iterator(movie)]
        # 12 frames a second: 83 ms, which a GIF holds in hundredths of a second
        assert movie.size == (315, 252) and movie.info["loop"] == 0 and movie.info["duration"] == 80
    assert len(frames) == 24
    strip = np.concatenate(drawn)  # the palette: Pillow's median cut of every pixel, cut from those not white
    every = Image.fromarray(strip).quantize(256, method=Image.Quantize.MEDIANCUT)
    assert np.array_equal(np.asarray(_figures._one_palette(strip).convert("RGB")), np.asarray(every.convert("RGB")))
    packed = np.stack(frames).astype(np.uint32) @ np.array([1 << 16, 1 << 8, 1], dtype=np.uint32)
    assert len(np.unique(packed)) <= 256
    for frame, truth in zip(frames, drawn):
        moved = (frame != truth).any(axis=2)
        assert not moved[(truth == 255).all(axis=2)].any()  # the background exact
        assert moved.mean() <= 0.02
    # the mechanism moves from frame to frame (a whole turn: the last pose is the first)
    assert len({frame.tobytes() for frame in frames[:-1]}) == 23


def test_log_axes_are_labelled_in_plain_text():
    """The log axes' labels are matplotlib's (10^k, c×10^k where it labels the
    minor ticks) in plain text with superscripts, and drawing the differences and
    convergence figures never starts matplotlib's mathtext parser."""
    formatter = _figures._PlainLogFormatter(10.0, labelOnlyBase=False)
    figure = Figure()
    ax = figure.add_subplot()
    ax.semilogy([0, 1], [2e-6, 7e-6])
    formatter.set_axis(ax.yaxis)
    formatter.set_locs([2e-6, 6e-6])
    assert [formatter(1e-4), formatter(1.0), formatter(1e3), formatter(6e-6)] == ["10⁻⁴", "10⁰", "10³", "6×10⁻⁶"]


def test_the_differences_and_convergence_figures_use_no_mathtext(two_input_run, monkeypatch):
    import matplotlib.mathtext

    def refused(*_):
        raise AssertionError("mathtext")

    monkeypatch.setattr(matplotlib.mathtext.MathTextParser, "parse", refused)
    for figure in (_figures.error_figure(two_input_run), _figures.convergence_figure(two_input_run)):
        assert figure is not None
        assert _figures._png(figure).startswith(b"\x89PNG")


def test_a_figures_png_holds_savefigs_pixels():
    """The report's PNG (RGB, no metadata but the resolution) has the pixels of
    matplotlib's own PNG of the same figure."""
    from PIL import Image

    def figure() -> Figure:
        made = Figure(figsize=(3.2, 2.6))
        ax = made.add_subplot()
        ax.loglog([1.5e-4, 2.1e-3], [3e-10, 4e-4], "o-", label="a")
        ax.grid(alpha=0.3, which="both")
        ax.legend()
        return made

    ours = Image.open(io.BytesIO(_figures._png(figure())))
    saved = io.BytesIO()
    figure().savefig(saved, format="png", dpi=90)
    theirs = Image.open(saved)
    assert ours.mode == "RGB" and set(ours.info) == {"dpi"}
    assert np.array_equal(np.asarray(ours.convert("RGBA")), np.asarray(theirs.convert("RGBA")))


def test_convergence_panels_in_a_grid_with_legends_under_them_and_round_off_said():
    """Two panels to a row; each legend under its panel with every series' order;
    Exudyn's positions, at round-off (index-3 loops), get no order and say so."""
    run = api.run("slider-crank", engines="mujoco-dynamic,pymunk-dynamic,exudyn-dynamic", samples=21, models=MODELS)
    figure = _figures.convergence_figure(run)
    assert figure is not None
    grid = figure.axes[0].get_gridspec()
    assert (grid.nrows, grid.ncols) == (2, 2) and len(figure.axes) == 3  # the grid's fourth place left empty
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in figure.axes[:3]:
        legend = ax.get_legend()
        assert legend.get_window_extent(renderer).y1 < ax.get_window_extent(renderer).y0  # under the data
    labels = {ax.get_title(): [t.get_text() for t in ax.get_legend().get_texts()] for ax in figure.axes[:3]}
    assert any("order 2" in label for label in labels["mujoco-dynamic"])
    assert all("at round-off, no order" in label for label in labels["exudyn-dynamic"][:-1])
    assert labels["exudyn-dynamic"][-1].startswith("round-off bound")
    assert not any(t.get_text().startswith("h") for t in figure.axes[2].texts)  # no slopes to fit
    _boxes_apart(figure)  # the title too, above the panels of a grid two rows high


def test_a_figure_fitted_to_its_contents_holds_a_legend_beside_its_panel():
    """A legend beside the axes, taller and wider than the figure, lies whole in
    the fitted PNG, measured at the resolution it is drawn at, with the margin asked."""
    figure = Figure(figsize=(3.0, 2.0))
    ax = figure.add_subplot()
    for k in range(30):
        ax.plot([0, 1], [k, k + 1], label=f"series {k}: a long label that runs beyond the figure")
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    FigureCanvasAgg(figure)
    figure.set_dpi(110)
    _figures._fit_to_contents(figure, 0.1)
    figure.canvas.draw()
    box = figure.get_tightbbox(figure.canvas.get_renderer())  # inches
    width, height = figure.get_size_inches()
    assert width > 3.0 and height > 2.0
    for margin in (box.x0, box.y0, width - box.x1, height - box.y1):
        assert margin == pytest.approx(0.1, abs=1.5 / 110)  # to the pixel


def test_free_motion_figures_are_written_as_a_runs_are(monkeypatch):
    """The free-motion report's figures: RGB with no metadata but the resolution,
    log axes labelled in plain text without matplotlib's mathtext."""
    import matplotlib.mathtext
    from PIL import Image

    from xcheck.report import _simulation
    from xcheck.simulation import simulate_all

    def refused(*_):
        raise AssertionError("mathtext")

    kinematics = api.load("iftomm-a01", models=MODELS).kinematics
    result = simulate_all(kinematics, ["mujoco-free"], duration=0.1)
    monkeypatch.setattr(matplotlib.mathtext.MathTextParser, "parse", refused)
    drawn = _simulation.figures(result)
    assert set(drawn) == {"drawing", "energy", "errors", "work-precision"}
    for data in drawn.values():
        with Image.open(io.BytesIO(data)) as image:
            assert image.mode == "RGB" and set(image.info) == {"dpi"}
