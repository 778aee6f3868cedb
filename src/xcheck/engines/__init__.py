"""Engine adapters: MuJoCo, Pinocchio and pymunk, each converting the canonical
mechanism model (nothing converts back) and returning :class:`~xcheck.compare.ModeResult`.

Each adapter module provides ``run_<mode>(kinematics, **options) -> ModeResult``
for its modes; :data:`MODES` maps a mode's name to (module, function) and
:data:`EXPORTERS` a file format to (module, function, directory, suffix). Modules
are imported on first use so that a broken or missing engine affects only its
own modes.
"""

from __future__ import annotations

import importlib

__all__ = ["MODES", "EXPORTERS", "mode_function", "exporter"]

MODES = {
    "mujoco-kinematic": ("xcheck.engines.mujoco", "run_kinematic"),
    "mujoco-dynamic": ("xcheck.engines.mujoco", "run_dynamic"),
    "pinocchio-kinematic": ("xcheck.engines.pinocchio", "run_kinematic"),
    "pinocchio-dynamic": ("xcheck.engines.pinocchio", "run_dynamic"),
    "pymunk-dynamic": ("xcheck.engines.pymunk", "run_dynamic"),
}

#: format -> (module, function, subdirectory of models/). The function
#: takes a Kinematics and returns {file name: text} (e.g. {"fourbar.xml": ...}).
EXPORTERS = {
    "mjcf": ("xcheck.engines.mujoco", "export_files", "mjcf"),
    "urdf": ("xcheck.engines.pinocchio", "export_files", "urdf"),
}


def mode_function(mode: str):
    """The function running an engine mode; ValueError listing the modes if unknown."""
    if mode not in MODES:
        raise ValueError(f"expected an engine mode ({', '.join(MODES)}), found {mode!r}")
    module, function = MODES[mode]
    return getattr(importlib.import_module(module), function)


def exporter(fmt: str):
    """(function, directory) of a model-file exporter."""
    if fmt not in EXPORTERS:
        raise ValueError(f"expected a format ({', '.join(EXPORTERS)}), found {fmt!r}")
    module, function, directory = EXPORTERS[fmt]
    return getattr(importlib.import_module(module), function), directory
