"""Drake's driven dynamics through SAP's implicit PD controller: the error
against the native solution over PD gains and time steps.

For each model, each stiffness kappa (``Kp = kappa M / dt^2``, M the total mass
times size^2 on a revolute, the total mass on a prismatic driver; ``Kd = Kp dt``
unless ``--critical``: ``Kd = 2 sqrt(Kp M)``) and each of 25, 50, 100 steps per
sample (:data:`xcheck.ladder.DRIVEN_SAMPLES` samples over the simulation
window), one run of :func:`xcheck.engines.drake.dynamic.simulate`, judged by the
driven ladder (:class:`xcheck.ladder.DrivenLadder`): the largest position error
(m, at the inputs Drake realised), the largest input error against the motion
law (the PD's lag; rad or m), the largest relative velocity error, the loops'
largest gap (m) and the position error's order between neighbouring steps.
Prints one table row per run.

Usage::

    python benchmarks/drake_pd_gain.py models/fourbar.toml models/slider-crank.toml \
        [--kappa 1e0 1e2 ...] [--critical]
"""

from __future__ import annotations

import argparse
import math

from xcheck import load_mechanism
from xcheck.engines._contract import with_unit_mass
from xcheck.engines.drake import dynamic
from xcheck.kinematics import Kinematics
from xcheck.ladder import DrivenLadder, Series


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+")
    parser.add_argument("--kappa", nargs="+", type=float, default=[1e0, 1e2, 1e4, 1e6, 1e8, 1e10])
    parser.add_argument("--steps", type=int, default=25, help="steps per sample of the coarsest run")
    parser.add_argument("--rungs", type=int, default=3, help="runs, the steps doubling")
    parser.add_argument("--critical", action="store_true", help="Kd = 2 sqrt(Kp M) instead of Kp dt")
    args = parser.parse_args()
    print("model | kappa | Kp | dt s | position m | order | input lag | velocity rel | loop gap m | cpu s | status")
    for path in args.models:
        kinematics = Kinematics(load_mechanism(path))
        massive = Kinematics(with_unit_mass(kinematics.mechanism))
        for kappa in args.kappa:

            def run_once(_, problem, rung, kappa=kappa):
                pd = dynamic.gains(massive, rung.timestep, kappa)
                if args.critical:
                    unit = dynamic.gains(massive, 1.0, 1.0)
                    pd = {j: (kp, 2.0 * math.sqrt(kp * unit[j][0])) for j, (kp, _) in pd.items()}
                start = problem.start
                per = rung.counts[0]
                return dynamic.simulate(
                    kinematics, massive, problem.window, start.q[0], start.qd[0], per, problem.samples, pd
                )

            def series(problem):
                return (
                    Series("default", dynamic.INTEGRATOR, timestep=problem.interval / args.steps, rungs=args.rungs),
                )

            result = DrivenLadder(dynamic.MODE, kinematics, None, series, run_once).run()
            for row in result.summary.to_dict("records"):
                kp = next(iter(dynamic.gains(massive, row["timestep"], kappa).values()))[0]
                print(
                    f"{kinematics.mechanism.name} | {kappa:.0e} | {kp:.2e} | {row['timestep']:.3e} | "
                    f"{row['position_error']:.3e} | {row['order']:.2f} | {row['input_error']:.3e} | "
                    f"{row['velocity_error']:.3e} | {row['loop_drift']:.2e} | {row['cpu_seconds']:.2f} | "
                    f"{row['status']}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
