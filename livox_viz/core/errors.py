"""The one exception family the model raises for bad user input."""

from __future__ import annotations


class LivoxVizError(ValueError):
    """Bad input from a user: a file, a value or a name that is not allowed.

    The message is one line that names what is wrong and what is allowed; the
    CLI prints it and exits with status 2, the GUI shows it in its heads-up text.
    """


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


def os_error_reason(exc: OSError) -> str:
    """An OSError in words; numpy's short writes ("100000 requested and 59904 written") carry no errno."""
    return exc.strerror or f"{exc}: is the disk full?"
