"""Random numbers keyed by a point's stream index: the same seed gives the same numbers however a scan is cut.

A generator drawn in call order would give a point different noise when the
scan is cut into frames differently (a GUI tick, a published frame, a
``--seconds`` run). Here every number is a pure function of ``(seed, purpose,
stream index, column)``: a counter-based generator, the SplitMix64 finalizer
(Steele, Lea and Flood 2014) applied to the counter plus a 64-bit key made
from the seed and the purpose. Normal numbers come two per hash by the
Box-Muller transform of its two 24-bit halves (tails end at 5.8 sigma).
"""

from __future__ import annotations

import numpy as np

_MASK = (1 << 64) - 1
_GAMMA = 0x9E3779B97F4A7C15
_M1 = 0xBF58476D1CE4E5B9
_M2 = 0x94D049BB133111EB
#: Columns per stream index at most: counters are ``index * MAX_COLUMNS + column``.
MAX_COLUMNS = 64


def _mix_int(value: int) -> int:
    z = (value + _GAMMA) & _MASK
    z = ((z ^ (z >> 30)) * _M1) & _MASK
    z = ((z ^ (z >> 27)) * _M2) & _MASK
    return z ^ (z >> 31)


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

    Column pair ``(2k, 2k + 1)`` is the Box-Muller transform of hash ``k``: ``u1`` from its top 24 bits, ``u2``
    from its low 24 bits, ``sqrt(-2 ln u1) (cos, sin)(2 pi u2)``, in float64.

    Returns
    -------
    z : (n, columns) float64
    """
    pairs = (columns + 1) // 2
    z = _hashes(stream_key(seed, purpose), index, pairs)
    scale = 1.0 / (1 << 24)
    u1 = ((z >> np.uint64(40)).astype(np.float64) + 0.5) * scale
    u2 = ((z & np.uint64(0xFFFFFF)).astype(np.float64) + 0.5) * scale
    radius = np.sqrt(-2.0 * np.log(u1))
    angle = 2.0 * np.pi * u2
    out = np.empty((z.shape[0], 2 * pairs), dtype=np.float64)
    out[:, 0::2] = radius * np.cos(angle)
    out[:, 1::2] = radius * np.sin(angle)
    return out[:, :columns]
