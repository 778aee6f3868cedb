"""The engines xcheck judges, on one contract.

Each engine is a subpackage whose ``__init__`` describes it (an
:class:`Engine` subclass: name, modes, tolerances, what it needs) without
importing the package it wraps; its modes, converter and file writer live in
the subpackage's modules and are imported when a mode runs:

- :mod:`xcheck.engines.mujoco`: the mechanism as an MJCF file; kinematic oracle and driven dynamics.
- :mod:`xcheck.engines.pinocchio`: a kinematic tree with loop constraints (URDF); the same two modes.
- :mod:`xcheck.engines.pymunk`: a 2-D constraint scene; driven dynamics.

The independent exact formulations of the seeds are registered the same way
(:mod:`xcheck.formulations.engine`). The registry (:func:`engines`,
:func:`modes`, :func:`register`) is open to other packages through the
entry-point group ``xcheck.engines``.
"""

from __future__ import annotations

from ._contract import DRIVEN_KINDS, KINDS, Engine, Finding, Mode, NotApplicable, with_unit_mass
from ._registry import (
    ALL,
    ENTRY_POINT_GROUP,
    engine,
    engine_of,
    engines,
    exporters,
    groups,
    load_problems,
    mode,
    modes,
    register,
    registered_at_run_time,
    unregister,
)

__all__ = [
    "KINDS",
    "DRIVEN_KINDS",
    "Engine",
    "Finding",
    "Mode",
    "NotApplicable",
    "with_unit_mass",
    "ENTRY_POINT_GROUP",
    "ALL",
    "engine",
    "engine_of",
    "engines",
    "exporters",
    "groups",
    "load_problems",
    "mode",
    "modes",
    "register",
    "registered_at_run_time",
    "unregister",
]
