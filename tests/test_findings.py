"""Stated findings apply by one rule to every verdict: a mode's categories, a run
that fails as a whole (:data:`~xcheck.ladder.FAILURE`), and a force source's
reactions (:data:`~xcheck.ladder.REACTIONS`), where the finding holds (its time
steps, its mechanisms); the JSON, the table and the report name the finding.
"""

from __future__ import annotations

import dataclasses
import json

import pytest
from conftest import DATA, MODELS, shifted_sweep
from typer.testing import CliRunner

from xcheck import engines, load_mechanism
from xcheck.cli import app
from xcheck.ladder import FAILURE, REACTIONS, Finding, applicable_findings
from xcheck.tolerances import Tolerance

FOURBAR = load_mechanism(MODELS / "fourbar.toml")
PENDULUM = load_mechanism(DATA / "pendulum.toml")


def _open_chain(mechanism) -> bool:
    return len(mechanism.joints) == len(mechanism.moving_bodies)


def test_one_rule_decides_where_a_finding_holds():
    """Kind, quantity, time step, closed loops and the engine's own condition on the mechanism."""
    blow_up = Finding("blows up", "measured", (FAILURE,), kinds=("dynamic",), closed_loops=True, steps_below=5e-5)
    assert applicable_findings([blow_up], "dynamic", FAILURE, FOURBAR, "default", 1e-5) == [blow_up]
    assert not applicable_findings([blow_up], "dynamic", FAILURE, FOURBAR, "default", 5e-5)  # at the bound: not
    assert not applicable_findings([blow_up], "dynamic", FAILURE, FOURBAR)  # a failure of no known step
    assert not applicable_findings([blow_up], "dynamic", "position", FOURBAR, "default", 1e-5)  # it spoils no value
    assert not applicable_findings([blow_up], "free", FAILURE, FOURBAR, "default", 1e-5)
    assert not applicable_findings([blow_up], "dynamic", FAILURE, PENDULUM, "default", 1e-5)  # no loop
    chain = Finding("chain", "measured", ("effort",), kinds=(REACTIONS,), mechanisms=_open_chain)
    assert applicable_findings([chain], REACTIONS, "effort", PENDULUM) == [chain]
    assert not applicable_findings([chain], REACTIONS, "effort", FOURBAR)
    assert not applicable_findings([chain], REACTIONS, "reaction", PENDULUM)
    assert blow_up.scope == "dynamic modes; the runs fail; closed loops only; time steps below 5e-05 s"
    assert blow_up.as_dict()["steps_below"] == 5e-5 and blow_up.as_dict()["mechanisms"] is None


#: the toys' reactions: every driving effort 1 % high, every reaction exact
EFFORT_SCALE = 1.01


class Crashing(engines.Engine):
    """A kinematic mode that always raises, and reactions that do too; both stated as
    findings that hold on an open chain only."""

    name = "crashing"
    modes = (engines.Mode("crashing-kinematic", "kinematic", Tolerance(1, 1, 1, 1, "anything")),)
    force_tolerance = 1e-6
    findings = (
        Finding("the toy crashes", "the toy crashes on an open chain", (FAILURE,), kinds=("kinematic",)),
        Finding(
            "the toy's reactions crash",
            "the toy's reactions crash on an open chain",
            (FAILURE,),
            kinds=(REACTIONS,),
            mechanisms=_open_chain,
        ),
    )

    def run(self, mode, kinematics, *, native, samples, branch=None):
        raise RuntimeError("the toy crashed")

    def inverse_dynamics(self, kinematics, branch=None, **options):
        raise RuntimeError("the toy's reactions crashed")


class HighEffort(engines.Engine):
    """The native sweep as its kinematic mode; reactions exact, driving efforts 1 % high:
    a finding on efforts where ``spoils`` says so."""

    name = "high-effort"
    modes = (engines.Mode("high-effort-kinematic", "kinematic", Tolerance(1e-9, 1e-9, 1e-9, 1e-9, "exact")),)
    force_tolerance = 1e-6
    findings = (Finding("efforts 1 % high", "the toy's efforts are 1 % high", ("effort",), kinds=(REACTIONS,)),)

    def run(self, mode, kinematics, *, native, samples, branch=None):
        return shifted_sweep(mode, kinematics, native, 0.0)

    def inverse_dynamics(self, kinematics, branch=None, **options):
        from xcheck.dynamics import newton_euler, window_states

        forces = newton_euler(window_states(kinematics, branch))
        drivers = {name: {"effort": q["effort"] * EFFORT_SCALE} for name, q in forces.drivers.items()}
        return dataclasses.replace(forces, drivers=drivers)


class HighReaction(HighEffort):
    """As :class:`HighEffort`, but its finding is on reactions: the efforts stay unexplained."""

    name = "high-reaction"
    modes = (engines.Mode("high-reaction-kinematic", "kinematic", Tolerance(1e-9, 1e-9, 1e-9, 1e-9, "exact")),)
    findings = (Finding("reactions off", "the toy's reactions are off", ("reaction",), kinds=(REACTIONS,)),)


@pytest.fixture
def toys():
    registered = [engines.register(engine) for engine in (Crashing, HighEffort, HighReaction)]
    yield registered
    for engine in registered:
        engines.unregister(engine.name)


def _run(path, engine, *extra):
    ran = CliRunner().invoke(
        app, ["run", str(path), "--engines", f"native,{engine}", "--samples", "5", "--no-cache", *extra]
    )
    return ran


def test_a_failure_a_finding_explains_is_the_engines_known_result(toys):
    """On the open chain the crash of the mode and of its reactions are the toy's stated
    findings (the run passes with findings); on a four-bar they are not (the mode's
    finding holds on any mechanism, the reactions' only on an open chain: the run fails)."""
    ran = _run(DATA / "pendulum.toml", "crashing", "--json", "--no-report")
    assert ran.exit_code == 0, ran.output
    doc = json.loads(ran.stdout)
    mode = doc["engines"]["crashing-kinematic"]
    assert mode["verdict"] == "finding" and mode["finding"] == "the toy crashes on an open chain"
    assert "the toy crashed" in mode["reason"] and doc["verdict"] == "pass with findings"
    forces = doc["forces"]["crashing"]
    assert forces["verdict"] == "finding" and forces["finding"] == "the toy's reactions crash on an open chain"
    assert "the toy's reactions crashed" in forces["reason"] and forces["pass"] is False
    ran = _run(MODELS / "fourbar-dynamics.toml", "crashing", "--json", "--no-report")
    assert ran.exit_code == 1, ran.output
    doc = json.loads(ran.stdout)
    assert doc["engines"]["crashing-kinematic"]["verdict"] == "finding"
    assert doc["forces"]["crashing"]["verdict"] == "failed" and doc["forces"]["crashing"]["finding"] is None
    assert doc["verdict"] == "fail"


def test_reactions_beyond_their_bound_are_a_finding_only_in_the_quantities_it_spoils(toys, tmp_path):
    ran = _run(MODELS / "fourbar-dynamics.toml", "high-effort", "--json", "--report", "--out", str(tmp_path))
    assert ran.exit_code == 0, ran.output
    forces = json.loads(ran.stdout)["forces"]["high-effort"]
    assert forces["relative"] > 1e-6 and forces["verdict"] == "finding"
    assert forces["finding"] == "the toy's efforts are 1 % high"
    report = (tmp_path / "fourbar-dynamics.md").read_text(encoding="utf-8")
    assert "Result: **pass with findings**" in report and "stated findings of `high-effort-forces`" in report
    assert "`high-effort` fails only where its engine is known to be wrong: the toy's efforts are 1 % high" in report
    table = _run(MODELS / "fourbar-dynamics.toml", "high-effort", "--no-report")
    assert "high-effort reactions: the engine's stated finding: the toy's efforts" in " ".join(table.stdout.split())
    ran = _run(MODELS / "fourbar-dynamics.toml", "high-reaction", "--json", "--no-report")
    assert ran.exit_code == 1, ran.output
    forces = json.loads(ran.stdout)["forces"]["high-reaction"]
    assert forces["verdict"] == "fail" and forces["finding"] is None


def test_pymunk_reactions_on_a_driven_point_mass_are_its_stated_finding():
    """IFToMM's pendulum held still: pymunk's scene comes apart (its pivot does not hold a
    point mass a motor holds, reproducers/pymunk_point_mass_motor.py); the run passes
    with that finding. The rod of the same mass (its moment m L^2 / 12) is not a point mass."""
    pytest.importorskip("pymunk")
    ran = _run(DATA / "pendulum.toml", "pymunk", "--json", "--no-report")
    assert ran.exit_code == 0, ran.output
    doc = json.loads(ran.stdout)
    forces = doc["forces"]["pymunk"]
    assert forces["verdict"] == "finding" and "came apart" in forces["reason"]
    assert forces["finding"].startswith("A body of 1 kg whose moment about its centre of mass is 1e-12 kg m^2")
    assert doc["verdict"] == "pass with findings"
    finding = engines.engine("pymunk").findings[0]
    rod = dataclasses.replace(PENDULUM.body("link"), inertia=1.0 / 12.0)
    held = dataclasses.replace(PENDULUM, bodies=tuple(rod if b.name == "link" else b for b in PENDULUM.bodies))
    assert applicable_findings([finding], REACTIONS, FAILURE, PENDULUM) == [finding]
    assert not applicable_findings([finding], REACTIONS, FAILURE, held)


def test_dart_coming_apart_below_its_smallest_step_names_its_finding():
    """The non-Grashof four-bar at 1200 rpm: its samples 1.5e-4 s apart force DART's
    steps down to 1.2e-5 s, where its loop constraint blows up (a stated finding):
    the failure line names it and the run passes with that finding."""
    pytest.importorskip("dartpy")
    ran = _run(DATA / "crank-cannot-turn.toml", "dart", "--no-report")
    assert ran.exit_code == 0, ran.output
    text = " ".join(ran.stdout.split())
    assert "dart-dynamic: default dt = 1.226e-05 s: came apart" in text
    assert "dart-dynamic: the engine's stated finding: A slider-crank closed by a RevoluteJointConstraint" in text
