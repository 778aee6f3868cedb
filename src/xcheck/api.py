"""The Python interface: what the command line does, as functions for scripts and notebooks.

>>> import xcheck
>>> mech = xcheck.load("fourbar")          # a bundled name, or a path to a .toml file
>>> mech.name, mech.drivers
('fourbar', ('crank',))
>>> state = mech.solve(at=45)              # display units of the file: degrees here
>>> frame = state.to_frame()               # one row per sample and point or body, SI
>>> row = frame[(frame.kind == "point") & (frame.name == "C")].iloc[0]
>>> print(f"{row.x_m:.6f} {row.vx_m_s:.6f}")   # m, m/s: xcheck solve fourbar --at 45 prints 737.864 mm
0.737864 -0.219406
>>> sweep = mech.sweep(samples=37)         # the feasible range, as ``xcheck run`` sweeps it
>>> len(sweep.to_frame()) == 37 * (len(mech.mechanism.point_owners) + 3)
True
>>> xcheck.select_modes("formulations")
('native', 'formulation-I', 'formulation-II')

:func:`run` runs the comparison of ``xcheck run`` and returns the whole
:class:`~xcheck.runner.RunResult`: its ``verdict``, and its ``summary`` with one
row per mode (the command line only adds printing, the reports and exit codes).
:func:`simulate` integrates a mechanism's free motion (``xcheck simulate``);
``mech.draw(at=...)`` and ``mech.animate()`` picture it (no engine runs).

Rates: an input given without rates moves as its driver's motion law in the
file says (``motion``, ``rate``, ...: the rule of ``xcheck solve --at`` and of
the sweeps); a driver whose law stands still gives a static position. Give
``rates`` to choose them yourself (then accelerations default to zero).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import arguments, engines
from .catalog import model_path, models_dir
from .errors import InputError
from .kinematics import Kinematics, Solution, Status
from .model import Mechanism, load_mechanism
from .motion import drive_warnings
from .states import drawn_state, limit_warnings, solve_asked, states_asked
from .textbook import check_printed, comparisons_of

if TYPE_CHECKING:
    import pandas as pd  # imported where used: `xcheck solve` need not pay for it
    from matplotlib.figure import Figure

    from .runner import RunResult

__all__ = [
    "Assembled",
    "Result",
    "load",
    "select_modes",
    "printed_answers",
    "run",
    "simulate",
]


@dataclass
class Result:
    """Positions, velocities and accelerations of a mechanism at N states.

    Attributes
    ----------
    solution : Solution
        The native solver's arrays (SI; see :class:`xcheck.kinematics.Solution`).
    labels : list of str
        A label per state.
    warnings : list of str
        What to beware of (:func:`xcheck.states.solve_asked`; of a sweep, also
        the states that did not solve), each also issued with
        :func:`warnings.warn` when the result is made.
    """

    solution: Solution
    labels: list[str]
    warnings: list[str] = field(default_factory=list)

    @property
    def mechanism(self) -> Mechanism:
        return self.solution.mechanism

    def to_frame(self) -> pd.DataFrame:
        """A tidy table: one row per state and named point or moving body, SI units.

        Columns: ``sample``, ``label``, per driver its value and rate
        (``crank_rad``, ``crank_rate_rad_s``; a slide's in ``_m``, ``_rate_m_s``),
        ``kind`` ("point" or "body"), ``name``, ``body`` (the point's body),
        ``x_m``, ``y_m``, ``vx_m_s``, ``vy_m_s``, ``ax_m_s2``, ``ay_m_s2``
        (a body's: its frame origin), ``angle_rad``, ``omega_rad_s``,
        ``alpha_rad_s2`` (bodies only; NaN for points), ``status``.
        Rows of states that did not solve hold NaN; ``status`` says why.
        """
        import pandas as pd

        sol, mech = self.solution, self.mechanism
        n = len(sol.status)
        common: dict[str, object] = {"sample": np.arange(n), "label": list(self.labels)}
        for k, driver in enumerate(mech.drivers):
            unit = "rad" if driver.quantity == "angle" else "m"
            common[f"{driver.name}_{unit}"] = sol.inputs[:, k]
            common[f"{driver.name}_rate_{unit}_s"] = sol.input_rates[:, k]
        status = [Status(int(c)).label for c in sol.status]
        parts = []
        nan = np.full(n, np.nan)
        for label, owner in mech.point_owners.items():
            p = sol.point(label, owner)
            parts.append(
                pd.DataFrame(
                    {
                        **common,
                        "kind": "point",
                        "name": label,
                        "body": owner,
                        "x_m": p["position"][:, 0],
                        "y_m": p["position"][:, 1],
                        "vx_m_s": p["velocity"][:, 0],
                        "vy_m_s": p["velocity"][:, 1],
                        "ax_m_s2": p["acceleration"][:, 0],
                        "ay_m_s2": p["acceleration"][:, 1],
                        "angle_rad": nan,
                        "omega_rad_s": nan,
                        "alpha_rad_s2": nan,
                        "status": status,
                    }
                )
            )
        for body in mech.moving_bodies:
            b = sol.body(body.name)
            parts.append(
                pd.DataFrame(
                    {
                        **common,
                        "kind": "body",
                        "name": body.name,
                        "body": body.name,
                        "x_m": b["position"][:, 0],
                        "y_m": b["position"][:, 1],
                        "vx_m_s": b["velocity"][:, 0],
                        "vy_m_s": b["velocity"][:, 1],
                        "ax_m_s2": b["acceleration"][:, 0],
                        "ay_m_s2": b["acceleration"][:, 1],
                        "angle_rad": b["angle"],
                        "omega_rad_s": b["omega"],
                        "alpha_rad_s2": b["alpha"],
                        "status": status,
                    }
                )
            )
        return pd.concat(parts, ignore_index=True).sort_values(["sample", "kind"], kind="stable", ignore_index=True)

    def plot(self, point: str | None = None, body: str | None = None) -> "Figure":
        """A figure of a point's x, speed, acceleration magnitude and a body's angle, omega, alpha
        against the input that varies (display units of the file).

        Parameters
        ----------
        point, body : str, optional
            Default: the fastest moving named point and the body with the
            largest range of angular velocity that no driver turns directly.
        """
        from matplotlib.figure import Figure

        sol, mech, units = self.solution, self.mechanism, self.mechanism.units
        point = _fastest_point(sol) if point is None else arguments.text(point, "point", list(mech.point_owners))
        body = _output_body(sol) if body is None else arguments.text(body, "body", [b.name for b in mech.moving_bodies])
        k = int(np.argmax(np.ptp(sol.inputs, axis=0))) if len(sol.status) > 1 else 0
        driver = mech.drivers[k]
        factor = units.angle_factor if driver.quantity == "angle" else units.length_factor
        x = sol.inputs[:, k] / factor
        xlabel = f"{driver.name} [{units.angle if driver.quantity == 'angle' else units.length}]"
        p, b = sol.point(point), sol.body(body)
        panels = [
            (p["position"][:, 0] / units.length_factor, f"x of {point} [{units.length}]"),
            (np.linalg.norm(p["velocity"], axis=1) / units.velocity_factor, f"|v| of {point} [{units.velocity}]"),
            (
                np.linalg.norm(p["acceleration"], axis=1) / units.acceleration_factor,
                f"|a| of {point} [{units.acceleration}]",
            ),
            (b["angle"] / units.angle_factor, f"angle of {body} [{units.angle}]"),
            (b["omega"] / units.angular_rate_factor, f"ω of {body} [{units.angular_rate}]"),
            (b["alpha"] / units.angular_acceleration_factor, f"α of {body} [{units.angular_acceleration}]"),
        ]
        figure = Figure(figsize=(12, 6.5))
        axes = figure.subplots(2, 3)
        style = {"marker": "o", "ms": 3} if len(x) < 30 else {}
        for ax, (values, label) in zip(axes.flat, panels):
            ax.plot(x, values, color="black", lw=1.4, **style)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
        figure.suptitle(f"{mech.name}: native solution ({len(x)} states)", fontsize=10)
        figure.tight_layout()
        return figure

    def draw(self, i: int = 0) -> "Figure":
        """The mechanism at state ``i`` (:func:`xcheck.drawing.figure_of`)."""
        from .drawing import figure_of

        return figure_of(self.solution, arguments.whole_number(i, "i", 0, len(self.labels) - 1))


def _fastest_point(sol: Solution) -> str:
    """The named moving point with the largest speed over the states."""
    mech = sol.mechanism
    speeds = {
        label: np.nanmax(np.linalg.norm(sol.point(label)["velocity"], axis=1), initial=0.0)
        for label in mech.point_owners
        if label not in mech.ground.points
    }
    return max(speeds, key=lambda label: speeds[label])


def _output_body(sol: Solution) -> str:
    """The body with the largest range of angular velocity that no driver turns directly."""
    mech = sol.mechanism
    driven = {mech.joint(d.joint).body_b for d in mech.drivers}
    spans = {b.name: float(np.nan_to_num(np.ptp(sol.body(b.name)["omega"]))) for b in mech.moving_bodies}
    candidates = {k: v for k, v in spans.items() if k not in driven} or spans
    return max(candidates, key=lambda name: candidates[name])


@dataclass
class Assembled:
    """A mechanism loaded from its file and assembled on a branch (:func:`load`).

    Attributes
    ----------
    kinematics : Kinematics
        The native solver.
    branch : str
        The assembly branch every solve keeps to.
    """

    kinematics: Kinematics
    branch: str

    @property
    def mechanism(self) -> Mechanism:
        return self.kinematics.mechanism

    @property
    def name(self) -> str:
        return self.mechanism.name

    @property
    def drivers(self) -> tuple[str, ...]:
        """The inputs' names, in the order ``at`` and ``rates`` take them."""
        return tuple(d.name for d in self.mechanism.drivers)

    def solve(self, at=None, rates=None, accelerations=None, si: bool = False) -> Result:
        """Positions, velocities and accelerations at given inputs.

        Parameters
        ----------
        at : float or array_like, optional
            The inputs: shape (N,) for N states of a one-input mechanism,
            (k,) for one state of a k-input one, or (N, k); in the file's
            display units (``[units]``: degrees for angles unless it says
            otherwise, its length unit for slides) unless ``si``. Default:
            the file's ``[[instants]]``, with their own rates.
        rates : float or array_like, optional
            The drivers' rates, one state for every input state or one per
            state (``angular_rate`` of ``[units]`` for angles, length unit per
            second for slides). Not
            given: the drivers' motion laws of the file at those inputs (the
            rule of ``xcheck solve --at``; a law that stands still gives a
            static position); an input its law never reaches is an error.
        accelerations : float or array_like, optional
            With ``rates``: the drivers' accelerations (rate unit per second),
            default zero. Without ``rates``: the laws' (and this must be None).
        si : bool
            ``at``, ``rates`` and ``accelerations`` in SI (rad, m, per s) instead.

        Returns
        -------
        Result

        Raises
        ------
        InputError or ModelError
            By the rules of ``xcheck solve`` (:mod:`xcheck.states`): a value of
            the wrong shape or not finite, (rates not given) one the driver's
            motion never reaches, an input outside the feasible range or at a
            limit position, a state that does not assemble with determined
            velocities. A state near a limit or singular position, or a
            driver's law that asks more than its joint can do, is warned about.

        Examples
        --------
        >>> import xcheck
        >>> mech = xcheck.load("fourbar")
        >>> given = mech.solve(at=45, rates=2.0)      # 45 deg at 2 rad/s, accelerating at 0
        >>> declared = mech.solve(at=45)              # the file's crank: 1 rad/s
        >>> float(given.solution.qd[0, 2] / declared.solution.qd[0, 2])
        2.0
        """
        solved = solve_asked(self.kinematics, states_asked(self.kinematics, at, rates, accelerations, si), self.branch)
        for line in solved.warnings:
            warnings.warn(line, stacklevel=2)
        return Result(solved.solution, solved.labels, solved.warnings)

    def sweep(self, samples: int = arguments.DEFAULT_SAMPLES) -> Result:
        """The sweep of ``xcheck run``: the first input over its feasible range
        (one turn of a crank, else the range less 1 % at each limit position),
        other inputs at the file's ``assembly.at``, rates and accelerations
        from the drivers' motion laws (:func:`xcheck.runner.sweep_inputs`).

        >>> import xcheck
        >>> result = xcheck.load("slider-crank").sweep(samples=5)
        >>> [round(float(v), 4) for v in result.solution.inputs[:, 0]]
        [0.0, 1.5708, 3.1416, 4.7124, 6.2832]
        """
        from .runner import sweep_inputs

        samples = arguments.samples(samples, low=2)
        inputs, rates, accelerations = sweep_inputs(self.kinematics, samples, self.branch)
        labels = [f"sample {i}" for i in range(samples)]
        return self._result(inputs, rates, accelerations, labels)

    def _result(self, inputs, rates, accelerations, labels) -> Result:
        sol = self.kinematics.solve(inputs, rates, accelerations, branch=self.branch)
        lines = [*drive_warnings(self.kinematics, self.branch), *limit_warnings(sol, self.branch)]
        for i, code in enumerate(sol.status):
            if code > Status.SINGULAR:
                lines.append(f"{self.name}: {labels[i]}: {Status(int(code)).label} ({Status(int(code)).message})")
        for line in lines:
            warnings.warn(line, stacklevel=3)
        return Result(sol, labels, lines)

    def animate(self, frames: int = 48, interval: float = 80.0):
        """The mechanism moving over its sweep (:meth:`sweep` with ``frames``
        samples) as a :class:`matplotlib.animation.FuncAnimation`: in a notebook
        ``IPython.display.HTML(animation.to_jshtml())``; in a script
        ``animation.save("motion.gif", writer="pillow")``.

        Parameters
        ----------
        frames : int
            Poses, evenly over the sweep.
        interval : float
            Milliseconds per frame.
        """
        from matplotlib.animation import FuncAnimation
        from matplotlib.figure import Figure

        from .drawing import Pose, draw_pose, guide_extents

        frames = arguments.whole_number(frames, "frames", 2, arguments.MAX_SAMPLES)
        interval = arguments.number(interval, "interval", 0.0, unit="ms")
        sol = self.sweep(samples=frames).solution
        good = np.flatnonzero(sol.status <= Status.NEAR_SINGULAR)
        if not good.size:
            raise InputError(f"{self.mechanism.path}: expected a sweep with assembled states to animate, found none")
        scale = self.mechanism.units.length_factor
        extents = guide_extents(sol)
        figure = Figure(figsize=(5.5, 4.5))
        ax = figure.add_subplot()
        # the view of every pose at once, fixed over the frames
        for i in good:
            draw_pose(ax, Pose.of(sol, int(i)), extents, scale=scale, labels=False)
        limits = ax.get_xlim(), ax.get_ylim()

        def pose(n: int):
            ax.clear()
            i = int(good[n])
            rates = {d.name: float(sol.input_rates[i, k]) for k, d in enumerate(self.mechanism.drivers)}
            draw_pose(ax, Pose.of(sol, i), extents, scale=scale, arrows=rates)
            ax.set_xlim(*limits[0])
            ax.set_ylim(*limits[1])
            ax.set_aspect("equal", adjustable="box")
            driver = self.mechanism.drivers[0]
            shown = self.mechanism.units.show_input(driver.quantity, float(sol.inputs[i, 0]), digits=4)
            ax.set_title(f"{self.name}: {driver.name} = {shown}", fontsize=9)
            return []

        return FuncAnimation(figure, pose, frames=len(good), interval=interval)

    def draw(self, at=None, si: bool = False) -> "Figure":
        """A drawing of the mechanism at an input (default: the file's
        ``assembly.at``), with the inputs' arrows; display units unless ``si``.

        >>> import xcheck
        >>> figure = xcheck.load("task-2-1").draw(at=40)
        >>> figure.axes[0].get_title()
        'task-2-1: crank = 40 deg'
        """
        from .drawing import figure_of

        return figure_of(drawn_state(self.kinematics, at, si, self.branch), 0)


def load(name: str | Path, models: str | Path | None = None, branch: str | None = None) -> Assembled:
    """A mechanism, assembled: by name from the models directory (``models``,
    else $XCHECK_MODELS, else ./models, else the bundled ones) or by path.

    Raises
    ------
    XcheckError
        If there is no such mechanism, its file is bad, or it does not assemble;
        the message is one line naming the file and the field.
    """
    directory = models_dir(None if models is None else arguments.path(models, "models"))
    kinematics = Kinematics(load_mechanism(model_path(str(arguments.path(name, "name")), directory)))
    if branch is not None:
        arguments.text(branch, "branch")
    kinematics.assemble(branch)
    return Assembled(kinematics, kinematics._branch_name(branch))


def select_modes(
    chosen: str | Sequence[str] | None = None, kinds: tuple[str, ...] = engines.DRIVEN_KINDS
) -> tuple[str, ...]:
    """The modes a selection names, "native" first.

    Parameters
    ----------
    chosen : str or sequence of str, optional
        Modes or groups (an engine's name such as ``"mujoco"``, or a kind:
        ``"kinematic"``, ``"dynamic"``; :func:`xcheck.engines.groups`), as a
        comma-separated string (``--engines``) or a sequence; ``"all"``: every
        mode; None: every mode but those run only on request
        (:attr:`xcheck.engines.Mode.on_request`: MJX's driven mode), which run
        when named, or their engine is (``"mjx"``), or with ``"all"``, and not
        with a kind (``"dynamic"``).
    kinds : tuple of str
        The kinds of mode to choose from: the driven ones (``xcheck run``,
        default) or ``("free",)`` (``xcheck simulate``).

    Raises
    ------
    InputError
        If a name is neither a mode nor a group, or none is given.
    """
    if not (isinstance(kinds, tuple) and kinds and all(k in engines.KINDS for k in kinds)):
        raise InputError(
            f"kinds: expected a tuple of kinds among {', '.join(engines.KINDS)}, found {arguments.shown(kinds)}"
        )
    every = ("native", *(m.name for m in engines.modes(kinds)))
    groups = engines.groups(kinds)
    if chosen is None:
        from .runner import default_modes

        return default_modes(kinds)
    if isinstance(chosen, str):
        text = chosen
    elif isinstance(chosen, Sequence) and all(isinstance(item, str) for item in chosen):
        text = ",".join(chosen)
    else:
        raise InputError(
            f"engines: expected a comma-separated string or a sequence of mode or group names, "
            f"found {arguments.shown(chosen)}"
        )
    picked: list[str] = []
    for item in (part.strip() for part in text.split(",") if part.strip()):
        if item in every:
            picked.append(item)
        elif item in groups:
            picked.extend(groups[item])
        elif item in {e.name for e in engines.engines()}:  # an engine with no mode of these kinds
            others = ", ".join(f"{m.name} ({m.kind})" for m in engines.engine(item).modes)
            command = "xcheck simulate" if all(m.kind == "free" for m in engines.engine(item).modes) else "xcheck run"
            raise InputError(
                f"--engines: expected an engine with a {' or '.join(kinds)} mode, found {item!r}, whose modes are "
                f"{others}: run them with {command}"
            )
        else:
            broken = engines.load_problems().get(item)
            raise InputError(
                f"--engines: expected modes or groups among {', '.join(every)}, {', '.join(groups)}, found {item!r}"
                + (f" (a plug-in of that name could not be loaded: {broken})" if broken else "")
            )
    if not picked:
        raise InputError(
            f"--engines: expected at least one mode or group among {', '.join(every)}, "
            f"{', '.join(groups)}, found {text!r}"
        )
    return tuple(dict.fromkeys(["native", *picked]))


def printed_answers(kinematics: Kinematics, comparisons: str | Path | None = None) -> tuple[list[dict] | None, str]:
    """The printed answers of a mechanism's comparisons file, checked value by
    value (:func:`xcheck.textbook.check_printed`), and the document they come
    from; (None, "") when the mechanism has no comparisons file.

    Raises
    ------
    XcheckError
        If the comparisons file is bad.
    """
    printed = comparisons_of(kinematics.mechanism, comparisons)
    if printed is None:
        return None, ""
    return check_printed(kinematics, printed), printed.document


def run(
    name: str | Path | Kinematics | Assembled,
    engines: str | Sequence[str] | None = None,
    samples: int = arguments.DEFAULT_SAMPLES,
    branch: str | None = None,
    models: str | Path | None = None,
    comparisons: str | Path | None = None,
    progress=None,
    jobs: int = 1,
    cache: bool = True,
) -> "RunResult":
    """Every requested mode on one mechanism against the exact native solution
    (``xcheck run`` without printing or reports).

    Parameters
    ----------
    name : str, Path, Kinematics or Assembled
        A mechanism name, a file, or a loaded mechanism.
    engines : str or sequence of str, optional
        As :func:`select_modes` (default: every mode but those run only on request).
    samples : int
        Samples of the sweeps over the feasible input range.
    progress : callable, optional
        Called with each mode's name before it runs (with ``jobs`` > 1: as it finishes).
    jobs : int
        Modes run at once, each in a worker process started afresh, where that
        could save time; the results are those of a serial run. A script that
        asks for more than 1 must call this under ``if __name__ == "__main__":``
        (a worker imports the script; notebooks need nothing). Engines
        registered in this session (:func:`xcheck.engines.register`) run here.
    cache : bool
        Take each mode's results from the results cache where this code
        computed them before, and keep what is computed (:mod:`xcheck.result_cache`);
        False computes everything (the results are the same either way).

    Returns
    -------
    RunResult
        ``verdict`` ("pass", "pass with findings" or "fail"), ``summary`` (a
        DataFrame, one row per mode; a notebook shows it as a table) and
        ``outcomes``, each mode's table of differences by category.

    Examples
    --------
    >>> import xcheck
    >>> run = xcheck.run("fourbar", engines="formulations", samples=21)
    >>> run.verdict
    'pass'
    >>> print(run.summary[["mode", "kind", "verdict"]].to_string(index=False))
              mode      kind verdict
            native    native    pass
     formulation-I kinematic    pass
    formulation-II kinematic    pass
    """
    from .runner import run_mechanism

    samples = arguments.samples(samples)
    jobs = arguments.processes(jobs)
    if branch is not None:
        arguments.text(branch, "branch")
    if progress is not None and not callable(progress):
        raise InputError(f"progress: expected a function or None, found {arguments.shown(progress)}")
    if isinstance(name, Assembled):
        kinematics, branch = name.kinematics, branch or name.branch
    elif isinstance(name, Kinematics):
        kinematics = name
    else:
        kinematics = load(name, models, branch).kinematics
    textbook, _ = printed_answers(kinematics, comparisons)
    return run_mechanism(
        kinematics, select_modes(engines), samples, branch, textbook, progress=progress, jobs=jobs, cache=cache
    )


def simulate(
    name: str | Path | Assembled,
    duration: float | None = None,
    branch: str | None = None,
    models: str | Path | None = None,
    check: bool = False,
) -> pd.DataFrame:
    """The native reference of a mechanism's free motion (``[free_motion]`` of
    its file; ``xcheck simulate`` without the engines): one row per output
    time and moving body, SI units.

    Columns: ``time_s``, ``body``, ``x_m``, ``y_m``, ``angle_rad`` (the body
    frame), ``vx_m_s``, ``vy_m_s``, ``omega_rad_s``, ``error_bound_m`` (the
    reference's stated error at that time). ``attrs`` holds ``method``,
    ``converged`` (bool), ``relative_error`` (the stated error per mechanism
    size) and, with ``check``, ``check_agreement_m`` and ``check_consistent``.

    Parameters
    ----------
    duration : float, optional
        Simulated time, s, a whole number of the file's output steps (default: the file's).
    check : bool
        Check the reference by the second native method, as ``xcheck simulate`` does.

    >>> import xcheck
    >>> motion = xcheck.simulate("iftomm-a01", duration=0.05)
    >>> sorted(motion.columns)[:4], bool(motion.attrs["converged"])
    (['angle_rad', 'body', 'error_bound_m', 'omega_rad_s'], True)
    """
    import pandas as pd

    from .dynamics._free import simulate as free_simulate

    loaded = name if isinstance(name, Assembled) else load(name, models, branch)
    mech = loaded.mechanism
    reference = free_simulate(loaded.kinematics, loaded.branch, duration, check=check)
    motion = reference.motion
    index = loaded.kinematics.system.body_index
    parts = []
    for body in mech.moving_bodies:
        k = 3 * index[body.name]
        parts.append(
            pd.DataFrame(
                {
                    "time_s": motion.times,
                    "body": body.name,
                    "x_m": motion.q[:, k],
                    "y_m": motion.q[:, k + 1],
                    "angle_rad": motion.q[:, k + 2],
                    "vx_m_s": motion.qd[:, k],
                    "vy_m_s": motion.qd[:, k + 1],
                    "omega_rad_s": motion.qd[:, k + 2],
                    "error_bound_m": reference.estimate,
                }
            )
        )
    frame = pd.concat(parts, ignore_index=True).sort_values(["time_s"], kind="stable", ignore_index=True)
    frame.attrs = {
        "method": reference.method,
        "converged": bool(reference.converged),
        "relative_error": float(reference.relative),
    }
    if reference.check is not None:
        frame.attrs["check_agreement_m"] = float(reference.check.agreement.max(initial=0.0))
        frame.attrs["check_consistent"] = reference.check.consistent  # None: inconclusive
    return frame
