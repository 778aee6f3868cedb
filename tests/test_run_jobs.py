"""`xcheck run --jobs N`: mechanisms (`run all`), or one mechanism's modes and
figures, in worker processes give the results and the report bytes of a serial
run (issue 17)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
from pathlib import Path

import pytest
from conftest import MODELS, ctrl_c_as_at_a_terminal, invoke

SMALL = ("fourbar", "slider-crank", "two-body-arm")


def _run(name: str, models, engines: str, out, jobs: str) -> tuple[list | dict, dict]:
    """``xcheck run NAME`` with --json and --report, every result computed (the
    results cache off, as the tests run): its JSON without the timings, and every
    file it wrote (the --out folder in the Markdown named OUT)."""
    done = invoke(
        "run",
        name,
        "--models",
        str(models),
        "--engines",
        engines,
        "--samples",
        "21",
        "--out",
        str(out),
        "--json",
        "--report",
        "--jobs",
        jobs,
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode in (0, 1), done.stderr
    documents = json.loads(done.stdout)
    for document in documents if isinstance(documents, list) else [documents]:
        assert document["cache"] == {"from_cache": {}, "recomputed": {}}, document["cache"]
        del document["timings"]
    files = {}
    for path in sorted(p for p in out.rglob("*") if p.is_file()):
        data = path.read_bytes()
        if path.suffix in (".md", ".json"):  # the reports and the index name the run's --out
            data = data.replace(str(out).encode(), b"OUT")
        files[str(path.relative_to(out))] = data
    return documents, files


def _run_all(models, out, jobs: str) -> tuple[list, dict]:
    documents, files = _run("all", models, "formulations,mujoco-kinematic", out, jobs)
    assert isinstance(documents, list)
    return documents, files


@pytest.mark.slow
def test_parallel_run_all_equals_the_serial_run(tmp_path):
    models = tmp_path / "models"
    models.mkdir()
    for name in SMALL:
        shutil.copy(MODELS / f"{name}.toml", models)
    serial_json, serial_files = _run_all(models, tmp_path / "serial", "1")
    parallel_json, parallel_files = _run_all(models, tmp_path / "parallel", "3")
    assert [d["mechanism"] for d in serial_json] == list(SMALL)
    assert parallel_json == serial_json
    assert {f"{name}.md" for name in SMALL} | {f"{name}/drawing.png" for name in SMALL} <= set(serial_files)
    assert parallel_files.keys() == serial_files.keys()
    for relative, data in serial_files.items():
        assert parallel_files[relative] == data, f"{relative} differs between the serial and the parallel run"


def test_a_bad_file_among_parallel_runs_is_one_line_and_the_others_run(tmp_path):
    models = tmp_path / "models"
    models.mkdir()
    shutil.copy(MODELS / "slider-crank.toml", models)
    (models / "broken.toml").write_text("[mechanism\n", encoding="utf-8")
    done = invoke(
        "run", "all", "--models", str(models), "--engines", "formulations", "--samples", "11", "--json", "--jobs", "2"
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "broken.toml" in done.stderr
    assert [d["mechanism"] for d in json.loads(done.stdout)] == ["slider-crank"]


def test_jobs_out_of_range_is_refused():
    done = invoke("run", "all", "--jobs", "0")
    assert (
        done.returncode == 2
        and done.stderr.strip() == "xcheck: error: --jobs: expected a whole number from 1 to 256, found 0"
    )


def _run_one(out, jobs: str) -> tuple[dict, dict]:
    """fourbar with modes whose summed cost is worth a pool (PARALLEL_SAVING)."""
    document, files = _run("fourbar", MODELS, "formulations,mujoco,pinocchio-dynamic,pymunk-dynamic", out, jobs)
    assert isinstance(document, dict) and document["verdict"] == "pass"
    return document, files


@pytest.mark.slow
def test_a_mechanisms_modes_in_worker_processes_equal_the_serial_run(tmp_path):
    from xcheck import engines
    from xcheck.runner import PARALLEL_SAVING

    costs = [engines.mode(m).cost for m in ("formulation-I", "formulation-II", "mujoco-kinematic", "mujoco-dynamic")]
    costs += [engines.mode("pinocchio-dynamic").cost, engines.mode("pymunk-dynamic").cost]
    assert sum(costs) - max(costs) > PARALLEL_SAVING  # so that --jobs 2 does use workers
    serial_json, serial_files = _run_one(tmp_path / "serial", "1")
    parallel_json, parallel_files = _run_one(tmp_path / "parallel", "2")
    assert list(parallel_json["engines"]) == list(serial_json["engines"])  # the order asked for
    assert parallel_json == serial_json
    # the parallel run's figures were drawn by two workers (report._WORKER_SHARES)
    assert parallel_files.keys() == serial_files.keys() and {"fourbar.md", "fourbar/motion.gif"} <= set(serial_files)
    for relative, data in serial_files.items():
        assert parallel_files[relative] == data, f"{relative} differs between the serial and the parallel run"


_TWIN_PLUG_IN = """
import dataclasses
import multiprocessing
import os
from xcheck import engines


class Twin(engines.Engine):
    name = "twin"
    modes = tuple(
        dataclasses.replace(engines.mode("formulation-I"), name=f"twin-{k}", cost=5.0) for k in (1, 2)
    )
    force_tolerance = 1e-9

    def inverse_dynamics(self, kinematics, branch=None, **options):
        from xcheck.dynamics import newton_euler, window_states

        with open(os.environ["TWIN_LOG"], "a") as log:  # which process computes the reactions
            log.write("worker\\n" if multiprocessing.parent_process() else "command\\n")
        return newton_euler(window_states(kinematics, branch))

    def run(self, mode, kinematics, *, native, samples, branch=None):
        if os.environ.get("TWIN_CRASH") == mode:  # a crash of the engine's library
            os._exit(1)
        result = engines.engine("formulations").run(
            "formulation-I", kinematics, native=native, samples=samples, branch=branch
        )
        return dataclasses.replace(result, mode=mode)
"""


def test_the_commands_forked_workers_give_the_serial_run(tmp_path):
    """The ``xcheck`` command forks its workers from itself (a program calling the
    API spawns them): its JSON with two workers equals its serial run's but for the
    timings. Two modes of an installed plug-in, each formulation I's solution and
    declared costly, so that the run sends them to workers; its reactions (the native
    per-body form's) are computed by the worker that runs its costlier mode, not by the
    command, with two workers. Where that mode crashes its worker, the reactions after it
    fail with the mode's reason and the other mode still counts."""
    import subprocess

    from conftest import ROOT, install_plug_in

    site = tmp_path / "site"
    site.mkdir()
    install_plug_in(site, "xcheck_twin_test", _TWIN_PLUG_IN, "[xcheck.engines]\ntwin = xcheck_twin_test:Twin\n")
    log = tmp_path / "reactions.log"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT / "src")]), "TWIN_LOG": str(log)}
    command = [sys.executable, "-m", "xcheck", "run", "slider-crank", "--models", str(MODELS), "--engines"]
    command += ["twin", "--samples", "11", "--json"]
    documents, computed_by = [], []
    for jobs in ("2", "1"):
        done = subprocess.run([*command, "--jobs", jobs], capture_output=True, text=True, timeout=300, env=env)
        assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
        document = json.loads(done.stdout)
        del document["timings"]
        documents.append(document)
        computed_by.append(log.read_text().split())
        log.unlink()
    assert list(documents[0]["engines"]) == ["native", "twin-1", "twin-2"]
    assert documents[0]["forces"]["twin"]["pass"] is True
    assert documents[0] == documents[1]
    assert computed_by == [["worker"], ["command"]]
    done = subprocess.run(
        [*command, "--jobs", "2"], capture_output=True, text=True, timeout=300, env={**env, "TWIN_CRASH": "twin-1"}
    )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    document = json.loads(done.stdout)
    crashed, forces = document["engines"]["twin-1"], document["forces"]["twin"]
    assert crashed["verdict"] == forces["verdict"] == "failed" and "worker process died" in forces["reason"]
    assert forces["reason"] == crashed["reason"] and document["engines"]["twin-2"]["verdict"] == "pass"


def test_a_script_without_a_main_guard_gets_the_reason_not_a_hang(tmp_path):
    """A spawned worker imports the script that started it: unguarded, the script
    starts workers again, which multiprocessing refuses; the modes fail with a
    reason that says what to do, and the script ends."""
    import subprocess

    from xcheck._parallel import WORKER_DIED

    script = tmp_path / "unguarded.py"
    script.write_text(
        "from xcheck import api\n"
        f"run = api.run('fourbar', engines='mujoco,pinocchio-dynamic,pymunk-dynamic', samples=21, "
        f"models={str(MODELS)!r}, jobs=2)\n"
        "print(sorted({o.reason for m, o in run.outcomes.items() if m != 'native'}))\n",
        encoding="utf-8",
    )
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == repr([WORKER_DIED])


def test_a_dead_worker_of_run_all_is_one_line_per_mechanism_not_a_traceback(tmp_path):
    """`run all --jobs 2` from a script without a main guard: every worker dies
    at its start; each mechanism is one failure line naming it, the exit code is
    2, and no traceback comes from the run itself (the workers' own start-up
    errors are multiprocessing's)."""
    import subprocess

    from xcheck._parallel import WORKER_DIED

    models = tmp_path / "models"
    models.mkdir()
    for name in ("slider-crank", "two-body-arm"):
        shutil.copy(MODELS / f"{name}.toml", models)
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import sys\n"
        "from xcheck.cli import main\n"
        f"sys.argv = ['xcheck', 'run', 'all', '--models', {str(models)!r}, '--engines', 'formulations', "
        "'--json', '--no-report', '--jobs', '2']\n"
        "main()\n",
        encoding="utf-8",
    )
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    ours = [line for line in done.stderr.splitlines() if line.startswith("xcheck: error: ")]
    assert ours == [
        f"xcheck: error: {name}: expected its run back from a worker process, found that {WORKER_DIED}"
        for name in ("slider-crank", "two-body-arm")
    ]
    assert "BrokenProcessPool" not in done.stderr
    assert json.loads(done.stdout) == []


def _alive(pid: int | str) -> bool:
    """Whether a process runs (from /proc; a zombie has exited)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
def test_a_worker_ends_with_its_killed_parent(tmp_path):
    """A run killed outright (SIGKILL: no clean-up of any kind) leaves no worker
    behind: each one, busy or idle, sees its parent go and exits within seconds
    (it waited forever before, a Python process with NumPy and xcheck loaded,
    after every killed `xcheck run` that used workers)."""
    import subprocess
    import sys
    import time

    script = tmp_path / "busy.py"
    script.write_text(
        "import time\n"
        "from xcheck._parallel import process_pool\n"
        "if __name__ == '__main__':\n"
        "    pool = process_pool(2)\n"
        "    busy = pool.submit(time.sleep, 300)\n"
        "    idle = pool.submit(abs, -1)\n"
        "    print(idle.result(), *pool._processes, flush=True)\n"
        "    time.sleep(300)\n",
        encoding="utf-8",
    )
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    assert parent.stdout is not None
    first, *workers = parent.stdout.readline().split()
    assert first == "1" and len(workers) == 2

    assert all(_alive(pid) for pid in workers)
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=30)
    parent.stdout.close()
    deadline = time.monotonic() + 20
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [pid for pid in workers if _alive(pid)]
    for pid in left:  # do not leave them to the next test either
        os.kill(int(pid), signal.SIGKILL)
    assert left == [], "workers outlived their killed parent"


_SLOW_PLUG_IN = """
import os, pathlib, time
from xcheck import engines
from xcheck.tolerances import Tolerance


class Slow(engines.Engine):
    name = "slow"
    modes = tuple(
        engines.Mode(f"slow-{k}", "kinematic", Tolerance(1, 1, 1, 1, "anything"), cost=5.0) for k in (1, 2)
    )

    def run(self, mode, kinematics, *, native, samples, branch=None):
        (pathlib.Path(os.environ["SLOW_STARTED"]) / f"{os.getpid()}-{os.getppid()}").touch()
        time.sleep(120)
        raise RuntimeError("still running after 120 s")
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
def test_ctrl_c_during_a_parallel_run_ends_it_without_a_traceback(tmp_path):
    """Ctrl-C reaches the whole foreground process group, the workers too: the
    run ends at once with a failing exit code, no traceback from it or its
    workers, and no worker left behind.

    Two modes of an installed plug-in (an entry point in a ``.dist-info``
    folder on the path, which the workers find too) sleep for two minutes,
    each in its worker, after leaving a file named by the worker's pid and its
    parent's: the signal comes only once both are inside their modes, and the
    run cannot have ended before it. (A worker still starting when the signal
    comes ends by the signal's default action, which the pool's initializer
    sets; that moment cannot be timed from here, and this test would pass
    without it.) The command's workers are forked from the command itself, which
    has loaded no engine.
    """
    import subprocess
    import time

    site, started = tmp_path / "site", tmp_path / "started"
    site.mkdir()
    started.mkdir()
    from conftest import ROOT, install_plug_in

    install_plug_in(site, "xcheck_slow_test", _SLOW_PLUG_IN, "[xcheck.engines]\nslow = xcheck_slow_test:Slow\n")

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT / "src")]), "SLOW_STARTED": str(started)}
    command = [sys.executable, "-m", "xcheck", "run", "fourbar", "--models", str(MODELS)]
    command += ["--engines", "slow-1,slow-2", "--samples", "21", "--no-report", "--jobs", "2"]
    run = subprocess.Popen(
        command, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,  # its own process group, as a shell gives a foreground job
        preexec_fn=ctrl_c_as_at_a_terminal,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 300
        while len(list(started.iterdir())) < 2 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        workers, parents = zip(*(map(int, p.name.split("-")) for p in started.iterdir()))
        assert len(workers) == 2 and run.poll() is None, "the two slow modes did not start"
        assert parents[0] == parents[1] == run.pid
        signalled = time.monotonic()
        os.killpg(run.pid, signal.SIGINT)
        _, stderr = run.communicate(timeout=60)
    finally:  # a failed wait leaves no sleeping run behind
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.communicate()
    assert time.monotonic() - signalled < 30  # not after the modes' two minutes
    assert run.returncode != 0
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    deadline = time.monotonic() + 20
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [pid for pid in workers if _alive(pid)]
    for pid in left:  # do not leave them to the next test either
        os.kill(pid, signal.SIGKILL)
    assert left == [], "workers outlived Ctrl-C"


def test_free_modes_in_worker_processes_equal_the_serial_run(monkeypatch):
    """`xcheck simulate --jobs`: the free modes in worker processes give the JSON
    of a serial run but for its timings, and the reference's figures, drawn
    while the workers ran the modes, are those of the serial run (the pool
    forced on, whatever the modes cost: PARALLEL_SAVING 0)."""
    from xcheck import load, runner
    from xcheck.output import simulation_json
    from xcheck.report import reference_figures as figures_of
    from xcheck.simulation import simulate_all

    timings = {"seconds", "cpu_seconds", "cpu_per_simulated_second"}

    def without_timings(value):
        if isinstance(value, dict):
            return {k: without_timings(v) for k, v in value.items() if k not in timings}
        if isinstance(value, list):
            return [without_timings(v) for v in value]
        return value

    monkeypatch.setattr(runner, "PARALLEL_SAVING", 0.0)
    kinematics = load(MODELS / "benchmarks" / "iftomm-a01.toml").kinematics
    modes = ["mujoco-free", "pinocchio-free", "pymunk-free"]
    documents, figures = [], []
    for jobs in (1, 2):
        drawn: dict = {}
        result = simulate_all(
            kinematics, modes, duration=0.3, jobs=jobs, meanwhile=lambda r: drawn.update(figures_of(r))
        )
        assert list(result.outcomes) == modes and all(result.outcomes[m].ok for m in modes)
        documents.append(without_timings(simulation_json(result.reference, result)))
        figures.append(drawn)
    assert documents[1] == documents[0]
    assert figures[1] == figures[0] and set(figures[0]) == {"drawing", "energy"}


def test_a_task_that_kills_its_worker_fails_alone():
    """A worker that dies (an engine crashing its process) takes its pool and every
    task in it down; those run again, each in a worker of its own, and only the
    one that kills its process fails."""
    import time

    from xcheck._parallel import WORKER_DIED, collect, process_pool, submit

    calls = {"dies": (os._exit, (3,)), "sleeps": (time.sleep, (1,)), "sums": (sum, ((1, 2),))}
    with process_pool(2) as pool:
        results = collect(submit(pool, calls), lambda key, why: why, None, calls, 2)
    assert results == {"dies": WORKER_DIED, "sleeps": None, "sums": 3}


def test_a_kept_pool_is_handed_out_again_then_shut():
    """Within workers_kept, the pool of a run's modes stays open for its report's
    figures (no second start of workers), a call for more workers gets a pool of
    its own, and every pool is shut at the end; outside, each call gets a new one."""
    from xcheck._parallel import process_pool, workers_kept

    with workers_kept():
        with process_pool(2) as modes:
            pass
        assert not modes.closed
        with process_pool(1) as figures:
            assert figures is modes
        wider = process_pool(3)
        assert wider is not modes and process_pool(2) is wider  # the newest kept pool is handed out
        wider.shutdown()
        assert process_pool(1) is not wider  # a pool shut down is never handed out again
    assert modes.closed and wider.closed
    with process_pool(1) as alone, process_pool(1) as other:
        assert other is not alone
    assert alone.closed and other.closed


def test_the_command_forks_its_workers_from_itself_only_where_that_is_safe(monkeypatch):
    """On Linux the command forks its workers from itself where it has loaded no
    engine and runs no thread but a progress bar's; else from a fork server (an
    engine's library, such as JAX, may hold threads a forked child would inherit)."""
    import threading
    import types

    from xcheck import _parallel, engines

    if not sys.platform.startswith("linux"):
        pytest.skip("the command spawns its workers where it is not on Linux")
    monkeypatch.setattr(_parallel, "_the_command", lambda: True)
    for package in {p for engine in engines.engines() for p in engine.requires}:
        monkeypatch.delitem(sys.modules, package, raising=False)
    main = threading.main_thread()
    progress = threading.Thread(name=_parallel.QUIET_ACROSS_FORKS)
    monkeypatch.setattr(threading, "enumerate", lambda: [main, progress])
    assert _parallel._context(()).get_start_method() == "fork"
    monkeypatch.setattr(threading, "enumerate", lambda: [main, progress, threading.Thread(name="another")])
    assert _parallel._context(()).get_start_method() == "forkserver"
    monkeypatch.setattr(threading, "enumerate", lambda: [main])
    monkeypatch.setitem(sys.modules, "pymunk", types.ModuleType("pymunk"))
    assert _parallel._context(()).get_start_method() == "forkserver"


def test_the_progress_bar_draws_only_while_it_holds_the_lock_each_fork_takes():
    """A worker forked while the progress bar is drawn never starts with the lock of
    stderr taken by the bar's thread, which it does not have: the thread draws only
    while it holds the terminal's lock, which a fork holds across it and which the
    child finds free."""
    import io
    import threading
    import time

    from rich.console import Console

    from xcheck._command_line import _Progress
    from xcheck._parallel import QUIET_ACROSS_FORKS, terminal_lock

    out = io.StringIO()
    with _Progress(console=Console(file=out, force_terminal=True), transient=True) as bar:
        bar.add_task("modes", total=2)
        assert [t for t in threading.enumerate() if t.name == QUIET_ACROSS_FORKS]
        with terminal_lock:
            drawn = out.tell()
            time.sleep(0.3)
            assert out.tell() == drawn
        time.sleep(0.3)
        assert out.tell() > drawn
        child = os.fork()
        if child == 0:  # the child: the lock is free there
            os._exit(0 if terminal_lock.acquire(timeout=5) else 1)
        assert os.waitpid(child, 0)[1] == 0


def test_workers_start_early_only_for_a_kept_pool():
    """Workers started ahead of a run's modes belong to the pool they will serve: outside
    workers_kept there is none, and nothing is started."""
    from xcheck._parallel import start_workers

    with pytest.raises(RuntimeError, match="within workers_kept"):
        start_workers(2)
