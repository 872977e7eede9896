"""The window's File > Open cloud reader: every format our scan writes comes back as the same points, in the frame
its file says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from livox_viz import LivoxVizError
from livox_viz.cli import main
from livox_viz.files.cloud_file import read_cloud, returns_only

SENSOR_FILES = ("s.ply", "s.pcd", "s.csv", "s.las", "s.lvx", "bag2")
WORLD_FILES = ("w.ply", "w.pcd", "w.csv", "w.las", "w.npz")


@pytest.fixture(scope="module")
def clouds(tmp_path_factory) -> Path:
    """One 0.05 s scan of the Mid-70 preset written in each format (sensor and world frames)."""
    folder = tmp_path_factory.mktemp("clouds")
    for name in SENSOR_FILES:
        out = ["--rosbag", str(folder / name)] if name == "bag2" else ["--out", str(folder / name)]
        assert main(["scan", "--seconds", "0.05", "--seed", "0", *out]) == 0
    for name in WORLD_FILES:
        assert main(["scan", "--seconds", "0.05", "--seed", "0", "--frame", "world", "--out", str(folder / name)]) == 0
    return folder


@pytest.mark.parametrize("name", SENSOR_FILES)
def test_a_sensor_frame_file_comes_back_in_the_sensor_frd_frame(clouds: Path, name: str) -> None:
    reference = read_cloud(clouds / "s.ply")
    cloud = read_cloud(clouds / name)
    assert cloud.frame == "sensor" and cloud.name == name
    assert cloud.points_m.shape == reference.points_m.shape
    # FRD: the Mid-70 looks forward (+x) at the ground below it (+z down in the sensor's frame, mostly).
    np.testing.assert_allclose(cloud.points_m, reference.points_m, atol=2e-3)
    assert np.median(reference.points_m[:, 0]) > 0


@pytest.mark.parametrize("name", WORLD_FILES)
def test_a_world_frame_file_comes_back_in_world_ned(clouds: Path, name: str) -> None:
    reference = read_cloud(clouds / "w.ply")
    cloud = read_cloud(clouds / name)
    assert cloud.frame == "world"
    assert cloud.points_m.shape == reference.points_m.shape
    # The NPZ's xyz_world is before the int16 wire (the others decoded from it): within its step.
    np.testing.assert_allclose(cloud.points_m, reference.points_m, atol=2e-2)


def test_too_many_points_are_refused_naming_the_limit(clouds: Path) -> None:
    for name in ("s.ply", "s.las", "w.npz"):
        with pytest.raises(LivoxVizError, match="at most 100 are opened"):
            read_cloud(clouds / name, max_points=100)


def test_bad_input_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "broken.ply").write_bytes(b"ply\nbroken")
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / "other.npz").write_bytes(b"not a zip")
    np.savez(tmp_path / "foreign.npz", points=np.zeros((3, 3)))
    for name, words in (("broken.ply", "end_header"), ("notes.txt", "unknown format"), (".", "no ROS 2 bag"),
                        ("missing.pcd", "no such file"), ("other.npz", "not an NPZ"),
                        ("foreign.npz", "xyz_world or xyz_sensor")):
        with pytest.raises(LivoxVizError, match=words) as error:
            read_cloud(tmp_path / name)
        assert "\n" not in str(error.value)


def test_a_foreign_recording_is_livox_flu_and_its_no_returns_are_dropped(tmp_path: Path) -> None:
    path = tmp_path / "frame.csv"
    path.write_text("x,y,z,intensity\n1,2,3,10\n0,0,0,0\n4,5,6,20\n")
    cloud = read_cloud(path)
    assert cloud.frame == "sensor"
    np.testing.assert_array_equal(cloud.points_m, [[1, -2, -3], [4, -5, -6]])
    with pytest.raises(LivoxVizError, match="no returns"):
        (tmp_path / "empty.csv").write_text("x,y,z\n0,0,0\n")
        read_cloud(tmp_path / "empty.csv")


def test_returns_only_drops_the_zero_rows() -> None:
    assert returns_only(np.array([[0.0, 0, 0], [0, 0, 1e-3]])).shape == (1, 3)
