"""Sphinx directives that write the engines' facts from xcheck's registry, so that a
page never restates by hand what an engine declares (and an engine added to the
registry appears in the table with no edit here).

``{xcheck-engines}``: one row per registered engine. ``{xcheck-engine} NAME``: the
facts of one engine (modes, kinds, what each is trusted for, tolerances' bases,
findings, install).
"""

from __future__ import annotations

from docutils.parsers.rst import Directive, directives
from docutils.statemachine import StringList

from xcheck import engines
from xcheck.output import mode_trust


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


class _Markdown(Directive):
    def _parse(self, lines: list[str]) -> list:
        from docutils import nodes

        container = nodes.container()
        self.state.nested_parse(StringList(lines, source="xcheck registry"), self.content_offset, container)
        return container.children


def _findings(engine, mode) -> str:
    """A mode's stated findings in a cell: the quantities they spoil (and where), "" without."""
    found = [f for f in engine.findings if mode.kind in f.kinds]
    if not found:
        return ""
    quantities = ", ".join(dict.fromkeys(q for f in found for q in f.quantities))
    return f"`{mode.name}`: {quantities}" + (" (closed loops)" if all(f.closed_loops for f in found) else "")


class EnginesTable(_Markdown):
    """The table of every registered engine."""

    has_content = False

    def run(self):
        lines = ["| engine | modes | trusted for | stated findings | install |", "|---|---|---|---|---|"]
        for engine in engines.engines():
            modes = "<br>".join(f"`{m.name}` ({m.kind})" for m in engine.modes)
            trust = "<br>".join(_cell(mode_trust(m)) for m in engine.modes)
            findings = "<br>".join(_findings(engine, m) for m in engine.modes if _findings(engine, m))
            page = f"[{engine.title}]({engine.name}.md)"
            lines.append(
                f"| {page} | {modes} | {trust} | {findings or '—'} | `{_cell(engine.install) or 'with xcheck'}` |"
            )
        return self._parse(lines)


class EngineFacts(_Markdown):
    """The facts one engine declares."""

    required_arguments = 1
    has_content = False

    def run(self):
        engine = engines.engine(self.arguments[0])
        lines = [
            f"{_cell(engine.notes)}",
            "",
            f"Install: `{engine.install or 'with xcheck'}`"
            + (f"; packages: {', '.join(f'`{d}`' for d in engine.distributions)}" if engine.distributions else "")
            + (f"; writes `{engine.export_format}` files (`xcheck export`)" if engine.export_format else "")
            + ".",
            "",
            "| mode | kind | trusted for | tolerance and its basis |",
            "|---|---|---|---|",
        ]
        for mode in engine.modes:
            lines.append(
                f"| `{mode.name}` | {mode.kind}{' (on request)' if mode.on_request else ''} | "
                f"{_cell(mode_trust(mode))} | {_cell(mode.tolerance.basis)} |"
            )
        if engine.force_tolerance is not None:
            lines += [
                "",
                f"Joint reactions and driving efforts: within {engine.force_tolerance:g} ({engine.force_basis}).",
            ]
        for finding in engine.findings:
            lines += ["", f"**Stated finding** ({finding.scope}): {_cell(finding.title)}. {_cell(finding.text)}."]
            if finding.reproducer:
                # the script as its engine's maintainers would run it (docs/engines/NAME.md -> the repository's root)
                lines += [
                    "",
                    f"Reproducer: `python {finding.reproducer}` (it imports only the engine and numpy; "
                    "exits 0 while the defect shows):",
                    "",
                    f"```{{literalinclude}} ../../{finding.reproducer}",
                    ":language: python",
                    "```",
                ]
        return self._parse(lines)


def setup(app):
    directives.register_directive("xcheck-engines", EnginesTable)
    directives.register_directive("xcheck-engine", EngineFacts)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
