"""A point cloud a user already has, read to be drawn beside the scan (the window's File > Open cloud).

Takes a PLY, PCD or CSV of x, y, z, an LVX2, LVX, ROS 1 ``.bag`` or ROS 2 bag
folder (what :func:`~livox_viz.files.frame_files.read_frame_rows` and the bag
reader read), an NPZ of our export or a LAS; gives its returns (no-returns,
``(0, 0, 0)``, dropped) in one of the project's frames:

- **world NED** (x north, y east, z down, metres): the world-frame exports of
  ``livox-viz scan`` as they are (a PLY, PCD or CSV whose header or sidecar
  says ``frame world``, a PCD's kilometre offset added back; an NPZ's
  ``xyz_world``), a world LAS (ENU) turned to NED, and any LAS that does not
  say it is ours (LAS is a z-up world format: taken as ENU).
- **sensor FRD** (x forward, y right, z down, metres): our sensor-frame
  exports as they are (PLY, PCD, CSV ``frame sensor``; an NPZ without
  ``xyz_world`` has its ``xyz_sensor``), and every recording in Livox's frame
  (x forward, y left, z up: a foreign PLY, PCD or CSV, LVX2, LVX, bags, a
  sensor LAS) turned to FRD. The window places these with the sensor's pose.

Memory is bounded: a cloud of more than :data:`MAX_CLOUD_POINTS` points is
refused in one line naming the limit.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.files.frame_files import FRAME_SUFFIXES, read_frame_rows

#: Most points of an opened cloud (about 0.5 GB as float64 x, y, z; a LAS or PLY of more is refused).
MAX_CLOUD_POINTS = 20_000_000
#: The suffixes read as clouds (and a ROS 2 bag folder, one holding ``metadata.yaml``, or that file itself).
CLOUD_SUFFIXES: tuple[str, ...] = (*FRAME_SUFFIXES, ".npz", ".las", ".laz")
#: Livox's FLU (and LAS's ENU read as x, y, z) to the project's z-down frames: FLU -> FRD.
_FLIP_YZ = np.array([1.0, -1.0, -1.0])
_OUR_FRAME = re.compile(rb"frame (world|sensor): ")
_PCD_OFFSET = re.compile(rb"# offset: the point is \(x, y, z\) \+ \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) m")


@dataclass(frozen=True)
class OpenedCloud:
    """A cloud read from a file, its returns only.

    Parameters
    ----------
    name : str
        The file's name.
    points_m : (n, 3) float64
        Metres, in :attr:`frame`.
    frame : {"world", "sensor"}
        World NED, or the sensor's FRD (placed with the sensor's pose to be drawn).
    source : str
        The format read and what said the frame, in words.
    """

    name: str
    points_m: np.ndarray
    frame: str
    source: str

    def __post_init__(self) -> None:
        if self.frame not in ("world", "sensor"):
            raise LivoxVizError(f"cloud frame {self.frame!r}; allowed: world, sensor")


def read_cloud(path: str | os.PathLike[str], max_points: int = MAX_CLOUD_POINTS) -> OpenedCloud:
    """Read a point cloud file (see the module's docstring).

    Parameters
    ----------
    path : path-like
    max_points : int
        Refuse a cloud of more points than this.

    Raises
    ------
    LivoxVizError
        One line: a folder that is no ROS 2 bag, an unknown suffix, a broken file, no returns, too many points.
    """
    path = Path(path)
    if path.name == "metadata.yaml":  # a file dialog picks files: a ROS 2 bag by its metadata
        path = path.parent
    allowed = f"allowed: a cloud file ({', '.join(CLOUD_SUFFIXES)}) or a ROS 2 bag folder"
    if path.is_dir() and not (path / "metadata.yaml").exists() and path.suffix.lower() != ".bag":
        raise LivoxVizError(f"{path}: is a folder that is no ROS 2 bag; {allowed}")
    if not path.exists():
        raise LivoxVizError(f"{path}: no such file; {allowed}")
    suffix = path.suffix.lower()
    if path.is_dir() or suffix in (".bag", ".lvx", ".lvx2"):
        cloud = _read_livox(path, max_points)
    elif suffix == ".npz":
        cloud = _read_npz(path, max_points)
    elif suffix in (".las", ".laz"):
        cloud = _read_las(path, max_points)
    elif suffix in (".ply", ".pcd", ".csv"):
        cloud = _read_rows(path, max_points)
    else:
        raise LivoxVizError(f"{path}: unknown format {path.suffix or '(none)'}; {allowed}")
    points = cloud.points_m
    if not np.all(np.isfinite(points)):
        raise LivoxVizError(f"{path}: its points hold NaN or infinite values; allowed: finite x, y, z")
    if len(points) > max_points:
        raise LivoxVizError(f"{path}: {len(points):,} points; at most {max_points:,} are opened")
    if len(points) == 0:
        raise LivoxVizError(f"{path}: holds no returns (every point is (0, 0, 0)); allowed: a cloud with points")
    return cloud


def returns_only(points_m: np.ndarray) -> np.ndarray:
    """``(m, 3)`` the rows of ``points_m`` ``(n, 3)`` that are not the no-return ``(0, 0, 0)``."""
    points_m = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    return points_m[np.any(points_m != 0.0, axis=1)]


def _too_many(path: Path, count: int, max_points: int) -> None:
    if count > max_points:
        raise LivoxVizError(f"{path}: {count:,} points; at most {max_points:,} are opened")


def _read_livox(path: Path, max_points: int) -> OpenedCloud:
    """An LVX2, LVX or bag: every device's every return, in Livox's frame (FLU) turned to FRD."""
    if path.is_dir() or path.suffix.lower() == ".bag":
        from livox_viz.files.livox_bag import read_livox_bag

        recording = read_livox_bag(path, max_points=max_points)
    else:
        from livox_viz.files.lvx_read import read_lvx

        recording = read_lvx(path, max_points=max_points)
    points = recording.points_m[~np.asarray(recording.no_return, dtype=bool)]
    return OpenedCloud(path.name, returns_only(points) * _FLIP_YZ, "sensor",
                       f"{recording.source}, Livox's frame (x forward, y left, z up)")


def _header_bytes(path: Path) -> bytes:
    with path.open("rb") as handle:
        return handle.read(8192)


def _read_rows(path: Path, max_points: int) -> OpenedCloud:
    """A PLY, PCD or CSV: ours in the frame its header (a CSV: its sidecar) names, anyone else's as Livox's FLU."""
    rows = read_frame_rows(path, max_rows=max_points + 1)
    if len(rows.points_m) > max_points:
        raise LivoxVizError(f"{path}: more than {max_points:,} points; at most {max_points:,} are opened")
    frame = None
    offset = np.zeros(3)
    if path.suffix.lower() == ".csv":
        sidecar = path.with_name(path.name + ".json")
        if sidecar.is_file():
            try:
                frame = json.loads(sidecar.read_text(encoding="utf-8")).get("coordinates")
            except (ValueError, AttributeError):
                frame = None
    else:
        head = _header_bytes(path)
        found = _OUR_FRAME.search(head.split(b"end_header")[0].split(b"\nDATA")[0])
        frame = found.group(1).decode() if found else None
        shift = _PCD_OFFSET.search(head)
        if shift is not None and frame == "world":
            offset = np.array([float(v) for v in shift.groups()])
    if frame in ("world", "sensor"):
        points = returns_only(rows.points_m) + offset
        what = "world NED" if frame == "world" else "sensor FRD"
        return OpenedCloud(path.name, points, frame, f"{rows.source} of livox-viz, {what}")
    return OpenedCloud(path.name, returns_only(rows.points_m) * _FLIP_YZ, "sensor",
                       f"{rows.source}, Livox's frame (x forward, y left, z up)")


def _npz_rows(archive: zipfile.ZipFile, member: str) -> int:
    """Rows of the array ``member`` (``name.npy``) of an NPZ, from its header alone."""
    with archive.open(member) as handle:
        version = np.lib.format.read_magic(handle)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, _ = read(handle)
    return int(shape[0]) if shape else 0


def _read_npz(path: Path, max_points: int) -> OpenedCloud:
    """Our NPZ export: its ``xyz_world`` (NED) when it holds one, else its ``xyz_sensor`` (FRD)."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            key = next((k for k in ("xyz_world", "xyz_sensor") if f"{k}.npy" in names), None)
            if key is None:
                raise LivoxVizError(f"{path}: holds {', '.join(sorted(n.removesuffix('.npy') for n in names))}; "
                                    "allowed: an NPZ of livox-viz with xyz_world or xyz_sensor")
            _too_many(path, _npz_rows(archive, f"{key}.npy"), max_points)
        with np.load(path, allow_pickle=False) as data:
            points = np.asarray(data[key], dtype=np.float64)
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise LivoxVizError(f"{path}: not an NPZ numpy reads ({exc})") from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise LivoxVizError(f"{path}: {key} is {points.shape}; allowed: (n, 3) metres")
    frame = "world" if key == "xyz_world" else "sensor"
    return OpenedCloud(path.name, returns_only(points), frame,
                       f"NPZ of livox-viz, {key} ({'world NED' if frame == 'world' else 'sensor FRD'})")


def _read_las(path: Path, max_points: int) -> OpenedCloud:
    """A LAS: ours in the frame its livox-viz record names (world ENU, sensor FLU); anyone else's as world ENU."""
    import laspy

    try:
        with laspy.open(path) as reader:
            _too_many(path, int(reader.header.point_count), max_points)
            records = [vlr for vlr in reader.header.vlrs if getattr(vlr, "user_id", "") == "livox-viz"]
            las = reader.read()
    except laspy.errors.LaspyException as exc:
        raise LivoxVizError(f"{path}: not a LAS laspy reads ({exc})") from None
    except (ValueError, EOFError) as exc:
        raise LivoxVizError(f"{path}: a broken LAS ({exc})") from None
    frame = "world"
    if records:
        description = bytes(records[0].record_data).decode("utf-8", "replace")
        try:
            frame = json.loads(description).get("frame", "world")
        except ValueError:
            frame = "sensor" if "sensor" in records[0].description else "world"
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)]).astype(np.float64)
    if frame == "sensor":  # FLU -> FRD
        return OpenedCloud(path.name, returns_only(xyz) * _FLIP_YZ, "sensor", "LAS of livox-viz, sensor FLU")
    # ENU -> NED: north = y, east = x, down = -z.
    ned = xyz[:, [1, 0, 2]] * np.array([1.0, 1.0, -1.0])
    return OpenedCloud(path.name, returns_only(ned), "world",
                       "LAS of livox-viz, world ENU" if records else "LAS, taken as world ENU (x east, y north, z up)")
