"""A fixed-capacity ring of points: what the views draw, updated in place.

Pure numpy (no VTK), so its bookkeeping is tested without a window. A view
wraps the ring's arrays once as VTK arrays (zero copy) and, after each write,
only marks them modified and points its vertex cells at the live slots
``tail .. tail+count`` through :meth:`PointRing.live_slots`, a slice of a
doubled index array, so a tick costs the new points, not all points on
screen.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np


class PointRing:
    """A circular queue of the newest points, oldest at the tail.

    Parameters
    ----------
    capacity : int
        Points held at most; writing into a full ring overwrites the oldest.
    sensor_frame : bool
        Also keep each point as the sensor measured it (:attr:`sensor_xyz`, :attr:`range_m`,
        :attr:`return_number`): what a click on a point shows (the scene's cloud).
    """

    def __init__(self, capacity: int, sensor_frame: bool = False) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = int(capacity)
        self.positions = np.zeros((self.capacity, 3), dtype=np.float32)
        self.scalars = np.zeros(self.capacity, dtype=np.float32)
        self.times = np.zeros(self.capacity, dtype=np.float64)
        self.stream_index = np.zeros(self.capacity, dtype=np.int64)
        #: Per point: the Livox reflectivity byte and tag (scene cloud; zeros for pattern points).
        self.reflectivity = np.zeros(self.capacity, dtype=np.uint8)
        self.tag = np.zeros(self.capacity, dtype=np.uint8)
        #: Per point, when kept (``sensor_frame``): the decoded point in the sensor's FRD frame (metres), its range
        #: (metres) and its return number (1-3; 0 unknown). Empty arrays otherwise.
        kept = self.capacity if sensor_frame else 0
        self.sensor_xyz = np.zeros((kept, 3), dtype=np.float32)
        self.range_m = np.zeros(kept, dtype=np.float32)
        self.return_number = np.zeros(kept, dtype=np.uint8)
        # Slot numbers twice over (any run of live slots is one contiguous slice) and cell offsets: read-only
        # tables shared by every ring of this capacity (making them was most of a preset change's 200 ms).
        self._doubled, self._offsets = _slot_tables(self.capacity)
        self.count = 0
        self.head = 0
        #: Called with the ``(k, 3)`` positions of points about to leave the ring (overwritten or dropped).
        self.on_evict: Callable[[np.ndarray], None] | None = None

    @property
    def tail(self) -> int:
        """Slot of the oldest live point."""
        return (self.head - self.count) % self.capacity

    def clear(self, first_index: int = 0) -> None:
        """Forget every point (the arrays keep their memory).

        ``first_index``: the stream index of the next point written. It goes to slot ``first_index mod capacity``,
        so a ring filled from any point of a stream lays its points out as one filled from the stream's start:
        drawn in the same order, the same points overlap the same way (a picture made again from a screenshot's
        sidecar is the screenshot's).
        """
        self.count = 0
        self.head = int(first_index) % self.capacity

    def write(self, positions: np.ndarray, scalars: np.ndarray, times: np.ndarray, stream_index: np.ndarray,
              reflectivity: np.ndarray | None = None, tag: np.ndarray | None = None,
              sensor_xyz: np.ndarray | None = None, range_m: np.ndarray | None = None,
              return_number: np.ndarray | None = None) -> None:
        """Append points in time order, dropping the oldest when full.

        Parameters
        ----------
        positions : (n, 3) float
        scalars : (n,) float
        times : (n,) float64
            Emission times, seconds, non-decreasing.
        stream_index : (n,) int64
            Point numbers in the pattern stream.
        reflectivity, tag : (n,) uint8, optional
            The points' Livox reflectivity and tag (default 0).
        sensor_xyz : (n, 3) float, optional
            Each point in the sensor's frame, metres (kept by a ``sensor_frame`` ring; default 0).
        range_m : (n,) float, optional
            Each point's range, metres (default: the length of ``sensor_xyz``).
        return_number : (n,) uint8, optional
            1-3 (default 0: unknown).
        """
        n = positions.shape[0]
        if n == 0:
            return
        reflectivity = np.zeros(n, np.uint8) if reflectivity is None else reflectivity
        tag = np.zeros(n, np.uint8) if tag is None else tag
        columns = [positions, scalars, times, stream_index, reflectivity, tag]
        targets = [self.positions, self.scalars, self.times, self.stream_index, self.reflectivity, self.tag]
        if self.sensor_xyz.shape[0]:
            local = np.zeros((n, 3), np.float32) if sensor_xyz is None else sensor_xyz
            ranges = np.linalg.norm(local, axis=1) if range_m is None else range_m
            columns += [local, ranges, np.zeros(n, np.uint8) if return_number is None else return_number]
            targets += [self.sensor_xyz, self.range_m, self.return_number]
        skipped = 0
        if n > self.capacity:
            # Only the newest fit; they go where writing all of them would have put them, so a point's slot does
            # not depend on how the stream was cut into writes.
            columns = [column[-self.capacity :] for column in columns]
            skipped, n = n - self.capacity, self.capacity
        evicted = self.count + n - self.capacity
        if evicted > 0 and self.on_evict is not None:
            self.on_evict(self.positions[self._doubled[self.tail : self.tail + evicted]])
        self.head = (self.head + skipped) % self.capacity
        first = min(n, self.capacity - self.head)
        for source, target in ((slice(0, first), slice(self.head, self.head + first)),
                               (slice(first, n), slice(0, n - first))):
            for column, array in zip(columns, targets, strict=True):
                array[target] = column[source]
        self.head = (self.head + n) % self.capacity
        self.count = min(self.capacity, self.count + n)

    def drop_older_than(self, time_limit: float) -> int:
        """Forget points emitted before ``time_limit`` seconds; returns how many remain."""
        if self.count == 0:
            return 0
        tail = self.tail
        end = tail + self.count
        if end <= self.capacity:
            old = int(np.searchsorted(self.times[tail:end], time_limit, side="left"))
        else:
            old = int(np.searchsorted(self.times[tail:], time_limit, side="left"))
            if old == self.capacity - tail:
                old += int(np.searchsorted(self.times[: end - self.capacity], time_limit, side="left"))
        if old and self.on_evict is not None:
            self.on_evict(self.positions[self._doubled[tail : tail + old]])
        self.count -= old
        return self.count

    def live_slots(self) -> np.ndarray:
        """``(count,)`` int64 slot numbers of the live points, oldest first (a view, no copy)."""
        return self._doubled[self.tail : self.tail + self.count]

    def live_pieces(self) -> list[slice]:
        """The live slots as at most two slices of the arrays, oldest first (no index array, no gather)."""
        if self.count == 0:
            return []
        tail = self.tail
        end = tail + self.count
        if end <= self.capacity:
            return [slice(tail, end)]
        return [slice(tail, self.capacity), slice(0, end - self.capacity)]

    def all_slots(self) -> np.ndarray:
        """``(capacity,)`` int64 every slot in storage order (a view, no copy): a full ring's cells."""
        return self._doubled[: self.capacity]

    def cell_offsets(self) -> np.ndarray:
        """``(count + 1,)`` int64 offsets of one vertex cell per live point (a view, no copy)."""
        return self._offsets[: self.count + 1]

    def ordered(self, array: np.ndarray) -> np.ndarray:
        """The live part of one of the ring's arrays, oldest first (a copy)."""
        return array[self.live_slots()]


@functools.lru_cache(maxsize=4)
def _slot_tables(capacity: int) -> tuple[np.ndarray, np.ndarray]:
    """``(2 capacity,)`` int64 slot numbers twice over and ``(capacity + 1,)`` int64 0..capacity, read-only."""
    doubled = np.empty(2 * capacity, dtype=np.int64)
    doubled[:capacity] = np.arange(capacity)
    doubled[capacity:] = doubled[:capacity]
    offsets = np.arange(capacity + 1, dtype=np.int64)
    doubled.setflags(write=False)
    offsets.setflags(write=False)
    return doubled, offsets


class CellCounts:
    """Points per cell of some grid, kept in step with a ring (add what it gains, remove what it evicts).

    Subclasses say which cell a point falls in; the cost of a change is the
    points changed plus one pass over the cells, never all the points held.

    Parameters
    ----------
    size : int
        Number of cells.
    """

    def __init__(self, size: int) -> None:
        self.flat = np.zeros(size, dtype=np.float64)

    def cells(self, positions: np.ndarray) -> np.ndarray:
        """``(n,)`` int64 cell of each point, -1 for none."""
        raise NotImplementedError

    def clear(self) -> None:
        self.flat[:] = 0.0

    def _counted(self, positions: np.ndarray) -> np.ndarray:
        cells = self.cells(positions)
        return np.bincount(cells[cells >= 0], minlength=self.flat.size)

    def add(self, positions: np.ndarray) -> None:
        """Count points in, ``(n, 3)`` or ``(n, 2)`` degrees."""
        self.flat += self._counted(positions)

    def remove(self, positions: np.ndarray) -> None:
        """Count points out."""
        self.flat -= self._counted(positions)


class CoverageCounts(CellCounts):
    """Points per 5 mrad coverage cell of the FOV (see :class:`livox_viz.patterns.metrics.CoverageGrid`).

    Parameters
    ----------
    fov : FieldOfView or float
        The field of view (or a cone's half-angle, degrees).
    """

    def __init__(self, fov) -> None:
        from livox_viz.patterns.metrics import LIVOX_CELL_DEG, CoverageGrid

        self.grid = CoverageGrid(fov, LIVOX_CELL_DEG)
        super().__init__(self.grid.inside_mask.size)
        self._cell_count = self.grid.cell_count

    def cells(self, positions: np.ndarray) -> np.ndarray:
        return self.grid.cell_index(positions[:, :2].astype(np.float64))

    def coverage(self) -> float:
        """Fraction of the FOV's cells holding at least one point of the ring."""
        return float(np.count_nonzero(self.flat)) / self._cell_count


class DensityGrid(CellCounts):
    """Points per cell of a grid of square cells over the field of view's bounding box, for the density image.

    Parameters
    ----------
    bounds : tuple of 4 float, or float
        (x_min, x_max, y_min, y_max) degrees, or the half-width of a square around the boresight.
    cells : int
        Cells along the longer side.
    """

    def __init__(self, bounds: tuple[float, float, float, float] | float, cells: int = 512) -> None:
        if np.ndim(bounds) == 0:
            bounds = (-float(bounds), float(bounds), -float(bounds), float(bounds))
        self.bounds = tuple(float(v) for v in bounds)
        x0, x1, y0, y1 = self.bounds
        self.cell = max(x1 - x0, y1 - y0) / int(cells)
        self.nx = max(1, round((x1 - x0) / self.cell))
        self.ny = max(1, round((y1 - y0) / self.cell))
        super().__init__(self.nx * self.ny)
        #: ``(ny, nx)`` counts, [row = y, column = x]: a view of :attr:`flat`.
        self.counts = self.flat.reshape(self.ny, self.nx)
        #: ``(ny * nx,)`` float32 log(1 + count), what the view shows.
        self.display = np.zeros(self.nx * self.ny, dtype=np.float32)

    @property
    def side(self) -> int:
        """Cells along the longer side."""
        return max(self.nx, self.ny)

    @property
    def radius(self) -> float:
        """Half the longer side, degrees."""
        x0, x1, y0, y1 = self.bounds
        return max(x1 - x0, y1 - y0) / 2

    def cells(self, positions: np.ndarray) -> np.ndarray:
        x0, _, y0, _ = self.bounds
        scale = 1.0 / self.cell
        ix = np.clip(((positions[:, 0] - x0) * scale).astype(np.int64), 0, self.nx - 1)
        iy = np.clip(((positions[:, 1] - y0) * scale).astype(np.int64), 0, self.ny - 1)
        return iy * self.nx + ix

    def refresh_display(self) -> np.ndarray:
        """Update and return :attr:`display`, log(1 + count)."""
        np.log1p(self.flat, out=self.display, casting="same_kind")
        return self.display
