"""The scan cast into a scene: frames of the point cloud a RflySim client receives.

One path makes every cloud of the project (``scan``, ``publish``, the GUI,
exports): :class:`MountedCaster` takes a :class:`~livox_viz.pattern.PatternChunk`
of any length and returns a :class:`ScanFrame` of its returns: true
sensor-frame points, their int16 encoding, the decoded points a client sees,
ranges, per-point times and stream indices, and the sensor's world pose.
Rays with no return within ``otherParams[0]`` are left out (the frame's point
count says how many returned), as the platform does. :class:`LidarScanner`
is a pattern stream and a mounted caster cut into published frames.

The configuration's return model chooses what a ray returns: ``"ideal"``, its
exact first hit (RflySim's own sensor: no intensity, reflectivity 0, tag 0x10,
return 1 of 1), or ``"datasheet"``, the sheet's sensor
(:mod:`~livox_viz.casting.returns`: noise, detection range, beam footprint,
multiple returns, reflectivity and tags).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from livox_viz.casting.codec import decode_int16
from livox_viz.casting.ray_kernels import ideal_points, scratch_rows, sensor_rays
from livox_viz.config.mount import sensor_mount, sensor_world_pose
from livox_viz.config.sensor import SensorConfig
from livox_viz.core.portable import at_fork_in_child, usable_cores
from livox_viz.core.poses import Pose, pose_quaternion
from livox_viz.core.rotations import quat_rotate
from livox_viz.motion.track import SensorTrack
from livox_viz.motion.trajectory import Trajectory
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.stream import PatternChunk, points_before
from livox_viz.scene.raycast import EmbreeCaster, RayCaster, casting_in_this_thread
from livox_viz.scene.scenes import check_reach

if TYPE_CHECKING:
    import trimesh

    from livox_viz.casting.returns import ReturnModel

#: Rays cast in one call at most: a huge frame is cast in parts so memory stays bounded.
CAST_PART = 1 << 20
#: The tag of an ideal point: return 1, no noise flags (Livox SDK1 layout).
IDEAL_TAG = 0x10
#: Rays a worker of :meth:`LidarScanner.frames` casts at least per hand-over (frames go a few at a time: each
#: hand-over wakes a worker, a tenth of a millisecond on virtual CPUs; 65 536 rather than 4096 took the whole
#: scan of a million Mid-70 rays from 183 to 154 ms).
TASK_RAYS = 65536
#: Frames a worker casts at most per hand-over, however few rays they hold: every frame is a record and arrays of a
#: few kilobytes even when empty, and a 1 x 1 x 1000 Hz configuration's batches of 65 536 one-ray frames held
#: 200 000 frames in flight (issue 47: the scan's memory grew to 1.16 GB).
TASK_FRAMES = 256


@dataclass(frozen=True)
class ScanFrame:
    """The returns of a run of rays (a published frame, or any chunk of the stream).

    Parameters
    ----------
    index : int
        Frame number of the first ray, from the scan start.
    ray_count : int
        Rays fired (W*H for a whole frame).
    stream_index : (M,) int64
        Stream index of each return's ray.
    t : (M,) float64
        Emission time of each return, seconds since the scan start.
    xy_deg : (M, 2) float64
        Pattern angles of the returns, degrees.
    range_m : (M,) float64
        True distance to the hit, metres.
    xyz_sensor : (M, 3) float64
        True hit points in the sensor FRD frame, metres.
    xyz_int16 : (M, 3) int16
        The published encoding (sensor FRD).
    xyz_world : (M, 3) float64
        True hit points in the world NED frame, metres.
    sensor_pose : Pose
        The sensor's pose in the world (NED) at the first ray.
    timestamp : float
        Scan time of the first ray, seconds (what RflySim stamps a frame with).
    end_time : float
        Scan time just after the last ray, seconds.
    range_max : float
        The int16 scale, metres.
    end_pose : Pose
        The sensor's pose just after the last ray (the same as ``sensor_pose`` for a fixed vehicle).
    track : SensorTrack, optional
        With a moving vehicle: the sensor's track (the one motion model), from which
        :attr:`point_origin` and :attr:`point_quaternion` follow when asked for.
    reflectivity : (M,) uint8, optional
        Livox's reflectivity byte: 0-150 Lambertian 0-100 %, 151-255 retroreflective (0 for ideal points).
    tag : (M,) uint8, optional
        Livox SDK1 tag: bits 0-1 spatial noise, 2-3 intensity noise, 4-5 return number (0x10 for ideal points).
    return_number : (M,) uint8, optional
        1, 2, 3 in range order within the point's pulse (a pulse may return several points; they share
        its stream index and time).
    number_of_returns : (M,) uint8, optional
        Points the pulse returned.

    The last four default to an ideal point's values.
    """

    index: int
    ray_count: int
    stream_index: np.ndarray
    t: np.ndarray
    xy_deg: np.ndarray
    range_m: np.ndarray
    xyz_sensor: np.ndarray
    xyz_int16: np.ndarray
    xyz_world: np.ndarray
    sensor_pose: Pose
    timestamp: float
    end_time: float
    range_max: float
    end_pose: Pose
    track: SensorTrack | None = field(default=None, repr=False)
    reflectivity: np.ndarray = field(default=None, repr=False)
    tag: np.ndarray = field(default=None, repr=False)
    return_number: np.ndarray = field(default=None, repr=False)
    number_of_returns: np.ndarray = field(default=None, repr=False)

    def __post_init__(self) -> None:
        count = len(self)
        for name, value in (("reflectivity", 0), ("tag", IDEAL_TAG), ("return_number", 1), ("number_of_returns", 1)):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.full(count, value, dtype=np.uint8))

    def __len__(self) -> int:
        return int(self.range_m.shape[0])

    @cached_property
    def _point_poses(self) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        return self.track.poses_at(self.t) if self.track is not None else (None, None)

    @property
    def point_origin(self) -> np.ndarray | None:
        """``(M, 3)`` float64 with a moving vehicle: the sensor's position when each return's ray fired, world NED."""
        return self._point_poses[0]

    @property
    def point_quaternion(self) -> np.ndarray | None:
        """``(M, 4)`` float64 with a moving vehicle: the sensor's orientation [x, y, z, w] (sensor FRD -> world
        NED) when each return's ray fired."""
        return self._point_poses[1]

    @cached_property
    def xyz_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 what a client decodes, sensor FRD, metres."""
        return decode_int16(self.xyz_int16, self.range_max)

    @property
    def wire_xyz_int16(self) -> np.ndarray:
        """``(K, 3)`` int16 what RflySim's wire carries: one point per ray, each pulse's first return.

        The wire has no field to tell a second return from a first, and RflySim's own frames hold at
        most one point per ray (W*H), so later returns stay off it.
        """
        if self.return_number.size and int(self.return_number.max()) > 1:
            return self.xyz_int16[self.return_number == 1]
        return self.xyz_int16

    @cached_property
    def xyz_world_decoded(self) -> np.ndarray:
        """``(M, 3)`` float64 the decoded points placed in the world (NED), each with the pose of its own time."""
        if self.point_quaternion is not None:
            return self.point_origin + quat_rotate(self.point_quaternion, self.xyz_decoded)
        return self.sensor_pose.origin + self.xyz_decoded @ self.sensor_pose.rotation.T



#: The per-point arrays of a :class:`ScanFrame`.
_RETURN_ARRAYS = ("stream_index", "t", "xy_deg", "range_m", "xyz_sensor", "xyz_int16", "xyz_world", "reflectivity",
                  "tag", "return_number", "number_of_returns")


class MountedCaster:
    """Casts pattern chunks from a sensor mounted on a vehicle into a scene.

    Parameters
    ----------
    config : SensorConfig
        Gives the mount (``SensorPosXYZ``, ``SensorAngEuler``) and the range.
    scene : trimesh.Trimesh or RayCaster
        The world NED scene, or a caster already built for it.
    vehicle_pose : Pose, optional
        The vehicle's pose in the world; default the origin.
    trajectory : Trajectory, optional
        A moving vehicle: each ray starts from the sensor's pose at its own time (``vehicle_pose``
        is then the pose at t = 0).
    seed : int
        Seed of the datasheet return model's noise (with each ray's stream index).
    """

    def __init__(self, config: SensorConfig, scene: trimesh.Trimesh | RayCaster,
                 vehicle_pose: Pose | None = None, trajectory: Trajectory | None = None, seed: int = 0) -> None:
        self.config = config
        # A caster has distances(); anything else is a mesh (trimesh is not imported just to ask).
        self.caster: RayCaster = scene if hasattr(scene, "distances") else EmbreeCaster(scene)
        #: The datasheet return model, or None for ideal returns.
        self.returns: ReturnModel | None = None
        if config.returns_model == "datasheet":
            # Imported here: the model and its loops are 30-40 ms of the start-up of every command that imports
            # this module (the wire's and the model-only ones among them).
            from livox_viz.casting.returns import ReturnModel

            self.returns = ReturnModel(config.return_params, self.caster, seed, config.range_max,
                                       config.point_rate, config.pattern_plane)
        self.trajectory = trajectory
        self.vehicle_pose = trajectory.pose_at(trajectory.span[0]) if trajectory is not None else (
            vehicle_pose or Pose())
        mesh = getattr(self.caster, "mesh", None)
        if mesh is not None:  # the float32 casts' span rule holds for where the rays start too
            check_reach(mesh, self.vehicle_pose.origin if trajectory is None else trajectory.position,
                        "the vehicle's pose" if trajectory is None else f"trajectory {trajectory.name}")
        self.mount_pose = sensor_mount(config)
        self.sensor_pose = sensor_world_pose(config, self.vehicle_pose)
        #: The sensor's track: the vehicle's motion model with the mount applied, evaluated exactly per ray.
        self.track = None if trajectory is None else SensorTrack(trajectory, self.mount_pose)

    def sensor_pose_at(self, t: float) -> Pose:
        """The sensor's pose in the world at scan time ``t`` seconds."""
        if self.track is None:
            return self.sensor_pose
        return self.track.pose_at(t)

    def sensor_poses_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sensor's position ``(n, 3)`` and orientation ``(n, 4)`` at times ``t`` ``(n,)``, world NED."""
        if self.track is None:
            count = np.asarray(t).size
            return (np.tile(self.sensor_pose.origin, (count, 1)),
                    np.tile(pose_quaternion(self.sensor_pose), (count, 1)))
        return self.track.poses_at(t)

    def _turn(self, t: np.ndarray):
        """Sensor-frame vectors of rays ``rows`` (fired at ``t[rows]``) into the world, each with its own pose."""
        return lambda vectors, rows: self.track.rays(t[rows], vectors)[1]

    def cast(self, chunk: PatternChunk) -> ScanFrame:
        """The returns of the chunk's rays (each from the sensor's pose at its own time when moving)."""
        parts = [self._cast_part(chunk, first) for first in range(0, max(len(chunk), 1), CAST_PART)]
        found = parts[0] if len(parts) == 1 else {
            name: np.concatenate([part[name] for part in parts]) for name in parts[0]}
        return self._frame(chunk.start, chunk.stop, **found)

    def _cast_part(self, chunk: PatternChunk, first: int) -> dict[str, np.ndarray]:
        """The returns of the chunk's rays ``first : first + CAST_PART`` (the arrays of :class:`ScanFrame`)."""
        config = self.config
        moving = self.trajectory is not None
        xy = chunk.xy_deg[first : first + CAST_PART]
        # A fixed sensor reads only the hits' times: a chunk whose times were never made (k / rate) does not
        # make them.
        t = chunk.t[first : first + CAST_PART] if moving or chunk.times_held is not None else None
        # Both models are done with the rays before this thread's next part (what they return is made anew):
        # the rays go in the thread's scratch arrays.
        if moving:
            directions_sensor, _ = sensor_rays(xy, config.pattern_plane, scratch=True)
            count = directions_sensor.shape[0]
            into = (scratch_rows("origin", count), scratch_rows("world", count))
            origin, directions_world = self.track.rays(t, directions_sensor, into)
        else:
            origin = self.sensor_pose.origin
            # Embree's own float32 directions when only the cast needs them (the ideal hits' float64 ones are
            # made again after it, the same numbers): a third of the memory the rays pass through.
            embree_only = self.returns is None and getattr(self.caster, "takes_float32", False)
            directions_sensor, directions_world = sensor_rays(xy, config.pattern_plane, self.sensor_pose.rotation,
                                                              True, np.float32 if embree_only else np.float64)
        if self.returns is None:
            distance = self.caster.distances(origin, directions_world, config.range_max)
            float64_world = directions_world if directions_world.dtype == np.float64 else None
            return ideal_points(distance, directions_sensor, float64_world, origin, xy, t, chunk.start + first,
                                config.point_rate, config.range_max, self.sensor_pose.rotation)
        found = self.returns.cast(chunk.start + first, xy, directions_sensor, directions_world, origin,
                                  None if moving else self.sensor_pose.rotation, self._turn(t) if moving else None, t)
        return {name: getattr(found, name) for name in _RETURN_ARRAYS}

    def _frame(self, start: int, stop: int, **returns: np.ndarray | None) -> ScanFrame:
        """The frame of the rays ``start:stop`` (stream indices) and their ``returns`` (the arrays of
        :class:`ScanFrame`), with their times and poses."""
        config = self.config
        return ScanFrame(index=start // config.points_per_frame, ray_count=stop - start,
                         sensor_pose=self.sensor_pose_at(start / config.point_rate),
                         timestamp=start / config.point_rate, end_time=stop / config.point_rate,
                         range_max=config.range_max, end_pose=self.sensor_pose_at(stop / config.point_rate),
                         track=self.track, **returns)

    def cast_frames(self, chunks: list[PatternChunk]) -> list[ScanFrame]:
        """The returns of consecutive chunks (published frames, in stream order), cast as one run.

        See :meth:`cast_run`; the chunks' points are joined into one run first.
        """
        if len(chunks) == 1:
            return [self.cast(chunks[0])]
        # Times are joined only when a chunk holds them; otherwise the run's are k / rate too, made when needed.
        held = any(chunk.times_held is not None for chunk in chunks)
        merged = PatternChunk(self.config, chunks[0].start, np.concatenate([chunk.xy_deg for chunk in chunks]),
                              t=np.concatenate([chunk.t for chunk in chunks]) if held else None)
        return self.cast_run(merged, [chunk.stop for chunk in chunks])

    def cast_run(self, chunk: PatternChunk, stops: list[int]) -> list[ScanFrame]:
        """The returns of a run of rays cut into frames that end at the stream indices ``stops``.

        One run instead of one per frame: each run's fixed steps (the Python between the compiled ones,
        each hand-over of the interpreter between threads) are paid once for the batch (the scan of
        ``scan`` 16-21 % faster with seven Mid-70 frames a batch). Each frame's arrays are views of the
        run's.

        Parameters
        ----------
        chunk : PatternChunk
            The run's rays.
        stops : list of int
            Stream index one past each frame's last ray, increasing; the last is ``chunk.stop``.

        Returns
        -------
        list of ScanFrame
            One a stop, the first from ``chunk.start``.
        """
        if len(stops) == 1:
            return [self.cast(chunk)]
        run = self.cast(chunk)
        # Points are in stream order (a pulse's returns together), so each frame is one slice.
        starts = [chunk.start, *stops[:-1]]
        bounds = np.searchsorted(run.stream_index, [*starts, stops[-1]])
        frames = []
        for start, stop, low, high in zip(starts, stops, bounds[:-1], bounds[1:], strict=True):
            part = slice(int(low), int(high))
            frames.append(self._frame(start, stop, **{name: getattr(run, name)[part] for name in _RETURN_ARRAYS}))
        return frames


_FRAME_POOLS: dict[int, ThreadPoolExecutor] = {}
_FRAME_POOL_LOCK = threading.Lock()


def _forget_frame_pools() -> None:
    """In a forked child: the parent's threads are not there, so its pools would take frames and never cast them."""
    global _FRAME_POOLS, _FRAME_POOL_LOCK
    _FRAME_POOLS, _FRAME_POOL_LOCK = {}, threading.Lock()


at_fork_in_child(_forget_frame_pools)


def frame_workers(workers: int | None = None) -> int:
    """Frames :meth:`LidarScanner.frames` casts side by side: ``workers``, or one per core this process may use.

    No cap: each frame is cast start to finish in one thread (pattern rays, Embree, the return model's compiled
    loops, the int16 encoding all release the interpreter), so the scan grows with the cores for as long as
    the machine has them. Measured on 16 cores (livox_mid70_risley, default scene): 2 workers 94 x real time,
    4 158 x, 8 279 x, 16 367 x (ideal); datasheet 45, 79, 136, 198 x: every added worker still paid, where the
    old cap of 4 left 165 x and 89 x. The cost of a worker is memory: one batch of at least :data:`TASK_RAYS`
    rays in flight each (about 10 MiB), plus one being cut.
    """
    return max(1, int(workers) if workers is not None else usable_cores())


def _frame_pool(workers: int) -> ThreadPoolExecutor:
    """The threads every :meth:`LidarScanner.frames` of ``workers`` casts its frames on, made once per process.

    Kept, not made per scan: each thread's scratch arrays (the rays, Embree's float32 copies) live as long as
    the thread, and a new thread faults all of them in again (1 800 page faults, a few ms, a scan of a million
    rays).
    """
    with _FRAME_POOL_LOCK:
        pool = _FRAME_POOLS.get(workers)
        if pool is None:
            pool = _FRAME_POOLS[workers] = ThreadPoolExecutor(workers, thread_name_prefix="livox-viz-frame")
        return pool


class LidarScanner:
    """Streams published frames of the configuration's pattern cast into a scene.

    Parameters
    ----------
    config : SensorConfig
    scene : trimesh.Trimesh or RayCaster
        The world NED scene, or a caster already built for it.
    vehicle_pose : Pose
        The vehicle's pose in the world.
    seed : int
        Seed of the pattern.
    trajectory : Trajectory, optional
        A moving vehicle (see :class:`MountedCaster`).
    workers : int, optional
        Frames :meth:`frames` casts side by side (:func:`frame_workers`: default one per core this process
        may use). The cloud is the same whatever the count.
    """

    def __init__(
        self,
        config: SensorConfig,
        scene: trimesh.Trimesh | RayCaster,
        vehicle_pose: Pose | None = None,
        seed: int = 0,
        trajectory: Trajectory | None = None,
        workers: int | None = None,
    ) -> None:
        self.config = config
        self.seed = seed
        self.workers = frame_workers(workers)
        self.mounted = MountedCaster(config, scene, vehicle_pose, trajectory, seed)
        self.pattern = make_pattern(config, seed=seed)
        self._handed_out: int | None = None  # inside frames(): the stream index after the last frame handed out

    @property
    def caster(self) -> RayCaster:
        """The ray caster of the scene."""
        return self.mounted.caster

    @property
    def sensor_pose(self) -> Pose:
        """The sensor's pose in the world."""
        return self.mounted.sensor_pose

    @property
    def time(self) -> float:
        """Scan time of the next ray, seconds (inside :meth:`frames`: after the last frame handed out)."""
        if self._handed_out is not None:
            return self._handed_out / self.config.point_rate
        return self.pattern.time

    def cast(self, chunk: PatternChunk) -> ScanFrame:
        """The returns of any chunk of the stream (see :meth:`MountedCaster.cast`)."""
        return self.mounted.cast(chunk)

    def next_frame(self) -> ScanFrame:
        """Fire the rest of the current frame (W*H rays from a frame start) and return its returns."""
        return self.mounted.cast(self.pattern.next_frame())

    def _cast_in_worker(self, chunk: PatternChunk, stops: list[int]) -> tuple[list[ScanFrame], Exception | None]:
        # The batches side by side already keep the cores busy: each casts its own rays in its own thread, as
        # one run. If the run fails, its frames are cast one by one: those before the failing one are still
        # handed out, then the error is raised in the caller's thread.
        frames: list[ScanFrame] = []
        with casting_in_this_thread():
            try:
                return self.mounted.cast_run(chunk, stops), None
            except Exception:
                pass  # cast again frame by frame below: that says which frame fails
            try:
                for start, stop in zip([chunk.start, *stops[:-1]], stops, strict=True):
                    rows = slice(start - chunk.start, stop - chunk.start)
                    frames.append(self.mounted.cast(PatternChunk(self.config, start, chunk.xy_deg[rows])))
            except Exception as error:  # raised again in the caller's thread, after those frames
                return frames, error
        return frames, None

    def frames(self, seconds: float) -> Iterator[ScanFrame]:
        """Frames until ``seconds`` of scan time (the last one partial if it does not fit).

        The frames are cast side by side, one per worker thread (:attr:`workers`; small
        frames a few to a thread, at least :data:`TASK_RAYS` rays, at most :data:`TASK_FRAMES` frames), and the
        next is cut from the pattern while they run, so every core is busy with everything a frame
        needs (directions, cast, encoding) while the caller writes the frame it was handed.
        Frames are handed out in order. The stream runs ahead of the caller by the frames in
        flight; if the caller stops early, it is put back after the last frame handed out.
        """
        total = points_before(seconds, self.config.point_rate)
        if self.mounted.trajectory is not None:
            self.mounted.trajectory.check_covers(self.pattern.time, total / self.config.point_rate)
        per_frame = self.config.points_per_frame
        per_task = max(1, min(TASK_FRAMES, -(-TASK_RAYS // per_frame)))
        workers = self.workers
        pool = _frame_pool(workers)
        in_flight: deque[tuple[Future[tuple[list[ScanFrame], Exception | None]], list[int]]] = deque()
        self._handed_out = self.pattern.position
        try:
            while in_flight or self.pattern.position < total:
                while self.pattern.position < total and len(in_flight) <= workers:
                    # One run of the stream for the batch's frames: every stream gives the same points however
                    # it is cut (tested), so this is the frames' points without joining them.
                    stops: list[int] = []
                    end = self.pattern.position
                    while end < total and len(stops) < per_task:
                        end = min((end // per_frame + 1) * per_frame, total)
                        stops.append(end)
                    chunk = self.pattern.take(end - self.pattern.position)
                    in_flight.append((pool.submit(self._cast_in_worker, chunk, stops), stops))
                future, stops = in_flight.popleft()
                cast, error = future.result()
                for frame, stop in zip(cast, stops[: len(cast)], strict=True):
                    self._handed_out = stop
                    yield frame
                if error is not None:
                    raise error
        finally:
            # The pool outlives this scan: its frames still queued are dropped, those being cast are waited for.
            pending = [future for future, _ in in_flight if not future.cancel()]
            wait(pending)
            if self.pattern.position != self._handed_out:
                # Stopped early: a fresh stream of the same seed, moved to the first ray not handed out.
                self.pattern = make_pattern(self.config, seed=self.seed)
                self.pattern.skip(self._handed_out)
            self._handed_out = None
