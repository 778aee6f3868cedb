"""What both formulations share: input checks, the not-applicable signal, and
body frames (held as complex numbers, the seeds' r e^{i phi}) turned into a
:class:`~xcheck.results.Trajectory`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kinematics import NEAR_SINGULAR, SINGULAR, Kinematics, Status
from ..results import Trajectory

__all__ = [
    "Frame",
    "as_inputs",
    "body_frames_from_q",
    "build_trajectory",
    "status_from_singularity",
    "wrap",
]


@dataclass
class Frame:
    """A body frame over N samples, complex positions (x + i y), SI units.

    Attributes
    ----------
    r, rd, rdd : ndarray of complex, shape (N,)
        Origin position (m), velocity (m/s), acceleration (m/s^2).
    phi, phid, phidd : ndarray, shape (N,)
        Angle of the frame's x axis (rad), angular velocity (rad/s),
        angular acceleration (rad/s^2).
    """

    r: np.ndarray
    rd: np.ndarray
    rdd: np.ndarray
    phi: np.ndarray
    phid: np.ndarray
    phidd: np.ndarray

    @classmethod
    def fixed(cls, n: int) -> "Frame":
        """The ground's frame (the global frame), N samples."""
        z, zc = np.zeros(n), np.zeros(n, dtype=complex)
        return cls(zc, zc, zc, z, z, z)

    @classmethod
    def through_point(cls, p, pd, pdd, phi, phid, phidd, local: complex) -> "Frame":
        """The frame of a body whose point ``local`` (body frame, m) moves as
        p, pd, pdd (complex, (N,)) while the body turns as phi, phid, phidd."""
        arm = np.exp(1j * phi) * local
        return cls(p - arm, pd - 1j * phid * arm, pdd - (1j * phidd - phid**2) * arm, phi, phid, phidd)

    def point(self, local: complex):
        """Position, velocity, acceleration (complex, (N,)) of a point of the body."""
        arm = np.exp(1j * self.phi) * local
        return (self.r + arm, self.rd + 1j * self.phid * arm, self.rdd + (1j * self.phidd - self.phid**2) * arm)


def wrap(angle):
    """Angle(s) wrapped into [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def as_inputs(kinematics: Kinematics, inputs, rates=None, accelerations=None):
    """Drivers' values, rates and accelerations as arrays of shape (N, k).

    Raises
    ------
    ValueError
        If a shape is not (N, k) (or (N,) when k = 1), or a value is not finite.
    """

    def shaped(values, name, shape=None):
        arr = kinematics.input_array(values, shape)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"expected finite {name}, found NaN or infinity")
        return arr

    c = shaped(inputs, "inputs")
    cd = np.zeros_like(c) if rates is None else shaped(rates, "rates", c.shape)
    cdd = np.zeros_like(c) if accelerations is None else shaped(accelerations, "accelerations", c.shape)
    return c, cd, cdd


def body_frames_from_q(kinematics: Kinematics, q: np.ndarray) -> dict[str, tuple[complex, float]]:
    """(origin as complex, angle) of every body, ground included, in a
    configuration ``q`` of shape (n,) of the general solver (x, y, phi per
    moving body, in ``mechanism.moving_bodies`` order)."""
    frames = {kinematics.mechanism.ground.name: (0j, 0.0)}
    for i, body in enumerate(kinematics.mechanism.moving_bodies):
        frames[body.name] = (complex(q[3 * i], q[3 * i + 1]), float(q[3 * i + 2]))
    return frames


def _xy(z: np.ndarray) -> np.ndarray:
    return np.stack([z.real, z.imag], axis=-1)


def status_from_singularity(assembled: np.ndarray, singularity: np.ndarray) -> np.ndarray:
    """Per-sample :class:`Status` codes from assembly flags (N,) and inverse
    condition numbers (N,), with the general solver's thresholds."""
    status = np.full(assembled.shape, Status.NOT_CONVERGED, dtype=np.int8)
    status[assembled] = Status.OK
    status[assembled & (singularity < NEAR_SINGULAR)] = Status.NEAR_SINGULAR
    status[assembled & (singularity < SINGULAR)] = Status.SINGULAR
    return status


def build_trajectory(
    kinematics: Kinematics,
    source: str,
    c,
    cd,
    cdd,
    frames: dict[str, Frame],
    status: np.ndarray,
    singularity: np.ndarray,
    diagnostics: dict,
    notes: str,
    settings: dict,
) -> Trajectory:
    """A :class:`Trajectory` of every moving body and named point.

    Rows that did not assemble hold NaN everywhere; rows at a singular
    configuration hold NaN velocities and accelerations (as the general
    solver's :class:`~xcheck.kinematics.Solution` does); ``diagnostics["status"]``
    is authoritative. ``diagnostics["residual"]`` is the largest violation (m)
    of the canonical model's constraints (drivers included) at the computed
    frames: a check that the formulation closed the same mechanism.
    """
    mech = kinematics.mechanism
    n = c.shape[0]
    lost = status == Status.NOT_CONVERGED
    undetermined = lost | (status == Status.SINGULAR)
    for frame in (frames[b.name] for b in mech.moving_bodies):
        for name, rows in (
            ("r", lost),
            ("phi", lost),
            ("rd", undetermined),
            ("rdd", undetermined),
            ("phid", undetermined),
            ("phidd", undetermined),
        ):
            values = getattr(frame, name)
            values[rows] = complex(np.nan, np.nan) if np.iscomplexobj(values) else np.nan
    bodies = {}
    q = np.empty((n, 3 * len(mech.moving_bodies)))
    for i, body in enumerate(mech.moving_bodies):
        f = frames[body.name]
        bodies[body.name] = {
            "position": _xy(f.r),
            "angle": f.phi,
            "velocity": _xy(f.rd),
            "omega": f.phid,
            "acceleration": _xy(f.rdd),
            "alpha": f.phidd,
        }
        q[:, 3 * i], q[:, 3 * i + 1], q[:, 3 * i + 2] = f.r.real, f.r.imag, f.phi
    points = {}
    for label, owner in mech.point_owners.items():
        s = mech.body(owner).points[label]
        p, pd, pdd = frames[owner].point(complex(s[0], s[1]))
        points[label] = {"position": _xy(p), "velocity": _xy(pd), "acceleration": _xy(pdd)}
    residual = np.full(n, np.nan)
    ok = ~lost
    if ok.any():
        system = kinematics.system
        residual[ok] = system.residual_metres(system.residual(q[ok], c[ok]))
    diagnostics = {"status": status, "singularity": singularity, "residual": residual, **diagnostics}
    return Trajectory(
        source=source,
        inputs=c,
        input_rates=cd,
        input_accelerations=cdd,
        bodies=bodies,
        points=points,
        settings=settings,
        diagnostics=diagnostics,
        notes=notes,
    )
