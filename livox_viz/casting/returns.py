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
into frames.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass

import numpy as np

from livox_viz.casting.beam import SUBRAY_WEIGHTS, Footprint, TileProxy, TriangleEdges
from livox_viz.config.returns_params import ReturnParams
from livox_viz.core.rotations import quat_rotate, rotate_rows
from livox_viz.core.streamrandom import MAX_COLUMNS, stream_normal, stream_uniform
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
#: The steps :attr:`ReturnModel.stage_seconds` times.
STAGES = ("central rays", "materials and reach", "edge test", "broad phase", "probes", "footprint sub-rays",
          "detection, noise, tags")


@dataclass(frozen=True)
class ReturnPoints:
    """The returns of a run of pulses, in pulse order and range order within a pulse.

    Parameters
    ----------
    beam : (M,) int64
        The pulse of each return, as a row of the run.
    range_m : (M,) float64
        Measured range, metres.
    xyz_sensor : (M, 3) float64
        The measured point in the sensor FRD frame at its pulse's time, metres.
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
    range_m: np.ndarray
    xyz_sensor: np.ndarray
    xyz_world: np.ndarray
    reflectivity: np.ndarray
    tag: np.ndarray
    return_number: np.ndarray
    number_of_returns: np.ndarray


@dataclass
class _Placement:
    """Where a run of pulses fires from: one pose, or one per pulse (moving sensor)."""

    origin: np.ndarray  # (3,) or (n, 3), world NED
    rotation: np.ndarray | None  # (3, 3) sensor FRD -> world NED, fixed pose
    quaternion: np.ndarray | None  # (n, 4), per pulse

    def origins(self, rows: np.ndarray, repeat: int = 1) -> np.ndarray:
        """Ray origins of ``rows`` (each ``repeat`` times), ``(3,)`` for a fixed pose."""
        if self.quaternion is None:
            return self.origin
        return np.repeat(self.origin[rows], repeat, axis=0)

    def origin_of(self, rows: np.ndarray) -> np.ndarray:
        """The origin of each of ``rows``: ``(3,)`` for a fixed pose, else ``(len(rows), 3)``."""
        return self.origin if self.quaternion is None else self.origin[rows]

    def to_world(self, vectors: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Sensor-frame vectors ``(len(rows), 3)`` of the pulses ``rows`` turned into the world frame."""
        if self.quaternion is None:
            return rotate_rows(vectors, self.rotation)
        return quat_rotate(self.quaternion[rows], vectors)


def _dot_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of ``(n, 3)`` arrays (``b`` may be ``(3,)``)."""
    if b.ndim == 1:
        return a[:, 0] * b[0] + a[:, 1] * b[1] + a[:, 2] * b[2]
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


@dataclass
class _Echoes:
    """Candidate echoes, one row each."""

    beam: np.ndarray  # (K,) int64 row of the run
    slot: np.ndarray  # (K,) int64 its rank in range among its pulse's echoes
    power: np.ndarray  # (K,) float64 over the detection threshold
    range_m: np.ndarray  # (K,) float64
    spatial: np.ndarray  # (K,) uint8 spatial-noise bits
    calibration: np.ndarray  # (K,) float64 the reflectance one unit of power means at the echo's range

    def where(self, keep: np.ndarray) -> _Echoes:
        return _Echoes(self.beam[keep], self.slot[keep], self.power[keep], self.range_m[keep], self.spatial[keep],
                       self.calibration[keep])


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
    """

    def __init__(self, params: ReturnParams, caster, seed: int, range_max: float) -> None:
        for method in ("hits", "occluded", "face_planes"):
            if not hasattr(caster, method):
                raise TypeError(f"the datasheet return model needs a caster with {method!r}")
        self.params = params
        self.caster = caster
        self.seed = int(seed)
        self.range_max = float(range_max)
        self.footprint = Footprint(params.divergence_deg)
        self._tables = _scene_tables(caster)
        if "brightness" not in self._tables:
            reflectance, gain = face_materials(caster.mesh)
            self._tables["brightness"] = reflectance * gain
        #: (F,) Lambertian reflectance x retroreflective gain of each triangle.
        self.brightness = self._tables["brightness"]
        #: Farthest range a false alarm may come from: the sensor's range gate.
        self.false_alarm_reach = min(self.range_max, params.detection_range(0.8))
        #: What the last run did (for benchmarks): pulses, footprints leaving their triangle, pulses the broad
        #: phase named, and those the probes found covered.
        self.last_counts: dict[str, int] = {}
        #: Wall time spent in each step since the model was made, seconds (for benchmarks).
        self.stage_seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._clock = 0.0

    def _lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.stage_seconds[stage] += now - self._clock
        self._clock = now

    @property
    def edges(self) -> TriangleEdges:
        """The triangles' edge lines and smooth neighbours (made on first use, once per scene)."""
        if "edges" not in self._tables:
            self._tables["edges"] = TriangleEdges(self.caster.mesh)
        return self._tables["edges"]

    @property
    def proxy(self) -> TileProxy:
        """The broad phase's boxes (made on first use, once per scene and beam divergence)."""
        key = ("proxy", self.footprint.tan_half_max)
        if key not in self._tables:
            self._tables[key] = TileProxy(self.caster.mesh, self.footprint.tan_half_max, type(self.caster))
        return self._tables[key]

    # The run ------------------------------------------------------------------------------------------
    def cast(self, start: int, xy_deg: np.ndarray, directions_sensor: np.ndarray, directions_world: np.ndarray,
             origin: np.ndarray, rotation: np.ndarray | None = None,
             quaternion: np.ndarray | None = None) -> ReturnPoints:
        """The returns of ``n`` consecutive pulses.

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
        quaternion : (n, 4) float64, optional
            Per pulse, moving sensor [x, y, z, w].
        """
        self._clock = time.perf_counter()
        n = xy_deg.shape[0]
        index = start + np.arange(n, dtype=np.int64)
        place = _Placement(np.asarray(origin, dtype=np.float64), rotation, quaternion)
        distance, triangle = self.caster.hits(place.origin, directions_world, self.range_max)
        self._lap("central rays")
        hit = np.flatnonzero(triangle >= 0)
        tri, d, ray = triangle[hit], distance[hit], directions_world[hit]
        normal = self.caster.face_planes[tri, :3]
        facing = _dot_rows(normal, ray)
        cos = np.maximum(np.abs(facing), 1e-6)
        power = self.params.signal_ratio(self.brightness[tri], cos, d)
        point = place.origin_of(hit) + ray * d[:, None]
        self._lap("materials and reach")
        leaves = self._leaves(hit, tri, d, ray, normal, facing, point, xy_deg, place)
        self._lap("edge test")
        # How far along each beam the footprint may meet something: the farthest range it reaches on its plane.
        reach = np.full(n, self.range_max)
        sine = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
        reach[hit] = np.minimum(d * (1.0 + 1.01 * self.footprint.tan_half_max * sine / cos) + 0.01, self.range_max)
        candidate = np.ones(n, dtype=bool)
        candidate[hit[leaves]] = False
        covered = self._covered(np.flatnonzero(candidate), xy_deg, directions_world, place, reach, distance,
                                triangle)
        sampled = np.union1d(hit[leaves], covered)
        self.last_counts = {"pulses": n, "leaves": int(leaves.sum()), "covered": int(covered.size),
                            "near": self.last_counts.get("near", 0)}
        whole = d >= self.params.blind_zone_m
        if sampled.size:
            whole[np.searchsorted(hit, sampled[triangle[sampled] >= 0])] = False
        # The reflectance one unit of power means at the echo's range (what the sensor calibrates by), from the
        # power itself: brightness x cos / power.
        kept = power[whole]
        echoes = _Echoes(hit[whole], np.zeros(kept.size, np.int64), kept, d[whole], np.zeros(kept.size, np.uint8),
                         (self.brightness[tri[whole]] * cos[whole]) / np.maximum(kept, 1e-300))
        if sampled.size:
            footprint = self._footprint_echoes(sampled, xy_deg, directions_world, place, distance, triangle)
            echoes = _concat(echoes, footprint)
            echoes = echoes.where(np.argsort(echoes.beam * MAX_COLUMNS + np.minimum(echoes.slot, MAX_COLUMNS - 1),
                                             kind="stable"))
        self._lap("footprint sub-rays")
        points = self._points(echoes, index, directions_sensor, directions_world, place)
        self._lap("detection, noise, tags")
        return points

    # Step 2: where to sample the footprint ------------------------------------------------------------------
    def _leaves(self, hit: np.ndarray, tri: np.ndarray, d: np.ndarray, ray: np.ndarray, normal: np.ndarray,
                facing: np.ndarray, point: np.ndarray, xy_deg: np.ndarray, place: _Placement) -> np.ndarray:
        """Whether each hit's footprint leaves its triangle (``(len(hit),)`` bool).

        A hit deeper inside its triangle's incircle than the footprint's largest reach on the plane stays
        inside; the others get the exact test.
        """
        edges = self.edges
        cos = np.maximum(np.abs(facing), 1e-6)
        bound = d * self.footprint.tan_half_max / cos
        offset = point - edges.incentre[tri]
        depth = edges.inradius[tri] - np.sqrt(_dot_rows(offset, offset))
        leaves = np.zeros(hit.size, dtype=bool)
        unsure = np.flatnonzero(depth < bound)
        if unsure.size == 0:
            return leaves
        rows = hit[unsure]
        basis_x, basis_y = _angle_basis(xy_deg[rows])
        basis_x, basis_y = place.to_world(basis_x, rows), place.to_world(basis_y, rows)
        u_ray, u_normal, u_facing = ray[unsure], normal[unsure], np.where(
            np.abs(facing[unsure]) < 1e-6, np.copysign(1e-6, facing[unsure]), facing[unsure])
        # The footprint's displacement on the plane per radian of pattern x and y, per metre of range.
        on_plane_x = basis_x - (_dot_rows(u_normal, basis_x) / u_facing)[:, None] * u_ray
        on_plane_y = basis_y - (_dot_rows(u_normal, basis_y) / u_facing)[:, None] * u_ray
        reach = d[unsure, None] * self.footprint.support(edges.inward[tri[unsure]], on_plane_x, on_plane_y)
        leaves[unsure] = edges.leaves(tri[unsure], point[unsure], u_ray, d[unsure], reach)
        return leaves

    def _covered(self, rows: np.ndarray, xy_deg: np.ndarray, directions_world: np.ndarray, place: _Placement,
                 reach: np.ndarray, distance: np.ndarray, triangle: np.ndarray) -> np.ndarray:
        """Of ``rows``, those whose footprint something nearer covers in part (sorted)."""
        proxy = self.proxy
        proxy.place(place.origin if place.quaternion is None else place.origin[:: max(1, rows.size // 64)],
                    self.range_max)
        near = proxy.near(place.origins(rows), directions_world[rows], reach[rows], triangle[rows])
        rows = rows[near]
        self.last_counts["near"] = int(rows.size)
        self._lap("broad phase")
        if rows.size == 0:
            return rows
        # Probe rays at the corners of the footprint's bounding box: is anything in front of the hit's plane?
        basis_x, basis_y = _angle_basis(xy_deg[rows])
        probes = self.footprint.rays(directions_world[rows], place.to_world(basis_x, rows),
                                     place.to_world(basis_y, rows), self.footprint.probe_offsets)
        limit = np.full((rows.size, 4), self.range_max)
        is_hit = triangle[rows] >= 0
        if is_hit.any():
            plane = self.caster.face_planes[triangle[rows[is_hit]]]
            height = plane[:, 3] - _dot_rows(plane[:, :3], place.origin_of(rows[is_hit]))
            with np.errstate(divide="ignore", invalid="ignore"):
                along = height[:, None] / np.einsum("ij,ikj->ik", plane[:, :3], probes[is_hit])
            # Stop short of the hit's own plane (a millimetre and 1e-4 of the range): only what lies in front counts.
            short = along * (1.0 - 1e-4) - 1e-3
            limit[is_hit] = np.where(np.isfinite(short) & (short > 0), np.minimum(short, self.range_max),
                                     self.range_max)
        blocked = self.caster.occluded(place.origins(rows, 4), probes.reshape(-1, 3), limit.reshape(-1))
        self._lap("probes")
        return rows[blocked.reshape(-1, 4).any(axis=1)]

    # Step 3: echoes of sampled footprints ------------------------------------------------------------------
    def _footprint_echoes(self, rows: np.ndarray, xy_deg: np.ndarray, directions_world: np.ndarray,
                          place: _Placement, distance: np.ndarray, triangle: np.ndarray) -> _Echoes:
        """The echoes of pulses sampled with all 19 sub-rays."""
        params = self.params
        m = rows.size
        count = SUBRAY_WEIGHTS.size
        basis_x, basis_y = _angle_basis(xy_deg[rows])
        rays = self.footprint.rays(directions_world[rows], place.to_world(basis_x, rows),
                                   place.to_world(basis_y, rows), self.footprint.subray_offsets)
        r = np.empty((m, count))
        tri = np.empty((m, count), dtype=np.int64)
        r[:, 0], tri[:, 0] = distance[rows], triangle[rows]
        more_r, more_tri = self.caster.hits(place.origins(rows, count - 1), rays[:, 1:].reshape(-1, 3),
                                            self.range_max)
        r[:, 1:], tri[:, 1:] = more_r.reshape(m, count - 1), more_tri.reshape(m, count - 1)
        valid = (tri >= 0) & (r >= params.blind_zone_m)
        beam_of, sub = np.nonzero(valid)
        if beam_of.size == 0:
            return _Echoes(*(np.zeros(0, t) for t in (np.int64, np.int64, np.float64, np.float64, np.uint8,
                                                      np.float64)))
        hit_tri, hit_r = tri[beam_of, sub], r[beam_of, sub]
        hit_ray = rays[beam_of, sub].astype(np.float64)
        plane = self.caster.face_planes[hit_tri]
        cos = np.abs(_dot_rows(plane[:, :3], hit_ray))
        p_hit = SUBRAY_WEIGHTS[sub] * params.signal_ratio(self.brightness[hit_tri], cos, hit_r)
        # Echoes: each pulse's sub-ray hits in range order, split where the gap exceeds the echo separation
        # (a single-return sensor merges them all).
        order = np.lexsort((hit_r, beam_of))
        beam_of, sub, hit_r, p_hit, hit_ray = beam_of[order], sub[order], hit_r[order], p_hit[order], hit_ray[order]
        hit_tri = hit_tri[order]
        new_pulse = np.r_[True, beam_of[1:] != beam_of[:-1]]
        if params.returns_per_pulse > 1:
            split = new_pulse | np.r_[False, np.diff(hit_r) > params.return_separation_m]
        else:
            split = new_pulse
        starts = np.flatnonzero(split)
        total = np.add.reduceat(p_hit, starts)
        blend = np.add.reduceat(p_hit * hit_r, starts) / total
        member = np.cumsum(split) - 1
        echo_beam = beam_of[starts]
        # The strongest sub-ray of each echo names its surface; depths off that plane make a point mixed.
        strongest = np.lexsort((-p_hit, member))[starts]
        surface = self.caster.face_planes[hit_tri[strongest]]
        member_surface = surface[member]
        height = member_surface[:, 3] - _dot_rows(member_surface[:, :3], place.origin_of(rows[beam_of]))
        with np.errstate(divide="ignore", invalid="ignore"):
            on_plane = height / _dot_rows(member_surface[:, :3], hit_ray)
            depth = np.where(np.isfinite(on_plane), np.abs(hit_r - on_plane), np.inf)
            spread = np.maximum.reduceat(depth, starts)
            centre_ray = rays[echo_beam, 0].astype(np.float64)
            centre = (surface[:, 3] - _dot_rows(surface[:, :3], place.origin_of(rows[echo_beam]))) / _dot_rows(
                surface[:, :3], centre_ray)
            between = np.where(np.isfinite(centre) & np.isfinite(spread) & (spread > 0),
                               np.abs(blend - centre) / spread, 1.0)
        mixed = spread > np.maximum(3.0 * params.range_sigma(blend), MIX_FLOOR_M)
        spatial = np.where(~mixed, 0, np.where(between > 0.25, SPATIAL_HIGH,
                                               np.where(between > 0.1, SPATIAL_MODERATE, SPATIAL_LOW)))
        slot = _rank_in_group(echo_beam)  # the echoes of a pulse are consecutive, in range order
        return _Echoes(rows[echo_beam], slot, total, blend, spatial.astype(np.uint8),
                       params.power_to_reflectance(np.ones(blend.size), blend))

    # Steps 4 and 5: detection and the points -----------------------------------------------------------
    def _points(self, echoes: _Echoes, index: np.ndarray, directions_sensor: np.ndarray,
                directions_world: np.ndarray, place: _Placement) -> ReturnPoints:
        """Detection, selection, noise, reflectivity and tags of echoes sorted by pulse and rank."""
        params = self.params
        beam = echoes.beam
        # Receiver noise (detection and intensity) and range noise: one pair of normal numbers per echo,
        # from its pulse's stream index and its rank among the pulse's echoes.
        later = np.flatnonzero(echoes.slot > 0)
        if later.size:
            noise = np.empty((beam.size, 2), dtype=np.float32)
            first = echoes.slot == 0
            noise[first] = stream_normal(self.seed, _ECHO_NOISE, index[beam[first]], 2)
            slot = np.minimum(echoes.slot[later], MAX_COLUMNS // 2 - 1)
            pairs = stream_normal(self.seed, _LATER_ECHO_NOISE, index[beam[later]], 2 * int(slot.max()) + 2)
            noise[later, 0] = pairs[np.arange(later.size), 2 * slot]
            noise[later, 1] = pairs[np.arange(later.size), 2 * slot + 1]
        else:
            noise = stream_normal(self.seed, _ECHO_NOISE, index[beam], 2)
        seen = echoes.power + noise[:, 0] * (1.0 / params.detection_snr)
        measured = echoes.range_m + params.range_sigma(echoes.range_m) * noise[:, 1]
        keep = (seen > 1.0) & (measured >= params.blind_zone_m) & (measured <= self.range_max)
        beam, seen, measured, spatial = beam[keep], seen[keep], measured[keep], echoes.spatial[keep]
        calibration = echoes.calibration[keep]
        repeated = beam.size > 1 and bool(np.any(beam[1:] == beam[:-1]))
        if repeated and params.returns_per_pulse > 1:
            chosen = _first_and_strongest(beam, seen, params.returns_per_pulse)
            beam, seen, measured, spatial = beam[chosen], seen[chosen], measured[chosen], spatial[chosen]
            calibration = calibration[chosen]
            repeated = bool(np.any(beam[1:] == beam[:-1]))
        if repeated:
            number = _rank_in_group(beam) + 1
            returns = np.bincount(beam, minlength=index.size)[beam]
        else:
            number = np.ones(beam.size, dtype=np.int64)
            returns = number
        reflectivity = reflectivity_byte(seen * calibration)
        return_bits = number if params.returns_per_pulse > 1 else 1
        near = measured < params.return0_range_m
        return_bits = np.where(near & (number == 1), 0, return_bits) if near.any() else return_bits
        tag = (spatial | (np.asarray(return_bits) << 4)).astype(np.uint8)
        if tag.shape != beam.shape:
            tag = np.broadcast_to(tag, beam.shape).copy()
        # False alarms: a pulse that returned nothing may still report noise.
        if params.false_alarm_rate > 0:
            empty = np.ones(index.size, dtype=bool)
            empty[beam] = False
            false = np.flatnonzero(empty)
            fire = stream_uniform(self.seed, _FALSE_ALARM, index[false], 1)[:, 0] < params.false_alarm_rate
            false = false[fire]
            if false.size:
                u = stream_uniform(self.seed, _FALSE_ALARM_POINT, index[false], 2)
                near_end = min(max(params.blind_zone_m, 0.1), self.false_alarm_reach)
                beam = np.concatenate([beam, false])
                measured = np.concatenate([measured, near_end + u[:, 0] * (self.false_alarm_reach - near_end)])
                reflectivity = np.concatenate([reflectivity, (u[:, 1] * 4).astype(np.uint8)])
                tag = np.concatenate([tag, np.full(false.size, SPATIAL_HIGH | INTENSITY_NOISE | 0x10, np.uint8)])
                number = np.concatenate([number, np.ones(false.size, np.int64)])
                returns = np.concatenate([returns, np.ones(false.size, np.int64)])
                order = np.argsort(beam, kind="stable")
                beam, measured, reflectivity, tag, number, returns = (
                    a[order] for a in (beam, measured, reflectivity, tag, number, returns))
        along = measured[:, None]
        if params.angular_sigma_deg > 0 and beam.size:
            direction = _jitter(directions_sensor[beam], stream_normal(self.seed, _ANGLE_NOISE, index[beam], 2),
                                np.radians(params.angular_sigma_deg))
            xyz_sensor = direction * along
            xyz_world = place.origin_of(beam) + place.to_world(xyz_sensor, beam)
        else:
            xyz_sensor = directions_sensor[beam] * along
            xyz_world = place.origin_of(beam) + directions_world[beam] * along
        return ReturnPoints(beam, measured, xyz_sensor, xyz_world, reflectivity, tag, number.astype(np.uint8),
                            returns.astype(np.uint8))


#: Per ray caster (one scene): the tables a return model makes from its mesh, kept while the caster lives, so a
#: restart (a slider, a new preset) does not make them again.
_TABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _scene_tables(caster) -> dict:
    try:
        return _TABLES.setdefault(caster, {})
    except TypeError:  # a caster that cannot be weakly referenced keeps its tables with the model
        return {}


def _jitter(direction: np.ndarray, noise: np.ndarray, sigma_rad: float) -> np.ndarray:
    """Unit directions turned by ``sigma_rad`` times 2D normal ``noise`` ``(n, 2)`` about themselves.

    The two axes are the horizontal tangent ``(-d_y, d_x, 0) / |.|`` and ``d x`` that one (every Livox ray is
    within 90 deg of the boresight x, so the first is never degenerate); the turn is small, so the result is
    unit length to within ``sigma^2``.
    """
    dx, dy, dz = direction[:, 0], direction[:, 1], direction[:, 2]
    scale = sigma_rad / np.sqrt(dx * dx + dy * dy)
    a = noise[:, 0] * scale
    b = noise[:, 1] * scale
    # horizontal h = (-dy, dx, 0)/|.|; vertical v = d x h = (-dz dx, -dz dy, dx^2 + dy^2)/|.|.
    out = np.empty_like(direction)
    out[:, 0] = dx - a * dy - b * dz * dx
    out[:, 1] = dy + a * dx - b * dz * dy
    out[:, 2] = dz + b * (dx * dx + dy * dy)
    return out


def reflectivity_byte(reflectance: np.ndarray) -> np.ndarray:
    """Livox's reflectivity byte of an echo whose power implies ``reflectance`` (white Lambertian = 1), ``(n,)`` uint8.

    0-150 for 0-100 % Lambertian (saturating at 150 up to twice a white target), 151-255 for a
    retroreflector, logarithmic from twice to 1000 times a white target's power.
    """
    reflectance = np.asarray(reflectance, dtype=np.float64)
    byte = np.rint(LAMBERTIAN_TOP * np.clip(reflectance, 0.0, 1.0))
    retro = np.flatnonzero(reflectance >= RETRO_FLOOR)
    if retro.size:
        byte[retro] = 151.0 + np.rint(104.0 * np.clip(np.log(reflectance[retro] / RETRO_FLOOR)
                                                      / np.log(RETRO_TOP / RETRO_FLOOR), 0.0, 1.0))
    return byte.astype(np.uint8)


def _angle_basis(xy_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The derivatives of the sensor-frame ray direction by pattern x and y (per radian), ``(n, 3)`` each.

    The ray is ``(cos a, s x, -s y)`` with ``a = |(x, y)|``, ``s = sin(a)/a`` (scan-model.md section 5).
    """
    xy = np.radians(xy_deg)
    x, y = xy[:, 0], xy[:, 1]
    alpha = np.hypot(x, y)
    s = np.sinc(alpha / np.pi)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(alpha < 1e-3, -1.0 / 3.0 + alpha**2 / 30.0,
                     (alpha * np.cos(alpha) - np.sin(alpha)) / np.maximum(alpha, 1e-300) ** 3)
    dx = np.column_stack([-s * x, s + x * x * q, -x * y * q])
    dy = np.column_stack([-s * y, x * y * q, -(s + y * y * q)])
    return dx, dy


def _concat(a: _Echoes, b: _Echoes) -> _Echoes:
    return _Echoes(*(np.concatenate([getattr(a, f), getattr(b, f)])
                     for f in ("beam", "slot", "power", "range_m", "spatial", "calibration")))


def _rank_in_group(group: np.ndarray) -> np.ndarray:
    """0, 1, 2, ... within each run of equal values of a sorted ``group``."""
    if group.size == 0:
        return np.zeros(0, np.int64)
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    return np.arange(group.size) - np.repeat(starts, np.diff(np.r_[starts, group.size]))


def _first_and_strongest(beam: np.ndarray, seen: np.ndarray, keep: int) -> np.ndarray:
    """Rows to report of echoes sorted by pulse then range: each pulse's first, then its strongest, up to ``keep``."""
    rank = _rank_in_group(beam)
    priority = np.where(rank == 0, -np.inf, -seen)
    order = np.lexsort((priority, beam))
    chosen = order[_rank_in_group(beam[order]) < keep]
    return np.sort(chosen)
