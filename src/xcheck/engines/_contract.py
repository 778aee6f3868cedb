"""The engine contract: what every engine gives xcheck, and in which shape.

An engine (a :class:`Engine` subclass, one per subpackage of
:mod:`xcheck.engines`, or one a third party registers) says what it is --
its name, its :class:`Mode` s with their tolerances and expected orders of
convergence, the packages it needs -- and provides its modes through
:meth:`Engine.run`, which returns a :class:`~xcheck.results.ModeResult` for
every engine alike. Importing an engine's description never imports the
package it wraps: :meth:`Engine.available` says whether it can run, and why
not, so a missing package is a reason shown in the report, never an
ImportError that stops the run.

Modes
-----
``kinematic``
    A driven kinematic oracle: the engine's own positions, velocities and
    accelerations at the inputs of a sweep (an exact method must meet
    round-off).
``dynamic``
    Driven dynamics: the engine integrates the mechanism with its inputs
    driven by the motion laws; judged by its convergence to the exact answer
    as the time step falls. Its result carries ``study``
    (:func:`~xcheck.results.convergence_study`) and the compared trajectory
    ``settings["timestep"]`` (s) and ``settings["series"]`` (what makes runs
    of one ladder).
``free``
    Free motion: the engine integrates the mechanism released by its
    ``[free_motion]`` section (no driver) and is compared with the native
    reference (:func:`xcheck.dynamics.simulate`) at the reference's output
    times, through :meth:`Engine.run_free`; its result carries a ladder of
    settings and time steps in ``summary`` (see :meth:`Engine.run_free`) and
    ``study``.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.machinery
import importlib.util
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from xcheck.errors import NotApplicable
from xcheck.ladder import DrivenLadder, DrivenProblem, Finding, FreeProblem, Run, Rung, Series, free_study
from xcheck.tolerances import Tolerance

if TYPE_CHECKING:
    from xcheck.dynamics import Forces
    from xcheck.dynamics._free import FreeReference
    from xcheck.kinematics import Kinematics, Solution
    from xcheck.model import Mechanism
    from xcheck.results import ModeResult

__all__ = [
    "KINDS",
    "DRIVEN_KINDS",
    "Mode",
    "Engine",
    "Finding",
    "NotApplicable",
    "POINT_MASS_INERTIA",
    "positive_inertia",
    "with_unit_mass",
]

#: what a mode does, in the order tables show them
KINDS = ("kinematic", "dynamic", "free")
#: the kinds ``xcheck run`` judges (driven motion); ``free`` modes run in ``xcheck simulate``
DRIVEN_KINDS = ("kinematic", "dynamic")


#: An engine that needs a positive moment of inertia (MuJoCo: above mjMINVAL =
#: 1e-15 kg m^2; pymunk: above 0) gets this fraction of m size^2 for a point mass
#: (inertia 0 in the file): its effect on the motion is below 1e-12 of the size.
POINT_MASS_INERTIA = 1e-12


def positive_inertia(mass: float, inertia: float, size: float, fraction: float = POINT_MASS_INERTIA) -> float:
    """``inertia`` (kg m^2), or for a point mass (0) the least an engine can hold:
    ``fraction`` (default :data:`POINT_MASS_INERTIA`) x mass x size^2."""
    return inertia if inertia > 0.0 else fraction * mass * size * size


def with_unit_mass(mech: Mechanism) -> Mechanism:
    """The mechanism with 1 kg and m size^2 / 12 about its frame origin for each moving
    body without mass data: what a driven mode whose engine needs masses simulates
    (the drivers prescribe the motion, so masses only weigh the solver)."""
    size = mech.size
    bodies = [mech.ground] + [
        b
        if b.mass is not None and b.mass > 0.0 and b.inertia is not None
        else dataclasses.replace(b, mass=1.0, inertia=size * size / 12.0, com=np.zeros(2))
        for b in mech.moving_bodies
    ]
    return dataclasses.replace(mech, bodies=tuple(bodies))


def _installed(name: str) -> bool:
    """Whether the module ``name`` (dotted for a submodule) can be imported, without
    importing it: ``importlib.util.find_spec("mujoco.mjx")`` would import mujoco
    (0.25 s of every ``xcheck list``) to find its submodule."""
    top, *parts = name.split(".")
    spec = importlib.util.find_spec(top)
    for part in parts:
        if spec is None:
            return False
        if spec.submodule_search_locations is None:  # not a package (os.path): ask the import system
            return importlib.util.find_spec(name) is not None
        spec = importlib.machinery.PathFinder.find_spec(part, list(spec.submodule_search_locations))
    return spec is not None


@dataclass(frozen=True)
class Mode:
    """One way an engine is judged.

    Attributes
    ----------
    name : str
        Unique over all engines, e.g. ``"mujoco-kinematic"``.
    kind : str
        One of :data:`KINDS`.
    tolerance : Tolerance
        What the mode must meet per quantity category (NaN: judged by the
        convergence orders below).
    orders : mapping of str to float or None
        ``dynamic`` modes: the expected order of convergence in the time step
        per category (None: judged by the fixed bound of ``tolerance``).
    style : mapping
        Matplotlib line style of the mode in plots.
    on_request : bool
        Run only when asked for by name, by its engine's name (``--engines
        mjx``) or with every mode (``--engines all``): not in the default
        selection, nor in a kind's group (``--engines dynamic``); for a mode
        whose cost alone would exceed what a default run is allowed (MJX's
        driven mode: its JAX compilation). A run of the default selection says
        which were left out, and why (``on_request_reason``).
        See :func:`xcheck.select_modes` and :func:`xcheck.engines.groups`.
    on_request_reason : str
        Why it runs only on request, one line (for the run's "left out" line).
    campaigns : bool
        Run in a fuzz campaign's default selection (:func:`xcheck.fuzz.campaign_modes`);
        False for a mode whose cost on each random mechanism would dominate
        the campaign (MJX's driven mode: a compilation for every mechanism).
    cost : float
        Its CPU seconds on the bundled four-bar, as measured (``xcheck run
        fourbar --json``, its ``timings``; default 1, a typical mode); a free
        mode's per simulated second of the IFToMM pendulum (``xcheck simulate
        iftomm-a01 --json``, its ladder's CPU over the 10 s): used only to
        schedule a run with ``--jobs``, which starts the costliest first, so
        that the longest does not start last, and sends modes to worker
        processes only where they could save time (:func:`xcheck.runner.worth_workers`).
    """

    name: str
    kind: str
    tolerance: Tolerance
    orders: Mapping[str, float | None] = field(default_factory=dict)
    style: Mapping[str, object] = field(default_factory=dict)
    on_request: bool = False
    on_request_reason: str = ""
    campaigns: bool = True
    cost: float = 1.0


class Engine:
    """An engine xcheck judges. Subclasses set the class attributes and
    implement :meth:`run` (and, where the engine has them, :meth:`inverse_dynamics`
    and :meth:`export_files`).

    Attributes
    ----------
    name : str
        Short, lower case: the ``--engines`` group of its modes.
    title : str
        As people write it ("MuJoCo").
    requires : tuple of str
        Import names the engine needs; :meth:`available` checks them.
    distributions : tuple of str
        Its packages' distribution names, whose versions every report states.
    install : str
        What to run when one is missing.
    modes : tuple of Mode
    force_tolerance : float or None
        Bound on its reactions and efforts relative to the native ones (None:
        no inverse dynamics).
    force_basis : str
        Where that bound comes from.
    force_order : float or None
        Where the reactions converge with a time step (pymunk's impulses: 1),
        their order: beyond the bound, the runner halves the step
        (``inverse_dynamics(..., refine=k)``) and judges the error's fall, as
        a dynamic mode's (None: the bound alone).
    export_format, export_directory : str or None
        The file format :meth:`export_files` writes and its folder under ``models/``.
    color : str
        Its colour in plots of forces.
    force_style : mapping
        Matplotlib style of its forces (lines, or markers where they scatter).
    notes : str
        What of the canonical model it can represent and what not, for the reader.
    implementation : str
        The module (imported when a mode runs) whose functions the default
        methods call: ``run_kinematic(kinematics, samples=, branch=)``; the
        dynamic ladder's ``dynamic_series(problem)``, ``prepare_dynamic(problem)``
        and ``run_dynamic_once(prepared, problem, rung)``; the free ladder's
        ``FREE_SERIES``, ``prepare_free(problem)`` and
        ``run_free_once(prepared, problem, rung)``; ``inverse_dynamics`` and
        ``export_files``. An engine may override the methods instead.
    findings : tuple of Finding
        Where the engine is known to be wrong (:class:`xcheck.ladder.Finding`:
        the quantities, the kinds of mode and the mechanisms where it holds,
        with the measured defect): a mode failing only in findings that apply
        still fails them (``passed`` False, the error and the bound shown), but a
        run whose only failures are stated findings exits 0
        (:attr:`xcheck.runner.ModeOutcome.finding`); every ladder row a finding
        applies to carries its title.
    """

    name: ClassVar[str] = ""
    title: ClassVar[str] = ""
    requires: ClassVar[tuple[str, ...]] = ()
    distributions: ClassVar[tuple[str, ...]] = ()
    install: ClassVar[str] = ""
    modes: ClassVar[tuple[Mode, ...]] = ()
    force_tolerance: ClassVar[float | None] = None
    force_basis: ClassVar[str] = ""
    force_order: ClassVar[float | None] = None
    export_format: ClassVar[str | None] = None
    export_directory: ClassVar[str | None] = None
    color: ClassVar[str] = "tab:gray"
    force_style: ClassVar[Mapping[str, object]] = {"lw": 1, "ls": "--"}
    notes: ClassVar[str] = ""
    implementation: ClassVar[str] = ""
    findings: ClassVar[tuple[Finding, ...]] = ()

    def available(self) -> str:
        """Empty if the engine can run here, else the reason (one line)."""
        missing = [package for package in self.requires if not _installed(package)]
        if missing:
            return f"not installed: {', '.join(missing)}" + (f" ({self.install})" if self.install else "")
        return ""

    def run(
        self,
        mode: str,
        kinematics: Kinematics,
        *,
        native: Solution,
        samples: int,
        branch: str | None = None,
    ) -> ModeResult:
        """Run one of the engine's kinematic or dynamic modes on a mechanism.

        A kinematic mode is :attr:`implementation`'s
        ``run_kinematic(kinematics, samples=, branch=)``; a dynamic mode is
        its ladder, :meth:`dynamic_ladder`'s ``run()`` (an engine implements
        :meth:`dynamic_series`, :meth:`prepare_dynamic` and
        :meth:`run_dynamic_once`, not this).

        Parameters
        ----------
        mode : str
            The name of one of :attr:`modes`.
        native : Solution
            The native sweep (inputs, rates, accelerations of ``samples``
            states); a mode may take its inputs or make its own sweep.
        samples : int
            Samples of a kinematic mode's sweep.

        Returns
        -------
        ModeResult
            A failure is ``ok`` False with its reason (one line);
            :class:`NotApplicable` says the mode does not apply.
        """
        kind = self._kind(mode)
        if kind == "kinematic":
            return self._function("run_kinematic")(kinematics, samples=samples, branch=branch)
        if kind == "dynamic":
            return self.dynamic_ladder(mode, kinematics, branch).run()
        raise ValueError(f"expected a kinematic or dynamic mode, found the {kind} mode {mode!r} (see run_free)")

    def _kind(self, mode: str) -> str:
        """The kind of one of the engine's modes."""
        kind = next((m.kind for m in self.modes if m.name == mode), None)
        if kind is None:
            raise ValueError(
                f"expected a mode of {self.name} ({', '.join(m.name for m in self.modes)}), found {mode!r}"
            )
        return kind

    def dynamic_ladder(
        self,
        mode: str,
        kinematics: Kinematics,
        branch: str | None = None,
        *,
        series: Sequence[Series] | None = None,
        duration: float | None = None,
    ) -> DrivenLadder:
        """A dynamic mode's ladder (:class:`xcheck.ladder.DrivenLadder`, the same for
        every engine): its ``run()`` is the mode's result, its ``refine(k)`` the
        ladder with the compared series' finest step halved k times, which the
        runner asks for where an observed order falls short.

        Parameters
        ----------
        series : sequence of Series, optional
            Instead of :meth:`dynamic_series`'s (the compared one first).
        duration : float, optional
            Simulated time, s (default: the drivers' simulation window).

        Raises
        ------
        NotImplementedError
            If the engine has no :meth:`run_dynamic_once` (it runs its own
            ladder in :meth:`run`: the runner cannot refine it).
        """
        self._kind(mode)
        module = importlib.import_module(self.implementation) if self.implementation else None
        if type(self).run_dynamic_once is Engine.run_dynamic_once and not hasattr(module, "run_dynamic_once"):
            raise NotImplementedError(f"{self.title or self.name} has no run_dynamic_once")
        return DrivenLadder(
            mode,
            kinematics,
            branch,
            partial(self.dynamic_series, mode) if series is None else (lambda problem: tuple(series)),
            partial(self.run_dynamic_once, mode),
            partial(self.prepare_dynamic, mode),
            self.findings,
            duration,
        )

    def dynamic_series(self, mode: str, problem: DrivenProblem) -> Sequence[Series]:
        """The series of a dynamic mode's ladder, the compared one first, each with
        its coarsest ``timestep`` and its ``rungs``; by default
        :attr:`implementation`'s ``dynamic_series(problem)``."""
        return tuple(self._function("dynamic_series")(problem))

    def prepare_dynamic(self, mode: str, problem: DrivenProblem) -> Any:
        """What every run of a dynamic ladder shares, built once; by default
        :attr:`implementation`'s ``prepare_dynamic(problem)``, or None where it
        has none.

        Raises
        ------
        NotApplicable
            What the engine cannot represent; any other exception fails the mode
            as a whole, its message the reason.
        """
        function = self._optional_function("prepare_dynamic")
        return None if function is None else function(problem)

    def run_dynamic_once(self, mode: str, prepared: Any, problem: DrivenProblem, rung: Rung) -> Run:
        """One driven run: the series ``rung.series`` at ``rung.timestep`` (s) from
        the native state ``problem.start`` at t = 0, the drivers following their
        laws, sampled at ``problem.times`` (``rung.counts`` steps apart), stopped
        where it goes non-finite or comes apart
        (:meth:`xcheck.ladder.DrivenProblem.came_apart`); by default
        :attr:`implementation`'s ``run_dynamic_once(prepared, problem, rung)``.

        Returns
        -------
        Run
            The states it reached (:class:`xcheck.ladder.Run`): the inputs,
            rates and accelerations as the engine realised them and what it
            gives of the bodies' and points' quantities; or its failure.
        """
        return self._function("run_dynamic_once")(prepared, problem, rung)

    def run_free(
        self,
        mode: str,
        kinematics: Kinematics,
        reference: FreeReference,
        branch: str | None = None,
        *,
        series: Sequence[Series] | None = None,
    ) -> ModeResult:
        """Run a ``free`` mode: the mechanism released as its ``[free_motion]``
        says, from the reference's initial state, compared with the reference.

        The ladder is :func:`xcheck.ladder.free_study`'s, the same for every
        engine: the engine's series (:meth:`free_series`, or ``series``), each
        at its halving time steps, each run made by :meth:`run_free_once` from
        what :meth:`prepare_free` built, and judged by one rule. An engine
        implements those three, not this.

        Returns
        -------
        ModeResult
            See :func:`xcheck.ladder.free_study`.

        Raises
        ------
        NotApplicable
            What the engine cannot represent (from :meth:`prepare_free`).
        """
        return free_study(
            mode,
            kinematics,
            reference,
            self.free_series(mode, kinematics) if series is None else series,
            partial(self.run_free_once, mode),
            partial(self.prepare_free, mode),
            self.findings,
        )

    def free_series(self, mode: str, kinematics: Kinematics) -> Sequence[Series]:
        """The series of a free mode's ladder (:class:`xcheck.ladder.Series`): by
        default :attr:`implementation`'s ``FREE_SERIES``."""
        return tuple(self._function("FREE_SERIES"))

    def prepare_free(self, mode: str, problem: FreeProblem) -> Any:
        """What every run of a free ladder shares, built once (the engine's model
        of the mechanism and its start); by default :attr:`implementation`'s
        ``prepare_free(problem)``, or None where it has none.

        Raises
        ------
        NotApplicable
            What the engine cannot represent; any other exception fails the mode
            as a whole, its message the reason.
        """
        function = self._optional_function("prepare_free")
        return None if function is None else function(problem)

    def run_free_once(self, mode: str, prepared: Any, problem: FreeProblem, rung: Rung) -> Run:
        """One free run: the series ``rung.series`` at ``rung.timestep`` (s), taking
        ``rung.counts`` steps between the compared outputs ``problem.times`` from
        the state ``problem.start``, stopped where it goes non-finite or comes
        apart (:meth:`xcheck.ladder.FreeProblem.came_apart`); by default
        :attr:`implementation`'s ``run_free_once(prepared, problem, rung)``.

        Returns
        -------
        Run
            The states it reached (:class:`xcheck.ladder.Run`), or its failure.
        """
        return self._function("run_free_once")(prepared, problem, rung)

    def inverse_dynamics(self, kinematics: Kinematics, branch: str | None = None, **options) -> Forces:
        """Reactions and driving efforts at the native states of the simulation
        window (:func:`xcheck.dynamics.window_states`); raises on failure."""
        return self._function("inverse_dynamics")(kinematics, branch=branch, **options)

    def export_files(self, kinematics: Kinematics) -> dict[str, str]:
        """The engine's model files of a mechanism: ``{file name: text}``."""
        return self._function("export_files")(kinematics)

    def _optional_function(self, name: str):
        """A function of :attr:`implementation` (imported now), or None where it has none."""
        module = importlib.import_module(self.implementation) if self.implementation else None
        return getattr(module, name, None)

    def _function(self, name: str):
        """A function (or constant) of :attr:`implementation` (imported now)."""
        if not self.implementation:
            raise NotImplementedError(f"{self.title or self.name} has no {name.replace('_', ' ')}")
        return getattr(importlib.import_module(self.implementation), name)
