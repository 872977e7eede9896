"""The beam's footprint: an elliptical Gaussian cone sampled with sub-rays, and when sampling can change the answer.

A Livox beam diverges into an ellipse, ``H x V`` degrees full width (0.03 x 0.28
deg: 1 x 10 cm at 20 m), its long axis along pattern y. Its energy falls off as
a Gaussian whose 1/e^2 contour is that ellipse. Following HELIOS++'s beam
sub-sampling (concentric rings of sub-rays), :data:`SUBRAY_UNIT` places 19
sub-rays in normalised ellipse coordinates: the centre, 6 at half the radius
and 12 on the 1/e^2 contour (their angles include both axes, so a straight
edge along an axis is seen exactly where the ellipse reaches it). Each carries
the Gaussian energy of its ring cell (Voronoi annuli 0-0.25-0.75-infinity,
shared equally round the ring), :data:`SUBRAY_WEIGHTS`.

Casting 19 rays for every pulse would cost 19 times the ideal scan, so the
footprint is sampled only where it can change the answer, found in three
tests from cheapest to dearest:

1. The edge test (:class:`TriangleEdges`, run by
   :mod:`~livox_viz.casting.return_kernels`): the footprint leaves the triangle the central
   ray hit. The ellipse's image on the triangle's plane is exact to first order
   (its support in the direction of each edge, from the ray's angular
   derivatives); an edge to a neighbour of the same material that continues
   the surface (less than 20 deg of dihedral angle, facing the ray the same
   way, wider than the footprint's reach) does not count, so a cylinder's
   facets or a wall's diagonal do not make every hit a footprint.
2. :class:`TileProxy`: a broad phase for occluders. The scene's objects are cut
   into tiles at most :data:`TILE_SIZE` across (a convex object up to
   :data:`WHOLE_CONVEX` is one) whose boxes are inflated by the footprint's radius
   at their farthest distance from the sensor; a ray through those boxes up to the
   footprint's farthest reach says whether any box but the hit's own comes near the
   beam (a fixed sensor's beam tests only the boxes filed under its direction,
   :class:`DirectionGrid`; a moving one's walks down a tree of them, :class:`BoxTree`).
   A tile of an object that is not convex (a terrain's) counts only where the beam
   also passes one of its :data:`SUB_TILE` cells' boxes, grown as much: its own box
   holds the air above the ground, which named 28 % of the dense terrain's pulses
   (10 % by the cells).
3. Probes (:data:`PROBE_UNIT`): for the pulses the broad phase names, four rays
   at the corners of the ellipse's bounding box ask (Embree's occlusion query)
   whether anything lies in front of the hit's plane along them. A straight
   edge that crosses the ellipse puts one of those corners on its far side, so
   a partial occluder whose silhouette crosses the footprint is found; an
   object thinner than the footprint lying between the probes (a wire) is
   missed, as by the ideal scan.
"""

from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING

import numpy as np

from livox_viz.casting.return_kernels import HULL_PAD_M, kernel
from livox_viz.scene.materials import face_materials, face_parts

if TYPE_CHECKING:
    import trimesh

_RING_HALF = np.deg2rad(np.arange(0, 360, 60))
_RING_EDGE = np.deg2rad(np.arange(0, 360, 30))
#: ``(19, 2)`` sub-ray positions in the unit ellipse (x along the horizontal divergence, y the vertical),
#: the central ray first.
SUBRAY_UNIT = np.vstack([
    [[0.0, 0.0]],
    0.5 * np.column_stack([np.cos(_RING_HALF), np.sin(_RING_HALF)]),
    np.column_stack([np.cos(_RING_EDGE), np.sin(_RING_EDGE)]),
])


def _ring_energy(inner: float, outer: float) -> float:
    """Energy of a Gaussian beam (1/e^2 radius 1) between two normalised radii."""
    return math.exp(-2.0 * inner**2) - (math.exp(-2.0 * outer**2) if math.isfinite(outer) else 0.0)


#: ``(19,)`` energy share of each sub-ray (sums to 1).
SUBRAY_WEIGHTS = np.concatenate([
    [_ring_energy(0.0, 0.25)],
    np.full(6, _ring_energy(0.25, 0.75) / 6),
    np.full(12, _ring_energy(0.75, math.inf) / 12),
])
#: ``(4, 2)`` the corners of the ellipse's bounding box, in the same units.
PROBE_UNIT = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
#: Largest dihedral angle between neighbours that continue one surface, degrees.
SMOOTH_DEG = 20.0
#: Tiles of the broad phase are at most this long in any axis, metres.
TILE_SIZE = 10.0
#: A tile of an object that is not convex also keeps the boxes of its triangles filed by a grid this fine, metres,
#: for the broad phase (:func:`~livox_viz.casting.return_kernels._near`): a terrain tile's box holds the air above
#: its ground, which names every beam passing low over it (28 % of the dense terrain's pulses); its sub-boxes do not.
SUB_TILE = 1.25
#: A convex object at most this long in every axis is one box of the broad phase, metres.
WHOLE_CONVEX = 50.0
#: A large triangle is cut into at most this many pieces along each of its two longest axes.
CUT_CELLS = 24
#: Objects of more triangles than this are not tested for convexity (taken as not convex).
CONVEX_TEST_MAX = 4000
#: A convex object with at most this many distinct face planes keeps them for the probes' test (a box, a roof).
HULL_PLANES_MAX = 16
#: The broad phase's loop without a direction grid (directions, bounds, cell starts, cell boxes, boxes holding the
#: sensor), resp. without a tree (node boxes and links): empty arrays of the types it takes.
_NO_GRID = (np.empty((0, 3)), np.zeros(3), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64))
_NO_TREE = (np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3), np.int64))


class Footprint:
    """The sub-rays and probes of one beam divergence.

    Parameters
    ----------
    divergence_deg : (float, float)
        Full divergence, degrees: horizontal (pattern x) and vertical (pattern y).
    """

    def __init__(self, divergence_deg: tuple[float, float]) -> None:
        half = np.radians(np.array(divergence_deg, dtype=np.float64) / 2.0)
        self.divergence_deg = tuple(float(v) for v in divergence_deg)
        #: The ellipse's semi-axes, radians: horizontal (pattern x), vertical (pattern y).
        self.half_rad = half
        #: ``(19, 2)`` sub-ray offsets from the beam's pattern angles, radians.
        self.subray_offsets = SUBRAY_UNIT * half
        #: ``(4, 2)`` probe offsets, radians.
        self.probe_offsets = PROBE_UNIT * half
        #: Tangent of the footprint's largest half-angle (the ellipse's semi-major axis).
        self.tan_half_max = math.tan(float(half.max()))


class TriangleEdges:
    """Each triangle's three edge lines in its own plane, and whether its neighbour across each continues it.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        World frame, metres, with its materials (:mod:`~livox_viz.scene.materials`).
    """

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        triangles = np.asarray(mesh.triangles, dtype=np.float64)
        faces = triangles.shape[0]
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        area2 = np.linalg.norm(normal, axis=1)
        normal /= np.where(area2 > 0, area2, 1.0)[:, None]
        # For edge k (from vertex k+1 to k+2), the in-plane unit vector pointing at vertex k, and its offset:
        # the signed distance of a point p of the plane from that edge is m . p - c (>= 0 inside).
        self.inward = np.empty((faces, 3, 3), dtype=np.float64)
        self.offset = np.empty((faces, 3), dtype=np.float64)
        longest = np.zeros(faces)
        for k in range(3):
            a, b = triangles[:, (k + 1) % 3], triangles[:, (k + 2) % 3]
            edge = b - a
            longest = np.maximum(longest, np.linalg.norm(edge, axis=1))
            inward = np.cross(normal, edge)
            inward /= np.maximum(np.linalg.norm(inward, axis=1), 1e-300)[:, None]
            flip = np.einsum("ij,ij->i", inward, triangles[:, k] - a) < 0
            inward[flip] *= -1.0
            self.inward[:, k] = inward
            self.offset[:, k] = np.einsum("ij,ij->i", inward, a)
        # A degenerate triangle has no inside: every footprint leaves it.
        self.offset[area2 <= 0] = np.inf
        # The incircle: a point deeper inside it than a footprint reaches needs no edge test.
        lengths = np.stack([np.linalg.norm(triangles[:, (k + 2) % 3] - triangles[:, (k + 1) % 3], axis=1)
                            for k in range(3)], axis=1)
        perimeter = np.maximum(lengths.sum(axis=1), 1e-300)
        #: (F, 3) each triangle's incentre, world frame.
        self.incentre = np.einsum("fk,fkj->fj", lengths, triangles) / perimeter[:, None]
        #: (F,) its inradius, metres (0 for a degenerate triangle).
        self.inradius = np.where(area2 > 0, area2 / perimeter, 0.0)
        #: (F, 3) the triangle across each edge when it continues the surface, else -1.
        self.neighbour = np.full((faces, 3), -1, dtype=np.int64)
        #: (F,) the triangle's least altitude (how far a footprint may reach across it), metres.
        self.narrowest = np.where(longest > 0, area2 / np.maximum(longest, 1e-300), 0.0)
        self.normal = normal
        self._find_neighbours(mesh)

    def _find_neighbours(self, mesh: trimesh.Trimesh) -> None:
        """Neighbours across shared edges (vertices merged by position) that continue the surface."""
        if len(mesh.faces) < 2:
            return
        scale = float(np.ptp(mesh.vertices, axis=0).max()) or 1.0
        import trimesh

        merged = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
        merged.merge_vertices(digits_vertex=max(0, int(-math.log10(scale * 1e-9))))
        pairs = merged.face_adjacency
        if len(pairs) == 0:
            return
        shared = merged.face_adjacency_edges
        faces = np.asarray(merged.faces)
        reflectance, gain = face_materials(mesh)
        brightness = reflectance * gain
        smooth = (np.einsum("ij,ij->i", self.normal[pairs[:, 0]], self.normal[pairs[:, 1]])
                  > math.cos(math.radians(SMOOTH_DEG)))
        same = brightness[pairs[:, 0]] == brightness[pairs[:, 1]]
        keep = smooth & same
        # An edge shared by more than two triangles continues nothing.
        edge_key = np.sort(shared, axis=1)
        _, first, counts = np.unique(edge_key, axis=0, return_index=True, return_counts=True)
        manifold = np.zeros(len(pairs), dtype=bool)
        manifold[first[counts == 1]] = True
        keep &= manifold
        for side in (0, 1):
            face = pairs[keep, side]
            other = pairs[keep, 1 - side]
            # The edge's index in `face` is the index of the vertex not on it.
            on_edge = (faces[face] == shared[keep, 0:1]) | (faces[face] == shared[keep, 1:2])
            k = np.argmin(on_edge, axis=1)
            self.neighbour[face, k] = other


class TileProxy:
    """The broad phase: the scene's objects cut into tiles, each a box inflated by the footprint's reach.

    Small triangles are grouped by object and a :data:`TILE_SIZE` grid; large ones are cut along it.
    A tile of the hit's own convex object cannot cover its footprint (that object's other faces lie
    behind the hit), so it counts as the hit's own; for other objects only the hit triangle's tile does.
    A flat object (every triangle in one plane, like the ground) has no tiles: it covers part of a
    footprint on something else along that thing's own edge with it, which the edge test sees where the
    other object's mesh stops at the plane (one that pierces the ground is the exception), or along its own
    far edge, which its box grown by the beam's own footprint reach names (a plate's edge before a wall).
    What the broad phase does not name: a surface in the hit's own tile of an object that is not convex
    (its concave self-cover is seen only where the edge test sees it).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The scene, world frame, with its part numbers (:func:`~livox_viz.scene.materials.face_parts`).
    tan_half : float
        Tangent of the footprint's largest half-angle.
    """

    def __init__(self, mesh: trimesh.Trimesh, tan_half: float) -> None:
        self.tan_half = tan_half
        parts = face_parts(mesh)
        triangles = np.asarray(mesh.triangles, dtype=np.float64)
        kind = _part_kinds(triangles, parts)
        low, high, tile_part, tile_triangle, triangle_tile = _tiles(triangles, parts, kind)
        self.low, self.high = low, high
        #: (T,) the object of each tile, and whether that object is convex.
        self.tile_part = tile_part
        self.tile_convex = kind[tile_part] == 1 if tile_part.size else np.zeros(0, dtype=bool)
        #: (T,) the one large triangle a tile is a piece of, else -1.
        self.tile_triangle = tile_triangle
        #: (F,) each small triangle's tile, -1 for a large one (its pieces name it) or a flat object's.
        self.triangle_tile = triangle_tile
        self.triangle_part = parts.astype(np.int64)
        #: (G, 3) each flat object's box and (G,) its object: what a probe can meet outside the tiles.
        in_flat = kind[parts] == 0 if parts.size else np.zeros(0, dtype=bool)
        self.flat_part, which = np.unique(parts[in_flat].astype(np.int64), return_inverse=True)
        self.flat_low, self.flat_high = (_group_boxes(triangles[in_flat].min(axis=1), triangles[in_flat].max(axis=1),
                                                      which.reshape(-1)) if self.flat_part.size
                                         else (np.zeros((0, 3)), np.zeros((0, 3))))
        #: Per object: its bounding sphere and cylinder ``(P, 11)`` (centre, radius; axis point, axis, radius;
        #: infinite unless convex) and, for a convex one of few faces, its face planes (outward normal, offset) from
        #: row ``hull_start[p]`` of ``hull_planes``: a probe that passes a convex object's tile box can still miss
        #: the object (a ball, a pole, a roof).
        self.part_sphere, self.hull_start, self.hull_planes = _convex_hulls(triangles, parts, kind)
        #: The sub-boxes of each tile of an object that is not convex, in rows (none for the others):
        #: ``(row_start, row_low, row_high, sub_start, sub_low, sub_high)``, :func:`_sub_boxes`.
        self.sub_tables = _sub_boxes(triangles, triangle_tile, self.tile_convex, self.tiles)
        # The tiles and flat objects a millimetre larger for :meth:`rays_may_meet`: a ray along a box's face or edge
        # rounds either way, and Embree may still meet what lies there.
        self._padded = (self.low - HULL_PAD_M, self.high + HULL_PAD_M, self.flat_low - HULL_PAD_M,
                        self.flat_high + HULL_PAD_M)
        self.centre: np.ndarray | None = None
        self.radius = 0.0
        self._tree: BoxTree | None = None
        self._grid: DirectionGrid | None = None
        self._rotation: np.ndarray | None = None
        self._pose_key: tuple | None = None
        #: Held by a caller from :meth:`place` to the end of its :meth:`near`: the boxes are placed for one caller.
        self.lock = threading.Lock()

    #: Whether :meth:`near` tests the sub-boxes of tiles of objects that are not convex (False: their boxes only, as
    #: before; the tests compare both).
    tight = True

    def sub_boxes(self) -> tuple[np.ndarray, ...]:
        """What :meth:`near` tests of each tile besides its box: :attr:`sub_tables` (none when not
        :attr:`tight`)."""
        if self.tight:
            return self.sub_tables
        row_start, row_low, row_high, sub_start, sub_low, sub_high = self.sub_tables
        return np.zeros_like(row_start), row_low[:0], row_high[:0], sub_start[:1], sub_low[:0], sub_high[:0]

    @property
    def tiles(self) -> int:
        """Boxes in the broad phase."""
        return int(self.low.shape[0])

    @property
    def boxes_in_use(self) -> int:
        """Boxes near enough to the sensor to matter, as last placed."""
        return 0 if self._tree is None else int(self._tree.tile.size)

    def place(self, positions: np.ndarray, range_max: float, rotation: np.ndarray | None = None,
              margin: float = 10.0) -> tuple[BoxTree | None, DirectionGrid | None]:
        """Make sure the inflated boxes cover beams fired from ``positions`` ``(k, 3)`` (world, metres).

        The boxes are inflated for a sphere of sensor positions: a fixed sensor's point, or the
        positions of a moving one plus ``margin`` metres; they are rebuilt only when the sensor leaves it.
        Tiles wholly beyond ``range_max`` metres from it are left out (nothing there is in front of a hit).
        A fixed sensor's ``rotation`` (sensor FRD -> world) also files the boxes by direction
        (:class:`DirectionGrid`), so a beam tests only those in its own direction.

        Returns the boxes placed, for :meth:`near`: a later placing replaces them but never changes them,
        so runs cast side by side each ask their own (the placing itself goes under :attr:`lock`).
        """
        positions = np.atleast_2d(np.asarray(positions, dtype=np.float64))
        # A fixed sensor asks again from the same pose every run: known by its bytes (two comparisons, where the
        # test below took a fifth of a small run's broad phase).
        pose_key = (positions.tobytes(), range_max, None if rotation is None else np.asarray(rotation).tobytes())
        if pose_key == self._pose_key:
            return self._tree, self._grid
        inside = self.centre is not None and np.all(
            np.linalg.norm(positions - self.centre, axis=1) <= self.radius + 1e-9)
        same_rotation = (rotation is None and self._rotation is None) or (
            rotation is not None and self._rotation is not None and np.array_equal(rotation, self._rotation))
        if inside and same_rotation:
            return self._tree, self._grid
        centre = positions.mean(axis=0) if not inside else self.centre
        spread = float(np.linalg.norm(positions - centre, axis=1).max())
        radius = self.radius if inside else (0.0 if spread == 0.0 and self.centre is None else spread + margin)
        self._tree = None
        self._grid = None
        if self.tiles:
            corners = np.where(((np.arange(8)[:, None] >> np.arange(3)) & 1).astype(bool)[None],
                               self.high[:, None, :], self.low[:, None, :])
            farthest = np.linalg.norm(corners - centre, axis=2).max(axis=1)
            nearest = np.linalg.norm(np.clip(centre, self.low, self.high) - centre, axis=1)
            in_use = np.flatnonzero(nearest - radius <= range_max)
            grow = ((farthest[in_use] + radius) * self.tan_half * 1.02 + 1e-3)[:, None]
            if in_use.size:
                self._tree = BoxTree(self.low[in_use] - grow, self.high[in_use] + grow, in_use)
                if radius == 0.0 and rotation is not None:
                    self._grid = DirectionGrid(self._tree.box_low, self._tree.box_high, centre, rotation)
        self.centre, self.radius = centre, radius
        self._rotation = None if rotation is None else np.array(rotation, dtype=np.float64)
        self._pose_key = pose_key if positions.shape[0] == 1 else None
        return self._tree, self._grid

    def near(self, candidate: np.ndarray, origins: np.ndarray, directions: np.ndarray, reach: np.ndarray,
             triangle: np.ndarray, directions_sensor: np.ndarray | None = None,
             boxes: tuple[BoxTree | None, DirectionGrid | None] | None = None,
             crossed: np.ndarray | None = None) -> np.ndarray:
        """Whether a box other than the hit's own lies along each ``candidate`` beam before ``reach``.

        Parameters
        ----------
        candidate : (n,) bool
            The beams to ask about (the others answer False).
        origins : (3,), (1, 3) or (n, 3) float64
        directions : (n, 3) float64
            World frame.
        reach : (n,) float64
            How far along the beam the footprint may meet something, metres.
        triangle : (n,) int
            The central ray's triangle, -1 for a miss.
        directions_sensor : (n, 3) float64, optional
            The same in the sensor frame (a fixed sensor's beams then look up their direction's boxes).
        boxes : tuple, optional
            What :meth:`place` returned; default the boxes placed last.
        crossed : (n, k) int32 or int64, optional
            Filled, for :meth:`rays_may_meet`, with the tiles of each beam's boxes a ray of its footprint could
            meet something in (-1 after the last; -2 where not listed: more than k, or a hit on an object that is
            not convex, whose rays then may meet something).
        """
        near = np.zeros(directions.shape[0], dtype=np.bool_)
        if crossed is None:
            crossed = np.empty((near.size, 1), np.int64)
        tree, grid = boxes if boxes is not None else (self._tree, self._grid)
        if tree is None or near.size == 0:
            crossed[:, 0] = -1
            return near
        arguments = (np.ascontiguousarray(candidate, dtype=np.bool_),
                     np.ascontiguousarray(np.asarray(origins, dtype=np.float64).reshape(-1, 3)),
                     np.ascontiguousarray(directions, dtype=np.float64),
                     np.ascontiguousarray(reach, dtype=np.float64), np.asarray(triangle, dtype=np.int64))
        if grid is not None and directions_sensor is not None:  # a beam tests the boxes of its direction
            boxes_from = (np.ascontiguousarray(directions_sensor, dtype=np.float64), grid.bounds, grid.cell_start,
                          grid.cell_boxes, grid.always, *_NO_TREE)
        else:  # a walk down the tree
            boxes_from = (*_NO_GRID, tree.node_low, tree.node_high, tree.node_link)
        kernel("near")(*arguments, *boxes_from, tree.box_low, tree.box_high, tree.tile, self.tile_part,
                       self.tile_convex, self.tile_triangle, self.triangle_tile, self.triangle_part, self.low,
                       self.part_sphere, self.hull_start, self.hull_planes, self.flat_low, self.flat_high,
                       self.flat_part, *self.sub_boxes(), self.tan_half, near, crossed)
        return near


    def rays_may_meet(self, pulse: np.ndarray, rays: np.ndarray, limit: np.ndarray, triangle: np.ndarray,
                      origins: np.ndarray, crossed: np.ndarray) -> np.ndarray:
        """Whether each ray of a footprint (a probe, a sub-ray) can meet anything but its pulse's hit before its
        limit: ``(r,)`` bool.

        :meth:`near` names a beam whose central ray passes within the footprint's reach of a box, a box
        inflated for the farthest beam that can reach it, and lists the boxes it crossed (``crossed``); a ray of
        its footprint can only meet what lies in one of those tiles itself (not inflated; for a convex object,
        also inside its bounding sphere and its faces' planes) or a flat object's box that it crosses. Tiles
        that cannot lie in front of the hit's plane (pieces of the hit triangle, tiles of its convex object)
        and its own flat object are left out, so the answer is False only where Embree would find nothing
        before the limit but, at most, the hit's own surface. Where :meth:`near` did not list a beam's boxes,
        its rays may meet something.

        Parameters
        ----------
        pulse : (r,) int
            The pulse (row of the run) of each ray.
        rays : (r, 3) float32
            Unit directions, world frame.
        limit : (r,) float64
            How far each ray looks, metres.
        triangle : (n,) int64
            Every pulse's hit triangle, -1 for a miss.
        origins : (1, 3) or (n, 3) float64
        crossed : (n, k) int32 or int64
            What :meth:`near` listed for the pulses.
        """
        meet = np.zeros(len(rays), dtype=np.bool_)
        if len(rays) == 0:
            return meet
        kernel("rays_may_meet")(np.asarray(pulse, dtype=np.int64), np.ascontiguousarray(rays, dtype=np.float32),
                                np.ascontiguousarray(limit, dtype=np.float64),
                                np.asarray(triangle, dtype=np.int64),
                                np.ascontiguousarray(np.asarray(origins, dtype=np.float64).reshape(-1, 3)), crossed,
                                self._padded[0], self._padded[1], self.tile_part, self.tile_convex,
                                self.tile_triangle, self.triangle_part, self._padded[2], self._padded[3],
                                self.flat_part, self.part_sphere, self.hull_start, self.hull_planes, meet)
        return meet


class DirectionGrid:
    """Boxes filed by the directions they cover as seen from a fixed sensor, for the broad phase's loop.

    A beam's sensor-frame direction ``d`` has gnomonic coordinates ``(d_y / d_x, d_z / d_x)``; a box wholly in
    front of the sensor covers the convex hull of its corners' coordinates (a central projection keeps
    straight lines straight), so it is filed in the grid cells of their bounding rectangle. A box reaching
    behind the sensor (a terrain's tiles under and behind it) is cut at ``x = r / 4`` in the sensor frame, r its
    distance from the sensor: a point of it nearer the sensor's plane lies farther than 2 (the grid's span) off
    the boresight in ``u`` or ``v``, where only beams outside the grid, which test every box, can meet it. The
    part beyond the cut is filed like a box in front; a box wholly before it is filed nowhere. Only a box that
    holds the sensor itself is tested by every beam (``always``): on the dense terrain the 48 tiles reaching
    behind the sensor were tested by every beam, six times the boxes of its own direction.

    Parameters
    ----------
    low, high : (B, 3) float64
        The boxes, world frame.
    centre : (3,) float64
        The sensor's position, world frame.
    rotation : (3, 3) float64
        Sensor FRD -> world.
    """

    #: Cells a metre of gnomonic coordinate (about 0.57 deg each on the boresight); the grid spans +-SPAN.
    CELLS_PER_UNIT = 100
    SPAN = 2.0

    def __init__(self, low: np.ndarray, high: np.ndarray, centre: np.ndarray, rotation: np.ndarray) -> None:
        corners = np.where(((np.arange(8)[:, None] >> np.arange(3)) & 1).astype(bool)[None],
                           high[:, None, :], low[:, None, :])
        local = (corners - centre) @ rotation  # sensor frame: R^T v, row by row
        distance = np.linalg.norm(np.clip(centre, low, high) - centre, axis=1)
        holds_sensor = distance <= 0.0
        side = int(2 * self.SPAN * self.CELLS_PER_UNIT)
        self.bounds = np.array([-self.SPAN, float(self.CELLS_PER_UNIT), float(side)])
        members: list[np.ndarray] = []
        owners: list[np.ndarray] = []
        for box in np.flatnonzero(~holds_sensor):
            seen = _beyond_cut(local[box], distance[box] / 4.0)
            if seen.shape[0] == 0:
                continue
            u = seen[:, 1] / seen[:, 0]
            v = seen[:, 2] / seen[:, 0]
            u0, u1 = (np.clip(np.floor((np.array([u.min(), u.max()]) + self.SPAN) * self.CELLS_PER_UNIT), 0,
                              side - 1).astype(int))
            v0, v1 = (np.clip(np.floor((np.array([v.min(), v.max()]) + self.SPAN) * self.CELLS_PER_UNIT), 0,
                              side - 1).astype(int))
            cells = (np.arange(u0, u1 + 1)[:, None] * side + np.arange(v0, v1 + 1)[None, :]).reshape(-1)
            members.append(cells)
            owners.append(np.full(cells.size, box))
        cells = np.concatenate(members) if members else np.zeros(0, np.int64)
        boxes = np.concatenate(owners) if owners else np.zeros(0, np.int64)
        order = np.argsort(cells, kind="stable")
        #: (side * side + 1,) where each cell's boxes start in :attr:`cell_boxes`.
        self.cell_start = np.searchsorted(cells[order], np.arange(side * side + 1)).astype(np.int64)
        self.cell_boxes = boxes[order].astype(np.int64)
        #: Boxes every beam tests (they hold the sensor).
        self.always = np.flatnonzero(holds_sensor).astype(np.int64)


#: The box corners' pairs (bits of the corner number) joined by the box's 12 edges.
_BOX_EDGES = np.array([(a, a | bit) for bit in (1, 2, 4) for a in range(8) if not a & bit])


def _beyond_cut(corners: np.ndarray, cut: float) -> np.ndarray:
    """The corners ``(k, 3)`` of the part of a box at ``x >= cut`` (its ``corners`` ``(8, 3)`` in the sensor
    frame, numbered by bits as :class:`DirectionGrid` makes them): the corners there and where the box's edges
    cross the cut; none when the box lies wholly before it."""
    x = corners[:, 0]
    if x.min() >= cut:
        return corners
    a, b = corners[_BOX_EDGES[:, 0]], corners[_BOX_EDGES[:, 1]]
    crossing = (a[:, 0] < cut) != (b[:, 0] < cut)
    share = (cut - a[crossing, 0]) / (b[crossing, 0] - a[crossing, 0])
    cut_points = a[crossing] + share[:, None] * (b[crossing] - a[crossing])
    cut_points[:, 0] = cut
    return np.concatenate([corners[x >= cut], cut_points])


class BoxTree:
    """A bounding-volume tree over boxes (median splits, up to four boxes a leaf), for the broad phase's loop.

    Parameters
    ----------
    low, high : (B, 3) float64
        The boxes.
    tile : (B,) int
        What each box stands for (its tile).
    """

    def __init__(self, low: np.ndarray, high: np.ndarray, tile: np.ndarray) -> None:
        nodes_low, nodes_high, links = [], [], []
        order: list[int] = []
        centre = (low + high) / 2.0

        def build(rows: np.ndarray) -> int:
            node = len(links)
            nodes_low.append(low[rows].min(axis=0))
            nodes_high.append(high[rows].max(axis=0))
            links.append([0, 0, 0])
            if rows.size <= 4:
                links[node] = [-1, len(order), rows.size]  # a leaf: its boxes' place in `order`, and how many
                order.extend(rows.tolist())
                return node
            axis = int(np.argmax(np.ptp(centre[rows], axis=0)))
            sorted_rows = rows[np.argsort(centre[rows, axis], kind="stable")]
            half = sorted_rows.size // 2
            left = build(sorted_rows[:half])
            right = build(sorted_rows[half:])
            links[node] = [left, right, 0]
            return node

        build(np.arange(low.shape[0]))
        order_array = np.array(order, dtype=np.int64)
        self.node_low = np.ascontiguousarray(nodes_low, dtype=np.float64)
        self.node_high = np.ascontiguousarray(nodes_high, dtype=np.float64)
        #: (N, 3) int: inner node (left, right, 0); leaf (-1, first, count) into the box arrays.
        self.node_link = np.ascontiguousarray(links, dtype=np.int64)
        self.box_low = np.ascontiguousarray(low[order_array])
        self.box_high = np.ascontiguousarray(high[order_array])
        self.tile = np.ascontiguousarray(np.asarray(tile, dtype=np.int64)[order_array])


def _part_kinds(triangles: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """``(P,)`` int: 0 flat (one plane), 1 convex, 2 anything else.

    Convex: every vertex of the part lies on one side of each of its triangles' planes (parts of more than
    :data:`CONVEX_TEST_MAX` triangles are not tested).
    """
    count = int(parts.max()) + 1 if parts.size else 0
    kind = np.full(count, 2, dtype=np.int64)
    for part, rows in enumerate(_part_rows(parts, count)):
        if rows.size == 0 or rows.size > CONVEX_TEST_MAX:
            continue
        tri = triangles[rows]
        normal, offset = _face_planes(tri)
        if not normal.size:
            continue
        vertices = np.unique(tri.reshape(-1, 3), axis=0)
        tolerance = 1e-9 * max(float(np.ptp(vertices, axis=0).max()), 1.0)
        height = vertices @ normal.T - offset[None, :]
        if np.all(np.abs(height) <= tolerance):
            kind[part] = 0
        elif np.all((height <= tolerance).all(axis=0) | (height >= -tolerance).all(axis=0)):
            kind[part] = 1  # every face's plane has the whole object on one side (whichever way it was wound)
    return kind


def _part_rows(parts: np.ndarray, count: int) -> list[np.ndarray]:
    """The rows (triangles) of each object ``0 .. count - 1``, in order."""
    order = np.argsort(parts, kind="stable")
    bounds = np.searchsorted(parts[order], np.arange(count + 1))
    return [order[bounds[part]:bounds[part + 1]] for part in range(count)]


def _face_planes(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The planes of the triangles ``tri`` ``(k, 3, 3)`` that have an area: unit normals ``(g, 3)`` (by their
    winding) and offsets ``(g,)`` (``n . v0``)."""
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    good = length > 0
    normal = normal[good] / length[good, None]
    return normal, np.einsum("ij,ij->i", normal, tri[good, 0])


def _tiles(triangles: np.ndarray, parts: np.ndarray, kind: np.ndarray):
    """The broad phase's tiles: small triangles grouped by object and grid cell, large ones cut; none for flat objects.

    Returns
    -------
    low, high : (T, 3) float64
        Each tile's box.
    tile_part : (T,) int
        The object of each tile.
    tile_triangle : (T,) int
        The one large triangle a tile is a piece of, else -1.
    triangle_tile : (F,) int
        The tile of each small triangle, -1 for a large one or a flat object's.
    """
    lows, highs, tile_parts, tile_triangles = [], [], [], []
    triangle_tile = np.full(triangles.shape[0], -1, dtype=np.int64)
    tri_low, tri_high = triangles.min(axis=1), triangles.max(axis=1)
    solid = kind[parts] != 0
    # A convex object up to WHOLE_CONVEX across is one box (its inflation stays small); a larger one is cut.
    part_low, part_high = _group_boxes(tri_low, tri_high, parts.astype(np.int64))
    whole = (kind == 1) & ((part_high - part_low).max(axis=1) <= WHOLE_CONVEX)
    large = solid & ~whole[parts] & ((tri_high - tri_low).max(axis=1) > TILE_SIZE)
    small = np.flatnonzero(solid & ~large)
    tiles = 0
    if small.size:
        # Grouped by object and the grid cell of their centroid (a whole convex object: one group); a group's
        # box may exceed its cell by a triangle's size (at most TILE_SIZE).
        cell = np.floor(triangles[small].mean(axis=1) / TILE_SIZE).astype(np.int64)
        cell[whole[parts[small]]] = 0
        _, group = np.unique(np.column_stack([parts[small], cell]), axis=0, return_inverse=True)
        group = group.reshape(-1)
        low, high = _group_boxes(tri_low[small], tri_high[small], group)
        part_of = np.zeros(low.shape[0], dtype=np.int64)
        part_of[group] = parts[small]
        triangle_tile[small] = group
        lows.append(low)
        highs.append(high)
        tile_parts.append(part_of)
        tile_triangles.append(np.full(low.shape[0], -1, dtype=np.int64))
        tiles = low.shape[0]
    for t in np.flatnonzero(large):
        low, high = _cut_triangle(triangles[t])
        lows.append(low)
        highs.append(high)
        tile_parts.append(np.full(low.shape[0], parts[t], dtype=np.int64))
        tile_triangles.append(np.full(low.shape[0], t, dtype=np.int64))
        tiles += low.shape[0]
    if not lows:
        empty = np.zeros(0, np.int64)
        return np.zeros((0, 3)), np.zeros((0, 3)), empty, empty, triangle_tile
    return (np.concatenate(lows), np.concatenate(highs), np.concatenate(tile_parts), np.concatenate(tile_triangles),
            triangle_tile)


def _convex_hulls(triangles: np.ndarray, parts: np.ndarray, kind: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each object's bounding shapes ``(P, 11)``: its bounding sphere (centre, radius: inf unless convex and the
    sphere is smaller than the object's box), then its bounding cylinder (a point of the axis, the unit axis,
    the radius: inf unless convex, with too many faces for planes, and smaller than the box: a pole); and the
    outward face planes of the convex ones with at most :data:`HULL_PLANES_MAX` distinct planes not along an
    axis (those are the box's faces): ``(P + 1,)`` starts into ``(K, 4)`` rows (unit normal, offset; a point
    inside has ``n . x <= offset``)."""
    count = kind.shape[0]
    sphere = np.zeros((count, 11))
    sphere[:, 3] = np.inf
    sphere[:, 10] = np.inf
    planes: list[np.ndarray] = []
    start = np.zeros(count + 1, dtype=np.int64)
    rows = 0
    for part, members in enumerate(_part_rows(parts, count)):
        start[part] = rows
        if kind[part] != 1:
            continue
        tri = triangles[members]
        vertices = tri.reshape(-1, 3)
        centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2.0
        radius = float(np.linalg.norm(vertices - centre, axis=1).max())
        if 4.0 / 3.0 * math.pi * radius**3 < np.prod(np.ptp(vertices, axis=0)):  # only where tighter than the box
            sphere[part, :4] = (*centre, radius)
        normal, offset = _face_planes(tri)
        inside = np.unique(vertices, axis=0).mean(axis=0)  # (the box's centre need not be inside: a wedge)
        outward = np.where(normal @ inside > offset, -1.0, 1.0)
        hull = np.unique(np.round(np.column_stack([normal, offset]) * outward[:, None], 9), axis=0)
        hull = hull[np.abs(hull[:, :3]).max(axis=1) < 1.0 - 1e-9]  # an axis-aligned face is the box's own
        if len(hull) <= HULL_PLANES_MAX:
            planes.append(hull)
            rows += len(hull)
        else:
            sphere[part, 4:] = _bounding_cylinder(np.unique(vertices, axis=0))
    start[count] = rows
    return sphere, start, np.concatenate(planes) if planes else np.zeros((0, 4))


def _bounding_cylinder(vertices: np.ndarray) -> np.ndarray:
    """``(7,)`` a cylinder holding every vertex, along their principal axis: a point of the axis (the vertices'
    mean), the unit axis, the radius; the radius is inf where the cylinder is no smaller than their box (so it
    would tell a ray nothing the box does not)."""
    centre = vertices.mean(axis=0)
    offsets = vertices - centre
    axis = np.linalg.svd(offsets, full_matrices=False)[2][0]
    along = offsets @ axis
    radius = float(np.sqrt(np.max(np.einsum("ij,ij->i", offsets, offsets) - along * along, initial=0.0)))
    if math.pi * radius**2 * float(np.ptp(along)) >= float(np.prod(np.ptp(vertices, axis=0))):
        radius = math.inf
    return np.array([*centre, *axis, radius])


def _sub_boxes(triangles: np.ndarray, triangle_tile: np.ndarray, tile_convex: np.ndarray, tiles: int
               ) -> tuple[np.ndarray, ...]:
    """Each tile's triangles (small triangles of an object that is not convex) filed by a :data:`SUB_TILE` grid of
    their centroids: the box of each cell's triangles (``sub_low``, ``sub_high`` ``(S, 3)``), in rows (the cells of
    one grid x in a tile: ``row_low``, ``row_high`` ``(R, 3)``, each the box of its cells, which are rows
    ``sub_start[r]`` to ``sub_start[r + 1]``), tile by tile from row ``row_start[t]`` (``(T + 1,)``; a tile without
    them has none). Every triangle of such a tile lies in one cell's box; returns ``(row_start, row_low, row_high,
    sub_start, sub_low, sub_high)``."""
    rows = np.flatnonzero(triangle_tile >= 0)
    rows = rows[~tile_convex[triangle_tile[rows]]] if rows.size else rows
    if rows.size == 0:
        return (np.zeros(tiles + 1, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(1, np.int64),
                np.zeros((0, 3)), np.zeros((0, 3)))
    cell = np.floor(triangles[rows].mean(axis=1) / SUB_TILE).astype(np.int64)
    keys, group = np.unique(np.column_stack([triangle_tile[rows], cell]), axis=0, return_inverse=True)
    low, high = _group_boxes(triangles[rows].min(axis=1), triangles[rows].max(axis=1), group.reshape(-1))
    # keys are sorted by tile, then cell x: a row is a run of the same (tile, x).
    row_keys, row_of = np.unique(keys[:, :2], axis=0, return_inverse=True)
    row_of = row_of.reshape(-1)
    row_low, row_high = _group_boxes(low, high, row_of)
    sub_start = np.zeros(row_keys.shape[0] + 1, np.int64)
    np.add.at(sub_start, row_of + 1, 1)
    row_start = np.zeros(tiles + 1, np.int64)
    np.add.at(row_start, row_keys[:, 0] + 1, 1)
    return np.cumsum(row_start), row_low, row_high, np.cumsum(sub_start), low, high


def _group_boxes(low: np.ndarray, high: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box of each group of boxes, ``(G, 3)`` each."""
    groups = int(group.max()) + 1
    out_low = np.full((groups, 3), np.inf)
    out_high = np.full((groups, 3), -np.inf)
    np.minimum.at(out_low, group, low)
    np.maximum.at(out_high, group, high)
    return out_low, out_high


def _cut_triangle(triangle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boxes covering a large triangle: a grid over its two longest axes, the third axis from its plane."""
    low, high = triangle.min(axis=0), triangle.max(axis=0)
    size = high - low
    axes = np.argsort(size)[::-1]
    u, v, w = axes
    # At most CUT_CELLS cells a side: a huge triangle's pieces grow (they are far, with a wide footprint anyway).
    nu = min(CUT_CELLS, max(1, math.ceil(size[u] / TILE_SIZE)))
    nv = min(CUT_CELLS, max(1, math.ceil(size[v] / TILE_SIZE)))
    eu = np.linspace(low[u], high[u], nu + 1)
    ev = np.linspace(low[v], high[v], nv + 1)
    cu0, cv0 = np.meshgrid(eu[:-1], ev[:-1], indexing="ij")
    cu1, cv1 = np.meshgrid(eu[1:], ev[1:], indexing="ij")
    cu0, cv0, cu1, cv1 = (a.ravel() for a in (cu0, cv0, cu1, cv1))
    # The triangle's plane as w = f(u, v) when it is not edge-on to w; else the triangle's whole w-range.
    normal = np.cross(triangle[1] - triangle[0], triangle[2] - triangle[0])
    if abs(normal[w]) > 1e-12 * np.linalg.norm(normal):
        c = normal @ triangle[0]
        ws = [(c - normal[u] * a - normal[v] * b) / normal[w] for a in (cu0, cu1) for b in (cv0, cv1)]
        w0 = np.clip(np.minimum.reduce(ws), low[w], high[w])
        w1 = np.clip(np.maximum.reduce(ws), low[w], high[w])
    else:
        w0, w1 = np.full(cu0.size, low[w]), np.full(cu0.size, high[w])
    # Keep the cells the triangle's 2D footprint meets (its box test against the cell is enough here).
    box_low = np.empty((cu0.size, 3))
    box_high = np.empty((cu0.size, 3))
    box_low[:, u], box_low[:, v], box_low[:, w] = cu0, cv0, w0
    box_high[:, u], box_high[:, v], box_high[:, w] = cu1, cv1, w1
    meets = _triangle_meets_rectangles(triangle[:, [u, v]], cu0, cv0, cu1, cv1)
    return box_low[meets], box_high[meets]


def _triangle_meets_rectangles(tri2: np.ndarray, u0, v0, u1, v1) -> np.ndarray:
    """Separating-axis test of a 2D triangle against axis-aligned rectangles, ``(k,)`` bool."""
    corners = np.stack([np.column_stack([u0, v0]), np.column_stack([u1, v0]), np.column_stack([u1, v1]),
                        np.column_stack([u0, v1])], axis=1)
    meets = (tri2[:, 0].max() >= u0) & (tri2[:, 0].min() <= u1) & (tri2[:, 1].max() >= v0) & (tri2[:, 1].min() <= v1)
    for k in range(3):
        a, b = tri2[k], tri2[(k + 1) % 3]
        normal = np.array([b[1] - a[1], a[0] - b[0]])
        third = tri2[(k + 2) % 3]
        side = np.sign(normal @ (third - a))
        # The rectangle is wholly outside this edge when every corner lies on the far side.
        outside = np.all(side * ((corners - a) @ normal) < 0, axis=1)
        meets &= ~outside
    return meets
