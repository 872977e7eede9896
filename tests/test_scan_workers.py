"""Frames cast side by side on every core: the worker count follows the cores and never changes the cloud."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.casting import scan
from livox_viz.casting.scan import LidarScanner, frame_workers
from livox_viz.cli import main
from livox_viz.core.portable import usable_cores
from livox_viz.motion.flights import builtin_trajectory
from livox_viz.scene.scenes import open_scene

ARRAYS = ("stream_index", "t", "xy_deg", "range_m", "xyz_sensor", "xyz_int16", "xyz_world", "reflectivity", "tag",
          "return_number", "number_of_returns")


def _cloud(preset: str, returns: str, moving: bool, workers: int) -> list[tuple]:
    cfg = load_preset(preset).with_returns_model(returns)
    scene = open_scene("urban")
    flight = builtin_trajectory("line", 6.0, scene.vehicle_pose, 0.6) if moving else None
    scanner = LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=3, trajectory=flight, workers=workers)
    assert scanner.workers == workers
    return [(frame.index, frame.ray_count, frame.timestamp, *(getattr(frame, name).tobytes() for name in ARRAYS))
            for frame in scanner.frames(0.6)]


@pytest.mark.parametrize(("preset", "returns", "moving"), [("livox_mid70", "ideal", False),
                                                           ("livox_mid70_risley", "datasheet", True)])
def test_the_cloud_is_the_same_bit_for_bit_for_1_2_3_and_7_workers(monkeypatch: pytest.MonkeyPatch, preset: str,
                                                                    returns: str, moving: bool) -> None:
    # One frame a batch: six batches, so seven workers hold every one of them in flight at once.
    monkeypatch.setattr(scan, "TASK_RAYS", 10_000)
    one = _cloud(preset, returns, moving, 1)
    assert len(one) == 6 and sum(len(frame[3]) for frame in one) > 0
    for workers in (2, 3, 7):
        assert _cloud(preset, returns, moving, workers) == one, f"{workers} workers"


def test_scan_workers_writes_the_same_file(tmp_path: Path) -> None:
    for workers in ("1", "3"):
        assert main(["scan", "--seconds", "0.3", "--workers", workers, "--out", str(tmp_path / f"w{workers}.npz")]) == 0
    one, three = np.load(tmp_path / "w1.npz"), np.load(tmp_path / "w3.npz")
    assert sorted(one.files) == sorted(three.files)
    for name in one.files:
        assert np.array_equal(one[name], three[name]), name


def test_workers_default_to_the_cores_this_process_may_use(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scan, "usable_cores", lambda: 13)
    assert frame_workers() == 13 and frame_workers(2) == 2  # no cap: a 16-core machine gets its 16
    assert LidarScanner(load_preset("livox_mid70"), open_scene("open_field").mesh).workers == 13


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no affinity mask on this platform")
def test_usable_cores_follow_the_affinity_mask() -> None:
    """A process pinned to one CPU (taskset, a batch system's CPU set) counts one core, not the machine's."""
    code = ("import os; os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})\n"
            "from livox_viz.core.portable import usable_cores; print(usable_cores())")
    pinned = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert pinned.stdout.strip() == "1"
    assert usable_cores() == len(os.sched_getaffinity(0))


def test_frames_of_one_ray_are_cast_a_bounded_number_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 1 x 1 x 1000 Hz configuration: batches of at least TASK_RAYS rays were 65 536 frames each, and the
    scan held some 200 000 frames in flight (1.16 GB at 741,786 frames, issue 47). At most TASK_FRAMES a batch
    now, whatever the rays, and the cloud is the one frame-by-frame casting gives."""
    from dataclasses import replace

    cfg = replace(load_preset("livox_mid70"), data_width=1, data_height=1, data_check_freq=1000)
    scene = open_scene("urban")
    batches: list[int] = []
    cast_in_worker = LidarScanner._cast_in_worker

    def counted(self, chunk, stops):
        batches.append(len(stops))
        return cast_in_worker(self, chunk, stops)

    monkeypatch.setattr(LidarScanner, "_cast_in_worker", counted)
    batched = [(f.index, f.range_m.tobytes()) for f in
               LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=1, workers=2).frames(3.0)]
    assert len(batched) == 3000
    assert max(batches) == scan.TASK_FRAMES and sum(batches) == 3000
    monkeypatch.setattr(scan, "TASK_FRAMES", 1)
    single = [(f.index, f.range_m.tobytes()) for f in
              LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=1, workers=2).frames(3.0)]
    assert single == batched
