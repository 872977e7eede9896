"""A LAS 1.4 file's points packed as they come, its header written last over room kept for it.

LAS stores each coordinate as an int32 times a scale plus an offset, in a
header before the points. The offset is taken from the first points (whole
metres, their middle) and the scale is 0.1 mm, which holds any point within
214 km of it; every later frame is checked to fit. The point records are packed
here as laspy packs them (point format 6 and the extra bytes the header
declares), and :meth:`LasStream.header` makes the final header (counts, bounds,
points per return) once the points are written: the same size as the room
kept for it, so the file is finished in place, with no second copy of its
points. A frame that does not fit (a cloud wider than 428 km, which wants a
coarser scale than the first points gave) is the caller's to handle
(:meth:`LasStream.pack` returns None).
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: The largest coordinate integer the packer writes (a margin under int32 for rounding).
_INT_LIMIT = 2**31 - 2**20


@dataclass
class PackedFrame:
    """One frame's point records as bytes and what they add to the header."""

    data: bytes
    count: int
    low: np.ndarray
    high: np.ndarray
    by_return: np.ndarray


class LasStream:
    """Packs LAS point records frame by frame and makes the header that goes in front of them.

    Parameters
    ----------
    make_header : callable
        ``make_header(offset, scale)``: a ``laspy.LasHeader`` (point format 6, its VLRs and extra bytes) for
        that offset and scale, metres ``(3,)`` each.
    offset_and_scale : callable
        ``offset_and_scale(low, high)``: the offset and scale for points within ``low``..``high`` ``(3,)``.
    extra_names : sequence of str
        The extra-byte fields, in the header's order, after ``range``, ``frame``, ``reflectivity`` and ``tag``.
    """

    def __init__(self, make_header: Callable, offset_and_scale: Callable, extra_names: tuple[str, ...]) -> None:
        self._make_header = make_header
        self._offset_and_scale = offset_and_scale
        self._extra_names = ("range", "frame", "reflectivity", "tag", *extra_names)
        empty = make_header(np.zeros(3), np.ones(3))
        self.dtype = empty.point_format.dtype()
        #: Bytes of the header and its VLRs: the room kept for it at the start of the file.
        self.header_size = len(_header_bytes(empty))
        self.offset: np.ndarray | None = None
        self.scale: np.ndarray | None = None
        self.count = 0
        self._low = np.full(3, np.iinfo(np.int64).max)
        self._high = np.full(3, np.iinfo(np.int64).min)
        self._by_return = np.zeros(15, dtype=np.uint64)

    def pack(self, xyz: np.ndarray, columns: dict[str, np.ndarray | float]) -> PackedFrame | None:
        """The point records of ``xyz`` ``(n, 3)`` (the LAS frame, metres) and ``columns`` (``gps_time``,
        ``intensity``, ``return_number``, ``number_of_returns`` and the extra fields, per point or one for all), or
        None when a point does not fit the offset and scale of the first."""
        count = xyz.shape[0]
        if self.offset is None:
            if not count:
                return PackedFrame(b"", 0, self._low, self._high, np.zeros(15, np.uint64))
            self.offset, self.scale = self._offset_and_scale(*_column_bounds(xyz))
        scaled = np.round((xyz - self.offset) / self.scale)
        if count and not (max(scaled.max(), -scaled.min()) <= _INT_LIMIT):
            return None
        packed = np.zeros(count, dtype=self.dtype)
        packed["X"], packed["Y"], packed["Z"] = scaled[:, 0], scaled[:, 1], scaled[:, 2]
        low, high = (tuple(bound.astype(np.int64) for bound in _column_bounds(scaled)) if count
                     else (self._low, self._high))
        returns = np.asarray(columns["return_number"], dtype=np.uint8)
        packed["bit_fields"] = (returns & 0x0F) | (np.asarray(columns["number_of_returns"], dtype=np.uint8) << 4)
        for name in ("intensity", "gps_time", *self._extra_names):
            packed[name] = columns[name]
        counts = np.bincount(returns, minlength=16)[1:16].astype(np.uint64)
        return PackedFrame(packed.tobytes(), count, low, high, counts)

    def commit(self, frame: PackedFrame) -> None:
        """Count a frame once its bytes are written."""
        if frame.count:
            self.count += frame.count
            self._low = np.minimum(self._low, frame.low)
            self._high = np.maximum(self._high, frame.high)
            self._by_return += frame.by_return

    def header(self) -> bytes:
        """The final header and VLRs (:attr:`header_size` bytes): point counts, bounds, points per return."""
        if self.offset is None:  # no point at all
            self.offset, self.scale = self._offset_and_scale(np.full(3, np.inf), np.full(3, -np.inf))
        header = self._make_header(self.offset, self.scale)
        header.point_count = self.count
        header.number_of_points_by_return = self._by_return.copy()
        if self.count:  # as laspy's writer makes them: the integers' bounds scaled
            header.mins = self._low * self.scale + self.offset
            header.maxs = self._high * self.scale + self.offset
        else:
            header.mins = header.maxs = np.zeros(3)
        data = _header_bytes(header)
        if len(data) != self.header_size:
            raise RuntimeError(f"the LAS header grew from {self.header_size} to {len(data)} bytes")
        return data


def _column_bounds(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest of each column of ``values`` ``(n, 3)``, column by column (numpy's reduction along
    the rows of a three-column table is fifteen times slower)."""
    return (np.array([values[:, k].min() for k in range(3)]), np.array([values[:, k].max() for k in range(3)]))


def _header_bytes(header) -> bytes:
    with io.BytesIO() as out:
        header.write_to(out)
        return out.getvalue()
