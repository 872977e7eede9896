"""A quiet progress line on stderr for work that takes more than a second."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """Prints ``label: 42 % (done/total unit)`` on one line, at most 5 times a second.

    Nothing is printed during the first second, so quick commands stay silent,
    and only to a terminal; :meth:`close` ends the line.

    Parameters
    ----------
    label : str
        What is being done.
    total : float
        The amount of work, in ``unit``.
    unit : str
        E.g. ``"s"`` of scan time or ``"frames"``.
    stream : TextIO, optional
        Default ``sys.stderr``.
    """

    def __init__(self, label: str, total: float, unit: str = "", stream: TextIO | None = None) -> None:
        self.label = label
        self.total = total
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self._start = time.monotonic()
        self._last = 0.0
        self._shown = False

    def update(self, done: float) -> None:
        """Report that ``done`` of ``total`` is finished."""
        now = time.monotonic()
        if now - self._start < 1.0 or now - self._last < 0.2:
            return
        if not getattr(self.stream, "isatty", lambda: False)():
            return
        self._last = now
        self._shown = True
        share = 100.0 * done / self.total if self.total else 100.0
        self.stream.write(f"\r{self.label}: {share:5.1f} % ({done:g}/{self.total:g} {self.unit})")
        self.stream.flush()

    def close(self) -> None:
        """End the progress line, if one was shown."""
        if self._shown:
            self.stream.write("\n")
            self.stream.flush()
