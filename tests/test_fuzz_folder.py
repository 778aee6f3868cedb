"""``xcheck fuzz --out DIR`` shares DIR with the user: it replaces only files it
wrote, resumes only a campaign of the same settings, and refuses in one line,
before any case runs, a folder it cannot use, a seed out of range, a foreign
results part, or a scheduler address where no Dask scheduler answers."""

from __future__ import annotations

import contextlib
import os
import socket
import stat
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import invoke

from xcheck import fuzz
from xcheck.errors import InputError

#: a quick campaign: one case, the exact formulations only
QUICK = ("--count", "1", "--engines", "formulations", "--workers", "1", "--samples", "21")


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` and its bytes (None for a folder or a FIFO)."""
    return {
        str(p.relative_to(folder)): p.read_bytes() if p.is_file() and not p.is_symlink() else None
        for p in sorted(folder.rglob("*"))
    }


def _refused(result, *needles: str) -> str:
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("xcheck: error: ") and "Traceback" not in result.stderr, lines
    assert all(n in lines[0] for n in needles), lines[0]
    return lines[0]


def _fuzz(out: Path, *args: str):
    return invoke("fuzz", *QUICK, *args, "--out", str(out))


def test_a_failures_md_of_the_users_is_never_replaced(tmp_path):
    """Case 5 of the issue: `fuzz --out DIR` overwrote DIR/failures.md without a word."""
    out = tmp_path / "proj"
    out.mkdir()
    (out / "failures.md").write_text("# My failures\nthe ones I care about\n", encoding="utf-8")
    (out / ".notes.md.20251126").write_text("hidden", encoding="utf-8")
    before = _snapshot(out)
    _refused(_fuzz(out), f"{out / 'failures.md'}: expected the failure report of xcheck fuzz", "left as it is")
    assert _snapshot(out) == before  # refused before anything was written


@pytest.mark.parametrize("kind", ["folder", "fifo", "symlink"])
def test_something_else_named_failures_md_is_refused_without_a_hang(tmp_path, kind):
    out = tmp_path / "proj"
    out.mkdir()
    target = out / "failures.md"
    if kind == "folder":
        target.mkdir()
        (target / "keep.txt").write_text("mine", encoding="utf-8")
    elif kind == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("no FIFOs here")
        os.mkfifo(target)
    else:
        (tmp_path / "elsewhere.md").write_text(fuzz._REPORT_MARK + "\n", encoding="utf-8")
        target.symlink_to(tmp_path / "elsewhere.md")
    before = _snapshot(out)
    _refused(_fuzz(out), "failures.md: expected the failure report of xcheck fuzz")
    assert _snapshot(out) == before


def test_a_campaign_rewrites_only_its_own_files_and_resumes(tmp_path):
    out = tmp_path / "campaign"
    out.mkdir()
    (out / "README.md").write_text("# my notes on this campaign\n", encoding="utf-8")
    first = _fuzz(out, "--seed", "3")
    assert first.returncode in (0, 1), first.stderr
    assert (out / "failures.md").read_text(encoding="utf-8").startswith(fuzz._REPORT_MARK)
    again = invoke("fuzz", *QUICK[:1], "2", *QUICK[2:], "--seed", "3", "--out", str(out))
    assert again.returncode in (0, 1), again.stderr
    assert len(fuzz.read_rows(out).case.unique()) == 2
    assert (out / "README.md").read_text(encoding="utf-8") == "# my notes on this campaign\n"
    umask = os.umask(0)
    os.umask(umask)
    for part in (out / "results").glob("part-*.parquet"):  # ordinary files, as every other output
        assert stat.S_IMODE(part.stat().st_mode) == 0o666 & ~umask


@pytest.mark.parametrize(
    "args, differs",
    [
        (("--engines", "native"), "modes formulation-I,formulation-II,native (asked: native)"),
        (("--samples", "31"), "samples 21 (asked: 31)"),
        (("--kinds", "slider-crank,fourbar"), "kinds fourbar,slider-crank,scotch-yoke (asked: slider-crank,fourbar)"),
    ],
)
def test_resuming_with_other_settings_is_refused(tmp_path, args, differs):
    """Case 10 of the issue: resuming into the same --out with other --engines or
    --samples mixed the rows without a word. The later option wins in typer."""
    out = tmp_path / "campaign"
    assert _fuzz(out).returncode in (0, 1)
    before = _snapshot(out)
    _refused(_fuzz(out, *args), f"{out}: expected the settings of the campaign there to resume it, found {differs}")
    assert _snapshot(out) == before


def test_results_without_settings_are_not_resumed(tmp_path):
    out = tmp_path / "older"
    assert _fuzz(out).returncode in (0, 1)
    (out / fuzz.SETTINGS_FILE).unlink()
    _refused(_fuzz(out), "found results/ without them")
    (out / fuzz.SETTINGS_FILE).write_text('{"kinds": ["mine"]}\n', encoding="utf-8")
    _refused(_fuzz(out), "campaign.json: expected the settings of an xcheck fuzz campaign")


def test_a_case_file_of_the_users_is_never_replaced(tmp_path):
    out = tmp_path / "campaign"
    name = fuzz.generate(0, 0).name
    (out / "cases").mkdir(parents=True)
    (out / "cases" / f"{name}.toml").write_text("# my own four-bar\n", encoding="utf-8")
    _refused(_fuzz(out, "--kinds", "fourbar,slider-crank,scotch-yoke"), f"{name}.toml: expected a case file")
    assert (out / "cases" / f"{name}.toml").read_text(encoding="utf-8") == "# my own four-bar\n"


@pytest.mark.parametrize(
    "content, needle",
    [
        (b"not parquet at all", "found a file that is not one"),
        (None, "found one without the columns"),  # a Parquet file of other columns
        ("folder", "found something that is not a plain file"),
    ],
)
def test_a_foreign_results_part_is_one_line(tmp_path, content, needle):
    """Case 16: a foreign results/part-*.parquet raised ArrowInvalid."""
    out = tmp_path / "campaign"
    assert _fuzz(out).returncode in (0, 1)
    part = out / "results" / "part-000000-foreign.parquet"
    if content is None:
        pd.DataFrame({"mine": [1, 2]}).to_parquet(part)
    elif content == "folder":
        part.mkdir()
    else:
        part.write_bytes(content)
    before = _snapshot(out)
    _refused(_fuzz(out), f"{part}: expected a part of the results xcheck fuzz writes", needle)
    assert _snapshot(out) == before
    with pytest.raises(InputError, match="expected a part of the results"):
        fuzz.read_rows(out)


@pytest.mark.parametrize("seed", ["-1", "123456789012345678901234567890", str(2**63)])
def test_a_seed_out_of_range_is_refused_before_any_case(tmp_path, seed):
    """Case 16: --seed -1 raised ValueError; a 30-digit seed OverflowError after its case ran."""
    out = tmp_path / "campaign"
    _refused(_fuzz(out, "--seed", seed), f"--seed: expected a whole number from 0 to {2**63 - 1}, found {seed}")
    assert not out.exists()
    with pytest.raises(InputError, match=r"^seed: expected a whole number"):
        fuzz.fuzz(out, count=1, seed=int(seed), modes="formulations", workers=1)


def test_the_largest_seed_runs(tmp_path):
    rows = fuzz.fuzz(tmp_path, count=1, seed=2**63 - 1, modes="formulations", workers=1, samples=21)
    assert (rows.seed == 2**63 - 1).all() and len(rows) >= 3


def test_an_out_through_a_file_is_refused(tmp_path):
    """Case 16: NotADirectoryError."""
    (tmp_path / "file").write_text("mine", encoding="utf-8")
    _refused(_fuzz(tmp_path / "file"), "--out", "expected a directory for the campaign, found a file")
    _refused(_fuzz(tmp_path / "file" / "below"), "expected a directory for the campaign, found that it cannot be made")
    assert (tmp_path / "file").read_text(encoding="utf-8") == "mine"


def test_an_out_that_cannot_be_written_is_refused(tmp_path):
    """Case 16: PermissionError. A read-only folder where this user cannot write
    there (not root), and a folder under /sys, which no one may make."""
    targets = []
    if Path("/sys/kernel").is_dir():
        targets.append(Path("/sys/xcheck-fuzz"))
    if hasattr(os, "geteuid") and os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o500)
        targets.append(locked)
    if not targets:
        pytest.skip("no folder here that this user cannot write")
    for target in targets:
        _refused(_fuzz(target), f"--out {target}: expected a directory for the campaign")


def test_the_api_refuses_what_the_command_line_refuses(tmp_path):
    for kwargs, needle in [
        ({"count": 0}, "count: expected a whole number from 1 to 100000, found 0"),
        ({"count": 10**9}, "count: expected a whole number from 1 to 100000"),
        ({"samples": -5}, "samples: expected a whole number from 3 to 100000, found -5"),
        ({"workers": 0}, "workers: expected a whole number from 1 to 256, found 0"),
        ({"batch": 0}, "batch: expected a whole number from 1 to 100000, found 0"),
        ({"kinds": ["hexapod"]}, "^kinds: expected kinds among"),
    ]:
        with pytest.raises(InputError, match=needle):
            fuzz.fuzz(tmp_path / "api", **{"count": 1, "modes": "formulations", **kwargs})
    assert not (tmp_path / "api").exists()


def test_write_failure_report_replaces_only_its_own(tmp_path):
    rows = fuzz.read_rows(tmp_path)  # no rows
    path = fuzz.write_failure_report(tmp_path, rows, "xcheck fuzz")
    assert path.read_text(encoding="utf-8").startswith(fuzz._REPORT_MARK)
    fuzz.write_failure_report(tmp_path, rows, "xcheck fuzz --count 2")  # its own: rewritten
    path.write_text("mine\n", encoding="utf-8")
    with pytest.raises(InputError, match="failures.md: expected the failure report of xcheck fuzz"):
        fuzz.write_failure_report(tmp_path, rows, "xcheck fuzz")
    assert path.read_text(encoding="utf-8") == "mine\n"


# ----------------------------------------------------------------------------- a scheduler that is not one


@contextlib.contextmanager
def _stranger(answer: bytes | None):
    """A TCP server on 127.0.0.1 that is not a Dask scheduler: it sends
    ``answer`` to each connection and then keeps it open in silence (None:
    silence from the start; b"": closes it at once). Yields its address."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.2)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except OSError:
                continue
            if answer == b"":
                connection.close()
                continue
            if answer:
                with contextlib.suppress(OSError):
                    connection.sendall(answer)
            held.append(connection)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(5)
        for connection in held:
            connection.close()
        server.close()


@pytest.mark.parametrize(
    "answer",
    [
        None,  # silence: this hung past 120 s
        b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n",  # a 3.07 EiB allocation
        bytes(range(256)) * 4,  # garbage: a bare ValueError
        b"",  # closes every connection
    ],
    ids=["silent", "http", "garbage", "closes"],
)
def test_a_scheduler_address_where_no_dask_scheduler_answers_is_one_line(tmp_path, monkeypatch, answer):
    """Cases 13 and 16, in bounded time (the limit made 2 s here; 0.5 s for the
    silent server, which only the limit ends, at one and a half times it)."""
    monkeypatch.setattr(fuzz, "SCHEDULER_TIMEOUT", 0.5 if answer is None else 2.0)
    with _stranger(answer) as address:
        start = time.monotonic()
        result = _fuzz(tmp_path / "campaign", "--scheduler", address)
        assert time.monotonic() - start < 20
    _refused(result, f"--scheduler {address}: expected the address of a running Dask scheduler, found")


def test_no_scheduler_at_a_closed_port_is_one_line(tmp_path, monkeypatch):
    """Dask tries the connection again until the limit (made 1 s here) and then
    raises; the limit's half again after it lets that error through."""
    monkeypatch.setattr(fuzz, "SCHEDULER_TIMEOUT", 1.0)
    with socket.socket() as probe:  # a port that was free a moment ago
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    _refused(_fuzz(tmp_path / "campaign", "--scheduler", f"tcp://127.0.0.1:{port}"), "found OSError")


@pytest.mark.parametrize("blocker", ["cases", "results"])
def test_a_file_where_a_campaign_folder_goes_is_refused_before_anything_is_written(tmp_path, blocker):
    out = tmp_path / "campaign"
    out.mkdir()
    (out / blocker).write_text("mine\n", encoding="utf-8")
    before = _snapshot(out)
    _refused(_fuzz(out), str(out))
    assert _snapshot(out) == before  # no campaign.json left behind either
