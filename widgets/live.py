"""The live view's own figures (``gui --listen``): what arrives, from whom, how fast, and when it stopped.

Qt-free: the session counts each poll's frames, the heads-up text and the status bar say :meth:`LiveStats.line`.
RViz shows a topic's rate and says "no messages received" when a stream stops; the window showed neither, and a
sender that stopped looked like a scan that holds still.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

#: Seconds of arrivals the rates are counted over.
RATE_WINDOW_S = 2.0
#: A stream is said to have stopped after this many of its frame intervals with nothing (and at least a second).
STOPPED_AFTER_FRAMES = 3


class LiveStats:
    """Arrivals of a live stream.

    Parameters
    ----------
    where : str
        Where the window listens, in words (``"udp 0.0.0.0:9999"``).
    """

    def __init__(self, where: str) -> None:
        self.where = where
        self.frames = 0
        self.points = 0
        #: Frames that arrived while paused: read and set aside, so that play resumes with the stream as it is
        #: now (left in the socket they overflowed its buffer, then came as a burst of old frames).
        self.paused_frames = 0
        self.sender = ""
        self.last_arrival: float | None = None
        self.first_arrival: float | None = None
        self._arrivals: deque[tuple[float, int, int]] = deque()  # (time, frames, points) of each poll

    def heard(self, frames: Sequence, now: float, drawn: bool = True) -> None:
        """Count one poll's frames (each with ``source`` and ``xyz_int16``), arrived at ``now`` (monotonic s)."""
        if not frames:
            return
        self.last_arrival = now
        if self.first_arrival is None:
            self.first_arrival = now
        count = sum(frame.xyz_int16.shape[0] for frame in frames)
        self._arrivals.append((now, len(frames), count))
        self.frames += len(frames)
        self.points += count
        if not drawn:
            self.paused_frames += len(frames)
        self.sender = frames[-1].source or self.sender
        self._forget_before(now - RATE_WINDOW_S)

    def _forget_before(self, oldest: float) -> None:
        while self._arrivals and self._arrivals[0][0] < oldest:
            self._arrivals.popleft()

    def rates(self, now: float) -> tuple[float, float]:
        """Frames and points a second over the last :data:`RATE_WINDOW_S` seconds (over the time since the first
        frame, but at least half a second, while the stream is younger)."""
        self._forget_before(now - RATE_WINDOW_S)
        if self.first_arrival is None:
            return 0.0, 0.0
        span = min(RATE_WINDOW_S, max(now - self.first_arrival, 0.5))
        frames = sum(count for _, count, _ in self._arrivals)
        points = sum(count for _, _, count in self._arrivals)
        return frames / span, points / span

    def stopped_for(self, now: float, frame_rate_hz: float) -> float | None:
        """Seconds since the last frame when that is longer than the stream's own pause (None while it flows)."""
        if self.last_arrival is None:
            return None
        quiet = now - self.last_arrival
        return quiet if quiet > max(1.0, STOPPED_AFTER_FRAMES / frame_rate_hz) else None

    def line(self, now: float, frame_rate_hz: float, lost: int = 0) -> str:
        """The live line: ``live: udp 0.0.0.0:9999 <- 127.0.0.1:5000, 10.0 frames/s, 100,000 pts/s``.

        Parameters
        ----------
        now : float
            Monotonic seconds.
        frame_rate_hz : float
            The frames a second the configuration expects (DataCheckFreq): when a stream counts as stopped.
        lost : int
            Frames the receiver counted lost (frame ids skipped).
        """
        if self.last_arrival is None:
            return f"live: {self.where}: waiting for the first frame"
        sender = f" <- {self.sender}" if self.sender else ""
        stopped = self.stopped_for(now, frame_rate_hz)
        if stopped is not None:
            return f"live: {self.where}{sender}: no frame for {stopped:.0f} s ({self.frames:,} frames received)"
        frames, points = self.rates(now)
        extra = f", {lost:,} lost" if lost else ""
        return f"live: {self.where}{sender}, {frames:.1f} frames/s, {points:,.0f} pts/s{extra}"
