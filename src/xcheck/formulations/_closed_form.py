"""Formulation I: one generalized coordinate (the crank angle) and direct
substitution (seed 000, formulation I).

Two mechanisms have such closed forms, and are recognised from the canonical
model's topology and geometry, whatever they are called:

- the four-bar: three moving bodies in one loop of four revolutes, the input a
  driven revolute at a ground pivot. The interior angles come from the seed's
  eq. (2)-(4): theta1 at the other ground pivot D from eq. (2), theta2 at C
  from the cosine law (3), theta3 at B from the angle sum (4). The
  quadrilateral may be re-entrant.
- the offset slider-crank: a driven crank on a ground pivot, a connecting rod,
  and the rod's far end B on a line fixed to the ground (a slider block on a
  prismatic joint, or the rod's pin in a ground slot), with
  ``x = r cos t + sqrt(l^2 - (e - r sin t)^2)`` along the line.

Velocities and accelerations are the closed forms differentiated analytically
(implicitly for eq. (2) and (3)). Everything else (all bodies' frames, all
named points) follows from these by rigid-body kinematics.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from ..errors import NotApplicable
from ..kinematics import Kinematics
from ..model import GROUND, Joint, Mechanism, PinInSlot, Prismatic, Revolute
from ..results import Trajectory
from ._common import (
    Frame,
    as_inputs,
    body_frames_from_q,
    build_trajectory,
    status_from_singularity,
    wrap,
)

__all__ = ["SOURCE", "recognise", "solve_closed_form"]

SOURCE = "formulation-I"
#: A link shorter than this fraction of the mechanism's size is degenerate.
_DEGENERATE = 1e-9
#: At the reference inputs the chosen root must reproduce the general solver's
#: assembly to this (rad, or length / size); a larger gap is a bug, not a branch.
_BRANCH_MATCH = 1e-6


def _local(mech: Mechanism, body: str, label: str) -> complex:
    s = mech.body(body).points[label]
    return complex(s[0], s[1])


def _joint_point(joint: Joint, body: str) -> str:
    """The label of a revolute's point on ``body``."""
    assert isinstance(joint, Revolute)  # the recognisers pass only the revolutes here
    return joint.point_a if body == joint.body_a else joint.point_b


def _other(joint, body: str) -> str:
    return joint.body_b if joint.body_a == body else joint.body_a


def _shown(mech: Mechanism, lengths) -> list[str]:
    """Lengths (m) as text in the file's display unit."""
    units = mech.units
    return [f"{x / units.length_factor:.6g} {units.length}" for x in lengths]


def _fail(mech: Mechanism, reason: str) -> NoReturn:
    raise NotApplicable(reason)


def _driven_crank(mech: Mechanism):
    """The one driven revolute at a ground pivot: (joint, crank body, sign)
    with crank frame angle = sign * input."""
    if len(mech.drivers) != 1:
        _fail(mech, f"{len(mech.drivers)} inputs; formulation I has one generalized coordinate")
    driver = mech.drivers[0]
    joint = mech.joint(driver.joint)
    if not isinstance(joint, Revolute):
        _fail(mech, f"the input is the slide of {joint.kind} joint {joint.name!r}, not a crank angle")
    if GROUND not in (joint.body_a, joint.body_b):
        _fail(mech, f"the driven revolute {joint.name!r} is not at a ground pivot")
    crank = _other(joint, GROUND)
    return joint, crank, (1.0 if joint.body_a == GROUND else -1.0)


def _joints_between(mech: Mechanism, a: str, b: str):
    return [j for j in mech.joints if {j.body_a, j.body_b} == {a, b}]


@dataclass(frozen=True)
class _FourBar:
    """A, D ground pivots (global, m); B crank-coupler, C coupler-rocker.
    ``local`` holds each body's joint points (body frame, m)."""

    mechanism: Mechanism
    crank: str
    coupler: str
    rocker: str
    sign: float
    a: complex
    d: complex
    local: dict  # (body, "A"|"B"|"C"|"D") -> complex
    labels: tuple[str, str, str, str]

    kind = "four-bar"

    @property
    def lengths(self):
        """r = AB, d = BC, s = DC, l = AD (m), the seed's names."""
        loc = self.local
        return (
            abs(loc[self.crank, "B"] - loc[self.crank, "A"]),
            abs(loc[self.coupler, "C"] - loc[self.coupler, "B"]),
            abs(loc[self.rocker, "C"] - loc[self.rocker, "D"]),
            abs(self.d - self.a),
        )

    def describe(self) -> str:
        r, d, s, l = _shown(self.mechanism, self.lengths)
        a, b, c, dd = self.labels
        return (
            f"four-bar {a}{b}{c}{dd}: crank {self.crank} {a}{b} = {r}, coupler {self.coupler} {b}{c} = {d}, "
            f"rocker {self.rocker} {dd}{c} = {s}, ground {a}{dd} = {l}; theta1 (at {dd}) from eq. (2), "
            f"theta2 (at {c}) from eq. (3), theta3 (at {b}) from eq. (4)"
        )

    def _crank_angle(self, c, cd, cdd):
        """The seed's phi: the crank AB from the ground line AD (rad), with rates."""
        loc = self.local
        gamma = cmath.phase(loc[self.crank, "B"] - loc[self.crank, "A"])
        beta = cmath.phase(self.d - self.a)
        return self.sign * c + gamma - beta, self.sign * cd, self.sign * cdd

    def thetas(self, c, cd, cdd, roots):
        """The seed's interior angles on the branch ``roots`` = (sigma1, sigma2).

        Parameters
        ----------
        c, cd, cdd : ndarray, shape (N,)
            The input (rad), its rate (rad/s) and acceleration (rad/s^2).

        Returns
        -------
        theta1, theta2, theta3 : ndarray, shape (3, N)
            Each angle (rad) with its first and second time derivatives.
        ok : ndarray of bool, shape (N,)
            False where the four-bar does not assemble.
        singularity : ndarray, shape (N,)
            |sin theta2|: 0 where coupler and rocker line up (a limit position).
        """
        r, d, s, l = self.lengths
        sigma1, sigma2 = roots
        phi, phid, phidd = self._crank_angle(c, cd, cdd)
        cos_phi, sin_phi = np.cos(phi), np.sin(phi)
        # eq. (2): P cos theta1 + Q sin theta1 + R = 0
        p = -2 * l * s + 2 * r * s * cos_phi
        q = -2 * r * s * sin_phi
        big_r = r * r + l * l + s * s - d * d - 2 * r * l * cos_phi
        ratio = -big_r / np.hypot(p, q)
        # eq. (3): cos theta2 = (s^2 + d^2 - r^2 - l^2 + 2 r l cos phi) / (2 d s)
        cos2 = (s * s + d * d - r * r - l * l + 2 * r * l * cos_phi) / (2 * d * s)
        ok = (np.abs(ratio) <= 1.0) & (np.abs(cos2) <= 1.0)
        t1 = np.arctan2(q, p) + sigma1 * np.arccos(np.clip(ratio, -1.0, 1.0))
        acos2 = np.arccos(np.clip(cos2, -1.0, 1.0))
        t2 = acos2 if sigma2 > 0 else 2 * math.pi - acos2
        t3 = 2 * math.pi - phi - t1 - t2  # eq. (4)
        # implicit derivatives of G(phi, theta1) = 0 (eq. 2) and H(phi, theta2) = 0 (eq. 3)
        s1p = np.sin(phi + t1)
        c1p = np.cos(phi + t1)
        g_t = 2 * l * s * np.sin(t1) - 2 * r * s * s1p
        g_p = 2 * r * l * sin_phi - 2 * r * s * s1p
        g_pp = 2 * r * l * cos_phi - 2 * r * s * c1p
        g_pt = -2 * r * s * c1p
        g_tt = 2 * l * s * np.cos(t1) - 2 * r * s * c1p
        with np.errstate(divide="ignore", invalid="ignore"):
            t1d = -g_p * phid / g_t
            t1dd = -(g_pp * phid**2 + 2 * g_pt * phid * t1d + g_tt * t1d**2 + g_p * phidd) / g_t
            h_p, h_t = 2 * r * l * sin_phi, -2 * d * s * np.sin(t2)
            h_pp, h_tt = 2 * r * l * cos_phi, -2 * d * s * np.cos(t2)
            t2d = -h_p * phid / h_t
            t2dd = -(h_pp * phid**2 + h_tt * t2d**2 + h_p * phidd) / h_t
        t3d, t3dd = -phid - t1d - t2d, -phidd - t1dd - t2dd
        return (np.stack([t1, t1d, t1dd]), np.stack([t2, t2d, t2dd]), np.stack([t3, t3d, t3dd]), ok, np.abs(np.sin(t2)))

    def reference_thetas(self, kinematics: Kinematics, branch: str):
        """theta1, theta2 (rad) in the general solver's assembly of ``branch``."""
        frames = body_frames_from_q(kinematics, kinematics.assemble(branch))
        rr, pr = frames[self.rocker]
        c_pt = rr + cmath.exp(1j * pr) * self.local[self.rocker, "C"]
        rc, pc = frames[self.crank]
        b_pt = rc + cmath.exp(1j * pc) * self.local[self.crank, "B"]
        theta1 = cmath.phase(self.a - self.d) - cmath.phase(c_pt - self.d)
        theta2 = cmath.phase(self.d - c_pt) - cmath.phase(b_pt - c_pt)
        return theta1, theta2

    def choose_roots(self, kinematics: Kinematics, branch: str) -> list[float]:
        """(sigma1, sigma2): the roots of eq. (2) and (3) that reproduce the
        general solver's assembly of ``branch`` at the reference input."""
        c_ref = kinematics.reference_inputs()[None, :]
        zero = np.zeros_like(c_ref)
        want = self.reference_thetas(kinematics, branch)
        roots = []
        for index in (0, 1):
            gaps = {}
            for sigma in (1.0, -1.0):
                trial = [1.0, 1.0]
                trial[index] = sigma
                values = self.thetas(c_ref[:, 0], zero[:, 0], zero[:, 0], trial)[index][0, 0]
                gaps[sigma] = abs(float(wrap(values - want[index])))
            best = min(gaps, key=gaps.__getitem__)
            if not gaps[best] <= _BRANCH_MATCH:
                raise RuntimeError(
                    f"{SOURCE}: {self.mechanism.name}: no root of theta{index + 1} reproduces "
                    f"the general solver's assembly (closest off by {gaps[best]:.3g} rad)"
                )
            roots.append(best)
        return roots

    def frames(self, c, cd, cdd, roots):
        """Every moving body's :class:`Frame`, the assembled flags, the
        singularity measure (N,) and the diagnostics theta1..3 (rad)."""
        th1, th2, th3, ok, singularity = self.thetas(c[:, 0], cd[:, 0], cdd[:, 0], roots)
        loc, n = self.local, c.shape[0]
        phi, phid, phidd = self._crank_angle(c[:, 0], cd[:, 0], cdd[:, 0])
        beta = cmath.phase(self.d - self.a)
        r = self.lengths[0]
        zero = np.zeros(n, dtype=complex)
        a = np.full(n, self.a, dtype=complex)
        d = np.full(n, self.d, dtype=complex)
        # crank: its frame turns with the input
        crank = Frame.through_point(
            a, zero, zero, self.sign * c[:, 0], self.sign * cd[:, 0], self.sign * cdd[:, 0], loc[self.crank, "A"]
        )
        # rocker: D -> C at beta + pi - theta1
        psi_r = beta + math.pi - th1[0]
        rocker = Frame.through_point(
            d,
            zero,
            zero,
            psi_r - cmath.phase(loc[self.rocker, "C"] - loc[self.rocker, "D"]),
            -th1[1],
            -th1[2],
            loc[self.rocker, "D"],
        )
        # coupler: B -> C at beta + phi + pi + theta3, through B = A + r e^{i(beta + phi)}
        ab = r * np.exp(1j * (beta + phi))
        b, bd, bdd = a + ab, 1j * phid * ab, (1j * phidd - phid**2) * ab
        psi_c = beta + phi + math.pi + th3[0]
        coupler = Frame.through_point(
            b,
            bd,
            bdd,
            psi_c - cmath.phase(loc[self.coupler, "C"] - loc[self.coupler, "B"]),
            phid + th3[1],
            phidd + th3[2],
            loc[self.coupler, "B"],
        )
        diagnostics = {
            "theta1": th1[0] % (2 * math.pi),
            "theta2": th2[0] % (2 * math.pi),
            "theta3": th3[0] % (2 * math.pi),
        }
        return {self.crank: crank, self.coupler: coupler, self.rocker: rocker}, ok, singularity, diagnostics


@dataclass(frozen=True)
class _SliderCrank:
    """Crank O-A, rod A-B, B on the ground line through ``l0`` (global, m)
    with unit direction ``u``; ``slider`` is the block body (None for a pin in
    a ground slot) turned by the constant ``slider_angle`` (rad)."""

    mechanism: Mechanism
    crank: str
    rod: str
    slider: str | None
    slider_angle: float
    sign: float
    o: complex
    l0: complex
    u: complex
    local: dict  # (body, "O"|"A"|"B") -> complex
    labels: tuple[str, str, str]

    kind = "slider-crank"

    @property
    def lengths(self):
        """r = OA, l = AB, e = offset of the line from O along i u (m)."""
        loc = self.local
        e = ((self.l0 - self.o) * self.u.conjugate()).imag
        return abs(loc[self.crank, "A"] - loc[self.crank, "O"]), abs(loc[self.rod, "B"] - loc[self.rod, "A"]), e

    def describe(self) -> str:
        r, l, e = _shown(self.mechanism, self.lengths)
        o, a, b = self.labels
        return (
            f"offset slider-crank {o}{a}{b}: crank {self.crank} {o}{a} = {r}, rod {self.rod} {a}{b} = {l}, "
            f"{b} on a ground line at offset e = {e} from {o}; x = r cos t + sqrt(l^2 - (e - r sin t)^2) "
            "along the line"
        )

    def _angle(self, c, cd, cdd):
        """t: the crank O->A from the line's direction (rad), with rates."""
        loc = self.local
        gamma = cmath.phase(loc[self.crank, "A"] - loc[self.crank, "O"])
        return self.sign * c + gamma - cmath.phase(self.u), self.sign * cd, self.sign * cdd

    def closed_form(self, c, cd, cdd, sigma):
        """x along the line from O's foot, the rod's angle from the line (rad),
        each with first and second time derivatives, (3, N); assembled flags
        and the singularity measure |cos| of the rod to the line, (N,)."""
        r, l, e = self.lengths
        t, td, tdd = self._angle(c, cd, cdd)
        v = e - r * np.sin(t)  # rod's extent across the line
        vd = -r * np.cos(t) * td
        vdd = r * np.sin(t) * td**2 - r * np.cos(t) * tdd
        ok = v * v <= l * l
        root = np.sqrt(np.where(ok, l * l - v * v, 0.0))  # rod's extent along the line (sigma: which way)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = r * np.cos(t) + sigma * root
            xd = -r * np.sin(t) * td - sigma * v * vd / root
            xdd = (
                -r * np.cos(t) * td**2
                - r * np.sin(t) * tdd
                - sigma * ((vd**2 + v * vdd) / root + v * v * vd**2 / root**3)
            )
            beta = np.arctan2(v, sigma * root)
            betad = sigma * vd / root
            betadd = sigma * (vdd / root + v * vd**2 / root**3)
        return np.stack([x, xd, xdd]), np.stack([beta, betad, betadd]), ok, root / l

    def choose_roots(self, kinematics: Kinematics, branch: str) -> list[float]:
        """[sigma]: the root of the closed form that puts B where the general
        solver's assembly of ``branch`` has it at the reference input."""
        frames = body_frames_from_q(kinematics, kinematics.assemble(branch))
        rr, pr = frames[self.rod]
        b_ref = rr + cmath.exp(1j * pr) * self.local[self.rod, "B"]
        x_ref = ((b_ref - self.o) * self.u.conjugate()).real
        c_ref = kinematics.reference_inputs()[None, :1]
        zero = np.zeros_like(c_ref[:, 0])
        gaps = {s: abs(float(self.closed_form(c_ref[:, 0], zero, zero, s)[0][0, 0]) - x_ref) for s in (1.0, -1.0)}
        best = min(gaps, key=gaps.__getitem__)
        if not gaps[best] <= _BRANCH_MATCH * self.mechanism.size:
            raise RuntimeError(
                f"{SOURCE}: {self.mechanism.name}: no root of the slider position reproduces "
                f"the general solver's assembly (closest off by {gaps[best]:.3g} m)"
            )
        return [best]

    def frames(self, c, cd, cdd, roots):
        """Every moving body's :class:`Frame`, the assembled flags, the
        singularity measure (N,) and the diagnostics slide_x (m), rod_angle (rad)."""
        (sigma,) = roots
        x, beta, ok, singularity = self.closed_form(c[:, 0], cd[:, 0], cdd[:, 0], sigma)
        r, l, e = self.lengths
        loc, n = self.local, c.shape[0]
        zero = np.zeros(n, dtype=complex)
        o = np.full(n, self.o, dtype=complex)
        crank = Frame.through_point(
            o, zero, zero, self.sign * c[:, 0], self.sign * cd[:, 0], self.sign * cdd[:, 0], loc[self.crank, "O"]
        )
        delta = cmath.phase(self.u)
        b = self.o + (x[0] + 1j * e) * self.u
        bd, bdd = x[1] * self.u, x[2] * self.u
        rod = Frame.through_point(
            b,
            bd,
            bdd,
            delta + beta[0] - cmath.phase(loc[self.rod, "B"] - loc[self.rod, "A"]),
            beta[1],
            beta[2],
            loc[self.rod, "B"],
        )
        frames = {self.crank: crank, self.rod: rod}
        if self.slider is not None:
            still = np.zeros(n)
            frames[self.slider] = Frame.through_point(
                b, bd, bdd, np.full(n, self.slider_angle), still, still.copy(), loc[self.slider, "B"]
            )
        return frames, ok, singularity, {"slide_x": x[0], "rod_angle": beta[0]}


def _recognise_four_bar(mech: Mechanism, joint: Revolute, crank: str, sign: float) -> _FourBar:
    ground_joints = [j for j in mech.joints if GROUND in (j.body_a, j.body_b) and j is not joint]
    (other,) = ground_joints
    rocker = _other(other, GROUND)
    (coupler,) = [b.name for b in mech.moving_bodies if b.name not in (crank, rocker)]
    links = {pair: _joints_between(mech, *pair) for pair in ((crank, coupler), (coupler, rocker))}
    if rocker == crank or any(len(found) != 1 for found in links.values()):
        _fail(mech, "the four revolutes do not form one loop ground-crank-coupler-rocker-ground")
    (jb,), (jc,) = links[crank, coupler], links[coupler, rocker]
    local = {
        (crank, "A"): _local(mech, crank, _joint_point(joint, crank)),
        (crank, "B"): _local(mech, crank, _joint_point(jb, crank)),
        (coupler, "B"): _local(mech, coupler, _joint_point(jb, coupler)),
        (coupler, "C"): _local(mech, coupler, _joint_point(jc, coupler)),
        (rocker, "C"): _local(mech, rocker, _joint_point(jc, rocker)),
        (rocker, "D"): _local(mech, rocker, _joint_point(other, rocker)),
    }
    a, d = _local(mech, GROUND, _joint_point(joint, GROUND)), _local(mech, GROUND, _joint_point(other, GROUND))
    labels = (
        _joint_point(joint, GROUND),
        _joint_point(jb, crank),
        _joint_point(jc, coupler),
        _joint_point(other, GROUND),
    )
    four = _FourBar(mech, crank, coupler, rocker, sign, a, d, local, labels)
    if min(four.lengths) <= _DEGENERATE * mech.size:
        _fail(mech, "a link of the four-bar has zero length")
    return four


def _recognise_slider_crank(mech: Mechanism, joint: Revolute, crank: str, sign: float) -> _SliderCrank:
    bad = "the joints do not form crank-rod-slider on a line fixed to the ground"
    crank_joints = [j for j in mech.joints if j is not joint and crank in (j.body_a, j.body_b)]
    if len(crank_joints) != 1 or not isinstance(crank_joints[0], Revolute):
        _fail(mech, bad)
    (ja,) = crank_joints
    rod = _other(ja, crank)
    if rod == GROUND:
        _fail(mech, bad)
    rest = [j for j in mech.joints if j not in (joint, ja)]
    local = {
        (crank, "O"): _local(mech, crank, _joint_point(joint, crank)),
        (crank, "A"): _local(mech, crank, _joint_point(ja, crank)),
        (rod, "A"): _local(mech, rod, _joint_point(ja, rod)),
    }
    o = _local(mech, GROUND, _joint_point(joint, GROUND))
    if len(mech.moving_bodies) == 2:
        # the rod's pin B in a slot of the ground
        if len(rest) != 1:
            _fail(mech, bad)
        (slot,) = rest
        if not isinstance(slot, PinInSlot) or slot.body_a != GROUND or slot.body_b != rod:
            _fail(mech, bad)
        local[rod, "B"] = _local(mech, rod, slot.point)
        l0, u = _local(mech, GROUND, slot.line_point), complex(*slot.direction)
        slider, slider_angle, label_b = None, 0.0, slot.point
    else:
        (slider,) = [b.name for b in mech.moving_bodies if b.name not in (crank, rod)]
        pins = [j for j in rest if isinstance(j, Revolute) and {j.body_a, j.body_b} == {rod, slider}]
        guides = [j for j in rest if isinstance(j, Prismatic) and {j.body_a, j.body_b} == {GROUND, slider}]
        if len(rest) != 2 or len(pins) != 1 or len(guides) != 1:
            _fail(mech, bad)
        (jb,), (guide,) = pins, guides
        local[rod, "B"] = _local(mech, rod, _joint_point(jb, rod))
        local[slider, "B"] = _local(mech, slider, _joint_point(jb, slider))
        d = complex(*guide.direction)
        if guide.body_a == GROUND:
            # slider point P on the ground line through Q: B = Q + s d + e^{i angle}(B - P)
            slider_angle = guide.angle
            turn = cmath.exp(1j * slider_angle)
            l0 = _local(mech, GROUND, guide.line_point) + turn * (
                local[slider, "B"] - _local(mech, slider, guide.point)
            )
            u = d
        else:
            # the line is on the slider, the ground point P on it: B = P + e^{i a}(B - Q) - s e^{i a} d
            slider_angle = -guide.angle
            turn = cmath.exp(1j * slider_angle)
            l0 = _local(mech, GROUND, guide.point) + turn * (
                local[slider, "B"] - _local(mech, slider, guide.line_point)
            )
            u = turn * d
        label_b = _joint_point(jb, rod)
    labels = (_joint_point(joint, GROUND), _joint_point(ja, crank), label_b)
    found = _SliderCrank(mech, crank, rod, slider, slider_angle, sign, o, l0, u, local, labels)
    if min(found.lengths[:2]) <= _DEGENERATE * mech.size:
        _fail(mech, "the crank or the rod has zero length")
    return found


def recognise(mechanism: Mechanism) -> _FourBar | _SliderCrank:
    """The four-bar or offset slider-crank that the mechanism is.

    Raises
    ------
    NotApplicable
        With the reason, if it is neither.
    """
    mech = mechanism
    joint, crank, sign = _driven_crank(mech)
    kinds = sorted(j.kind for j in mech.joints)
    n_bodies = len(mech.moving_bodies)
    if n_bodies == 3 and kinds == ["revolute"] * 4:
        if sum(GROUND in (j.body_a, j.body_b) for j in mech.joints) != 2:
            _fail(mech, "four revolutes, but not two of them at ground pivots")
        return _recognise_four_bar(mech, joint, crank, sign)
    if (n_bodies == 3 and kinds == ["prismatic"] + ["revolute"] * 3) or (
        n_bodies == 2 and kinds == ["pin-in-slot", "revolute", "revolute"]
    ):
        return _recognise_slider_crank(mech, joint, crank, sign)
    joint_text = ", ".join(f"{kinds.count(k)} {k}" for k in sorted(set(kinds)))
    _fail(
        mech,
        f"{n_bodies} moving bodies with {joint_text} joints: formulation I has closed forms "
        "for a four-bar and an offset slider-crank only",
    )


def solve_closed_form(
    kinematics: Kinematics, inputs, rates=None, accelerations=None, branch: str | None = None
) -> Trajectory:
    """Formulation I over a sweep of inputs.

    Parameters
    ----------
    kinematics : Kinematics
        The general solver of the mechanism; only its model, its assembly at
        the reference inputs (to pick the closed form's root) and its
        constraint residual (a diagnostic) are used.
    inputs, rates, accelerations : array_like, shape (N, 1) or (N,)
        The crank's angle (rad), rate (rad/s) and acceleration (rad/s^2).
    branch : str, optional
        Assembly branch (default: the model file's first).

    Returns
    -------
    Trajectory
        Source ``"formulation-I"``; ``diagnostics`` holds ``status`` (codes of
        :class:`~xcheck.kinematics.Status`), ``singularity`` (|sin theta2| of
        a four-bar, |cos| of a slider-crank's rod to its line), ``residual``
        (m), and ``theta1``, ``theta2``, ``theta3`` (rad, in [0, 2 pi)) of a
        four-bar or ``slide_x`` (m) and ``rod_angle`` (rad) of a slider-crank.

    Raises
    ------
    NotApplicable
        If the mechanism is neither a four-bar nor an offset slider-crank
        driven at the crank.
    """
    found = recognise(kinematics.mechanism)
    c, cd, cdd = as_inputs(kinematics, inputs, rates, accelerations)
    name = kinematics.branches[0] if branch is None else branch  # assemble() checks the name
    roots = found.choose_roots(kinematics, name)
    frames, ok, singularity, diagnostics = found.frames(c, cd, cdd, roots)
    frames[kinematics.mechanism.ground.name] = Frame.fixed(c.shape[0])
    status = status_from_singularity(ok, np.where(ok, singularity, 0.0))
    for key, value in diagnostics.items():
        diagnostics[key] = np.where(ok, value, np.nan)
    notes = (
        f"{SOURCE} (generalized coordinate, direct substitution): {found.describe()}; roots "
        + ", ".join("+" if s > 0 else "-" for s in roots)
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
        diagnostics,
        notes,
        {"formulation": "I", "mechanism": found.kind, "branch": name, "roots": roots},
    )
