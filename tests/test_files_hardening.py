"""Files, outputs and bags under hostile use: huge frames, bad output paths, far-away worlds, read-only
files, full disks, endless inputs, bad ROS names, warnings and signals (issue 15)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from livox_viz.cli import main
from tests.conftest import SEED_JSON


def test_a_frame_of_more_rays_than_one_cast_part_is_cast_in_parts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """5000 x 220 rays per frame (1.1 M, over CAST_PART) and a fixed sensor: the parts join, as one cast would."""
    from livox_viz.casting import scan

    config = tmp_path / "wide.json"
    config.write_text(json.dumps({**SEED_JSON, "DataWidth": 5000, "DataHeight": 220, "DataCheckFreq": 1}))
    assert 5000 * 220 > scan.CAST_PART
    out = tmp_path / "wide.npz"
    argv = ["scan", "--config", str(config), "--seconds", "1", "--scene", "open_field", "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    split = np.load(out)
    monkeypatch.setattr(scan, "CAST_PART", 1 << 30)  # the same frame cast in one part
    whole = tmp_path / "whole.npz"
    assert main([*argv[:-1], str(whole)]) == 0
    whole_data = np.load(whole)
    assert len(split["t"]) > 100_000
    for name in ("xyz_int16", "t", "xyz_world", "frame"):
        np.testing.assert_array_equal(split[name], whole_data[name])
