"""What xcheck writes reads the same on another CPU.

Another CPU, or other builds of the libraries, computes the same values a few
units in the last place apart. These tests stand in for one: the solver's
results (every assembly, every solved state and its conditioning) are nudged
by up to four units in the last place, and what xcheck writes must still agree
with what is committed: every engine file within the precision of its numbers
(as ``xcheck export --check`` judges), and the fourbar report's Markdown
character for character.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import MODEL_NAMES, MODELS, ROOT

from xcheck import Kinematics, engines, load_mechanism
from xcheck.api import run
from xcheck.catalog import benchmark_names
from xcheck.precision import canonical_numbers, drift
from xcheck.report import write_report

ULPS = 4


def _nudged(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``values`` each moved by 0 to ULPS units in the last place, up or down."""
    out = np.array(values, dtype=float, copy=True)
    for _ in range(ULPS):
        step = rng.integers(-1, 2, out.shape)
        out = np.where(step > 0, np.nextafter(out, np.inf), np.where(step < 0, np.nextafter(out, -np.inf), out))
    return out


@pytest.fixture
def another_cpu(monkeypatch):
    """Kinematics whose assemblies and solutions come out a few ulps apart."""
    rng = np.random.default_rng(31)
    assemble, solve = Kinematics.assemble, Kinematics.solve

    def nudged_assemble(self, branch=None):
        return _nudged(assemble(self, branch), rng)

    def nudged_solve(self, *args, **kwargs):
        solution = solve(self, *args, **kwargs)
        for name in ("q", "qd", "qdd", "singularity"):
            setattr(solution, name, _nudged(getattr(solution, name), rng))
        return solution

    monkeypatch.setattr(Kinematics, "assemble", nudged_assemble)
    monkeypatch.setattr(Kinematics, "solve", nudged_solve)


FILES = [MODELS / f"{n}.toml" for n in MODEL_NAMES] + [
    MODELS / "benchmarks" / f"{n}.toml" for n in benchmark_names(MODELS)
]


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_the_engine_files_agree_with_the_committed_ones(another_cpu, path):
    kinematics = Kinematics(load_mechanism(path))
    checked = 0
    for writer in engines.exporters().values():
        if writer.available():
            continue  # its engine is not installed here
        try:
            with canonical_numbers() as units:
                texts = writer.export_files(kinematics)
        except engines.NotApplicable:
            continue
        for name, text in texts.items():
            committed = path.parent / (writer.export_directory or writer.export_format) / name
            moved = drift(committed.read_text(encoding="utf-8"), text, units)
            assert moved is None, f"{committed}: {moved}"
            checked += 1
    assert checked >= 2  # MJCF and URDF at least


def _without_marks(text: str) -> str:
    """A report's text without what says which parts were kept from the committed run."""
    lines = [line for line in text.split("\n") if not line.startswith("[1] Kept from an earlier run")]
    text = "\n".join(lines).replace(" [1]", "").replace("\n\n(Figure: kept from an earlier run.)", "")
    while "\n\n\n" in text:
        text = text.replace("\n\n\n", "\n\n")
    return text


def test_the_fourbar_reports_markdown_is_the_committed_one(another_cpu, tmp_path):
    """The exact methods and the engines' kinematics at round-off, rerun: their
    rows, the printed answers, the reactions, the power balance and the solver's
    figures read as committed (the dynamic modes, kept from the committed
    run, are marked; without the marks the text is the same)."""
    out = tmp_path / "reports"
    shutil.copytree(ROOT / "reports" / "fourbar", out / "fourbar")
    shutil.copyfile(ROOT / "reports" / "fourbar.md", out / "fourbar.md")
    committed = (ROOT / "reports" / "fourbar.md").read_text(encoding="utf-8")
    command = committed.rstrip().rsplit("Reproduce: `", 1)[1].rstrip("`")  # the committed run's own
    result = run(MODELS / "fourbar.toml", "formulations,kinematic", jobs=1)
    path, _ = write_report(result, out, command)
    text = path.read_text(encoding="utf-8")
    assert "| `formulation-I` | pass |" in text and "| `mujoco-kinematic` | pass |" in text  # rerun, not kept
    assert _without_marks(text) == committed
