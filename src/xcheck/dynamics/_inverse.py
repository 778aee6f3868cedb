"""Native inverse dynamics in body coordinates, in two independent forms.

Multiplier form (:func:`inverse_dynamics`)
    With the body coordinates q = (x, y, phi) of every moving body's frame,
    the equations of motion of the constrained system are

        M(q) q'' - Q_v(q, q') - Phi_q^T lambda = Q(q),

    with M the mass matrix in frame coordinates (a centre of mass off the
    frame's origin couples translation and rotation), Q_v the quadratic
    velocity term of that offset, Q the generalised gravity and applied loads,
    and Phi_q the Jacobian of the joint and driver equations of
    :class:`~xcheck.kinematics.ConstraintSystem`. For a prescribed motion q,
    q', q'' is the kinematic solution, so Phi_q^T lambda = M q'' - Q_v - Q is a
    square linear system for the multipliers (one per constraint row), and
    Phi_q^T lambda is the generalised constraint force. Each multiplier is
    then read as a reaction, a moment or a driver's effort.

Per-body Newton-Euler form (:func:`newton_euler`, seed 003: M a = D R + Q)
    Free-body diagrams at the centres of mass: for every moving body,
    m a_G = sum of forces and I_G alpha = sum of moments about G, with the
    reactions, moments and efforts as unknowns R in engineering form (the
    force components at each pin, the normal force and couple of each slider,
    each driver's torque or force) placed at the points where they act. The
    3n x 3n matrix D is assembled from geometry only (no constraint Jacobian);
    D R = M a - Q gives R. The two forms agree to round-off: a check of each.

Everything is vectorised over the N states of a :class:`~xcheck.kinematics.Solution`.
States that did not assemble with determined velocities give NaN rows (their
``status`` says why).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..joints import Action, Joint
from ..kinematics import Solution, Status
from ..model import GROUND, Driver, Mechanism
from ._forces import Forces, require_constant_loads, require_mass_data

__all__ = [
    "AppliedLoad",
    "applied_loads",
    "inverse_dynamics",
    "newton_euler",
    "body_dynamics",
    "directionless_springs",
]

#: A spring's ends closer than this fraction of the mechanism's size coincide to
#: round-off (its positions are held to a few eps of the size): the direction of
#: its pull is then noise.
COINCIDENT = 64 * np.finfo(float).eps


def _rot(phi: np.ndarray, s: np.ndarray) -> np.ndarray:
    """A(phi) s for angles (N,) and body vectors (2,) or (N, 2); returns (N, 2)."""
    c, sn = np.cos(phi), np.sin(phi)
    s = np.broadcast_to(s, phi.shape + (2,))
    return np.stack([c * s[..., 0] - sn * s[..., 1], sn * s[..., 0] + c * s[..., 1]], axis=-1)


def _perp(v: np.ndarray) -> np.ndarray:
    """R v, v turned by +90 degrees; (..., 2)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """z component of u x v for (..., 2) arrays."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def body_dynamics(solution: Solution) -> dict[str, dict[str, np.ndarray]]:
    """Per moving body, its centre of mass's motion and the loads on it.

    Returns
    -------
    dict
        Per body name: ``mass`` (kg), ``inertia`` (kg m^2 about G), ``com``
        (N, 2) position of G, m; ``arm`` (N, 2) G minus the frame origin;
        ``velocity``, ``acceleration`` (N, 2) of G; ``angle``, ``omega``,
        ``alpha`` (N,); ``force`` (N, 2), N: gravity plus the
        :func:`applied_loads` (loads, springs' and dampers' pulls); ``moment``
        (N,), N m: their moment about G plus applied torques.

    Raises
    ------
    ModelError
        If a moving body has no mass or inertia.
    """
    mech = solution.mechanism
    require_mass_data(mech)
    loads = applied_loads(solution)
    out = {}
    for body in mech.moving_bodies:
        assert body.mass is not None and body.inertia is not None  # require_mass_data
        state = solution.body(body.name)
        com = np.zeros(2) if body.com is None else np.asarray(body.com, dtype=float)
        phi, omega, alpha = state["angle"], state["omega"], state["alpha"]
        arm = _rot(phi, com)
        normal = _perp(arm)
        position = state["position"] + arm
        force = np.broadcast_to(body.mass * mech.gravity, arm.shape).copy()
        moment = np.zeros(phi.shape)
        for load in loads:
            if load.body != body.name:
                continue
            at = state["position"] + _rot(phi, load.point)
            force += load.force
            moment += _cross(at - position, load.force) + load.torque
        out[body.name] = {
            "mass": float(body.mass),
            "inertia": float(body.inertia),
            "com": position,
            "arm": arm,
            "velocity": state["velocity"] + omega[:, None] * normal,
            "acceleration": state["acceleration"] + alpha[:, None] * normal - (omega**2)[:, None] * arm,
            "angle": phi,
            "omega": omega,
            "alpha": alpha,
            "force": force,
            "moment": moment,
        }
    return out


@dataclass(frozen=True)
class AppliedLoad:
    """A force at a point of a moving body and a torque on the body, per state.

    Attributes
    ----------
    name : str
        The load's name, or ``"SPRING@LABEL"`` for a spring-damper's end.
    body : str
    point : ndarray, shape (2,)
        Where the force acts, in the body frame, m.
    force : ndarray, shape (N, 2)
        Global frame, N.
    torque : ndarray, shape (N,)
        N m, counter-clockwise.
    """

    name: str
    body: str
    point: np.ndarray
    force: np.ndarray
    torque: np.ndarray


def applied_loads(solution: Solution) -> list[AppliedLoad]:
    """Everything applied to the moving bodies besides gravity, over the states
    of ``solution``: the file's constant ``[[loads]]``, then each spring-damper's
    pull on each end that lies on a moving body (the tension k (l - l0) + c dl/dt
    pulls each end towards the other; at zero length it has no direction and
    pulls nowhere), then each rotational spring-damper's torque on its joint's
    moving bodies (-k (phi_b - phi_a - rest) - c (omega_b - omega_a) on body b,
    the opposite on body a).

    Raises
    ------
    ModelError
        If a load has a time law (the states carry no time).
    """
    mech = solution.mechanism
    require_constant_loads(mech)
    n = solution.q.shape[0]
    out = [
        AppliedLoad(
            load.name,
            load.body,
            np.asarray(load.point, dtype=float),
            np.broadcast_to(np.asarray(load.force, dtype=float), (n, 2)),
            np.full(n, float(load.torque)),
        )
        for load in mech.loads
    ]
    owners = mech.point_owners
    size = solution.kinematics.system.size
    for spring in mech.springs:
        ends = [solution.point(label) for label in spring.points]
        d = ends[1]["position"] - ends[0]["position"]
        length = np.hypot(d[:, 0], d[:, 1])
        unit = np.divide(d, length[:, None], out=np.zeros_like(d), where=length[:, None] > 0.0)
        rate = np.einsum("ij,ij->i", unit, ends[1]["velocity"] - ends[0]["velocity"])
        tension = spring.stiffness * (length - spring.rest_length) + spring.damping * rate
        tension[_directionless(spring, length, size)] = np.nan
        for label, sign in zip(spring.points, (1.0, -1.0)):
            body = owners[label]
            if body != GROUND:
                point = np.asarray(mech.body(body).points[label], dtype=float)
                pull = sign * tension[:, None] * unit
                out.append(AppliedLoad(f"{spring.name}@{label}", body, point, pull, np.zeros(n)))
    zero = np.zeros(2)
    for twist in mech.rotational_springs:
        a, b = (
            solution.body(name) if name != GROUND else {"angle": np.zeros(n), "omega": np.zeros(n)}
            for name in (twist.body_a, twist.body_b)
        )
        angle = b["angle"] - a["angle"] - twist.rest_angle
        torque = -twist.stiffness * angle - twist.damping * (b["omega"] - a["omega"])  # on body b
        for body, sign in ((twist.body_b, 1.0), (twist.body_a, -1.0)):
            if body != GROUND:
                out.append(AppliedLoad(f"{twist.name}@{body}", body, zero, np.zeros((n, 2)), sign * torque))
    return out


def directionless_springs(solution: Solution) -> dict[str, np.ndarray]:
    """Per spring, the states (N,) bool where its ends coincide to round-off
    (:data:`COINCIDENT`) while its rest length or damping pulls: its pull has
    no direction there, so the reactions and efforts are not determined (a spring
    of rest length 0 without damping pulls with nothing there)."""
    size = solution.kinematics.system.size
    out = {}
    for spring in solution.mechanism.springs:
        ends = [solution.point(label)["position"] for label in spring.points]
        out[spring.name] = _directionless(spring, np.hypot(*(ends[1] - ends[0]).T), size)
    return out


def _directionless(spring, length: np.ndarray, size: float) -> np.ndarray:
    """The rule of :func:`directionless_springs` for one spring whose length at each
    state is ``length`` (N,) (m), the mechanism's size ``size`` (m): (N,) bool."""
    pulls = spring.rest_length > 0.0 or spring.damping > 0.0
    return pulls & (length <= COINCIDENT * size)


def _good(solution: Solution) -> np.ndarray:
    return solution.status <= Status.NEAR_SINGULAR


def _solve(matrices: np.ndarray, rhs: np.ndarray, good: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve matrices x = rhs on the good samples; NaN elsewhere. Returns x (N, n)
    and the relative residual |A x - b| / (|A| |x| + |b|) per sample (N,)."""
    x = np.full(rhs.shape, np.nan)
    residual = np.full(rhs.shape[0], np.nan)
    if np.any(good):
        a, b = matrices[good], rhs[good]
        sol = np.linalg.solve(a, b[..., None])[..., 0]
        x[good] = sol
        r = np.einsum("nij,nj->ni", a, sol) - b
        scale = np.linalg.norm(a, axis=(1, 2)) * np.linalg.norm(sol, axis=1) + np.linalg.norm(b, axis=1)
        residual[good] = np.linalg.norm(r, axis=1) / np.where(scale > 0.0, scale, 1.0)
    return x, residual


def _empty(mech: Mechanism, n: int) -> tuple[dict, dict]:
    joints = {}
    for joint in mech.joints:
        joints[joint.name] = {q: np.full((n, 2) if q == "reaction" else n, np.nan) for q in joint.quantities}
    drivers = {d.name: {"effort": np.full(n, np.nan)} for d in mech.drivers}
    return joints, drivers


def inverse_dynamics(solution: Solution) -> Forces:
    """Reactions and efforts from the multipliers of M q'' - Phi_q^T lambda = Q.

    Parameters
    ----------
    solution : Solution
        The prescribed motion (N states) of a mechanism whose moving bodies
        all have mass properties.

    Returns
    -------
    Forces
        Source ``"native"``; ``diagnostics["residual"]`` (N,) the relative
        residual of the linear solve.

    Raises
    ------
    ModelError
        If a moving body has no mass or inertia.
    """
    mech = solution.mechanism
    require_mass_data(mech)
    system = solution.kinematics.system
    n_samples, n = solution.q.shape
    good = _good(solution)
    # generalised inertia force minus applied forces, per body (x, y, phi): M q'' - Q_v - Q
    rhs = np.zeros((n_samples, n))
    for i, (name, b) in enumerate(body_dynamics(solution).items()):
        m = b["mass"]
        linear = m * b["acceleration"] - b["force"]
        # moment about the frame origin: I_G alpha + arm x m a_G - (moments of the loads about the origin)
        rotational = (
            b["inertia"] * b["alpha"]
            + _cross(b["arm"], m * b["acceleration"])
            - b["moment"]
            - _cross(b["arm"], b["force"])
        )
        rhs[:, 3 * i : 3 * i + 2] = linear
        rhs[:, 3 * i + 2] = rotational
    q = np.where(good[:, None], solution.q, 0.0)
    jacobian = system.jacobian(q)  # (N, rows, n), rows = n after assembly
    multipliers, residual = _solve(np.swapaxes(jacobian, 1, 2), rhs, good)

    joints, drivers = _empty(mech, n_samples)
    row = 0
    for joint in mech.joints:
        joints[joint.name].update(joint.reactions(multipliers[:, row : row + joint.rows], solution))
        row += joint.rows
    for k, driver in enumerate(mech.drivers):
        drivers[driver.name]["effort"] = multipliers[:, system.n_kinematic + k]
    return Forces(
        "native",
        solution.inputs,
        solution.input_rates,
        solution.input_accelerations,
        joints,
        drivers,
        diagnostics={"residual": residual},
        notes="Multipliers of M q'' - Phi_q^T lambda = Q in body-frame coordinates (x, y, phi), "
        "with the exact kinematic solution and the analytic constraint Jacobian.",
    )


def newton_euler(solution: Solution) -> Forces:
    """Reactions and efforts from per-body Newton-Euler equations, M a = D R + Q.

    Unknowns R, in this order: per joint in file order, a revolute's force
    (Fx, Fy) at the pin, a line joint's normal force at its sliding point and
    a prismatic joint's couple; then each driver's torque or force. Each acts
    with + on ``body_b`` and - on ``body_a`` (see :mod:`._forces`). Rows: per
    moving body, m a_G (x, y) and I_G alpha about its centre of mass.

    Returns
    -------
    Forces
        Source ``"native-newton-euler"``; ``diagnostics["residual"]``.
    """
    mech = solution.mechanism
    require_mass_data(mech)
    n_samples = solution.q.shape[0]
    good = _good(solution)
    bodies = body_dynamics(solution)
    index = {name: i for i, name in enumerate(bodies)}
    n = 3 * len(bodies)
    d = np.zeros((n_samples, n, n))
    column = 0

    def act(col: int, action: Action) -> None:
        """Column ``col``: a unit reaction's or effort's force or couple on one body."""
        if action.body == GROUND:
            return
        i = 3 * index[action.body]
        if action.direction is None:
            d[:, i + 2, col] += action.scale
            return
        force = action.scale * action.direction
        d[:, i : i + 2, col] += force
        d[:, i + 2, col] += _cross(action.at - bodies[action.body]["com"], force)

    layout: list[tuple[Joint | Driver, int, int]] = []  # (joint or driver, first column, columns)
    for joint in mech.joints:
        columns = joint.reaction_actions(solution)
        for k, actions in enumerate(columns):
            for action in actions:
                act(column + k, action)
        layout.append((joint, column, len(columns)))
        column += len(columns)
    for driver in mech.drivers:
        for action in mech.joint(driver.joint).driver_actions(solution):
            act(column, action)
        layout.append((driver, column, 1))
        column += 1

    rhs = np.zeros((n_samples, n))
    for name, b in bodies.items():
        i = 3 * index[name]
        rhs[:, i : i + 2] = b["mass"] * b["acceleration"] - b["force"]
        rhs[:, i + 2] = b["inertia"] * b["alpha"] - b["moment"]
    d = np.where(good[:, None, None], d, np.eye(n))
    unknowns, residual = _solve(d, np.where(good[:, None], rhs, 0.0), good)

    joints, drivers = _empty(mech, n_samples)
    for owner, first, count in layout:
        values = unknowns[:, first : first + count]
        if isinstance(owner, Driver):
            drivers[owner.name]["effort"] = values[:, 0]
        else:
            joints[owner.name].update(owner.reactions_from_unknowns(values, solution))
    return Forces(
        "native-newton-euler",
        solution.inputs,
        solution.input_rates,
        solution.input_accelerations,
        joints,
        drivers,
        diagnostics={"residual": residual},
        notes="Per-body Newton-Euler equations at the centres of mass (M a = D R + Q, seed 003), "
        "D assembled from the points where the reactions and efforts act.",
    )
