"""Newton-Raphson on Phi(q, c) = 0, batched over samples, and continuation.

Continuation walks the inputs in small steps from a known configuration,
predicting each step with the tangent dq/dc, so that the mechanism stays on
its assembly branch. A step is accepted only if Newton converges, the
Jacobian's determinant keeps its sign (no singular configuration was crossed)
and the correction from the prediction is small.
"""

from __future__ import annotations

import functools
import sys

import numpy as np

from ._system import ConstraintSystem

__all__ = [
    "solve_linear",
    "newton",
    "tangent",
    "det_sign",
    "continue_to",
    "converged_tolerance",
    "minpack_least_squares",
]

#: Newton stops once the violation is below this fraction of the mechanism's size.
STOP_TOLERANCE = 1e-15
#: A sample counts as assembled when its violation is below this fraction.
CONVERGED_TOLERANCE = 1e-10
#: ... or below this many units of round-off of its largest body angle, where
#: that is larger. Angles are continuous, never wrapped, and a double holds an
#: angle phi only to eps |phi|: the loops cannot close better than about that
#: times a length (measured on the four-bar of fuzz case s1-00419, 3000 inputs
#: from 1e3 to 1e9 rad: at most 0.36 eps |phi| size), so past some 10^4 turns
#: the fixed fraction above would reject every exact solution.
ANGLE_ROUNDOFF = 16 * np.finfo(float).eps
#: ... but never above this fraction: past some 1e11 rad a double no longer holds
#: an angle well enough to place a mechanism (at 1e17 deg the input's own spacing
#: is 16 deg), and loops open by more than this are not assembled, whatever the angle.
LARGEST_CONVERGED = 1e-5
#: Largest accepted correction from the predicted configuration (scaled units:
#: radians, or lengths per mechanism size) before a step counts as a jump.
MAX_CORRECTION = 0.1
#: Continuation does not step onto a configuration whose dimensionless Jacobian
#: has an inverse condition number below this. Near a limit position (a fold)
#: the number falls like the square root of the distance, so the walk still gets
#: within 1e-10 of it; at a bifurcation (the change point of a parallelogram,
#: where two branches cross) it falls linearly, and the walk stops there instead
#: of carrying on along whichever branch keeps the determinant's sign.
MIN_CONDITION = 1e-8


def solve_linear(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve jac x = rhs per sample, shapes (N, n, n), (N, n[, m]).

    A sample whose matrix is exactly singular gets the least-squares
    (minimum-norm) solution instead; callers flag such samples by the
    singularity measure.
    """
    vector = rhs.ndim == 2
    b = rhs[..., None] if vector else rhs
    try:
        x = np.linalg.solve(jac, b)
    except np.linalg.LinAlgError:
        x = np.empty(jac.shape[:1] + (jac.shape[2],) + b.shape[2:])
        for i in range(jac.shape[0]):
            try:
                x[i] = np.linalg.solve(jac[i], b[i])
            except np.linalg.LinAlgError:
                x[i] = np.linalg.lstsq(jac[i], b[i], rcond=None)[0]
    return x[..., 0] if vector else x


def newton(system: ConstraintSystem, q0: np.ndarray, c: np.ndarray, max_iter: int = 30):
    """Solve Phi(q, c) = 0 from q0, all samples at once.

    Parameters
    ----------
    q0 : ndarray, shape (N, n)
    c : ndarray, shape (N, k)
        Input values (rad or m).

    Returns
    -------
    q : ndarray, shape (N, n)
    residual : ndarray, shape (N,)
        Largest constraint violation in metres.
    iterations : ndarray of int, shape (N,)
    converged : ndarray of bool, shape (N,)
    """
    q = np.array(q0, dtype=float, copy=True)
    stop = STOP_TOLERANCE * system.size
    iterations = np.zeros(q.shape[0], dtype=int)
    with np.errstate(all="ignore"):
        residual = system.residual_metres(system.residual(q, c))
        for _ in range(max_iter):
            active = np.flatnonzero(residual > stop)
            if active.size == 0:
                break
            qa = q[active]
            step = solve_linear(system.jacobian(qa), system.residual(qa, c[active]))
            qa = qa - step
            new = system.residual_metres(system.residual(qa, c[active]))
            finite = np.isfinite(new) & np.all(np.isfinite(qa), axis=1)
            q[active[finite]] = qa[finite]
            new_residual = np.where(finite, new, np.inf)
            # samples that stopped improving are done (round-off floor)
            stalled = new_residual >= residual[active]
            residual[active] = np.where(finite, new_residual, residual[active])
            iterations[active] += 1
            if np.all(stalled | ~finite):
                break
    converged = residual <= converged_tolerance(system, q)
    return q, residual, iterations, converged


def converged_tolerance(system: ConstraintSystem, q: np.ndarray) -> np.ndarray:
    """Largest violation (m) at which configurations count as assembled, shape (N,).

    :data:`CONVERGED_TOLERANCE` of the mechanism's size, or the round-off of
    the largest body angle (:data:`ANGLE_ROUNDOFF`) where that is larger, at
    most :data:`LARGEST_CONVERGED` of the size.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Configurations (x, y in m and phi in rad per body); NaN rows give the
        fixed fraction.
    """
    angles = np.abs(q[:, 2::3])
    largest = np.max(np.where(np.isfinite(angles), angles, 0.0), axis=1, initial=0.0)
    return system.size * np.minimum(np.maximum(CONVERGED_TOLERANCE, ANGLE_ROUNDOFF * largest), LARGEST_CONVERGED)


#: Samples per batch of :func:`polish` (bounds its (N, n, n) Jacobians' memory).
POLISH_CHUNK = 8192


def polish(system: ConstraintSystem, q: np.ndarray, c: np.ndarray, jac: np.ndarray | None = None) -> np.ndarray:
    """One more Newton step from converged configurations, with Phi(q, c) in long double.

    Newton in double precision stops where the residual is a few eps * size of
    round-off, which leaves q off the exact configuration by about that times
    the condition number kappa; the velocities and accelerations computed there
    inherit it amplified once more (fuzz case s1-00441, a slider-crank at kappa
    = 393: the rod's angular acceleration 1.7e-9 off its closed form, 49 eps
    kappa^2). The same step with the residual in long double (x86: 64-bit
    significand) takes q to the exact configuration rounded to double, and the
    rod's angular acceleration to 4.2e-12 of the closed form. Where long double
    is double (some platforms), this is one more ordinary Newton step.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Converged configurations.
    c : ndarray, shape (N, k)
        Their inputs (rad or m).
    jac : ndarray, shape (N, rows, n), optional
        Phi_q at q, where the caller has it.

    Returns
    -------
    ndarray, shape (N, n)
    """
    out = np.array(q, dtype=float, copy=True)
    for start in range(0, q.shape[0], POLISH_CHUNK):
        rows = slice(start, start + POLISH_CHUNK)
        matrices = system.jacobian(out[rows]) if jac is None else jac[rows]
        step = solve_linear(matrices, long_double_residual(system, out[rows], c[rows]))
        with np.errstate(all="ignore"):
            polished = out[rows] - step
        out[rows] = np.where(np.isfinite(polished), polished, out[rows])
    return out


def long_double_residual(system: ConstraintSystem, q: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Phi(q, c) evaluated in long double and rounded to double, shape (N, rows):
    at a converged q it is the exact residual to double precision, not round-off.
    (q - step is then one rounding: the step needs no long double itself.)"""
    wide = system.residual(np.asarray(q, dtype=np.longdouble), np.asarray(c, dtype=np.longdouble))
    return wide.astype(float)


def tangent(system: ConstraintSystem, q: np.ndarray, jac: np.ndarray | None = None) -> np.ndarray:
    """dq/dc at q: the solution of Phi_q T = [0; I]; shape (N, n, k).

    ``jac`` is Phi_q at q when the caller has it already.
    """
    rhs = np.zeros((q.shape[0], system.n_rows, system.n_drivers))
    rhs[:, system.n_kinematic :, :] = np.eye(system.n_drivers)
    return solve_linear(system.jacobian(q) if jac is None else jac, rhs)


def inverse_condition(system: ConstraintSystem, jac: np.ndarray) -> np.ndarray:
    """1 / cond_1 of the dimensionless Jacobian per sample, shape (N,); 0 if singular."""
    scaled = system.scaled_jacobian(jac)
    with np.errstate(all="ignore"):
        conditions = np.linalg.cond(scaled, 1)
    return np.where(np.isfinite(conditions), 1.0 / conditions, 0.0)


def det_sign(system: ConstraintSystem, jac: np.ndarray) -> np.ndarray:
    """Sign of det Phi_q per sample, shape (N,): it flips only through a singular
    configuration, so a change marks a branch jump or a crossed singularity."""
    return np.sign(np.linalg.det(system.scaled_jacobian(jac)))


def continue_to(
    system: ConstraintSystem,
    q: np.ndarray,
    c: np.ndarray,
    target: np.ndarray,
    max_step: float = np.radians(2.0),
    min_step: float = 1e-10,
):
    """Walk the inputs from c (configuration q) to target, staying on the branch.

    Parameters
    ----------
    q : ndarray, shape (n,)
        An assembled configuration at inputs c.
    c, target : ndarray, shape (k,)
    max_step, min_step : float
        Step bounds in scaled input units (radians; slides per mechanism size).

    Returns
    -------
    q, c : ndarray
        The configuration and inputs reached (target if reached).
    reached : bool
        False when the walk stopped at a limit position or singularity; c is
        then within about ``min_step`` of it (or of 64 units in the last place
        of the inputs, where that is more).
    trail : list of (fraction, q)
        Every accepted step: the fraction of the way from c to target, and
        the configuration there. Steps are short where the mechanism moves
        fast (near limit positions), so the trail is a good set of anchors
        for predicting nearby samples.
    """
    scale = system.input_scale()
    q, c = np.array(q, dtype=float), np.array(c, dtype=float)
    jac = system.jacobian(q[None])
    sign = det_sign(system, jac)[0]
    step = max_step
    start = c.copy()
    total = float(np.max(np.abs((target - start) * scale)))
    trail: list[tuple[float, np.ndarray]] = []
    while True:
        remaining = (target - c) * scale
        distance = float(np.max(np.abs(remaining)))
        if distance == 0.0:  # there: reached if the loops close (a start given at the target may not)
            closes = system.residual_metres(system.residual(q[None], target[None]))[0]
            return q, c, bool(closes <= converged_tolerance(system, q[None])[0]), trail
        fraction = min(1.0, step / distance)
        c_next = target if fraction == 1.0 else c + (target - c) * fraction
        guess = q + tangent(system, q[None], jac)[0] @ (c_next - c)
        q_new, _, _, ok = newton(system, guess[None], c_next[None], max_iter=100)
        accepted = bool(ok[0])
        if accepted:
            correction = np.max(np.abs((q_new[0] - guess) * system.coordinate_scale()))
            new_jac = system.jacobian(q_new)
            new_sign = det_sign(system, new_jac)[0]
            accepted = (
                correction <= MAX_CORRECTION
                and (new_sign == sign or sign == 0.0)
                and inverse_condition(system, new_jac)[0] >= MIN_CONDITION
            )
        if accepted:
            sign, jac = new_sign, new_jac
            q, c = q_new[0], c_next
            trail.append((1.0 - float(np.max(np.abs((target - c) * scale))) / total, q))
            step = min(max_step, step * 1.5)
        else:
            step *= 0.5
            # steps of a few units in the last place of the inputs make no headway
            # (an input of 3.4e6 rad is held to 4.7e-10 rad): stop there too
            if step < max(min_step, 64.0 * float(np.max(np.spacing(np.abs(c * scale))))):
                return q, c, False, trail


def minpack_least_squares(residuals, jacobian, x0: np.ndarray, tolerance: float = 1e-15, max_evaluations: int = 2000):
    """Minimise ``|residuals(x)|^2`` from ``x0`` by MINPACK's Levenberg-Marquardt
    (``lmder``), as SciPy's ``least_squares(method="lm")`` calls it, its three
    tolerances ``tolerance``.

    Parameters
    ----------
    residuals : callable
        x, shape (n,), to r, shape (m,).
    jacobian : callable
        x to dr/dx, shape (m, n).
    x0 : ndarray, shape (n,)

    Returns
    -------
    ndarray, shape (n,)
    """
    lmder = _minpack_lmder()
    if lmder is not None:
        try:  # as scipy.optimize._lsq.least_squares.call_minpack calls it, x_scale "jac" (diag None)
            x, _, _ = lmder(
                residuals,
                jacobian,
                np.array(x0, dtype=float),
                (),
                True,
                False,
                tolerance,
                tolerance,
                tolerance,
                max_evaluations,
                100.0,
                None,
            )
            return x
        except TypeError:  # another SciPy's binding: its public function
            pass
    from scipy.optimize import least_squares  # imports all of scipy.optimize

    fit = least_squares(
        residuals,
        x0,
        jac=jacobian,
        method="lm",
        xtol=tolerance,
        ftol=tolerance,
        gtol=tolerance,
        max_nfev=max_evaluations,
        x_scale="jac",
    )
    return fit.x


@functools.cache
def _minpack_lmder():
    """SciPy's binding of MINPACK's ``lmder``, loaded from its extension module alone:
    importing it the ordinary way imports all of ``scipy.optimize`` first, most of a
    command's sketch fit (docs/benchmarks.md). None where that module is not found."""
    import importlib.machinery
    import importlib.util
    from pathlib import Path

    import scipy

    folder = Path(scipy.__file__).parent / "optimize"
    name = "scipy.optimize._minpack"
    if name in sys.modules:
        return getattr(sys.modules[name], "_lmder", None)
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = folder / f"_minpack{suffix}"
        if path.is_file():
            loader = importlib.machinery.ExtensionFileLoader(name, str(path))
            spec = importlib.util.spec_from_file_location(name, path, loader=loader)
            if spec is None:
                return None
            try:
                module = importlib.util.module_from_spec(spec)
                loader.exec_module(module)
            except ImportError:
                return None
            return getattr(module, "_lmder", None)
    return None
