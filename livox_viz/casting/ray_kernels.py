"""The scan's per-ray steps before and after the cast, compiled (numba, ``nogil``).

A scan turns every pattern sample into a sensor-frame direction and a world
direction before the cast, and every ideal hit into its sensor-frame and world
points and its int16 encoding after it. In numpy that took a pass an operation
(two dozen over every ray) and was as dear as the cast itself: 100 ns a ray
against Embree's 130 ns on the default scene (measured, one thread). Here each
side is one pass that releases the GIL, so both frames cast side by side run it
at once.

The numbers are those of the numpy steps they replace, bit for bit:
:func:`~livox_viz.patterns.planes.directions_from_xy` (the same series, and
libm's ``sin`` and ``cos`` beyond them, operations in the same order, no
``fastmath``),
:func:`~livox_viz.core.rotations.rotate_rows` (``(x R[i,0] + y R[i,1]) + z
R[i,2]``) and :func:`~livox_viz.casting.codec.encode_int16` (``rint``, then the
clip); the tests hold them to each other.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from livox_viz.casting.codec import INT16_SCALE
from livox_viz.core.buffers import RecycledBlocks, carve, carved_size
from livox_viz.core.compiled import LazyKernels
from livox_viz.patterns.planes import COS_SERIES, PLANES, SERIES_LIMIT, SIN_RATIO_SERIES

#: A (0, 3) float64 argument for "none" (no rotation, no world rays): the loops test its length.
_NONE = np.empty((0, 3), dtype=np.float64)
_SCRATCH = threading.local()
_NO_TIMES = np.empty(0, dtype=np.float64)
#: Where the ideal points' arrays live: a frame's arrays are handed out and dropped a moment later, so their
#: blocks are reused instead of faulted in afresh (see :mod:`livox_viz.core.buffers`).
POINT_BLOCKS = RecycledBlocks()


def sensor_rays(xy_deg: np.ndarray, plane: str, rotation: np.ndarray | None = None, scratch: bool = False,
                world_dtype: type = np.float64) -> tuple[np.ndarray, np.ndarray | None]:
    """The rays of pattern samples in the sensor frame and, given the sensor's rotation, in the world.

    Parameters
    ----------
    xy_deg : (n, 2) float64
        Pattern x, y in ``plane``, degrees.
    plane : {"boresight", "panorama"}
        See :func:`~livox_viz.patterns.planes.directions_from_xy`.
    rotation : (3, 3) float64, optional
        Sensor FRD -> world NED.
    scratch : bool
        Write into the calling thread's scratch arrays instead of new ones: they are overwritten by its next
        call with ``scratch``. Fresh arrays of a frame's rays cost more in page faults than the kernel itself
        (12 of 27 ns a ray, measured), so a caller that is done with them before its next call reuses them.
    world_dtype : {numpy.float64, numpy.float32}
        Of the world directions: float32 is what Embree takes (the float64 ones rounded), for a caller that
        needs them for the cast alone.

    Returns
    -------
    directions_sensor : (n, 3) float64
        Unit vectors, sensor FRD: ``directions_from_xy(xy_deg, plane)``.
    directions_world : (n, 3) float64 (or float32) or None
        ``rotate_rows(directions_sensor, rotation)``, world NED; None without a rotation.
    """
    if plane not in PLANES:
        raise ValueError(f"pattern plane {plane!r}; allowed: {' or '.join(PLANES)}")
    xy = np.ascontiguousarray(xy_deg, dtype=np.float64).reshape(-1, 2)
    count = xy.shape[0]
    sensor, world = ((scratch_rows("sensor", count), scratch_rows("world", count, world_dtype)) if scratch
                     else (np.empty((count, 3)), np.empty((count, 3), dtype=world_dtype)))
    if rotation is None:
        _KERNELS("rays")(xy, plane == "panorama", _NONE, sensor, _NONE)
        return sensor, None
    _KERNELS("rays")(xy, plane == "panorama", np.ascontiguousarray(rotation, dtype=np.float64), sensor, world)
    return sensor, world


def scratch_rows(name: str, count: int, dtype: type = np.float64) -> np.ndarray:
    """The calling thread's ``(count, 3)`` scratch array ``name`` (grown when too short).

    Its contents are undefined and overwritten by the thread's next use of the same name and dtype: for arrays a
    caller is done with before then (see ``scratch`` of :func:`sensor_rays`).
    """
    key = f"{name}_{np.dtype(dtype).name}"
    held = getattr(_SCRATCH, key, None)
    if held is None or held.shape[0] < count:
        held = np.empty((count, 3), dtype=dtype)
        setattr(_SCRATCH, key, held)
    return held[:count]


def ideal_points(distance: np.ndarray, directions_sensor: np.ndarray, directions_world: np.ndarray | None,
                 origins: np.ndarray, xy_deg: np.ndarray, t: np.ndarray | None, first_index: int, point_rate: float,
                 range_max: float, rotation: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The ideal returns of cast rays: each ray that met something within range, its points and encoding.

    A ray returns when its distance is finite and its int16 encoding is not (0, 0, 0) (a point nearer than
    half a step, which a client would read as "no return"). The arrays are views of one block of
    :data:`POINT_BLOCKS`, used again once nothing holds any of them.

    Parameters
    ----------
    distance : (n,) float64
        Each ray's distance to its first hit, metres; ``inf`` (or NaN) for none.
    directions_sensor : (n, 3) float64
        The rays, sensor FRD.
    directions_world : (n, 3) float64 or None
        The rays, world NED; None: ``rotate_rows(directions_sensor, rotation)`` for the hits alone (the same
        numbers).
    origins : (1, 3) or (n, 3) float64
        The rays' origin(s), world NED, metres.
    xy_deg : (n, 2) float64
        The rays' pattern angles, degrees.
    t : (n,) float64 or None
        Their emission times, seconds; None for the stream's own, ``stream index / point_rate``.
    first_index : int
        Stream index of the first ray.
    point_rate : float
        Points per second of the stream.
    range_max : float
        The int16 scale, metres.
    rotation : (3, 3) float64, optional
        Sensor FRD -> world NED, when ``directions_world`` is None.

    Returns
    -------
    dict of (m,) arrays
        ``stream_index`` int64, ``t``, ``xy_deg`` (m, 2), ``range_m``, ``xyz_sensor`` (m, 3) and
        ``xyz_world`` (m, 3) float64, ``xyz_int16`` (m, 3) int16: the returning rays in order.
    """
    hits = int(np.count_nonzero(distance < np.inf))
    layout = [("stream_index", (hits,), np.int64), ("t", (hits,), np.float64), ("xy_deg", (hits, 2), np.float64),
              ("range_m", (hits,), np.float64), ("xyz_sensor", (hits, 3), np.float64),
              ("xyz_world", (hits, 3), np.float64), ("xyz_int16", (hits, 3), np.int16)]
    found = carve(POINT_BLOCKS.get(carved_size(layout)), layout)
    count = _KERNELS("ideal_points")(
        np.ascontiguousarray(distance, dtype=np.float64), np.ascontiguousarray(directions_sensor),
        _NONE if directions_world is None else np.ascontiguousarray(directions_world, dtype=np.float64),
        _NONE if directions_world is not None else np.ascontiguousarray(rotation, dtype=np.float64),
        np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(xy_deg, dtype=np.float64),
        _NO_TIMES if t is None else np.ascontiguousarray(t, dtype=np.float64), first_index, float(point_rate),
        INT16_SCALE / range_max, *found.values())
    return found if count == hits else {name: values[:count] for name, values in found.items()}


def _sin_ratio(u):  # pragma: no cover - compiled, inlined
    """sin(a)/a of ``u = a^2``: :data:`~livox_viz.patterns.planes.SIN_RATIO_SERIES` in Horner's order."""
    c = SIN_RATIO_SERIES
    return c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * (c[5] + u * (c[6] + u * (c[7] + u * (
        c[8] + u * c[9]))))))))


def _cos_series(u):  # pragma: no cover - compiled, inlined
    """cos(a) of ``u = a^2``: :data:`~livox_viz.patterns.planes.COS_SERIES` in Horner's order."""
    c = COS_SERIES
    return c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * (c[5] + u * (c[6] + u * (c[7] + u * (
        c[8] + u * (c[9] + u * c[10])))))))))


def _rays(xy, panorama, rotation, sensor, world):  # pragma: no cover - compiled
    """``sensor = directions_from_xy(xy)``; ``world = rotate_rows(sensor, rotation)`` unless ``world`` is empty.

    The boresight plane's rays as :func:`~livox_viz.patterns.planes.directions_from_xy` makes them: the series
    in alpha^2 (no sqrt, sin, cos or division: 23 -> 15 ns a ray), then libm's sin and cos for the rare rays
    beyond the series' reach, in a second pass so that the first has no call in it.
    """
    turn = world.shape[0] > 0
    r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = 0.0
    if turn:
        r00, r01, r02 = rotation[0, 0], rotation[0, 1], rotation[0, 2]
        r10, r11, r12 = rotation[1, 0], rotation[1, 1], rotation[1, 2]
        r20, r21, r22 = rotation[2, 0], rotation[2, 1], rotation[2, 2]
    scale = math.pi / 180.0
    # Pass 0 makes every ray (the boresight's by the series); pass 1, only when needed, makes again with libm
    # the boresight rays beyond the series' reach.
    far = False
    for beyond in (False, True):
        if beyond and not far:
            break
        for i in range(xy.shape[0]):
            x = xy[i, 0] * scale
            y = xy[i, 1] * scale
            if panorama:
                cos_elevation = math.cos(y)
                d0 = cos_elevation * math.cos(x)
                d1 = cos_elevation * math.sin(x)
                d2 = -math.sin(y)
            else:
                square = x * x + y * y
                if beyond:
                    if square <= SERIES_LIMIT:
                        continue
                    alpha = math.sqrt(square)
                    ratio = math.sin(alpha) / alpha
                    d0 = math.cos(alpha)
                else:
                    far |= square > SERIES_LIMIT
                    ratio = _sin_ratio(square)
                    d0 = _cos_series(square)
                d1 = ratio * x
                d2 = -(ratio * y)
            sensor[i, 0] = d0
            sensor[i, 1] = d1
            sensor[i, 2] = d2
            if turn:
                world[i, 0] = (d0 * r00 + d1 * r01) + d2 * r02
                world[i, 1] = (d0 * r10 + d1 * r11) + d2 * r12
                world[i, 2] = (d0 * r20 + d1 * r21) + d2 * r22


def _ideal_points(distance, sensor, world, rotation, origins, xy, t, first_index, point_rate, scale,
                  index_out, t_out, xy_out, range_out, sensor_out, world_out, int16_out):  # pragma: no cover
    """See :func:`ideal_points`; the outputs hold at least the finite distances; returns the points written.

    An empty ``t``: each time is ``float(stream index) / point_rate``, what ``np.arange(...) / point_rate``
    gives, so no array of every ray's time is made to read only the hits'.
    """
    shared = origins.shape[0] == 1
    given = t.shape[0] > 0
    turn = world.shape[0] == 0
    r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = 0.0
    if turn:
        r00, r01, r02 = rotation[0, 0], rotation[0, 1], rotation[0, 2]
        r10, r11, r12 = rotation[1, 0], rotation[1, 1], rotation[1, 2]
        r20, r21, r22 = rotation[2, 0], rotation[2, 1], rotation[2, 2]
    count = 0
    for i in range(distance.shape[0]):
        r = distance[i]
        if not r < np.inf:
            continue
        s0 = sensor[i, 0] * r
        s1 = sensor[i, 1] * r
        s2 = sensor[i, 2] * r
        q0 = np.rint(s0 * scale)
        q1 = np.rint(s1 * scale)
        q2 = np.rint(s2 * scale)
        if q0 == 0.0 and q1 == 0.0 and q2 == 0.0:
            continue
        o = 0 if shared else i
        index_out[count] = first_index + i
        t_out[count] = t[i] if given else (first_index + i) / point_rate
        xy_out[count, 0] = xy[i, 0]
        xy_out[count, 1] = xy[i, 1]
        range_out[count] = r
        sensor_out[count, 0] = s0
        sensor_out[count, 1] = s1
        sensor_out[count, 2] = s2
        if turn:
            d0, d1, d2 = sensor[i, 0], sensor[i, 1], sensor[i, 2]
            w0 = (d0 * r00 + d1 * r01) + d2 * r02
            w1 = (d0 * r10 + d1 * r11) + d2 * r12
            w2 = (d0 * r20 + d1 * r21) + d2 * r22
        else:
            w0, w1, w2 = world[i, 0], world[i, 1], world[i, 2]
        world_out[count, 0] = w0 * r + origins[o, 0]
        world_out[count, 1] = w1 * r + origins[o, 1]
        world_out[count, 2] = w2 * r + origins[o, 2]
        int16_out[count, 0] = np.int16(min(max(q0, -32767.0), 32767.0))
        int16_out[count, 1] = np.int16(min(max(q1, -32767.0), 32767.0))
        int16_out[count, 2] = np.int16(min(max(q2, -32767.0), 32767.0))
        count += 1
    return count


#: The loops above, compiled on first use (the series helpers compiled into them).
_KERNELS = LazyKernels(globals(), helpers=("_sin_ratio", "_cos_series"))
