"""ROS 2 bags (rosbag2, MCAP storage) of a scan, for FAST-LIO, LIO-Livox, Point-LIO, RViz and Foxglove.

Written with the pure-Python ``rosbags`` library; no ROS installation is
needed. Topics (the Livox ROS driver 2's names by default, all settable):

* ``/livox/lidar``: ``livox_ros_driver2/msg/CustomMsg``, one per frame, each
  point with its ``offset_time`` (ns) from the frame's ``timebase`` (what
  FAST-LIO reads by default);
* ``/livox/points``: ``sensor_msgs/msg/PointCloud2`` in the driver's layout
  (x, y, z, intensity float32; tag, line uint8; timestamp float64 ns), one per frame;

  both carry each point's reflectivity (CustomMsg ``reflectivity``, PointCloud2
  ``intensity``) and its SDK1 tag, whose return-number bits are 0x10 for a first
  return (0x00 nearer than the sensor's return-0 range), 0x20 and 0x30 for a
  second and third: FAST-LIO keeps the points with ``tag & 0x30`` 0x00 or 0x10;
* ``/livox/imu``: ``sensor_msgs/msg/Imu`` (no orientation: covariance[0] = -1; the
  rates' and accelerations' covariances state the white noise's variance per
  sample on their diagonals, all zero, "unknown", for a perfect IMU), in
  ``base_link`` (the vehicle's body origin and axes) by default, or in
  ``livox_frame`` (the lidar's origin and axes, lever-arm effects included) as the
  Livox driver publishes its built-in IMU: ``imu_frame``;
* ``/odom``: ``nav_msgs/msg/Odometry``, the ground truth of the vehicle (pose in
  ``odom``; twist in ``base_link``, as REP 105 and nav_msgs say), and the same pose
  on ``/tf`` (odom -> base_link); ``/tf_static`` holds base_link -> livox_frame.

The IMU, ``/odom`` and ``/tf`` all evaluate the one motion model the points were
cast with (:mod:`~livox_viz.motion.trajectory`), so points placed with ``/odom``
(interpolated) and ``/tf_static`` land where they were hit.

**Frames (REP 103/105).** The project is NED/FRD; ROS is ENU/FLU. At this
boundary, and only here: world NED (x north, y east, z down) -> ENU
``(y, x, -z)``; body and sensor FRD (x forward, y right, z down) -> FLU
``(x, -y, -z)``; an orientation R (FRD -> NED) becomes
``R_ENU_FLU = C_NED_ENU R C_FRD_FLU``. Points are in the sensor's FLU frame at
their own time (what the driver gives); times are ``time_base`` plus the scan
time.

**What ROS reads.** Messages are written in log-time order (each call's messages
wait until no earlier one can come). Every topic records the QoS its publisher
would offer, as ``ros2 bag record`` writes it (metadata version 8, which Humble
and Jazzy both read): reliable and volatile, and ``/tf_static`` reliable and
transient local, so that ``ros2 bag play`` latches it for RViz.
"""

from __future__ import annotations

import heapq
import itertools
import os
import struct
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from livox_viz.casting.scan import ScanFrame
from livox_viz.core.atomic import WorkDir, remove_dead_leftovers
from livox_viz.core.errors import LivoxVizError, quoted
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import FRD_TO_FLU, enu_flu_from_ned_frd, enu_from_ned, flu_from_frd, quat_from_matrix
from livox_viz.files.ros_names import check_ros_names
from livox_viz.motion.imu import IMU_FRAMES, ImuSamples
from livox_viz.motion.trajectory import Trajectory

#: Scan time 0 is this many seconds after the Unix epoch in the bag (a fixed, reproducible date).
DEFAULT_TIME_BASE = 1_700_000_000.0

CUSTOM_POINT_MSG = """uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""
CUSTOM_MSG = """std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
"""
#: The Livox ROS driver 2's PointCloud2 point: (name, offset, PointField datatype, numpy type).
POINTCLOUD2_FIELDS: tuple[tuple[str, int, int, str], ...] = (
    ("x", 0, 7, "<f4"), ("y", 4, 7, "<f4"), ("z", 8, 7, "<f4"), ("intensity", 12, 7, "<f4"),
    ("tag", 16, 2, "u1"), ("line", 17, 2, "u1"), ("timestamp", 18, 8, "<f8"),
)
POINT_STEP = 26
_PC2_DTYPE = np.dtype({"names": [f[0] for f in POINTCLOUD2_FIELDS], "formats": [f[3] for f in POINTCLOUD2_FIELDS],
                       "offsets": [f[1] for f in POINTCLOUD2_FIELDS], "itemsize": POINT_STEP})
# A CustomPoint in CDR: 19 bytes, then padding so the next one's uint32 is 4-aligned.
_CUSTOM_POINT_DTYPE = np.dtype([("offset_time", "<u4"), ("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                ("reflectivity", "u1"), ("tag", "u1"), ("line", "u1"), ("pad", "u1")])


@dataclass(frozen=True)
class RosNames:
    """Topic and frame names (defaults: the Livox ROS driver 2's and REP 105's).

    Parameters
    ----------
    lidar, points, imu, odom : str
        Topics of the CustomMsg, PointCloud2, Imu and Odometry messages.
    lidar_frame, body_frame, world_frame : str
        The sensor's, the vehicle's and the world's frame ids.
    """

    lidar: str = "/livox/lidar"
    points: str = "/livox/points"
    imu: str = "/livox/imu"
    odom: str = "/odom"
    lidar_frame: str = "livox_frame"
    body_frame: str = "base_link"
    world_frame: str = "odom"

    def __post_init__(self) -> None:
        """Valid as ROS 2 names them, and no two colliding (see :mod:`livox_viz.files.ros_names`)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        check_ros_names({k: v for k, v in values.items() if not k.endswith("_frame")},
                        {k: v for k, v in values.items() if k.endswith("_frame")},
                        ("world_frame", "body_frame", "lidar_frame"))

    @classmethod
    def parse(cls, text: str) -> RosNames:
        """``lidar=/x,imu=/y,...`` as given to ``--ros-names``."""
        values = {}
        for part in filter(None, (p.strip() for p in text.split(","))):
            key, _, value = part.partition("=")
            if key not in cls.__dataclass_fields__ or not value:
                raise LivoxVizError(f"--ros-names {quoted(part)}; allowed: NAME=VALUE with NAME one of "
                                    f"{', '.join(cls.__dataclass_fields__)}")
            if key in values:
                raise LivoxVizError(f"--ros-names gives {key} twice ({quoted(values[key])} and {quoted(value)}); "
                                    "allowed: each name once")
            values[key] = value
        return cls(**values)


class RosbagWriter:
    """Writes a rosbag2 folder (MCAP) of frames, IMU samples and the ground truth, atomically.

    The bag is written into a temporary folder beside ``path`` and renamed to
    ``path`` only by :meth:`close`; :meth:`abort` (or any exception in a
    ``with`` block) removes it. An existing ``path`` is refused, never replaced.

    Parameters
    ----------
    path : path-like
        The bag folder to make.
    mount : Pose
        The sensor's pose on the vehicle (FRD), for ``/tf_static``.
    names : RosNames
    time_base : float
        Unix seconds of scan time 0.
    lasers : int
        The ``line`` of a point is its laser (0 for one).
    imu_frame : {"body", "lidar"}
        The frame the IMU samples given to :meth:`write_imu` are in: the vehicle's (``base_link``) or the
        lidar's (``livox_frame``, the Livox driver's convention); it names their ``frame_id``.
    imu_variances : (float, float)
        The IMU's noise variance per sample, gyroscope (rad/s)^2 and accelerometer (m/s^2)^2
        (:meth:`~livox_viz.motion.imu.ImuNoise.sample_variances`): the diagonals of its messages' covariances.
        0 (a perfect IMU's) states none: the covariance stays all zero, ``sensor_msgs/Imu``'s "unknown".
    """

    def __init__(self, path: str | os.PathLike[str], mount: Pose, names: RosNames | None = None,
                 time_base: float = DEFAULT_TIME_BASE, lasers: int = 1, imu_frame: str = "body",
                 imu_variances: tuple[float, float] = (0.0, 0.0)) -> None:
        self.path = Path(path)
        if os.path.lexists(self.path):  # a dangling symbolic link too: the bag would be renamed onto it
            raise LivoxVizError(f"{self.path}: exists; allowed: a new folder name for the bag (nothing is replaced)")
        if not self.path.absolute().parent.is_dir():
            raise LivoxVizError(f"{self.path}: the folder {self.path.absolute().parent} does not exist")
        self.names = names or RosNames()
        if imu_frame not in IMU_FRAMES:
            raise LivoxVizError(f"IMU frame {quoted(imu_frame)}; allowed: {', '.join(IMU_FRAMES)}")
        self.imu_frame = imu_frame
        self.imu_variances = (float(imu_variances[0]), float(imu_variances[1]))
        self.time_base_ns = round(time_base * 1e9)
        self.lasers = lasers
        self.frames = 0
        self.points = 0
        #: Why closing the bag failed during an abort, if it did.
        self.abort_error = ""
        self._closed = False
        self._bag = None
        # Messages wait here, (stamp ns, order, connection, bytes), until no earlier one can come.
        self._pending: list[tuple[int, int, object, bytes | memoryview]] = []
        self._order = itertools.count()
        self._latest: dict[int, int] = {}
        # Named before it exists and created inside the try, so no signal can leave it behind.
        self._work = WorkDir(self.path.absolute().parent / self.path.name)
        try:
            self._work.create()
            self._open(mount)
        except BaseException:
            self.abort()
            raise

    def _open(self, mount: Pose) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        store = get_typestore(Stores.ROS2_HUMBLE)
        types = get_types_from_msg(CUSTOM_POINT_MSG, "livox_ros_driver2/msg/CustomPoint")
        types.update(get_types_from_msg(CUSTOM_MSG, "livox_ros_driver2/msg/CustomMsg"))
        store.register(types)
        self.store = store
        self._imu_layout: FixedLayout | None = None
        self._odom_layout: FixedLayout | None = None
        self._tf_layout: FixedLayout | None = None
        bag = Writer(self._work.path / "bag", version=8, storage_plugin=StoragePlugin.MCAP)
        bag.open()
        self._bag = bag

        def connect(topic: str, msgtype: str, latched: bool = False):
            return bag.add_connection(topic, msgtype, typestore=store, offered_qos_profiles=[offered_qos(latched)])

        self._lidar = connect(self.names.lidar, "livox_ros_driver2/msg/CustomMsg")
        self._points = connect(self.names.points, "sensor_msgs/msg/PointCloud2")
        self._imu = connect(self.names.imu, "sensor_msgs/msg/Imu")
        self._odom = connect(self.names.odom, "nav_msgs/msg/Odometry")
        self._tf = connect("/tf", "tf2_msgs/msg/TFMessage")
        self._tf_static = connect("/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
        # The mount between two FLU frames: both sides of the FRD rotation turned into FLU.
        mount_flu = FRD_TO_FLU @ mount.rotation @ FRD_TO_FLU
        self._write(self._tf_static, self.time_base_ns, self._tf_message(
            [(self.time_base_ns, self.names.body_frame, self.names.lidar_frame, flu_from_frd(mount.origin),
              quat_from_matrix(mount_flu))]))

    # Messages -----------------------------------------------------------------------------
    def _stamp(self, nanoseconds: int):
        time_type = self.store.types["builtin_interfaces/msg/Time"]
        return time_type(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)

    def _header(self, nanoseconds: int, frame_id: str):
        return self.store.types["std_msgs/msg/Header"](stamp=self._stamp(nanoseconds), frame_id=frame_id)

    def _ns(self, seconds: float) -> int:
        return self.time_base_ns + round(seconds * 1e9)

    def _write(self, connection, nanoseconds: int, message) -> None:
        self._emit(connection, [nanoseconds], [self.store.serialize_cdr(message, connection.msgtype)])

    def _emit(self, connection, stamps, messages) -> None:
        """Queue messages of one connection (stamps non-decreasing, ns) and write whatever is now in order."""
        for stamp, data in zip(stamps, messages, strict=True):
            heapq.heappush(self._pending, (stamp, next(self._order), connection, data))
            if connection is not self._tf_static:  # written once: it must not hold the others back
                self._latest[connection.id] = stamp
        self._release(min(self._latest.values(), default=-1))

    def _release(self, upto: int) -> None:
        """Write the queued messages stamped ``upto`` ns or earlier, in stamp order.

        Each connection's stamps only grow, so none earlier than the latest stamp of every
        connection can still come.
        """
        pending = self._pending
        ready = []
        while pending and pending[0][0] <= upto:
            stamp, _, connection, data = heapq.heappop(pending)
            ready.append((stamp, connection, data))
        try:
            self._write_in_order(ready)
        except OSError as exc:  # a full disk: say which file
            raise LivoxVizError(f"{self.path}: cannot write the bag ({exc.strerror or exc}); nothing is kept") \
                from exc

    def _write_in_order(self, messages: list) -> None:
        """``(stamp ns, connection, bytes)`` in log order into the bag: a batch at once where the bag's storage is
        rosbags' MCAP writer (:func:`append_mcap_messages`), else one by one."""
        if not messages:
            return
        if not append_mcap_messages(self._bag, messages):
            for stamp, connection, data in messages:
                self._bag.write(connection, stamp, data)

    def _tf_message(self, transforms):
        """``transforms``: (stamp ns, parent, child, translation (3,), quaternion [x, y, z, w])."""
        types = self.store.types
        stamped = []
        for nanoseconds, parent, child, translation, q in transforms:
            stamped.append(types["geometry_msgs/msg/TransformStamped"](
                header=self._header(nanoseconds, parent), child_frame_id=child,
                transform=types["geometry_msgs/msg/Transform"](
                    translation=types["geometry_msgs/msg/Vector3"](*map(float, translation)),
                    rotation=types["geometry_msgs/msg/Quaternion"](*map(float, q)))))
        return types["tf2_msgs/msg/TFMessage"](transforms=stamped)

    def write_frame(self, frame: ScanFrame) -> None:
        """One frame as CustomMsg and PointCloud2: decoded points in the sensor FLU frame at their own time."""
        stamp = self._ns(frame.timestamp)
        xyz = flu_from_frd(frame.xyz_decoded).astype(np.float32)
        offset = np.round((frame.t - frame.timestamp) * 1e9).astype(np.int64)
        line = (frame.stream_index % self.lasers).astype(np.uint8)
        self._emit(self._lidar, [stamp], [custom_msg_cdr(stamp, self.names.lidar_frame, xyz, offset, line,
                                                         frame.reflectivity, frame.tag)])
        cloud = np.zeros(len(frame), dtype=_PC2_DTYPE)
        cloud["x"], cloud["y"], cloud["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        cloud["intensity"] = frame.reflectivity
        cloud["tag"] = frame.tag
        cloud["line"] = line
        cloud["timestamp"] = (stamp + offset).astype(np.float64)
        types = self.store.types
        fields = [types["sensor_msgs/msg/PointField"](name=name, offset=offset_, datatype=kind, count=1)
                  for name, offset_, kind, _ in POINTCLOUD2_FIELDS]
        message = types["sensor_msgs/msg/PointCloud2"](
            header=self._header(stamp, self.names.lidar_frame), height=1, width=len(frame), fields=fields,
            is_bigendian=False, point_step=POINT_STEP, row_step=POINT_STEP * len(frame),
            data=np.frombuffer(cloud.tobytes(), dtype=np.uint8), is_dense=True)
        self._write(self._points, stamp, message)
        self.frames += 1
        self.points += len(frame)

    def write_imu(self, samples: ImuSamples) -> None:
        """IMU samples (FRD of ``imu_frame``) as ``sensor_msgs/Imu`` in its FLU frame, without orientation."""
        frame_id = self.names.body_frame if self.imu_frame == "body" else self.names.lidar_frame
        if self._imu_layout is None:
            types = self.store.types
            vector = types["geometry_msgs/msg/Vector3"]
            no_orientation = np.zeros(9)
            no_orientation[0] = -1.0
            gyroscope, accelerometer = (np.diag(np.full(3, variance)).reshape(9) for variance in self.imu_variances)

            def build(stamp: int, v: np.ndarray):
                return types["sensor_msgs/msg/Imu"](
                    header=self._header(stamp, frame_id),
                    orientation=types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                    orientation_covariance=no_orientation, angular_velocity=vector(*v[:3]),
                    angular_velocity_covariance=gyroscope, linear_acceleration=vector(*v[3:]),
                    linear_acceleration_covariance=accelerometer)

            self._imu_layout = FixedLayout(self.store, "sensor_msgs/msg/Imu", build, 6)
        stamps = self.time_base_ns + np.round(samples.t * 1e9).astype(np.int64)
        values = np.hstack([flu_from_frd(samples.angular_velocity), flu_from_frd(samples.specific_force)])
        self._write_packed(self._imu, stamps, self._imu_layout.pack(stamps, values))

    def write_ground_truth(self, t: np.ndarray, position: np.ndarray, rotation: np.ndarray,
                           velocity: np.ndarray, angular_velocity: np.ndarray) -> None:
        """The vehicle's true motion as ``/odom`` and ``/tf``.

        Parameters
        ----------
        t : (n,) float64
            Seconds.
        position : (n, 3) float64
            World NED.
        rotation : (n, 3, 3) float64
            Body FRD -> world NED.
        velocity : (n, 3) float64
            World NED, m/s.
        angular_velocity : (n, 3) float64
            Body FRD, rad/s.
        """
        if len(t) == 0:
            return
        if self._odom_layout is None:
            types = self.store.types
            vector = types["geometry_msgs/msg/Vector3"]
            zeros = np.zeros(36)

            def odometry(stamp: int, v: np.ndarray):
                pose = types["geometry_msgs/msg/Pose"](position=types["geometry_msgs/msg/Point"](*v[:3]),
                                                        orientation=types["geometry_msgs/msg/Quaternion"](*v[3:7]))
                twist = types["geometry_msgs/msg/Twist"](linear=vector(*v[7:10]), angular=vector(*v[10:13]))
                return types["nav_msgs/msg/Odometry"](
                    header=self._header(stamp, self.names.world_frame), child_frame_id=self.names.body_frame,
                    pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=zeros),
                    twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=zeros))

            def transform(stamp: int, v: np.ndarray):
                return self._tf_message([(stamp, self.names.world_frame, self.names.body_frame, v[:3], v[3:7])])

            self._odom_layout = FixedLayout(self.store, "nav_msgs/msg/Odometry", odometry, 13)
            self._tf_layout = FixedLayout(self.store, "tf2_msgs/msg/TFMessage", transform, 7)
        enu = enu_from_ned(position)
        quaternions = quat_from_matrix(enu_flu_from_ned_frd(rotation))
        body_velocity = flu_from_frd(np.einsum("nji,nj->ni", rotation, velocity))
        stamps = self.time_base_ns + np.round(np.asarray(t) * 1e9).astype(np.int64)
        pose = np.hstack([enu, quaternions])
        twist = np.hstack([body_velocity, flu_from_frd(angular_velocity)])
        odometry_bytes = self._odom_layout.pack(stamps, np.hstack([pose, twist]))
        transform_bytes = self._tf_layout.pack(stamps, pose)
        self._write_packed(self._odom, stamps, odometry_bytes)
        self._write_packed(self._tf, stamps, transform_bytes)

    def write_motion(self, trajectory: Trajectory, t: np.ndarray) -> None:
        """The ground truth of a trajectory's motion model at times ``t`` (s), see :meth:`write_ground_truth`."""
        self.write_ground_truth(t, trajectory.position_at(t), trajectory.rotation_at(t).as_matrix(),
                                trajectory.velocity_at(t), trajectory.angular_velocity_at(t))

    def _write_packed(self, connection, stamps: np.ndarray, records: np.ndarray) -> None:
        size = records.dtype.itemsize
        view = memoryview(records.tobytes())
        self._emit(connection, stamps.tolist(), [view[k * size : (k + 1) * size] for k in range(len(stamps))])

    # Files ------------------------------------------------------------------------------------
    def close(self) -> Path:
        """Finish the bag and move the folder into place; returns its path.

        Raises
        ------
        LivoxVizError
            Naming the bag, if it cannot be finished or moved (nothing is left behind then).
        """
        if self._closed:
            return self.path
        try:
            self._release(2**63)
            self._bag.close()
            self._closed = True
            if os.path.lexists(self.path):
                raise LivoxVizError(f"{self.path}: appeared while writing; the bag was not moved over it")
            os.rename(self._work.path / "bag", self.path)
        except OSError as exc:
            self.abort()
            raise LivoxVizError(f"{self.path}: cannot write the bag ({exc.strerror or exc}); nothing was kept") \
                from exc
        except BaseException:
            self.abort()
            raise
        self._work.remove()
        remove_dead_leftovers(self.path.absolute().parent)
        return self.path

    def abort(self) -> None:
        """Drop the bag; nothing is left behind."""
        if not self._closed:
            self._closed = True
            self._pending.clear()
            try:
                if self._bag is not None:
                    self._bag.close()
            except Exception as exc:  # the half-written bag is removed below anyway
                self.abort_error = str(exc)
        self._work.remove()

    def __enter__(self) -> RosbagWriter:
        return self

    def __exit__(self, kind, error, tb) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


def offered_qos(latched: bool = False):
    """The QoS a publisher offers, as ``ros2 bag record`` stores it (history unknown, depth 0, durations infinite).

    Reliable and volatile, as the Livox driver and tf2's broadcaster publish; ``latched`` (``/tf_static``):
    reliable and transient local, as tf2's static broadcaster publishes, so ``ros2 bag play`` offers it
    latched and a late subscriber (RViz) still receives it.
    """
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(9_223_372_036, 854_775_807)  # RMW_DURATION_INFINITE, as Humble and Jazzy record it
    return Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE,
               QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
               infinite, infinite, QosLiveliness.AUTOMATIC, infinite, False)


class FixedLayout:
    """CDR messages of one type whose only changing parts are the stamp and some float64 values.

    One message is serialized by rosbags with distinct sentinel numbers; their byte offsets make a
    numpy record type over the whole message, so thousands of messages are packed at once (rosbags
    builds one Python object tree per message, about 100 us each). The tests compare the packed
    bytes with rosbags' own serialization.

    Parameters
    ----------
    store : rosbags Typestore
    msgtype : str
    build : callable
        ``build(stamp_ns, values)`` -> the message, values ``(count,)`` float64.
    count : int
        Values per message.
    """

    _SEC, _NSEC = 2_000_000_011, 987_654_321

    def __init__(self, store, msgtype: str, build, count: int) -> None:
        sentinels = -1.0e300 / (1.0 + np.arange(count) * 0.37)
        data = bytes(store.serialize_cdr(build(self._SEC * 10**9 + self._NSEC, sentinels), msgtype))
        marks = [(np.array([self._SEC], "<i4").tobytes(), "<i4"), (np.array([self._NSEC], "<u4").tobytes(), "<u4")]
        marks += [(np.array([v], "<f8").tobytes(), "<f8") for v in sentinels]
        offsets = []
        for mark, _ in marks:
            where = data.find(mark)
            if where < 0 or data.find(mark, where + 1) >= 0:
                raise RuntimeError(f"{msgtype}: cannot place a field of the template (found {where})")
            offsets.append(where)
        self.dtype = np.dtype({"names": ["sec", "nsec", *(f"v{k}" for k in range(count))],
                               "formats": [kind for _, kind in marks], "offsets": offsets, "itemsize": len(data)})
        self.template = np.frombuffer(data, dtype=np.uint8)

    def pack(self, stamps_ns: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``(n,)`` records (each one message's bytes) for stamps ``(n,)`` ns and values ``(n, count)``."""
        # Copies of the whole template (strings and constants included), the numbers written over them.
        records = np.tile(self.template, (len(stamps_ns), 1)).view(self.dtype).reshape(len(stamps_ns))
        records["sec"] = stamps_ns // 1_000_000_000
        records["nsec"] = stamps_ns % 1_000_000_000
        for k in range(values.shape[1]):
            records[f"v{k}"] = values[:, k]
        return records


def custom_msg_cdr(stamp_ns: int, frame_id: str, xyz_flu: np.ndarray, offset_ns: np.ndarray,
                   line: np.ndarray, reflectivity: np.ndarray | None = None, tag: np.ndarray | None = None) -> bytes:
    """A ``livox_ros_driver2/msg/CustomMsg`` in little-endian CDR, built with numpy (rosbags would make a
    Python object per point); the tests check it byte for byte against rosbags' own serializer.

    Parameters
    ----------
    stamp_ns : int
        Header stamp and ``timebase``, ns.
    frame_id : str
    xyz_flu : (M, 3) float32
    offset_ns : (M,) int64
        Each point's time after ``timebase``, ns (< 2**32).
    line : (M,) uint8
    reflectivity, tag : (M,) uint8, optional
        Default 0 (no intensity) and 0x10 (a first return).
    """
    if offset_ns.size and (offset_ns.min() < 0 or offset_ns.max() >= 2**32):
        raise LivoxVizError("a CustomMsg's offset_time must fit uint32 ns (a frame under 4.29 s)")
    out = bytearray(b"\x00\x01\x00\x00")  # CDR, little-endian

    def align(size: int) -> None:
        out.extend(b"\x00" * (-(len(out) - 4) % size))

    name = frame_id.encode() + b"\x00"
    out += np.array([stamp_ns // 1_000_000_000], "<i4").tobytes() + np.array([stamp_ns % 1_000_000_000],
                                                                             "<u4").tobytes()
    out += np.array([len(name)], "<u4").tobytes() + name
    align(8)
    out += np.array([stamp_ns], "<u8").tobytes()
    align(4)
    out += np.array([len(offset_ns)], "<u4").tobytes()
    out += bytes([0, 0, 0, 0])  # lidar_id, rsvd[3]
    align(4)
    out += np.array([len(offset_ns)], "<u4").tobytes()
    points = np.zeros(len(offset_ns), dtype=_CUSTOM_POINT_DTYPE)
    points["offset_time"] = offset_ns
    points["x"], points["y"], points["z"] = xyz_flu[:, 0], xyz_flu[:, 1], xyz_flu[:, 2]
    points["line"] = line
    points["reflectivity"] = 0 if reflectivity is None else reflectivity
    points["tag"] = 0x10 if tag is None else tag
    body = points.tobytes()
    return bytes(out) + (body[:-1] if body else body)  # no padding after the last point


#: What one MCAP Message record holds before its data (opcode, record length, channel, sequence, log and publish
#: time), as rosbags' MCAP writer writes it.
_MCAP_MESSAGE = struct.Struct("<BQHIQQ")
#: rosbags' MCAP writer closes a chunk once it holds more than this many bytes.
_MCAP_CHUNK = 2**20


def append_mcap_messages(bag, messages: list) -> bool:
    """Append ``(stamp ns, connection, bytes)`` messages, in log order, to a rosbags ``Writer`` with MCAP storage,
    a batch at a time: the bytes, chunks and indexes its ``write`` would make one by one (rosbags builds each
    message's record in ten small writes through two layers, about 15 us a message: a bag's IMU, odometry and /tf
    are 600 messages a second of scan). Returns False, having written nothing, where the storage is not the MCAP
    writer this knows (another rosbags, per-message compression): the caller writes them one by one then.

    The tests compare a bag written this way with one written message by message, byte for byte.
    """
    storage = getattr(bag, "storage", None)
    chunk = getattr(storage, "chunk", None)
    if (type(storage).__name__ != "McapWriter" or not hasattr(chunk, "bio") or not hasattr(chunk, "msgs")
            or not hasattr(storage, "close_chunk") or not hasattr(storage, "channel_stats")
            or not hasattr(bag, "min_timestamp") or not hasattr(bag, "max_timestamp")
            or getattr(getattr(bag, "compression_mode", None), "name", "") == "MESSAGE"):
        return False
    pack = _MCAP_MESSAGE.pack
    head = _MCAP_MESSAGE.size
    stats, counts = storage.channel_stats, bag.counts
    pieces: list = []
    position = chunk.bio.tell()
    low, high = chunk.message_start_time, chunk.message_end_time
    for stamp, connection, data in messages:
        channel = connection.id
        size = len(data)
        chunk.msgs[channel].append((stamp, position))
        pieces += (pack(5, 22 + size, channel, 0, stamp, stamp), data)
        position += head + size
        stats[channel] += 1
        counts[channel] += 1
        low, high = min(low, stamp), max(high, stamp)
        if position > _MCAP_CHUNK:  # where its write closes the chunk: after the message that fills it
            chunk.bio.write(b"".join(pieces))
            pieces = []
            _note_times(storage, chunk, low, high)
            storage.close_chunk()
            chunk = storage.chunk
            position = chunk.bio.tell()
            low, high = chunk.message_start_time, chunk.message_end_time
    if pieces:
        chunk.bio.write(b"".join(pieces))
        _note_times(storage, chunk, low, high)
    if messages:  # in log order: the first is the earliest, the last the latest
        bag.min_timestamp = min(bag.min_timestamp, messages[0][0])
        bag.max_timestamp = max(bag.max_timestamp, messages[-1][0])
    return True


def _note_times(storage, chunk, low: int, high: int) -> None:
    chunk.message_start_time, chunk.message_end_time = low, high
    storage.message_start_time = min(low, storage.message_start_time)
    storage.message_end_time = max(high, storage.message_end_time)
