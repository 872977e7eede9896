"""Commands on RflySim's wire: ``publish``, ``listen``, ``request``."""

from __future__ import annotations

import argparse
import math
import signal
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import nullcontext

import numpy as np

from livox_viz import __version__
from livox_viz.casting.scan import LidarScanner, ScanFrame
from livox_viz.config.presets import DEFAULT_PRESET, load_preset
from livox_viz.config.sensor import load_config
from livox_viz.core.workload import check_points
from livox_viz.files.export import CLOUD_FORMATS, PointCloudWriter, WritingStopped
from livox_viz.wire.received import RECORDING_FIELDS, RECORDING_TABLE_COLUMNS, RecordingClock
from livox_viz.wire.rflysim import (
    REQUEST_PORT_BASE,
    WireFormat,
    parse_host_port,
    send_protocol_destination,
    sensor_request,
)
from livox_viz.wire.transport import (
    ShmReceiver,
    ShmSender,
    UdpReceiver,
    UdpSender,
    drops_text,
    print_status,
    publish,
    status_line,
)

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
    config_label,
    port_value,
    positive_float,
    refuse_seq_id_without_config,
    scene_from_args,
    trajectory_from_args,
    whole_number,
)
from .signals import StopRequests, signal_name, signal_status

SPEED_RANGE = (0.01, 1000.0)
#: Seconds published when --seconds is not given (and no TUM trajectory sets the length).
DEFAULT_PUBLISH_SECONDS = 10.0


def _seconds_or_forever(text: str) -> float:
    if text.strip().lower() == "forever":
        return math.inf
    return positive_float(text)


def _speed(text: str) -> float:
    value = positive_float(text)
    if not SPEED_RANGE[0] <= value <= SPEED_RANGE[1]:
        raise argparse.ArgumentTypeError(f"{text}: allowed: {SPEED_RANGE[0]:g} to {SPEED_RANGE[1]:g} x real time")
    return value


class _Every:
    """True at most once per ``seconds`` of wall time (for live status lines)."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._last = time.monotonic()

    def due(self) -> bool:
        now = time.monotonic()
        if now - self._last < self.seconds:
            return False
        self._last = now
        return True


# publish -------------------------------------------------------------------------------------
def endless_frames(scanner: LidarScanner, chunk_frames: int = 600) -> Iterator[ScanFrame]:
    """Frames without end (``--seconds forever``), asked of the scanner ``chunk_frames`` at a time.

    Each chunk ends half a point before a frame boundary, so rounding its end
    to whole points never cuts a frame, however long the run.
    """
    per_frame, rate = scanner.config.points_per_frame, scanner.config.point_rate
    end = 0
    while True:
        end += chunk_frames * per_frame
        yield from scanner.frames((end - 0.5) / rate)


def _publish_seconds(args: argparse.Namespace) -> float | None:
    """Seconds to publish: as given ('forever': None); not given, a TUM file's whole span (None), else 10 s."""
    from livox_viz.motion.flights import BUILTIN_TRAJECTORIES

    if args.seconds is not None:
        return None if math.isinf(args.seconds) else args.seconds
    if args.trajectory is not None and args.trajectory.strip().lower() not in BUILTIN_TRAJECTORIES:
        return None
    return DEFAULT_PUBLISH_SECONDS


def cmd_publish(args: argparse.Namespace) -> int:
    if args.unpaced and args.speed is not None:
        raise UsageError(f"--speed {args.speed:g} with --unpaced; allowed: one of them (--unpaced sends as fast as "
                         "possible, --speed paces at that many times real time)")
    if args.to and args.shm_dir is not None:
        raise UsageError("--shm-dir with --to; allowed: one of them (--to sends over UDP, --shm-dir is the folder of "
                         "the shared memory block a configuration's SendProtocol[0] = 0 writes)")
    cfg = config_from_args(args)
    seconds = _publish_seconds(args)
    if seconds is not None:
        check_points(seconds * cfg.point_rate, f"publish --seconds {seconds:g}", force=args.force)
    _, pose, caster = scene_from_args(args, cfg)
    trajectory = trajectory_from_args(args, pose, seconds)
    if trajectory is not None and seconds is not None:
        trajectory.check_covers(0.0, seconds)
    wire = WireFormat.of(cfg)
    sender: UdpSender | ShmSender
    if args.to:
        host, port = parse_host_port(args.to)
        sender = UdpSender(host, port, wire)
        where = f"udp {host}:{port}"
    else:
        destination = send_protocol_destination(cfg)
        if destination.transport == "udp":
            if args.shm_dir is not None:
                raise UsageError(f"--shm-dir with a configuration that sends over UDP (SendProtocol[0] = 1, to "
                                 f"{destination.host}:{destination.port}); allowed: --shm-dir with SendProtocol[0] = 0")
            sender = UdpSender(destination.host, destination.port, wire)
            where = f"udp {destination.host}:{destination.port} (SendProtocol)"
        else:
            sender = ShmSender(cfg, args.shm_dir)
            where = f"shared memory {sender.link.name} (SendProtocol[0] = 0)"
    scanner = LidarScanner(cfg, caster, pose, seed=args.seed, trajectory=trajectory)
    if seconds is not None:
        frames, until = scanner.frames(seconds), f"for {seconds:g} s"
    elif trajectory is not None:
        frames, until = scanner.frames(trajectory.span[1]), f"to the trajectory's end at {trajectory.span[1]:g} s"
    else:
        frames, until = endless_frames(scanner), "until stopped (Ctrl-C)"
    speed = None if args.unpaced else args.speed or 1.0
    print(f"publishing {cfg.points_per_frame:,}-ray frames at {cfg.data_check_freq} Hz "
          f"({'unpaced' if speed is None else f'{speed:g}x real time'}) to {where}, {until}; RflySim SDK "
          f"{cfg.sdk} (TypeID {cfg.type_id}): {wire.describe()}", file=sys.stderr)
    every = _Every(1.0)

    def progress(report) -> None:
        if every.due():
            error = f", send errors {sender.errors} ({sender.last_error})" if sender.errors else ""
            print(f"  {report.frames} frames, {report.points:,} points, scan t = {report.scan_seconds:.1f} s"
                  f"{error}", file=sys.stderr)

    # A signal ends publishing after the frame being sent: the summary is printed, the sender closed.
    with StopRequests() as stop:
        try:
            report = publish(frames, sender, speed, progress, stop=lambda: stop.requested)
        finally:
            sender.close()
    error = f", {report.send_errors} send errors (last: {sender.last_error})" if report.send_errors else ""
    print(f"sent {report.frames} frames, {report.points:,} points in {report.wall_seconds:.2f} s: "
          f"{report.frames / max(report.wall_seconds, 1e-9):.1f} frames/s = "
          f"{report.scan_seconds / max(report.wall_seconds, 1e-9):.1f} x real time{error}")
    if report.late_frames:
        print(f"{PROG}: publish: {report.late_frames} of {report.frames} frames were not ready at their time (late by "
              f"{report.late_seconds:.2f} s in all): each left when ready and the next at its interval from it; "
              f"{'the first compiled the scan loops; ' if report.late_frames == 1 else ''}a lower --speed keeps up",
              file=sys.stderr)
    if report.frames and report.datagrams == 0:
        raise UsageError(f"nothing could be sent to {where} ({sender.last_error or 'every send failed'})")
    if stop.signum is not None:
        print(f"{PROG}: stopped by {signal_name(stop.signum)} after scan t = {report.scan_seconds:.1f} s",
              file=sys.stderr)
        return signal_status(stop.signum)
    return 0


def _publish_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    add_scene_arguments(parser)
    add_trajectory_arguments(parser)
    add_seed_argument(parser)
    parser.add_argument("--to", help="HOST:PORT for UDP (default: the config's SendProtocol)")
    parser.add_argument("--seconds", type=_seconds_or_forever,
                        help=f"scan time, or 'forever' (default {DEFAULT_PUBLISH_SECONDS:g}; with a TUM "
                             "--trajectory, to its end)")
    parser.add_argument("--speed", type=_speed,
                        help=f"times real time, {SPEED_RANGE[0]:g} to {SPEED_RANGE[1]:g} (default 1)")
    parser.add_argument("--unpaced", action="store_true", help="send as fast as possible (not with --speed)")
    parser.add_argument("--shm-dir", help="folder of the shared memory block's file (default /dev/shm, the "
                                          "temporary folder on macOS; Windows uses RflySim's named mapping)")
    parser.add_argument("--force", action="store_true",
                        help="allow more points, or a scene of more triangles, than the documented budgets")


# listen --------------------------------------------------------------------------------------
#: Where ``listen`` (and the window's ``--listen``) binds without ``--host``/``--port``.
DEFAULT_LISTEN_HOST, DEFAULT_LISTEN_PORT = "0.0.0.0", 9999


def open_receiver(args: argparse.Namespace, config) -> tuple[UdpReceiver | ShmReceiver, str]:
    """The receiver ``--port``/``--host``/``--shm`` name, and where it listens in words.

    An option the receiver would not use is refused: ``--shm --port 5000`` read shared memory, and ``--shm-dir``
    without ``--shm`` listened on UDP, without a word.
    """
    if args.shm:
        given = [f"--{name}" for name in ("host", "port") if getattr(args, name) is not None]
        if given:
            raise UsageError(f"{' and '.join(given)} with --shm; allowed: --host and --port for UDP, or --shm (and "
                             "--shm-dir) for shared memory")
        shm = ShmReceiver(config, args.shm_dir)
        waiting = "" if shm.link is not None else ", waiting for a publisher to make it"
        return shm, f"shared memory {shm.path}{waiting}"
    if args.shm_dir is not None:
        raise UsageError("--shm-dir without --shm; allowed: with --shm (the folder of the shared memory block), "
                         "or --host and --port for UDP")
    host = DEFAULT_LISTEN_HOST if args.host is None else args.host
    port = DEFAULT_LISTEN_PORT if args.port is None else args.port
    udp = UdpReceiver(host, port, "world" if WireFormat.of(config).world_points else "sensor")
    return udp, f"udp {host}:{udp.port}"



def add_receiver_arguments(parser: argparse.ArgumentParser) -> None:
    """``--host``, ``--port``, ``--shm``, ``--shm-dir`` (shared with the GUI's live view)."""
    parser.add_argument("--host", help=f"address to bind (default {DEFAULT_LISTEN_HOST})")
    parser.add_argument("--port", type=port_value,
                        help=f"UDP port, 0 for any free one (default {DEFAULT_LISTEN_PORT})")
    parser.add_argument("--shm", action="store_true", help="read RflySim3DImg_<SeqID> (a file in /dev/shm; on Windows "
                                                           "RflySim's named mapping) instead of UDP")
    parser.add_argument("--shm-dir", help="folder of the shared memory block's file (default /dev/shm, the temporary "
                                          "folder on macOS; not used on Windows)")


class _Listening:
    """When ``listen`` stops: after ``--frames`` frames, ``--seconds`` of wall time, ``--timeout`` of silence,
    or a signal (Ctrl-C, SIGTERM, SIGHUP).

    It also prints the live status line once a second.
    """

    def __init__(self, args: argparse.Namespace, receiver: UdpReceiver | ShmReceiver, signals: StopRequests) -> None:
        self.args = args
        self.receiver = receiver
        self.signals = signals
        self.start = self.last_data = time.monotonic()
        self.every = _Every(1.0)

    def heard(self) -> None:
        self.last_data = time.monotonic()

    def __call__(self) -> bool:
        args, now = self.args, time.monotonic()
        if self.every.due():
            print_status(status_line(self.receiver.report, self.receiver.assembler, now - self.start))
        if self.signals.requested:
            return True
        if args.frames is not None and self.receiver.report.frames >= args.frames:
            return True
        if args.seconds is not None and now - self.start >= args.seconds:
            return True
        return args.timeout is not None and now - self.last_data >= args.timeout


#: What a recording's NPZ arrays are (stated in its ``frame_of_reference``).
RECORDING_NPZ_RULE = ("xyz_int16: the points as received (sensor FRD; world NED from RflySim v3's Mid-360, TypeID "
                      "23); xyz_sensor: those decoded (xyz_int16 x range_max / 32767, the listener's range_max) in "
                      "the sensor frame; xyz_world and range: the decoded points placed with their frame's posAng "
                      "(as received for world points), and their distance; channel4: a v3 frame's fourth int16 a "
                      "point as received (0 for three values a point)")


def cmd_listen(args: argparse.Namespace) -> int:
    refuse_seq_id_without_config(args)
    cfg = load_config(args.config, seq_id=args.seq_id) if args.config else load_preset(DEFAULT_PRESET)
    out = check_output_path(args.record, CLOUD_FORMATS) if args.record else None
    clock = RecordingClock(cfg.range_max, cfg.data_check_freq)
    # A recording is the user's data: Ctrl-C, SIGTERM and SIGHUP end listening after the frame in hand, and the
    # file is closed properly (the signals stay noted, not raised, until it is in place).
    # The recording's temporary is made first: a folder we cannot write in fails before a port is taken.
    # RflySim's wire has no range: its int16 points are decoded with this configuration's, which must be the
    # sender's (a Horizon's 260 m read with the default 600 m puts every point 2.3 times too far). The recording
    # says which it used.
    label = config_label(args)
    made = (f"livox-viz {__version__} listen: RflySim frames received, their int16 points decoded with the range "
            f"{cfg.range_max:g} m of {label}; each point at its frame's time")
    stopped = ""
    with StopRequests() as signals, \
            PointCloudWriter(out, extra_fields=RECORDING_FIELDS, source=made, npz_rule=RECORDING_NPZ_RULE
                             ) if out is not None else nullcontext() as writer:
        receiver, where = open_receiver(args, cfg)
        stop = _Listening(args, receiver, signals)
        print(f"listening on {where} (decoding with the range {cfg.range_max:g} m of {label}: the sender's must be "
              "the same, --config FILE as it was started with); Ctrl-C to stop", file=sys.stderr, flush=True)
        try:
            for frame in receiver.frames(stop):
                stop.heard()
                numbered = clock.number(frame, time.monotonic() - stop.start)
                if writer is not None:
                    try:
                        writer.write(numbered, {"sender_frame": numbered.sender_index,
                                                "sender_time": numbered.sender_time, "session": numbered.session,
                                                "channel4": numbered.channel4})
                    except WritingStopped:
                        # What was recorded is the user's data: the file is finished with the frames before.
                        stopped = (f"{out}: {writer.stopped}: recording stopped; the {writer.frames} frames "
                                   "received before are kept")
                        clock.forget_last()
                        break
        finally:
            receiver.close()
            if writer is not None:
                writer.npz_arrays = {"received_frames": clock.table_array(),
                                     "received_frames_columns": np.array(RECORDING_TABLE_COLUMNS),
                                     "session_source": np.array(clock.sessions, dtype=str)}
    report = receiver.report
    print_status(status_line(report, receiver.assembler, time.monotonic() - stop.start))
    cpu = report.cpu_seconds / report.frames * 1e3 if report.frames else 0.0
    sessions = len(clock.sessions)
    restarts = (f"; {sessions} sender sessions (new senders {sessions - 1 - clock.restarts}, restarts "
                f"{clock.restarts})" if sessions > 1 else "")
    dropped = drops_text(receiver.assembler.drops)
    print(f"received {report.frames} frames, {report.points:,} points{restarts}" + (f"; {dropped}" if dropped else "")
          + f"; receiver CPU {cpu:.2f} ms per frame" + (f"; recorded to {out}" if writer is not None else ""))
    if stopped:
        print(f"{PROG}: {stopped}", file=sys.stderr)
        return 1
    if signals.signum is None:
        return 0
    kept = f"; the recording {out} was kept ({report.frames} frames)" if writer is not None else ""
    print(f"{PROG}: stopped by {signal_name(signals.signum)}{kept}", file=sys.stderr)
    # Ctrl-C is how listening is meant to end (it says so); SIGTERM and SIGHUP give the shell's status.
    return 0 if signals.signum == signal.SIGINT else signal_status(signals.signum)


def _listen_arguments(parser: argparse.ArgumentParser) -> None:
    add_receiver_arguments(parser)
    parser.add_argument("--config", help="sensor JSON giving the range (int16 scale) and, by its TypeID, where the "
                                         "points are (23: world); either SDK's frames are taken; default the "
                                         "default preset")
    parser.add_argument("--seq-id", type=int, help="SeqID in a Config.json")
    parser.add_argument("--record", help="write the frames to .ply .pcd .las .npz or .csv")
    parser.add_argument("--frames", type=whole_number(1, 2**62, "a whole number >= 1"),
                        help="stop after this many frames")
    parser.add_argument("--seconds", type=positive_float, help="stop after this many wall seconds")
    parser.add_argument("--timeout", type=positive_float, help="stop after this many seconds without a frame")


# request -------------------------------------------------------------------------------------
def cmd_request(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    data = sensor_request(cfg)
    host, port = parse_host_port(args.to, REQUEST_PORT_BASE + args.window)
    if args.dry_run:
        print(f"sensor request for {config_label(args)} ({len(data)} bytes) to {host}:{port}:")
        print(data.hex())
        return 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        # RflySim on another machine of the LAN may be asked through its broadcast address.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        try:
            sock.sendto(data, (host, port))
        except OSError as exc:
            raise UsageError(f"cannot send to {host}:{port} ({exc.strerror or exc})") from None
    print(f"sent the {len(data)}-byte sensor request of {config_label(args)} to {host}:{port}")
    return 0


def _request_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("--to", required=True, help="HOST[:PORT]; the port defaults to 20010 + --window")
    parser.add_argument("--window", type=whole_number(0, 65535 - REQUEST_PORT_BASE), default=0,
                        help="RflySim window index (default 0)")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the request (92 bytes, or 144 for a configuration with EularOrQuat) in hex "
                             "instead of sending")


COMMANDS: tuple[Command, ...] = (
    Command("publish", cmd_publish, "stand in for RflySim's Livox sensor: send scan frames live",
            "livox-viz publish --to 127.0.0.1:9999 --seconds 10 --speed 1", _publish_arguments),
    Command("listen", cmd_listen, "receive RflySim Livox frames, report them, record them",
            "livox-viz listen --port 9999 --record received.npz", _listen_arguments),
    Command("request", cmd_request, "ask a running RflySim for this sensor (<16H15f, or <16H28f with EularOrQuat)",
            "livox-viz request --to 127.0.0.1 --dry-run", _request_arguments),
)
