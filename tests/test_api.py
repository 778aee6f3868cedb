"""The Python interface (xcheck.api): what ``xcheck run`` does, as functions."""

from __future__ import annotations

import doctest

import pytest
from conftest import MODELS

import xcheck
from xcheck import api


def test_docstring_examples_run():
    failed, attempted = doctest.testmod(api)
    assert attempted >= 2 and failed == 0


def test_load_by_name_and_by_path_is_assembled():
    by_name = xcheck.load("fourbar", models=MODELS)
    by_path = xcheck.load(MODELS / "fourbar.toml")
    assert by_name.mechanism.path == by_path.mechanism.path
    assert by_name.mechanism.name == "fourbar"


def test_select_modes_takes_groups_and_sequences():
    assert xcheck.select_modes(["mujoco-kinematic", "formulations"]) == (
        "native",
        "mujoco-kinematic",
        "formulation-I",
        "formulation-II",
    )
    assert xcheck.select_modes("pymunk") == ("native", "pymunk-dynamic")
    with pytest.raises(xcheck.InputError, match="found 'nosuch'"):
        xcheck.select_modes("nosuch")


def test_compare_is_the_run_without_printing():
    run = api.compare("fourbar", engines="formulations", samples=21, models=MODELS)
    assert run.passed
    assert set(run.outcomes) == {"native", "formulation-I", "formulation-II"}
    assert len(run.textbook) == 96  # comparisons/fourbar.toml, found beside models/
