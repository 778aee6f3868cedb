"""Shared helpers for the tests."""

from __future__ import annotations

import contextlib
import gc
import os
from pathlib import Path

import pytest

#: No cyclic garbage collection while the tests are collected: rewriting the test
#: modules' assertions makes millions of short-lived AST nodes, which start full
#: collections that traverse every object the imports left (numpy, SciPy, pandas,
#: the engines), about a quarter of each xdist worker's collection. The nodes are
#: freed by reference counting alone; collection turns back on when it ends
#: (:func:`pytest_collection`).
gc.disable()

from threadpoolctl import threadpool_limits  # noqa: E402

from xcheck import Kinematics, load_mechanism  # noqa: E402

#: One BLAS thread in every test process and the processes they start: xdist runs a
#: worker per core, and OpenBLAS's own threads on top of them spin against each other
#: (iftomm-a02-n40's MJCF, measured under load: 78 CPU s with two threads a process,
#: 4.1 s with one)
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
_BLAS_LIMITS = threadpool_limits(limits=1, user_api="blas")
#: In an xdist worker each core already runs a worker of the test run: the commands a
#: test runs (here or in a subprocess) default to one process ($XCHECK_JOBS), not to one
#: per core on top, whose start-up alone (the engines' imports) cost about a CPU second
#: a command. A test about worker processes names its --jobs; run serially (-n 0), the
#: tests keep the default of one process per core.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("XCHECK_JOBS", "1")
#: JAX's compiled functions (MJX's rollouts) kept between test runs in this checkout,
#: as numba keeps xcheck's kernels in __pycache__: JAX keys each entry by the graph,
#: the compiler's options and JAX's version, so a change to the code compiles anew,
#: and a run finds what an earlier run compiled instead of compiling it again (about
#: 25 CPU s of the quick selection here). Read by JAX at its import, in this process
#: and in the commands the tests start; a cache the environment already names is kept.
JAX_CACHE = Path(__file__).resolve().parent / ".jax-cache"
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(JAX_CACHE))
os.environ.setdefault("JAX_COMPILATION_CACHE_MAX_SIZE", str(2**28))  # bytes; the least recently used go


@pytest.hookimpl(wrapper=True)
def pytest_collection(session):
    """The collection, then cyclic garbage collection back on (see :func:`gc.disable` above)."""
    try:
        return (yield)
    finally:
        gc.enable()


ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
#: mechanism files written for the tests (each with a header saying what it covers)
DATA = Path(__file__).resolve().parent / "data"
MODEL_NAMES = sorted(p.stem for p in MODELS.glob("*.toml"))


@pytest.fixture(scope="session", autouse=True)
def branch_map_cache(tmp_path_factory):
    """xcheck's cache directory (xcheck.store: the branch maps) of the whole
    test run in a temporary directory, never the user's, and one for all the
    run's xdist workers (each worker's basetemp is a folder of the run's); JAX's
    compiled functions go to :data:`JAX_CACHE` instead. The results cache
    (xcheck.result_cache) is off: every test computes what it checks (the
    cache's own tests turn it on, and :func:`whole_run` shares one comparison
    per mechanism through it). The command lines run here and in subprocesses
    read the environment."""
    from xcheck.result_cache import RESULTS_ENV
    from xcheck.store import CACHE_ENV

    run_root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        run_root = run_root.parent
    directory = run_root / "xcheck-cache"
    directory.mkdir(exist_ok=True)
    previous = {name: os.environ.get(name) for name in (CACHE_ENV, RESULTS_ENV)}
    os.environ[CACHE_ENV] = str(directory)
    os.environ[RESULTS_ENV] = "off"
    yield directory
    for name, value in previous.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value


@pytest.fixture(autouse=True)
def _cache_environment(branch_map_cache):
    """Every test ends with the run's cache environment (:func:`branch_map_cache`)
    as it found it: a test that turned the results cache on, or pointed the cache
    elsewhere, and undid it in the wrong order (a ``monkeypatch`` undone after a
    :func:`results_cache_on` it was set inside) would otherwise leave it so for
    the tests that follow in its worker, which then read results kept by others."""
    from xcheck.result_cache import RESULTS_ENV
    from xcheck.store import CACHE_ENV

    yield
    os.environ[CACHE_ENV] = str(branch_map_cache)
    os.environ[RESULTS_ENV] = "off"


@contextlib.contextmanager
def results_cache_on():
    """The results cache (xcheck.result_cache) on, in the run's cache directory, for
    what runs inside (in this process and the subprocesses it starts)."""
    from xcheck.result_cache import RESULTS_ENV

    previous = os.environ.pop(RESULTS_ENV, None)
    try:
        yield
    finally:
        if previous is not None:
            os.environ[RESULTS_ENV] = previous


#: the samples of a whole comparison shared between tests (:func:`whole_run`)
WHOLE_RUN_SAMPLES = 61


@pytest.fixture(scope="session")
def whole_run(branch_map_cache):
    """The whole comparison of a mechanism file (every mode, those run only on
    request included; :data:`WHOLE_RUN_SAMPLES` samples), computed once for the
    whole test run: the first worker to ask computes it into the run's results
    cache while holding the file's lock, the others wait and read it from there.
    A test that runs the same comparison through the command line with the
    results cache on (:func:`results_cache_on`) reads the same results."""
    import fcntl

    from xcheck.runner import all_modes, run_mechanism

    runs: dict[Path, object] = {}

    def get(path: Path):
        if path not in runs:
            lock = branch_map_cache / f"whole-run-{path.stem}.lock"
            with open(lock, "w") as held, results_cache_on():
                fcntl.flock(held, fcntl.LOCK_EX)
                runs[path] = run_mechanism(Kinematics(load_mechanism(path)), all_modes(), WHOLE_RUN_SAMPLES)
        return runs[path]

    return get


@pytest.fixture(scope="session")
def once_per_run(branch_map_cache):
    """``get(key, make)``: the text ``make()`` returns, computed once for the whole
    test run: the first worker to ask computes it into the run's cache directory
    while holding the key's lock, the others wait and read it from there. For a
    costly text that several tests check in their own ways (an engine file of a
    large mechanism)."""
    import fcntl

    folder = branch_map_cache / "once-per-run"
    folder.mkdir(exist_ok=True)

    def get(key: str, make) -> str:
        path = folder / f"{key}.txt"
        with open(folder / f"{key}.lock", "w") as held:
            fcntl.flock(held, fcntl.LOCK_EX)
            if not path.exists():
                staged = folder / f"{key}.staged"
                staged.write_text(make(), encoding="utf-8")
                staged.replace(path)
            return path.read_text(encoding="utf-8")

    return get


@pytest.fixture(scope="session")
def kinematics():
    """Kinematics of a model in models/ by name, built once per session."""
    cache: dict[str, Kinematics] = {}

    def get(name: str) -> Kinematics:
        if name not in cache:
            cache[name] = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
        return cache[name]

    return get


def ctrl_c_as_at_a_terminal() -> None:
    """A ``preexec_fn`` for a child the test will interrupt: SIGINT's default
    action, as a shell gives a foreground job. A child inherits an ignored
    SIGINT (a test run started in the background by a non-interactive shell),
    and Python then installs no KeyboardInterrupt handler at all."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def invoke(*args: str, cwd: Path = ROOT, unset: tuple[str, ...] = ("XCHECK_MODELS", "XCHECK_COMPARISONS")):
    """Run the command line in this process (typer's CliRunner), from ``cwd``
    and without the environment variables ``unset``, as a
    :class:`subprocess.CompletedProcess` (returncode, stdout, stderr). An
    exception the CLI did not turn into an exit code shows as its traceback
    on stderr, as it would from the shell."""
    import contextlib
    import subprocess
    import traceback

    from typer.testing import CliRunner

    from xcheck.cli import app

    with contextlib.chdir(cwd):
        result = CliRunner().invoke(app, list(args), env=dict.fromkeys(unset))
    stderr = result.stderr
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        stderr += "".join(traceback.format_exception(result.exception))
    return subprocess.CompletedProcess(["xcheck", *args], result.exit_code, result.stdout, stderr)


def run_free(mode: str, kinematics, reference, series=None, timestep=None, rungs=None):
    """A free mode's ladder through its engine (:meth:`xcheck.engines.Engine.run_free`),
    of ``series`` (default: the engine's), each from ``timestep`` (s) over ``rungs`` runs
    where given."""
    import dataclasses

    from xcheck import engines

    engine = engines.engine_of(mode)
    if timestep is not None or rungs is not None:
        change = {k: v for k, v in (("timestep", timestep), ("rungs", rungs)) if v is not None}
        series = [dataclasses.replace(s, **change) for s in (series or engine.free_series(mode, kinematics))]
    return engine.run_free(mode, kinematics, reference, series=series)


def run_dynamic(mode: str, kinematics, branch=None, **options):
    """A dynamic mode's ladder through its engine (:meth:`xcheck.engines.Engine.dynamic_ladder`;
    ``options``: ``series``, ``duration``), run."""
    from xcheck import engines

    return engines.engine_of(mode).dynamic_ladder(mode, kinematics, branch, **options).run()


def assert_first_order(result, finest: float) -> None:
    """A free mode's ladder all ran (status ok) and, per setting, its error at the finest
    step is at most ``finest`` (m) and halves with each halved step (ratios 1.8 to 2.2)."""
    assert result.ok and (result.summary["status"] == "ok").all()
    for _, part in result.summary.groupby("setting"):
        errors = part.sort_values("timestep")["position_error"].to_numpy()
        assert errors[0] <= finest
        assert all(1.8 <= coarse / fine <= 2.2 for fine, coarse in zip(errors[:-1], errors[1:]))


def shifted_sweep(mode: str, kinematics, native, fraction: float):
    """A toy engine's result: the native sweep with every body and point position
    moved by ``fraction`` of the mechanism's size along x (a known error)."""
    import numpy as np

    from xcheck.results import ModeResult, trajectory_from_solution

    trajectory = trajectory_from_solution(native, source=mode)
    shift = np.array([fraction * kinematics.system.size, 0.0])
    for states in (*trajectory.bodies.values(), *trajectory.points.values()):
        states["position"] = states["position"] + shift
    return ModeResult(mode, kinematics.mechanism.name, True, trajectories=[trajectory])


def install_plug_in(site: Path, module: str, source: str, entry_points: str) -> None:
    """A distribution in ``site`` as pip leaves one: ``module``.py with ``source``,
    and its ``.dist-info`` folder (METADATA, and ``entry_points`` as entry_points.txt)."""
    (site / f"{module}.py").write_text(source, encoding="utf-8")
    info = site / f"{module}-1.0.dist-info"
    info.mkdir(parents=True)
    name = module.replace("_", "-")
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(entry_points, encoding="utf-8")


@pytest.fixture(scope="session")
def released_fourbar():
    """tests/data/free-fourbar-released.toml assembled, with its native free reference
    (computed once per session): the engines' free four-bar."""
    from xcheck.dynamics._free import simulate

    kin = Kinematics(load_mechanism(DATA / "free-fourbar-released.toml"))
    kin.assemble()
    return kin, simulate(kin)
