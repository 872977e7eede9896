"""Measures of a scan pattern: FOV coverage against integration time, radial density.

Coverage (scan-model.md section 7): a square grid of cell size ``cell_deg``
(edges at multiples of it, so the boresight is a cell corner) is laid over the
angular plane; of the cells whose centre lies inside the FOV circle, the
fraction holding at least one point. Livox's own figure uses 5 mrad cells
(0.2865 degrees), the default here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.stream import points_before

LIVOX_CELL_DEG = math.degrees(0.005)


@dataclass(frozen=True)
class CoverageGrid:
    """The cells of the FOV disk.

    Parameters
    ----------
    radius_deg : float
        FOV half-angle, degrees.
    cell_deg : float
        Cell size, degrees.
    """

    radius_deg: float
    cell_deg: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cell_deg) and self.cell_deg > 0):
            raise LivoxVizError(f"cell size = {self.cell_deg!r} deg; allowed: a number > 0")
        if not (math.isfinite(self.radius_deg) and self.radius_deg > 0):
            raise LivoxVizError(f"FOV radius = {self.radius_deg!r} deg; allowed: a number > 0")
        if (2 * self.radius_deg / self.cell_deg) ** 2 > 4e8:
            raise LivoxVizError(
                f"cell size {self.cell_deg:g} deg gives too many cells for a {self.radius_deg:g} deg FOV; "
                f"allowed: >= {2 * self.radius_deg / 2e4:g} deg"
            )

    @property
    def cells_per_side(self) -> int:
        """Cells along each axis on each side of the boresight."""
        return math.ceil(self.radius_deg / self.cell_deg)

    @cached_property
    def inside_mask(self) -> np.ndarray:
        """``(2M, 2M)`` bool: which cells have their centre inside the FOV circle (M = cells per side); never none."""
        half = self.cells_per_side
        centres = (np.arange(-half, half) + 0.5) * self.cell_deg
        inside = np.hypot(centres[:, None], centres[None, :]) <= self.radius_deg
        if not inside.any():  # a FOV narrower than a cell: the four cells that meet at the boresight
            inside[half - 1 : half + 1, half - 1 : half + 1] = True
        return inside

    @property
    def cell_count(self) -> int:
        """How many cells the FOV holds (the denominator of coverage)."""
        return int(self.inside_mask.sum())

    def cell_index(self, xy_deg: np.ndarray) -> np.ndarray:
        """Flat cell number of each point, -1 for points in no FOV cell.

        Parameters
        ----------
        xy_deg : (n, 2) float64

        Returns
        -------
        cell : (n,) int64
        """
        half = self.cells_per_side
        position = np.asarray(xy_deg, dtype=np.float64) * (1.0 / self.cell_deg)
        position += half
        # Inside [0, 2 half) truncation is the floor; anything outside is no cell.
        valid = np.all((position >= 0) & (position < 2 * half), axis=1)
        index = position.astype(np.int64)
        candidate = index[:, 0] * (2 * half) + index[:, 1]
        candidate[~valid] = 0
        inside = self.inside_mask.ravel()[candidate] & valid
        return np.where(inside, candidate, -1)


def coverage(xy_deg: np.ndarray, radius_deg: float, cell_deg: float = LIVOX_CELL_DEG) -> float:
    """Fraction of the FOV's cells that hold at least one of the points.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles, degrees.
    radius_deg : float
        FOV half-angle, degrees.
    cell_deg : float
        Cell size, degrees.
    """
    return float(coverage_curve(xy_deg, [len(xy_deg)], radius_deg, cell_deg)[0])


def coverage_curve(
    xy_deg: np.ndarray,
    counts: Sequence[int] | np.ndarray,
    radius_deg: float,
    cell_deg: float = LIVOX_CELL_DEG,
) -> np.ndarray:
    """Coverage of each prefix of the points (the first ``counts[k]`` of them), in one pass.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles in emission order, degrees.
    counts : (k,) int
        Prefix lengths.
    radius_deg, cell_deg : float
        FOV half-angle and cell size, degrees.

    Returns
    -------
    fraction : (k,) float64
        In [0, 1].
    """
    grid = CoverageGrid(radius_deg, cell_deg)
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
        raise LivoxVizError(f"integration times {list(seconds)!r}; allowed: numbers > 0 seconds")
    counts = points_before(times, config.point_rate)
    if counts.max() > 200_000_000:
        raise LivoxVizError(f"{times.max():g} s is {counts.max()} points; allowed: at most 200 million")
    grid = CoverageGrid(config.half_fov_deg, cell_deg)
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
    radius_deg: float,
    bins: int = 35,
) -> tuple[np.ndarray, np.ndarray]:
    """Points per steradian against the angle off the boresight.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern angles, degrees.
    radius_deg : float
        FOV half-angle, degrees; the bins span [0, radius].
    bins : int
        Number of equal-width rings.

    Returns
    -------
    edges_deg : (bins + 1,) float64
        Ring edges, degrees off the boresight.
    density : (bins,) float64
        Points per steradian in each ring.
    """
    if bins < 1:
        raise LivoxVizError(f"bins = {bins}; allowed: an integer >= 1")
    alpha = np.hypot(xy_deg[:, 0], xy_deg[:, 1])
    edges = np.linspace(0.0, radius_deg, bins + 1)
    counts, _ = np.histogram(alpha, bins=edges)
    solid_angle = 2.0 * np.pi * -np.diff(np.cos(np.radians(edges)))
    return edges, counts / solid_angle


#: Integration times of the coverage chart, seconds.
CURVE_SECONDS: tuple[float, ...] = (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
#: Points a chart's curves are computed from at most (so a redraw stays well under 100 ms).
CURVE_POINTS = 1_000_000


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
        Ring centres, degrees off the boresight.
    density : (b,) float64
        Points per steradian per second over the whole stream.
    """

    seconds: np.ndarray
    coverage: np.ndarray
    density_alpha_deg: np.ndarray
    density: np.ndarray


def stream_curves(xy_deg: np.ndarray, rate: float, radius_deg: float,
                  seconds: Sequence[float] = CURVE_SECONDS, bins: int = 30) -> PatternCurves:
    """:class:`PatternCurves` of the points ``xy_deg`` (in firing order at ``rate`` points/s).

    Parameters
    ----------
    xy_deg : (n, 2) float64
    rate : float
    radius_deg : float
        FOV half-angle for coverage and the density's outer edge.
    seconds : (k,) float
    bins : int
    """
    usable = np.array([s for s in seconds if points_before(s, rate) <= xy_deg.shape[0]], dtype=np.float64)
    counts = points_before(usable, rate)
    fraction = coverage_curve(xy_deg, counts, radius_deg) if usable.size else np.zeros(0)
    edges, density = radial_density(xy_deg, radius_deg, bins)
    duration = xy_deg.shape[0] / rate
    return PatternCurves(usable, fraction, 0.5 * (edges[1:] + edges[:-1]), density / max(duration, 1e-12))


def config_curves(config: SensorConfig, seed: int = 0, seconds: Sequence[float] = CURVE_SECONDS) -> PatternCurves:
    """:class:`PatternCurves` of a configuration's pattern over ``max(seconds)`` (at most :data:`CURVE_POINTS`)."""
    count = min(points_before(max(seconds), config.point_rate), CURVE_POINTS)
    xy = make_pattern(config, seed).take(count).xy_deg
    return stream_curves(xy, config.point_rate, config.half_fov_deg, seconds)


def window_coverage(xy_deg: np.ndarray, rate: float, seconds: tuple[float, ...] | list[float], radius_deg: float,
                    cell_deg: float = LIVOX_CELL_DEG, starts: int = 6) -> np.ndarray:
    """Coverage at each integration time, the mean over ``starts`` windows spread over the stream.

    Parameters
    ----------
    xy_deg : (n, 2) float64
    rate : float
        Points per second.
    seconds : (k,) float
    radius_deg, cell_deg : float
    starts : int

    Returns
    -------
    fraction : (k,) float64
    """
    total = xy_deg.shape[0]
    result = np.zeros(len(seconds))
    counts = points_before(np.asarray(seconds, dtype=np.float64), rate)
    if counts.max() > total:
        raise LivoxVizError(f"{max(seconds):g} s needs {counts.max()} points; the stream has {total}")
    for k, count in enumerate(counts):
        span = total - count
        offsets = np.linspace(0, span, starts).astype(int) if span > 0 else np.zeros(1, dtype=int)
        values = [coverage_curve(xy_deg[o : o + count], [count], radius_deg, cell_deg)[0] for o in offsets]
        result[k] = float(np.mean(values))
    return result
