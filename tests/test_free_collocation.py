"""The check of the native free-motion reference, Gauss-Legendre collocation
(xcheck.dynamics._collocation): its tableau, a singular crossing, and a step whose
fixed-point iteration does not settle."""

from __future__ import annotations

import numpy as np
from conftest import MODELS
from test_free_motion import _double_fourbar_state

from xcheck import Kinematics, load_mechanism
from xcheck.dynamics._collocation import STAGES, simulate_collocation, tableau
from xcheck.dynamics._free import FreeState, release_state


def test_the_tableau_is_gauss_legendre_of_order_eight():
    """b c^k = 1 / (k + 1) for k < 2 s (the order conditions of the quadrature), not for k = 2 s;
    A c^k = c^(k+1) / (k + 1) for k < s (the stage order), the nodes symmetric about 1/2."""
    a, c, b = tableau(STAGES)
    assert STAGES == 4
    for k in range(2 * STAGES):
        assert abs(b @ c**k - 1.0 / (k + 1)) <= 1e-15
    assert abs(b @ c ** (2 * STAGES) - 1.0 / (2 * STAGES + 1)) > 1e-6
    for k in range(STAGES):
        assert np.abs(a @ c**k - c ** (k + 1) / (k + 1)).max() <= 1e-15
    assert np.abs(c + c[::-1] - 1.0).max() <= 1e-15 and 0.0 < c.min() < c.max() < 1.0


def test_collocation_crosses_a_singular_position_at_round_off():
    """A02 from its exact state 0.2 s before the pass at 0.714 s to 0.2 s after it, at steps of
    10 and 5 ms: the crossing is planned into the middle of a step (found within 1e-6 s of the
    pass) and the velocity error at the end stays within 5e-14 m/s. Measured: 8.9e-15 and
    3.1e-15 m/s, positions 8.9e-16 and 1.3e-15 m (DOP853 at its finest tolerances: 2.7e-14 m/s)."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a02.toml"))
    q0, qd0 = _double_fourbar_state(0.5)
    q1, qd1 = _double_fourbar_state(0.9)
    for step in (0.01, 0.005):
        motion = simulate_collocation(kin, FreeState(q0, qd0), 0.4, 0.01, step, 1e9)
        assert not motion.failure and motion.statistics["crossings"] == 1
        assert len(motion.singular_passes) == 1 and abs(motion.singular_passes[0] - 0.2143555) <= 1e-6
        off = np.abs(motion.qd[-1] - qd1)
        off[2::3] *= kin.system.size
        assert off.max() <= 5e-14, step


def test_a_step_whose_iteration_does_not_settle_stops_the_run():
    """Andrews' squeezer (stiff: its fastest motions take microseconds) at one step of 10 ms:
    the fixed-point iteration diverges, and the run stops at its start with that reason rather
    than take the step."""
    kin = Kinematics(load_mechanism(MODELS / "benchmarks" / "iftomm-a03.toml"))
    kin.assemble()
    motion = simulate_collocation(kin, release_state(kin), 0.01, 0.01, 0.01, 1e9)
    assert motion.failure == "the collocation's fixed-point iteration did not converge after t = 0 s"
    assert len(motion.times) == 1 and motion.statistics["steps"] == 0
