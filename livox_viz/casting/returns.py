"""The datasheet return model: what a real Livox returns for each pulse, from the scene's geometry and materials.

For every pulse (a ray of the pattern) :meth:`ReturnModel.cast` gives its
returns, in five steps:

1. **Hits.** The central ray's first hit: range, triangle, material
   (:mod:`~livox_viz.scene.materials`) and incidence.
2. **Footprint.** Where the beam's footprint can see more than that triangle
   (:mod:`~livox_viz.casting.beam`), 18 more sub-rays sample it, each with its
   Gaussian share of the energy.
3. **Echoes.** Every sub-ray's echo power follows the lidar equation
   (:meth:`~livox_viz.config.returns_params.ReturnParams.signal_ratio`:
   reflectance x retroreflective gain x cos(incidence) x exp(-2 alpha r) / r^2,
   over the detection threshold); nothing nearer than the blind zone echoes.
   Sub-ray echoes nearer to each other than the echo separation merge into one
   echo at their energy-weighted range; a single-return sensor merges them all.
   An echo whose sub-rays lie at depths more than 3 range sigmas (at least 5 cm)
   off its strongest surface is a mixed point, and its tag's spatial-noise bits
   say how far between the surfaces it sits (01 high, 10 moderate, 11 low
   confidence of noise), as the Livox firmware flags its trailing edge points.
4. **Detection.** Each echo is seen when its power plus the receiver's noise
   (Gaussian, threshold / ``detection_snr`` 1-sigma) passes the threshold:
   exactly 50 % at the datasheet range for that reflectivity. A multi-return
   sensor reports the first echo and then the strongest others, up to its
   returns per pulse, in range order.
5. **The point.** Range noise (the sheet's 1-sigma at that range), direction
   noise, the reflectivity byte from the echo's power (0-150 Lambertian 0-100 %,
   151-255 retroreflective: power above twice a white Lambertian target's),
   the tag (SDK1 layout: bits 0-1 spatial noise, 2-3 intensity noise, 4-5
   return number: 1-3 in range order, 0 for a first return nearer than
   ``return0_range_m``, which merges with the sensor's internal return 0) and
   the return number (1-based, as LAS). A pulse that returns nothing gives no
   point, except a false alarm at the sheet's rate: a point at a random range,
   tagged as noise (spatial 01, intensity 01).

Every random number is a function of the seed and the pulse's stream index
(:mod:`~livox_viz.core.streamrandom`), so a scan is the same however it is cut
into frames. The per-pulse loops are compiled (:mod:`~livox_viz.casting.return_kernels`);
Embree casts the central rays, the broad phase's boxes, the probes and the sub-rays.
"""

from __future__ import annotations

import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np

from livox_viz.casting.beam import SUBRAY_WEIGHTS, Footprint, TileProxy, TriangleEdges
from livox_viz.casting.codec import INT16_SCALE
from livox_viz.casting.return_kernels import kernel
from livox_viz.config.returns_params import ReturnParams
from livox_viz.core.buffers import RecycledBlocks, carve, carved_size
from livox_viz.core.rotations import rotate_rows
from livox_viz.core.streamrandom import stream_key
from livox_viz.scene.materials import face_materials

#: The purposes of the random numbers (each its own stream under one seed).
_ECHO_NOISE, _LATER_ECHO_NOISE, _ANGLE_NOISE, _FALSE_ALARM, _FALSE_ALARM_POINT = 1, 2, 3, 4, 5
#: Reflectivity byte: Lambertian 0-100 % -> 0-150; a retroreflector (power over twice a white Lambertian
#: target's) -> 151 at twice, 255 at 1000 times.
LAMBERTIAN_TOP = 150
RETRO_FLOOR, RETRO_TOP = 2.0, 1000.0
#: Tag bits (Livox SDK1 layout).
SPATIAL_HIGH, SPATIAL_MODERATE, SPATIAL_LOW = 0x01, 0x02, 0x03
INTENSITY_NOISE = 0x04
#: Least depth off its surface that makes a point mixed, metres (3 range sigmas when larger).
MIX_FLOOR_M = 0.05
#: Pulses a part of :meth:`ReturnModel.cast` has at least when a run is cut over the caster's threads.
SPLIT_PULSES = 2048
#: Where a run's points' arrays live (see :mod:`livox_viz.core.buffers`): a pool of the model's own, so that its
#: blocks, a third larger than the ideal scan's for as many points, and the ideal scan's do not push each other out
#: when both run in turn (the blocks made anew faulted in 200-500 pages a second of scan). Four blocks: a scan holds
#: up to four runs at once (two cast, one waiting, one being written); eight kept 50-80 MiB more over a 10-minute
#: flight to a bag, two faulted in pages again.
RETURN_BLOCKS = RecycledBlocks(keep=4)
#: Rows for false alarms in a run's points, first try: this many times those expected, and this many more.
FALSE_ALARM_ROWS = (4.0, 64)
#: Tiles the broad phase lists per beam for the narrow phase (a beam crossing more may meet something anywhere).
CROSSED_LISTED = 8
#: The steps :attr:`ReturnModel.stage_seconds` times (summed over the threads that ran them).
STAGES = ("central rays", "materials, edges and reach", "broad phase", "probes", "footprint sub-rays",
          "detection, noise, tags")
#: "No times given" for the compiled loops (they test its length).
_NO_TIMES = np.empty(0, dtype=np.float64)
#: Turns sensor-frame vectors of some pulses (rows of the run) into the world frame: a moving sensor's own pose
#: at each pulse's time.
Turn = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ReturnPoints:
    """The returns of a run of pulses, in pulse order and range order within a pulse.

    Parameters
    ----------
    beam : (M,) int64
        The pulse of each return, as a row of the run.
    stream_index : (M,) int64
        Its pulse's stream index.
    t : (M,) float64
        Its pulse's emission time, seconds.
    xy_deg : (M, 2) float64
        Its pulse's pattern angles, degrees.
    range_m : (M,) float64
        Measured range, metres.
    xyz_sensor : (M, 3) float64
        The measured point in the sensor FRD frame at its pulse's time, metres.
    xyz_int16 : (M, 3) int16
        Its int16 encoding (:func:`~livox_viz.casting.codec.encode_int16`), never (0, 0, 0).
    xyz_world : (M, 3) float64
        The same point in the world NED frame.
    reflectivity : (M,) uint8
        0-150 Lambertian 0-100 %, 151-255 retroreflective.
    tag : (M,) uint8
        Bits 0-1 spatial noise, 2-3 intensity noise, 4-5 return number (Livox SDK1).
    return_number : (M,) uint8
        1 for the nearest return of its pulse, then 2, 3.
    number_of_returns : (M,) uint8
        Returns of its pulse.
    """

    beam: np.ndarray
    stream_index: np.ndarray
    t: np.ndarray
    xy_deg: np.ndarray
    range_m: np.ndarray
    xyz_sensor: np.ndarray
    xyz_int16: np.ndarray
    xyz_world: np.ndarray
    reflectivity: np.ndarray
    tag: np.ndarray
    return_number: np.ndarray
    number_of_returns: np.ndarray


def sensor_basis(xy_deg: np.ndarray, plane: str = "boresight") -> tuple[np.ndarray, np.ndarray]:
    """The directions a beam's footprint spreads along, sensor frame: ``(n, 3)`` derivatives of each ray by
    pattern x and y per radian (boresight plane), or the unit azimuth and elevation tangents (panorama, whose
    beams' divergence is H along the azimuth, V along the elevation)."""
    xy_deg = np.ascontiguousarray(xy_deg, dtype=np.float64)
    along_x, along_y = np.empty((xy_deg.shape[0], 3)), np.empty((xy_deg.shape[0], 3))
    kernel("sensor_basis")(xy_deg, plane == "panorama", along_x, along_y)
    return along_x, along_y


class _Basis:
    """What gives beams' ray derivatives by pattern x and y: a fixed sensor's pattern angles and rotation, or a
    moving one's per-pulse world vectors (``basis_x``, ``basis_y``; empty for a fixed sensor)."""

    def __init__(self, xy_deg: np.ndarray, panorama: bool, rotation: np.ndarray, basis_x: np.ndarray,
                 basis_y: np.ndarray) -> None:
        self.xy_deg, self.panorama, self.rotation, self.basis_x, self.basis_y = (xy_deg, panorama, rotation, basis_x,
                                                                                 basis_y)

    def rays(self, rows: np.ndarray, directions_world: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Unit directions ``(len(rows), k, 3)`` float32 of the rays at ``offsets`` ``(k, 2)`` radians around the
        beams ``rows``."""
        out = np.empty((rows.size, offsets.shape[0], 3), dtype=np.float32)
        kernel("offset_rays")(rows, directions_world, self.xy_deg, self.panorama, self.rotation, self.basis_x,
                              self.basis_y, offsets, out)
        return out


class ReturnModel:
    """A sensor's datasheet return model over one scene.

    Parameters
    ----------
    params : ReturnParams
    caster : EmbreeCaster or TrimeshCaster
        The scene's caster (``hits``, ``occluded``, ``face_planes``, ``mesh`` with its materials).
    seed : int
        Seed of every random number (with each pulse's stream index).
    range_max : float
        The scan's maximum range (``otherParams[0]``), metres.
    point_rate : float
        Pulses per second: a pulse's time is its stream index over it when :meth:`cast` is given none.
    plane : {"boresight", "panorama"}
        The pattern plane of the angles :meth:`cast` is given (:mod:`livox_viz.patterns.planes`).
    """

    def __init__(self, params: ReturnParams, caster, seed: int, range_max: float, point_rate: float,
                 plane: str = "boresight") -> None:
        for method in ("hits", "occluded", "face_planes"):
            if not hasattr(caster, method):
                raise TypeError(f"the datasheet return model needs a caster with {method!r}")
        self.params = params
        self.caster = caster
        self.seed = int(seed)
        self.range_max = float(range_max)
        self.plane = plane
        self.point_rate = float(point_rate)
        self.footprint = Footprint(params.divergence_deg)
        self._tables = _scene_tables(caster)
        if "brightness" not in self._tables:
            reflectance, gain = face_materials(caster.mesh)
            self._tables["brightness"] = np.ascontiguousarray(reflectance * gain)
        #: (F,) Lambertian reflectance x retroreflective gain of each triangle.
        self.brightness = self._tables["brightness"]
        rho_a, r_a = params.detection_range_m[0]
        self._calibration = np.array([rho_a, r_a, params.range_loss_per_m])
        self._sigma_table = np.ascontiguousarray(params.range_sigma_m, dtype=np.float64)
        #: The random streams' keys: echo noise, later echoes' noise, angular noise, false alarms, their points.
        self._key_array = np.array([stream_key(self.seed, purpose) for purpose in (
            _ECHO_NOISE, _LATER_ECHO_NOISE, _ANGLE_NOISE, _FALSE_ALARM, _FALSE_ALARM_POINT)], dtype=np.uint64)
        #: Farthest range a false alarm may come from: the sensor's range gate.
        self.false_alarm_reach = min(self.range_max, params.detection_range(0.8))
        #: What the last run did (for benchmarks): pulses, footprints leaving their triangle, pulses the broad
        #: phase named, those of them whose footprint stays on its triangle (probed), and those the probes found
        #: covered.
        self.last_counts: dict[str, int] = {}
        #: Wall time spent in each step since the model was made, seconds (for benchmarks).
        self.stage_seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._laps = threading.local()  # each worker thread times its own frame
        self._laps_lock = threading.Lock()

    def _lap(self, stage: str) -> None:
        now = time.perf_counter()
        with self._laps_lock:
            self.stage_seconds[stage] += now - self._laps.clock
        self._laps.clock = now

    @property
    def edges(self) -> TriangleEdges:
        """The triangles' edge lines and smooth neighbours (made on first use, once per scene)."""
        with _TABLES_MADE:
            if "edges" not in self._tables:
                self._tables["edges"] = TriangleEdges(self.caster.mesh)
            return self._tables["edges"]

    @property
    def proxy(self) -> TileProxy:
        """The broad phase's boxes (made on first use, once per scene and beam divergence)."""
        key = ("proxy", self.footprint.tan_half_max)
        with _TABLES_MADE:
            if key not in self._tables:
                self._tables[key] = TileProxy(self.caster.mesh, self.footprint.tan_half_max)
            return self._tables[key]

    # The run ------------------------------------------------------------------------------------------
    def cast(self, start: int, xy_deg: np.ndarray, directions_sensor: np.ndarray, directions_world: np.ndarray,
             origin: np.ndarray, rotation: np.ndarray | None = None, turn: Turn | None = None,
             times: np.ndarray | None = None) -> ReturnPoints:
        """The returns of ``n`` consecutive pulses.

        A long run is cut into one part per thread of the caster (at least :data:`SPLIT_PULSES` pulses each),
        each part cast start to finish on its own thread: every step, not only Embree's, then uses both
        cores. Each pulse's returns depend only on the seed and its stream index, so the parts give the
        cloud the whole run would.

        Parameters
        ----------
        start : int
            Stream index of the first pulse.
        xy_deg : (n, 2) float64
            Pattern angles, degrees.
        directions_sensor, directions_world : (n, 3) float64
            Unit ray directions, sensor FRD and world NED.
        origin : (3,) or (n, 3) float64
            The sensor's position (per pulse when moving), world NED, metres.
        rotation : (3, 3) float64, optional
            Sensor FRD -> world NED, fixed pose.
        turn : callable, optional
            A moving sensor: ``turn(vectors, rows)`` gives the sensor-frame ``vectors`` of the pulses ``rows``
            in the world frame, each with its pulse's pose.
        times : (n,) float64, optional
            The pulses' emission times, seconds; default their stream index / ``point_rate``.
        """
        n = xy_deg.shape[0]
        origins = np.asarray(origin, dtype=np.float64).reshape(-1, 3)
        map_parts = getattr(self.caster, "map_parts", None)

        def part(bounds: tuple[int, int]) -> tuple[ReturnPoints, dict[str, int]]:
            low, high = bounds
            shifted = None if turn is None else (lambda vectors, rows: turn(vectors, rows + low))
            points, counts = self._cast_run(start + low, xy_deg[low:high], directions_sensor[low:high],
                                            directions_world[low:high],
                                            origins if origins.shape[0] == 1 else origins[low:high], rotation,
                                            shifted, None if times is None else times[low:high])
            np.add(points.beam, low, out=points.beam)  # rows of the whole run
            return points, counts

        found = map_parts(part, n, SPLIT_PULSES) if map_parts is not None else [part((0, n))]
        counts: dict[str, int] = {}
        for _, part_counts in found:
            for name, value in part_counts.items():
                counts[name] = counts.get(name, 0) + value
        self.last_counts = counts
        if len(found) == 1:
            return found[0][0]
        return ReturnPoints(*(np.concatenate([getattr(p, column.name) for p, _ in found])
                              for column in fields(ReturnPoints)))

    def _cast_run(self, start: int, xy_deg: np.ndarray, directions_sensor: np.ndarray,
                  directions_world: np.ndarray, origin: np.ndarray, rotation: np.ndarray | None,
                  turn: Turn | None, times: np.ndarray | None) -> tuple[ReturnPoints, dict[str, int]]:
        """:meth:`cast` of one part in the calling thread, with what its footprint tests sent on."""
        self._laps.clock = time.perf_counter()
        footprint = self.footprint
        n = xy_deg.shape[0]
        origins = np.ascontiguousarray(np.asarray(origin, dtype=np.float64).reshape(-1, 3))
        moving = origins.shape[0] > 1 or turn is not None
        directions_world = np.ascontiguousarray(directions_world, dtype=np.float64)
        distance, triangle = self._central_hits(origins, directions_world, moving)
        self._lap("central rays")
        planes = self.caster.face_planes
        edges = self.edges
        xy_deg = np.ascontiguousarray(xy_deg, dtype=np.float64)
        rotation = np.eye(3) if rotation is None else np.ascontiguousarray(rotation, dtype=np.float64)
        panorama = self.plane == "panorama"
        if turn is None:
            basis_x = basis_y = np.empty((0, 3))  # a fixed sensor's come from the pattern angles and the rotation
        else:
            basis_x, basis_y = sensor_basis(xy_deg, self.plane)
            every = np.arange(n)
            basis_x, basis_y = turn(basis_x, every), turn(basis_y, every)
        power, unit, reach = np.empty(n), np.empty(n), np.empty(n)
        leaves = np.empty(n, dtype=np.bool_)
        kernel("central")(distance, triangle, directions_world, origins, xy_deg, panorama, rotation, basis_x, basis_y,
                          planes, self.brightness, edges.incentre, edges.inradius, edges.inward, edges.offset,
                          edges.neighbour, edges.narrowest, footprint.half_rad[0], footprint.half_rad[1],
                          footprint.tan_half_max, self._calibration, self.range_max, power, unit, leaves, reach)
        rows_basis = _Basis(xy_deg, panorama, rotation, basis_x, basis_y)
        self._lap("materials, edges and reach")
        covered, near, may_meet, probed = self._covered(leaves, directions_world, origins, rows_basis, reach,
                                                        triangle, distance, moving, directions_sensor, rotation)
        sampled_mask = leaves.copy()
        sampled_mask[covered] = True
        sampled = np.flatnonzero(sampled_mask)
        counts = {"pulses": n, "leaves": int(leaves.sum()), "named": int(near.sum()), "probed": probed,
                  "covered": int(covered.size)}
        if sampled.size:
            footprint_echoes = self._footprint_echoes(sampled, directions_world, origins, rows_basis, distance,
                                                      triangle, moving, ~near[sampled], may_meet)
        else:
            footprint_echoes = [np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0, np.uint8), np.zeros(0)]
        self._lap("footprint sub-rays")
        points = self._points(start, sampled, triangle, power, unit, distance, footprint_echoes, directions_sensor,
                              directions_world, origins, rotation, turn, xy_deg, times)
        self._lap("detection, noise, tags")
        return points, counts

    def _central_hits(self, origins: np.ndarray, directions_world: np.ndarray,
                      moving: bool) -> tuple[np.ndarray, np.ndarray]:
        """Each central ray's distance (float64, from its triangle's plane) and triangle (int64, as every step
        wants it; -1 for a miss)."""
        ray_origin = origins[0] if not moving else origins
        if not hasattr(self.caster, "triangle_ids"):
            distance, triangle = self.caster.hits(ray_origin, directions_world, self.range_max)
            return distance, triangle.astype(np.int64)
        triangle = self.caster.triangle_ids(ray_origin, directions_world, self.range_max).astype(np.int64)
        distance = np.empty(triangle.size)
        if kernel("plane_distance")(triangle, directions_world, origins, self.caster.face_planes, self.range_max,
                                    distance):
            # A ray along its triangle's plane: Embree's own distance.
            rows = np.flatnonzero(distance < 0)
            distance[rows] = self.caster.distances(origins[rows] if moving else ray_origin, directions_world[rows],
                                                   self.range_max)
            triangle[rows[~np.isfinite(distance[rows])]] = -1
        return distance, triangle

    # Step 2: footprints something nearer covers --------------------------------------------------------------
    def _covered(self, leaves: np.ndarray, directions_world: np.ndarray, origins: np.ndarray,
                 rows_basis: _Basis, reach: np.ndarray, triangle: np.ndarray, distance: np.ndarray, moving: bool,
                 directions_sensor: np.ndarray, rotation: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray], int]:
        """The pulses whose footprint stays on its triangle (or whose ray meets nothing) but something nearer covers
        in part (sorted rows);
        for every pulse whether the broad phase names anything but its own surface along the beam (``(n,)``
        bool: a footprint leaving its triangle with nothing named needs no cast for its sub-rays that stay on it);
        and ``may_meet(pulse, rays, limit)``, whether rays of those pulses' footprints can meet anything but their
        hit before their limits (:meth:`~livox_viz.casting.beam.TileProxy.rays_may_meet` over the boxes placed);
        and how many pulses the broad phase named whose footprint stays on its triangle (those probed).

        Nearer means in front of the hit's plane by more than the range sigma at the hit: a surface closer
        to the plane than that (a crease of a terrain, a poster on a wall) moves the point by less than its
        range noise and can neither make it mixed (3 sigmas) nor a return of its own (the echo separation),
        so its footprint is not sampled; what it leaves out is that surface's share of the energy.
        """
        proxy = self.proxy
        # Frames (and parts of one) are cast side by side, and the boxes are placed for one run's sensor
        # positions: each run asks the boxes placed for it, which a later placing replaces but does not change.
        with proxy.lock:
            boxes = proxy.place(origins[0] if not moving else origins[:: max(1, origins.shape[0] // 64)],
                                self.range_max, None if moving else rotation)
        # A fixed sensor's beams look up their direction's boxes (a boresight grid: not for a panoramic head).
        in_grid = None if moving or self.plane != "boresight" else directions_sensor
        crossed = np.empty((triangle.size, CROSSED_LISTED), np.int32)
        near = proxy.near(np.ones(triangle.size, dtype=np.bool_), origins, directions_world, reach, triangle,
                          in_grid, boxes, crossed)
        rows = np.flatnonzero(near & ~leaves)

        def may_meet(pulse: np.ndarray, rays: np.ndarray, limit: np.ndarray) -> np.ndarray:
            return proxy.rays_may_meet(pulse, rays, limit, triangle, origins, crossed)

        self._lap("broad phase")
        if rows.size == 0:
            return rows, near, may_meet, 0
        # Probe rays at the corners of the footprint's bounding box: is anything in front of the hit's plane?
        probes = rows_basis.rays(rows, directions_world, self.footprint.probe_offsets)
        limit = np.empty((rows.size, 4))
        kernel("probe_limits")(rows, probes, triangle, distance, self.caster.face_planes, origins, self.range_max,
                               self._sigma_table, limit)
        # Embree casts only the probes that can meet something (in a tile itself, a convex object's hull, a flat
        # object): a probe that cannot is not blocked. Each probe is asked on its own: a test costs a
        # sixteenth of a cast, and a third of the probes of the beams worth probing can meet nothing.
        probe_rows = np.repeat(rows, 4)
        worth = np.flatnonzero(may_meet(probe_rows, probes.reshape(-1, 3), limit.reshape(-1)))
        probe_rows = probe_rows[worth]
        ray_origin = origins[0] if not moving else origins[probe_rows]
        blocked = self.caster.occluded(ray_origin, probes.reshape(-1, 3)[worth], limit.reshape(-1)[worth])
        self._lap("probes")
        covered = probe_rows[blocked]  # in order, a pulse's blocked probes side by side
        return (covered[np.r_[True, covered[1:] != covered[:-1]]] if covered.size else covered, near, may_meet,
                int(rows.size))

    # Step 3: echoes of sampled footprints ------------------------------------------------------------------
    def _footprint_echoes(self, rows: np.ndarray, directions_world: np.ndarray, origins: np.ndarray,
                          rows_basis: _Basis, distance: np.ndarray, triangle: np.ndarray,
                          moving: bool, clear: np.ndarray,
                          may_meet: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> list[np.ndarray]:
        """The echoes of pulses sampled with all 19 sub-rays: how many each has, then, in 19 slots a pulse, their
        power, range, spatial bits and the reflectance one unit of power means at their range.

        A sub-ray that lands inside its pulse's own triangle meets that triangle when nothing else can be in
        front: for a ``clear`` pulse (the broad phase named nothing but its own surface before the footprint's
        reach), and for another where ``may_meet`` says the sub-ray can meet nothing before the plane. Its range
        comes from the plane, without a cast. A sub-ray of a pulse whose central ray met nothing, and which
        ``may_meet`` says can meet nothing within the range, is a miss without a cast. The others are cast.
        """
        params = self.params
        m = rows.size
        count = SUBRAY_WEIGHTS.size
        rays = rows_basis.rays(rows, directions_world, self.footprint.subray_offsets)
        ranges = np.empty((m, count))
        triangles = np.empty((m, count), dtype=np.int64)
        ranges[:, 0], triangles[:, 0] = distance[rows], triangle[rows]
        edges = self.edges
        most = m * (count - 1)
        slots, listed_rays = np.empty(most, np.int64), np.empty((most, 3), np.float32)
        asked, asked_rays = np.empty(most, np.int64), np.empty((most, 3), np.float32)
        asked_pulse, asked_limit = np.empty(most, np.int64), np.empty(most)
        listed, questions = kernel("own_subrays")(rows, np.ascontiguousarray(clear, dtype=np.bool_), rays, triangle,
                                                  self.caster.face_planes, origins, edges.inward, edges.offset,
                                                  self.range_max, ranges, triangles, slots, listed_rays, asked,
                                                  asked_rays, asked_pulse, asked_limit)
        # A sub-ray that lands on its own triangle, or one of a pulse whose central ray met nothing, and that can
        # meet nothing else before there, resp. before the range: the plane's range, resp. a miss, without a cast.
        if questions:
            meet = may_meet(asked_pulse[:questions], asked_rays[:questions], asked_limit[:questions])
            listed = kernel("free_subrays")(listed, asked[:questions], meet, slots, listed_rays)
        slots, sub_rays = slots[:listed], listed_rays[:listed]
        ray_origin = origins[0] if not moving else origins[rows[slots // count]]
        if hasattr(self.caster, "triangle_ids"):
            # The sub-rays' triangles from Embree, their ranges from those triangles' planes.
            kernel("cast_subrays")(slots, self.caster.triangle_ids(ray_origin, sub_rays, self.range_max), sub_rays,
                                   rows, origins, self.caster.face_planes, self.range_max, ranges, triangles)
        else:
            ranges.reshape(-1)[slots], triangles.reshape(-1)[slots] = self.caster.hits(ray_origin, sub_rays,
                                                                                       self.range_max)
        written = np.empty(m, np.int64)
        slot = np.empty(m * count, np.int64)
        power, range_m, unit = np.empty(m * count), np.empty(m * count), np.empty(m * count)
        spatial = np.zeros(m * count, np.uint8)
        kernel("footprint_echoes")(rows, ranges, triangles, rays, SUBRAY_WEIGHTS, self.caster.face_planes,
                                   self.brightness, origins, params.blind_zone_m, params.returns_per_pulse > 1,
                                   params.return_separation_m, self._sigma_table, MIX_FLOOR_M, self._calibration,
                                   written, slot, power, range_m, spatial, unit)
        return [written, power, range_m, spatial, unit]

    # Steps 4 and 5: detection and the points -----------------------------------------------------------
    def _points(self, start: int, sampled: np.ndarray, triangle: np.ndarray, power: np.ndarray, unit: np.ndarray,
                distance: np.ndarray, footprint_echoes: list[np.ndarray], directions_sensor: np.ndarray,
                directions_world: np.ndarray, origins: np.ndarray, rotation: np.ndarray, turn: Turn | None,
                xy_deg: np.ndarray, times: np.ndarray | None) -> ReturnPoints:
        """Detection, selection, noise, reflectivity and tags, false alarms: the run's points in pulse order, each
        with its pulse's index, time and angles and its int16 encoding (none that encodes as (0, 0, 0)).

        ``start`` is the first pulse's stream index; ``sampled`` the pulses whose footprint was sampled (rows,
        ascending) and ``footprint_echoes`` their echoes (:meth:`_footprint_echoes`); every other pulse whose
        central ray met a triangle past the blind zone is whole (its hit's ``power`` at ``distance``)."""
        params = self.params
        echoes = footprint_echoes[1].size
        seen, measured, chosen = np.empty(echoes), np.empty(echoes), np.empty(echoes, dtype=np.bool_)
        # A point a pulse that met something and a footprint echo at most, and a false alarm from a pulse without
        # either: rows for a few times the expected false alarms, and for all of them in the rare run that has more
        # (sized for every pulse, the blocks were a third larger than the points: they faulted in pages again).
        hits = int(np.count_nonzero(triangle >= 0))
        others = triangle.size - hits
        scale, least = FALSE_ALARM_ROWS
        jitter = float(np.radians(params.angular_sigma_deg))
        for total in (hits + echoes + min(others, int(scale * params.false_alarm_rate * others) + least),
                      triangle.size + echoes):
            out = self._emit(total, start, sampled, triangle, power, distance, unit, footprint_echoes,
                             directions_sensor, directions_world, origins, xy_deg, times, jitter, seen, measured,
                             chosen)
            if out is not None:
                break
        if jitter > 0 and out["beam"].size:
            xyz_sensor, beam = out["xyz_sensor"], out["beam"]
            turned = rotate_rows(xyz_sensor, rotation) if turn is None else turn(xyz_sensor, beam)
            np.add(origins[0] if origins.shape[0] == 1 else origins[beam], turned, out=out["xyz_world"])
        return ReturnPoints(**out)

    def _emit(self, total: int, start: int, sampled: np.ndarray, triangle: np.ndarray, power: np.ndarray,
              distance: np.ndarray, unit: np.ndarray, footprint_echoes: list[np.ndarray],
              directions_sensor: np.ndarray, directions_world: np.ndarray, origins: np.ndarray, xy_deg: np.ndarray,
              times: np.ndarray | None, jitter: float, seen: np.ndarray, measured: np.ndarray,
              chosen: np.ndarray) -> dict[str, np.ndarray] | None:
        """The compiled pass of :meth:`_points` into arrays of ``total`` rows (views of a recycled block), cut to
        the points written; None when ``total`` rows were too few. ``jitter``: the angular noise's 1-sigma,
        radians."""
        params = self.params
        written, e_power, e_range, e_spatial, e_unit = footprint_echoes
        layout = [("beam", (total,), np.int64), ("stream_index", (total,), np.int64), ("t", (total,), np.float64),
                  ("xy_deg", (total, 2), np.float64), ("range_m", (total,), np.float64),
                  ("xyz_sensor", (total, 3), np.float64), ("xyz_int16", (total, 3), np.int16),
                  ("xyz_world", (total, 3), np.float64), ("reflectivity", (total,), np.uint8),
                  ("tag", (total,), np.uint8), ("return_number", (total,), np.uint8),
                  ("number_of_returns", (total,), np.uint8)]
        out = carve(RETURN_BLOCKS.get(carved_size(layout)), layout)
        kept = kernel("emit")(triangle, power, distance, unit, sampled, written, SUBRAY_WEIGHTS.size, e_power,
                              e_range, e_spatial, e_unit, start, self._key_array, params.detection_snr,
                              self._sigma_table, params.blind_zone_m, self.range_max, params.returns_per_pulse,
                              params.false_alarm_rate, params.return0_range_m, self.false_alarm_reach,
                              np.ascontiguousarray(directions_sensor), directions_world, origins, jitter, xy_deg,
                              _NO_TIMES if times is None else np.ascontiguousarray(times, dtype=np.float64),
                              self.point_rate, INT16_SCALE / self.range_max, seen, measured, chosen, *out.values())
        if kept < 0:
            return None
        return out if kept == total else {name: values[:kept] for name, values in out.items()}


def reflectivity_byte(reflectance: np.ndarray) -> np.ndarray:
    """Livox's reflectivity byte of an echo whose power implies ``reflectance`` (white Lambertian = 1), ``(n,)`` uint8.

    0-150 for 0-100 % Lambertian (saturating at 150 up to twice a white target), 151-255 for a
    retroreflector, logarithmic from twice to 1000 times a white target's power (rounded half up).
    """
    reflectance = np.asarray(reflectance, dtype=np.float64)
    byte = np.floor(LAMBERTIAN_TOP * np.clip(reflectance, 0.0, 1.0) + 0.5)
    retro = np.flatnonzero(reflectance >= RETRO_FLOOR)
    if retro.size:
        byte[retro] = 151.0 + np.floor(104.0 * np.clip(np.log(reflectance[retro] / RETRO_FLOOR)
                                                       / np.log(RETRO_TOP / RETRO_FLOOR), 0.0, 1.0) + 0.5)
    return byte.astype(np.uint8)


#: Per ray caster (one scene): the tables a return model makes from its mesh, kept while the caster lives, so a
#: restart (a slider, a new preset) does not make them again.
_TABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: Held while a scene's table is looked up or made: frames cast on worker threads share them.
_TABLES_MADE = threading.RLock()


def _scene_tables(caster) -> dict:
    try:
        return _TABLES.setdefault(caster, {})
    except TypeError:  # a caster that cannot be weakly referenced keeps its tables with the model
        return {}
