"""The Risley-prism pattern stream: the real sensors' track as a series of rotating vectors (``risley.md``).

Sample k fires at t = k / rate and belongs to laser k mod K; its point is

    z = sum_j  c_{k,j} exp(i (m_j A(t) + l_j B(t)))   (degrees, z = x + iy)

with the parameters of :class:`~livox_viz.risley_params.RisleyParams`. There is
no randomness (the seed is ignored) and no flower or figure structure.

A block of samples (first sample k0) is one complex matrix product. Row s of
the block holds samples k0 + s*L .. k0 + s*L + L-1 (L, the row length, a
multiple of K, so every row starts on laser 0), and with w_j the term's phase
step per sample and phi_j its phase at k = 0,

    z[s, d] = sum_j  (P_j R_{s,j}) T_{j,d},    P_j = exp(i w_j k0),
              R_{s,j} = exp(i w_j s L),        T_{j,d} = c_{laser(d),j} exp(i phi_j) exp(i w_j d).

P is computed from k0 directly (not by recurrence, so nothing drifts however
long the stream runs); R and T are made once. That is a (rows x J) by (J x L)
product, a small GEMM, which BLAS does several times faster than the
row-vector-times-table product it replaces; it runs under
:func:`~livox_viz.core.blas.one_blas_thread`, as OpenBLAS would otherwise split
it over threads that spin. A block is the sensor's frame when the frame splits
into rows, so a frame is one product written straight into the chunk; a chunk
that covers part of a block copies from the last block made, which is kept.
Every sample is therefore computed by the same product however the stream is
cut: bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.blas import one_blas_thread
from livox_viz.core.errors import ConfigError
from livox_viz.patterns.stream import PatternChunk, PatternStream

#: Samples in a row of a block, about: a (rows x J) by (J x 256) product is where BLAS is fastest here.
_ROW = 256
#: Samples in a block, about; a frame of up to :data:`_FRAME_BLOCK` points is one block (or whole frames are).
_BLOCK = 8192
_FRAME_BLOCK = 65_536


def block_shape(points_per_frame: int, lasers: int) -> tuple[int, int]:
    """``(rows, row)`` of the blocks of a stream: whole frames when a frame splits into rows.

    Parameters
    ----------
    points_per_frame : int
    lasers : int
        K; a row is a multiple of it, so every row starts on laser 0.

    Returns
    -------
    rows, row : int
        A block is ``rows * row`` samples.
    """
    shortest = lasers * max(1, _ROW // 4 // lasers)
    dividing = [row for row in range(shortest, 4 * _ROW + 1, lasers) if points_per_frame % row == 0]
    if dividing and points_per_frame <= _FRAME_BLOCK:
        row = min(dividing, key=lambda r: abs(math.log(r / _ROW)))
        frames = max(1, _BLOCK // points_per_frame)
        return frames * points_per_frame // row, row
    row = lasers * max(1, round(_ROW / lasers))
    return max(1, _BLOCK // row), row


def series_block(block_phasors: np.ndarray, row_steps: np.ndarray, table: np.ndarray, out: np.ndarray,
                 work: np.ndarray) -> None:
    """One block of the series: ``out = (row_steps * block_phasors) @ table``.

    Parameters
    ----------
    block_phasors : (J,) complex128
        exp(2 pi i frac(w_j k)) at the block's first sample k (the phases at k = 0 are in the table).
    row_steps : (rows, J) complex128
        exp(i w_j s L): each row's phase advance over the first.
    table : (J, L) complex128
        c_{laser(d), j} exp(i phi_j) exp(i w_j d), d = 0 .. L-1 (phi_j: the term's phase at k = 0).
    out : (rows, L) complex128, C-contiguous
        The block's points, degrees (x + iy).
    work : (rows, J) complex128
        Scratch.
    """
    with one_blas_thread():
        _series_product(block_phasors, row_steps, table, out, work)


def _series_product(block_phasors: np.ndarray, row_steps: np.ndarray, table: np.ndarray, out: np.ndarray,
                    work: np.ndarray) -> None:
    """:func:`series_block` for a caller already holding :func:`~livox_viz.core.blas.one_blas_thread`."""
    np.multiply(row_steps, block_phasors, out=work)
    np.matmul(work, table, out=out)


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
        self._cycles_per_sample = params.term_hz / config.point_rate
        rows, row = block_shape(config.points_per_frame, params.lasers)
        self._rows, self._row = rows, row
        self._block = rows * row
        cycles = self._cycles_per_sample[:, None] * np.arange(row, dtype=np.float64)[None, :]
        laser = np.arange(row) % params.lasers
        # The terms' phases at k = 0 go into the table too: a block's phasors are then exp(2 pi i frac(w k)).
        start_phasors = np.exp(1j * params.term_phase)[:, None]
        self._table = np.ascontiguousarray(params.coefficients[laser].T * start_phasors
                                           * np.exp(2j * np.pi * np.mod(cycles, 1.0)))
        advance = (np.arange(rows, dtype=np.float64) * row)[:, None] * self._cycles_per_sample[None, :]
        self._row_steps = np.exp(2j * np.pi * np.mod(advance, 1.0))
        self._work = np.empty((rows, len(params.terms)), dtype=np.complex128)
        # A block's phasors are made in these (a frame's product takes 30 us: fresh arrays here cost a tenth).
        self._turns = np.empty(len(params.terms), dtype=np.float64)
        self._phasors = np.empty(len(params.terms), dtype=np.complex128)
        self._kept = (-1, np.empty((rows, row), dtype=np.complex128))
        self._position = 0

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` (any range: the track is a function of k alone)."""
        path = self._path_buffer(count)
        block, stop = self._block, start + count
        with one_blas_thread():  # once for the chunk: the blocks are made under it
            for first in range(start - start % block, stop, block):
                if first >= start and first + block <= stop:
                    self._make_block(first, path[first - start : first - start + block].reshape(self._rows,
                                                                                                 self._row))
                    continue
                low, high = max(first, start), min(first + block, stop)
                path[low - start : high - start] = self._kept_block(first).ravel()[low - first : high - first]
        return PatternChunk(self.config, start, path.view(np.float64).reshape(count, 2))

    def _make_block(self, first: int, out: np.ndarray) -> None:
        """Block from sample ``first`` into ``out`` ``(rows, row)`` complex128 (the caller holds one BLAS thread)."""
        turns = np.multiply(self._cycles_per_sample, float(first), out=self._turns)
        np.mod(turns, 1.0, out=turns)
        phasors = np.multiply(turns, 2j * math.pi, out=self._phasors)
        _series_product(np.exp(phasors, out=phasors), self._row_steps, self._table, out, self._work)

    def _kept_block(self, first: int) -> np.ndarray:
        """The block starting at sample ``first``, made once and kept until another is asked for."""
        if self._kept[0] != first:
            self._make_block(first, self._kept[1])
            self._kept = (first, self._kept[1])
        return self._kept[1]


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
