"""What every pattern stream shares: chunks of points, a position in the endless stream, and time.

Point k of any stream fires at ``t_k = k / rate`` seconds (``rate`` = W*H*F);
:func:`points_before` is the one conversion from seconds to a point count.
A :class:`PatternChunk` is a run of consecutive points with their pattern angles
(degrees, x right, y up) and times; its labels (frame, arc, petal, ...) follow
from the stream index alone. :class:`PatternStream` moves through the stream
(``take``, ``take_until``, ``next_frame``, ``skip``); each model makes points with
``points(start, count)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from livox_viz.config.sensor import SERIES_MODELS, SensorConfig
from livox_viz.core.buffers import RecycledBlocks
from livox_viz.core.workload import MOST_POINTS as WORKLOAD_MOST_POINTS

#: The largest count :func:`points_before` gives: a longer time is that many points (far past any budget), not an
#: integer that overflows (``--seconds 1e308``); :func:`~livox_viz.core.workload.check_points` refuses it as such.
MOST_POINTS = WORKLOAD_MOST_POINTS


def points_before(seconds, rate: float):
    """How many points a stream of ``rate`` points/s emits in [0, ``seconds``): the one seconds-to-points rule.

    Point k fires at k / rate, so this is ceil(seconds * rate); the tolerance
    keeps a time computed as k / rate from counting point k itself.

    Parameters
    ----------
    seconds : float or (k,) float64
        Integration times, seconds.
    rate : float
        Points per second.

    Returns
    -------
    count : int, or (k,) int64 for an array of times
        At most :data:`MOST_POINTS`.
    """
    if np.ndim(seconds):
        with np.errstate(over="ignore"):  # a time past 1e300 s is inf points, then the most
            counts = np.ceil(np.asarray(seconds, dtype=np.float64) * rate - 1e-9)
        return np.clip(counts, 0, MOST_POINTS).astype(np.int64)
    value = seconds * rate - 1e-9
    return MOST_POINTS if not value < MOST_POINTS else max(0, math.ceil(value))


class _TimesOnDemand:
    """The ``t`` field of :class:`PatternChunk`: the times given, or k / rate made on first use and kept.

    A data descriptor as the field's default: the dataclass's ``__init__`` stores
    through :meth:`__set__` (None when no times were given).
    """

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = f"_{name}_given"

    def __get__(self, chunk: PatternChunk | None, owner: type | None = None) -> np.ndarray | None:
        if chunk is None:
            return None  # the dataclass asks for the field's default
        times = chunk.__dict__.get(self._name)
        if times is None:
            times = np.arange(chunk.start, chunk.start + chunk.xy_deg.shape[0], dtype=np.float64)
            times /= chunk.config.point_rate
            chunk.__dict__[self._name] = times
        return times

    def __set__(self, chunk: PatternChunk, times: np.ndarray | None) -> None:
        chunk.__dict__[self._name] = times


@dataclass(frozen=True)
class PatternChunk:
    """A run of consecutive points of the endless stream.

    Parameters
    ----------
    config : SensorConfig
        The configuration that made the points.
    start : int
        Stream index of the first point (points are numbered from 0).
    xy_deg : (n, 2) float64
        Pattern x, y, degrees.
    t : (n,) float64, optional
        Emission time of each point, seconds since the scan start; by default
        k / rate, made on first use (a stream that only needs the angles, such as
        the coverage charts, never pays for it).
    figure8_angle_deg : (m,) float64
        Rotation of each figure-8 the chunk touches, first one first, degrees
        in [0, 360) (rosette only; empty for the Risley track).

    Notes
    -----
    The labels (``frame``, ``arc``, ``petal``, ``figure8``, ``flower``,
    ``figure``: running indices from the scan start; ``arc_in_figure8`` 0..3)
    follow from the stream index alone and are computed on first use.
    """

    config: SensorConfig
    start: int
    xy_deg: np.ndarray
    t: np.ndarray = _TimesOnDemand()  # type: ignore[assignment]
    figure8_angle_deg: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    @classmethod
    def from_stream(cls, config: SensorConfig, start: int, xy_deg: np.ndarray,
                    figure8_angle_deg: np.ndarray) -> PatternChunk:
        """The chunk a stream hands out, made without the dataclass's ``__init__`` (times made on first use).

        A stream makes one per frame, and the frozen dataclass's ``__init__`` (a guarded ``object.__setattr__``
        per field) cost 1.3 us of a Risley frame's 30 us; this fills the same fields directly in 0.5 us.

        Parameters
        ----------
        config, start, xy_deg, figure8_angle_deg
            As for the class.

        Returns
        -------
        PatternChunk
            Equal field for field to ``PatternChunk(config, start, xy_deg, None, figure8_angle_deg)``.
        """
        chunk = object.__new__(cls)
        # ``_t_given``: where _TimesOnDemand keeps the field ``t`` (None: made on first use).
        chunk.__dict__.update(config=config, start=start, xy_deg=xy_deg, _t_given=None,
                              figure8_angle_deg=figure8_angle_deg)
        return chunk

    def __len__(self) -> int:
        return int(self.xy_deg.shape[0])

    @property
    def times_held(self) -> np.ndarray | None:
        """``(n,)`` float64 the times when given or already made, else None: they are then ``k / rate``, which a
        caller that needs only some of them can compute itself."""
        return self.__dict__.get("_t_given")

    @property
    def stop(self) -> int:
        """Stream index one past the last point."""
        return self.start + len(self)

    @cached_property
    def index(self) -> np.ndarray:
        """``(n,)`` int64 stream index of every point."""
        return np.arange(self.start, self.stop, dtype=np.int64)

    def unit_number(self, unit: str) -> np.ndarray:
        """``(n,)`` int64 running number of each point's ``unit`` (a key of ``config.unit_points``)."""
        return self.index // self.config.unit_points[unit]

    @property
    def arc(self) -> np.ndarray:
        """``(n,)`` int64 running arc number."""
        return self.unit_number("arc")

    @property
    def petal(self) -> np.ndarray:
        """``(n,)`` int64 running petal number (two arcs each)."""
        return self.unit_number("petal")

    @property
    def figure8(self) -> np.ndarray:
        """``(n,)`` int64 running figure-8 number."""
        return self.unit_number("figure8")

    @property
    def flower(self) -> np.ndarray:
        """``(n,)`` int64 running flower number."""
        return self.unit_number("flower")

    @property
    def figure(self) -> np.ndarray:
        """``(n,)`` int64 running figure number."""
        return self.unit_number("figure")

    @property
    def frame(self) -> np.ndarray:
        """``(n,)`` int64 published frame number."""
        return self.unit_number("frame")

    @property
    def arc_in_figure8(self) -> np.ndarray:
        """``(n,)`` int64 arc within its figure-8, 0..3 in scan order (see :data:`ARC_NAMES`)."""
        return self.arc % 4

    @cached_property
    def point_angle_deg(self) -> np.ndarray:
        """``(n,)`` float64 rotation of the figure-8 each point belongs to, degrees."""
        first = self.start // self.config.points_per_figure8
        return self.figure8_angle_deg[self.figure8 - first]

    def labels(self) -> dict[str, np.ndarray]:
        """All integer labels by name (frame first, then the units smallest first), each ``(n,)`` int64."""
        names = ["frame", *(unit for unit in self.config.unit_points if unit != "frame")]
        labels = {name: self.unit_number(name) for name in names}
        if self.config.pattern_model in SERIES_MODELS:
            labels["laser"] = self.laser
        return labels

    @property
    def laser(self) -> np.ndarray:
        """``(n,)`` int64 laser of each point (k mod K; all 0 for one laser or the rosette)."""
        return self.index % self.config.lasers


#: Where streams make their chunks' points: a fresh array of a frame's size costs more in page faults than the
#: arithmetic that fills it (``bench_pattern.py``: a frame of the default preset 280 us fresh, 50 us reused), so a
#: block is used again once no chunk (nor any view of one) holds it. One pool for every stream of the process: a
#: scan's stream is new each scan, and its first few dozen chunks would otherwise all be fresh.
PATH_BLOCKS = RecycledBlocks(keep=8)


class PatternStream:
    """What every pattern stream offers: a position in the endless stream and ways to move it.

    Subclasses set ``config`` and ``_position`` and make points with
    :meth:`points` (``start``, ``count``) -> :class:`PatternChunk`.
    """

    config: SensorConfig
    _position: int = 0

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` of the stream, without moving it."""
        raise NotImplementedError

    def _path_buffer(self, count: int) -> np.ndarray:
        """A ``(count,)`` complex128 array to fill with points (x + iy, degrees), from :data:`PATH_BLOCKS`."""
        return PATH_BLOCKS.get(count * np.dtype(np.complex128).itemsize).view(np.complex128)

    @property
    def position(self) -> int:
        """How many points the stream has emitted so far."""
        return self._position

    @property
    def time(self) -> float:
        """Scan time of the next point, seconds."""
        return self._position / self.config.point_rate

    def take(self, count: int) -> PatternChunk:
        """The next ``count`` points of the stream."""
        if count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        chunk = self.points(self._position, count)
        self._position += count
        return chunk

    def take_until(self, scan_time: float) -> PatternChunk:
        """All points emitted before ``scan_time`` seconds that were not taken yet."""
        return self.take(max(0, points_before(scan_time, self.config.point_rate) - self._position))

    def next_frame(self) -> PatternChunk:
        """The rest of the current frame: W*H points when the stream sits on a frame start."""
        per_frame = self.config.points_per_frame
        return self.take(per_frame - self._position % per_frame)

    def skip(self, count: int) -> None:
        """Advance the stream by ``count`` points without making them."""
        if count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        self._position += count
