"""RflySim's wire formats for the Livox sensor (scan-model.md section 6), as pure functions.

* Frame payload: ``float32 posAng[6]`` (sensor pose in the world: x, y, z
  metres NED, roll, pitch, yaw radians), ``int32 PointNum``, then
  ``int16 xyz[PointNum*3]`` point-major, in the sensor frame.
* UDP: the payload cut into chunks of at most 60000 bytes, each datagram a
  ``<4i1d`` header (checksum 1234567890, datagram length with the header,
  chunk index, chunk count, timestamp) and its chunk; chunk 0 first.
* Shared memory (``/dev/shm/RflySim3DImg_<SeqID>``): flag byte, float64
  timestamp, posAng, PointNum, points.
* The sensor request a client sends to port 20010 + window index:
  ``<16H15f``, checksum 12345.

Everything here is independent of sockets, so it is tested byte for byte.
"""

from __future__ import annotations

import math
import mmap
import os
import struct
from collections import Counter, OrderedDict, deque
from collections.abc import Hashable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from livox_viz.casting.codec import decode_int16
from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError

FRAME_CHECKSUM = 1234567890
REQUEST_CHECKSUM = 12345
REQUEST_PORT_BASE = 20010
MAX_CHUNK = 60000
DATAGRAM_HEADER = struct.Struct("<4i1d")
PAYLOAD_HEADER = struct.Struct("<6fi")
REQUEST = struct.Struct("<16H15f")
SHM_FLAG_WRITTEN, SHM_FLAG_READING, SHM_FLAG_DONE = 2, 3, 4
SHM_HEADER = struct.Struct("<Bd6fi")


@dataclass(frozen=True)
class LivoxFrame:
    """One decoded frame as RflySim sends it.

    Parameters
    ----------
    timestamp : float
        Seconds since the scan start.
    pos_ang : (6,) float64
        Sensor pose: x, y, z (m, NED), roll, pitch, yaw (rad), as float32 on the wire.
    xyz_int16 : (M, 3) int16
        The points as published, sensor frame.
    source : str
        Who sent it: ``HOST:PORT`` of a UDP sender, the block's path for shared memory ("" when unknown).
    """

    timestamp: float
    pos_ang: np.ndarray
    xyz_int16: np.ndarray
    source: str = ""

    def decoded(self, range_max: float) -> np.ndarray:
        """``(M, 3)`` float64 metres in the sensor frame."""
        return decode_int16(self.xyz_int16, range_max)


# Frame payload ---------------------------------------------------------------------------
def pack_payload(pos_ang: np.ndarray, xyz_int16: np.ndarray) -> bytes:
    """The frame payload: ``<6f`` posAng, ``<i`` PointNum, ``<h`` points.

    Parameters
    ----------
    pos_ang : (6,) float
    xyz_int16 : (M, 3) int16
    """
    points = np.ascontiguousarray(xyz_int16, dtype="<i2")
    if points.ndim != 2 or points.shape[1] != 3:
        raise LivoxVizError(f"points have shape {points.shape}; allowed: (M, 3)")
    pose = np.asarray(pos_ang, dtype=np.float64).ravel()
    if pose.size != 6:
        raise LivoxVizError(f"posAng has {pose.size} values; allowed: 6")
    return PAYLOAD_HEADER.pack(*pose.tolist(), points.shape[0]) + points.tobytes()


def unpack_payload(payload: bytes, timestamp: float, source: str = "") -> LivoxFrame:
    """Read a frame payload (``timestamp``: its datagrams' header time, seconds); raises :class:`LivoxVizError`
    if it is short or its PointNum lies."""
    if len(payload) < PAYLOAD_HEADER.size:
        raise LivoxVizError(f"payload of {len(payload)} bytes; allowed: at least {PAYLOAD_HEADER.size}")
    *pose, count = PAYLOAD_HEADER.unpack_from(payload, 0)
    available = (len(payload) - PAYLOAD_HEADER.size) // 6
    if count < 0 or count > available:
        raise LivoxVizError(f"PointNum {count} but the payload holds {available} points")
    points = np.frombuffer(payload, dtype="<i2", count=count * 3, offset=PAYLOAD_HEADER.size).reshape(count, 3)
    return LivoxFrame(timestamp, np.array(pose, dtype=np.float64), points.astype(np.int16), source)


# UDP datagrams ---------------------------------------------------------------------------
def split_datagrams(payload: bytes, timestamp: float, max_chunk: int = MAX_CHUNK) -> list[bytes]:
    """Cut a payload into datagrams with the ``<4i1d`` header, chunk 0 first.

    Parameters
    ----------
    payload : bytes
    timestamp : float
        Seconds since the scan start, the same on every chunk of the frame.
    max_chunk : int
        Largest chunk, bytes (RflySim uses 60000).
    """
    if not 1 <= max_chunk <= MAX_CHUNK:
        raise LivoxVizError(f"chunk size {max_chunk}; allowed: 1 to {MAX_CHUNK}")
    count = max(1, math.ceil(len(payload) / max_chunk))
    datagrams = []
    for index in range(count):
        chunk = payload[index * max_chunk : (index + 1) * max_chunk]
        header = DATAGRAM_HEADER.pack(FRAME_CHECKSUM, DATAGRAM_HEADER.size + len(chunk), index, count, timestamp)
        datagrams.append(header + chunk)
    return datagrams


@dataclass
class _PendingFrame:
    count: int
    arrival: int
    chunks: dict[int, bytes] = field(default_factory=dict)
    size: int = 0


@dataclass
class _SenderState:
    """What the reassembler remembers of one source address."""

    newest_done: float = -math.inf
    last_delivered: tuple[float, int] | None = None
    #: Complete frames waiting for one the sender began before them, (arrival, timestamp, payload) in arrival order.
    held: list[tuple[int, float, bytes]] = field(default_factory=list)


class Reassembler:
    """Puts datagrams back into frames, in any order; drops what is broken, incomplete or a duplicate.

    Frames are reassembled per source address: two senders that stamp the
    same time (two simulators started together, or a publisher beside RflySim)
    give two frames, never one mixed from both.

    Memory is bounded: at most ``max_pending`` frames wait for chunks at once
    (the one heard from least recently makes room), each holding up to
    ``reorder_frames`` complete later frames of its sender, a frame may claim at
    most ``max_frame_bytes``, and at most ``max_sources`` senders are
    remembered; garbage never grows it.

    Frames come out in the order their senders began them: a frame complete
    while one its sender began before is still missing chunks (datagrams
    reordered across the two frames' boundary) waits for it, and the older one
    is given up as incomplete once ``reorder_frames`` later frames of that
    sender are complete. A lost chunk thus delays the frames after it by up to
    ``reorder_frames`` frames; in-order frames are never held.

    It never goes deaf: a sender's timestamps may go back (a restarted
    publisher or RflySim, or one absurd timestamp before them). A frame that
    goes back in time against its own sender's last one is delivered and
    counted in :attr:`restarts`. What is refused is a late chunk of a frame
    recently given up as incomplete, and a frame identical to the one its
    sender delivered just before it (a duplicate).

    Parameters
    ----------
    max_frame_bytes : int
        Largest payload accepted (default 64 MiB, ample for 10 million points).
    max_pending : int
        Frames (source and timestamp) waiting for chunks at once.
    max_chunks : int, optional
        Largest chunk count accepted; default what ``max_frame_bytes`` needs.
    max_sources : int
        Senders whose last frame is remembered (for restarts and duplicates); the least recent is forgotten.
    reorder_frames : int
        Complete frames of a sender that wait for an older one of its frames before that one is given up.

    Attributes
    ----------
    drops : collections.Counter
        Dropped datagrams or frames by reason.
    frames : int
        Complete frames returned.
    restarts : int
        Times a sender's timestamps went back (a restarted sender or clock).
    senders : int
        Source addresses heard from (one forgotten and heard again counts again).
    last_error : str
        The last drop's reason or restart, for the status line.
    source : Hashable
        The sender of the frame :meth:`feed` or :meth:`next_ready` returned last.
    """

    _REMEMBERED = 16

    def __init__(self, max_frame_bytes: int = 64 << 20, max_pending: int = 4, max_chunks: int | None = None,
                 max_sources: int = 256, reorder_frames: int = 2) -> None:
        self.max_frame_bytes = max_frame_bytes
        self.max_chunks = max_chunks or math.ceil(max_frame_bytes / MAX_CHUNK)
        self.max_pending = max_pending
        self.max_sources = max_sources
        self.reorder_frames = reorder_frames
        self.source: Hashable = None
        self._ready: deque[tuple[Hashable, float, bytes]] = deque()
        self.drops: Counter[str] = Counter()
        self.frames = 0
        self.restarts = 0
        self.senders = 0
        self._pending: dict[tuple[Hashable, float], _PendingFrame] = {}
        self._given_up: deque[tuple[Hashable, float]] = deque(maxlen=self._REMEMBERED)
        self._senders: OrderedDict[Hashable, _SenderState] = OrderedDict()
        self._arrivals = 0
        self.last_error = ""

    def _drop(self, reason: str) -> None:
        self.drops[reason] += 1
        self.last_error = reason

    def _give_up(self, key: tuple[Hashable, float]) -> None:
        del self._pending[key]
        self._given_up.append(key)
        self._drop("incomplete frame")
        self._release(key[0])

    def _release(self, source: Hashable) -> None:
        """The sender's held frames that no longer wait for an older frame of it, delivered in order."""
        state = self._senders.get(source)
        while state is not None and state.held:
            arrival = state.held[0][0]
            if any(key[0] == source and frame.arrival < arrival for key, frame in self._pending.items()):
                return
            _, timestamp, payload = state.held.pop(0)
            self._deliver(source, state, timestamp, payload)

    def _deliver(self, source: Hashable, sender: _SenderState, timestamp: float, payload: bytes) -> None:
        fingerprint = (timestamp, hash(payload))
        if fingerprint == sender.last_delivered:
            self._drop("duplicate frame")
            return
        sender.last_delivered = fingerprint
        if timestamp < sender.newest_done:
            self.restarts += 1
            self.last_error = (f"timestamps went back from {sender.newest_done:.6g} s to {timestamp:.6g} s: "
                               "a restarted sender or clock")
        sender.newest_done = timestamp
        self.frames += 1
        self._ready.append((source, timestamp, payload))

    def next_ready(self) -> tuple[float, bytes] | None:
        """Another frame the last datagram made ready (one completed may free frames that waited for it), or
        None; its sender in :attr:`source`."""
        if not self._ready:
            return None
        self.source, timestamp, payload = self._ready.popleft()
        return timestamp, payload

    def _sender(self, source: Hashable) -> _SenderState:
        state = self._senders.get(source)
        if state is None:
            state = self._senders[source] = _SenderState()
            self.senders += 1
            if len(self._senders) > self.max_sources:
                self._senders.popitem(last=False)
        self._senders.move_to_end(source)
        return state

    def feed(self, datagram: bytes, source: Hashable = None) -> tuple[float, bytes] | None:
        """Take one datagram from ``source`` (e.g. the sender's address); returns ``(timestamp, payload)`` of a
        frame it made ready (its sender in :attr:`source`; more with :meth:`next_ready`), or None."""
        self._take(datagram, source)
        return self.next_ready()

    def _take(self, datagram: bytes, source: Hashable) -> None:
        """:meth:`feed`'s work: the frames it makes ready go to the queue :meth:`next_ready` takes."""
        if len(datagram) < DATAGRAM_HEADER.size:
            self._drop("truncated header")
            return
        checksum, length, index, count, timestamp = DATAGRAM_HEADER.unpack_from(datagram, 0)
        if checksum != FRAME_CHECKSUM:
            self._drop("wrong checksum")
            return
        if length != len(datagram):
            self._drop("length field does not match the datagram")
            return
        if not 1 <= count <= self.max_chunks:
            self._drop("chunk count out of range")
            return
        if not 0 <= index < count:
            self._drop("chunk index out of range")
            return
        if not math.isfinite(timestamp):
            self._drop("timestamp not finite")
            return
        key = (source, timestamp)
        if key in self._given_up:
            self._drop("stale chunk")
            return
        frame = self._pending.get(key)
        if frame is None:
            if len(self._pending) >= self.max_pending:
                self._give_up(min(self._pending, key=lambda k: self._pending[k].arrival))
            self._arrivals += 1
            frame = self._pending[key] = _PendingFrame(count, self._arrivals)
        if frame.count != count:
            self._drop("chunk count differs within a frame")
            return
        chunk = datagram[DATAGRAM_HEADER.size :]
        if index in frame.chunks:
            self._drop("duplicate chunk")
            return
        if frame.size + len(chunk) > self.max_frame_bytes:
            del self._pending[key]
            self._given_up.append(key)
            self._drop("frame too large")
            self._release(source)
            return
        frame.chunks[index] = chunk
        frame.size += len(chunk)
        if len(frame.chunks) < count:
            return
        del self._pending[key]
        sender = self._sender(source)
        sender.held.append((frame.arrival, timestamp, b"".join(frame.chunks[i] for i in range(count))))
        sender.held.sort(key=lambda held: held[0])
        self._release(source)
        # Frames the sender began before the held ones, still incomplete after reorder_frames later ones: lost.
        while len(sender.held) > self.reorder_frames:
            first = sender.held[0][0]
            self._give_up(min((k for k, f in self._pending.items() if k[0] == source and f.arrival < first),
                              key=lambda k: self._pending[k].arrival))

    @property
    def pending_bytes(self) -> int:
        """Bytes held for frames not complete yet, and complete ones waiting for an older frame."""
        return (sum(frame.size for frame in self._pending.values())
                + sum(len(held[2]) for state in self._senders.values() for held in state.held))


#: The largest timestamp a frame may carry, seconds (317 years; a Unix time is 1.7e9): a recording's clock runs on
#: from a sender's times, and one frame stamped 1e300 left every later frame of it at 2e300.
MAX_TIMESTAMP_S = 1e10


def frame_problem(frame: LivoxFrame) -> str | None:
    """Why a well-formed frame cannot be used (a NaN or infinite posAng or timestamp, a timestamp beyond
    :data:`MAX_TIMESTAMP_S`), or None.

    Such a frame has no place in the world; a client drops it and counts it under this reason.
    """
    if not math.isfinite(frame.timestamp):
        return "timestamp not finite"
    if abs(frame.timestamp) > MAX_TIMESTAMP_S:
        return f"timestamp beyond {MAX_TIMESTAMP_S:g} s"
    if not np.all(np.isfinite(frame.pos_ang)):
        return "posAng not finite"
    return None


# Sensor request and SendProtocol ------------------------------------------------------------
def sensor_request(config: SensorConfig) -> bytes:
    """The 92-byte ``<16H15f`` request that asks RflySim for this sensor."""
    ints = [REQUEST_CHECKSUM, config.seq_id, config.type_id, config.target_copter, config.target_mount_type,
            config.data_width, config.data_height, config.data_check_freq, *config.send_protocol]
    for name, value in zip(("SeqID", "TypeID", "TargetCopter", "TargetMountType", "DataWidth", "DataHeight",
                            "DataCheckFreq"), ints[1:8], strict=True):
        if not 0 <= value <= 0xFFFF:
            raise LivoxVizError(f"{name} = {value} does not fit the request's uint16; allowed: 0 to 65535")
    if not all(0 <= v <= 0xFFFF for v in config.send_protocol):
        raise LivoxVizError(f"SendProtocol {list(config.send_protocol)} does not fit uint16 values")
    floats = [config.camera_fov, *config.sensor_pos_xyz, *config.sensor_ang_euler, *config.other_params]
    return REQUEST.pack(*ints, *floats)


@dataclass(frozen=True)
class Destination:
    """Where a configuration's frames go (from ``SendProtocol``).

    Parameters
    ----------
    transport : {"udp", "shm"}
    host : str
    port : int
    """

    transport: str
    host: str
    port: int


def send_protocol_destination(config: SensorConfig) -> Destination:
    """Decode ``SendProtocol``: [0] 1 = UDP / 0 = shared memory, [1..4] IPv4 bytes, [5] port."""
    protocol = config.send_protocol
    if any(not 0 <= b <= 255 for b in protocol[1:5]):
        raise LivoxVizError(f"SendProtocol[1..4] = {list(protocol[1:5])}; allowed: IPv4 bytes 0-255")
    if not 0 <= protocol[5] <= 65535:
        raise LivoxVizError(f"SendProtocol[5] = {protocol[5]}; allowed: a port 0-65535")
    transport = "udp" if protocol[0] == 1 else "shm"
    return Destination(transport, ".".join(str(b) for b in protocol[1:5]), int(protocol[5]))


def parse_host_port(text: str, default_port: int | None = None) -> tuple[str, int]:
    """``HOST:PORT`` (or ``HOST`` with a default port) -> (host, port)."""
    host, _, port_text = text.rpartition(":") if ":" in text else (text, "", "")
    if not host:
        raise LivoxVizError(f"address {text!r}; allowed: HOST:PORT, e.g. 127.0.0.1:9999")
    if not port_text:
        if default_port is None:
            raise LivoxVizError(f"address {text!r} has no port; allowed: HOST:PORT")
        return host, default_port
    try:
        port = int(port_text)
    except ValueError:
        raise LivoxVizError(f"port {port_text!r}; allowed: a number 1-65535") from None
    if not 1 <= port <= 65535:
        raise LivoxVizError(f"port {port}; allowed: 1-65535")
    return host, port


# Shared memory ---------------------------------------------------------------------------------
def shm_path(seq_id: int, folder: str | os.PathLike[str] = "/dev/shm") -> Path:
    """``/dev/shm/RflySim3DImg_<SeqID>``."""
    return Path(folder) / f"RflySim3DImg_{seq_id}"


def shm_size(config: SensorConfig) -> int:
    """Bytes of the shared-memory block: W*H*3*2 + 1 + 8 + 28."""
    return config.points_per_frame * 6 + SHM_HEADER.size


class SharedMemoryLink:
    """Either side of the ``/dev/shm/RflySim3DImg_<SeqID>`` handshake.

    The writer fills the block and sets the flag byte to 2 (frame written); it
    does not overwrite a block whose flag is 3 (a reader is reading). The
    reader takes a frame only when the flag is 2, sets 3 while it copies and 4
    when it is done.

    Parameters
    ----------
    path : path-like
        The block's file.
    size : int
        Its size in bytes (see :func:`shm_size`).
    create : bool
        Create (or resize) the file, as the writer does.
    """

    def __init__(self, path: str | os.PathLike[str], size: int, create: bool = False) -> None:
        self.path = Path(path)
        self.size = size
        flags = os.O_RDWR | (os.O_CREAT if create else 0)
        try:
            fd = os.open(self.path, flags, 0o666)
        except OSError as exc:
            raise LivoxVizError(f"{self.path}: cannot open the shared memory ({exc.strerror})") from None
        try:
            if create and os.fstat(fd).st_size != size:
                os.ftruncate(fd, size)
            if os.fstat(fd).st_size < size:
                raise LivoxVizError(f"{self.path}: {os.fstat(fd).st_size} bytes; expected {size}")
            self._map = mmap.mmap(fd, size)
        finally:
            os.close(fd)

    def write(self, timestamp: float, pos_ang: np.ndarray, xyz_int16: np.ndarray) -> bool:
        """Publish a frame; False (nothing written) while a reader holds the block."""
        if self._map[0] == SHM_FLAG_READING:
            return False
        points = np.ascontiguousarray(xyz_int16, dtype="<i2")
        if points.nbytes > self.size - SHM_HEADER.size:
            raise LivoxVizError(f"{points.shape[0]} points do not fit the block of {self.size} bytes")
        self._map[SHM_HEADER.size : SHM_HEADER.size + points.nbytes] = points.tobytes()
        pose = np.asarray(pos_ang, dtype=np.float64).tolist()
        self._map[1 : SHM_HEADER.size] = SHM_HEADER.pack(0, timestamp, *pose, points.shape[0])[1:]
        self._map[0] = SHM_FLAG_WRITTEN
        return True

    def read(self) -> LivoxFrame | None:
        """Take the frame if one is waiting (flag 2); None otherwise."""
        if self._map[0] != SHM_FLAG_WRITTEN:
            return None
        self._map[0] = SHM_FLAG_READING
        try:
            _, timestamp, *pose, count = SHM_HEADER.unpack_from(self._map, 0)
            capacity = (self.size - SHM_HEADER.size) // 6
            if not 0 <= count <= capacity:
                raise LivoxVizError(f"shared memory PointNum {count}; allowed: 0 to {capacity}, the block's size for "
                                    "this configuration's DataWidth x DataHeight (is --config the sender's?)")
            points = np.frombuffer(self._map, dtype="<i2", count=count * 3, offset=SHM_HEADER.size)
            frame = LivoxFrame(timestamp, np.array(pose), points.reshape(count, 3).astype(np.int16), str(self.path))
        finally:
            self._map[0] = SHM_FLAG_DONE
        return frame

    def close(self) -> None:
        """Unmap the block (the file stays, as RflySim's does)."""
        self._map.close()
