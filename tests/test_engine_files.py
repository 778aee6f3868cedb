"""The exported engine files open as they should: the MJCF assembled at qpos0
with the tight settings and mass-free visuals, the URDF parsable with visuals
on every link and ROS names, its loops file giving the assembled joint values.
These are the writers' files with every number exact, as the engine modes load
them; the committed files (the same with their numbers rounded to 12
significant digits, so that any machine writes the same text) are checked
current by test_mujoco and test_pinocchio.

Tolerances, measured on every bundled mechanism and benchmark (2026-11,
``mj_forward`` at qpos0 against ``Kinematics.assemble``): body positions at most
4.6e-16 of the mechanism's size, body angles at most 4.6e-16 rad, equality
violations (``efc_pos``) at most 2.8e-16 m. The bound 1e-14 (of the size, in
rad, in m) is about twenty times the worst: round-off of composing a few
rotations, where a wrong convention would show as 1e-3 or more.
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import MODEL_NAMES, MODELS

from xcheck import Kinematics, cache
from xcheck.engines.mujoco.mjcf import (
    TIGHT_SOLIMP,
    TIGHT_SOLREF,
    file_mass_properties,
    joint_coordinates,
    layout,
    mjcf_text,
)
from xcheck.engines.pinocchio.modes import build, export_files
from xcheck.engines.pinocchio.modes import joint_coordinates as pin_coordinates
from xcheck.engines.pinocchio.urdf import ROS_NAME, UrdfNames, ros_name
from xcheck.kinematics import Status
from xcheck.model import load_mechanism

BENCHMARKS = sorted(p.stem for p in (MODELS / "benchmarks").glob("*.toml"))
ROUND_OFF = 1e-14


def _file(name: str):
    path = MODELS / f"{name}.toml"
    return path if path.is_file() else MODELS / "benchmarks" / f"{name}.toml"


@pytest.fixture
def mjcf(once_per_run, tmp_path):
    """``mjcf(name)``: the writer's MJCF of a model, every number exact (as the
    engine's modes load it; the committed file, the same rounded to 12 significant
    digits, is checked current by test_mujoco), loaded from a path, with the model's
    kinematics. The text is written once per test run for this module's tests
    (iftomm-a02-n40's alone costs 3.6 CPU s: its servos' inertia sweeps the input's range).
    The kinematics given with it start from the branch map that sweep computed (the
    run's branch-map cache, xcheck.cache), as a command's do, instead of walking the
    range again (2.5 CPU s of n40's tests)."""

    def text(name: str) -> str:
        kin = Kinematics(load_mechanism(_file(name)))
        written = mjcf_text(kin)
        cache.store(kin)
        return written

    def get(name: str) -> tuple[Kinematics, mujoco.MjModel]:
        path = tmp_path / f"{name}.xml"
        path.write_text(once_per_run(f"mjcf-{name}", lambda: text(name)))
        return cache.cached_kinematics(load_mechanism(_file(name))), mujoco.MjModel.from_xml_path(str(path))

    return get


def _pose_error(kin: Kinematics, model, data, q: np.ndarray) -> tuple[float, float]:
    """(worst body position error / size, worst angle error rad) of MuJoCo's bodies against q."""
    position = angle = 0.0
    for i, body in enumerate(kin.mechanism.moving_bodies):
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body.name)
        position = max(position, float(np.max(np.abs(data.xpos[b, :2] - q[3 * i : 3 * i + 2]))))
        phi = np.arctan2(data.xmat[b, 3], data.xmat[b, 0])
        angle = max(angle, abs((phi - q[3 * i + 2] + np.pi) % (2 * np.pi) - np.pi))
    return position / kin.mechanism.size, angle


def _equality_violation(model, data, size: float) -> float:
    """The largest loop-closure (equality) violation per mechanism size: round-off grows
    with the size and along a chain (iftomm-a02-n40, 81 bodies, 40 m: 1.4e-14 m)."""
    rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return float(np.max(np.abs(data.efc_pos[rows]))) / size if rows.any() else 0.0


@pytest.mark.parametrize("name", MODEL_NAMES + BENCHMARKS)
def test_mjcf_opens_assembled_at_qpos0(name, mjcf):
    kin, model = mjcf(name)
    q = kin.assemble()
    data = mujoco.MjData(model)  # qpos = qpos0, no keyframe reset
    np.testing.assert_array_equal(data.qpos, model.qpos0)
    mujoco.mj_forward(model, data)
    position, angle = _pose_error(kin, model, data, q)
    assert position < ROUND_OFF and angle < ROUND_OFF, (position, angle)
    assert _equality_violation(model, data, kin.mechanism.size) < ROUND_OFF
    if model.nkey:  # the keyframe is the same configuration
        np.testing.assert_array_equal(model.key_qpos[0], model.qpos0)


@pytest.mark.parametrize("name", MODEL_NAMES + BENCHMARKS)
def test_mjcf_qpos_keeps_its_meaning_away_from_the_assembly(name, mjcf):
    """With every joint's ref at the assembly, qpos is still the model's joint
    coordinate: native states away from the assembly (inputs moved by 0.05 and
    0.1 rad, or that times the size for a slide), mapped by joint_coordinates,
    put MuJoCo's bodies where the native solver does (this checks the
    re-expressed axes of a body with two joints, a pin-in-slot)."""
    kin, model = mjcf(name)
    mech = kin.mechanism
    lay = layout(mech)
    scale = np.array([1.0 if d.quantity == "angle" else mech.size for d in mech.drivers])
    inputs = kin.reference_inputs()[None] + np.array([0.05, -0.05, 0.1, -0.1])[:, None] * scale
    solution = kin.solve(inputs, np.zeros_like(inputs))
    determined = solution.q[solution.status <= Status.NEAR_SINGULAR]
    assert len(determined) >= 2
    data = mujoco.MjData(model)
    moved = 0.0
    for q in determined:
        data.qpos[:] = joint_coordinates(kin.mechanism, lay, q)
        moved = max(moved, float(np.max(np.abs(data.qpos - model.qpos0))))
        mujoco.mj_forward(model, data)
        position, angle = _pose_error(kin, model, data, q)
        assert position < ROUND_OFF and angle < ROUND_OFF, (position, angle)
        assert _equality_violation(model, data, kin.mechanism.size) < ROUND_OFF
    assert moved > 1e-3  # the states are away from the assembly


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_mjcf_settings_and_visuals_leave_the_mass_alone(name, mjcf, tmp_path):
    """The tight equality settings, stated in a comment; every moving body has a
    visual geom that neither collides nor adds mass (explicit inertials)."""
    kin, model = mjcf(name)
    text = (tmp_path / f"{name}.xml").read_text()
    assert "Solver settings: the tight ones xcheck's dynamic mode verifies" in text
    if model.neq:
        np.testing.assert_array_equal(model.eq_solref, np.tile(TIGHT_SOLREF, (model.neq, 1)))
        np.testing.assert_array_equal(model.eq_solimp, np.tile(TIGHT_SOLIMP, (model.neq, 1)))
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)
    written, _ = file_mass_properties(kin.mechanism, layout(kin.mechanism).topology)
    for body in kin.mechanism.moving_bodies:
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body.name)
        assert np.count_nonzero(model.geom_bodyid == b) >= 1, body.name
        props = written[body.name]
        assert model.body_mass[b] == props.mass
        np.testing.assert_array_equal(model.body_ipos[b, :2], props.com)
        np.testing.assert_array_equal(model.body_inertia[b], [props.inertia] * 3)


# -- URDF ----------------------------------------------------------------------
@pytest.mark.parametrize("name", MODEL_NAMES)
def test_urdf_parses_with_visuals_and_ros_names(name):
    path = MODELS / "urdf" / f"{name}.urdf"
    model = pin.buildModelFromUrdf(str(path))
    geometry = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.VISUAL)
    root = ET.parse(path).getroot()
    links = root.findall("link")
    assert all(link.find("visual") is not None for link in links), [
        link.get("name") for link in links if link.find("visual") is None
    ]
    assert geometry.ngeoms >= len(links)
    names = [root.get("name")] + [e.get("name") for e in root.iter() if e.tag in ("link", "joint")]
    names += [e.get("link") for e in root.iter() if e.tag in ("parent", "child")]
    bad = [n for n in names if not ROS_NAME.fullmatch(n)]
    assert not bad


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_urdf_loops_file_gives_the_assembly(name, tmp_path):
    """The loops file beside the URDF: each loop's frames exist, and the joint
    values at the assembly close every loop (to round-off) in the URDF model.
    The writer's files with every number exact (the committed ones, the same
    rounded to 12 significant digits, are checked current by test_pinocchio)."""
    kin = Kinematics(load_mechanism(_file(name)))
    files = export_files(kin)
    path = tmp_path / f"{name}.urdf"
    path.write_text(files[path.name])
    loops = json.loads(files[f"{name}.loops.json"])
    model = pin.buildModelFromUrdf(str(path))
    assert set(loops["assembly"]) == {model.names[j] for j in range(1, model.njoints)}
    q = pin.neutral(model)
    for j in range(1, model.njoints):
        x, k = loops["assembly"][model.names[j]], model.idx_qs[j]
        q[k : k + model.joints[j].nq] = [np.cos(x), np.sin(x)] if model.joints[j].nq == 2 else [x]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    for loop in loops["loops"]:
        f1, f2 = (model.getFrameId(loop[k]) for k in ("frame1", "frame2"))
        assert f1 < model.nframes and f2 < model.nframes
        gap = np.max(np.abs(data.oMf[f1].translation - data.oMf[f2].translation))
        assert gap < ROUND_OFF * kin.mechanism.size, (loop["cut"], gap)
    # and they are the programmatic model's assembled coordinates
    pm = build(kin)
    expected = pin_coordinates(pm, kin.assemble())
    for model_name, urdf_name in loops["names"].items():
        if urdf_name in loops["assembly"]:
            j = pm.model.getJointId(model_name)
            assert loops["assembly"][urdf_name] == expected[pm.model.idx_qs[j]]


def test_ros_names_are_deterministic_and_distinct():
    assert ros_name("crank.A") == "crank__A" and ros_name("left arm-2") == "left_arm_2"
    assert re.fullmatch(r"[A-Za-z0-9_]+", ros_name("é.x y"))

    n = UrdfNames()
    assert [n("a b"), n("a-b"), n("a b")] == ["a_b", "a_b_2", "a_b"]
