"""A toy engine that keeps the engine contract: every mode gives xcheck's own
answer (the native sweep, the native states at the drivers' laws, the free
reference's motion) in the shapes the contract states. Self-contained, so that
its source also serves as a plug-in module (tests/test_check_engine.py)."""

from __future__ import annotations

import numpy as np

from xcheck import engines
from xcheck.ladder import Run, Series
from xcheck.results import ModeResult, trajectory_from_solution
from xcheck.tolerances import Tolerance

TOLERANCE = Tolerance(1e-9, 1e-9, 1e-9, 1e-9, "the toy: xcheck's own answer")


class Toy(engines.Engine):
    """A kinematic, a dynamic and a free mode, each xcheck's own answer."""

    name = "toyc"
    title = "a conforming toy"
    modes = (
        engines.Mode("toyc-kinematic", "kinematic", TOLERANCE),
        engines.Mode("toyc-dynamic", "dynamic", TOLERANCE, orders={"position": 1.0}),
        engines.Mode("toyc-free", "free", TOLERANCE),
    )

    def run(self, mode, kinematics, *, native, samples, branch=None):
        if self._kind(mode) == "kinematic":
            return ModeResult(mode, kinematics.mechanism.name, True, trajectories=[self.sweep(mode, native)])
        return super().run(mode, kinematics, native=native, samples=samples, branch=branch)

    def sweep(self, mode, native):
        """The kinematic mode's trajectory: the native sweep."""
        return trajectory_from_solution(native, source=mode)

    def dynamic_series(self, mode, problem):
        return (Series("exact", "the native states"),)

    def run_dynamic_once(self, mode, prepared, problem, rung):
        times = problem.times
        solution = problem.kinematics.solve(*problem.window.inputs(problem.kinematics, times), branch=problem.branch)
        trajectory = trajectory_from_solution(solution, source=mode)
        trajectory.times, trajectory.settings = times, rung.settings
        trajectory.diagnostics = {"constraint_violation": np.zeros(len(times))}
        return Run(trajectory)

    def free_series(self, mode, kinematics):
        return (Series("exact", "the reference"),)

    def run_free_once(self, mode, prepared, problem, rung):
        index = problem.index
        trajectory = trajectory_from_solution(problem.reference.motion.solution(), source=mode)
        trajectory.times, trajectory.settings = problem.times, rung.settings
        for part in (*trajectory.bodies.values(), *trajectory.points.values()):
            for key in list(part):
                part[key] = part[key][index]
        trajectory.inputs = trajectory.input_rates = trajectory.input_accelerations = np.zeros((len(index), 0))
        trajectory.diagnostics = {"constraint_violation": np.zeros(len(index))}
        return Run(trajectory)
