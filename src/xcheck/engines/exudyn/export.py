"""The Exudyn script of a mechanism (``xcheck export --format exudyn``): the very
system the ``exudyn-free`` mode integrates (:func:`.model.build_system`), read back
item by item from Exudyn and written as ``mbs.AddNode({...})``,
``mbs.AddObject({...})``, ``mbs.AddMarker({...})`` and ``mbs.AddLoad({...})``
calls, so a user can open, run and change what xcheck tested.

Only a mechanism with a ``[free_motion]`` section is written: its nodes start at
the release state (:func:`xcheck.dynamics.release_state`). A load's time law
becomes a Python user function in the script. Run as a program, the script
integrates the system with the ``default`` setting of the mode (generalized-alpha,
spectral radius 0.9, fixed steps) and prints each body's final node coordinates.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from xcheck.engines._contract import NotApplicable
from xcheck.kinematics import Kinematics
from xcheck.ladder import FREE_STEPS
from xcheck.model import LoadLaw
from xcheck.precision import number

from .free import FREE_SERIES
from .model import build_system

__all__ = ["export_files", "script"]

#: Exudyn's item kinds, in the order the script adds them (markers name bodies,
#: joints name markers, loads name markers: every number exists when Assemble checks)
_KINDS = (("Node", "NumberOfNodes"), ("Object", "NumberOfObjects"), ("Marker", "NumberOfMarkers"))


def export_files(kinematics: Kinematics) -> dict[str, str]:
    """``{NAME.py: the script}``; NotApplicable without ``[free_motion]`` or for
    what Exudyn cannot hold."""
    return {f"{kinematics.mechanism.name}.py": script(kinematics)}


def _plain(value):
    """A field's value with arrays as (nested) lists."""
    return value.tolist() if isinstance(value, np.ndarray) else value


def _floats(value) -> list[float]:
    """The floats of a field's value, nested lists flattened."""
    if isinstance(value, float):
        return [value]
    if isinstance(value, (list, tuple)):
        return [f for v in value for f in _floats(v)]
    return []


def _value(value, scale: float = 0.0) -> str:
    """Python source of one item field: a vector's numbers on ``scale`` (the largest
    magnitude of the field over the file), a number on its own relative to itself
    (:func:`xcheck.precision.number`: canonical when exported, else exact)."""
    value = _plain(value)
    if isinstance(value, float):
        value = number(value, scale)
        return repr(value) if math.isfinite(value) else f"float({str(value)!r})"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v, scale) for v in value) + "]"
    return repr(value)


def _law_function(name: str, law: LoadLaw) -> str:
    """The source of an Exudyn load user function for a time law."""
    if law.kind == "harmonic":
        factor = f"{law.offset!r} + math.sin(2.0 * math.pi * {law.frequency!r} * t + {law.phase!r})"
    else:
        factor = f"min(t / {law.duration!r}, 1.0)"
    return (
        f"def {name}(mbs, t, load):\n"
        f'    """The load times its {law.describe()}."""\n'
        f"    return [({factor}) * v for v in load]\n"
    )


def script(kinematics: Kinematics) -> str:
    """The Exudyn script of the mechanism released in free motion (text)."""
    from xcheck import __version__
    from xcheck.dynamics._free import release_state
    from xcheck.errors import XcheckError

    mech = kinematics.mechanism
    spec = mech.free_motion
    if spec is None:
        raise NotApplicable("no [free_motion]: the Exudyn script holds a mechanism released in free motion")
    try:
        start = release_state(kinematics)
    except XcheckError as error:
        raise NotApplicable(f"no release state: {' '.join(str(error).split())}") from error
    model = build_system(mech, start.q, start.qd)
    mbs = model.mbs
    names = {int(node): body for body, node in model.nodes.items()}
    laws: list[str] = []
    lines: list[str] = []
    data = mbs.systemData
    items = []
    for kind, count in (*_KINDS, ("Load", "NumberOfLoads")):
        for index in range(getattr(data, count)()):
            item = dict(getattr(mbs, f"Get{kind}")(index))
            if kind == "Node" and index in names:
                item["name"] = names[index]
            # drawing data (V...) is nothing the dynamics reads
            items.append((kind, index, {k: v for k, v in item.items() if not k.startswith("V") or k == "Vshow"}))
    # a vector field's scale: its largest magnitude over the file (the state's
    # coordinates and velocities, positions, loads), so round-off of a zero is 0
    scales: dict[str, float] = {}
    for _, _, item in items:
        for key, value in item.items():
            plain = _plain(value)
            if isinstance(plain, (list, tuple)):
                magnitudes = [abs(f) for f in _floats(plain) if math.isfinite(f)]
                scales[key] = max([scales.get(key, 0.0), *magnitudes])
    for kind, index, item in items:
        fields = []
        for key, value in item.items():
            if isinstance(value, dict) and "function" in value:  # a load's time law
                law = getattr(value["function"], "law", None)
                if law is None:
                    raise NotApplicable(f"{kind.lower()} {index}: a user function xcheck cannot write")
                function = f"law_{len(laws)}"
                laws.append(_law_function(function, law))
                fields.append(f"{key!r}: {function}")
                continue
            fields.append(f"{key!r}: {_value(value, scales.get(key, 0.0))}")
        lines.append(f"mbs.Add{kind}({{{', '.join(fields)}}})")
    setting, dt = FREE_SERIES[0].options, min(FREE_STEPS[0], spec.output_step / 10.0)
    steps = max(1, round(spec.duration / dt))
    header = (
        f'"""Exudyn model of {mech.name} ({Path(mech.path).name}), written by `xcheck export --format exudyn`\n'
        f"(xcheck {__version__}); regenerate it rather than edit it.\n\n"
        "The system xcheck's mode exudyn-free integrates: 2-D rigid bodies with their nodes at the\n"
        "centres of mass, at the release state of [free_motion]; joints as index-3 constraints;\n"
        "gravity as a force at each centre of mass; springs, torques and loads as in the file.\n"
        f"Run it to integrate {spec.duration:g} s at a step of {dt:g} s with Exudyn's {setting.integrator}\n"
        "(xcheck's `default` setting) and print each body's final node coordinates (x, y of the\n"
        'centre of mass in m, angle in rad).\n"""\n'
    )
    body = [
        header,
        "import math  # noqa: F401 - used by the load laws, when there are some",
        "",
        "import exudyn as exu",
        "",
        "SC = exu.SystemContainer()",
        "mbs = SC.AddSystem()",
        "",
        *laws,
        *lines,
        "",
        "",
        'if __name__ == "__main__":',
        "    mbs.Assemble()",
        "    settings = exu.SimulationSettings()",
        f"    settings.timeIntegration.numberOfSteps = {steps}",
        f"    settings.timeIntegration.endTime = {spec.duration!r}",
        "    settings.timeIntegration.verboseMode = 0",
        "    settings.timeIntegration.adaptiveStep = False",
        f"    settings.timeIntegration.generalizedAlpha.spectralRadius = {setting.spectral_radius!r}",
        "    settings.solution.file.write = False",
        "    mbs.SolveDynamic(settings)",
        f"    for name in {sorted(model.nodes)!r}:",
        "        node = mbs.GetNodeNumber(name)",
        "        start = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates, exu.ConfigurationType.Reference)",
        "        displaced = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates)",
        "        print(name, *(f'{r + d:.12g}' for r, d in zip(start, displaced)))",
        "",
    ]
    return "\n".join(body)
