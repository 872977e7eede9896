"""The ``livox-viz`` command line: one table of commands, grouped by area.

The model's commands live in this package. Other installed packages add
theirs through the ``livox_viz.commands`` entry-point group: each entry point
names a sequence of :class:`~livox_viz.cli.common.Command` rows (the model
never names those packages). Every command exits 0 on success and 2 with a
one-line ``livox-viz: error:`` message on bad input.

This module imports nothing heavy: :func:`main` takes Ctrl-C, SIGTERM and SIGHUP
first and only then loads the commands (:mod:`~livox_viz.cli.program`: numpy and
the model), so a signal while they load ends the program quietly with 130 (143,
129) instead of a traceback. The table's names are loaded on first use.
"""

from __future__ import annotations

import importlib
import signal
import sys
from collections.abc import Sequence
from typing import Any

from .signals import Terminated, raise_stop, signal_name, signal_status, take_raised, take_signals

PROG = "livox-viz"  # common.PROG, not imported from there: common loads the model
#: Names of this package loaded on first use, and the module that holds each.
_LAZY = {"ENTRY_POINT_GROUP": "program", "MODEL_COMMANDS": "program", "build_parser": "program",
         "installed_commands": "program", "Command": "common", "UsageError": "common"}

__all__ = ["ENTRY_POINT_GROUP", "MODEL_COMMANDS", "Command", "Terminated", "UsageError", "build_parser", "main"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    With no command (or only options), the installed default command runs
    (the GUI's window, when the GUI package is installed). Ctrl-C, SIGTERM and
    SIGHUP unwind the command (a command that must keep what it has takes them
    itself for a while, :class:`~livox_viz.cli.signals.StopRequests`); they are
    taken before the commands are even loaded.
    """
    take_raised()  # a signal an earlier run in this process noted is not this run's
    previous = take_signals(raise_stop)
    try:
        from .program import run

        return run(argv)
    except KeyboardInterrupt:
        # Ctrl-C while the program loaded or parsed its arguments (the command's own handling is in run()).
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"{PROG}: stopped by {signal_name(exc.signum)}", file=sys.stderr)
        return signal_status(exc.signum)
    finally:
        take_raised()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
