"""Bounded cost (issue 18): loading is linear in the number of bodies, and the
stated limits (bodies, file size, ``--samples``, ``--at`` states) are refused
with one line and exit code 2, before any work that grows with them."""

from __future__ import annotations

import itertools
import random
from pathlib import Path

import numpy as np
import pytest
from test_bad_input import FOURBAR, MODELS, error_line, library_error, run_cli, write

from xcheck import ModelError, load_mechanism
from xcheck.arguments import MAX_SAMPLES, MAX_STATES
from xcheck.model import MAX_BODIES, MAX_FILE_BYTES, Body, Revolute
from xcheck.model._load import _Reader


def pinned_chain(n: int, missing: int | None = None) -> str:
    """``n`` bodies all pinned at one label P: ground-b0, b0-b1, ... (each with
    its own driver); without the joint to body ``missing`` if given."""
    parts = ['[mechanism]\nname = "chain"\n\n[ground]\npoints = { P = [0, 0] }\n']
    parts += [f"[bodies.b{i}]\npoints = {{ P = [0, 0], T{i} = [{i + 1}, 0] }}\n" for i in range(n)]
    joints = [i for i in range(n) if i != missing]
    parts += [
        f'[[joints]]\nname = "J{i}"\ntype = "revolute"\nbodies = ["{f"b{i - 1}" if i else "ground"}", '
        f'"b{i}"]\npoint = "P"\n'
        for i in joints
    ]
    parts += [f'[[drivers]]\nname = "d{i}"\njoint = "J{i}"\nstart = 0\nrate = 1\n' for i in joints]
    return "\n".join(parts)


def ground_star(n: int, coincide: tuple[int, int] | None = None) -> str:
    """``n`` cranks pinned to the ground, each at its own ground point G{i};
    with ``coincide = (i, k)`` the ground points of i and k are at one place."""
    place = {i: [i, 2 * i] for i in range(n)}
    if coincide:
        place[coincide[1]] = place[coincide[0]]
    ground = ", ".join(f"G{i} = {place[i]}" for i in range(n))
    parts = [f'[mechanism]\nname = "star"\n\n[ground]\npoints = {{ {ground} }}\n']
    parts += [f"[bodies.c{i}]\npoints = {{ G{i} = [0, 0], T{i} = [1, 0] }}\n" for i in range(n)]
    parts += [f'[[joints]]\ntype = "revolute"\nbodies = ["ground", "c{i}"]\npoint = "G{i}"\n' for i in range(n)]
    parts += [f'[[drivers]]\njoint = "G{i}"\nstart = 0\nrate = 1\n' for i in range(n)]
    return "\n".join(parts)


# -- loading is linear --------------------------------------------------------------
# (these files used to hang the loader: its label check was O(n^4), 60 bodies 12 s)


def test_long_chain_pinned_at_one_label_loads(tmp_path):
    mech = load_mechanism(write(tmp_path, pinned_chain(MAX_BODIES)))
    assert len(mech.moving_bodies) == MAX_BODIES
    assert len(mech.joints) == MAX_BODIES


def test_unlinked_body_in_a_long_chain_is_named(tmp_path):
    err = library_error(write(tmp_path, pinned_chain(MAX_BODIES, missing=150)))
    assert err.field == "joints"
    assert err.expected == "a revolute joint at 'P' between ground and b150 (they share the label)"


def test_many_ground_points_load(tmp_path):
    mech = load_mechanism(write(tmp_path, ground_star(MAX_BODIES)))
    assert len(mech.moving_bodies) == MAX_BODIES


def test_coincident_ground_points_among_many_are_named(tmp_path):
    err = library_error(write(tmp_path, ground_star(MAX_BODIES, coincide=(123, 156))))
    assert err.field == "ground.points.G156"
    assert "apart from its joint point 'G123'" in err.expected
    assert err.found == "G123 and G156 coincide"


def many_joint_points(n: int, coincide: tuple[int, int] | None = None, loads: int = 0) -> str:
    """One plate pinned to the ground at ``n`` points (far too many joints to
    assemble, but loading does not count them); with ``coincide = (i, k)`` the
    ground points G{i} and G{k} at one place; with ``loads`` torques on the plate."""
    place = {i: [i % 100, i // 100] for i in range(n)}
    if coincide:
        place[coincide[1]] = place[coincide[0]]
    ground = ", ".join(f"G{i} = {place[i]}" for i in range(n))
    plate = ", ".join(f"G{i} = [{i % 100}, {i // 100}]" for i in range(n))
    parts = [
        f'[mechanism]\nname = "plate"\n\n[ground]\npoints = {{ {ground} }}\n',
        f"[bodies.plate]\npoints = {{ {plate} }}\nmass = 1\ninertia = 1\n",
    ]
    parts += [f'[[joints]]\ntype = "revolute"\nbodies = ["ground", "plate"]\npoint = "G{i}"\n' for i in range(n)]
    parts.append('[[drivers]]\njoint = "G0"\nstart = 0\nrate = 1\n')
    parts += [f'[[loads]]\nbody = "plate"\ntorque = {i}\n' for i in range(loads)]
    return "\n".join(parts)


def test_many_joints_and_loads_load(tmp_path):
    mech = load_mechanism(write(tmp_path, many_joint_points(5000, loads=5000)))
    assert (len(mech.joints), len(mech.loads)) == (5000, 5000)


def test_coincident_points_among_many_joints_are_named(tmp_path):
    err = library_error(write(tmp_path, many_joint_points(5000, coincide=(1234, 4321))))
    assert err.field == "ground.points.G4321"
    assert err.found == "G1234 and G4321 coincide"


def _pairwise_label_error(bodies: list[Body], joints: list[Revolute]) -> str | None:
    """The message of the former pairwise check (every pair of owners of a label,
    in order, reachable through revolutes at that label), as the reference."""
    pinned = {(j.point_a, frozenset((j.body_a, j.body_b))) for j in joints if j.point_a == j.point_b}
    labels = dict.fromkeys(label for b in bodies for label in b.points)
    for label in labels:
        names = [b.name for b in bodies if label in b.points]
        for first, second in itertools.combinations(names, 2):
            reached, frontier = {first}, [first]
            while frontier:
                node = frontier.pop()
                for lbl, pair in pinned:
                    if lbl == label and node in pair:
                        (other,) = pair - {node}
                        if other not in reached:
                            reached.add(other)
                            frontier.append(other)
            if second not in reached:
                return f"a revolute joint at {label!r} between {first} and {second} (they share the label)"
    return None


@pytest.mark.parametrize("seed", range(200))
def test_shared_label_check_matches_the_pairwise_check(seed):
    """On random small mechanisms the linear check refuses exactly what the
    pairwise one refused, naming the same pair."""
    rng = random.Random(seed)
    names = ["ground"] + [f"b{i}" for i in range(rng.randint(1, 6))]
    labels = "PQR"
    bodies = [
        Body(name, {lbl: np.zeros(2) for lbl in labels if rng.random() < 0.6} or {"X": np.zeros(2)}) for name in names
    ]
    joints = []
    for _ in range(rng.randint(0, 8)):
        a, b = rng.sample(bodies, 2)
        common = sorted(set(a.points) & set(b.points))
        if common:
            label = rng.choice(common)
            joints.append(Revolute(f"J{len(joints)}", a.name, b.name, label, label))
    expected = _pairwise_label_error(bodies, joints)
    reader = _Reader("random.toml")
    if expected is None:
        reader.check_shared_labels(bodies, joints)
    else:
        with pytest.raises(ModelError) as info:
            reader.check_shared_labels(bodies, joints)
        assert info.value.expected == expected


# -- stated limits ------------------------------------------------------------------


def test_too_many_bodies_are_refused(tmp_path):
    path = write(tmp_path, pinned_chain(MAX_BODIES + 1))
    err = library_error(path)
    assert (err.field, err.expected, err.found) == (
        "bodies",
        f"at most {MAX_BODIES} moving bodies",
        str(MAX_BODIES + 1),
    )
    error_line(
        run_cli("solve", str(path)),
        f"{path}: bodies: expected at most {MAX_BODIES} moving bodies, found {MAX_BODIES + 1}",
    )


def test_a_large_file_is_refused_before_parsing(tmp_path):
    path = tmp_path / "huge.toml"
    with path.open("wb") as file:  # 50 MB that are not even TOML: never parsed
        file.truncate(50_000_000)
    err = library_error(path)
    assert (err.field, err.found) == ("", "50000000 bytes")
    assert err.expected == f"a mechanism file of at most {MAX_FILE_BYTES} bytes"
    error_line(
        run_cli("solve", str(path)),
        f"{path}: expected a mechanism file of at most {MAX_FILE_BYTES} bytes, found 50000000 bytes",
    )


def test_a_file_just_within_the_size_limit_loads(tmp_path):
    text = FOURBAR + "\n"
    text += "#" * (MAX_FILE_BYTES - len(text.encode("utf-8")) - 1) + "\n"
    path = write(tmp_path, text)
    assert path.stat().st_size == MAX_FILE_BYTES
    assert load_mechanism(path).name == "fourbar"


def test_crlf_line_ends_still_read(tmp_path):
    path = tmp_path / "crlf.toml"
    path.write_bytes(FOURBAR.replace("\n", "\r\n").encode("utf-8"))
    mech = load_mechanism(path)
    assert mech.name == "fourbar"
    assert "\r" not in mech.notes


@pytest.mark.parametrize("samples", [2, MAX_SAMPLES + 1, 100_000_000])
def test_samples_out_of_bounds_are_refused(samples):
    error_line(
        run_cli("run", "fourbar", "--samples", str(samples), "--models", str(MODELS), "--no-report"),
        f"--samples: expected a whole number from 3 to {MAX_SAMPLES}, found {samples}",
    )


def test_too_many_at_states_are_refused():
    at = ",".join(["45"] * (MAX_STATES + 1))
    error_line(
        run_cli("solve", "fourbar", "--at", at, "--models", str(MODELS)),
        f"fourbar.toml: --at: expected from 1 to {MAX_STATES} states, found {MAX_STATES + 1}",
    )


def test_too_many_instants_are_refused(tmp_path):
    text = FOURBAR.split("[[instants]]")[0] + "[[instants]]\ncrank = 30\n\n" * (MAX_STATES + 1)
    err = library_error(write(tmp_path, text))
    assert (err.field, err.expected, err.found) == (
        "instants",
        f"at most {MAX_STATES} [[instants]]",
        str(MAX_STATES + 1),
    )


def test_limits_are_documented():
    docs = (Path(__file__).resolve().parents[1] / "docs" / "mechanism-format.md").read_text(encoding="utf-8")
    for limit in (MAX_BODIES, MAX_FILE_BYTES, MAX_SAMPLES, MAX_STATES):
        assert str(limit) in docs, limit


def test_too_many_outputs_are_counted_whole(tmp_path):
    """1 000 001 outputs were refused as "found 1e+06", below the limit they exceed."""
    from xcheck.model._free_motion import MAX_OUTPUTS

    text = (MODELS / "benchmarks" / "iftomm-a01.toml").read_text(encoding="utf-8")
    text = text.replace("duration = 10\noutput_step = 0.01", "duration = 1.000001\noutput_step = 1e-6")
    err = library_error(write(tmp_path, text))
    assert (err.field, err.expected, err.found) == (
        "free_motion.output_step",
        f"at most {MAX_OUTPUTS} outputs over the duration",
        "1000001 (1.000001 s / 1e-06 s)",
    )
