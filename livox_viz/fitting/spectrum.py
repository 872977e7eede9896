"""The lines of a track's spectrum and the two base frequencies that explain them.

A scan head's parts turn or swing at two steady rates f_A, f_B, so each laser's
direction is a sum of lines at m f_A + l f_B (small integers of either sign).
:func:`spectral_peaks` reads the strongest lines of one laser's evenly spaced
samples (Hann window, zero-padded FFT, parabolic peaks); :func:`choose_base`
finds the pair that explains the most line amplitude with the lowest orders
(of every pair of candidates: the lines, their sums and differences, halves
and thirds). One frequency alone (f_B = 0) is tried too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError

#: Spectral lines read off laser 0 for the base frequencies.
PEAKS = 16
#: Largest |m|, |l| a line may need to count as explained by a base pair.
LINE_ORDER = 8
#: Two candidate frequencies related by integers this small span a line rather than a lattice.
DEGENERATE_ORDER = 4


def spectral_peaks(z: np.ndarray, rate: float, count: int = 2) -> list[tuple[float, float]]:
    """The ``count`` strongest lines of a signal's spectrum away from 0 Hz: (frequency Hz, amplitude)."""
    n = z.size
    window = np.hanning(n)
    # Zero-padded 4 x for the parabolic peaks; 2 x past a million samples, whose bins are fine enough already
    # (the transform of a 10-million-row table would otherwise take 1.3 GB).
    size = 1 << (math.ceil(math.log2(n)) + (2 if n <= 1 << 20 else 1))
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
        raise LivoxVizError(f"its strongest lines are not combinations of two frequencies (at most {100 * share:.0f} % "
                            "of their amplitude explained)")
    return best[2] if spin_hz is not None else _normalise(best[2])


def _normalise(choice: BaseChoice) -> BaseChoice:
    """f_A the stronger-explained positive one where the orders allow: (1, 0) before (0, 1), both signs free."""
    (a, b), orders = choice.hz, choice.orders
    if b != 0 and not any(o == (1, 0) or o == (-1, 0) for o in orders) and any(abs(m) + abs(n) == 1 and n
                                                                                 for m, n in orders):
        a, b = b, a
        orders = tuple((n, m) for m, n in orders)
    return BaseChoice((a, b), orders, choice.explained)
