"""A non-editable install carries the bundled mechanisms and printed answers:
the wheel, installed into a folder of its own (``pip install --target``; the
dependencies are the test's own environment's), lists and runs them from a
directory with no models/, and writes reports under that directory, never into
the installed package.

Slow: building the wheel takes 5 to 30 s (pip fetches setuptools and wheel
for an isolated build), the run about 15 s.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import MODELS, ROOT

pytestmark = pytest.mark.slow


def _files(folder: Path) -> set[Path]:
    return {p.relative_to(folder) for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


def _can_build_here() -> bool:
    import importlib.util

    import setuptools

    major, minor = (int(part) for part in setuptools.__version__.split(".")[:2])
    return (major, minor) >= (70, 1) or importlib.util.find_spec("wheel") is not None


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The folder the wheel is installed into."""
    tmp = tmp_path_factory.mktemp("install")
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    # the test environment's own setuptools when it can build a wheel (wheel installed, or
    # setuptools >= 70.1 which has bdist_wheel); else pip's isolated build fetches them
    isolation = ["--no-build-isolation"] if _can_build_here() else []
    subprocess.run([*pip, "wheel", "--no-deps", *isolation, "-q", str(ROOT), "-w", str(tmp / "wheel")], check=True)
    (wheel,) = (tmp / "wheel").glob("xcheck-*.whl")
    site = tmp / "site"
    subprocess.run([*pip, "install", "--no-deps", "--no-index", "-q", "--target", str(site), str(wheel)], check=True)
    return site


def _xcheck(site: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("XCHECK_")}
    env["PYTHONPATH"] = str(site)  # the installed copy, not the checkout's src/
    return subprocess.run(
        [sys.executable, "-m", "xcheck", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


def test_installed_package_lists_the_bundled_mechanisms(installed, tmp_path):
    result = _xcheck(installed, tmp_path, "list", "--json")
    assert result.returncode == 0, result.stderr
    for path in MODELS.glob("*.toml"):
        assert f'"{path.stem}"' in result.stdout
    probe = subprocess.run(
        [sys.executable, "-c", "import xcheck, xcheck.catalog as c; print(xcheck.__file__); print(c.models_dir())"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(installed)},
        capture_output=True,
        text=True,
    )
    module, models = probe.stdout.split()
    assert Path(module).is_relative_to(installed) and Path(models).is_relative_to(installed)
    assert not Path(models).is_symlink()  # a copy in the wheel, not a link into the checkout


def test_installed_package_runs_fourbar_and_writes_reports_in_the_cwd(installed, tmp_path):
    before = _files(installed)
    result = _xcheck(installed, tmp_path, "run", "fourbar", "--engines", "native,kinematic", "--samples", "37")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "printed answers: 96 values" in result.stdout  # the bundled comparisons were found
    assert (tmp_path / "reports" / "fourbar.md").is_file()
    assert (tmp_path / "reports" / "fourbar" / "quantities.png").is_file()
    assert _files(installed) == before  # nothing written into the package
