"""An output folder (``--out``) is shared with the user: xcheck writes and
replaces only what it can tell it wrote, removes only temporaries of its own,
and a mechanism may not take the index's names. Each case starts from a
scratch folder holding a user's files, and ends with every one of them as it
was."""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA
from typer.testing import CliRunner

from xcheck.cli import app
from xcheck.fileio import MARK, reserved_name

FOURBAR = DATA / "fourbar-200.toml"  # name "fourbar-200"
RUN = ("--engines", "native", "--samples", "11", "--no-gif", "-q")


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _snapshot(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` (links as their target) -> its SHA-256; folders as "folder"."""
    found = {}
    for path in sorted(folder.rglob("*")):
        key = str(path.relative_to(folder))
        if path.is_symlink():
            found[key] = "-> " + os.readlink(path)
        elif path.is_dir():
            found[key] = "folder"
        elif not stat.S_ISREG(path.stat().st_mode):
            found[key] = "special"  # a FIFO: reading it would block
        else:
            found[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def _users_folder(root: Path) -> Path:
    """A project folder as a user has it: a README, notes, hidden files that look
    like temporaries, a hidden folder, a thesis beside a drawing."""
    files = {
        "README.md": "# My project\n",
        "index.json": '{"mine": true}\n',
        "notes.md": "mine\n",
        "notes/.report.md": "scratch\n",
        ".notes.md.20251126": "yesterday's notes\n",
        ".draft.md.backup_1": "draft\n",
        ".photos.2025abcd/holiday.jpg": "jpeg\n",
        ".fourbar-200.xcheck-staging-0123abcd/mine.txt": "named like a temporary, but mine\n",
        "thesis/fourbar-200/drawing.png": "my drawing\n",
        "thesis/fourbar-200/thesis.tex": "\\documentclass{article}\n",
    }
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def _one_line(result, *parts: str) -> None:
    line = result.stderr.strip()
    assert result.exit_code == 2, result.output
    assert len(line.splitlines()) == 1 and line.startswith("xcheck: error: "), line
    for part in parts:
        assert part in line, line


def test_a_users_readme_and_index_are_never_replaced(tmp_path):
    """The reports' index would be README.md and index.json: a user's are in the
    way; the run says so in one line before it works, and writes nothing."""
    project = _users_folder(tmp_path / "proj")
    before = _snapshot(project)
    result = _cli("run", FOURBAR, "--out", project, *RUN)
    _one_line(result, str(project / "README.md"), "xcheck did not write", "--out")
    assert _snapshot(project) == before
    (project / "README.md").unlink()
    before = _snapshot(project)
    result = _cli("run", FOURBAR, "--out", project, *RUN)
    _one_line(result, str(project / "index.json"), "xcheck did not write")
    assert _snapshot(project) == before


def test_hidden_files_and_a_users_notes_are_left_alone(tmp_path):
    """A run into a folder with hidden files that look like temporaries, a
    notes.md and a folder notes/ holding a .report.md: the reports are written
    beside them, and nothing of the user's changes or goes."""
    project = _users_folder(tmp_path / "proj")
    for name in ("README.md", "index.json"):
        (project / name).unlink()
    before = _snapshot(project)
    result = _cli("run", FOURBAR, "--out", project, *RUN)
    assert result.exit_code == 0, result.output
    after = _snapshot(project)
    assert {k: v for k, v in after.items() if k in before} == before
    written = set(after) - set(before)
    assert {"README.md", "index.json", "fourbar-200.md", "fourbar-200", "fourbar-200/results.json"} <= written
    assert all(not k.startswith(".") for k in written)
    assert (project / "fourbar-200.md").read_text().startswith(MARK)
    # and again: its own files are replaced, the user's still left alone
    assert _cli("run", FOURBAR, "--out", project, *RUN).exit_code == 0
    assert {k: v for k, v in _snapshot(project).items() if k in before} == before


def test_a_folder_with_the_reports_name_and_a_users_file_in_it_is_kept_whole(tmp_path):
    """thesis/fourbar-200/ holds a drawing.png, as a report's folder does, and a
    thesis.tex: not a report of xcheck's, so it is neither replaced nor deleted."""
    project = _users_folder(tmp_path / "proj")
    before = _snapshot(project)
    result = _cli("run", FOURBAR, "--out", project / "thesis", *RUN)
    _one_line(result, str(project / "thesis" / "fourbar-200"), "a folder xcheck did not write")
    assert _snapshot(project) == before


def test_a_users_markdown_with_a_reports_name_is_kept(tmp_path):
    out = tmp_path / "reports"
    out.mkdir()
    (out / "fourbar-200.md").write_text("# my own notes on the four-bar\n\nReproduce: `xcheck run` later\n")
    before = _snapshot(out)
    result = _cli("run", FOURBAR, "--out", out, *RUN)
    _one_line(result, str(out / "fourbar-200.md"), "a file xcheck did not write")
    assert _snapshot(out) == before


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_link_or_a_fifo_in_the_way_is_left_alone_and_never_read(tmp_path):
    out = tmp_path / "reports"
    out.mkdir()
    target = tmp_path / "elsewhere.md"
    target.write_text("mine\n")
    (out / "fourbar-200.md").symlink_to(target)
    result = _cli("run", FOURBAR, "--out", out, *RUN)
    _one_line(result, "fourbar-200.md", "xcheck did not write")
    assert target.read_text() == "mine\n" and (out / "fourbar-200.md").is_symlink()
    (out / "fourbar-200.md").unlink()
    os.mkfifo(out / "README.md")  # reading it would block for ever
    result = _cli("run", FOURBAR, "--out", out, *RUN)
    _one_line(result, "README.md", "xcheck did not write")


def test_the_next_run_completes_only_its_own_reports(tmp_path):
    """A folder notes/ with a .report.md that is not xcheck's is no report
    waiting to be completed: notes.md stays the user's."""
    project = _users_folder(tmp_path / "proj")
    for name in ("README.md", "index.json"):
        (project / name).unlink()
    assert _cli("run", FOURBAR, "--out", project, *RUN).exit_code == 0
    assert (project / "notes.md").read_text() == "mine\n"
    assert (project / "notes" / ".report.md").read_text() == "scratch\n"


@pytest.mark.parametrize("name", ["README", "readme", "README.md", "index.json", "Index.JSON", "fourbar.md", "x.MD"])
def test_a_mechanism_may_not_take_the_indexs_or_another_reports_name(tmp_path, name):
    assert reserved_name(name) is not None
    path = tmp_path / "models" / "named.toml"
    path.parent.mkdir()
    path.write_text(FOURBAR.read_text().replace('name = "fourbar-200"', f'name = "{name}"', 1))
    out = tmp_path / "reports"
    result = _cli("run", path, "--out", out, *RUN)
    _one_line(result, "mechanism.name", name)
    assert not out.exists()
    assert _cli("solve", path).exit_code == 2


@pytest.mark.parametrize("name", ["index", "readme-notes", "README2", "notes.mdx", "md"])
def test_names_near_the_reserved_ones_are_fine(name):
    assert reserved_name(name) is None


# -- a seeded campaign -----------------------------------------------------------
#: what a user's folder may hold where xcheck writes: name -> (how to make it, whether xcheck may replace it)
NAME = "fourbar-200"


def _file(text: str):
    return lambda path: path.write_text(text)


def _folder(files: dict[str, str]):
    def make(path: Path) -> None:
        path.mkdir()
        for name, text in files.items():
            (path / name).write_text(text)

    return make


def _link(path: Path) -> None:
    target = path.parent.parent / f"target-of-{path.name}"
    target.write_text("the user's\n")
    path.symlink_to(target)


def _fifo(path: Path) -> None:
    os.mkfifo(path)


_MARKED = f"{MARK}: an earlier report. -->\n# old\n"
_OLD = "# fourbar-200: old\n\nReproduce: `xcheck run fourbar-200`\n"
#: (entry, variants: (label, make, xcheck may replace it))
CHOICES = {
    "README.md": [
        ("user's", _file("# My project\n"), False),
        ("xcheck's", _file(f"{MARK}: the index. -->\n# Reports\n"), True),
        ("link", _link, False),
        ("fifo", _fifo, False),
    ],
    "index.json": [
        ("user's", _file('{"mine": 1}\n'), False),
        ("xcheck's", _file('{"generator": "xcheck", "entries": []}\n'), True),
        ("not json", _file("garbage\n"), False),
    ],
    f"{NAME}.md": [
        ("user's", _file("my notes\n"), False),
        ("xcheck's", _file(_MARKED), True),
        ("an earlier version's", _file(_OLD), True),
        ("a folder", _folder({"x.txt": "mine\n"}), False),
        ("fifo", _fifo, False),
    ],
    NAME: [
        ("user's folder", _folder({"thesis.tex": "mine\n"}), False),
        ("figures and a user's file", _folder({"drawing.png": "png\n", "thesis.tex": "mine\n"}), False),
        # an earlier version's report has no evidence to keep the modes a run of some modes leaves out
        ("an earlier version's figures", _folder({"drawing.png": "png\n", "quantities.png": "png\n"}), False),
        ("a foreign results.json", _folder({"results.json": '{"files": []}\n', "drawing.png": "png\n"}), False),
        ("a file", _file("mine\n"), False),
        ("link", _link, False),
    ],
    f".{NAME}.xcheck-staging-0a1b2c3d": [("named like staging, no mark", _folder({"mine.txt": "mine\n"}), True)],
    f".{NAME}.md.1a2b3c4d": [("an old temporary's name", _file("mine\n"), True)],
}


def _campaign_case(seed: int, root: Path) -> tuple[Path, bool, list[str]]:
    """A folder of random entries; whether a run must be refused; what it holds."""
    rng = np.random.default_rng(seed)
    root.mkdir()
    refused, made = False, []
    for entry, variants in CHOICES.items():
        if rng.random() < 0.5:
            continue
        label, make, replaceable = variants[int(rng.integers(len(variants)))]
        make(root / entry)
        made.append(f"{entry}: {label}")
        # a hidden entry is never in xcheck's way, whatever it holds
        refused |= not replaceable and not entry.startswith(".")
    return root, refused, made


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("seed", range(16))
def test_a_seeded_campaign_of_users_folders(tmp_path, seed):
    """Random folders of a user's files, xcheck's, earlier versions', links and
    FIFOs where the report and the index go: a run (of some modes) writes its
    reports (exit 0) exactly where nothing of the user's, and no report it
    cannot keep the other modes of, is in the way, else says so in one line
    (exit 2); either way every file of the user's is as it was."""
    root, refused, made = _campaign_case(seed, tmp_path / "out")
    before = _snapshot(tmp_path)
    result = _cli("run", FOURBAR, "--out", root, *RUN)
    if refused:
        _one_line(result, "it is left as it is")
        assert _snapshot(tmp_path) == before, made
    else:
        assert result.exit_code == 0, (made, result.output)
        assert (root / f"{NAME}.md").read_text().startswith(MARK)
        after = _snapshot(tmp_path)
        # what links point at, and everything hidden, is the user's
        users = {k: v for k, v in before.items() if k.startswith("target-of") or k.startswith("out/.")}
        assert {k: after.get(k) for k in users} == users, made
