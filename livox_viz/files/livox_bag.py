"""Reading the Livox drivers' bags: ROS 1 ``.bag`` of livox_ros_driver and ROS 2 bags of livox_ros_driver2.

Read with the pure-Python ``rosbags`` library (already the project's ROS 2
bag writer; its ``AnyReader`` reads ROS 1 bags too, no ROS needed). The lidar
topic is the first ``CustomMsg`` one holding messages (``livox_ros_driver/CustomMsg`` or
``livox_ros_driver2/msg/CustomMsg``), else the first ``sensor_msgs/PointCloud2``.

**Times, as the drivers made them.** A ``CustomMsg`` point's time is the
message's ``timebase`` plus its ``offset_time`` (ns). A ``PointCloud2`` of
livox_ros_driver2 holds each point's ``timestamp`` (float64 ns); one of
livox_ros_driver (x, y, z, intensity, tag, line; no time) holds the packages'
points one after the other from the header's stamp, so point ``i`` is at
``stamp + i * interval``, the interval being the time to the next message over
the points (as :mod:`~livox_viz.files.lvx_read` takes a package's), the last
message's that of the one before. Points are in the drivers' frame (x
forward, y left, z up; the extrinsics the driver was given applied); (0, 0, 0)
is a firing that returned nothing.

A ROS 1 ``CustomMsg`` is parsed from its bytes with numpy (``rosbags`` would
make a Python object per point); the rest through ``rosbags``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.files.livox_recording import LivoxDevice, LivoxRecording

#: Points read at most unless told otherwise (as :data:`~livox_viz.files.lvx_read.MAX_POINTS`).
MAX_POINTS = 20_000_000
#: A ROS 1 CustomPoint: offset_time u32 (ns), x y z f32 (m), reflectivity, tag, line (no padding in ROS 1).
_ROS1_POINT = np.dtype([("offset_time", "<u4"), ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("reflectivity", "u1"),
                        ("tag", "u1"), ("line", "u1")])
_PC2_TYPES = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}


def read_livox_bag(path: str | os.PathLike[str], max_points: int = MAX_POINTS) -> LivoxRecording:
    """The lidar points of a ROS 1 ``.bag`` (or a ROS 2 bag folder) recorded from a Livox driver.

    Parameters
    ----------
    path : path-like
    max_points : int
        Refuse a bag of more points.

    Raises
    ------
    LivoxVizError
        One line: not a bag ``rosbags`` reads, no Livox lidar topic, a PointCloud2 without x, y, z, more than
        ``max_points`` points.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise LivoxVizError(f"{path}: does not exist; allowed: a ROS 1 .bag or a ROS 2 bag folder")
    ros1 = path.is_file()
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises its own errors for every kind of bad bag
        raise LivoxVizError(f"{path}: not a bag rosbags reads ({str(exc).splitlines()[0] if str(exc) else exc!r}); "
                            "allowed: a ROS 1 .bag or a ROS 2 bag folder") from None
    try:
        holding = [c for c in reader.connections if getattr(c, "msgcount", 1)]
        custom = [c for c in holding if c.msgtype.endswith("/CustomMsg")]
        clouds = [c for c in holding if c.msgtype == "sensor_msgs/msg/PointCloud2"]
        if not custom and not clouds:
            topics = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})) or "nothing"
            raise LivoxVizError(f"{path}: holds {topics:.200}; allowed: a bag with a Livox CustomMsg or a "
                                "PointCloud2 topic")
        connection = (custom or clouds)[0]
        parts: list[dict[str, np.ndarray]] = []
        count = 0
        for _, stamp, raw in reader.messages(connections=[connection]):
            if custom and ros1:
                part = _ros1_custom(raw)
            else:
                message = reader.deserialize(raw, connection.msgtype)
                part = _custom(message) if custom else _cloud(path, message, stamp)
            count += len(part["times"])
            if count > max_points:
                raise LivoxVizError(f"{path}: holds more than {max_points:,} points on {connection.topic}; allowed: "
                                    f"at most {max_points:,} (pass a larger max_points)")
            parts.append(part)
    finally:
        reader.close()
    _rebuild_times(parts)
    return _recording(parts, "ROS 1 bag" if ros1 else "ROS 2 bag", connection.topic)


def _ros1_custom(raw: bytes | memoryview) -> dict[str, np.ndarray]:
    """A ROS 1 ``livox_ros_driver/CustomMsg`` from its bytes: header (seq, stamp, frame_id), timebase, point_num,
    lidar_id, rsvd[3], points[]."""
    data = bytes(raw)
    frame_id = int(np.frombuffer(data, "<u4", 1, 12)[0])
    at = 16 + frame_id
    timebase = int(np.frombuffer(data, "<u8", 1, at)[0])
    at += 8 + 4 + 1 + 3
    count = int(np.frombuffer(data, "<u4", 1, at)[0])
    points = np.frombuffer(data, _ROS1_POINT, count, at + 4)
    return _columns(points, timebase + points["offset_time"].astype(np.int64), points["line"], points["tag"])


def _custom(message) -> dict[str, np.ndarray]:
    """A CustomMsg deserialized by ``rosbags`` (a ROS 2 one)."""
    points = message.points
    table = np.zeros(len(points), _ROS1_POINT)
    for name in _ROS1_POINT.names:
        table[name] = [getattr(point, name) for point in points]
    return _columns(table, int(message.timebase) + table["offset_time"].astype(np.int64), table["line"], table["tag"])


def _columns(table: np.ndarray, times_ns: np.ndarray, line: np.ndarray, tag: np.ndarray) -> dict[str, np.ndarray]:
    return {"xyz": np.column_stack([table["x"], table["y"], table["z"]]).astype(np.float64),
            "times": times_ns.astype(np.float64), "line": np.asarray(line, np.uint8),
            "reflectivity": np.asarray(table["reflectivity"], np.uint8), "tag": np.asarray(tag, np.uint8),
            "rebuild": np.zeros(len(table), bool)}


def _cloud(path: Path, message, stamp: int) -> dict[str, np.ndarray]:
    """A PointCloud2 of either driver: its fields by name, times from its ``timestamp`` field or rebuilt."""
    fields = {field.name: (field.offset, _PC2_TYPES.get(field.datatype)) for field in message.fields}
    if not {"x", "y", "z"} <= fields.keys() or message.is_bigendian:
        raise LivoxVizError(f"{path}: a PointCloud2 with fields {', '.join(fields):.120}; allowed: little-endian "
                            "x, y, z (and intensity, tag, line, timestamp as the Livox drivers write them)")
    count = int(message.width) * int(message.height)
    data = np.asarray(message.data, dtype=np.uint8).tobytes()

    def column(name: str, default: float = 0.0) -> np.ndarray:
        if name not in fields or fields[name][1] is None:
            return np.full(count, default)
        offset, kind = fields[name]
        layout = np.dtype({"names": [name], "formats": [kind], "offsets": [offset],
                           "itemsize": int(message.point_step)})
        return np.frombuffer(data, layout, count)[name].astype(np.float64)

    header = int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)
    timed = "timestamp" in fields
    times = column("timestamp") if timed else np.full(count, float(header))
    reflectivity = column("intensity") if "intensity" in fields else column("reflectivity")
    return {"xyz": np.column_stack([column("x"), column("y"), column("z")]), "times": times,
            "line": column("line").astype(np.uint8), "reflectivity": np.clip(reflectivity, 0, 255).astype(np.uint8),
            "tag": column("tag").astype(np.uint8), "rebuild": np.full(count, not timed)}


def _rebuild_times(parts: list[dict[str, np.ndarray]]) -> None:
    """Points of a message without times: its stamp plus their place times the interval to the next message."""
    spans = [part["times"][0] for part in parts if len(part["times"])]
    for k, part in enumerate(parts):
        if not part["rebuild"].any() or not len(part["times"]):
            continue
        start = part["times"][0]
        later = [s for s in spans if s > start]
        earlier = [(s, len(p["times"])) for s, p in zip(spans, parts, strict=False) if s < start]
        if later:
            interval = (later[0] - start) / len(part["times"])
        elif earlier:
            interval = (start - earlier[-1][0]) / earlier[-1][1]
        else:
            interval = 0.0
        part["times"] = start + np.arange(len(part["times"])) * interval
        parts[k] = part


def _recording(parts: list[dict[str, np.ndarray]], source: str, topic: str) -> LivoxRecording:
    def cat(name: str, shape: tuple[int, ...] = (), dtype=np.float64) -> np.ndarray:
        return np.concatenate([p[name] for p in parts]) if parts else np.zeros((0, *shape), dtype)

    xyz = cat("xyz", (3,))
    count = len(xyz)
    return LivoxRecording(points_m=xyz, times_s=cat("times") / 1e9, lasers=cat("line", dtype=np.uint8),
                          reflectivity=cat("reflectivity", dtype=np.uint8), tags=cat("tag", dtype=np.uint8),
                          return_number=np.ones(count, np.uint8), no_return=~xyz.any(axis=1),
                          device_index=np.zeros(count, np.uint8),
                          devices=(LivoxDevice("", -1, f"a Livox driver's {topic}"),), source=source, skipped={})
