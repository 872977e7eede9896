"""Reading LVX2 and LVX 1.1 files (Livox Viewer's, livox_ros_driver's, ours) frame by frame, into a recording.

The layouts are :mod:`~livox_viz.files.lvx_format`'s. The file is read one
50 ms frame at a time (:func:`iter_lvx`): each frame header is checked against
the file before its frame is read (it must start where the previous one ended,
end after its start and within the file, and hold at most
:data:`MAX_FRAME_BYTES`), so a truncated or looping file, or one that claims
gigabytes, is refused with one line and nothing is read past its end; memory
holds one frame. :func:`read_lvx` joins the frames, up to ``max_points``.

**Each point's time and laser are rebuilt as the drivers rebuild them.** A
package's points are consecutive firings: point ``i`` (pulse ``i // echoes`` of
a dual or triple return type) has the line ``pulse % lines`` (4 on a Mid-360, 6
on a HAP, Horizon, Tele-15 and Avia, 1 on a Mid-40 and Mid-70) and the time
``timestamp + pulse * interval``. The interval is the package's span over its
firings, the span being the time to the device's next package (what the
Ethernet packet's ``time_interval`` says to livox_ros_driver2; the file drops
that field): for a real head this is its drivers' point interval (5 us on a
Mid-360, 4.167 us on a Horizon), and for our scans, at whatever rate they were
cast, it gives each firing's time back. Where the next package is missing or
more than twice as far as the frame's median (a dropped packet), and for a
frame's last package, the frame's median span is used; for a frame of one
package, the head's nominal rate.

Read: LVX2 point types 1 (cartesian, int32 mm) and 2 (int16 cm); LVX 1.1 data
types 0 (Mid-40 cartesian, no tag), 2 (cartesian), 4 (dual) and 7 (triple);
LVX 1.1's IMU packages (type 6) are read past and counted. Spherical types, LVX
1.0.0.0 files and UTC timestamps (SDK1 type 3) are refused by name.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from livox_viz.core.errors import LivoxVizError, require_file
from livox_viz.files.livox_recording import LivoxDevice, LivoxRecording
from livox_viz.files.lvx_format import (
    FRAME_HEADER,
    HEADS,
    LVX1_DATA_TYPES,
    LVX1_DEVICE,
    LVX1_IMU,
    LVX1_PACKAGE,
    LVX2_DATA_TYPES,
    LVX2_DEVICE,
    LVX2_KNOWN,
    LVX2_PACKAGE,
    MAGIC_CODE,
    NS_TIMESTAMPS,
    PRIVATE_HEADER,
    PUBLIC_HEADER,
    SIGNATURE,
    DataType,
    HeadModel,
    head_by_type,
)

#: Largest frame read, bytes: a 50 ms frame of the fastest head (a HAP's 452 000 points/s) is about 330 kB; Livox's
#: own reader holds 2 MiB. A header claiming more is refused before anything is read.
MAX_FRAME_BYTES = 64 << 20
#: Points :func:`read_lvx` joins at most unless told otherwise (some 1.3 GB of arrays; 100 s of a Mid-360).
MAX_POINTS = 20_000_000
#: Points a byte of an LVX holds at most (96 in a package of 1363 bytes, the densest type), for the estimate that
#: refuses a huge file before reading it.
POINTS_PER_BYTE = 96 / 1363
#: LVX2 type 2: int16 centimetres, reflectivity, tag.
_CARTESIAN_LOW = np.dtype([("x", "<i2"), ("y", "<i2"), ("z", "<i2"), ("reflectivity", "u1"), ("tag", "u1")])
_LVX2_TYPES = {**LVX2_DATA_TYPES, 2: DataType(2, 96, 1, _CARTESIAN_LOW, 8)}
_LVX1_READ = (0, 2, 4, 7)


@dataclass(frozen=True)
class LvxLayout:
    """What an LVX's headers say: the format, its devices and where its frames start."""

    suffix: str
    source: str
    devices: tuple[LivoxDevice, ...]
    heads: tuple[HeadModel | None, ...]
    #: LVX2: each device's lidar id (packages name their device by it).
    lidar_ids: tuple[int, ...]
    data_start: int
    size: int


def _fail(path: Path, what: str) -> LivoxVizError:
    return LivoxVizError(f"{path}: {what}")


def _read_exact(handle: BinaryIO, count: int, path: Path, what: str) -> bytes:
    data = handle.read(count)
    if len(data) != count:
        raise _fail(path, f"ends inside {what} ({len(data)} of {count} bytes); allowed: a whole LVX2 or LVX 1.1 file")
    return data


def read_layout(path: str | os.PathLike[str], handle: BinaryIO | None = None) -> LvxLayout:
    """The headers of an LVX2 or LVX 1.1 file, checked.

    Raises
    ------
    LivoxVizError
        One line: not an LVX (signature, magic code), a version not read, no device, an unknown device type.
    """
    path = Path(path)
    require_file(path, "LVX2 or LVX file")
    if handle is None:
        with open(path, "rb") as own:
            return read_layout(path, own)
    size = os.fstat(handle.fileno()).st_size
    public = np.frombuffer(_read_exact(handle, PUBLIC_HEADER.itemsize, path, "its public header"), PUBLIC_HEADER)[0]
    if not bytes(public["signature"]).startswith(SIGNATURE):
        raise _fail(path, f"not a Livox file (signature {bytes(public['signature'])[:16]!r}); allowed: an LVX2 or "
                          "LVX 1.1 file starting with \"livox_tech\"")
    if int(public["magic_code"]) != MAGIC_CODE:
        raise _fail(path, f"magic code 0x{int(public['magic_code']):08X}; allowed: 0x{MAGIC_CODE:08X} (an LVX2 or "
                          "LVX 1.1 file)")
    version = tuple(int(v) for v in public["version"])
    if version[0] == 2:
        suffix, source, device_dtype = ".lvx2", "LVX2", LVX2_DEVICE
    elif version[:2] == (1, 1):
        suffix, source, device_dtype = ".lvx", "LVX 1.1", LVX1_DEVICE
    else:
        raise _fail(path, f"LVX version {'.'.join(map(str, version))}; allowed: 2.x (LVX2) or 1.1 (LVX 1.1; the "
                          "1.0 of the first Mid-100 samples is not read)")
    private = np.frombuffer(_read_exact(handle, PRIVATE_HEADER.itemsize, path, "its private header"),
                            PRIVATE_HEADER)[0]
    count = int(private["device_count"])
    if count == 0:
        raise _fail(path, "holds no device; allowed: an LVX with at least one device")
    table = np.frombuffer(_read_exact(handle, count * device_dtype.itemsize, path, f"its {count} device infos"),
                          device_dtype)
    devices, heads, ids = [], [], []
    for k, info in enumerate(table):
        device_type = int(info["device_type"])
        head = head_by_type(suffix, device_type)
        if head is None:
            known = ", ".join(f"{h.device_type} {h.name}" for h in HEADS if h.suffix == suffix)
            raise _fail(path, f"device {k} has device type {device_type}, unknown to {source}; allowed: {known}")
        extrinsics = tuple(float(info[name]) for name in ("roll", "pitch", "yaw", "x", "y", "z"))
        devices.append(LivoxDevice(bytes(info["lidar_sn"]).split(b"\0")[0].decode("ascii", "replace"), device_type,
                                   head.name, bool(info["extrinsic_enable"]), extrinsics))  # type: ignore[arg-type]
        heads.append(head)
        ids.append(int(info["lidar_id"]) if suffix == ".lvx2" else int(info["device_index"]))
    return LvxLayout(suffix, source, tuple(devices), tuple(heads), tuple(ids), handle.tell(), size)


def iter_lvx(path: str | os.PathLike[str], max_frame_bytes: int = MAX_FRAME_BYTES) -> Iterator[LivoxRecording]:
    """The file's frames, one :class:`LivoxRecording` each, in file order.

    Raises
    ------
    LivoxVizError
        One line, at the frame where it is found: a frame header that is cut, does not start where the last
        frame ended, ends before it starts or past the file's end, or claims more than ``max_frame_bytes``; a
        package that is cut or of a type not read (see the module docstring).
    """
    path = Path(path)
    with open(path, "rb") as handle:
        layout = read_layout(path, handle)
        position, index = layout.data_start, 0
        while position < layout.size:
            left = layout.size - position
            if left < FRAME_HEADER.itemsize:
                raise _fail(path, f"truncated: {left} bytes after frame {index - 1}, less than a frame header (24)")
            header = np.frombuffer(_read_exact(handle, FRAME_HEADER.itemsize, path, f"frame {index}'s header"),
                                   FRAME_HEADER)[0]
            start, end = int(header["current_offset"]), int(header["next_offset"])
            where = f"frame {index} at byte {position:,}"
            if start != position:
                raise _fail(path, f"{where} says it starts at byte {start:,}; allowed: frames one after the other, "
                                  "each starting where the last ended")
            if end < position + FRAME_HEADER.itemsize:
                raise _fail(path, f"{where} says the next frame starts at byte {end:,}, before its own end (its "
                                  "offsets loop back); allowed: a next offset after the frame header")
            if end > layout.size:
                raise _fail(path, f"truncated: {where} ends at byte {end:,}, past the file's end ({layout.size:,} "
                                  "bytes); allowed: a whole file")
            body_size = end - position - FRAME_HEADER.itemsize
            if body_size > max_frame_bytes:
                raise _fail(path, f"{where} claims {body_size / 2**20:,.1f} MiB; allowed: frames of at most "
                                  f"{max_frame_bytes / 2**20:g} MiB (50 ms of a head is under 1 MiB)")
            body = _read_exact(handle, body_size, path, where)
            yield _frame_points(path, layout, body, where)
            position, index = end, index + 1


def read_lvx_start(path: str | os.PathLike[str], rows: int,
                   keep: Callable[[LivoxRecording], np.ndarray] | None = None) -> LivoxRecording:
    """A file's first ``rows`` points (those ``keep`` keeps, given a frame: a boolean mask), read frame by frame
    only as far as they go: an hour's recording is read from its start in bounded memory."""
    path = Path(path)
    parts, count = [], 0
    for frame in iter_lvx(path):
        part = frame if keep is None else frame.subset(keep(frame))
        parts.append(part)
        count += len(part)
        if count >= rows:
            break
    layout = read_layout(path)
    return LivoxRecording.join(parts, layout.devices, layout.source, {}).subset(slice(0, rows))


def read_lvx(path: str | os.PathLike[str], max_points: int = MAX_POINTS) -> LivoxRecording:
    """Every point of an LVX2 or LVX 1.1 file (no-return firings included, marked), up to ``max_points``.

    Parameters
    ----------
    path : path-like
    max_points : int
        Refuse a file of more points (estimated from its size before reading, counted while reading).

    Returns
    -------
    LivoxRecording

    Raises
    ------
    LivoxVizError
        As :func:`iter_lvx`, and for a file of more than ``max_points`` points.
    """
    path = Path(path)
    layout = read_layout(path)
    estimate = int((layout.size - layout.data_start) * POINTS_PER_BYTE)
    allowed = (f"allowed: at most {max_points:,} points at once (read it frame by frame with iter_lvx, or pass a "
               "larger max_points)")
    if estimate > max_points:
        raise _fail(path, f"holds about {estimate:,} points ({layout.size / 2**30:.2f} GiB); {allowed}")
    parts, count, skipped = [], 0, {}
    for part in iter_lvx(path):
        count += len(part)
        if count > max_points:
            raise _fail(path, f"holds more than {max_points:,} points; {allowed}")
        parts.append(part)
        for key, value in part.skipped.items():
            skipped[key] = skipped.get(key, 0) + value
    return LivoxRecording.join(parts, layout.devices, layout.source, skipped)


def _frame_points(path: Path, layout: LvxLayout, body: bytes, where: str) -> LivoxRecording:
    """A frame's packages as points."""
    lvx2 = layout.suffix == ".lvx2"
    header_dtype = LVX2_PACKAGE if lvx2 else LVX1_PACKAGE
    head_size = header_dtype.itemsize
    types = _LVX2_TYPES if lvx2 else LVX1_DATA_TYPES
    raw = np.frombuffer(body, np.uint8)
    # Where each package starts, and its type: the packages of a frame are most often all alike (one stride);
    # otherwise (LVX 1.1's IMU packages among the points) they are walked one by one.
    offsets: dict[int, list[int]] = {}
    position, skipped = 0, {}
    while position < len(body):
        if len(body) - position < head_size:
            raise _fail(path, f"{where}: a package header cut at byte {position} of the frame's {len(body)}")
        head = np.frombuffer(body, header_dtype, count=1, offset=position)[0]
        number = int(head["data_type"])
        kind = types.get(number)
        if kind is None or (not lvx2 and number not in _LVX1_READ and number != LVX1_IMU):
            raise _fail(path, f"{where}: data type {number} ({_type_name(lvx2, number)}) is not read; allowed: "
                              + ("1 (cartesian int32 mm) or 2 (int16 cm)" if lvx2 else
                                 "0, 2, 4 (dual), 7 (triple) cartesian, 6 (IMU, skipped)"))
        size = head_size + (int(head["length"]) if lvx2 else kind.points_bytes)
        if lvx2 and int(head["length"]) != kind.points_bytes:
            raise _fail(path, f"{where}: a type {number} package of {int(head['length'])} bytes of points; allowed: "
                              f"{kind.points_bytes} ({kind.firings} points of {kind.size} bytes)")
        stride = _uniform_run(body, position, size, header_dtype, number)
        if position + size > len(body):
            raise _fail(path, f"{where}: a package at byte {position} runs past the frame's end ({len(body)} bytes)")
        if number == LVX1_IMU and not lvx2:
            skipped["IMU packages"] = skipped.get("IMU packages", 0) + stride
        else:
            offsets.setdefault(number, []).extend(range(position, position + stride * size, size))
        position += stride * size
    parts = [_packages(path, layout, raw, np.array(found, dtype=np.int64), types[number], where)
             for number, found in offsets.items()]
    return LivoxRecording.join(parts, layout.devices, layout.source, skipped)


def _uniform_run(body: bytes, position: int, size: int, header_dtype: np.dtype, number: int) -> int:
    """How many packages of ``size`` bytes and type ``number`` follow one another from ``position`` (at least 1)."""
    count = (len(body) - position) // size
    if count <= 1:
        return 1
    records = np.ndarray((count,), np.dtype({"names": ["data_type"], "formats": ["u1"],
                                              "offsets": [header_dtype.fields["data_type"][1]], "itemsize": size}),
                         buffer=body, offset=position)
    differ = np.flatnonzero(records["data_type"] != number)
    return int(differ[0]) if differ.size else count


def _type_name(lvx2: bool, number: int) -> str:
    if lvx2:
        return LVX2_KNOWN.get(number, "unknown")
    return {0: "cartesian", 1: "spherical", 2: "cartesian", 3: "spherical", 4: "dual cartesian",
            5: "dual spherical", 6: "IMU", 7: "triple cartesian", 8: "triple spherical"}.get(number, "unknown")


def _packages(path: Path, layout: LvxLayout, raw: np.ndarray, offsets: np.ndarray, kind: DataType,
              where: str) -> LivoxRecording:
    """The points of packages of one data type at ``offsets`` in the frame's bytes ``raw``."""
    lvx2 = layout.suffix == ".lvx2"
    header_dtype = LVX2_PACKAGE if lvx2 else LVX1_PACKAGE
    assert kind.point is not None
    record = np.dtype([("head", header_dtype), ("points", kind.point, (kind.firings, kind.echoes))])
    gathered = raw[offsets[:, None] + np.arange(record.itemsize)]
    packages = np.frombuffer(gathered.tobytes(), record)
    heads = packages["head"]
    stamp_types = np.unique(heads["timestamp_type"])
    bad = [int(t) for t in stamp_types if int(t) not in NS_TIMESTAMPS[layout.suffix]]
    if bad:
        raise _fail(path, f"{where}: timestamp type {bad[0]}; allowed: "
                          f"{', '.join(map(str, NS_TIMESTAMPS[layout.suffix]))} (nanoseconds)")
    ids = heads["lidar_id"] if lvx2 else heads["device_index"]
    device = np.full(len(packages), -1, dtype=np.int64)
    for k, lidar_id in enumerate(layout.lidar_ids):
        device[ids == lidar_id] = k
    if np.any(device < 0):
        stray = int(ids[np.flatnonzero(device < 0)[0]])
        raise _fail(path, f"{where}: a package of {'lidar id' if lvx2 else 'device index'} {stray}, which no device "
                          f"info names; allowed: {', '.join(map(str, layout.lidar_ids))}")
    stamps = heads["timestamp"].astype(np.int64)
    interval = _intervals(stamps, device, layout, kind.firings)
    lines = np.array([head.lines if head is not None else 1 for head in layout.heads], dtype=np.int64)[device]
    pulse = np.arange(kind.firings, dtype=np.int64)
    n, e = len(packages), kind.echoes
    points = packages["points"]  # (n, firings, echoes)
    scale = 0.01 if kind.point == _CARTESIAN_LOW else 0.001
    xyz = np.stack([points[axis].astype(np.float64) * scale for axis in "xyz"], axis=-1).reshape(-1, 3)
    times = ((stamps[:, None] + pulse[None, :] * interval[:, None]) / 1e9)[:, :, None]
    zero = (points["x"] == 0) & (points["y"] == 0) & (points["z"] == 0)
    shape = (n, kind.firings, e)
    tags = points["tag"] if "tag" in kind.point.names else np.zeros(shape, np.uint8)
    return LivoxRecording(
        points_m=xyz,
        times_s=np.broadcast_to(times, shape).reshape(-1),
        lasers=np.broadcast_to((pulse[None, :] % lines[:, None])[:, :, None], shape).reshape(-1).astype(np.uint8),
        reflectivity=points["reflectivity"].reshape(-1).astype(np.uint8),
        tags=np.asarray(tags).reshape(-1).astype(np.uint8),
        return_number=np.broadcast_to(np.arange(1, e + 1, dtype=np.uint8), shape).reshape(-1).copy(),
        no_return=zero.reshape(-1),
        device_index=np.broadcast_to(device[:, None, None], shape).reshape(-1).astype(np.uint8),
        devices=layout.devices, source=layout.source, skipped={})


def _intervals(stamps: np.ndarray, device: np.ndarray, layout: LvxLayout, firings: int) -> np.ndarray:
    """``(n,)`` float64 each package's point interval, ns (see the module docstring)."""
    interval = np.empty(len(stamps))
    for k in np.unique(device):
        mine = np.flatnonzero(device == k)
        head = layout.heads[int(k)]
        nominal = head.point_interval_ns if head is not None else 1e4
        spans = np.diff(stamps[mine]).astype(np.float64)
        positive = spans[spans > 0]
        typical = float(np.median(positive)) if positive.size else nominal * firings
        spans = np.append(spans, typical)
        spans[(spans <= 0) | (spans > 2 * typical) | (spans < typical / 2)] = typical
        interval[mine] = spans / firings
    return interval
