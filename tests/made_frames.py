"""Recorded frames made from a preset's track, written as a real sensor's frame files.

Rows in firing order in the Livox frame (x forward, y left, z up, metres), a
quarter of them no-returns as ``(0, 0, 0)``, as Livox Viewer and
livox_ros_driver2 save a frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from livox_viz import load_preset
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.planes import directions_from_xy

#: The head the frames are made from.
HEAD = "livox_tele15"


def made_frame(seconds: float = 0.1, first_sample: int = 0, no_returns: float = 0.25, seed: int = 0,
               preset: str = HEAD) -> np.ndarray:
    """``(n, 3)`` metres: ``seconds`` of ``preset``'s track from ``first_sample``, each row at 5-80 m, a share
    ``no_returns`` of them zero."""
    config = load_preset(preset)
    count = round(seconds * config.point_rate)
    xy = make_pattern(config).points(first_sample, count).xy_deg
    rng = np.random.default_rng(seed)
    points = directions_from_xy(xy, config.pattern_plane) * np.array([1.0, -1.0, -1.0]) * rng.uniform(5.0, 80.0,
                                                                                                     (count, 1))
    points[rng.random(count) < no_returns] = 0.0
    return points


def write_pcd(path: Path, points: np.ndarray) -> Path:
    """An ascii PCD of fields x, y, z."""
    count = points.shape[0]
    with path.open("w", encoding="ascii") as handle:
        handle.write(f"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {count}\nHEIGHT 1\n"
                     f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {count}\nDATA ascii\n")
        np.savetxt(handle, points, fmt="%.6f")
    return path


def write_xyz_csv(path: Path, points: np.ndarray, times_s: np.ndarray | None = None) -> Path:
    """A CSV whose header names x, y, z (and t, seconds, when ``times_s`` is given)."""
    columns = points if times_s is None else np.column_stack([points, times_s])
    header = "x,y,z" if times_s is None else "x,y,z,t"
    np.savetxt(path, columns, fmt="%.9f", delimiter=",", header=header, comments="")
    return path
