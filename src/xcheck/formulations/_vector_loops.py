"""Formulation II: relative coordinates solved loop after loop by the
complex-number method (seed 000, formulation II; seed 004).

The unknowns are the bodies' angles and the slides of the prismatic and
pin-in-slot joints. Each closed chain of joints gives a vector loop
``sum r e^{i phi} = 0`` whose vectors are read off the canonical model:

- along a body, from the point of the joint it is entered by to the point of
  the joint it is left by: a fixed vector of the body's frame, turned by the
  body's angle (constant length, angle tied to the body);
- across a prismatic or pin-in-slot joint, from its line point to its sliding
  point: ``s`` times the line's unit direction, turned by the angle of the body
  that carries the line (variable length, angle tied to the line's body);
- across a revolute joint: nothing (its two points coincide).

Bodies whose angles are tied (a prismatic joint locks ``phi_b - phi_a``, a
driven revolute prescribes it) share one unknown angle. Loops are taken one
after another, each with exactly two unknowns not found by the loops before it,
and solved in closed form as the seeds do: two angles (the triangle, cosine
law), a length and an angle (a quadratic), or two lengths (linear). Velocities
and accelerations come from differentiating each loop once and twice: a linear
2 x 2 system per loop. When no such order of loops exists the mechanism is not
dyadic and the formulation does not apply.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..errors import NotApplicable
from ..kinematics import Kinematics
from ..model import Mechanism, PinInSlot, Prismatic, Revolute
from ..results import Trajectory
from ._common import (
    Frame,
    as_inputs,
    body_frames_from_q,
    build_trajectory,
    status_from_singularity,
    wrap,
)

__all__ = ["SOURCE", "LoopPlan", "plan_loops", "solve_vector_loops"]

SOURCE = "formulation-II"
#: Simple cycles searched at most (a planar linkage has a handful).
_MAX_CYCLES = 5000
#: A body's loop vector shorter than this fraction of the mechanism's size is
#: a zero vector (two joints at one place): it carries no unknown.
_ZERO_LENGTH = 1e-12
#: At the reference inputs the chosen root must reproduce the general solver's
#: assembly to this (rad, or slide / size); a larger gap is a bug, not a branch.
_BRANCH_MATCH = 1e-6


@dataclass(frozen=True)
class _Term:
    """One vector ``l e^{i phi_body} w`` of a loop or of a path from the ground.

    Attributes
    ----------
    body : str
        The body whose angle turns the vector (the ground: a fixed vector).
    w : complex
        The vector in that body's frame, m; for a slide, its signed unit direction.
    slide : str or None
        The joint whose slide ``l`` (m) multiplies ``w``; None: ``l = 1``.
    text : str
        The vector named by point labels, e.g. ``"A→C [coupler]"``.
    """

    body: str
    w: complex
    slide: str | None
    text: str


@dataclass(frozen=True)
class _Loop:
    """A vector loop, its two unknowns (``("angle", root body)`` or
    ``("slide", joint)``), and the closed-form case that solves it."""

    terms: tuple[_Term, ...]
    unknowns: tuple[tuple[str, str], tuple[str, str]]
    case: str  # "two angles", "length and angle", "two lengths"

    def describe(self, plan: "LoopPlan") -> str:
        names = ", ".join(plan.unknown_name(u) for u in self.unknowns)
        return f"{' + '.join(t.text for t in self.terms)} = 0; unknowns {names} ({self.case})"


@dataclass
class LoopPlan:
    """How formulation II solves a mechanism: angle ties, loops in solving
    order, and the tree of joints that places every body from the ground.

    Attributes
    ----------
    root : dict of str to str
        Each body's angle class, named by its root body (the ground's class is
        known: angle 0).
    offset : dict of str to (float, ndarray of shape (k,))
        ``phi_body = theta_root + const + coef . inputs`` (rad).
    slides : dict of str to int or None
        Each prismatic / pin-in-slot joint and its driver index (None: unknown).
    loops : list of _Loop
        In solving order.
    tree : list of (joint, parent body, child body)
        Parents first.
    """

    mechanism: Mechanism
    root: dict
    offset: dict
    slides: dict
    loops: list = field(default_factory=list)
    tree: list = field(default_factory=list)

    def unknown_name(self, unknown: tuple[str, str]) -> str:
        kind, name = unknown
        if kind == "slide":
            return f"s({name})"
        members = [b for b, r in self.root.items() if r == name]
        return f"phi({name})" + (f" (with {', '.join(m for m in members if m != name)})" if len(members) > 1 else "")

    def describe(self) -> list[str]:
        """The loops in solving order, one line each."""
        return [f"loop {i + 1}: {loop.describe(self)}" for i, loop in enumerate(self.loops)]


# -- planning -------------------------------------------------------------


def _fail(mech: Mechanism, reason: str):
    raise NotApplicable(reason)


def _angle_ties(mech: Mechanism):
    """Angle classes: bodies whose relative angle is locked (prismatic) or
    prescribed (driven revolute) share one unknown angle."""
    k = len(mech.drivers)
    edges: dict[str, list] = {b.name: [] for b in mech.bodies}

    def tie(a: str, b: str, const: float, coef: np.ndarray, why: str):
        # phi_b = phi_a + const + coef . c
        edges[a].append((b, const, coef, why))
        edges[b].append((a, -const, -coef, why))

    for joint in mech.joints:
        if isinstance(joint, Prismatic):
            tie(joint.body_a, joint.body_b, joint.angle, np.zeros(k), f"prismatic {joint.name}")
    for index, driver in enumerate(mech.drivers):
        joint = mech.joint(driver.joint)
        if isinstance(joint, Revolute):
            tie(joint.body_a, joint.body_b, 0.0, np.eye(k)[index], f"driver {driver.name}")
    root, offset = {}, {}
    for start in [b.name for b in mech.bodies]:  # ground first: it roots its class
        if start in root:
            continue
        root[start], offset[start] = start, (0.0, np.zeros(k))
        queue = deque([start])
        while queue:
            a = queue.popleft()
            const_a, coef_a = offset[a]
            for b, const, coef, why in edges[a]:
                want = (const_a + const, coef_a + coef)
                if b not in root:
                    root[b], offset[b] = start, want
                    queue.append(b)
                elif abs(wrap(offset[b][0] - want[0])) > 1e-12 or not np.array_equal(offset[b][1], want[1]):
                    _fail(mech, f"the angle ties close on themselves inconsistently at {why}")
    return root, offset


def _joint_point(mech: Mechanism, joint, body: str) -> tuple[str, complex]:
    """The label and body-frame position (m) of a joint's point on one of its bodies."""
    if isinstance(joint, Revolute):
        label = joint.point_a if body == joint.body_a else joint.point_b
    else:
        label = joint.line_point if body == joint.body_a else joint.point
    s = mech.body(body).points[label]
    return label, complex(s[0], s[1])


def _simple_cycles(mech: Mechanism) -> list[list[tuple[int, str, str]]]:
    """Every simple cycle of the body graph (bodies as nodes, joints as edges),
    each as a list of (joint index, from body, to body); cycles through the
    ground start at the ground."""
    order = {b.name: i for i, b in enumerate(mech.bodies)}
    adjacent: dict[str, list] = {b.name: [] for b in mech.bodies}
    for j, joint in enumerate(mech.joints):
        adjacent[joint.body_a].append((j, joint.body_b))
        adjacent[joint.body_b].append((j, joint.body_a))
    seen, cycles = set(), []
    for start in [b.name for b in mech.bodies]:
        stack: list[tuple[str, list[tuple[int, str, str]], set[str]]] = [(start, [], {start})]
        while stack:
            node, path, visited = stack.pop()
            for j, nxt in reversed(adjacent[node]):  # the stack pops them in joint order
                if path and j == path[-1][0]:
                    continue
                if nxt == start and path:
                    cycle = path + [(j, node, nxt)]
                    key = frozenset(e[0] for e in cycle)
                    if key not in seen:
                        seen.add(key)
                        cycles.append(cycle)
                        if len(cycles) > _MAX_CYCLES:
                            _fail(mech, f"more than {_MAX_CYCLES} loops to search")
                elif nxt not in visited and order[nxt] > order[start]:
                    stack.append((nxt, path + [(j, node, nxt)], visited | {nxt}))
    ground = mech.ground.name
    cycles.sort(key=lambda c: (len(c), c[0][1] != ground, sorted(e[0] for e in c)))
    return cycles


def _loop_terms(mech: Mechanism, cycle) -> tuple[_Term, ...]:
    """The vectors of a cycle: across each joint, then along the body it enters
    up to the joint that leaves it."""
    terms = []
    joints = mech.joints
    for index, (j, u, v) in enumerate(cycle):
        joint = joints[j]
        if not isinstance(joint, Revolute):
            d = complex(joint.direction[0], joint.direction[1])
            sign = 1.0 if u == joint.body_a else -1.0
            q_label, p_label = joint.line_point, joint.point
            text = (
                f"{q_label}→{p_label} [slide {joint.name}]" if sign > 0 else f"{p_label}→{q_label} [slide {joint.name}]"
            )
            terms.append(_Term(joint.body_a, sign * d, joint.name, text))
        next_joint = joints[cycle[(index + 1) % len(cycle)][0]]
        label_in, p_in = _joint_point(mech, joint, v)
        label_out, p_out = _joint_point(mech, next_joint, v)
        if abs(p_out - p_in) > _ZERO_LENGTH * mech.size:
            terms.append(_Term(v, p_out - p_in, None, f"{label_in}→{label_out} [{v}]"))
    return tuple(terms)


def _appearing(terms, root, unknown_classes, unknown_slides) -> set:
    found = set()
    for t in terms:
        if root[t.body] in unknown_classes:
            found.add(("angle", root[t.body]))
        if t.slide is not None and t.slide in unknown_slides:
            found.add(("slide", t.slide))
    return found


def _case(unknowns) -> str:
    kinds = sorted(u[0] for u in unknowns)
    if kinds == ["angle", "angle"]:
        return "two angles"
    if kinds == ["slide", "slide"]:
        return "two lengths"
    return "length and angle"


def _tree(mech: Mechanism) -> list[tuple]:
    """A spanning tree of joints from the ground, parents first."""
    placed, tree = {mech.ground.name}, []
    queue = deque([mech.ground.name])
    while queue:
        u = queue.popleft()
        for joint in mech.joints:
            if u in (joint.body_a, joint.body_b):
                v = joint.body_b if u == joint.body_a else joint.body_a
                if v not in placed:
                    placed.add(v)
                    tree.append((joint, u, v))
                    queue.append(v)
    return tree


def plan_loops(mechanism: Mechanism) -> LoopPlan:
    """The loops that solve a mechanism one after another, two unknowns each.

    Raises
    ------
    NotApplicable
        If no order of loops with two new unknowns each determines every
        body angle and slide (a non-dyadic mechanism), a body is not
        connected to the ground, or a joint couples motions (a gear pair).
    """
    mech = mechanism
    coupled = [j for j in mech.joints if not isinstance(j, (Revolute, Prismatic, PinInSlot))]
    if coupled:
        _fail(mech, f"a {coupled[0].kind} joint ({coupled[0].name}): vector loops hold revolute, prismatic and "
              "pin-in-slot joints only")  # fmt: skip
    root, offset = _angle_ties(mech)
    driven = {d.joint: i for i, d in enumerate(mech.drivers)}
    slides = {j.name: driven.get(j.name) for j in mech.joints if isinstance(j, (Prismatic, PinInSlot))}
    plan = LoopPlan(mech, root, offset, slides, tree=_tree(mech))
    if len(plan.tree) != len(mech.moving_bodies):
        _fail(mech, "a body is not connected to the ground")
    unknown_classes = {r for b, r in root.items() if r != root[mech.ground.name]}
    unknown_slides = {name for name, k in slides.items() if k is None}
    candidates = [_loop_terms(mech, c) for c in _simple_cycles(mech)]
    while unknown_classes or unknown_slides:
        counts = []
        for terms in candidates:
            found = _appearing(terms, root, unknown_classes, unknown_slides)
            if len(found) == 2:
                unknowns = tuple(sorted(found))
                plan.loops.append(_Loop(terms, unknowns, _case(unknowns)))
                unknown_classes -= {u[1] for u in found if u[0] == "angle"}
                unknown_slides -= {u[1] for u in found if u[0] == "slide"}
                candidates.remove(terms)
                break
            counts.append(len(found))
        else:
            left = ", ".join(
                sorted(plan.unknown_name(("angle", c)) for c in unknown_classes)
                + sorted(f"s({s})" for s in unknown_slides)
            )
            solved = f"after {len(plan.loops)} loop(s) with two unknowns each, " if plan.loops else ""
            most = [n for n in counts if n > 0]
            if most and min(most) > 2:
                _fail(
                    mech,
                    f"not dyadic: {solved}every remaining loop has {min(most)} or more unknowns "
                    f"(of {left}): the loops must be solved simultaneously",
                )
            _fail(
                mech,
                f"{solved}{left} cannot be found two at a time from any loop "
                f"(loops with {sorted(set(counts))} unknowns)",
            )
    return plan


# -- solving --------------------------------------------------------------


class _State:
    """Angles of the classes and slides over N samples, with their first and
    second time derivatives; unknown ones start at zero."""

    def __init__(self, plan: LoopPlan, c, cd, cdd):
        self.plan, self.c, self.cd, self.cdd = plan, c, cd, cdd
        n = c.shape[0]
        self.theta = {r: np.zeros((3, n)) for r in set(plan.root.values())}
        self.slide = {}
        for name, k in plan.slides.items():
            self.slide[name] = np.stack([c[:, k], cd[:, k], cdd[:, k]]) if k is not None else np.zeros((3, n))

    def angle(self, body: str) -> np.ndarray:
        """(phi, phi_dot, phi_ddot) of a body, shape (3, N)."""
        const, coef = self.plan.offset[body]
        theta = self.theta[self.plan.root[body]]
        return theta + np.stack([const + self.c @ coef, self.cd @ coef, self.cdd @ coef])

    def length(self, term: _Term) -> np.ndarray:
        """(l, l_dot, l_ddot) of a term, shape (3, N)."""
        if term.slide is None:
            n = self.c.shape[0]
            return np.stack([np.ones(n), np.zeros(n), np.zeros(n)])
        return self.slide[term.slide]

    def term(self, t: _Term):
        """A term's value, first and second time derivatives (complex, (N,))."""
        phi, phid, phidd = self.angle(t.body)
        l, ld, ldd = self.length(t)
        e = np.exp(1j * phi) * t.w
        return l * e, (ld + 1j * l * phid) * e, (ldd + 2j * ld * phid + 1j * l * phidd - l * phid**2) * e

    def set(self, unknown, order: int, values):
        """Set an unknown's value (order 0), rate (1) or acceleration (2), (N,) or scalar."""
        kind, name = unknown
        (self.theta if kind == "angle" else self.slide)[name][order] = values


def _pieces(loop: _Loop, state: _State):
    """The loop at the current state, split by its unknowns:
    ``K + sum_theta e^{i theta} (C_theta + s D_theta) + s D_known = 0``.

    Returns
    -------
    k_sum : ndarray of complex, shape (N,)
        The known vectors' sum K, m.
    angles, slides : list of str
        The unknown angle classes (root bodies) and unknown slides (joints).
    c_of, d_theta : dict of str to ndarray of complex, shape (N,)
        Per unknown angle: its fixed-length vectors C (m) and the unit
        direction D of an unknown slide it turns, both at theta = 0.
    d_known : dict of str to ndarray of complex, shape (N,)
        Per unknown slide whose line's angle is known: its unit direction.
    """
    plan = state.plan
    angle_unknowns = [u[1] for u in loop.unknowns if u[0] == "angle"]
    slide_unknowns = [u[1] for u in loop.unknowns if u[0] == "slide"]
    n = state.c.shape[0]
    zero = np.zeros(n, dtype=complex)
    k_sum = zero.copy()
    c_of = {r: zero.copy() for r in angle_unknowns}
    d_theta = {r: zero.copy() for r in angle_unknowns}
    d_known = {s: zero.copy() for s in slide_unknowns}
    for t in loop.terms:
        r = plan.root[t.body]
        const, coef = plan.offset[t.body]
        turned = np.exp(1j * (const + state.c @ coef)) * t.w  # w turned by the body's offset from its root
        unknown_length = t.slide in slide_unknowns
        length = 1.0 if t.slide is None or unknown_length else state.slide[t.slide][0]
        if r in angle_unknowns:
            if unknown_length:
                d_theta[r] = d_theta[r] + turned
            else:
                c_of[r] = c_of[r] + length * turned
        else:
            value = np.exp(1j * state.theta[r][0]) * turned
            if unknown_length:
                assert t.slide is not None  # it is one of slide_unknowns
                d_known[t.slide] = d_known[t.slide] + value
            else:
                k_sum = k_sum + length * value
    return k_sum, angle_unknowns, slide_unknowns, c_of, d_theta, d_known


def _quadratic(b_half: np.ndarray, c0: np.ndarray, sigma: float):
    """The root -b_half + sigma sqrt(b_half^2 - c0) of s^2 + 2 b_half s + c0 = 0,
    and where it is real (N,)."""
    disc = b_half**2 - c0
    ok = disc >= 0.0
    return -b_half + sigma * np.sqrt(np.where(ok, disc, 0.0)), ok


def _solve_position(loop: _Loop, state: _State, sigma: float):
    """The loop's two unknowns in closed form on branch ``sigma`` (+1 or -1).

    Returns
    -------
    values : list of two ndarrays, shape (N,)
        In the order of ``loop.unknowns``.
    ok : ndarray of bool, shape (N,)
        False where the loop does not close (the mechanism does not assemble).
    """
    k_sum, angles, slides, c_of, d_theta, d_known = _pieces(loop, state)
    p = -k_sum
    result = {}
    if loop.case == "two angles":
        # a e^{i psi1} + b e^{i psi2} = P: cosine law in the triangle (a, b, |P|)
        (r1, r2) = angles
        a, b, dist = np.abs(c_of[r1]), np.abs(c_of[r2]), np.abs(p)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_gamma = (a * a + dist * dist - b * b) / (2.0 * a * dist)
        ok = np.abs(cos_gamma) <= 1.0
        psi1 = np.angle(p) + sigma * np.arccos(np.clip(cos_gamma, -1.0, 1.0))
        first = a * np.exp(1j * psi1)
        result[("angle", r1)] = psi1 - np.angle(c_of[r1])
        result[("angle", r2)] = np.angle(p - first) - np.angle(c_of[r2])
    elif loop.case == "length and angle":
        (r,), (s_name,) = angles, slides
        c, dt, dk = c_of[r], d_theta[r], d_known[s_name]
        if np.any(dt != 0):
            # e^{i theta}(C + s D) = P with |D| = 1: |C + s D| = |P|
            s, ok = _quadratic(np.real(c * np.conj(dt)), np.abs(c) ** 2 - np.abs(p) ** 2, sigma)
            theta = np.angle(p) - np.angle(c + s * dt)
        else:
            # e^{i theta} C = P - s D with |D| = 1: |P - s D| = |C|
            s, ok = _quadratic(-np.real(p * np.conj(dk)), np.abs(p) ** 2 - np.abs(c) ** 2, sigma)
            theta = np.angle(p - s * dk) - np.angle(c)
        result[("angle", r)], result[("slide", s_name)] = theta, s
    else:
        # s1 D1 + s2 D2 = P: linear (Cramer's rule)
        s1, s2 = slides
        d1, d2 = d_known[s1], d_known[s2]
        det = d1.real * d2.imag - d1.imag * d2.real
        ok = det != 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            result[("slide", s1)] = (p.real * d2.imag - p.imag * d2.real) / det
            result[("slide", s2)] = (d1.real * p.imag - d1.imag * p.real) / det
    ok = ok & np.all([np.isfinite(result[u]) for u in loop.unknowns], axis=0)
    return [result[u] for u in loop.unknowns], ok


def _derivative_columns(loop: _Loop, state: _State):
    """d(loop)/d(unknown rate) for the two unknowns, complex (N,) each."""
    columns = []
    for kind, name in loop.unknowns:
        col = np.zeros(state.c.shape[0], dtype=complex)
        for t in loop.terms:
            if kind == "angle" and state.plan.root[t.body] == name:
                col = col + 1j * state.term(t)[0]
            elif kind == "slide" and t.slide == name:
                phi = state.angle(t.body)[0]
                col = col + np.exp(1j * phi) * t.w
        columns.append(col)
    return columns


def _solve_rates(loop: _Loop, state: _State, order: int, size: float) -> np.ndarray:
    """Set the loop's unknown rates (order 1) or accelerations (order 2) from
    the differentiated loop; returns the inverse condition number (N,) of its
    dimensionless 2 x 2 matrix."""
    for u in loop.unknowns:
        state.set(u, order, 0.0)
    rhs = -sum(state.term(t)[order] for t in loop.terms)
    cols = _derivative_columns(loop, state)
    scale = [1.0 / size if kind == "angle" else 1.0 for kind, _ in loop.unknowns]  # m per rad -> 1
    a, b = cols[0].real * scale[0], cols[1].real * scale[1]
    c, d = cols[0].imag * scale[0], cols[1].imag * scale[1]
    det = a * d - b * c
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (rhs.real * d - rhs.imag * b) / det
        y = (a * rhs.imag - c * rhs.real) / det
        norm = np.maximum(np.abs(a) + np.abs(c), np.abs(b) + np.abs(d))
        inverse_norm = np.maximum(np.abs(d) + np.abs(c), np.abs(b) + np.abs(a)) / np.abs(det)
        inverse_condition = 1.0 / (norm * inverse_norm)
    state.set(loop.unknowns[0], order, x * scale[0])
    state.set(loop.unknowns[1], order, y * scale[1])
    return np.where(np.isfinite(inverse_condition), inverse_condition, 0.0)


def _reference_values(kinematics: Kinematics, plan: LoopPlan, branch: str | None) -> dict:
    """The unknowns' values in the general solver's assembled configuration."""
    mech = kinematics.mechanism
    frames = body_frames_from_q(kinematics, kinematics.assemble(branch))
    values = {}
    for body, r in plan.root.items():
        if r == body:
            values[("angle", body)] = frames[body][1]
    for name in plan.slides:
        joint = mech.joint(name)
        assert isinstance(joint, (Prismatic, PinInSlot))  # plan.slides names the line joints
        (ra, pa), (rb, pb) = frames[joint.body_a], frames[joint.body_b]
        q_local, p_local = mech.body(joint.body_a).points[joint.line_point], mech.body(joint.body_b).points[joint.point]
        rq = ra + np.exp(1j * pa) * complex(*q_local)
        rp = rb + np.exp(1j * pb) * complex(*p_local)
        d = np.exp(1j * pa) * complex(*joint.direction)
        values[("slide", name)] = float(np.real((rp - rq) * np.conj(d)))
    return values


def _choose_branches(kinematics: Kinematics, plan: LoopPlan, branch: str | None) -> list[float]:
    """Per loop, the root (+1 or -1) that reproduces the general solver's
    assembly of ``branch`` at the reference inputs."""
    reference = _reference_values(kinematics, plan, branch)
    c_ref = kinematics.reference_inputs()[None, :]
    state = _State(plan, c_ref, np.zeros_like(c_ref), np.zeros_like(c_ref))
    size = kinematics.mechanism.size
    signs = []
    for loop in plan.loops:
        gaps = {}
        for sigma in (1.0,) if loop.case == "two lengths" else (1.0, -1.0):
            values, ok = _solve_position(loop, state, sigma)
            gap = max(
                abs(float(wrap(v[0] - reference[u]))) if u[0] == "angle" else abs(v[0] - reference[u]) / size
                for u, v in zip(loop.unknowns, values)
            )
            gaps[sigma] = (gap if ok[0] else math.inf, values)
        sigma = min(gaps, key=lambda s: gaps[s][0])
        if gaps[sigma][0] > _BRANCH_MATCH:
            raise RuntimeError(
                f"{SOURCE}: {kinematics.mechanism.name}: no root of {loop.describe(plan)} "
                f"reproduces the general solver's assembly (closest off by {gaps[sigma][0]:.3g})"
            )
        for u, v in zip(loop.unknowns, gaps[sigma][1]):
            state.set(u, 0, v)
        signs.append(sigma)
    return signs


def solve_vector_loops(
    kinematics: Kinematics, inputs, rates=None, accelerations=None, branch: str | None = None
) -> Trajectory:
    """Formulation II over a sweep of inputs.

    Parameters
    ----------
    kinematics : Kinematics
        The general solver of the mechanism; only its model, its assembly at
        the reference inputs (to pick each loop's root) and its constraint
        residual (a diagnostic) are used.
    inputs, rates, accelerations : array_like, shape (N, k) or (N,) for k = 1
        Drivers' values (rad or m), rates (per s) and accelerations (per s^2).
    branch : str, optional
        Assembly branch (default: the model file's first).

    Returns
    -------
    Trajectory
        Source ``"formulation-II"``; ``diagnostics`` holds ``status`` (codes
        of :class:`~xcheck.kinematics.Status`), ``singularity`` (smallest
        inverse condition number of the loops' 2 x 2 matrices), ``residual``
        (m) and ``loop_closure`` (largest |sum of a loop's vectors|, m);
        ``settings["loops"]`` lists the loops in solving order.

    Raises
    ------
    NotApplicable
        If the mechanism cannot be solved loop after loop (see :func:`plan_loops`).
    """
    mech = kinematics.mechanism
    plan = plan_loops(mech)
    c, cd, cdd = as_inputs(kinematics, inputs, rates, accelerations)
    name = kinematics.branches[0] if branch is None else branch  # assemble() checks the name
    signs = _choose_branches(kinematics, plan, name)
    state = _State(plan, c, cd, cdd)
    n, size = c.shape[0], mech.size
    assembled = np.ones(n, dtype=bool)
    singularity = np.ones(n)
    closure = np.zeros(n)
    for loop, sigma in zip(plan.loops, signs):
        values, ok = _solve_position(loop, state, sigma)
        assembled &= ok
        for u, v in zip(loop.unknowns, values):
            state.set(u, 0, np.where(assembled, v, np.nan))
        closure = np.maximum(closure, np.abs(sum(state.term(t)[0] for t in loop.terms)))
        for order in (1, 2):
            condition = _solve_rates(loop, state, order, size)
        singularity = np.minimum(singularity, condition)
    frames = {mech.ground.name: Frame.fixed(n)}
    for joint, parent, child in plan.tree:
        # child origin = parent origin + (joint point on parent) + slide - (joint point on child)
        terms = [
            _Term(parent, _joint_point(mech, joint, parent)[1], None, ""),
            _Term(child, -_joint_point(mech, joint, child)[1], None, ""),
        ]
        if not isinstance(joint, Revolute):
            sign = 1.0 if parent == joint.body_a else -1.0
            terms.append(_Term(joint.body_a, sign * complex(*joint.direction), joint.name, ""))
        base = frames[parent]
        r, rd, rdd = base.r.copy(), base.rd.copy(), base.rdd.copy()
        for t in terms:
            value, first, second = state.term(t)
            r, rd, rdd = r + value, rd + first, rdd + second
        phi, phid, phidd = state.angle(child)
        frames[child] = Frame(r, rd, rdd, phi.copy(), phid.copy(), phidd.copy())
    status = status_from_singularity(assembled, singularity)
    described = plan.describe()
    notes = (
        f"{SOURCE} (relative coordinates, complex-number method): "
        + ("; ".join(described) if described else "no closed loop: every angle and slide is an input")
        + "; branch roots "
        + ", ".join("+" if s > 0 else "-" for s in signs)
        + f" match branch {name!r}"
    )
    return build_trajectory(
        kinematics,
        SOURCE,
        c,
        cd,
        cdd,
        frames,
        status,
        singularity,
        {"loop_closure": np.where(assembled, closure, np.nan)},
        notes,
        {"formulation": "II", "branch": name, "loops": described, "roots": signs},
    )
