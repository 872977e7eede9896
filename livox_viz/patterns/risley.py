"""The Risley-prism pattern stream: the real sensors' track as a series of rotating vectors (``risley.md``).

Sample k fires at t = k / rate and belongs to laser k mod K; its point is

    z = sum_j  c_{k,j} exp(i (m_j A(t) + l_j B(t)))   (degrees, z = x + iy)

with the parameters of :class:`~livox_viz.risley_params.RisleyParams`. There is
no randomness (the seed is ignored) and no flower or figure structure.

Each term's phase grows linearly with k, so a block of samples is a fixed
table of unit phasors ``exp(i w_j d)`` (d = 0 .. block-1) times the term's
phasor at the block's first sample: one small complex matrix-vector product
per block and laser. The block-start phasors are computed from k directly
(not by recurrence), so nothing drifts however long the stream runs.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import ConfigError
from livox_viz.patterns.stream import PatternChunk, PatternStream

_BLOCK = 8192


class RisleyPattern(PatternStream):
    """The endless, deterministic point stream of a Risley configuration.

    Parameters
    ----------
    config : SensorConfig
        With ``pattern_model == "risley"`` (or any configuration carrying ``risley`` parameters).
    seed : int
        Accepted for a common interface with :class:`~livox_viz.pattern.ScanPattern`; ignored.
    """

    def __init__(self, config: SensorConfig, seed: int = 0) -> None:
        params = config.track if config.pattern_model == "track" else config.risley
        if params is None:
            raise ConfigError("the Risley pattern needs LivoxVizRisley parameters (e.g. preset livox_mid70_risley)")
        self.config = config
        self.seed = int(seed)
        self._lasers = params.lasers
        self._cycles_per_sample = params.term_hz / config.point_rate
        self._phase0 = params.term_phase
        self._coefficients = np.ascontiguousarray(params.coefficients)
        self._block = _BLOCK - _BLOCK % self._lasers if self._lasers <= _BLOCK else self._lasers
        steps = self._cycles_per_sample[:, None] * np.arange(self._block, dtype=np.float64)[None, :]
        # (J, block): one term's phasors along a row, so a block is one row-vector-times-matrix product.
        self._table = np.exp(2j * np.pi * np.mod(steps, 1.0))
        self._cached_block = (-1, np.zeros(0, dtype=np.complex128))
        self._position = 0

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` (any range: the track is a function of k alone)."""
        path, times = self._output(start, count)
        lasers, block, stop = self._lasers, self._block, start + count
        # Blocks start at multiples of the block size whatever the chunk, so a sample is computed
        # the same way however the stream is cut: bit for bit.
        for first in range(start - start % block, stop, block):
            low, high = max(first, start) - first, min(first + block, stop) - first
            phasor = self._phasors_at(first)
            out = path[first + low - start : first + high - start]
            if lasers == 1:
                np.matmul(self._coefficients[0] * phasor, self._table[:, low:high], out=out)
                continue
            for laser in range(lasers):
                offset = (laser - low) % lasers  # block is a multiple of K: sample r of the block is laser r mod K
                if offset < high - low:
                    rows = slice(low + offset, high, lasers)
                    out[offset::lasers] = (self._coefficients[laser] * phasor) @ self._table[:, rows]
        return PatternChunk(self.config, start, path.view(np.float64).reshape(count, 2), times)

    def _phasors_at(self, sample: int) -> np.ndarray:
        """``(J,)`` complex128 exp(i (m_j A + l_j B)) at sample ``sample``, from k directly (the last one kept)."""
        if self._cached_block[0] != sample:
            turns = np.mod(self._cycles_per_sample * float(sample), 1.0)
            self._cached_block = (sample, np.exp(1j * (self._phase0 + 2.0 * math.pi * turns)))
        return self._cached_block[1]


def risley_xy(params, t: np.ndarray, laser: np.ndarray | None = None) -> np.ndarray:
    """The series evaluated directly at times ``t`` (the reference the stream is tested against).

    Parameters
    ----------
    params : RisleyParams
    t : (n,) float64
        Seconds.
    laser : (n,) int, optional
        Laser of each sample; default laser 0.

    Returns
    -------
    xy_deg : (n, 2) float64
    """
    t = np.asarray(t, dtype=np.float64)
    laser = np.zeros(t.shape, dtype=np.int64) if laser is None else np.asarray(laser)
    phase = 2.0 * np.pi * np.outer(t, params.term_hz) + params.term_phase[None, :]
    z = np.sum(params.coefficients[laser] * np.exp(1j * phase), axis=1)
    return np.column_stack([z.real, z.imag])
