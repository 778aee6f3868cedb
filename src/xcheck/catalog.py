"""Finding mechanism files by name."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import InputError

__all__ = [
    "models_dir",
    "model_path",
    "model_names",
    "benchmark_names",
    "BENCHMARKS",
    "reports_dir",
    "comparisons_dir",
    "comparisons_path",
]

#: The repository's models/ (an editable or source install).
_BUNDLED = Path(__file__).resolve().parents[2] / "models"


def models_dir(override: str | Path | None = None) -> Path:
    """The directory of mechanism files: ``override``, else $XCHECK_MODELS,
    else ./models if it exists, else the repository's models/."""
    if override is not None:
        return Path(override)
    if os.environ.get("XCHECK_MODELS"):
        return Path(os.environ["XCHECK_MODELS"])
    local = Path("models")
    return local if local.is_dir() else _BUNDLED


def model_names(directory: Path) -> list[str]:
    """Names of the mechanism files (``*.toml``) in a directory, sorted."""
    if not directory.is_dir():
        raise InputError(f"{directory}: expected a directory of mechanism files, found none")
    return sorted(p.stem for p in directory.glob("*.toml"))


def model_path(name: str, directory: Path) -> Path:
    """The file of a mechanism given by name (``fourbar``) or path (``x/y.toml``).

    Raises
    ------
    InputError
        If there is no such file; the message lists the known names.
    """
    as_path = Path(name)
    if as_path.suffix == ".toml" or os.sep in name:
        if as_path.is_file():
            return as_path
        raise InputError(f"{name}: expected a mechanism file, found no such file")
    for candidate in (directory / f"{name}.toml", directory / BENCHMARKS / f"{name}.toml"):
        if candidate.is_file():
            return candidate
    known = ", ".join(model_names(directory) + benchmark_names(directory)) or "none"
    raise InputError(f"unknown mechanism {name!r}: expected one of {known} (in {directory})")


#: the subfolder of the models directory with the free-motion benchmark problems
#: (``xcheck simulate NAME``; ``xcheck run all`` runs the models beside it)
BENCHMARKS = "benchmarks"


def benchmark_names(directory: Path) -> list[str]:
    """Names of the benchmark files in ``directory/benchmarks``, sorted (none if absent)."""
    return sorted(p.stem for p in (Path(directory) / BENCHMARKS).glob("*.toml"))


def _home(model_file: Path) -> Path:
    """Where a mechanism file's companions live: beside the ``models/`` directory
    it is in, or beside the file itself when it is elsewhere."""
    folder = Path(model_file).resolve().parent
    if folder.name == BENCHMARKS and folder.parent.name == "models":
        return folder.parent.parent
    return folder.parent if folder.name == "models" else folder


def comparisons_dir(model_file: Path, override: str | Path | None = None) -> Path:
    """The directory of printed textbook answers for a mechanism file:
    ``override``, else $XCHECK_COMPARISONS, else ``comparisons/`` at the file's
    home (beside its ``models/`` directory, or beside the file)."""
    if override is not None:
        return Path(override)
    if os.environ.get("XCHECK_COMPARISONS"):
        return Path(os.environ["XCHECK_COMPARISONS"])
    return _home(model_file) / "comparisons"


def reports_dir(model_file: Path, override: str | Path | None = None) -> Path:
    """Where ``xcheck run`` writes a mechanism's report: ``override``, else
    ``reports/`` at the file's home (so a file of one's own never writes into
    the repository's reports)."""
    return Path(override) if override is not None else _home(model_file) / "reports"


def comparisons_path(model_file: Path, directory: Path) -> Path | None:
    """The comparisons file of a mechanism file (``NAME.toml`` for
    ``NAME.toml``), or None if there is none."""
    candidate = Path(directory) / f"{Path(model_file).stem}.toml"
    return candidate if candidate.is_file() else None


def indexed_names(model_file: Path) -> set[str]:
    """The mechanisms whose reports the index beside a mechanism file's reports
    keeps: the models of its folder and their benchmarks (a benchmark's folder
    is the models folder's ``benchmarks/``)."""
    folder = Path(model_file).parent
    if folder.name == BENCHMARKS:
        folder = folder.parent
    names = set(model_names(folder)) if folder.is_dir() else set()
    return names | set(benchmark_names(folder))
