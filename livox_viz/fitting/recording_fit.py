"""A preset's track fitted to a frame recorded by a real sensor: phases, clocks, handedness and laser order.

A scan table says where Livox's simulation points the lasers; a recording says
where the hardware did. Their disagreements are whole symmetries, which a fit of
the table alone cannot see: a track mirrored left-right, lasers numbered in the
reverse order, an azimuth that turns the other way. This module takes one
frame recorded in firing order (row i fired at about ``t0 + i / rate``, a
no-return kept in its place) and a head's series track (``LivoxVizRisley`` or
``LivoxVizTrack``), and finds, by search then least squares:

- which of the track's four mirror images the recording is (as printed, mirrored
  left-right, mirrored top-bottom, turned 180 degrees about the boresight),
  and whether its lasers fire in the track's order or the reverse;
- which laser the recording's first row is;
- the phases of the track's two base motions at the first row;
- each base motion's speed against the firing clock (a real sensor's motors and
  clock are not exactly nominal: about 1,500 ppm on a Tele-15).

Its residual is the angle between each returned row and the fitted track's
sample at the same firing, as the median of each :data:`WINDOW_SECONDS`
window. A fit is only reported when it is far better than the same track at
random phases (:data:`NOISE_RATIO`): a frame from another head, with its rows
sorted, or with almost no returns is refused, not fitted to noise.

The mirror images of a series ``w = sum_j c_j exp(i (m_j A + l_j B))`` are
exact transforms of its parameters (the pattern's x is to the right, y up):
left-right ``x -> -x`` is ``c -> -conj(c)`` with both base frequencies and
phases negated; top-bottom ``y -> -y`` is ``c -> conj(c)`` with the same
negations; turned 180 degrees is ``c -> -c``. For a spin track (the azimuth is
``degrees(A) + Re w``) the same transforms hold, the azimuth turning the other
way with a negated f_A.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from livox_viz.config.sensor import SERIES_MODELS, SensorConfig
from livox_viz.core.blas import one_blas_thread
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.table import PLANE_IMAGES
from livox_viz.patterns.planes import angle_between_deg, xy_from_directions

#: The residual is reported as the median angle in windows of this many seconds.
WINDOW_SECONDS = 0.002
#: A fit is refused unless its median residual is at most this fraction of the same track's at random phases.
NOISE_RATIO = 0.25
#: Fewest returned rows a recording needs (a tenth of a 10 Hz frame of the slowest head).
MIN_RETURNS = 1_000
#: The mirror images, in the order they are tried: the (x, y) sign flips of the pattern plane.
IMAGES = PLANE_IMAGES
#: Laser orders tried: the track's own, and the reverse.
ORDERS: tuple[str, ...] = ("as the track's", "reversed")
#: Seconds of the recording the first, coarse phase search looks at (the clocks' drift is small within it).
COARSE_SECONDS = 0.006
#: Rows the coarse search compares, at most; rows the least-squares refinement uses, at most.
COARSE_ROWS = 240
REFINE_ROWS = 6_000
#: Random phase pairs the noise baseline is the median over.
NOISE_DRAWS = 24
#: A terms refit learns on alternate blocks of this many seconds and is judged on the others.
HOLD_OUT_SECONDS = 0.01
#: Rounds of coefficients, then phases and motor speeds, in a terms refit.
REFIT_ROUNDS = 3
#: Ridge of the terms refit, as a fraction of the normal equations' mean diagonal.
REFIT_RIDGE = 1e-3
#: A coarse distance above this many degrees counts as this many (one wild row must not outweigh the rest).
CAP_DEG = 3.0


@dataclass(frozen=True)
class RecordedFrame:
    """One frame of a real sensor in firing order.

    Parameters
    ----------
    name : str
    directions : (n, 3) float64
        Each row's direction in the sensor's FRD frame (x forward, y right, z down), any length; a no-return
        row's is ``(0, 0, 0)``.
    t : (n,) float64, optional
        Each row's time from the first row, seconds, when the file says it (a driver's per-point offset
        time). Default: row i at ``i / rate``, ``rate`` the head's nominal rate.
    lasers : (n,) int, optional
        Each row's laser as the file numbers them (a driver's ``line``). Default: the firing slot's
        (``round(t * rate)`` mod the head's lasers).
    """

    name: str
    directions: np.ndarray
    t: np.ndarray | None = None
    lasers: np.ndarray | None = None

    @property
    def returned(self) -> np.ndarray:
        """``(n,)`` bool: the rows with a return."""
        return np.any(self.directions != 0.0, axis=1)

    @property
    def rows(self) -> int:
        """Rows, returned or not."""
        return int(self.directions.shape[0])


@dataclass(frozen=True)
class _Series:
    """A track as the fit moves it: base frequencies and phases, terms, per-laser coefficients, the spin."""

    base_hz: np.ndarray
    phase_rad: np.ndarray
    order_a: np.ndarray
    order_b: np.ndarray
    coefficients: np.ndarray
    spin: bool

    def image(self, signs: tuple[int, int], reverse: bool, first_laser: int) -> _Series:
        """The series mirrored by ``signs``, its lasers reversed, relabelled to start at ``first_laser``."""
        flip = signs[0] * signs[1] < 0
        return dataclasses.replace(self, base_hz=-self.base_hz if flip else self.base_hz,
                                   phase_rad=-self.phase_rad if flip else self.phase_rad,
                                   coefficients=imaged_coefficients(self.coefficients, signs, reverse, first_laser))


    def xy(self, t: np.ndarray, laser: np.ndarray, shift: Sequence[float] = (0.0, 0.0),
           ppm: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
        """``(n, 2)`` degrees: the series at times ``t`` (seconds) for ``laser``, its phases moved by ``shift``
        (radians) and its base speeds by ``ppm``."""
        a = 2.0 * np.pi * self.base_hz[0] * (1.0 + 1e-6 * ppm[0]) * t + self.phase_rad[0] + shift[0]
        b = 2.0 * np.pi * self.base_hz[1] * (1.0 + 1e-6 * ppm[1]) * t + self.phase_rad[1] + shift[1]
        w = np.einsum("nj,nj->n", self.coefficients[laser],
                      np.exp(1j * (np.outer(a, self.order_a) + np.outer(b, self.order_b))))
        xy = np.column_stack([w.real, w.imag])
        if self.spin:
            xy[:, 0] += np.degrees(a)
            xy[:, 0] = (xy[:, 0] + 180.0) % 360.0 - 180.0
        return xy


def imaged_coefficients(c: np.ndarray, signs: tuple[int, int], reverse: bool, first_laser: int) -> np.ndarray:
    """``(K, J)`` complex: a series' coefficients mirrored by ``signs`` (with its base motions negated when the
    image is a reflection), its lasers reversed and relabelled to start at ``first_laser``."""
    if signs[0] * signs[1] < 0:
        # A reflection: the conjugate runs every term backwards in time (the base motions are negated with it).
        c = np.conj(c)
    if signs[0] < 0:
        c = -c
    if reverse:
        c = c[::-1]
    return np.roll(c, -first_laser, axis=0)


def _series_of(config: SensorConfig) -> _Series:
    if config.pattern_model not in SERIES_MODELS:
        raise LivoxVizError(f"this configuration has the {config.pattern_model!r} pattern, "
                            "which has no fixed track to fit a recording to; allowed: a preset with a series "
                            "track (risley or track: livox_tele15, livox_horizon, livox_mid360, ...)")
    if config.pattern_model == "risley":
        params = config.risley
        base, phase = params.prism_hz, params.phase_rad
        spin = False
    else:
        params = config.track
        base, phase = params.base_hz, params.phase_rad
        spin = params.form == "spin"
    terms = np.array(params.terms, dtype=np.int64)
    return _Series(np.array(base, dtype=np.float64), np.array(phase, dtype=np.float64), terms[:, 0].astype(float),
                   terms[:, 1].astype(float), np.array(params.coefficients, dtype=np.complex128), spin)


@dataclass(frozen=True)
class RecordingFit:
    """What a recording says of a head's track.

    Parameters
    ----------
    config : SensorConfig
        The head's configuration with its track made the recording's: mirrored and reordered as found, its
        phases the recording's at its first row (which is laser 0), its base speeds the recording's.
    image : str
        Which of :data:`IMAGES` the recording is of the track as it was.
    laser_order : str
        One of :data:`ORDERS`.
    first_laser : int
        The track's laser (as it was) that fired the recording's first row.
    ppm : tuple of 2 float
        Each base motion's speed against the nominal, parts per million.
    window_start_s : (w,) float64
        Each residual window's start, seconds from the first row.
    window_median_deg : (w,) float64
        Median angle between each returned row and the fitted track's sample in the window, degrees.
    window_aligned_deg : (w,) float64
        The same with the track's phases aligned again in each window (its clocks and speeds as fitted):
        how well the track's shape matches, apart from the motors' drift within the frame.
    median_deg : float
        Median over all returned rows, degrees.
    random_median_deg : float
        The same track at random phases (the best image and order), degrees: what noise scores.
    returns : int
        Returned rows.
    no_return_share : float
        Share of rows with no return.
    seconds : float
        Time the fit took, wall clock.
    refitted : int
        Coefficients fitted to the recording (0: the track's own shape, only imaged and moved).
    held_out_window_deg : (h,) float64
        With a terms refit, the median per 2 ms window of the held-out blocks (empty without one), degrees.
    """

    config: SensorConfig
    image: str
    laser_order: str
    first_laser: int
    ppm: tuple[float, float]
    window_start_s: np.ndarray
    window_median_deg: np.ndarray
    window_aligned_deg: np.ndarray
    median_deg: float
    random_median_deg: float
    returns: int
    no_return_share: float
    seconds: float
    refitted: int = 0
    held_out_window_deg: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))


def recorded_xy(frame: RecordedFrame, plane: str) -> np.ndarray:
    """``(n, 2)`` degrees: the frame's rows in a pattern plane (no-return rows are meaningless there)."""
    return xy_from_directions(frame.directions, plane)


def _distance(model: np.ndarray, measured: np.ndarray, spin: bool) -> np.ndarray:
    """Degrees between pattern points, about (the azimuth wrapped and shortened by the elevation for a spin)."""
    dx = model[..., 0] - measured[..., 0]
    if spin:
        dx = (dx + 180.0) % 360.0 - 180.0
        dx = dx * np.cos(np.radians(measured[..., 1]))
    return np.hypot(dx, model[..., 1] - measured[..., 1])


def _coarse(series: _Series, t: np.ndarray, laser: np.ndarray, measured: np.ndarray, steps_a: int,
            steps_b: int, typical: bool = False) -> tuple[float, ...]:
    """The best phase shift on a grid: (capped mean distance, shift A, shift B); with ``typical``, (the best
    capped mean distance, the median over the grid)."""
    a0 = 2.0 * np.pi * series.base_hz[0] * t + series.phase_rad[0]
    b0 = 2.0 * np.pi * series.base_hz[1] * t + series.phase_rad[1]
    rows = series.coefficients[laser] * np.exp(1j * (np.outer(a0, series.order_a) + np.outer(b0, series.order_b)))
    grid_a = np.arange(steps_a) * (2.0 * np.pi / steps_a)
    grid_b = np.arange(steps_b) * (2.0 * np.pi / steps_b)
    turn_b = np.exp(1j * np.outer(series.order_b, grid_b))
    best = (math.inf, 0.0, 0.0)
    scores = []
    for shift_a in grid_a:
        w = (rows * np.exp(1j * series.order_a * shift_a)[None, :]) @ turn_b
        x = w.real
        if series.spin:
            x = x + np.degrees(a0 + shift_a)[:, None]
            x = (x + 180.0) % 360.0 - 180.0
        model = np.stack([x, w.imag], axis=-1)
        score = np.minimum(_distance(model, measured[:, None, :], series.spin), CAP_DEG).mean(axis=0)
        scores.append(score)
        k = int(np.argmin(score))
        if score[k] < best[0]:
            best = (float(score[k]), float(shift_a), float(grid_b[k]))
    if typical:
        return best[0], float(np.median(np.concatenate(scores)))
    return best


def _residual_deg(series: _Series, t: np.ndarray, laser: np.ndarray, measured: np.ndarray,
                  ppm: Sequence[float] | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """The least-squares residual (degrees, x then y; a spin's azimuth wrapped and shortened by the elevation) of
    the phase vector: (shift A, shift B, ppm A, ppm B), or with ``ppm`` fixed, the two shifts alone."""
    cos_el = np.cos(np.radians(measured[:, 1])) if series.spin else 1.0

    def residual(x: np.ndarray) -> np.ndarray:
        model = series.xy(t, laser, x[:2], x[2:] if ppm is None else ppm)
        dx = model[:, 0] - measured[:, 0]
        if series.spin:
            dx = ((dx + 180.0) % 360.0 - 180.0) * cos_el
        return np.concatenate([dx, model[:, 1] - measured[:, 1]])

    return residual


def _refine(series: _Series, t: np.ndarray, laser: np.ndarray, measured: np.ndarray,
            start: Sequence[float]) -> np.ndarray:
    """Least squares on (shift A, shift B, ppm A, ppm B), robust to the rows that hit something odd."""
    from scipy.optimize import least_squares

    solution = least_squares(_residual_deg(series, t, laser, measured), np.asarray(start, dtype=np.float64),
                             loss="soft_l1", f_scale=0.05, x_scale=np.array([1e-3, 1e-3, 10.0, 10.0]))
    return solution.x


def _aligned_median(series: _Series, t: np.ndarray, laser: np.ndarray, measured: np.ndarray, x: np.ndarray,
                    plane: str) -> float:
    """Median angle in one window after its phases alone are fitted again (degrees)."""
    from scipy.optimize import least_squares

    if t.size < 8:
        return math.nan
    shift = least_squares(_residual_deg(series, t, laser, measured, x[2:]), x[:2], loss="soft_l1", f_scale=0.05,
                          x_scale=1e-3).x
    return float(np.median(angle_between_deg(series.xy(t, laser, shift, x[2:]), measured, plane)))


def _images_of(series: _Series, images: Sequence[str]) -> list[str]:
    """The images worth trying: a spin track's azimuth is degrees(A) + Re w, so only its left-right image is a
    track of the same form."""
    return [image for image in images if not series.spin or IMAGES[image][1] == 1]


def _grid_steps(series: _Series) -> tuple[int, int]:
    """Phase grid steps of the coarse search: fine enough for the highest order (and a spin's azimuth)."""
    return (max(48, int(8 * np.abs(series.order_a).max()) + (90 if series.spin else 0)),
            max(48, int(8 * np.abs(series.order_b).max())))


def _times_and_lasers(frame: RecordedFrame, rate: float, lasers: int) -> tuple[np.ndarray, np.ndarray]:
    """Each row's time (seconds from the first) and laser: the file's, else from the firing order."""
    t = frame.t if frame.t is not None else np.arange(frame.rows, dtype=np.float64) / rate
    if frame.lasers is not None:
        return t, np.asarray(frame.lasers, dtype=np.int64) % lasers
    return t, np.rint((t - t[0]) * rate).astype(np.int64) % lasers


def head_likeness(config: SensorConfig, frame: RecordedFrame) -> float:
    """How well a head's track explains a frame at its best coarse phase, against its typical phase: the ratio
    of the two capped mean distances (small: this head; near 1: not this head). Seconds, not minutes: only
    the frame's first :data:`COARSE_SECONDS` are looked at."""
    with one_blas_thread():  # many small products: OpenBLAS's spinning threads made them 10-25 x slower
        return _head_likeness(config, frame)


def _head_likeness(config: SensorConfig, frame: RecordedFrame) -> float:
    series = _series_of(config)
    lasers = series.coefficients.shape[0]
    t, row_laser = _times_and_lasers(frame, float(config.point_rate), lasers)
    index = np.flatnonzero(frame.returned)
    if index.size < 16:
        return 1.0
    early = _spread_rows(index[t[index] <= t[index[0]] + COARSE_SECONDS], COARSE_ROWS // 4)
    measured = recorded_xy(frame, config.pattern_plane)[early]
    # Half the fit's grid: a ranking of heads, not a phase to start from.
    steps_a, steps_b = (max(24, steps // 2) for steps in _grid_steps(series))
    best = 1.0
    for image in _images_of(series, tuple(IMAGES)):
        for reverse in (False, True):
            for first in range(lasers):
                moved = series.image(IMAGES[image], reverse, first)
                score, typical = _coarse(moved, t[early], row_laser[early], measured, steps_a, steps_b,
                                         typical=True)
                best = min(best, score / max(typical, 1e-9))
    return best


def _spread_rows(indices: np.ndarray, count: int) -> np.ndarray:
    """At most ``count`` of ``indices``, evenly spread."""
    if indices.size <= count:
        return indices
    return indices[np.linspace(0, indices.size - 1, count).astype(np.int64)]


def fit_recording(config: SensorConfig, frame: RecordedFrame, images: Sequence[str] = tuple(IMAGES),
                  orders: Sequence[str] = ORDERS, seed: int = 0,
                  refit_orders: tuple[int, int] | None = None) -> RecordingFit:
    """Fit a head's track to one recorded frame (see the module's docstring).

    Parameters
    ----------
    config : SensorConfig
        The head (a series-track preset).
    frame : RecordedFrame
        Its rows in firing order.
    images, orders : sequence of str
        The mirror images (:data:`IMAGES`) and laser orders (:data:`ORDERS`) to try.
    seed : int
        Seed of the random phases of the noise baseline.
    refit_orders : (int, int), optional
        Also fit the coefficients of the track's terms with ``|m| <= refit_orders[0]`` and
        ``|l| <= refit_orders[1]`` to the recording, where the table's model itself is off the hardware (the
        Mid-360's is 2 deg off): on alternate :data:`HOLD_OUT_SECONDS` blocks only, the others held out and
        reported (:attr:`RecordingFit.held_out_window_deg`), ridge-regularised towards the track's own.

    Raises
    ------
    LivoxVizError
        A configuration with no series track, too few returns, or a fit no better than random phases.
    """
    # The grid search is thousands of small complex products: with OpenBLAS's two threads spinning on the
    # 2-core machine a refused frame took 8-19 s, with one 0.7 s.
    with one_blas_thread():
        return _fit_recording(config, frame, images, orders, seed, refit_orders)


def _fit_recording(config: SensorConfig, frame: RecordedFrame, images: Sequence[str], orders: Sequence[str],
                   seed: int, refit_orders: tuple[int, int] | None) -> RecordingFit:
    started = time.perf_counter()
    series = _series_of(config)
    plane = config.pattern_plane
    returned = frame.returned
    returns = int(returned.sum())
    if returns < MIN_RETURNS:
        raise LivoxVizError(f"{frame.name}: {returns:,} of its {frame.rows:,} rows have a return; allowed: at "
                            f"least {MIN_RETURNS:,} (a frame of a scan in firing order, no-returns as (0, 0, 0))")
    rate = float(config.point_rate)
    t, row_laser = _times_and_lasers(frame, rate, series.coefficients.shape[0])
    measured = recorded_xy(frame, plane)
    lasers = series.coefficients.shape[0]
    index = np.flatnonzero(returned)
    early = _spread_rows(index[t[index] <= t[index[0]] + COARSE_SECONDS], COARSE_ROWS)
    steps_a, steps_b = _grid_steps(series)
    candidates = []
    images = _images_of(series, images)
    for image in images:
        for order in orders:
            for first in range(lasers):
                moved = series.image(IMAGES[image], order == "reversed", first)
                score, shift_a, shift_b = _coarse(moved, t[early], row_laser[early], measured[early], steps_a,
                                                  steps_b)
                candidates.append((score, image, order, first, moved, (shift_a, shift_b)))
    candidates.sort(key=lambda c: c[0])
    refine_rows = _spread_rows(index, REFINE_ROWS)
    best = None
    for _score, image, order, first, moved, shift in candidates[:3]:
        x = _refine(moved, t[early], row_laser[early], measured[early], [*shift, 0.0, 0.0])
        x = _refine(moved, t[refine_rows], row_laser[refine_rows], measured[refine_rows], x)
        model = moved.xy(t[index], row_laser[index], x[:2], x[2:])
        angle = angle_between_deg(model, measured[index], plane)
        median = float(np.median(angle))
        if best is None or median < best[0]:
            best = (median, image, order, first, moved, x, angle)
    median, image, order, first, moved, x, angle = best
    held_out = np.zeros(0)
    refitted = 0
    if refit_orders is not None:
        train = (np.floor((t[index] - t[0]) / HOLD_OUT_SECONDS) % 2) == 0
        moved, x, refitted = _refit_terms(moved, t[index], row_laser[index], measured[index], x, train,
                                          refit_orders)
        angle = angle_between_deg(moved.xy(t[index], row_laser[index], x[:2], x[2:]), measured[index], plane)
        median = float(np.median(angle))
        test_window = np.floor((t[index][~train] - t[0]) / WINDOW_SECONDS).astype(np.int64)
        _, test_where = np.unique(test_window, return_index=True)
        held_out = np.array([np.median(part) for part in np.split(angle[~train], test_where[1:])])
    rng = np.random.default_rng(seed)
    noise = [float(np.median(angle_between_deg(moved.xy(t[refine_rows], row_laser[refine_rows],
                                                        rng.uniform(0, 2 * np.pi, 2), x[2:]),
                                               measured[refine_rows], plane))) for _ in range(NOISE_DRAWS)]
    random_median = float(np.median(noise))
    if median > NOISE_RATIO * random_median:
        raise LivoxVizError(f"{frame.name}: the best fit of the head's track leaves a median "
                            f"{median:.3g} deg, and random phases {random_median:.3g} deg: the recording is not "
                            "this head's scan in firing order (another head, rows sorted or deduplicated, or "
                            "too few returns); allowed: one frame of this head, rows in firing order with "
                            "no-returns kept as (0, 0, 0)")
    window = np.floor((t[index] - t[0]) / WINDOW_SECONDS).astype(np.int64)
    starts, where = np.unique(window, return_index=True)
    medians = np.array([np.median(part) for part in np.split(angle, where[1:])])
    aligned = np.array([_aligned_median(moved, t[rows], row_laser[rows], measured[rows], x, plane)
                        for rows in np.split(index, where[1:])])
    fitted = _fitted_config(config, moved, x, (IMAGES[image], order == "reversed", first),
                            refitted=refitted > 0)
    return RecordingFit(fitted, image, order, first, (float(x[2]), float(x[3])), starts * WINDOW_SECONDS,
                        medians, aligned, median, random_median, returns, 1.0 - returns / frame.rows,
                        time.perf_counter() - started, refitted, held_out)


def _refit_terms(series: _Series, t: np.ndarray, laser: np.ndarray, measured: np.ndarray, x: np.ndarray,
                 train: np.ndarray, orders: tuple[int, int]) -> tuple[_Series, np.ndarray, int]:
    """The low-order terms' coefficients fitted to the training rows, laser by laser, alternating with the
    phases and motor speeds (:data:`REFIT_ROUNDS` rounds); returns the series, the phase vector and how many
    coefficients were fitted."""
    chosen = (np.abs(series.order_a) <= orders[0]) & (np.abs(series.order_b) <= orders[1])
    if not chosen.any():
        raise LivoxVizError(f"no term of the track has |m| <= {orders[0]} and |l| <= {orders[1]}; allowed: orders "
                            "that take in some of its terms")
    lasers = series.coefficients.shape[0]
    for _ in range(REFIT_ROUNDS):
        a = 2.0 * np.pi * series.base_hz[0] * (1.0 + 1e-6 * x[2]) * t + series.phase_rad[0] + x[0]
        b = 2.0 * np.pi * series.base_hz[1] * (1.0 + 1e-6 * x[3]) * t + series.phase_rad[1] + x[1]
        target = measured[:, 0] - (np.degrees(a) if series.spin else 0.0)
        if series.spin:
            target = (target + 180.0) % 360.0 - 180.0
        target = target + 1j * measured[:, 1]
        coefficients = series.coefficients.copy()
        for k in range(lasers):
            rows = train & (laser == k)
            if rows.sum() < 4 * chosen.sum():
                continue
            every = np.exp(1j * (np.outer(a[rows], series.order_a) + np.outer(b[rows], series.order_b)))
            design = every[:, chosen]
            left = target[rows] - every @ coefficients[k]
            weight = np.ones(design.shape[0])
            for _ in range(3):
                # Iteratively reweighted (Huber at 0.1 deg): rows that hit something odd must not pull the track.
                gram = (design.conj().T * weight) @ design
                ridge = REFIT_RIDGE * np.trace(gram).real / gram.shape[0]
                step = np.linalg.solve(gram + ridge * np.eye(gram.shape[0]), (design.conj().T * weight) @ left)
                weight = 1.0 / np.maximum(np.abs(left - design @ step) / 0.1, 1.0)
            coefficients[k, chosen] += step
        series = dataclasses.replace(series, coefficients=coefficients)
        x = _refine(series, t[train], laser[train], measured[train], x)
    return series, x, int(chosen.sum()) * lasers


def imaged_config(config: SensorConfig, image: str, reverse: bool = False, first_laser: int = 0) -> SensorConfig:
    """A series-track configuration whose pattern is ``image`` (a key of :data:`IMAGES`) of the given one, its
    lasers reversed when asked and relabelled to start at ``first_laser`` (exact: the parameters are transformed,
    nothing is fitted)."""
    moved = _series_of(config).image(IMAGES[image], reverse, first_laser)
    return _fitted_config(config, moved, np.zeros(4), (IMAGES[image], reverse, first_laser))


def _fitted_config(config: SensorConfig, moved: _Series, x: np.ndarray,
                   how: tuple[tuple[int, int], bool, int], refitted: bool = False) -> SensorConfig:
    """The configuration with the fitted series: base speeds scaled, phases moved, coefficients imaged (or, after
    a terms refit, the fitted ones)."""
    base = tuple(float(v) for v in moved.base_hz * (1.0 + 1e-6 * x[2:]))
    phase = tuple(float(math.remainder(v, 2.0 * math.pi)) for v in moved.phase_rad + x[:2])
    if config.pattern_model == "risley":
        params = config.risley
        # The user's deflections and laser spacing scale the base coefficients; both commute with the images.
        if refitted:
            # The fitted coefficients are the effective ones: they replace the base and the user's scalings.
            risley = dataclasses.replace(params, prism_hz=base, phase_rad=phase, base_coefficients=moved.coefficients,
                                         deflection_deg=None, laser_spacing=1.0)
            return dataclasses.replace(config, risley=risley)
        risley = dataclasses.replace(params, prism_hz=base, phase_rad=phase,
                                     base_coefficients=imaged_coefficients(params.base_coefficients, *how))
        return dataclasses.replace(config, risley=risley)
    track = dataclasses.replace(config.track, base_hz=base, phase_rad=phase, coefficients=moved.coefficients)
    return dataclasses.replace(config, track=track)
