"""``xcheck fuzz`` (issue 18): random mechanisms, Parquet rows, resume, Dask.

Also the one rule for a motion that starts outside the feasible range
(tests/data/start-outside.toml): ``xcheck run`` refuses it up front, whatever
modes are asked for and whether or not the bodies have masses.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from conftest import invoke, shifted_sweep

from xcheck import fuzz
from xcheck.kinematics import Kinematics
from xcheck.model import load_mechanism, parse_mechanism

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"

#: figures that differ between two runs of the same cases: the wall-clock times
TIMINGS = ["seconds"]


def _comparable(rows: pd.DataFrame, out: Path) -> pd.DataFrame:
    """Rows without timings and with the file paths relative to the campaign folder."""
    rows = rows.drop(columns=TIMINGS).copy()
    rows["file"] = [str(Path(f).relative_to(out)) for f in rows.file]
    return rows.reset_index(drop=True)


def test_same_seed_same_files_other_seed_other_files():
    first = [fuzz.generate(7, i).text for i in range(30)]
    assert first == [fuzz.generate(7, i).text for i in range(30)]
    assert first[5] == fuzz.generate(7, 5).text  # a case does not depend on the others drawn
    other = [fuzz.generate(8, i).text for i in range(30)]
    assert all(a != b for a, b in zip(first, other))


def test_kinds_are_chosen_and_checked():
    assert {fuzz.generate(3, i, ("slider-crank",)).kind for i in range(10)} == {"slider-crank"}
    with pytest.raises(
        fuzz.InputError, match=r"^kinds: expected kinds among fourbar, slider-crank, scotch-yoke, found"
    ):
        fuzz.generate(3, 0, ("fourbar", "crank"))
    assert fuzz.generate(3, 0, "slider-crank").kind == "slider-crank"  # a comma-separated string, as --kinds


def _assembles_where_drawn(count: int) -> set:
    """``count`` cases of each kind load, assemble, and put the sketched point (C, B
    or P) where the generator's closed-form position says: the branch drawn.
    Returns the (kind, shape, law, masses) seen."""
    seen = set()
    for kind in fuzz.KINDS:
        for i in range(count):
            case = fuzz.generate(11, i, (kind,))
            seen.add((case.kind, case.shape, case.law, case.masses))
            kin = Kinematics(parse_mechanism(case.text, case.name))
            kin.assemble()
            solution = kin.solve(kin.reference_inputs()[None, :])
            assert solution.success, case.name
            sketch = next(iter(kin.mechanism.assembly.branches.values()))
            for label, expected in sketch.items():
                found = solution.point(label)["position"][0]
                assert np.allclose(found, expected, rtol=0, atol=1e-6 * case.scale), (case.name, label, found, expected)
    return seen


def test_generated_mechanisms_assemble_where_drawn():
    _assembles_where_drawn(4)


@pytest.mark.slow
def test_every_kind_shape_and_law_is_drawn_and_assembles():
    seen = _assembles_where_drawn(40)
    shapes = {(k, s) for k, s, _, _ in seen}
    assert {("fourbar", s) for s in ("grashof", "non-grashof", "near-parallelogram", "near-change-point")} <= shapes
    assert {("slider-crank", s) for s in ("full-turn", "rocking", "near-dead-centre", "extreme-ratio")} <= shapes
    assert {law for _, _, law, _ in seen} == {"constant-rate", "constant-acceleration", "harmonic"}
    assert {m for *_, m in seen} == {True, False}


def test_scales_span_centimetres_to_kilometres():
    scales = [fuzz.generate(2, i).scale for i in range(300)]
    assert 0.01 <= min(scales) < 0.05 and 200 < max(scales) <= 1000


def test_small_run_writes_one_row_per_case_and_mode_and_resumes(tmp_path):
    out = tmp_path / "campaign"
    rows = fuzz.fuzz(out, count=3, seed=1, modes="formulations", workers=1, batch=2)
    modes = ("native", "formulation-I", "formulation-II")
    driven = rows[rows["mode"].isin(modes)]
    assert len(driven) == 3 * len(modes)
    assert set(driven.case) == {fuzz.generate(1, i).name for i in range(3)}
    assert set(rows.columns) == set(fuzz.COLUMNS)
    assert len(list((out / "results").glob("part-*.parquet"))) == 2  # batches of 2 and 1
    assert all(Path(f).is_file() for f in rows.file)  # every case has its file
    assert rows.outcome.isin(["passed", "failed", "error", "not-applicable", "refused", "crashed"]).all()
    # resume: the three done are skipped, two more are run
    parts = set((out / "results").glob("part-*.parquet"))
    again = fuzz.fuzz(out, count=5, seed=1, modes="formulations", workers=1, batch=4)
    new = set((out / "results").glob("part-*.parquet")) - parts
    assert len(new) == 1
    assert set(pd.read_parquet(new.pop()).case) == {fuzz.generate(1, i).name for i in (3, 4)}
    assert again[again["mode"] == "native"].case.nunique() == 5
    assert not again.duplicated(["case", "mode"]).any()


def test_summary_and_failure_report(tmp_path):
    rows = fuzz.fuzz(tmp_path, count=2, seed=4, modes="formulations", workers=1)
    table = fuzz.summary(rows)
    assert list(table["mode"][:3]) == ["native", "formulation-I", "formulation-II"]
    assert (table.passed + table.failed + table.error + table["not applicable"] == table.cases).all()
    fake = rows.copy()
    fake.loc[fake["mode"] == "formulation-II", ["outcome", "origin", "category"]] = ["failed", "disagreement", "alpha"]
    classes = fuzz.failure_classes(fake)
    assert len(classes) == 1 and classes.iloc[0]["count"] == 2
    reproducer = classes.iloc[0].reproducer
    sizes = {f: Path(f).stat().st_size for f in fake.file}
    assert sizes[reproducer] == min(sizes.values()) or fake[fake.file == reproducer].masses.iloc[0] == False  # noqa: E712
    text = fuzz.failure_report(fake, "xcheck fuzz --count 2 --seed 4")
    assert "outside tolerance: alpha" in text and reproducer in text


def test_cli_fuzz(tmp_path):
    result = invoke(
        "fuzz", "--count", "2", "--seed", "5", "--engines", "formulations", "--workers", "1", "--out", str(tmp_path)
    )
    assert result.returncode in (0, 1), result.stderr
    assert "native" in result.stdout and "formulation-II" in result.stdout
    assert (tmp_path / "failures.md").is_file()
    assert len(fuzz.read_rows(tmp_path)) >= 6


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--count", "0"], "--count"),
        (["--kinds", "fourbar,hexapod"], "--kinds"),
        (["--engines", "nosuch"], "--engines"),
        (["--workers", "0"], "--workers"),
        (["--count", "1", "--engines", "formulations", "--scheduler", "nonsense"], "--scheduler nonsense: expected"),
    ],
)
def test_cli_fuzz_bad_options(tmp_path, args, needle):
    result = invoke("fuzz", *args, "--out", str(tmp_path / "x"))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert len(result.stderr.splitlines()) == 1 and needle in result.stderr


def test_a_local_pool_gets_batches_small_enough_to_keep_every_process_busy(tmp_path):
    """Eight cases in batches of at most 4 on two processes go as eight tasks of
    one case (four or more a process, so that the last batch does not leave one
    process idle for four cases), and give the rows of a serial run."""
    pooled = fuzz.fuzz(tmp_path / "pool", count=8, seed=1, modes="formulations", workers=2, batch=4)
    assert len(list((tmp_path / "pool" / "results").glob("part-*.parquet"))) == 8
    serial = fuzz.fuzz(tmp_path / "serial", count=8, seed=1, modes="formulations", workers=1, batch=4)
    assert len(list((tmp_path / "serial" / "results").glob("part-*.parquet"))) == 2
    pd.testing.assert_frame_equal(_comparable(pooled, tmp_path / "pool"), _comparable(serial, tmp_path / "serial"))


@pytest.mark.slow
def test_local_pool_and_dask_cluster_give_the_same_rows(tmp_path):
    """The same cases on two local processes and on a two-worker Dask
    LocalCluster (processes): the same rows but for the timings."""
    distributed = pytest.importorskip("dask.distributed")
    local = fuzz.fuzz(tmp_path / "local", count=4, seed=1, modes="kinematic", workers=2, batch=1)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            remote = fuzz.fuzz(tmp_path / "dask", count=4, seed=1, modes="kinematic", client=client, batch=1)
    assert remote[remote["mode"] == "native"].case.nunique() == 4
    pd.testing.assert_frame_equal(_comparable(local, tmp_path / "local"), _comparable(remote, tmp_path / "dask"))


# -- a motion that starts outside the feasible range: refused up front -----------------


START_OUTSIDE = DATA / "start-outside.toml"


@pytest.mark.parametrize("engines", ["formulations", "kinematic", "mujoco-dynamic", "dynamic"])
def test_motion_starting_outside_is_refused_whatever_the_modes(engines):
    result = invoke("run", str(START_OUTSIDE), "--engines", engines, "--no-report")
    assert result.returncode == 2 and result.stdout == "" and "Traceback" not in result.stderr
    (line,) = result.stderr.splitlines()
    assert f"{START_OUTSIDE}: drivers[0]: expected a motion that starts inside the feasible range" in line
    assert "found crank starting at 140 deg" in line


def test_motion_starting_outside_is_refused_with_masses_too(tmp_path):
    """The same four-bar with mass data (forces and power balance would run): the same line."""
    text = (ROOT / "models" / "fourbar.toml").read_text(encoding="utf-8").replace("start = 30\n", "start = 140\n")
    path = tmp_path / "start-outside-masses.toml"
    path.write_text(text, encoding="utf-8")
    result = invoke("run", str(path), "--engines", "formulations", "--no-report")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    (line,) = result.stderr.splitlines()
    assert "drivers[0]: expected a motion that starts inside the feasible range" in line
    assert "found crank starting at 140 deg" in line


def test_motion_starting_inside_still_runs():
    kin = Kinematics(load_mechanism(START_OUTSIDE))
    rng = kin.input_range(0)
    assert math.degrees(rng.high) == pytest.approx(129.02, abs=0.01)  # 140 deg is past the limit
    text = START_OUTSIDE.read_text(encoding="utf-8").replace("start = 140\n", "start = 30\n")
    kin = Kinematics(parse_mechanism(text, "inside"))
    kin.assemble()
    from xcheck.runner import run_mechanism

    assert run_mechanism(kin, ("native", "formulation-II"), 21).outcomes["formulation-II"].ok


# -- force tolerances are conditioned (a fuzz finding) ------------------------------------


def test_force_tolerance_is_conditioned():
    from xcheck.runner import force_tolerance

    eps = np.finfo(float).eps
    assert force_tolerance("pinocchio") == force_tolerance("pinocchio", 6.0) == 1e-12
    # an engine's own double-precision computation: 100 eps kappa^2; Newton-Euler at the native states: 10
    assert force_tolerance("pinocchio", 4326.0) == pytest.approx(100 * eps * 4326.0**2)
    assert force_tolerance("newton-euler", 4326.0) == pytest.approx(10 * eps * 4326.0**2)
    assert force_tolerance("pymunk", 4326.0) == 7e-2


def test_reactions_of_a_near_parallelogram_are_judged_at_its_conditioning():
    """Pinocchio's reactions on the fuzz reproducer (kappa = 4326) pass the conditioned bound.
    They were 3.2e-12, over the unconditioned 1e-12, while Pinocchio's least squares ran
    on the unscaled system; equilibrated (issue 18) they are 1.3e-14."""
    from xcheck import api

    run = api.run(DATA / "fuzz-near-parallelogram.toml", "pinocchio-kinematic", samples=31)
    row = run.force_table.set_index("engine").loc["pinocchio"]
    assert row.ok and row.max_rel <= min(row.tolerance, 1e-13)
    assert row.tolerance > 1e-12  # the conditioned bound, 10 eps kappa^2


def test_a_failure_is_the_engines_only_where_it_is_a_stated_or_refined_limitation():
    """MuJoCo's qacc carries its constraint stabilisation and is judged by a fixed bound
    (its mode's orders say None): beyond it, the failure is the engine's. An observed
    order short of the expected one is the engine's only once the runner's finer runs
    (REFINEMENTS) kept it short or broke down; before that, and for a round-off
    verdict, it stays a disagreement."""
    import pandas as pd

    from xcheck.fuzz import _engine_limitation
    from xcheck.runner import REFINEMENTS

    fixed = pd.DataFrame(
        {"category": ["acceleration"], "basis": ["fixed bound 0.015 (the quantity does not converge)"]}
    )
    order = pd.DataFrame({"category": ["velocity"], "basis": ["observed order 0.328 (expected 1; ...)"]})
    assert "fixed bound" in _engine_limitation(fixed, "mujoco-dynamic")
    assert _engine_limitation(order, "drake-dynamic") == ""
    assert _engine_limitation(pd.concat([fixed, order]), "mujoco-dynamic") == ""
    assert _engine_limitation(fixed.iloc[:0], "mujoco-dynamic") == ""
    once = order.assign(refinements=REFINEMENTS - 1)
    assert _engine_limitation(once, "drake-dynamic") == ""
    refined = order.assign(refinements=REFINEMENTS)
    assert f"halved {REFINEMENTS} times" in _engine_limitation(refined, "drake-dynamic")
    both = pd.concat([fixed, refined]).reset_index(drop=True)
    assert "fixed bound" in _engine_limitation(both, "mujoco-dynamic")
    assert "stated order" in _engine_limitation(both, "mujoco-dynamic")
    broke = order.assign(refinement_failure="diverged: a point moves at 2.8e4 m/s")
    assert "diverged" in _engine_limitation(broke, "pymunk-dynamic")
    round_off = pd.DataFrame({"category": ["alpha"], "basis": ["within the engine's round-off bound ..."]})
    assert _engine_limitation(round_off.assign(refinements=REFINEMENTS), "pinocchio-dynamic") == ""


def test_a_mode_with_unobserved_orders_and_a_fixed_bound_failure_is_the_engines():
    """Fuzz case s3-00052 (a slider-crank through its change point): MuJoCo's coarser
    runs leave the branch, so its positions and rates have no order to observe, and its
    qacc is beyond the fixed bound. Each failing category is the engine's stated
    result, so the row is too (it was labelled a disagreement when the two met)."""
    import pandas as pd

    from xcheck.fuzz import Case, _engine_explanation, run_case

    fixed = pd.DataFrame({"category": ["alpha"], "basis": ["fixed bound 0.015 (the quantity does not converge)"]})
    unobserved = pd.DataFrame(
        {"category": ["position"], "basis": ["no coarser run of the same settings ran through: the order ..."]}
    )
    round_off = pd.DataFrame({"category": ["omega"], "basis": ["within the engine's round-off bound ..."]})
    no_result = SimpleNamespace(result=None)
    mixed = _engine_explanation(no_result, pd.concat([unobserved, fixed]), "mujoco-dynamic")
    assert mixed.startswith("position: no coarser run") and "fixed bound" in mixed
    assert _engine_explanation(no_result, unobserved, "mujoco-dynamic").startswith("no coarser run")
    assert _engine_explanation(no_result, pd.concat([unobserved, round_off]), "mujoco-dynamic") == ""

    path = DATA / "fuzz-slider-crank-unobserved-and-fixed-bound.toml"
    case = Case(3, 52, "slider-crank", "near-dead-centre", "constant-acceleration", False, 20.35, {}, path.read_text())
    (row,) = run_case(case, str(path), ["mujoco-dynamic"], 181)
    assert row["outcome"] == "failed" and row["origin"] == "engine", row
    assert "no coarser run" in row["reason"] and "fixed bound" in row["reason"], row["reason"]


def test_a_stated_finding_is_the_engines_result():
    """A mode failing only in its engine's stated findings (xcheck.engines.Engine.findings)
    is an engine-stated row with the finding as its reason, not a disagreement."""
    from xcheck import engines
    from xcheck.fuzz import Case, run_case
    from xcheck.tolerances import Tolerance

    class Shifted(engines.Engine):
        """The native sweep, every position moved by 1e-6 of the size, judged at 1e-8."""

        name = "fuzz-toy"
        modes = (
            engines.Mode(
                "fuzz-toy-kinematic",
                "kinematic",
                Tolerance(1e-8, 1e-12, 1e-12, 1e-12, "positions within 1e-8 of the size"),
            ),
        )
        findings = (
            engines.Finding("the toy moves", "the toy moves every position by 1e-6 of the size", ("position",)),
        )

        def run(self, mode, kinematics, *, native, samples, branch=None):
            return shifted_sweep(mode, kinematics, native, 1e-6)

    engines.register(Shifted)
    try:
        path = DATA / "fuzz-slider-crank-unobserved-and-fixed-bound.toml"
        case = Case(
            3, 52, "slider-crank", "near-dead-centre", "constant-acceleration", False, 20.35, {}, path.read_text()
        )
        (row,) = run_case(case, str(path), ["fuzz-toy-kinematic"], 21)
    finally:
        engines.unregister("fuzz-toy")
    assert row["outcome"] == "failed" and row["origin"] == "engine", row
    assert row["reason"] == "the engine's stated finding: the toy moves every position by 1e-6 of the size"


def test_a_campaign_leaves_out_what_would_dominate_it():
    """fuzz's default selection is run's, less the modes marked campaigns=False
    (a mode whose cost on each random mechanism would dominate the campaign); named,
    they run. MJX's driven mode (a compilation for every random mechanism) is out of
    both: it runs only on request."""
    from xcheck import engines
    from xcheck.fuzz import campaign_modes
    from xcheck.runner import default_modes
    from xcheck.tolerances import Tolerance

    class Dominating(engines.Engine):
        name = "fuzz-dominating"
        modes = (
            engines.Mode(
                "fuzz-dominating-kinematic", "kinematic", Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "toy"), campaigns=False
            ),
        )

    engines.register(Dominating())
    try:
        left_out = set(default_modes()) - set(campaign_modes())
        assert left_out == {m.name for m in engines.modes() if not m.campaigns} & set(default_modes())
        assert "fuzz-dominating-kinematic" in left_out and "mujoco-dynamic" in campaign_modes()
    finally:
        engines.unregister("fuzz-dominating")
    assert "mjx-dynamic" not in campaign_modes() and not engines.mode("mjx-dynamic").campaigns
    assert campaign_modes()[0] == "native"


def test_a_campaign_with_an_engine_registered_here_runs_here(tmp_path):
    """A spawned worker does not know an engine registered at run time: a campaign
    naming one of its modes runs in this process, whatever ``workers`` says."""
    from xcheck import engines
    from xcheck.fuzz import fuzz
    from xcheck.tolerances import Tolerance

    class Here(engines.Engine):
        name = "fuzz-here"
        modes = (engines.Mode("fuzz-here-kinematic", "kinematic", Tolerance(1e-6, 1e-12, 1e-12, 1e-12, "as the toy")),)

        def run(self, mode, kinematics, *, native, samples, branch=None):
            return shifted_sweep(mode, kinematics, native, 1e-8)

    engines.register(Here)
    try:
        rows = fuzz(tmp_path, count=2, seed=5, modes=["fuzz-here-kinematic"], workers=2, batch=1, samples=21)
    finally:
        engines.unregister("fuzz-here")
    toy = rows[rows["mode"] == "fuzz-here-kinematic"]
    assert len(toy) == 2 and set(toy.outcome) == {"passed"}, toy[["case", "outcome", "reason"]]
