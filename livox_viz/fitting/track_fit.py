"""Fitting the general track model to any scan table: lasers, base frequencies, form, terms, coefficients.

Nothing here knows a sensor by name; every step reads the table:

1. **Plane and form.** A table whose rays go all around is in the panorama
   plane (:mod:`~livox_viz.patterns.planes`); if its azimuth turns steadily
   (two turns or more over the table) the track is a ``"spin"``: azimuth =
   degrees(A(t)) + a series, elevation = a series, with A's rate first read
   off the azimuth's slope. Otherwise the track is a ``"plane"`` series.
2. **Lasers.** K lasers fire in turn, so the row-to-row step repeats with
   period K (:func:`find_lasers`); ``beams`` forces K.
3. **Base frequencies.** The strongest lines of laser 0's spectrum (Hann
   window, zero-padded FFT, parabolic peaks) are explained as m f_A + l f_B
   with small integers of either sign: of every pair of candidates (the lines
   and their sums and differences), the one that explains the most line
   amplitude with the lowest orders wins (:func:`choose_base`). One
   frequency alone (f_B = 0) is tried too.
4. **Refinement.** Variable projection: for trial frequencies the
   coefficients are linear least squares (:mod:`~livox_viz.fitting.series_lsq`,
   Gram matrix in closed form), and ``scipy.optimize.least_squares`` moves
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
   cannot follow (a residual over 5 % of how far the table moves: noise, or
   rows in the wrong order) is refused rather than written as a preset.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from livox_viz.config.fov import FieldOfView
from livox_viz.config.track_params import MAX_TERMS, TrackParams
from livox_viz.core.blas import one_blas_thread
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.reference import ReferencePattern
from livox_viz.fitting.series_lsq import LaserRows, resolvable, rms
from livox_viz.patterns.planes import angle_between_deg

MAX_LASERS = 16
#: Residual the pruning keeps to by default, degrees rms (a tenth of the 0.01 deg goal).
DEFAULT_TOLERANCE_DEG = 1e-3
#: Spectral lines read off laser 0 for the base frequencies.
PEAKS = 16
#: Largest |m|, |l| a line may need to count as explained by a base pair.
LINE_ORDER = 8
#: Two candidate frequencies related by integers this small span a line rather than a lattice.
DEGENERATE_ORDER = 4
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
        How far the table's rows move: rms distance from each laser's mean, degrees of the plane.
    seconds : float
        Time the fit took (reported only: nothing in the fit reads the clock).
    budget_notes : tuple of str
        Each budget that stopped the fit short of its tolerance, and by how much (empty when none did).
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


# Lasers and lines -------------------------------------------------------------------------------------------
def find_lasers(z: np.ndarray, max_lasers: int = MAX_LASERS) -> int:
    """K, the number of lasers firing in turn, from the period of the row-to-row steps.

    For each candidate K the mean change between a step and the step K rows
    later is small only at the true K (and its multiples): the smallest K whose
    score is within 1.5 x the best wins.

    Parameters
    ----------
    z : (n,) complex128
        The table's points, degrees (x + iy).
    """
    steps = np.diff(z)
    scores = []
    for k in range(1, min(max_lasers, steps.size // 8) + 1):
        scores.append(float(np.mean(np.abs(steps[k:] - steps[:-k]))))
    if not scores:
        return 1
    best = min(scores)
    return next(k for k, score in enumerate(scores, start=1) if score <= 1.5 * best)


def spectral_peaks(z: np.ndarray, rate: float, count: int = 2) -> list[tuple[float, float]]:
    """The ``count`` strongest lines of a signal's spectrum away from 0 Hz: (frequency Hz, amplitude)."""
    n = z.size
    window = np.hanning(n)
    size = 1 << (math.ceil(math.log2(n)) + 2)
    spectrum = np.abs(np.fft.fft((z - z.mean()) * window, size))
    freqs = np.fft.fftfreq(size, 1.0 / rate)
    resolution = rate / n
    peaks: list[tuple[float, float]] = []
    spectrum[np.abs(freqs) < 2 * resolution] = 0.0
    for _ in range(count):
        i = int(np.argmax(spectrum))
        if spectrum[i] <= 0:
            break
        left, right = spectrum[i - 1], spectrum[(i + 1) % size]
        denominator = left - 2 * spectrum[i] + right
        shift = 0.5 * (left - right) / denominator if denominator != 0 else 0.0
        peaks.append((float(freqs[i] + shift * rate / size), float(spectrum[i] * 2 / window.sum())))
        spectrum[np.abs(freqs - freqs[i]) < 4 * resolution] = 0.0
    return peaks


@dataclass(frozen=True)
class BaseChoice:
    """Two base frequencies and how they explain the strongest lines.

    Parameters
    ----------
    hz : tuple of 2 float
        f_A, f_B (f_B = 0: one frequency).
    orders : tuple of (int, int)
        (m, l) of each explained line.
    explained : float
        Fraction of the lines' amplitude explained.
    """

    hz: tuple[float, float]
    orders: tuple[tuple[int, int], ...]
    explained: float


def _explain(freqs: np.ndarray, a: float, b: float, tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each line, the lattice point m a + l b (|m|, |l| <= LINE_ORDER) nearest it: (m, l, explained)."""
    m = np.arange(-LINE_ORDER, LINE_ORDER + 1)
    if b == 0:
        l_best = np.zeros((freqs.size, m.size))
    else:
        l_best = np.clip(np.round((freqs[:, None] - m[None, :] * a) / b), -LINE_ORDER, LINE_ORDER)
    error = np.abs(m[None, :] * a + l_best * b - freqs[:, None])
    # Among equally good lattice points prefer the lowest order.
    cost = error + 1e-9 * (np.abs(m)[None, :] + np.abs(l_best))
    pick = np.argmin(cost, axis=1)
    rows = np.arange(freqs.size)
    return m[pick], l_best[rows, pick].astype(np.int64), error[rows, pick] <= tolerance


def _degenerate(a: float, b: float, tolerance: float) -> bool:
    """Whether p a + q b = 0 for small integers, |p|, |q| <= 4: the pair spans a line, not a lattice (f and 2f).

    Relations of higher order (the Mid-360's 182.4 Hz is 18.24 x 10 Hz) leave a true lattice whose lines are
    told apart by their lowest orders.
    """
    if b == 0:
        return a == 0
    p = np.arange(-DEGENERATE_ORDER, DEGENERATE_ORDER + 1)
    q = np.round(-p * a / b)
    close = (np.abs(p * a + q * b) <= 2 * tolerance) & (np.abs(q) <= DEGENERATE_ORDER) & ((p != 0) | (q != 0))
    return bool(np.any(close))


def choose_base(peaks: list[tuple[float, float]], resolution: float, spin_hz: float | None = None) -> BaseChoice:
    """The two base frequencies that explain the strongest lines best (see the module notes).

    Parameters
    ----------
    peaks : list of (Hz, amplitude)
        Strongest first.
    resolution : float
        1 / duration, Hz.
    spin_hz : float, optional
        A spin track's turn rate: f_A is fixed to it.

    Raises
    ------
    LivoxVizError
        If no pair explains the lines (no periodic track).
    """
    if not peaks:
        raise LivoxVizError("the spectrum holds no lines; is it a scan track?")
    freqs = np.array([f for f, _ in peaks])
    amps = np.array([a for _, a in peaks])
    tolerance = 0.2 * resolution
    floor = 2 * resolution
    strong = freqs[:8]
    pool = list(strong)
    pool += [combined for i, f in enumerate(strong[:4]) for g in strong[i + 1 : 4] for combined in (f + g, f - g)]
    pool += [f / n for f in strong[:2] for n in (2, 3)]
    pool = [f for f in pool if abs(f) > floor]
    if spin_hz is not None:
        pairs = [(spin_hz, f - m * spin_hz) for f in strong for m in range(-2, 3)]
        pairs = [(a, b) for a, b in pairs if abs(b) > floor] + [(spin_hz, 0.0)]
    else:
        pairs = [(a, b) for i, a in enumerate(pool) for b in pool[i + 1 :]] + [(a, 0.0) for a in pool]
    best: tuple[float, float, BaseChoice] | None = None
    total = float(amps.sum())
    for a, b in pairs:
        if _degenerate(a, b, tolerance):
            continue
        order_a, order_b, explained = _explain(freqs, a, b, tolerance)
        share = float(amps[explained].sum()) / total
        cost = float(np.sum(amps[explained] * (np.abs(order_a) + np.abs(order_b))[explained])) / total
        choice = BaseChoice((float(a), float(b)), tuple(zip(order_a[explained].tolist(), order_b[explained].tolist(),
                                                            strict=True)), share)
        key = (share - 0.02 * cost, -cost)
        if best is None or key > best[:2]:
            best = (*key, choice)
    if best is None or best[2].explained < 0.5:
        share = 0.0 if best is None else best[2].explained
        raise LivoxVizError(f"the strongest lines of the spectrum are not combinations of two frequencies (at most "
                            f"{100 * share:.0f} % explained): no periodic scan track in this table")
    return best[2] if spin_hz is not None else _normalise(best[2])


def _normalise(choice: BaseChoice) -> BaseChoice:
    """f_A the stronger-explained positive one where the orders allow: (1, 0) before (0, 1), both signs free."""
    (a, b), orders = choice.hz, choice.orders
    if b != 0 and not any(o == (1, 0) or o == (-1, 0) for o in orders) and any(abs(m) + abs(n) == 1 and n
                                                                                 for m, n in orders):
        a, b = b, a
        orders = tuple((n, m) for m, n in orders)
    return BaseChoice((a, b), orders, choice.explained)


# The fit ------------------------------------------------------------------------------------------------------
@dataclass
class _Signals:
    """Each laser's rows as complex signals (x + iy, or for a spin the azimuth less the turn)."""

    x: list[np.ndarray]
    y: list[np.ndarray]
    t0: list[float]
    dt: float

    def lasers(self, spin_hz: float, stride: int = 1) -> list[LaserRows]:
        out = []
        for x, y, t0 in zip(self.x, self.y, self.t0, strict=True):
            xs, ys = x[::stride], y[::stride]
            if spin_hz:
                t = t0 + np.arange(xs.size) * (self.dt * stride)
                xs = xs - 360.0 * spin_hz * t
            out.append(LaserRows(xs + 1j * ys, t0, self.dt * stride))
        return out


def _terms_box(reach_a: int, reach_b: int) -> list[tuple[int, int]]:
    return [(m, n) for m in range(-reach_a, reach_a + 1) for n in range(-reach_b, reach_b + 1)]


def _term_hz(terms: list[tuple[int, int]], hz: tuple[float, float]) -> np.ndarray:
    return np.array([m * hz[0] + n * hz[1] for m, n in terms], dtype=np.float64)


def _solve_all(lasers: list[LaserRows], hz: np.ndarray, residual: bool = True
               ) -> tuple[np.ndarray, list[np.ndarray]]:
    coefficients, residuals = [], []
    for laser in lasers:
        c, r = laser.solve(hz, residual)
        coefficients.append(c)
        residuals.append(r)
    return np.array(coefficients), residuals


def _refine(make_lasers: Callable[[float], list[LaserRows]], hz: tuple[float, float],
            terms: list[tuple[int, int]], span: float, spin: bool) -> tuple[tuple[float, float], str | None]:
    """Variable projection over the base frequencies (f_B held at 0 for one frequency).

    Returns the frequencies and, when the evaluation budget ran out before the steps converged, a note that
    says how far the last step still moved them.
    """
    from scipy.optimize import least_squares

    one = hz[1] == 0.0

    def residual(values: np.ndarray) -> np.ndarray:
        trial = (float(values[0]), 0.0 if one else float(values[1]))
        _, parts = _solve_all(make_lasers(trial[0] if spin else 0.0), _term_hz(terms, trial))
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
    return (float(result.x[0]), 0.0 if one else float(result.x[1])), note


def fit_track(table: ReferencePattern, beams: int | None = None,
              tolerance_deg: float = DEFAULT_TOLERANCE_DEG) -> TrackFit:
    """Fit the general track model to a scan table (row r fires at r / rate and is laser r mod K).

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
        A table too short, a bad ``beams``, or a table with no periodic track in it.
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
    if not 1e-12 < tolerance_deg <= 1.0:
        raise LivoxVizError(f"tolerance {tolerance_deg!r} deg; allowed: (0, 1]")
    plane = table.plane
    rate = table.rate
    panorama = plane == "panorama"
    order_x = np.unwrap(xy[:, 0], period=360.0) if panorama else xy[:, 0]
    found = find_lasers((order_x + 1j * xy[:, 1])[:200_000])
    lasers = beams or found
    dt = lasers / rate
    signals = _Signals([], [], [], dt)
    for k in range(lasers):
        x = xy[k::lasers, 0]
        signals.x.append(np.unwrap(x, period=360.0) if panorama else x.copy())
        signals.y.append(xy[k::lasers, 1].copy())
        signals.t0.append(k / rate)
    per_laser = min(x.size for x in signals.x)
    signals.x = [x[:per_laser] for x in signals.x]
    signals.y = [y[:per_laser] for y in signals.y]
    span = (per_laser - 1) * dt
    spin_hz = _spin_rate(signals) if panorama else 0.0
    spin = spin_hz != 0.0

    # Base frequencies from laser 0's spectrum.
    first = signals.lasers(spin_hz)[0].z
    peaks = spectral_peaks(first, 1.0 / dt, PEAKS)
    choice = choose_base(peaks, 1.0 / span, spin_hz if spin else None)
    hz = choice.hz
    slowest = min(abs(f) for f in hz if f != 0)
    if span < 2.0 / slowest:
        raise LivoxVizError(f"{table.name}: {table.seconds:.4g} s of data; allowed: at least two periods of the "
                            f"slowest base frequency ({2.0 / slowest:.4g} s at {slowest:.4g} Hz)")
    spread = rms(np.concatenate([(lr.z - lr.z.mean()) for lr in signals.lasers(spin_hz, max(1, per_laser // 20_000))]))

    # Refine the frequencies on a few rows with the terms the lines asked for.
    reach_a = max(2, max(abs(m) for m, _ in choice.orders) + 1)
    reach_b = 0 if hz[1] == 0 else max(2, max(abs(n) for _, n in choice.orders) + 1)
    separation = 1.0 / span
    refine_stride = _stride(per_laser * lasers, REFINE_ROWS, dt, _term_hz(_terms_box(reach_a, reach_b), hz))
    terms = _resolvable_box(reach_a, reach_b, hz, separation)
    hz, refine_note = _refine(lambda s: signals.lasers(s, refine_stride), hz, terms, span, spin)
    notes = [refine_note] if refine_note else []
    spin_hz = hz[0] if spin else 0.0

    # Grow the box on more rows until the residual is within the tolerance, or growing stops paying (the
    # table's own noise floor: a table printed to 0.01 deg cannot be followed closer than about 0.003 deg).
    previous = math.inf
    while True:
        box_hz = _term_hz(_terms_box(reach_a, reach_b), hz)
        stride = _stride(per_laser * lasers, GROWTH_ROWS, dt, box_hz)
        terms = _resolvable_box(reach_a, reach_b, hz, separation)
        coefficients, residuals = _solve_all(signals.lasers(spin_hz, stride), _term_hz(terms, hz))
        error = rms(np.concatenate(residuals))
        if error > 0.3 * spread:
            _no_track(table, error, spread)
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
    every_row = signals.lasers(spin_hz)
    coefficients, residuals = _solve_all(every_row, _term_hz(terms, hz))
    params = TrackParams(form="spin" if spin else "plane", base_hz=hz, phase_rad=(0.0, 0.0), terms=tuple(terms),
                         coefficients=coefficients)

    # The residual as the angle between each row's ray and the model's, laser by laser.
    distances = []
    for rows_k, residual in zip(every_row, residuals, strict=True):
        measured = np.column_stack([rows_k.z.real, rows_k.z.imag])
        model = measured - np.column_stack([residual.real, residual.imag])
        distances.append(angle_between_deg(model, measured, plane))
    per = np.array([math.sqrt(float(np.mean(d**2))) for d in distances])
    distance = np.concatenate(distances)
    total = math.sqrt(float(np.mean(distance**2)))
    if total > NO_TRACK_FRACTION * spread:
        _no_track(table, total, spread)
    return TrackFit(params, FieldOfView.of_points(xy, plane), found, total, float(np.percentile(distance, 95)),
                    float(distance.max()), per, spread, time.perf_counter() - started, tuple(notes))


def _no_track(table: ReferencePattern, error: float, spread: float) -> None:
    raise LivoxVizError(f"{table.name}: the best track leaves {error:.3g} deg rms of the table's {spread:.3g} deg "
                        f"spread ({100 * error / max(spread, 1e-300):.0f} %): there is no periodic scan track in it "
                        "(noise, or rows not in firing order?)")


def _spin_rate(signals: _Signals) -> float:
    """The azimuth's turn rate (Hz) if it turns two times or more over the table, else 0."""
    x = signals.x[0]
    if abs(x[-1] - x[0]) < 720.0:
        return 0.0
    slopes = []
    for x, t0 in zip(signals.x, signals.t0, strict=True):
        t = t0 + np.arange(x.size) * signals.dt
        slopes.append(np.polyfit(t, x, 1)[0])
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
