"""The compiled free-motion integrator against the NumPy one it mirrors.

Both run the same steps (RK4, Gauss's principle, projection after every
step); they differ only in how the linear algebra is done (Cholesky and an
SVD below the least-squares threshold against LAPACK's LU and gelsd), so
they agree to round-off amplified by the conditioning of J M^-1 J^T.
Measured (2026-11-25), largest |difference| / largest |value| over the
cases below: 3.1e-13 (q), 3.7e-13 (qd; both on Andrews' squeezer, whose
angle turns several times at 2e5 rad/s^2), 1.2e-11 (qdd, at the double
four-bar's singular pass), 1.3e-13 (energy), 3e-16 (work); the bounds
leave a factor of about 8. The chain of seven windows (the banded path)
agrees as closely except at the output that lands on the step closest to its
singular pass (0.72 s), where the velocity and the acceleration differ by
1.3e-10 and 9.7e-8 of their largest: round-off of order eps over the
squared singularity measure, which the two dense paths (compiled and NumPy,
before the banded one) show as well there (1.0e-9 m/s, 5.0e-6 m/s^2); the next
outputs agree to 1e-14 again. Its bounds for those two leave a factor of 8.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from xcheck.dynamics._free import _Dynamics, release_state, simulate_free
from xcheck.kinematics import Kinematics
from xcheck.model import load_mechanism

ROOT = Path(__file__).resolve().parent.parent

CASES = {
    # every term and load: slot (point on a line), prismatic on a moving body (line
    # + angle), springs to the ground and between bodies, dampers, forces, torques,
    # offset centres of mass, gravity
    "free-mixed": (ROOT / "tests/data/free-mixed.toml", 0.5, 0.01, 5e-4),
    # through the first singular (all-horizontal) pass at 0.714 s
    "iftomm-a02": (ROOT / "models/benchmarks/iftomm-a02.toml", 1.0, 0.01, 2.5e-3),
    # 15 bars, 44 rows: the banded path (J M^-1 J^T along the chain), through the
    # first all-horizontal pass, where all seven windows lose rank together
    "fourbar-chain-7": (ROOT / "tests/data/fourbar-chain-7.toml", 1.0, 0.01, 2.5e-3),
    # seven bodies, a stiff spring, 2000 rad/s^2 and more
    "iftomm-a03": (ROOT / "models/benchmarks/iftomm-a03.toml", 0.01, 1e-3, 1e-4),
    # two gear pairs on a moving arm: rows of three bodies' angles
    "planetary-train": (ROOT / "tests/data/planetary-train.toml", 0.5, 0.05, 1e-3),
}
BOUNDS = {"q": 3e-12, "qd": 3e-12, "qdd": 1e-10, "energy": 1e-12, "work": 1e-12}
#: per case, where an output lands on a singular pass (see the module's docstring)
WIDER = {"fourbar-chain-7": {"qd": 1e-9, "qdd": 8e-7}}


@pytest.mark.parametrize("name", sorted(CASES))
def test_compiled_integrator_matches_the_numpy_one(name):
    path, duration, output_step, step = CASES[name]
    kin = Kinematics(load_mechanism(path))
    assert _Dynamics(kin).banded == (name == "fourbar-chain-7")
    start = release_state(kin)
    compiled = simulate_free(kin, start, duration, output_step, step)
    reference = simulate_free(kin, start, duration, output_step, step, compiled=False)
    assert np.array_equal(compiled.times, reference.times)
    for field, bound in (BOUNDS | WIDER.get(name, {})).items():
        ours, theirs = getattr(compiled, field), getattr(reference, field)
        scale = max(float(np.abs(theirs).max()), 1e-300)
        assert float(np.abs(ours - theirs).max()) <= bound * scale, field
    # loops closed alike (both well below a micrometre), passes found at the same steps
    assert compiled.residual.max() <= 10.0 * reference.residual.max() + 1e-15
    assert compiled.singular_passes == reference.singular_passes
    if name in ("iftomm-a02", "fourbar-chain-7"):
        assert len(compiled.singular_passes) == 1


@pytest.mark.parametrize("compiled", [True, False])
def test_integrator_reports_a_blow_up_as_the_runs_result(compiled):
    """A state that goes non-finite ends the run with its time, the outputs before it kept,
    never NaNs passed on (both integrators): from a non-finite start, at once; from a
    speed no step can follow (1e150 m/s), at the first output."""
    kin = Kinematics(load_mechanism(CASES["iftomm-a02"][0]))
    start = release_state(kin)
    bad = type(start)(start.q, np.full_like(start.qd, np.inf))
    motion = simulate_free(kin, bad, 0.1, 0.01, 2.5e-3, compiled=compiled)
    assert motion.failure == "the state went non-finite at t = 0 s"
    assert len(motion.times) == len(motion.q) == len(motion.energy) == 0
    fast = type(start)(start.q, start.qd * 1e150)
    motion = simulate_free(kin, fast, 0.1, 0.01, 2.5e-3, compiled=compiled)
    assert motion.failure.startswith("the state went non-finite at t = ")
    assert len(motion.times) >= 1 and np.all(np.isfinite(motion.q)) and np.all(np.isfinite(motion.qd))
