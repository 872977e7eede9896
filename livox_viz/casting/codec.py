"""The int16 point encoding RflySim publishes (scan-model.md section 4).

``x_int = round(x / range_max * 32767)`` clipped to [-32767, 32767]; a client
decodes ``x = x_int / 32767 * range_max``. Inside [-range_max, range_max] the
decoding error is at most ``range_max / 65534`` per axis (half a step).
"""

from __future__ import annotations

import numpy as np

INT16_SCALE = 32767


def encode_int16(xyz: np.ndarray, range_max: float) -> np.ndarray:
    """Encode metres as RflySim's int16 values.

    Parameters
    ----------
    xyz : (..., 3) float64
        Coordinates in metres (any shape; every value is encoded alike).
    range_max : float
        The scale, metres (``otherParams[0]``).

    Returns
    -------
    xyz_int : (..., 3) int16
        Rounded to nearest, clipped to [-32767, 32767].
    """
    scaled = np.asarray(xyz, dtype=np.float64) * (INT16_SCALE / range_max)
    np.rint(scaled, out=scaled)
    np.clip(scaled, -INT16_SCALE, INT16_SCALE, out=scaled)
    return scaled.astype(np.int16)


def decode_int16(xyz_int: np.ndarray, range_max: float) -> np.ndarray:
    """Decode RflySim's int16 values to metres: ``x_int / 32767 * range_max``.

    Parameters
    ----------
    xyz_int : (..., 3) int16
    range_max : float
        The scale, metres.

    Returns
    -------
    xyz : (..., 3) float64
    """
    return np.asarray(xyz_int, dtype=np.float64) / INT16_SCALE * range_max


def max_decode_error(range_max: float) -> float:
    """The largest per-axis decoding error inside the range, ``range_max / 65534`` metres."""
    return range_max / (2 * INT16_SCALE)
