"""The one exception family the model raises for bad user input, and how its messages quote what they were given.

An error line quotes the user's value so they can find it, but a value can be
anything a 64 MiB JSON file or a 128 KiB argument holds: :func:`quoted` shows at
most :data:`QUOTE_CHARS` characters of it and says how long it was, and a
:class:`LivoxVizError` whose message still runs past :data:`MAX_MESSAGE_CHARS`
(a value some message did not quote through it) is shortened in its middle, so
no error line is ever longer than a few hundred characters.
"""

from __future__ import annotations

import errno
import os
import reprlib
import stat
from typing import Any

#: Characters of a value an error line quotes at most.
QUOTE_CHARS = 80
#: Characters of an error message at most (its start and its end are kept: the end says what is allowed).
MAX_MESSAGE_CHARS = 600


class _ShortRepr(reprlib.Repr):
    """``repr`` that stops early: a few items of a list, a few levels deep, whatever the value's size."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel = 3
        self.maxtuple = self.maxlist = self.maxset = self.maxfrozenset = self.maxdeque = 6
        self.maxdict = 4
        self.maxstring = self.maxother = QUOTE_CHARS
        self.maxlong = 40


_SHORT_REPR = _ShortRepr()


def quoted(value: Any, limit: int = QUOTE_CHARS) -> str:
    """``repr(value)`` for an error line: at most about ``limit`` characters, and how long the value was when cut.

    Parameters
    ----------
    value : object
        What the user gave (a JSON value, an argument's text).
    limit : int
        Characters of it to show at most.

    Examples
    --------
    >>> quoted("asphalt")
    "'asphalt'"
    >>> quoted("x" * 100_000)[-30:]
    "xxx'... (100,000 characters)"
    """
    if isinstance(value, str):
        if len(value) <= limit:
            return repr(value)
        return f"{value[:limit]!r}... ({len(value):,} characters)"
    text = _SHORT_REPR.repr(value)
    size = len(value) if isinstance(value, (list, tuple, dict, set, frozenset)) else None
    cut = len(text) > limit
    if cut:
        text = text[:limit] + "..."
    shown = _SHORT_REPR.maxdict if isinstance(value, dict) else _SHORT_REPR.maxlist
    if size is not None and (cut or size > shown):
        text += f" ({size:,} {'keys' if isinstance(value, dict) else 'items'})"
    return text


def bounded_message(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``message`` on one line of at most about ``limit`` characters: a longer one loses its middle, and says so."""
    message = " ".join(str(message).splitlines())
    if len(message) <= limit:
        return message
    head, tail = (2 * limit) // 3, limit // 3
    return f"{message[:head]} [... {len(message) - head - tail:,} characters left out ...] {message[-tail:]}"


class LivoxVizError(ValueError):
    """Bad input from a user: a file, a value or a name that is not allowed.

    The message is one line that names what is wrong and what is allowed; the
    CLI prints it and exits with status 2, the GUI shows it in its heads-up text.
    Messages quote values through :func:`quoted`; any message is kept to one line
    of at most about :data:`MAX_MESSAGE_CHARS` characters (:func:`bounded_message`).
    """

    def __init__(self, message: object = "", *args: object) -> None:
        super().__init__(bounded_message(str(message)), *args)


class ConfigError(LivoxVizError):
    """A sensor configuration that fails validation."""


def require_file(path, what: str = "file") -> None:
    """Raise a :class:`LivoxVizError` unless ``path`` is a readable, non-empty file, saying which it is not.

    Parameters
    ----------
    path : pathlib.Path
    what : str
        What was expected, e.g. ``"mesh file"``.
    """
    if path.is_dir():
        raise LivoxVizError(f"{path}: is a folder; allowed: a {what}")
    if not path.exists():
        raise LivoxVizError(f"{path}: no such {what}")
    if not path.is_file():
        raise LivoxVizError(f"{path}: is not a regular file; allowed: a {what}")
    if path.stat().st_size == 0:
        raise LivoxVizError(f"{path}: is empty; allowed: a {what}")


def not_a_file(path: str | os.PathLike[str]) -> str | None:
    """What ``path`` is when it is there but is no regular file (nor a link to one), in words; None otherwise.

    Asks ``stat`` only: it never opens the path (a named pipe would block until a writer came).

    Examples
    --------
    >>> not_a_file("/dev/zero")
    'a device'
    """
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a loop of symbolic links"
        if os.path.islink(path):
            return "a symbolic link to nothing (dangling)"
        return None if exc.errno == errno.ENOENT else f"unreadable ({exc.strerror})"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket" if stat.S_ISSOCK(mode) else "not a regular file"


def os_error_reason(exc: OSError) -> str:
    """An OSError in words; numpy's short writes ("100000 requested and 59904 written") carry no errno."""
    return exc.strerror or f"{exc}: is the disk full?"
