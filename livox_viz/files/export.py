"""Point-cloud files: PLY and PCD (binary or ASCII), LAS 1.4, NPZ and CSV, streamed frame by frame.

Every writer takes frames one at a time (memory stays flat however long the
scan), writes into temporary files next to the destination and renames the
finished file over it on :meth:`PointCloudWriter.close`; on failure nothing is
left behind. Each file states its frame of reference (``sensor`` = the
decoded int16 points a RflySim client sees, sensor FRD metres; ``world`` =
world NED metres) in its header or metadata.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

import numpy as np

from livox_viz.casting.point_frame import PointFrame
from livox_viz.core.atomic import atomic_path, make_work_dir, resolve_destination
from livox_viz.core.errors import LivoxVizError
from livox_viz.files.npzstream import NpzColumns

FORMATS = (".ply", ".pcd", ".las", ".npz", ".csv")
FRAMES = ("sensor", "world")
FRAME_DESCRIPTION = {
    "sensor": "sensor FRD (x forward, y right, z down), metres, decoded from RflySim int16",
    "world": "world NED (x north, y east, z down), metres",
}
#: Per-point fields of PLY, PCD and CSV, with their numpy types.
POINT_FIELDS: tuple[tuple[str, str], ...] = (
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("range", "<f4"), ("time", "<f8"), ("frame", "<u4"),
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
}


def frame_records(frame: PointFrame, coordinates: str, extra_fields: Sequence[tuple[str, str]] = (),
                  extra: Mapping[str, np.ndarray | float] | None = None) -> np.ndarray:
    """The frame's points as a structured array of :data:`POINT_FIELDS` and ``extra_fields``, ``(M,)``."""
    xyz = frame.xyz_decoded if coordinates == "sensor" else frame.xyz_world
    records = np.empty(len(frame), dtype=[*POINT_FIELDS, *extra_fields])
    records["x"], records["y"], records["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    records["range"] = frame.range_m
    records["time"] = frame.t
    records["frame"] = frame.index
    for name, _ in extra_fields:
        records[name] = (extra or {})[name]
    return records


class PointCloudWriter:
    """Streams frames into one point-cloud file; the format follows the extension.

    Parameters
    ----------
    path : path-like
        Destination: ``.ply``, ``.pcd``, ``.las``, ``.npz`` or ``.csv``.
    coordinates : {"sensor", "world"}
        Which points PLY/PCD/LAS/CSV hold (NPZ holds both).
    ascii : bool
        ASCII instead of binary PLY/PCD.
    extra_fields : sequence of (name, numpy type)
        Per-point fields after :data:`POINT_FIELDS` (an NPZ column, a LAS extra dimension), e.g. a received
        frame's ``("sender_time", "<f8")``; :meth:`write` is given their values. Types: ``<f8``, ``<i4``, ``<u4``.

    Attributes
    ----------
    npz_arrays : dict of str to ndarray
        Arrays an NPZ gets besides its columns when it is closed (e.g. one row per received frame).

    Examples
    --------
    >>> with PointCloudWriter("scan.ply") as writer:      # doctest: +SKIP
    ...     for frame in scanner.frames(1.0):
    ...         writer.write(frame)
    """

    def __init__(self, path: str | os.PathLike[str], coordinates: str = "sensor", ascii: bool = False,
                 extra_fields: Sequence[tuple[str, str]] = ()) -> None:
        self.path = Path(path)
        self.format = self.path.suffix.lower()
        if self.format not in FORMATS:
            raise LivoxVizError(f"{self.path}: unknown format {self.format or '(none)'}; allowed: {', '.join(FORMATS)}")
        if coordinates not in FRAMES:
            raise LivoxVizError(f"coordinates {coordinates!r}; allowed: {' or '.join(FRAMES)}")
        resolve_destination(self.path)
        self.coordinates = coordinates
        self.ascii = ascii
        self.extra_fields = tuple(extra_fields)
        self.npz_arrays: dict[str, np.ndarray] = {}
        self.count = 0
        self._work = make_work_dir(self.path)
        self._body: BinaryIO | None = None
        self._npz: NpzColumns | None = None
        self._npz_poses: list[np.ndarray] = []
        self._las = None
        self._closed = False
        #: Why closing the LAS writer failed during an abort, if it did.
        self.abort_error = ""
        try:
            self._open()
        except BaseException:  # also Ctrl-C and SIGTERM (cli.signals.Terminated): no work folder is left
            self.abort()
            raise

    def _open(self) -> None:
        if self.format == ".npz":
            self._npz = NpzColumns(self._work, {**_NPZ_ARRAYS, **{name: (t, ()) for name, t in self.extra_fields}})
        elif self.format == ".las":
            self._las = _open_las(self._work / "points.las", self.coordinates, self.extra_fields)
        else:
            self._body = open(self._work / "body", "wb")
            if self.format == ".csv":
                self._body.write(f"# livox-viz scan; coordinates: {FRAME_DESCRIPTION[self.coordinates]}\n".encode())
                self._body.write((",".join(name for name, _ in self._fields) + "\n").encode())

    @property
    def _fields(self) -> tuple[tuple[str, str], ...]:
        return (*POINT_FIELDS, *self.extra_fields)

    def write(self, frame: PointFrame, extra: Mapping[str, np.ndarray | float] | None = None) -> None:
        """Append one frame's returns; ``extra`` holds the values of ``extra_fields`` (per point, or one per frame)."""
        if self._closed:
            raise LivoxVizError(f"{self.path}: the writer is closed")
        extra = {name: np.broadcast_to(np.asarray((extra or {})[name], dtype=t), (len(frame),))
                 for name, t in self.extra_fields}
        if self._npz is not None:
            self._npz.append({
                "xyz_sensor": frame.xyz_decoded, "xyz_world": frame.xyz_world, "xyz_int16": frame.xyz_int16,
                "range": frame.range_m, "t": frame.t, "frame": np.full(len(frame), frame.index), **extra,
            })
            self._npz_poses.append(np.concatenate([[frame.index], frame.sensor_pose.as_array(),
                                                   frame.end_pose.as_array()]))
        elif self.format == ".las":
            _write_las(self._las, frame, self.coordinates, extra)
        else:
            records = frame_records(frame, self.coordinates, self.extra_fields, extra)
            assert self._body is not None
            if self.format == ".csv" or self.ascii:
                formats = ["%.6f"] * 4 + ["%.9f", "%d"] + ["%.9f" if t[1] == "f" else "%d"
                                                            for _, t in self.extra_fields]
                np.savetxt(self._body, _records_as_columns(records), fmt=formats,
                           delimiter="," if self.format == ".csv" else " ")
            else:
                self._body.write(records.tobytes())
        self.count += len(frame)

    def close(self) -> Path:
        """Finish the file and move it into place; returns its path."""
        if self._closed:
            return self.path
        try:
            with atomic_path(self.path) as tmp:
                if self._npz is not None:
                    poses = np.array(self._npz_poses).reshape(-1, 13)
                    self._npz.finish(tmp, {**self.npz_arrays, "frame_pose": poses, "frame_of_reference": np.array(
                        json.dumps({**FRAME_DESCRIPTION, "frame_pose": "index, then the sensor's pose at the "
                                    "frame's first ray and just after its last: x y z (m, world NED) roll pitch "
                                    "yaw (rad) each"}))})
                elif self.format == ".las":
                    self._las.close()
                    self._las = None
                    shutil.move(self._work / "points.las", tmp)
                else:
                    assert self._body is not None
                    self._body.close()
                    with open(tmp, "wb") as out, open(self._work / "body", "rb") as body:
                        out.write(self._header())
                        shutil.copyfileobj(body, out, 1 << 20)
        finally:
            self.abort()
        return self.path

    def abort(self) -> None:
        """Drop everything written so far; the destination is left as it was."""
        self._closed = True
        if self._body is not None and not self._body.closed:
            self._body.close()
        if self._npz is not None:
            self._npz.close()
        if self._las is not None:
            las, self._las = self._las, None
            try:
                las.close()
            except (OSError, ValueError) as exc:  # a half-written LAS is removed below anyway
                self.abort_error = str(exc)
        shutil.rmtree(self._work, ignore_errors=True)

    def __enter__(self) -> PointCloudWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()

    # Headers -------------------------------------------------------------------------
    def _header(self) -> bytes:
        if self.format == ".csv":
            return b""
        if self.format == ".ply":
            encoding = "ascii" if self.ascii else "binary_little_endian"
            types = {"<f4": "float", "<f8": "double", "<u4": "uint", "<i4": "int"}
            lines = ["ply", f"format {encoding} 1.0", "comment livox-viz scan",
                     f"comment frame {self.coordinates}: {FRAME_DESCRIPTION[self.coordinates]}",
                     f"element vertex {self.count}"]
            lines += [f"property {types[t]} {name}" for name, t in self._fields]
            lines.append("end_header")
            return ("\n".join(lines) + "\n").encode()
        sizes = {"<f4": ("4", "F"), "<f8": ("8", "F"), "<u4": ("4", "U"), "<i4": ("4", "I")}
        lines = [
            f"# .PCD v0.7 - livox-viz scan; frame {self.coordinates}: {FRAME_DESCRIPTION[self.coordinates]}",
            "VERSION 0.7",
            "FIELDS " + " ".join(name for name, _ in self._fields),
            "SIZE " + " ".join(sizes[t][0] for _, t in self._fields),
            "TYPE " + " ".join(sizes[t][1] for _, t in self._fields),
            "COUNT " + " ".join("1" for _ in self._fields),
            f"WIDTH {self.count}",
            "HEIGHT 1",
            "VIEWPOINT 0 0 0 1 0 0 0",
            f"POINTS {self.count}",
            f"DATA {'ascii' if self.ascii else 'binary'}",
        ]
        return ("\n".join(lines) + "\n").encode()

def _records_as_columns(records: np.ndarray) -> np.ndarray:
    return np.column_stack([records[name].astype(np.float64) for name in records.dtype.names])


def _open_las(path: Path, coordinates: str, extra_fields: Sequence[tuple[str, str]] = ()):
    import laspy

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.array([1e-4, 1e-4, 1e-4])
    header.offsets = np.zeros(3)
    header.add_extra_dims([laspy.ExtraBytesParams("range", np.float32, description="range m"),
                           laspy.ExtraBytesParams("frame", np.uint32, description="frame index"),
                           *(laspy.ExtraBytesParams(name, np.dtype(t).newbyteorder("=")) for name, t in extra_fields)])
    header.generating_software = "livox-viz"
    header.system_identifier = f"livox-viz {coordinates}"[:32]
    metadata = {"frame": coordinates, "description": FRAME_DESCRIPTION[coordinates]}
    header.vlrs.append(laspy.VLR("livox-viz", 1, f"frame: {coordinates}"[:32], json.dumps(metadata).encode()))
    return laspy.open(path, mode="w", header=header)


def _write_las(writer, frame: PointFrame, coordinates: str, extra: Mapping[str, np.ndarray] | None = None) -> None:
    import laspy

    if not len(frame):
        return
    xyz = frame.xyz_decoded if coordinates == "sensor" else frame.xyz_world
    points = laspy.ScaleAwarePointRecord.zeros(len(frame), header=writer.header)
    points.x, points.y, points.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    points.gps_time = frame.t
    points.range = frame.range_m.astype(np.float32)
    points.frame = np.full(len(frame), frame.index, dtype=np.uint32)
    for name, values in (extra or {}).items():
        points[name] = values
    writer.write_points(points)
