"""Writing keeps up with scanning: files written on their own threads, in place, with compiled text, are the files
the serial writer made (byte for byte, or by their third-party readers)."""

from __future__ import annotations

import io
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import enu_from_ned
from livox_viz.files import las_stream
from livox_viz.files.export import PointCloudWriter, frame_records
from livox_viz.files.text_rows import WHOLE, TextRows, format_rows
from livox_viz.scene.scenes import open_scene


@pytest.fixture(scope="module")
def frames() -> list:
    scene = open_scene("urban")
    scanner = LidarScanner(load_preset("livox_mid70_risley"), scene.mesh, scene.vehicle_pose, seed=5)
    return list(scanner.frames(0.3))


# The compiled text is numpy.savetxt's, byte for byte -------------------------------------------------------
def test_text_rows_are_savetxt_byte_for_byte() -> None:
    rng = np.random.default_rng(7)
    count = 20_000
    float32 = rng.normal(0, 100, (count, 2)).astype(np.float32).astype(np.float64)  # exact halves at 6 decimals
    specials = np.array([0.0078125, -0.0078125, -0.0, 0.0, -1e-9, 1e-7, 5e-7, 2.5e-6, 0.5, 1.5, 2.5, 1e9, 4.6e9,
                         1e15, 123.4567895, np.nan, np.inf, -np.inf, 9.9999995, 99.9999999999])
    values = np.column_stack([rng.normal(0, 1e3, count), float32, np.arange(count) / 100_000.0,
                              rng.integers(-5, 10**6, count).astype(float), rng.integers(0, 256, count).astype(float),
                              np.resize(specials, count)])
    decimals = [6, 6, 6, 9, WHOLE, WHOLE, 6]
    text = io.BytesIO()
    np.savetxt(text, values, fmt=["%.6f"] * 3 + ["%.9f", "%d", "%d", "%.6f"], delimiter=",")
    assert format_rows(values, decimals) == text.getvalue()
    ties = np.array([[k * 0.0078125] for k in range(-300, 300)])  # every one an exact tie at the 7th decimal
    spaced = io.BytesIO()
    np.savetxt(spaced, ties, fmt="%.6f", delimiter=" ")
    assert format_rows(ties, [6], " ") == spaced.getvalue()
    rows = TextRows([6, WHOLE])
    assert b"".join(rows.format(np.array([[1.5, 3.0], [np.nan, 4.0]]))) == b"1.500000,3\nnan,4\n"
    assert rows.format(np.zeros((0, 2))) == []


@pytest.mark.parametrize(("suffix", "ascii"), [(".csv", False), (".ply", True), (".pcd", True)])
def test_text_files_hold_the_rows_savetxt_wrote(tmp_path: Path, frames: list, suffix: str, ascii: bool) -> None:
    """The body after the header is what the serial writer's ``numpy.savetxt`` made of each frame's records."""
    out = tmp_path / f"cloud{suffix}"
    with PointCloudWriter(out, "world", ascii=ascii) as writer:
        for frame in frames:
            writer.write(frame)
    data = out.read_bytes()
    marker = {".csv": b"number_of_returns\n", ".ply": b"end_header\n", ".pcd": b"DATA ascii\n"}[suffix]
    body = data[data.index(marker) + len(marker):]
    formats = ["%.6f"] * 4 + ["%.9f", "%d"] + ["%d"] * 4
    expected = io.BytesIO()
    offset = writer.offset
    for frame in frames:
        records = frame_records(frame, "world", (), None, suffix, offset)
        np.savetxt(expected, np.column_stack([records[n].astype(np.float64) for n in records.dtype.names]),
                   fmt=formats, delimiter="," if suffix == ".csv" else " ")
    assert body == expected.getvalue()


# LAS in place against the LAS assembled at the end; NPZ against numpy's own ---------------------------------
def _las_fields(path: Path) -> dict[str, np.ndarray]:
    import laspy

    las = laspy.read(path)
    fields = {name: np.asarray(las[name]) for name in las.point_format.dimension_names if name not in "XYZ"}
    fields.update(x=np.asarray(las.x), y=np.asarray(las.y), z=np.asarray(las.z))
    header = las.header
    fields["header"] = np.array([header.point_count, *header.number_of_points_by_return, *header.mins, *header.maxs])
    return fields


@pytest.mark.parametrize("coordinates", ["sensor", "world"])
def test_a_las_written_in_place_reads_as_the_las_assembled_at_the_end(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, frames: list, coordinates: str) -> None:
    def write(path: Path) -> None:
        with PointCloudWriter(path, coordinates, source="test") as writer:
            for frame in frames:
                writer.write(frame)

    write(tmp_path / "in_place.las")
    with monkeypatch.context() as patch:  # every frame refused by the packer: the old raw body, assembled by laspy
        patch.setattr(las_stream.LasStream, "pack", lambda self, xyz, columns: None)
        write(tmp_path / "assembled.las")
    in_place, assembled = _las_fields(tmp_path / "in_place.las"), _las_fields(tmp_path / "assembled.las")
    assert sorted(in_place) == sorted(assembled)
    assert in_place["header"][0] == sum(len(f) for f in frames) and in_place["header"][2] > 0  # second returns
    for name, values in assembled.items():  # the same 0.1 mm grid: offsets differ by whole metres
        np.testing.assert_allclose(in_place[name], values, rtol=0, atol=1e-9, err_msg=name)


def test_a_las_that_outgrows_its_first_offset_is_assembled_with_one_for_all(tmp_path: Path, frames: list) -> None:
    """A frame 500 km from the first (beyond what int32 holds at 0.1 mm from the first points): the file takes a
    coarser scale for all of them, each point within it."""
    import laspy

    far = replace(frames[1], sensor_pose=Pose(position=(500_000.0, 0.0, 0.0)))
    far.__dict__.pop("xyz_world_decoded", None)
    out = tmp_path / "wide.las"
    with PointCloudWriter(out, "world") as writer:
        for frame in (frames[0], far, frames[2]):
            writer.write(frame)
    las = laspy.read(out)
    expected = enu_from_ned(np.concatenate([f.xyz_world_decoded for f in (frames[0], far, frames[2])]))
    assert las.header.scales.max() == pytest.approx(1e-3)
    np.testing.assert_allclose(np.column_stack([las.x, las.y, las.z]), expected, rtol=0, atol=0.5e-3 + 0.5e-4)
    assert las.header.point_count == len(expected)
    np.testing.assert_array_equal(np.asarray(las.return_number),
                                  np.concatenate([f.return_number for f in (frames[0], far, frames[2])]))


def test_the_npz_is_numpys_own_arrays_and_a_sound_zip(tmp_path: Path, frames: list) -> None:
    out = tmp_path / "cloud.npz"
    with PointCloudWriter(out, "sensor") as writer:
        for frame in frames:
            writer.write(frame)
    with zipfile.ZipFile(out) as archive:
        assert archive.testzip() is None  # every member's CRC-32 right
    data = np.load(out)
    for name, column in (("xyz_world", "xyz_world"), ("xyz_int16", "xyz_int16"), ("range", "range_m"), ("t", "t"),
                         ("reflectivity", "reflectivity"), ("return_number", "return_number")):
        expected = np.concatenate([getattr(frame, column) for frame in frames])
        assert data[name].dtype == expected.dtype and np.array_equal(data[name], expected), name
    assert np.array_equal(data["frame"], np.concatenate([np.full(len(f), f.index) for f in frames]))
    assert data["frame_pose"].shape == (len(frames), 13)
    again = tmp_path / "again.npz"
    with PointCloudWriter(again, "sensor") as writer:
        for frame in frames:
            writer.write(frame)
    assert again.read_bytes() == out.read_bytes()  # the same frames, the same file


def test_npz_columns_start_on_a_block_boundary(tmp_path: Path, frames: list) -> None:
    """So a file system with shared extents (btrfs, XFS) moves them into the archive without a copy."""
    from livox_viz.files.npzstream import DATA_ALIGN

    out = tmp_path / "cloud.npz"
    with PointCloudWriter(out, "sensor") as writer:
        writer.write(frames[0])
    with zipfile.ZipFile(out) as archive, open(out, "rb") as raw:
        for info in archive.infolist()[:3]:
            raw.seek(info.header_offset + 26)
            name_length, extra_length = np.frombuffer(raw.read(4), "<u2")
            member = info.header_offset + 30 + int(name_length) + int(extra_length)
            raw.seek(member + 8)
            header_length = int(np.frombuffer(raw.read(4), "<u4")[0])
            assert (member + 12 + header_length) % DATA_ALIGN == 0, info.filename


def test_a_bag_written_in_batches_is_the_bag_written_message_by_message(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The IMU, odometry and /tf go into rosbags' MCAP chunks a batch at a time: the same bytes, chunks (about three
    here) and indexes as its own writer makes one message at a time."""
    from livox_viz.cli import main
    from livox_viz.files import rosbag

    for how in ("batch", "single"):
        with monkeypatch.context() as patch:
            if how == "single":
                patch.setattr(rosbag, "append_mcap_messages", lambda bag, messages: False)
            assert main(["scan", "--seconds", "1.2", "--trajectory", "circle", "--imu-noise", "0.01,0.001,0.1,0.01",
                         "--rosbag", str(tmp_path / how)]) == 0
    batch, single = (sorted(p for p in (tmp_path / how).iterdir()) for how in ("batch", "single"))
    assert [p.name for p in batch] == [p.name for p in single]
    assert [p.read_bytes() for p in batch] == [p.read_bytes() for p in single]
    assert sum(p.stat().st_size for p in batch) > 3 * 2**20  # more than one chunk


def test_a_trajectory_evaluates_the_same_whether_kept_or_not() -> None:
    """A bag's frame asks for the same times' motion several times: the kept values are the values, and a copy."""
    from livox_viz.motion.flights import builtin_trajectory

    flight = builtin_trajectory("figure8", 5.0, Pose((0.0, 0.0, -10.0)), 20.0)
    t = np.linspace(3.0, 3.1, 21)
    first = (flight.position_at(t), flight.velocity_at(t), flight.angular_velocity_at(t), flight.orientation_at(t))
    first[0][:] = 0.0  # a caller's array is its own
    again = (flight.position_at(t), flight.velocity_at(t), flight.angular_velocity_at(t), flight.orientation_at(t))
    fresh = builtin_trajectory("figure8", 5.0, Pose((0.0, 0.0, -10.0)), 20.0)
    expected = (fresh._evaluate(t, 0)[:, :3], fresh._evaluate(t, 1)[:, :3], fresh.angular_velocity_at(t),
                fresh.orientation_at(t))
    for got, want in zip(again, expected, strict=True):
        assert np.array_equal(got, want)
    assert not np.array_equal(first[0], again[0])
