"""Commands that cast the scan into a scene: ``scan`` and ``scenes``."""

from __future__ import annotations

import argparse
import math
import sys
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

from livox_viz.casting.scan import LidarScanner
from livox_viz.core.progress import Progress
from livox_viz.core.workload import check_points
from livox_viz.files.export import FORMATS, PointCloudWriter
from livox_viz.motion.flights import builtin_trajectory
from livox_viz.motion.imu import ImuNoise, ImuSamples
from livox_viz.patterns.stream import points_before
from livox_viz.scene.scenes import list_scenes

from .common import (
    PROG,
    Command,
    UsageError,
    add_config_arguments,
    add_scene_arguments,
    add_seed_argument,
    add_trajectory_arguments,
    check_output_path,
    config_from_args,
    positive_float,
    scene_from_args,
    trajectory_from_args,
)


def cmd_scan(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    if not args.out and not args.rosbag:
        raise UsageError("give --out FILE, --rosbag DIR, or both")
    out = check_output_path(args.out, FORMATS) if args.out else None
    check_points(points_before(args.seconds, cfg.point_rate), f"scan --seconds {args.seconds:g}", force=args.force)
    _, pose, caster = scene_from_args(args)
    trajectory = trajectory_from_args(args, pose, args.seconds)
    if trajectory is not None:
        trajectory.check_covers(0.0, args.seconds)
    scanner = LidarScanner(cfg, caster, pose, seed=args.seed, trajectory=trajectory)
    frames = points = 0
    progress = Progress(f"scan -> {(out or Path(args.rosbag)).name}", args.seconds, "s")
    with ExitStack() as files:
        writer = files.enter_context(PointCloudWriter(out, coordinates=args.frame, ascii=args.ascii)) if out else None
        bag = files.enter_context(_open_bag(args, cfg, scanner, trajectory, pose)) if args.rosbag else None
        for frame in scanner.frames(args.seconds):
            if writer is not None:
                writer.write(frame)
            if bag is not None:
                bag.write(frame)
            frames += 1
            points += len(frame)
            progress.update(scanner.time)
    progress.close()
    if points == 0:
        print(f"{PROG}: warning: no ray hit anything within {cfg.range_max:g} m; wrote an empty point cloud",
              file=sys.stderr)
    where = " and ".join(str(p) for p in (out, args.rosbag) if p)
    moving = f", moving along {trajectory.name}" if trajectory is not None else ""
    print(f"wrote {points:,} points of {frames} frames ({args.seconds:g} s, {args.frame} frame{moving}) to {where}")
    return 0


class _BagSink:
    """Frames into a bag, with the IMU samples and ground truth of the same time written alongside."""

    def __init__(self, writer, imu, motion) -> None:
        self.writer = writer
        self.imu = imu
        self.motion = motion
        self._done = 0

    def write(self, frame) -> None:
        self.writer.write_frame(frame)
        self.motion_until(int(np.searchsorted(self.imu.t, frame.end_time, side="left")))

    def motion_until(self, upto: int) -> None:
        """IMU and ground-truth samples up to (not including) sample ``upto``."""
        if upto > self._done:
            rows = slice(self._done, upto)
            t = self.imu.t[rows]
            self.writer.write_imu(ImuSamples(t, self.imu.angular_velocity[rows], self.imu.specific_force[rows]))
            self.writer.write_motion(self.motion, t)
            self._done = upto


@contextmanager
def _open_bag(args, cfg, scanner, trajectory, pose):
    from livox_viz.files.rosbag import RosbagWriter, RosNames
    from livox_viz.motion.imu import TrajectoryMotion, synthesize_imu

    flight = trajectory if trajectory is not None else builtin_trajectory("hover", 0.0, pose, args.seconds + 0.5)
    noise = ImuNoise(*args.imu_noise) if args.imu_noise else ImuNoise()
    imu = synthesize_imu(flight, args.imu_rate, noise, seed=args.seed, start=0.0, stop=args.seconds)
    names = RosNames.parse(args.ros_names) if args.ros_names else RosNames()
    with RosbagWriter(args.rosbag, scanner.mounted.mount_pose, names, lasers=cfg.lasers) as writer:
        sink = _BagSink(writer, imu, TrajectoryMotion(flight))
        yield sink
        sink.motion_until(imu.t.size)  # the samples at the scan's very end


def _imu_noise(text: str) -> tuple[float, float, float, float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4 or not all(math.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: allowed: 4 numbers (Kalibr: gyroscope_noise_density, "
                                         "gyroscope_random_walk, accelerometer_noise_density, "
                                         "accelerometer_random_walk)")
    return tuple(values)


def _scan_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    add_scene_arguments(parser)
    add_trajectory_arguments(parser)
    parser.add_argument("--seconds", type=positive_float, default=1.0, help="scan time (default 1)")
    add_seed_argument(parser)
    parser.add_argument("--frame", choices=("sensor", "world"), default="sensor",
                        help="coordinates in PLY/PCD/LAS/CSV: decoded sensor FRD at each point's own time "
                             "(default) or world NED; NPZ has both")
    parser.add_argument("--ascii", action="store_true", help="ASCII PLY/PCD instead of binary")
    parser.add_argument("--out", help="output: .ply .pcd .las .npz or .csv")
    parser.add_argument("--rosbag", help="also (or only) write a ROS 2 bag folder (MCAP): CustomMsg, PointCloud2, "
                                         "Imu, Odometry, /tf")
    parser.add_argument("--imu-rate", type=positive_float, default=200.0, help="IMU samples per second in the bag "
                                                                              "(default 200)")
    parser.add_argument("--imu-noise", type=_imu_noise, help="Kalibr's four IMU noise numbers, comma-separated "
                                                             "(default: a perfect IMU)")
    parser.add_argument("--ros-names", help="topic/frame names, e.g. lidar=/livox/lidar,imu=/livox/imu,"
                                            "lidar_frame=livox_frame (defaults: the Livox ROS driver 2's)")
    parser.add_argument("--force", action="store_true", help="allow more points than the documented budget")


def cmd_scenes(args: argparse.Namespace) -> int:
    for name, description in list_scenes():
        print(f"{name:<14}  {description}")
    return 0


COMMANDS: tuple[Command, ...] = (
    Command("scan", cmd_scan, "cast the scan into a scene and write the point cloud a client receives",
            "livox-viz scan --scene urban --seconds 1 --out cloud.ply", _scan_arguments),
    Command("scenes", cmd_scenes, "list the built-in scenes", "livox-viz scenes", lambda parser: None),
)
