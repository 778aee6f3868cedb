"""Newton in free motion (newton-free, on request) against the native reference: each
solver that takes a loop joint, on the free four-bar (tests/data/free-fourbar-released.toml);
and in driven dynamics (newton-dynamic, on request), the crank a kinematic body, on the
bundled four-bar. Its solvers' warp kernels compile on first use (about 40 CPU s for the
four, cached after in warp's kernel cache): each ladder runs once per session, at two steps.

Measured with newton 1.8.0 (warp 1.19, mujoco-warp 3.17 on MuJoCo 4.0) at dt = 1, 0.5,
0.25 ms over 1 s: SolverMuJoCo 5.0e-2, 5.5e-2, 5.7e-2 m (not converging: MuJoCo's
default constraint softness, solref 0.02; loops 6.2e-4 .. 7.4e-4 m open); SolverXPBD
0.30, 0.14, 0.10 m (loops 2.3e-4 .. 1.1e-5 m); SolverFeatherstone comes apart at 0.1 s
(the loop joint ignored: 3.3e-2 m open at the first output); SolverSemiImplicit leaves
the branch at 0.13 s.
"""

from __future__ import annotations

import dataclasses
import warnings

import pytest
from conftest import run_dynamic, run_free

pytest.importorskip("newton")
pytest.importorskip("mujoco_warp")

from xcheck import engines  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.newton.dynamic import driven_bodies  # noqa: E402
from xcheck.ladder import DrivenProblem  # noqa: E402

FEATHERSTONE = "Newton's SolverFeatherstone ignores loop joints"


@pytest.fixture(scope="module")
def ladder(released_fourbar):
    kin, reference = released_fourbar
    return run_free("newton-free", kin, reference, timestep=1e-3, rungs=2)


@pytest.fixture(scope="module")
def driven(kinematics):
    """newton-dynamic's ladder on the four-bar at 25 and 50 steps a sample, every solver."""
    kin = kinematics("fourbar")
    problem = DrivenProblem.of(kin)
    series = engines.engine("newton").dynamic_series("newton-dynamic", problem)
    return run_dynamic(
        "newton-dynamic", kin, series=[dataclasses.replace(s, timestep=problem.interval / 25, rungs=2) for s in series]
    )


@pytest.mark.parametrize("name", ["newton-free", "newton-dynamic"])
def test_the_modes_run_on_request_and_say_why(name):
    mode = engines.mode(name)
    assert mode.on_request and "compile" in mode.on_request_reason and not mode.campaigns
    assert engines.engine("newton").install == "pip install xcheck[newton]"


@pytest.mark.slow
def test_each_solver_is_a_row_and_featherstone_shows_its_dropped_loop(ladder):
    rows = {name: part for name, part in ladder.summary.groupby("series")}
    assert set(rows) == {"mujoco", "xpbd", "featherstone", "semi-implicit"}
    featherstone = rows["featherstone"]
    assert featherstone["status"].str.startswith("came apart").all()  # measured: 3.3e-2 m open at 0.1 s
    # its finding flags its rows, and only its
    assert (featherstone["finding"] == FEATHERSTONE).all() and not ladder.summary[
        ladder.summary.series != "featherstone"
    ]["finding"].any()
    mujoco = rows["mujoco"]
    assert (mujoco["status"] == "ok").all() and mujoco["loop_drift"].max() <= 2e-3  # measured 6.2e-4, 7.0e-4 m
    # MuJoCo's default softness: an error that does not fall with the step (measured 5.0e-2, 5.5e-2 m)
    verdicts = ladder.study.groupby("series")["verdict"].first()
    assert verdicts["mujoco"] == "not converging" and verdicts["featherstone"] == "cannot tell"
    xpbd = rows["xpbd"].sort_values("timestep", ascending=False)
    assert (xpbd["status"] == "ok").all() and xpbd["loop_drift"].iloc[-1] < xpbd["loop_drift"].iloc[0]


def test_driven_xpbd_converges_at_second_order_around_the_kinematic_crank(driven):
    """Measured at 25 and 50 steps a sample (1.6 and 0.8 ms): XPBD's position errors 2.1e-4,
    5.4e-5 (ratio 3.8), the crank where it was set to 1.9e-7 rad (float32); MuJoCo's backend
    1.4e-3, 6.5e-4 (first order, its soft loop constraint); Featherstone's loop comes apart
    at 0.53 s (its finding flags its rows, and only its)."""
    assert driven.ok
    verdicts = driven.study.groupby("series")["verdict"].last()
    assert verdicts["xpbd"] == "converging" and verdicts["featherstone"] == "cannot tell"
    rows = {name: part.sort_values("timestep") for name, part in driven.summary.groupby("series")}
    xpbd = rows["xpbd"]
    assert (xpbd["status"] == "ok").all() and (xpbd["input_error"] < 1e-6).all()
    errors = xpbd["position_error"].to_numpy()  # finest first
    assert 3.5 <= errors[1] / errors[0] <= 4.5
    mujoco = rows["mujoco"]
    assert (mujoco["status"] == "ok").all() and mujoco["position_error"].max() < 1e-2
    featherstone = rows["featherstone"]
    assert featherstone["status"].str.startswith("came apart").all() and (featherstone["finding"] == FEATHERSTONE).all()
    assert not driven.summary[driven.summary.series != "featherstone"]["finding"].any()


def test_a_driver_between_moving_bodies_is_not_applicable(kinematics):
    arm = kinematics("two-body-arm")
    with pytest.raises(NotApplicable, match="joins two moving bodies: Newton prescribes a motion only through"):
        driven_bodies(arm.mechanism, DrivenProblem.of(arm).start.q[0])
    fourbar = kinematics("fourbar")
    assert driven_bodies(fourbar.mechanism, DrivenProblem.of(fourbar).start.q[0]) == {"crank"}


def test_a_point_mass_keeps_the_least_inertia_every_engine_gets():
    """IFToMM A01's bob (inertia 0 in its file): Newton would raise the least inertia,
    1e-12 m size^2, to about 1e-6 kg m^2 with a warning."""
    import numpy as np

    import xcheck
    from xcheck.engines._contract import positive_inertia
    from xcheck.engines.newton.model import build

    kin = xcheck.load("iftomm-a01").kinematics
    q = kin.assemble()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        built = build(kin.mechanism, q, np.zeros_like(q))
    bob = kin.mechanism.moving_bodies[0]
    least = positive_inertia(float(bob.mass), 0.0, kin.mechanism.size)
    assert np.allclose(np.diag(built.model.body_inertia.numpy()[0]), least, rtol=1e-6)
