"""Pattern angles to unit rays in the sensor frame (scan-model.md section 5).

A sample (x, y) in degrees is a direction ``alpha = hypot(x, y)`` off the
boresight, rolled by ``beta = atan2(y, x)`` about it. The sensor frame is FRD
like the platform's: x forward along the boresight, y right, z down; pattern x
points right and pattern y up, so ``d = (cos a, sin a cos b, -sin a sin b)``.
"""

from __future__ import annotations

import numpy as np


def directions_from_xy(xy_deg: np.ndarray) -> np.ndarray:
    """Unit ray directions in the sensor FRD frame.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern x (right), y (up), degrees.

    Returns
    -------
    d : (n, 3) float64
        Unit vectors, x forward, y right, z down.
    """
    xy = np.radians(np.asarray(xy_deg, dtype=np.float64))
    alpha = np.hypot(xy[:, 0], xy[:, 1])
    # sin(alpha)/alpha, which tends to 1 on the boresight.
    ratio = np.sinc(alpha / np.pi)
    d = np.empty((xy.shape[0], 3), dtype=np.float64)
    d[:, 0] = np.cos(alpha)
    d[:, 1] = ratio * xy[:, 0]
    d[:, 2] = -ratio * xy[:, 1]
    return d


def xy_from_directions(d: np.ndarray) -> np.ndarray:
    """The inverse of :func:`directions_from_xy` for rays within 180 degrees of the boresight.

    Parameters
    ----------
    d : (n, 3) float64
        Directions in the sensor FRD frame (need not be unit length).

    Returns
    -------
    xy_deg : (n, 2) float64
    """
    d = np.asarray(d, dtype=np.float64)
    lateral = np.hypot(d[:, 1], d[:, 2])
    alpha = np.arctan2(lateral, d[:, 0])
    scale = np.divide(np.degrees(alpha), lateral, out=np.zeros_like(alpha), where=lateral > 0)
    return np.stack([d[:, 1] * scale, -d[:, 2] * scale], axis=-1)
