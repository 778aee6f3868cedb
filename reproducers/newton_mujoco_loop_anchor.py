"""Newton: the MuJoCo backend places a loop joint's anchors as if the model were assembled at q = 0.

A four-bar (crank 0.1 m about O (0, 0), coupler 0.3 m, rocker 0.22 m about
Q (0.2, 0)), uniform 1 kg rods, gravity 9.81 m/s^2 along -y, released at rest
with the crank at 45 deg: two articulations (crank-coupler, rocker) and the
coupler-rocker pin B as a revolute joint left out of ``add_articulation`` (a
loop joint). ``SolverMuJoCo`` (``use_mujoco_cpu=True``) should hold B closed as
its own joints are. Built two ways that differ only in where the joint
coordinates are zero, the model starts with B closed to float32 round-off
(``eval_fk``). Measured with Newton 1.8.0 (warp 1.19, mujoco-warp 3.17, MuJoCo
4.0) over 0.1 s at dt = 1 ms: with q = 0 the assembled pose B opens by at most
3.5e-4 m (MuJoCo's soft constraint); with the joints' frames at the rods' ends (q = 0 the rods along +x, not
assembled) B opens by 2e-2 m in the first steps: the loop's anchors were
computed at q = 0.

Run: ``python newton_mujoco_loop_anchor.py`` (its kernels compile in about a
minute the first time, cached after). Prints B's largest gap for each way
beside the expected one; exits 0 while the defect shows, 1 once it no longer does.
"""

import math
import sys

import mujoco_warp  # noqa: F401 - the MuJoCo backend (pip install mujoco-warp)
import newton
import numpy as np
import warp as wp

CRANK, COUPLER, ROCKER, Q = 0.1, 0.3, 0.22, 0.2
START = (math.radians(45.0), 0.2721247429362482, 0.7586309236111005)  # crank, coupler, rocker angles (rad)


def frame(x: float, angle: float = 0.0):
    return wp.transform((x, 0.0, 0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), angle))


def build(zero_assembled: bool):
    """The four-bar; the joint coordinates at the assembled start."""
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
    bodies = []
    for length in (CRANK, COUPLER, ROCKER):  # frames at the rods' middles, x along the rod
        inertia = length * length / 12.0
        bodies.append(builder.add_link(mass=1.0, inertia=wp.mat33(inertia, 0, 0, 0, inertia, 0, 0, 0, inertia)))
    crank, coupler, rocker = bodies
    a1, a2, a3 = START if zero_assembled else (0.0, 0.0, 0.0)  # each joint's frame turned by its start
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
    model = builder.finalize(device="cpu")
    crank_a, coupler_a, rocker_a = START
    coordinates = [0.0] * 4 if zero_assembled else [crank_a, coupler_a - crank_a, rocker_a, rocker_a - coupler_a]
    return model, np.array(coordinates, dtype=np.float32)


def gap(state) -> float:
    """B on the coupler minus B on the rocker, m."""
    ends = []
    for body, half in ((1, COUPLER / 2), (2, ROCKER / 2)):
        x, y, _, _, _, qz, qw = (float(v) for v in state.body_q.numpy()[body])
        angle = 2.0 * math.atan2(qz, qw)
        ends.append(np.array([x + half * math.cos(angle), y + half * math.sin(angle)]))
    return float(np.hypot(*(ends[0] - ends[1])))


def run(zero_assembled: bool, steps: int = 100, dt: float = 1e-3) -> tuple[float, float]:
    """(B's gap at the start, its largest over the run), m."""
    model, coordinates = build(zero_assembled)
    state, next_state, control = model.state(), model.state(), model.control()
    state.joint_q.assign(coordinates)
    state.joint_qd.zero_()
    newton.eval_fk(model, state.joint_q, state.joint_qd, state)
    start = gap(state)
    solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=True, disable_contacts=True)
    widest = start
    for _ in range(steps):
        state.clear_forces()
        solver.step(state, next_state, control, None, dt)
        state, next_state = next_state, state
        widest = max(widest, gap(state))
    return start, widest


if __name__ == "__main__":
    from importlib.metadata import version

    wp.config.quiet = True
    print(f"Newton {version('newton')}, warp {wp.__version__}: a four-bar's loop joint in SolverMuJoCo, 0.1 s")
    zero = run(True)
    other = run(False)
    print("  expected: the same gap however the joint coordinates are zeroed")
    print(f"  measured, q = 0 assembled:  starts {zero[0]:.2g} m, largest {zero[1]:.3g} m")
    print(f"  measured, q = 0 elsewhere:  starts {other[0]:.2g} m, largest {other[1]:.3g} m")
    shown = other[1] > 10.0 * zero[1] and other[1] > 5e-3
    print("defect shown" if shown else "defect not shown")
    sys.exit(0 if shown else 1)
