"""The one exception family the model raises for bad user input."""

from __future__ import annotations


class LivoxVizError(ValueError):
    """Bad input from a user: a file, a value or a name that is not allowed.

    The message is one line that names what is wrong and what is allowed; the
    CLI prints it and exits with status 2, the GUI shows it in its heads-up text.
    """


class ConfigError(LivoxVizError):
    """A sensor configuration that fails validation."""
