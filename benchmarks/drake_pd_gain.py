"""Drake's driven dynamics through SAP's implicit PD controller: the error
against the native solution over PD gains and time steps.

For each model, each stiffness kappa (``Kp = kappa M / dt^2``, M the total mass
times size^2 on a revolute, the total mass on a prismatic driver; ``Kd = Kp dt``
unless ``--critical``: ``Kd = 2 sqrt(Kp M)``) and each of 25, 50, 100 steps per
sample (:data:`xcheck.engines.drake.dynamic.SAMPLES` samples over the
simulation window), one run of :func:`xcheck.engines.drake.dynamic.simulate`,
judged by :func:`xcheck.engines._driven.driven_result`: the largest position
error (m, at the inputs Drake realised), the largest input error against the
motion law (the PD's lag; rad or m), the largest relative velocity error, the
loops' largest gap (m) and the position error's order between neighbouring
steps. Prints one table row per run.

Usage::

    python benchmarks/drake_pd_gain.py models/fourbar.toml models/slider-crank.toml \
        [--kappa 1e0 1e2 ...] [--critical]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from xcheck import load_mechanism
from xcheck.engines._contract import with_unit_mass
from xcheck.engines._driven import driven_result
from xcheck.engines.drake import dynamic
from xcheck.kinematics import Kinematics
from xcheck.motion import simulation_window


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="+")
    parser.add_argument("--kappa", nargs="+", type=float, default=[1e0, 1e2, 1e4, 1e6, 1e8, 1e10])
    parser.add_argument("--steps", nargs="+", type=int, default=[25, 50, 100])
    parser.add_argument("--critical", action="store_true", help="Kd = 2 sqrt(Kp M) instead of Kp dt")
    args = parser.parse_args()
    print("model | kappa | Kp | dt s | position m | order | input lag | velocity rel | loop gap m | cpu s | status")
    for path in args.models:
        kinematics = Kinematics(load_mechanism(path))
        massive = Kinematics(with_unit_mass(kinematics.mechanism))
        window = simulation_window(kinematics)
        q, qd, qdd = window.inputs(kinematics, np.zeros(1))
        start = kinematics.solve(q, qd, qdd)
        for kappa in args.kappa:
            runs = []
            for per in args.steps:
                dt = window.duration / (dynamic.SAMPLES * per)
                pd = dynamic.gains(massive, dt, kappa)
                if args.critical:
                    unit = dynamic.gains(massive, 1.0, 1.0)
                    pd = {j: (kp, 2.0 * math.sqrt(kp * unit[j][0])) for j, (kp, _) in pd.items()}
                runs.append(dynamic.simulate(kinematics, massive, window, start.q[0], start.qd[0], per, pd))
            result = driven_result(dynamic.MODE, kinematics, runs, dynamic.ERRORS)
            previous = math.nan
            for row in result.summary.to_dict("records"):
                error = row.get("position_error", math.nan)
                order = math.log(previous / error) / math.log(2.0) if previous > 0.0 and error > 0.0 else math.nan
                previous = error
                kp = next(iter(dynamic.gains(massive, row["timestep"], kappa).values()))[0]
                lag, velocity = row.get("input_error", math.nan), row.get("velocity_error", math.nan)
                print(
                    f"{kinematics.mechanism.name} | {kappa:.0e} | {kp:.2e} | {row['timestep']:.3e} | {error:.3e} | "
                    f"{order:.2f} | {lag:.3e} | {velocity:.3e} | {row.get('loop_gap', math.nan):.2e} | "
                    f"{row['cpu_seconds']:.2f} | {row['status']}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
