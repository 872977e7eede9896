"""The scene view's picks as a list, without Qt or VTK: their columns, the measures between them, their text.

A pick is what :meth:`~livox_viz.widgets.session.Session.scene_point` gives for a point clicked in the scene
view (its world NED and sensor FRD coordinates, range, angles, reflectivity, time...). The picks are numbered
1, 2, 3... in the order they were made; the measures are those of CloudCompare's distance and 3-point angle
tools, taken on the last picks: the distance between the last two, the angle between their rays as the sensor
fired them, and the angle at the middle one of the last three. The Picks panel
(:mod:`~livox_viz.widgets.picks_panel`), the status bar and the clipboard all show the text made here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: What the picks' x, y and z are: the scene's world frame, as the cloud is drawn and as ``scan`` and File >
#: Export write PLY, PCD and CSV (so a pick's numbers are found again in an exported file).
FRAME_NOTE = "x, y, z: world NED (x north, y east, z down), metres, as the PLY, PCD and CSV exports"

#: The list's columns: (the pick's key or "number", the table's header, the clipboard's header, its format).
COLUMNS: tuple[tuple[str, str, str, str], ...] = (
    ("number", "#", "pick", "d"),
    ("x", "x north, m", "x_north_m", ".3f"),
    ("y", "y east, m", "y_east_m", ".3f"),
    ("z", "z down, m", "z_down_m", ".3f"),
    ("range_m", "range, m", "range_m", ".3f"),
    ("azimuth_deg", "azimuth, °", "azimuth_deg", ".3f"),
    ("elevation_deg", "elevation, °", "elevation_deg", ".3f"),
    ("reflectivity", "reflectivity", "reflectivity", "d"),
    ("t_s", "time, s", "time_s", ".6f"),
)


def ray_angle_deg(a: Sequence[float], b: Sequence[float]) -> float:
    """The angle between two rays from one origin, degrees (exact for small and large angles); NaN when either
    is a null vector.

    Parameters
    ----------
    a, b : (3,) float
        Points on the rays (each ray runs from the origin through its point), in one frame, metres.
    """
    u, v = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if not (np.any(u) and np.any(v)):
        return math.nan
    # atan2 of the cross and dot products: arccos of the normalised dot product loses the small angles between
    # neighbouring beams (0.05 deg is 4e-7 off 1 in its cosine).
    return math.degrees(math.atan2(float(np.linalg.norm(np.cross(u, v))), float(np.dot(u, v))))


def vertex_angle_deg(a: Sequence[float], b: Sequence[float], c: Sequence[float]) -> float:
    """The angle ABC at ``b`` between the segments to ``a`` and to ``c``, degrees, 0 to 180; NaN when ``a`` or
    ``c`` is at ``b``.

    Parameters
    ----------
    a, b, c : (3,) float
        Three points in one frame, metres.
    """
    middle = np.asarray(b, dtype=np.float64)
    return ray_angle_deg(np.asarray(a, dtype=np.float64) - middle, np.asarray(c, dtype=np.float64) - middle)


@dataclass(frozen=True)
class PickMeasures:
    """What the last picks measure (None where there are too few picks).

    Parameters
    ----------
    count : int
        How many picks there are.
    distance_m : float or None
        Between the last two picks' world points, metres.
    ray_angle_deg : float or None
        Between the last two picks' rays as the sensor fired them (their sensor-frame points from its origin),
        degrees; NaN if a point is at the sensor.
    vertex_angle_deg : float or None
        The angle at the middle one of the last three picks (ABC at B, world points), degrees; NaN when a pick
        next to it lies at the same point.
    """

    count: int
    distance_m: float | None = None
    ray_angle_deg: float | None = None
    vertex_angle_deg: float | None = None


def pick_measures(picks: Sequence[Mapping[str, Any]]) -> PickMeasures:
    """The measures of the last two and last three of ``picks`` (each with ``xyz_world`` and ``xyz_sensor``)."""
    count = len(picks)
    if count < 2:
        return PickMeasures(count)
    a, b = picks[-2], picks[-1]
    distance = float(np.linalg.norm(np.subtract(b["xyz_world"], a["xyz_world"])))
    # A point of an opened cloud has no ray of the sensor's (xyz_sensor None): no angle between rays.
    fired = a.get("xyz_sensor") is not None and b.get("xyz_sensor") is not None
    rays = ray_angle_deg(a["xyz_sensor"], b["xyz_sensor"]) if fired else None
    vertex = vertex_angle_deg(picks[-3]["xyz_world"], a["xyz_world"], b["xyz_world"]) if count >= 3 else None
    return PickMeasures(count, distance, rays, vertex)


def _degrees(value: float, decimals: int) -> str:
    return "undefined" if math.isnan(value) else f"{value:.{decimals}f} deg"


def measures_text(measures: PickMeasures) -> str:
    """The measures in words ("" with fewer than two picks): the ray angle to three decimals (neighbouring beams
    are hundredths of a degree apart), the angle ABC to two."""
    n = measures.count
    if measures.distance_m is None:
        return ""
    text = f"{measures.distance_m:.3f} m from pick {n - 1}"
    if measures.ray_angle_deg is not None:
        text += f", rays {_degrees(measures.ray_angle_deg, 3)} apart seen from the sensor"
    if measures.vertex_angle_deg is not None:
        text += f"; angle {n - 2}-{n - 1}-{n} at pick {n - 1}: {_degrees(measures.vertex_angle_deg, 2)}"
    return text


def status_line(picks: Sequence[Mapping[str, Any]]) -> str:
    """The status bar's line for the last pick: its number and values, then what it measures with those before."""
    found = picks[-1]
    if "cloud" in found:  # a point of an opened cloud: what its file holds
        x, y, z = (float(v) for v in found["xyz_world"])
        text = (f"pick {len(picks)}: point {found['index'] + 1:,} of the opened cloud {found['cloud']}, x {x:.3f} m, "
                f"y {y:.3f} m, z {z:.3f} m (world NED)")
    else:
        text = (f"pick {len(picks)}: range {found['range_m']:.3f} m, azimuth {found['azimuth_deg']:.2f} deg, elevation "
                f"{found['elevation_deg']:.2f} deg, reflectivity {found['reflectivity']}, tag 0x{found['tag']:02x}, "
                f"return {found['return_number']}, t {found['t_s']:.4f} s, frame {found['frame']}")
    measured = measures_text(pick_measures(picks))
    return f"{text}; {measured}" if measured else text


def pick_cells(number: int, pick: Mapping[str, Any]) -> list[str]:
    """One pick's row as text, :data:`COLUMNS` in order (what the table shows and the clipboard gets)."""
    x, y, z = (float(v) for v in pick["xyz_world"])
    values = {"number": number, "x": x, "y": y, "z": z}
    # An opened cloud's point has no range, angles, reflectivity or time of the scan's: those cells are empty.
    return [format(values[key], spec) if key in values else format(pick[key], spec) if key in pick else ""
            for key, _, _, spec in COLUMNS]


def picks_tsv(picks: Sequence[Mapping[str, Any]], rows: Sequence[int] | None = None) -> str:
    """The picks as tab-separated text with a header line (what a spreadsheet takes pasted), one line each.

    Parameters
    ----------
    picks : sequence of mappings
        Every pick, in order (their numbers are their places, from 1).
    rows : sequence of int, optional
        Only these picks (places from 0), in order; default all.
    """
    chosen = range(len(picks)) if rows is None else sorted(rows)
    lines = ["\t".join(header for _, _, header, _ in COLUMNS)]
    lines += ["\t".join(pick_cells(row + 1, picks[row])) for row in chosen]
    return "\n".join(lines) + "\n"
