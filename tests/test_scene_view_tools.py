"""The scene view's projection arithmetic, its range and reflectivity filter and its saved viewpoints, without a
window (issue 45 item 6): pure functions, checked against numbers computed here another way."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from livox_viz.widgets.cameras import CameraState, distance_for, fit_parallel, parallel_scale_for
from livox_viz.widgets.filters import CloudFilter, filtered_slots
from livox_viz.widgets.ring import PointRing
from livox_viz.widgets.viewpoints import (
    FORMAT_KEY,
    delete_viewpoint,
    read_viewpoints,
    save_viewpoint,
    viewpoints_path,
)

from livox_viz import LivoxVizError

CAMERA = CameraState(position=(-9.0, 0.0, 6.3), focal_point=(25.0, 0.0, 0.8), up=(0.0, 0.0, 1.0),
                     parallel_scale=16.0, view_angle=50.0, parallel=True)


# The projection's arithmetic -------------------------------------------------------------------------------------
def test_the_parallel_scale_shows_the_focal_plane_as_the_perspective_view_does() -> None:
    """A perspective view of vertical angle a shows, at distance d from its eye, a plane 2 d tan(a / 2) tall: the
    orthographic view of half that height shows the same; the inverse gives the distance back."""
    for distance, angle in ((34.4, 50.0), (1.0, 30.0), (250.0, 10.0)):
        top = distance * math.sin(math.radians(angle / 2)) / math.cos(math.radians(angle / 2))
        assert parallel_scale_for(distance, angle) == pytest.approx(top, rel=1e-12)
        assert distance_for(parallel_scale_for(distance, angle), angle) == pytest.approx(distance, rel=1e-12)


@pytest.mark.parametrize("aspect", [0.6, 1.0, 16 / 9])
def test_an_orthographic_fit_puts_every_point_inside_the_free_part_of_the_view(aspect: float) -> None:
    """Each point projected as an orthographic camera at the fitted focal point and scale projects it (written out
    here: its offset from the focal point along the screen's axes over the half-height) lands inside the free part
    (left ``free_width`` of the width, bottom ``free_height`` of the height), and the points' extent fills the
    ``margin`` of that part along one axis at least: no wasted zoom."""
    rng = np.random.default_rng(3)
    points = rng.normal([40.0, -5.0, 2.0], [30.0, 12.0, 3.0], (500, 3))
    direction, up = np.array([0.3, 0.1, -1.0]), np.array([1.0, 0.0, 0.0])
    free_width, free_height, margin = 0.82, 0.9, 0.85
    focal, scale = fit_parallel(points, direction, up, aspect, free_width, free_height, margin)
    forward = direction / np.linalg.norm(direction)
    right = np.cross(forward, up) / np.linalg.norm(np.cross(forward, up))
    screen_up = np.cross(right, forward)
    # Screen coordinates from 0 (left, bottom) to 1 (right, top).
    x = 0.5 + (points - focal) @ right / (2 * scale * aspect)
    y = 0.5 + (points - focal) @ screen_up / (2 * scale)
    assert x.min() >= -1e-9 and x.max() <= free_width + 1e-9
    assert y.min() >= -1e-9 and y.max() <= free_height + 1e-9
    filled = max(np.ptp(x) / free_width, np.ptp(y) / free_height)
    assert filled == pytest.approx(margin, rel=1e-9)
    # The middle of the points in the middle of the free part, and the focal point amid them in depth.
    assert (x.min() + x.max()) / 2 == pytest.approx(free_width / 2, abs=1e-9)
    assert (y.min() + y.max()) / 2 == pytest.approx(free_height / 2, abs=1e-9)
    depth = (points - focal) @ forward
    assert depth.min() == pytest.approx(-depth.max(), abs=1e-9)


def test_a_camera_is_written_as_the_sidecar_writes_it_and_a_bad_one_refused_in_one_line() -> None:
    data = CAMERA.to_json()
    assert list(data) == ["position", "focal_point", "up", "parallel_scale", "view_angle", "parallel"]
    assert CameraState.from_json(json.loads(json.dumps(data))) == CAMERA
    for change, words in (({"up": [34.0, 0.0, -5.5]}, "along the line of sight"),
                          ({"position": [25.0, 0.0, 0.8]}, "equals its focal point"),
                          ({"view_angle": 180}, "between 0 and 180"), ({"parallel_scale": 0}, "> 0"),
                          ({"parallel": 1}, "true or false"), ({"position": [1, 2]}, "three numbers"),
                          ({"focal_point": [1, "2", 3]}, "three numbers"), ({"up": [0, 0, True]}, "three numbers")):
        with pytest.raises(LivoxVizError) as refused:
            CameraState.from_json({**data, **change}, "viewpoint 'x''s camera")
        line = str(refused.value)
        assert "\n" not in line and line.startswith("viewpoint 'x''s camera: ") and words in line, line
    with pytest.raises(LivoxVizError, match="no view_angle, parallel; allowed"):
        CameraState.from_json({k: v for k, v in data.items() if k not in ("view_angle", "parallel")})
    with pytest.raises(LivoxVizError, match="allowed: three finite numbers"):
        CameraState.from_json({**data, "position": [float("nan"), 0, 0]})


# The filter --------------------------------------------------------------------------------------------------
def ring_of(rng: np.random.Generator, capacity: int, written: int) -> PointRing:
    """A scene ring (ranges kept) that took ``written`` points of random ranges and reflectivities."""
    ring = PointRing(capacity, sensor_frame=True)
    local = rng.normal(0.0, 20.0, (written, 3)).astype(np.float32)
    ring.write(local, np.zeros(written, np.float32), np.arange(written) * 1e-5, np.arange(written),
               reflectivity=rng.integers(0, 256, written).astype(np.uint8), sensor_xyz=local)
    return ring


@pytest.mark.parametrize(("capacity", "written", "stride"), [(1000, 700, 1), (1000, 2500, 1), (1000, 2500, 3),
                                                             (1000, 1000, 4)])
def test_the_filter_keeps_exactly_the_live_points_inside_its_bounds(capacity: int, written: int,
                                                                    stride: int) -> None:
    """Against a loop over the live slots, point by point: the slots kept are those drawn whose range and
    reflectivity are within the bounds (both included), and the points hidden are counted over all live ones."""
    from livox_viz.widgets.views import drawn_slots

    ring = ring_of(np.random.default_rng(capacity + written + stride), capacity, written)
    ring.drop_older_than(float(ring.times[ring.live_slots()[50]]))  # a time window's cut: dead slots keep points
    bounds = CloudFilter(range_min_m=15.0, range_max_m=40.0, reflectivity_min=30, reflectivity_max=200)
    drawn = drawn_slots(ring, stride)
    kept, hidden = filtered_slots(ring, drawn, bounds)

    def inside(slot: int) -> bool:
        distance = float(ring.range_m[slot])
        return 15.0 <= distance <= 40.0 and 30 <= int(ring.reflectivity[slot]) <= 200

    assert sorted(kept.tolist()) == sorted(s for s in drawn.tolist() if inside(s))
    assert hidden == sum(not inside(s) for s in ring.live_slots().tolist())
    assert 0 < kept.size < drawn.size and set(kept.tolist()) <= set(ring.live_slots().tolist())


def test_a_bound_on_each_side_alone_and_the_full_byte_range_hides_nothing_more() -> None:
    ring = ring_of(np.random.default_rng(5), 500, 500)
    slots = ring.live_slots()
    assert not CloudFilter(range_min_m=0.0, reflectivity_min=0, reflectivity_max=255).active
    for bounds, inside in ((CloudFilter(range_min_m=30.0), ring.range_m >= 30.0),
                           (CloudFilter(range_max_m=30.0), ring.range_m <= 30.0),
                           (CloudFilter(reflectivity_min=128), ring.reflectivity >= 128),
                           (CloudFilter(reflectivity_max=127), ring.reflectivity <= 127)):
        assert bounds.active
        kept, hidden = filtered_slots(ring, slots, bounds)
        assert sorted(kept.tolist()) == np.flatnonzero(inside).tolist() and hidden == 500 - inside.sum()


def test_a_bad_filter_is_refused_in_one_line_naming_what_is_allowed_and_it_reads_as_it_is_said() -> None:
    for values, words in (({"range_min_m": 20.0, "range_max_m": 1.0}, "range filter 20-1 m refused"),
                          ({"reflectivity_min": 200, "reflectivity_max": 10}, "reflectivity filter 200-10 refused"),
                          ({"range_min_m": -1.0}, "a range of 0 m or more"),
                          ({"range_max_m": float("inf")}, "a range of 0 m or more"),
                          ({"reflectivity_max": 256}, "a whole number from 0 to 255"),
                          ({"reflectivity_min": 12.5}, "a whole number from 0 to 255")):
        with pytest.raises(LivoxVizError) as refused:
            CloudFilter(**values)
        assert words in str(refused.value) and "allowed" in str(refused.value) and "\n" not in str(refused.value)
    assert CloudFilter(1.0, 20.0).describe() == "range 1-20 m"
    assert CloudFilter(range_min_m=2.5, reflectivity_max=150).describe() == "range >= 2.5 m, reflectivity <= 150"
    both = CloudFilter(1.0, 20.0, 10, 255)
    assert CloudFilter.from_json(json.loads(json.dumps(both.to_json()))) == both
    assert CloudFilter.from_json(None) == CloudFilter()
    with pytest.raises(LivoxVizError, match="unknown range_m; allowed"):
        CloudFilter.from_json({"range_m": 3})


# Saved viewpoints ------------------------------------------------------------------------------------------------
@pytest.fixture
def viewpoints_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("LIVOX_VIZ_VIEWPOINTS", str(tmp_path / "views"))
    return viewpoints_path()


def test_viewpoints_are_kept_in_the_user_s_folder_in_order_replaced_by_name_and_deleted(viewpoints_file: Path,
                                                                                       monkeypatch) -> None:
    monkeypatch.delenv("LIVOX_VIZ_VIEWPOINTS")
    from livox_viz.config.presets import user_config_dir

    assert viewpoints_path().parent.parent == user_config_dir("presets").parent  # beside the user presets
    monkeypatch.setenv("LIVOX_VIZ_VIEWPOINTS", str(viewpoints_file.parent))
    assert read_viewpoints().viewpoints == [] and not read_viewpoints().problem  # no file yet: nothing to say
    top = CameraState((0.0, 0.0, 60.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 40.0, 50.0, True)
    assert "'map' saved (orthographic)" in save_viewpoint("  map ", top)
    assert "'behind' saved (perspective)" in save_viewpoint("behind", CAMERA.__class__(**{**CAMERA.__dict__,
                                                                                         "parallel": False}))
    moved = CameraState((0.0, 0.0, 80.0), (5.0, 0.0, 0.0), (1.0, 0.0, 0.0), 60.0, 50.0, True)
    assert "'map' replaced" in save_viewpoint("map", moved)
    data = json.loads(viewpoints_file.read_text())
    assert data[FORMAT_KEY] == 1 and [v["name"] for v in data["viewpoints"]] == ["behind", "map"]
    assert data["viewpoints"][1]["camera"] == moved.to_json()
    assert read_viewpoints().find("map").camera == moved
    assert "deleted" in delete_viewpoint("behind")
    assert read_viewpoints().names() == ["map"]
    with pytest.raises(LivoxVizError, match=r"no viewpoint 'behind' in .*; allowed: map"):
        delete_viewpoint("behind")
    for name in ("", "   ", "a\nb", "x" * 61):
        with pytest.raises(LivoxVizError, match="allowed: 1 to 60 printable characters"):
            save_viewpoint(name, top)
    assert read_viewpoints().names() == ["map"]
    assert sorted(p.name for p in viewpoints_file.parent.iterdir()) == ["viewpoints.json"]  # no temporaries left


def test_a_hand_edited_file_keeps_what_cannot_be_read_and_a_damaged_one_is_set_aside_never_lost(
        viewpoints_file: Path) -> None:
    """An entry with a bad camera or a name taken twice is said in one line and written back as it was when
    another is saved; a file that is no viewpoints file (half a JSON, a list) is renamed aside, byte for byte,
    before a new one is written; a newer format is read but never written over."""
    good = {"name": "map", "camera": CAMERA.to_json()}
    bad_camera = {"name": "wrong", "camera": {**CAMERA.to_json(), "view_angle": 0}}
    viewpoints_file.parent.mkdir(parents=True)
    viewpoints_file.write_text(json.dumps({FORMAT_KEY: 1, "viewpoints": [good, bad_camera, good, "x"]}))
    book = read_viewpoints()
    assert book.names() == ["map"] and book.kept == [bad_camera, good, "x"]
    assert "\n" not in book.problem and "3 of 4 viewpoints could not be read and are kept" in book.problem
    assert "viewpoint 'wrong''s camera: view_angle 0.0 deg" in book.problem
    said = save_viewpoint("new", CAMERA)
    assert "3 unreadable entries kept as they were" in said
    assert json.loads(viewpoints_file.read_text())["viewpoints"][1:] == [{"name": "new", "camera": CAMERA.to_json()},
                                                                         bad_camera, good, "x"]

    for damaged in (b'{"livox_viz_viewpoints": 1, "viewpoints": [{"na', b"[1, 2]", b'{"viewpoints": []}'):
        viewpoints_file.write_bytes(damaged)
        book = read_viewpoints()
        assert book.unreadable and book.viewpoints == [] and "\n" not in book.problem
        assert book.problem.startswith("viewpoints.json: ") and book.problem.endswith(f"({viewpoints_file.parent})")
        assert "set aside when a viewpoint is saved" in book.problem
        said = save_viewpoint("fresh", CAMERA)
        aside = [p for p in viewpoints_file.parent.iterdir() if p.name.startswith("viewpoints.unreadable-")]
        assert len(aside) == 1 and aside[0].read_bytes() == damaged and f"kept as {aside[0].name}" in said
        aside[0].unlink()
        assert read_viewpoints().names() == ["fresh"] and not read_viewpoints().problem

    newer = json.dumps({FORMAT_KEY: 2, "viewpoints": [good], "more": True})
    viewpoints_file.write_text(newer)
    assert read_viewpoints().names() == ["map"] and "newer livox-viz" in read_viewpoints().problem
    with pytest.raises(LivoxVizError, match="newer livox-viz; allowed"):
        save_viewpoint("over", CAMERA)
    assert viewpoints_file.read_text() == newer


def test_a_viewpoint_that_cannot_be_written_leaves_the_file_as_it_was(viewpoints_file: Path, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A read-only file (its owner's word, which even an administrator's run respects) and a folder that cannot be
    made are one line each; the file is as it was."""
    save_viewpoint("map", CAMERA)
    before = viewpoints_file.read_bytes()
    viewpoints_file.chmod(0o444)
    try:
        with pytest.raises(LivoxVizError) as refused:
            save_viewpoint("other", CAMERA)
    finally:
        viewpoints_file.chmod(0o644)
    assert "\n" not in str(refused.value) and "read-only" in str(refused.value)
    assert viewpoints_file.read_bytes() == before and read_viewpoints().names() == ["map"]
    (tmp_path / "a-file").write_text("")
    monkeypatch.setenv("LIVOX_VIZ_VIEWPOINTS", str(tmp_path / "a-file" / "views"))
    with pytest.raises(LivoxVizError, match="cannot make its folder"):
        save_viewpoint("other", CAMERA)
