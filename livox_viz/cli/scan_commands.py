"""Commands that cast the scan into a scene: ``scan`` and ``scenes``."""

from __future__ import annotations

import argparse
import sys

from ..export import FORMATS, PointCloudWriter
from ..pattern import points_before
from ..progress import Progress
from ..scan import LidarScanner
from ..scene import list_scenes
from ..workload import check_points
from .common import (
    PROG,
    Command,
    add_config_arguments,
    add_scene_arguments,
    add_seed_argument,
    check_output_path,
    config_from_args,
    positive_float,
    scene_from_args,
)


def cmd_scan(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    out = check_output_path(args.out, FORMATS)
    check_points(points_before(args.seconds, cfg.point_rate), f"scan --seconds {args.seconds:g}", force=args.force)
    _, pose, caster = scene_from_args(args)
    scanner = LidarScanner(cfg, caster, pose, seed=args.seed)
    frames = 0
    progress = Progress(f"scan -> {out.name}", args.seconds, "s")
    with PointCloudWriter(out, coordinates=args.frame, ascii=args.ascii) as writer:
        for frame in scanner.frames(args.seconds):
            writer.write(frame)
            frames += 1
            progress.update(scanner.time)
    progress.close()
    if writer.count == 0:
        print(f"{PROG}: warning: no ray hit anything within {cfg.range_max:g} m; wrote an empty point cloud",
              file=sys.stderr)
    print(f"wrote {writer.count:,} points of {frames} frames ({args.seconds:g} s, {args.frame} frame) to {out}")
    return 0


def _scan_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    add_scene_arguments(parser)
    parser.add_argument("--seconds", type=positive_float, default=1.0, help="scan time (default 1)")
    add_seed_argument(parser)
    parser.add_argument("--frame", choices=("sensor", "world"), default="sensor",
                        help="coordinates in PLY/PCD/LAS/CSV: decoded sensor FRD (default) or world NED; NPZ has both")
    parser.add_argument("--ascii", action="store_true", help="ASCII PLY/PCD instead of binary")
    parser.add_argument("--out", required=True, help="output: .ply .pcd .las .npz or .csv")
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
