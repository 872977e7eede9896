"""The program behind ``livox-viz``: the command table, its parser and one run of a command.

Imported by :func:`livox_viz.cli.main` once it has taken Ctrl-C, SIGTERM and SIGHUP: loading the commands
loads numpy and the model (a few tenths of a second), and a signal in that time must end the program
quietly, not with a traceback.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from collections.abc import Iterable, Sequence
from importlib.metadata import entry_points

from livox_viz.core.atomic import remove_unfinished
from livox_viz.core.errors import LivoxVizError, bounded_message

from . import batch_commands, fit_commands, pattern_commands, scan_commands, wire_commands
from .common import PROG, Command, UsageError
from .signals import Terminated, signal_name, signal_status, take_raised

ENTRY_POINT_GROUP = "livox_viz.commands"
MODEL_COMMANDS: tuple[Command, ...] = (
    *pattern_commands.COMMANDS, *scan_commands.COMMANDS, *batch_commands.COMMANDS, *fit_commands.COMMANDS,
    *wire_commands.COMMANDS,
)

__all__ = ["ENTRY_POINT_GROUP", "MODEL_COMMANDS", "build_parser", "installed_commands", "run"]


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with a one-line message (argparse's own usage dump is long), and takes a value
    that starts with a minus and a digit as a value (Python 3.13's rule): before 3.13 only a plain number did, so
    ``--size -5x10`` and ``--pose -5,0,-2,0,0,0`` said "expected one argument". No option here is named like that.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"-\.?\d")

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {bounded_message(message)}\n")


def installed_commands() -> list[Command]:
    """The commands other installed packages register under :data:`ENTRY_POINT_GROUP`."""
    found: list[Command] = []
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        found.extend(entry.load())
    return found


def build_parser(commands: Iterable[Command]) -> argparse.ArgumentParser:
    """The whole command line; each subcommand has ``--help`` with an example."""
    parser = _Parser(
        prog=PROG,
        description="Visualise and tune the simulated Livox lidars of RflySim: the rosette (TypeID 6 in SDK v2, 22 in "
                    "v3) and the Mid-360 (TypeID 23).",
        epilog="Run 'livox-viz COMMAND --help' for a command's options.",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for command in commands:
        child = sub.add_parser(
            command.name, help=command.help, description=f"{command.help}\n\nexample:\n  {command.example}",
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        command.arguments(child)
        # Which of the namespace's names are positional arguments, for messages (argparse keeps no public list).
        child.set_defaults(handler=command.handler,
                           positionals=tuple(action.dest for action in child._actions if not action.option_strings))
    return parser


def _version() -> str:
    from .. import __version__

    return __version__


def _refuse_empty_values(args: argparse.Namespace) -> None:
    """An option given an empty text was taken for one left out (``--trajectory ""`` scanned standing still,
    ``compare --plot ""`` drew nothing, ``--config ""`` read the default preset): refuse it instead."""
    for name, value in vars(args).items():
        if isinstance(value, str) and not value.strip() and name != "command":
            if name in args.positionals:
                raise UsageError(f"{name.upper()} {value!r}: empty; allowed: a value")
            raise UsageError(f"--{name.replace('_', '-')} {value!r}: empty; allowed: a value, or leave the option "
                             "out for its default")


def run(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run the command it names; returns the exit status (see :func:`livox_viz.cli.main`,
    which has taken the stop signals already).

    With no command (or only options), the installed default command runs
    (the GUI's window, when the GUI package is installed).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    commands = [*MODEL_COMMANDS, *installed_commands()]
    parser = build_parser(commands)
    default = next((c.name for c in commands if c.default), None)
    names = {c.name for c in commands}
    if default and not any(a in names or a in ("-h", "--help", "--version") for a in argv):
        argv = [default, *argv]
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help, --version, or a usage error (status 2)
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        _refuse_empty_values(args)
        status = int(args.handler(args) or 0)
        swallowed = take_raised()
        if swallowed is not None and status == 0:
            # Raised during the start-up and swallowed by a library on its way: the command ran to its end.
            print(f"{PROG}: {signal_name(swallowed)} arrived while starting and was lost in a library's import; "
                  "the command had finished", file=sys.stderr)
            return signal_status(swallowed)
        return status
    except LivoxVizError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader of our output went away (``livox-viz info | head -3``): stop quietly, as a pipe's writer does.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing left to flush at exit
        return 128 + int(getattr(signal, "SIGPIPE", 13))  # Windows has no SIGPIPE: the shell's number all the same
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{PROG}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        remove_unfinished()  # what a signal between a temporary's creation and its writer's knowing of it left
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        remove_unfinished()
        print(f"{PROG}: stopped by {exc}; unfinished files were removed", file=sys.stderr)
        return signal_status(exc.signum)


