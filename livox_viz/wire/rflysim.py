"""RflySim's wire formats for the Livox sensor (scan-model.md section 6), as pure functions, in both SDKs.

* Frame payload: ``float32 posAng[6]`` (sensor pose in the world: x, y, z
  metres NED, roll, pitch, yaw radians), ``int32 PointNum``, then the points
  point-major: ``int16 xyz[PointNum*3]`` in SDK v2 (TypeID 6); four int16 a
  point in SDK v3 (TypeID 20-23: x, y, z and a fourth value RflySim's client
  scales like the others and its ROS publisher calls ``seg``; undocumented, so
  we send 0 there and keep what arrives). The points are in the sensor frame,
  except the v3 Mid-360's (TypeID 23), which RflySim's sensor page says are
  "mapped directly into the world frame": world NED, metres.
* UDP: the payload cut into chunks of at most 60000 bytes, each datagram a
  header and its chunk, chunk 0 first. The old header ``<4i1d`` (checksum
  1234567890, datagram length with the header, chunk index, chunk count,
  timestamp); the new ``<6i1d`` (checksum 1234567893, length, chunk index,
  chunk count, frame id, padding, timestamp). RflySim's v3 client takes both,
  its v2 client only the old.
* Shared memory (``RflySim3DImg_<SeqID>``: a file in ``/dev/shm`` on Linux, a
  named mapping on Windows, the same bytes): flag byte, float64 timestamp,
  posAng, PointNum, points (three or four int16 each).
* The sensor request a client sends to port 20010 + window index: checksum
  12345, ``<16H15f`` (92 bytes) for a configuration without ``EularOrQuat``,
  ``<16H28f`` (144 bytes) with it.

The layouts were read in public copies of RflySim's ``VisionCaptureApi.py``
(v2: childefuintheflowers/Multi-UAV-Target-Localization; v3:
Ding-Guo/RflySimVision ``sensor_pkg/VisionCaptureApi.py``). Everything here is
independent of sockets, so it is tested byte for byte.
"""

from __future__ import annotations

import math
import mmap
import os
import struct
import sys
import tempfile
from collections import Counter, OrderedDict, deque
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from livox_viz.casting.codec import decode_int16
from livox_viz.config.sensor import V3_MID360_TYPE_ID, SensorConfig
from livox_viz.core.errors import LivoxVizError, quoted

#: The old datagram header's checksum (``<4i1d``), and the new one's (``<6i1d``, with a frame id).
FRAME_CHECKSUM = 1234567890
FRAME_CHECKSUM_V3 = 1234567893
REQUEST_CHECKSUM = 12345
REQUEST_PORT_BASE = 20010
MAX_CHUNK = 60000
DATAGRAM_HEADER = struct.Struct("<4i1d")
DATAGRAM_HEADER_V3 = struct.Struct("<6i1d")
#: The datagram headers by checksum.
DATAGRAM_HEADERS = {FRAME_CHECKSUM: DATAGRAM_HEADER, FRAME_CHECKSUM_V3: DATAGRAM_HEADER_V3}
PAYLOAD_HEADER = struct.Struct("<6fi")
REQUEST = struct.Struct("<16H15f")
REQUEST_V3 = struct.Struct("<16H28f")
SHM_FLAG_WRITTEN, SHM_FLAG_READING, SHM_FLAG_DONE = 2, 3, 4
SHM_HEADER = struct.Struct("<Bd6fi")
#: The name of a configuration's shared-memory block (a file in /dev/shm on Linux, a named mapping on Windows).
SHM_NAME = "RflySim3DImg_{seq_id}"


@dataclass(frozen=True)
class WireFormat:
    """What a configuration's frames look like on RflySim's wire.

    Parameters
    ----------
    channels : {3, 4}
        int16 values a point: x, y, z (SDK v2), and a fourth (SDK v3).
    frame_ids : bool
        The new ``<6i1d`` datagram header with a frame id (SDK v3), or the old ``<4i1d``.
    world_points : bool
        Points in the world NED frame (the v3 Mid-360, TypeID 23) instead of the sensor frame.
    """

    channels: int = 3
    frame_ids: bool = False
    world_points: bool = False

    @classmethod
    def of(cls, config: SensorConfig) -> WireFormat:
        """The format of the configuration's SDK (its TypeID: 6 is v2's, 22 and 23 v3's)."""
        if config.sdk == "v2":
            return cls()
        return cls(4, True, config.type_id == V3_MID360_TYPE_ID)

    def describe(self) -> str:
        """``4 int16 a point, the <6i1d header, sensor frame``."""
        header = "<6i1d header (frame ids)" if self.frame_ids else "<4i1d header"
        return f"{self.channels} int16 a point, the {header}, {'world' if self.world_points else 'sensor'} frame"


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
        The points as published: sensor frame (world NED for ``points_frame`` "world").
    source : str
        Who sent it: ``HOST:PORT`` of a UDP sender, the block's path for shared memory ("" when unknown).
    channel4 : (M,) int16, optional
        A v3 frame's fourth value of each point, as sent (None for a frame of three values a point).
    frame_id : int, optional
        The frame id of the new ``<6i1d`` datagram header (None with the old header or shared memory).
    points_frame : {"sensor", "world"}
        Where the points are: the sensor frame, or the world (RflySim v3's Mid-360).
    """

    timestamp: float
    pos_ang: np.ndarray
    xyz_int16: np.ndarray
    source: str = ""
    channel4: np.ndarray | None = None
    frame_id: int | None = None
    points_frame: str = "sensor"

    def decoded(self, range_max: float) -> np.ndarray:
        """``(M, 3)`` float64 metres in :attr:`points_frame` (the sensor's, or the world's)."""
        return decode_int16(self.xyz_int16, range_max)

    @property
    def channels(self) -> int:
        """int16 values a point on the wire: 3, or 4 (a v3 frame)."""
        return 3 if self.channel4 is None else 4


# Frame payload ---------------------------------------------------------------------------
def pack_payload(pos_ang: np.ndarray, points_int16: np.ndarray) -> bytes:
    """The frame payload: ``<6f`` posAng, ``<i`` PointNum, ``<h`` points (three or four values each).

    Parameters
    ----------
    pos_ang : (6,) float
    points_int16 : (M, 3) or (M, 4) int16
        x, y, z (SDK v2), or x, y, z and the fourth value (SDK v3).
    """
    points = np.ascontiguousarray(points_int16, dtype="<i2")
    if points.ndim != 2 or points.shape[1] not in (3, 4):
        raise LivoxVizError(f"points have shape {points.shape}; allowed: (M, 3) or (M, 4)")
    pose = np.asarray(pos_ang, dtype=np.float64).ravel()
    if pose.size != 6:
        raise LivoxVizError(f"posAng has {pose.size} values; allowed: 6")
    return PAYLOAD_HEADER.pack(*pose.tolist(), points.shape[0]) + points.tobytes()


def payload_channels(size: int, count: int) -> int | None:
    """int16 values a point of a payload of ``size`` bytes holding ``count`` points: 3 or 4 when its length is
    exactly that of PointNum points of three or of four values, else None (its PointNum lies)."""
    body = size - PAYLOAD_HEADER.size
    if count < 0:
        return None
    if body == 6 * count:
        return 3
    if body == 8 * count:
        return 4
    return None


def unpack_payload(payload: bytes, timestamp: float, source: str = "", frame_id: int | None = None,
                   points_frame: str = "sensor") -> LivoxFrame:
    """Read a frame payload (``timestamp``: its datagrams' header time, seconds) of either SDK: three int16 a
    point (v2) or four (v3), told apart by the payload's length against its PointNum.

    Raises
    ------
    LivoxVizError
        If it is short, or its PointNum lies (the payload is neither PointNum points of three values nor of four).
    """
    if len(payload) < PAYLOAD_HEADER.size:
        raise LivoxVizError(f"payload of {len(payload)} bytes; allowed: at least {PAYLOAD_HEADER.size}")
    *pose, count = PAYLOAD_HEADER.unpack_from(payload, 0)
    channels = payload_channels(len(payload), count)
    if channels is None:
        body = len(payload) - PAYLOAD_HEADER.size
        raise LivoxVizError(f"PointNum {count} but the payload holds {body // 6} points of 3 int16 or {body // 8} "
                            f"of 4 ({body} bytes)")
    points = np.frombuffer(payload, dtype="<i2", count=count * channels, offset=PAYLOAD_HEADER.size)
    points = points.reshape(count, channels).astype(np.int16)
    channel4 = np.ascontiguousarray(points[:, 3]) if channels == 4 else None
    return LivoxFrame(timestamp, np.array(pose, dtype=np.float64), np.ascontiguousarray(points[:, :3]), source,
                      channel4, frame_id, points_frame)


# UDP datagrams ---------------------------------------------------------------------------
def split_datagrams(payload: bytes, timestamp: float, max_chunk: int = MAX_CHUNK,
                    frame_id: int | None = None) -> list[bytes]:
    """Cut a payload into datagrams, chunk 0 first: the old ``<4i1d`` header, or with a ``frame_id`` the new
    ``<6i1d`` one (checksum 1234567893, length, chunk index, chunk count, frame id, padding 0, timestamp).

    Parameters
    ----------
    payload : bytes
    timestamp : float
        Seconds since the scan start, the same on every chunk of the frame.
    max_chunk : int
        Largest chunk, bytes (RflySim uses 60000).
    frame_id : int, optional
        The frame's number (SDK v3), kept in int32's positive range (RflySim's client warns of a negative one).
    """
    if not 1 <= max_chunk <= MAX_CHUNK:
        raise LivoxVizError(f"chunk size {max_chunk}; allowed: 1 to {MAX_CHUNK}")
    count = max(1, math.ceil(len(payload) / max_chunk))
    header = DATAGRAM_HEADER if frame_id is None else DATAGRAM_HEADER_V3
    datagrams = []
    for index in range(count):
        chunk = payload[index * max_chunk : (index + 1) * max_chunk]
        length = header.size + len(chunk)
        if frame_id is None:
            head = header.pack(FRAME_CHECKSUM, length, index, count, timestamp)
        else:
            head = header.pack(FRAME_CHECKSUM_V3, length, index, count, frame_id % 2**31, 0, timestamp)
        datagrams.append(head + chunk)
    return datagrams


@dataclass
class _PendingFrame:
    count: int
    arrival: int
    frame_id: int | None = None
    chunks: dict[int, bytes] = field(default_factory=dict)
    size: int = 0


@dataclass
class _SenderState:
    """What the reassembler remembers of one source address."""

    newest_done: float = -math.inf
    last_delivered: tuple[float, int] | None = None
    #: Complete frames waiting for one the sender began before them, (arrival, timestamp, payload, frame id) in
    #: arrival order.
    held: list[tuple[int, float, bytes, int | None]] = field(default_factory=list)
    #: The frame id of its last frame delivered (the new header's), None before one or with the old header.
    last_id: int | None = None


class Reassembler:
    """Puts datagrams back into frames, in any order; drops what is broken, incomplete or a duplicate.

    Datagrams may carry either header, the old ``<4i1d`` or the new ``<6i1d``
    (SDK v3, with a frame id: kept in :attr:`frame_id`); anything else is a
    wrong checksum. Frames are reassembled per source address: two senders that stamp the
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
    frame_id : int or None
        Its frame id (the new header's), None with the old header.
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
        self.frame_id: int | None = None
        self._ready: deque[tuple[Hashable, float, bytes, int | None]] = deque()
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
            _, timestamp, payload, frame_id = state.held.pop(0)
            self._deliver(source, state, timestamp, payload, frame_id)

    def _deliver(self, source: Hashable, sender: _SenderState, timestamp: float, payload: bytes,
                 frame_id: int | None) -> None:
        fingerprint = (timestamp, hash(payload))
        if fingerprint == sender.last_delivered:
            self._drop("duplicate frame")
            return
        if len(payload) < PAYLOAD_HEADER.size or payload_channels(
                len(payload), PAYLOAD_HEADER.unpack_from(payload, 0)[-1]) is None:
            # No frame (a header-only datagram, random bytes with a valid header): it says nothing of its sender's
            # time, and counted as a restart (random headers gave 80 of them; issue 47).
            self._drop("bad payload")
            return
        sender.last_delivered = fingerprint
        went_back = timestamp < sender.newest_done
        if went_back:
            self.restarts += 1
            self.last_error = (f"timestamps went back from {sender.newest_done:.6g} s to {timestamp:.6g} s: "
                               "a restarted sender or clock")
        if frame_id is not None and sender.last_id is not None:
            if frame_id > sender.last_id + 1:
                # Frames lost whole (every datagram of them): the v3 frame ids show the gap that nothing else does
                # (drops 0 was said of a stream that lost 40 % of its frames).
                self.drops["lost frames (frame ids skipped)"] += frame_id - sender.last_id - 1
                self.last_error = f"frame ids skipped from {sender.last_id} to {frame_id}: frames lost whole"
            elif frame_id <= sender.last_id and not went_back:
                self.restarts += 1
                self.last_error = (f"frame ids went back from {sender.last_id} to {frame_id}: a restarted sender")
        if frame_id is not None:
            sender.last_id = frame_id
        sender.newest_done = timestamp
        self.frames += 1
        self._ready.append((source, timestamp, payload, frame_id))

    def next_ready(self) -> tuple[float, bytes] | None:
        """Another frame the last datagram made ready (one completed may free frames that waited for it), or
        None; its sender in :attr:`source`."""
        if not self._ready:
            return None
        self.source, timestamp, payload, self.frame_id = self._ready.popleft()
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
        header = DATAGRAM_HEADERS.get(struct.unpack_from("<i", datagram, 0)[0])
        if header is None:
            self._drop("wrong checksum")
            return
        if len(datagram) < header.size:
            self._drop("truncated header")
            return
        frame_id: int | None = None
        if header is DATAGRAM_HEADER_V3:
            _, length, index, count, frame_id, _, timestamp = header.unpack_from(datagram, 0)
        else:
            _, length, index, count, timestamp = header.unpack_from(datagram, 0)
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
            frame = self._pending[key] = _PendingFrame(count, self._arrivals, frame_id)
        if frame.count != count:
            self._drop("chunk count differs within a frame")
            return
        chunk = datagram[header.size :]
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
        sender.held.append((frame.arrival, timestamp, b"".join(frame.chunks[i] for i in range(count)),
                            frame.frame_id))
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
    """The request that asks RflySim for this sensor, as RflySim's client packs it for the configuration.

    Without ``EularOrQuat`` the 92-byte ``<16H15f``: checksum 12345, SeqID, TypeID, TargetCopter,
    TargetMountType, DataWidth, DataHeight, DataCheckFreq, SendProtocol[8]; CameraFOV, SensorPosXYZ[3],
    SensorAngEular[3], otherParams[8]. With it (the v3 form) the 144-byte ``<16H28f``: the same sixteen uint16,
    then CameraFOV, SensorPosXYZ[3], EularOrQuat, SensorAngEular[3], SensorAngQuat[4] (as written: [w, x, y,
    z]), otherParams[16]. A Mid-360's W and H go as its file has them (RflySim ignores them).
    """
    written = config.to_json_dict()
    ints = [REQUEST_CHECKSUM, config.seq_id, config.type_id, config.target_copter, config.target_mount_type,
            written["DataWidth"], written["DataHeight"], config.data_check_freq, *config.send_protocol]
    for name, value in zip(("SeqID", "TypeID", "TargetCopter", "TargetMountType", "DataWidth", "DataHeight",
                            "DataCheckFreq"), ints[1:8], strict=True):
        if not isinstance(value, int) or not 0 <= value <= 0xFFFF:
            raise LivoxVizError(f"{name} = {value} does not fit the request's uint16; allowed: 0 to 65535")
    if not all(0 <= v <= 0xFFFF for v in config.send_protocol):
        raise LivoxVizError(f"SendProtocol {list(config.send_protocol)} does not fit uint16 values")
    if config.eular_or_quat is None:
        floats = [config.camera_fov, *config.sensor_pos_xyz, *config.sensor_ang_euler, *config.other_params[:8]]
        return REQUEST.pack(*ints, *floats)
    floats = [config.camera_fov, *config.sensor_pos_xyz, config.eular_or_quat, *config.sensor_ang_euler,
              *(config.sensor_ang_quat or (0.0, 0.0, 0.0, 0.0)), *config.other_params]
    return REQUEST_V3.pack(*ints, *floats)


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
    if text.count(":") > 1 or text.startswith("["):
        # Split at its last colon, "::1" was host ":" and port 1. RflySim's frames and requests go over IPv4.
        raise LivoxVizError(f"address {quoted(text)} is IPv6; allowed: an IPv4 address or a host name, as HOST:PORT, "
                            "e.g. 127.0.0.1:9999")
    host, colon, port_text = text.rpartition(":") if ":" in text else (text, "", "")
    if not host:
        raise LivoxVizError(f"address {quoted(text)}; allowed: HOST:PORT, e.g. 127.0.0.1:9999")
    if not colon:
        if default_port is None:
            raise LivoxVizError(f"address {quoted(text)} has no port; allowed: HOST:PORT")
        return host, default_port
    # A colon and no port ("127.0.0.1:" from "HOST:$PORT" with PORT unset) went to the default port, and int() takes
    # "+5", "1_000", " 5" and other scripts' digits ("٣"): only ASCII digits are a port.
    if not (port_text.isascii() and port_text.isdigit()):
        allowed = "HOST alone for the default port, or " if default_port is not None else ""
        raise LivoxVizError(f"port {quoted(port_text)} in {quoted(text)}; allowed: {allowed}HOST:PORT with PORT a "
                            "number 1-65535")
    port = int(port_text)
    if not 1 <= port <= 65535:
        raise LivoxVizError(f"port {port}; allowed: 1-65535")
    return host, port


# Shared memory ---------------------------------------------------------------------------------
def shm_name(seq_id: int) -> str:
    """``RflySim3DImg_<SeqID>``: the block's file name in /dev/shm, or its mapping's name on Windows."""
    return SHM_NAME.format(seq_id=seq_id)


def default_shm_folder() -> str:
    """Where the block's file lives off Windows: ``/dev/shm`` (Linux), else the temporary folder (macOS has no
    /dev/shm; on Windows the block is a named mapping and has no folder)."""
    return "/dev/shm" if os.path.isdir("/dev/shm") else tempfile.gettempdir()


def shm_path(seq_id: int, folder: str | os.PathLike[str] | None = None) -> Path:
    """``/dev/shm/RflySim3DImg_<SeqID>`` (``folder`` default :func:`default_shm_folder`)."""
    return Path(folder if folder is not None else default_shm_folder()) / shm_name(seq_id)


def shm_size(config: SensorConfig) -> int:
    """Bytes of the shared-memory block: W*H*channels*2 + 1 + 8 + 28 (three int16 a point in SDK v2, four in
    v3, where a Mid-360's W*H is 64 x 272)."""
    return config.points_per_frame * 2 * WireFormat.of(config).channels + SHM_HEADER.size


def open_shm_file(path: str | os.PathLike[str], size: int, create: bool = False) -> mmap.mmap:
    """The block as POSIX shares it: the file ``path`` (in /dev/shm), mapped; created or resized by a writer.

    Raises
    ------
    LivoxVizError
        If it cannot be opened, or is smaller than ``size``.
    """
    path = Path(path)
    flags = os.O_RDWR | (os.O_CREAT if create else 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as exc:
        raise LivoxVizError(f"{path}: cannot open the shared memory ({exc.strerror})") from None
    try:
        if create and os.fstat(fd).st_size != size:
            os.ftruncate(fd, size)
        if os.fstat(fd).st_size < size:
            raise LivoxVizError(f"{path}: {os.fstat(fd).st_size} bytes; expected {size}")
        return mmap.mmap(fd, size)
    finally:
        os.close(fd)


def open_named_mapping(name: str, size: int, mapping: Callable[..., mmap.mmap] = mmap.mmap) -> mmap.mmap:
    """The block as Windows shares it: the named mapping ``name`` (``RflySim3DImg_<SeqID>``), as RflySim's client
    opens it (``mmap(-1, size, tagname)``: opened if RflySim made it, else made, all zeros: nothing to read yet).

    Parameters
    ----------
    name : str
    size : int
    mapping : callable
        ``mmap.mmap`` (Windows's, which takes ``tagname``); a test stands in its own.
    """
    try:
        return mapping(-1, size, tagname=name)
    except OSError as exc:
        raise LivoxVizError(f"{name}: cannot open the shared memory mapping ({exc.strerror or exc})") from None


def open_shared_block(seq_id: int, size: int, folder: str | os.PathLike[str] | None = None,
                      create: bool = False) -> tuple[mmap.mmap, str]:
    """The block of SeqID ``seq_id`` by the platform's opener, and its name for messages: the named mapping on
    Windows (``folder`` unused), the file in ``folder`` elsewhere."""
    if sys.platform == "win32":
        name = shm_name(seq_id)
        return open_named_mapping(name, size), name
    path = shm_path(seq_id, folder)
    return open_shm_file(path, size, create), str(path)


class SharedMemoryLink:
    """Either side of the ``RflySim3DImg_<SeqID>`` handshake, over a block either opener made.

    The writer fills the block and sets the flag byte to 2 (frame written); it
    does not overwrite a block whose flag is 3 (a reader is reading). The
    reader takes a frame only when the flag is 2, sets 3 while it copies and 4
    when it is done.

    Parameters
    ----------
    path : path-like, optional
        The block's file (POSIX); give ``block`` instead for one already opened (a Windows mapping).
    size : int
        Its size in bytes (see :func:`shm_size`).
    create : bool
        Create (or resize) the file, as the writer does.
    channels : {3, 4}
        int16 values a point (SDK v2 or v3).
    block : mmap.mmap, optional
        The opened block (from :func:`open_named_mapping` or :func:`open_shared_block`).
    name : str
        What to call it in messages (with ``block``).
    points_frame : {"sensor", "world"}
        Where the points it carries are (the v3 Mid-360's are in the world).
    """

    def __init__(self, path: str | os.PathLike[str] | None, size: int, create: bool = False, *, channels: int = 3,
                 block: mmap.mmap | None = None, name: str = "", points_frame: str = "sensor") -> None:
        if channels not in (3, 4):
            raise LivoxVizError(f"{channels} int16 a point; allowed: 3 (SDK v2) or 4 (SDK v3)")
        self.size = size
        self.channels = channels
        self.points_frame = points_frame
        if block is None:
            if path is None:
                raise LivoxVizError("a shared-memory link needs a file or an opened block")
            block = open_shm_file(path, size, create)
            name = str(path)
        if len(block) < size:
            raise LivoxVizError(f"{name}: {len(block)} bytes; expected {size}")
        self.path = Path(path) if path is not None else Path(name)
        self.name = name
        self._map = block

    def write(self, timestamp: float, pos_ang: np.ndarray, points_int16: np.ndarray) -> bool:
        """Publish a frame (``(M, channels)`` int16); False (nothing written) while a reader holds the block."""
        if self._map[0] == SHM_FLAG_READING:
            return False
        points = np.ascontiguousarray(points_int16, dtype="<i2")
        if points.ndim != 2 or points.shape[1] != self.channels:
            raise LivoxVizError(f"points of shape {points.shape}; this block takes (M, {self.channels})")
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
            capacity = (self.size - SHM_HEADER.size) // (2 * self.channels)
            if not 0 <= count <= capacity:
                raise LivoxVizError(f"shared memory PointNum {count}; allowed: 0 to {capacity}, the block's size for "
                                    "this configuration's DataWidth x DataHeight (is --config the sender's?)")
            values = np.frombuffer(self._map, dtype="<i2", count=count * self.channels, offset=SHM_HEADER.size)
            points = values.reshape(count, self.channels).astype(np.int16)
            channel4 = np.ascontiguousarray(points[:, 3]) if self.channels == 4 else None
            frame = LivoxFrame(timestamp, np.array(pose), np.ascontiguousarray(points[:, :3]), self.name, channel4,
                               None, self.points_frame)
        finally:
            self._map[0] = SHM_FLAG_DONE
        return frame

    def close(self) -> None:
        """Unmap the block (the file stays, as RflySim's does)."""
        self._map.close()
