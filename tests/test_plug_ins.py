"""A plug-in (an entry point of group ``xcheck.engines``) can never stop xcheck:
one that raises anything at import, calls ``sys.exit``, raises
``KeyboardInterrupt`` itself, sleeps or loops, or another package's malformed
``entry_points.txt``, becomes a "could not be loaded" line, and every command
goes on with the other engines. A real Ctrl-C still stops xcheck.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from importlib import metadata

import pytest
from conftest import MODELS, ROOT, ctrl_c_as_at_a_terminal, install_plug_in

from xcheck.engines import _registry

_GOOD = """
from xcheck import engines
from xcheck.tolerances import Tolerance


class Plugged(engines.Engine):
    name = "plugged"
    modes = (engines.Mode("plugged-kinematic", "kinematic", Tolerance(1, 1, 1, 1, "anything")),)
"""

#: bodies of plug-in modules that must not load, and the reason each gets
_BROKEN = {
    "exit0": ("import sys\nsys.exit(0)\n", "its import called sys.exit(0)"),
    "exit3": ("raise SystemExit(3)\n", "its import called sys.exit(3)"),
    "exitnone": ("import sys\nsys.exit()\n", "its import called sys.exit(None)"),
    "interrupt": ("raise KeyboardInterrupt\n", "KeyboardInterrupt"),
    "generator": ("raise GeneratorExit('gone')\n", "GeneratorExit: gone"),
    "error": ("raise RuntimeError('no licence\\nsecond line')\n", "RuntimeError: no licence second line"),
    "notengine": ("X = 42\n", "TypeError: expected an xcheck.engines.Engine, found int"),
}


def _entry_point(tmp_path, monkeypatch, source: str) -> metadata.EntryPoint:
    """An entry point to a fresh module holding ``source`` (object ``X``)."""
    module = f"xcheck_plug_{uuid.uuid4().hex[:10]}"
    (tmp_path / f"{module}.py").write_text(source, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    return metadata.EntryPoint(name=module, value=f"{module}:X", group=_registry.ENTRY_POINT_GROUP)


@pytest.mark.parametrize("kind", sorted(_BROKEN))
def test_a_plug_in_that_raises_anything_is_a_reason(tmp_path, monkeypatch, kind):
    source, reason = _BROKEN[kind]
    point = _entry_point(tmp_path, monkeypatch, source)
    with pytest.raises(_registry._NotLoaded) as caught:
        _registry._load_plug_in(point, timeout=30.0)
    assert str(caught.value) == reason


@pytest.mark.parametrize("body", ["import time\ntime.sleep(4)\n", "while True:\n    pass\n"])
def test_a_plug_in_that_hangs_is_given_up_on_time(tmp_path, monkeypatch, body):
    """A sleep or an endless loop at import: refused after the timeout; the loop
    is stopped where it runs (the sleep ends alone, in its daemon thread)."""
    point = _entry_point(tmp_path, monkeypatch, body)
    before = set(threading.enumerate())
    start = time.monotonic()
    with pytest.raises(_registry._NotLoaded, match=r"its import did not finish within 0\.5 s"):
        _registry._load_plug_in(point, timeout=0.5)
    assert time.monotonic() - start < 3.0
    if "while" in body:  # the loop was interrupted: its thread ends at once
        (left,) = set(threading.enumerate()) - before
        left.join(5.0)
        assert not left.is_alive()


def test_the_timeout_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv(_registry.TIMEOUT_ENV, "2.5")
    assert _registry._plug_in_timeout() == 2.5
    for bad in ("", "soon", "-1", "nan", "inf", "0"):
        monkeypatch.setenv(_registry.TIMEOUT_ENV, bad)
        assert _registry._plug_in_timeout() == _registry.PLUG_IN_TIMEOUT


# ----------------------------------------------------------------------------- end to end


def _site(tmp_path, *names: str):
    """A folder of installed distributions: the good plug-in and the broken ones named."""
    site = tmp_path / "site"
    site.mkdir()
    install_plug_in(site, "xcheck_plug_good", _GOOD, "[xcheck.engines]\nplugged = xcheck_plug_good:Plugged\n")
    bodies = {
        **{k: v[0] for k, v in _BROKEN.items()},
        "sleeps": "import time\ntime.sleep(600)\n",
        "loops": "while True:\n    pass\n",
    }
    for name in names:
        install_plug_in(site, f"xcheck_plug_{name}", bodies[name], f"[xcheck.engines]\n{name} = xcheck_plug_{name}:X\n")
    return site


def _xcheck(site, *args, timeout: float = 120.0, **env):
    environment = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), str(ROOT / "src")]),
        _registry.TIMEOUT_ENV: "0.5",  # each hanging plug-in costs the command this wait
        **env,
    }
    return subprocess.run(
        [sys.executable, "-m", "xcheck", *args],
        env=environment,
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=ctrl_c_as_at_a_terminal,
    )


def _unwrapped(text: str) -> str:
    """The terminal's text with its line wrapping undone (the engines line wraps at any space)."""
    return " ".join(text.split())


def _warned(stderr: str) -> dict[str, str]:
    """The plug-ins a command said it could not load: name -> reason."""
    found = {}
    for line in stderr.splitlines():
        assert line.startswith("xcheck: warning: plug-in "), line
        name = line.split("'")[1]
        found[name] = line.split("runs nowhere: ", 1)[1]
    return found


def test_run_goes_on_beside_plug_ins_that_exit_interrupt_or_hang(tmp_path):
    """The cases of the issue: a plug-in calling sys.exit(0) made `xcheck run`
    exit 0 with no output; SystemExit(3) and KeyboardInterrupt silent exits 3
    and 130; one that sleeps hung it. Now the run prints its table, exits 0 and
    names each plug-in it could not load, the hanging ones after the timeout."""
    site = _site(tmp_path, "exit0", "exit3", "interrupt", "sleeps", "loops")
    start = time.monotonic()
    result = _xcheck(site, "run", str(MODELS / "fourbar.toml"), "--engines", "native,formulations", "--no-report")
    assert time.monotonic() - start < 60
    assert result.returncode == 0, result.stderr
    assert "native" in result.stdout and "formulation-II" in result.stdout
    assert _warned(result.stderr) == {
        "exit0": "its import called sys.exit(0)",
        "exit3": "its import called sys.exit(3)",
        "interrupt": "KeyboardInterrupt",
        "sleeps": f"its import did not finish within 0.5 s (${_registry.TIMEOUT_ENV} sets the limit)",
        "loops": f"its import did not finish within 0.5 s (${_registry.TIMEOUT_ENV} sets the limit)",
    }


def test_list_and_engines_name_the_plug_ins_they_could_not_load(tmp_path):
    site = _site(tmp_path, "exit0", "error")
    listed = _xcheck(site, "list", str(MODELS / "fourbar.toml"))
    assert listed.returncode == 0 and "plugged (plugged-kinematic)" in _unwrapped(listed.stdout)
    assert set(_warned(listed.stderr)) == {"exit0", "error"}
    shown = _xcheck(site, "engines", "--json")
    doc = json.loads(shown.stdout)
    assert shown.returncode == 0 and "plugged" in {e["name"] for e in doc["engines"]}
    assert doc["plugin_errors"] == _warned(shown.stderr)


def test_a_command_that_needs_no_engine_says_nothing_of_plug_ins(tmp_path):
    site = _site(tmp_path, "exit0")
    # slider-crank: a law its crank can follow, so solve has nothing to warn about at all
    result = _xcheck(site, "solve", str(MODELS / "slider-crank.toml"), "--at", "30")
    assert result.returncode == 0 and result.stderr == ""


def test_a_malformed_entry_points_file_of_another_package_is_passed_over(tmp_path):
    """Another distribution's entry_points.txt that metadata cannot parse made
    `engines` and `list` fail with `TypeError: Pair.__new__()`; now one that does
    not name xcheck's group is none of xcheck's business, and one that does is
    named."""
    site = _site(tmp_path)
    install_plug_in(site, "unrelated_pkg", "", "[console_scripts]\nno equals sign here\n")
    result = _xcheck(site, "engines", "--json")
    assert result.returncode == 0 and result.stderr == ""
    assert "plugged" in {e["name"] for e in json.loads(result.stdout)["engines"]}
    install_plug_in(site, "half_plug", "", "[xcheck.engines]\nmissing its equals sign\n")
    result = _xcheck(site, "list", str(MODELS / "fourbar.toml"))
    assert result.returncode == 0 and "plugged (plugged-kinematic)" in _unwrapped(result.stdout)
    ((name, reason),) = _warned(result.stderr).items()
    assert name.endswith("half_plug-1.0.dist-info") and reason.startswith("its entry_points.txt cannot be read")


def test_worker_processes_do_not_wait_for_a_hanging_plug_in_again(tmp_path):
    """`run --jobs 2`: the parent gave up on the plug-in; its workers are told,
    and do not import it (each import leaves a file)."""
    site = _site(tmp_path, "exit0")
    imports = tmp_path / "imports"
    imports.mkdir()
    counting = f"import os, pathlib, time\npathlib.Path({str(imports)!r}, str(os.getpid())).touch()\ntime.sleep(600)\n"
    install_plug_in(site, "xcheck_plug_counted", counting, "[xcheck.engines]\ncounted = xcheck_plug_counted:X\n")
    result = _xcheck(
        site,
        "run",
        str(MODELS / "fourbar.toml"),
        "--engines",
        "native,formulations",
        "--no-report",
        "--jobs",
        "2",
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert set(_warned(result.stderr)) == {"exit0", "counted"}
    assert len(list(imports.iterdir())) == 1


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_a_real_ctrl_c_while_a_plug_in_hangs_still_stops_xcheck(tmp_path):
    site = _site(tmp_path)
    started = tmp_path / "started"
    hanging = f"import pathlib, time\npathlib.Path({str(started)!r}).touch()\ntime.sleep(600)\n"
    install_plug_in(site, "xcheck_plug_hangs", hanging, "[xcheck.engines]\nhangs = xcheck_plug_hangs:X\n")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), str(ROOT / "src")]),
        _registry.TIMEOUT_ENV: "300",
    }
    run = subprocess.Popen(
        [sys.executable, "-m", "xcheck", "engines"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=ctrl_c_as_at_a_terminal,
    )
    try:
        deadline = time.monotonic() + 60
        while not started.exists() and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert started.exists() and run.poll() is None
        signalled = time.monotonic()
        run.send_signal(signal.SIGINT)
        _, stderr = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert time.monotonic() - signalled < 10
    assert run.returncode == 130 and "Traceback" not in stderr


def test_a_ctrl_c_the_kernel_hands_to_the_plug_ins_thread_still_stops_xcheck_at_once(tmp_path):
    """A process-wide SIGINT may be delivered to any thread; the plug-in's thread
    taking it (here it sends it to itself) must not leave the main thread waiting
    out the import's timeout (300 s) before it stops."""
    site = _site(tmp_path)
    kill = "signal.pthread_kill(threading.get_ident(), signal.SIGINT)"
    body = f"import signal, threading, time\n{kill}\ntime.sleep(600)\n"
    install_plug_in(site, "xcheck_plug_taken", body, "[xcheck.engines]\ntaken = xcheck_plug_taken:X\n")
    start = time.monotonic()
    result = _xcheck(site, "engines", timeout=60.0, **{_registry.TIMEOUT_ENV: "300"})
    assert time.monotonic() - start < 30
    assert result.returncode == 130 and "Traceback" not in result.stderr


def test_naming_a_plug_in_that_could_not_load_says_why(tmp_path):
    site = _site(tmp_path, "exit3")
    result = _xcheck(site, "run", str(MODELS / "fourbar.toml"), "--engines", "exit3", "--no-report")
    assert result.returncode == 2
    (error,) = [line for line in result.stderr.splitlines() if line.startswith("xcheck: error: ")]
    assert error.startswith("xcheck: error: --engines: expected modes or groups among native, ")
    assert error.endswith(", found 'exit3' (a plug-in of that name could not be loaded: its import called sys.exit(3))")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("declared_too", [False, True])
def test_an_entry_points_file_that_is_a_fifo_or_a_giant_does_not_hang(tmp_path, declared_too):
    """A FIFO named entry_points.txt would block the read for ever, a sparse giant
    be read whole: each is named, and the good plug-in still loads (with another
    distribution declaring the group, or with none)."""
    site = _site(tmp_path) if declared_too else tmp_path / "site"
    site.mkdir(exist_ok=True)
    for name in ("fifo", "giant"):
        info = site / f"odd_{name}-1.0.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: odd-{name}\nVersion: 1.0\n", encoding="utf-8")
        if name == "fifo":
            os.mkfifo(info / "entry_points.txt")
        else:
            with open(info / "entry_points.txt", "wb") as giant:
                giant.truncate(2**30)
    result = _xcheck(site, "engines", "--json", timeout=60)
    assert result.returncode == 0, result.stderr
    assert set(_warned(result.stderr)) == {str(site / "odd_fifo-1.0.dist-info"), str(site / "odd_giant-1.0.dist-info")}
    assert ("plugged" in {e["name"] for e in json.loads(result.stdout)["engines"]}) == declared_too
