"""Random numbers keyed by a point's stream index: the same seed gives the same numbers however a scan is cut.

A generator drawn in call order would give a point different noise when the
scan is cut into frames differently (a GUI tick, a published frame, a
``--seconds`` run). Here every number is a pure function of ``(seed, purpose,
stream index, column)``: a counter-based generator, the SplitMix64 finalizer
(Steele, Lea and Flood 2014) applied to the counter plus a 64-bit key made
from the seed and the purpose. Normal numbers come two per hash, one from each
32-bit half, by the ziggurat method (Marsaglia and Tsang 2000; 128 layers after
Doornik 2005): 97 % of them are one multiplication, the rest (a layer's edge, the
tail beyond 3.44 sigma, sampled exactly) draw on a second stream of the same
key, so every number is still a pure function of its stream index and column.
"""

from __future__ import annotations

import math

import numpy as np

_MASK = (1 << 64) - 1
_GAMMA = 0x9E3779B97F4A7C15
_M1 = 0xBF58476D1CE4E5B9
_M2 = 0x94D049BB133111EB
#: Columns per stream index at most: counters are ``index * MAX_COLUMNS + column``.
MAX_COLUMNS = 64


#: The ziggurat's base strip's edge R and each layer's area V (128 layers: Marsaglia and Tsang 2000).
ZIGGURAT_R = 3.442619855899
ZIGGURAT_V = 9.91256303526217e-3
ZIGGURAT_LAYERS = 128
#: Mixed into the key of the second stream (retries of a layer's edge, the tail).
RETRY_MASK = 0xD1B54A32D192ED03
#: Retries a number may draw at most (2.8 % of numbers need one; 63 in a row does not happen).
RETRIES = 63
_UNIT_24 = 1.0 / (1 << 24)


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, ratio, f)``: the layers' right edges x_0 > x_1 = R > ... > x_127 > x_128 = 0 (x_0 = V / f(R), the base
    strip's width with its tail's area), ``ratio[i] = x_(i+1) / x_i`` (a draw below it is under the curve), and
    ``f(x_i) = exp(-x_i^2 / 2)``."""
    x = np.zeros(ZIGGURAT_LAYERS + 1)
    x[0] = ZIGGURAT_V / math.exp(-0.5 * ZIGGURAT_R * ZIGGURAT_R)
    x[1] = ZIGGURAT_R
    for i in range(2, ZIGGURAT_LAYERS):
        x[i] = math.sqrt(-2.0 * math.log(ZIGGURAT_V / x[i - 1] + math.exp(-0.5 * x[i - 1] * x[i - 1])))
    return x, x[1:] / x[:-1], np.exp(-0.5 * x * x)


ZIGGURAT_X, ZIGGURAT_RATIO, ZIGGURAT_F = _ziggurat_tables()


def _finalize_int(z: int) -> int:
    """SplitMix64's finalizer on a Python integer (what :func:`_mix` does to each element)."""
    z = ((z ^ (z >> 30)) * _M1) & _MASK
    z = ((z ^ (z >> 27)) * _M2) & _MASK
    return z ^ (z >> 31)


def _mix_int(value: int) -> int:
    return _finalize_int((value + _GAMMA) & _MASK)


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer on a ``uint64`` array (in place; numpy's uint64 arithmetic wraps)."""
    z ^= z >> np.uint64(30)
    z *= np.uint64(_M1)
    z ^= z >> np.uint64(27)
    z *= np.uint64(_M2)
    z ^= z >> np.uint64(31)
    return z


def stream_key(seed: int, purpose: int) -> int:
    """The 64-bit key of one purpose's numbers under ``seed`` (both whole numbers >= 0)."""
    return _mix_int(_mix_int(seed & _MASK) ^ ((purpose * _GAMMA) & _MASK))


def _hashes(key: int, index: np.ndarray, columns: int) -> np.ndarray:
    if not 1 <= columns <= MAX_COLUMNS:
        raise ValueError(f"columns {columns}; allowed: 1 to {MAX_COLUMNS}")
    counter = np.asarray(index, dtype=np.int64).astype(np.uint64)[:, None] * np.uint64(MAX_COLUMNS)
    counter = counter + np.arange(columns, dtype=np.uint64)[None, :]
    counter += np.uint64(key)
    counter *= np.uint64(_GAMMA)
    return _mix(counter)


def stream_uniform(seed: int, purpose: int, index: np.ndarray, columns: int = 1) -> np.ndarray:
    """Uniform numbers in (0, 1), one row per stream index.

    Parameters
    ----------
    seed, purpose : int
    index : (n,) int64
        Stream indices (>= 0).
    columns : int
        Numbers per index.

    Returns
    -------
    u : (n, columns) float64
    """
    z = _hashes(stream_key(seed, purpose), index, columns)
    return ((z >> np.uint64(11)).astype(np.float64) + 0.5) * (1.0 / (1 << 53))


def stream_normal(seed: int, purpose: int, index: np.ndarray, columns: int = 1) -> np.ndarray:
    """Standard normal numbers, one row per stream index.

    Column pair ``(2k, 2k + 1)`` comes from hash ``k``: column ``2k`` from its low 32 bits, ``2k + 1`` from its
    high ones, each by the ziggurat (:func:`ziggurat_normal`; bits 0-6 the layer, bit 7 the sign, bits 8-31 the
    uniform).

    Returns
    -------
    z : (n, columns) float64
    """
    pairs = (columns + 1) // 2
    key = stream_key(seed, purpose)
    index = np.asarray(index, dtype=np.int64).reshape(-1)
    z = _hashes(key, index, pairs)
    bits = np.empty((z.shape[0], 2 * pairs), dtype=np.uint64)
    bits[:, 0::2] = z & np.uint64(0xFFFFFFFF)
    bits[:, 1::2] = z >> np.uint64(32)
    layer = (bits & np.uint64(ZIGGURAT_LAYERS - 1)).astype(np.int64)
    u = (((bits >> np.uint64(8)) & np.uint64(0xFFFFFF)).astype(np.float64) + 0.5) * _UNIT_24
    out = u * ZIGGURAT_X[layer]
    for row, column in np.argwhere(u >= ZIGGURAT_RATIO[layer]):  # the 2.8 % past their layer's inner part
        out[row, column] = ziggurat_normal(int(bits[row, column]), key, retry_counter(int(index[row]), int(column)))
    out[(bits >> np.uint64(7)) & np.uint64(1) == 1] *= -1.0
    return out[:, :columns]


def retry_counter(index: int, column: int) -> int:
    """The first counter of the second stream that normal ``column`` at ``index`` retries with (64 a number)."""
    return (index * MAX_COLUMNS + column) * (RETRIES + 1)


def ziggurat_normal(bits: int, key: int, counter: int) -> float:
    """The absolute value of the normal number of 32 ``bits`` (its sign is bit 7), drawing retries from the second
    stream of ``key`` at ``counter``, ``counter + 1``, ... (see :func:`stream_normal`).

    A draw ``u`` (bits 8-31) in layer ``i`` (bits 0-6) is ``u x_i`` when ``u`` is below ``x_(i+1) / x_i``. Past it
    in a layer above the base, it stands when a uniform height in the layer lies under the curve, else the next
    retry is a new draw; in the base strip, it is the tail: ``R + a`` with ``a = -ln(u1) / R``, kept when
    ``-2 ln(u2) >= a^2``. The compiled loops do the same in the same order
    (:func:`~livox_viz.casting.return_kernels._ziggurat`).
    """
    layer = bits & (ZIGGURAT_LAYERS - 1)
    u = (((bits >> 8) & 0xFFFFFF) + 0.5) * _UNIT_24
    retry_key = key ^ RETRY_MASK
    taken = 0
    while True:
        if u < ZIGGURAT_RATIO[layer]:
            return float(u * ZIGGURAT_X[layer])
        w = _hash_int(retry_key, counter + taken)
        taken += 1
        if layer == 0:
            while True:
                a = -math.log(((w >> 40) + 0.5) * _UNIT_24) / ZIGGURAT_R
                b = -math.log((((w >> 8) & 0xFFFFFF) + 0.5) * _UNIT_24)
                if b + b >= a * a or taken >= RETRIES:
                    return ZIGGURAT_R + a
                w = _hash_int(retry_key, counter + taken)
                taken += 1
        x = float(u * ZIGGURAT_X[layer])
        height = ZIGGURAT_F[layer] + ((w >> 40) + 0.5) * _UNIT_24 * (ZIGGURAT_F[layer + 1] - ZIGGURAT_F[layer])
        if height < math.exp(-0.5 * x * x) or taken >= RETRIES:
            return x
        layer = w & (ZIGGURAT_LAYERS - 1)
        u = (((w >> 8) & 0xFFFFFF) + 0.5) * _UNIT_24


def _hash_int(key: int, counter: int) -> int:
    """One hash of :func:`_hashes`, in Python integers."""
    return _finalize_int(((counter + key) * _GAMMA) & _MASK)
