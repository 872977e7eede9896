"""The reference overlay: a measured table, a real sensor's recording or another preset's pattern, played in step
with the scan.

It has its own point ring and integration window, so a user can hold the
real sensor's 1 s picture beside their own 0.1 s one. Each row is drawn at its
own firing (a recording's no-returns are gaps); a table loops, a recording
(a saved frame, an LVX, a bag) holds its own span only: past its end the
overlay keeps its last window.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livox_viz import LivoxVizError, SensorConfig
from livox_viz.fitting.reference import ReferencePattern
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.metrics import coverage
from livox_viz.patterns.stream import points_before

from .ring import PointRing

#: Integration windows a user can pick, seconds (None = unlimited, up to :data:`UNLIMITED_POINTS`).
WINDOWS: tuple[float | None, ...] = (0.1, 0.5, 1.0, 2.0, None)
#: Points the unlimited window holds at most.
UNLIMITED_POINTS = 1_000_000


def window_label(window: float | None) -> str:
    """``"0.5 s"`` or ``"unlimited"``."""
    return "unlimited" if window is None else f"{window:g} s"


def window_capacity(window: float | None, rate: float) -> int:
    """Points a ring needs for ``window`` seconds at ``rate`` points/s."""
    return UNLIMITED_POINTS if window is None else max(1, points_before(window, rate))


class TableSource:
    """A measured table, looped, or a recording, played once.

    Parameters
    ----------
    table : ReferencePattern
    """

    def __init__(self, table: ReferencePattern) -> None:
        self.table = table
        self.name = table.name
        self.rate = table.rate
        self.fov = table.field_of_view
        self.plane = table.plane
        #: Firings a loop of the table spans (its first row fires at 0, its last before this).
        self.period = int(table.slots[-1]) + 1
        #: Seconds a recording lasts (it is not looped: a real sensor's pattern does not repeat), or None.
        self.end: float | None = self.period / table.rate if table.recording else None

    def samples(self, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """The rows fired in firings ``first .. stop-1``: ``(m, 2)`` float64 degrees and their ``(m,)`` int64
        firings (every firing of a table without gaps; a recording's none past its end)."""
        xy, slots = self.table.xy_deg, self.table.slots
        if self.end is None and self.table.consecutive:
            index = np.arange(first, stop)
            return xy[index % xy.shape[0]], index
        # Each loop of the table the firings reach (one for a recording): its rows in the firings asked for.
        loops = [0] if self.end is not None else range(first // self.period, (stop - 1) // self.period + 1)
        rows, firings = [], []
        for loop in loops:
            base = loop * self.period
            a, b = np.searchsorted(slots, [first - base, stop - base])
            rows.append(xy[a:b])
            firings.append(slots[a:b] + base)
        return np.concatenate(rows), np.concatenate(firings)


class PresetSource:
    """Another configuration's pattern stream (e.g. the ``livox_mid70_risley`` preset).

    Parameters
    ----------
    config : SensorConfig
    name : str
    seed : int
    """

    def __init__(self, config: SensorConfig, name: str, seed: int = 0) -> None:
        self.config = config
        self.name = name
        self.rate = float(config.point_rate)
        self.fov = config.field_of_view
        self.plane = config.pattern_plane
        self.seed = seed
        self._stream = make_pattern(config, seed)

    #: A preset's pattern plays for ever.
    end: float | None = None

    def samples(self, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """``(stop-first, 2)`` float64 degrees of samples ``first .. stop-1``, and their ``(stop-first,)``
        firings."""
        if first < self._stream.position:
            self._stream = make_pattern(self.config, self.seed)
        self._stream.skip(first - self._stream.position)
        return self._stream.take(stop - first).xy_deg, np.arange(first, stop)


@dataclass
class ReferenceOverlay:
    """What the overlay shows, and how.

    Parameters
    ----------
    source : TableSource or PresetSource, optional
    window_index : int
        Into :data:`WINDOWS`.
    visible : bool
    """

    source: TableSource | PresetSource | None = None
    window_index: int = 1
    visible: bool = True

    def __post_init__(self) -> None:
        self.ring = PointRing(1)
        self._position = 0
        #: Whether the scan has run past a recording's end (the overlay holds its last window).
        self.ended = False

    def _held(self, scan_time: float) -> float:
        """The time the overlay shows at ``scan_time``: a recording's end once the scan is past it."""
        end = self.source.end if self.source is not None else None
        return scan_time if end is None else min(scan_time, end)

    @property
    def window(self) -> float | None:
        """The overlay's integration window, seconds (None = unlimited)."""
        return WINDOWS[self.window_index]

    def set_source(self, source: TableSource | PresetSource | None, scan_time: float) -> None:
        """Show ``source`` (None: no overlay), filled up to ``scan_time``."""
        self.source = source
        self.refill(scan_time)

    def set_window(self, index: int, scan_time: float) -> None:
        """Pick :data:`WINDOWS` ``[index]``."""
        if not 0 <= index < len(WINDOWS):
            raise LivoxVizError(f"window index {index}; allowed: 0 to {len(WINDOWS) - 1}")
        self.window_index = index
        self.refill(scan_time)

    def refill(self, scan_time: float) -> None:
        """Empty the ring and fill it with the window that ends at ``scan_time``."""
        self.ended = False
        if self.source is None:
            self.ring = PointRing(1)
            self._position = 0
            return
        window = self.window
        self.ring = PointRing(window_capacity(window, self.source.rate))
        start = 0.0 if window is None else max(0.0, self._held(scan_time) - window)
        self._position = points_before(start, self.source.rate)
        self.advance_to(scan_time)

    def advance_to(self, scan_time: float) -> bool:
        """Add the samples emitted before ``scan_time`` and drop those older than the window (a recording's: up to
        its end, then held). Whether the scan has just run past a recording's end."""
        source = self.source
        if source is None:
            return False
        shown = self._held(scan_time)
        just_ended = shown < scan_time and not self.ended
        self.ended = shown < scan_time
        target = points_before(shown, source.rate)
        count = min(target - self._position, self.ring.capacity)
        if count <= 0:
            return just_ended
        xy, index = source.samples(target - count, target)
        xyz = np.zeros((index.size, 3), dtype=np.float32)
        xyz[:, :2] = xy
        self.ring.write(xyz, np.zeros(index.size, dtype=np.float32), index / source.rate, index)
        self._position = target
        if self.window is not None:
            self.ring.drop_older_than(shown - self.window)
        return just_ended

    def coverage(self) -> float | None:
        """FOV coverage of the overlay's points in its own FOV, or None without a source."""
        if self.source is None or self.ring.count == 0:
            return None
        live = self.ring.positions[self.ring.live_slots(), :2].astype(np.float64)
        return coverage(live, self.source.fov)
