"""Measured scan patterns: the reference ``.npy`` table and Livox's simulation CSV, in our angular plane.

Both forms give, row by row in firing order, a ray as azimuth and elevation
(``.npy``: ``[theta, phi]`` radians, x forward, y left, z up) or azimuth and
zenith (CSV: ``Time/s,Azimuth/deg,Zenith/deg``, degrees). They are turned into
FRD rays and then into pattern x (right), y (up) in degrees of one of the two
pattern planes (:mod:`livox_viz.patterns.planes`): the boresight plane (angle
off the boresight as the polar radius), or, for a table whose rays go all
around the sensor (more than 1 % of them behind it, e.g. the Mid-360), the
panorama plane (azimuth, elevation).

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
from pathlib import Path
from typing import Any

import numpy as np

from livox_viz.config.presets import shipped_preset_dir
from livox_viz.core.errors import LivoxVizError, require_file
from livox_viz.fitting.table import ReferencePattern
from livox_viz.patterns.planes import frd_from_zup, xy_from_directions

DEFAULT_RATE = 100_000.0
#: Most rows a table may hold (100 s at 100 000 rows/s; a fit of this many rows stays within about 2 GB).
MAX_TABLE_ROWS = 10_000_000
#: Largest Livox CSV read (a CSV row is about 30 bytes: some 8 million rows).
MAX_CSV_BYTES = 256 * 1024 * 1024
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
    """The shipped tables by name (``mid40``, ...): each with its ``rate`` (rows/s) and a ``description``."""
    try:
        index = json.loads((shipped_table_dir() / "index.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    return {name: entry for name, entry in index.items() if (shipped_table_dir() / f"{name}.npy").is_file()}


def is_table(text: str | os.PathLike[str]) -> bool:
    """Whether a reference names a scan table (a shipped table's name, or a .npy/.csv file) rather than a preset."""
    return os.fspath(text) in shipped_tables() or Path(text).suffix.lower() in (".npy", ".csv")


def load_reference(source: str | os.PathLike[str], rate: float | None = None) -> ReferencePattern:
    """Read a scan table: a shipped one by name (``"mid70"``), a ``.npy`` table (radians) or a Livox CSV (degrees).

    Parameters
    ----------
    source : str or path-like
        A name from :func:`shipped_tables` or a file.
    rate : float, optional
        Rows per second. Default: a shipped table's own rate, a CSV's ``Time/s`` column, else 100 000. A
        rate that contradicts a shipped table's own or a CSV's time column is refused rather than replayed
        at the wrong times.

    Raises
    ------
    LivoxVizError
        Wrong shape, NaN, degrees where radians are expected, too few rows, a contradicting rate.
    """
    known = shipped_tables().get(os.fspath(source))
    if known is not None:
        own = float(known["rate"])
        if rate is not None and rate != own:
            raise LivoxVizError(f"{source} is a {own:g} rows/s table; --rate {rate:g} contradicts it "
                                "(leave --rate out)")
        return _load_file(shipped_table_dir() / f"{source}.npy", own, str(source))
    return _load_file(Path(source), rate, Path(source).stem)


def _load_file(path: Path, rate: float | None, name: str) -> ReferencePattern:
    """A table file at ``rate`` rows/s (default: a CSV's time column, else :data:`DEFAULT_RATE`), named ``name``."""
    if rate is not None and (not math.isfinite(rate) or rate <= 0):
        raise LivoxVizError(f"rate {rate!r}; allowed: points per second > 0")
    require_file(path, "scan table (.npy or Livox CSV)")
    if path.suffix.lower() == ".npy":
        table = _read_npy(path)
        xy, plane = xy_from_zup(table[:, 0], table[:, 1])
    elif path.suffix.lower() == ".csv":
        xy, plane, rate = _read_csv(path, rate)
    else:
        raise LivoxVizError(f"{path}: unknown format {path.suffix or '(none)'}; allowed: .npy or .csv")
    if xy.shape[0] < 16:
        raise LivoxVizError(f"{path}: {xy.shape[0]} rows; allowed: at least a petal's worth (16 rows)")
    rate = DEFAULT_RATE if rate is None else rate
    t = np.arange(xy.shape[0], dtype=np.float64) / rate
    return ReferencePattern(name, xy, t, float(rate), plane)


def _read_npy(path: Path) -> np.ndarray:
    """The ``(n, 2)`` float64 radians of a ``.npy`` table, its shape and size checked before its data is read."""
    allowed = "allowed: a NumPy .npy array of (n, 2) numbers, [theta, phi] in radians"
    # The header first: what it claims (a shape, Python objects) is named before any data is mapped.
    header = np.lib.format
    try:
        with open(path, "rb") as handle:
            version = header.read_magic(handle)
            read = header.read_array_header_1_0 if version == (1, 0) else header.read_array_header_2_0
            shape, _, dtype = read(handle)
    except (ValueError, OSError, EOFError, SyntaxError) as exc:
        raise LivoxVizError(f"{path}: not a NumPy .npy array ({exc}); {allowed}") from None
    if dtype.hasobject:
        raise LivoxVizError(f"{path}: holds Python objects (pickled data, never loaded); {allowed}")
    if len(shape) == 2 and shape[0] > MAX_TABLE_ROWS:
        raise LivoxVizError(f"{path}: {shape[0]:,} rows; allowed: at most {MAX_TABLE_ROWS:,} (cut the table: "
                            "a few seconds are enough to fit a track)")
    try:
        mapped = np.load(path, allow_pickle=False, mmap_mode="r")
    except (ValueError, OSError, EOFError) as exc:
        raise LivoxVizError(f"{path}: not a whole NumPy .npy array ({exc}); {allowed}") from None
    if mapped.ndim != 2 or mapped.shape[1] != 2:
        raise LivoxVizError(f"{path}: shape {mapped.shape}; allowed: (n, 2) columns [theta, phi] in radians")
    if mapped.shape[0] < 16:
        raise LivoxVizError(f"{path}: {mapped.shape[0]} rows; allowed: at least a petal's worth (16 rows)")
    if mapped.shape[0] > MAX_TABLE_ROWS:
        raise LivoxVizError(f"{path}: {mapped.shape[0]:,} rows; allowed: at most {MAX_TABLE_ROWS:,} (cut the table: "
                            "a few seconds are enough to fit a track)")
    try:
        table = np.array(mapped, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise LivoxVizError(f"{path}: not numeric angles ({exc})") from None
    _check_finite(path, table)
    if np.abs(table).max() > 2 * math.pi + 1e-6:
        raise LivoxVizError(f"{path}: angles up to {np.abs(table).max():.4g} look like degrees; the .npy form is "
                            "radians")
    return table


def _check_finite(path: Path, table: np.ndarray, first_line: int | None = None) -> None:
    """Refuse NaN or infinite rows; ``first_line`` numbers CSV rows by their line in the file."""
    bad = ~np.isfinite(table).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        where = f"line {row + first_line}" if first_line is not None else f"row {row}"
        raise LivoxVizError(f"{path}: {int(bad.sum())} rows hold NaN or infinite values (first at {where}); "
                            "allowed: finite angles")


def _read_csv(path: Path, rate: float | None) -> tuple[np.ndarray, str, float | None]:
    """Azimuth and zenith columns of a Livox CSV, degrees, as pattern x, y, their plane, and the rows' rate.

    The rate is the one given, else the one the ``Time/s`` column says (when it holds times rather than a
    row index), else None; a given rate that contradicts the time column is refused. Errors name the line.
    """
    size = path.stat().st_size
    if size > MAX_CSV_BYTES:
        raise LivoxVizError(f"{path}: {size / 2**20:.0f} MiB; allowed: a CSV of at most {MAX_CSV_BYTES // 2**20} MiB "
                            "(cut the table, or save it as .npy)")
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise LivoxVizError(f"{path}: not UTF-8 text (byte {exc.start}, line {line}); allowed: a Livox CSV "
                            "(Time/s,Azimuth/deg,Zenith/deg)") from None
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
    if time_col is not None:
        rate = _rate_from_times(path, table[:, 2], rate)
        table = table[:, :2]
    if np.abs(table).max() <= 2 * math.pi and np.abs(table[:, 1]).max() < 3.2:
        raise LivoxVizError(f"{path}: angles at most {np.abs(table).max():.3g} look like radians; "
                            "the CSV form is degrees (Azimuth/deg, Zenith/deg)")
    azimuth = np.radians(table[:, 0])
    elevation = np.radians(90.0 - table[:, 1])
    xy, plane = xy_from_zup(azimuth, elevation)
    return xy, plane, rate


def _rate_from_times(path: Path, times: np.ndarray, rate: float | None) -> float | None:
    """The rate a ``Time/s`` column says (rows per second), checked against a given ``rate``.

    A column counting rows (0, 1, 2, ...) or holding one value says nothing. Times printed with few
    decimals step unevenly, so the rate is the mean step over the whole column.
    """
    steps = np.diff(times)
    if times.size < 2 or np.all(steps == 0) or np.allclose(steps, 1.0):
        return rate
    if np.any(steps < 0):
        row = int(np.flatnonzero(steps < 0)[0]) + 3
        raise LivoxVizError(f"{path}: Time/s goes back at line {row}; allowed: rows in firing order")
    said = (times.size - 1) / float(times[-1] - times[0])
    if rate is not None and abs(rate - said) > 1e-3 * said:
        raise LivoxVizError(f"{path}: its Time/s column says {said:,.6g} rows/s; --rate {rate:g} contradicts it "
                            "(leave --rate out)")
    return said if rate is None else rate


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
                            config.pattern_plane)


def load_table_or_preset(text: str, rate: float | None = None, seconds: float = 4.0,
                         seed: int = 0) -> ReferencePattern:
    """A reference given on the command line: a table (shipped name or file), or a preset (name or JSON)
    replayed for ``seconds``."""
    if is_table(text):
        return load_reference(text, rate=rate)
    if Path(text).is_dir():
        raise LivoxVizError(f"{text}: is a folder; allowed: a table (.npy or Livox .csv) or a preset (name or .json)")
    from livox_viz.config.presets import load_preset

    return pattern_table(load_preset(text), Path(text).stem, seconds, seed)
