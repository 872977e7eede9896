"""The reference overlay: a measured table or another preset's pattern, played in step with the scan.

It has its own point ring and integration window, so a user can hold the
real sensor's 1 s picture beside their own 0.1 s one.
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
    """A measured table, looped.

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

    def xy(self, first: int, stop: int) -> np.ndarray:
        """``(stop-first, 2)`` float64 degrees of samples ``first .. stop-1``."""
        return self.table.xy_deg[np.arange(first, stop) % self.table.xy_deg.shape[0]]


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

    def xy(self, first: int, stop: int) -> np.ndarray:
        """``(stop-first, 2)`` float64 degrees of samples ``first .. stop-1``."""
        if first < self._stream.position:
            self._stream = make_pattern(self.config, self.seed)
        self._stream.skip(first - self._stream.position)
        return self._stream.take(stop - first).xy_deg


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
        if self.source is None:
            self.ring = PointRing(1)
            self._position = 0
            return
        window = self.window
        self.ring = PointRing(window_capacity(window, self.source.rate))
        start = 0.0 if window is None else max(0.0, scan_time - window)
        self._position = points_before(start, self.source.rate)
        self.advance_to(scan_time)

    def advance_to(self, scan_time: float) -> None:
        """Add the samples emitted before ``scan_time`` and drop those older than the window."""
        source = self.source
        if source is None:
            return
        target = points_before(scan_time, source.rate)
        count = min(target - self._position, self.ring.capacity)
        if count <= 0:
            return
        first = target - count
        xyz = np.zeros((count, 3), dtype=np.float32)
        xyz[:, :2] = source.xy(first, target)
        index = np.arange(first, target)
        self.ring.write(xyz, np.zeros(count, dtype=np.float32), index / source.rate, index)
        self._position = target
        if self.window is not None:
            self.ring.drop_older_than(scan_time - self.window)

    def coverage(self) -> float | None:
        """FOV coverage of the overlay's points in its own FOV, or None without a source."""
        if self.source is None or self.ring.count == 0:
            return None
        live = self.ring.positions[self.ring.live_slots(), :2].astype(np.float64)
        return coverage(live, self.source.fov)
