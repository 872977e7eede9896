"""The scan cast into a scene: frames of the point cloud a RflySim client receives.

For each frame of W*H rays the scanner gives the returns as true sensor-frame
points, their int16 encoding, the decoded points a client sees, the ranges,
the per-point times and the frame's world pose. Rays with no return within
``otherParams[0]`` are left out (the frame's point count says how many
returned), as the platform does.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import trimesh

from .codec import decode_int16, encode_int16
from .config import SensorConfig
from .directions import directions_from_xy
from .pattern import ScanPattern
from .poses import Pose, sensor_world_pose
from .raycast import EmbreeCaster, RayCaster


@dataclass(frozen=True)
class ScanFrame:
    """The returns of one published frame (M of its W*H rays).

    Parameters
    ----------
    index : int
        Frame number from the scan start.
    ray_count : int
        Rays fired in the frame (W*H, fewer for a partial last frame).
    t : (M,) float64
        Emission time of each return, seconds since the scan start.
    xy_deg : (M, 2) float64
        Pattern angles of the returns, degrees.
    range_m : (M,) float64
        True distance to the hit, metres.
    xyz_sensor : (M, 3) float64
        True hit points in the sensor FRD frame, metres.
    xyz_int16 : (M, 3) int16
        The published encoding.
    xyz_decoded : (M, 3) float64
        What a client decodes, sensor FRD, metres.
    xyz_world : (M, 3) float64
        True hit points in the world NED frame, metres.
    sensor_pose : Pose
        The sensor's pose in the world for this frame.
    timestamp : float
        Scan time of the frame's first ray, seconds (what RflySim stamps a frame with).
    """

    index: int
    ray_count: int
    t: np.ndarray
    xy_deg: np.ndarray
    range_m: np.ndarray
    xyz_sensor: np.ndarray
    xyz_int16: np.ndarray
    xyz_decoded: np.ndarray
    xyz_world: np.ndarray
    sensor_pose: Pose
    timestamp: float

    def __len__(self) -> int:
        return int(self.range_m.shape[0])


class LidarScanner:
    """Streams frames of the configuration's pattern cast into a scene.

    Parameters
    ----------
    config : SensorConfig
    scene : trimesh.Trimesh or RayCaster
        The world NED scene, or a caster already built for it.
    vehicle_pose : Pose
        The vehicle's pose in the world.
    seed : int
        Seed of the pattern.
    """

    def __init__(
        self,
        config: SensorConfig,
        scene: trimesh.Trimesh | RayCaster,
        vehicle_pose: Pose | None = None,
        seed: int = 0,
    ) -> None:
        self.config = config
        self.caster: RayCaster = EmbreeCaster(scene) if isinstance(scene, trimesh.Trimesh) else scene
        self.vehicle_pose = vehicle_pose or Pose()
        self.sensor_pose = sensor_world_pose(config, self.vehicle_pose)
        self.pattern = ScanPattern(config, seed=seed)
        self._rotation = self.sensor_pose.rotation
        self._origin = self.sensor_pose.origin

    @property
    def time(self) -> float:
        """Scan time of the next ray, seconds."""
        return self.pattern.time

    def next_frame(self) -> ScanFrame:
        """Fire the rest of the current frame (W*H rays from a frame start) and return its returns."""
        frame_index = self.pattern.position // self.config.points_per_frame
        chunk = self.pattern.next_frame()
        return self._cast(frame_index, chunk.xy_deg, chunk.t)

    def frames(self, seconds: float) -> Iterator[ScanFrame]:
        """Frames until ``seconds`` of scan time (the last one partial if it does not fit)."""
        total = int(np.ceil(seconds * self.config.point_rate - 1e-9))
        while self.pattern.position < total:
            frame_index = self.pattern.position // self.config.points_per_frame
            frame_end = (frame_index + 1) * self.config.points_per_frame
            chunk = self.pattern.take(min(frame_end, total) - self.pattern.position)
            yield self._cast(frame_index, chunk.xy_deg, chunk.t)

    def cast_sensor_directions(self, directions_sensor: np.ndarray) -> np.ndarray:
        """Ranges along rays given in the sensor frame.

        Parameters
        ----------
        directions_sensor : (n, 3) float64
            Unit rays, sensor FRD.

        Returns
        -------
        range_m : (n,) float64
            Metres; ``inf`` where nothing is hit within ``otherParams[0]``.
        """
        return self.caster.distances(self._origin, directions_sensor @ self._rotation.T, self.config.range_max)

    def _cast(self, frame_index: int, xy_deg: np.ndarray, t: np.ndarray) -> ScanFrame:
        directions_sensor = directions_from_xy(xy_deg)
        directions_world = directions_sensor @ self._rotation.T
        distance = self.caster.distances(self._origin, directions_world, self.config.range_max)
        hit = np.isfinite(distance)
        range_m = distance[hit]
        xyz_sensor = directions_sensor[hit] * range_m[:, None]
        xyz_int16 = encode_int16(xyz_sensor, self.config.range_max)
        return ScanFrame(
            index=frame_index,
            ray_count=int(xy_deg.shape[0]),
            t=t[hit].copy(),
            xy_deg=xy_deg[hit].copy(),
            range_m=range_m,
            xyz_sensor=xyz_sensor,
            xyz_int16=xyz_int16,
            xyz_decoded=decode_int16(xyz_int16, self.config.range_max),
            xyz_world=self._origin + directions_world[hit] * range_m[:, None],
            sensor_pose=self.sensor_pose,
            timestamp=frame_index * self.config.points_per_frame / self.config.point_rate,
        )
