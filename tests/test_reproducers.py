"""Every stated finding's reproducer (reproducers/*.py) still shows its defect where
its engine is installed: a script that imports only that engine and numpy, prints
the measured numbers beside the expected ones and exits 0 while the defect shows,
1 once it does not (a fixed upstream release: the finding is to be retired)."""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = sorted((ROOT / "reproducers").glob("*.py"))


def _needs(script: Path) -> list[str]:
    """The top-level packages the script imports, the standard library's and numpy left out."""
    names = []
    for node in ast.walk(ast.parse(script.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            found = [node.module]
        else:
            continue
        for name in found:
            top = name.split(".")[0]
            if top not in sys.stdlib_module_names and top not in ("numpy", "__future__") and top not in names:
                names.append(top)
    return names


def test_each_reproducer_imports_only_its_engine_and_numpy():
    for script in SCRIPTS:
        assert "xcheck" not in _needs(script), f"{script.name} imports xcheck"
        assert _needs(script), f"{script.name} imports no engine"


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_reproducer_still_shows_its_defect(script: Path):
    missing = [name for name in _needs(script) if importlib.util.find_spec(name) is None]
    if missing:
        pytest.skip(f"not installed: {', '.join(missing)}")
    child = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=900, cwd=script.parent
    )
    lines = child.stdout.strip().splitlines()
    assert child.returncode == 0 and lines and lines[-1] == "defect shown", (
        f"{script.name} (exit status {child.returncode}) no longer shows its defect: retire its finding, "
        f"or fix the script\n{child.stdout}\n{child.stderr[-2000:]}"
    )
    assert any("expected" in line for line in lines) and any("measured" in line for line in lines)


def test_every_finding_names_its_reproducer_and_every_reproducer_a_finding():
    from xcheck import engines

    named = {}
    for engine in engines.engines():
        for finding in engine.findings:
            assert finding.reproducer, f"{engine.name}: {finding.title!r} has no reproducer"
            assert (ROOT / finding.reproducer).is_file(), finding.reproducer
            named[Path(finding.reproducer).name] = engine.name
    assert {script.name for script in SCRIPTS} == set(named)
    for script in SCRIPTS:  # each script imports its engine's own package
        assert script.name.startswith(named[script.name] + "_"), script.name
