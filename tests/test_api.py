"""The Python interface (xcheck.api): what ``xcheck run`` does, as functions."""

from __future__ import annotations

import doctest
import math
import warnings

import pytest
from conftest import MODEL_NAMES, MODELS

import xcheck
from xcheck import api
from xcheck.motion import drive_warnings


def test_docstring_examples_run():
    failed, attempted = doctest.testmod(api)
    assert attempted >= 2 and failed == 0


def test_load_by_name_and_by_path_is_assembled():
    by_name = xcheck.load("fourbar", models=MODELS)
    by_path = xcheck.load(MODELS / "fourbar.toml")
    assert by_name.mechanism.path == by_path.mechanism.path
    assert by_name.mechanism.name == "fourbar"


def test_select_modes_takes_groups_and_sequences():
    assert xcheck.select_modes(["mujoco-kinematic", "formulations"]) == (
        "native",
        "mujoco-kinematic",
        "formulation-I",
        "formulation-II",
    )
    assert xcheck.select_modes("pymunk") == ("native", "pymunk-dynamic")
    with pytest.raises(xcheck.InputError, match="found 'nosuch'"):
        xcheck.select_modes("nosuch")


def test_an_engine_with_free_motion_only_is_named_where_it_runs():
    class FreeOnly(xcheck.engines.Engine):
        name = "freeonly"
        modes = (xcheck.engines.Mode("freeonly-free", "free", xcheck.tolerances.FREE_MOTION),)

    xcheck.engines.register(FreeOnly)
    try:
        with pytest.raises(xcheck.InputError) as raised:
            xcheck.select_modes("dart,freeonly")
    finally:
        xcheck.engines.unregister("freeonly")
    assert "found 'freeonly', whose modes are freeonly-free (free): run them with xcheck simulate" in str(raised.value)


def test_run_is_the_run_without_printing():
    run = api.run("fourbar", engines="formulations", samples=21, models=MODELS)
    assert run.passed
    assert set(run.outcomes) == {"native", "formulation-I", "formulation-II"}
    assert len(run.textbook) == 96  # comparisons/fourbar.toml, found beside models/


def test_import_xcheck_stays_light():
    """``import xcheck`` loads neither the runner, pandas, matplotlib nor an engine."""
    import subprocess
    import sys

    code = (
        "import sys, xcheck; heavy = [m for m in ('xcheck.runner', 'xcheck.api', 'pandas', 'matplotlib', "
        "'mujoco', 'pinocchio', 'pymunk') if m in sys.modules]; print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert xcheck.run is api.run and xcheck.simulate is api.simulate


def test_rates_default_to_the_drivers_laws_not_to_zero():
    mech = xcheck.load("fourbar", models=MODELS)
    declared = mech.solve(at=[30, 60]).solution
    assert declared.input_rates[:, 0].tolist() == [1.0, 1.0]  # rate = 1.0 rad/s in models/fourbar.toml
    assert abs(declared.qd).max() > 0.1
    static = mech.solve(at=[30, 60], rates=0).solution
    assert abs(static.qd).max() == 0.0
    doubled = mech.solve(at=60, rates=2).solution
    assert abs(doubled.qd[0] - 2 * declared.qd[1]).max() < 1e-12
    si = mech.solve(at=math.radians(60), si=True).solution
    assert abs(si.q[0] - declared.q[1]).max() < 1e-12
    with pytest.raises(xcheck.InputError, match="accelerations alone"):
        mech.solve(at=60, accelerations=1)


def test_instants_are_the_default_states():
    mech = xcheck.load("fourbar", models=MODELS)
    result = mech.solve()
    assert result.labels == [inst.label for inst in mech.mechanism.instants]


def test_to_frame_is_tidy_and_in_si():
    mech = xcheck.load("task-2-2", models=MODELS)
    result = mech.sweep(samples=11)
    frame = result.to_frame()
    points, bodies = len(mech.mechanism.point_owners), len(mech.mechanism.moving_bodies)
    assert len(frame) == 11 * (points + bodies)
    assert {"sample", "kind", "name", "x_m", "vx_m_s", "ax_m_s2", "angle_rad", "omega_rad_s", "r_y_m"} <= set(
        frame.columns
    )
    # a point's row is the solution's own numbers, in metres
    a = frame[(frame.kind == "point") & (frame.name == "A")].sort_values("sample")
    assert abs(a.y_m.to_numpy() - result.solution.point("A")["position"][:, 1]).max() == 0.0
    assert frame.groupby("sample").size().eq(points + bodies).all()
    assert frame[frame.kind == "point"].angle_rad.isna().all()


def test_a_limit_position_is_warned_about_with_its_input():
    mech = xcheck.load("fourbar", models=MODELS)
    # the file's crank is driven round but rocks: warned about on every solve, as on the command line
    drive = drive_warnings(mech.kinematics)
    assert len(drive) == 1 and "cannot turn fully" in drive[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = mech.solve(at=129.0227)
    assert result.warnings[:1] == drive and len(result.warnings) == 2
    assert "crank = 129.0227 deg is near a limit" in result.warnings[1]
    assert [str(w.message) for w in caught] == result.warnings
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        assert mech.solve(at=90).warnings == drive
        assert mech.sweep(samples=21).warnings == drive  # the runner's sweep keeps 1 % clear


def test_plot_and_draw_return_figures():
    from matplotlib.figure import Figure

    mech = xcheck.load("slider-crank", models=MODELS)
    assert isinstance(mech.sweep(samples=9).plot(), Figure)
    figure = mech.draw(at=30)
    assert isinstance(figure, Figure) and figure.axes[0].get_title() == "slider-crank: crank = 30 deg"
    with pytest.raises(xcheck.InputError, match="expected finite values|expected inputs"):
        mech.solve(at=[[1, 2]])


def test_the_summary_has_one_row_per_mode_and_shows_as_a_table():
    from xcheck.runner import SUMMARY_COLUMNS

    run = xcheck.run("fourbar", engines="formulations", samples=21, models=MODELS)
    table = run.summary
    assert list(table.columns) == list(SUMMARY_COLUMNS)
    assert table["mode"].tolist() == ["native", "formulation-I", "formulation-II"]
    assert (table.verdict == "pass").all() and (table.error <= table.tolerance).all()
    assert run.verdict == "pass"
    html = run._repr_html_()
    assert html.startswith("<p><b>fourbar</b>: pass") and html.count("<tr") == 4  # header + three modes


def test_a_fresh_import_gives_the_whole_public_surface():
    """The README's Python example on a fresh ``import xcheck``: no ``xcheck.load``
    first, ``xcheck.api`` reachable, and the names a newcomer may try for the
    comparison say which one it is."""
    import subprocess
    import sys

    code = (
        "import xcheck\n"
        "assert callable(xcheck.api.run)\n"
        "run = xcheck.run('fourbar', engines='formulations', samples=11)\n"
        "print(run.verdict, len(run.summary))\n"
        "try:\n    xcheck.compare_engines\nexcept AttributeError as err:\n    print(err)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    lines = out.stdout.splitlines()
    assert lines[0] == "pass 3"
    assert "xcheck.run(...) compares the engines" in lines[1]


def test_solve_warns_about_a_limit_position_before_the_numbers():
    from conftest import invoke

    result = invoke("solve", "fourbar", "--at", "129.0227", "--models", str(MODELS))
    assert result.returncode == 0
    # the textbook's crank is driven round at 1 rad/s but rocks: that is warned about too, first
    drive = "xcheck: warning: fourbar: crank is driven round at a constant rate of 1 rad/s, but it cannot turn fully"
    lines = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(lines) == 2 and lines[0].startswith(drive) and "crank = 129.0227 deg is near a limit" in lines[1]
    quiet = invoke("solve", "fourbar", "--at", "60", "--models", str(MODELS))
    assert quiet.returncode == 0 and [line for line in quiet.stderr.splitlines() if "warning" in line] == [lines[0]]


def test_animate_gives_an_animation_that_saves(tmp_path):
    mech = xcheck.load("slider-crank", models=MODELS)
    movie = mech.animate(frames=6)
    target = tmp_path / "motion.gif"
    movie.save(target, writer="pillow")
    assert target.read_bytes()[:6] == b"GIF89a"


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_no_warning_on_the_bundled_instants_and_sweeps(name):
    """The thresholds of limit_warnings are loose enough that the runner's
    sweep (1 % clear of a limit) and the books' instants are never flagged:
    their only warnings are the file's own (a driver's law that asks more than
    its joint can do), those the command line prints too."""
    mech = xcheck.load(name, models=MODELS)
    drive = drive_warnings(mech.kinematics)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert mech.sweep(samples=181).warnings == drive
        if mech.mechanism.instants:
            assert mech.solve().warnings == drive
    assert [str(w.message) for w in caught] == drive * (2 if mech.mechanism.instants else 1)
