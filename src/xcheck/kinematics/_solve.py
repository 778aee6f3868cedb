"""The general native solver: assembly, mobility, and position, velocity and
acceleration over a sweep of inputs.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from ..errors import ModelError
from ..model import Mechanism
from ._newton import (
    ANGLE_ROUNDOFF,
    CONVERGED_TOLERANCE,
    LARGEST_CONVERGED,
    MAX_CORRECTION,
    POLISH_CHUNK,
    STOP_TOLERANCE,
    continue_to,
    det_sign,
    long_double_residual,
    minpack_least_squares,
    newton,
    polish,
    tangent,
)
from ._system import ConstraintSystem, _perp, rotate

__all__ = ["Status", "Solution", "Kinematics", "NEAR_SINGULAR", "SINGULAR"]

#: feasible ranges walked in this process (the walk, by :func:`_walk_key`: its range, the
#: configurations it walked through and the change of q over one turn or None), so that
#: another Kinematics of the same mechanism does not walk it again; the latest kept
_WALKS: collections.OrderedDict = collections.OrderedDict()
_WALKS_KEPT = 64

#: Below this inverse condition number of the scaled Jacobian, results lose
#: more than about six digits: flagged, still reported.
NEAR_SINGULAR = 1e-6
#: Samples this close (scaled input units) to a stretch that continuation
#: reached are still attempted.
_PATH_TOLERANCE = 1e-9
#: Sweeps of at least this many samples run compiled by default (the break-even
#: of the compiled kernels' loading time against the reference's speed).
COMPILED_FROM = 50_000
#: Below this, the configuration is singular (dead centre, limit position):
#: velocities and accelerations are not determined and are not reported.
SINGULAR = 1e-12


def _inverse_with_condition(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverses of matrices of shape (N, n, n) and their inverse condition numbers
    1 / (|A|_1 |A^-1|_1): 1 when well conditioned, 0 when singular (whose
    inverse is then the pseudo-inverse)."""
    norm = np.max(np.sum(np.abs(matrices), axis=1), axis=1)
    try:
        inverse = np.linalg.inv(matrices)
    except np.linalg.LinAlgError:
        inverse = np.empty_like(matrices)
        for i, m in enumerate(matrices):
            try:
                inverse[i] = np.linalg.inv(m)
            except np.linalg.LinAlgError:
                inverse[i] = np.linalg.pinv(m)
                norm[i] = np.inf
    inverse_norm = np.max(np.sum(np.abs(inverse), axis=1), axis=1)
    with np.errstate(all="ignore"):
        result = 1.0 / (norm * inverse_norm)
    return inverse, np.where(np.isfinite(result), result, 0.0)


class Status(IntEnum):
    """Per-sample outcome of a solve."""

    OK = 0
    NEAR_SINGULAR = 1
    SINGULAR = 2
    NOT_CONVERGED = 3
    BRANCH_JUMP = 4

    @property
    def message(self) -> str:
        return _STATUS_MESSAGES[self]

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", "-")


_STATUS_MESSAGES = {
    Status.OK: "assembled; velocity and acceleration determined",
    Status.NEAR_SINGULAR: "close to a singular configuration: results lose accuracy",
    Status.SINGULAR: "singular configuration (dead centre or limit position): velocity and acceleration not determined",
    Status.NOT_CONVERGED: "the mechanism does not assemble at this input",
    Status.BRANCH_JUMP: "the solution would leave the assembly branch here",
}


@dataclass
class Solution:
    """The state of a mechanism over N samples of its inputs (SI units).

    Attributes
    ----------
    kinematics : Kinematics
    branch : str
    inputs, input_rates, input_accelerations : ndarray, shape (N, k)
        Drivers' values (rad or m), rates and accelerations, in driver order.
    q, qd, qdd : ndarray, shape (N, n)
        Body coordinates (x, y, phi per moving body) and their derivatives.
        Rows whose status is not-converged or branch-jump hold NaN; so do qd
        and qdd where the status is singular. ``status`` is authoritative.
    status : ndarray of int, shape (N,)
        :class:`Status` codes.
    residual : ndarray, shape (N,)
        Largest constraint violation, m.
    singularity : ndarray, shape (N,)
        Inverse condition number (1-norm) of the dimensionless Jacobian
        Phi_q (1: well conditioned, 0: singular).
    iterations : ndarray of int, shape (N,)
    """

    kinematics: "Kinematics"
    branch: str
    inputs: np.ndarray
    input_rates: np.ndarray
    input_accelerations: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    singularity: np.ndarray
    iterations: np.ndarray

    @property
    def mechanism(self) -> Mechanism:
        return self.kinematics.mechanism

    @property
    def success(self) -> bool:
        """True when every sample assembled with determined velocities."""
        return bool(np.all(self.status <= Status.NEAR_SINGULAR))

    def _frame(self, body: str):
        index = self.kinematics.system.body_index[body]
        n = self.q.shape[0]
        if index < 0:
            zero2, zero = np.zeros((n, 2)), np.zeros(n)
            return zero2, zero, zero2, zero, zero2, zero
        k = 3 * index
        return (
            self.q[:, k : k + 2],
            self.q[:, k + 2],
            self.qd[:, k : k + 2],
            self.qd[:, k + 2],
            self.qdd[:, k : k + 2],
            self.qdd[:, k + 2],
        )

    def body(self, name: str) -> dict[str, np.ndarray]:
        """A body frame's state: position (N, 2) m, angle (N,) rad, velocity,
        omega, acceleration, alpha."""
        r, phi, rd, phid, rdd, phidd = self._frame(name)
        return {"position": r, "angle": phi, "velocity": rd, "omega": phid, "acceleration": rdd, "alpha": phidd}

    def point(self, label: str, body: str | None = None) -> dict[str, np.ndarray]:
        """A named point's position, velocity and acceleration, each (N, 2), SI.

        ``body`` defaults to the first body (ground first) that has the label.
        """
        body = body or self.mechanism.point_owners[label]
        s = self.mechanism.body(body).points[label]
        r, phi, rd, phid, rdd, phidd = self._frame(body)
        arm = rotate(phi, s)
        normal = _perp(arm)
        return {
            "position": r + arm,
            "velocity": rd + phid[:, None] * normal,
            "acceleration": rdd + phidd[:, None] * normal - (phid**2)[:, None] * arm,
        }


def _predict(system, anchor_path, anchor_q, anchor_c, anchor, sample_path, sample_c) -> np.ndarray:
    """Predicted configurations of samples from the anchors around them, (N, n).

    Between two anchors: the cubic Hermite curve through both anchors'
    configurations and tangents (error of fourth order in the spacing);
    past the last anchor: the tangent line of that anchor.
    """
    tangents = tangent(system, anchor_q)  # (M, n, k)
    nxt = np.minimum(anchor + 1, len(anchor_q) - 1)
    span = anchor_path[nxt] - anchor_path[anchor]
    inside = span > 0.0
    t = np.where(inside, (sample_path - anchor_path[anchor]) / np.where(inside, span, 1.0), 0.0)[:, None]
    step = anchor_c[nxt] - anchor_c[anchor]  # input change over the interval, (N, k)
    d0 = np.einsum("nik,nk->ni", tangents[anchor], step)
    d1 = np.einsum("nik,nk->ni", tangents[nxt], step)
    h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
    h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
    hermite = h00 * anchor_q[anchor] + h10 * d0 + h01 * anchor_q[nxt] + h11 * d1
    linear = anchor_q[anchor] + np.einsum("nik,nk->ni", tangents[anchor], sample_c - anchor_c[anchor])
    return np.where(inside[:, None], hermite, linear)


@dataclass(frozen=True)
class InputRange:
    """Feasible interval of one driver's input, others held at the assembly inputs.

    ``low``/``high`` are SI values (rad or m); None means no limit was met
    within ``span`` of the assembly input (a crank that turns round).
    """

    driver: str
    low: float | None
    high: float | None
    span: float

    @property
    def full_turn(self) -> bool:
        return self.low is None and self.high is None

    def contains(self, value: float) -> bool:
        return (self.low is None or value >= self.low) and (self.high is None or value <= self.high)


def _walk_key(mechanism: Mechanism, branch: str, driver: int, start: np.ndarray) -> str | None:
    """What a feasible-range walk depends on, digested: the canonical mechanism (not
    the path it was read from), the branch, the driver and the configuration it
    starts from, to every bit; None where the mechanism cannot be digested."""
    from ..store import mechanism_digest

    return mechanism_digest("walk", mechanism, branch, driver, start)


@dataclass
class Kinematics:
    """The native general solver for one mechanism.

    Parameters
    ----------
    mechanism : Mechanism

    Notes
    -----
    Build once per mechanism; the assembled reference configuration of each
    branch and the feasible input ranges are computed on first use and kept.
    A feasible range's walk is also kept for the process: another Kinematics
    of the same mechanism, assembled the same, takes it instead of walking again
    (the same floats).
    """

    mechanism: Mechanism
    system: ConstraintSystem = field(init=False)
    _assembled: dict = field(init=False, default_factory=dict)
    _ranges: dict = field(init=False, default_factory=dict)
    _turns: dict = field(init=False, default_factory=dict)
    _walked: dict = field(init=False, default_factory=dict)
    _atlases: dict = field(init=False, default_factory=dict)
    _atlas_slopes: dict = field(init=False, default_factory=dict)
    _packed: Any = field(init=False, default=None)

    def __post_init__(self):
        self.system = ConstraintSystem(self.mechanism)

    @property
    def branches(self) -> list[str]:
        return list(self.mechanism.assembly.branches)

    def _branch_name(self, branch: str | None) -> str:
        names = self.branches
        if branch is None:
            return names[0]
        if branch not in names:
            raise ModelError(
                self.mechanism.path, "assembly.branches", f"a branch named one of {', '.join(names)}", repr(branch)
            )
        return branch

    # -- assembly and mobility ---------------------------------------------
    def reference_inputs(self) -> np.ndarray:
        """The drivers' values at which the branch sketches are drawn, shape (k,)."""
        at = self.mechanism.assembly.at
        return np.array([at[d.name] for d in self.mechanism.drivers])

    def mobility(self, q: np.ndarray | None = None) -> dict[str, int]:
        """Degrees of freedom by Grübler's count and by the rank of Phi_q.

        The rank is taken at q (default: the assembled reference configuration).
        """
        if q is None:
            q = self.assemble()
        jac = self.system.scaled_jacobian(self.system.jacobian(q[None], kinematic_only=True))[0]
        singular_values = np.linalg.svd(jac, compute_uv=False) if jac.size else np.zeros(0)
        rank = int(np.sum(singular_values > 1e-9 * max(1.0, singular_values.max(initial=0.0))))
        return {"grubler": self.mechanism.grubler(), "rank": self.system.n - rank, "drivers": self.system.n_drivers}

    def assemble(self, branch: str | None = None) -> np.ndarray:
        """The configuration at the reference inputs on a branch, shape (n,).

        The branch's rough sketch is fitted first (least squares of the
        constraints plus a weak pull towards the sketched points), then
        Newton-Raphson closes the loops exactly.

        Raises
        ------
        ModelError
            If the drivers do not match the degrees of freedom, or the sketch
            does not assemble.
        """
        name = self._branch_name(branch)
        if name in self._assembled:
            return self._assembled[name]
        system, mech = self.system, self.mechanism
        c_ref = self.reference_inputs()
        drawn = mech.assembly.branches[name]
        field_name = f"assembly.branches.{name}" if drawn else "assembly.branches"
        loops = sum(j.connects for j in mech.joints) - len(mech.moving_bodies)
        if loops > 0 and not drawn:
            raise ModelError(
                mech.path,
                "assembly.branches",
                "a rough sketch of a few points that picks the assembly branch "
                f"(the mechanism has {loops} closed loop(s))",
                "none",
            )
        where = ", ".join(f"{d.name} = {mech.units.show_input(d.quantity, v)}" for d, v in zip(mech.drivers, c_ref))

        def no_assembly(why: str):
            return ModelError(
                mech.path,
                field_name,
                f"a sketch from which the mechanism assembles at {where}",
                f"none that closes the loops ({why})",
            )

        sketch = {**{lbl: xy for lbl, xy in mech.ground.points.items()}, **drawn}
        try:
            with np.errstate(all="ignore"):  # absurd sizes overflow: reported below, not warned
                guess = system.unwind_angles(self._sketch_guess(sketch), c_ref)
                fitted = system.unwind_angles(self._fit_sketch(guess, c_ref, sketch), c_ref)
                joint_gap = float(
                    system.residual_metres(system.residual(fitted[None], c_ref[None], kinematic_only=True))[0]
                )
                dof = self.mobility(fitted)
        except np.linalg.LinAlgError as err:
            raise no_assembly(f"the linear algebra failed: {err}") from None
        # the weak pull towards a rough sketch leaves small gaps that Newton closes
        joints_close = joint_gap <= 1e-2 * system.size
        if not joints_close and dof["grubler"] == dof["drivers"]:
            # the joints cannot close near the sketch: the input (or a length) where no configuration
            # closes a loop, or else a sketch of no branch
            unclosed = self._unclosed_loop(fitted, c_ref, sketch)
            if unclosed is not None:
                raise ModelError(mech.path, "assembly.at", "an input at which every loop closes", unclosed)
            raise no_assembly(
                f"the best fit leaves the joints {joint_gap / mech.units.length_factor:.3g} {mech.units.length} apart"
            )
        if dof["rank"] != dof["drivers"]:
            raise ModelError(
                mech.path,
                "drivers",
                f"{dof['rank']} driver(s), one per degree of freedom (Grübler count {dof['grubler']}, "
                f"rank of the constraint Jacobian {dof['rank']})",
                f"{dof['drivers']}",
            )
        if system.n_rows != system.n:
            raise ModelError(
                mech.path,
                "joints",
                f"independent joint constraints (Grübler count {dof['grubler']} degrees of freedom)",
                f"{system.n_rows - system.n} redundant constraint equation(s), which xcheck cannot solve: "
                "replace a joint by one that removes fewer degrees of freedom",
            )
        q, residual, _, ok = newton(system, fitted[None], c_ref[None], max_iter=50)
        if not ok[0]:
            gap = residual[0] / mech.units.length_factor
            raise no_assembly(
                f"Newton-Raphson left a violation of {gap:.3g} {mech.units.length}"
                if np.isfinite(gap) and gap < 1e3 * system.size / mech.units.length_factor
                else "Newton-Raphson diverged from the sketch"
            )
        q = q[0]  # body angles continuous: never wrapped, the angle rows hold exactly
        self._assembled[name] = q
        return q

    def _sketch_guess(self, sketch: dict[str, np.ndarray]) -> np.ndarray:
        """Best rigid fit of each moving body's points to the sketch, shape (n,)."""
        q = np.zeros(self.system.n)
        for i, body in enumerate(self.mechanism.moving_bodies):
            labels = [lbl for lbl in body.points if lbl in sketch]
            if not labels:
                continue
            local = np.array([body.points[lbl] for lbl in labels])
            world = np.array([sketch[lbl] for lbl in labels])
            lc, wc = local.mean(axis=0), world.mean(axis=0)
            if len(labels) >= 2:
                a, b = local - lc, world - wc
                phi = math.atan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a * b))
            else:
                phi = 0.0
            q[3 * i : 3 * i + 2] = wc - rotate(np.array([phi]), lc)[0]
            q[3 * i + 2] = phi
        return q

    def _unclosed_loop(self, fitted: np.ndarray, c_ref: np.ndarray, sketch) -> str | None:
        """Where the loops cannot close at the reference inputs, whatever the
        sketch: the loop through the joint left farthest apart by the least
        squares of the constraints alone (no pull towards the sketch), with the
        lengths around it; None where that fit closes them (the sketch was of
        no branch)."""
        system, mech = self.system, self.mechanism
        units = mech.units
        with np.errstate(all="ignore"):
            q = self._fit_sketch(fitted, c_ref, sketch, weights=(0.0,), held=1e6)  # the inputs as given
            phi = system.residual(q[None], c_ref[None], kinematic_only=True)[0]
        gaps = np.abs(phi) * np.where(system.row_is_angle[: phi.size], system.size, 1.0)
        if not np.all(np.isfinite(gaps)) or gaps.max(initial=0.0) <= 1e-6 * system.size:
            return None
        rows = np.cumsum([0] + [sum(t.rows for t in joint.terms(system._local)) for joint in mech.joints])
        per_joint = [float(np.linalg.norm(gaps[a:b])) for a, b in zip(rows[:-1], rows[1:])]
        worst = int(np.argmax(per_joint))
        loop, joints = self._loop_through(worst)
        if any(body == "ground" for body, _ in loop):  # read from the ground round
            first = next(i for i, (body, _) in enumerate(loop) if body == "ground")
            loop = loop[first:] + loop[:first]
        short = sum(per_joint[k] for k in joints)  # the least squares share the gap among the loop's joints
        where = ", ".join(f"{d.name} = {units.show_input(d.quantity, v)}" for d, v in zip(mech.drivers, c_ref))
        joint = mech.joints[worst]
        name = joint.shared_label() or "/".join(label for _, label in joint.anchors())
        lengths = []
        for body, (enter, leave) in loop:
            points = mech.ground.points if body == "ground" else mech.body(body).points
            if enter in points and leave in points and enter != leave:
                length = float(np.hypot(*(np.asarray(points[leave]) - np.asarray(points[enter]))))
                lengths.append(f"{body} {enter}-{leave} {length / units.length_factor:.6g}")
        bodies = " - ".join([body for body, _ in loop] + [loop[0][0]])
        return (
            f"{where}, where the loop {bodies} cannot close: its joints stay {short / units.length_factor:.3g} "
            f"{units.length} apart in all at best, most at {name} ({joint.body_a}, {joint.body_b})"
            + (f"; the lengths around it ({units.length}): {', '.join(lengths)}" if lengths else "")
        )

    def _loop_through(self, index: int) -> tuple[list[tuple[str, tuple[str, str]]], list[int]]:
        """The shortest loop of bodies closed by joint ``index``: (body, (the
        label where the loop enters it, where it leaves)) in order, starting
        with the joint's second body, and the indices of the loop's joints."""
        mech = self.mechanism
        joints = mech.joints

        def label(joint, body: str) -> str:
            own = [lbl for b, lbl in joint.anchors() if b == body]
            return own[0] if own else (joint.shared_label() or "")

        start, goal = joints[index].body_b, joints[index].body_a
        previous: dict[str, tuple[str, int] | None] = {start: None}
        frontier = [start]
        while frontier and goal not in previous:
            following = []
            for body in frontier:
                for k, joint in enumerate(joints):
                    if k == index or body not in joint.bodies:
                        continue
                    other = joint.body_b if joint.body_a == body else joint.body_a
                    if other not in previous:
                        previous[other] = (body, k)
                        following.append(other)
            frontier = following
        if goal not in previous:
            return [(start, ("", "")), (goal, ("", ""))], [index]
        path = [goal]  # goal back to start
        via = []
        while previous[path[-1]] is not None:
            body, k = previous[path[-1]]  # type: ignore[misc]
            via.append(k)
            path.append(body)
        path.reverse()
        via.reverse()  # via[i] joins path[i] and path[i + 1]
        loop = []
        for i, body in enumerate(path):
            enter = joints[index] if i == 0 else joints[via[i - 1]]
            leave = joints[via[i]] if i < len(via) else joints[index]
            loop.append((body, (label(enter, body), label(leave, body))))
        return loop, [index, *via]

    def _fit_sketch(self, q0, c_ref, sketch, weights=(1.0, 1e-1, 1e-2, 1e-3), held: float = 1.0) -> np.ndarray:
        """Least squares of the constraints plus a pull towards the sketched
        points, the pull relaxed in stages (1, 0.1, 0.01, 0.001) so that the
        fit closes the loops without wandering off the sketched branch."""
        system, mech = self.system, self.mechanism
        targets = [
            (system.body_index[b.name], b.points[lbl], sketch[lbl])
            for b in mech.moving_bodies
            for lbl in b.points
            if lbl in sketch
        ]
        if system.n_rows + 2 * len(targets) < system.n:
            return q0  # too few equations for least squares; Newton decides
        size = system.size
        row_scale = np.where(system.row_is_angle, 1.0, 1.0 / size)
        row_scale[system.n_kinematic :] *= held  # the drivers' rows: held harder than the joints' with held > 1

        def residuals(q, weight):
            phi = system.residual(q[None], c_ref[None])[0] * row_scale
            pulls = [
                weight * (q[3 * i : 3 * i + 2] + rotate(q[3 * i + 2 : 3 * i + 3], s)[0] - xy) / size
                for i, s, xy in targets
            ]
            return np.concatenate([phi] + pulls) if pulls else phi

        def jacobian(q, weight):
            jac = system.jacobian(q[None])[0] * row_scale[:, None]
            rows = []
            for i, s, _ in targets:
                row = np.zeros((2, system.n))
                row[:, 3 * i : 3 * i + 2] = np.eye(2)
                row[:, 3 * i + 2] = _perp(rotate(q[3 * i + 2 : 3 * i + 3], s))[0]
                rows.append(weight * row / size)
            return np.vstack([jac] + rows) if rows else jac

        q = q0
        for weight in weights:
            q = minpack_least_squares(
                lambda x, weight=weight: residuals(x, weight), lambda x, weight=weight: jacobian(x, weight), q
            )
        return q

    # -- feasible range ---------------------------------------------------
    def input_range(self, driver: str | int, branch: str | None = None) -> InputRange:
        """Feasible interval of a driver's input on a branch (limit positions found
        by continuation from the reference configuration)."""
        drivers = self.mechanism.drivers
        k = driver if isinstance(driver, int) else [d.name for d in drivers].index(driver)
        name = self._branch_name(branch)
        key = (name, k)
        if key not in self._ranges:
            q_ref, c_ref = self.assemble(name), self.reference_inputs()
            walk = _walk_key(self.mechanism, name, k, q_ref)
            if walk in _WALKS:  # another Kinematics of this mechanism in this process walked it
                _WALKS.move_to_end(walk)
                self._ranges[key], self._walked[key], turn = _WALKS[walk]
                self._walked[key] = list(self._walked[key])
                if turn is not None:
                    self._turns[key] = turn
                return self._ranges[key]
            is_angle = drivers[k].quantity == "angle"
            span = 2.0 * math.pi if is_angle else 10.0 * self.system.size
            ends = []
            walked = [(float(c_ref[k]), q_ref)]  # (input k, q) on the branch, for the atlas
            for direction in (-1.0, 1.0):
                target = c_ref.copy()
                target[k] += direction * span
                q_end, c, reached, trail = continue_to(self.system, q_ref, c_ref, target)
                walked += [(float(c_ref[k] + f * direction * span), q_step) for f, q_step in trail]
                ends.append(None if reached else float(c[k]))
                if reached and is_angle:  # turned round once: the input is a crank
                    ends = [None, None]
                    self._record_turn(name, k, direction * (q_end - q_ref))
                    break
            self._walked[key] = walked
            self._ranges[key] = InputRange(drivers[k].name, ends[0], ends[-1], span)
            if walk is not None:
                _WALKS[walk] = (self._ranges[key], tuple(walked), self._turns.get(key))
                while len(_WALKS) > _WALKS_KEPT:
                    _WALKS.popitem(last=False)
        return self._ranges[key]

    def _record_turn(self, branch: str, k: int, change: np.ndarray) -> None:
        """Keep the change of q over one turn of input k if the mechanism is then
        back where it started (positions equal, angles changed by whole turns)."""
        scale = self.system.coordinate_scale()
        turns = np.round(change / (2.0 * math.pi))
        turns[0::3] = turns[1::3] = 0.0
        shift = turns * 2.0 * math.pi
        if np.max(np.abs((change - shift) * scale)) <= 1e-9:
            self._turns[(branch, k)] = shift

    def _atlas(self, branch: str):
        """The branch mapped once, for a one-input mechanism: (inputs (M,),
        configurations (M, n), period) from the feasible-range walk, whose steps
        are short where the mechanism moves fast. ``period`` is the change of q
        over one turn of a crank (None for a bounded input). None when there is
        no atlas (several inputs, or a crank that is not back where it started
        after one turn): sweeps then walk from the reference."""
        if self.system.n_drivers != 1:
            return None
        if branch not in self._atlases:
            rng = self.input_range(0, branch)
            period = self._turns.get((branch, 0))
            atlas = None
            if not rng.full_turn or period is not None:
                walked = sorted(self._walked[(branch, 0)], key=lambda item: item[0])
                c = np.array([w[0] for w in walked])
                q = np.array([w[1] for w in walked])
                keep = np.concatenate([[True], np.diff(c) > 0.0])
                atlas = (c[keep], q[keep], period)
            self._atlases[branch] = atlas
        return self._atlases[branch]

    def _atlas_tangents_and_signs(self, branch: str, atlas) -> tuple[np.ndarray, np.ndarray]:
        """dq/dc (M, n) and the sign of det Phi_q (M,) at the branch's atlas points,
        computed once per branch (n^3 each: on a long chain, more than the sweep)."""
        if branch not in self._atlas_slopes:
            q_atlas = atlas[1]
            tangents = np.ascontiguousarray(tangent(self.system, q_atlas)[:, :, 0])
            self._atlas_slopes[branch] = (tangents, det_sign(self.system, self.system.jacobian(q_atlas)))
        return self._atlas_slopes[branch]

    def _atlas_predictions(self, atlas, c: np.ndarray):
        """Samples the atlas covers, their predicted configurations, and the atlas
        point before each (shifted by whole turns) for the branch check.

        Returns
        -------
        idx : ndarray of int
            Samples inside the feasible range (the others lie past a limit).
        guess : ndarray, shape (len(idx), n)
        anchor_q, anchor_c : ndarray, shapes (len(idx), n), (len(idx), 1)
        anchor : ndarray of int
            Index of the atlas point before each sample (for its determinant sign).
        """
        c_atlas, q_atlas, period = atlas
        x = c[:, 0]
        if period is None:
            turns = np.zeros_like(x)
            idx = np.flatnonzero((x >= c_atlas[0] - _PATH_TOLERANCE) & (x <= c_atlas[-1] + _PATH_TOLERANCE))
        else:
            turns = np.floor((x - c_atlas[0]) / (2.0 * math.pi))
            idx = np.arange(len(x))
        reduced = x[idx] - 2.0 * math.pi * turns[idx]
        scale = self.system.input_scale()[0]
        anchor = np.clip(np.searchsorted(c_atlas, reduced, side="right") - 1, 0, len(c_atlas) - 1)
        guess = _predict(
            self.system, c_atlas * scale, q_atlas, c_atlas[:, None], anchor, reduced * scale, reduced[:, None]
        )
        shift = 0.0 if period is None else turns[idx, None] * period
        return (
            idx,
            guess + shift,
            q_atlas[anchor] + shift,
            (c_atlas[anchor] + 2.0 * math.pi * turns[idx])[:, None],
            anchor,
        )

    def _shift_by_turns(self, branch: str, q: np.ndarray, c: np.ndarray, target: np.ndarray):
        """(q, c) moved by whole turns of periodic inputs to within half a turn of target."""
        for k, driver in enumerate(self.mechanism.drivers):
            turns = round((target[k] - c[k]) / (2.0 * math.pi))
            if driver.quantity != "angle" or turns == 0:
                continue
            if not self.input_range(k, branch).full_turn or (branch, k) not in self._turns:
                continue
            c = c.copy()
            c[k] += turns * 2.0 * math.pi
            q = q + turns * self._turns[(branch, k)]
        return q, c

    # -- sweeps -----------------------------------------------------------
    def solve(
        self,
        inputs,
        rates=None,
        accelerations=None,
        branch: str | None = None,
        waypoint_spacing: float = math.radians(2.0),
        compiled: bool | None = None,
    ) -> Solution:
        """Positions, velocities and accelerations over a sweep of inputs.

        Parameters
        ----------
        inputs, rates, accelerations : array_like, shape (N, k) or (N,) for k = 1
            Drivers' values (rad or m), rates (per s) and accelerations
            (per s^2), samples in the order the mechanism moves through them.
            Rates and accelerations default to zero.
        branch : str, optional
            Assembly branch (default: the model file's first).
        waypoint_spacing : float
            For mechanisms with several inputs: input distance (rad; slides
            per mechanism size) between the waypoints tracked one by one by
            continuation. A one-input mechanism needs no waypoints: its branch
            is mapped once (the feasible-range walk) and every sample is
            predicted from that map.
        compiled : bool, optional
            True runs the numba-compiled sweep (:mod:`._compiled`: one sample
            at a time, working memory flat in N, each Jacobian factorised once;
            5x faster on the four-bar); False the batched NumPy reference it is
            tested against. Both give the same statuses and iterations, and
            results equal to round-off (not bit for bit). The default compiles
            sweeps of at least ``COMPILED_FROM`` samples: loading the compiled
            kernels from numba's cache costs 0.8 s per process on this 2-core
            machine (compiling them, once per install, 23 s), which smaller
            sweeps do not win back, and their results
            (the committed reports) stay those of the reference.

        Returns
        -------
        Solution
        """
        name = self._branch_name(branch)
        c = self.input_array(inputs)
        cd = np.zeros_like(c) if rates is None else self.input_array(rates, c.shape)
        cdd = np.zeros_like(c) if accelerations is None else self.input_array(accelerations, c.shape)
        if compiled is None:
            compiled = c.shape[0] >= COMPILED_FROM
        if compiled:
            return self._solve_compiled(name, c, cd, cdd, waypoint_spacing)
        system = self.system
        n_samples = c.shape[0]

        q = np.full((n_samples, system.n), np.nan)
        residual = np.full(n_samples, np.inf)
        iterations = np.zeros(n_samples, dtype=int)
        status = np.full(n_samples, Status.NOT_CONVERGED, dtype=np.int8)
        jac = np.zeros((n_samples, system.n_rows, system.n))  # Phi_q where solved
        prediction = self._predictions(name, c, waypoint_spacing)
        if prediction is not None:
            # 2. every sample in one batch, predicted from the anchors around it
            idx, guess, base_q, base_c, base_sign = prediction
            q_i, res_i, it_i, ok_i = newton(system, guess, c[idx])
            # stayed on the branch: small correction, same determinant sign as the anchor
            correction = np.max(np.abs((q_i - guess) * system.coordinate_scale()), axis=1)
            jac_i = system.jacobian(q_i)
            sign = det_sign(system, jac_i)
            on_branch = (correction <= MAX_CORRECTION) & ((sign == base_sign) | (sign == 0))
            accept = ok_i & on_branch
            q[idx[accept]] = q_i[accept]
            jac[idx[accept]] = jac_i[accept]
            residual[idx] = res_i
            iterations[idx] = it_i
            status[idx[accept]] = Status.OK
            status[idx[ok_i & ~on_branch]] = Status.BRANCH_JUMP
            # 3. the few that failed in the batch: walk to them from their anchor
            for j in np.flatnonzero(~accept):
                i = idx[j]
                q_new, _, reached, _ = continue_to(system, base_q[j], base_c[j], c[i])
                if reached:
                    q[i], status[i] = q_new, Status.OK
                    jac[i] = system.jacobian(q_new[None])[0]
                    residual[i] = system.residual_metres(system.residual(q_new[None], c[i][None]))[0]

        # 4. velocities and accelerations
        qd = np.full_like(q, np.nan)
        qdd = np.full_like(q, np.nan)
        singularity = np.zeros(n_samples)
        done = np.flatnonzero(status == Status.OK)
        if done.size:
            q[done] = polish(system, q[done], c[done], jac[done])
            jac[done] = system.jacobian(q[done])
            # with the dimensionless Jacobian S = D_r J C^-1 (rows per size,
            # coordinates per size), J^-1 b = C^-1 S^-1 D_r b
            inverse, singularity[done] = _inverse_with_condition(system.scaled_jacobian(jac[done]))
            row_scale = np.where(system.row_is_angle, 1.0, 1.0 / system.size)
            coordinate_scale = system.coordinate_scale()

            def apply_inverse(rhs):
                return np.einsum("nij,nj->ni", inverse, rhs * row_scale) / coordinate_scale

            qd[done] = apply_inverse(system.velocity_rhs(cd[done]))
            qdd[done] = apply_inverse(system.gamma(q[done], qd[done], cdd[done]))
            near = done[singularity[done] < NEAR_SINGULAR]
            status[near] = Status.NEAR_SINGULAR
            flat = done[singularity[done] < SINGULAR]
            status[flat] = Status.SINGULAR
            qd[flat] = qdd[flat] = np.nan
        return Solution(self, name, c, cd, cdd, q, qd, qdd, status, residual, singularity, iterations)

    def _solve_compiled(
        self, name: str, c: np.ndarray, cd: np.ndarray, cdd: np.ndarray, waypoint_spacing: float
    ) -> Solution:
        """:meth:`solve` through the compiled kernels of :mod:`._compiled`.

        The steps of the reference, sample by sample: the prediction (from the
        atlas in compiled code, or from continuation through waypoints), Newton
        in rounds, the branch check, the continuation walk for the few rejected
        samples, then velocities and accelerations from one LU per sample.
        Working memory besides the results: O(n^2) scratch and 5 bytes a
        sample (which samples are attempted, the branch's determinant sign).
        """
        from .._numba import run_compiled
        from . import _compiled

        fast: Any = _compiled  # numba's dispatchers carry no signatures for mypy
        system = self.system
        if self._packed is None:
            self._packed = fast.Packed(system)
        packed = self._packed
        terms = packed.terms()
        c, cd, cdd = (np.ascontiguousarray(a, dtype=float) for a in (c, cd, cdd))
        n_samples = c.shape[0]
        q = np.full((n_samples, system.n), np.nan)
        qd = np.full_like(q, np.nan)  # holds the predictions until the velocities overwrite them
        qdd = np.full_like(q, np.nan)
        residual = np.full(n_samples, np.inf)
        iterations = np.zeros(n_samples, dtype=int)
        status = np.full(n_samples, Status.NOT_CONVERGED, dtype=np.int8)
        singularity = np.zeros(n_samples)
        base_sign = np.zeros(n_samples, dtype=np.float32)  # +-1, 0 or NaN: exact in float32
        atlas = self._atlas(name)
        prediction = None
        if atlas is not None:
            c_atlas, q_atlas, period = atlas
            tangents, signs = self._atlas_tangents_and_signs(name, atlas)
            inside = run_compiled(
                fast.predict_atlas,
                c,
                c_atlas,
                q_atlas,
                tangents,
                np.zeros(system.n) if period is None else period,
                period is not None,
                float(system.input_scale()[0]),
                _PATH_TOLERANCE,
                q,
                qd,
                base_sign,
                signs,
            )
            attempt = inside
        else:
            prediction = self._predictions(name, c, waypoint_spacing)
            attempt = np.zeros(n_samples, dtype=bool)
            if prediction is not None:
                idx = prediction[0]
                attempt[idx] = True
                q[idx] = qd[idx] = prediction[1]
                base_sign[idx] = prediction[4]
        structure = packed.structure()  # dense or banded Phi_q
        metres, stop = packed.metres, STOP_TOLERANCE * system.size
        run_compiled(fast.newton_rounds, q, c, attempt, *terms, *structure, metres, stop, 30, residual, iterations)
        assembled = np.empty(n_samples, dtype=bool)
        tolerances = (CONVERGED_TOLERANCE * system.size, ANGLE_ROUNDOFF * system.size)
        run_compiled(fast.assembled, q, residual, attempt, *tolerances, assembled)
        assembled &= residual <= LARGEST_CONVERGED * system.size  # the cap of converged_tolerance
        converged = np.flatnonzero(assembled)
        for start in range(0, converged.size, POLISH_CHUNK):  # polish, as the reference's step 4
            chunk = converged[start : start + POLISH_CHUNK]
            run_compiled(fast.correct, q, chunk, long_double_residual(system, q[chunk], c[chunk]), *terms, *structure)
        kernel_terms = (*terms[:3], *terms[4:])  # no angle offsets
        rest = (packed.jacobian_scale, packed.row_scale, packed.coordinate_scale, *kernel_terms, *structure)
        limits = (system.n_kinematic, NEAR_SINGULAR, SINGULAR, status, singularity)
        run_compiled(
            fast.check_and_finish, q, qd, qdd, cd, cdd, attempt, assembled, MAX_CORRECTION, base_sign, *rest, *limits
        )
        # the few rejected in the batch: walk to them from their anchor
        failed = np.flatnonzero(attempt & (status >= Status.NOT_CONVERGED))
        if failed.size:
            if prediction is None:
                _, _, base_q, base_c, _ = self._atlas_predictions(atlas, c[failed])
            else:
                at = np.searchsorted(prediction[0], failed)
                base_q, base_c = prediction[2][at], prediction[3][at]
            reached = []
            for j, i in enumerate(failed):
                q_new, _, ok, _ = continue_to(system, base_q[j], base_c[j], c[i])
                if ok:
                    q[i], status[i] = polish(system, q_new[None], c[i][None])[0], Status.OK
                    residual[i] = system.residual_metres(system.residual(q_new[None], c[i][None]))[0]
                    reached.append(i)
            run_compiled(fast.finish, q, qd, qdd, cd, cdd, np.array(reached, dtype=np.intp), *rest, *limits)
        return Solution(self, name, c, cd, cdd, q, qd, qdd, status, residual, singularity, iterations)

    def _predictions(self, branch: str, c: np.ndarray, waypoint_spacing: float):
        """Predicted configurations of the samples that can assemble, from the
        branch's atlas (one input) or from continuation through waypoints.

        Returns
        -------
        (idx, guess, anchor_q, anchor_c, anchor_sign) or None
            Attempted samples, their predictions (len(idx), n), the assembled
            configuration and inputs each was predicted from, and the sign of
            det Phi_q there; None when no sample can be reached.
        """
        system = self.system
        atlas = self._atlas(branch)
        if atlas is not None:
            idx, guess, base_q, base_c, anchor = self._atlas_predictions(atlas, c)
            _, signs = self._atlas_tangents_and_signs(branch, atlas)
            return idx, guess, base_q, base_c, signs[anchor]
        n_samples = c.shape[0]
        path = np.concatenate([[0.0], np.cumsum(np.max(np.abs(np.diff(c, axis=0)) * system.input_scale(), axis=1))])
        bins = np.floor(path / waypoint_spacing)
        waypoints = np.flatnonzero(np.concatenate([[True], bins[1:] != bins[:-1]]))
        if waypoints[-1] != n_samples - 1:
            waypoints = np.append(waypoints, n_samples - 1)
        anchors, covered = self._walk_waypoints(branch, c, path, waypoints)
        if not anchors:
            return None
        anchors.sort(key=lambda a: a[0])
        anchor_path, anchor_q, anchor_c = (np.array([a[i] for a in anchors]) for i in range(3))
        # only samples on stretches of the sweep that continuation reached are attempted:
        # the others lie past a limit position
        lows, highs = (np.array(v) for v in zip(*sorted(covered)))
        highs = np.maximum.accumulate(highs)
        slot = np.searchsorted(lows, path + _PATH_TOLERANCE, side="right") - 1
        idx = np.flatnonzero((slot >= 0) & (path <= highs[np.maximum(slot, 0)] + _PATH_TOLERANCE))
        anchor = np.clip(np.searchsorted(anchor_path, path[idx], side="right") - 1, 0, None)
        guess = _predict(system, anchor_path, anchor_q, anchor_c, anchor, path[idx], c[idx])
        signs = det_sign(system, system.jacobian(anchor_q))
        return idx, guess, anchor_q[anchor], anchor_c[anchor], signs[anchor]

    def _walk_waypoints(self, branch: str, c: np.ndarray, path: np.ndarray, waypoints: np.ndarray):
        """Continuation from the reference configuration through the waypoints.

        Returns
        -------
        anchors : list of (path position, q, c)
            Assembled configurations on the sweep's path: the waypoints and
            every step taken between them.
        covered : list of (low, high)
            Stretches of the path that continuation walked; the rest lies past
            a limit position.
        """
        system = self.system
        anchors, covered = [], []
        q_last, c_last = self.assemble(branch), self.reference_inputs()
        previous = None  # the waypoint the mechanism stands at, if any
        stop = None  # input where the last walk met a limit (one-input sweeps)
        for j, i in enumerate(waypoints):
            if stop is not None and system.n_drivers == 1:
                ahead, to_stop = c[i, 0] - c_last[0], stop - c_last[0]
                if ahead * to_stop > 0.0 and abs(ahead) >= abs(to_stop):
                    continue  # behind the same limit position as the last failed walk
            q_start, c_start = self._shift_by_turns(branch, q_last, c_last, c[i])
            if not np.array_equal(c_start, c_last):  # jumped whole turns: not along the path
                previous = None
            q_new, c_new, reached, trail = continue_to(system, q_start, c_start, c[i])
            if previous is not None:  # walked along the sweep's own path
                p0, length = path[previous], path[i] - path[previous]
                for fraction, q_step in trail:
                    anchors.append((p0 + fraction * length, q_step, c[previous] + fraction * (c[i] - c[previous])))
                covered.append((p0, p0 + (trail[-1][0] if trail else 0.0) * length))
            elif reached:  # arrived from elsewhere: cover the way back to the last waypoint
                anchors.append((path[i], q_new, c[i]))
                covered.append((path[i], path[i]))
                if j > 0 and i - 1 > waypoints[j - 1]:  # samples lie between the two waypoints
                    back = waypoints[j - 1] + 1
                    _, _, _, trail_back = continue_to(system, q_new, c[i], c[back])
                    length = path[i] - path[back]
                    for fraction, q_step in trail_back:
                        anchors.append((path[i] - fraction * length, q_step, c[i] + fraction * (c[back] - c[i])))
                    covered.append((path[i] - (trail_back[-1][0] if trail_back else 0.0) * length, path[i]))
            if reached:
                q_last, c_last, previous, stop = q_new, c[i], i, None
            else:
                previous, stop = None, float(c_new[0])
        return anchors, covered

    def input_array(self, values, shape=None) -> np.ndarray:
        """Inputs (or their rates or accelerations) as an array of shape (N, k):
        (N,) is N samples of a one-input mechanism, (k,) one sample.

        Raises
        ------
        ValueError
            If the shape does not fit (or differs from ``shape``).
        """
        k = self.system.n_drivers
        arr = np.asarray(values, dtype=float)
        if arr.ndim == 0:
            arr = arr.reshape(1, 1)
        if arr.ndim == 1:
            arr = arr[:, None] if k == 1 else arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != k or (shape is not None and arr.shape != shape):
            raise ValueError(f"expected inputs of shape (N, {k}), found {np.shape(values)}")
        return arr
