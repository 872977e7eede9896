"""Sending and receiving live frames: UDP sockets and shared memory around :mod:`livox_viz.wire.rflysim`.

A sender writes what the configuration's SDK receives (:class:`~livox_viz.wire.rflysim.WireFormat`); a receiver
takes both SDKs' frames (either datagram header, three or four int16 a point)."""

from __future__ import annotations

import errno
import mmap
import socket
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from livox_viz.casting.codec import encode_int16
from livox_viz.casting.scan import ScanFrame
from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.wire.rflysim import (
    LivoxFrame,
    Reassembler,
    SharedMemoryLink,
    WireFormat,
    frame_problem,
    open_named_mapping,
    open_shared_block,
    pack_payload,
    shm_name,
    shm_path,
    shm_size,
    split_datagrams,
    unpack_payload,
)


@dataclass
class PublishReport:
    """What a publisher did."""

    frames: int = 0
    points: int = 0
    datagrams: int = 0
    send_errors: int = 0
    wall_seconds: float = 0.0
    scan_seconds: float = 0.0
    #: Frames that were not ready (or not sent) by their time: each left when it could, the next ones at their own
    #: intervals from it, never in a burst.
    late_frames: int = 0
    #: Seconds those frames were late, in all.
    late_seconds: float = 0.0

    @property
    def speed(self) -> float:
        """Scan seconds published per wall second."""
        return self.scan_seconds / self.wall_seconds if self.wall_seconds > 0 else float("inf")


def wire_points(frame: ScanFrame, wire: WireFormat) -> np.ndarray:
    """``(K, channels)`` int16 what the wire carries of a frame: one point per ray (each pulse's first return).

    In the sensor frame (the frame's own int16), or for the v3 Mid-360 in the world NED frame, encoded with the
    same scale; a world point beyond the range in any axis cannot be encoded and is left out (RflySim's points
    are scaled by otherParams[0] whatever the frame). The fourth value of a v3 point is 0: RflySim documents
    nothing for it.
    """
    if wire.world_points:
        first = frame.return_number == 1
        world = frame.xyz_world[first]
        fits = np.all(np.abs(world) <= frame.range_max, axis=1)
        points = encode_int16(world[fits], frame.range_max)
    else:
        points = frame.wire_xyz_int16
    if wire.channels == 3:
        return points
    out = np.zeros((points.shape[0], 4), dtype=np.int16)
    out[:, :3] = points
    return out


class UdpSender:
    """Sends frames as RflySim datagrams to one address; send errors are counted, not fatal.

    Parameters
    ----------
    host : str
    port : int
    wire : WireFormat
        What the frames look like: v2's (three int16 a point, the old header) by default.
    """

    def __init__(self, host: str, port: int, wire: WireFormat | None = None) -> None:
        self.wire = wire or WireFormat()
        try:
            infos = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
        except socket.gaierror as exc:
            raise LivoxVizError(f"cannot resolve {quoted(host)}: {exc.strerror}") from None
        self.address = infos[0][4]
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 8 << 20)
        # A LAN's broadcast address (every listener on the network) is refused without it: "Permission denied".
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        self.errors = 0
        self.last_error = ""

    def send(self, timestamp: float, pos_ang: np.ndarray, points_int16: np.ndarray, frame_id: int = 0) -> int:
        """Send one frame (``(M, channels)`` int16, chunk 0 first; ``frame_id`` in the new header); returns the
        datagrams sent."""
        sent = 0
        ids = frame_id if self.wire.frame_ids else None
        for datagram in split_datagrams(pack_payload(pos_ang, points_int16), timestamp, frame_id=ids):
            try:
                self.socket.sendto(datagram, self.address)
                sent += 1
            except OSError as exc:
                self.errors += 1
                self.last_error = exc.strerror or str(exc)
        return sent

    def close(self) -> None:
        self.socket.close()


class ShmSender:
    """Writes frames into RflySim's shared-memory block for a configuration.

    A reader copying the previous frame (flag 3) is waited for, up to ``patience`` seconds, before the frame is
    dropped: its copy takes a fraction of a millisecond, but a reader the system has just descheduled mid-copy
    held the block for a frame's interval on a busy machine, and the frame was lost at once.

    Parameters
    ----------
    config : SensorConfig
    folder : str, optional
        Where the block's file lives (default /dev/shm; Windows has a named mapping instead).
    patience : float
        Seconds a frame waits for a reader to finish its copy, at most.
    """

    #: How long each wait for a reader lasts, seconds.
    POLL_SECONDS = 0.0005

    def __init__(self, config: SensorConfig, folder: str | None = None, patience: float = 0.05) -> None:
        self.wire = WireFormat.of(config)
        size = shm_size(config)
        block, name = open_shared_block(config.seq_id, size, folder, create=True)
        self.link = SharedMemoryLink(None, size, channels=self.wire.channels, block=block, name=name)
        self.patience = patience
        self.errors = 0
        self.last_error = ""

    def send(self, timestamp: float, pos_ang: np.ndarray, points_int16: np.ndarray, frame_id: int = 0) -> int:
        """Write one frame (``(M, channels)`` int16; shared memory has no frame id); 1 when written."""
        deadline = time.monotonic() + self.patience
        while not self.link.write(timestamp, pos_ang, points_int16):
            if time.monotonic() >= deadline:
                self.errors += 1
                self.last_error = f"the reader still held the previous frame after {self.patience * 1e3:.0f} ms"
                return 0
            time.sleep(self.POLL_SECONDS)
        return 1

    def close(self) -> None:
        self.link.close()


def publish(frames: Iterable[ScanFrame], sender: UdpSender | ShmSender, speed: float | None,
            on_progress: Callable[[PublishReport], None] | None = None,
            stop: Callable[[], bool] | None = None, *,
            clock: Callable[[], float] = time.monotonic,
            sleep: Callable[[float], None] = time.sleep) -> PublishReport:
    """Send each frame at its scan time divided by ``speed`` (None: as fast as possible).

    Pacing is against the clock (frame k is due at start + t_k / speed), so
    sleeping never accumulates drift. A frame late by more than half its
    interval (the first one compiled the scan's loops; a machine that cannot
    keep up) leaves at once and the schedule starts again from it: the next
    frames leave at their own intervals, as the sensor sends them, where they
    all went at once before (the first five within 16 ms, of which RflySim's
    own client, keeping the latest frame, showed two). The report counts
    them. ``stop()`` true ends publishing before the next frame (``frames``
    may be endless). ``clock`` (seconds) and ``sleep`` are the wall clock's,
    replaceable so that a test can check the schedule.
    """
    report = PublishReport()
    start = clock()
    anchor_wall, anchor_scan = start, 0.0  # the schedule: scan time t is due at anchor_wall + (t - anchor_scan) / speed
    previous = 0.0

    def wait_until(due: float) -> None:
        # In steps of at most 0.1 s, so that a stop request is seen while waiting.
        while (delay := due - clock()) > 0 and not (stop is not None and stop()):
            sleep(min(delay, 0.1))

    for frame in frames:
        if speed is not None:
            due = anchor_wall + (frame.timestamp - anchor_scan) / speed
            late = clock() - due
            if late > max(0.5 * (frame.timestamp - previous) / speed, 1e-3):
                report.late_frames += 1
                report.late_seconds += late
                anchor_wall, anchor_scan = clock(), frame.timestamp
            else:
                wait_until(due)
            previous = frame.timestamp
        if stop is not None and stop():
            break
        points = wire_points(frame, sender.wire)
        report.datagrams += sender.send(frame.timestamp, frame.sensor_pose.as_array(), points, frame.index)
        report.frames += 1
        report.points += len(points)
        report.scan_seconds = frame.end_time
        if on_progress is not None:
            on_progress(report)
    if speed is not None and report.frames:
        # The last frame lasts until its end time too: a real-time run of 0.5 s of scan takes 0.5 s (it reported
        # 1.1-1.25 x real time, its wall time ending as the last frame began).
        wait_until(anchor_wall + (report.scan_seconds - anchor_scan) / speed)
    report.send_errors = sender.errors
    report.wall_seconds = clock() - start
    return report


@dataclass
class ListenReport:
    """What a receiver saw."""

    frames: int = 0
    points: int = 0
    datagrams: int = 0
    bad_payloads: int = 0
    cpu_seconds: float = 0.0


class UdpReceiver:
    """Binds a UDP port and yields complete frames, of either SDK.

    Parameters
    ----------
    host, port : str, int
    points_frame : {"sensor", "world"}
        Where the points that arrive are (the v3 Mid-360 sends world points; the wire does not say).
    """

    def __init__(self, host: str, port: int, points_frame: str = "sensor") -> None:
        self.points_frame = points_frame
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 << 20)
        try:
            self.socket.bind((host, port))
        except OSError as exc:
            self.socket.close()
            if exc.errno == errno.EADDRINUSE:
                raise LivoxVizError(f"port {port} on {host} is in use by another program") from None
            if exc.errno == errno.EACCES:
                # The address is fine (it named the address as the fault): the system refuses the port to this user.
                raise LivoxVizError(f"cannot listen on {host}:{port} ({exc.strerror}): ports below 1024 need "
                                    "administrator rights (on Windows, a port held exclusively or reserved is "
                                    "refused too); allowed: a port from 1024 to 65535, or 0 for any free one"
                                    ) from None
            # RflySim sends over IPv4: an IPv6 address, a name without an IPv4 address or another machine's
            # address cannot be bound.
            raise LivoxVizError(f"cannot listen on {host}:{port} ({exc.strerror}); allowed: an IPv4 address of "
                                "this machine, a name that has one, or 0.0.0.0 for all") from None
        self.socket.settimeout(0.2)
        #: The port bound (the one the system chose when asked for port 0).
        self.port = int(self.socket.getsockname()[1])
        self.assembler = Reassembler()
        self.report = ListenReport()

    def frames(self, stop: Callable[[], bool]) -> Iterable[LivoxFrame]:
        """Complete, well-formed frames until ``stop()`` is true, each reassembled from its own sender."""
        buffer = bytearray(65536)
        while not stop():
            try:
                size, address = self.socket.recvfrom_into(buffer)
            except (TimeoutError, BlockingIOError):
                continue
            cpu = time.process_time()
            self.report.datagrams += 1
            done = self.assembler.feed(bytes(buffer[:size]), address)
            self.report.bad_payloads = self.assembler.drops["bad payload"]
            ready: list[LivoxFrame] = []
            while done is not None:  # one datagram may free frames that waited for the one it completed
                sender = self.assembler.source
                frame = None
                try:
                    frame = unpack_payload(done[1], done[0], f"{sender[0]}:{sender[1]}", self.assembler.frame_id,
                                           self.points_frame)
                except LivoxVizError as exc:  # (the reassembler drops most bad payloads itself)
                    self.assembler.drops["bad payload"] += 1
                    self.assembler.last_error = str(exc)
                frame = _usable(frame, self.assembler)
                if frame is not None:
                    ready.append(frame)
                done = self.assembler.next_ready()
            self.report.cpu_seconds += time.process_time() - cpu
            for frame in ready:
                self.report.frames += 1
                self.report.points += frame.xyz_int16.shape[0]
                yield frame

    def poll(self, max_datagrams: int = 100_000) -> list[LivoxFrame]:
        """Every complete frame that has arrived, without waiting."""
        frames: list[LivoxFrame] = []
        self.socket.setblocking(False)
        try:
            for frame in self.frames(_UntilEmpty(self.socket, max_datagrams)):
                frames.append(frame)
        finally:
            self.socket.settimeout(0.2)
        return frames

    def close(self) -> None:
        self.socket.close()


class _UntilEmpty:
    """A stop test for :meth:`UdpReceiver.frames` that ends when no datagram is waiting (or after ``limit``)."""

    def __init__(self, sock: socket.socket, limit: int) -> None:
        self.socket = sock
        self.limit = limit
        self.seen = 0

    def __call__(self) -> bool:
        import select

        self.seen += 1
        if self.seen > self.limit:
            return True
        ready, _, _ = select.select([self.socket], [], [], 0)
        return not ready


def _usable(frame: LivoxFrame | None, assembler: Reassembler) -> LivoxFrame | None:
    """The frame, or None (dropped and counted) when its pose or time is not finite."""
    problem = frame_problem(frame) if frame is not None else None
    if problem is None:
        return frame
    assembler.drops[problem] += 1
    assembler.last_error = f"{problem} (t = {frame.timestamp:.6g} s, posAng {np.round(frame.pos_ang, 3).tolist()})"
    return None


class ShmReceiver:
    """Polls RflySim's shared-memory block and yields new frames.

    The block may not exist yet: a listener started before its publisher waits for its file (as one on UDP waits
    for datagrams), opening it once the publisher has made it at this configuration's size. On Windows the block
    is RflySim's named mapping ``RflySim3DImg_<SeqID>``, opened (or made, empty) at once, as RflySim's client does.
    """

    def __init__(self, config: SensorConfig, folder: str | None = None) -> None:
        self.wire = WireFormat.of(config)
        self.size = shm_size(config)
        self.link: SharedMemoryLink | None = None
        self.report = ListenReport()
        self.assembler = Reassembler()
        self.seq_id = config.seq_id
        if sys.platform == "win32":
            self.path = Path(shm_name(config.seq_id))
            self._attach(open_named_mapping(shm_name(config.seq_id), self.size), shm_name(config.seq_id))
            return
        self.path = shm_path(config.seq_id, folder)
        if not self.path.parent.is_dir():
            raise LivoxVizError(f"{self.path.parent}: no such folder; allowed: the shared memory folder (/dev/shm)")
        self._opened()

    def _attach(self, block: mmap.mmap, name: str) -> None:
        self.link = SharedMemoryLink(None, self.size, channels=self.wire.channels, block=block, name=name,
                                     points_frame="world" if self.wire.world_points else "sensor")

    def _opened(self) -> bool:
        """Whether the block is open, opening it if its file has appeared at its full size."""
        if self.link is None and self.path.exists():
            try:
                block, name = open_shared_block(self.seq_id, self.size, self.path.parent)
                self._attach(block, name)
            except LivoxVizError as exc:  # being made (not its size yet), or another configuration's
                self.assembler.last_error = f"{exc} (is --config the sender's?)"
        return self.link is not None

    def _read(self) -> LivoxFrame | None:
        if not self._opened():
            return None
        try:
            frame = self.link.read()
        except LivoxVizError as exc:
            self.assembler.drops["bad payload"] += 1
            self.assembler.last_error = str(exc)
            return None
        frame = _usable(frame, self.assembler)
        if frame is not None:
            self.report.frames += 1
            self.report.points += frame.xyz_int16.shape[0]
        return frame

    def frames(self, stop: Callable[[], bool]) -> Iterable[LivoxFrame]:
        while not stop():
            frame = self._read()
            if frame is None:
                time.sleep(0.001 if self.link is not None else 0.05)
                continue
            yield frame

    def poll(self, max_datagrams: int = 1) -> list[LivoxFrame]:
        """The frame waiting in the block, if any, without waiting."""
        frame = self._read()
        return [] if frame is None else [frame]

    def close(self) -> None:
        if self.link is not None:
            self.link.close()


def status_line(report: ListenReport, assembler: Reassembler, elapsed: float) -> str:
    """``12.0 frames/s, 7400 points/frame, drops 0`` and the last reason, for the live line."""
    rate = report.frames / elapsed if elapsed > 0 else 0.0
    per_frame = report.points / report.frames if report.frames else 0.0
    drops = sum(assembler.drops.values())
    senders = f", senders {assembler.senders}" if assembler.senders > 1 else ""
    restarts = f", sender restarts {assembler.restarts}" if assembler.restarts else ""
    reason = f" (last: {assembler.last_error})" if drops or assembler.restarts else ""
    return (f"{report.frames} frames, {rate:5.1f} frames/s, {per_frame:8.0f} points/frame, drops {drops}"
            f"{senders}{restarts}{reason}")


def drops_text(drops: Counter[str]) -> str:
    """``2 dropped (posAng not finite 2)``, or "" when nothing was dropped (for the final summary)."""
    total = sum(drops.values())
    if not total:
        return ""
    return f"{total} dropped ({', '.join(f'{reason} {count}' for reason, count in drops.most_common())})"


def print_status(text: str) -> None:
    """Rewrite the live line on a terminal; print it plainly otherwise."""
    if sys.stderr.isatty():
        sys.stderr.write("\r" + text[:160].ljust(100))
    else:
        sys.stderr.write(text + "\n")
    sys.stderr.flush()
