"""Point-cloud files: PLY and PCD (binary or ASCII), LAS 1.4, NPZ and CSV, streamed frame by frame.

Every writer takes frames one at a time (memory stays flat however long the
scan), writes into a work folder next to the destination and renames the
finished file over it on :meth:`PointCloudWriter.close`; on any failure (a full
disk included) the work folder is removed, the message names the file, and
the old file, if any, is kept. An existing read-only file is refused.

**A full disk.** PLY, PCD, CSV and LAS are written in place: their header goes
over room kept for it at the start of the points (a LAS's points are packed as
they come, :mod:`~livox_viz.files.las_stream`), and that file is renamed into
place, so finishing one needs no free space. An NPZ's columns are put together
at the end (:mod:`~livox_viz.files.npzstream`: by the kernel, a copy unless the
file system shares extents), and a LAS whose points outgrow the offset of its
first ones is assembled then too: the writer keeps room for that copy. Before each frame the writer checks that
the disk holds the frame and what finishing needs; where it does not, or where
a write fails all the same, nothing of that frame stays and the writer stops
(:class:`WritingStopped`): :meth:`PointCloudWriter.close` still makes the file
of the whole frames written before, which is what ``listen`` does with a
recording (``scan``, which can be run again, gives up and keeps the old file).

**Which points.** PLY, PCD, LAS and CSV hold what a RflySim client receives:
each point decoded from the int16 wire (steps of ``range / 32767``), in the
sensor frame at its own time (``sensor``) or placed in the world with the
sensor's pose at its own time (``world``); ``range`` is the decoded point's
distance. The NPZ, the full record, holds the wire's ``xyz_int16``, those
points decoded (``xyz_sensor``) and, only there, the points before the encoding
(``xyz_world``, ``range``: the ideal model's exact hits, the datasheet model's
measured points). Every file says so in its header, and what made it (``source``:
the preset, return model, seed, scene) when the writer is told.

**Frames and precision.** PLY, PCD and CSV are in the project's frames (sensor
FRD, world NED). World coordinates stay exact far from the origin (float32
would round them to 12 cm 2000 km out): float64 in PLY (which CloudCompare,
PDAL and Open3D read) and CSV; PCD keeps float32, because PCL and Open3D read
no binary float64 coordinates, relative to a whole-kilometre offset taken from
the first points and stated in its header (zero within 500 m of the origin).
Sensor coordinates are float32 (exact to 1e-7 of the range, far below the
int16 step). LAS is z-up, as every LAS viewer and GIS
expects: world ENU (x east, y north, z up), sensor FLU (x forward, y left, z
up), said in a WKT coordinate system (a local one) and in a livox-viz record;
its offset and scale are chosen from the data (0.1 mm wherever the cloud's
extent allows).

**What each file says of itself.** PLY and PCD in their header's comments, LAS
in its WKT and livox-viz records, NPZ in its ``frame_of_reference``. A CSV holds
only its column names and the values, so that ``pandas.read_csv(f)`` and
``numpy.genfromtxt(f, delimiter=",", names=True)`` read it with no options (a
``#`` line before the names was taken for the header by one and refused by the
other); what it is goes in a JSON sidecar beside it, ``<name>.csv.json``
(:func:`sidecar_path`), renamed into place just after the CSV.

**Types every reader takes.** PLY properties are ``float``, ``double``, ``int``
and ``uchar`` only: Open3D's tensor reader skips a ``uint`` property
("unsupported datatype"), so the frame index (and a recording's unsigned
numbers) are written as ``int``.

**Livox fields.** Every format carries each point's ``reflectivity`` (uint8,
0-150 Lambertian 0-100 %, 151-255 retroreflective), ``tag`` (SDK1: bits 0-1
spatial noise, 2-3 intensity noise, 4-5 return number), ``return_number`` and
``number_of_returns``: PLY, PCD and CSV fields and columns, NPZ arrays; LAS's
own ``intensity`` (the byte x 256, LAS's 16-bit scale), ``return_number`` and
``number_of_returns``, the byte and the tag as extra bytes.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping, Sequence
from contextlib import ExitStack
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

import numpy as np

from livox_viz.casting.point_frame import PointFrame
from livox_viz.core.atomic import WorkDir, atomic_path, resolve_destination
from livox_viz.core.errors import LivoxVizError, os_error_reason, quoted
from livox_viz.core.portable import free_disk_bytes, write_at
from livox_viz.core.rotations import enu_from_ned, flu_from_frd
from livox_viz.files.las_stream import LasStream, PackedFrame
from livox_viz.files.lvx_format import LIVOX_FORMATS, LivoxHead, heads_of
from livox_viz.files.lvx_write import LvxEncoder
from livox_viz.files.npzstream import NpzColumns
from livox_viz.files.text_rows import WHOLE, TextRows

FORMATS = (".ply", ".pcd", ".las", ".npz", ".csv", *LIVOX_FORMATS)
#: The formats that hold any frame (Livox's need a scan's firing order and head).
CLOUD_FORMATS = tuple(suffix for suffix in FORMATS if suffix not in LIVOX_FORMATS)
#: Formats written in place: the points go straight into the file, after room kept for the header (PLY, PCD) or
#: after the header itself (CSV, LVX2, LVX), so finishing one is a rename and needs no free space (an LVX's last
#: 50 ms frame, under a megabyte, is within :data:`FREE_MARGIN`).
IN_PLACE = (".ply", ".pcd", ".csv", *LIVOX_FORMATS)
#: Room kept at the start of a PLY or PCD for its header beyond what it holds with no point, bytes: the counts'
#: digits and a PCD's offset (a header that outgrows it is copied in front of the points instead).
HEADER_ROOM = 256
#: Free space left on the disk beyond a frame and what finishing the file needs, bytes (the file system's own
#: bookkeeping, the other writers of the disk between the check and the write).
FREE_MARGIN = 1 << 20
#: What finishing a LAS or NPZ needs beyond its points, per frame (an NPZ's frame poses and receiving table) and in
#: all (headers, members), bytes.
FINISH_PER_FRAME, FINISH_FIXED = 1024, 1 << 16
FRAMES = ("sensor", "world")
FRAME_DESCRIPTION = {
    "sensor": "sensor FRD (x forward, y right, z down), metres, at each point's own time",
    "world": "world NED (x north, y east, z down), metres",
}
#: LAS is z-up: the same frames turned as ROS turns them (REP 103).
LAS_FRAME_DESCRIPTION = {
    "sensor": "sensor FLU (x forward, y left, z up), metres, at each point's own time",
    "world": "world ENU (x east, y north, z up), metres; east = the scene's NED y, north = its x, up = -z",
}
#: The one rule for the points of PLY, PCD, LAS and CSV (stated in every file).
POINTS_RULE = ("points as a RflySim client decodes them from the int16 wire (range/32767 steps); world: each "
               "placed with the sensor pose at its own time; range: the decoded point's distance")
NPZ_RULE = ("xyz_int16: the wire (sensor FRD); xyz_sensor: those points decoded (xyz_int16 * range_max / 32767), "
            "as every other format holds them; xyz_world and range: each point before the int16 encoding (the ideal "
            "model's exact hit; the datasheet model's measured point, its range and angular noise included), which "
            "only the NPZ keeps")
#: LAS coordinates are stored to this step (metres) unless the cloud is too wide for int32 at it.
LAS_SCALE = 1e-4


#: The Livox per-point fields every format carries.
LIVOX_FIELDS: tuple[str, ...] = ("reflectivity", "tag", "return_number", "number_of_returns")


def point_fields(coordinates: str, file_format: str = ".ply") -> tuple[tuple[str, str], ...]:
    """Per-point fields of PLY, PCD and CSV with their numpy types; world x, y, z are float64 but in a PCD; a PLY
    has no unsigned 32-bit field (:func:`file_type`)."""
    xyz = "<f8" if coordinates == "world" and file_format != ".pcd" else "<f4"
    return (("x", xyz), ("y", xyz), ("z", xyz), ("range", "<f4"), ("time", "<f8"),
            ("frame", file_type("<u4", file_format)), *((name, "u1") for name in LIVOX_FIELDS))


#: The PLY property types every reader takes: Open3D's tensor reader (``t.io``) reads ``uint8``/``uchar``,
#: ``uint16``, ``int32``/``int``, ``float32``/``float`` and ``float64``/``double``, and skips any other property.
PLY_TYPES = {"<f4": "float", "<f8": "double", "<i4": "int", "u1": "uchar"}


def file_type(numpy_type: str, file_format: str) -> str:
    """The numpy type a field of ``numpy_type`` is written with in ``file_format``: a PLY's unsigned 32-bit field
    is a signed one (frame numbers and sessions stay far below 2^31), everything else as given."""
    return "<i4" if file_format == ".ply" and numpy_type == "<u4" else numpy_type


def sidecar_path(path: str | os.PathLike[str]) -> Path | None:
    """The JSON sidecar a :class:`PointCloudWriter` writes beside ``path``: ``<name>.csv.json`` for a CSV (which
    holds only its column names and values), else None."""
    path = Path(path)
    return path.with_name(path.name + ".json") if path.suffix.lower() == ".csv" else None


#: The sensor-frame fields (see :func:`point_fields`).
POINT_FIELDS = point_fields("sensor")
#: The LAS body, kept as raw records until the file's offset and scale are known: x y z in the LAS frame.
_LAS_BODY: tuple[tuple[str, str], ...] = (
    ("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("gps_time", "<f8"), ("range", "<f4"), ("frame", "<u4"),
    ("return_number", "u1"), ("number_of_returns", "u1"), ("intensity", "<u2"), ("reflectivity", "u1"), ("tag", "u1"),
)
#: NPZ columns, one row per point; ``frame_pose`` holds one row per frame: index, then the sensor's
#: posAng (x, y, z, roll, pitch, yaw) at the frame's first ray and just after its last.
_NPZ_ARRAYS: dict[str, tuple[str, tuple[int, ...]]] = {
    "xyz_sensor": ("<f8", (3,)),
    "xyz_world": ("<f8", (3,)),
    "xyz_int16": ("<i2", (3,)),
    "range": ("<f8", ()),
    "t": ("<f8", ()),
    "frame": ("<i8", ()),
    **{name: ("u1", ()) for name in LIVOX_FIELDS},
}


def frame_points(frame: PointFrame, coordinates: str) -> np.ndarray:
    """``(M, 3)`` float64 the decoded points of the frame in ``coordinates`` (FRD or NED), metres."""
    return frame.xyz_decoded if coordinates == "sensor" else frame.xyz_world_decoded


def decoded_range(frame: PointFrame) -> np.ndarray:
    """``(M,)`` float64 the length of each decoded point, metres: ``numpy.linalg.norm(xyz, axis=1)`` bit for bit,
    column by column (numpy's reduction across three columns cost six times as much, 45 ns a point)."""
    xyz = frame.xyz_decoded
    return np.sqrt(xyz[:, 0] * xyz[:, 0] + xyz[:, 1] * xyz[:, 1] + xyz[:, 2] * xyz[:, 2])


def frame_records(frame: PointFrame, coordinates: str, extra_fields: Sequence[tuple[str, str]] = (),
                  extra: Mapping[str, np.ndarray | float] | None = None, file_format: str = ".ply",
                  offset: np.ndarray | None = None) -> np.ndarray:
    """The frame's points as a structured array of :func:`point_fields` and ``extra_fields``, ``(M,)``;
    ``offset`` ``(3,)`` metres is taken off x, y, z."""
    xyz = frame_points(frame, coordinates) - (0.0 if offset is None else offset)
    records = np.empty(len(frame), dtype=[*point_fields(coordinates, file_format),
                                          *((name, file_type(t, file_format)) for name, t in extra_fields)])
    records["x"], records["y"], records["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    records["range"] = decoded_range(frame)
    records["time"] = frame.t
    records["frame"] = frame.index
    for name in LIVOX_FIELDS:
        records[name] = getattr(frame, name)
    for name, _ in extra_fields:
        records[name] = (extra or {})[name]
    return records


def frame_columns(frame: PointFrame, coordinates: str, extra_fields: Sequence[tuple[str, str]] = (),
                  extra: Mapping[str, np.ndarray | float] | None = None, file_format: str = ".csv",
                  offset: np.ndarray | None = None) -> np.ndarray:
    """``(M, k)`` float64: the values :func:`frame_records` holds, column by column (each rounded to its field's
    type first), for the text formats, without the records in between."""
    fields = (*point_fields(coordinates, file_format), *((name, file_type(t, file_format)) for name, t in extra_fields))
    values = np.empty((len(frame), len(fields)))
    xyz = frame_points(frame, coordinates) - (0.0 if offset is None else offset)
    values[:, :3] = xyz.astype(np.float32) if fields[0][1] == "<f4" else xyz
    values[:, 3] = decoded_range(frame).astype(np.float32)
    values[:, 4] = frame.t
    values[:, 5] = frame.index
    for column, name in enumerate(LIVOX_FIELDS, start=6):
        values[:, column] = getattr(frame, name)
    for column, (name, kind) in enumerate(fields[6 + len(LIVOX_FIELDS):], start=6 + len(LIVOX_FIELDS)):
        values[:, column] = np.asarray((extra or {})[name]).astype(kind)
    return values


class WritingStopped(LivoxVizError):
    """A frame could not be written (a full disk): the file holds the whole frames before it, and the writer takes
    no more; :meth:`PointCloudWriter.close` still finishes the file of those frames."""


def free_bytes(folder: str | os.PathLike[str]) -> int:
    """Bytes this process may still write on the disk holding ``folder`` (root may use the blocks kept for it)."""
    return free_disk_bytes(folder)


class PointCloudWriter:
    """Streams frames into one point-cloud file; the format follows the extension.

    Parameters
    ----------
    path : path-like
        Destination: ``.ply``, ``.pcd``, ``.las``, ``.npz``, ``.csv``, or Livox's ``.lvx2`` and ``.lvx``
        (:mod:`~livox_viz.files.lvx_write`).
    coordinates : {"sensor", "world"}
        Which points PLY/PCD/LAS/CSV hold (NPZ holds both; LVX2 and LVX always the sensor's, Livox's FLU).
    ascii : bool
        ASCII instead of binary PLY/PCD.
    extra_fields : sequence of (name, numpy type)
        Per-point fields after :func:`point_fields` (an NPZ column, a LAS extra dimension), e.g. a received
        frame's ``("sender_time", "<f8")``; :meth:`write` is given their values. Types: ``<f8``, ``<i4``, ``<u4``.
    source : str
        What made the cloud, one line (``scan`` writes e.g. ``"livox-viz 0.1.0 scan of livox_mid70 (datasheet
        returns, seed 0) in urban from t = 0, fixed"``),
        stated in the header of every format (PLY and PCD comments, the CSV's sidecar, LAS's livox-viz
        record, the NPZ's ``frame_of_reference``); none when empty.
    npz_rule : str
        What the NPZ's arrays are, stated in its ``frame_of_reference`` (default :data:`NPZ_RULE`, a scan's).
    livox : LivoxHead, optional
        For ``.lvx2`` and ``.lvx`` (required there): the head, its firing rate and lasers, and the mount
        (:func:`~livox_viz.files.lvx_format.livox_head`).

    Attributes
    ----------
    npz_arrays : dict of str to ndarray
        Arrays an NPZ gets besides its columns when it is closed (e.g. one row per received frame).
    count, frames : int
        Points and frames written.
    stopped : str
        Why writing stopped (a full disk), else empty: :meth:`close` makes the file of the frames before.

    Examples
    --------
    >>> with PointCloudWriter("scan.ply") as writer:      # doctest: +SKIP
    ...     for frame in scanner.frames(1.0):
    ...         writer.write(frame)
    """

    def __init__(self, path: str | os.PathLike[str], coordinates: str = "sensor", ascii: bool = False,
                 extra_fields: Sequence[tuple[str, str]] = (), source: str = "", npz_rule: str = NPZ_RULE,
                 livox: LivoxHead | None = None) -> None:
        self.path = Path(path)
        self.source = " ".join(source.split())  # one line in every header
        self.npz_rule = npz_rule
        self.format = self.path.suffix.lower()
        if self.format not in FORMATS:
            raise LivoxVizError(f"{self.path}: unknown format {self.format or '(none)'}; allowed: {', '.join(FORMATS)}")
        if coordinates not in FRAMES:
            raise LivoxVizError(f"coordinates {quoted(coordinates)}; allowed: {' or '.join(FRAMES)}")
        #: An LVX2's or LVX's packages and frames (None for another format).
        self._lvx: LvxEncoder | None = None
        if self.format in LIVOX_FORMATS:
            if livox is None:
                raise LivoxVizError(f"{self.path}: {self.format} needs the scan's Livox head; allowed: {self.format} "
                                    f"from scan, batch or the window's export of {heads_of(self.format)}")
            if livox.model.suffix != self.format:
                raise LivoxVizError(f"{self.path}: a {livox.model.name} is written as {livox.model.suffix}; allowed: "
                                    f"{self.format} for {heads_of(self.format)}")
            if extra_fields:
                raise LivoxVizError(f"{self.path}: {self.format} holds Livox's fields only; allowed: no extra fields")
            if coordinates != "sensor":
                raise LivoxVizError(f"{self.path}: {self.format} holds points in the sensor's frame (Livox's x "
                                    "forward, y left, z up), the mount as the device's extrinsics; allowed: "
                                    "coordinates sensor")
            self._lvx = LvxEncoder(livox)
        self.coordinates = coordinates
        self.ascii = ascii
        self.extra_fields = tuple(extra_fields)
        self.npz_arrays: dict[str, np.ndarray] = {}
        self.count = 0
        self.frames = 0
        self.stopped = ""
        #: Bytes of the points written (the body, with its header or the room kept for it; an NPZ's columns).
        self._written = 0
        #: The room kept for a PLY's or PCD's header at the start of the body, bytes.
        self._header_room = 0
        #: A failed write could not be cut back to whole frames: closing keeps nothing.
        self._unusable = False
        self._body: BinaryIO | None = None
        #: A LAS written in place; None for another format, or once a point did not fit its first offset and
        #: scale (then its raw records are assembled at the end).
        self._las: LasStream | None = None
        #: The frame being written's LAS records as packed by :attr:`_las`.
        self._packed: PackedFrame | None = None
        #: The frame being written's LVX bytes and the encoder's state after them.
        self._lvx_packed = None
        self._npz: NpzColumns | None = None
        self._npz_poses: NpzColumns | None = None
        #: Where the NPZ's points and poses stood before the frame being appended (a failed frame is cut back to it).
        self._npz_checkpoints: tuple[tuple[int, dict[str, int]], tuple[int, dict[str, int]]] = ((0, {}), (0, {}))
        #: World PCD: metres taken off every point (whole kilometres, from the first points; stated in the header).
        self.offset: np.ndarray | None = None
        self._low = np.full(3, np.inf)
        self._high = np.full(3, -np.inf)
        self._closed = False
        #: CSV and ASCII PLY/PCD: the text of the rows, as ``numpy.savetxt`` writes it.
        self._text: TextRows | None = None
        if self.format == ".csv" or (ascii and self.format in (".ply", ".pcd")):
            decimals = [6] * 4 + [9, WHOLE] + [WHOLE] * len(LIVOX_FIELDS) + [
                9 if t[1] == "f" else WHOLE for _, t in self.extra_fields]
            self._text = TextRows(decimals, "," if self.format == ".csv" else " ")
        #: Why closing a part failed during an abort, if it did.
        self.abort_error = ""
        # Named (and the destination checked) before anything exists; made inside the try, so a signal
        # arriving at any moment leaves nothing behind.
        self._work = WorkDir(self.path)
        sidecar = sidecar_path(self.path)
        #: The CSV's sidecar (checked now, written by :meth:`close`), else None.
        self.sidecar = None if sidecar is None else resolve_destination(sidecar)
        try:
            self._work.create()
            self._open()
        except BaseException:
            self.abort()
            raise

    def _open(self) -> None:
        work = self._work.path
        if self.format == ".npz":
            self._npz = NpzColumns(work, {**_NPZ_ARRAYS, **{name: (t, ()) for name, t in self.extra_fields}})
            # A frame's poses on disk too, as its points are: a list of them grew by some 230 bytes a frame (3.6
            # million frames of an hour of a 1000 Hz configuration: 830 MB).
            self._npz_poses = NpzColumns(work, {"frame_pose": ("<f8", (13,))})
            return
        # Unbuffered: what a failed write left can be cut off (a buffer would still hold it and write it later).
        self._body = open(work / "body", "wb", buffering=0)
        if self._lvx is not None:  # Livox's headers: all known before the first point
            start = self._lvx.header
        elif self.format == ".csv":  # the column names alone: what the file is goes in its sidecar
            start = (",".join(name for name, _ in self._fields) + "\n").encode()
        elif self.format in IN_PLACE:
            self._header_room = len(self._header()) + HEADER_ROOM
            start = b" " * self._header_room
        else:  # a LAS: its points packed as they come, after room for its header
            self._las = LasStream(lambda offset, scale: _las_header(self.coordinates, offset, scale,
                                                                    self.extra_fields, self.source),
                                  las_offset_and_scale, tuple(name for name, _ in self.extra_fields))
            start = bytes(self._las.header_size)
        self._put(start)
        self._written = len(start)

    @property
    def _fields(self) -> tuple[tuple[str, str], ...]:
        return (*point_fields(self.coordinates, self.format),
                *((name, file_type(t, self.format)) for name, t in self.extra_fields))

    def write(self, frame: PointFrame, extra: Mapping[str, np.ndarray | float] | None = None) -> None:
        """Append one frame's returns; ``extra`` holds the values of ``extra_fields`` (per point, or one per frame).

        Raises
        ------
        LivoxVizError
            If the writer is closed, or writing fails (a full disk): the message names the file.
        """
        if self._closed:
            raise LivoxVizError(f"{self.path}: the writer is closed")
        if self.stopped:
            raise WritingStopped(f"{self.path}: {self.stopped}; the old file, if any, is kept")
        values = {name: np.broadcast_to(np.asarray((extra or {})[name], dtype=t), (len(frame),))
                  for name, t in self.extra_fields}
        if self._npz is not None:
            payload: list[bytes | memoryview] | dict[str, np.ndarray] = {
                "xyz_sensor": frame.xyz_decoded, "xyz_world": frame.xyz_world, "xyz_int16": frame.xyz_int16,
                "range": frame.range_m, "t": frame.t, "frame": np.full(len(frame), frame.index),
                **{name: getattr(frame, name) for name in LIVOX_FIELDS}, **values}
            size = self._npz.chunk_bytes(payload)
        else:
            payload = self._encode(frame, values)
            size = sum(len(piece) for piece in payload)
        self._make_room(size)
        packed = self._packed
        lvx_packed = self._lvx_packed
        try:
            if isinstance(payload, dict):
                assert self._npz is not None
                assert self._npz_poses is not None
                self._npz_checkpoints = (self._npz.checkpoint(), self._npz_poses.checkpoint())
                self._npz.append(payload)
                self._npz_poses.append({"frame_pose": np.concatenate([[frame.index], frame.sensor_pose.as_array(),
                                                                      frame.end_pose.as_array()])[None]})
            else:
                for piece in payload:
                    self._put(piece)
        except OSError as exc:
            self._cut_back()
            self.stopped = f"cannot write ({os_error_reason(exc)})"
            raise WritingStopped(f"{self.path}: {self.stopped}; the old file, if any, is kept") from exc
        self._written += size
        self.count += len(frame)
        self.frames += 1
        if packed is not None and self._las is not None:
            self._las.commit(packed)
        if lvx_packed is not None and self._lvx is not None:
            self._lvx.commit(lvx_packed)

    def _make_room(self, size: int) -> None:
        """Stop writing (:class:`WritingStopped`, nothing of the frame written) unless the disk holds ``size`` more
        bytes, what finishing the file will then need, and :data:`FREE_MARGIN`."""
        in_place = self.format in IN_PLACE or self._las is not None
        finish = 0 if in_place else (self._written + size + FINISH_FIXED + FINISH_PER_FRAME * (self.frames + 1))
        need = size + finish + FREE_MARGIN
        free = free_bytes(self._work.path)
        if free < need:
            self.stopped = (f"the disk is full ({free / 2**20:.1f} MiB free; the next frame and finishing the file "
                            f"need {need / 2**20:.1f} MiB)")
            raise WritingStopped(f"{self.path}: {self.stopped}; the old file, if any, is kept")

    def _encode(self, frame: PointFrame, extra: dict[str, np.ndarray]) -> list[bytes | memoryview]:
        """A frame's bytes in the body, in pieces: LAS's raw records, or the points as the file holds them."""
        self._packed = None
        self._lvx_packed = None
        if self._lvx is not None:
            self._lvx_packed = self._lvx.pack(frame)
            return list(self._lvx_packed.data)
        if self.format == ".las":
            if self._las is not None:
                self._packed = self._las.pack(*_las_columns(frame, self.coordinates, extra))
                if self._packed is not None:
                    return [self._packed.data]
                self._las_to_raw()  # wider than the first points' offset and scale hold: assembled at the end
            records = _las_records(frame, self.coordinates, self.extra_fields, extra)
            if len(records):
                self._low = np.minimum(self._low, [records[axis].min() for axis in "xyz"])
                self._high = np.maximum(self._high, [records[axis].max() for axis in "xyz"])
            return [records.tobytes()]
        if self.format == ".pcd" and self.coordinates == "world" and self.offset is None and len(frame):
            self.offset = np.round(np.median(frame_points(frame, "world"), axis=0) / 1000.0) * 1000.0 + 0.0  # no -0
        if self._text is not None:
            return self._text.format(frame_columns(frame, self.coordinates, self.extra_fields, extra, self.format,
                                                   self.offset))
        return [frame_records(frame, self.coordinates, self.extra_fields, extra, self.format, self.offset).tobytes()]

    def _las_to_raw(self) -> None:
        """A LAS whose points outgrew the offset and scale of its first: its points so far turned back into raw
        records (each its 0.1 mm grid point), assembled with an offset and scale for all of them at the end."""
        assert self._las is not None and self._body is not None
        stream, self._las = self._las, None
        body, raw = self._work.path / "body", self._work.path / "raw"
        raw_dtype = np.dtype([*_LAS_BODY, *self.extra_fields])
        rows = 1 << 16
        with open(body, "rb") as packed, open(raw, "wb") as out:
            packed.seek(stream.header_size)
            while block := packed.read(rows * stream.dtype.itemsize):
                points = np.frombuffer(block, dtype=stream.dtype)
                records = np.zeros(len(points), dtype=raw_dtype)
                for k, (axis, field) in enumerate(zip("xyz", "XYZ", strict=True)):
                    records[axis] = points[field] * stream.scale[k] + stream.offset[k]
                records["return_number"] = points["bit_fields"] & 0x0F
                records["number_of_returns"] = points["bit_fields"] >> 4
                for name in ("gps_time", "range", "frame", "intensity", "reflectivity", "tag",
                             *(name for name, _ in self.extra_fields)):
                    records[name] = points[name]
                if len(records):
                    self._low = np.minimum(self._low, [records[axis].min() for axis in "xyz"])
                    self._high = np.maximum(self._high, [records[axis].max() for axis in "xyz"])
                out.write(records.tobytes())
        self._body.close()
        os.replace(raw, body)
        self._body = open(body, "ab", buffering=0)
        self._written = body.stat().st_size

    def _put(self, data: bytes | memoryview) -> None:
        """Append ``data`` to the body (an unbuffered file may take a write in pieces)."""
        assert self._body is not None
        view = memoryview(data)
        while view.nbytes:
            done = self._body.write(view)
            view = view[done:]

    def _cut_back(self) -> None:
        """After a failed write: the body or the NPZ's columns cut back to the whole frames written."""
        try:
            if self._npz is not None:
                assert self._npz_poses is not None
                # Both back to the frames before the one that failed (its points may be whole, its pose not).
                points, poses = self._npz_checkpoints
                self._npz.cut_to_rows(points)
                self._npz_poses.cut_to_rows(poses)
            elif self._body is not None:
                os.ftruncate(self._body.fileno(), self._written)
                self._body.seek(self._written)
        except OSError:  # the frames cannot be told apart any more: nothing of them is kept
            self._unusable = True

    def close(self) -> Path:
        """Finish the file and move it into place; returns its path.

        Raises
        ------
        LivoxVizError
            Naming the file, if it cannot be finished (the work folder is removed, the old file kept).
        """
        if self._closed:
            return self.path
        if self._unusable:
            self.abort()
            raise LivoxVizError(f"{self.path}: {self.stopped}; the old file, if any, is kept")
        try:
            with ExitStack() as sidecar:
                if self.sidecar is not None:  # written first, renamed into place just after the file
                    self._write_sidecar(sidecar.enter_context(atomic_path(self.sidecar)))
                self._finish()
        finally:
            self.abort()
        return self.path

    def _write_sidecar(self, tmp: Path) -> None:
        """What a CSV is (it holds only its column names and values), as JSON."""
        about = {"file": self.path.name, "what": "livox-viz point cloud, one row per point",
                 **({"source": self.source} if self.source else {}), "coordinates": self.coordinates,
                 "frame": FRAME_DESCRIPTION[self.coordinates], "points": POINTS_RULE, "rows": self.count,
                 "frames": self.frames, "columns": [name for name, _ in self._fields]}
        tmp.write_text(json.dumps(about, indent=1) + "\n", encoding="utf-8")

    def _finish(self) -> None:
        """The file finished and renamed into place."""
        with atomic_path(self.path) as tmp:
            if self.format in IN_PLACE or self._las is not None:
                self._finish_in_place(tmp)
            elif self._npz is not None:
                assert self._npz_poses is not None
                about = json.dumps({**FRAME_DESCRIPTION, "points": self.npz_rule,
                                    **({"source": self.source} if self.source else {}),
                                    "frame_pose": "index, then the sensor's pose at the frame's first ray and just "
                                    "after its last: x y z (m, world NED) roll pitch yaw (rad) each"})
                self._npz.finish(tmp, more=(self._npz_poses,),
                                 extra={**self.npz_arrays, "frame_of_reference": np.array(about)})
            else:
                assert self._body is not None
                self._body.close()
                self._finish_las(tmp)

    def _finish_in_place(self, tmp: Path) -> None:
        """A PLY, PCD, CSV or LAS: its header over the room kept for it, and the body renamed to ``tmp``."""
        assert self._body is not None
        body = self._work.path / "body"
        if self._las is not None:
            write_at(self._body, self._las.header(), 0)
        elif self._lvx is not None:  # the last package and frame; the headers are written already
            self._put(self._lvx.finish())
        elif self.format != ".csv":
            header = self._header(self._header_room)
            if header is not None:
                write_at(self._body, header, 0)
            else:  # a header that outgrew its room (an offset of astronomical size): in front of a copy
                self._body.close()
                with open(tmp, "wb") as out, open(body, "rb") as points:
                    out.write(self._header())
                    points.seek(self._header_room)
                    shutil.copyfileobj(points, out, 1 << 20)
                return
        self._body.close()
        os.replace(body, tmp)

    def abort(self) -> None:
        """Drop everything written so far; the destination is left as it was, the work folder removed."""
        self._closed = True
        try:
            if self._body is not None and not self._body.closed:
                try:
                    self._body.close()
                except OSError as exc:  # its unwritten buffer: a full disk; the folder goes anyway
                    self.abort_error = os_error_reason(exc)
            if self._npz is not None:
                self._npz.discard()
            if self._npz_poses is not None:
                self._npz_poses.discard()
        finally:
            self._work.remove()

    def __enter__(self) -> PointCloudWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()

    # Headers -------------------------------------------------------------------------
    def _header(self, room: int | None = None) -> bytes | None:
        """The PLY's or PCD's header; with ``room``, exactly that long (a comment line fills it), or None when it
        does not fit."""
        lines = self._header_lines()
        text = "\n".join(lines) + "\n"
        if room is None:
            return text.encode()
        fill = room - len(text.encode()) - 1  # the filling line's own newline
        comment = "comment" if self.format == ".ply" else "#"
        if fill < len(comment) + 1:
            return None
        # The last comment, after those a reader shows first.
        last = next(k for k, line in enumerate(lines) if line.startswith(("element", "VERSION")))
        lines.insert(last, comment + " " * (fill - len(comment)))
        return ("\n".join(lines) + "\n").encode()

    def _header_lines(self) -> list[str]:
        fields = self._fields
        frame = f"frame {self.coordinates}: {FRAME_DESCRIPTION[self.coordinates]}"
        if self.format == ".ply":
            encoding = "ascii" if self.ascii else "binary_little_endian"
            lines = ["ply", f"format {encoding} 1.0", "comment livox-viz scan",
                     *([f"comment source: {self.source}"] if self.source else []), f"comment {frame}",
                     f"comment {POINTS_RULE}", f"element vertex {self.count}"]
            lines += [f"property {PLY_TYPES[t]} {name}" for name, t in fields]
            lines.append("end_header")
            return lines
        sizes = {"<f4": ("4", "F"), "<f8": ("8", "F"), "<u4": ("4", "U"), "<i4": ("4", "I"), "u1": ("1", "U")}
        offset = np.zeros(3) if self.offset is None else self.offset
        lines = [
            f"# .PCD v0.7 - livox-viz scan; {frame}",
            *([f"# source: {self.source}"] if self.source else []),
            f"# {POINTS_RULE}",
            *([f"# offset: the point is (x, y, z) + ({offset[0]:.0f}, {offset[1]:.0f}, {offset[2]:.0f}) m in the world"]
              if self.coordinates == "world" else []),
            "VERSION 0.7",
            "FIELDS " + " ".join(name for name, _ in fields),
            "SIZE " + " ".join(sizes[t][0] for _, t in fields),
            "TYPE " + " ".join(sizes[t][1] for _, t in fields),
            "COUNT " + " ".join("1" for _ in fields),
            f"WIDTH {self.count}",
            "HEIGHT 1",
            "VIEWPOINT 0 0 0 1 0 0 0",
            f"POINTS {self.count}",
            f"DATA {'ascii' if self.ascii else 'binary'}",
        ]
        return lines

    def _finish_las(self, tmp: Path) -> None:
        """The LAS file from the raw body, with an offset and scale that hold every point."""
        import laspy

        offset, scale = las_offset_and_scale(self._low, self._high)
        header = _las_header(self.coordinates, offset, scale, self.extra_fields, self.source)
        body_dtype = np.dtype([*_LAS_BODY, *self.extra_fields])
        block = bytearray(body_dtype.itemsize << 19)
        with laspy.open(tmp, mode="w", header=header) as writer, open(self._work.path / "body", "rb") as body:
            while size := body.readinto(block):
                records = np.frombuffer(block, dtype=body_dtype, count=size // body_dtype.itemsize)
                points = laspy.ScaleAwarePointRecord.zeros(len(records), header=writer.header)
                # The integers themselves: offset and scale were chosen so that every point fits.
                points.X, points.Y, points.Z = (np.round((records[axis] - offset[k]) / scale[k]).astype(np.int32)
                                                for k, axis in enumerate("xyz"))
                for name in ("gps_time", "range", "frame", "return_number", "number_of_returns", "intensity",
                             "reflectivity", "tag", *(name for name, _ in self.extra_fields)):
                    points[name] = records[name]
                writer.write_points(points)


def las_offset_and_scale(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A LAS offset (whole metres, the middle of the data) and scale (:data:`LAS_SCALE`, coarser only where the
    extent does not fit int32 at it) for points within ``low``..``high`` ``(3,)`` metres; zeros if empty."""
    if not np.all(np.isfinite(low)):
        return np.zeros(3), np.full(3, LAS_SCALE)
    offset = np.round((low + high) / 2)
    half = np.maximum(np.abs(high - offset), np.abs(low - offset))
    limit = 2**31 - 2**20  # a margin under int32 for rounding
    scale = np.full(3, LAS_SCALE)
    too_wide = half / scale > limit
    scale[too_wide] = 10.0 ** np.ceil(np.log10(half[too_wide] / limit))
    return offset, scale


def _las_wkt(coordinates: str) -> str:
    """A local (engineering) WKT coordinate system naming the LAS frame's axes."""
    if coordinates == "world":
        name, axes = "livox-viz world ENU (east, north, up)", ("EAST", "NORTH", "UP")
    else:
        name, axes = "livox-viz sensor FLU (forward, left, up)", ("FORWARD", "LEFT", "UP")
    # WKT1 axis directions are NORTH/SOUTH/EAST/WEST/UP/DOWN/OTHER: forward and left are OTHER.
    direction = {"FORWARD": "OTHER", "LEFT": "OTHER"}
    listed = ",".join(f'AXIS["{label}",{direction.get(label, label)}]' for label in axes)
    return f'LOCAL_CS["{name}",LOCAL_DATUM["livox-viz scene origin",0],UNIT["metre",1],{listed}]'


def _las_header(coordinates: str, offset: np.ndarray, scale: np.ndarray,
                extra_fields: Sequence[tuple[str, str]] = (), source: str = ""):
    import laspy
    from laspy.vlrs.known import WktCoordinateSystemVlr

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.offsets = offset
    header.scales = scale
    header.global_encoding.wkt = True  # required for point formats 6-10 (LAS 1.4 R15)
    header.add_extra_dims([laspy.ExtraBytesParams("range", np.float32, description="range m"),
                           laspy.ExtraBytesParams("frame", np.uint32, description="frame index"),
                           laspy.ExtraBytesParams("reflectivity", np.uint8, description="Livox reflectivity"),
                           laspy.ExtraBytesParams("tag", np.uint8, description="Livox tag (SDK1)"),
                           *(laspy.ExtraBytesParams(name, np.dtype(t).newbyteorder("=")) for name, t in extra_fields)])
    header.generating_software = "livox-viz"
    header.system_identifier = f"livox-viz {coordinates}"[:32]
    header.vlrs.append(WktCoordinateSystemVlr(_las_wkt(coordinates)))
    metadata = {"frame": coordinates, "description": LAS_FRAME_DESCRIPTION[coordinates], "points": POINTS_RULE,
                "gps_time": "seconds since the scan start", **({"source": source} if source else {})}
    header.vlrs.append(laspy.VLR("livox-viz", 1, f"frame: {coordinates}"[:32], json.dumps(metadata).encode()))
    return header


def _las_columns(frame: PointFrame, coordinates: str, extra: Mapping[str, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, dict[str, np.ndarray | float]]:
    """The frame's decoded points turned z-up (world ENU, sensor FLU) ``(M, 3)`` and its LAS fields by name (the
    extra ones from ``extra``)."""
    xyz = frame_points(frame, coordinates)
    xyz = enu_from_ned(xyz) if coordinates == "world" else flu_from_frd(xyz)
    # LAS keeps intensity on 16 bits: the byte times 256 (the LAS 1.4 normalisation of an 8-bit sensor).
    return xyz, {"gps_time": frame.t, "range": decoded_range(frame), "frame": frame.index,
                 "return_number": frame.return_number, "number_of_returns": frame.number_of_returns,
                 "intensity": frame.reflectivity.astype(np.uint16) * 256, "reflectivity": frame.reflectivity,
                 "tag": frame.tag, **(extra or {})}


def _las_records(frame: PointFrame, coordinates: str, extra_fields: Sequence[tuple[str, str]] = (),
                 extra: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
    """The frame's LAS body records (:func:`_las_columns` as one record a point, x y z in the LAS frame), then
    ``extra_fields``."""
    xyz, columns = _las_columns(frame, coordinates, extra)
    records = np.zeros(len(frame), dtype=[*_LAS_BODY, *extra_fields])
    records["x"], records["y"], records["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    for name in records.dtype.names[3:]:
        records[name] = columns[name]
    return records
