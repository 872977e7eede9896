"""A scan from t = 0 into a ROS 2 bag, with the IMU and the ground truth of the same time.

What ``livox-viz scan --rosbag`` writes, in one place for every caller: the
command (:mod:`~livox_viz.cli.scan_commands`, which writes a point-cloud file
beside it) and anything that has its configuration, caster and motion in hand
(:func:`write_scan_bag`). The bag is written atomically
(:class:`~livox_viz.files.rosbag.RosbagWriter`): it appears whole or not at all.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

from livox_viz.core.errors import LivoxVizError

if TYPE_CHECKING:  # the casting path is imported when a bag is written: every command's start-up would pay for it
    from livox_viz.casting.scan import ScanFrame
    from livox_viz.config.sensor import SensorConfig
    from livox_viz.core.poses import Pose
    from livox_viz.files.rosbag import RosbagWriter, RosNames
    from livox_viz.motion.imu import ImuNoise, ImuStream
    from livox_viz.motion.trajectory import Trajectory
    from livox_viz.scene.raycast import RayCaster

#: IMU samples per second in a bag unless asked otherwise, and the frame they are in.
DEFAULT_IMU_RATE = 200.0
DEFAULT_IMU_FRAME = "body"


class BagSink:
    """Frames into a bag, with the IMU samples and the ground truth of the same time written alongside.

    The IMU is made a frame at a time (:class:`~livox_viz.motion.imu.ImuStream`): memory stays flat.
    """

    def __init__(self, writer: RosbagWriter, imu: ImuStream, flight: Trajectory, end: float) -> None:
        self.writer = writer
        self.imu = imu
        self.flight = flight
        #: Where the IMU and ground truth end, seconds: the scan's end, or its last frame's when it stopped early.
        self.end = end

    def write(self, frame: ScanFrame) -> None:
        self.writer.write_frame(frame)
        self.motion_until(frame.end_time)

    def motion_until(self, stop: float, inclusive: bool = False) -> None:
        """IMU and ground-truth samples before ``stop`` seconds (and at it, with ``inclusive``)."""
        samples = self.imu.until(stop, inclusive)
        if samples.t.size:
            self.writer.write_imu(samples)
            self.writer.write_motion(self.flight, samples.t)


@contextmanager
def open_scan_bag(path: str | os.PathLike[str], config: SensorConfig, mount: Pose, pose: Pose,
                  trajectory: Trajectory | None, seconds: float, seed: int, imu_rate: float = DEFAULT_IMU_RATE,
                  imu_noise: ImuNoise | None = None, imu_frame: str = DEFAULT_IMU_FRAME,
                  names: RosNames | None = None) -> Iterator[BagSink]:
    """A bag to write a scan's frames into (:meth:`BagSink.write`); finished (moved into place) on leaving the
    block, removed if it is left by an exception.

    Parameters
    ----------
    path : path-like
        The bag folder to make (a new name).
    config : SensorConfig
    mount : Pose
        The sensor on the vehicle (FRD), as the scanner casts with it.
    pose : Pose
        The vehicle's pose, NED: a fixed vehicle hovers there (its IMU reads gravity alone).
    trajectory : Trajectory or None
        The vehicle's motion; None for a fixed vehicle.
    seconds : float
        The scan's length, seconds: the IMU and the ground truth run to it.
    seed : int
        The IMU noise's seed (the scan's).
    imu_rate : float
        IMU samples per second.
    imu_noise : ImuNoise, optional
        Default: a perfect IMU.
    imu_frame : {"body", "lidar"}
    names : RosNames, optional
        Topic and frame names (default: the Livox ROS driver 2's).
    """
    from livox_viz.files.rosbag import RosbagWriter, RosNames
    from livox_viz.motion.flights import builtin_trajectory
    from livox_viz.motion.imu import ImuNoise, ImuStream

    flight = trajectory if trajectory is not None else builtin_trajectory("hover", 0.0, pose, seconds)
    noise = imu_noise if imu_noise is not None else ImuNoise()
    imu = ImuStream(flight, imu_rate, noise, seed=seed, start=0.0, mount=mount if imu_frame == "lidar" else None)
    with RosbagWriter(path, mount, names or RosNames(), lasers=config.lasers, imu_frame=imu_frame,
                      imu_variances=noise.sample_variances(imu_rate)) as writer:
        sink = BagSink(writer, imu, flight, seconds)
        yield sink
        sink.motion_until(sink.end, inclusive=True)  # the samples at its very end (the last frame's when stopped)


class ScanCancelled(LivoxVizError):
    """A scan into a bag given up on request (nothing was kept)."""


@dataclass(frozen=True)
class BagWritten:
    """What :func:`write_scan_bag` wrote: frames and points, and the bag's folder."""

    frames: int
    points: int
    path: os.PathLike[str]


def write_scan_bag(path: str | os.PathLike[str], config: SensorConfig, caster: RayCaster, pose: Pose,
                   trajectory: Trajectory | None, seed: int, seconds: float, workers: int | None = None,
                   progress: Callable[[float], None] | None = None,
                   cancelled: Callable[[], bool] | None = None) -> BagWritten:
    """Scan ``seconds`` from t = 0 into a new bag at ``path``: the bag ``scan --rosbag`` writes with the same
    configuration, scene, pose, motion and seed (and the default IMU: 200 Hz, perfect, in the body frame).

    Parameters
    ----------
    path : path-like
        The bag folder to make (a new name).
    config, caster, pose, trajectory, seed
        The scan: as :class:`~livox_viz.casting.scan.LidarScanner` takes them.
    seconds : float
        Scan time, seconds.
    workers : int, optional
        Frames cast side by side (default one per core).
    progress : callable, optional
        Called with the scan time written, seconds, after each frame.
    cancelled : callable, optional
        Checked after each frame: true gives the bag up (nothing is kept) and raises :class:`ScanCancelled`.
    """
    from livox_viz.casting.scan import LidarScanner

    scanner = LidarScanner(config, caster, pose, seed=seed, trajectory=trajectory, workers=workers)
    frames = points = 0
    with open_scan_bag(path, config, scanner.mounted.mount_pose, pose, trajectory, seconds, seed) as bag:
        for frame in scanner.frames(seconds):
            bag.write(frame)
            frames += 1
            points += len(frame)
            if progress is not None:
                progress(scanner.time)
            if cancelled is not None and cancelled():
                raise ScanCancelled(f"{path}: the bag was given up; nothing was kept")
    return BagWritten(frames, points, path)
