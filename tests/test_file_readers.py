"""Our files as the tools users have read them, with no options: pandas and numpy the CSV, Open3D the PLY."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.files.export import PointCloudWriter, sidecar_path
from livox_viz.scene.scenes import open_scene
from livox_viz.wire.received import RECORDING_FIELDS

COLUMNS = ["x", "y", "z", "range", "time", "frame", "reflectivity", "tag", "return_number", "number_of_returns"]
def third_party(name: str):
    """Import a third-party reader; skipped where it is not installed, but a failure in CI, which installs it."""
    import importlib
    import os

    try:
        return importlib.import_module(name)
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail(f"CI must install {name} (see .ci/run)")
        pytest.skip(f"{name} is not installed (pip install {name}; CI installs it)")


#: The PLY property types Open3D's tensor reader (open3d.t.io) reads; it skips a property of any other type
#: ("unsupported datatype"): its FilePLY.cpp maps uint8/uchar, uint16, int32/int, float32/float, float64/double.
OPEN3D_PLY_TYPES = {"uint8", "uchar", "uint16", "int32", "int", "float32", "float", "float64", "double"}


@pytest.fixture(scope="module")
def frames() -> list:
    """A datasheet scan: second returns, reflectivities and tags in every column."""
    scene = open_scene("urban")
    scanner = LidarScanner(load_preset("livox_mid70_risley"), scene.mesh, scene.vehicle_pose, seed=2)
    frames = list(scanner.frames(0.2))
    assert max(int(frame.return_number.max()) for frame in frames) == 2
    return frames


def _write(path: Path, frames: list, coordinates: str = "sensor", **options) -> Path:
    with PointCloudWriter(path, coordinates, source="a test scan", **options) as writer:
        for frame in frames:
            recorded = {"sender_frame": frame.index, "sender_time": frame.timestamp, "session": 1}
            writer.write(frame, {name: recorded.get(name, 0) for name, _ in RECORDING_FIELDS}
                         if options.get("extra_fields") else None)
    return path


def _expected(frames: list, coordinates: str) -> dict[str, np.ndarray]:
    xyz = np.concatenate([f.xyz_decoded if coordinates == "sensor" else f.xyz_world_decoded for f in frames])
    return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
            "range": np.linalg.norm(np.concatenate([f.xyz_decoded for f in frames]), axis=1),
            "time": np.concatenate([f.t for f in frames]),
            "frame": np.concatenate([np.full(len(f), f.index) for f in frames]),
            **{name: np.concatenate([getattr(f, name) for f in frames])
               for name in ("reflectivity", "tag", "return_number", "number_of_returns")}}


def _assert_columns(read: dict[str, np.ndarray], expected: dict[str, np.ndarray]) -> None:
    """Equal to float32 (sensor x, y, z and range) or to the text's micrometre."""
    for name, values in expected.items():
        np.testing.assert_allclose(np.asarray(read[name], dtype=np.float64), values, rtol=1e-6, atol=1e-6,
                                   err_msg=name)


@pytest.mark.parametrize("coordinates", ["sensor", "world"])
def test_pandas_read_csv_with_no_options_reads_our_csv(tmp_path: Path, frames: list, coordinates: str) -> None:
    """Item 19: a '#' line before the names made pandas take it for the header (7 columns, x/y/z in the index)."""
    import pandas

    out = _write(tmp_path / "cloud.csv", frames, coordinates)
    table = pandas.read_csv(out)
    assert list(table.columns) == COLUMNS
    expected = _expected(frames, coordinates)
    assert len(table) == len(expected["x"])
    _assert_columns({name: table[name].to_numpy() for name in COLUMNS}, expected)
    assert all(table[name].dtype.kind == "i" for name in COLUMNS[5:])  # whole numbers stay whole


@pytest.mark.parametrize("coordinates", ["sensor", "world"])
def test_numpy_genfromtxt_with_names_reads_our_csv(tmp_path: Path, frames: list, coordinates: str) -> None:
    """Item 19: numpy.genfromtxt(names=True) raised on the '#' line with commas."""
    out = _write(tmp_path / "cloud.csv", frames, coordinates)
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert list(table.dtype.names) == COLUMNS
    expected = _expected(frames, coordinates)
    assert table.shape == expected["x"].shape
    _assert_columns({name: table[name] for name in COLUMNS}, expected)


def test_the_csv_says_what_it_is_in_its_sidecar(tmp_path: Path, frames: list) -> None:
    out = _write(tmp_path / "cloud.csv", frames, "world")
    sidecar = sidecar_path(out)
    assert sidecar == tmp_path / "cloud.csv.json" and sorted(p.name for p in tmp_path.iterdir()) == [
        "cloud.csv", "cloud.csv.json"]
    about = json.loads(sidecar.read_text())
    assert about["file"] == "cloud.csv" and about["source"] == "a test scan" and about["coordinates"] == "world"
    assert "world NED" in about["frame"] and "int16" in about["points"]
    assert about["columns"] == COLUMNS and about["rows"] == sum(len(f) for f in frames) and about["frames"] == 2


def test_a_recording_csv_reads_with_no_options_too(tmp_path: Path, frames: list) -> None:
    import pandas

    out = _write(tmp_path / "rec.csv", frames, extra_fields=RECORDING_FIELDS)
    table = pandas.read_csv(out)
    assert list(table.columns) == [*COLUMNS, *(name for name, _ in RECORDING_FIELDS)]
    assert table["session"].tolist() == [1] * len(table)
    assert list(np.genfromtxt(out, delimiter=",", names=True).dtype.names) == list(table.columns)


def _ply_types(path: Path) -> dict[str, str]:
    header = path.read_bytes().split(b"end_header", 1)[0].decode("ascii")
    return {name: kind for kind, name in re.findall(r"^property (\w+) (\w+)$", header, flags=re.MULTILINE)}


PLY_CASES = [({}, "sensor"), ({}, "world"), ({"ascii": True}, "sensor"), ({"extra_fields": RECORDING_FIELDS}, "world")]


@pytest.mark.parametrize(("options", "coordinates"), PLY_CASES)
def test_every_ply_property_has_a_type_open3d_reads(tmp_path: Path, frames: list, options: dict,
                                                    coordinates: str) -> None:
    """Item 20: ``property uint frame`` was skipped by Open3D's tensor reader; plyfile reads every value back."""
    from plyfile import PlyData

    out = _write(tmp_path / "cloud.ply", frames, coordinates, **options)
    types = _ply_types(out)
    assert list(types)[:10] == COLUMNS
    assert set(types.values()) <= OPEN3D_PLY_TYPES, types
    vertex = PlyData.read(str(out))["vertex"]
    _assert_columns({name: vertex[name] for name in COLUMNS}, _expected(frames, coordinates))
    if "extra_fields" in options:
        assert vertex["session"].tolist() == [1] * vertex.count


@pytest.mark.parametrize(("options", "coordinates"), PLY_CASES)
def test_open3d_tensor_reader_reads_every_ply_field(tmp_path: Path, frames: list, options: dict,
                                                   coordinates: str) -> None:
    """Item 20 with the third party itself: Open3D (the bench extra; CI installs it, see .ci/run: 400 MB is too much
    to ask of every `make test`, so elsewhere this is skipped)."""
    o3d = third_party("open3d")

    out = _write(tmp_path / "cloud.ply", frames, coordinates, **options)
    cloud = o3d.t.io.read_point_cloud(str(out))
    expected = _expected(frames, coordinates)
    read = {"x": cloud.point.positions.numpy()[:, 0], "y": cloud.point.positions.numpy()[:, 1],
            "z": cloud.point.positions.numpy()[:, 2]}
    recorded = [name for name, _ in RECORDING_FIELDS] if "extra_fields" in options else []
    for name in COLUMNS[3:] + recorded:
        assert name in cloud.point, f"Open3D dropped {name}"
        read[name] = cloud.point[name].numpy().reshape(-1)
    _assert_columns(read, expected)


def test_the_guide_says_which_return_numbers_a_las_holds(tmp_path: Path, frames: list) -> None:
    """Item 21: the README (its text now in docs/files.md) said every LAS has return_number = number_of_returns = 1,
    where a datasheet LAS holds second returns (its own Outputs paragraph said so): what it says now is what laspy
    reads."""
    import laspy

    guide = (Path(__file__).resolve().parent.parent / "docs" / "files.md").read_text(encoding="utf-8")
    guide = " ".join(guide.split())
    said = guide[guide.index("**A LAS is z-up**"):]
    said = said[: said.index(" - **")]
    assert "`number_of_returns` = 1" not in said
    datasheet = laspy.read(_write(tmp_path / "datasheet.las", frames))
    pairs = set(zip(np.asarray(datasheet.return_number).tolist(), np.asarray(datasheet.number_of_returns).tolist(),
                    strict=True))
    assert {(1, 1), (1, 2), (2, 2)} <= pairs
    scene = open_scene("urban")
    ideal = laspy.read(_write(tmp_path / "ideal.las", list(
        LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose).frames(0.1))))
    ideal_pairs = set(zip(np.asarray(ideal.return_number).tolist(), np.asarray(ideal.number_of_returns).tolist(),
                          strict=True))
    assert ideal_pairs == {(1, 1)}
    assert "1 of 1 for ideal returns" in said and "second" in said and "2 of 2" in said and "1 of 2" in said
