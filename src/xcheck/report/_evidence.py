"""A report's evidence: what each mode (and each force source) of a run showed,
as the report shows it, kept beside the report in its folder
(``reports/NAME/results.json``, :data:`xcheck.fileio.MANIFEST`), with the run
that produced it. A later run of some modes (``--engines``) updates their parts
and keeps the others' with their provenance; a figure drawn from modes the
later run did not run is kept as it was.

The file is also the folder's manifest: ``files`` names every file xcheck
wrote there, and nothing else in the folder is xcheck's.
"""

from __future__ import annotations

import datetime
import json
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..fileio import MANIFEST, read_json

__all__ = ["Evidence", "produced", "read_evidence", "merge"]

#: the layout of the file; another value is no evidence (the report is then written afresh)
FORMAT = 1


def produced(command: str) -> dict:
    """Where a part comes from: the command, xcheck's version and the date (UTC)."""
    return {"command": command, "xcheck": __version__, "date": _today()}


def _today() -> str:
    return datetime.datetime.now(datetime.UTC).date().isoformat()


@dataclass
class Evidence:
    """A report's parts by what produced them.

    Attributes
    ----------
    kind : str
        "run" (``xcheck run``) or "simulate" (``xcheck simulate``).
    mechanism : str
    modes : dict
        Mode name -> its parts: what the report shows of it (table rows as
        lists of cells, text blocks), its verdict, and ``produced``
        (:func:`produced`).
    sources : dict
        Force source -> its parts (``run`` only).
    figures : dict
        File name -> ``{"modes": [the modes and sources it shows], "produced": ...}``.
    carried : set of str
        The modes and sources kept from an earlier run (not in the file).
    kept : set of str
        The figures kept from an earlier run (not in the file).
    """

    kind: str
    mechanism: str
    modes: dict[str, dict] = field(default_factory=dict)
    sources: dict[str, dict] = field(default_factory=dict)
    figures: dict[str, dict] = field(default_factory=dict)
    carried: set[str] = field(default_factory=set)
    kept: set[str] = field(default_factory=set)

    def document(self, files: list[str]) -> dict:
        """The JSON document of the folder's manifest, ``files`` its files."""
        return {
            "generator": "xcheck",
            "format": FORMAT,
            "kind": self.kind,
            "mechanism": self.mechanism,
            "files": sorted(files),
            "modes": self.modes,
            "sources": self.sources,
            "figures": self.figures,
        }


def read_evidence(folder: Path, kind: str, mechanism: str) -> Evidence | None:
    """The evidence of the report in ``folder`` (its :data:`~xcheck.fileio.MANIFEST`),
    or None where there is none of this kind and mechanism in a layout this
    version reads (the report is then written afresh)."""
    document = read_json(folder / MANIFEST)
    if not isinstance(document, dict) or document.get("generator") != "xcheck":
        return None
    if document.get("format") != FORMAT or document.get("kind") != kind or document.get("mechanism") != mechanism:
        return None
    modes, sources, figures = (document.get(key) for key in ("modes", "sources", "figures"))
    if not all(isinstance(p, dict) and all(isinstance(v, dict) for v in p.values()) for p in (modes, sources, figures)):
        return None
    assert isinstance(modes, dict) and isinstance(sources, dict) and isinstance(figures, dict)
    if not all(_provenance(p) for p in (*modes.values(), *sources.values(), *figures.values())):
        return None
    if not all(isinstance(f.get("modes"), list) for f in figures.values()):
        return None
    return Evidence(kind, mechanism, modes, sources, figures)


def _provenance(part: dict) -> bool:
    made = part.get("produced")
    return isinstance(made, dict) and all(isinstance(made.get(k), str) for k in ("command", "xcheck", "date"))


def merge(fresh: Evidence, previous: Evidence | None) -> Evidence:
    """The evidence of a report after a run: ``fresh``'s parts, and those of
    ``previous`` for the modes and sources the run did not run (``carried``).
    A figure of ``previous`` that shows a carried mode is kept (``kept``)
    instead of the run's own, which would leave that mode out. A fresh part
    that reproduces ``previous``'s keeps its provenance (:func:`_restamped`)."""
    if previous is None:
        return fresh
    modes = _carried_in_place(
        {key: _restamped(part, previous.modes.get(key)) for key, part in fresh.modes.items()}, previous.modes
    )
    sources = _carried_in_place(
        {key: _restamped(part, previous.sources.get(key)) for key, part in fresh.sources.items()}, previous.sources
    )
    carried = (previous.modes.keys() - fresh.modes.keys()) | (previous.sources.keys() - fresh.sources.keys())
    figures = {key: _restamped(part, previous.figures.get(key)) for key, part in fresh.figures.items()}
    kept = set()
    for file, figure in previous.figures.items():
        if carried & set(figure["modes"]):
            figures[file] = figure
            kept.add(file)
    return Evidence(fresh.kind, fresh.mechanism, modes, sources, figures, carried, kept)


def _carried_in_place(fresh: dict[str, dict], previous: dict[str, dict]) -> dict[str, dict]:
    """``fresh`` with the parts of ``previous`` it lacks, each placed after the
    part it followed in ``previous`` (first where none did): the rows of a
    partial run read in the order of a whole one, whichever modes it reran."""
    merged = list(fresh.items())
    placed = set(fresh)
    before = None
    for key, part in previous.items():
        if key not in placed:
            at = 0 if before is None else next(i for i, (k, _) in enumerate(merged) if k == before) + 1
            merged.insert(at, (key, part))
            placed.add(key)
        before = key
    return dict(merged)


def _restamped(part: dict, earlier: dict | None) -> dict:
    """``part`` with the provenance of ``earlier``, the same part of the report
    before, where the run reproduced it: the same command and version of xcheck
    produced what it shows (a figure: the modes it shows). The evidence then
    still reads as it did, whatever the date or the results cache's times, so a
    rerun of a committed report leaves its file as it was."""
    if earlier is None:
        return part
    made, before = part["produced"], earlier["produced"]
    if (made["command"], made["xcheck"]) != (before["command"], before["xcheck"]):
        return part
    if _shown(part) != _shown(earlier):
        return part
    return {**part, "produced": before}


def _shown(part: dict) -> str:
    """What a part shows, as its JSON reads, without its provenance."""
    return json.dumps({key: value for key, value in part.items() if key != "produced"}, sort_keys=True)
