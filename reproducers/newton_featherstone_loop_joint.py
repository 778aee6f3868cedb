"""Newton: SolverFeatherstone ignores a loop joint.

A four-bar (crank 0.1 m about O (0, 0), coupler 0.3 m, rocker 0.22 m about
Q (0.2, 0)), uniform 1 kg rods, gravity 9.81 m/s^2 along -y, released at rest
with the crank at 45 deg: two articulations (crank-coupler, rocker) and the
coupler-rocker pin B as a revolute joint left out of ``add_articulation`` (a
loop joint, as Newton's documentation describes loops). Its other solvers hold
B (``SolverXPBD``: within 1e-3 m at dt = 1 ms). Measured with Newton 1.8.0
(warp 1.19) over 1 s at dt = 1 ms: ``SolverFeatherstone`` moves the two
articulations as if B did not exist; B opens by 0.5 m, with no warning.

Run: ``python newton_featherstone_loop_joint.py`` (its kernels compile in one to
three minutes the first time, cached after). Prints B's largest gap for each
solver beside the expected one; exits 0 while the defect shows, 1 once it no
longer does.
"""

import math
import sys

import newton
import numpy as np
import warp as wp

CRANK, COUPLER, ROCKER, Q = 0.1, 0.3, 0.22, 0.2
START = (math.radians(45.0), 0.2721247429362482, 0.7586309236111005)  # crank, coupler, rocker angles (rad)


def frame(x: float, angle: float = 0.0):
    return wp.transform((x, 0.0, 0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), angle))


def build():
    """The four-bar, its joint coordinates zero at the assembled start."""
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
    bodies = []
    for length in (CRANK, COUPLER, ROCKER):  # frames at the rods' middles, x along the rod
        inertia = length * length / 12.0
        bodies.append(builder.add_link(mass=1.0, inertia=wp.mat33(inertia, 0, 0, 0, inertia, 0, 0, 0, inertia)))
    crank, coupler, rocker = bodies
    a1, a2, a3 = START
    z = (0.0, 0.0, 1.0)
    o = builder.add_joint_revolute(-1, crank, parent_xform=frame(0.0, a1), child_xform=frame(-CRANK / 2), axis=z)
    a = builder.add_joint_revolute(
        crank, coupler, parent_xform=frame(CRANK / 2, a2 - a1), child_xform=frame(-COUPLER / 2), axis=z
    )
    q = builder.add_joint_revolute(-1, rocker, parent_xform=frame(Q, a3), child_xform=frame(-ROCKER / 2), axis=z)
    builder.add_joint_revolute(
        coupler, rocker, parent_xform=frame(COUPLER / 2, a3 - a2), child_xform=frame(ROCKER / 2), axis=z
    )
    builder.add_articulation([o, a])
    builder.add_articulation([q])
    return builder.finalize(device="cpu")


def gap(state) -> float:
    """B on the coupler minus B on the rocker, m."""
    ends = []
    for body, half in ((1, COUPLER / 2), (2, ROCKER / 2)):
        x, y, _, _, _, qz, qw = (float(v) for v in state.body_q.numpy()[body])
        angle = 2.0 * math.atan2(qz, qw)
        ends.append(np.array([x + half * math.cos(angle), y + half * math.sin(angle)]))
    return float(np.hypot(*(ends[0] - ends[1])))


def run(solver_type, steps: int = 1000, dt: float = 1e-3) -> float:
    """B's largest gap over the run, m."""
    model = build()
    state, next_state, control = model.state(), model.state(), model.control()
    newton.eval_fk(model, state.joint_q, state.joint_qd, state)
    solver = solver_type(model)
    widest = gap(state)
    for _ in range(steps):
        state.clear_forces()
        solver.step(state, next_state, control, None, dt)
        state, next_state = next_state, state
        widest = max(widest, gap(state))
    return widest


if __name__ == "__main__":
    from importlib.metadata import version

    wp.config.quiet = True
    print(f"Newton {version('newton')}, warp {wp.__version__}: a four-bar's loop joint, 1 s at dt = 1 ms")
    print("  expected: B's gap within 1e-3 m")
    featherstone = run(newton.solvers.SolverFeatherstone)
    xpbd = run(newton.solvers.SolverXPBD)
    print(f"  measured: SolverFeatherstone {featherstone:.3g} m, SolverXPBD {xpbd:.3g} m")
    shown = featherstone > 0.1 and xpbd < 1e-3
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
