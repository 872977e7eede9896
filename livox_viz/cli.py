"""The ``livox-viz`` command line.

Every command exits 0 on success and 2 with a one-line ``livox-viz: error:``
message on bad input. Commands that need the GUI import it lazily.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .atomic import atomic_path
from .codec import max_decode_error
from .config import SensorConfig, load_config
from .errors import LivoxVizError
from .metrics import LIVOX_CELL_DEG, pattern_coverage
from .pattern import ScanPattern
from .presets import DEFAULT_PRESET, list_presets, load_preset
from .progress import Progress

PROG = "livox-viz"
Handler = Callable[[argparse.Namespace], int]


class UsageError(LivoxVizError):
    """A command-line value that does not parse."""


# Shared arguments --------------------------------------------------------------------
def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """``--preset NAME | --config FILE [--seq-id N]``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--preset", help=f"preset name or JSON path (default {DEFAULT_PRESET})")
    group.add_argument("--config", help="RflySim sensor JSON or Config.json")
    parser.add_argument("--seq-id", type=int, help="SeqID of the sensor to use in a Config.json")


def config_from_args(args: argparse.Namespace) -> SensorConfig:
    """The configuration the ``--preset``/``--config`` arguments name."""
    if getattr(args, "config", None):
        return load_config(args.config, seq_id=args.seq_id)
    return load_preset(args.preset or DEFAULT_PRESET)


def config_label(args: argparse.Namespace) -> str:
    """A short name for the configuration in use (for titles and sidecars)."""
    if getattr(args, "config", None):
        return Path(args.config).stem
    return Path(args.preset).stem if args.preset else DEFAULT_PRESET


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed: a finite number > 0")
    return value


def float_list(text: str) -> list[float]:
    """argparse type: comma-separated numbers > 0, e.g. ``0.1,0.5,1``."""
    return [positive_float(part) for part in text.split(",") if part.strip()]


# info ----------------------------------------------------------------------------------
def derived_figures(cfg: SensorConfig) -> dict[str, float | int | str]:
    """The figures ``livox-viz info`` prints, by name."""
    rate = cfg.point_rate
    return {
        "point_rate_pts_per_s": rate,
        "points_per_arc": cfg.data_width,
        "points_per_petal": 2 * cfg.data_width,
        "points_per_figure8": cfg.points_per_figure8,
        "points_per_flower": cfg.points_per_flower,
        "points_per_figure": cfg.points_per_figure,
        "points_per_frame": cfg.points_per_frame,
        "arc_s": cfg.data_width / rate,
        "petal_s": 2 * cfg.data_width / rate,
        "figure8_s": cfg.points_per_figure8 / rate,
        "flower_s": cfg.points_per_flower / rate,
        "figure_s": cfg.points_per_figure / rate,
        "frame_s": 1.0 / cfg.data_check_freq,
        "petals_per_flower": 2 * cfg.figure8_per_flower,
        "petal_spacing_deg": cfg.petal_spacing_deg,
        "flower_step_deg": cfg.flower_step_deg,
        "jitter_max_deg": cfg.jitter_max_deg,
        "jitter_scope": cfg.jitter_scope,
        "fov_deg": cfg.camera_fov,
        "petal_length_deg": cfg.half_fov_deg,
        "petal_height_deg": cfg.petal_height,
        "range_max_m": cfg.range_max,
        "range_step_m": cfg.range_step,
        "max_decode_error_m": max_decode_error(cfg.range_max),
    }


def cmd_info(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    figures = derived_figures(cfg)
    if args.json:
        print(json.dumps({"config": config_label(args), **figures}, indent=2))
        return 0
    f = figures
    print(f"{config_label(args)}: Livox rosette lidar (RflySim TypeID {cfg.type_id}), SeqID {cfg.seq_id}")
    print(f"  field of view      {cfg.camera_fov:g} deg (cone of half-angle {cfg.half_fov_deg:g} deg)")
    print(f"  point rate         {cfg.point_rate:,} pts/s = "
          f"{cfg.data_width} x {cfg.data_height} x {cfg.data_check_freq} Hz")
    rows = [
        ("arc", f["points_per_arc"], f["arc_s"]),
        ("petal", f["points_per_petal"], f["petal_s"]),
        ("figure-8", f["points_per_figure8"], f["figure8_s"]),
        ("flower", f["points_per_flower"], f["flower_s"]),
        ("figure", f["points_per_figure"], f["figure_s"]),
        ("frame", f["points_per_frame"], f["frame_s"]),
    ]
    for name, points, seconds in rows:
        print(f"  {name:<18} {points:>10,} pts  {seconds * 1e3:10.3f} ms")
    print(f"  petals per flower  {f['petals_per_flower']}, {f['petal_spacing_deg']:g} deg apart")
    print(f"  flower step        {f['flower_step_deg']:g} deg, "
          f"+ U(0,1) x {cfg.jitter_max_deg:g} deg after each {cfg.jitter_scope}")
    print(f"  petal              length {cfg.half_fov_deg:g} deg, half-width {cfg.petal_height:g} deg, "
          f"p = {cfg.spacing_exponent:g}, q = {cfg.tip_exponent:g}")
    print(f"  range              {cfg.range_max:g} m, int16 step {cfg.range_step * 1e3:.3f} mm, "
          f"max decode error {max_decode_error(cfg.range_max) * 1e3:.3f} mm")
    return 0


# presets -------------------------------------------------------------------------------
def cmd_presets(args: argparse.Namespace) -> int:
    presets = list_presets()
    if args.json:
        print(json.dumps([{"name": p.name, "path": str(p.path), "description": p.description,
                           "shipped": p.shipped} for p in presets], indent=2))
        return 0
    width = max((len(p.name) for p in presets), default=10)
    for info in presets:
        origin = "" if info.shipped else "  [user]"
        print(f"{info.name:<{width}}  {info.description}{origin}")
    return 0


# pattern -------------------------------------------------------------------------------
PATTERN_FIELDS = ("frame", "arc", "petal", "figure8", "flower", "figure")


def cmd_pattern(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    out = Path(args.out)
    suffix = out.suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise UsageError(f"--out {out}: unknown format {suffix or '(none)'}; allowed: .npz or .csv")
    total = int(np.ceil(args.seconds * cfg.point_rate - 1e-9))
    if total > 100_000_000:
        raise UsageError(f"--seconds {args.seconds:g} is {total:,} points; allowed: at most 100 million")
    pattern = ScanPattern(cfg, seed=args.seed)
    progress = Progress(f"pattern -> {out.name}", args.seconds, "s")
    block = max(cfg.points_per_frame, 100_000)
    with atomic_path(out) as tmp:
        if suffix == ".npz":
            arrays = {"xy_deg": np.empty((total, 2)), "t": np.empty(total)}
            arrays.update({name: np.empty(total, dtype=np.int64) for name in PATTERN_FIELDS})
            while pattern.position < total:
                chunk = pattern.take(min(block, total - pattern.position))
                where = slice(chunk.start, chunk.stop)
                arrays["xy_deg"][where] = chunk.xy_deg
                arrays["t"][where] = chunk.t
                for name, values in chunk.labels().items():
                    arrays[name][where] = values
                progress.update(chunk.stop / cfg.point_rate)
            with open(tmp, "wb") as handle:
                np.savez(handle, **arrays)
        else:
            with open(tmp, "w", newline="", encoding="utf-8") as handle:
                writer = csv.writer(handle)
                writer.writerow(["x_deg", "y_deg", "t", *PATTERN_FIELDS])
                while pattern.position < total:
                    chunk = pattern.take(min(block, total - pattern.position))
                    columns = [chunk.xy_deg[:, 0], chunk.xy_deg[:, 1], chunk.t]
                    columns += [values for values in chunk.labels().values()]
                    _write_csv_rows(handle, columns, ["%.9g", "%.9g", "%.9g"] + ["%d"] * len(PATTERN_FIELDS))
                    progress.update(chunk.stop / cfg.point_rate)
    progress.close()
    print(f"wrote {total:,} points ({args.seconds:g} s, seed {args.seed}) to {out}")
    return 0


def _write_csv_rows(handle, columns: Sequence[np.ndarray], formats: Sequence[str]) -> None:
    """Write columns of equal length as CSV rows, vectorised through ``numpy.savetxt``."""
    np.savetxt(handle, np.column_stack(columns), fmt=list(formats), delimiter=",")


# coverage ------------------------------------------------------------------------------
def cmd_coverage(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    fractions = pattern_coverage(cfg, args.seconds, cell_deg=args.cell_deg, seed=args.seed)
    if args.json:
        print(json.dumps({"config": config_label(args), "cell_deg": args.cell_deg, "seed": args.seed,
                          "coverage": [{"seconds": s, "fraction": float(f)}
                                       for s, f in zip(args.seconds, fractions, strict=True)]}, indent=2))
        return 0
    print(f"{config_label(args)}: FOV coverage, {args.cell_deg:g} deg cells, seed {args.seed}")
    print("  integration s   coverage %")
    for seconds, fraction in zip(args.seconds, fractions, strict=True):
        print(f"  {seconds:13g}   {100 * fraction:10.2f}")
    return 0


# scan / scenes -------------------------------------------------------------------------
def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """``--scene NAME|FILE [--up z|y] [--pose x,y,z,roll,pitch,yaw]``."""
    parser.add_argument("--scene", default="urban", help="scene preset name or mesh file (default urban)")
    parser.add_argument("--up", choices=("z", "y"), default="z", help="up axis of a mesh file (default z)")
    parser.add_argument("--pose", help="vehicle pose x,y,z,roll,pitch,yaw in metres/radians, NED "
                                       "(default: the scene's own); write --pose=-5,0,... when it starts with -")


def scene_from_args(args: argparse.Namespace):
    """The :class:`~livox_viz.scene.Scene` and vehicle :class:`~livox_viz.poses.Pose` the arguments name."""
    from .poses import Pose
    from .scene import open_scene

    scene = open_scene(args.scene, up=args.up)
    pose = Pose.parse(args.pose) if args.pose else scene.vehicle_pose
    return scene, pose


def cmd_scan(args: argparse.Namespace) -> int:
    from .export import PointCloudWriter
    from .scan import LidarScanner

    cfg = config_from_args(args)
    scene, pose = scene_from_args(args)
    writer = PointCloudWriter(args.out, coordinates=args.frame, ascii=args.ascii)
    frames = 0
    try:
        scanner = LidarScanner(cfg, scene.mesh, pose, seed=args.seed)
        progress = Progress(f"scan -> {Path(args.out).name}", args.seconds, "s")
        for frame in scanner.frames(args.seconds):
            writer.write(frame)
            frames += 1
            progress.update(scanner.time)
        progress.close()
    except BaseException:
        writer.abort()
        raise
    writer.close()
    if writer.count == 0:
        print(f"{PROG}: warning: no ray hit anything within {cfg.range_max:g} m; wrote an empty point cloud",
              file=sys.stderr)
    print(f"wrote {writer.count:,} points of {frames} frames ({args.seconds:g} s, {args.frame} frame) to {args.out}")
    return 0


def cmd_scenes(args: argparse.Namespace) -> int:
    from .scene import list_scenes

    for name, description in list_scenes():
        print(f"{name:<14}  {description}")
    return 0


# publish / listen / request -------------------------------------------------------------
def _seconds_or_forever(text: str) -> float | None:
    if text.strip().lower() == "forever":
        return None
    return positive_float(text)


def cmd_publish(args: argparse.Namespace) -> int:
    from .rflysim import parse_host_port, send_protocol_destination
    from .scan import LidarScanner
    from .transport import ShmSender, UdpSender, publish

    cfg = config_from_args(args)
    scene, pose = scene_from_args(args)
    if args.to:
        host, port = parse_host_port(args.to)
        sender = UdpSender(host, port)
        where = f"udp {host}:{port}"
    else:
        destination = send_protocol_destination(cfg)
        if destination.transport == "udp":
            sender = UdpSender(destination.host, destination.port)
            where = f"udp {destination.host}:{destination.port} (SendProtocol)"
        else:
            sender = ShmSender(cfg, args.shm_dir)
            where = f"shared memory {sender.link.path} (SendProtocol[0] = 0)"
    scanner = LidarScanner(cfg, scene.mesh, pose, seed=args.seed)
    seconds = args.seconds
    frames = scanner.frames(seconds if seconds is not None else float("inf"))
    speed = None if args.unpaced else args.speed
    print(f"publishing {cfg.points_per_frame:,}-ray frames at {cfg.data_check_freq} Hz "
          f"({'unpaced' if speed is None else f'{speed:g}x real time'}) to {where}", file=sys.stderr)
    last = [time.monotonic()]

    def progress(report) -> None:
        now = time.monotonic()
        if now - last[0] >= 1.0:
            last[0] = now
            error = f", send errors {sender.errors} ({sender.last_error})" if sender.errors else ""
            print(f"  {report.frames} frames, {report.points:,} points, scan t = {report.scan_seconds:.1f} s"
                  f"{error}", file=sys.stderr)

    try:
        report = publish(frames, sender, speed, cfg.point_rate, progress)
    finally:
        sender.close()
    error = f", {report.send_errors} send errors (last: {sender.last_error})" if report.send_errors else ""
    print(f"sent {report.frames} frames, {report.points:,} points in {report.wall_seconds:.2f} s: "
          f"{report.frames / max(report.wall_seconds, 1e-9):.1f} frames/s = "
          f"{(report.frames / cfg.data_check_freq) / max(report.wall_seconds, 1e-9):.1f} x real time{error}")
    return 0


def cmd_listen(args: argparse.Namespace) -> int:
    from .export import PointCloudWriter
    from .transport import ShmReceiver, UdpReceiver, livox_to_scan_frame, print_status, status_line

    cfg = load_config(args.config, seq_id=args.seq_id) if args.config else load_preset(DEFAULT_PRESET)
    receiver = ShmReceiver(cfg, args.shm_dir) if args.shm else UdpReceiver(args.host, args.port)
    if args.gui:
        try:
            return _gui_module().run_listen_gui(receiver, cfg, args)
        finally:
            receiver.close()
    writer = PointCloudWriter(args.record) if args.record else None
    start = time.monotonic()
    last_data = [start]
    last_status = [start]

    def stop() -> bool:
        now = time.monotonic()
        if now - last_status[0] >= 1.0:
            last_status[0] = now
            print_status(status_line(receiver.report, receiver.assembler, now - start))
        if args.frames is not None and receiver.report.frames >= args.frames:
            return True
        if args.seconds is not None and now - start >= args.seconds:
            return True
        return args.timeout is not None and now - last_data[0] >= args.timeout

    where = f"shared memory {receiver.link.path}" if args.shm else f"udp {args.host}:{args.port}"
    print(f"listening on {where} (range {cfg.range_max:g} m); Ctrl-C to stop", file=sys.stderr)
    try:
        for frame in receiver.frames(stop):
            last_data[0] = time.monotonic()
            if writer is not None:
                writer.write(livox_to_scan_frame(frame, cfg))
    except KeyboardInterrupt:
        pass
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        receiver.close()
    if writer is not None:
        writer.close()
    report = receiver.report
    elapsed = time.monotonic() - start
    print_status(status_line(report, receiver.assembler, elapsed))
    cpu = report.cpu_seconds / report.frames * 1e3 if report.frames else 0.0
    print(f"received {report.frames} frames, {report.points:,} points; receiver CPU {cpu:.2f} ms per frame"
          + (f"; recorded to {args.record}" if writer is not None else ""))
    return 0


def cmd_request(args: argparse.Namespace) -> int:
    import socket

    from .rflysim import REQUEST_PORT_BASE, parse_host_port, sensor_request

    cfg = config_from_args(args)
    data = sensor_request(cfg)
    host, port = parse_host_port(args.to, REQUEST_PORT_BASE + args.window)
    if args.dry_run:
        print(f"sensor request for {config_label(args)} ({len(data)} bytes) to {host}:{port}:")
        print(data.hex())
        return 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.sendto(data, (host, port))
        except OSError as exc:
            raise UsageError(f"cannot send to {host}:{port} ({exc.strerror or exc})") from None
    print(f"sent the {len(data)}-byte sensor request of {config_label(args)} to {host}:{port}")
    return 0


# fit / compare -----------------------------------------------------------------------------
def cmd_fit(args: argparse.Namespace) -> int:
    from .fit import fit_reference
    from .presets import DESCRIPTION_KEY
    from .reference import load_reference

    reference = load_reference(args.reference, rate=args.rate)
    result = fit_reference(reference)
    cfg, shape, structure = result.config, result.shape, result.structure
    print(f"{reference.name}: {len(reference.t):,} points, {reference.seconds:g} s, {shape.petals} petals")
    print(f"  CameraFOV        {cfg.camera_fov:10.4f} deg")
    print(f"  otherParams[1] h {cfg.petal_height:10.4f} deg")
    print(f"  otherParams[2] p {cfg.spacing_exponent:10.4f}")
    print(f"  otherParams[3] q {cfg.tip_exponent:10.4f}")
    print(f"  otherParams[4]   {cfg.figure8_per_flower:10d}  figure-8s per flower   ({structure.method})")
    print(f"  otherParams[5]   {cfg.flowers_per_figure:10d}  flowers per figure")
    print(f"  otherParams[6]   {cfg.jitter_max_deg:10.4f} deg jitter after each {cfg.jitter_scope}")
    print(f"  DataWidth/Height/CheckFreq {cfg.data_width}/{cfg.data_height}/{cfg.data_check_freq} "
          f"(measured {shape.points_per_arc:.2f} points per arc)")
    print(f"  shape residual   rms {shape.rms_deg:.4f} deg, p95 {shape.p95_deg:.4f} deg (perpendicular distance)")
    print("  coverage         integration s   reference %   fit %")
    rows = []
    for t, ref, fit in zip(result.seconds, result.coverage_reference, result.coverage_fit, strict=True):
        print(f"                   {t:13g}   {100 * ref:11.2f}   {100 * fit:5.2f}")
        rows.append(f"{t:g} s {100 * ref:.1f}/{100 * fit:.1f} %")
    if args.out:
        data = cfg.to_json_dict()
        data[DESCRIPTION_KEY] = (
            f"Fitted to {reference.name} ({reference.seconds:g} s): shape residual rms {shape.rms_deg:.3f} deg, "
            f"p95 {shape.p95_deg:.3f} deg; coverage reference/fit {', '.join(rows)}"
        )
        from .atomic import write_text_atomic

        write_text_atomic(args.out, json.dumps(data, indent=2) + "\n")
        print(f"wrote {args.out}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from .fit import compare, plot_comparison
    from .reference import load_reference

    cfg = config_from_args(args)
    reference = load_reference(args.reference, rate=args.rate)
    result = compare(cfg, reference, seed=args.seed)
    print(f"{config_label(args)} against {reference.name} ({reference.seconds:g} s)")
    print("  integration s   reference %   ours %   difference pp")
    for t, ref, ours in zip(result.seconds, result.coverage_reference, result.coverage_ours, strict=True):
        print(f"  {t:13g}   {100 * ref:11.2f}   {100 * ours:6.2f}   {100 * (ours - ref):+13.2f}")
    print("  radial density, million points per sr per s")
    print("  alpha deg      reference      ours")
    edges = result.density_edges_deg
    for k in range(0, len(result.density_ours), max(1, len(result.density_ours) // 10)):
        print(f"  {edges[k]:5.1f}-{edges[k + 1]:<5.1f}  {result.density_reference[k] / 1e6:9.3f}  "
              f"{result.density_ours[k] / 1e6:9.3f}")
    if args.plot:
        plot_comparison(result, args.plot, f"{config_label(args)} vs {reference.name}")
        print(f"wrote {args.plot}")
    return 0


# The parser --------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with a one-line message (argparse's own usage dump is long)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def _command(subparsers, name: str, handler: Handler, help_text: str, example: str) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        name,
        help=help_text,
        description=f"{help_text}\n\nexample:\n  {example}",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.set_defaults(handler=handler)
    return parser


def build_parser() -> argparse.ArgumentParser:
    """The whole command line; each subcommand has ``--help`` with an example."""
    parser = _Parser(
        prog=PROG,
        description="Visualise and tune the simulated Livox rosette lidar of RflySim (TypeID 6).",
        epilog="Run 'livox-viz COMMAND --help' for a command's options. With no command: gui.",
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = _command(sub, "info", cmd_info, "print the derived figures of a sensor configuration",
                 "livox-viz info --preset livox_mid70")
    add_config_arguments(p)
    p.add_argument("--json", action="store_true", help="print JSON")

    p = _command(sub, "presets", cmd_presets, "list the sensor presets", "livox-viz presets")
    p.add_argument("--json", action="store_true", help="print JSON")

    p = _command(sub, "pattern", cmd_pattern, "write the scan pattern (angles, times, labels) to .npz or .csv",
                 "livox-viz pattern --seconds 0.5 --seed 1 --out pattern.npz")
    add_config_arguments(p)
    p.add_argument("--seconds", type=positive_float, default=1.0, help="scan time to write (default 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="output file, .npz or .csv")

    p = _command(sub, "coverage", cmd_coverage, "FOV coverage against integration time",
                 "livox-viz coverage --seconds 0.1,0.5,1,2 --json")
    add_config_arguments(p)
    p.add_argument("--seconds", type=float_list, default=[0.1, 0.5, 1.0, 2.0],
                   help="integration times, comma-separated (default 0.1,0.5,1,2)")
    p.add_argument("--cell-deg", type=positive_float, default=LIVOX_CELL_DEG,
                   help=f"grid cell size in degrees (default {LIVOX_CELL_DEG:.4f} = 5 mrad)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON")

    p = _command(sub, "scan", cmd_scan, "cast the scan into a scene and write the point cloud a client receives",
                 "livox-viz scan --scene urban --seconds 1 --out cloud.ply")
    add_config_arguments(p)
    add_scene_arguments(p)
    p.add_argument("--seconds", type=positive_float, default=1.0, help="scan time (default 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--frame", choices=("sensor", "world"), default="sensor",
                   help="coordinates in PLY/PCD/LAS/CSV: decoded sensor FRD (default) or world NED; NPZ has both")
    p.add_argument("--ascii", action="store_true", help="ASCII PLY/PCD instead of binary")
    p.add_argument("--out", required=True, help="output: .ply .pcd .las .npz or .csv")

    p = _command(sub, "scenes", cmd_scenes, "list the built-in scenes", "livox-viz scenes")

    p = _command(sub, "fit", cmd_fit, "fit the model's parameters to a measured pattern and write a preset",
                 "livox-viz fit ../shared/reference/mid40.npy --out presets/livox_mid40.json")
    p.add_argument("reference", help="measured pattern: .npy [theta, phi] radians or Livox CSV (degrees)")
    p.add_argument("--rate", type=positive_float, default=100_000.0, help="points per second (default 100000)")
    p.add_argument("--out", help="write the fitted preset JSON here")

    p = _command(sub, "compare", cmd_compare, "coverage and radial density of a preset against a measured pattern",
                 "livox-viz compare --preset livox_mid40 ../shared/reference/mid40.npy --plot compare.png")
    add_config_arguments(p)
    p.add_argument("reference", help="measured pattern: .npy or Livox CSV")
    p.add_argument("--rate", type=positive_float, default=100_000.0, help="points per second (default 100000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--plot", help="write a PNG plot of both curves and their difference")

    p = _command(sub, "publish", cmd_publish, "stand in for RflySim's Livox sensor: send scan frames live",
                 "livox-viz publish --to 127.0.0.1:9999 --seconds 10 --speed 1")
    add_config_arguments(p)
    add_scene_arguments(p)
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--to", help="HOST:PORT for UDP (default: the config's SendProtocol)")
    p.add_argument("--seconds", type=_seconds_or_forever, default=10.0, help="scan time, or 'forever' (default 10)")
    p.add_argument("--speed", type=positive_float, default=1.0, help="times real time (default 1)")
    p.add_argument("--unpaced", action="store_true", help="send as fast as possible")
    p.add_argument("--shm-dir", default="/dev/shm", help="folder of the shared memory block (default /dev/shm)")

    p = _command(sub, "listen", cmd_listen, "receive RflySim Livox frames, report them, record them",
                 "livox-viz listen --port 9999 --record received.npz")
    p.add_argument("--host", default="0.0.0.0", help="address to bind (default 0.0.0.0)")
    p.add_argument("--port", type=int, default=9999, help="UDP port (default 9999)")
    p.add_argument("--config", help="sensor JSON giving the range (int16 scale); default the default preset")
    p.add_argument("--seq-id", type=int, help="SeqID in a Config.json")
    p.add_argument("--record", help="write the frames to .ply .pcd .las .npz or .csv")
    p.add_argument("--shm", action="store_true", help="read /dev/shm/RflySim3DImg_<SeqID> instead of UDP")
    p.add_argument("--shm-dir", default="/dev/shm", help="folder of the shared memory block")
    p.add_argument("--frames", type=int, help="stop after this many frames")
    p.add_argument("--seconds", type=positive_float, help="stop after this many wall seconds")
    p.add_argument("--timeout", type=positive_float, help="stop after this many seconds without a frame")
    p.add_argument("--gui", action="store_true", help="show the frames in the window (angles and decoded cloud)")
    p.add_argument("--scene", default="urban", help="scene drawn behind the received cloud with --gui")

    p = _command(sub, "request", cmd_request, "ask a running RflySim for this sensor (the <16H15f request)",
                 "livox-viz request --to 127.0.0.1 --dry-run")
    add_config_arguments(p)
    p.add_argument("--to", required=True, help="HOST[:PORT]; the port defaults to 20010 + --window")
    p.add_argument("--window", type=int, default=0, help="RflySim window index (default 0)")
    p.add_argument("--dry-run", action="store_true", help="print the 92 bytes in hex instead of sending")

    for register in _EXTRA_COMMANDS:
        register(sub)
    return parser


def _gui_module():
    """The GUI's command module, imported only when a GUI command runs (it pulls in VTK)."""
    import importlib

    return importlib.import_module("widgets.cli")


def cmd_gui(args: argparse.Namespace) -> int:
    """``gui``: the GUI package (VTK) is imported only now."""
    return _gui_module().cmd_gui(args)


def cmd_render(args: argparse.Namespace) -> int:
    """``render``: the GUI package (VTK) is imported only now."""
    return _gui_module().cmd_render(args)


def _register_gui(sub: argparse._SubParsersAction) -> None:
    p = _command(sub, "gui", cmd_gui, "open the interactive window (the default command)",
                 "livox-viz gui --preset livox_mid70 --scene urban")
    add_config_arguments(p)
    add_scene_arguments(p)
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--size", default="1600x900", help="window size WIDTHxHEIGHT (default 1600x900)")
    p.add_argument("--seconds", type=positive_float, default=1.0,
                   help="scan time of the off-screen pictures when there is no display (default 1)")
    _add_reference_arguments(p)

    p = _command(sub, "render", cmd_render, "render what the GUI shows after S seconds into a PNG, off-screen",
                 "livox-viz render --view both --seconds 1 --out screenshots/both.png")
    add_config_arguments(p)
    add_scene_arguments(p)
    p.add_argument("--seconds", type=positive_float, default=1.0, help="scan time (default 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--view", choices=("pattern", "scene", "both"), default="both", help="which view (default both)")
    p.add_argument("--size", default="1600x900", help="image size WIDTHxHEIGHT (default 1600x900)")
    p.add_argument("--out", required=True, help="output PNG")
    _add_reference_arguments(p)


def _add_reference_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--reference", help="overlay a measured pattern (.npy radians or Livox CSV) in the "
                                            "pattern view")
    parser.add_argument("--reference-rate", type=positive_float, default=100_000.0,
                        help="points per second of the reference (default 100000)")


#: Functions that add further subcommands, registered by their modules.
_EXTRA_COMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [_register_gui]


def _version() -> str:
    from . import __version__

    return __version__


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(argv)
        if args.command is None and "gui" in _commands(parser):
            args = parser.parse_args(["gui", *argv])
    except SystemExit as exc:  # argparse: --help, --version, or a usage error (status 2)
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return int(args.handler(args) or 0)
    except LivoxVizError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130


def _commands(parser: argparse.ArgumentParser) -> set[str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return set(action.choices)
    return set()


if __name__ == "__main__":
    sys.exit(main())
