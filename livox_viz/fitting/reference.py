"""Measured scan patterns: the reference ``.npy`` table and Livox's simulation CSV, in our angular plane.

Both forms give, row by row in firing order, a ray as azimuth and elevation
(``.npy``: ``[theta, phi]`` radians, x forward, y left, z up) or azimuth and
zenith (CSV: ``Time/s,Azimuth/deg,Zenith/deg``, degrees). They are turned into
FRD rays and then into pattern x (right), y (up) in degrees of one of the two
pattern planes (:mod:`livox_viz.patterns.planes`): the boresight plane (angle
off the boresight as the polar radius), or, for a table whose rays go all
around the sensor (more than 1 % of them behind it, e.g. the Mid-360), the
panorama plane (azimuth, elevation).

A real sensor's recording (``.lvx2``, ``.lvx``, a ROS 1 ``.bag`` of
livox_ros_driver, or a frame saved as ``.pcd``, ``.ply`` or a ``.csv`` whose
header names ``x``, ``y``, ``z``; read by :mod:`livox_viz.files`) gives its
first device's first returns as rows (the firings that returned nothing are
gaps in the slots), each with the time its file gives it, or, for a frame
without per-point times, its row's place in the firing order (a no-return row
``(0, 0, 0)`` is a gap); only its first :data:`MAX_TABLE_ROWS` rows are read.
A CSV is a recording when its header names x, y and z, else a Livox table.

Limits: a table holds at most :data:`MAX_TABLE_ROWS` rows (a ``.npy``'s shape
is read before its data), a CSV is at most :data:`MAX_CSV_BYTES`; a CSV's
``Time/s`` column, when it holds times, gives the rows' rate.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from livox_viz.config.presets import shipped_preset_dir
from livox_viz.core.errors import LivoxVizError, require_file
from livox_viz.core.textfile import ENCODINGS, decode_text
from livox_viz.fitting.table import PLANE_IMAGES, ReferencePattern
from livox_viz.patterns.planes import frd_from_zup, xy_from_directions

#: Recordings a table may be read from: LVX2, LVX 1.1, ROS 1 bags of livox_ros_driver and frames saved as PCD or
#: PLY (and a CSV whose header names x, y and z: :func:`is_point_csv`).
RECORDING_SUFFIXES = (".lvx2", ".lvx", ".bag", ".pcd", ".ply")
#: The file forms a table may come in.
TABLE_SUFFIXES = (".npy", ".npz", ".csv", *RECORDING_SUFFIXES)
#: Rates a table's times may say, rows per second.
MIN_RATE = 1.0
MAX_RATE = 10_000_000.0
#: A table's times may leave at most this many firings per row (the rest missing).
MAX_GAP_RATIO = 100
#: Rows compared with the shipped tables to recognise a copy of one.
MATCH_ROWS = 2000
#: Most rows a table may hold (100 s at 100 000 rows/s; a fit of this many rows stays within about 2 GB).
MAX_TABLE_ROWS = 10_000_000
#: Largest Livox CSV read (a CSV row is about 30 bytes: some 8 million rows).
MAX_CSV_BYTES = 256 * 1024 * 1024
#: Times printed to a step over this fraction of the firing period cannot place each row on its firing.
MAX_PRINT_STEP = 0.3
#: A table is in the panorama plane when more than this fraction of its rays point behind the sensor.
PANORAMA_FRACTION = 0.01


def xy_from_zup(azimuth: np.ndarray, elevation: np.ndarray, plane: str | None = None) -> tuple[np.ndarray, str]:
    """Pattern angles from azimuth about +z and elevation (radians; x forward, y left, z up).

    Parameters
    ----------
    azimuth, elevation : (n,) float64
        Radians.
    plane : {"boresight", "panorama"}, optional
        Default: the panorama plane when more than 1 % of the rays point behind the sensor.

    Returns
    -------
    xy_deg : (n, 2) float64
    plane : str
    """
    d = frd_from_zup(azimuth, elevation)
    if plane is None:
        plane = "panorama" if np.mean(d[:, 0] < 0) > PANORAMA_FRACTION else "boresight"
    return xy_from_directions(d, plane), plane


def shipped_table_dir() -> Path:
    """The folder of the shipped scan tables (a checkout's ``presets/tables`` or the wheel's copy)."""
    return shipped_preset_dir() / "tables"


def shipped_tables() -> dict[str, dict[str, Any]]:
    """The shipped tables by name (``mid40``, ...): each with its ``rate`` (rows/s), ``sensor``, ``preset`` (the
    sensor's shipped preset), a ``description``, and the ``image`` of the printed rows that is the real sensor's
    pattern (a key of :data:`~livox_viz.fitting.table.PLANE_IMAGES`) with its ``image_evidence``."""
    try:
        index = json.loads((shipped_table_dir() / "index.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    return {name: entry for name, entry in index.items() if (shipped_table_dir() / f"{name}.npy").is_file()}


def is_point_csv(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a CSV of points (a recorded frame: its header names x, y and z) rather than a Livox
    table (``Time/s,Azimuth/deg,Zenith/deg``)."""
    path = Path(path)
    if path.suffix.lower() != ".csv":
        return False
    try:
        with path.open(newline="", encoding="utf-8", errors="replace") as handle:
            header = [name.strip().lower() for name in next(csv.reader([handle.readline(4096)]), [])]
    except OSError:
        return False
    return {"x", "y", "z"} <= set(header)


def is_table(text: str | os.PathLike[str]) -> bool:
    """Whether a reference names a scan table (a shipped table's name, or a table file) rather than a preset."""
    return os.fspath(text) in shipped_tables() or Path(text).suffix.lower() in TABLE_SUFFIXES


def load_reference(source: str | os.PathLike[str], rate: float | None = None,
                   recording_rate: float | None = None) -> ReferencePattern:
    """Read a scan table: a shipped one by name (``"mid70"``), a ``.npy`` (radians), an ``.npz`` with times, a
    Livox CSV (degrees) or a recording (``.pcd``, ``.ply``, a CSV of x, y, z, ``.lvx2``, ``.lvx``, ``.bag``).

    Parameters
    ----------
    source : str or path-like
        A name from :func:`shipped_tables` or a file.
    rate : float, optional
        Firings per second. Default, in this order: a shipped table's own rate (by name, or a file whose
        first rows are a shipped table's), the rows' own times (a CSV's ``Time/s`` column, an ``.npz``'s
        ``t``), else the spectrum's (:func:`~livox_viz.fitting.track_fit.rate_from_spectrum`: the rate at
        which the head's parts turn at whole rpm). The table's ``rate_source`` says which. A rate that
        contradicts a shipped table's own or the rows' times is refused rather than replayed at the wrong
        times.
    recording_rate : float, optional
        Firings per second of a recording whose file has no per-point times (a saved frame): the rate of the head
        it is compared with or shown beside, in place of the spectrum's (a frame of 0.1 s is too short to read a
        rate off). Ignored for other tables and when ``rate`` is given.

    Raises
    ------
    LivoxVizError
        Wrong shape or type, NaN, degrees where radians are expected, too few rows, a contradicting rate,
        times that go back or say no rate a head fires at, a rate nothing gives.
    """
    if rate is not None and (not math.isfinite(rate) or rate <= 0):
        raise LivoxVizError(f"rate {rate!r}; allowed: points per second > 0")
    known = shipped_tables().get(os.fspath(source))
    if known is not None:
        own = float(known["rate"])
        if rate is not None and rate != own:
            raise LivoxVizError(f"{source} is a {own:g} rows/s table; --rate {rate:g} contradicts it "
                                "(leave --rate out)")
        table = _read_file(shipped_table_dir() / f"{source}.npy")
        return _as_pattern(table, str(source), own, "the shipped tables' index", shipped=str(source))
    path = Path(source)
    table = _read_file(path)
    name = path.stem
    slots, said, column = _slots(path, table)
    if said is not None and table.recording and abs(said - round(said)) <= 1e-6 * said:
        said = float(round(said))  # a recording's times are whole nanoseconds: a head fires a whole number a second
    match = _shipped_match(table)
    if said is not None:
        if rate is not None and abs(rate - said) > 1e-3 * said:
            raise LivoxVizError(f"{path}: its {column} column says {said:,.6g} rows/s; --rate {rate:g} contradicts "
                                "it (leave --rate out)")
        shared = ""
        if slots is not None and np.any(np.diff(slots) == 0):
            shared = f", each group of {int(np.bincount(slots).max())} rows at one time"
        return _as_pattern(table, name, rate or said, "given (--rate)" if rate else f"its {column} column{shared}",
                           slots, match or "", table.recording)
    if rate is not None:
        return _as_pattern(table, name, rate, "given (--rate)", slots, match or "", table.recording)
    if match is not None:
        return _as_pattern(table, name, float(shipped_tables()[match]["rate"]),
                           f"the shipped tables' index (its first rows are the shipped {match} table's)", slots, match,
                           table.recording)
    if recording_rate is not None and table.recording:
        return _as_pattern(table, name, float(recording_rate), "the head's point rate (the recording has no per-point "
                           "times)", slots, recording=table.recording)
    from livox_viz.fitting.track_fit import rate_from_spectrum

    xy, plane = xy_from_zup(table.azimuth, table.elevation)
    said, how = rate_from_spectrum(name, xy, plane, slots)
    return _as_pattern(table, name, said, how, slots, recording=table.recording)


@dataclass(frozen=True)
class _FileRows:
    """A table file's rows: azimuth about +z and elevation (radians; x forward, y left, z up) and, when the file
    has them, each row's time (seconds) or a column counting rows."""

    azimuth: np.ndarray
    elevation: np.ndarray
    times: np.ndarray | None = None
    column: str = ""
    #: The first line of data in the file (a CSV's line numbers in messages), or None for a row index.
    first_line: int | None = None
    #: The recording's format when the rows are a real sensor's recording (:data:`RECORDING_READERS`), else "".
    recording: str = ""


def _as_pattern(table: _FileRows, name: str, rate: float, source: str, slots: np.ndarray | None = None,
                shipped: str = "", recording: str = "") -> ReferencePattern:
    xy, plane = xy_from_zup(table.azimuth, table.elevation)
    # Some of Livox's tables are mirror images of what the hardware does: their rows are turned as the index says.
    image = shipped_tables()[shipped].get("image", "as printed") if shipped else "as printed"
    xy *= np.array(PLANE_IMAGES[image], dtype=np.float64)
    count = xy.shape[0]
    t = (np.arange(count, dtype=np.float64) if slots is None else slots.astype(np.float64)) / rate
    return ReferencePattern(name, xy, t, float(rate), plane, source, shipped, image, recording)


def _read_file(path: Path) -> _FileRows:
    require_file(path, "scan table (.npy, .npz, Livox CSV) or recording (.pcd, .ply, x,y,z .csv, .lvx2, .lvx or "
                       "ROS 1 .bag)")
    suffix = path.suffix.lower()
    if suffix in RECORDING_SUFFIXES or is_point_csv(path):
        table = _read_recording(path)
    elif suffix == ".npy":
        angles = _checked_angles(path, _checked_header(path, "the table"), "a .npy table")
        table = _FileRows(angles[:, 0], angles[:, 1])
    elif suffix == ".npz":
        table = _read_npz(path)
    elif suffix == ".csv":
        table = _read_csv(path)
    else:
        raise LivoxVizError(f"{path}: unknown format {path.suffix or '(none)'}; allowed: "
                            f"{', '.join(TABLE_SUFFIXES)}")
    if table.azimuth.size < 16:
        raise LivoxVizError(f"{path}: {table.azimuth.size} rows; allowed: at least a petal's worth (16 rows)")
    return table


#: Readers of recordings by suffix, registered by :mod:`livox_viz.files` (a later stage of the pipeline, which this
#: module may not import): ``reader(path, rows)`` gives the first device's first returns in firing order, at most
#: ``rows`` of them, as points ``(n, 3)`` (x forward, y left, z up, metres; a no-return, ``(0, 0, 0)``, is a gap)
#: and times ``(n,)`` seconds, or None when the file has no per-point times: then the rows are every firing, and
#: each returned row's slot is its row index. The result's third item is the format read ("PCD", "LVX2", ...).
RECORDING_READERS: dict[str, Callable[[Path, int], tuple[np.ndarray, np.ndarray | None, str]]] = {}


def _read_recording(path: Path) -> _FileRows:
    """A recording's returned rows (:data:`RECORDING_READERS`), each with its time from the first row's (or, without
    times, its row index: the no-returns between are gaps)."""
    reader = RECORDING_READERS.get(path.suffix.lower())
    if reader is None:
        raise LivoxVizError(f"{path}: recordings are read by livox_viz.files; allowed: import livox_viz.files "
                            "first (the command line and the window do)")
    points, times, form = reader(path, MAX_TABLE_ROWS)
    returned = np.flatnonzero(np.any(points != 0.0, axis=1))
    if returned.size == 0:
        raise LivoxVizError(f"{path}: no returns in its {points.shape[0]:,} rows (every point (0, 0, 0) or none); "
                            "allowed: a recorded frame with returns")
    x, y, z = points[returned].T
    if times is None:
        rows, column = returned, "row"  # firing order from the file's first row: a no-return row is a gap
    else:
        rows, column = times[returned] - times[0], "time"
    return _FileRows(np.arctan2(y, x), np.arctan2(z, np.hypot(x, y)), rows.astype(np.float64), column, None, form)


def _checked_header(path: Path, what: str, source: Any = None) -> np.ndarray:
    """A ``.npy`` array (``source``: an open member of an ``.npz``), its header checked before its data is read:
    no Python objects, no complex numbers or text, at most :data:`MAX_TABLE_ROWS` rows."""
    allowed = "allowed: a NumPy .npy array of (n, 2) numbers, [theta, phi] in radians"
    # The header first: what it claims (a shape, Python objects) is named before any data is mapped.
    header = np.lib.format
    try:
        handle = source if source is not None else open(path, "rb")
        try:
            version = header.read_magic(handle)
            read = header.read_array_header_1_0 if version == (1, 0) else header.read_array_header_2_0
            shape, _, dtype = read(handle)
        finally:
            if source is None:
                handle.close()
    except (ValueError, OSError, EOFError, SyntaxError) as exc:
        raise LivoxVizError(f"{path}: {what} is not a NumPy array ({exc}); {allowed}") from None
    if dtype.hasobject:
        raise LivoxVizError(f"{path}: {what} holds Python objects (pickled data, never loaded); {allowed}")
    if dtype.kind not in "fiu":
        kind = {"c": "complex numbers", "b": "true/false values", "U": "text", "S": "bytes", "V": "records",
                "M": "dates", "m": "time spans"}.get(dtype.kind, f"values of type {dtype}")
        raise LivoxVizError(f"{path}: {what} holds {kind}; allowed: real numbers (radians, seconds)")
    if len(shape) >= 1 and shape[0] > MAX_TABLE_ROWS:
        raise LivoxVizError(f"{path}: {shape[0]:,} rows; allowed: at most {MAX_TABLE_ROWS:,} (cut the table: "
                            "a few seconds are enough to fit a track)")
    return shape


def _checked_angles(path: Path, shape: tuple[int, ...], what: str, member: str | None = None) -> np.ndarray:
    """The ``(n, 2)`` float64 [theta, phi] radians of a ``.npy`` file (or of ``member`` of an ``.npz``)."""
    if len(shape) != 2 or shape[1] != 2:
        raise LivoxVizError(f"{path}: shape {shape}; allowed: (n, 2) columns [theta, phi] in radians")
    if shape[0] < 16:
        raise LivoxVizError(f"{path}: {shape[0]} rows; allowed: at least a petal's worth (16 rows)")
    try:
        if member is None:
            table = np.array(np.load(path, allow_pickle=False, mmap_mode="r"), dtype=np.float64)
        else:
            with np.load(path, allow_pickle=False) as archive:
                table = np.array(archive[member], dtype=np.float64)
    except (ValueError, OSError, EOFError, TypeError) as exc:
        raise LivoxVizError(f"{path}: not a whole NumPy array ({exc}); allowed: {what} of (n, 2) numbers") from None
    _check_radians(path, table, f"{what} holds")
    return table


def _check_radians(path: Path, angles: np.ndarray, holds: str) -> None:
    """Refuse NaN, infinite values and degrees (angles past 2 pi) in angles that should be radians."""
    _check_finite(path, angles)
    if np.abs(angles).max() > 2 * math.pi + 1e-6:
        raise LivoxVizError(f"{path}: angles up to {np.abs(angles).max():.4g} look like degrees; {holds} radians")


def _read_npz(path: Path) -> _FileRows:
    """An ``.npz`` of ``theta`` and ``phi`` (radians, or ``angles`` (n, 2)) and optionally ``t`` (seconds)."""
    allowed = "allowed: an .npz of theta and phi (radians) or angles (n, 2), and t (seconds) for the rows' times"
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise LivoxVizError(f"{path}: not an .npz archive ({exc}); {allowed}") from None
    with archive:
        members = {Path(info.filename).stem: info.filename for info in archive.infolist()
                   if info.filename.endswith(".npy")}
        shapes = {}
        for key in ("theta", "phi", "angles", "t"):
            if key in members:
                with archive.open(members[key]) as handle:
                    shapes[key] = _checked_header(path, f"its {key}", handle)
    if "angles" in shapes:
        angles = _checked_angles(path, shapes["angles"], "an .npz's angles", "angles")
    elif "theta" in shapes and "phi" in shapes:
        if shapes["theta"] != shapes["phi"] or len(shapes["theta"]) != 1:
            raise LivoxVizError(f"{path}: theta {shapes['theta']} and phi {shapes['phi']}; allowed: two columns of "
                                "one length")
        with np.load(path, allow_pickle=False) as data:
            angles = np.column_stack([np.asarray(data["theta"], dtype=np.float64),
                                      np.asarray(data["phi"], dtype=np.float64)])
        _check_radians(path, angles, "theta and phi hold")
    else:
        raise LivoxVizError(f"{path}: holds {', '.join(sorted(members)) or 'no arrays'}; {allowed}")
    times = None
    if "t" in shapes:
        if shapes["t"] != (angles.shape[0],):
            raise LivoxVizError(f"{path}: t has shape {shapes['t']} for {angles.shape[0]} rows; allowed: one time "
                                "per row")
        with np.load(path, allow_pickle=False) as data:
            times = np.asarray(data["t"], dtype=np.float64)
        _check_finite(path, times[:, None], column="t")
    return _FileRows(angles[:, 0], angles[:, 1], times, "t", 0)


def _check_finite(path: Path, table: np.ndarray, first_line: int | None = None, column: str = "") -> None:
    """Refuse NaN or infinite rows; ``first_line`` numbers CSV rows by their line in the file."""
    bad = ~np.isfinite(table).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        where = f"line {row + first_line}" if first_line is not None else f"row {row}"
        what = f"values of {column}" if column else "values"
        raise LivoxVizError(f"{path}: {int(bad.sum())} rows hold NaN or infinite {what} (first at {where}); "
                            f"allowed: finite {'times' if column else 'angles'}")


def _read_csv(path: Path) -> _FileRows:
    """Azimuth and zenith columns of a Livox CSV (degrees) and its ``Time/s`` column, if any. Errors name the
    line."""
    size = path.stat().st_size
    if size > MAX_CSV_BYTES:
        raise LivoxVizError(f"{path}: {size / 2**20:.0f} MiB; allowed: a CSV of at most {MAX_CSV_BYTES // 2**20} MiB "
                            "(cut the table, or save it as .npy)")
    raw = path.read_bytes()
    try:
        text = decode_text(raw)
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise LivoxVizError(f"{path}: not UTF-8 text (byte {exc.start}, line {line}); allowed: a Livox CSV "
                            f"(Time/s,Azimuth/deg,Zenith/deg) in {ENCODINGS}") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise LivoxVizError(f"{path}: is empty; allowed: a Livox CSV with a header line Time/s,Azimuth/deg,Zenith/deg")
    header = next(csv.reader([lines[0]]))
    names = [h.strip().lower() for h in header]
    try:
        azimuth_col = next(i for i, n in enumerate(names) if n.startswith("azimuth"))
        zenith_col = next(i for i, n in enumerate(names) if n.startswith("zenith"))
    except StopIteration:
        raise LivoxVizError(f"{path}: header {header!r}; allowed: Time/s,Azimuth/deg,Zenith/deg") from None
    rows = lines[1:]
    if not any(row.strip() for row in rows):
        raise LivoxVizError(f"{path}: has a header but no data rows")
    time_col = next((i for i, n in enumerate(names) if n.startswith("time")), None)
    columns = (azimuth_col, zenith_col) if time_col is None else (azimuth_col, zenith_col, time_col)
    if len(rows) > MAX_TABLE_ROWS:
        raise LivoxVizError(f"{path}: {len(rows):,} rows; allowed: at most {MAX_TABLE_ROWS:,}")
    try:
        table = np.loadtxt(rows, delimiter=",", usecols=columns, ndmin=2)
    except ValueError as exc:
        message = re.sub(r"at row (\d+)", lambda m: f"at line {int(m.group(1)) + 2}", str(exc).splitlines()[0])
        raise LivoxVizError(f"{path}: not numeric ({message})") from None
    _check_finite(path, table, first_line=2)
    angles = table[:, :2]
    if np.abs(angles).max() <= 2 * math.pi and np.abs(angles[:, 1]).max() < 3.2:
        raise LivoxVizError(f"{path}: angles at most {np.abs(angles).max():.3g} look like radians; "
                            "the CSV form is degrees (Azimuth/deg, Zenith/deg)")
    times = table[:, 2] if time_col is not None else None
    return _FileRows(np.radians(angles[:, 0]), np.radians(90.0 - angles[:, 1]), times,
                     header[time_col].strip() if time_col is not None else "", 2)


def _slots(path: Path, table: _FileRows) -> tuple[np.ndarray | None, float | None, str]:
    """Each row's firing slot from the file's time column, and the rate it says (None: it says none).

    A column that counts rows (whole numbers stepping by 1 or more) gives the slots, gaps and all, but no rate;
    one holding a single value says nothing. Times in seconds step by whole numbers of one firing period: the
    period is the smallest common step (a low percentile of the steps, refined over the whole column), each
    step a whole number of periods. Rows listed in groups that share one time (a head firing its K lasers
    together, each group printed once, in any order within it) keep their group's time: every group of K rows
    at one slot, K slots after the last (:func:`_shared_time_slots`). Times printed too coarsely to place each
    row (steps that are no whole number of periods, or runs of rows of uneven length sharing a time) give the
    rate of a line through the times, the rows taken as consecutive (which laser fired when is then the
    geometry's to say, :func:`~livox_viz.fitting.lasers.assign_lasers`).
    """
    times, column = table.times, table.column
    if times is None or times.size < 2:
        return None, None, column

    def line(row: int) -> str:
        return f"line {row + table.first_line}" if table.first_line else f"row {row}"

    if column == "row":  # a recording's rows in firing order: the returned rows' indices are their slots
        slots = times.astype(np.int64)
        _check_gaps(path, slots, "rows", line, "count")
        return (None if slots[0] == 0 and slots[-1] == slots.size - 1 else slots), None, column
    steps = np.diff(times)
    if np.any(steps < 0):
        row = int(np.flatnonzero(steps < 0)[0]) + 1
        raise LivoxVizError(f"{path}: {column} goes back at {line(row)} ({times[row - 1]:.9g} then {times[row]:.9g} "
                            "s); allowed: rows in firing order (an export sorted by another column has lost it: "
                            "export the rows unsorted)")
    if np.all(steps == 0):
        return None, None, column
    if np.all(times == np.round(times)) and steps[steps > 0].min() == 1:
        slots = (times - times[0]).astype(np.int64)
        _check_gaps(path, slots, column, line, "counts rows")
        return (None if np.all(steps == 1) else slots), None, column
    shared = _shared_time_slots(times)
    if shared is not None:
        slots, said = shared
        _check_gaps(path, slots, column, line, "steps")
    else:
        placed = _placed(times)
        if placed is not None and np.all(steps > 0):
            slots = placed
            _check_gaps(path, slots, column, line, "steps")
            said = 1.0 / float(np.polyfit(slots.astype(np.float64), times - times[0], 1)[0])
            if table.recording:  # a frame's times start at its first row, which may be a no-return: a gap
                slots = slots + round(times[0] * said)
        else:
            slots = None
            rows = np.arange(times.size, dtype=np.float64)
            said = 1.0 / float(np.polyfit(rows, times - times[0], 1)[0])
    if not MIN_RATE <= said <= MAX_RATE:
        raise LivoxVizError(f"{path}: its {column} column steps {1 / said:.3g} s from firing to firing ({said:.3g} "
                            f"rows/s); allowed: times in seconds, {MIN_RATE:g} to {MAX_RATE:,.0f} rows/s")
    return slots, said, column


def _placed(times: np.ndarray) -> np.ndarray | None:
    """Each time's slot, a whole number of one period from the first (None when the times are no such steps).

    The period is the smallest common step (a low percentile of the steps, refined over the whole column); each
    step is a whole number of periods, and every time must lie within 0.4 period of its slot. Times rounded to
    a print step over :data:`MAX_PRINT_STEP` of the period place nothing (unless they sit on the periods
    exactly, one after another): 1 us steps on a 2.2 us period (452 000 rows/s) read as 1.8 us steps with
    gaps that pass the 0.4 test.
    """
    steps = np.diff(times)
    if not np.any(steps > 0):
        return None
    period = float(np.percentile(steps[steps > 0], 5))
    span = float(times[-1] - times[0])
    whole = np.ones_like(steps)
    for _ in range(4):  # times printed to a few decimals: the period from the span, the steps from the period
        whole = np.maximum(1.0, np.round(steps / period))
        period = span / float(whole.sum())
    slots = np.concatenate([[0], np.cumsum(whole.astype(np.int64))])
    off = float(np.abs(times - times[0] - slots * period).max())
    if off > 0.4 * period:
        return None
    # Printed as coarsely as the period, times place rows only when they sit on it exactly, nearly every one a
    # period after the last (10 us steps on a 13.3 us period read as a 10 us period with every third missing).
    exact = off <= 1e-3 * period and np.mean(whole == 1) >= 0.99
    if _print_step(times) > MAX_PRINT_STEP * period and not exact:
        return None
    return slots


def _print_step(times: np.ndarray) -> float:
    """The step the times are printed to (seconds: 1e-6 for six decimals), 0 when finer than 1e-12 s."""
    for decimals in range(13):
        scaled = times * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-6 + 1e-14 * np.abs(scaled)):
            return 10.0**-decimals
    return 0.0


def _shared_time_slots(times: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Slots and rate (rows per second) of rows listed in groups of K that share one time, else None.

    Every distinct time but the first and last (a table cut anywhere) holds the same K >= 2 rows, and the
    distinct times step by whole numbers of one group period P: each row's slot is K x its group's, the rate
    K / P. The rows of a group are then each at the group's time, whatever order they are listed in.
    """
    distinct, counts = np.unique(times, return_counts=True)
    if distinct.size < 3 or distinct.size == times.size:
        return None
    lasers = int(np.bincount(counts[1:-1]).argmax())
    if lasers < 2 or np.any(counts[1:-1] != lasers) or counts[0] > lasers or counts[-1] > lasers:
        return None
    groups = _placed(distinct)
    if groups is None:
        return None
    period = float(np.polyfit(groups.astype(np.float64), distinct - distinct[0], 1)[0])
    slots = np.repeat(lasers * groups, counts)
    return slots, lasers / period


def _check_gaps(path: Path, slots: np.ndarray, column: str, line: Any, what: str) -> None:
    """Refuse a time column whose rows are mostly gaps (one wrong time far off the others)."""
    firings = int(slots[-1]) + 1
    if firings > MAX_GAP_RATIO * slots.size:
        gaps = np.diff(slots)
        row = int(np.argmax(gaps)) + 1
        raise LivoxVizError(f"{path}: its {column} column {what} to {firings:,} firings for {slots.size:,} rows (the "
                            f"largest jump, {int(gaps[row - 1]):,} firings, at {line(row)}); allowed: rows with at "
                            f"most {MAX_GAP_RATIO - 1} firings missing per row")


def _shipped_match(table: _FileRows) -> str | None:
    """The shipped table whose first rows this file's first rows are (a copy or a longer export of it)."""
    head = min(table.azimuth.size, MATCH_ROWS)
    ours = np.column_stack([table.azimuth[:head], table.elevation[:head]])
    for name in shipped_tables():
        shipped = np.load(shipped_table_dir() / f"{name}.npy", mmap_mode="r")
        if shipped.shape[0] >= head and np.allclose(np.asarray(shipped[:head], dtype=np.float64), ours,
                                                    rtol=0, atol=1e-6):
            return name
    return None


def pattern_table(config, name: str, seconds: float = 4.0, seed: int = 0) -> ReferencePattern:
    """The first ``seconds`` of a configuration's pattern as a table, like a measured one.

    Parameters
    ----------
    config : SensorConfig
    name : str
    seconds : float
    seed : int
    """
    from livox_viz.core.workload import check_points
    from livox_viz.patterns.factory import make_pattern
    from livox_viz.patterns.stream import points_before

    count = points_before(seconds, config.point_rate)
    check_points(count, f"{seconds:g} s of {name}")
    chunk = make_pattern(config, seed).take(count)
    return ReferencePattern(name, chunk.xy_deg.copy(), chunk.t.copy(), float(config.point_rate),
                            config.pattern_plane, "the preset's point rate")


def load_table_or_preset(text: str, rate: float | None = None, seconds: float = 4.0,
                         seed: int = 0, recording_rate: float | None = None) -> ReferencePattern:
    """A reference given on the command line: a table (shipped name or file) or a recording (``recording_rate``:
    see :func:`load_reference`), or a preset (name or JSON) replayed for ``seconds``."""
    if Path(text).is_dir() and Path(text).suffix.lower() != ".bag":
        raise LivoxVizError(f"{text}: is a folder; allowed: a table (.npy, .npz or Livox .csv), a recording (.pcd, "
                            ".ply, x,y,z .csv, .lvx2, .lvx or .bag) or a preset (name or .json)")
    if is_table(text):
        return load_reference(text, rate=rate, recording_rate=recording_rate)
    from livox_viz.config.presets import load_preset

    return pattern_table(load_preset(text), Path(text).stem, seconds, seed)
