"""The scene view's projection arithmetic and its camera's form, without a window (issue 45 item 6): pure
functions, checked against numbers computed here another way."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from livox_viz.widgets.cameras import CameraState, distance_for, fit_parallel, parallel_scale_for

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

