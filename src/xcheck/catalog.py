"""Finding mechanism files by name."""

from __future__ import annotations

import os
from importlib import resources
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
    "installed",
]

#: The package's data: ``xcheck/_data/models`` and ``xcheck/_data/comparisons``.
#: In the repository they are links to the top-level models/ and comparisons/
#: (the one copy, which an editable install reads); a wheel holds copies.
_DATA = Path(str(resources.files("xcheck") / "_data"))
_BUNDLED = _DATA / "models"
#: Where the installed package lives: nothing is ever written under it.
_PACKAGE = Path(__file__).resolve().parent


def models_dir(override: str | Path | None = None) -> Path:
    """The directory of mechanism files: ``override``, else $XCHECK_MODELS,
    else ./models if it exists, else the bundled ones (the package's data)."""
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


def installed(model_file: Path) -> bool:
    """Whether a mechanism file is one of an installed package's bundled files
    (its folder is inside the package, not a link to a checkout's models/)."""
    return Path(model_file).resolve().is_relative_to(_PACKAGE)


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
    the repository's reports), else, for a file bundled with an installed
    package, ``./reports`` (nothing is written into the package)."""
    if override is not None:
        return Path(override)
    return Path("reports") if installed(model_file) else _home(model_file) / "reports"


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
