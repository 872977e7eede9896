"""Reflectivity, tag and return numbers in every output, read back by third-party readers; never a (0, 0, 0)."""

from __future__ import annotations

import json
from pathlib import Path

import laspy
import numpy as np
import pytest
import trimesh

from livox_viz.cli import main

from .test_rosbag import read_bag


def urban_scan(tmp_path: Path, suffix: str, *extra: str) -> Path:
    out = tmp_path / f"cloud{suffix}"
    assert main(["scan", "--preset", "livox_mid70_risley", "--seconds", "0.3", "--seed", "4", "--out", str(out),
                 *extra]) == 0
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, np.ndarray]:
    """The NPZ of a datasheet scan of the default scene (dual returns, mixed points, signs, the near box)."""
    data = np.load(urban_scan(tmp_path_factory.mktemp("npz"), ".npz"))
    return {name: data[name] for name in data.files}


def test_the_npz_has_the_livox_fields_and_no_point_at_the_origin(reference: dict[str, np.ndarray]) -> None:
    tag, number, returns = reference["tag"], reference["return_number"], reference["number_of_returns"]
    assert reference["reflectivity"].dtype == np.uint8 and tag.dtype == np.uint8
    assert set(np.unique(number)) == {1, 2} and np.all(number <= returns)
    # Return bits: 1 (0x10) for a first return unless nearer than 1.5 m (0x00), 2 (0x20) for a second.
    near = reference["range"] < 1.5
    assert np.all(tag[(number == 1) & ~near] & 0x30 == 0x10) and np.all(tag[(number == 1) & near] & 0x30 == 0)
    assert np.all(tag[number == 2] & 0x30 == 0x20) and near.any()
    assert (reference["reflectivity"] >= 151).any()  # the urban scene's road signs
    assert ((tag & 0x03) != 0).any()  # mixed points at edges
    assert np.all(np.abs(reference["xyz_int16"]).max(axis=1) > 0)
    assert np.all(np.linalg.norm(reference["xyz_sensor"], axis=1) > 0)
    notes = json.loads(str(reference["frame_of_reference"]))
    assert notes["source"].endswith("scan of livox_mid70_risley (datasheet returns, seed 4) in urban from t = 0, fixed")
    assert "measured point" in notes["points"] and "exact hits" not in notes["points"]


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".las", ".csv"])
def test_every_format_carries_them(tmp_path: Path, reference: dict[str, np.ndarray], suffix: str) -> None:
    out = urban_scan(tmp_path, suffix)
    if suffix == ".ply":
        cloud = trimesh.load(out)
        fields = cloud.metadata["_ply_raw"]["vertex"]["data"]
        xyz = np.column_stack([fields["x"], fields["y"], fields["z"]]).astype(np.float64)
    elif suffix == ".pcd":
        from .readers import read_pcd

        fields = read_pcd(out)
        xyz = np.column_stack([fields["x"], fields["y"], fields["z"]]).astype(np.float64)
    elif suffix == ".las":
        las = laspy.read(out)
        # LAS keeps intensity on 16 bits: the byte times 256.
        np.testing.assert_array_equal(np.asarray(las.intensity), reference["reflectivity"].astype(np.uint16) * 256)
        fields = {"reflectivity": np.asarray(las.reflectivity), "tag": np.asarray(las.tag),
                  "return_number": np.asarray(las.return_number),
                  "number_of_returns": np.asarray(las.number_of_returns)}
        xyz = np.column_stack([las.x, las.y, las.z])
    else:
        table = np.genfromtxt(out, delimiter=",", names=True)
        fields = {name: table[name] for name in table.dtype.names}
        xyz = np.column_stack([table["x"], table["y"], table["z"]])
    for name in ("reflectivity", "tag", "return_number", "number_of_returns"):
        np.testing.assert_array_equal(np.asarray(fields[name]).astype(int), reference[name].astype(int), name)
    assert xyz.shape[0] == reference["tag"].size
    assert np.all(np.abs(xyz).max(axis=1) > 0)
    # Each file says what made it, where its own format's readers show a file's notes.
    if suffix == ".ply":
        from plyfile import PlyData

        notes = " ".join(PlyData.read(out).comments)
    elif suffix == ".las":
        notes = " ".join(json.loads(v.record_data).get("source", "") for v in las.header.vlrs
                         if v.user_id == "livox-viz")
    elif suffix == ".csv":  # a CSV holds only its columns: what made it is in its sidecar
        notes = json.loads(out.with_name(out.name + ".json").read_text())["source"]
    else:
        notes = out.read_bytes()[:2000].decode("utf-8", "replace")
    assert "livox_mid70_risley (datasheet returns, seed 4) in urban from t = 0, fixed" in notes


def test_the_bag_is_right_for_fast_lio(tmp_path: Path, reference: dict[str, np.ndarray]) -> None:
    bag = tmp_path / "bag"
    assert main(["scan", "--preset", "livox_mid70_risley", "--seconds", "0.3", "--seed", "4", "--rosbag",
                 str(bag)]) == 0
    messages = read_bag(bag)
    points = [p for _, m in messages["/livox/lidar"] for p in m.points]
    tag = np.array([p.tag for p in points])
    reflectivity = np.array([p.reflectivity for p in points])
    np.testing.assert_array_equal(tag, reference["tag"])
    np.testing.assert_array_equal(reflectivity, reference["reflectivity"])
    # FAST-LIO's Livox filter keeps tag & 0x30 in {0x00, 0x10}: exactly the first returns.
    kept = (tag & 0x30 == 0x00) | (tag & 0x30 == 0x10)
    np.testing.assert_array_equal(kept, reference["return_number"] == 1)
    assert not any(p.x == p.y == p.z == 0 for p in points)
    cloud = messages["/livox/points"][1][1]
    layout = np.dtype({"names": ["intensity", "tag"], "formats": ["<f4", "u1"], "offsets": [12, 16],
                       "itemsize": cloud.point_step})
    decoded = np.frombuffer(cloud.data.tobytes(), dtype=layout)
    frame = reference["frame"] == 1
    np.testing.assert_array_equal(decoded["intensity"], reference["reflectivity"][frame].astype(np.float32))
    np.testing.assert_array_equal(decoded["tag"], reference["tag"][frame])


def test_the_rflysim_wire_carries_one_point_per_ray(tmp_path: Path) -> None:
    from livox_viz import load_preset
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.scene.scenes import open_scene

    urban = open_scene("urban")
    frame = LidarScanner(load_preset("livox_mid70_risley"), urban.mesh, urban.vehicle_pose, seed=4).next_frame()
    assert len(frame) > frame.wire_xyz_int16.shape[0]  # dual returns
    np.testing.assert_array_equal(frame.wire_xyz_int16, frame.xyz_int16[frame.return_number == 1])
    assert frame.wire_xyz_int16.shape[0] <= frame.ray_count


def test_returns_flag_and_reflectance_default_on_the_command_line(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    mesh = trimesh.creation.box((1, 40, 40), trimesh.transformations.translation_matrix((20.5, 0, 0)))
    path = tmp_path / "wall.stl"  # no colours, no sidecar: --reflectance decides
    mesh.export(path)
    bytes_by_reflectance = {}
    for reflectance in ("0.3", "0.6"):
        out = tmp_path / f"w{reflectance}.npz"
        assert main(["scan", "--preset", "livox_mid40_risley", "--scene", str(path), "--pose", "0,0,0,0,0,0",
                     "--reflectance", reflectance, "--seconds", "0.1", "--out", str(out)]) == 0
        data = np.load(out)
        normal = np.hypot(*data["xyz_sensor"][:, 1:].T) / data["xyz_sensor"][:, 0] < np.tan(np.radians(3))
        bytes_by_reflectance[reflectance] = float(np.median(data["reflectivity"][normal]))
    assert abs(bytes_by_reflectance["0.3"] - 45) <= 2 and abs(bytes_by_reflectance["0.6"] - 90) <= 2
    out = tmp_path / "ideal.npz"
    assert main(["scan", "--preset", "livox_mid40_risley", "--returns", "ideal", "--scene", str(path), "--pose",
                 "0,0,0,0,0,0", "--seconds", "0.1", "--out", str(out)]) == 0
    assert np.all(np.load(out)["reflectivity"] == 0) and np.all(np.load(out)["tag"] == 0x10)
    assert main(["scan", "--reflectance", "1.5", "--seconds", "0.1", "--out", str(tmp_path / "x.npz")]) == 2
    assert "reflectance from 0 to 1" in capsys.readouterr().err
    assert main(["info", "--preset", "livox_mid70", "--returns", "datasheet", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["returns_model"] == "datasheet" and info["returns_detection_range_m"] == [[0.1, 90], [0.8, 260]]


def test_the_bags_line_field_is_each_points_laser(tmp_path: Path) -> None:
    """The Avia fires six lasers in turn (sample k on laser k mod 6): CustomMsg and PointCloud2 carry it."""
    from livox_viz import load_preset
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.scene.scenes import open_scene

    bag = tmp_path / "bag"
    assert main(["scan", "--preset", "livox_avia", "--seconds", "0.2", "--seed", "4", "--rosbag", str(bag)]) == 0
    urban = open_scene("urban")
    frames = list(LidarScanner(load_preset("livox_avia"), urban.mesh, urban.vehicle_pose, seed=4).frames(0.2))
    laser = np.concatenate([f.stream_index for f in frames]) % 6
    messages = read_bag(bag)
    line = np.array([p.line for _, m in messages["/livox/lidar"] for p in m.points])
    np.testing.assert_array_equal(line, laser)
    assert set(line.tolist()) == set(range(6))
    cloud = messages["/livox/points"][1][1]
    (offset,) = [f.offset for f in cloud.fields if f.name == "line"]  # where the message says it is
    layout = np.dtype({"names": ["line"], "formats": ["u1"], "offsets": [offset], "itemsize": cloud.point_step})
    first = len(frames[0])
    np.testing.assert_array_equal(np.frombuffer(cloud.data.tobytes(), dtype=layout)["line"],
                                  laser[first : first + len(frames[1])])
