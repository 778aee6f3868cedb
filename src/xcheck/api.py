"""The Python interface: what the command line does, as functions for scripts and notebooks.

>>> import xcheck
>>> kin = xcheck.load("fourbar")
>>> kin.mechanism.name
'fourbar'
>>> xcheck.select_modes("formulations")
('native', 'formulation-I', 'formulation-II')

:func:`compare` runs the comparison of ``xcheck run`` and returns its
:class:`~xcheck.runner.RunResult`; the command line only adds printing, the
reports and exit codes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from . import engines
from .catalog import comparisons_dir, comparisons_path, model_path, models_dir
from .errors import InputError
from .kinematics import Kinematics
from .model import load_mechanism
from .runner import RunResult, run_mechanism
from .textbook import check_printed, load_comparisons

__all__ = ["load", "select_modes", "printed_answers", "compare"]


def load(name: str | Path, models: str | Path | None = None, branch: str | None = None) -> Kinematics:
    """A mechanism, assembled: by name from the models directory (``models``,
    else $XCHECK_MODELS, else ./models, else the bundled ones) or by path.

    Raises
    ------
    XcheckError
        If there is no such mechanism, its file is bad, or it does not assemble;
        the message is one line naming the file and the field.
    """
    kinematics = Kinematics(load_mechanism(model_path(str(name), models_dir(models))))
    kinematics.assemble(branch)
    return kinematics


def select_modes(
    chosen: str | Sequence[str] | None = None, kinds: tuple[str, ...] = engines.DRIVEN_KINDS
) -> tuple[str, ...]:
    """The modes a selection names, "native" first.

    Parameters
    ----------
    chosen : str or sequence of str, optional
        Modes or groups (an engine's name such as ``"mujoco"``, or a kind:
        ``"kinematic"``, ``"dynamic"``; :func:`xcheck.engines.groups`), as a
        comma-separated string (``--engines``) or a sequence; None: every mode.
    kinds : tuple of str
        The kinds of mode to choose from: the driven ones (``xcheck run``,
        default) or ``("free",)`` (``xcheck simulate``).

    Raises
    ------
    InputError
        If a name is neither a mode nor a group, or none is given.
    """
    every = ("native", *(m.name for m in engines.modes(kinds)))
    groups = engines.groups(kinds)
    if chosen is None:
        return every
    text = chosen if isinstance(chosen, str) else ",".join(chosen)
    picked: list[str] = []
    for item in (part.strip() for part in text.split(",") if part.strip()):
        if item in every:
            picked.append(item)
        elif item in groups:
            picked.extend(groups[item])
        else:
            raise InputError(
                f"--engines: expected modes or groups among {', '.join(every)}, {', '.join(groups)}, found {item!r}"
            )
    if not picked:
        raise InputError(
            f"--engines: expected at least one mode or group among {', '.join(every)}, "
            f"{', '.join(groups)}, found {text!r}"
        )
    return tuple(dict.fromkeys(["native", *picked]))


def printed_answers(kinematics: Kinematics, comparisons: str | Path | None = None) -> tuple[list[dict] | None, str]:
    """The printed answers of a mechanism's comparisons file, checked value by
    value (:func:`xcheck.textbook.check_printed`), and the document they come
    from; (None, "") when the mechanism has no comparisons file.

    Raises
    ------
    XcheckError
        If the comparisons file is bad.
    """
    path = Path(kinematics.mechanism.path)
    found = comparisons_path(path, comparisons_dir(path, comparisons))
    if found is None:
        return None, ""
    printed = load_comparisons(found, kinematics.mechanism)
    return check_printed(kinematics, printed), printed.document


def compare(
    name: str | Path | Kinematics,
    engines: str | Sequence[str] | None = None,
    samples: int = 181,
    branch: str | None = None,
    models: str | Path | None = None,
    comparisons: str | Path | None = None,
    progress=None,
) -> RunResult:
    """Every requested mode on one mechanism against the exact native solution
    (``xcheck run`` without printing or reports).

    Parameters
    ----------
    name : str, Path or Kinematics
        A mechanism name, a file, or a loaded mechanism.
    engines : str or sequence of str, optional
        As :func:`select_modes` (default: every mode).
    samples : int
        Samples of the sweeps over the feasible input range.
    progress : callable, optional
        Called with each mode's name before it runs.

    Returns
    -------
    RunResult
        ``passed`` says whether every mode met its tolerance; ``outcomes`` has
        each mode's table of differences by category.
    """
    kinematics = name if isinstance(name, Kinematics) else load(name, models, branch)
    textbook, _ = printed_answers(kinematics, comparisons)
    return run_mechanism(kinematics, select_modes(engines), samples, branch, textbook, progress=progress)
