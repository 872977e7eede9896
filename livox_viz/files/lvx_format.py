"""Livox's own point-cloud files, LVX2 (Livox Viewer 2) and LVX 1.1 (Livox Viewer 0.x): their byte layouts and heads.

Laid out as Livox's "LVX2 Specifications" v1.0 (2023.06) and "LVX
Specifications" v1.1 (2020.05) say, and as Livox's own code writes and reads
them (Livox-SDK ``sample/lidar_lvx_file/lvx_file.h``, livox_ros_driver
``lvx_file.h``/``lds.h``, livox_ros_driver2 ``src/comm/pub_handler.cpp``).
Little-endian, no padding::

    public header   24 B  signature "livox_tech" char[16], version u8[4] (2.0.0.0 / 1.1.0.0), magic u32 0xAC0EA767
    private header   5 B  frame duration u32 (ms, 50), device count u8
    device info     63 B  (LVX2) lidar SN char[16], hub SN char[16], lidar id u32, lidar type u8 (reserved),
                          device type u8, extrinsic enable u8, roll pitch yaw f32 (deg), x y z f32 (m)
                    59 B  (LVX 1.1) lidar broadcast code char[16], hub code char[16], device index u8,
                          device type u8, extrinsic enable u8, roll pitch yaw f32 (deg), x y z f32 (m)
    frame header    24 B  current offset u64, next offset u64, frame index u64 (offsets from the file start)
    package         27 B  (LVX2) version u8, lidar id u32, lidar type u8, timestamp type u8, timestamp u64 (ns),
                          udp counter u16, data type u8, length u32 (bytes of points), frame counter u8, reserve u8[4]
                    19 B  (LVX 1.1) device index u8, version u8 (5), slot u8, lidar id u8, reserved u8,
                          status code u32, timestamp type u8, data type u8, timestamp u64 (ns)
                          then the points of the data type (fixed count, :data:`LVX1_DATA_TYPES`)

Points are in the sensor's own frame, x forward, y left, z up, integer
millimetres; a firing that returned nothing is (0, 0, 0). A package holds
consecutive firings: a driver gives point ``i`` the line ``i % lines`` (of
pulse ``i // echoes`` for a dual or triple return type) and the time
``timestamp + i * point interval``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import FRD_TO_FLU, matrix_to_euler

SIGNATURE = b"livox_tech"
MAGIC_CODE = 0xAC0EA767
#: The frame duration both formats are written with, milliseconds (Livox Viewer's and the SDK samples').
FRAME_MS = 50
LVX2_VERSION = (2, 0, 0, 0)
LVX1_VERSION = (1, 1, 0, 0)
#: Livox's formats by suffix.
LIVOX_FORMATS = (".lvx2", ".lvx")

PUBLIC_HEADER = np.dtype([("signature", "S16"), ("version", "u1", (4,)), ("magic_code", "<u4")])
PRIVATE_HEADER = np.dtype([("frame_duration", "<u4"), ("device_count", "u1")])
_EXTRINSIC = [("extrinsic_enable", "u1"), ("roll", "<f4"), ("pitch", "<f4"), ("yaw", "<f4"),
              ("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
LVX2_DEVICE = np.dtype([("lidar_sn", "S16"), ("hub_sn", "S16"), ("lidar_id", "<u4"), ("lidar_type", "u1"),
                        ("device_type", "u1"), *_EXTRINSIC])
LVX1_DEVICE = np.dtype([("lidar_sn", "S16"), ("hub_sn", "S16"), ("device_index", "u1"), ("device_type", "u1"),
                        *_EXTRINSIC])
FRAME_HEADER = np.dtype([("current_offset", "<u8"), ("next_offset", "<u8"), ("frame_index", "<u8")])
LVX2_PACKAGE = np.dtype([("version", "u1"), ("lidar_id", "<u4"), ("lidar_type", "u1"), ("timestamp_type", "u1"),
                         ("timestamp", "<u8"), ("udp_counter", "<u2"), ("data_type", "u1"), ("length", "<u4"),
                         ("frame_counter", "u1"), ("reserve", "u1", (4,))])
LVX1_PACKAGE = np.dtype([("device_index", "u1"), ("version", "u1"), ("slot", "u1"), ("lidar_id", "u1"),
                         ("reserved", "u1"), ("status_code", "<u4"), ("timestamp_type", "u1"), ("data_type", "u1"),
                         ("timestamp", "<u8")])
#: One return of the cartesian types: int32 mm x, y, z, reflectivity, tag (LVX2 type 1, LVX 1.1 types 2, 4, 7).
CARTESIAN_POINT = np.dtype([("x", "<i4"), ("y", "<i4"), ("z", "<i4"), ("reflectivity", "u1"), ("tag", "u1")])
#: LVX 1.1 type 0 (Mid-40/100): int32 mm x, y, z, reflectivity, no tag.
RAW_POINT = np.dtype([("x", "<i4"), ("y", "<i4"), ("z", "<i4"), ("reflectivity", "u1")])
#: The one version of a package's points livox_ros_driver reads from an LVX 1.1 (it refuses any other).
LVX1_PACKAGE_VERSION = 5
#: LVX2 packages' lidar type (SDK2's kLivoxLidarType), and the device info's "reserved" lidar type byte Livox
#: Viewer 2 records.
LVX2_LIDAR_TYPE, LVX2_DEVICE_LIDAR_TYPE = 8, 247
#: Timestamp types whose 8 bytes are nanoseconds (SDK1: 0 none, 1 PTP, 4 PPS; SDK2: 0 none, 1 gPTP, 2 GPS).
NS_TIMESTAMPS = {".lvx": (0, 1, 4), ".lvx2": (0, 1, 2)}


@dataclass(frozen=True)
class DataType:
    """A point data type: its number, firings a package, returns a firing, and the record of one return.

    ``None`` for ``point`` marks a type that is read past but holds no points (LVX 1.1's IMU, type 6)."""

    number: int
    firings: int
    echoes: int
    point: np.dtype | None
    size: int

    @property
    def points_bytes(self) -> int:
        """Bytes of one package's points."""
        return self.firings * self.echoes * self.size


#: LVX 1.1's data types (livox_ros_driver ``lds.h``: points a package, bytes a point, returns a point). The
#: spherical ones (1, 3, 5, 8) are known by size only: they are refused by name, not misread.
LVX1_DATA_TYPES = {
    0: DataType(0, 100, 1, RAW_POINT, 13),
    1: DataType(1, 100, 1, None, 9),
    2: DataType(2, 96, 1, CARTESIAN_POINT, 14),
    3: DataType(3, 96, 1, None, 10),
    4: DataType(4, 48, 2, CARTESIAN_POINT, 14),
    5: DataType(5, 48, 2, None, 8),
    6: DataType(6, 1, 1, None, 24),
    7: DataType(7, 30, 3, CARTESIAN_POINT, 14),
    8: DataType(8, 30, 3, None, 11),
}
LVX1_IMU = 6
LVX1_SPHERICAL = (1, 3, 5, 8)
#: LVX2's point types (SDK2): 1 cartesian high (int32 mm), 2 cartesian low (int16 cm), 3 spherical; 96 a package.
LVX2_DATA_TYPES = {1: DataType(1, 96, 1, CARTESIAN_POINT, 14)}
LVX2_KNOWN = {1: "cartesian int32 mm", 2: "cartesian int16 cm", 3: "spherical"}


@dataclass(frozen=True)
class HeadModel:
    """A Livox head as its files name it.

    Attributes
    ----------
    name : str
        Livox's name ("Mid-360").
    device_type : int
        The device info's device type.
    suffix : {".lvx2", ".lvx"}
        The format Livox's viewer for it reads.
    lines : int
        Lasers firing in turn: a driver's ``line = i % lines``.
    rate : int
        Firings per second of the real head (its drivers' point interval, 1e9 / rate ns).
    presets : tuple of str
        The shipped presets of this head (their names start so).
    """

    name: str
    device_type: int
    suffix: str
    lines: int
    rate: int
    presets: tuple[str, ...]

    @property
    def point_interval_ns(self) -> float:
        return 1e9 / self.rate


#: The heads each format takes (device types: SDK2's for LVX2, SDK1's ``livox_def.h`` for LVX 1.1; lines and rates
#: from livox_ros_driver(2)).
HEADS = (
    HeadModel("Mid-360", 9, ".lvx2", 4, 200_000, ("livox_mid360",)),
    HeadModel("HAP", 10, ".lvx2", 6, 452_000, ("livox_hap",)),
    HeadModel("Mid-40/100", 1, ".lvx", 1, 100_000, ("livox_mid40",)),
    HeadModel("Tele-15", 2, ".lvx", 6, 240_000, ("livox_tele15",)),
    HeadModel("Horizon", 3, ".lvx", 6, 240_000, ("livox_horizon",)),
    HeadModel("Mid-70", 6, ".lvx", 1, 100_000, ("livox_mid70",)),
    HeadModel("Avia", 7, ".lvx", 6, 240_000, ("livox_avia",)),
)


def heads_of(suffix: str) -> str:
    """``"Mid-360 (device type 9) or HAP (10)"``: the heads a format takes, for messages."""
    heads = [head for head in HEADS if head.suffix == suffix]
    names = [f"{head.name} ({'device type ' if k == 0 else ''}{head.device_type})" for k, head in enumerate(heads)]
    return ", ".join(names[:-1]) + " or " + names[-1]


def head_by_type(suffix: str, device_type: int) -> HeadModel | None:
    """The head of a device type in a format, or None."""
    return next((head for head in HEADS if head.suffix == suffix and head.device_type == device_type), None)


def head_named(name: str) -> HeadModel | None:
    """The head whose shipped presets ``name`` (a preset's or configuration's name) is one of or starts with."""
    stem = name.lower()
    return next((head for head in HEADS for preset in head.presets
                 if stem == preset or stem.startswith((preset + "_", preset + "-"))), None)


@dataclass(frozen=True)
class LivoxHead:
    """What an LVX file needs of the scan: the head, how it fires, where it sits.

    Parameters
    ----------
    model : HeadModel
    rate : int
        Firings per second of the scan (its point rate): the packages' timestamps follow it.
    lasers : int
        The scan's lasers; must be the head's ``lines``, so a driver's ``i % lines`` is our laser.
    echoes : int
        Returns a firing may hold: 1, or 2 and 3 (LVX 1.1's dual and triple return types).
    mount : Pose
        The sensor's pose on the vehicle (body FRD), written as the device's extrinsics.
    """

    model: HeadModel
    rate: int
    lasers: int
    echoes: int
    mount: Pose

    def __post_init__(self) -> None:
        if self.lasers != self.model.lines:
            raise LivoxVizError(f"the scan fires {self.lasers} lasers in turn, a {self.model.name} {self.model.lines}; "
                                f"allowed: a {self.model.name} configuration of {self.model.lines} (its drivers read "
                                f"line = i % {self.model.lines})")
        if self.rate <= 0:
            raise LivoxVizError(f"point rate {self.rate}; allowed: > 0")
        if self.data_type is None:
            kinds = {1: "single", 2: "dual", 3: "triple"}
            raise LivoxVizError(f"a {self.model.name} has no {kinds.get(self.echoes, str(self.echoes))} return "
                                f"{self.model.suffix} data type; allowed: single returns (or dual/triple in .lvx for "
                                "Tele-15, Horizon, Mid-70, Avia)")

    @property
    def data_type(self) -> DataType | None:
        """The package type written: LVX2 type 1; LVX 1.1 type 0 (Mid-40), 2, 4 (dual) or 7 (triple)."""
        if self.model.suffix == ".lvx2":
            return LVX2_DATA_TYPES[1] if self.echoes == 1 else None
        if self.model.device_type == 1:
            return LVX1_DATA_TYPES[0] if self.echoes == 1 else None
        return {1: LVX1_DATA_TYPES[2], 2: LVX1_DATA_TYPES[4], 3: LVX1_DATA_TYPES[7]}.get(self.echoes)

    def extrinsics(self) -> tuple[float, float, float, float, float, float]:
        """The mount as Livox's extrinsics: roll, pitch, yaw (degrees; ``Rz(yaw) Ry(pitch) Rx(roll)``, the SDKs'
        rotation) and x, y, z (metres), of the sensor's FLU frame in the vehicle's FLU frame."""
        rotation = FRD_TO_FLU @ self.mount.rotation @ FRD_TO_FLU
        angles = [math.degrees(a) for a in matrix_to_euler(rotation)]
        x, y, z = (FRD_TO_FLU @ self.mount.origin).tolist()
        return (angles[0], angles[1], angles[2], x, y, z)


def livox_head(suffix: str, name: str, rate: int, lasers: int, echoes: int, mount: Pose,
               type_id: int | None = None) -> LivoxHead:
    """The head a scan of configuration ``name`` is written as in a ``suffix`` file.

    Parameters
    ----------
    suffix : {".lvx2", ".lvx"}
    name : str
        The preset's or configuration's name (``livox_mid360``, ``livox_mid360-tuned-...``).
    rate, lasers, echoes : int
        The scan's firings per second, lasers and returns per firing.
    mount : Pose
    type_id : int, optional
        RflySim's TypeID: 23 is a Mid-360 whatever its name.

    Raises
    ------
    LivoxVizError
        One line naming the heads the format takes, when the configuration is none of them or another format's.
    """
    model = head_named(name)
    if model is None and type_id == 23:
        model = HEADS[0]
    presets = ", ".join(preset for head in HEADS if head.suffix == suffix for preset in head.presets)
    allowed = f"allowed: {suffix} takes {heads_of(suffix)} (presets {presets})"
    if model is None:
        raise LivoxVizError(f"{name} is no Livox head {suffix} knows; {allowed}")
    if model.suffix != suffix:
        raise LivoxVizError(f"a {model.name} is written as {model.suffix}, not {suffix}; {allowed}")
    return LivoxHead(model, rate, lasers, echoes, mount)


def head_for_config(suffix: str, config, name: str) -> LivoxHead:
    """The head a scan of ``config`` (a :class:`~livox_viz.config.sensor.SensorConfig` named ``name``) is written
    as in a ``suffix`` file: its point rate, lasers, returns a firing (the datasheet model's, 1 for ideal returns)
    and mount (:func:`livox_head`)."""
    from livox_viz.config.mount import sensor_mount

    echoes = config.return_params.returns_per_pulse if config.returns_model == "datasheet" else 1
    return livox_head(suffix, name, config.point_rate, config.lasers, echoes, sensor_mount(config), config.type_id)
