"""Recordings as reference tables: what ``compare``, ``fit`` and the window read from an LVX, a bag or a saved frame.

Registered with :data:`livox_viz.fitting.reference.RECORDING_READERS` when
:mod:`livox_viz.files` is imported (the fitting stage comes before the files
stage and may not import it). A recording gives its first device's first
returns in firing order (the firings that returned nothing are left out: they
are the table's gaps), each with the time its file's driver gives it; an LVX is
read frame by frame only as far as the rows asked for. A frame saved as PCD,
PLY or a CSV of x, y, z (:mod:`~livox_viz.files.frame_files`) gives its rows
in firing order with its no-returns as ``(0, 0, 0)``, and its per-point times
when it has them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from livox_viz.files.livox_recording import LivoxRecording


def _first_returns_mask(recording: LivoxRecording) -> np.ndarray:
    return ~recording.no_return & (recording.return_number == 1) & (recording.device_index == 0)


def _first_returns(recording: LivoxRecording) -> LivoxRecording:
    return recording.subset(_first_returns_mask(recording))


def lvx_rows(path: Path, rows: int) -> tuple[np.ndarray, np.ndarray, str]:
    """An LVX2's or LVX 1.1's first ``rows`` first returns: points ``(n, 3)`` metres (x forward, y left, z up),
    times ``(n,)`` seconds and the format."""
    from livox_viz.files.lvx_read import read_lvx_start

    joined = read_lvx_start(path, rows, _first_returns_mask)
    return joined.points_m, joined.times_s, joined.source


def bag_rows(path: Path, rows: int) -> tuple[np.ndarray, np.ndarray, str]:
    """A Livox driver's bag's first ``rows`` first returns, as :func:`lvx_rows`."""
    from livox_viz.files.livox_bag import read_livox_bag

    recording = read_livox_bag(path, max_points=4 * rows)
    joined = _first_returns(recording).subset(slice(0, rows))
    return joined.points_m, joined.times_s, recording.source


def frame_rows(path: Path, rows: int) -> tuple[np.ndarray, np.ndarray | None, str]:
    """A saved frame's (PCD, PLY, CSV of x, y, z) first ``rows`` rows in firing order: points ``(n, 3)`` metres
    (x forward, y left, z up; no-returns ``(0, 0, 0)``), times ``(n,)`` seconds or None when the file has none, and
    the format."""
    from livox_viz.files.frame_files import read_frame_rows

    frame = read_frame_rows(path, rows)
    return frame.points_m, frame.times_s, frame.source


def register() -> None:
    """Make ``.lvx2``, ``.lvx``, ``.bag``, ``.pcd``, ``.ply`` and a CSV of x, y, z readable as reference tables."""
    from livox_viz.fitting.reference import RECORDING_READERS

    RECORDING_READERS.update({".lvx2": lvx_rows, ".lvx": lvx_rows, ".bag": bag_rows, ".pcd": frame_rows,
                              ".ply": frame_rows, ".csv": frame_rows})
