"""Fitting the general track model to any scan table: lasers, base frequencies, form, terms, coefficients.

Nothing here knows a sensor by name; every step reads the table:

1. **Plane and form.** A table whose rays go all around is in the panorama
   plane (:mod:`~livox_viz.patterns.planes`); if its azimuth turns steadily
   (two turns or more over the table) the track is a ``"spin"``: azimuth =
   degrees(A(t)) + a series, elevation = a series, with A's rate first read
   off the azimuth's slope. Otherwise the track is a ``"plane"`` series.
2. **Lasers.** Each row's laser from the rows' geometry
   (:func:`~livox_viz.fitting.lasers.assign_lasers`): the K lasers followed as
   K tracks through the rows, which may be out of laser order, have gaps or
   be cut anywhere (each row at its own time, ``table.t``); ``beams`` forces K.
3. **Base frequencies.** The strongest lines of laser 0's spectrum are
   explained as m f_A + l f_B with small integers of either sign
   (:mod:`~livox_viz.fitting.spectrum`).
4. **Refinement.** Variable projection: for trial frequencies the
   coefficients are linear least squares (:mod:`~livox_viz.fitting.series_lsq`:
   Gram matrix in closed form for every firing of a laser in order, separable
   sums for rows at any times), and ``scipy.optimize.least_squares`` moves
   the frequencies to the smallest residual, on evenly strided rows.
5. **Terms.** A box of orders |m| <= M_A, |l| <= M_B (terms the table cannot
   tell apart, closer than 1 / duration, dropped) grows along each axis
   while its outer layer still holds energy, until the residual is under the
   tolerance; then the weakest terms are pruned as long as the residual they
   leave stays within the tolerance, and the rest solved again on every row.
   Every budget is a count (orders :data:`MAX_BOX`, terms :data:`MAX_BOX_TERMS`
   and the preset's :data:`~livox_viz.config.track_params.MAX_TERMS`, the
   refinement's evaluations), never a time: the same table and options give
   the same track bit for bit whatever the machine's load, and a budget that
   stops the fit short of its tolerance is named in :attr:`TrackFit.budget_notes`.
6. **Report.** The residual is the angle between each row's ray and the
   model's ray at the same time (rms, p95, max, per laser). A table the model
   cannot follow (a residual over 5 % of how far the table moves: noise, rows
   of two heads, a wrong ``beams``) is refused in one line that says what the
   fit found (lasers, frequencies, the residual reached, where it failed) and
   what to try. Rows whose laser the geometry got wrong (a few in 10^5 out of
   laser order) are given to the laser whose track passes nearest, and the
   coefficients solved again.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from livox_viz.config.fov import FieldOfView
from livox_viz.config.track_params import MAX_TERMS, TrackParams
from livox_viz.core.blas import one_blas_thread
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.lasers import MAX_LASERS, LaserAssignment, assign_lasers, even_series, find_lasers
from livox_viz.fitting.series_lsq import LaserRows, TimedRows, resolvable, rms
from livox_viz.fitting.spectrum import PEAKS, BaseChoice, _normalise, choose_base, spectral_peaks
from livox_viz.fitting.table import ReferencePattern
from livox_viz.patterns.planes import angle_between_deg, directions_from_xy

__all__ = ["DEFAULT_TOLERANCE_DEG", "MAX_LASERS", "BaseChoice", "TrackFit", "_normalise", "choose_base",
           "find_lasers", "fit_track", "spectral_peaks"]

#: Residual the pruning keeps to by default, degrees rms (a tenth of the 0.01 deg goal).
DEFAULT_TOLERANCE_DEG = 1e-3
#: Largest order the term box grows to along each axis.
MAX_BOX = 24
#: Rows (all lasers) the refinement and the box growth use at most, evenly strided.
REFINE_ROWS = 48_000
GROWTH_ROWS = 240_000
#: A residual over this fraction of the table's own spread means there is no track in it.
NO_TRACK_FRACTION = 0.05
#: Growing the box stops when it no longer cuts the residual by 15 %.
FLOOR_GAIN = 0.85
#: Most terms the growing box may hold (its solves stay within the fit's 30 s on 2 cores).
MAX_BOX_TERMS = 4 * MAX_TERMS
#: Residual evaluations the frequency refinement may spend.
REFINE_EVALUATIONS = 60
#: The smallest --tolerance (deg rms): a track is computed to about 1e-9 deg.
MIN_TOLERANCE_DEG = 1e-6
#: A row this many times the typical distance off its laser's track is offered to the other lasers.
RELABEL_FACTOR = 8.0
#: Rounds of moving rows to the laser whose track passes nearest.
RELABEL_ROUNDS = 3
#: The public exports' length, seconds: a table without a rate is taken as at most this long.
EXPORT_SECONDS = 4.0
#: Livox's published point rates (Mid-40/70, Mid-360, Horizon/Avia/Tele-15, HAP), rows per second: preferred
#: among the rates a spectrum allows.
LIVOX_RATES = (100_000.0, 200_000.0, 240_000.0, 452_000.0)
#: Largest rate read off a spectrum, rows per second, and largest rpm a whole-rpm ratio may need.
MAX_SPECTRUM_RATE = 2_000_000.0
MAX_WHOLE_RPM = 20_000
#: Relative closeness that counts as whole (rpm ratio, thousands of rows per second), at least and at most: a
#: random pair of frequencies passes the loosest one in a few trials in a thousand.
MIN_WHOLE_TOLERANCE = 1e-12
MAX_WHOLE_TOLERANCE = 2e-6


@dataclass(frozen=True)
class TrackFit:
    """A fitted track and how well it replays the table.

    Parameters
    ----------
    params : TrackParams
    field_of_view : FieldOfView
        What the table's rays fill (a cone, an outline or a band).
    lasers_found : int
        K from the table's step pattern (equal to ``params.lasers`` unless forced).
    rms_deg, p95_deg, max_deg : float
        Angle between every row's ray and the model's ray at the same time, degrees.
    rms_per_laser_deg : (K,) float64
    spread_deg : float
        How far the table's rows move: rms angle between each row's ray and its laser's mean ray, degrees.
    seconds : float
        Time the fit took (reported only: nothing in the fit reads the clock).
    budget_notes : tuple of str
        Each budget that stopped the fit short of its tolerance, and by how much (empty when none did).
    in_order : bool
        Whether the lasers fired in one fixed order (row at slot s is laser s mod K).
    relabelled : int
        Rows the geometry had given to another laser, moved to the laser whose track passes nearest.
    grouped : bool
        Whether the rows were listed in groups of K in no fixed order, each fitted at its group's time.
    """

    params: TrackParams
    field_of_view: FieldOfView
    lasers_found: int
    rms_deg: float
    p95_deg: float
    max_deg: float
    rms_per_laser_deg: np.ndarray
    spread_deg: float
    seconds: float
    budget_notes: tuple[str, ...] = ()
    in_order: bool = True
    relabelled: int = 0
    grouped: bool = False



# The rows, laser by laser -----------------------------------------------------------------------------------
@dataclass
class _Signals:
    """Each laser's rows as complex signals (x + iy, or for a spin the azimuth less the turn) at their times.

    ``regular``: every firing of each laser in one fixed order, so laser k's rows are ``dt`` apart (the Gram
    matrix in closed form); otherwise each row is taken at its own time. ``index`` holds each laser's rows'
    places in the table.
    """

    x: list[np.ndarray]
    y: list[np.ndarray]
    t: list[np.ndarray]
    index: list[np.ndarray]
    dt: float
    regular: bool

    def lasers(self, spin_hz: float, stride: int = 1) -> list[LaserRows | TimedRows]:
        out: list[LaserRows | TimedRows] = []
        for x, y, t in zip(self.x, self.y, self.t, strict=True):
            xs, ys, ts = x[::stride], y[::stride], t[::stride]
            if spin_hz:
                xs = xs - 360.0 * spin_hz * ts
            z = xs + 1j * ys
            out.append(LaserRows(z, float(ts[0]), self.dt * stride) if self.regular else TimedRows(z, ts))
        return out

    @property
    def rows(self) -> int:
        return sum(x.size for x in self.x)

    @property
    def span(self) -> float:
        """Seconds from the first row to the last, of the laser with the shortest span."""
        return min(float(t[-1] - t[0]) for t in self.t)


def _signals(table: ReferencePattern, assignment: LaserAssignment, panorama: bool) -> _Signals:
    """The table's rows split by laser (every firing in order: K evenly spaced series of equal length)."""
    xy = np.asarray(table.xy_deg, dtype=np.float64)
    lasers = assignment.lasers
    regular = assignment.in_order and table.consecutive
    if regular:
        per_laser = xy.shape[0] // lasers
        places = [np.arange(k, k + lasers * per_laser, lasers) for k in range(lasers)]
    else:
        places = [np.flatnonzero(assignment.labels == k) for k in range(lasers)]
    fewest = min(p.size for p in places)
    if fewest < 16:
        k = min(range(lasers), key=lambda k: places[k].size)
        raise _Refusal(f"laser {k} of {lasers} has {fewest} rows", "the lasers")
    x = [np.unwrap(xy[p, 0], period=360.0) if panorama else xy[p, 0].copy() for p in places]
    y = [xy[p, 1].copy() for p in places]
    if regular:
        t = [(k + lasers * np.arange(p.size, dtype=np.float64)) / table.rate for k, p in enumerate(places)]
        dt = lasers / table.rate
    else:
        # Each row at its own time, or, for rows listed in groups in no fixed order, at its group's.
        times = (assignment.slots / table.rate) if assignment.grouped else np.asarray(table.t, dtype=np.float64)
        t = [times[p] for p in places]
        dt = float(np.median([(tk[-1] - tk[0]) / (tk.size - 1) for tk in t]))
    return _Signals(x, y, t, places, dt, regular)


def _even_signal(signals: _Signals, spin_hz: float, rate: float, lasers: int) -> tuple[np.ndarray, float]:
    """Laser 0's rows as an evenly spaced series for its spectrum, and their spacing (seconds)."""
    rows = signals.lasers(spin_hz)[0]
    if signals.regular:
        return rows.z, signals.dt
    return even_series(rows.z, np.rint(signals.t[0] * rate).astype(np.int64), lasers), lasers / rate


# The fit ------------------------------------------------------------------------------------------------------
class _Refusal(Exception):
    """A table with no track in it: what was found (``detail``) and at which step (``stage``)."""

    def __init__(self, detail: str, stage: str) -> None:
        super().__init__(detail)
        self.detail = detail
        self.stage = stage


def _terms_box(reach_a: int, reach_b: int) -> list[tuple[int, int]]:
    return [(m, n) for m in range(-reach_a, reach_a + 1) for n in range(-reach_b, reach_b + 1)]


def _term_hz(terms: Sequence[tuple[int, int]], hz: tuple[float, float]) -> np.ndarray:
    return np.array([m * hz[0] + n * hz[1] for m, n in terms], dtype=np.float64)


def _solve_all(lasers: list[LaserRows | TimedRows], hz: tuple[float, float], terms: Sequence[tuple[int, int]],
               residual: bool = True) -> tuple[np.ndarray, list[np.ndarray]]:
    coefficients, residuals = [], []
    for laser in lasers:
        c, r = laser.solve_terms(hz, terms, residual)
        coefficients.append(c)
        residuals.append(r)
    return np.array(coefficients), residuals


def _refine(make_lasers: Callable[[float], list[LaserRows | TimedRows]], hz: tuple[float, float],
            terms: list[tuple[int, int]], span: float, spin: bool
            ) -> tuple[tuple[float, float], str | None, tuple[float, float]]:
    """Variable projection over the base frequencies (f_B held at 0 for one frequency).

    Returns the frequencies, a note when the evaluation budget ran out before the steps converged (else None),
    and each frequency's standard error (Hz) as the residual's scatter makes it.
    """
    from scipy.optimize import least_squares

    one = hz[1] == 0.0

    def residual(values: np.ndarray) -> np.ndarray:
        trial = (float(values[0]), 0.0 if one else float(values[1]))
        _, parts = _solve_all(make_lasers(trial[0] if spin else 0.0), trial, terms)
        joined = np.concatenate(parts)
        return np.concatenate([joined.real, joined.imag])

    start = np.array(hz[:1] if one else hz)
    result = least_squares(residual, start, x_scale=np.full(start.size, 0.05 / span), method="lm",
                           diff_step=np.full(start.size, 1e-9), xtol=1e-14, ftol=1e-14,
                           max_nfev=REFINE_EVALUATIONS)
    note = None
    if result.status == 0:  # the evaluation budget, not a convergence test, ended it
        note = (f"the frequency refinement used its {REFINE_EVALUATIONS} evaluations before converging "
                f"(its residual {rms(result.fun):.3g} deg on the refinement's rows)")
    jacobian = np.atleast_2d(result.jac)
    scatter = float(np.sum(result.fun**2)) / max(1, result.fun.size - start.size)
    try:
        sigma = np.sqrt(np.abs(np.diag(np.linalg.inv(jacobian.T @ jacobian))) * scatter)
    except np.linalg.LinAlgError:
        sigma = np.full(start.size, np.inf)
    errors = (float(sigma[0]), 0.0 if one else float(sigma[1]))
    return (float(result.x[0]), 0.0 if one else float(result.x[1])), note, errors


def fit_track(table: ReferencePattern, beams: int | None = None,
              tolerance_deg: float = DEFAULT_TOLERANCE_DEG) -> TrackFit:
    """Fit the general track model to a scan table (each row at its time ``table.t``, its laser from the geometry).

    Its products are many and small (Gram matrices of a few hundred terms, blocks of 2048 rows): they run on
    one BLAS thread (:func:`~livox_viz.core.blas.one_blas_thread`), 10 x faster on the 2-core machine than
    OpenBLAS's spinning threads.

    Parameters
    ----------
    table : ReferencePattern
    beams : int, optional
        Force the number of lasers K.
    tolerance_deg : float
        Residual (rms, degrees) the term pruning keeps to.

    Raises
    ------
    LivoxVizError
        A table too short, a bad ``beams``, or a table with no periodic track in it (the message says what the
        fit found and what to try).
    """
    import scipy.linalg  # noqa: F401  (loaded before the pin: its own OpenBLAS is pinned with numpy's)

    with one_blas_thread():
        return _fit_track(table, beams, tolerance_deg)


def _fit_track(table: ReferencePattern, beams: int | None, tolerance_deg: float) -> TrackFit:
    started = time.perf_counter()
    xy = np.asarray(table.xy_deg, dtype=np.float64)
    rows = xy.shape[0]
    if rows < 1000:
        raise LivoxVizError(f"{table.name}: {rows} rows; allowed: at least 1000 (two turns of the slowest part)")
    if not np.all(np.isfinite(xy)):
        raise LivoxVizError(f"{table.name}: holds NaN or infinite angles; allowed: finite numbers")
    table.require_a_scan()
    if beams is not None and not 1 <= beams <= MAX_LASERS:
        raise LivoxVizError(f"--beams {beams}; allowed: 1 to {MAX_LASERS}")
    if not MIN_TOLERANCE_DEG <= tolerance_deg <= 1.0:
        raise LivoxVizError(f"--tolerance {tolerance_deg:g} deg; allowed: {MIN_TOLERANCE_DEG:g} to 1 deg rms")
    plane = table.plane
    panorama = plane == "panorama"
    order_x = np.unwrap(xy[:, 0], period=360.0) if panorama else xy[:, 0]
    assignment = assign_lasers(order_x + 1j * xy[:, 1], table.slots, beams)
    found: dict[str, object] = {"assignment": assignment}
    try:
        return _fit_assigned(table, assignment, tolerance_deg, started, found)
    except _Refusal as refusal:
        raise LivoxVizError(_refusal_message(table, beams, found, refusal)) from None


@dataclass
class _Bases:
    """What the first steps find: the rows by laser, the base frequencies, the first box of terms."""

    signals: _Signals
    assignment: LaserAssignment
    span: float
    spin: bool
    spin_hz: float
    hz: tuple[float, float]
    reach: tuple[int, int]
    notes: list[str]
    moved: int
    spread: float
    spread_deg: float
    hz_error: tuple[float, float]


def _bases(table: ReferencePattern, assignment: LaserAssignment, found: dict[str, object]) -> _Bases:
    """Rows by laser, the base frequencies off laser 0's spectrum refined by variable projection, the first box;
    ``found`` collects what the steps find, for a refusal's message."""
    plane = table.plane
    panorama = plane == "panorama"
    lasers = assignment.lasers
    signals = _signals(table, assignment, panorama)
    span = signals.span
    spin_hz = _spin_rate(signals) if panorama else 0.0
    spin = spin_hz != 0.0
    spread = _spread(signals, spin_hz)
    spread_deg = _spread_deg(signals, plane)
    found["spread_deg"] = spread_deg

    # Base frequencies from laser 0's spectrum.
    even, spacing = _even_signal(signals, spin_hz, table.rate, lasers)
    peaks = spectral_peaks(even, 1.0 / spacing, PEAKS)
    found["peaks"] = [f for f, _ in peaks[:3]]
    try:
        choice = choose_base(peaks, 1.0 / span, spin_hz if spin else None)
    except LivoxVizError as exc:
        raise _Refusal(str(exc), "the base frequencies") from None
    hz = choice.hz
    found["hz"] = hz
    slowest = min(abs(f) for f in hz if f != 0)
    if span < 2.0 / slowest:
        raise LivoxVizError(f"{table.name}: {table.seconds:.4g} s of data; allowed: at least two periods of the "
                            f"slowest base frequency ({2.0 / slowest:.4g} s at {slowest:.4g} Hz)")

    # Refine the frequencies on a few rows with the terms the lines asked for.
    reach_a = max(2, max(abs(m) for m, _ in choice.orders) + 1)
    reach_b = 0 if hz[1] == 0 else max(2, max(abs(n) for _, n in choice.orders) + 1)
    separation = 1.0 / span
    refine_stride = _stride(signals.rows, REFINE_ROWS, signals.dt, _term_hz(_terms_box(reach_a, reach_b), hz))
    terms = _resolvable_box(reach_a, reach_b, hz, separation)
    hz, refine_note, hz_error = _refine(lambda s: signals.lasers(s, refine_stride), hz, terms, span, spin)
    found["hz"] = hz
    notes = [refine_note] if refine_note else []
    spin_hz = hz[0] if spin else 0.0
    # A track the first terms cannot begin to follow is no track: said now, before any work on every row.
    strided = signals.lasers(spin_hz, refine_stride)
    _, residuals = _solve_all(strided, hz, terms)
    if rms(np.concatenate(residuals)) > 0.3 * spread:
        found["error_deg"] = _angle_rms(strided, residuals, plane)
        found["terms"] = len(terms)
        raise _Refusal("", "the base frequencies' first terms")
    moved = 0
    if not signals.regular:  # rows the geometry gave to the wrong laser would hold the growth at their distance
        signals, assignment, moved, _ = _settle(table, signals, assignment, hz, terms, spin_hz)
    return _Bases(signals, assignment, span, spin, spin_hz, hz, (reach_a, reach_b), notes, moved, spread, spread_deg,
                  hz_error)


def _fit_assigned(table: ReferencePattern, assignment: LaserAssignment, tolerance_deg: float, started: float,
                  found: dict[str, object]) -> TrackFit:
    """The fit once each row has its laser; ``found`` collects what the steps find, for a refusal's message."""
    plane = table.plane
    bases = _bases(table, assignment, found)
    signals, assignment, span, spin, spin_hz = bases.signals, bases.assignment, bases.span, bases.spin, bases.spin_hz
    hz, (reach_a, reach_b), notes, moved, spread = bases.hz, bases.reach, bases.notes, bases.moved, bases.spread
    spread_deg = bases.spread_deg
    separation = 1.0 / span

    # Grow the box on more rows until the residual is within the tolerance, or growing stops paying (the
    # table's own noise floor: a table printed to 0.01 deg cannot be followed closer than about 0.003 deg).
    previous = math.inf
    while True:
        box_hz = _term_hz(_terms_box(reach_a, reach_b), hz)
        stride = _stride(signals.rows, GROWTH_ROWS, signals.dt, box_hz)
        terms = _resolvable_box(reach_a, reach_b, hz, separation)
        strided = signals.lasers(spin_hz, stride)
        coefficients, residuals = _solve_all(strided, hz, terms)
        error = rms(np.concatenate(residuals))
        if error > 0.3 * spread:
            found["error_deg"] = _angle_rms(strided, residuals, plane)
            found["terms"] = len(terms)
            raise _Refusal("", "the terms")
        if error <= tolerance_deg / 2 or error > FLOOR_GAIN * previous:
            break
        previous = error
        energy = np.mean(np.abs(coefficients) ** 2, axis=0)
        edge_a = math.sqrt(sum(e for (m, _), e in zip(terms, energy, strict=True) if abs(m) == reach_a))
        edge_b = math.sqrt(sum(e for (_, n), e in zip(terms, energy, strict=True) if abs(n) == reach_b))
        grow_a = edge_a > tolerance_deg / 8
        grow_b = hz[1] != 0 and edge_b > tolerance_deg / 8
        next_a = reach_a + 2 if grow_a and reach_a < MAX_BOX else reach_a
        next_b = reach_b + 2 if grow_b and reach_b < MAX_BOX else reach_b
        capped = (grow_a and reach_a >= MAX_BOX) or (grow_b and reach_b >= MAX_BOX)
        if (2 * next_a + 1) * (2 * next_b + 1) > MAX_BOX_TERMS:
            next_a, next_b, capped = reach_a, reach_b, True
        if (next_a, next_b) == (reach_a, reach_b) and capped and error > tolerance_deg:
            notes.append(f"the term box stopped at |m| <= {reach_a}, |l| <= {reach_b} ({len(terms)} terms; budget: "
                         f"orders up to {MAX_BOX}, {MAX_BOX_TERMS} terms) with {error:.3g} deg rms on the growth's "
                         f"rows, {error / tolerance_deg:.3g} x the tolerance {tolerance_deg:g} deg")
        if (next_a, next_b) == (reach_a, reach_b):
            break
        reach_a, reach_b = next_a, next_b

    # Prune the weakest terms while the residual they leave stays within the tolerance (or within 10 % of
    # the noise floor, when the table does not allow the tolerance).
    energy = np.mean(np.abs(coefficients) ** 2, axis=0)
    order = np.argsort(energy)
    allowance = max(tolerance_deg, 1.1 * error) ** 2 - error**2
    dropped = np.cumsum(energy[order]) <= allowance
    keep = np.ones(len(terms), dtype=bool)
    keep[order[dropped]] = False
    if keep.sum() > MAX_TERMS:
        left_out = math.sqrt(error**2 + float(np.sum(energy[order[:-MAX_TERMS]])))
        notes.append(f"kept the {MAX_TERMS} strongest of {int(keep.sum())} terms (a preset's limit): about "
                     f"{left_out:.3g} deg rms where the tolerance asked {tolerance_deg:g} deg")
        keep[:] = False
        keep[order[-MAX_TERMS:]] = True
    terms = [term for term, kept in zip(terms, keep, strict=True) if kept]
    found["terms"] = len(terms)
    if signals.regular:
        every_row = signals.lasers(spin_hz)
        coefficients, residuals = _solve_all(every_row, hz, terms)
    else:
        signals, assignment, more, (every_row, coefficients, residuals) = _settle(table, signals, assignment, hz,
                                                                                  terms, spin_hz)
        moved += more
    params = TrackParams(form="spin" if spin else "plane", base_hz=hz, phase_rad=(0.0, 0.0), terms=tuple(terms),
                         coefficients=coefficients)

    # The residual as the angle between each row's ray and the model's, laser by laser.
    distances = _angles(every_row, residuals, plane)
    per = np.array([math.sqrt(float(np.mean(d**2))) for d in distances])
    distance = np.concatenate(distances)
    total = math.sqrt(float(np.mean(distance**2)))
    if total > NO_TRACK_FRACTION * spread_deg:
        found["error_deg"] = total
        raise _Refusal("", "the last solve")
    return TrackFit(params, FieldOfView.of_points(table.xy_deg, plane), assignment.found, total,
                    float(np.percentile(distance, 95)), float(distance.max()), per, spread_deg,
                    time.perf_counter() - started, tuple(notes), assignment.in_order, moved, assignment.grouped)


def _settle(table: ReferencePattern, signals: _Signals, assignment: LaserAssignment, hz: tuple[float, float],
            terms: Sequence[tuple[int, int]], spin_hz: float) -> tuple[_Signals, LaserAssignment, int, tuple]:
    """Solve on every row and move rows far off their laser's track to the nearest laser, until none moves (at
    most :data:`RELABEL_ROUNDS` rounds); returns the signals, the assignment, the rows moved and the last solve
    (rows, coefficients, residuals)."""
    moved = 0
    for round_ in range(RELABEL_ROUNDS + 1):
        every_row = signals.lasers(spin_hz)
        coefficients, residuals = _solve_all(every_row, hz, terms)
        if round_ == RELABEL_ROUNDS:
            break
        labels, count = _relabel(signals, assignment.labels, every_row, residuals, coefficients, hz, terms)
        if not count:
            break
        moved += count
        assignment = LaserAssignment(assignment.lasers, assignment.found, labels, False,
                                     assignment.prediction_error_deg, assignment.slots, assignment.grouped)
        signals = _signals(table, assignment, table.plane == "panorama")
    return signals, assignment, moved, (every_row, coefficients, residuals)


def _relabel(signals: _Signals, labels: np.ndarray, every_row: list[LaserRows | TimedRows],
             residuals: list[np.ndarray], coefficients: np.ndarray, hz: tuple[float, float],
             terms: Sequence[tuple[int, int]]) -> tuple[np.ndarray, int]:
    """Rows far off their laser's track given to the laser whose track passes nearest; (labels, rows moved)."""
    distance = [np.abs(r) for r in residuals]
    joined = np.concatenate(distance)
    typical = math.sqrt(float(np.mean(np.minimum(joined, np.percentile(joined, 99.9)) ** 2)))
    suspects = [np.flatnonzero(d > RELABEL_FACTOR * typical) for d in distance]
    if not any(s.size for s in suspects):
        return labels, 0
    z = np.concatenate([rows.z[s] for rows, s in zip(every_row, suspects, strict=True)])
    t = np.concatenate([signals.t[k][s] for k, s in enumerate(suspects)])
    places = np.concatenate([signals.index[k][s] for k, s in enumerate(suspects)])
    current = np.concatenate([np.full(s.size, k) for k, s in enumerate(suspects)])
    timed = TimedRows(z, t)
    # Every laser's model at the suspects' times (a spin's turn is the same for every laser, already taken out).
    off = np.array([np.abs(z - timed.model(hz, terms, c)) for c in coefficients])
    nearest = off.argmin(axis=0)
    move = nearest != current
    labels = labels.copy()
    labels[places[move]] = nearest[move]
    return labels, int(move.sum())


def _angles(lasers: list[LaserRows | TimedRows], residuals: list[np.ndarray], plane: str) -> list[np.ndarray]:
    """Per laser, the angle between each row's ray and the model's ray (degrees).

    A spin's turn was taken out of both alike, which leaves the angle between them as it is.
    """
    out = []
    for rows, residual in zip(lasers, residuals, strict=True):
        measured = np.column_stack([rows.z.real, rows.z.imag])
        model = measured - np.column_stack([residual.real, residual.imag])
        out.append(angle_between_deg(model, measured, plane))
    return out


def _angle_rms(lasers: list[LaserRows | TimedRows], residuals: list[np.ndarray], plane: str) -> float:
    return math.sqrt(float(np.mean(np.concatenate(_angles(lasers, residuals, plane)) ** 2)))


def _spread(signals: _Signals, spin_hz: float) -> float:
    """Rms distance of the rows from their laser's mean, degrees of the plane (a spin's turn taken out)."""
    stride = max(1, min(x.size for x in signals.x) // 20_000)
    return rms(np.concatenate([(rows.z - rows.z.mean()) for rows in signals.lasers(spin_hz, stride)]))


def _spread_deg(signals: _Signals, plane: str) -> float:
    """Rms angle between each row's ray and its laser's mean ray, degrees: how far the table moves."""
    stride = max(1, min(x.size for x in signals.x) // 20_000)
    angles = []
    for x, y in zip(signals.x, signals.y, strict=True):
        rays = directions_from_xy(np.column_stack([x[::stride], y[::stride]]), plane)
        mean = rays.mean(axis=0)
        norm = float(np.linalg.norm(mean))
        if norm < 1e-9:
            angles.append(np.full(rays.shape[0], 90.0))
            continue
        angles.append(np.degrees(np.arccos(np.clip(rays @ (mean / norm), -1.0, 1.0))))
    return math.sqrt(float(np.mean(np.concatenate(angles) ** 2)))


def _refusal_message(table: ReferencePattern, beams: int | None, found: dict[str, object],
                     refusal: _Refusal) -> str:
    """One line: what the fit found, where it failed, what to try."""
    assignment = found["assignment"]
    assert isinstance(assignment, LaserAssignment)
    parts = [f"{assignment.lasers} laser{'s' if assignment.lasers > 1 else ''}"
             + (f" (--beams {beams}; the rows' geometry says {assignment.found})"
                if beams is not None and beams != assignment.found else "")]
    hz = found.get("hz")
    if isinstance(hz, tuple):
        parts.append(f"base {hz[0]:+.5g} and {hz[1]:+.5g} Hz" if hz[1] else f"base {hz[0]:+.5g} Hz")
    elif found.get("peaks"):
        peaks = found["peaks"]
        assert isinstance(peaks, list)
        parts.append("strongest lines " + ", ".join(f"{f:+.4g}" for f in peaks) + " Hz")
    error, spread = found.get("error_deg"), found.get("spread_deg")
    if isinstance(error, float) and isinstance(spread, float):
        terms = found.get("terms")
        parts.append(f"{'with ' + str(terms) + ' terms ' if terms else ''}the best track leaves {error:.3g} deg rms "
                     f"between rays of the rows' {spread:.3g} deg ({100 * error / max(spread, 1e-300):.0f} %)")
    if refusal.detail:
        parts.append(refusal.detail)
    if beams is not None and beams != assignment.found:
        plural = "s" if assignment.found > 1 else ""
        advice = f"leave out --beams (the rows' geometry says {assignment.found} laser{plural})"
    else:
        advice = ("check that each row is one firing's angles, in time order ([theta, phi] in radians in a .npy), "
                  "from one head")
    return (f"{table.name}: no periodic scan track found: {'; '.join(parts)} (failed at {refusal.stage}); "
            f"noise, rows of two heads or rows that are not one firing each have none: {advice}")


def _spin_rate(signals: _Signals) -> float:
    """The azimuth's turn rate (Hz) if it turns two times or more over the table, else 0."""
    x = signals.x[0]
    if abs(x[-1] - x[0]) < 720.0:
        return 0.0
    slopes = [np.polyfit(t, x, 1)[0] for x, t in zip(signals.x, signals.t, strict=True)]
    return float(np.mean(slopes)) / 360.0


def _stride(total_rows: int, budget: int, dt: float, hz: np.ndarray) -> int:
    """Every how many rows of a laser to use: within ``budget`` rows, but fast enough for every term."""
    wanted = max(1, total_rows // budget)
    top = float(np.max(np.abs(hz))) if hz.size else 0.0
    nyquist_stride = max(1, int(1.0 / (2.5 * top * dt))) if top > 0 else wanted
    return max(1, min(wanted, nyquist_stride))


def _resolvable_box(reach_a: int, reach_b: int, hz: tuple[float, float], separation: float) -> list[tuple[int, int]]:
    terms = _terms_box(reach_a, reach_b)
    frequencies = _term_hz(terms, hz)
    order = np.array([abs(m) + abs(n) for m, n in terms])
    keep = resolvable(frequencies, order, separation)
    return [term for term, kept in zip(terms, keep, strict=True) if kept]


# A table's rate from its spectrum ----------------------------------------------------------------------------
def rate_from_spectrum(name: str, xy_deg: np.ndarray, plane: str, slots: np.ndarray | None = None
                       ) -> tuple[float, str]:
    """The firing rate of a table that says none, from its base frequencies; and how it was found, in words.

    A table without times gives its base frequencies in cycles per firing, nu_A and nu_B; at a rate r the parts
    turn at 60 nu r rpm. Livox's public tables come from heads whose parts turn at whole rpm (Mid-40/70 4664
    and 7294, Horizon 7352 and 619, Mid-360 10 945 and 600, Avia 2448 and 7893, Tele-15 3087 and 9837) and
    fire a whole number of thousands of times a second, so the candidates are the rates of whole thousands
    of rows per second at which both frequencies are whole rpm (nu_A / nu_B a fraction of denominator at
    most :data:`MAX_WHOLE_RPM`, within ten standard errors of the fitted frequencies). These repeat at
    multiples; the public exports last 4 s, so only candidates at least the firings over 4 s count, of which
    a published Livox rate (:data:`LIVOX_RATES`) is taken first, else the lowest; the others are named in the
    words returned.

    Parameters
    ----------
    name : str
    xy_deg : (n, 2) float64
        Pattern angles in ``plane``.
    plane : {"boresight", "panorama"}
    slots : (n,) int64, optional
        Each row's firing slot (default: consecutive rows).

    Raises
    ------
    LivoxVizError
        When no such rate exists (a track that is no whole rpm, or noise): the user is asked for ``--rate``.
    """
    import scipy.linalg  # noqa: F401  (loaded before the pin: its own OpenBLAS is pinned with numpy's)

    xy = np.asarray(xy_deg, dtype=np.float64)
    slots = np.arange(xy.shape[0], dtype=np.int64) if slots is None else np.asarray(slots, dtype=np.int64)
    # At one firing a second the table's frequencies are cycles per firing.
    per_firing = ReferencePattern(name, xy, (slots - slots[0]).astype(np.float64), 1.0, plane,
                                  "one firing a second")
    asked = "give --rate ROWS_PER_SECOND (a .npy says no rate; a CSV's Time/s or an .npz's t would)"
    try:
        with one_blas_thread():
            if xy.shape[0] < 1000 or not np.all(np.isfinite(xy)):
                raise LivoxVizError(f"{xy.shape[0]} rows; at least 1000 finite rows are needed to read it")
            per_firing.require_a_scan()
            order_x = np.unwrap(xy[:, 0], period=360.0) if plane == "panorama" else xy[:, 0]
            assignment = assign_lasers(order_x + 1j * xy[:, 1], per_firing.slots)
            found: dict[str, object] = {"assignment": assignment}
            try:
                bases = _bases(per_firing, assignment, found)
            except _Refusal as refusal:
                raise LivoxVizError(_refusal_message(per_firing, None, found, refusal)) from None
    except LivoxVizError as exc:
        raise LivoxVizError(f"{name}: no rate given, and none read off its spectrum ({exc}); {asked}") from None
    nu = bases.hz
    # Whole within what the frequencies are known to: ten standard errors (the residual is the model's, not
    # white noise), relative, of the less certain one.
    known = max(error / abs(f) for f, error in zip(nu, bases.hz_error, strict=True) if f)
    candidates = _whole_rpm_rates(nu, min(MAX_WHOLE_TOLERANCE, max(MIN_WHOLE_TOLERANCE, 10 * known)))
    least = per_firing.firings / EXPORT_SECONDS
    chosen = [r for r in candidates if r >= least * (1 - 1e-9)]
    if not chosen:
        lines = ", ".join(f"{abs(f):.6g}" for f in nu if f)
        raise LivoxVizError(f"{name}: no rate given, and its frequencies ({lines} cycles per firing) turn at whole rpm "
                            f"at no rate of whole thousands of rows/s from {least:,.0f} (its firings over "
                            f"{EXPORT_SECONDS:g} s) to {MAX_SPECTRUM_RATE:,.0f}; {asked}")
    published = [r for r in chosen if r in LIVOX_RATES]
    rate = (published or chosen)[0]
    rpm = " and ".join(f"{60 * f * rate:+.0f}" for f in nu if f)
    which = ("a published Livox rate" if published else "the lowest rate of whole thousands of rows/s")
    others = [r for r in candidates if r != rate][:3]
    also = f"; also whole at {', '.join(f'{r:,.0f}' for r in others)} rows/s (give --rate to choose)" if others else ""
    return rate, (f"read off the spectrum: {which}, at least its firings over {EXPORT_SECONDS:g} s, at which its "
                  f"parts turn at whole rpm ({rpm} rpm){also}")


def _whole_rpm_rates(nu: tuple[float, float], tolerance: float) -> list[float]:
    """Rates (whole thousands of rows/s, up to :data:`MAX_SPECTRUM_RATE`) at which every base frequency (cycles per
    firing) is a whole number of rpm, within a relative ``tolerance``, lowest first."""
    frequencies = [abs(f) for f in nu if f]
    first = frequencies[0]
    if len(frequencies) == 2:
        # The rates at which the parts turn at p and q rpm, for each fraction p / q that explains the ratio.
        units = [p / (60.0 * first) for p in _whole_ratios(first / frequencies[1], tolerance)]
    else:
        units = [1.0 / (60.0 * first)]
    rates = set()
    for unit in units:
        for multiple in range(1, int(MAX_SPECTRUM_RATE / unit) + 1):
            rate = multiple * unit
            thousands = round(rate / 1000.0)
            if thousands and abs(rate - 1000.0 * thousands) <= tolerance * rate:
                rates.add(1000.0 * thousands)
    return sorted(rates)


def _whole_ratios(ratio: float, tolerance: float) -> list[int]:
    """p of each convergent p / q of ``ratio``'s continued fraction within ``tolerance`` (relative) of it, with p
    and q at most :data:`MAX_WHOLE_RPM` (the whole-rpm pairs that explain it, simplest first)."""
    found = []
    p0, q0, p1, q1 = 0, 1, 1, 0
    rest = ratio
    for _ in range(40):
        whole = math.floor(rest)
        p0, q0, p1, q1 = p1, q1, whole * p1 + p0, whole * q1 + q0
        if p1 > MAX_WHOLE_RPM or q1 > MAX_WHOLE_RPM:
            break
        if abs(p1 / q1 - ratio) <= tolerance * ratio:
            found.append(p1)
        if rest == whole:
            break
        rest = 1.0 / (rest - whole)
    return found
