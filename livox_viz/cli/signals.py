"""How ``livox-viz`` stops on Ctrl-C, SIGTERM and SIGHUP (SIGBREAK on Windows).

By default a command unwinds on any of them (SIGTERM and SIGHUP raise
:class:`Terminated`, Ctrl-C raises :class:`KeyboardInterrupt`), so every writer
removes its temporary files and the destination is left as it was. A command
whose partial result is the user's data (a scan's files, a recording, a live
publisher, the window) asks instead to be *told*: inside :class:`StopRequests` a signal is
only noted, the command finishes its current step, closes its files properly
and returns :func:`signal_status`.

Windows has no SIGHUP: a closed console window sends SIGBREAK (Ctrl-Break too), which is
taken the same way there. Every signal is named only where the platform has it.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from types import FrameType, TracebackType


def _stop_signals() -> tuple[signal.Signals, ...]:
    """Ctrl-C, SIGTERM and the hang-up the platform has: SIGHUP (POSIX), SIGBREAK (Windows: a closed console or
    Ctrl-Break). Looked up by name: naming a signal the platform lacks fails at import (Windows has no SIGHUP)."""
    hang_ups = (getattr(signal, name, None) for name in ("SIGHUP", "SIGBREAK"))
    return (signal.SIGINT, signal.SIGTERM, *(sig for sig in hang_ups if sig is not None))


#: The signals a command stops on.
STOP_SIGNALS: tuple[signal.Signals, ...] = _stop_signals()
#: The signals :func:`raise_stop` raised, until :func:`take_raised`: one a library swallowed on its way (trimesh
#: imports its optional dependencies under ``except BaseException``) still stops the command, at its next
#: :class:`StopRequests` or when it returns.
_RAISED: list[int] = []


class Terminated(BaseException):
    """SIGTERM or SIGHUP (SIGBREAK on Windows) arrived: unwind like Ctrl-C, so writers remove their temporary files.

    A :class:`BaseException`, as :class:`KeyboardInterrupt` is, so no ``except Exception`` swallows it.

    Parameters
    ----------
    signum : int
        The signal's number.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def signal_status(signum: int) -> int:
    """The shell's exit status for a process stopped by ``signum``: 128 + its number (SIGTERM 143)."""
    return 128 + int(signum)


def signal_name(signum: int) -> str:
    """``SIGTERM``; SIGINT is called Ctrl-C, as the user pressed it."""
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


def raise_stop(signum: int, _frame: FrameType | None) -> None:
    """The command line's handler outside :class:`StopRequests`: the signal is noted (:func:`take_raised`), then
    raised, :class:`KeyboardInterrupt` for Ctrl-C and :class:`Terminated` for the others."""
    _RAISED.append(int(signum))
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def take_raised() -> int | None:
    """The first signal :func:`raise_stop` raised since the last call (None if none), forgetting them all."""
    first = _RAISED[0] if _RAISED else None
    _RAISED.clear()
    return first


def in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def take_signals(handler: Callable[[int, FrameType | None], None],
                 signals: tuple[signal.Signals, ...] = STOP_SIGNALS) -> dict[int, object]:
    """Install ``handler`` for each of ``signals`` not ignored; returns the handlers it replaced.

    A signal the process was started ignoring stays ignored: ``nohup livox-viz listen ...`` must outlive
    the terminal's hang-up, and a background job of a non-interactive shell ignores Ctrl-C. Only the main
    thread can take signals: elsewhere nothing is installed.
    """
    if not in_main_thread():
        return {}
    return {sig: signal.signal(sig, handler) for sig in signals if signal.getsignal(sig) is not signal.SIG_IGN}


class StopRequests:
    """Inside this context Ctrl-C, SIGTERM and SIGHUP are noted instead of raised.

    Only the main thread can take signals; elsewhere (a test running a command
    in a thread) the context does nothing and :attr:`signum` stays None. A
    signal the process ignores (``nohup``) stays ignored.

    Parameters
    ----------
    on_request : callable, optional
        Called with the signal number when the first one arrives (from the main
        thread, between two Python steps: it must not block).

    Attributes
    ----------
    signum : int or None
        The first signal that arrived.
    """

    def __init__(self, on_request: Callable[[int], None] | None = None) -> None:
        self.on_request = on_request
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    @property
    def requested(self) -> bool:
        """Whether a signal asked to stop."""
        return self.signum is not None

    def _note(self, signum: int, _frame: FrameType | None) -> None:
        if self.signum is None:
            self.signum = signum
            if self.on_request is not None:
                self.on_request(signum)

    def __enter__(self) -> StopRequests:
        self._previous = take_signals(self._note)
        if self._previous:
            earlier = take_raised()  # raised before and swallowed on its way: it asked to stop all the same
            if earlier is not None:
                self._note(earlier, None)
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 tb: TracebackType | None) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
        self._previous = {}
