"""A run killed at any moment leaves every report file whole or absent.

The real ``xcheck run`` is started as a process and sent SIGKILL at seeded
random moments, ten times, into one output directory. After each kill every
visible file there is complete (a report ends with its Versions table and the
command that reproduces it, the index with its table, every PNG with its IEND
chunk, the GIF with its trailer), and anything else is hidden staging of the
kinds the next write removes. A last run to completion leaves no staging.
"""

from __future__ import annotations

import json
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import MODELS, ROOT

from xcheck.fileio import MANIFEST, MARK, PENDING_MARKDOWN, STAGING_MARK

XCHECK = Path(sys.executable).with_name("xcheck")
COMMAND = ["run", "fourbar", "--engines", "formulations", "--samples", "31", "--quiet"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the IEND chunk: zero length, type, CRC
#: hidden staging as xcheck names it: "." + name + ".xcheck-" + kind + "-" + 8 characters
STAGING = re.compile(r"\.(fourbar|fourbar\.md|README\.md|index\.json)\.xcheck-(tmp|staging|retired)-[a-z0-9]{8}")


def _start(out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    env.pop("XCHECK_MODELS", None)
    return subprocess.Popen(
        [str(XCHECK), *COMMAND, "--out", str(out), "--models", str(MODELS)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


def _check_report(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    assert text.startswith(MARK) and text.splitlines()[1].startswith("# fourbar: "), path
    assert "\n## Versions\n" in text, path
    assert text.endswith("\n") and text.rstrip("\n").splitlines()[-1].startswith("Reproduce: `xcheck run fourbar"), (
        f"{path} does not end with the command that reproduces it"
    )
    assert text.rstrip("\n").endswith("`"), path


def _check_index(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    assert text.startswith(MARK) and text.splitlines()[1] == "# Reports", path
    assert text.endswith("|\n") and text.splitlines()[-1].startswith("| [fourbar](fourbar.md) |"), path


def _check_image(path: Path) -> None:
    data = path.read_bytes()
    if path.suffix == ".png":
        assert data.startswith(PNG_SIGNATURE) and data.endswith(PNG_END), f"{path} is not a whole PNG"
    else:
        assert path.suffix == ".gif", path
        assert data[:6] in (b"GIF87a", b"GIF89a") and data.endswith(b";"), f"{path} is not a whole GIF"


def _check_directory(out: Path) -> list[str]:
    """Check every entry of ``out``; returns the hidden staging names found."""
    staging = []
    if not out.exists():
        return staging
    for entry in sorted(out.iterdir()):
        if entry.name.startswith("."):
            assert STAGING.fullmatch(entry.name), f"unexpected hidden entry {entry.name}"
            if entry.name.split(".")[-2] in ("md", "json"):
                assert entry.is_file(), entry
            else:
                assert entry.is_dir(), entry
            staging.append(entry.name)
        elif entry.name == "fourbar.md":
            _check_report(entry)
        elif entry.name == "README.md":
            _check_index(entry)
        elif entry.name == "index.json":  # the index's data: whole JSON naming the report
            assert [e["name"] for e in json.loads(entry.read_text(encoding="utf-8"))["entries"]] == ["fourbar"]
        elif entry.name == "fourbar":
            assert entry.is_dir()
            names = {p.name for p in entry.iterdir()}
            assert "drawing.png" in names, names
            for image in entry.iterdir():
                if image.name == MANIFEST:  # the report's evidence: whole JSON listing the folder's figures
                    listed = set(json.loads(image.read_text(encoding="utf-8"))["files"])
                    assert listed == names - {MANIFEST, PENDING_MARKDOWN, STAGING_MARK}, (listed, names)
                elif image.name == PENDING_MARKDOWN:  # killed between the unit's two renames
                    _check_report(image)
                elif image.name != STAGING_MARK:  # killed just after the swap
                    _check_image(image)
        else:
            raise AssertionError(f"unexpected entry {entry.name} in {out}")
    return staging


@pytest.mark.slow
def test_sigkill_at_random_moments_leaves_no_partial_file(tmp_path):
    out = tmp_path / "reports"
    started = time.monotonic()
    first = _start(out)
    assert first.wait(timeout=300) == 0, first.stderr.read().decode()
    duration = time.monotonic() - started  # kills fall anywhere in a whole run, writes included
    _check_directory(out)
    rng = random.Random(18)
    staged = set()
    for _ in range(10):
        process = _start(out)
        time.sleep(rng.uniform(0.2, max(3.0, duration)))
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=60)
        process.stderr.close()
        staged.update(_check_directory(out))
    last = _start(out)
    assert last.wait(timeout=300) == 0, last.stderr.read().decode()
    assert _check_directory(out) == [], "staging left after a complete run"
    for name in ("fourbar.md", "README.md", "fourbar/drawing.png"):
        assert (out / name).is_file(), name
