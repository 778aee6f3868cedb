"""The least squares that fit a rough sketch call MINPACK's binding in SciPy directly,
without importing all of ``scipy.optimize``: the same numbers, bit for bit, as SciPy's
``least_squares`` gives."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA, MODELS

from xcheck import Kinematics, load_mechanism
from xcheck.kinematics import _newton


def _rosenbrock(q):
    return np.array([10.0 * (q[1] - q[0] ** 2), 1.0 - q[0]])


def _rosenbrock_jacobian(q):
    return np.array([[-20.0 * q[0], 10.0], [-1.0, 0.0]])


def test_minpack_finds_rosenbrocks_minimum():
    """Rosenbrock's valley as residuals (10 (y - x^2), 1 - x) from (-1.2, 1): the one
    minimum, (1, 1), where both residuals are zero."""
    assert _newton._minpack_lmder() is not None  # the direct binding, not the fallback
    q = _newton.minpack_least_squares(_rosenbrock, _rosenbrock_jacobian, np.array([-1.2, 1.0]))
    assert np.max(np.abs(q - 1.0)) <= 1e-12


@pytest.mark.parametrize(
    "path", [MODELS / "fourbar.toml", DATA / "fivebar.toml", DATA / "bad/reach-sketch-no-closure.toml"]
)
def test_the_sketch_fit_is_scipys_least_squares_bit_for_bit(path, monkeypatch):
    """Every branch's staged fit, and the constraints-only fit that names the loop that
    cannot close, by the direct binding and by ``least_squares`` (the fallback where
    SciPy's binding is not found): the same bits."""
    mech = load_mechanism(path)
    for branch in mech.assembly.branches:
        kin = Kinematics(mech)
        system, c_ref = kin.system, kin.reference_inputs()
        sketch = {**mech.ground.points, **mech.assembly.branches[branch]}
        guess = system.unwind_angles(kin._sketch_guess(sketch), c_ref)
        fits = []
        for binding in (_newton._minpack_lmder(), None):
            monkeypatch.setattr(_newton, "_minpack_lmder", lambda binding=binding: binding)
            staged = kin._fit_sketch(guess, c_ref, sketch)
            fits += [staged, kin._fit_sketch(staged, c_ref, sketch, weights=(0.0,), held=1e6)]
        assert np.array_equal(fits[0], fits[2]) and np.array_equal(fits[1], fits[3]), branch
