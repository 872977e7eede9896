"""The scene view's camera as data, without a window (issue 45 item 6): pure functions, checked against numbers
computed here another way."""

from __future__ import annotations

import json

import pytest
from livox_viz.widgets.cameras import CameraState

from livox_viz import LivoxVizError

CAMERA = CameraState(position=(-9.0, 0.0, 6.3), focal_point=(25.0, 0.0, 0.8), up=(0.0, 0.0, 1.0),
                     parallel_scale=16.0, view_angle=50.0, parallel=True)


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

