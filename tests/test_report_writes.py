"""Reports written by runs that are killed or run side by side: the hidden
staging a killed run leaves is removed at the next write (and nothing else
is), and the index's read-modify-write holds the directory's lock."""

from __future__ import annotations

import fcntl
import os
import threading
import time

from conftest import MODELS
from typer.testing import CliRunner

from xcheck.catalog import model_names
from xcheck.cli import app
from xcheck.fileio import STAGING_MARK, marked
from xcheck.report import update_index


def _touch(path, data: bytes = b"stale") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


def test_staging_left_by_a_killed_run_is_removed_at_the_next_write(tmp_path):
    out = tmp_path / "reports"
    # what a run killed while writing leaves: staging with some images, an empty
    # staging folder, a retired report folder, temporary Markdown files; each
    # with a temporary's name of xcheck's, a folder with its mark
    staging = out / ".fourbar.xcheck-staging-k3j4h5g6"
    _touch(staging / STAGING_MARK, b"")
    _touch(staging / "drawing.png")
    _touch(out / ".scotch-yoke.xcheck-staging-abcd1234" / STAGING_MARK, b"")
    _touch(out / ".fourbar.xcheck-retired-a1b2c3d4" / STAGING_MARK, b"")
    _touch(out / ".fourbar.xcheck-retired-a1b2c3d4" / "fourbar" / "motion.gif")
    _touch(out / ".README.md.xcheck-tmp-99aa88bb")
    _touch(out / ".fourbar.md.xcheck-tmp-01234567")
    # what xcheck did not write stays, hidden or not, however much it looks like a temporary
    keep = [
        ".git/config",
        ".notes.abcdefgh/mine.txt",
        ".mine.txt.abcdefgh",
        ".other.old.a1b2c3d5/other/x.png",
        ".README.md.zz99yy88",
        ".notes.md.20251126",
        ".draft.md.backup_1",
        ".photos.2025abcd/a.jpg",
        ".fourbar.xcheck-staging-99999999/mine.txt",
        "notes.md",
    ]
    for name in keep:
        _touch(out / name)
    result = CliRunner().invoke(
        app,
        [
            "run",
            "fourbar",
            "--engines",
            "formulations",
            "--samples",
            "31",
            "--quiet",
            "--out",
            str(out),
            "--models",
            str(MODELS),
        ],
    )
    assert result.exit_code == 0, result.output
    left = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert [p for p in left if p.startswith(".")] == sorted(k for k in keep if k.startswith("."))
    assert {"README.md", "fourbar.md", "fourbar/drawing.png", "notes.md"} <= set(left)


def test_index_update_waits_for_the_directory_lock(tmp_path):
    entry = {"name": "fourbar", "title": "Four-bar", "passed": True, "worst": "-", "textbook": "-"}
    worker = threading.Thread(target=update_index, args=(tmp_path, [entry], set(model_names(MODELS))))
    fd = os.open(tmp_path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # another run writing the reports
        worker.start()
        time.sleep(0.5)
        assert worker.is_alive()
        assert not (tmp_path / "README.md").exists()
    finally:
        os.close(fd)
    worker.join(30)
    assert not worker.is_alive()
    assert "[fourbar](fourbar.md)" in (tmp_path / "README.md").read_text(encoding="utf-8")


def test_the_index_is_built_from_its_data_not_from_its_markdown(tmp_path):
    """A run of one mechanism keeps the other mechanisms' lines from index.json;
    what the Markdown says is never read back."""
    first = {"name": "fourbar", "title": "Four-bar", "passed": True, "worst": "-", "textbook": "-"}
    second = {"name": "slider-crank", "title": "Slider-crank", "passed": False, "worst": "x", "textbook": "-"}
    keep = set(model_names(MODELS))
    update_index(tmp_path, [first], keep)
    index = tmp_path / "README.md"
    mark = index.read_text(encoding="utf-8").splitlines()[0]  # xcheck's, kept: edited but still xcheck's file
    index.write_text(f"{mark}\n| [edited](edited.md) | by hand | pass | - | - |\n", encoding="utf-8")
    update_index(tmp_path, [second], keep)
    index = (tmp_path / "README.md").read_text(encoding="utf-8")
    assert "[fourbar](fourbar.md)" in index and "[slider-crank](slider-crank.md)" in index
    assert "edited" not in index
    gone = {"name": "removed-model", "title": "gone", "passed": True, "worst": "-", "textbook": "-"}
    update_index(tmp_path, [gone], keep)
    update_index(tmp_path, [first], keep)
    assert "removed-model" not in (tmp_path / "README.md").read_text(encoding="utf-8")  # not in the folder


def test_a_report_is_one_unit_completed_by_the_next_writer(tmp_path, monkeypatch):
    """A run killed after the new images are swapped in but before its Markdown is
    renamed out of them (the one gap left, two renames): the new Markdown waits
    in the image folder, the old one is untouched; the next writer, under the
    lock, completes the unit before anything else."""
    import xcheck.report as report
    from xcheck import api

    out = tmp_path / "reports"
    run = api.run(MODELS / "fourbar.toml", "formulations", samples=31)
    report.write_report(run, out, "xcheck run fourbar", gif=False)  # the earlier report, with its evidence
    old_report = marked("old report\n", "the report of fourbar").encode()
    _touch(out / "fourbar.md", old_report)
    _touch(out / "fourbar" / "drawing.png", b"old image")

    complete = report.complete_reports

    def killed(directory, name=None):
        if name is None:  # the writer's first step: nothing pending yet
            return complete(directory)
        raise KeyboardInterrupt  # stands for SIGKILL between the two renames

    monkeypatch.setattr(report, "complete_reports", killed)
    try:
        report.write_report(run, out, "xcheck run fourbar", gif=False)
    except KeyboardInterrupt:
        pass
    assert (out / "fourbar.md").read_bytes() == old_report
    pending = out / "fourbar" / ".report.md"
    assert pending.is_file() and (out / "fourbar" / "drawing.png").read_bytes() != b"old image"
    new_text = pending.read_text(encoding="utf-8")
    assert "fourbar/drawing.png" in new_text
    monkeypatch.undo()
    update_index(out, [], {"fourbar"})  # any later writer in the folder completes it first
    assert (out / "fourbar.md").read_text(encoding="utf-8") == new_text
    assert not pending.exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
