"""Commands that cast the scan into a scene: ``scan`` and ``scenes``."""

from __future__ import annotations

import argparse
import os
import sys
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from livox_viz import __version__
from livox_viz.core.atomic import resolve_destination
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.progress import Progress
from livox_viz.core.workload import check_points
from livox_viz.files.export import FORMATS, PointCloudWriter, sidecar_path
from livox_viz.files.overlap import OverlappedWriting
from livox_viz.files.scan_bag import DEFAULT_IMU_FRAME, DEFAULT_IMU_RATE, open_scan_bag
from livox_viz.motion.imu import IMU_FRAMES, MAX_RATE, MIN_RATE, ImuNoise
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
    check_bag_path,
    check_output_path,
    config_from_args,
    config_label,
    positive_float,
    scene_from_args,
    trajectory_from_args,
    whole_number,
)
from .signals import StopRequests, signal_name, signal_status

#: The most frame workers ``--workers`` takes (each holds a batch of frames in flight).
MAX_WORKERS = 1024


@dataclass(frozen=True)
class ScanReport:
    """What :func:`run_scan` did.

    Attributes
    ----------
    frames, points : int
        Frames and points written.
    seconds : float
        Scan time written, seconds (less than asked when a signal stopped the scan).
    returns_model : str
        The return model used.
    range_max : float
        The configuration's range, metres.
    outputs : tuple of Path
        The file and the bag written.
    motion : str
        ``""`` for a fixed sensor, else how it moved (``", moving along line at 5 m/s"``).
    stopped_by : int or None
        The signal that stopped the scan early, if one did.
    """

    frames: int
    points: int
    seconds: float
    returns_model: str
    range_max: float
    outputs: tuple[Path, ...]
    motion: str
    stopped_by: int | None


def cmd_scan(args: argparse.Namespace) -> int:
    report = run_scan(args)
    if report.points == 0:
        why = (f"no ray hit anything within {report.range_max:g} m" if report.returns_model == "ideal" else
               f"no ray returned a point (nothing within {report.range_max:g} m, or nothing detected: the datasheet "
               "model's detection range, blind zone and reflectances decide)")
        print(f"{PROG}: warning: {why}; wrote an empty point cloud", file=sys.stderr)
    where = " and ".join(str(p) for p in report.outputs)
    if report.stopped_by is not None:
        print(f"{PROG}: stopped by {signal_name(report.stopped_by)} after {report.seconds:g} of {args.seconds:g} s of "
              f"scan: kept {report.points:,} points of {_frames(report.frames)} ({args.frame} frame{report.motion}) "
              f"in {where}", file=sys.stderr)
        return signal_status(report.stopped_by)
    print(f"wrote {report.points:,} points of {_frames(report.frames)} ({args.seconds:g} s, {args.frame} "
          f"frame{report.motion}) to {where}")
    return 0


def run_scan(args: argparse.Namespace, progress: TextIO | None = None) -> ScanReport:
    """The scan ``args`` (``scan``'s options) asks for, into its files; ``progress``: where its progress line goes
    (default stderr, when it is a terminal)."""
    cfg = config_from_args(args)
    if not args.out and not args.rosbag:
        raise UsageError("give --out FILE, --rosbag DIR, or both")
    _check_bag_options(args)
    out = check_output_path(args.out, FORMATS) if args.out else None
    sidecar = sidecar_path(out) if out else None
    if sidecar is not None:  # a CSV's JSON sidecar
        resolve_destination(sidecar)
    if args.rosbag:  # every output and name is checked before any work
        from livox_viz.files.rosbag import RosNames

        check_bag_path(args.rosbag, out, sidecar)
        RosNames.parse(args.ros_names or "")
    elif args.ros_names is not None:
        raise UsageError("--ros-names without --rosbag; allowed: with --rosbag DIR (the names are the bag's)")
    check_points(points_before(args.seconds, cfg.point_rate), f"scan --seconds {args.seconds:g}", force=args.force)
    livox = scan_head(out, cfg, config_label(args), args.frame) if out is not None else None
    scene, pose, caster = scene_from_args(args, cfg)
    trajectory = trajectory_from_args(args, pose, args.seconds)
    if trajectory is not None:
        trajectory.check_covers(0.0, args.seconds)
    # Imported here: the casting path (the return model's loops among it) is 60 ms of every command's start-up.
    from livox_viz.casting.scan import LidarScanner

    scanner = LidarScanner(cfg, caster, pose, seed=args.seed, trajectory=trajectory, workers=args.workers)
    frames = points = 0
    shown = Progress(f"scan -> {(out or Path(args.rosbag)).name}", args.seconds, "s", stream=progress)
    with ExitStack() as files:
        # What the files hold: the scan from t = 0 (its length is in its frames: a stopped scan is shorter).
        motion = "fixed" if trajectory is None else f"moving along {trajectory.name}"
        made = (f"livox-viz {__version__} scan of {config_label(args)} ({cfg.returns_model} returns, seed {args.seed}) "
                f"in {scene.name} from t = 0, {motion}")
        # Ctrl-C, SIGTERM and SIGHUP stop the scan after the frame in hand: the files are finished with what was
        # scanned until then (a 10-minute flight's bag stopped at minute 8 keeps its 8 minutes), not removed.
        # Entered first, so a second signal while they are being finished is noted too, not raised.
        stop = files.enter_context(StopRequests(_say_stopping))
        writer = files.enter_context(PointCloudWriter(out, coordinates=args.frame, ascii=args.ascii, source=made,
                                                      livox=livox)) if out else None
        bag = files.enter_context(_open_bag(args, cfg, scanner, trajectory, pose)) if args.rosbag else None
        # Each output is written on a thread of its own while the next frames are cast; leaving this block waits
        # for every frame handed over (a failed writer's error is raised then, and every file is given up).
        with OverlappedWriting([sink for sink in (writer, bag) if sink is not None]) as writing:
            for frame in scanner.frames(args.seconds):
                writing.write(frame)
                frames += 1
                points += len(frame)
                shown.update(scanner.time)
                if stop.requested:
                    if bag is not None:
                        bag.end = frame.end_time  # its IMU and ground truth end with the frames
                    break
    shown.close()
    moving = "" if trajectory is None else (f", moving along {trajectory.name}" if trajectory.moves else
                                            f", not moving ({trajectory.name})")
    scanned = frames / cfg.data_check_freq if stop.signum is not None else args.seconds
    return ScanReport(frames, points, scanned, cfg.returns_model, cfg.range_max,
                      tuple(Path(p) for p in (out, args.rosbag) if p), moving, stop.signum)


def scan_head(out: Path, cfg, name: str, frame: str = "sensor"):
    """The Livox head an ``.lvx2`` or ``.lvx`` of configuration ``cfg`` (named ``name``) is written as, checked
    before any work; None for another format.

    Raises
    ------
    LivoxVizError
        The configuration is no head the format takes, or ``frame`` is not the sensor's.
    """
    from livox_viz.files.lvx_format import LIVOX_FORMATS, head_for_config

    suffix = out.suffix.lower()
    if suffix not in LIVOX_FORMATS:
        return None
    if frame != "sensor":
        raise UsageError(f"--frame {frame} with {out.name}: {suffix} holds the sensor's points (the mount is its "
                         "device's extrinsics); allowed: --frame sensor")
    return head_for_config(suffix, cfg, name)


def _say_stopping(signum: int) -> None:
    """Said at once when a stop signal arrives: the frame in hand may take long (a datasheet scan's first frame
    compiles its loops, up to a minute on a slow machine). Written with one system call, not through ``sys.stderr``:
    the signal may land inside the progress line's own write."""
    os.write(2, f"\n{PROG}: {signal_name(signum)}: stopping after the frame in hand (the first frame of a datasheet "
                "scan compiles its loops first); the files keep what was scanned\n".encode())


def _frames(count: int) -> str:
    return f"{count} frame" + ("" if count == 1 else "s")


#: The bag options and their defaults (given without --rosbag they would be ignored: refused instead).
BAG_OPTIONS = {"imu_rate": DEFAULT_IMU_RATE, "imu_noise": None, "imu_frame": DEFAULT_IMU_FRAME}


def _check_bag_options(args: argparse.Namespace) -> None:
    given = [f"--{name.replace('_', '-')}" for name in BAG_OPTIONS if getattr(args, name) is not None]
    if given and not args.rosbag:
        raise UsageError(f"{', '.join(given)} without --rosbag; allowed: with --rosbag DIR (the IMU is written "
                         "into the bag only)")


def _open_bag(args, cfg, scanner, trajectory, pose):
    """The bag ``--rosbag`` and its options ask for (:func:`~livox_viz.files.scan_bag.open_scan_bag`)."""
    from livox_viz.files.rosbag import RosNames

    def option(name: str):
        value = getattr(args, name)
        return BAG_OPTIONS[name] if value is None else value

    return open_scan_bag(args.rosbag, cfg, scanner.mounted.mount_pose, pose, trajectory, args.seconds, args.seed,
                         imu_rate=option("imu_rate"), imu_noise=ImuNoise(*args.imu_noise) if args.imu_noise else None,
                         imu_frame=option("imu_frame"),
                         names=RosNames.parse(args.ros_names) if args.ros_names else None)


def _imu_noise(text: str) -> tuple[float, float, float, float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4:
        raise argparse.ArgumentTypeError(f"{quoted(text)}: allowed: 4 numbers (Kalibr: gyroscope_noise_density, "
                                         "gyroscope_random_walk, accelerometer_noise_density, "
                                         "accelerometer_random_walk)")
    try:
        ImuNoise(*values)
    except LivoxVizError as error:
        raise argparse.ArgumentTypeError(f"{quoted(text)}: {error}") from None
    return tuple(values)


def _imu_rate(text: str) -> float:
    value = positive_float(text)
    if not MIN_RATE <= value <= MAX_RATE:
        raise argparse.ArgumentTypeError(f"{text}: allowed: {MIN_RATE:g} to {MAX_RATE:g} Hz")
    return value


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
    parser.add_argument("--imu-rate", type=_imu_rate, help=f"IMU samples per second in the bag, {MIN_RATE:g} to "
                                                           f"{MAX_RATE:g} (default 200; needs --rosbag)")
    parser.add_argument("--imu-noise", type=_imu_noise, help="Kalibr's four IMU noise numbers, comma-separated: "
                                                             "gyroscope noise density and random walk (0 to 1), "
                                                             "accelerometer's (0 to 10) (default: a perfect IMU; "
                                                             "needs --rosbag)")
    parser.add_argument("--imu-frame", choices=IMU_FRAMES,
                        help="where the bag's IMU sits: body (base_link, the vehicle's origin and axes; default) or "
                             "lidar (livox_frame, the lidar's origin and axes, as the Livox driver publishes its "
                             "IMU; lever-arm effects included); needs --rosbag")
    parser.add_argument("--ros-names", help="topic/frame names, e.g. lidar=/livox/lidar,imu=/livox/imu,"
                                            "lidar_frame=livox_frame (defaults: the Livox ROS driver 2's)")
    parser.add_argument("--workers", type=whole_number(1, MAX_WORKERS, f"1 to {MAX_WORKERS} threads"),
                        help="frames cast side by side (default: one per core this process may use); the cloud is "
                             "the same whatever the count")
    parser.add_argument("--force", action="store_true",
                        help="allow more points, or a scene of more triangles, than the documented budgets")


def cmd_scenes(args: argparse.Namespace) -> int:
    for name, description in list_scenes():
        print(f"{name:<14}  {description}")
    return 0


def cmd_prepare(args: argparse.Namespace) -> int:
    """Compile every loop the casting stages use into numba's cache, once, where the program is installed."""
    from livox_viz.casting.warm import STAGES, warm

    unknown = [stage for stage in args.stages if stage not in STAGES]
    if unknown:
        raise UsageError(f"prepare {quoted(unknown[0])}: no such stage; allowed: {', '.join(STAGES)}, or none for all")
    stages = args.stages or list(STAGES)
    total = 0.0
    for stage in stages:
        print(f"prepare: {stage} ...", end="", flush=True)
        seconds = warm(stage)
        total += seconds
        print(f" {seconds:.1f} s", flush=True)
    print(f"prepared {', '.join(stages)} in {total:.0f} s: the window and the commands now load these loops in "
          "seconds (numba's cache; prepared again only after an update)")
    return 0


def _prepare_arguments(parser: argparse.ArgumentParser) -> None:
    from livox_viz.casting.warm import STAGES

    parser.add_argument("stages", nargs="*", metavar="STAGE",
                        help=f"what to prepare: {', '.join(STAGES)} (default all; the datasheet returns take 1-2 "
                             "minutes on 2 cores the first time)")


COMMANDS: tuple[Command, ...] = (
    Command("scan", cmd_scan, "cast the scan into a scene and write the point cloud a client receives",
            "livox-viz scan --scene urban --seconds 1 --out cloud.ply", _scan_arguments),
    Command("prepare", cmd_prepare, "compile the ray caster's and return models' loops once, after installing (the "
                                    "window's first datasheet scan is then ready at once)",
            "livox-viz prepare", _prepare_arguments),
    Command("scenes", cmd_scenes, "list the built-in scenes", "livox-viz scenes", lambda parser: None),
)
