"""The native solver's accuracy near a singular configuration: positions polished
with a long-double residual (``kinematics._newton.polish``), so that velocities and
accelerations carry the conditioning once (eps kappa^2 at most), not the round-off
of a double-precision Newton stop amplified by it.

Fuzz case s1-00441: a slider-crank (crank 418.6 m, rod 656.9 m, guide 238.3 m
above the crank's pivot) whose rod comes within 0.00003 % of perpendicular to its
guide, kappa = 393. Before polishing, the rod's angular acceleration was 1.7e-9 of
its largest value off the closed form (49 eps kappa^2), and formulations I and II
and Pinocchio, which agree with the closed form, failed against it.
"""

from __future__ import annotations

import numpy as np
from conftest import DATA

from xcheck import api

EPS = np.finfo(float).eps
CRANK, ROD, GUIDE = (np.longdouble(v) for v in ("418.6052631744128", "656.9152329087625", "238.30922419513954"))


def closed_form(theta, rate, acceleration, native_angle):
    """The rod's angle, rate and angular acceleration of the offset slider-crank in long
    double: its end A = CRANK (cos theta, sin theta), its end B on the guide y = GUIDE,
    so sin phi = (GUIDE - CRANK sin theta) / ROD; differentiated twice. The branch
    (phi or pi - phi) is the one of ``native_angle``."""
    theta, rate, acceleration = (np.asarray(v, dtype=np.longdouble) for v in (theta, rate, acceleration))
    sine = (GUIDE - CRANK * np.sin(theta)) / ROD
    phi = np.arcsin(sine)
    phi = np.where(np.abs(np.sin((native_angle - phi.astype(float)) / 2)) < 1e-3, phi, np.pi - phi)
    cosine = np.cos(phi)
    omega = -CRANK * np.cos(theta) * rate / (ROD * cosine)
    alpha = (CRANK * np.sin(theta) * rate**2 - CRANK * np.cos(theta) * acceleration + ROD * sine * omega**2) / (
        ROD * cosine
    )
    return phi, omega, alpha


def test_native_accelerations_near_a_singular_configuration_meet_the_closed_form():
    run = api.run(DATA / "fuzz-slider-crank-near-dead-centre.toml", "formulation-I,formulation-II", samples=181)
    native = run.native
    assert native.success
    rod = 3 * run.kinematics.system.body_index["rod"] + 2
    kappa = 1.0 / float(np.min(native.singularity))
    assert 300 < kappa < 500  # the case is as ill-conditioned as when it failed
    _, omega, alpha = closed_form(
        native.inputs[:, 0], native.input_rates[:, 0], native.input_accelerations[:, 0], native.q[:, rod]
    )
    omega_error = np.max(np.abs(native.qd[:, rod] - omega)) / np.max(np.abs(omega))
    alpha_error = np.max(np.abs(native.qdd[:, rod] - alpha)) / np.max(np.abs(alpha))
    # measured: 3.0e-14 (0.34 eps kappa) and 4.3e-12 (0.12 eps kappa^2); before polishing 1.2e-11, 1.7e-9
    assert float(omega_error) <= EPS * kappa
    assert float(alpha_error) <= EPS * kappa**2
    # two independent exact methods now agree with it within their bound (10 eps kappa^2)
    for mode in ("formulation-I", "formulation-II"):
        assert run.outcomes[mode].passed, run.outcomes[mode].categories
