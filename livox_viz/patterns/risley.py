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
long the stream runs); R and T are made once. Blocks start at fixed absolute
sample indices (multiples of the block) and all have one shape, so a sample is
always element (s, d) of the same product, however the stream is cut.

**The product is our own compiled loop, not BLAS** (issue 36). A BLAS GEMM's
result for an element depends on how the library tiles and threads the
product: OpenBLAS split a (40 x 10) by (10 x 250) product over two threads
when called one way and not another, and on an AMD EPYC 4 537 of 60 000
values of the same samples differed by an ulp depending on where the stream
was cut (BLAS threads spin on products this small anyway). The loop
:func:`_block_product` sums the terms of each element in one fixed order with
plain IEEE multiplications and additions (no fused multiply-add, no
reassociation: numba's default), so an element's value depends on its inputs
alone: the same whatever the cut, the thread, the BLAS library or its kernel,
and the vector width of the CPU. It runs at 0.7-1 x BLAS's speed (two rows at
a time, each table element loaded once for both; ``benchmarks/bench_risley.py``).

Around the product a frame costs little more: a stream read block after block
makes the left sides P R of the next :data:`_BATCH` blocks in one numpy pass
each (each block's P still from its own k0, the same arithmetic element by
element), a block-sized chunk's arrays and views are made once and reused, and
the chunk is filled in directly
(:meth:`~livox_viz.patterns.stream.PatternChunk.from_stream`).
"""

from __future__ import annotations

import math
import sys

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.compiled import LazyKernels
from livox_viz.core.errors import ConfigError
from livox_viz.patterns.stream import PatternChunk, PatternStream

#: Samples in a row of a block, about: a (rows x J) by (J x 256) product is where BLAS is fastest here.
_ROW = 256
#: Samples in a block, about; a frame of up to :data:`_FRAME_BLOCK` points is one block (or whole frames are).
_BLOCK = 8192
_FRAME_BLOCK = 65_536
#: Blocks whose phasors are made together when the stream is read in order (see :meth:`RisleyPattern._left_side`).
_BATCH = 16
#: The figure-8 rotations of every Risley chunk: none (one shared empty array, read-only).
_NO_ROTATIONS = np.zeros(0)
_NO_ROTATIONS.flags.writeable = False


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
    rows = np.arange(shortest, 4 * _ROW + 1, lasers)  # one numpy pass: a stream is made per slider move
    dividing = rows[points_per_frame % rows == 0].tolist()
    if dividing and points_per_frame <= _FRAME_BLOCK:
        row = min(dividing, key=lambda r: abs(math.log(r / _ROW)))
        frames = max(1, _BLOCK // points_per_frame)
        return frames * points_per_frame // row, row
    row = lasers * max(1, round(_ROW / lasers))
    return max(1, _BLOCK // row), row


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
        table = params.coefficients[laser].T * start_phasors * np.exp(2j * np.pi * np.mod(cycles, 1.0))
        #: T of the block product, ``(J, row)`` complex128, and its real and imaginary parts as the loop reads them.
        self._table = np.ascontiguousarray(table)
        self._table_re, self._table_im = np.ascontiguousarray(table.real), np.ascontiguousarray(table.imag)
        advance = (np.arange(rows, dtype=np.float64) * row)[:, None] * self._cycles_per_sample[None, :]
        self._row_steps = np.exp(2j * np.pi * np.mod(advance, 1.0))
        # The left-hand sides (row_steps * phasors) of up to _BATCH blocks in a row, made together.
        terms = len(params.terms)
        self._batch_steps = np.arange(_BATCH, dtype=np.int64) * self._block
        self._batch_firsts = np.empty(_BATCH, dtype=np.float64)
        self._batch_turns = np.empty((_BATCH, terms), dtype=np.float64)
        self._batch_phasors = np.empty((_BATCH, terms), dtype=np.complex128)
        self._batch_work = np.empty((_BATCH, rows, terms), dtype=np.complex128)
        self._left_sides = list(self._batch_work)  # its blocks' (rows, J) views, made once
        # The blocks held: from sample _held_first, _held of them (none yet; block 0 then starts a batch).
        self._held_first, self._held = 0, 0
        self._frames = _FrameBuffers(rows, row)
        self._product = _KERNELS("block_product")
        self._kept = (-1, np.empty((rows, row), dtype=np.complex128))
        self._position = 0

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` (any range: the track is a function of k alone)."""
        block = self._block
        if count == block and start % block == 0:  # a whole block: one product (the Mid-70's frame by frame)
            out, xy = self._frames.get()
            index = (start - self._held_first) // block  # _left_side's first lines, spelled out: a call costs
            left = self._left_sides[index] if 0 <= index < self._held else self._left_side(start)
            self._product(left, self._table_re, self._table_im, out)
            return PatternChunk.from_stream(self.config, start, xy, _NO_ROTATIONS)
        path = self._path_buffer(count)
        stop = start + count
        for first in range(start - start % block, stop, block):
            if first >= start and first + block <= stop:
                out = path[first - start : first - start + block].reshape(self._rows, self._row)
                self._product(self._left_side(first), self._table_re, self._table_im, out)
                continue
            low, high = max(first, start), min(first + block, stop)
            path[low - start : high - start] = self._kept_block(first).ravel()[low - first : high - first]
        return PatternChunk.from_stream(self.config, start, path.view(np.float64).reshape(count, 2), _NO_ROTATIONS)

    def _left_side(self, first: int) -> np.ndarray:
        """``(rows, J)`` complex128: ``row_steps * phasors`` of the block from sample ``first`` (a block start).

        Each block's phasors are exp(2 pi i frac(w_j first)) from its own ``first``, element by element the
        same arithmetic whether made alone or with others, so the points are the same bit for bit. A block
        right after the ones held starts a batch of :data:`_BATCH` (a stream read in order: numpy's per-call
        cost, 4 us for one block's six small passes, is then shared); any other block is made alone.
        """
        index = (first - self._held_first) // self._block
        if 0 <= index < self._held:
            return self._left_sides[index]
        count = len(self._left_sides) if index == self._held else 1
        firsts = np.add(self._batch_steps[:count], first, out=self._batch_firsts[:count])
        turns = np.multiply(firsts[:, None], self._cycles_per_sample, out=self._batch_turns[:count])
        np.mod(turns, 1.0, out=turns)
        phasors = np.multiply(turns, 2j * math.pi, out=self._batch_phasors[:count])
        np.exp(phasors, out=phasors)
        np.multiply(self._row_steps, phasors[:, None, :], out=self._batch_work[:count])
        self._held_first, self._held = first, count
        return self._left_sides[0]

    def _kept_block(self, first: int) -> np.ndarray:
        """The block starting at sample ``first``, made once and kept until another is asked for."""
        if self._kept[0] != first:
            self._product(self._left_side(first), self._table_re, self._table_im, self._kept[1])
            self._kept = (first, self._kept[1])
        return self._kept[1]


class _FrameBuffers:
    """A stream's block-sized output arrays, each with the two views a chunk of one block needs, made once.

    As :class:`~livox_viz.patterns.stream.PatternStream`'s pool does, an array is handed out again only once
    nothing outside refers to it or its chunk's ``xy_deg`` (a view of either holds a reference to the
    array), so a chunk a caller keeps is never overwritten. Kept here for one size with its views: making
    the two views per chunk cost 0.6 us of a 30 us frame.

    Parameters
    ----------
    rows, row : int
        The block's shape.
    """

    _KEEP = 4

    def __init__(self, rows: int, row: int) -> None:
        self._shape = (rows, row)
        self._free: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def get(self) -> tuple[np.ndarray, np.ndarray]:
        """``(out, xy)``: ``(rows, row)`` complex128 to fill (x + iy, degrees) and its ``(rows*row, 2)`` float64 view.

        Their contents are undefined.
        """
        for buffer, out, xy in self._free:
            if sys.getrefcount(buffer) <= _UNHELD_BUFFER and sys.getrefcount(xy) <= _UNHELD_VIEW:
                return out, xy
        buffer = np.empty(self._shape[0] * self._shape[1], dtype=np.complex128)
        self._free.append((buffer, buffer.reshape(self._shape), buffer.view(np.float64).reshape(-1, 2)))
        if len(self._free) > self._KEEP:
            self._free.pop(0)
        return self._free[-1][1:]


def _unheld_refcounts() -> tuple[int, int]:
    """The reference counts :meth:`_FrameBuffers.get` sees for an array and its ``xy`` view only it holds."""
    buffer = np.empty(2, dtype=np.complex128)
    free = [(buffer, buffer.reshape(1, 2), buffer.view(np.float64).reshape(-1, 2))]
    del buffer
    for buffer, _out, xy in free:
        return sys.getrefcount(buffer), sys.getrefcount(xy)
    raise AssertionError("unreachable")


_UNHELD_BUFFER, _UNHELD_VIEW = _unheld_refcounts()


def _block_product(left: np.ndarray, table_re: np.ndarray, table_im: np.ndarray, out: np.ndarray) -> None:
    """``out = left @ table`` for one block, each element's terms summed in order j = 0 .. J-1 (compiled).

    Every element is ``sum_j (a_j t_j - b_j u_j) + i (a_j u_j + b_j t_j)`` (a + ib from ``left``, t + iu from
    the table) in plain IEEE arithmetic, accumulated from 0 in term order, so its value depends on its inputs
    alone, never on where the element sits in the block, the vector width, or a library's tiling. Rows go two
    at a time: each table element is loaded once for both.

    Parameters
    ----------
    left : (rows, J) complex128
        The block's left side, P R.
    table_re, table_im : (J, row) float64
        The real and imaginary parts of T.
    out : (rows, row) complex128
        Written: the block's points, x + iy in degrees.
    """
    rows, terms = left.shape
    row = table_re.shape[1]
    x0 = np.empty(row)
    y0 = np.empty(row)
    x1 = np.empty(row)
    y1 = np.empty(row)
    for s in range(0, rows - 1, 2):
        x0[:] = 0.0
        y0[:] = 0.0
        x1[:] = 0.0
        y1[:] = 0.0
        for j in range(terms):
            a0, b0 = left[s, j].real, left[s, j].imag
            a1, b1 = left[s + 1, j].real, left[s + 1, j].imag
            for d in range(row):
                t, u = table_re[j, d], table_im[j, d]
                x0[d] += a0 * t - b0 * u
                y0[d] += a0 * u + b0 * t
                x1[d] += a1 * t - b1 * u
                y1[d] += a1 * u + b1 * t
        for d in range(row):
            out[s, d] = complex(x0[d], y0[d])
            out[s + 1, d] = complex(x1[d], y1[d])
    if rows % 2:
        s = rows - 1
        x0[:] = 0.0
        y0[:] = 0.0
        for j in range(terms):
            a0, b0 = left[s, j].real, left[s, j].imag
            for d in range(row):
                t, u = table_re[j, d], table_im[j, d]
                x0[d] += a0 * t - b0 * u
                y0[d] += a0 * u + b0 * t
        for d in range(row):
            out[s, d] = complex(x0[d], y0[d])


_KERNELS = LazyKernels(globals())


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
