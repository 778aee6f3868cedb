"""Every code block of the README and of the documentation pages is checked.

- ``python``: the blocks of a page run in order, in one fresh interpreter;
- ``toml``: parses; a whole mechanism file (``[mechanism]``) loads and assembles;
- ``json``: parses;
- ``sh``: each line that calls ``xcheck`` is parsed by the command line itself
  (every option and value must exist and convert), and the quick commands
  (``list``, ``engines``, ``solve``, ``draw``, ``--help``) run and must exit 0;
  ``make TARGET`` names a target of the Makefile, ``pip install ".[EXTRA]"`` an
  extra of pyproject.toml, ``python -m MODULE`` an importable module. The long
  commands (``run``, ``simulate``, ``fuzz``, ``export``) are the subject of their
  own tests, which run them;
- ``console``: each ``$ xcheck …`` line runs and must print the lines under it;
- ``text``: output shown beside a command (``test_readme_example.py`` checks the
  one the guide quotes).

Quick commands run in a scratch folder that sees the repository's ``models``,
``comparisons`` and ``docs`` under their own names, so a block's relative paths
mean what they mean at the repository's root and what a command writes stays there.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from conftest import ROOT

PAGES = sorted(
    [ROOT / "README.md", ROOT / "CONTRIBUTING.md", ROOT / "CHANGELOG.md"]
    + [p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts]
)
FENCE = re.compile(r"^(?P<indent>[ ]*)```(?P<lang>[^\n`]*)\n(?P<body>.*?)^(?P=indent)```[ ]*$", re.M | re.S)
#: the languages a block may have; a MyST directive ({toctree}, {eval-rst}, ...) is built by `make docs`
LANGUAGES = {"python", "toml", "json", "sh", "console", "text"}
QUICK = {"list", "engines", "solve", "draw"}
#: programs a shell block may name besides xcheck, make, pip and python
OTHER_PROGRAMS = {"dask"}


def blocks(page: Path) -> list[tuple[str, str, int]]:
    """(language, body, line) of every fenced block of a page, the body dedented."""
    text = page.read_text(encoding="utf-8")
    found = []
    for match in FENCE.finditer(text):
        indent = len(match.group("indent"))
        body = "\n".join(line[indent:] for line in match.group("body").splitlines())
        found.append((match.group("lang").strip(), body, text.count("\n", 0, match.start()) + 1))
    return found


def _id(page: Path) -> str:
    return str(page.relative_to(ROOT))


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A folder where models/, comparisons/ and docs/ are the repository's."""
    for name in ("models", "comparisons", "docs"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("XCHECK_MODELS", raising=False)
    return tmp_path


def _xcheck(args: list[str]):
    from typer.testing import CliRunner

    from xcheck.cli import app

    return CliRunner().invoke(app, args)


def _parses(args: list[str]) -> None:
    """The command line as xcheck's own parser reads it: an unknown option or a
    value of the wrong type raises."""
    import typer.main

    from xcheck.cli import app

    group = typer.main.get_command(app)
    context = group.make_context("xcheck", list(args))
    protected = getattr(context, "_protected_args", None) or getattr(
        context, "protected_args", []
    )  # click 8.2: private
    name, command, rest = group.resolve_command(context, [*protected, *context.args])
    assert command is not None, args
    command.make_context(name, rest, parent=context)


def _shell_commands(body: str) -> list[list[str]]:
    commands = []
    for line in body.splitlines():
        for part in re.split(r"&(?!&)|&&|;", line.split(" #")[0] if not line.startswith("#") else ""):
            words = shlex.split(part, comments=True)
            if words:
                commands.append(words)
    return commands


def test_every_block_has_a_language_the_tests_check():
    for page in PAGES:
        for lang, _, line in blocks(page):
            assert lang in LANGUAGES or lang.startswith("{"), f"{_id(page)}:{line}: a block in {lang or 'no language'}"


def test_the_readme_fits_two_screens_and_links_only_what_exists():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if "://" not in target:
            assert (ROOT / target).exists(), target


@pytest.mark.parametrize("page", [p for p in PAGES if any(lang == "python" for lang, _, _ in blocks(p))], ids=_id)
def test_python_blocks_run(page):
    code = "\n\n".join(body for lang, body, _ in blocks(page) if lang == "python")
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT / "src")}
    env.pop("XCHECK_MODELS", None)
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{_id(page)}:\n{done.stderr[-3000:]}"


@pytest.mark.parametrize(
    "page", [p for p in PAGES if any(lang in ("toml", "json") for lang, _, _ in blocks(p))], ids=_id
)
def test_data_blocks_parse_and_mechanisms_assemble(page, tmp_path):
    import xcheck

    for lang, body, line in blocks(page):
        try:
            document = tomllib.loads(body) if lang == "toml" else json.loads(body) if lang == "json" else None
        except (tomllib.TOMLDecodeError, json.JSONDecodeError) as err:
            pytest.fail(f"{_id(page)}:{line}: {err}")
        if lang == "toml" and "mechanism" in document:
            path = tmp_path / f"block-{line}.toml"
            path.write_text(body, encoding="utf-8")
            xcheck.load(path)


@pytest.mark.parametrize("page", [p for p in PAGES if any(lang == "sh" for lang, _, _ in blocks(p))], ids=_id)
def test_shell_blocks(page, scratch):
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    for lang, body, line in blocks(page):
        if lang != "sh":
            continue
        for words in _shell_commands(body):
            where = f"{_id(page)}:{line}: {' '.join(words)}"
            program, args = words[0], words[1:]
            if program == "xcheck":
                _parses(args)
                if args[0] in QUICK or "--help" in args:
                    result = _xcheck(args)
                    assert result.exit_code == 0, f"{where}\n{result.output}"
            elif program == "make":
                assert all(re.search(rf"^{re.escape(t)}:", makefile, re.M) for t in args), where
            elif program == "pip":
                for extra in re.findall(r"\[([a-z,]+)\]", " ".join(args)):
                    assert set(extra.split(",")) <= set(extras), where
            elif program == "python":
                import importlib.util

                assert args[0] == "-m" and importlib.util.find_spec(args[1]) is not None, where
            else:
                assert program in OTHER_PROGRAMS, where


@pytest.mark.parametrize("page", [p for p in PAGES if any(lang == "console" for lang, _, _ in blocks(p))], ids=_id)
def test_console_blocks_print_what_they_show(page, scratch):
    for lang, body, line in blocks(page):
        if lang != "console":
            continue
        for chunk in re.split(r"^\$ ", body, flags=re.M)[1:]:
            command, *shown = chunk.splitlines()
            words = shlex.split(command)
            assert words[0] == "xcheck", f"{_id(page)}:{line}: {command}"
            result = _xcheck(words[1:])
            printed = " ".join(result.output.split())
            for expected in shown:
                assert " ".join(expected.split()) in printed, f"{_id(page)}:{line}: {command}\n{result.output}"
