"""The Exudyn script ``xcheck export --format exudyn`` writes: run as a program,
it integrates the system exudyn-free integrates and lands where that system
lands (the same numbers: the script is the model, load time laws included), and
near the closed form of the pendulum (IFToMM A01) within the error of Exudyn's
default setting at its step. A file without ``[free_motion]`` is skipped, said
so, not an error."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import DATA, MODELS, invoke
from test_free_motion import pendulum_exact

pytest.importorskip("exudyn")

from xcheck import Kinematics, load_mechanism  # noqa: E402
from xcheck.dynamics._free import release_state  # noqa: E402
from xcheck.engines import NotApplicable  # noqa: E402
from xcheck.engines.exudyn.export import script  # noqa: E402
from xcheck.engines.exudyn.free import FREE_SERIES  # noqa: E402
from xcheck.engines.exudyn.model import build_system, solver_settings  # noqa: E402
from xcheck.ladder import FREE_STEPS  # noqa: E402


def _run_script(kin: Kinematics, tmp_path) -> dict[str, np.ndarray]:
    """The exported script run in a fresh interpreter: each body's final node
    coordinates (x, y of the centre of mass in m, angle in rad)."""
    path = tmp_path / f"{kin.mechanism.name}.py"
    path.write_text(script(kin), encoding="utf-8")
    done = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=300, check=True)
    rows = [line.split() for line in done.stdout.splitlines() if line.strip()]
    return {row[0]: np.array([float(v) for v in row[1:]]) for row in rows}


def test_the_script_is_the_system_the_mode_integrates_with_its_load_laws(tmp_path):
    """tests/data/free-mixed.toml: every joint kind, springs, a rotational spring,
    ramped and harmonic loads (the laws become functions in the script)."""
    kin = Kinematics(load_mechanism(DATA / "free-mixed.toml"))
    kin.assemble()
    printed = _run_script(kin, tmp_path)
    spec = kin.mechanism.free_motion
    assert spec is not None
    start = release_state(kin)
    model = build_system(kin.mechanism, start.q, start.qd)
    import exudyn
    from exudyn import ConfigurationType, OutputVariableType

    model.mbs.Assemble()
    dt = min(FREE_STEPS[0], spec.output_step / 10.0)
    assert exudyn.SolveDynamic(model.mbs, solver_settings(FREE_SERIES[0].options, dt, spec.duration, spec.output_step))
    assert set(printed) == set(model.nodes)
    for name, node in model.nodes.items():
        here = model.mbs.GetNodeOutput(node, OutputVariableType.Coordinates) + model.mbs.GetNodeOutput(
            node, OutputVariableType.Coordinates, ConfigurationType.Reference
        )
        # printed to 12 significant digits
        np.testing.assert_allclose(printed[name], here, rtol=1e-11, atol=1e-12 * kin.mechanism.size)


def test_the_pendulum_script_lands_near_the_closed_form(tmp_path):
    """A01 over its 10 s at 1 ms with Exudyn's defaults (order 2): measured 1.17e-4 m
    from the closed form at the end (the native reference: 1.2e-4 m from the script)."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a01.toml"))
    kin.assemble()
    printed = _run_script(kin, tmp_path)
    (body,) = printed  # one body, the link, its centre of mass at P1
    exact = pendulum_exact(np.array([0.0, 10.0]))[-1]
    error = float(np.hypot(*(printed[body][:2] - exact)))
    assert error < 2e-4
    assert error > 1e-6  # it is Exudyn's integration at 1 ms, not a copy of an answer


def test_a_file_without_free_motion_is_skipped_not_an_error():
    kin = Kinematics(load_mechanism(MODELS / "fourbar.toml"))
    kin.assemble()
    with pytest.raises(NotApplicable, match="free_motion"):
        script(kin)
    result = invoke("export", "fourbar", "--format", "exudyn", "--check")
    assert result.returncode == 0, result.stderr
    assert "skipped exudyn of fourbar: no [free_motion]" in result.stdout
