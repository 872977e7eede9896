"""Fitting the rosette model (RflySim's ``otherParams``) to a measured pattern.

Shape (CameraFOV, petal height h, spacing exponent p, tip exponent q): the
stream is cut into petals at its centre crossings (minima of the angle off
the boresight); each petal is turned so its tip lies on -x and mirrored so its
outward half is on top; a sample's place in its half (0 at the centre, 1 at
the tip, from its firing order) gives the model point it should sit on, and
``scipy.optimize.least_squares`` fits the four parameters to all of them.
The residual reported is the perpendicular distance of every measured point
to the fitted petal curve.

Structure (figure-8s per flower N8, flowers per figure Nf, jitter): when the
petals come in figure-8 pairs (as our own model's do) they are read off the
tip angles exactly; otherwise (a real sensor's prisms do not pair petals)
they are chosen so that the coverage against integration time matches the
measured one best.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.reference import ReferencePattern
from livox_viz.patterns.metrics import coverage_curve, window_coverage
from livox_viz.patterns.rosette import ScanPattern, arc_xy
from livox_viz.patterns.stream import points_before

#: A petal residual over this fraction of the half-angle means the points are no rosette (noise, say).
NO_ROSETTE_FRACTION = 0.2
#: A petal residual over this fraction of the half-angle is a rough fit, said as a warning: the rosette heads' own
#: tables leave 0.4-1.2 % (Mid-70 0.13 deg of 35, Mid-40 0.22 of 19), the heads a rosette cannot draw 5-8 % (the
#: Avia 1.7 deg of 34, the HAP 3.1 of 54, the Horizon 2.9 of 37, the Tele-15 0.53 of 7.1).
ROUGH_ROSETTE_FRACTION = 0.025
#: Integration times the structure fit matches, seconds.
FIT_TIMES = (0.1, 0.2, 0.5, 1.0)


@dataclass(frozen=True)
class Petals:
    """Petals found in a stream: index of each start (centre), tip and end (next centre), ``(k,)`` int64 each."""

    start: np.ndarray
    tip: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return int(self.start.size)


def find_petals(xy_deg: np.ndarray) -> Petals:
    """Cut a stream into petals at the minima of the angle off the boresight.

    Raises
    ------
    LivoxVizError
        If the stream holds less than one whole petal.
    """
    alpha = np.hypot(xy_deg[:, 0], xy_deg[:, 1])
    if alpha.size < 5:
        raise LivoxVizError(f"{alpha.size} points; a fit needs at least one whole petal")
    top = alpha.max()
    interior = slice(1, -1)
    minima = np.flatnonzero((alpha[interior] < alpha[:-2]) & (alpha[interior] <= alpha[2:])
                            & (alpha[interior] < 0.25 * top)) + 1
    if alpha[0] < 0.25 * top and alpha[0] <= alpha[1]:
        minima = np.concatenate([[0], minima])
    starts, tips, ends = [], [], []
    for a, b in itertools.pairwise(minima):
        tip = a + int(np.argmax(alpha[a:b]))
        if alpha[tip] > 0.75 * top and tip - a >= 2 and b - tip >= 2:
            starts.append(a)
            tips.append(tip)
            ends.append(b)
    if not starts:
        raise LivoxVizError("found no whole petal (centre -> tip -> centre); a fit needs at least one")
    return Petals(np.array(starts), np.array(tips), np.array(ends))


def petal_frames(xy_deg: np.ndarray, petals: Petals, limit: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every petal's points turned tip-to--x and outward-half-up, with their place along the arc.

    Returns
    -------
    local : (m, 2) float64
        Points of the petals, degrees, tip on -x, outward half at y >= 0.
    place : (m,) float64
        Signed place along the arc: +s for the outward half, -s for the inward one
        (s = 0 at the centre, 1 at the tip).
    """
    count = len(petals) if limit is None else min(limit, len(petals))
    blocks, places = [], []
    for k in range(count):
        s, m, e = int(petals.start[k]), int(petals.tip[k]), int(petals.end[k])
        points = xy_deg[s:e]
        turn = math.pi - math.atan2(xy_deg[m, 1], xy_deg[m, 0])
        c, si = math.cos(turn), math.sin(turn)
        local = np.column_stack([points[:, 0] * c - points[:, 1] * si, points[:, 0] * si + points[:, 1] * c])
        index = np.arange(s, e)
        outward = index < m
        frac = np.where(outward, (index - s) / (m - s), (e - index) / (e - m))
        if local[outward, 1].mean() < 0:
            local[:, 1] *= -1
        blocks.append(local)
        places.append(np.where(outward, frac, -frac))
    return np.concatenate(blocks), np.concatenate(places)


def model_points(place: np.ndarray, half_fov: float, h: float, p: float, q: float) -> np.ndarray:
    """Model petal points for signed arc places (see :func:`petal_frames`), ``(m,)`` -> ``(m, 2)``."""
    xy = arc_xy(np.abs(place), 1, 2.0 * half_fov, h, p, q)
    xy[place < 0, 1] *= -1
    return xy


@dataclass(frozen=True)
class ShapeFit:
    """The fitted petal and how well it fits.

    Parameters
    ----------
    camera_fov, petal_height, spacing_exponent, tip_exponent : float
    rms_deg, p95_deg : float
        Perpendicular distance of the measured points to the fitted petal.
    points_per_arc : float
        Mean samples from centre to tip (the measured W).
    petals : int
    """

    camera_fov: float
    petal_height: float
    spacing_exponent: float
    tip_exponent: float
    rms_deg: float
    p95_deg: float
    points_per_arc: float
    petals: int

    def rough_warning(self) -> str | None:
        """A warning when the petal is only roughly the points' (:data:`ROUGH_ROSETTE_FRACTION` of the
        half-angle or more): a head whose scan no rosette draws. None for a good fit."""
        half_fov = self.camera_fov / 2.0
        if self.rms_deg <= ROUGH_ROSETTE_FRACTION * half_fov:
            return None
        return (f"the rosette follows the reference only roughly: {self.rms_deg:.3g} deg rms off its petals, "
                f"{100 * self.rms_deg / half_fov:.1f} % of the {half_fov:.3g} deg half-angle (a rosette head's own "
                f"table leaves under {100 * ROUGH_ROSETTE_FRACTION:g} %); a rosette cannot draw this scan: its "
                "series-track or Risley preset can")


def fit_shape(xy_deg: np.ndarray, max_petals: int = 40) -> ShapeFit:
    """Least-squares fit of CameraFOV, h, p, q to the petals of a stream."""
    from scipy.optimize import least_squares

    petals = find_petals(xy_deg)
    local, place = petal_frames(xy_deg, petals, max_petals)
    half_fov0 = float(np.hypot(local[:, 0], local[:, 1]).max())
    h0 = max(float(np.abs(local[:, 1]).max()) * 0.9, 1e-3)

    def residual(params: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return (model_points(place, *params) - local).ravel()

    start = [min(half_fov0, 89.0), min(h0, half_fov0 / 2, 45.0), 1.3, 1.1]
    if not np.all(np.isfinite(residual(np.array(start)))):
        raise LivoxVizError("the points do not form rosette petals (centre -> tip -> centre arcs); no rosette fits")
    solution = least_squares(
        residual, x0=start,
        bounds=([start[0] * 0.8, 1e-3, 0.05, 0.05], [min(start[0] * 1.2, 89.9), 45.0, 10.0, 10.0]),
        x_scale="jac", method="trf",
    )
    half_fov, h, p, q = (float(v) for v in solution.x)
    every, _ = petal_frames(xy_deg, petals)
    with np.errstate(invalid="ignore", divide="ignore"):
        distance = perpendicular_distance(every, half_fov, h, p, q)
    rms_deg = float(np.sqrt(np.mean(distance**2)))
    if not math.isfinite(rms_deg) or rms_deg > NO_ROSETTE_FRACTION * half_fov:
        raise LivoxVizError(f"the points do not form rosette petals: the best petal is {rms_deg:.3g} deg rms off them "
                            f"({100 * rms_deg / half_fov:.0f} % of the {half_fov:.3g} deg half-angle); no rosette fits")
    return ShapeFit(
        camera_fov=2 * half_fov, petal_height=h, spacing_exponent=p, tip_exponent=q,
        rms_deg=rms_deg, p95_deg=float(np.percentile(distance, 95)),
        points_per_arc=float(np.mean(petals.tip - petals.start)), petals=len(petals),
    )


def perpendicular_distance(local: np.ndarray, half_fov: float, h: float, p: float, q: float) -> np.ndarray:
    """Distance of each turned petal point to the model petal curve, degrees, ``(m,)``."""
    from scipy.spatial import cKDTree

    fine = np.linspace(0.0, 1.0, 20_001)
    curve = np.concatenate([model_points(fine, half_fov, h, p, q), model_points(-fine, half_fov, h, p, q)])
    distance, _ = cKDTree(curve).query(local)
    return distance


@dataclass(frozen=True)
class StructureFit:
    """Figure-8s per flower, flowers per figure and jitter, and how they were found."""

    figure8_per_flower: int
    flowers_per_figure: int
    jitter_max_deg: float
    jitter_scope: str
    method: str


def fit_structure_from_pairs(xy_deg: np.ndarray, petals: Petals) -> StructureFit | None:
    """Read N8, Nf and jitter off the tip angles when petals come in figure-8 pairs; None if they do not."""
    tips = np.degrees(np.arctan2(xy_deg[petals.tip, 1], xy_deg[petals.tip, 0]))
    pairs = len(tips) // 2
    if pairs < 4:
        return None
    first, second = tips[0 : 2 * pairs : 2], tips[1 : 2 * pairs : 2]
    opposite = np.abs(((second - first) % 360.0) - 180.0)
    if np.max(opposite) > 1e-3:
        return None
    theta = np.mod(first - 180.0, 360.0)  # rotation of each figure-8
    # N8 * Nf also passes when the offset stands still within a figure, and 1 always does:
    # the true N8 is the smallest that passes above 1.
    passing = []
    for n8 in range(1, min(360, pairs // 2) + 1):
        groups = pairs // n8
        spacing = 180.0 / n8
        residue = np.mod(theta[: groups * n8], spacing).reshape(groups, n8)
        spread = np.abs(((residue - residue[:, :1]) + spacing / 2) % spacing - spacing / 2).max()
        slots = np.round(np.mod(theta[: groups * n8].reshape(groups, n8) - residue[:, :1], 360.0) / spacing)
        if spread < 1e-4 and all(len(set(row.tolist())) == n8 for row in slots):
            passing.append(n8)
    above_one = [n8 for n8 in passing if n8 > 1]
    best = above_one[0] if above_one else (1 if passing else None)
    if best is None:
        return None
    n8 = best
    spacing = 180.0 / n8
    flowers = pairs // n8
    phase = np.mod(theta[: flowers * n8 : n8], spacing)
    steps = np.mod(np.diff(phase), spacing)
    if steps.size < 2:
        return None
    best_nf, best_score, best_u = 1, math.inf, steps
    for nf in range(1, 361):
        step = spacing / nf
        u = np.mod(steps - step + 1e-9, spacing) - 1e-9
        score = float(u.max())
        if score < best_score - 1e-9:
            best_nf, best_score, best_u = nf, score, u
    moving = best_u > 1e-6
    if not moving.any():
        return StructureFit(n8, best_nf, 0.0, "flower", "figure-8 pairs")
    scope = "flower" if moving.mean() > 0.5 or best_nf == 1 else "figure"
    jumps = best_u[moving]
    jitter = float(jumps.max() * (jumps.size + 1) / jumps.size)
    return StructureFit(n8, best_nf, jitter, scope, "figure-8 pairs")


def model_coverage(config: SensorConfig, seconds: tuple[float, ...], radius_deg: float, seeds: int = 3) -> np.ndarray:
    """Coverage of the model from its start, the mean over ``seeds`` seeds."""
    counts = points_before(np.asarray(seconds, dtype=np.float64), config.point_rate)
    count = int(counts.max())
    curves = [coverage_curve(ScanPattern(config, seed=seed).take(count).xy_deg, counts, radius_deg)
              for seed in range(seeds)]
    return np.mean(curves, axis=0)


def fit_structure_by_coverage(reference_curve: np.ndarray, base: SensorConfig, radius_deg: float) -> StructureFit:
    """Choose N8, Nf and jitter whose coverage at :data:`FIT_TIMES` is closest to the measured one."""
    def error(n8: int, nf: int, jitter: float, seeds: int) -> float:
        config = base.with_param("figure8_per_flower", n8).with_param("flowers_per_figure", nf)
        config = config.with_param("jitter_max_deg", jitter)
        curve = model_coverage(config, FIT_TIMES, radius_deg, seeds)
        return float(np.sum((curve - reference_curve) ** 2))

    scores = sorted((error(n8, nf, 1.0, 1), n8, nf) for n8 in range(1, 21) for nf in range(1, 11))
    best = min(((error(n8, nf, jitter, 3), n8, nf, jitter) for _, n8, nf in scores[:4]
                for jitter in (0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)))
    return StructureFit(best[1], best[2], best[3], "flower", "coverage growth")


@dataclass(frozen=True)
class FitResult:
    """Everything ``livox-viz fit`` reports."""

    config: SensorConfig
    shape: ShapeFit
    structure: StructureFit
    seconds: tuple[float, ...]
    coverage_reference: np.ndarray = field(repr=False)
    coverage_fit: np.ndarray = field(repr=False)


def fit_reference(reference: ReferencePattern, base: SensorConfig | None = None) -> FitResult:
    """Fit every model parameter to a measured pattern and build a valid configuration."""
    base = base or SensorConfig()
    reference.require_a_scan()
    if reference.plane != "boresight":
        raise LivoxVizError(f"{reference.name}: its rays go all around the sensor; RflySim's rosette looks one way "
                            "(no rosette fits a 360-degree head)")
    seconds = tuple(t for t in FIT_TIMES if t * reference.rate <= len(reference.t))
    if not seconds:
        raise LivoxVizError(f"{reference.name}: {reference.seconds:.4g} s of data; allowed: at least "
                            f"{min(FIT_TIMES):g} s ({round(min(FIT_TIMES) * reference.rate):,} rows at "
                            f"{reference.rate:g} rows/s)")
    shape = fit_shape(reference.xy_deg)
    petals = find_petals(reference.xy_deg)
    width = max(1, round(shape.points_per_arc))
    rate = round(reference.rate)
    config = _rate_config(base, width, rate)
    config = replace(config, camera_fov=round(shape.camera_fov, 4))
    config = config.with_param("petal_height", round(shape.petal_height, 4))
    config = config.with_param("spacing_exponent", round(shape.spacing_exponent, 4))
    config = config.with_param("tip_exponent", round(shape.tip_exponent, 4))
    radius = shape.camera_fov / 2
    structure = fit_structure_from_pairs(reference.xy_deg, petals)
    # Each pattern's coverage in its own field of view, as ``compare`` counts it: the table's is its own cone,
    # not the fitted one (the Mid-70's 35.216 deg against a fitted 35.062 gave 10.78 % where compare says 10.75).
    reference_curve = window_coverage(reference.xy_deg, reference.rate, seconds, reference.field_of_view)
    if structure is None:
        if seconds != FIT_TIMES:
            raise LivoxVizError(f"{reference.seconds:.2f} s of data; the coverage fit needs at least "
                                f"{max(FIT_TIMES):g} s")
        structure = fit_structure_by_coverage(reference_curve, config, radius)
    config = config.with_param("figure8_per_flower", structure.figure8_per_flower)
    config = config.with_param("flowers_per_figure", structure.flowers_per_figure)
    config = config.with_param("jitter_max_deg", round(min(structure.jitter_max_deg, 360.0), 4))
    config = replace(config, jitter_scope=structure.jitter_scope)
    fitted_curve = model_coverage(config, seconds, radius) if seconds else np.zeros(0)
    return FitResult(config, shape, structure, seconds, reference_curve, fitted_curve)


def _rate_config(base: SensorConfig, width: int, rate: int) -> SensorConfig:
    """W near the measured points per arc, with H and F whole numbers giving exactly ``rate``."""
    best = None
    for w in range(max(1, width - 10), width + 11):
        for f in (10, 20, 5, 25, 50, 4, 8, 2, 1):
            h, rest = divmod(rate, w * f)
            if rest == 0 and 1 <= h <= 2000:
                candidate = (abs(w - width), f != 10, w, h, f)
                best = candidate if best is None or candidate < best else best
    if best is None:
        w = width
        return replace(base, data_width=w, data_height=max(1, round(rate / (w * 10))), data_check_freq=10)
    _, _, w, h, f = best
    return replace(base, data_width=w, data_height=h, data_check_freq=f)
