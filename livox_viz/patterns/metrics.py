"""Measures of a scan pattern: FOV coverage against integration time, density along the FOV's profile.

Coverage (scan-model.md section 7): a square grid of cell size ``cell_deg``
(edges at multiples of it, so the boresight is a cell corner) is laid over the
pattern plane; of the cells whose centre lies inside the field of view (the
cone of CameraFOV / 2, or a sensor's own outline or band:
:class:`~livox_viz.config.fov.FieldOfView`), the fraction holding at least one
point. Livox's own figure uses 5 mrad cells (0.2865 degrees), the default here.
In the panorama plane (azimuth, elevation) the cells are 5 mrad of azimuth by
5 mrad of elevation (the azimuth's step rounded so whole cells go round).

Density is points per steradian against the angle off the boresight (or, for a
panorama, against the elevation), each ring's solid angle counted inside the
field of view only.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from livox_viz.config.fov import FieldOfView
from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.workload import check_points
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.stream import points_before

LIVOX_CELL_DEG = math.degrees(0.005)
#: Points :func:`pattern_coverage` draws at most (the pattern is streamed; only its time is bounded).
COVERAGE_BUDGET = 200_000_000
#: Points whose cells :meth:`CoverageGrid.cell_index` finds at once.
_CELL_BLOCK = 65_536

#: A field of view, or the half-angle of a cone around the boresight, degrees.
FovLike = FieldOfView | float


def as_fov(fov: FovLike) -> FieldOfView:
    """A :class:`FieldOfView` from a field of view or a cone's half-angle (degrees)."""
    if isinstance(fov, FieldOfView):
        return fov
    radius = float(fov)
    if not (math.isfinite(radius) and 0 < radius < 90):
        raise LivoxVizError(f"FOV radius = {quoted(fov)} deg; allowed: a number in (0, 90)")
    return FieldOfView.cone(radius)


@dataclass(frozen=True)
class CoverageGrid:
    """The cells of a field of view.

    Parameters
    ----------
    fov : FieldOfView or float
        The field of view, or a cone's half-angle in degrees.
    cell_deg : float
        Cell size, degrees.
    """

    fov: FovLike
    cell_deg: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cell_deg) and self.cell_deg > 0):
            raise LivoxVizError(f"cell size = {quoted(self.cell_deg)} deg; allowed: a number > 0")
        object.__setattr__(self, "fov", as_fov(self.fov))
        x0, x1, y0, y1 = self.fov.bounds
        if ((x1 - x0) / self.cell_deg) * ((y1 - y0) / self.cell_deg) > 4e8:
            raise LivoxVizError(
                f"cell size {self.cell_deg:g} deg gives too many cells for a {self.fov.describe()}; "
                f"allowed: >= {max(x1 - x0, y1 - y0) / 2e4:g} deg"
            )

    @property
    def radius_deg(self) -> float:
        """The field of view's largest angle off the boresight (a cone's half-angle)."""
        return self.fov.reach_deg

    @cached_property
    def _axes(self) -> tuple[float, int, float, int, float, float]:
        """(x0, nx, y0, ny, cell_x, cell_y): the grid's first edges, cells per axis and cell sizes."""
        x_min, x_max, y_min, y_max = self.fov.bounds
        cell = self.cell_deg
        if self.fov.plane == "panorama":
            across = max(1, round(360.0 / cell))
            cell_x = 360.0 / across
            return (-180.0, across, math.floor(y_min / cell) * cell, math.ceil(y_max / cell)
                    - math.floor(y_min / cell), cell_x, cell)
        low_x, high_x = math.floor(x_min / cell), math.ceil(x_max / cell)
        low_y, high_y = math.floor(y_min / cell), math.ceil(y_max / cell)
        return (low_x * cell, high_x - low_x, low_y * cell, high_y - low_y, cell, cell)

    @property
    def cells_per_side(self) -> int:
        """Cells from the boresight to the cone's edge along an axis (a cone's grid is 2M x 2M)."""
        return math.ceil(self.radius_deg / self.cell_deg)

    @property
    def shape(self) -> tuple[int, int]:
        """Cells along x and along y."""
        _, nx, _, ny, _, _ = self._axes
        return (nx, ny)

    @cached_property
    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """``(nx,)`` and ``(ny,)`` float64 the cells' centres along x and y, degrees."""
        x0, nx, y0, ny, cell_x, cell_y = self._axes
        return (x0 + (np.arange(nx) + 0.5) * cell_x, y0 + (np.arange(ny) + 0.5) * cell_y)

    @cached_property
    def inside_mask(self) -> np.ndarray:
        """``(nx, ny)`` bool: which cells have their centre inside the field of view; never none."""
        inside = self.fov.grid_inside(*self.centres)
        if not inside.any():
            # A field of view narrower than a cell: the cells that meet at its middle (the boresight's four).
            x0, x1, y0, y1 = self.fov.bounds
            _, _, _, _, cell_x, cell_y = self._axes
            near_x = np.abs(self.centres[0] - (x0 + x1) / 2) <= cell_x / 2 + 1e-12
            near_y = np.abs(self.centres[1] - (y0 + y1) / 2) <= cell_y / 2 + 1e-12
            inside[np.ix_(near_x, near_y)] = True
        return inside

    @property
    def cell_count(self) -> int:
        """How many cells the FOV holds (the denominator of coverage)."""
        return int(self.inside_mask.sum())

    @cached_property
    def cell_solid_angle(self) -> np.ndarray:
        """``(nx, ny)`` float64 each cell's solid angle, steradians."""
        _, _, _, _, cell_x, cell_y = self._axes
        gx, gy = np.meshgrid(*self.centres, indexing="ij")
        return self.fov.cell_solid_angle(gx, gy, cell_x, cell_y)

    def cell_index(self, xy_deg: np.ndarray) -> np.ndarray:
        """Flat cell number of each point, -1 for points in no FOV cell.

        Parameters
        ----------
        xy_deg : (n, 2) float64

        Returns
        -------
        cell : (n,) int64
        """
        xy = np.asarray(xy_deg, dtype=np.float64)
        cell = np.empty(xy.shape[0], dtype=np.int64)
        # In blocks: the temporaries of a million points at once cost more in fresh pages than the arithmetic
        # (a slider's chart curves count 400 000 points).
        for start in range(0, xy.shape[0], _CELL_BLOCK):
            self._cells_of_block(xy[start : start + _CELL_BLOCK], cell[start : start + _CELL_BLOCK])
        return cell

    def _cells_of_block(self, xy: np.ndarray, out: np.ndarray) -> None:
        x0, nx, y0, ny, cell_x, cell_y = self._axes
        column = (xy[:, 0] - x0) * (1.0 / cell_x)
        row = (xy[:, 1] - y0) * (1.0 / cell_y)
        # Inside [0, n) truncation is the floor; anything outside is no cell.
        valid = (column >= 0) & (column < nx) & (row >= 0) & (row < ny)
        with np.errstate(invalid="ignore"):  # NaN or far-off points cast to junk; ``valid`` drops them
            candidate = column.astype(np.int64) * ny + row.astype(np.int64)
        candidate[~valid] = 0
        inside = self.inside_mask.ravel()[candidate] & valid
        candidate[~inside] = -1
        out[:] = candidate


def coverage(xy_deg: np.ndarray, fov: FovLike, cell_deg: float = LIVOX_CELL_DEG) -> float:
    """Fraction of the FOV's cells that hold at least one of the points.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles, degrees.
    fov : FieldOfView or float
        The field of view, or a cone's half-angle, degrees.
    cell_deg : float
        Cell size, degrees.
    """
    return float(coverage_curve(xy_deg, [len(xy_deg)], fov, cell_deg)[0])


def coverage_curve(
    xy_deg: np.ndarray,
    counts: Sequence[int] | np.ndarray,
    fov: FovLike,
    cell_deg: float = LIVOX_CELL_DEG,
) -> np.ndarray:
    """Coverage of each prefix of the points (the first ``counts[k]`` of them), in one pass.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles in emission order, degrees.
    counts : (k,) int
        Prefix lengths.
    fov : FieldOfView or float
        The field of view, or a cone's half-angle, degrees.
    cell_deg : float
        Cell size, degrees.

    Returns
    -------
    fraction : (k,) float64
        In [0, 1].
    """
    grid = _grid(as_fov(fov), cell_deg)
    cells = grid.cell_index(xy_deg)
    hit = np.flatnonzero(cells >= 0)
    first = np.full(grid.inside_mask.size, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(first, cells[hit], hit)  # the first point in each cell
    first_seen = np.sort(first[first != np.iinfo(np.int64).max])
    counted = np.searchsorted(first_seen, np.asarray(counts, dtype=np.int64), side="left")
    return counted / grid.cell_count


def pattern_coverage(
    config: SensorConfig,
    seconds: Sequence[float],
    cell_deg: float = LIVOX_CELL_DEG,
    seed: int = 0,
) -> np.ndarray:
    """Coverage of the configuration's pattern at each integration time from the scan start.

    Parameters
    ----------
    config : SensorConfig
    seconds : (k,) float
        Integration times T, seconds; points emitted in [0, T) count.
    cell_deg : float
        Cell size, degrees.
    seed : int

    Returns
    -------
    fraction : (k,) float64
    """
    times = np.asarray(seconds, dtype=np.float64)
    if times.size == 0 or not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise LivoxVizError(f"integration times {quoted(list(seconds))}; allowed: numbers > 0 seconds")
    counts = points_before(times, config.point_rate)
    # As the scan refuses them: a time that holds no point (1e-300 s printed 0.00 %), or too many.
    for count, seconds_asked in ((counts.min(), times.min()), (counts.max(), times.max())):
        check_points(int(count), f"an integration time of {seconds_asked:g} s", COVERAGE_BUDGET, can_force=False)
    grid = _grid(config.field_of_view, cell_deg)
    pattern = make_pattern(config, seed)
    seen = np.zeros(grid.inside_mask.size, dtype=bool)
    covered_at = np.zeros(counts.size, dtype=np.int64)
    order = np.argsort(counts)
    total = 0
    block = max(config.points_per_frame, 200_000)
    for position in order:
        target = int(counts[position])
        while pattern.position < target:
            chunk = pattern.take(min(block, target - pattern.position))
            cells = grid.cell_index(chunk.xy_deg)
            cells = cells[cells >= 0]
            new = np.unique(cells[~seen[cells]])
            seen[new] = True
            total += new.size
        covered_at[position] = total
    return covered_at / grid.cell_count


def radial_density(
    xy_deg: np.ndarray,
    fov: FovLike,
    bins: int = 35,
    profile_range: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Points per steradian along the field of view's profile: the angle off the boresight, or the elevation.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles, degrees.
    fov : FieldOfView or float
        The field of view (a cone's half-angle, degrees): the rings' solid angle is counted inside it.
    bins : int
        Number of equal-width rings.
    profile_range : tuple of 2 float, optional
        The rings' span, degrees (default the field of view's own, e.g. [0, half-angle]).

    Returns
    -------
    edges_deg : (bins + 1,) float64
        Ring edges, degrees off the boresight (or of elevation).
    density : (bins,) float64
        Points per steradian in each ring (0 where the ring holds no solid angle of the field of view).
    """
    if bins < 1:
        raise LivoxVizError(f"bins = {bins}; allowed: an integer >= 1")
    field = as_fov(fov)
    low, high = profile_range if profile_range is not None else field.profile_range
    edges = np.linspace(low, high, bins + 1)
    counts, _ = np.histogram(field.profile(xy_deg), bins=edges)
    solid_angle = ring_solid_angles(field, edges)
    density = np.divide(counts, solid_angle, out=np.zeros(bins), where=solid_angle > 0)
    return edges, density


def ring_solid_angles(fov: FieldOfView, edges_deg: np.ndarray) -> np.ndarray:
    """``(bins,)`` the solid angle of each ring of the profile inside the field of view, steradians.

    Exact for a cone (2 pi (cos a - cos b), clipped at its edge) and a band (2 pi (sin b - sin a));
    summed over fine cells otherwise.
    """
    edges = np.asarray(edges_deg, dtype=np.float64)
    if fov.shape == "cone":
        clipped = np.radians(np.clip(edges, 0.0, fov.half_angle_deg))
        return 2.0 * np.pi * -np.diff(np.cos(clipped))
    if fov.shape == "band":
        low, high = fov.elevation_deg
        clipped = np.radians(np.clip(edges, low, high))
        return 2.0 * np.pi * np.diff(np.sin(clipped))
    return _outline_ring_solid_angles(fov, tuple(edges.tolist())).copy()


@functools.lru_cache(maxsize=32)
def _outline_ring_solid_angles(fov: FieldOfView, edges: tuple[float, ...]) -> np.ndarray:
    """:func:`ring_solid_angles` of an outline, summed over 600 x 600 cells: made once per field of view and
    rings (120 ms for the Avia's; every chart of a reference at that sensor asked again)."""
    x0, x1, y0, y1 = fov.bounds
    grid = _grid(fov, max(x1 - x0, y1 - y0) / 600)
    gx, gy = np.meshgrid(*grid.centres, indexing="ij")
    inside = grid.inside_mask
    profile = fov.profile(np.column_stack([gx[inside], gy[inside]]))
    solid, _ = np.histogram(profile, bins=np.asarray(edges), weights=grid.cell_solid_angle[inside])
    return solid


@functools.lru_cache(maxsize=32)
def _grid(fov: FieldOfView, cell_deg: float) -> CoverageGrid:
    """The coverage grid of a field of view (kept: its inside mask costs a pass over every cell)."""
    return CoverageGrid(fov, cell_deg)


#: Integration times of the coverage chart, seconds.
CURVE_SECONDS: tuple[float, ...] = (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
#: Points a chart's curves are computed from at most (so a redraw stays under 100 ms): the 4 s of every shipped
#: preset, the HAP's 452 000 points/s the fastest (81 ms; at 1 M points its curve stopped at 2 s).
CURVE_POINTS = 2_000_000


@dataclass(frozen=True)
class PatternCurves:
    """Coverage against integration time and radial density of a stream from its start.

    Parameters
    ----------
    seconds : (k,) float64
        Integration times the stream covers.
    coverage : (k,) float64
        Fraction of the FOV's 5 mrad cells hit in [0, T).
    density_alpha_deg : (b,) float64
        Ring centres, degrees off the boresight (elevation, for a panorama).
    density : (b,) float64
        Points per steradian per second over the whole stream.
    """

    seconds: np.ndarray
    coverage: np.ndarray
    density_alpha_deg: np.ndarray
    density: np.ndarray


def stream_curves(xy_deg: np.ndarray, rate: float, fov: FovLike,
                  seconds: Sequence[float] = CURVE_SECONDS, bins: int = 30,
                  slots: np.ndarray | None = None) -> PatternCurves:
    """:class:`PatternCurves` of the points ``xy_deg`` (in firing order at ``rate`` points/s).

    Parameters
    ----------
    xy_deg : (n, 2) float64
    rate : float
    fov : FieldOfView or float
        The field of view (or a cone's half-angle, degrees) for coverage and the density's span.
    seconds : (k,) float
    bins : int
    slots : (n,) int64, optional
        Each point's firing (increasing, from firing 0), for a stream with gaps (a recording's no-returns);
        default: point k is firing k.
    """
    firings = xy_deg.shape[0] if slots is None or not len(slots) else int(slots[-1]) + 1
    usable = np.array([s for s in seconds if points_before(s, rate) <= firings], dtype=np.float64)
    counts = points_before(usable, rate)
    if slots is not None:
        counts = np.searchsorted(slots, counts, side="left")  # the points fired before each time
    fraction = coverage_curve(xy_deg, counts, fov) if usable.size else np.zeros(0)
    edges, density = radial_density(xy_deg, fov, bins)
    duration = firings / rate
    return PatternCurves(usable, fraction, 0.5 * (edges[1:] + edges[:-1]), density / max(duration, 1e-12))


def received_curves(xy_deg: np.ndarray, t_s: np.ndarray, rate: float, fov: FovLike,
                    seconds: Sequence[float] = CURVE_SECONDS, bins: int = 30) -> PatternCurves:
    """:class:`PatternCurves` of points received with their times (a live stream's: in any order, with gaps where
    nothing returned), from the first point's time.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        The points in the pattern's plane, degrees.
    t_s : (n,) float64
        Each point's time, seconds.
    rate : float
        Firings per second the times are counted in (the sensor's point rate): a point's firing is its time
        after the first times ``rate``.
    fov : FieldOfView or float
    seconds : (k,) float
        Integration times; those past the points' span are left out, and so are those shorter than the times'
        own step (RflySim's wire stamps a whole frame with one time: at 10 frames/s, 0.05 s of it is not known).
    bins : int
    """
    if xy_deg.shape[0] == 0:
        return PatternCurves(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))
    order = np.argsort(t_s, kind="stable")
    times = np.asarray(t_s, dtype=np.float64)[order]
    steps = np.diff(np.unique(times))
    step = float(steps.min()) if steps.size else 0.0
    known = [s for s in seconds if s >= step * (1.0 - 1e-9)]
    slots = np.rint((times - times[0]) * rate).astype(np.int64)
    return stream_curves(np.asarray(xy_deg, dtype=np.float64)[order], rate, fov, known, bins, slots=slots)


def config_curves(config: SensorConfig, seed: int = 0, seconds: Sequence[float] = CURVE_SECONDS) -> PatternCurves:
    """:class:`PatternCurves` of a configuration's pattern over ``max(seconds)`` (at most :data:`CURVE_POINTS`)."""
    count = min(points_before(max(seconds), config.point_rate), CURVE_POINTS)
    xy = make_pattern(config, seed).take(count).xy_deg
    return stream_curves(xy, config.point_rate, config.field_of_view, seconds)


def window_coverage(xy_deg: np.ndarray, rate: float, seconds: tuple[float, ...] | list[float], fov: FovLike,
                    cell_deg: float = LIVOX_CELL_DEG, starts: int = 6, slots: np.ndarray | None = None) -> np.ndarray:
    """Coverage at each integration time, the mean over ``starts`` windows spread over the stream.

    Parameters
    ----------
    xy_deg : (n, 2) float64
    rate : float
        Points per second.
    seconds : (k,) float
    fov : FieldOfView or float
        The field of view, or a cone's half-angle, degrees.
    cell_deg : float
    starts : int
    slots : (n,) int64, optional
        Each point's firing (increasing), for a stream with gaps (a recording's no-returns): a window is the
        points fired within it, and one longer than the stream holds all of them. Default: point k is firing k.

    Returns
    -------
    fraction : (k,) float64
    """
    total = xy_deg.shape[0] if slots is None or not len(slots) else int(slots[-1]) + 1
    result = np.zeros(len(seconds))
    counts = points_before(np.asarray(seconds, dtype=np.float64), rate)
    if slots is None and counts.max() > total:
        raise LivoxVizError(f"{max(seconds):g} s needs {counts.max()} points; the stream has {total}")
    for k, count in enumerate(counts):
        span = total - count
        offsets = np.linspace(0, span, starts).astype(int) if span > 0 else np.zeros(1, dtype=int)
        if slots is None:
            rows = [(o, o + count) for o in offsets]
        else:
            rows = zip(np.searchsorted(slots, offsets), np.searchsorted(slots, offsets + count), strict=True)
        values = [coverage_curve(xy_deg[a:b], [b - a], fov, cell_deg)[0] for a, b in rows]
        result[k] = float(np.mean(values))
    return result
