"""One recorded frame from the files users have: a PCD, PLY or CSV of points, an LVX2, LVX or a driver's bag.

What ``fit RECORDING`` and the window's reference read: a real sensor's frame
with its rows **in firing order** and its no-returns kept in place as
``(0, 0, 0)`` (as Livox Viewer and livox_ros_driver2 save them), points in the
sensor's own frame (x forward, y left, z up, metres: Livox's and REP 103's).

- PCD (``ascii`` or ``binary``; ``binary_compressed`` is refused with a way
  out), PLY (``ascii``, ``binary_little_endian``, ``binary_big_endian``) and
  CSV with a header naming ``x``, ``y``, ``z`` (and optionally ``intensity`` or
  ``reflectivity``, a per-point time ``t``/``time``/``timestamp``/``offset_time``
  and a ``line``/``laser``): no per-point time means times from the firing order
  and the head's rate.
- LVX2, LVX 1.1 and bags (:mod:`~livox_viz.files.lvx_read`,
  :mod:`~livox_viz.files.livox_bag`): each point's time and laser as the
  drivers rebuild them; the first device's first returns.

Memory is bounded: at most :data:`MAX_FRAME_ROWS` rows are read (a recording
longer than that is read from its start).
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError

#: Most rows read from one recording (40 s of a Mid-360, 4 s of a HAP).
MAX_FRAME_ROWS = 2_000_000
#: The suffixes read as recorded frames.
FRAME_SUFFIXES: tuple[str, ...] = (".pcd", ".ply", ".csv", ".lvx2", ".lvx", ".bag")
_TIME_COLUMNS = ("offset_time", "timestamp", "time", "t")
_LASER_COLUMNS = ("line", "laser", "ring")
_REFLECTIVITY_COLUMNS = ("reflectivity", "intensity")


@dataclass(frozen=True)
class FrameRows:
    """A recording's rows in firing order.

    Parameters
    ----------
    name : str
    points_m : (n, 3) float64
        x forward, y left, z up, metres; ``(0, 0, 0)`` where nothing returned.
    times_s : (n,) float64, optional
        Seconds from the first row, when the file says them.
    lasers : (n,) int64, optional
        Each row's laser as the file numbers them (the drivers' ``line``).
    reflectivity : (n,) float64, optional
        0-255.
    device_type : int
        Livox's device type when the file says it (LVX), else -1.
    source : str
        The format read.
    """

    name: str
    points_m: np.ndarray
    times_s: np.ndarray | None = None
    lasers: np.ndarray | None = None
    reflectivity: np.ndarray | None = None
    device_type: int = -1
    source: str = ""

    @property
    def returned(self) -> np.ndarray:
        """``(n,)`` bool: rows with a return."""
        return np.any(self.points_m != 0.0, axis=1)

    @property
    def frd(self) -> np.ndarray:
        """``(n, 3)`` the rows in the sensor's FRD frame (x forward, y right, z down)."""
        return self.points_m * np.array([1.0, -1.0, -1.0])


def read_frame_rows(path: str | os.PathLike[str], max_rows: int = MAX_FRAME_ROWS) -> FrameRows:
    """Read a recording's rows (see the module's docstring).

    Raises
    ------
    LivoxVizError
        A missing or unreadable file, an unknown format, a header that does not say x, y and z, rows that are
        not numbers.
    """
    path = Path(path)
    if path.is_dir() and path.suffix.lower() != ".bag":
        raise LivoxVizError(f"{path}: is a folder; allowed: a recorded frame file ({', '.join(FRAME_SUFFIXES)})")
    if not path.exists():
        raise LivoxVizError(f"{path}: no such file; allowed: a recorded frame ({', '.join(FRAME_SUFFIXES)})")
    suffix = path.suffix.lower()
    if suffix == ".pcd":
        rows = _read_pcd(path, max_rows)
    elif suffix == ".ply":
        rows = _read_ply(path, max_rows)
    elif suffix == ".csv":
        rows = _read_csv(path, max_rows)
    elif suffix in (".lvx2", ".lvx", ".bag"):
        rows = _read_livox(path, max_rows)
    else:
        raise LivoxVizError(f"{path}: unknown format {path.suffix or '(none)'}; allowed: "
                            f"{', '.join(FRAME_SUFFIXES)}")
    if not np.all(np.isfinite(rows.points_m)):
        raise LivoxVizError(f"{path}: its points hold NaN or infinite values; allowed: finite x, y, z with "
                            "no-returns as (0, 0, 0)")
    return rows


def _columns(path: Path, names: list[str], data: np.ndarray, source: str) -> FrameRows:
    """Pick x, y, z and the optional columns by name out of ``data`` (rows x columns)."""
    lower = [name.strip().lower() for name in names]
    missing = [axis for axis in "xyz" if axis not in lower]
    if missing:
        raise LivoxVizError(f"{path}: its fields are {', '.join(names)}; allowed: fields x, y and z (metres, the "
                            "sensor's frame), optionally intensity or reflectivity, a time and a line")
    points = np.column_stack([data[:, lower.index(axis)] for axis in "xyz"]).astype(np.float64)

    def first(candidates: tuple[str, ...]) -> np.ndarray | None:
        for name in candidates:
            if name in lower:
                return np.asarray(data[:, lower.index(name)], dtype=np.float64)
        return None

    times = first(_TIME_COLUMNS)
    if times is not None and times.size:
        times = times - times[0]
        if "offset_time" in lower or ("timestamp" in lower and np.nanmax(np.abs(times)) > 1e3):
            times = times * 1e-9  # nanoseconds, as the Livox drivers write them
    lasers = first(_LASER_COLUMNS)
    return FrameRows(path.stem, points, times, None if lasers is None else lasers.astype(np.int64),
                     first(_REFLECTIVITY_COLUMNS), -1, source)


def _read_pcd(path: Path, max_rows: int) -> FrameRows:
    with path.open("rb") as handle:
        header: dict[str, list[str]] = {}
        while True:
            line = handle.readline(4096)
            if not line:
                raise LivoxVizError(f"{path}: its header has no DATA line; allowed: a PCD file (ascii or binary)")
            words = line.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            header[words[0].upper()] = words[1:]
            if words[0].upper() == "DATA":
                break
        fields = header.get("FIELDS", [])
        sizes = [int(v) for v in header.get("SIZE", [])]
        kinds = header.get("TYPE", [])
        counts = [int(v) for v in header.get("COUNT", ["1"] * len(fields))]
        points = int(header.get("POINTS", header.get("WIDTH", ["0"]))[0])
        mode = header["DATA"][0].lower() if header["DATA"] else ""
        if not fields or len(sizes) != len(fields) or len(kinds) != len(fields) or any(c != 1 for c in counts):
            raise LivoxVizError(f"{path}: its FIELDS, SIZE, TYPE and COUNT lines do not agree; allowed: one value "
                                "per field")
        rows = min(points, max_rows)
        if mode == "ascii":
            text = b"".join(handle.readline() for _ in range(rows)).decode("ascii", "replace")
            try:
                data = np.loadtxt(io.StringIO(text), dtype=np.float64, ndmin=2)
            except ValueError as error:
                raise LivoxVizError(f"{path}: a row is not {len(fields)} numbers ({error}); allowed: ascii rows of "
                                    f"{' '.join(fields)}") from None
        elif mode == "binary":
            letters = {"F": "f", "I": "i", "U": "u"}
            dtype = np.dtype([(f"f{i}", f"<{letters.get(k.upper(), 'f')}{s}")
                              for i, (k, s) in enumerate(zip(kinds, sizes, strict=True))])
            raw = handle.read(rows * dtype.itemsize)
            if len(raw) < rows * dtype.itemsize:
                raise LivoxVizError(f"{path}: ends after {len(raw) // dtype.itemsize:,} of its {rows:,} points; "
                                    "allowed: a whole file")
            table = np.frombuffer(raw, dtype=dtype)
            data = np.column_stack([table[name].astype(np.float64) for name in dtype.names])
        else:
            raise LivoxVizError(f"{path}: DATA {mode or '(none)'}; allowed: ascii or binary (save a "
                                "binary_compressed PCD as binary, e.g. pcl_convert_pcd_ascii_binary IN OUT 1)")
    if data.shape[1] != len(fields):
        raise LivoxVizError(f"{path}: rows of {data.shape[1]} numbers for {len(fields)} fields; allowed: one number "
                            "per field")
    return _columns(path, fields, data, "PCD")


def _read_ply(path: Path, max_rows: int) -> FrameRows:
    with path.open("rb") as handle:
        if handle.readline(64).strip() != b"ply":
            raise LivoxVizError(f"{path}: does not start with 'ply'; allowed: a PLY file")
        mode, vertices, properties, in_vertex = "", 0, [], False
        while True:
            line = handle.readline(4096)
            if not line:
                raise LivoxVizError(f"{path}: its header has no end_header; allowed: a PLY file")
            words = line.decode("ascii", "replace").split()
            if not words:
                continue
            if words[0] == "format":
                mode = words[1]
            elif words[0] == "element":
                in_vertex = words[1] == "vertex"
                if in_vertex:
                    vertices = int(words[2])
            elif words[0] == "property" and in_vertex:
                if words[1] == "list":
                    raise LivoxVizError(f"{path}: a list property in its vertices; allowed: scalar properties")
                properties.append((words[2], words[1]))
            elif words[0] == "end_header":
                break
        rows = min(vertices, max_rows)
        names = [name for name, _ in properties]
        if mode == "ascii":
            text = b"".join(handle.readline() for _ in range(rows)).decode("ascii", "replace")
            data = np.loadtxt(io.StringIO(text), dtype=np.float64, ndmin=2)[:, :len(names)]
        elif mode in ("binary_little_endian", "binary_big_endian"):
            types = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
                     "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2",
                     "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}
            order = "<" if mode == "binary_little_endian" else ">"
            try:
                dtype = np.dtype([(name, order + types[kind]) for name, kind in properties])
            except KeyError as error:
                raise LivoxVizError(f"{path}: property type {error}; allowed: {', '.join(types)}") from None
            raw = handle.read(rows * dtype.itemsize)
            if len(raw) < rows * dtype.itemsize:
                raise LivoxVizError(f"{path}: ends after {len(raw) // dtype.itemsize:,} of its {rows:,} vertices; "
                                    "allowed: a whole file")
            table = np.frombuffer(raw, dtype=dtype)
            data = np.column_stack([table[name].astype(np.float64) for name in names])
        else:
            raise LivoxVizError(f"{path}: format {mode or '(none)'}; allowed: ascii, binary_little_endian or "
                                "binary_big_endian")
    return _columns(path, names, data, "PLY")


def _read_csv(path: Path, max_rows: int) -> FrameRows:
    with path.open(newline="", encoding="utf-8", errors="replace") as handle:
        reader = csv.reader(handle)
        names = next(reader, [])
        rows = []
        for number, row in enumerate(reader, start=2):
            if len(rows) >= max_rows:
                break
            if not row:
                continue
            try:
                rows.append([float(value) for value in row[:len(names)]])
            except ValueError:
                raise LivoxVizError(f"{path}: line {number} is not numbers; allowed: a header line naming x, y, z "
                                    "then rows of numbers") from None
    data = np.array(rows, dtype=np.float64).reshape(-1, len(names)) if rows else np.zeros((0, len(names)))
    return _columns(path, names, data, "CSV")


def _read_livox(path: Path, max_rows: int) -> FrameRows:
    """An LVX2, LVX 1.1 or bag: the first device's first returns and no-returns, in firing order."""
    if path.suffix.lower() == ".bag":
        from livox_viz.files.livox_bag import read_livox_bag

        recording = read_livox_bag(path, max_points=max_rows)
    else:
        from livox_viz.files.lvx_read import read_lvx_start

        recording = read_lvx_start(path, max_rows)
    keep = (recording.return_number <= 1) & (recording.device_index == 0)
    part = recording.subset(keep)
    times = part.times_s - part.times_s[0] if len(part) else part.times_s
    return FrameRows(path.stem, part.points_m.astype(np.float64), times.astype(np.float64),
                     part.lasers.astype(np.int64), part.reflectivity.astype(np.float64), recording.device_type,
                     recording.source)
