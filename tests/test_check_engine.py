"""The engine contract's conformance suite (:func:`xcheck.testing.check_engine`):
every built-in engine installed here passes it, so does a toy engine loaded as a
plug-in, and a toy that breaks one promise fails with one line naming the
engine, the mode and the promise."""

from __future__ import annotations

import dataclasses
import importlib
import uuid
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
import toy_engine
from conftest import install_plug_in
from toy_engine import TOLERANCE, Toy

from xcheck import engines
from xcheck.engines import _registry
from xcheck.ladder import Run
from xcheck.results import ModeResult
from xcheck.testing import ContractBroken, check_engine

#: every built-in engine ("module:class")
BUILT_IN = [pytest.param(spec, id=spec.rpartition(":")[2].lower()) for spec in _registry._BUILT_IN]
#: engines checked at their cheapest level, the modes named: MJX's free mode (3 CPU s with
#: JAX's import, its cache cold) and not its dynamic mode (8 CPU s more: its own compilation)
CHEAPEST = {"mjx": ["mjx-free"]}


@pytest.mark.parametrize("spec", BUILT_IN)
def test_every_built_in_engine_keeps_the_contract(spec):
    module, _, name = spec.partition(":")
    engine = getattr(importlib.import_module(module), name)()
    reason = engine.available()
    if reason:
        assert "not installed" in reason  # and check_engine says so, running nothing
        assert check_engine(engine).skipped == dict.fromkeys((m.name for m in engine.modes), reason)
        pytest.skip(f"{engine.name}: {reason}")
    chosen = CHEAPEST.get(engine.name)
    check = check_engine(engine, chosen)
    assert check.broken == [] and check.ran  # every mode ran, or does not apply with its reason
    assert set(check.ran) | set(check.skipped) == set(chosen or (m.name for m in engine.modes))


def test_a_plug_in_keeps_the_contract(tmp_path, monkeypatch):
    """The toy, installed as a distribution declaring it under the entry-point group
    and loaded as xcheck loads a plug-in, passes with every mode run."""
    module = f"xcheck_plug_{uuid.uuid4().hex[:10]}"
    source = Path(toy_engine.__file__).read_text(encoding="utf-8")
    install_plug_in(tmp_path, module, source, f"[xcheck.engines]\ntoyc = {module}:Toy\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    (point,) = [
        p
        for d in metadata.distributions(path=[str(tmp_path)])
        for p in d.entry_points.select(group=_registry.ENTRY_POINT_GROUP)
    ]
    engine = _registry._load_plug_in(point, timeout=30.0)
    check = check_engine(engine)
    assert check.broken == [] and check.skipped == {}
    assert check.ran == ["toyc-kinematic", "toyc-dynamic", "toyc-free"]


def _only(*kinds: str):
    """The toy's modes of these kinds (a broken toy runs only what its promise needs)."""
    return tuple(m for m in Toy.modes if m.kind in kinds)


class BadKind(Toy):
    modes = (engines.Mode("toyc-static", "static", TOLERANCE),)


class Twice(Toy):
    modes = _only("kinematic") * 2


class OnRequest(Toy):
    modes = (dataclasses.replace(Toy.modes[0], on_request=True),)


class Costless(Toy):
    modes = (dataclasses.replace(Toy.modes[0], cost=0.0),)


class ForceOrder(Toy):
    modes = _only("kinematic")
    force_order = 1.0


class BadQuantity(Toy):
    modes = _only("kinematic")
    findings = (engines.Finding("a defect", "measured", ("speed",), reproducer="reproducers/toyc_defect.py"),)


class NoReproducer(Toy):
    modes = _only("kinematic")
    findings = (engines.Finding("a defect", "measured", ("position",)),)


class Unsaid(Toy):
    modes = _only("kinematic")
    requires = ("no_such_package_xcheck_test",)

    def available(self):
        return ""


class Raises(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        raise RuntimeError("the toy broke")


class Unexplained(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        raise engines.NotApplicable("")


class Reasonless(Toy):
    modes = _only("kinematic")

    def run(self, mode, kinematics, *, native, samples, branch=None):
        return ModeResult(mode, kinematics.mechanism.name, False, "")


class Flat(Toy):
    """Each body's angle as a column (N, 1) instead of (N,)."""

    modes = _only("kinematic")

    def sweep(self, mode, native):
        trajectory = super().sweep(mode, native)
        for states in trajectory.bodies.values():
            states["angle"] = states["angle"][:, None]
        return trajectory


class NotFinite(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        trajectory = super().sweep(mode, native)
        next(iter(trajectory.points.values()))["position"][1] = np.nan
        return trajectory


class Millimetres(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        trajectory = super().sweep(mode, native)
        for part in (*trajectory.bodies.values(), *trajectory.points.values()):
            part["position"] = part["position"] * 1000.0
        return trajectory


class Ghost(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        trajectory = super().sweep(mode, native)
        trajectory.bodies["ghost"] = dict(next(iter(trajectory.bodies.values())))
        return trajectory


class FixedStep(Toy):
    """Settings that always say 1 ms, whatever step the ladder asked for."""

    modes = _only("dynamic")

    def run_dynamic_once(self, mode, prepared, problem, rung):
        run = super().run_dynamic_once(mode, prepared, problem, rung)
        run.trajectory.settings = {**rung.settings, "timestep": 1e-3}
        return run


class Late(Toy):
    modes = _only("dynamic")

    def run_dynamic_once(self, mode, prepared, problem, rung):
        run = super().run_dynamic_once(mode, prepared, problem, rung)
        run.trajectory.times = run.trajectory.times + 0.5 * problem.interval
        return run


class Quitter(Toy):
    """Half the outputs, and no word why."""

    modes = _only("dynamic")

    def run_dynamic_once(self, mode, prepared, problem, rung):
        run = super().run_dynamic_once(mode, prepared, problem, rung)
        trajectory, half = run.trajectory, len(problem.times) // 2
        trajectory.times = trajectory.times[:half]
        for name in ("inputs", "input_rates", "input_accelerations"):
            setattr(trajectory, name, getattr(trajectory, name)[:half])
        for part in (*trajectory.bodies.values(), *trajectory.points.values()):
            for key in list(part):
                part[key] = part[key][:half]
        trajectory.diagnostics = {"constraint_violation": np.zeros(half)}
        return run


class Apart(Toy):
    """Loops reported open by half the size, the run carrying on."""

    modes = _only("free")

    def run_free_once(self, mode, prepared, problem, rung):
        run = super().run_free_once(mode, prepared, problem, rung)
        run.trajectory.diagnostics["constraint_violation"][:] = 0.5 * problem.kinematics.mechanism.size
        return run


class Nothing(Toy):
    modes = _only("free")

    def run_free_once(self, mode, prepared, problem, rung):
        return Run(None)


class Pointless(Toy):
    modes = _only("free")

    def run_free_once(self, mode, prepared, problem, rung):
        run = super().run_free_once(mode, prepared, problem, rung)
        run.trajectory.points = {}
        return run


class BadExport(Toy):
    modes = _only("kinematic")
    export_format = "toy"

    def export_files(self, kinematics):
        return {"toy.txt": 42}


class BadForces(Toy):
    modes = _only("kinematic")
    force_tolerance = 1e-6

    def inverse_dynamics(self, kinematics, branch=None, **options):
        return {"reactions": []}


class Impostor:
    """Not an Engine at all."""

    name = "toyc"


class Reserved(Toy):
    name = "native"


class Modeless(Toy):
    modes = ()


class Moody(Toy):
    modes = _only("kinematic")

    def available(self):
        raise OSError("no licence")


class Wordy(Toy):
    modes = _only("kinematic")

    def available(self):
        return "not today:\nthe licence server is down"


class TwoLineTitle(Toy):
    modes = _only("kinematic")
    findings = (
        engines.Finding("a defect\nin two lines", "measured", ("position",), reproducer="reproducers/toyc_a.py"),
    )


class Textless(Toy):
    modes = _only("kinematic")
    findings = (engines.Finding("a defect", " ", ("position",), reproducer="reproducers/toyc_a.py"),)


class BadKinds(Toy):
    modes = _only("kinematic")
    findings = (
        engines.Finding("a defect", "measured", ("position",), ("static",), reproducer="reproducers/toyc_a.py"),
    )


class NotAScript(Toy):
    modes = _only("kinematic")
    findings = (engines.Finding("a defect", "measured", ("position",), reproducer="reproducers/toyc_a.txt"),)


class NotAResult(Toy):
    modes = _only("kinematic")

    def run(self, mode, kinematics, *, native, samples, branch=None):
        return {"ok": True}


class Elsewhere(Toy):
    modes = _only("kinematic")

    def run(self, mode, kinematics, *, native, samples, branch=None):
        result = super().run(mode, kinematics, native=native, samples=samples, branch=branch)
        return dataclasses.replace(result, mode="toyc-other")


class Empty(Toy):
    modes = _only("kinematic")

    def run(self, mode, kinematics, *, native, samples, branch=None):
        return ModeResult(mode, kinematics.mechanism.name, True)


class ExtraQuantity(Toy):
    modes = _only("kinematic")

    def sweep(self, mode, native):
        trajectory = super().sweep(mode, native)
        for states in trajectory.bodies.values():
            states["jerk"] = states["alpha"]
        return trajectory


class OwnLadder(Toy):
    """A dynamic mode that runs its own ladder in run() (no series: the runner cannot
    refine it), its trajectory's settings stated, but no convergence study."""

    modes = _only("dynamic")

    def dynamic_series(self, mode, problem):
        raise NotImplementedError("runs its own ladder")

    def run(self, mode, kinematics, *, native, samples, branch=None):
        trajectory = self.sweep(mode, native)
        trajectory.settings = {"timestep": 1e-3, "series": "own"}
        return ModeResult(mode, kinematics.mechanism.name, True, trajectories=[trajectory], study=self.study())

    def study(self):
        return None


class OwnLadderUnsettled(OwnLadder):
    """Its own ladder with a study, but a trajectory that does not say its step."""

    def run(self, mode, kinematics, *, native, samples, branch=None):
        result = super().run(mode, kinematics, native=native, samples=samples, branch=branch)
        result.trajectories[0].settings = {"integrator": "its own"}
        return result

    def study(self):
        from xcheck.ladder import empty_study

        return empty_study()


class NotARun(Toy):
    modes = _only("dynamic")

    def run_dynamic_once(self, mode, prepared, problem, rung):
        return super().run_dynamic_once(mode, prepared, problem, rung).trajectory


class Rambling(Toy):
    modes = _only("free")

    def run_free_once(self, mode, prepared, problem, rung):
        return Run(None, "it stopped:\nsee the log")


class ExportRaises(Toy):
    modes = _only("kinematic")
    export_format = "toy"

    def export_files(self, kinematics):
        raise RuntimeError("no writer")


class NoRefine(Toy):
    """Reactions whose order the runner judges, but no ``refine`` option."""

    modes = _only("kinematic")
    force_tolerance, force_order = 1e-6, 1.0

    def inverse_dynamics(self, kinematics, branch=None):
        from xcheck.dynamics import window_states

        return self.native_forces(window_states(kinematics, branch))

    def native_forces(self, states):
        from xcheck.dynamics import newton_euler

        return newton_euler(states)


#: a toy per broken promise: (the toy, how its one line starts: "ENGINE: MODE or engine: PROMISE")
BROKEN = {
    "a kind outside KINDS": (BadKind, "toyc: toyc-static: declares a kind among kinematic, dynamic, free"),
    "a mode named twice": (Twice, "toyc: toyc-kinematic: names each mode once"),
    "on request without a reason": (OnRequest, "toyc: toyc-kinematic: says in one line why it runs only on request"),
    "no cost": (Costless, "toyc: toyc-kinematic: states a positive cost (CPU s)"),
    "a force order alone": (ForceOrder, "toyc: engine: states a force tolerance beside its force order"),
    "a finding's unknown quantity": (BadQuantity, "toyc: engine: states its finding 'a defect' with quantities among"),
    "a finding without reproducer": (NoReproducer, "toyc: engine: states its finding 'a defect' with a reproducer"),
    "a missing package unsaid": (Unsaid, "toyc: engine: says a missing package is not installed"),
    "an exception": (Raises, "toyc: toyc-kinematic: fails as data (ok False with its reason) or raises NotApplicable"),
    "NotApplicable without reason": (Unexplained, "toyc: toyc-kinematic: says in one line why it does not apply"),
    "a failure without reason": (Reasonless, "toyc: toyc-kinematic: states a failure's reason in one line"),
    "a wrong shape": (Flat, "toyc: toyc-kinematic: gives trajectories of the stated shapes"),
    "a NaN": (NotFinite, "toyc: toyc-kinematic: gives finite numbers or a stated failure"),
    "millimetres": (Millimetres, "toyc: toyc-kinematic: gives positions in metres (SI inside)"),
    "an unknown body": (Ghost, "toyc: toyc-kinematic: names only the mechanism's bodies and points"),
    "settings not the run's": (FixedStep, "toyc: toyc-dynamic: states its run's settings"),
    "other times": (Late, "toyc: toyc-dynamic: samples at the compared times (problem.times)"),
    "a silent stop": (Quitter, "toyc: toyc-dynamic: states why a run stopped before the end"),
    "apart and running": (Apart, "toyc: toyc-free: stops a run where its loops come apart"),
    "nothing, silently": (Nothing, "toyc: toyc-free: states why a run reached no output"),
    "no points in free motion": (Pointless, "toyc: toyc-free: gives the named points' positions in free motion"),
    "files not text": (BadExport, "toyc: engine: exports its model files as {file name: text}"),
    "forces of another kind": (BadForces, "toyc: engine: gives reactions and efforts (inverse_dynamics)"),
    "not an Engine": (Impostor, "toyc: engine: is an xcheck.engines.Engine"),
    "a reserved name": (Reserved, "native: engine: declares a name of its own"),
    "no modes": (Modeless, "toyc: engine: declares its modes"),
    "availability raising": (Moody, "toyc: engine: says whether it can run, never raising: OSError: no licence"),
    "a two-line reason": (Wordy, "toyc: engine: says in one line why it cannot run"),
    "a two-line title": (TwoLineTitle, "toyc: engine: states its finding 'a defect\\nin two lines' with a one-line"),
    "a finding without text": (Textless, "toyc: engine: states its finding 'a defect' with the measured defect"),
    "a finding's unknown kind": (BadKinds, "toyc: engine: states its finding 'a defect' with kinds among"),
    "a reproducer not a script": (NotAScript, "toyc: engine: states its finding 'a defect' with a reproducer script"),
    "not a ModeResult": (NotAResult, "toyc: toyc-kinematic: returns an xcheck.results.ModeResult"),
    "another mode's result": (Elsewhere, "toyc: toyc-kinematic: returns the result of the mode asked for"),
    "no trajectory": (Empty, "toyc: toyc-kinematic: gives its trajectories"),
    "an unknown quantity": (ExtraQuantity, "toyc: toyc-kinematic: gives only the quantities xcheck knows"),
    "its own ladder without study": (OwnLadder, "toyc: toyc-dynamic: gives its convergence study"),
    "its own ladder without settings": (OwnLadderUnsettled, "toyc: toyc-dynamic: states each trajectory's settings"),
    "not a Run": (NotARun, "toyc: toyc-dynamic: returns an xcheck.ladder.Run"),
    "a two-line failure": (Rambling, "toyc: toyc-free: states a run's failure in one line"),
    "export raising": (ExportRaises, "toyc: engine: exports its model files or raises NotApplicable"),
    "forces without refine": (NoRefine, "toyc: engine: gives reactions and efforts (inverse_dynamics(refine=1))"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_promise_is_one_clear_line(case):
    toy, start = BROKEN[case]
    found = check_engine(toy, raises=False)
    assert len(found.broken) == 1, found.broken
    assert found.broken[0].startswith(start), found.broken[0]
    with pytest.raises(ContractBroken, match=f"{found.engine} breaks 1 promise") as raised:
        check_engine(toy)
    assert found.broken[0] in str(raised.value)
