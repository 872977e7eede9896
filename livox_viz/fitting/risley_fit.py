"""Fitting the Risley model to a scan table: lasers, prism frequencies, phases and the series' coefficients.

The steps (``risley.md``):

1. **Lasers.** Each row's laser from the rows' geometry
   (:func:`~livox_viz.fitting.lasers.assign_lasers`: in one fixed order, row r
   is laser r mod K, as the public tables have it; rows out of order, with
   gaps or cut anywhere are followed laser by laser). ``beams`` forces K.
2. **Frequencies.** The two prisms' own terms are the two strongest lines of
   laser 0's spectrum (Hann window, zero-padded FFT, parabolic peak). They are
   refined by variable projection: for trial frequencies the coefficients are
   a linear least-squares problem, and ``scipy.optimize.least_squares`` moves
   the two frequencies to the smallest residual, first with the two prism
   terms alone, then with the whole series.
3. **Coefficients.** One linear least-squares solve per laser on every row.
   One laser on the boresight needs only rotation-equivariant terms
   (m + l = 1); off-axis lasers also get the terms of first and second order
   in their offset (m + l = -1 .. 3). Terms below 1e-5 deg for every laser
   are dropped and the rest solved again.
4. **Phases.** a0 and b0 are chosen so that laser 0's prism terms are real
   and positive (they are then the deflections).

Prism A is the one turning counter-clockwise (positive frequency); if both
turn the same way, the stronger one.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from livox_viz.config.risley_params import MAX_PRISM_HZ, RisleyParams
from livox_viz.core.blas import one_blas_thread
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.lasers import assign_lasers, even_series, find_lasers
from livox_viz.fitting.series_lsq import LaserRows, TimedRows
from livox_viz.fitting.spectrum import spectral_peaks
from livox_viz.fitting.table import ReferencePattern
from livox_viz.fitting.track_fit import NO_TRACK_FRACTION
from livox_viz.patterns.planes import angle_between_deg

__all__ = ["RisleyFit", "find_lasers", "fit_risley", "series_terms", "track_residual"]

MAX_LASERS = 16
#: Largest |m| of the rotation-equivariant family (m, 1 - m).
SINGLE_ORDER = 5
#: Largest |m| of the other families of an off-axis laser.
OFFSET_ORDER = 3
PRUNE_DEG = 1e-5
#: Rows the frequency refinement uses at most (whole firing groups, spread over the table).
SUBSAMPLE_ROWS = 100_000


@dataclass(frozen=True)
class RisleyFit:
    """A fitted Risley track and how well it replays the table.

    Parameters
    ----------
    params : RisleyParams
    lasers_found : int
        K from the table's step pattern (equal to ``params.lasers`` unless forced).
    rms_deg, p95_deg, max_deg : float
        Angle between every row's ray and the model's ray at the same time, degrees.
    rms_per_laser_deg : (K,) float64
    seconds : float
        Time the fit took.
    """

    params: RisleyParams
    lasers_found: int
    rms_deg: float
    p95_deg: float
    max_deg: float
    rms_per_laser_deg: np.ndarray
    seconds: float


def series_terms(lasers: int) -> tuple[tuple[int, int], ...]:
    """The (m, l) terms fitted: the equivariant family, plus the offset families for several lasers."""
    terms = [(1, 0), (0, 1)]
    for order in range(2, SINGLE_ORDER + 1):
        terms += [(order, 1 - order), (1 - order, order)]
    if lasers > 1:
        for total in (0, 2, -1, 3):
            for m in range(-OFFSET_ORDER, OFFSET_ORDER + 1):
                if (m, total - m) not in terms:
                    terms.append((m, total - m))
    return tuple(terms)


def _solve(z: np.ndarray, t: np.ndarray, laser: np.ndarray, lasers: int, hz: tuple[float, float],
           terms: tuple[tuple[int, int], ...], regular: bool) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients ``(K, J)`` and residuals ``(n,)`` complex for given frequencies.

    ``regular``: each laser's rows are evenly spaced in time (every K-th row, or every K-th of evenly spaced
    firing groups), solved with :class:`~livox_viz.fitting.series_lsq.LaserRows`, rows at any times with
    :class:`~livox_viz.fitting.series_lsq.TimedRows`: no ``(n, J)`` design matrix is made, so memory does not
    grow with rows x terms.
    """
    coefficients = np.zeros((lasers, len(terms)), dtype=np.complex128)
    residual = np.empty_like(z)
    for k in range(lasers):
        rows = np.flatnonzero(laser == k)
        times = t[rows]
        if regular and times.size > 1:
            solver: LaserRows | TimedRows = LaserRows(z[rows], float(times[0]), float(times[1] - times[0]))
        else:  # rows with gaps, or lasers out of order: each row at its own time
            solver = TimedRows(z[rows], times)
        solution, part = solver.solve_terms(hz, terms)
        coefficients[k] = solution
        residual[rows] = part
    return coefficients, residual


def _refine(z: np.ndarray, t: np.ndarray, laser: np.ndarray, lasers: int, hz: tuple[float, float],
            terms: tuple[tuple[int, int], ...], regular: bool) -> tuple[float, float]:
    from scipy.optimize import least_squares

    def residual(values: np.ndarray) -> np.ndarray:
        _, r = _solve(z, t, laser, lasers, (values[0], values[1]), terms, regular)
        return np.concatenate([r.real, r.imag])

    span = float(t[-1] - t[0]) if t.size > 1 else 1.0
    result = least_squares(residual, np.array(hz), x_scale=np.full(2, 0.05 / span), method="lm",
                           diff_step=np.full(2, 1e-9), xtol=1e-14, ftol=1e-14)
    return float(result.x[0]), float(result.x[1])


def fit_risley(table: ReferencePattern, beams: int | None = None) -> RisleyFit:
    """Fit a Risley track to a scan table (sample k fires at k / rate, laser k mod K).

    Parameters
    ----------
    table : ReferencePattern
    beams : int, optional
        Force the number of lasers K.

    Raises
    ------
    LivoxVizError
        For a table too short to tell the prisms apart, or a bad ``beams``.
    """
    import scipy.linalg  # noqa: F401  (loaded before the pin: its own OpenBLAS is pinned with numpy's)

    with one_blas_thread():  # many small products: one thread is several times faster than OpenBLAS's spinning
        return _fit_risley(table, beams)


def _fit_risley(table: ReferencePattern, beams: int | None) -> RisleyFit:
    start = time.perf_counter()
    if table.plane != "boresight":
        raise LivoxVizError(f"{table.name}: its rays go all around the sensor; a two-prism head looks one way "
                            "(fit it with --model track)")
    z = table.xy_deg[:, 0] + 1j * table.xy_deg[:, 1]
    if z.size < 1000:
        raise LivoxVizError(f"{table.name}: {z.size} rows; allowed: at least 1000 (two turns of the slower prism)")
    if not np.all(np.isfinite(z)):
        raise LivoxVizError(f"{table.name}: holds NaN or infinite angles; allowed: finite numbers")
    table.require_a_scan()
    if beams is not None and not 1 <= beams <= MAX_LASERS:
        raise LivoxVizError(f"--beams {beams}; allowed: 1 to {MAX_LASERS}")
    slots = table.slots
    assignment = assign_lasers(z, slots, beams)
    found, lasers, laser = assignment.found, assignment.lasers, assignment.labels
    rate = table.rate
    # Each row at its own time, or, for rows listed in groups in no fixed order, at its group's.
    slots = assignment.slots
    t = slots / rate if assignment.grouped else np.asarray(table.t, dtype=np.float64)
    first = laser == 0
    peaks = spectral_peaks(even_series(z[first], slots[first], lasers), rate / lasers, 2)
    if len(peaks) < 2:
        raise LivoxVizError(f"{table.name}: found fewer than two rotating lines; is it a Risley scan?")
    (f1, a1), (f2, a2) = peaks
    swings = abs(f1 + f2) < 4.0 / table.seconds
    if swings and table.seconds * min(abs(f1), abs(f2)) >= 4.0:
        raise LivoxVizError(f"{table.name}: its strongest lines are at +{abs(f1):.4g} and -{abs(f1):.4g} Hz, a part "
                            "that swings rather than two prisms that turn; fit it with --model track")
    if swings:
        raise LivoxVizError(f"{table.name}: {table.seconds:.4g} s of data; allowed: at least two periods of the slower "
                            "beat (the spectrum's two strongest lines are not yet apart)")
    if (f1 > 0) == (f2 > 0):
        hz = (f1, f2) if a1 >= a2 else (f2, f1)
    else:
        hz = (f1, f2) if f1 > 0 else (f2, f1)
    slowest = min(abs(hz[0]), abs(hz[1]), abs(hz[0] + hz[1]))
    if table.seconds < 2.0 / slowest:
        raise LivoxVizError(f"{table.name}: {table.seconds:.4g} s of data; allowed: at least two periods of the "
                            f"slower beat ({2.0 / slowest:.4g} s at {slowest:.4g} Hz)")
    # Frequencies on whole firing groups spread over the table (the same precision per period, far less
    # time); the coefficients on every row.
    groups = max(1, z.size // (SUBSAMPLE_ROWS if lasers == 1 else SUBSAMPLE_ROWS // 2))
    sub = np.flatnonzero((slots // lasers) % groups == 0)
    terms = series_terms(lasers)
    first_terms = terms[:2] + (((0, 0),) if lasers > 1 else ())
    regular = assignment.in_order and table.consecutive
    hz = _refine(z[sub], t[sub], laser[sub], lasers, hz, first_terms, regular)
    hz = _refine(z[sub], t[sub], laser[sub], lasers, hz, terms, regular)
    coefficients, _ = _solve(z, t, laser, lasers, hz, terms, regular)
    keep = np.abs(coefficients).max(axis=0) >= PRUNE_DEG
    keep[:2] = True
    terms = tuple(term for term, kept in zip(terms, keep, strict=True) if kept)
    coefficients, residual = _solve(z, t, laser, lasers, hz, terms, regular)
    distance = np.abs(residual)
    means = np.array([z[laser == k].mean() for k in range(lasers)])
    spread = math.sqrt(float(np.mean(np.abs(z - means[laser]) ** 2)))
    error = math.sqrt(float(np.mean(distance**2)))
    if error > NO_TRACK_FRACTION * spread or max(abs(hz[0]), abs(hz[1])) > MAX_PRISM_HZ:
        forced = beams is not None and beams != found
        told = f" (--beams {beams}; the rows' geometry says {found})" if forced else ""
        advice = (f"leave out --beams (the rows' geometry says {found})" if forced
                  else "noise, rows of two heads, or another head: try --model track")
        raise LivoxVizError(f"{table.name}: no periodic scan track of two prisms in it: {lasers} "
                            f"laser{'s' if lasers > 1 else ''}{told}, prisms at {hz[0]:+.5g} and {hz[1]:+.5g} Hz; "
                            f"the best leaves {error:.3g} deg rms of the rows' {spread:.3g} deg spread; {advice}")
    # Phases that make laser 0's prism terms real and positive.
    a0, b0 = float(np.angle(coefficients[0, 0])), float(np.angle(coefficients[0, 1]))
    shift = np.exp(-1j * np.array([m * a0 + n * b0 for m, n in terms]))
    params = RisleyParams(prism_hz=hz, phase_rad=(a0, b0), terms=terms, base_coefficients=coefficients * shift)
    # What is reported is the angle between each row's ray and the model's (as ``compare`` and the README say),
    # not the fit's own distance in the pattern plane (which differs from it by up to 0.6 % at 35 deg off axis).
    table_xy = np.column_stack([z.real, z.imag])
    model_xy = table_xy - np.column_stack([residual.real, residual.imag])
    angle = _angles_deg(table_xy, model_xy)
    per_laser = np.array([math.sqrt(float(np.mean(angle[laser == k] ** 2))) for k in range(lasers)])
    return RisleyFit(params, found, math.sqrt(float(np.mean(angle**2))), float(np.percentile(angle, 95)),
                     float(angle.max()), per_laser, time.perf_counter() - start)


def _angles_deg(xy_a: np.ndarray, xy_b: np.ndarray, plane: str = "boresight") -> np.ndarray:
    """Sample-for-sample angle between the rays at pattern angles ``xy_a`` and ``xy_b`` ``(n, 2)``, degrees ``(n,)``,
    in parts of 200 000 rows (the rays' arrays of a whole table at once took hundreds of MB)."""
    if not len(xy_a):
        return np.zeros(1)
    return np.concatenate([angle_between_deg(xy_a[s : s + 200_000], xy_b[s : s + 200_000], plane)
                           for s in range(0, len(xy_a), 200_000)])


def track_residual(xy_a: np.ndarray, xy_b: np.ndarray, plane: str = "boresight") -> tuple[float, float, float]:
    """Sample-for-sample angle between the rays of two tracks of the same length: (rms, p95, max) degrees.

    Parameters
    ----------
    xy_a, xy_b : (n, 2) float64
        Pattern angles in ``plane``.
    plane : {"boresight", "panorama"}
    """
    distance = _angles_deg(xy_a, xy_b, plane)
    return (math.sqrt(float(np.mean(distance**2))), float(np.percentile(distance, 95)), float(distance.max()))
