"""The datasheet return model's per-pulse loops, compiled (numba, ``nogil``).

Each loop here replaces dozens of numpy passes over every pulse (measured:
the numpy version of the model cost three to four times its scan's ideal
rays); :mod:`~livox_viz.casting.returns` calls them and says what they compute.
numba is already a dependency for the moving sensor's per-ray kernel.

Every random number comes from the counter-based generator of
:mod:`~livox_viz.core.streamrandom`, written out here the same way (SplitMix64
of ``(stream index * 64 + column + key) * gamma``; normal numbers by the
ziggurat of the hash's two 32-bit halves, in the same steps): the tests hold the
two implementations to each other.
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.core.compiled import LazyKernels
from livox_viz.core.streamrandom import (
    RETRIES,
    RETRY_MASK,
    ZIGGURAT_F,
    ZIGGURAT_LAYERS,
    ZIGGURAT_R,
    ZIGGURAT_RATIO,
    ZIGGURAT_X,
)

#: The small functions the loops call: compiled (in this module's namespace) before the first loop is.
_HELPERS = ("_hash", "_ziggurat", "_normal_pair", "_uniform", "_sigma", "_plane_range", "_slab_span", "_slab",
            "_round_bounds", "_in_round", "_in_planes", "_near_flat", "_basis_at", "_byte", "_point_direction",
            "_decodes_within")


#: The loops that would run their pulses on every core (``prange``). None does: on this 2-core machine shared
#: with Embree's two threads (and others' work) numba's parallel regions cost ten times what they save (measured).
_PARALLEL: tuple[str, ...] = ()


def _use_prange(namespace: dict) -> None:
    import numba

    namespace["prange"] = numba.prange


#: ``kernel(name)``: the compiled loop ``_name`` (compiled, or loaded from numba's cache, on first use, once
#: across threads: frames are cast on worker threads).
kernel = LazyKernels(globals(), helpers=_HELPERS, options=lambda name: {"parallel": name in _PARALLEL},
                     prepare=_use_prange, called=("_ziggurat_edge",))
#: The loops compiled so far, by name.
_KERNELS = kernel.compiled


#: How much larger than an object its boxes, sphere and planes are when a ray of a footprint is tested against
#: them, metres (a ray along a face or an edge rounds either way, and Embree may still meet it there).
HULL_PAD_M = 1e-3

#: ``numba.prange`` once the loops are compiled (plain ``range`` before, so the module imports without numba).
prange = range


# Counter-based random numbers (the same as core.streamrandom) -------------------------------------------------------
_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _hash(key, counter):  # pragma: no cover - compiled
    z = (counter + key) * _GAMMA
    z ^= z >> np.uint64(30)
    z *= _M1
    z ^= z >> np.uint64(27)
    z *= _M2
    z ^= z >> np.uint64(31)
    return z


_ZIG_X, _ZIG_RATIO, _ZIG_F = ZIGGURAT_X, ZIGGURAT_RATIO, ZIGGURAT_F
_ZIG_R = ZIGGURAT_R
_RETRY_MASK = np.uint64(RETRY_MASK)
_UNIT_24 = 1.0 / 16777216.0


def _ziggurat(bits, key, counter):  # pragma: no cover - compiled
    """:func:`~livox_viz.core.streamrandom.ziggurat_normal` with its sign: the normal number of 32 ``bits``, in
    the same steps (a layer's inner part: one multiplication; its edge and the tail: retries from the second
    stream of ``key`` at ``counter``, ``counter + 1``, ...)."""
    layer = int(bits & np.uint64(ZIGGURAT_LAYERS - 1))
    negative = (bits >> np.uint64(7)) & np.uint64(1)
    u = (float((bits >> np.uint64(8)) & np.uint64(0xFFFFFF)) + 0.5) * _UNIT_24
    x = u * _ZIG_X[layer] if u < _ZIG_RATIO[layer] else _ziggurat_edge(layer, u, key, counter)
    return -x if negative else x


def _ziggurat_edge(layer, u, key, counter):  # pragma: no cover - compiled
    """The rare steps of :func:`_ziggurat` (a draw past its layer's inner part: 1 in 36), a function of its
    own: inlined with the rest, at the dozen places the point loop draws normal numbers, they made that loop's
    first compile take 28 s of the datasheet model's 49 (12 s now)."""
    x = u * _ZIG_X[layer]
    retry_key = key ^ _RETRY_MASK
    taken = 0
    while True:
        w = _hash(retry_key, counter + np.uint64(taken))
        taken += 1
        if layer == 0:
            while True:
                a = -math.log((float(w >> np.uint64(40)) + 0.5) * _UNIT_24) / _ZIG_R
                b = -math.log((float((w >> np.uint64(8)) & np.uint64(0xFFFFFF)) + 0.5) * _UNIT_24)
                if b + b >= a * a or taken >= RETRIES:
                    break
                w = _hash(retry_key, counter + np.uint64(taken))
                taken += 1
            x = _ZIG_R + a
            break
        x = u * _ZIG_X[layer]
        height = _ZIG_F[layer] + (float(w >> np.uint64(40)) + 0.5) * _UNIT_24 * (_ZIG_F[layer + 1] - _ZIG_F[layer])
        if height < math.exp(-0.5 * x * x) or taken >= RETRIES:
            break
        layer = int(w & np.uint64(ZIGGURAT_LAYERS - 1))  # a new draw; the sign stays the first one's
        u = (float((w >> np.uint64(8)) & np.uint64(0xFFFFFF)) + 0.5) * _UNIT_24
        x = u * _ZIG_X[layer]
        if u < _ZIG_RATIO[layer]:
            break
    return x


def _normal_pair(key, index, pair):  # pragma: no cover - compiled
    """Columns ``2 pair`` and ``2 pair + 1`` of :func:`~livox_viz.core.streamrandom.stream_normal` at ``index``:
    the ziggurat of the hash's low and high 32 bits."""
    z = _hash(key, np.uint64(index) * np.uint64(64) + np.uint64(pair))
    retries = np.uint64(RETRIES + 1)
    first = (np.uint64(index) * np.uint64(64) + np.uint64(2 * pair)) * retries  # retry_counter(index, 2 pair)
    return _ziggurat(z & np.uint64(0xFFFFFFFF), key, first), _ziggurat(z >> np.uint64(32), key, first + retries)


def _uniform(key, index, column):  # pragma: no cover - compiled
    """Column ``column`` of :func:`~livox_viz.core.streamrandom.stream_uniform` at ``index``."""
    z = _hash(key, np.uint64(index) * np.uint64(64) + np.uint64(column))
    return (float(z >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


def _sigma(range_m, table):  # pragma: no cover - compiled
    """The range noise table ``(k, 2)`` at ``range_m``: linear between its rows, flat outside."""
    if range_m <= table[0, 0]:
        return table[0, 1]
    last = table.shape[0] - 1
    if range_m >= table[last, 0]:
        return table[last, 1]
    k = 0
    while table[k + 1, 0] < range_m:
        k += 1
    share = (range_m - table[k, 0]) / (table[k + 1, 0] - table[k, 0])
    return table[k, 1] + share * (table[k + 1, 1] - table[k, 1])


# The rays ----------------------------------------------------------------------------------------------------------
def _sensor_basis(xy_deg, panorama, out_x, out_y):  # pragma: no cover - compiled
    """The directions each ray's footprint spreads along, sensor frame (:func:`_basis_at` of every row)."""
    for i in range(xy_deg.shape[0]):
        out_x[i, 0], out_x[i, 1], out_x[i, 2], out_y[i, 0], out_y[i, 1], out_y[i, 2] = _basis_at(
            xy_deg[i, 0], xy_deg[i, 1], panorama)


def _basis_at(x_deg, y_deg, panorama):  # pragma: no cover - compiled
    """The directions one ray's footprint spreads along, sensor frame (six numbers: along x, then along y).

    Boresight plane: the derivatives of the ray by pattern x and y, per radian. The ray is ``(cos a, s x, -s y)``,
    ``a = |(x, y)|``, ``s = sin(a)/a``; with ``q = (a cos a - sin a)/a^3`` (-1/3 at the boresight):
    ``d/dx = (-s x, s + x^2 q, -x y q)``, ``d/dy = (-s y, x y q, -(s + y^2 q))``. Panorama plane (x the azimuth,
    y the elevation): the unit azimuth and elevation tangents, ``(-sin x, cos x, 0)`` and
    ``(-sin y cos x, -sin y sin x, -cos y)`` (a panoramic head's divergence is H along the azimuth, V along the
    elevation).
    """
    scale = math.pi / 180.0
    x = x_deg * scale
    y = y_deg * scale
    if panorama:
        sin_x, cos_x, sin_y = math.sin(x), math.cos(x), math.sin(y)
        return -sin_x, cos_x, 0.0, -sin_y * cos_x, -sin_y * sin_x, -math.cos(y)
    alpha = math.sqrt(x * x + y * y)
    if alpha < 1e-3:
        s = 1.0 - alpha * alpha / 6.0
        q = -1.0 / 3.0 + alpha * alpha / 30.0
    else:
        s = math.sin(alpha) / alpha
        q = (alpha * math.cos(alpha) - math.sin(alpha)) / (alpha * alpha * alpha)
    return -s * x, s + x * x * q, -x * y * q, -s * y, x * y * q, -(s + y * y * q)


def _offset_rays(rows, directions, xy_deg, panorama, rotation, basis_x, basis_y, offsets,
                 out):  # pragma: no cover - compiled
    """Unit directions of the rays at ``offsets`` ``(k, 2)`` radians around each beam ``rows``: ``out (m, k, 3)``.

    The directions a beam's footprint spreads along come from its pattern angles (in the ``panorama`` plane or
    the boresight one) and ``rotation`` (a fixed sensor: ``basis_x`` empty), else from ``basis_x``, ``basis_y``
    (per pulse, world frame).
    """
    fixed = basis_x.shape[0] == 0
    for r in range(rows.shape[0]):
        i = rows[r]
        if fixed:
            ax, ay, az, bx, by, bz = _basis_at(xy_deg[i, 0], xy_deg[i, 1], panorama)
            wx0 = rotation[0, 0] * ax + rotation[0, 1] * ay + rotation[0, 2] * az
            wx1 = rotation[1, 0] * ax + rotation[1, 1] * ay + rotation[1, 2] * az
            wx2 = rotation[2, 0] * ax + rotation[2, 1] * ay + rotation[2, 2] * az
            wy0 = rotation[0, 0] * bx + rotation[0, 1] * by + rotation[0, 2] * bz
            wy1 = rotation[1, 0] * bx + rotation[1, 1] * by + rotation[1, 2] * bz
            wy2 = rotation[2, 0] * bx + rotation[2, 1] * by + rotation[2, 2] * bz
        else:
            wx0, wx1, wx2 = basis_x[i, 0], basis_x[i, 1], basis_x[i, 2]
            wy0, wy1, wy2 = basis_y[i, 0], basis_y[i, 1], basis_y[i, 2]
        for k in range(offsets.shape[0]):
            a, b = offsets[k, 0], offsets[k, 1]
            x = directions[i, 0] + a * wx0 + b * wy0
            y = directions[i, 1] + a * wx1 + b * wy1
            z = directions[i, 2] + a * wx2 + b * wy2
            inverse = 1.0 / math.sqrt(x * x + y * y + z * z)
            out[r, k, 0] = x * inverse
            out[r, k, 1] = y * inverse
            out[r, k, 2] = z * inverse


# Step 1 and 2: the central hits, and whether the footprint leaves the triangle --------------------------------------
def _plane_distance(triangle, directions, origins, planes, range_max, distance):  # pragma: no cover - compiled
    """Each ray's distance to the plane of the triangle it hit, float64 (``inf`` for a miss); -1 where the plane
    cannot say (a ray along it), for Embree's own distance. Returns how many those are."""
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    unresolved = 0
    for i in range(triangle.shape[0]):
        t = triangle[i]
        if t < 0:
            distance[i] = np.inf
            continue
        o = i * stride
        distance[i] = _plane_range(planes[t, 0], planes[t, 1], planes[t, 2], planes[t, 3], origins[o, 0],
                                   origins[o, 1], origins[o, 2], float(directions[i, 0]), float(directions[i, 1]),
                                   float(directions[i, 2]), range_max)
        if distance[i] < 0.0:
            unresolved += 1
    return unresolved


def _plane_range(nx, ny, nz, offset, ox, oy, oz, ux, uy, uz, range_max):  # pragma: no cover - compiled
    """How far the ray from o along u meets the plane ``n . x = offset``, at most ``range_max``; -1 where the plane
    cannot say (the ray along it, or the plane behind or beyond the range)."""
    along = nx * ux + ny * uy + nz * uz
    height = offset - (nx * ox + ny * oy + nz * oz)
    d = height / along if abs(along) > 1e-9 else -1.0
    if not (0.0 <= d <= range_max * (1.0 + 1e-9)):
        return -1.0
    return min(d, range_max)



def _central(distance, triangle, directions, origins, xy_deg, panorama, rotation, basis_x, basis_y, planes, brightness,
             incentre, inradius, inward, offset, neighbour, narrowest, half_x, half_y, tan_half, calibration,
             range_max, power, unit, leaves, reach):  # pragma: no cover - compiled
    """Per pulse: echo power of the whole footprint on the hit triangle, the reflectance one unit of power means at
    its range (for its reflectivity byte), whether the
    footprint leaves the triangle (an edge that does not continue the surface within its reach), and how far
    along the beam the footprint can meet something.

    ``origins`` is ``(1, 3)`` for a fixed sensor, whose footprint's directions come from ``xy_deg`` (in the
    ``panorama`` plane or the boresight one) and ``rotation``; a moving one gives them per pulse (``basis_x``,
    ``basis_y``, world frame). ``calibration`` = (reflectivity a,
    range a, alpha): power = rho cos (r_a^2 / rho_a) / r^2 exp(-2 alpha (r - r_a)).
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    fixed = basis_x.shape[0] == 0
    rho_a, r_a, alpha = calibration[0], calibration[1], calibration[2]
    for i in prange(distance.shape[0]):
        t = triangle[i]
        reach[i] = range_max
        leaves[i] = False
        if t < 0:
            power[i] = 0.0
            unit[i] = 0.0
            continue
        o = i * stride
        d = distance[i]
        ux, uy, uz = directions[i, 0], directions[i, 1], directions[i, 2]
        nx, ny, nz = planes[t, 0], planes[t, 1], planes[t, 2]
        facing = nx * ux + ny * uy + nz * uz
        if abs(facing) < 1e-6:
            facing = 1e-6 if facing >= 0 else -1e-6
        cos = abs(facing)
        near = max(d, 1e-3)  # a hit at the window itself (the sensor touching a surface) has no finite power
        loss = math.exp(-2.0 * alpha * (d - r_a))
        power[i] = brightness[t] * cos * (r_a * r_a / rho_a) / (near * near) * loss
        unit[i] = rho_a * (d / r_a) ** 2 / loss  # the inverse of power per brightness x cos, without a second exp
        sine = math.sqrt(max(1.0 - cos * cos, 0.0))
        reach[i] = min(d * (1.0 + 1.01 * tan_half * sine / cos) + 0.01, range_max)
        px = origins[o, 0] + ux * d
        py = origins[o, 1] + uy * d
        pz = origins[o, 2] + uz * d
        cx, cy, cz = px - incentre[t, 0], py - incentre[t, 1], pz - incentre[t, 2]
        if inradius[t] - math.sqrt(cx * cx + cy * cy + cz * cz) >= d * tan_half / cos:
            continue  # deep inside the incircle: the footprint stays on the triangle
        # The footprint reaches at most d tan_half / cos from its centre on the plane (the bound the incircle test
        # uses): farther than that from every edge line, it stays on the triangle too, without its ray's
        # derivatives (a sine and a cosine; this took the loop from 27 to 19 ns a pulse on the default scene).
        # Near an edge, the same with that bound in place of the footprint's reach across it: an edge the bound
        # does not reach, or a soft edge (below) the bound cannot reach past, is settled without the ray's
        # derivatives (a tenth of the pulses, most of them by soft edges: the loop's third).
        bound = d * tan_half / cos
        settled = True
        for k in range(3):
            gap = inward[t, k, 0] * px + inward[t, k, 1] * py + inward[t, k, 2] * pz - offset[t, k]
            if gap >= bound:
                continue
            other = neighbour[t, k]
            if other < 0:
                settled = False
                break
            other_facing = planes[other, 0] * ux + planes[other, 1] * uy + planes[other, 2] * uz
            if not ((other_facing > 0) == (facing > 0) and abs(other_facing) > 0.5 * abs(facing) and (
                    bound - max(gap, 0.0) < narrowest[other])):
                settled = False
                break
        if settled:
            continue
        if fixed:
            ax, ay, az, bx, by, bz = _basis_at(xy_deg[i, 0], xy_deg[i, 1], panorama)
            bxx = rotation[0, 0] * ax + rotation[0, 1] * ay + rotation[0, 2] * az
            bxy = rotation[1, 0] * ax + rotation[1, 1] * ay + rotation[1, 2] * az
            bxz = rotation[2, 0] * ax + rotation[2, 1] * ay + rotation[2, 2] * az
            byx = rotation[0, 0] * bx + rotation[0, 1] * by + rotation[0, 2] * bz
            byy = rotation[1, 0] * bx + rotation[1, 1] * by + rotation[1, 2] * bz
            byz = rotation[2, 0] * bx + rotation[2, 1] * by + rotation[2, 2] * bz
        else:
            bxx, bxy, bxz = basis_x[i, 0], basis_x[i, 1], basis_x[i, 2]
            byx, byy, byz = basis_y[i, 0], basis_y[i, 1], basis_y[i, 2]
        # The footprint's displacement on the plane per radian of pattern x and y, per metre of range.
        sx = (nx * bxx + ny * bxy + nz * bxz) / facing
        sy = (nx * byx + ny * byy + nz * byz) / facing
        wx0, wx1, wx2 = bxx - sx * ux, bxy - sx * uy, bxz - sx * uz
        wy0, wy1, wy2 = byx - sy * ux, byy - sy * uy, byz - sy * uz
        for k in range(3):
            mx, my, mz = inward[t, k, 0], inward[t, k, 1], inward[t, k, 2]
            gap = mx * px + my * py + mz * pz - offset[t, k]
            across = d * math.sqrt((half_x * (mx * wx0 + my * wx1 + mz * wx2)) ** 2
                                   + (half_y * (mx * wy0 + my * wy1 + mz * wy2)) ** 2)
            if gap >= across:
                continue
            other = neighbour[t, k]
            if other >= 0:
                other_facing = planes[other, 0] * ux + planes[other, 1] * uy + planes[other, 2] * uz
                # Across a soft edge the footprint lands on the neighbour: fine while the neighbour faces the ray as
                # the hit does, not much more edge-on (not a silhouette), and the footprint cannot reach past it.
                if (other_facing > 0) == (facing > 0) and abs(other_facing) > 0.5 * abs(facing) and (
                        across - max(gap, 0.0) < narrowest[other]):
                    continue
            leaves[i] = True
            break


def _near(candidate, origins, directions, reach, triangle, directions_sensor, bounds, cell_start, cell_boxes, always,
          node_low, node_high, node_link, box_low, box_high, box_tile, tile_part, tile_convex, tile_triangle,
          triangle_tile, triangle_part, tile_low, part_sphere, hull_start, hull_planes, flat_low, flat_high, flat_part,
          row_start, row_low, row_high, sub_start, sub_low, sub_high, tan_half, near,
          crossed):  # pragma: no cover - compiled
    """Per ``candidate`` beam: does it pass through a box, other than its hit's own, before ``reach``? And the
    tiles a ray of its footprint could meet something in (``crossed``).

    A box is the hit's own when it is the hit triangle's tile, a piece of the hit triangle, or a tile of the hit's
    convex object. A convex object's box counts only where the beam also passes its sphere, cylinder and planes
    grown as much as the box (its inflation: ``box_low`` against ``tile_low``). A flat object other than the hit's
    own, passed within the footprint's reach, names the beam too (:func:`_near_flat`). ``origins`` is ``(1, 3)``
    for a fixed sensor.

    The boxes a beam tests come from one of two places. With a direction grid (``cell_start`` not empty: a fixed
    sensor, :class:`~livox_viz.casting.beam.DirectionGrid`), those filed in its direction's cell (``bounds`` =
    (lowest coordinate, cells per unit, cells a side)) and those holding the sensor (``always``); a beam outside
    the grid tests them all. Otherwise (a moving sensor) a walk down the tree ``node_low``, ``node_high``,
    ``node_link``, depth first, whose leaves hold the boxes. Either way each box is tested here, in one loop.

    The tiles of each beam's boxes that a ray of its footprint could meet something in (every box it crosses
    before ``reach`` but the pieces of its hit triangle and its convex object's: its own tile counts here) go to
    ``crossed (n, k)``, -1 after the last; -2 in the first column when there were more than k, when the beam
    hit an object that is not convex (its own tile is always crossed: it stops at the first other box, a
    terrain's cells hold dozens), or was not asked. Every ray of the footprint lies within the inflation of
    the box it meets, so these are all the boxes :func:`_rays_may_meet` needs to test for the beam.

    A tile of an object that is not convex (a terrain's, a building's) has sub-boxes (its triangles filed by a finer
    grid), in rows (rows ``row_start[tile]`` to ``row_start[tile + 1]`` of ``row_low``, ``row_high``, each the box of
    its sub-boxes, rows ``sub_start[row]`` to ``sub_start[row + 1]`` of ``sub_low``, ``sub_high``); when it has them,
    the beam must also pass one of them grown as much as the tile's box, or the tile does not count (a terrain
    tile's box holds the air above its ground: the beam passing over it names it, its sub-boxes do not). The
    guarantee is the box's: a ray of the footprint that meets a triangle of the tile at distance s from the sensor
    (s at most the tile's farthest corner's distance, at most the reach) is within s tan_half of the beam's point
    at s, less than the inflation ``grow``; the triangle lies in one sub-box, so the beam's point at s lies in that
    sub-box grown by ``grow`` (a box grown by g holds every point within g of it), before ``reach``: the tile is
    still named.
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    gridded = cell_start.shape[0] > 0
    low, per_unit, side = (bounds[0], bounds[1], int(bounds[2])) if gridded else (0.0, 0.0, 0)
    boxes = box_tile.shape[0]
    most = crossed.shape[1]
    stack = np.empty(128, dtype=np.int64)
    for i in range(directions.shape[0]):
        near[i] = False
        crossed[i, 0] = -1
        if not candidate[i]:
            crossed[i, 0] = -2
            continue
        # The beam's boxes: rows first .. stop of the cell, then ``extra`` more (gridded), or the tree's leaves.
        cell = -1
        first = stop = extra = 0
        if gridded:
            sx = directions_sensor[i, 0]
            if sx > 1e-6:
                cu = math.floor((directions_sensor[i, 1] / sx - low) * per_unit)
                cv = math.floor((directions_sensor[i, 2] / sx - low) * per_unit)
                if 0 <= cu < side and 0 <= cv < side:
                    cell = cu * side + cv
            if cell >= 0:
                first, stop, extra = cell_start[cell], cell_start[cell + 1], always.shape[0]
            else:
                extra = boxes
        o = i * stride
        ox, oy, oz = origins[o, 0], origins[o, 1], origins[o, 2]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        ix = 1.0 / dx if dx != 0.0 else np.inf
        iy = 1.0 / dy if dy != 0.0 else np.inf
        iz = 1.0 / dz if dz != 0.0 else np.inf
        limit = reach[i]
        hit = triangle[i]
        part = triangle_part[hit] if hit >= 0 else -1
        found = _near_flat(ox, oy, oz, ix, iy, iz, limit, part, flat_low, flat_high, flat_part, tan_half)
        if gridded and stop + extra == first:
            near[i] = found
            continue  # no box in this direction (half the beams of the default scene): nothing more to look up
        own_tile = triangle_tile[hit] if hit >= 0 else -1
        listing = own_tile < 0 or tile_convex[own_tile]
        listed = 0
        j = first
        leaf_stop = 0
        stack[0] = 0
        top = 0 if gridded else 1
        while True:
            # The next box: the cell's, the extra ones, or the next of the leaves the walk down the tree reaches.
            if gridded:
                if j >= stop + extra:
                    break
                if j < stop:
                    b = cell_boxes[j]
                elif cell >= 0:
                    b = always[j - stop]
                else:
                    b = j - stop
                j += 1
            else:
                while j >= leaf_stop and top > 0:
                    top -= 1
                    node = stack[top]
                    if not _slab(ox, oy, oz, ix, iy, iz, limit, node_low[node, 0], node_low[node, 1],
                                 node_low[node, 2], node_high[node, 0], node_high[node, 1], node_high[node, 2]):
                        continue
                    if node_link[node, 0] >= 0:
                        stack[top] = node_link[node, 0]
                        stack[top + 1] = node_link[node, 1]
                        top += 2
                    else:
                        j, leaf_stop = node_link[node, 1], node_link[node, 1] + node_link[node, 2]
                if j >= leaf_stop:
                    break
                b = j
                j += 1
            # (written out: a helper taking the arrays pays their reference counts, five times this loop)
            tile = box_tile[b]
            if hit >= 0 and (tile_triangle[tile] == hit or (tile_convex[tile] and tile_part[tile] == part) or (
                    not listing and tile == own_tile)):
                continue
            enter, leave = _slab_span(ox, oy, oz, ix, iy, iz, limit, box_low[b, 0], box_low[b, 1], box_low[b, 2],
                                      box_high[b, 0], box_high[b, 1], box_high[b, 2])
            grow = tile_low[tile, 0] - box_low[b, 0]
            hull = tile_part[tile]
            inside = enter <= leave and _in_round(ox, oy, oz, dx, dy, dz, enter, leave, grow,
                                                  _round_bounds(part_sphere, hull))
            if inside and hull_start[hull] < hull_start[hull + 1]:
                inside = _in_planes(ox, oy, oz, dx, dy, dz, enter, leave, grow, hull_planes, hull_start[hull],
                                    hull_start[hull + 1])
            if inside and row_start[tile] < row_start[tile + 1]:
                # The tile's rows of sub-boxes, then a row's sub-boxes, each grown as much as its box (the guarantee
                # above: a row's box holds its sub-boxes).
                inside = False
                for w in range(row_start[tile], row_start[tile + 1]):
                    if not _slab(ox, oy, oz, ix, iy, iz, leave, row_low[w, 0] - grow, row_low[w, 1] - grow,
                                 row_low[w, 2] - grow, row_high[w, 0] + grow, row_high[w, 1] + grow,
                                 row_high[w, 2] + grow):
                        continue
                    for s in range(sub_start[w], sub_start[w + 1]):
                        if _slab(ox, oy, oz, ix, iy, iz, leave, sub_low[s, 0] - grow, sub_low[s, 1] - grow,
                                 sub_low[s, 2] - grow, sub_high[s, 0] + grow, sub_high[s, 1] + grow,
                                 sub_high[s, 2] + grow):
                            inside = True
                            break
                    if inside:
                        break
            if not inside:
                continue
            found = found or tile != own_tile
            if listed < most:
                crossed[i, listed] = tile
            listed += 1
            if found and (listed > most or not listing):
                break  # named, and nothing more to list: the rest cannot change either answer
        if listed < most:
            crossed[i, listed] = -1
        if listed > most or not listing:
            crossed[i, 0] = -2
        near[i] = found


def _near_flat(ox, oy, oz, ix, iy, iz, limit, part, flat_low, flat_high, flat_part,
               tan_half):  # pragma: no cover - compiled
    """Whether the beam passes within its footprint's reach (``limit`` x ``tan_half``) of a flat object other than
    its hit's own before ``limit``: the far edge of a ground plate can cover part of a footprint on a wall behind
    it (one call a beam: the arrays' reference counts are paid once)."""
    grown = limit * tan_half * 1.02 + HULL_PAD_M
    for f in range(flat_part.shape[0]):
        if flat_part[f] != part and _slab(ox, oy, oz, ix, iy, iz, limit, flat_low[f, 0] - grown, flat_low[f, 1] - grown,
                                          flat_low[f, 2] - grown, flat_high[f, 0] + grown, flat_high[f, 1] + grown,
                                          flat_high[f, 2] + grown):
            return True
    return False


def _rays_may_meet(pulse, rays, limit, triangle, origins, crossed, tile_low, tile_high, tile_part, tile_convex,
                   tile_triangle, triangle_part, flat_low, flat_high, flat_part, part_sphere, hull_start, hull_planes,
                   meet):  # pragma: no cover - compiled
    """Per ray of a footprint (``rays (r, 3)``, of the pulses ``pulse``, each to its own ``limit``): can it meet
    anything but its pulse's hit? Only where it passes through a tile itself (``tile_low``, ``tile_high``: not
    inflated; for a convex object also its bounding sphere, ``part_sphere``, and its face planes, ``hull_planes``
    from ``hull_start``) or a flat object's box (``flat_low``, ``flat_high``), except the tiles that cannot lie in
    front of the hit's plane (pieces of the hit triangle, tiles of the hit's convex object) and the hit's own
    flat object.

    The tiles are those the broad phase listed for the pulse (``crossed``: every ray of the footprint lies
    within the inflation of the box it meets); where it did not list them (-2), the ray may meet something.
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    for r in range(rays.shape[0]):
        i = pulse[r]
        meet[r] = crossed[i, 0] == -2
        if meet[r]:
            continue
        hit = triangle[i]
        part = triangle_part[hit] if hit >= 0 else -1
        o = i * stride
        ox, oy, oz = origins[o, 0], origins[o, 1], origins[o, 2]
        dx, dy, dz = float(rays[r, 0]), float(rays[r, 1]), float(rays[r, 2])
        ix = 1.0 / dx if dx != 0.0 else np.inf
        iy = 1.0 / dy if dy != 0.0 else np.inf
        iz = 1.0 / dz if dz != 0.0 else np.inf
        reach = limit[r]
        for f in range(flat_part.shape[0]):
            if flat_part[f] != part and _slab(ox, oy, oz, ix, iy, iz, reach, flat_low[f, 0], flat_low[f, 1],
                                              flat_low[f, 2], flat_high[f, 0], flat_high[f, 1], flat_high[f, 2]):
                meet[r] = True
                break
        if meet[r]:
            continue
        for k in range(crossed.shape[1]):
            tile = crossed[i, k]
            if tile < 0:
                break
            # (written out: a helper taking the arrays pays their reference counts, five times this loop)
            if hit >= 0 and (tile_triangle[tile] == hit or (tile_convex[tile] and tile_part[tile] == part)):
                continue
            enter, leave = _slab_span(ox, oy, oz, ix, iy, iz, reach, tile_low[tile, 0], tile_low[tile, 1],
                                      tile_low[tile, 2], tile_high[tile, 0], tile_high[tile, 1], tile_high[tile, 2])
            hull = tile_part[tile]
            inside = enter <= leave and _in_round(ox, oy, oz, dx, dy, dz, enter, leave, HULL_PAD_M,
                                                  _round_bounds(part_sphere, hull))
            if inside and hull_start[hull] < hull_start[hull + 1]:
                inside = _in_planes(ox, oy, oz, dx, dy, dz, enter, leave, HULL_PAD_M, hull_planes, hull_start[hull],
                                    hull_start[hull + 1])
            if inside:
                meet[r] = True
                break


def _round_bounds(sphere, part):  # pragma: no cover - compiled
    """Object ``part``'s bounding sphere and cylinder, ``sphere``'s row as a tuple of 11 numbers (for
    :func:`_in_round`)."""
    return (sphere[part, 0], sphere[part, 1], sphere[part, 2], sphere[part, 3], sphere[part, 4], sphere[part, 5],
            sphere[part, 6], sphere[part, 7], sphere[part, 8], sphere[part, 9], sphere[part, 10])


def _in_round(ox, oy, oz, dx, dy, dz, enter, leave, pad, bounds):  # pragma: no cover - compiled
    """Whether the ray from o along d (unit), between ``enter`` and ``leave`` (where it is inside the object's box),
    meets the object's bounding sphere and cylinder (``bounds``: centre, radius; a point of the axis, the unit
    axis, the radius; infinite radii for an object that is not convex), both ``pad`` metres larger than the object
    (at least :data:`HULL_PAD_M`, so a ray that grazes it is kept; the broad phase's inflation for a central ray).

    Numbers only, no arrays: a compiled helper that takes arrays pays an atomic increment and decrement of each
    one's reference count per call, which cost the broad phase's loops a tenth of their time (and the narrow
    phase's a third) when this test took the three tables."""
    cx, cy, cz, radius = bounds[0] - ox, bounds[1] - oy, bounds[2] - oz, bounds[3]
    if radius < np.inf:
        along = min(max(cx * dx + cy * dy + cz * dz, enter), leave)
        ex, ey, ez = cx - along * dx, cy - along * dy, cz - along * dz
        if ex * ex + ey * ey + ez * ez > (radius + pad) ** 2:
            return False
    radius = bounds[10]
    if radius < np.inf:
        # The nearest the ray comes to the cylinder's axis between enter and leave, both taken across the axis.
        ax, ay, az = bounds[7], bounds[8], bounds[9]
        wx, wy, wz = ox - bounds[4], oy - bounds[5], oz - bounds[6]
        w_along, d_along = wx * ax + wy * ay + wz * az, dx * ax + dy * ay + dz * az
        wx, wy, wz = wx - w_along * ax, wy - w_along * ay, wz - w_along * az
        ux, uy, uz = dx - d_along * ax, dy - d_along * ay, dz - d_along * az
        across = ux * ux + uy * uy + uz * uz
        t = min(max(-(wx * ux + wy * uy + wz * uz) / across, enter), leave) if across > 0.0 else enter
        ex, ey, ez = wx + t * ux, wy + t * uy, wz + t * uz
        if ex * ex + ey * ey + ez * ez > (radius + pad) ** 2:
            return False
    return True


def _in_planes(ox, oy, oz, dx, dy, dz, enter, leave, pad, planes, first, stop):  # pragma: no cover - compiled
    """Whether the ray from o along d, between ``enter`` and ``leave``, passes inside the face planes ``first`` to
    ``stop`` of ``planes`` (a convex object's, ``pad`` metres out). Called only for an object that has planes."""
    for k in range(first, stop):
        facing = planes[k, 0] * dx + planes[k, 1] * dy + planes[k, 2] * dz
        room = planes[k, 3] + pad - (planes[k, 0] * ox + planes[k, 1] * oy + planes[k, 2] * oz)
        if facing == 0.0:
            if room < 0.0:
                return False
        elif facing > 0.0:
            leave = min(leave, room / facing)
        else:
            enter = max(enter, room / facing)
        if enter > leave:
            return False
    return True


def _slab_span(ox, oy, oz, ix, iy, iz, limit, lx, ly, lz, hx, hy, hz):  # pragma: no cover - compiled
    """Where the ray from o (inverse direction i, infinite along an axis it does not move on) is inside the box
    [l, h] between 0 and ``limit``: ``(enter, leave)``, empty when enter > leave."""
    near_t = 0.0
    far_t = limit
    if ix == np.inf:
        if ox < lx or ox > hx:
            return 1.0, 0.0
    else:
        a = (lx - ox) * ix
        b = (hx - ox) * ix
        near_t = max(near_t, min(a, b))
        far_t = min(far_t, max(a, b))
    if iy == np.inf:
        if oy < ly or oy > hy:
            return 1.0, 0.0
    else:
        a = (ly - oy) * iy
        b = (hy - oy) * iy
        near_t = max(near_t, min(a, b))
        far_t = min(far_t, max(a, b))
    if iz == np.inf:
        if oz < lz or oz > hz:
            return 1.0, 0.0
    else:
        a = (lz - oz) * iz
        b = (hz - oz) * iz
        near_t = max(near_t, min(a, b))
        far_t = min(far_t, max(a, b))
    return near_t, far_t


def _slab(ox, oy, oz, ix, iy, iz, limit, lx, ly, lz, hx, hy, hz):  # pragma: no cover - compiled
    """Whether the ray from o (inverse direction i, infinite along an axis it does not move on) meets the box
    [l, h] between 0 and ``limit``."""
    enter, leave = _slab_span(ox, oy, oz, ix, iy, iz, limit, lx, ly, lz, hx, hy, hz)
    return enter <= leave


def _probe_limits(rows, probes, triangle, distance, planes, origins, range_max, sigma_table,
                  out):  # pragma: no cover - compiled
    """How far each probe ray may look: short of the hit's own plane by the range sigma at the hit (the whole
    range for a miss)."""
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    for r in prange(rows.shape[0]):
        i = rows[r]
        t = triangle[i]
        o = i * stride
        margin = max(_sigma(distance[i], sigma_table), 1e-3) if t >= 0 else 0.0
        for k in range(probes.shape[1]):
            out[r, k] = range_max
            if t < 0:
                continue
            nx, ny, nz = planes[t, 0], planes[t, 1], planes[t, 2]
            height = planes[t, 3] - (nx * origins[o, 0] + ny * origins[o, 1] + nz * origins[o, 2])
            along = nx * probes[r, k, 0] + ny * probes[r, k, 1] + nz * probes[r, k, 2]
            if along == 0.0:
                continue
            short = height / along * (1.0 - 1e-4) - margin
            if short > 0.0:
                out[r, k] = min(short, range_max)


# Step 3: echoes of sampled footprints ------------------------------------------------------------------------------
def _own_subrays(rows, clear, rays, triangle, planes, origins, inward, offset, range_max, ranges, triangles, slots,
                 cast_rays, asked, asked_rays, asked_pulse, asked_limit):  # pragma: no cover - compiled
    """Sub-rays ``rays (m, k, 3)`` (ray 0 the central one) of the pulses ``rows`` that land inside their pulse's own
    triangle, strictly (a micrometre per metre of range inside every edge): for a ``clear`` pulse, their range
    from its plane and its index go into ``ranges`` and ``triangles``. Every other sub-ray (1 to k - 1) is listed
    for Embree, in pulse then sub-ray order: its flat index into ``ranges`` in ``slots``, its direction in
    ``cast_rays``.

    A listed sub-ray that lands inside its own triangle, or one of a pulse whose central ray met nothing, is also
    asked about (for :func:`_rays_may_meet`): can it meet anything else before its landing (a millimetre beyond
    the plane: what touches it could still be nearer), resp. before the range? Its row of the list goes in
    ``asked``, its direction, pulse and that limit in ``asked_rays``, ``asked_pulse`` and ``asked_limit``, and
    the answer should it meet nothing else in ``ranges`` and ``triangles``: the plane's range and the pulse's
    triangle, resp. a miss. Returns how many are listed and how many asked.
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    count = rays.shape[1]
    listed = 0
    questions = 0
    for m in range(rows.shape[0]):
        i = rows[m]
        t = triangle[i]
        o = i * stride
        nx = ny = nz = height = 0.0
        if t >= 0:
            nx, ny, nz = planes[t, 0], planes[t, 1], planes[t, 2]
            height = planes[t, 3] - (nx * origins[o, 0] + ny * origins[o, 1] + nz * origins[o, 2])
        for k in range(1, count):
            landing = -1.0
            if t >= 0:
                ux, uy, uz = float(rays[m, k, 0]), float(rays[m, k, 1]), float(rays[m, k, 2])
                along = nx * ux + ny * uy + nz * uz
                if abs(along) > 1e-9:
                    d = height / along
                    if 0.0 <= d <= range_max:
                        px, py, pz = origins[o, 0] + ux * d, origins[o, 1] + uy * d, origins[o, 2] + uz * d
                        landing = d
                        for e in range(3):
                            if (inward[t, e, 0] * px + inward[t, e, 1] * py + inward[t, e, 2] * pz - offset[t, e]
                                    < 1e-6 * d):
                                landing = -1.0
                                break
            if landing >= 0.0 and clear[m]:
                ranges[m, k] = landing
                triangles[m, k] = t
                continue
            slots[listed] = m * count + k
            cast_rays[listed, 0] = rays[m, k, 0]
            cast_rays[listed, 1] = rays[m, k, 1]
            cast_rays[listed, 2] = rays[m, k, 2]
            if landing >= 0.0 or t < 0:
                asked[questions] = listed
                asked_rays[questions, 0] = rays[m, k, 0]
                asked_rays[questions, 1] = rays[m, k, 1]
                asked_rays[questions, 2] = rays[m, k, 2]
                asked_pulse[questions] = i
                asked_limit[questions] = landing + 1e-3 if t >= 0 else range_max
                questions += 1
                # The answer when it can meet nothing else (a cast overwrites it otherwise).
                ranges[m, k] = landing if t >= 0 else np.inf
                triangles[m, k] = t
            listed += 1
    return listed, questions


def _free_subrays(listed, asked, meet, slots, cast_rays):  # pragma: no cover - compiled
    """Of the ``listed`` sub-rays, those asked (rows ``asked``) that can meet nothing else (``meet`` False) keep the
    answer :func:`_own_subrays` wrote; the others stay listed for Embree, moved up in order in ``slots`` and
    ``cast_rays``. Returns how many stay."""
    kept = 0
    question = 0
    for j in range(listed):
        if question < asked.shape[0] and asked[question] == j:
            question += 1
            if not meet[question - 1]:
                continue
        slots[kept] = slots[j]
        cast_rays[kept, 0] = cast_rays[j, 0]
        cast_rays[kept, 1] = cast_rays[j, 1]
        cast_rays[kept, 2] = cast_rays[j, 2]
        kept += 1
    return kept


def _cast_subrays(slots, hit, cast_rays, rows, origins, planes, range_max, ranges, triangles):  # pragma: no cover
    """Embree's triangles ``hit`` of the sub-rays :func:`_own_subrays` listed, put back at their ``slots`` of
    ``ranges`` and ``triangles`` (``(m, k)``), each range from its triangle's plane as :func:`_plane_distance`
    gives it (a sub-ray along its plane, -1 there, carries no energy back: its triangle is -1 too)."""
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    count = ranges.shape[1]
    for j in range(slots.shape[0]):
        m = slots[j] // count
        k = slots[j] - m * count
        t = hit[j]
        if t < 0:
            ranges[m, k] = np.inf
            triangles[m, k] = -1
            continue
        o = rows[m] * stride
        d = _plane_range(planes[t, 0], planes[t, 1], planes[t, 2], planes[t, 3], origins[o, 0], origins[o, 1],
                         origins[o, 2], float(cast_rays[j, 0]), float(cast_rays[j, 1]), float(cast_rays[j, 2]),
                         range_max)
        ranges[m, k] = d
        triangles[m, k] = t if d >= 0.0 else -1


def _footprint_echoes(rows, ranges, triangles, rays, weights, planes, brightness, origins, blind, separate,
                      separation, sigma_table, mix_floor, calibration,
                      written, slot, power, range_m, spatial, unit_power):  # pragma: no cover - compiled
    """Echoes of each sampled pulse's 19 sub-rays, in slots ``m * 19 ..``; ``written[m]`` says how many.

    Sub-rays sorted by range; a gap over ``separation`` starts a new echo (never when not ``separate``: a
    single-return sensor). An echo's power sums its sub-rays', its range is their power-weighted mean. Its
    strongest sub-ray names its surface: when sub-rays lie more than 3 range sigmas (at least ``mix_floor``)
    off that plane the point is mixed, its spatial bits from where it sits between the depths (01 beyond a
    quarter of the spread from the surface, 10 beyond a tenth, else 11).
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    rho_a, r_a, alpha = calibration[0], calibration[1], calibration[2]
    count = weights.shape[0]
    # One pulse's scratch for all (an allocation a pulse cost a tenth of the loop): the loop is serial.
    order = np.empty(count, dtype=np.int64)
    sub_power = np.empty(count)
    for m in range(rows.shape[0]):
        i = rows[m]
        o = i * stride
        live = 0
        for k in range(count):
            t = triangles[m, k]
            r = ranges[m, k]
            if t < 0 or r < blind:
                continue
            cos = abs(planes[t, 0] * rays[m, k, 0] + planes[t, 1] * rays[m, k, 1] + planes[t, 2] * rays[m, k, 2])
            near = max(r, 1e-3)
            sub_power[k] = weights[k] * brightness[t] * cos * (r_a * r_a / rho_a) / (near * near) * math.exp(
                -2.0 * alpha * (r - r_a))
            if sub_power[k] <= 0.0:
                continue
            # Insertion by range.
            j = live
            while j > 0 and ranges[m, order[j - 1]] > r:
                order[j] = order[j - 1]
                j -= 1
            order[j] = k
            live += 1
        out = m * count
        first = 0
        while first < live:
            last = first + 1
            while last < live and not (separate and ranges[m, order[last]] - ranges[m, order[last - 1]] > separation):
                last += 1
            total = 0.0
            weighted = 0.0
            strongest = order[first]
            for j in range(first, last):
                k = order[j]
                total += sub_power[k]
                weighted += sub_power[k] * ranges[m, k]
                if sub_power[k] > sub_power[strongest]:
                    strongest = k
            blend = weighted / total
            t = triangles[m, strongest]
            nx, ny, nz, c = planes[t, 0], planes[t, 1], planes[t, 2], planes[t, 3]
            height = c - (nx * origins[o, 0] + ny * origins[o, 1] + nz * origins[o, 2])
            spread = 0.0
            for j in range(first, last):
                k = order[j]
                along = nx * rays[m, k, 0] + ny * rays[m, k, 1] + nz * rays[m, k, 2]
                depth = abs(ranges[m, k] - height / along) if along != 0.0 else np.inf
                spread = max(spread, depth)
            along = nx * rays[m, 0, 0] + ny * rays[m, 0, 1] + nz * rays[m, 0, 2]
            bits = 0
            if spread > max(3.0 * _sigma(blend, sigma_table), mix_floor):
                between = abs(blend - height / along) / spread if along != 0.0 and spread < np.inf else 1.0
                bits = 1 if between > 0.25 else (2 if between > 0.1 else 3)
            slot[out] = out - m * count
            power[out] = total
            range_m[out] = blend
            spatial[out] = bits
            unit_power[out] = rho_a * (blend / r_a) ** 2 * math.exp(2.0 * alpha * (blend - r_a))
            out += 1
            first = last
        written[m] = out - m * count


# Steps 4 and 5: detection, selection, noise, bytes, tags, false alarms ------------------------------------------------
def _emit(triangle, power, distance, unit, sampled, written, slots, e_power, e_range, e_spatial, e_unit, start, keys,
          snr, sigma_table, blind, range_max, keep_returns, false_rate, return0, false_reach, directions_sensor,
          directions_world, origins, jitter, xy, times, point_rate, scale, seen, measured, chosen, beam, index_out,
          t_out, xy_out, range_out, xyz_sensor, int16_out, xyz_world, reflectivity, tag, number,
          returns):  # pragma: no cover - compiled
    """Detection, selection and the points of every pulse, in pulse order and range order within a pulse; returns
    how many points, or -1 when the outputs are too short. They need a row a whole pulse, one a footprint
    echo, and one a false alarm.

    Pulse ``i`` (stream index ``start + i``) is sampled when it is listed in ``sampled`` (rows, ascending): the
    ``s``-th listed has ``written[s]`` footprint echoes from row ``s * slots`` of ``e_power``, ``e_range``, in range
    order (``seen``, ``measured`` and ``chosen`` are their scratch). Any other pulse whose central ray met a
    ``triangle`` at a ``distance`` past the blind zone is whole: one echo, its hit's ``power``. (Walking the sampled
    rows here, the caller makes no per-pulse tables of which pulse is what: three numpy passes and two zeroed arrays
    of 8 bytes a pulse, 4 ns a pulse.) Receiver noise (the detection's and the intensity's) and range noise are one
    normal pair per echo: the pulse's first pair (``keys[0]``) for its nearest echo, the later stream's pair
    ``slot - 1`` (``keys[1]``) for the others. An echo is seen when power plus noise / ``snr`` passes 1 and its measured
    range lies in [blind zone, range_max], both as measured and as a client decodes its int16 point
    (:func:`_decodes_within`); when more are seen than ``keep_returns``, the first and then the
    strongest others are kept. A pulse left without a point reports a false alarm with probability ``false_rate``
    (``keys[3]``): a range uniform in [blind zone, ``false_reach``] (``keys[4]``; none that decodes outside), byte
    0-3, tag spatial 01 and intensity 01.

    Each point lies at its measured range along the pulse's direction (turned by the angular noise,
    ``keys[2]``); its reflectivity byte comes from seen power x the reflectance one unit of power means at
    that range (``unit`` for a whole pulse, ``e_unit`` for a footprint echo; 0-150 Lambertian, 151-255
    logarithmic from twice to 1000 times a white target's power); its tag has the spatial bits and the return
    number (1-3, or 0 for a first return nearer than ``return0``).

    With each point its pulse's stream index, time (``times``, or stream index / ``point_rate`` when empty)
    and pattern angles, and its int16 encoding (``rint`` of the sensor-frame point x ``scale``, clipped, as
    :func:`~livox_viz.casting.codec.encode_int16`). A point that encodes as (0, 0, 0), which a client reads as
    "no return", is left out; its pulse's other points keep their return numbers.
    """
    stride = 0 if origins.shape[0] == 1 else 1  # one origin for all, or one a pulse
    given = times.shape[0] > 0
    multi = keep_returns > 1
    p = 0
    kept = 0
    listed = 0
    for i in range(triangle.shape[0]):
        rows_start = p
        index = start + i
        echoes = -1
        if listed < sampled.shape[0] and sampled[listed] == i:
            echoes = written[listed]
            listed += 1
        if echoes < 0:
            if triangle[i] >= 0 and distance[i] >= blind:
                a, b = _normal_pair(keys[0], index, 0)
                heard = power[i] + a / snr
                at = distance[i] + _sigma(distance[i], sigma_table) * b
                if heard > 1.0 and blind <= at <= range_max and _decodes_within(
                        at, directions_sensor[i], index, jitter, keys[2], scale, blind, range_max):
                    range_out[p] = at
                    reflectivity[p] = _byte(heard * unit[i])
                    tag[p] = 0
                    p += 1
        elif echoes > 0:
            first = (listed - 1) * slots
            stop = first + echoes
            heard_count = 0
            for e in range(first, stop):
                if e == first:
                    a, b = _normal_pair(keys[0], index, 0)
                else:
                    a, b = _normal_pair(keys[1], index, e - first - 1)
                seen[e] = e_power[e] + a / snr
                measured[e] = e_range[e] + _sigma(e_range[e], sigma_table) * b
                chosen[e] = seen[e] > 1.0 and blind <= measured[e] <= range_max and _decodes_within(
                    measured[e], directions_sensor[i], index, jitter, keys[2], scale, blind, range_max)
                if chosen[e]:
                    heard_count += 1
            if heard_count > keep_returns:
                picked = np.zeros(stop - first, dtype=np.bool_)
                nearest = first
                while not chosen[nearest]:
                    nearest += 1
                picked[nearest - first] = True
                for _ in range(keep_returns - 1):
                    best = -1
                    for e in range(first, stop):
                        if chosen[e] and not picked[e - first] and (best < 0 or seen[e] > seen[best]):
                            best = e
                    picked[best - first] = True
                for e in range(first, stop):
                    chosen[e] = picked[e - first]
            for e in range(first, stop):
                if chosen[e]:
                    range_out[p] = measured[e]
                    reflectivity[p] = _byte(seen[e] * e_unit[e])
                    tag[p] = e_spatial[e]
                    p += 1
        if p == rows_start:
            if not (false_rate > 0.0 and _uniform(keys[3], index, 0) < false_rate):
                continue
            if p >= range_out.shape[0]:
                return -1  # more false alarms than the outputs were sized for
            near_end = min(max(blind, 0.1), false_reach)
            range_out[p] = near_end + _uniform(keys[4], index, 0) * (false_reach - near_end)
            if not _decodes_within(range_out[p], directions_sensor[i], index, jitter, keys[2], scale, blind,
                                   range_max):
                continue
            reflectivity[p] = math.floor(_uniform(keys[4], index, 1) * 4.0)
            tag[p] = 0x05
            p += 1
        o = i * stride
        dx, dy, dz = _point_direction(directions_sensor[i], index, jitter, keys[2])
        # The pulse's points were written from rows_start; each moves down to the next kept row (kept <= q).
        for q in range(rows_start, p):
            r = range_out[q]
            s0, s1, s2 = dx * r, dy * r, dz * r
            q0, q1, q2 = np.rint(s0 * scale), np.rint(s1 * scale), np.rint(s2 * scale)
            if q0 == 0.0 and q1 == 0.0 and q2 == 0.0:
                continue
            place = q - rows_start + 1
            bits = place if multi else 1
            if place == 1 and r < return0:
                bits = 0
            tag[kept] = tag[q] | (bits << 4)
            reflectivity[kept] = reflectivity[q]
            range_out[kept] = r
            number[kept] = place
            returns[kept] = p - rows_start
            beam[kept] = i
            index_out[kept] = index
            t_out[kept] = times[i] if given else index / point_rate
            xy_out[kept, 0] = xy[i, 0]
            xy_out[kept, 1] = xy[i, 1]
            xyz_sensor[kept, 0], xyz_sensor[kept, 1], xyz_sensor[kept, 2] = s0, s1, s2
            int16_out[kept, 0] = np.int16(min(max(q0, -32767.0), 32767.0))
            int16_out[kept, 1] = np.int16(min(max(q1, -32767.0), 32767.0))
            int16_out[kept, 2] = np.int16(min(max(q2, -32767.0), 32767.0))
            if jitter <= 0.0:
                xyz_world[kept, 0] = origins[o, 0] + directions_world[i, 0] * r
                xyz_world[kept, 1] = origins[o, 1] + directions_world[i, 1] * r
                xyz_world[kept, 2] = origins[o, 2] + directions_world[i, 2] * r
            kept += 1
        p = kept  # the next pulse writes after the rows kept
    return kept


def _point_direction(direction, index, jitter, key):  # pragma: no cover - compiled
    """A pulse's direction ``(3,)`` (sensor frame) turned by its angular noise (``jitter`` 1-sigma radians, the
    normal pair of ``key`` at ``index``)."""
    dx, dy, dz = direction[0], direction[1], direction[2]
    if jitter > 0.0:
        a, b = _normal_pair(key, index, 0)
        jitter_scale = jitter / math.sqrt(dx * dx + dy * dy)
        a *= jitter_scale
        b *= jitter_scale
        dx, dy, dz = dx - a * dy - b * dz * dx, dy + a * dx - b * dz * dy, dz + b * (dx * dx + dy * dy)
    return dx, dy, dz


def _decodes_within(range_m, direction, index, jitter, key, scale, low, high):  # pragma: no cover - compiled
    """Whether a point at ``range_m`` along the pulse's direction (:func:`_point_direction`) decodes, int16 and
    back (``scale`` levels a metre), at a range in [``low``, ``high``]: what a client measures, which can lie up to
    sqrt(3)/2 of a level off the range itself (1.6 cm with a 600 m range's 18 mm level). Asked only within a level
    of either end."""
    step = 1.0 / scale
    if low + step <= range_m <= high - step:
        return True
    dx, dy, dz = _point_direction(direction, index, jitter, key)
    q0 = min(max(np.rint(dx * range_m * scale), -32767.0), 32767.0)
    q1 = min(max(np.rint(dy * range_m * scale), -32767.0), 32767.0)
    q2 = min(max(np.rint(dz * range_m * scale), -32767.0), 32767.0)
    decoded = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2) * step
    return low <= decoded <= high


def _byte(value):  # pragma: no cover - compiled
    """Livox's reflectivity byte of an echo as bright as a Lambertian target of reflectance ``value``."""
    if value >= 2.0:
        share = math.log(value / 2.0) / math.log(500.0)
        return 151 + math.floor(104.0 * min(max(share, 0.0), 1.0) + 0.5)
    return math.floor(150.0 * min(max(value, 0.0), 1.0) + 0.5)
