"""Livox recordings as reference tables: what ``compare``, ``fit`` and the window read from an LVX or a bag.

Registered with :data:`livox_viz.fitting.reference.RECORDING_READERS` when
:mod:`livox_viz.files` is imported (the fitting stage comes before the files
stage and may not import it). A recording gives its first device's first
returns in firing order (the firings that returned nothing are left out: they
are the table's gaps), each with the time its file's driver gives it; an LVX is
read frame by frame only as far as the rows asked for.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from livox_viz.files.livox_recording import LivoxRecording


def _first_returns(recording: LivoxRecording) -> LivoxRecording:
    return recording.subset(~recording.no_return & (recording.return_number == 1) & (recording.device_index == 0))


def lvx_rows(path: Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """An LVX2's or LVX 1.1's first ``rows`` first returns: points ``(n, 3)`` metres (x forward, y left, z up) and
    times ``(n,)`` seconds."""
    from livox_viz.files.lvx_read import iter_lvx, read_layout

    parts, count = [], 0
    for frame in iter_lvx(path):
        part = _first_returns(frame)
        parts.append(part)
        count += len(part)
        if count >= rows:
            break
    layout = read_layout(path)
    joined = LivoxRecording.join(parts, layout.devices, layout.source, {}).subset(slice(0, rows))
    return joined.points_m, joined.times_s


def bag_rows(path: Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """A Livox driver's bag's first ``rows`` first returns, as :func:`lvx_rows`."""
    from livox_viz.files.livox_bag import read_livox_bag

    joined = _first_returns(read_livox_bag(path, max_points=4 * rows)).subset(slice(0, rows))
    return joined.points_m, joined.times_s


def register() -> None:
    """Make ``.lvx2``, ``.lvx`` and ``.bag`` readable as reference tables."""
    from livox_viz.fitting.reference import RECORDING_READERS

    RECORDING_READERS.update({".lvx2": lvx_rows, ".lvx": lvx_rows, ".bag": bag_rows})
