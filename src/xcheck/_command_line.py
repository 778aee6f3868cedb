"""How xcheck's command line meets a terminal, for every command alike: a command
line it cannot parse in one line, an error in one line and exit code 2, the
loggers' lines on stderr, help texts escaped for rich, the progress bar."""

from __future__ import annotations

import functools
import logging
import re
import sys
import threading
from collections.abc import Sequence
from typing import Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from typer.core import TyperGroup

from . import engines as registry
from ._parallel import QUIET_ACROSS_FORKS, terminal_lock
from .errors import XcheckError

__all__ = [
    "OneLineUsageErrors",
    "escape_help_markup",
    "print_version",
    "progress_bar",
    "reports_errors",
    "route_loggers",
]


#: the base of the errors typer raises for a command line it cannot parse (click's
#: ClickException, which typer vendors from 0.2x on)
_USAGE_ERROR: type[Exception] = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


class OneLineUsageErrors(TyperGroup):
    """The command group, but a command line it cannot parse (an option's value
    of the wrong type, an unknown option or command, a missing argument) is one
    line on stderr, ``xcheck: error: OPTION: expected ..., found ...``, and exit
    code 2, as every other bad input; not a box of usage and help."""

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        forward = {"complete_var": complete_var, "windows_expand_args": windows_expand_args, **extra}
        if not standalone_mode:
            return super().main(args, prog_name, standalone_mode=False, **forward)
        try:
            code = super().main(args, prog_name, standalone_mode=False, **forward)
        except _USAGE_ERROR as err:
            if type(err).__name__ != "NoArgsIsHelpError":  # `xcheck` alone: the help, printed already
                typer.echo(f"xcheck: error: {usage_line(err)}", err=True)
            sys.exit(getattr(err, "exit_code", 2))
        except typer.Abort:
            typer.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


def usage_line(err: Exception) -> str:
    """A command line typer could not parse, as what was expected and what was found."""
    message = " ".join(str(err.format_message()).split())  # type: ignore[attr-defined]
    what = message[:1].lower() + message[1:]
    kind = type(err).__name__
    param = getattr(err, "param", None)
    hint = getattr(err, "param_hint", None) or (param.opts[0] if param is not None and param.opts else "")
    hint = " / ".join(hint) if isinstance(hint, (list, tuple)) else str(hint).strip("'\"")
    ctx = getattr(err, "ctx", None)
    if kind == "NoSuchOption":
        known = (
            sorted(o for p in ctx.command.params for o in (*p.opts, *p.secondary_opts) if o[:1] == "-") if ctx else []
        )
        return f"{err.option_name}: expected an option among {', '.join(known)}, found none of that name"  # type: ignore[attr-defined]
    if kind == "MissingParameter":
        return f"{hint or 'an argument'}: expected a value, found none"
    if param is not None:
        names = {"float": "a number", "integer": "a whole number", "int": "a whole number", "boolean": "yes or no"}
        expected = names.get(param.type.name)
        found = re.search(r": '(.*)' is not a valid", message)
        if expected and found:
            return f"{hint}: expected {expected}, found {found[1]!r}"
        return f"{hint}: expected a valid value, found that {what}"
    found = re.search(r"No such command '(.*)'", message)
    if found and ctx is not None and hasattr(ctx.command, "list_commands"):
        return f"expected a command among {', '.join(ctx.command.list_commands(ctx))}, found {found[1]!r}"
    found = re.search(r"Got unexpected extra argument(?:s|\(s\))? \((.*)\)", message)
    if found:
        return f"expected no more arguments, found {found[1]!r}"
    found = re.search(r"Option '(.*)' requires an argument", message)
    if found:
        return f"{found[1]}: expected a value after it, found none"
    return f"expected a command line that `xcheck --help` describes, found that {what}"


def reports_errors(command):
    """Turn an XcheckError into one line on stderr and exit code 2; say which
    plug-ins could not be loaded, if the command looked for engines."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except XcheckError as err:
            typer.echo(f"xcheck: error: {err}", err=True)
            raise typer.Exit(2) from None
        finally:
            warn_of_plug_ins()

    return wrapper


def warn_of_plug_ins() -> None:
    """One line on stderr per plug-in that could not be loaded, where the
    registry was loaded (the command ran without it)."""
    for name, reason in registry.load_problems(load=False).items():
        typer.echo(
            f"xcheck: warning: plug-in {name!r} (entry-point group {registry.ENTRY_POINT_GROUP!r}) could not be "
            f"loaded, and runs nowhere: {reason}",
            err=True,
        )


class ToStderr(logging.Handler):
    """What xcheck's loggers say (a cache entry not used, and why), one line each
    on stderr: the stderr of the moment, which a test runner may have replaced."""

    def emit(self, record: logging.LogRecord) -> None:
        typer.echo(self.format(record), err=True)


class _Progress(Progress):
    """rich's progress bar, redrawn ten times a second by a thread of its own that draws
    only while it holds :data:`xcheck._parallel.terminal_lock`, so that a worker forked
    from this process meanwhile never starts with the lock of stderr taken (rich's own
    thread, ``auto_refresh``, would draw at any moment)."""

    def __init__(self, *columns, **options) -> None:
        super().__init__(*columns, auto_refresh=False, **options)
        self._stopped = threading.Event()
        self._redraw: threading.Thread | None = None

    def start(self) -> None:
        super().start()
        if not self.disable:
            self._stopped.clear()
            self._redraw = threading.Thread(target=self._redraw_until_stopped, name=QUIET_ACROSS_FORKS, daemon=True)
            self._redraw.start()

    def stop(self) -> None:
        if self._redraw is not None:
            self._stopped.set()
            self._redraw.join()
            self._redraw = None
        super().stop()

    def _redraw_until_stopped(self) -> None:
        while not self._stopped.wait(0.1):
            with terminal_lock:
                self.refresh()


def progress_bar(off: bool, label: str = "{task.description}", stdout_terminal: bool = True) -> Progress:
    """A transient progress bar on stderr (``label``, done/total, time): only
    when stderr is a terminal, and stdout too unless ``stdout_terminal`` is
    False; never with --json or --quiet (``off``), so that piped or captured
    output stays clean."""
    stderr = Console(stderr=True)
    return _Progress(
        SpinnerColumn(),
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=stderr,
        transient=True,
        disable=off or not stderr.is_terminal or (stdout_terminal and not sys.stdout.isatty()),
    )


def escape_help_markup(application: typer.Typer) -> None:
    """Escape the help texts of every command and parameter for the terminal's
    renderer, which reads square brackets as markup ("of [units]" showed as "of ").

    Typer renders help with rich markup; xcheck's help is plain text, so each
    text is escaped once here rather than at each of its many definitions."""
    import inspect
    from typing import get_type_hints

    from typer.models import ParameterInfo

    done: set[int] = set()  # Annotated options shared by several commands are escaped once
    for info in [application.registered_callback, *application.registered_commands]:
        if info is None or info.callback is None:
            continue
        if info.help is None and info.callback.__doc__:
            info.help = escape(inspect.cleandoc(info.callback.__doc__))
        # typer evaluates the (string) annotations anew each time it builds the
        # command: they are evaluated once here, so that the escaped texts stay
        function = inspect.unwrap(info.callback)
        function.__annotations__ = hints = get_type_hints(function, include_extras=True)
        for hint in hints.values():
            for meta in getattr(hint, "__metadata__", ()):
                if isinstance(meta, ParameterInfo) and meta.help and id(meta) not in done:
                    done.add(id(meta))
                    meta.help = escape(meta.help)


def route_loggers() -> None:
    """What xcheck's loggers say at warning level and above, one line each on stderr."""
    said = logging.getLogger("xcheck")
    if not any(isinstance(h, ToStderr) for h in said.handlers):
        said.addHandler(ToStderr(logging.WARNING))


def print_version(value: bool) -> None:
    """``--version``: print xcheck's version and stop."""
    if value:
        from . import __version__

        typer.echo(f"xcheck {__version__}")
        raise typer.Exit()
