"""The picks' list without a window (issue 45 item 6): the angles between picks against independent formulas, the
clipboard's text read back as a spreadsheet reads it."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from livox_viz.widgets.picks import (
    COLUMNS,
    PickMeasures,
    measures_text,
    pick_measures,
    picks_tsv,
    ray_angle_deg,
    status_line,
    vertex_angle_deg,
)


def haversine_deg(az_a: float, el_a: float, az_b: float, el_b: float) -> float:
    """The great-circle angle between two directions given by azimuth and elevation, degrees (the haversine
    formula: another road to the angle between two rays than their vectors' cross and dot products)."""
    az_a, el_a, az_b, el_b = map(math.radians, (az_a, el_a, az_b, el_b))
    h = math.sin((el_b - el_a) / 2) ** 2 + math.cos(el_a) * math.cos(el_b) * math.sin((az_b - az_a) / 2) ** 2
    return math.degrees(2 * math.asin(math.sqrt(min(h, 1.0))))


def law_of_cosines_deg(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """The angle at ``b`` of the triangle abc from its three sides' lengths, degrees."""
    ab, bc, ac = np.linalg.norm(a - b), np.linalg.norm(c - b), np.linalg.norm(c - a)
    return math.degrees(math.acos(np.clip((ab**2 + bc**2 - ac**2) / (2 * ab * bc), -1.0, 1.0)))


def frd(range_m: float, az_deg: float, el_deg: float) -> np.ndarray:
    """A sensor-frame (FRD) point at ``range_m`` in the direction azimuth (to the right) and elevation (up)."""
    az, el = math.radians(az_deg), math.radians(el_deg)
    return range_m * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])


def a_pick(rng: np.random.Generator, origin: np.ndarray | None = None) -> dict:
    """A pick as the session gives one: a point at a random range and direction (static sensor at ``origin``)."""
    range_m, az, el = rng.uniform(1, 200), rng.uniform(-180, 180), rng.uniform(-60, 60)
    local = frd(range_m, az, el)
    origin = np.zeros(3) if origin is None else origin
    return {"xyz_world": (origin + local).tolist(), "xyz_sensor": local.tolist(), "range_m": range_m,
            "azimuth_deg": az, "elevation_deg": el, "reflectivity": int(rng.integers(0, 256)), "tag": 0x10,
            "return_number": 1, "t_s": float(rng.uniform(0, 10)), "frame": int(rng.integers(0, 100))}


def test_the_angle_between_two_rays_is_the_great_circle_angle_of_their_directions() -> None:
    rng = np.random.default_rng(7)
    for _ in range(200):
        a, b = a_pick(rng), a_pick(rng)
        expected = haversine_deg(a["azimuth_deg"], a["elevation_deg"], b["azimuth_deg"], b["elevation_deg"])
        assert ray_angle_deg(a["xyz_sensor"], b["xyz_sensor"]) == pytest.approx(expected, abs=1e-9)
    # Neighbouring beams (hundredths of a degree) and nearly opposite rays keep their digits.
    for az_b in (0.001, 0.05, 179.999):
        assert ray_angle_deg(frd(10, 0, 0), frd(300, az_b, 0)) == pytest.approx(az_b, rel=1e-9)
    assert math.isnan(ray_angle_deg((0, 0, 0), (1, 0, 0)))


def test_the_angle_at_the_middle_pick_is_the_triangle_s_angle_from_its_sides() -> None:
    rng = np.random.default_rng(11)
    for _ in range(200):
        a, b, c = (rng.uniform(-50, 50, 3) for _ in range(3))
        assert vertex_angle_deg(a, b, c) == pytest.approx(law_of_cosines_deg(a, b, c), abs=1e-7)
    assert vertex_angle_deg((1, 0, 0), (0, 0, 0), (0, 2, 0)) == pytest.approx(90.0)
    assert vertex_angle_deg((1, 0, 0), (0, 0, 0), (-3, 0, 0)) == pytest.approx(180.0)
    assert math.isnan(vertex_angle_deg((1, 2, 3), (1, 2, 3), (0, 0, 0)))


def test_the_measures_are_those_of_the_last_two_and_the_last_three_picks() -> None:
    rng = np.random.default_rng(3)
    origin = np.array([5.0, -2.0, -1.5])  # a sensor away from the world's origin: rays are from the sensor
    picks = [a_pick(rng, origin) for _ in range(5)]
    assert pick_measures(picks[:1]) == PickMeasures(1)
    assert measures_text(pick_measures(picks[:1])) == ""
    two = pick_measures(picks[:2])
    assert two.vertex_angle_deg is None
    assert two.distance_m == pytest.approx(float(np.linalg.norm(np.subtract(picks[1]["xyz_world"],
                                                                             picks[0]["xyz_world"]))))
    measures = pick_measures(picks)
    a, b, c = (np.asarray(p["xyz_world"]) for p in picks[-3:])
    assert measures.count == 5
    assert measures.distance_m == pytest.approx(float(np.linalg.norm(c - b)), rel=1e-12)
    assert measures.ray_angle_deg == pytest.approx(haversine_deg(picks[3]["azimuth_deg"], picks[3]["elevation_deg"],
                                                                 picks[4]["azimuth_deg"], picks[4]["elevation_deg"]),
                                                   abs=1e-9)
    assert measures.vertex_angle_deg == pytest.approx(law_of_cosines_deg(a, b, c), abs=1e-7)
    text = measures_text(measures)
    assert f"{measures.distance_m:.3f} m from pick 4" in text
    assert f"rays {measures.ray_angle_deg:.3f} deg apart" in text
    assert f"angle 3-4-5 at pick 4: {measures.vertex_angle_deg:.2f} deg" in text
    line = status_line(picks)
    assert line.startswith(f"pick 5: range {picks[4]['range_m']:.3f} m") and line.endswith(text)
    assert "\n" not in line
    # Two picks of one point: no angle at it, said in words rather than "nan".
    same = [picks[0], picks[1], dict(picks[1])]
    assert "angle 1-2-3 at pick 2: undefined" in measures_text(pick_measures(same))


def test_the_clipboard_text_is_a_header_and_a_row_per_pick_that_a_spreadsheet_reads_back() -> None:
    rng = np.random.default_rng(5)
    picks = [a_pick(rng) for _ in range(4)]
    text = picks_tsv(picks)
    rows = list(csv.reader(io.StringIO(text), delimiter="\t"))
    assert rows[0] == [header for _, _, header, _ in COLUMNS]
    assert rows[0][:4] == ["pick", "x_north_m", "y_east_m", "z_down_m"]
    assert len(rows) == 5 and all(len(row) == len(COLUMNS) for row in rows)
    for number, (row, pick) in enumerate(zip(rows[1:], picks, strict=True), start=1):
        values = dict(zip(rows[0], row, strict=True))
        assert int(values["pick"]) == number
        np.testing.assert_allclose([float(values[k]) for k in ("x_north_m", "y_east_m", "z_down_m")],
                                   pick["xyz_world"], atol=5e-4)
        assert float(values["range_m"]) == pytest.approx(pick["range_m"], abs=5e-4)
        assert float(values["azimuth_deg"]) == pytest.approx(pick["azimuth_deg"], abs=5e-4)
        assert float(values["elevation_deg"]) == pytest.approx(pick["elevation_deg"], abs=5e-4)
        assert int(values["reflectivity"]) == pick["reflectivity"]
        assert float(values["time_s"]) == pytest.approx(pick["t_s"], abs=5e-7)
    # The selected rows only, numbered as in the list.
    chosen = list(csv.reader(io.StringIO(picks_tsv(picks, [3, 1])), delimiter="\t"))
    assert [row[0] for row in chosen] == ["pick", "2", "4"]
