"""Shared helpers for the tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from xcheck import Kinematics, load_mechanism

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
MODEL_NAMES = sorted(p.stem for p in MODELS.glob("*.toml"))


@pytest.fixture(scope="session")
def kinematics():
    """Kinematics of a model in models/ by name, built once per session."""
    cache: dict[str, Kinematics] = {}

    def get(name: str) -> Kinematics:
        if name not in cache:
            cache[name] = Kinematics(load_mechanism(MODELS / f"{name}.toml"))
        return cache[name]

    return get
