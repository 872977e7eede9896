"""The two pattern planes and their rays: boresight-polar angles, or azimuth and elevation.

``"boresight"`` (scan-model.md section 5): a sample (x, y) in degrees is a
direction ``alpha = hypot(x, y)`` off the boresight, rolled by
``beta = atan2(y, x)`` about it, so ``d = (cos a, sin a cos b, -sin a sin b)``.

``"panorama"`` (heads that see all around, :mod:`~livox_viz.config.fov`): x is
the azimuth, positive to the right (about the FRD z axis, which points down),
y the elevation, positive up: ``d = (cos y cos x, cos y sin x, -sin y)``.

Both give unit rays in the sensor frame FRD (x forward along the boresight,
y right, z down). A scan table's rows (``[theta, phi]``: azimuth about +z and
elevation in a frame with x forward, y left, z up) are the FRD ray
``(cos phi cos theta, -cos phi sin theta, -sin phi)``.
"""

from __future__ import annotations

import math

import numpy as np

PLANES: tuple[str, ...] = ("boresight", "panorama")

#: Taylor coefficients of sin(a)/a and cos(a) in u = a^2, lowest first. Within u <= SERIES_LIMIT (a <= 1 rad,
#: 57 degrees off the boresight: every Livox head's field) the first omitted terms are below 1e-19, and the
#: directions are within 2 ulp of libm's (tested); beyond it libm's sin and cos are used.
SIN_RATIO_SERIES: tuple[float, ...] = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(10))
COS_SERIES: tuple[float, ...] = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(11))
SERIES_LIMIT = 1.0


def _series(coefficients: tuple[float, ...], u: np.ndarray) -> np.ndarray:
    """``c0 + u (c1 + u (c2 + ...))``, Horner's order (the order the compiled rays evaluate it in)."""
    value = np.full(u.shape, coefficients[-1])
    for coefficient in coefficients[-2::-1]:
        value *= u
        value += coefficient
    return value


def directions_from_xy(xy_deg: np.ndarray, plane: str = "boresight") -> np.ndarray:
    """Unit ray directions in the sensor FRD frame.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern x, y in ``plane``, degrees.
    plane : {"boresight", "panorama"}

    Returns
    -------
    d : (n, 3) float64
        Unit vectors, x forward, y right, z down.
    """
    xy = np.asarray(xy_deg, dtype=np.float64)
    d = np.empty((xy.shape[0], 3), dtype=np.float64)
    if plane == "panorama":
        xy = np.radians(xy)
        cos_elevation = np.cos(xy[:, 1])
        d[:, 0] = cos_elevation * np.cos(xy[:, 0])
        d[:, 1] = cos_elevation * np.sin(xy[:, 0])
        d[:, 2] = -np.sin(xy[:, 1])
        return d
    _check_plane(plane)
    # x and y as two contiguous rows: every ufunc below runs over unit-stride arrays (a scan makes a direction
    # for every ray, so this is on its hot path).
    x, y = np.multiply(xy.T, math.pi / 180.0)
    square = np.multiply(x, x)
    square += y * y
    # sin(alpha)/alpha and cos(alpha) as series in alpha^2 = x^2 + y^2 (no square root, no division, and 0 on the
    # boresight needs no guard), evaluated in the order the scan's compiled rays use, so both give the same bits.
    ratio = _series(SIN_RATIO_SERIES, square)
    np.multiply(ratio, x, out=d[:, 1])
    np.multiply(ratio, y, out=d[:, 2])
    np.negative(d[:, 2], out=d[:, 2])
    d[:, 0] = _series(COS_SERIES, square)
    far = np.flatnonzero(square > SERIES_LIMIT)
    if far.size:  # beyond the series' reach: libm's sin and cos
        alpha = np.sqrt(square[far])
        far_ratio = np.sin(alpha) / alpha
        d[far, 0] = np.cos(alpha)
        d[far, 1] = far_ratio * x[far]
        d[far, 2] = -(far_ratio * y[far])
    return d


def xy_from_directions(d: np.ndarray, plane: str = "boresight") -> np.ndarray:
    """The inverse of :func:`directions_from_xy` (boresight: rays within 180 degrees of the boresight).

    Parameters
    ----------
    d : (n, 3) float64
        Directions in the sensor FRD frame (need not be unit length).
    plane : {"boresight", "panorama"}

    Returns
    -------
    xy_deg : (n, 2) float64
        Panorama azimuths in [-180, 180].
    """
    d = np.asarray(d, dtype=np.float64)
    if plane == "panorama":
        return np.column_stack([np.degrees(np.arctan2(d[:, 1], d[:, 0])),
                                np.degrees(np.arctan2(-d[:, 2], np.hypot(d[:, 0], d[:, 1])))])
    _check_plane(plane)
    lateral = np.hypot(d[:, 1], d[:, 2])
    alpha = np.arctan2(lateral, d[:, 0])
    scale = np.divide(np.degrees(alpha), lateral, out=np.zeros_like(alpha), where=lateral > 0)
    return np.stack([d[:, 1] * scale, -d[:, 2] * scale], axis=-1)


def frd_from_zup(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """FRD unit rays of scan-table rows: azimuth ``theta`` about +z and elevation ``phi`` (radians; x forward,
    y left, z up).

    Returns
    -------
    d : (n, 3) float64
    """
    theta = np.asarray(theta, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    cos_phi = np.cos(phi)
    return np.column_stack([cos_phi * np.cos(theta), -cos_phi * np.sin(theta), -np.sin(phi)])


def angle_between_deg(xy_a: np.ndarray, xy_b: np.ndarray, plane: str = "boresight") -> np.ndarray:
    """``(n,)`` the angle between the rays of two samples, degrees (exact for small and large angles).

    Parameters
    ----------
    xy_a, xy_b : (n, 2) float64
        Pattern angles in ``plane``.
    plane : {"boresight", "panorama"}
    """
    chord = np.linalg.norm(directions_from_xy(xy_a, plane) - directions_from_xy(xy_b, plane), axis=1)
    return np.degrees(2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0)))


def _check_plane(plane: str) -> None:
    if plane != "boresight":
        raise ValueError(f"pattern plane {plane!r}; allowed: {' or '.join(PLANES)}")
