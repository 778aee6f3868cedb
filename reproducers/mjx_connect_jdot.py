"""MJX: a connect (loop) constraint leaves out J-dot qd, which MuJoCo's C library has.

A four-bar (crank 0.1 m about O, coupler 0.3 m, rocker 0.22 m about Q (0.2, 0)),
its loop cut at the coupler-rocker pin B and closed by an ``<equality><connect>``
between two sites, the constraint made stiff (solimp 0.9999). At an assembled
pose with a velocity that keeps the loop closed (the crank at 2 rad/s), the
constraint's acceleration is J qacc + J-dot qd, which a rigid loop holds at 0 and
MuJoCo's near-rigid one at a small fraction of |J-dot qd| (J and J-dot qd from
``mj_jac`` and ``mj_jacDot`` of the two sites). Measured with MuJoCo 4.0.0 and
MJX 3.17 (JAX on CPU, float64): MuJoCo C leaves 4e-5 of |J-dot qd| (its
``efc_aref`` carries the term); MJX's ``qacc`` leaves all of it: J qacc is 0, as
if the loop did not turn.

Run: ``python mjx_connect_jdot.py``. Prints J qacc + J-dot qd of each beside the
expected value; exits 0 while the defect shows, 1 once it no longer does.
"""

import sys

import numpy as np

MJCF = """
<mujoco>
  <compiler angle="radian"/>
  <option gravity="0 0 0" timestep="0.001"/>
  <worldbody>
    <body name="crank">
      <joint name="O" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.005" mass="1" contype="0" conaffinity="0"/>
      <body name="coupler" pos="0.1 0 0">
        <joint name="A" type="hinge" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.005" mass="1" contype="0" conaffinity="0"/>
        <site name="B_coupler" pos="0.3 0 0"/>
      </body>
    </body>
    <body name="rocker" pos="0.2 0 0">
      <joint name="Q" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.22 0 0" size="0.005" mass="1" contype="0" conaffinity="0"/>
      <site name="B_rocker" pos="0.22 0 0"/>
    </body>
  </worldbody>
  <equality>
    <connect site1="B_coupler" site2="B_rocker" solimp="0.9999 0.9999 0.001"/>
  </equality>
</mujoco>
"""


def assembled(crank: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """qpos and qvel with the loop closed (B above the line AQ) and the crank at ``rate`` rad/s."""
    a = 0.1 * np.array([np.cos(crank), np.sin(crank)])
    q = np.array([0.2, 0.0])
    d = np.linalg.norm(q - a)
    base = np.arctan2(*(q - a)[::-1])
    coupler = base + np.arccos((0.3**2 + d**2 - 0.22**2) / (2 * 0.3 * d))
    b = a + 0.3 * np.array([np.cos(coupler), np.sin(coupler)])
    rocker = np.arctan2(b[1] - q[1], b[0] - q[0])
    # velocities: B's velocity the same on the coupler and on the rocker
    u, v = np.array([-np.sin(coupler), np.cos(coupler)]), np.array([-np.sin(rocker), np.cos(rocker)])
    va = rate * 0.1 * np.array([-np.sin(crank), np.cos(crank)])
    w_coupler, w_rocker = np.linalg.solve(np.column_stack([0.3 * u, -0.22 * v]), -va)
    return np.array([crank, coupler - crank, rocker]), np.array([rate, w_coupler - rate, w_rocker])


def site_terms(mujoco, model, data) -> tuple[np.ndarray, np.ndarray]:
    """J (3, nv) and J-dot qd (3,) of the constraint: site B_coupler minus site B_rocker."""
    jac, jdot = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    out_j, out_d = [], []
    for name in ("B_coupler", "B_rocker"):
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
        mujoco.mj_jacSite(model, data, jac, None, site)
        mujoco.mj_jacDot(model, data, jdot, None, data.site_xpos[site], model.site_bodyid[site])
        out_j.append(jac.copy())
        out_d.append(jdot @ data.qvel)
    return out_j[0] - out_j[1], out_d[0] - out_d[1]


def main() -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    import mujoco
    from mujoco import mjx

    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = assembled(np.radians(60.0), 2.0)
    mujoco.mj_forward(model, data)
    jac, drift = site_terms(mujoco, model, data)
    c_residual = jac @ data.qacc + drift
    mjx_data = jax.jit(mjx.forward)(mjx.put_model(model), mjx.put_data(model, data))
    mjx_qacc = np.asarray(mjx_data.qacc, dtype=float)
    mjx_residual = jac @ mjx_qacc + drift
    size = np.linalg.norm(drift[:2])
    from importlib.metadata import version

    print(f"MuJoCo {mujoco.__version__}, MJX {version('mujoco-mjx')}, JAX {jax.__version__}: a four-bar at 2 rad/s")
    print(f"  |J-dot qd| = {size:.4g} m/s^2 (the planar rows)")
    print("  expected: |J qacc + J-dot qd| / |J-dot qd| near 0 (a near-rigid loop, solimp 0.9999)")
    c_ratio = np.linalg.norm(c_residual[:2]) / size
    mjx_ratio = np.linalg.norm(mjx_residual[:2]) / size
    mjx_jqacc = np.linalg.norm((jac @ mjx_qacc)[:2])
    print(f"  measured: MuJoCo C {c_ratio:.3g}, MJX {mjx_ratio:.3g} (MJX's |J qacc| = {mjx_jqacc:.3g} m/s^2)")
    shown = c_ratio < 1e-3 and mjx_ratio > 0.5
    print("defect shown" if shown else "defect not shown")
    return 0 if shown else 1


if __name__ == "__main__":
    sys.exit(main())
