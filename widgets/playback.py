"""The playback clock and the small choices a user cycles through with keys."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from livox_viz import LivoxVizError

SPEED_RANGE = (0.01, 10.0)
T = TypeVar("T")


def next_choice(choices: Sequence[T], current: T, step: int = 1) -> T:
    """The choice ``step`` places after ``current``, wrapping around."""
    return choices[(list(choices).index(current) + step) % len(choices)]


@dataclass
class Playback:
    """Scan time advances ``speed`` times as fast as wall time unless paused.

    Parameters
    ----------
    speed : float
        Scan seconds per wall second, in :data:`SPEED_RANGE`.
    paused : bool
    """

    speed: float = 1.0
    paused: bool = False
    _last_wall: float | None = field(default=None, repr=False)

    def set_speed(self, speed: float) -> float:
        """Set the speed, clipped into :data:`SPEED_RANGE`; returns the speed set."""
        if not math.isfinite(speed):
            raise LivoxVizError(f"speed {speed!r}; allowed: {SPEED_RANGE[0]} to {SPEED_RANGE[1]}")
        self.speed = float(min(max(speed, SPEED_RANGE[0]), SPEED_RANGE[1]))
        return self.speed

    def restart(self) -> None:
        """Forget the last tick's wall time, so a restart does not jump ahead."""
        self._last_wall = None

    def elapsed(self, now: float | None = None) -> float:
        """Scan seconds to add since the last call (0 when paused)."""
        now = time.monotonic() if now is None else now
        last, self._last_wall = self._last_wall, now
        if last is None or self.paused:
            return 0.0
        return max(0.0, now - last) * self.speed
